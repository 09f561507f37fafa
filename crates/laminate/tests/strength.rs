//! Failure criteria against hand calculations (T300/5208-like strengths, MPa: Xt 1500,
//! Xc 1200, Yt 40, Yc 246, S12 68), the reserve factor's meaning (the scaled stress meets the
//! criterion, the index is proportional to the load), and the indices' derivatives against
//! central differences.

use laminate::{Criterion, OrthotropicMaterial, PlyStrength, TSAI_WU_INTERACTION};
use sens::{Dual, Scalar};

const MPA: f64 = 1e6;

fn material() -> OrthotropicMaterial {
    OrthotropicMaterial::new(
        [181e9, 10.3e9, 10.3e9],
        [7.17e9, 7.17e9, 3.78e9],
        [0.28, 0.28, 0.36],
        1600.0,
    )
    .unwrap()
}

fn strength() -> PlyStrength {
    PlyStrength::new(
        1500.0 * MPA,
        1200.0 * MPA,
        40.0 * MPA,
        246.0 * MPA,
        68.0 * MPA,
    )
    .unwrap()
}

/// A plane stress `[σ11, σ22, τ12]` (MPa) as a 3-D one (Pa).
fn plane(s11: f64, s22: f64, t12: f64) -> [f64; 6] {
    [s11 * MPA, s22 * MPA, 0.0, 0.0, 0.0, t12 * MPA]
}

fn index(c: Criterion, s: &[f64; 6]) -> f64 {
    c.index(&material(), &strength(), s)
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * b.abs().max(1e-300)
}

#[test]
fn maximum_stress_takes_the_largest_ratio_with_the_strength_of_each_sign() {
    // 800/1500, 20/40, 34/68
    let fi = index(Criterion::MaxStress, &plane(800.0, 20.0, 34.0));
    assert!(close(fi, 800.0 / 1500.0, 1e-14), "{fi}");
    // compression against Xc and Yc, shear by its magnitude
    let fi = index(Criterion::MaxStress, &plane(-600.0, -100.0, -51.0));
    assert!(close(fi, 51.0 / 68.0, 1e-14), "{fi}");
    let fi = index(Criterion::MaxStress, &plane(-1140.0, -100.0, -51.0));
    assert!(close(fi, 1140.0 / 1200.0, 1e-14), "{fi}");
}

#[test]
fn maximum_strain_compares_strains_with_the_strengths_over_the_moduli() {
    let m = material();
    let [e1, e2, _] = m.young_moduli();
    let nu12 = m.poisson_ratios()[0];
    // σ22 alone: ε22 = σ22/E2 against Yt/E2 (the index of σ22 over Yt), ε11 = −ν12 σ22/E1
    // against Xc/E1
    let fi = index(Criterion::MaxStrain, &plane(0.0, 20.0, 0.0));
    assert!(close(fi, 0.5, 1e-12), "{fi}");
    // σ11 alone, large: ε22 = −ν21 σ11/E2 = −ν12 σ11/E1 against Yc/E2
    let s11 = 1000.0;
    let fi = index(Criterion::MaxStrain, &plane(s11, 0.0, 0.0));
    let expected = (s11 / 1500.0).max(nu12 * s11 / e1 * e2 / 246.0);
    assert!(close(fi, expected, 1e-12), "{fi} vs {expected}");
    // shear: γ12 = τ12/G12 against S12/G12
    let fi = index(Criterion::MaxStrain, &plane(0.0, 0.0, 34.0));
    assert!(close(fi, 0.5, 1e-12), "{fi}");
}

#[test]
fn tsai_hill_reduces_to_the_classical_plane_stress_form() {
    // (σ1/X)² − σ1σ2/X² + (σ2/Y)² + (τ/S)², X and Y of the stresses' signs
    let fi = index(Criterion::TsaiHill, &plane(500.0, 10.0, 20.0));
    assert!(close(fi, 0.507832727578981, 1e-13), "{fi}");
    let fi = index(Criterion::TsaiHill, &plane(500.0, -100.0, 20.0));
    assert!(close(fi, 0.620551431018675, 1e-13), "{fi}");
}

#[test]
fn tsai_wu_solves_for_the_reserve_factor_with_the_tsai_hahn_interaction() {
    assert_eq!(TSAI_WU_INTERACTION, -0.5);
    // F1 σ1 + F2 σ2 + F11 σ1² + F22 σ2² + F66 τ² + 2 F12 σ1σ2 = 0.32400 at the stress; the
    // reserve factor R solves a R² + b R = 1
    let fi = index(Criterion::TsaiWu, &plane(500.0, 10.0, 20.0));
    assert!(close(fi, 0.5124045443655304, 1e-13), "{fi}");
}

