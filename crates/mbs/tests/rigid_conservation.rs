//! Conservation laws and a closed-form solution for rigid bodies: a spatial double pendulum
//! (energy) and a torque-free asymmetric body (angular momentum, energy, and the polhode
//! period of the Jacobi elliptic-function solution of Euler's equations).

mod common;

use common::assembled;
use mbs::{BdfOptions, Joint, JointKind, Marker, Model, RigidBody, simulate};
use nalgebra::{Matrix3, Vector3};

#[test]
fn spatial_double_pendulum_conserves_energy() {
    let mut model = Model::new();
    model.gravity = Vector3::new(0.0, 0.0, -9.81);
    let (m, l) = (1.0, 1.0);
    let inertia = common::rod_inertia(m, l);
    let b1 = model
        .add_rigid_body(RigidBody::new("upper", m, inertia))
        .unwrap();
    let b2 = model
        .add_rigid_body(RigidBody::new("lower", m, inertia))
        .unwrap();
    let half = Vector3::new(l / 2.0, 0.0, 0.0);
    model
        .add_joint(Joint::new(
            "pivot",
            JointKind::Spherical,
            Marker::ground(Vector3::zeros()),
            Marker::on(b1, -half),
        ))
        .unwrap();
    model
        .add_joint(Joint::new(
            "elbow",
            JointKind::Spherical,
            Marker::on(b1, half),
            Marker::on(b2, -half),
        ))
        .unwrap();
    let mut state = model.rest_state();
    // both links horizontal along x; spinning about different axes so the motion is spatial
    model.set_pose(&mut state, b1, half, &Matrix3::identity());
    model.set_pose(&mut state, b2, half * 3.0, &Matrix3::identity());
    model.set_velocity(
        &mut state,
        b1,
        Vector3::new(0.0, 1.0, 0.0),
        Vector3::new(0.3, 0.0, 2.0),
    );
    model.set_velocity(
        &mut state,
        b2,
        Vector3::new(0.0, 3.0, 1.0),
        Vector3::new(-0.5, -1.0, 1.0),
    );
    let (mut sys, state) = assembled(model, state);
    assert!(sys.removed_equations().is_empty());
    let t_out: Vec<f64> = (0..=100).map(|i| 0.05 * i as f64).collect();
    let sim = simulate(&mut sys, &state, &t_out, BdfOptions::adaptive(1e-10, 1e-12)).unwrap();
    let e0 = sim.outputs[0].energy.total();
    let scale = sim
        .outputs
        .iter()
        .map(|o| o.energy.kinetic)
        .fold(0.0, f64::max);
    let drift = sim
        .outputs
        .iter()
        .map(|o| (o.energy.total() - e0).abs())
        .fold(0.0, f64::max)
        / scale;
    let violation = sim
        .outputs
        .iter()
        .map(|o| o.position_violation)
        .fold(0.0, f64::max);
    eprintln!(
        "energy drift {drift:e} (scale {scale} J), violation {violation:e}, {:?}",
        sim.statistics
    );
    assert!(scale > 5.0, "the pendulum must actually swing");
    assert!(drift < 1e-6, "relative energy drift {drift:e}");
    assert!(violation < 1e-7, "constraint violation {violation:e}");
}

/// Complete elliptic integral of the first kind `K(k)` by the arithmetic–geometric mean.
fn elliptic_k(k2: f64) -> f64 {
    let (mut a, mut b) = (1.0, (1.0 - k2).sqrt());
    for _ in 0..30 {
        let (an, bn) = (0.5 * (a + b), (a * b).sqrt());
        a = an;
        b = bn;
    }
    std::f64::consts::PI / (2.0 * a)
}

#[test]
fn torque_free_asymmetric_body_keeps_angular_momentum_and_follows_the_polhode() {
    let i = Vector3::new(1.0, 2.0, 3.0);
    let mut model = Model::new();
    let b = model
        .add_rigid_body(RigidBody::new("top", 2.0, Matrix3::from_diagonal(&i)))
        .unwrap();
    let mut state = model.rest_state();
    let a0 = nalgebra::Rotation3::from_euler_angles(0.3, -0.2, 0.7).into_inner();
    model.set_pose(&mut state, b, Vector3::new(1.0, 2.0, 3.0), &a0);
    let w0 = Vector3::new(1.0, 0.0, 3.0);
    model.set_velocity(&mut state, b, Vector3::new(0.1, 0.0, -0.2), w0);
    // closed form (Landau & Lifshitz §37): rotation about the axis of largest inertia
    let two_e = i.component_mul(&w0).dot(&w0);
    let m2 = i.component_mul(&w0).norm_squared();
    let k2 = (i.y - i.x) * (two_e * i.z - m2) / ((i.z - i.y) * (m2 - two_e * i.x));
    let p = ((i.z - i.y) * (m2 - two_e * i.x) / (i.x * i.y * i.z)).sqrt();
    let period = 4.0 * elliptic_k(k2) / p;
    let w1 = ((two_e * i.z - m2) / (i.x * (i.z - i.x))).sqrt();
    let w2 = ((two_e * i.z - m2) / (i.y * (i.z - i.y))).sqrt();
    let w3 = ((m2 - two_e * i.x) / (i.z * (i.z - i.x))).sqrt();
    let expected = [
        Vector3::new(w1, 0.0, w3),
        Vector3::new(0.0, w2, w3 * (1.0 - k2).sqrt()),
        Vector3::new(-w1, 0.0, w3),
        Vector3::new(0.0, -w2, w3 * (1.0 - k2).sqrt()),
        Vector3::new(w1, 0.0, w3),
    ];
    let (mut sys, state) = assembled(model, state);
    let t_out: Vec<f64> = (0..=4).map(|k| period * k as f64 / 4.0).collect();
    let sim = simulate(&mut sys, &state, &t_out, BdfOptions::adaptive(1e-11, 1e-12)).unwrap();
    let h0 = a0 * i.component_mul(&w0);
    for (o, w_exp) in sim.outputs.iter().zip(&expected) {
        let w = Vector3::new(o.v[3], o.v[4], o.v[5]);
        let h = o.orientations[0] * i.component_mul(&w);
        eprintln!("t {:.4}: ω' {w:?} expected {w_exp:?}", o.t);
        assert!(
            (w - w_exp).norm() < 1e-7 * w0.norm(),
            "t = {}: ω' = {w:?}, expected {w_exp:?}",
            o.t
        );
        assert!(
            (h - h0).norm() < 1e-8 * h0.norm(),
            "angular momentum drifted: {h:?} vs {h0:?}"
        );
        assert!((o.energy.total() - 0.5 * two_e - 0.5 * 2.0 * 0.05).abs() < 1e-9 * two_e);
        // the centre of mass moves uniformly
        let r = Vector3::new(1.0, 2.0, 3.0) + Vector3::new(0.1, 0.0, -0.2) * o.t;
        assert!((o.positions[0] - r).norm() < 1e-9);
    }
}
