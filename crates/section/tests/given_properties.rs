//! Sections given by their properties: the stiffness built from stiffnesses about the tension
//! and shear centres reproduces an analysed isotropic channel (whose shear centre lies outside
//! it, away from its tension centre), and a section given by an analysed section's stiffness
//! and mass has the analysed compliance, classical stiffness and centres.

mod common;
use common::*;
use nalgebra::Matrix6;
use section::{BoxWalls, PlySpec, SectionProperties, analyse, channel, stiffness_from_centres};

/// An isotropic channel, 60 × 40 mm, 3 mm walls, open towards +x₂.
fn channel_properties() -> SectionProperties {
    let ply = |name: &str| vec![PlySpec::new(name, isotropic(70e9, 0.3), 0.0, 3e-3, 2)];
    let walls = BoxWalls {
        top: ply("top"),
        bottom: ply("bottom"),
        left: ply("web"),
        right: Vec::new(),
    };
    analyse(&channel(0.04, 0.06, &walls, 8, 12).unwrap()).unwrap()
}

#[test]
fn stiffness_from_the_centres_reproduces_an_analysed_channel() {
    let p = channel_properties();
    let (t, s) = (p.tension_centre, p.shear_centre);
    // the channel's shear centre lies beyond its web, its tension centre inside
    assert!(s[0] < t[0] - 0.01, "{t:?} {s:?}");
    // the stiffnesses about the centres: axial and bending at the tension centre, shear and
    // torsion at the shear centre
    let at_t = p.stiffness_at(t);
    let at_s = p.stiffness_at(s);
    let diagonal = [
        at_t[(0, 0)],
        at_s[(1, 1)],
        at_s[(2, 2)],
        at_s[(3, 3)],
        at_t[(4, 4)],
        at_t[(5, 5)],
    ];
    let k = stiffness_from_centres(diagonal, t, s);
    let scale = |i: usize, j: usize| (p.stiffness[(i, i)] * p.stiffness[(j, j)]).sqrt();
    for i in 0..6 {
        for j in 0..6 {
            let err = (k[(i, j)] - p.stiffness[(i, j)]).abs() / scale(i, j);
            assert!(
                err < 1e-6,
                "K{}{}: {:e} against the analysis's {:e}",
                i + 1,
                j + 1,
                k[(i, j)],
                p.stiffness[(i, j)]
            );
        }
    }
    // the couplings at the origin are real: the offsets matter
    assert!(p.stiffness[(0, 5)].abs() > 1e-3 * scale(0, 5));
    assert!(p.stiffness[(2, 3)].abs() > 1e-3 * scale(2, 3));
}

#[test]
fn a_section_given_by_an_analysed_ones_properties_is_that_section() {
    let p = channel_properties();
    let q = SectionProperties::given(
        p.stiffness,
        p.mass_per_length,
        p.mass_centre,
        p.mass_inertia,
    )
    .unwrap();
    let close = |a: f64, b: f64, scale: f64| (a - b).abs() <= 1e-9 * scale;
    for i in 0..6 {
        for j in 0..6 {
            let f = (p.compliance[(i, i)] * p.compliance[(j, j)]).sqrt();
            assert!(close(q.compliance[(i, j)], p.compliance[(i, j)], f));
        }
    }
    for i in 0..4 {
        for j in 0..4 {
            let k = (p.classical_stiffness[(i, i)] * p.classical_stiffness[(j, j)]).sqrt();
            assert!(close(
                q.classical_stiffness[(i, j)],
                p.classical_stiffness[(i, j)],
                k
            ));
        }
    }
    for (a, b) in [
        (q.tension_centre, p.tension_centre),
        (q.shear_centre, p.shear_centre),
    ] {
        assert!(
            close(a[0], b[0], 0.04) && close(a[1], b[1], 0.04),
            "{a:?} {b:?}"
        );
    }
    assert!(q.area.is_nan());
}

#[test]
fn given_properties_that_are_no_section_are_refused() {
    let p = channel_properties();
    let given = |k: Matrix6<f64>, m: f64, i: [f64; 3]| {
        SectionProperties::given(k, m, [0.0, 0.0], i)
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default()
    };
    let mut asymmetric = p.stiffness;
    asymmetric[(0, 5)] += 1e-3 * p.stiffness[(0, 0)];
    assert!(given(asymmetric, 1.0, [1.0, 1.0, 0.0]).contains("not symmetric"));
    let mut indefinite = p.stiffness;
    indefinite[(3, 3)] = -1.0;
    assert!(given(indefinite, 1.0, [1.0, 1.0, 0.0]).contains("not positive definite"));
    assert!(given(p.stiffness, 0.0, [1.0, 1.0, 0.0]).contains("mass per length"));
    assert!(given(p.stiffness, 1.0, [1.0, 1.0, 2.0]).contains("inertias"));
    assert!(given(p.stiffness * f64::NAN, 1.0, [1.0, 1.0, 0.0]).contains("finite"));
}

/// The mass properties read back from the 6×6 mass matrix the section writes, for a section
/// whose mass centre is off the origin; a matrix of no rigid section is refused.
#[test]
fn the_mass_of_a_mass_matrix_is_the_sections() {
    let mut p = channel_properties();
    p.mass_centre = [0.004, -0.003];
    p.mass_inertia = [2.0e-6, 3.0e-6, 0.4e-6];
    let (m, c, i) = SectionProperties::mass_of_matrix(&p.mass_matrix()).unwrap();
    assert!((m - p.mass_per_length).abs() < 1e-14 * m);
    for k in 0..2 {
        assert!((c[k] - p.mass_centre[k]).abs() < 1e-15, "{c:?}");
    }
    for k in 0..3 {
        assert!(
            (i[k] - p.mass_inertia[k]).abs() < 1e-12 * p.mass_inertia[0],
            "{i:?}"
        );
    }
    let mut polar = p.mass_matrix();
    polar[(3, 3)] *= 1.1;
    let e = SectionProperties::mass_of_matrix(&polar)
        .unwrap_err()
        .to_string();
    assert!(e.contains("entry (4, 4)"), "{e}");
}
