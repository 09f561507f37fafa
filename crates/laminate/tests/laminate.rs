//! Laminate theory against invariants, closed forms, Eq. (50) and central differences.

use laminate::{
    LaminateError, OrthotropicMaterial, Ply, PlyStack, ReferenceSurface, bond_stress_matrix,
    plane_stress, rotate_stiffness, rotated_stiffness_angle_derivative, rotation_about_normal,
};
use nalgebra::{Matrix3, Matrix6, Vector6};
use sens::{Dual, Scalar, seed_chunk};

fn paper_composite() -> OrthotropicMaterial {
    // Neto, Ambrósio & Leal 2008, §5.1
    let g = 5.36e9;
    OrthotropicMaterial::new(
        [128e9, 10.1e9, 10.1e9],
        [g, g, g],
        [0.23, 0.23, 0.23],
        1586.0,
    )
    .unwrap()
}

fn deg(x: f64) -> f64 {
    x.to_radians()
}

fn stack(mat: OrthotropicMaterial, angles_deg: &[f64], t: f64) -> PlyStack<f64> {
    PlyStack::new(
        angles_deg
            .iter()
            .map(|&a| Ply {
                material: mat,
                thickness: t,
                angle: deg(a),
            })
            .collect(),
    )
    .unwrap()
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs().max(1e-300)
}

fn max_abs3(m: &Matrix3<f64>) -> f64 {
    m.iter().fold(0.0f64, |a, &x| a.max(x.abs()))
}

#[test]
fn stiffness_inverts_compliance() {
    let m = paper_composite();
    let prod = m.stiffness() * m.compliance();
    assert!((prod - Matrix6::identity()).abs().max() < 1e-12);
}

#[test]
fn quasi_isotropic_laminate_is_isotropic_in_plane() {
    let s = stack(
        paper_composite(),
        &[0.0, 45.0, -45.0, 90.0, 90.0, -45.0, 45.0, 0.0],
        0.125e-3,
    );
    let k = s.stiffness();
    let a = k.a;
    assert!(
        rel(a[(0, 0)], a[(1, 1)]) < 1e-12,
        "A11 {} A22 {}",
        a[(0, 0)],
        a[(1, 1)]
    );
    assert!(a[(0, 2)].abs() < 1e-12 * a[(0, 0)] && a[(1, 2)].abs() < 1e-12 * a[(0, 0)]);
    assert!(rel(a[(2, 2)], (a[(0, 0)] - a[(0, 1)]) / 2.0) < 1e-12);
    // symmetric stack: no extension–bending coupling
    assert!(max_abs3(&k.b) < 1e-12 * a[(0, 0)] * 1e-3);
}

#[test]
fn symmetric_stacks_have_no_coupling() {
    for angles in [
        vec![30.0, -60.0, -60.0, 30.0],
        vec![15.0, 15.0],
        vec![0.0, 90.0, 0.0],
        vec![10.0, 47.0, 10.0],
    ] {
        let k = stack(paper_composite(), &angles, 0.2e-3).stiffness();
        assert!(
            max_abs3(&k.b) < 1e-12 * max_abs3(&k.a) * 1e-3,
            "{angles:?}: B = {}",
            k.b
        );
    }
    // …and a non-symmetric one does couple
    let k = stack(paper_composite(), &[0.0, 90.0], 0.2e-3).stiffness();
    assert!(k.b[(0, 0)].abs() > 1e-3 * max_abs3(&k.a) * 0.2e-3);
}

#[test]
fn half_turn_leaves_a_ply_unchanged() {
    let c_bar = paper_composite().stiffness();
    for t in [0.0, 17.0, 45.0, 133.0, -70.0] {
        let c0 = rotate_stiffness(&c_bar, &rotation_about_normal(deg(t)));
        let c1 = rotate_stiffness(&c_bar, &rotation_about_normal(deg(t + 180.0)));
        assert!((c0 - c1).abs().max() < 1e-12 * c_bar.abs().max(), "θ = {t}");
    }
}

