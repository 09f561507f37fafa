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
