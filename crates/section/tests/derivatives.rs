//! Ply-angle derivatives of every section result against central differences, and their
//! independence of the chunk width.

mod common;
use common::*;
use section::{
    BoxWalls, DesignMap, GeneratedSection, PlySpec, SectionMesh, SectionProperties, analyse,
    analyse_with_derivatives, thin_walled_box, tube,
};

const DEG: f64 = std::f64::consts::PI / 180.0;

fn layered_tube() -> (SectionMesh, DesignMap) {
    let plies = [
        PlySpec::new("p0", composite(), 30.0 * DEG, 0.0005, 1),
        PlySpec::new("p1", composite(), -45.0 * DEG, 0.0005, 1),
        PlySpec::new("p2", composite(), 60.0 * DEG, 0.0005, 1),
    ];
    let mesh = tube(0.01, &plies, 24).unwrap().translated([0.002, 0.001]);
    let design = DesignMap::new()
        .with_named_variable(&mesh, "inner", &[("p0", 1.0)])
        .unwrap()
        .with_named_variable(&mesh, "balanced", &[("p1", 1.0), ("p2", -1.0)])
        .unwrap()
        .with_named_variable(&mesh, "double", &[("p2", 2.0)])
        .unwrap();
    (mesh, design)
}

fn unsymmetric_box() -> (SectionMesh, DesignMap) {
    let ply = |n: &str, a: f64, t: f64| PlySpec::new(n, composite(), a * DEG, t, 1);
    let walls = BoxWalls {
        top: vec![ply("a", 30.0, 0.001), ply("b", -10.0, 0.0005)],
        bottom: vec![ply("a", 60.0, 0.0008)],
        left: vec![ply("a", 0.0, 0.001), ply("b", 45.0, 0.001)],
        right: vec![ply("a", -20.0, 0.0006)],
    };
    let mesh = thin_walled_box(0.03, 0.02, &walls, 6, 4).unwrap();
    let design = DesignMap::each_region(&mesh);
    (mesh, design)
}

/// All results as one vector, with a natural scale for each.
fn flatten(p: &SectionProperties, scale: &SectionProperties) -> Vec<(f64, f64, String)> {
    let mut v = Vec::new();
    for i in 0..6 {
        for j in 0..6 {
            let s = (scale.stiffness[(i, i)] * scale.stiffness[(j, j)]).sqrt();
            v.push((p.stiffness[(i, j)], s, format!("K[{i}][{j}]")));
            let s = (scale.compliance[(i, i)] * scale.compliance[(j, j)]).sqrt();
            v.push((p.compliance[(i, j)], s, format!("F[{i}][{j}]")));
        }
    }
    for i in 0..4 {
        for j in 0..4 {
            let c = &scale.classical_stiffness;
            let s = (c[(i, i)] * c[(j, j)]).sqrt();
            v.push((p.classical_stiffness[(i, j)], s, format!("Kc[{i}][{j}]")));
        }
    }
    // Centres: scale by the section size (~1 cm).
    for k in 0..2 {
        v.push((p.tension_centre[k], 0.01, format!("tension centre {k}")));
        v.push((p.shear_centre[k], 0.01, format!("shear centre {k}")));
    }
    v
}

fn check_against_central_differences(mesh: &SectionMesh, design: &DesignMap) {
    let s = analyse_with_derivatives::<2>(mesh, design).unwrap();
    let h = 1e-5;
    let mut worst: f64 = 0.0;
    for (k, d) in s.derivatives.iter().enumerate() {
        let plus = analyse(&design.step(mesh, k, h)).unwrap();
        let minus = analyse(&design.step(mesh, k, -h)).unwrap();
        let (fp, fm, fd) = (
            flatten(&plus, &s.properties),
            flatten(&minus, &s.properties),
            flatten(d, &s.properties),
        );
        let mut nonzero = false;
        for ((p, m), (a, scale, name)) in fp.iter().zip(&fm).zip(&fd) {
            let cd = (p.0 - m.0) / (2.0 * h);
            let err = (a - cd).abs() / scale;
            worst = worst.max(err);
            assert!(
                err < 1e-6,
                "variable {k}, {name}: dual {a:e}, central difference {cd:e}"
            );
            nonzero |= a.abs() > 1e-3 * scale;
        }
        assert!(
            nonzero,
            "variable {k}: all derivatives vanish, the check is empty"
        );
        // Ply angles do not change the mass.
        assert_eq!(d.mass_per_length, 0.0);
    }
    println!("worst scaled error {worst:e}");
}

#[test]
fn tube_derivatives_match_central_differences() {
    let (mesh, design) = layered_tube();
    check_against_central_differences(&mesh, &design);
}

#[test]
fn box_derivatives_match_central_differences() {
    let (mesh, design) = unsymmetric_box();
    check_against_central_differences(&mesh, &design);
}