#[test]
fn quarter_turn_swaps_the_in_plane_directions() {
    let c_bar = paper_composite().stiffness();
    let c = rotate_stiffness(&c_bar, &rotation_about_normal(deg(90.0)));
    let tol = 1e-9 * c_bar.abs().max();
    assert!((c[(0, 0)] - c_bar[(1, 1)]).abs() < tol);
    assert!((c[(1, 1)] - c_bar[(0, 0)]).abs() < tol);
    assert!((c[(0, 2)] - c_bar[(1, 2)]).abs() < tol);
    assert!((c[(3, 3)] - c_bar[(4, 4)]).abs() < tol, "G23 ↔ G13");
    assert!((c[(5, 5)] - c_bar[(5, 5)]).abs() < tol);
    assert!(c[(0, 5)].abs() < tol && c[(3, 4)].abs() < tol);
}

#[test]
fn rotation_preserves_strain_energy() {
    // Energy εᵀCε is frame independent: with engineering strains ε_material = Tᵀ ε_laminate.
    let c_bar = paper_composite().stiffness();
    let r = nalgebra::Rotation3::from_euler_angles(0.3, -1.1, 2.0).into_inner();
    let c = rotate_stiffness(&c_bar, &r);
    let t = bond_stress_matrix(&r);
    let eps = Vector6::new(1e-3, -2e-4, 5e-4, 3e-4, -1e-4, 7e-4);
    let e_lam = (eps.transpose() * c * eps)[0];
    let eps_mat = t.transpose() * eps;
    let e_mat = (eps_mat.transpose() * c_bar * eps_mat)[0];
    assert!(rel(e_lam, e_mat) < 1e-12);
}

#[test]
fn antisymmetric_angle_ply_couples_bending_and_twist() {
    let k = stack(paper_composite(), &[30.0, -30.0], 0.5e-3).stiffness();
    let scale = max_abs3(&k.b);
    assert!(k.a[(0, 2)].abs() < 1e-12 * k.a[(0, 0)] && k.a[(1, 2)].abs() < 1e-12 * k.a[(0, 0)]);
    assert!(
        k.b[(0, 2)].abs() > 0.1 * scale && k.b[(1, 2)].abs() > 0.1 * scale,
        "B16, B26 = {}",
        k.b
    );
    assert!(k.b[(0, 0)].abs() < 1e-12 * scale && k.b[(2, 2)].abs() < 1e-12 * scale);
}

#[test]
fn isotropic_ply_matches_plate_theory() {
    let (e, nu, rho, h) = (70e9, 0.33, 2700.0, 2e-3);
    let mat = OrthotropicMaterial::isotropic(e, nu, rho).unwrap();
    let q = plane_stress(&mat.stiffness());
    assert!(rel(q[(0, 0)], e / (1.0 - nu * nu)) < 1e-12);
    assert!(rel(q[(0, 1)], nu * e / (1.0 - nu * nu)) < 1e-12);
    assert!(rel(q[(2, 2)], e / (2.0 * (1.0 + nu))) < 1e-12);
    for angle in [0.0, 33.0] {
        let k = stack(mat, &[angle], h).stiffness();
        assert!(rel(k.d[(0, 0)], e * h.powi(3) / (12.0 * (1.0 - nu * nu))) < 1e-12);
        assert!(rel(k.a[(0, 0)], e * h / (1.0 - nu * nu)) < 1e-12);
        assert!(rel(k.shear[(0, 0)], 5.0 / 6.0 * e / (2.0 * (1.0 + nu)) * h) < 1e-12);
        assert!(k.shear[(0, 1)].abs() < 1e-6);
        assert!(rel(k.mass_per_area, rho * h) < 1e-14);
        assert!(rel(k.rotary_inertia, rho * h.powi(3) / 12.0) < 1e-12);
        assert!(k.first_moment.abs() < 1e-12 * rho * h * h);
    }
}

