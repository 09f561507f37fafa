//! Applied forces: a spring–damper conserves energy without damping and dissipates with it;
//! a tabulated point force changes momentum by its time integral; a constant torque changes
//! angular momentum linearly.

mod common;

use common::assembled;
use mbs::{BdfOptions, Force, Load, LoadFrame, Marker, Model, RigidBody, simulate};
use nalgebra::{Matrix3, Vector3};

fn two_bodies_on_a_spring(damping: f64) -> Vec<mbs::Output> {
    let mut model = Model::new();
    model.gravity = Vector3::new(0.0, 0.0, -9.81);
    let inertia = Matrix3::from_diagonal(&Vector3::new(0.01, 0.02, 0.03));
    let a = model
        .add_rigid_body(RigidBody::new("a", 1.0, inertia))
        .unwrap();
    let b = model
        .add_rigid_body(RigidBody::new("b", 0.5, inertia))
        .unwrap();
    model
        .add_force(Force::SpringDamper {
            a: Marker::on(a, Vector3::new(0.1, 0.0, 0.0)),
            b: Marker::on(b, Vector3::new(0.0, 0.05, 0.0)),
            stiffness: 200.0,
            damping,
            free_length: 0.3,
        })
        .unwrap();
    let mut state = model.rest_state();
    model.set_pose(
        &mut state,
        b,
        Vector3::new(0.5, 0.1, 0.0),
        &Matrix3::identity(),
    );
    model.set_velocity(
        &mut state,
        a,
        Vector3::new(0.0, 0.0, 1.0),
        Vector3::new(1.0, 2.0, 0.0),
    );
    model.set_velocity(
        &mut state,
        b,
        Vector3::new(0.2, 0.0, 0.0),
        Vector3::new(0.0, -1.0, 3.0),
    );
    let (mut sys, state) = assembled(model, state);
    let t_out: Vec<f64> = (0..=100).map(|i| 0.02 * i as f64).collect();
    simulate(&mut sys, &state, &t_out, BdfOptions::adaptive(1e-10, 1e-12))
        .unwrap()
        .outputs
}

#[test]
fn spring_conserves_energy_and_damper_dissipates_it() {
    let out = two_bodies_on_a_spring(0.0);
    let e0 = out[0].energy.total();
    let scale = out.iter().map(|o| o.energy.spring).fold(0.0, f64::max);
    assert!(scale > 0.5, "the spring must work");
    let drift = out
        .iter()
        .map(|o| (o.energy.total() - e0).abs())
        .fold(0.0, f64::max)
        / scale;
    assert!(drift < 1e-6, "energy drift {drift:e}");
    let out = two_bodies_on_a_spring(2.0);
    for w in out.windows(2) {
        assert!(
            w[1].energy.total() < w[0].energy.total() + 1e-9,
            "damping must dissipate"
        );
    }
    assert!(out.last().unwrap().energy.total() < out[0].energy.total() - 0.1 * scale);
}

