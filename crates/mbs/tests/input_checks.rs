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

#[test]
fn a_joint_between_ground_and_ground_is_refused() {
    let (mut m, _) = pendulum();
    let e = m
        .add_joint(Joint::new(
            "nothing",
            JointKind::Spherical,
            Marker::ground(Vector3::zeros()),
            Marker::ground(Vector3::x()),
        ))
        .unwrap_err();
    assert!(e.to_string().contains("nothing") && e.to_string().contains("two different"));
}

#[test]
fn impossible_rigid_inertias_are_refused() {
    let diag = |a: f64, b: f64, c: f64| Matrix3::from_diagonal(&Vector3::new(a, b, c));
    let mut skew = diag(1.0, 1.0, 1.0);
    skew[(0, 1)] = 0.5;
    for (inertia, mass) in [
        (diag(1.0, 1.0, 0.0), 1.0),  // a zero principal moment
        (diag(1.0, -1.0, 1.0), 1.0), // a negative one
        (diag(1.0, 1.0, 3.0), 1.0),  // 3 > 1 + 1: no mass distribution has it
        (diag(1.0, 1.0, f64::NAN), 1.0),
        (skew, 1.0), // not symmetric
        (diag(1.0, 1.0, 1.0), f64::INFINITY),
    ] {
        let mut m = Model::<f64>::new();
        let e = m.add_rigid_body(RigidBody::new("lump", mass, inertia));
        assert!(e.is_err(), "{inertia} {mass}");
        assert!(e.unwrap_err().to_string().contains("lump"));
    }
    // a flat plate (equality) and a slender rod are fine
    let mut m = Model::<f64>::new();
    m.add_rigid_body(RigidBody::new("plate", 1.0, diag(1.0, 1.0, 2.0)))
        .unwrap();
    m.add_rigid_body(RigidBody::new("rod", 1.0, diag(1e-8, 1.0, 1.0)))
        .unwrap();
}

#[test]
fn bad_spring_parameters_are_refused_and_a_zero_length_spring_is_named() {
    let (mut m, s) = pendulum();
    let bob = m.body_ids().next().unwrap();
    let spring = |k: f64, c: f64, l0: f64| mbs::Force::SpringDamper {
        a: Marker::ground(Vector3::new(0.0, -0.5, 0.0)),
        b: Marker::on(bob, Vector3::zeros()),
        stiffness: k,
        damping: c,
        free_length: l0,
    };
    for (k, c, l0) in [(-1.0, 0.0, 0.0), (1.0, f64::NAN, 0.0), (1.0, 0.0, -0.1)] {
        assert!(
            m.clone().add_force(spring(k, c, l0)).is_err(),
            "{k} {c} {l0}"
        );
    }
    // the spring's two points coincide at the start: its direction is undefined
    m.add_force(spring(100.0, 0.0, 0.1)).unwrap();
    assert_eq!(m.zero_length_springs(&s.q), vec![0]);
    let sys = MultibodySystem::new(m, &s, RedundancyPolicy::Remove).unwrap();
    let e = sys.solve(0.0, &s.q, &s.v).err().expect("non-finite");
    let msg = e.to_string();
    assert!(
        msg.contains("zero length") && msg.contains("force 0"),
        "{msg}"
    );
}

#[test]
fn negative_or_non_finite_baumgarte_parameters_are_refused() {
    for (alpha, beta) in [(-1.0, 1.0), (1.0, f64::NAN), (f64::INFINITY, 0.0)] {
        let (mut m, s) = pendulum();
        m.baumgarte = mbs::Baumgarte { alpha, beta };
        let e = MultibodySystem::new(m, &s, RedundancyPolicy::Remove)
            .err()
            .expect("refused");
        assert!(
            matches!(e, mbs::ConstraintError::BadStabilisation { .. })
                && e.to_string().contains("Baumgarte"),
            "{e}"
        );
    }
    let (mut m, s) = pendulum();
    m.baumgarte = mbs::Baumgarte::off();
    assert!(MultibodySystem::new(m, &s, RedundancyPolicy::Remove).is_ok());
}