#[test]
fn moving_the_reference_surface_follows_the_parallel_axis_rule() {
    let mat = paper_composite();
    let plies: Vec<Ply<f64>> = [0.0, 35.0, -20.0, 90.0]
        .iter()
        .map(|&a| Ply {
            material: mat,
            thickness: 0.3e-3,
            angle: deg(a),
        })
        .collect();
    let mid = PlyStack::new(plies.clone()).unwrap().stiffness();
    let h = 1.2e-3;
    for (reference, e) in [
        (ReferenceSurface::Bottom, -h / 2.0),
        (ReferenceSurface::Top, h / 2.0),
        (ReferenceSurface::Offset(0.17e-3), 0.17e-3),
    ] {
        let k = PlyStack::with_options(plies.clone(), reference, 5.0 / 6.0)
            .unwrap()
            .stiffness();
        // z' = z − e: B' = B − eA, D' = D − 2eB + e²A
        let b = mid.b - mid.a * e;
        let d = mid.d - mid.b * (2.0 * e) + mid.a * (e * e);
        assert!(max_abs3(&(k.a - mid.a)) < 1e-9 * max_abs3(&mid.a));
        assert!(max_abs3(&(k.b - b)) < 1e-9 * max_abs3(&b));
        assert!(max_abs3(&(k.d - d)) < 1e-9 * max_abs3(&d));
        assert!(
            rel(
                k.rotary_inertia,
                mid.rotary_inertia + e * e * mid.mass_per_area
            ) < 1e-9
        );
    }
}

/// The laminate's A, B, D, shear as a flat vector, for derivative checks.
fn flat<S: Scalar>(k: &laminate::LaminateStiffness<S>) -> Vec<S> {
    k.a.iter()
        .chain(k.b.iter())
        .chain(k.d.iter())
        .chain(k.shear.iter())
        .copied()
        .collect()
}

#[test]
fn rotated_stiffness_derivative_eq50_matches_duals() {
    let c_bar = paper_composite().stiffness();
    for t in [0.0, 15.0, 30.0, 75.0, -110.0] {
        let th = Dual::<1>::variable(deg(t), 0);
        let c = rotate_stiffness(&c_bar, &rotation_about_normal(th));
        let closed = rotated_stiffness_angle_derivative(&c_bar, deg(t));
        let scale = c_bar.abs().max();
        for i in 0..6 {
            for j in 0..6 {
                assert!(
                    (c[(i, j)].d[0] - closed[(i, j)]).abs() < 1e-12 * scale,
                    "θ = {t}, ({i},{j})"
                );
            }
        }
    }
}

#[test]
fn laminate_angle_derivatives_agree_with_eq50_and_central_differences() {
    let mat = paper_composite();
    let angles = [deg(20.0), deg(-35.0), deg(60.0), deg(20.0)];
    let base = PlyStack::new(
        angles
            .iter()
            .map(|&a| Ply {
                material: mat,
                thickness: 0.25e-3,
                angle: a,
            })
            .collect(),
    )
    .unwrap();
    // design variable 0 drives plies 0 and 3 (a common angle); variable 1 drives ply 2
    let groups: [&[usize]; 2] = [&[0, 3], &[2]];
    let b = [angles[0], angles[2]];
    let angles_of = |b: &[Dual<2>]| vec![b[0], Dual::constant(angles[1]), b[1], b[0]];
    let dual = base
        .with_angles(&angles_of(&seed_chunk::<2>(&b, 0)))
        .unwrap()
        .stiffness();
    let dual_flat = flat(&dual);
    let value_of = |b: &[f64]| {
        let a = [b[0], angles[1], b[1], b[0]];
        flat(&base.with_angles(&a).unwrap().stiffness())
    };
    for (var, plies) in groups.iter().enumerate() {
        let closed = flat(&base.angle_derivative(plies));
        let h = 1e-6;
        let mut bp = b;
        let mut bm = b;
        bp[var] += h;
        bm[var] -= h;
        let (fp, fm) = (value_of(&bp), value_of(&bm));
        let scale = closed.iter().fold(0.0f64, |a, &x| a.max(x.abs()));
        for i in 0..closed.len() {
            let d = dual_flat[i].d[var];
            assert!(
                (d - closed[i]).abs() <= 1e-12 * scale,
                "var {var} entry {i}: dual {d} vs Eq. 50 {}",
                closed[i]
            );
            let fd = (fp[i] - fm[i]) / (2.0 * h);
            assert!(
                (d - fd).abs() <= 1e-7 * d.abs().max(1e-3 * scale),
                "var {var} entry {i}: dual {d} vs central difference {fd}"
            );
        }
    }
    // values of the dual evaluation are those of the f64 evaluation
    let plain = flat(&base.stiffness());
    assert!(plain.iter().zip(&dual_flat).all(|(a, b)| *a == b.v));
}

