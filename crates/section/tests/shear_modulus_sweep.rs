//! The transverse shear stiffness of a composite tube over shear moduli from 1e-3 to 1e3 times
//! the transverse modulus. Issue 35 reported "shear stiffness falling as G rises" as an anomaly;
//! it is the Saint-Venant flexure solution, which the section analysis reproduces exactly:
//!
//! - with ν = 0 the flexure warping does not depend on the material, so the shear compliance is
//!   `F₂₂ = 1/(k G A)`, `k` the geometric (Cowper, ν = 0) coefficient: `K₂₂ / (G A)` is the
//!   same at every G;
//! - with ν ≠ 0 the axial stress that varies along a beam in flexure strains the section
//!   through Poisson's ratio, and that anticlastic warping adds a compliance `c ν² G` (c ∝ 1/E²)
//!   that grows with G. So `F₂₂ = a/G + c ν² G` has a minimum at `G* = sqrt(a / (c ν²))`, a few
//!   hundred times E₂ for this tube. Beyond it K₂₂ falls as G rises, a property of the
//!   energy-equivalent Timoshenko model (Dong, Alpdogan & Taciroglu 2010), not round-off: it
//!   does not change with the mesh.

mod common;
use common::*;
use laminate::OrthotropicMaterial;
use section::{PlySpec, analyse, tube};
use std::f64::consts::PI;

const E1: f64 = 128e9;
const E2: f64 = 10.1e9;
const RI: f64 = 4.529e-3;
const T: f64 = 1e-3;

/// The shear compliance `F₂₂` of a 0° tube of shear modulus `g` (all three) and Poisson ratio
/// `nu` (all three), meshed `through` × `around`.
fn shear_compliance(g: f64, nu: f64, through: usize, around: usize) -> f64 {
    let m = OrthotropicMaterial::new([E1, E2, E2], [g, g, g], [nu, nu, nu], 1586.0).unwrap();
    let plies = [PlySpec::new("wall", m, 0.0, T, through)];
    let p = analyse(&tube(RI, &plies, around).unwrap()).unwrap();
    p.stiffness.try_inverse().unwrap()[(1, 1)]
}

#[test]
fn without_poisson_the_shear_stiffness_is_k_g_a_at_every_shear_modulus() {
    let ro = RI + T;
    let area = PI * (ro * ro - RI * RI);
    let m = RI / ro;
    let m2 = m * m;
    // Cowper's tube coefficient at ν = 0 (exact for ν = 0)
    let cowper = 6.0 * (1.0 + m2).powi(2) / (7.0 * (1.0 + m2).powi(2) + 20.0 * m2);
    let k0 = 1.0 / (shear_compliance(E2 * 1e-3, 0.0, 2, 64) * E2 * 1e-3 * area);
    assert!(rel(k0, cowper) < 1e-5, "k = {k0}, Cowper {cowper}");
    for f in [1e-2, 1e-1, 1.0, 1e1, 1e2, 1e3] {
        let g = E2 * f;
        let k = 1.0 / (shear_compliance(g, 0.0, 2, 64) * g * area);
        assert!(rel(k, k0) < 1e-9, "G = {f} E2: k = {k} against {k0}");
    }
}

#[test]
fn the_poisson_part_of_the_shear_compliance_grows_as_nu_squared_times_g() {
    let nu = 0.23;
    // c ν² = (F₂₂(ν) − F₂₂(0)) / G, the same at every large G and four times smaller at ν/2
    let poisson = |f: f64, nu: f64| {
        let g = E2 * f;
        (shear_compliance(g, nu, 1, 64) - shear_compliance(g, 0.0, 1, 64)) / g
    };
    let c = poisson(100.0, nu);
    assert!(c > 0.0);
    for f in [10.0, 1000.0] {
        assert!(rel(poisson(f, nu), c) < 2e-4, "G = {f} E2");
    }
    assert!(rel(poisson(100.0, nu / 2.0), c / 4.0) < 1e-4);
    // so K₂₂ peaks near G* = sqrt(a / (c ν²)), a = F₂₂(ν = 0) G, and falls beyond it
    let a = shear_compliance(E2, 0.0, 1, 64) * E2;
    let g_star = (a / c).sqrt();
    assert!(
        g_star > 100.0 * E2 && g_star < 1000.0 * E2,
        "G* = {:e}",
        g_star / E2
    );
    let k22 = |g: f64| 1.0 / shear_compliance(g, nu, 1, 64);
    assert!(k22(g_star) > k22(g_star / 10.0) && k22(g_star) > k22(g_star * 10.0));
    // a finer mesh changes none of it
    let fine = (shear_compliance(10.0 * g_star, nu, 4, 128)
        - shear_compliance(10.0 * g_star, 0.0, 4, 128))
        / (10.0 * g_star);
    assert!(rel(fine, c) < 1e-2, "{fine:e} against {c:e}");
}