#[test]
fn derivatives_do_not_depend_on_chunk_width() {
    let (mesh, design) = unsymmetric_box();
    let a = analyse_with_derivatives::<1>(&mesh, &design).unwrap();
    let b = analyse_with_derivatives::<2>(&mesh, &design).unwrap();
    let c = analyse_with_derivatives::<4>(&mesh, &design).unwrap();
    assert_eq!(a.variables, c.variables);
    assert_eq!(a.derivatives.len(), design.variables.len());
    for k in 0..design.variables.len() {
        let (fa, fb, fc) = (
            flatten(&a.derivatives[k], &a.properties),
            flatten(&b.derivatives[k], &a.properties),
            flatten(&c.derivatives[k], &a.properties),
        );
        for ((x, y), z) in fa.iter().zip(&fb).zip(&fc) {
            assert!(
                (x.0 - y.0).abs() <= 1e-12 * x.1,
                "{}: {} vs {}",
                x.2,
                x.0,
                y.0
            );
            assert!(
                (x.0 - z.0).abs() <= 1e-12 * x.1,
                "{}: {} vs {}",
                x.2,
                x.0,
                z.0
            );
        }
    }
}

/// The stiffness about a centre that moves with the design: its derivative includes the
/// centre's motion.
#[test]
fn stiffness_about_moving_centres_matches_central_differences() {
    use section::ReferencePoint;
    let (mesh, design) = unsymmetric_box();
    let s = analyse_with_derivatives::<4>(&mesh, &design).unwrap();
    let h = 1e-5;
    for at in [ReferencePoint::TensionCentre, ReferencePoint::ShearCentre] {
        let (k, dk) = s.stiffness_about(at);
        for (v, d) in dk.iter().enumerate().take(3) {
            let sp = section::SectionSensitivities {
                properties: analyse(&design.step(&mesh, v, h)).unwrap(),
                ..Default::default()
            };
            let sm = section::SectionSensitivities {
                properties: analyse(&design.step(&mesh, v, -h)).unwrap(),
                ..Default::default()
            };
            let cd = (sp.stiffness_about(at).0 - sm.stiffness_about(at).0) / (2.0 * h);
            let err = scaled_diff(d, &cd, &k);
            assert!(err < 1e-6, "{at:?}, variable {v}: error {err:e}");
            // The centre's motion matters: the fixed-point derivative is different.
            let fixed = s.stiffness_about(ReferencePoint::Point(match at {
                ReferencePoint::TensionCentre => s.properties.tension_centre,
                _ => s.properties.shear_centre,
            }));
            assert!(
                scaled_diff(&fixed.1[v], &cd, &k) > 1e-4,
                "{at:?}, variable {v}"
            );
        }
    }
}

/// A region's density as a design variable: the mass per length, mass centre and inertias move
/// (against central differences and the closed form of a thin ring's mass), the stiffness not.
#[test]
fn density_derivatives_of_the_mass_properties() {
    let (mesh, _) = layered_tube();
    let rho = mesh.regions[0].material.density();
    let design = DesignMap {
        variables: vec![section::DesignVariable {
            name: "rho0".into(),
            links: Vec::new(),
            materials: Vec::new(),
            densities: vec![(0, 1.0)],
            nodes: Vec::new(),
        }],
    };
    let d = &analyse_with_derivatives::<1>(&mesh, &design)
        .unwrap()
        .derivatives[0];
    let at = |r: f64| {
        let mut m = mesh.clone();
        m.regions[0].material = m.regions[0].material.with_density(r).unwrap();
        analyse(&m).unwrap()
    };
    let h = 1e-3 * rho;
    let (p, q) = (at(rho + h), at(rho - h));
    let fd = |f: &dyn Fn(&SectionProperties) -> f64| (f(&p) - f(&q)) / (2.0 * h);
    let checks: [(&str, f64, f64); 3] = [
        (
            "mass per length",
            d.mass_per_length,
            fd(&|s| s.mass_per_length),
        ),
        ("I22", d.mass_inertia[0], fd(&|s| s.mass_inertia[0])),
        ("I33", d.mass_inertia[1], fd(&|s| s.mass_inertia[1])),
    ];
    for (what, exact, diff) in checks {
        assert!(
            (exact - diff).abs() <= 1e-7 * exact.abs().max(1e-12),
            "{what}: {exact} vs {diff}"
        );
    }
    // the innermost ply's area (inner radius 10 mm, 0.5 mm thick): the mass per length moves
    // by the ply's area per unit density (the 24-sided mesh's chords: within 1 %)
    let ring = std::f64::consts::PI * (0.0105f64.powi(2) - 0.01f64.powi(2));
    assert!(
        (d.mass_per_length - ring).abs() < 1e-2 * ring,
        "{}",
        d.mass_per_length
    );
    // the plies are concentric: the mass centre does not move; nor does the stiffness
    assert!(
        d.mass_centre.iter().all(|x| x.abs() < 1e-15),
        "{:?}",
        d.mass_centre
    );
    assert_eq!(d.stiffness, nalgebra::Matrix6::zeros());
}