#[test]
fn invalid_materials_are_rejected_with_the_bad_value() {
    let g = [5e9; 3];
    let nu = [0.25; 3];
    let e = OrthotropicMaterial::new([-1.0, 1e10, 1e10], g, nu, 1500.0).unwrap_err();
    assert_eq!(
        e,
        LaminateError::NotPositive {
            constant: "E1",
            value: -1.0
        }
    );
    assert!(e.to_string().contains("E1 = -1"), "{e}");
    let e = OrthotropicMaterial::new([1e11, 1e10, 1e10], [5e9, 0.0, 5e9], nu, 1500.0).unwrap_err();
    assert!(e.to_string().contains("G13 = 0"), "{e}");
    let e =
        OrthotropicMaterial::new([1e11, 1e10, 1e10], g, [f64::NAN, 0.2, 0.2], 1500.0).unwrap_err();
    assert!(e.to_string().contains("nu12 = NaN"), "{e}");
    let e = OrthotropicMaterial::new([1e11, 1e10, 1e10], g, nu, f64::INFINITY).unwrap_err();
    assert!(e.to_string().contains("density = inf"), "{e}");
    // ν12 beyond sqrt(E1/E2) ≈ 3.16
    let e = OrthotropicMaterial::new([1e11, 1e10, 1e10], g, [3.5, 0.2, 0.2], 1500.0).unwrap_err();
    assert!(
        matches!(e, LaminateError::NotPositiveDefinite { .. })
            && e.to_string().contains("nu12 = 3.5"),
        "{e}"
    );
    // each pair admissible, the triple not: isotropic ν ≥ 0.5
    let e = OrthotropicMaterial::isotropic(1e9, 0.5, 1000.0).unwrap_err();
    assert!(
        matches!(e, LaminateError::NotPositiveDefinite { .. }),
        "{e}"
    );
    assert!(OrthotropicMaterial::isotropic(1e9, 0.499, 1000.0).is_ok());
    assert!(
        OrthotropicMaterial::isotropic(1e9, -0.9, 1000.0).is_ok(),
        "auxetic but admissible"
    );
}

#[test]
fn invalid_plies_are_rejected_with_the_bad_value() {
    let m = paper_composite();
    let ok = Ply {
        material: m,
        thickness: 1e-3,
        angle: 0.0,
    };
    let e = PlyStack::new(vec![
        ok,
        Ply {
            thickness: -2e-3,
            ..ok
        },
    ])
    .unwrap_err();
    assert_eq!(
        e,
        LaminateError::PlyThickness {
            ply: 1,
            value: -2e-3
        }
    );
    assert!(
        e.to_string().contains("ply 1") && e.to_string().contains("-0.002"),
        "{e}"
    );
    let e = PlyStack::new(vec![Ply {
        thickness: f64::NAN,
        ..ok
    }])
    .unwrap_err();
    assert!(e.to_string().contains("NaN"), "{e}");
    let e = PlyStack::new(vec![Ply {
        angle: f64::INFINITY,
        ..ok
    }])
    .unwrap_err();
    assert!(matches!(e, LaminateError::PlyAngle { ply: 0, .. }), "{e}");
    assert_eq!(
        PlyStack::<f64>::new(vec![]).unwrap_err(),
        LaminateError::Empty
    );
    assert!(PlyStack::with_options(vec![ok], ReferenceSurface::MidPlane, 0.0).is_err());
    assert!(PlyStack::with_options(vec![ok], ReferenceSurface::Offset(f64::NAN), 0.8).is_err());
}

