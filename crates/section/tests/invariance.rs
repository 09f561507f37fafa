//! Rigid motions of the section mesh in its plane: rotation rotates the 6×6 stiffness,
//! translation moves the centres and leaves the stiffness about them unchanged.

mod common;
use common::*;
use nalgebra::{Matrix2, Matrix6};
use section::{BoxWalls, PlySpec, SectionMesh, analyse, thin_walled_box, tube};

/// An unsymmetric composite box: every kind of coupling is present.
fn unsymmetric_box() -> SectionMesh {
    let deg = std::f64::consts::PI / 180.0;
    let ply = |n: &str, a: f64, t: f64| PlySpec::new(n, composite(), a * deg, t, 1);
    let walls = BoxWalls {
        top: vec![ply("a", 30.0, 0.001), ply("b", -10.0, 0.0005)],
        bottom: vec![ply("a", 60.0, 0.0008)],
        left: vec![ply("a", 0.0, 0.001), ply("b", 45.0, 0.001)],
        right: vec![ply("a", -20.0, 0.0006)],
    };
    thin_walled_box(0.03, 0.02, &walls, 8, 6).unwrap()
}

fn rotation6(alpha: f64) -> Matrix6<f64> {
    let (s, c) = alpha.sin_cos();
    let r = Matrix2::new(c, -s, s, c);
    let mut g = Matrix6::zeros();
    g[(0, 0)] = 1.0;
    g[(3, 3)] = 1.0;
    g.fixed_view_mut::<2, 2>(1, 1).copy_from(&r);
    g.fixed_view_mut::<2, 2>(4, 4).copy_from(&r);
    g
}

#[test]
fn rotating_the_mesh_rotates_the_stiffness() {
    for mesh in [unsymmetric_box(), {
        let deg = std::f64::consts::PI / 180.0;
        let plies = [
            PlySpec::new("in", composite(), 25.0 * deg, 0.0005, 1),
            PlySpec::new("out", composite(), -60.0 * deg, 0.0007, 1),
        ];
        tube(0.01, &plies, 24).unwrap().translated([0.004, -0.002])
    }] {
        let p = analyse(&mesh).unwrap();
        let alpha = 0.7;
        let q = analyse(&mesh.rotated(alpha)).unwrap();
        let g = rotation6(alpha);
        let expected = g * p.stiffness * g.transpose();
        let d = scaled_diff(&q.stiffness, &expected, &expected);
        assert!(d < 1e-9, "rotated stiffness differs by {d:e}");
        let rot = |c: [f64; 2]| {
            [
                c[0] * alpha.cos() - c[1] * alpha.sin(),
                c[0] * alpha.sin() + c[1] * alpha.cos(),
            ]
        };
        for (a, b) in [
            (q.tension_centre, rot(p.tension_centre)),
            (q.shear_centre, rot(p.shear_centre)),
            (q.mass_centre, rot(p.mass_centre)),
        ] {
            assert!(
                (a[0] - b[0]).abs() < 1e-12 && (a[1] - b[1]).abs() < 1e-12,
                "{a:?} vs {b:?}"
            );
        }
    }
}

#[test]
fn translating_the_mesh_moves_the_centres_only() {
    let mesh = unsymmetric_box();
    let p = analyse(&mesh).unwrap();
    // The unsymmetric box really has off-origin centres and couplings.
    assert!(p.tension_centre[0].abs() > 1e-4 && p.shear_centre[1].abs() > 1e-5);
    let shift = [0.013, -0.021];
    let q = analyse(&mesh.translated(shift)).unwrap();
    for (a, b) in [
        (q.tension_centre, p.tension_centre),
        (q.shear_centre, p.shear_centre),
        (q.mass_centre, p.mass_centre),
    ] {
        assert!((a[0] - b[0] - shift[0]).abs() < 1e-12 && (a[1] - b[1] - shift[1]).abs() < 1e-12);
    }
    // About the (moved) tension centre the stiffness is the same …
    let kp = p.stiffness_at(p.tension_centre);
    let kq = q.stiffness_at(q.tension_centre);
    let d = scaled_diff(&kq, &kp, &kp);
    assert!(
        d < 1e-9,
        "stiffness about the tension centre differs by {d:e}"
    );
    // … and about the origin it is not (the check can fail).
    assert!(scaled_diff(&q.stiffness, &p.stiffness, &p.stiffness) > 1e-2);
    // About the tension centre an axial force causes no bending curvature, and about the
    // shear centre a shear force causes no twist.
    let fp = kp.try_inverse().unwrap();
    for j in [4, 5] {
        assert!(fp[(j, 0)].abs() < 1e-9 * (fp[(0, 0)] * fp[(j, j)]).sqrt());
    }
    let fs = p.stiffness_at(p.shear_centre).try_inverse().unwrap();
    for j in [1, 2] {
        assert!(fs[(3, j)].abs() < 1e-9 * (fs[(3, 3)] * fs[(j, j)]).sqrt());
    }
    let cp = p.classical_stiffness_at(p.tension_centre);
    let cq = q.classical_stiffness_at(q.tension_centre);
    for i in 0..4 {
        for j in 0..4 {
            let s = (cp[(i, i)] * cp[(j, j)]).sqrt();
            assert!((cp[(i, j)] - cq[(i, j)]).abs() < 1e-9 * s);
        }
    }
}