#[test]
fn tabulated_force_and_constant_torque_change_the_momenta_by_their_impulses() {
    let mut model = Model::new();
    let inertia = Matrix3::from_diagonal(&Vector3::new(0.1, 0.2, 0.3));
    let a = model
        .add_rigid_body(RigidBody::new("pushed", 2.0, inertia))
        .unwrap();
    let b = model
        .add_rigid_body(RigidBody::new("twisted", 1.0, inertia))
        .unwrap();
    let times = vec![0.0, 0.2, 0.5, 1.0];
    let values = vec![
        Vector3::new(0.0, 0.0, 0.0),
        Vector3::new(4.0, -2.0, 0.0),
        Vector3::new(4.0, 1.0, 3.0),
        Vector3::zeros(),
    ];
    let load = Load::Table {
        times: times.clone(),
        values: values.clone(),
    };
    model
        .add_force(Force::PointForce {
            marker: Marker::on(a, Vector3::zeros()),
            load,
            frame: LoadFrame::Global,
        })
        .unwrap();
    let torque = Vector3::new(0.1, -0.2, 0.3);
    model
        .add_force(Force::PointTorque {
            marker: Marker::on(b, Vector3::zeros()),
            load: Load::Constant(torque),
            frame: LoadFrame::Global,
        })
        .unwrap();
    let mut state = model.rest_state();
    model.set_velocity(
        &mut state,
        b,
        Vector3::zeros(),
        Vector3::new(1.0, 0.5, -0.5),
    );
    let (mut sys, state) = assembled(model, state);
    let t_out = [0.0, 0.2, 0.5, 1.0, 1.5];
    let out = simulate(&mut sys, &state, &t_out, BdfOptions::adaptive(1e-10, 1e-12))
        .unwrap()
        .outputs;
    // impulse of the piecewise-linear table: trapezoids
    let mut impulse = Vector3::zeros();
    let mut cumulative = vec![Vector3::zeros()];
    for i in 1..times.len() {
        impulse += (values[i] + values[i - 1]) * 0.5 * (times[i] - times[i - 1]);
        cumulative.push(impulse);
    }
    cumulative.push(impulse);
    let h0 = inertia * Vector3::new(1.0, 0.5, -0.5);
    for (o, j) in out.iter().zip(&cumulative) {
        let p = Vector3::new(o.v[0], o.v[1], o.v[2]) * 2.0;
        // the table has kinks the adaptive steps do not land on
        assert!(
            (p - j).norm() < 1e-7,
            "t = {}: momentum {p:?} vs impulse {j:?}",
            o.t
        );
        let w = Vector3::new(o.v[9], o.v[10], o.v[11]);
        let h = o.orientations[1] * (inertia * w);
        let expected = h0 + torque * o.t;
        assert!(
            (h - expected).norm() < 1e-8,
            "t = {}: angular momentum {h:?} vs {expected:?}",
            o.t
        );
    }
}

#[test]
fn joint_reactions_of_a_hanging_double_pendulum_carry_the_weights() {
    use mbs::{Joint, JointKind};
    let mut model = Model::new();
    let g = 9.81;
    model.gravity = Vector3::new(0.0, -g, 0.0);
    let (m1, m2) = (1.5, 0.5);
    let upper = model
        .add_rigid_body(RigidBody::new("upper", m1, common::rod_inertia(m1, 1.0)))
        .unwrap();
    let lower = model
        .add_rigid_body(RigidBody::new("lower", m2, common::rod_inertia(m2, 1.0)))
        .unwrap();
    let half = Vector3::new(0.0, 0.5, 0.0);
    model
        .add_joint(Joint::new(
            "pivot",
            JointKind::Revolute,
            Marker::ground(Vector3::zeros()),
            Marker::on(upper, half),
        ))
        .unwrap();
    model
        .add_joint(Joint::new(
            "elbow",
            JointKind::Spherical,
            Marker::on(upper, -half),
            Marker::on(lower, half),
        ))
        .unwrap();
    let mut state = model.rest_state();
    model.set_pose(&mut state, upper, -half, &Matrix3::identity());
    model.set_pose(&mut state, lower, -half * 3.0, &Matrix3::identity());
    let (sys, state) = assembled(model, state);
    let o = sys.output(0.0, &state.to_vec()).unwrap();
    let up = Vector3::new(0.0, 1.0, 0.0);
    let (pivot, elbow) = (&o.reactions[0], &o.reactions[1]);
    assert!(
        (pivot.force_on_b - up * (m1 + m2) * g).norm() < 1e-10,
        "{pivot:?}"
    );
    assert!(pivot.force_on_a.norm() == 0.0, "the ground has no body");
    assert!((elbow.force_on_b - up * m2 * g).norm() < 1e-10, "{elbow:?}");
    assert!(
        (elbow.force_on_a + elbow.force_on_b).norm() < 1e-10,
        "action and reaction"
    );
    assert!(pivot.moment_on_b.norm() < 1e-10 && elbow.moment_on_b.norm() < 1e-10);
    assert!(
        o.accelerations.iter().all(|a| a.abs() < 1e-10),
        "equilibrium"
    );
}