#[test]
fn stiffness_derivative_of_each_elastic_constant_matches_central_differences() {
    let m = paper_composite();
    let c0 = m.constants();
    for i in 0..9 {
        let mut dc = [0.0; 9];
        dc[i] = 1.0;
        let exact = m.stiffness_derivative(&dc);
        let h = 1e-6 * c0[i].abs();
        let at = |s: f64| {
            let mut c = c0;
            c[i] += s;
            m.with_constants(c).unwrap().stiffness()
        };
        let fd = (at(h) - at(-h)) / (2.0 * h);
        let scale = exact.abs().max();
        assert!(scale > 0.0, "constant {i}");
        assert!(
            (exact - fd).abs().max() <= 1e-7 * scale,
            "constant {i}: {exact} vs {fd}"
        );
    }
    // an isotropic material's stiffness is linear in E at fixed ν: dC/dE = C/E
    let iso = OrthotropicMaterial::isotropic(70e9, 0.3, 2700.0).unwrap();
    let g = 1.0 / (2.0 * 1.3);
    let d = iso.stiffness_derivative(&[1.0, 1.0, 1.0, g, g, g, 0.0, 0.0, 0.0]);
    let expected = iso.stiffness() / 70e9;
    assert!((d - expected).abs().max() <= 1e-12 * expected.abs().max());
}

#[test]
fn stack_stiffness_with_dual_materials_carries_the_material_derivative() {
    let m = paper_composite();
    let st = stack(m, &[0.0, 45.0, -45.0, 90.0], 0.25e-3);
    // E2 of every ply as one variable
    let mut dc = [0.0; 9];
    dc[1] = 1.0;
    let dcbar = m.stiffness_derivative(&dc);
    let c_bar: Vec<Matrix6<Dual<1>>> = (0..4)
        .map(|_| m.stiffness().zip_map(&dcbar, |v, d| Dual::new(v, [d])))
        .collect();
    let angles: Vec<Dual<1>> = st.plies().iter().map(|p| Dual::constant(p.angle)).collect();
    let rho = vec![Dual::constant(m.density()); 4];
    let dual = st
        .with_angles(&angles)
        .unwrap()
        .stiffness_with_materials(&c_bar, &rho);
    assert_eq!(dual.a.map(|x| x.v), st.stiffness().a);
    // a dual density: ∂I0/∂ρ = h, ∂I1/∂ρ = 0 and ∂I2/∂ρ = h³/12 about the mid-plane
    let constant: Vec<Matrix6<Dual<1>>> =
        (0..4).map(|_| m.stiffness().map(Dual::constant)).collect();
    let rho = vec![Dual::new(m.density(), [1.0]); 4];
    let mass = st
        .with_angles(&angles)
        .unwrap()
        .stiffness_with_materials(&constant, &rho);
    let h = 4.0 * 0.25e-3;
    assert!((mass.mass_per_area.d[0] - h).abs() < 1e-15);
    assert!(mass.first_moment.d[0].abs() < 1e-18);
    assert!((mass.rotary_inertia.d[0] - h * h * h / 12.0).abs() < 1e-12 * h * h * h);
    assert_eq!(mass.a.map(|x| x.d[0]), nalgebra::Matrix3::zeros());
    let h = 1e-4 * m.constants()[1];
    let at = |s: f64| {
        let mut c = m.constants();
        c[1] += s;
        stack(
            m.with_constants(c).unwrap(),
            &[0.0, 45.0, -45.0, 90.0],
            0.25e-3,
        )
        .stiffness()
    };
    let (p, q) = (at(h), at(-h));
    for (d, plus, minus) in [
        (dual.a.map(|x| x.d[0]), p.a, q.a),
        (dual.d.map(|x| x.d[0]), p.d, q.d),
    ] {
        let fd = (plus - minus) / (2.0 * h);
        assert!((d - fd).abs().max() <= 1e-7 * d.abs().max(), "{d} vs {fd}");
    }
}
