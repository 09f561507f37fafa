//! Shared materials and checks for the section tests.
#![allow(dead_code)]

use laminate::OrthotropicMaterial;
use nalgebra::Matrix6;

/// The composite of the paper's examples (docs/design.md §4).
pub fn composite() -> OrthotropicMaterial {
    OrthotropicMaterial::new(
        [128e9, 10.1e9, 10.1e9],
        [5.36e9, 5.36e9, 5.36e9],
        [0.23, 0.23, 0.23],
        1586.0,
    )
    .unwrap()
}

pub fn isotropic(e: f64, nu: f64) -> OrthotropicMaterial {
    OrthotropicMaterial::isotropic(e, nu, 2700.0).unwrap()
}

pub fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

/// Largest entry difference, each entry scaled by `sqrt(K_ii K_jj)` (the natural size of a
/// stiffness coupling).
pub fn scaled_diff(a: &Matrix6<f64>, b: &Matrix6<f64>, scale: &Matrix6<f64>) -> f64 {
    let mut m: f64 = 0.0;
    for i in 0..6 {
        for j in 0..6 {
            let s = (scale[(i, i)] * scale[(j, j)]).abs().sqrt();
            m = m.max((a[(i, j)] - b[(i, j)]).abs() / s);
        }
    }
    m
}