#[test]
fn hashin_modes_against_hand_calculations() {
    let s = strength()
        .with_transverse(40.0 * MPA, 246.0 * MPA, 68.0 * MPA, 50.0 * MPA)
        .unwrap();
    let fi = |c: Criterion, x: [f64; 6]| c.index(&material(), &s, &x);
    // fibre tension √((σ1/Xt)² + (τ12/S12)²), fibre compression σ1/Xc
    let ft = fi(Criterion::HashinFibre, plane(1000.0, 0.0, 30.0));
    assert!(close(ft, 0.7994254953684781, 1e-13), "{ft}");
    let fc = fi(Criterion::HashinFibre, plane(-600.0, 0.0, 30.0));
    assert!(close(fc, 0.5, 1e-14), "{fc}");
    // matrix tension √((σ2/Yt)² + (τ12/S12)²)
    let mt = fi(Criterion::HashinMatrix, plane(0.0, 20.0, 30.0));
    assert!(close(mt, 0.6668108263973315, 1e-13), "{mt}");
    // matrix compression: [(Yc/2S23)² − 1] σ2/Yc + σ2²/4S23² + (τ12/S12)², R by a R² + b R = 1
    let mc = fi(Criterion::HashinMatrix, plane(0.0, -150.0, 20.0));
    assert!(close(mc, 0.6297814602114244, 1e-13), "{mc}");
    // the criterion: the larger mode
    let both = fi(Criterion::Hashin, plane(1000.0, -150.0, 20.0));
    let larger = fi(Criterion::HashinFibre, plane(1000.0, -150.0, 20.0))
        .max(fi(Criterion::HashinMatrix, plane(1000.0, -150.0, 20.0)));
    assert_eq!(both, larger);
}

/// Stress states of every sign combination, 3-D.
fn states() -> Vec<[f64; 6]> {
    let mut out = Vec::new();
    for s1 in [-700.0, 300.0] {
        for s2 in [-90.0, 15.0] {
            for s3 in [-40.0, 0.0, 10.0] {
                out.push([s1, s2, s3, 12.0, -9.0, 25.0].map(|x| x * MPA));
            }
        }
    }
    out
}

#[test]
fn every_index_is_proportional_to_the_load_and_the_scaled_stress_meets_the_criterion() {
    for c in Criterion::ALL {
        for s in states() {
            let fi = index(c, &s);
            assert!(fi > 0.0 && fi.is_finite(), "{c:?}: {fi}");
            for lambda in [0.3, 2.5] {
                let scaled = s.map(|x| x * lambda);
                let f2 = index(c, &scaled);
                assert!(
                    close(f2, lambda * fi, 1e-12),
                    "{c:?} {s:?}: {f2} vs {}",
                    lambda * fi
                );
            }
            // at the reserve factor the index is one
            let at_failure = s.map(|x| x / fi);
            let one = index(c, &at_failure);
            assert!(close(one, 1.0, 1e-12), "{c:?}: {one}");
        }
    }
}

#[test]
fn tsai_wu_polynomial_is_one_at_the_reserve_factor() {
    // the polynomial itself, written out here, at the stress scaled to failure
    let f = strength();
    let s = [420.0, -35.0, 0.0, 0.0, 0.0, 30.0].map(|x| x * MPA);
    let r = 1.0 / index(Criterion::TsaiWu, &s);
    let [s1, s2, _, _, _, t] = s.map(|x| x * r);
    let (f11, f22) = (1.0 / (f.xt * f.xc), 1.0 / (f.yt * f.yc));
    let poly = (1.0 / f.xt - 1.0 / f.xc) * s1
        + (1.0 / f.yt - 1.0 / f.yc) * s2
        + f11 * s1 * s1
        + f22 * s2 * s2
        + t * t / (f.s12 * f.s12)
        - (f11 * f22).sqrt() * s1 * s2;
    assert!((poly - 1.0).abs() < 1e-12, "{poly}");
}

#[test]
fn index_derivatives_equal_central_differences() {
    for c in Criterion::ALL {
        for s in states() {
            let seeded: [Dual<6>; 6] = std::array::from_fn(|i| Dual::variable(s[i], i));
            let d = c.index(&material(), &strength(), &seeded);
            assert_eq!(d.value(), index(c, &s));
            for i in 0..6 {
                let h = 1e-4 * MPA;
                let (mut p, mut m) = (s, s);
                p[i] += h;
                m[i] -= h;
                let fd = (index(c, &p) - index(c, &m)) / (2.0 * h);
                let scale = d.value() / (50.0 * MPA);
                assert!(
                    (d.d[i] - fd).abs() < 1e-7 * scale.max(fd.abs()),
                    "{c:?} {s:?} component {i}: {} vs {fd}",
                    d.d[i]
                );
            }
        }
    }
}

#[test]
fn strengths_must_be_positive() {
    let e = PlyStrength::new(1.0, 1.0, -1.0, 1.0, 1.0).unwrap_err();
    assert!(e.to_string().contains("Yt"), "{e}");
    let e = strength()
        .with_transverse(1.0, 1.0, f64::NAN, 1.0)
        .unwrap_err();
    assert!(e.to_string().contains("S13"), "{e}");
}
