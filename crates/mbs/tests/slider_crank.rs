//! Rigid slider-crank at constant crank speed against closed-form kinematics.

mod common;

use common::{CRANK, ROD, assembled, slider_crank, slider_exact};
use mbs::{BdfOptions, simulate};

#[test]
fn rigid_slider_crank_matches_closed_form_kinematics_over_two_revolutions() {
    let omega = 150.0;
    let (model, state, slider_id) = slider_crank(omega, None);
    let n_eq = model.n_constraints();
    let (mut sys, state) = assembled(model, state);
    // 21 equations for 18 velocity variables: a planar mechanism modelled in 3-D has exactly 3
    // redundant equations.
    assert_eq!(n_eq, 21);
    assert_eq!(sys.removed_equations().len(), 3);
    let period = 2.0 * std::f64::consts::PI / omega;
    let t_out: Vec<f64> = (0..=200).map(|i| 2.0 * period * i as f64 / 200.0).collect();
    let sim = simulate(&mut sys, &state, &t_out, BdfOptions::adaptive(1e-11, 1e-12)).unwrap();
    let slider = slider_id.index();
    let v_slider = sys.model().v_range(slider_id).start;
    let (mut ex, mut ev, mut ea) = (0.0f64, 0.0f64, 0.0f64);
    for o in &sim.outputs {
        let [x, v, a] = slider_exact(omega * o.t, omega);
        ex = ex.max((o.positions[slider].x - x).abs() / (CRANK + ROD));
        ev = ev.max((o.v[v_slider] - v).abs() / (CRANK * omega));
        ea = ea.max((o.accelerations[v_slider] - a).abs() / (CRANK * omega * omega));
    }
    eprintln!("{:?} errors x {ex:e} v {ev:e} a {ea:e}", sim.statistics);
    assert!(
        ex < 1e-8 && ev < 1e-8 && ea < 1e-8,
        "x {ex:e} v {ev:e} a {ea:e}"
    );
}

#[test]
fn redundant_constraints_are_reported_with_their_joints_or_removed() {
    let (model, state, _) = slider_crank(150.0, None);
    let err = mbs::MultibodySystem::new(model.clone(), &state, mbs::RedundancyPolicy::Error)
        .err()
        .expect("a planar slider-crank in 3-D is over-constrained");
    let msg = err.to_string();
    assert!(msg.contains("redundant"), "{msg}");
    let mbs::ConstraintError::Redundant { equations } = err else {
        panic!("{err}")
    };
    assert_eq!(equations.len(), 3);
    for (joint, _) in &equations {
        assert!(
            model.joints().iter().any(|j| &j.name == joint),
            "unknown joint {joint}"
        );
        assert!(msg.contains(joint.as_str()));
    }
    let sys = mbs::MultibodySystem::new(model, &state, mbs::RedundancyPolicy::Remove).unwrap();
    assert_eq!(sys.removed_equations().len(), 3);
    assert_eq!(sys.active_rows().len(), 18);
}

#[test]
fn inconsistent_initial_conditions_are_projected_onto_the_constraints() {
    let omega = 150.0;
    let (model, mut state, slider) = slider_crank(omega, None);
    // disturb every position and velocity
    for (i, q) in state.q.iter_mut().enumerate() {
        *q += 1e-2 * ((i as f64) * 1.7).sin();
    }
    for (i, v) in state.v.iter_mut().enumerate() {
        *v += 0.3 * ((i as f64) * 0.9).cos();
    }
    let mut sys = mbs::MultibodySystem::new(model, &state, mbs::RedundancyPolicy::Remove).unwrap();
    sys.assemble(0.0, &mut state, 1e-13).unwrap();
    let c = sys.model().constraints(0.0, &state.q, &state.v);
    let max = |x: &[f64]| x.iter().fold(0.0f64, |m, a| m.max(a.abs()));
    assert!(max(&c.phi) < 1e-12, "Φ = {:e}", max(&c.phi));
    assert!(max(&c.phi_dot) < 1e-10, "Φ̇ = {:e}", max(&c.phi_dot));
    // a zero-dof mechanism: the projection lands on the closed-form configuration
    let [x, v, _] = slider_exact(0.0, omega);
    let r = sys.model().q_range(slider).start;
    let rv = sys.model().v_range(slider).start;
    assert!((state.q[r] - x).abs() < 1e-12 && (state.v[rv] - v).abs() < 1e-9);
    // Euler parameters stay normalised
    for id in sys.model().body_ids() {
        let r = sys.model().q_range(id).start;
        let n: f64 = state.q[r + 3..r + 7].iter().map(|p| p * p).sum();
        assert!((n - 1.0).abs() < 1e-14);
    }
}
