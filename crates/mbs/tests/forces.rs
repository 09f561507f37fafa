//! Applied forces: a spring–damper conserves energy without damping and dissipates with it;
//! a tabulated point force changes momentum by its time integral; a constant torque changes
//! angular momentum linearly; a joint actuator drives a pinned arm as its closed-form motion
//! (a tabulated torque, and a PD law tracking a ramp).

mod common;

use common::assembled;
use mbs::{
    BdfOptions, Force, Joint, JointKind, Load, LoadFrame, Marker, Model, Response, RigidBody,
    TimeFunction, TorqueLaw, simulate,
};
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

/// Length, mass and moment of inertia about the pin of the arm of [`pinned_arm`].
const ARM: (f64, f64) = (0.4, 1.5);

fn arm_inertia_about_pin() -> f64 {
    let (l, m) = ARM;
    m * l * l / 3.0
}

/// A slender arm along x pinned to the ground at the origin about z, at rest, no gravity,
/// driven by an actuator `law` between the ground and the arm at the pin (reversed: the
/// arm's marker first, so the torque about its axis acts on the ground with the opposite
/// sign); its angle at `times`.
fn pinned_arm(law: TorqueLaw, reversed: bool, times: &[f64]) -> Vec<f64> {
    let (mut sys, state) = pinned_arm_system(law, reversed);
    let out = simulate(&mut sys, &state, times, BdfOptions::adaptive(1e-10, 1e-13))
        .unwrap()
        .outputs;
    out.iter()
        .map(|o| o.orientations[0][(1, 0)].atan2(o.orientations[0][(0, 0)]))
        .collect()
}

/// The system of [`pinned_arm`], assembled at rest.
fn pinned_arm_system(law: TorqueLaw, reversed: bool) -> (mbs::MultibodySystem, mbs::State) {
    let (l, m) = ARM;
    let mut model = Model::new();
    let inertia = Matrix3::from_diagonal(&Vector3::new(1e-6, m * l * l / 12.0, m * l * l / 12.0));
    let arm = model
        .add_rigid_body(RigidBody::new("arm", m, inertia))
        .unwrap();
    let ground = Marker::ground(Vector3::zeros());
    let pin = Marker::on(arm, Vector3::new(-l / 2.0, 0.0, 0.0));
    model
        .add_joint(Joint::new(
            "pin",
            JointKind::Revolute,
            ground.clone(),
            pin.clone(),
        ))
        .unwrap();
    let (a, b) = if reversed {
        (pin, ground)
    } else {
        (ground, pin)
    };
    model.add_force(Force::JointTorque { a, b, law }).unwrap();
    let mut state = model.rest_state();
    model.set_pose(
        &mut state,
        arm,
        Vector3::new(l / 2.0, 0.0, 0.0),
        &Matrix3::identity(),
    );
    assembled(model, state)
}

#[test]
fn a_pd_actuators_jacobian_matches_central_differences() {
    use mbs::OdeSystem;
    let law = TorqueLaw::Pd {
        kp: 5.0,
        kd: 0.2,
        motion: TimeFunction::ConstantSpeed {
            initial: 0.3,
            rate: 1.5,
        },
    };
    let (mut sys, state) = pinned_arm_system(law, false);
    // turned by 0.7 rad and swinging at 2 rad/s about the pin
    let (l, _) = ARM;
    let (s, c) = 0.7f64.sin_cos();
    let rot = Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0);
    let mut st = state.clone();
    let arm = mbs::BodyId::from(0);
    sys.model()
        .set_pose(&mut st, arm, rot * Vector3::new(l / 2.0, 0.0, 0.0), &rot);
    sys.model().set_velocity(
        &mut st,
        arm,
        Vector3::new(-2.0 * s * l / 2.0, 2.0 * c * l / 2.0, 0.0),
        Vector3::new(0.0, 0.0, 2.0),
    );
    let y = st.to_vec();
    let n = y.len();
    let t = 0.2;
    let mut jac = nalgebra::DMatrix::zeros(n, n);
    sys.jacobian(t, &y, &mut jac).unwrap();
    let (mut fp, mut fm) = (vec![0.0; n], vec![0.0; n]);
    for col in 0..n {
        let h = 1e-6;
        let (mut yp, mut ym) = (y.clone(), y.clone());
        yp[col] += h;
        ym[col] -= h;
        sys.rhs(t, &yp, &mut fp).unwrap();
        sys.rhs(t, &ym, &mut fm).unwrap();
        for r in 0..n {
            let fd = (fp[r] - fm[r]) / (2.0 * h);
            assert!(
                (jac[(r, col)] - fd).abs() < 1e-6 * (1.0 + fd.abs()),
                "∂f{r}/∂y{col}: {} against {fd}",
                jac[(r, col)]
            );
        }
    }
}

