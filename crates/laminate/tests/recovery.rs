//! Ply stresses and strains through the thickness against closed forms: a homogeneous plate's
//! bending stress and parabolic shear, a cross-ply's plies under stretching, a turned ply's
//! strains by the tensor rule; the shear's equilibrium on a composite stack (its resultant and
//! free faces); ply-angle and material-constant derivatives against central differences.

use laminate::{OrthotropicMaterial, PlateState, Ply, PlyPosition, PlyStack};
use sens::{Dual, Scalar};

fn composite() -> OrthotropicMaterial {
    let g = 5.36e9;
    OrthotropicMaterial::new(
        [128e9, 10.1e9, 10.1e9],
        [g, g, g],
        [0.23, 0.23, 0.23],
        1586.0,
    )
    .unwrap()
}

fn stack<S: Scalar>(m: OrthotropicMaterial, angles: &[S], t: f64) -> PlyStack<S> {
    PlyStack::new(
        angles
            .iter()
            .map(|&a| Ply {
                material: m,
                thickness: S::from_f64(t),
                angle: a,
            })
            .collect(),
    )
    .unwrap()
}

fn state(membrane: [f64; 3], curvature: [f64; 3], shear: [f64; 2]) -> PlateState<f64> {
    PlateState {
        membrane,
        curvature,
        shear_forces: shear,
    }
}

#[test]
fn a_homogeneous_plate_bends_linearly_and_carries_shear_as_a_parabola() {
    let (e, nu, t) = (70e9, 0.3, 0.5e-3);
    let m = OrthotropicMaterial::isotropic(e, nu, 2700.0).unwrap();
    let s = stack(m, &[0.0; 4], t);
    let h = 4.0 * t;
    let (kappa, q) = (0.1, 1000.0);
    let points = s.ply_points(&state([0.0; 3], [kappa, 0.0, 0.0], [q, 0.0]));
    assert_eq!(points.len(), 12);
    let plate = e / (1.0 - nu * nu);
    for p in &points {
        let z = p.z;
        let sxx = plate * z * kappa;
        assert!(
            (p.stress[0] - sxx).abs() < 1e-9 * plate * h * kappa,
            "{p:?}"
        );
        assert!((p.stress[1] - nu * sxx).abs() < 1e-9 * plate * h * kappa);
        let tau = 1.5 * q / h * (1.0 - (2.0 * z / h).powi(2));
        assert!(
            (p.stress[4] - tau).abs() < 1e-9 * q / h,
            "z = {z}: {} vs {tau}",
            p.stress[4]
        );
        assert!(p.stress[3].abs() < 1e-9 * q / h && p.stress[5].abs() < 1e-6);
        // strains by Hooke's law: ε_xx = z κ, γ_xz = τ/G
        assert!((p.strain[0] - z * kappa).abs() < 1e-12);
        assert!((p.strain[4] - tau * 2.0 * (1.0 + nu) / e).abs() < 1e-15);
    }
    assert_eq!(points[1].position, PlyPosition::Middle);
}

#[test]
fn a_stretched_cross_ply_loads_its_plies_along_and_across_their_fibres() {
    let m = composite();
    let [e1, e2, _] = m.young_moduli();
    let nu12 = m.poisson_ratios()[0];
    let nu21 = nu12 * e2 / e1;
    let d = 1.0 - nu12 * nu21;
    let (q11, q22, q12) = (e1 / d, e2 / d, nu12 * e2 / d);
    let right = std::f64::consts::FRAC_PI_2;
    let s = stack(m, &[0.0, right, right, 0.0], 0.125e-3);
    let ex = 1e-3;
    for p in s.ply_points(&state([ex, 0.0, 0.0], [0.0; 3], [0.0; 2])) {
        let (s1, s2) = match p.ply {
            0 | 3 => (q11 * ex, q12 * ex),
            _ => (q12 * ex, q22 * ex),
        };
        assert!((p.stress[0] - s1).abs() < 1e-9 * q11 * ex, "{p:?}");
        assert!((p.stress[1] - s2).abs() < 1e-9 * q11 * ex, "{p:?}");
        assert!(p.stress[5].abs() < 1e-9 * q11 * ex);
    }
}

#[test]
fn a_turned_ply_sees_the_laminate_strains_by_the_tensor_rule() {
    let theta: f64 = 30f64.to_radians();
    let s = stack(composite(), &[theta], 0.2e-3);
    let (ex, ey, gxy) = (1e-3, -4e-4, 6e-4);
    let (sn, c) = theta.sin_cos();
    let e1 = c * c * ex + sn * sn * ey + c * sn * gxy;
    let e2 = sn * sn * ex + c * c * ey - c * sn * gxy;
    let g12 = -2.0 * c * sn * ex + 2.0 * c * sn * ey + (c * c - sn * sn) * gxy;
    for p in s.ply_points(&state([ex, ey, gxy], [0.0; 3], [0.0; 2])) {
        for (got, want) in [(p.strain[0], e1), (p.strain[1], e2), (p.strain[5], g12)] {
            assert!((got - want).abs() < 1e-12, "{got} vs {want}");
        }
    }
}

