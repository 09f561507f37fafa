//! Baumgarte stabilisation (Eq. 10a): with it the constraint violation of a double pendulum
//! stays bounded at loose integration tolerances; without it the violation drifts and grows,
//! until the step guard stops the run.

mod common;

use common::assembled;
use mbs::{
    Baumgarte, BdfOptions, IntegrationFailure, Joint, JointKind, Marker, Model, MultibodySystem,
    OdeSystem, RigidBody, SimulationError, State, StepGuard, simulate,
};
use nalgebra::{Matrix3, Vector3};

/// The double pendulum, assembled, with its initial state.
fn pendulum_system(baumgarte: Baumgarte) -> (MultibodySystem, State) {
    let mut model = Model::new();
    model.gravity = Vector3::new(0.0, -9.81, 0.0);
    model.baumgarte = baumgarte;
    let inertia = common::rod_inertia(1.0, 1.0);
    let b1 = model
        .add_rigid_body(RigidBody::new("upper", 1.0, inertia))
        .unwrap();
    let b2 = model
        .add_rigid_body(RigidBody::new("lower", 1.0, inertia))
        .unwrap();
    let half = Vector3::new(0.5, 0.0, 0.0);
    model
        .add_joint(Joint::new(
            "pivot",
            JointKind::Revolute,
            Marker::ground(Vector3::zeros()),
            Marker::on(b1, -half),
        ))
        .unwrap();
    model
        .add_joint(Joint::new(
            "elbow",
            JointKind::Revolute,
            Marker::on(b1, half),
            Marker::on(b2, -half),
        ))
        .unwrap();
    let mut state = model.rest_state();
    model.set_pose(&mut state, b1, half, &Matrix3::identity());
    model.set_pose(&mut state, b2, half * 3.0, &Matrix3::identity());
    model.set_velocity(
        &mut state,
        b2,
        Vector3::zeros(),
        Vector3::new(0.0, 0.0, 4.0),
    );
    assembled(model, state)
}

/// `(t, max |Φ|)` at the output times; `max_violation` replaces the guard's limit.
fn pendulum(
    baumgarte: Baumgarte,
    max_violation: Option<f64>,
    t_end: f64,
) -> Result<Vec<(f64, f64)>, SimulationError> {
    let (mut sys, state) = pendulum_system(baumgarte);
    if let Some(v) = max_violation {
        sys.set_guard(StepGuard {
            max_violation: v,
            ..sys.guard()
        });
    }
    let t_out: Vec<f64> = (0..=(t_end * 10.0).round() as usize)
        .map(|i| 0.1 * i as f64)
        .collect();
    let sim = simulate(&mut sys, &state, &t_out, BdfOptions::adaptive(1e-4, 1e-6))?;
    Ok(sim
        .outputs
        .iter()
        .map(|o| (o.t, o.position_violation))
        .collect())
}

fn max_between(v: &[(f64, f64)], t0: f64, t1: f64) -> f64 {
    v.iter()
        .filter(|(t, _)| *t >= t0 && *t <= t1)
        .map(|x| x.1)
        .fold(0.0, f64::max)
}

#[test]
fn violations_stay_bounded_with_baumgarte_and_grow_without() {
    let with = pendulum(Baumgarte::default(), None, 40.0).unwrap();
    // the drift passes the guard's 5 % of the pendulum's size (7.5 cm) at about 15 s
    let without = pendulum(Baumgarte::off(), Some(f64::INFINITY), 20.0).unwrap();
    let (w1, w2) = (
        max_between(&with, 0.0, 20.0),
        max_between(&with, 20.0, 40.0),
    );
    let (n1, n2) = (
        max_between(&without, 0.0, 10.0),
        max_between(&without, 10.0, 20.0),
    );
    eprintln!("with Baumgarte: {w1:e} then {w2:e}; without: {n1:e} then {n2:e}");
    // bounded at the level the tolerance allows, with no trend: the largest violation of a
    // 10 s window scatters from 1.2e-3 to 4.7e-3 over 80 s (the chaotic motion and the step
    // sequence move it; a last-bit change of the LU moves it within that band), so the
    // halves of 40 s are compared
    assert!(
        w1 < 5e-3 && w2 < 5e-3 && w2 < 2.5 * w1,
        "stabilised violation must stay bounded: {w1:e} → {w2:e}"
    );
    assert!(
        n2 > 1.5 * n1,
        "unstabilised violation must grow: {n1:e} → {n2:e}"
    );
    assert!(
        n2 > 10.0 * w2,
        "Baumgarte must keep the violation far smaller: {w2:e} vs {n2:e}"
    );
}

/// The drift without stabilisation is stopped by the step guard, naming the joint, instead of
/// running on with the links apart.
#[test]
fn the_step_guard_stops_an_unstabilised_drift() {
    let err = pendulum(Baumgarte::off(), None, 20.0).unwrap_err();
    let SimulationError::Integration(e) = &err else {
        panic!("{err}");
    };
    assert!(matches!(e.reason, IntegrationFailure::Refused(_)), "{err}");
    let msg = err.to_string();
    assert!(
        msg.contains("joint `elbow`") || msg.contains("joint `pivot`"),
        "{msg}"
    );
    assert!(msg.contains("7.500e-2"), "{msg}");
    assert!(e.t > 10.0 && e.t < 20.0, "{msg}");
}

/// The step check reads the constraint violation of the last right-hand side (the step's last
/// Newton iterate) when it was evaluated at the step's time and within half the limit, and
/// evaluates the state itself otherwise.
#[test]
fn the_step_check_reads_the_last_right_hand_side_only_at_its_time_and_below_half_the_limit() {
    let (mut sys, state) = pendulum_system(Baumgarte::default());
    let limit = sys.guard().max_violation;
    let y_ok: Vec<f64> = state.q.iter().chain(&state.v).copied().collect();
    // the lower link's origin moved along x: the elbow opens by `gap`
    let opened = |gap: f64| {
        let mut y = y_ok.clone();
        y[7] += gap;
        y
    };
    let (y_mid, y_bad) = (opened(0.7 * limit), opened(1.5 * limit));
    let mut dy = vec![0.0; y_ok.len()];
    let violation = |sys: &MultibodySystem, y: &[f64]| {
        let (q, v) = y.split_at(state.q.len());
        sys.check_state(0.0, q, v)
    };
    assert!(violation(&sys, &y_ok).is_ok() && violation(&sys, &y_mid).is_ok());
    let refusal = violation(&sys, &y_bad).unwrap_err();
    assert!(refusal.contains("joint `elbow`"), "{refusal}");

    // at the time of the last right-hand side, within half the limit: read from it
    sys.rhs(0.0, &y_ok, &mut dy).unwrap();
    assert!(sys.check_step(0.0, &y_ok).is_ok());
    assert!(
        sys.check_step(0.0, &y_bad).is_ok(),
        "the iterate's violation is read"
    );
    // at another time: the state itself
    assert_eq!(sys.check_step(0.5, &y_bad), Err(refusal.clone()));
    // above half the limit at the last right-hand side: the state itself
    sys.rhs(0.0, &y_mid, &mut dy).unwrap();
    assert_eq!(sys.check_step(0.0, &y_bad), Err(refusal.clone()));
    assert!(sys.check_step(0.0, &y_mid).is_ok());
}
