//! Solid isotropic circles (the O-grid generator) against closed forms: `EA = E π R²`,
//! `EI = E π R⁴ / 4`, `GJ = G π R⁴ / 2` (a circle does not warp in torsion), mass properties,
//! and the exact shear coefficient of a circle for ν = 0, `6/7` (Cowper's value, exact there).
//! Everything converges as the mesh is refined.

mod common;
use common::*;
use section::{analyse, circle};
use std::f64::consts::PI;

const E: f64 = 70e9;

fn errors(around: usize, radial: usize, nu: f64) -> [f64; 5] {
    let r = 0.01;
    let g = E / (2.0 * (1.0 + nu));
    let p = analyse(&circle(r, around, radial, isotropic(E, nu), 0.0).unwrap()).unwrap();
    let a = PI * r * r;
    let i = PI * r.powi(4) / 4.0;
    let k = p.stiffness;
    for c in [p.tension_centre, p.shear_centre, p.mass_centre] {
        assert!(c[0].abs() < 1e-12 && c[1].abs() < 1e-12, "centre {c:?}");
    }
    [
        rel(k[(0, 0)], E * a),
        rel(k[(4, 4)], E * i).max(rel(k[(5, 5)], E * i)),
        rel(k[(3, 3)], 2.0 * g * i),
        rel(p.mass_per_length, 2700.0 * a).max(rel(p.polar_mass_inertia(), 2700.0 * 2.0 * i)),
        rel(k[(1, 1)], 6.0 / 7.0 * g * a).max(rel(k[(2, 2)], 6.0 / 7.0 * g * a)),
    ]
}

#[test]
fn solid_circle_matches_closed_forms_and_converges() {
    let coarse = errors(8, 2, 0.0);
    let fine = errors(24, 6, 0.0);
    eprintln!("circle, ν = 0: 8 × 2 {coarse:?}, 24 × 6 {fine:?}");
    // measured 8 × 2: 4e-4 … 1.6e-3; 24 × 6: 6e-6 … 2e-5 (the quadratic rim converges)
    for (c, f) in coarse.iter().zip(&fine) {
        assert!(*f < c / 20.0, "{coarse:?} → {fine:?}");
    }
    assert!(fine.iter().all(|&e| e < 5e-5), "{fine:?}");
    // ν > 0: stiffnesses (not the shear coefficient, which is then Cowper's only approximately)
    let nu = errors(24, 6, 0.3);
    assert!(nu[..4].iter().all(|&e| e < 5e-5), "{nu:?}");
}

#[test]
fn bad_circles_are_refused() {
    let m = isotropic(E, 0.3);
    for (r, around, radial) in [
        (0.0, 8, 2),
        (f64::NAN, 8, 2),
        (0.01, 6, 2),
        (0.01, 10, 2),
        (0.01, 8, 0),
    ] {
        assert!(
            circle(r, around, radial, m, 0.0).is_err(),
            "{r} {around} {radial}"
        );
    }
}