/// Ply thicknesses as design variables: the nodes move with velocities generated by the same
/// code that places them. Every result (stiffness, compliance, centres, mass properties)
/// against central differences of sections generated again at `t ± h` (not moved by the
/// velocities), for a tube (a middle ply: the plies outside it move out) and a box (one
/// ply on all four walls, and one wall's ply alone), chunked with an angle variable.
#[test]
fn ply_thickness_derivatives_match_regenerated_sections() {
    let ply = |n: &str, a: f64, t: f64| PlySpec::new(n, composite(), a * DEG, t, 1);
    let tube = GeneratedSection::Tube {
        inner_radius: 0.01,
        plies: vec![
            ply("p0", 30.0, 0.0005),
            ply("p1", -45.0, 0.0007),
            ply("p2", 60.0, 0.0004),
        ],
        circumferential: 24,
    };
    let walls = BoxWalls {
        top: vec![ply("a", 30.0, 0.001), ply("b", -10.0, 0.0005)],
        bottom: vec![ply("a", 60.0, 0.0008), ply("b", 15.0, 0.0006)],
        left: vec![ply("la", 0.0, 0.001), ply("b", 45.0, 0.001)],
        right: vec![ply("a", -20.0, 0.0006), ply("b", 5.0, 0.0009)],
    };
    let boxed = GeneratedSection::Walled {
        width: 0.03,
        height: 0.02,
        walls,
        n_width: 6,
        n_height: 4,
        open: false,
    };
    // (section, plies moved: name → dt/db, how to move them)
    type Mover = fn(&mut GeneratedSection, f64);
    let cases: [(&GeneratedSection, &str, Mover); 3] = [
        (&tube, "p1", |g, dt| {
            if let GeneratedSection::Tube { plies, .. } = g {
                plies[1].thickness += dt;
            }
        }),
        (&boxed, "b", |g, dt| {
            if let GeneratedSection::Walled { walls, .. } = g {
                for w in [
                    &mut walls.top,
                    &mut walls.bottom,
                    &mut walls.left,
                    &mut walls.right,
                ] {
                    w[1].thickness += dt;
                }
            }
        }),
        (&boxed, "la", |g, dt| {
            if let GeneratedSection::Walled { walls, .. } = g {
                walls.left[0].thickness += dt;
            }
        }),
    ];
    for (case, (generated, ply_name, moved)) in cases.into_iter().enumerate() {
        let mesh = generated.mesh().unwrap();
        let velocities = generated
            .node_velocities(|p| f64::from(u8::from(p.name == ply_name)))
            .unwrap();
        let design = DesignMap::new()
            .with_named_variable(&mesh, "angle", &[(mesh.regions[0].name.as_str(), 1.0)])
            .unwrap()
            .with_geometry_variable("t", &velocities);
        let s = analyse_with_derivatives::<2>(&mesh, &design).unwrap();
        let h = 1e-8;
        let at = |dt: f64| {
            let mut g = generated.clone();
            moved(&mut g, dt);
            analyse(&g.mesh().unwrap()).unwrap()
        };
        let (plus, minus) = (at(h), at(-h));
        let d = &s.derivatives[1];
        let (fp, fm, fd) = (
            flatten(&plus, &s.properties),
            flatten(&minus, &s.properties),
            flatten(d, &s.properties),
        );
        let mut worst: f64 = 0.0;
        for ((p, m), (a, scale, name)) in fp.iter().zip(&fm).zip(&fd) {
            // a thickness step of 1e-8 m changes the section by ~1e-5: scale to per 1 mm
            let cd = (p.0 - m.0) / (2.0 * h);
            let err = (a - cd).abs() * 1e-3 / scale;
            worst = worst.max(err);
            assert!(
                err < 1e-6,
                "case {case}, {name}: dual {a:e}, central {cd:e}"
            );
        }
        let dm = (plus.mass_per_length - minus.mass_per_length) / (2.0 * h);
        assert!(
            rel(d.mass_per_length, dm) < 1e-6,
            "case {case}: dm/dt {} against {dm}",
            d.mass_per_length
        );
        for i in 0..3 {
            let cd = (plus.mass_inertia[i] - minus.mass_inertia[i]) / (2.0 * h);
            let scale = s.properties.mass_inertia[0] * 1e3;
            assert!(
                (d.mass_inertia[i] - cd).abs() < 1e-6 * scale,
                "case {case}: mass inertia {i}: {} against {cd}",
                d.mass_inertia[i]
            );
        }
        assert!(
            d.stiffness[(0, 0)] > 0.0,
            "case {case}: a thicker ply stiffens"
        );
        println!("case {case}: worst scaled error {worst:e}");
    }
}