#[test]
fn the_recovered_shear_balances_the_shear_forces_and_leaves_the_faces_free() {
    let angles = [0.0, 45.0, -45.0, 90.0, 20.0].map(f64::to_radians);
    let s = stack(composite(), &angles, 0.15e-3);
    let h = 5.0 * 0.15e-3;
    let (qx, qy) = (800.0, -300.0);
    let points = s.ply_points(&state([2e-4, 0.0, 1e-4], [0.5, -0.2, 0.1], [qx, qy]));
    // Simpson's rule over each ply is exact for the piecewise-quadratic shear
    let laminate = |p: &laminate::PlyPoint<f64>| {
        // back to laminate axes: τ_xz = c τ13 − s τ23, τ_yz = s τ13 + c τ23
        let (sn, c) = angles[p.ply].sin_cos();
        (
            c * p.stress[4] - sn * p.stress[3],
            sn * p.stress[4] + c * p.stress[3],
        )
    };
    let (mut fx, mut fy) = (0.0, 0.0);
    for ply in points.chunks(3) {
        let t = ply[2].z - ply[0].z;
        let w = [1.0, 4.0, 1.0];
        for (p, w) in ply.iter().zip(w) {
            let (txz, tyz) = laminate(p);
            fx += txz * w * t / 6.0;
            fy += tyz * w * t / 6.0;
        }
    }
    let scale = qx.abs() / h;
    assert!((fx - qx).abs() < 1e-9 * qx.abs(), "{fx} vs {qx}");
    assert!((fy - qy).abs() < 1e-9 * qx.abs(), "{fy} vs {qy}");
    for p in [&points[0], &points[points.len() - 1]] {
        let (txz, tyz) = laminate(p);
        assert!(
            txz.abs() < 1e-9 * scale && tyz.abs() < 1e-9 * scale,
            "{txz} {tyz}"
        );
    }
    // continuous across each interface
    for k in 1..5 {
        let (a, b) = (laminate(&points[3 * k - 1]), laminate(&points[3 * k]));
        assert!((a.0 - b.0).abs() < 1e-9 * scale && (a.1 - b.1).abs() < 1e-9 * scale);
    }
}

#[test]
fn ply_stress_derivatives_equal_central_differences() {
    let angles = [0.3, -0.8, 1.1];
    let st = state([3e-4, -1e-4, 2e-4], [0.4, 0.1, -0.3], [500.0, 200.0]);
    let at = |a: &[f64]| stack(composite(), a, 0.2e-3).ply_points(&st);
    let seeded: Vec<Dual<3>> = (0..3).map(|i| Dual::variable(angles[i], i)).collect();
    let dual_state = PlateState {
        membrane: st.membrane.map(Dual::constant),
        curvature: st.curvature.map(Dual::constant),
        shear_forces: st.shear_forces.map(Dual::constant),
    };
    let d = stack(composite(), &seeded, 0.2e-3).ply_points(&dual_state);
    let h = 1e-6;
    for j in 0..3 {
        let (mut p, mut m) = (angles, angles);
        p[j] += h;
        m[j] -= h;
        let (fp, fm) = (at(&p), at(&m));
        for (k, pt) in d.iter().enumerate() {
            for c in 0..6 {
                let fd = (fp[k].stress[c] - fm[k].stress[c]) / (2.0 * h);
                let scale = 1e8;
                assert!(
                    (pt.stress[c].d[j] - fd).abs() < 1e-6 * scale.max(fd.abs()),
                    "point {k} component {c} angle {j}: {} vs {fd}",
                    pt.stress[c].d[j]
                );
            }
        }
    }
}

#[test]
fn ply_stress_derivatives_along_a_material_constant_equal_central_differences() {
    // E1 moved: C̄ carries dC̄/dE1 (the stiffness and the stack's ABD of the shear gradient)
    let angles = [0.3, -0.8, 1.1];
    let st = state([3e-4, -1e-4, 2e-4], [0.4, 0.1, -0.3], [500.0, 200.0]);
    let with_e1 = |e1: f64| {
        let m = composite();
        let mut c = m.constants();
        c[0] = e1;
        m.with_constants(c).unwrap()
    };
    let at = |e1: f64| stack(with_e1(e1), &angles, 0.2e-3).ply_points(&st);
    let e1 = 128e9;
    let mut dc = [0.0; 9];
    dc[0] = 1.0;
    let m = composite();
    let c_bar: Vec<_> = (0..3)
        .map(|_| {
            let d = m.stiffness_derivative(&dc);
            m.stiffness().zip_map(&d, |c, dc| Dual::<1>::new(c, [dc]))
        })
        .collect();
    let dual_state = PlateState {
        membrane: st.membrane.map(Dual::constant),
        curvature: st.curvature.map(Dual::constant),
        shear_forces: st.shear_forces.map(Dual::constant),
    };
    let seeded: Vec<Dual<1>> = angles.iter().map(|&a| Dual::constant(a)).collect();
    let d = stack(m, &seeded, 0.2e-3).ply_points_with_materials(&dual_state, &c_bar);
    let nominal = at(e1);
    let h = 1e3;
    let (fp, fm) = (at(e1 + h), at(e1 - h));
    let mut moved = 0;
    for (k, pt) in d.iter().enumerate() {
        for c in 0..6 {
            assert!((pt.stress[c].v - nominal[k].stress[c]).abs() < 1e-6);
            let fd = (fp[k].stress[c] - fm[k].stress[c]) / (2.0 * h);
            assert!(
                (pt.stress[c].d[0] - fd).abs() < 1e-6 * (1e-3f64).max(fd.abs()),
                "point {k} component {c}: {} vs {fd}",
                pt.stress[c].d[0]
            );
            moved += usize::from(fd.abs() > 1e-6);
            // the strains through the moved compliance
            let fd = (fp[k].strain[c] - fm[k].strain[c]) / (2.0 * h);
            assert!(
                (pt.strain[c].d[0] - fd).abs() < 1e-5 * fd.abs() + 1e-20,
                "point {k} strain {c}: {} vs {fd}",
                pt.strain[c].d[0]
            );
        }
    }
    assert!(moved > 10, "E1 moves the ply stresses ({moved} components)");
}
