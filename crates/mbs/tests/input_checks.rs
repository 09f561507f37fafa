//! Bad settings and states give errors, not panics or silent results (findings of the review).

use mbs::{
    Bdf, BdfOptions, IntegrationFailure, Joint, JointKind, Marker, Model, MultibodySystem,
    OdeSystem, RedundancyPolicy, RhsError, RigidBody,
};
use nalgebra::{DMatrix, Matrix3, Vector3};

struct Decay;

impl OdeSystem for Decay {
    fn dim(&self) -> usize {
        2
    }
    fn rhs(&mut self, _t: f64, y: &[f64], f: &mut [f64]) -> Result<(), RhsError> {
        f[0] = -y[0];
        f[1] = -2.0 * y[1];
        Ok(())
    }
    fn jacobian(&mut self, _t: f64, _y: &[f64], j: &mut DMatrix<f64>) -> Result<(), RhsError> {
        j.fill(0.0);
        j[(0, 0)] = -1.0;
        j[(1, 1)] = -2.0;
        Ok(())
    }
}

#[test]
fn zero_atol_is_refused_with_a_clear_reason() {
    let mut b = Bdf::new(BdfOptions::adaptive(1e-6, 0.0));
    let e = b.init(&mut Decay, 0.0, &[1.0, 0.0]).unwrap_err();
    assert!(
        matches!(e.reason, IntegrationFailure::Settings(s) if s.contains("atol")),
        "{e}"
    );
}

#[test]
fn unsorted_or_non_finite_output_times_are_refused() {
    for t_out in [vec![0.0, 1.0, 0.5], vec![0.0, f64::NAN], vec![0.0, 2.0]] {
        let mut b = Bdf::new(BdfOptions::adaptive(1e-6, 1e-9));
        b.init(&mut Decay, 0.0, &[1.0, 1.0]).unwrap();
        let e = b.integrate_to(&mut Decay, 1.0, &t_out, |_| {}).unwrap_err();
        assert!(
            matches!(e.reason, IntegrationFailure::Settings(_)),
            "{t_out:?}: {e}"
        );
    }
}

fn pendulum() -> (Model<f64>, mbs::State) {
    let mut m = Model::new();
    let b = m
        .add_rigid_body(RigidBody::new("bob", 1.0, Matrix3::identity() * 0.01))
        .unwrap();
    m.add_joint(Joint::new(
        "pin",
        JointKind::Spherical,
        Marker::ground(Vector3::zeros()),
        Marker::on(b, Vector3::new(0.0, 0.5, 0.0)),
    ))
    .unwrap();
    let mut s = m.rest_state();
    m.set_pose(
        &mut s,
        b,
        Vector3::new(0.0, -0.5, 0.0),
        &Matrix3::identity(),
    );
    (m, s)
}

#[test]
fn empty_output_times_are_an_error_not_a_panic() {
    let (m, s) = pendulum();
    let mut sys = MultibodySystem::new(m, &s, RedundancyPolicy::Remove).unwrap();
    assert!(mbs::simulate(&mut sys, &s, &[], BdfOptions::adaptive(1e-6, 1e-9)).is_err());
}

#[test]
fn assembling_a_nan_state_fails() {
    let (m, mut s) = pendulum();
    let mut sys = MultibodySystem::new(m, &s, RedundancyPolicy::Remove).unwrap();
    s.q[0] = f64::NAN;
    assert!(sys.assemble(0.0, &mut s, 1e-10).is_err());
}

#[test]
fn markers_with_nan_points_or_degenerate_axes_are_refused() {
    let (mut m, _) = pendulum();
    let nan = Marker::ground(Vector3::new(f64::NAN, 0.0, 0.0));
    let e = m.add_joint(Joint::new(
        "bad",
        JointKind::Spherical,
        nan,
        Marker::ground(Vector3::zeros()),
    ));
    assert!(e.is_err());
    let zero_axis = Marker::ground(Vector3::zeros()).with_axis(Vector3::zeros());
    let e = m.add_joint(Joint::new(
        "bad2",
        JointKind::Revolute,
        zero_axis,
        Marker::ground(Vector3::x()),
    ));
    assert!(e.is_err());
}