#[test]
fn a_tabulated_joint_torque_turns_a_pinned_arm_as_its_closed_form() {
    // τ = τ0 until 0.5 s, then falling linearly to zero at 1 s: θ = ∫∫ τ/J
    let tau0 = 0.3;
    let law = TorqueLaw::Table {
        times: vec![0.5, 1.0],
        values: vec![tau0, 0.0],
    };
    let times: Vec<f64> = (0..=12).map(|i| 0.1 * i as f64).collect();
    let j = arm_inertia_about_pin();
    let exact = |t: f64| {
        let a = tau0 / j;
        if t <= 0.5 {
            0.5 * a * t * t
        } else {
            // ramp-down over 0.5 s: α = a (1 − (t − 0.5)/0.5)
            let s = (t - 0.5).min(0.5);
            let (th0, om0) = (0.5 * a * 0.25, a * 0.5);
            let th = th0 + om0 * s + 0.5 * a * s * s - a * s * s * s / 3.0;
            let om = om0 + a * s - a * s * s;
            th + om * (t - 0.5 - s)
        }
    };
    for reversed in [false, true] {
        let th = pinned_arm(law.clone(), reversed, &times);
        for (&t, &x) in times.iter().zip(&th) {
            let e = if reversed { -exact(t) } else { exact(t) };
            assert!(
                (x - e).abs() < 1e-7 * exact(1.2),
                "reversed {reversed}, t = {t}: θ {x} against {e}"
            );
        }
    }
}

#[test]
fn a_pd_actuator_tracks_a_ramp_as_the_closed_form_linear_response() {
    // J θ̈ = kp (ω t − θ) + kd (ω − θ̇) from rest: the error e = ω t − θ obeys
    // J ë + kd ė + kp e = 0, e(0) = 0, ė(0) = ω; exact, the arm having no gravity
    let (omega, kp, kd) = (1.5, 5.0, 0.2);
    let j = arm_inertia_about_pin();
    let law = TorqueLaw::Pd {
        kp,
        kd,
        motion: TimeFunction::ConstantSpeed {
            initial: 0.0,
            rate: omega,
        },
    };
    let times: Vec<f64> = (0..=40).map(|i| 0.05 * i as f64).collect();
    let (mut sys, state) = pinned_arm_system(law, false);
    let out = simulate(&mut sys, &state, &times, BdfOptions::adaptive(1e-10, 1e-13))
        .unwrap()
        .outputs;
    let (wn, zeta) = ((kp / j).sqrt(), kd / (2.0 * (kp * j).sqrt()));
    let wd = wn * (1.0 - zeta * zeta).sqrt();
    assert!(zeta < 0.5, "underdamped: ζ = {zeta}");
    let motor = mbs::ForceId::from(0);
    let torque = Response::ActuatorTorque { force: motor };
    let power = Response::ActuatorPower { force: motor };
    let mut largest_error = 0.0f64;
    for (&t, o) in times.iter().zip(&out) {
        let decay = (-zeta * wn * t).exp();
        let e = omega / wd * decay * (wd * t).sin();
        let e_dot = omega * decay * ((wd * t).cos() - zeta * wn / wd * (wd * t).sin());
        largest_error = largest_error.max(e.abs());
        // the angle wraps past π: compare on the circle
        let x = o.orientations[0][(1, 0)].atan2(o.orientations[0][(0, 0)]);
        let d = (x - (omega * t - e)).sin();
        assert!(d.abs() < 1e-7, "t = {t}: θ {x} against {}", omega * t - e);
        // the actuator's torque and power as responses
        let tau = kp * e + kd * e_dot;
        let got = torque.value(sys.model(), o);
        assert!(
            (got - tau).abs() < 1e-6 * kp,
            "t = {t}: τ {got} against {tau}"
        );
        let p = tau * (omega - e_dot);
        let got = power.value(sys.model(), o);
        assert!(
            (got - p).abs() < 1e-6 * kp,
            "t = {t}: power {got} against {p}"
        );
    }
    // the comparison means something: the error swings by a tenth of a radian
    assert!(largest_error > 0.1, "{largest_error}");
}

#[test]
fn an_actuator_between_a_body_and_itself_is_refused() {
    let mut model = Model::new();
    let arm = model
        .add_rigid_body(RigidBody::new("arm", 1.0, Matrix3::identity()))
        .unwrap();
    let law = TorqueLaw::Pd {
        kp: 1.0,
        kd: 0.0,
        motion: TimeFunction::ConstantSpeed {
            initial: 0.0,
            rate: 0.0,
        },
    };
    let m = Marker::on(arm, Vector3::zeros());
    assert!(
        model
            .add_force(Force::JointTorque {
                a: m.clone(),
                b: m.clone(),
                law,
            })
            .is_err()
    );
    let bad = TorqueLaw::Table {
        times: vec![0.0, 0.0],
        values: vec![1.0, 2.0],
    };
    let ground = Marker::ground(Vector3::zeros());
    assert!(
        model
            .add_force(Force::JointTorque {
                a: ground,
                b: m,
                law: bad,
            })
            .is_err()
    );
}
