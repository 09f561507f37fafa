//! Derivatives produced by the crate against central differences: the constraint rates and `γ`
//! (product-rule kinematics, including FE-node markers of a flexible body), the exact state
//! Jacobian of `f` from the dual path, and the tangent of the accelerations with respect to a
//! model parameter through the `f64` LU (the Eq. 40 pattern).

mod common;

use common::{assembled, flow, slider_crank};
use mbs::{Body, OdeSystem};
use nalgebra::DMatrix;
use sens::{Dual, solve_tangents};

/// The flexible slider-crank at a consistent state, then given arbitrary modal coordinates and
/// velocities (the derivative identities hold at any state).
fn flexible_state() -> (mbs::MultibodySystem, Vec<f64>) {
    let (model, state, _) = slider_crank(150.0, Some(4));
    let (sys, mut state) = assembled(model, state);
    let rod = mbs::BodyId::from(1);
    let w = [2e-4, -1e-4, 5e-5, 3e-5];
    let wd = [0.3, -0.2, 0.1, 0.05];
    sys.model().set_modal(&mut state, rod, &w, &wd);
    // some out-of-plane velocity too
    state.v[2] += 0.1;
    state.v[9] -= 0.5;
    (sys, state.to_vec())
}

#[test]
fn constraint_rates_and_gamma_match_central_differences_along_the_motion() {
    let (sys, y) = flexible_state();
    let model = sys.model();
    let (q, v) = y.split_at(model.n_q());
    let t = 0.01;
    // the rod moves with its full rigid velocity (about 11 m/s, 75 rad/s): the differences'
    // truncation error h² Φ⃛ / 6 is 2.2e-6 at h = 2e-6 and falls as h² (1.4e-7 at 5e-7)
    let h = 5e-7;
    let c0 = model.constraints(t, q, v);
    let cp = model.constraints(t + h, &flow(model, q, v, h), v);
    let cm = model.constraints(t - h, &flow(model, q, v, -h), v);
    let rate_scale = c0.phi_dot.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let acc_scale = c0.gamma.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    assert!(rate_scale > 1.0 && acc_scale > 100.0, "test state too tame");
    for i in 0..model.n_constraints() {
        let d1 = (cp.phi[i] - cm.phi[i]) / (2.0 * h);
        let d2 = (cp.phi[i] - 2.0 * c0.phi[i] + cm.phi[i]) / (h * h);
        assert!(
            (d1 - c0.phi_dot[i]).abs() < 1e-7 * rate_scale,
            "row {i}: Φ̇ {} vs {d1}",
            c0.phi_dot[i]
        );
        assert!(
            (d2 + c0.gamma[i]).abs() < 1e-5 * acc_scale,
            "row {i}: −γ {} vs {d2}",
            -c0.gamma[i]
        );
        // Φ̇ = Φ_v v + Φ_t: check the Jacobian part with the driver-free rows
        let jv: f64 = (0..model.n_v()).map(|c| c0.jacobian[(i, c)] * v[c]).sum();
        if model.joint(model.joint_of_row(i)).name != "crank driver" {
            assert!(
                (jv - c0.phi_dot[i]).abs() < 1e-12 * rate_scale,
                "row {i}: Φ_v v ≠ Φ̇"
            );
        }
    }
}

#[test]
fn exact_jacobian_of_the_right_hand_side_matches_central_differences() {
    let (mut sys, y) = flexible_state();
    let n = y.len();
    let t = 0.01;
    let mut jac = DMatrix::zeros(n, n);
    sys.jacobian(t, &y, &mut jac).unwrap();
    let mut f0 = vec![0.0; n];
    sys.rhs(t, &y, &mut f0).unwrap();
    let f_max = f0.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let mut f_p = vec![0.0; n];
    let mut f_m = vec![0.0; n];
    for c in 0..n {
        let h = 1e-6 * y[c].abs().max(1e-3);
        // round-off of the difference quotient (the LU solve spreads it over all rows)
        let noise = |_r: usize| 20.0 * f64::EPSILON * f_max / h;
        let mut yp = y.clone();
        yp[c] += h;
        let mut ym = y.clone();
        ym[c] -= h;
        sys.rhs(t, &yp, &mut f_p).unwrap();
        sys.rhs(t, &ym, &mut f_m).unwrap();
        let fd: Vec<f64> = f_p
            .iter()
            .zip(&f_m)
            .map(|(a, b)| (a - b) / (2.0 * h))
            .collect();
        let scale = fd
            .iter()
            .chain(jac.column(c).iter())
            .fold(1.0f64, |m, x| m.max(x.abs()));
        for r in 0..n {
            assert!(
                (jac[(r, c)] - fd[r]).abs() < 1e-6 * scale + noise(r),
                "∂f{r}/∂y{c}: dual {} vs central difference {}",
                jac[(r, c)],
                fd[r]
            );
        }
    }
}

#[test]
fn acceleration_tangent_wrt_a_modal_eigenvalue_matches_central_differences() {
    let (sys, y) = flexible_state();
    let t = 0.01;
    let model = sys.model();
    let (q, v) = y.split_at(model.n_q());
    let rows = sys.active_rows().to_vec();
    let rod = mbs::BodyId::from(1);
    let sol = sys.solve(t, q, v).unwrap();
    // Model<Dual<1>> with the first eigenvalue as the design variable
    let mut dual_model = model.map(Dual::<1>::constant);
    if let Body::Flexible(b) = dual_model.body_mut(rod) {
        b.modal.eigenvalues[0] = Dual::variable(b.modal.eigenvalues[0].v, 0);
    }
    let qd: Vec<Dual<1>> = q.iter().map(|&x| Dual::constant(x)).collect();
    let vd: Vec<Dual<1>> = v.iter().map(|&x| Dual::constant(x)).collect();
    let res = dual_model.residual(t, &qd, &vd, &rows, &sol.x);
    let x = solve_tangents(&sol.lu, &sol.x, &res);
    let lam0 = match model.body(rod) {
        Body::Flexible(b) => b.modal.eigenvalues[0],
        Body::Rigid(_) => unreachable!(),
    };
    let h = 1e-6 * lam0;
    let perturbed = |d: f64| {
        let mut m = model.clone();
        if let Body::Flexible(b) = m.body_mut(rod) {
            b.modal.eigenvalues[0] += d;
        }
        sys.with_model(m).solve(t, q, v).unwrap().x
    };
    let (xp, xm) = (perturbed(h), perturbed(-h));
    let scale = x.iter().map(|d| d.d[0].abs()).fold(0.0, f64::max);
    assert!(scale > 0.0);
    for i in 0..x.len() {
        let fd = (xp[i] - xm[i]) / (2.0 * h);
        assert!(
            (x[i].d[0] - fd).abs() < 1e-6 * scale,
            "entry {i}: {} vs {fd}",
            x[i].d[0]
        );
    }
}
