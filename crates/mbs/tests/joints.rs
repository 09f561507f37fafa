//! Every joint kind and driver, between rigid bodies, the ground and FE nodes of a flexible
//! body in general (inconsistent) poses: `Φ̇` and `γ` against central differences along the
//! motion, and the prescribed time functions against differences of their values.

mod common;

use common::{Beam, flow};
use fem::GeometricStiffness;
use mbs::{FlexibleBody, Joint, JointKind, Marker, Model, RigidBody, TimeFunction};
use nalgebra::{DMatrix, Matrix3, Rotation3, Vector3};

/// A second-order field for every node of a body with `nodes` nodes and `modes` modes, of all
/// but its last mode (arbitrary, symmetric in the mode pair; large enough to show in `Φ̇` and
/// `γ`).
fn second_order_field(nodes: usize, modes: usize) -> fem::GeometricStiffness<f64> {
    let field = modes - 1;
    GeometricStiffness {
        n_modes: modes,
        field_modes: field,
        eigenmodes: field,
        clamp: 0,
        nodal: (0..3 * nodes)
            .map(|r| {
                DMatrix::from_fn(field, field, |j, l| {
                    40.0 * ((r * 7 + (j + l) * 3 + j * l) as f64 * 0.53).sin()
                })
            })
            .collect(),
        elements: None,
    }
}

/// Joints of every kind; the flexible body with a second-order field when `second_order`.
fn model_with_every_joint(second_order: bool) -> (Model<f64>, Vec<f64>, Vec<f64>) {
    let mut model = Model::new();
    let r1 = model
        .add_rigid_body(RigidBody::new("r1", 1.0, Matrix3::identity()))
        .unwrap();
    let r2 = model
        .add_rigid_body(RigidBody::new("r2", 2.0, Matrix3::identity() * 0.1))
        .unwrap();
    let beam = Beam::slider_crank_rod(8);
    let mut flexible = FlexibleBody::new("f", beam.modal_body(-0.152, 4, 4, 0.01));
    if second_order {
        flexible = flexible.with_geometric_stiffness(second_order_field(beam.n_nodes(), 4));
    }
    let f = model.add_flexible_body(flexible).unwrap();
    let p = |x: f64, y: f64, z: f64| Vector3::new(x, y, z);
    let joints = vec![
        (
            JointKind::Spherical,
            Marker::ground(p(0.1, 0.0, 0.0)),
            Marker::on(r1, p(0.0, 0.2, 0.0)),
        ),
        (
            JointKind::Revolute,
            Marker::on(r1, p(0.1, 0.0, 0.1)).with_axis(p(1.0, 1.0, 0.0)),
            Marker::node(f, 0).with_axis(p(0.0, 1.0, 1.0)),
        ),
        (
            JointKind::Universal,
            Marker::node(f, 8).with_axis(p(0.0, 0.0, 1.0)),
            Marker::on(r2, p(0.05, 0.0, 0.0)).with_axis(p(0.0, 1.0, 0.0)),
        ),
        (
            JointKind::Cylindrical,
            Marker::on(r1, p(0.0, 0.0, 0.0)).with_axis(p(0.2, 0.3, 1.0)),
            Marker::on(r2, p(0.0, 0.1, 0.0)).with_axis(p(0.0, 0.0, 1.0)),
        ),
        (
            JointKind::Translational,
            Marker::ground(p(0.0, 0.0, 0.0)).with_axis(p(1.0, 0.0, 0.0)),
            Marker::node(f, 3).with_axes(p(0.0, 1.0, 0.0), p(0.0, 0.0, 1.0)),
        ),
        (
            JointKind::Fixed,
            Marker::on(r2, p(0.0, 0.0, 0.1)),
            Marker::on(f, p(0.02, 0.0, 0.0)),
        ),
        (
            JointKind::AngleDriver(TimeFunction::Polynomial(vec![0.1, 2.0, -3.0, 0.5])),
            Marker::on(r1, p(0.0, 0.0, 0.0)).with_axis(p(0.0, 0.0, 1.0)),
            Marker::on(r2, p(0.0, 0.0, 0.0)),
        ),
        (
            JointKind::DistanceDriver(TimeFunction::SmoothRamp {
                from: 0.1,
                to: 0.4,
                t0: 0.0,
                t1: 1.0,
            }),
            Marker::ground(p(0.0, 0.0, 0.0)).with_axis(p(0.0, 1.0, 0.0)),
            Marker::node(f, 5),
        ),
    ];
    for (i, (kind, a, b)) in joints.into_iter().enumerate() {
        model
            .add_joint(Joint::new(format!("joint {i}"), kind, a, b))
            .unwrap();
    }
    let mut state = model.rest_state();
    model.set_pose(
        &mut state,
        r1,
        p(0.1, 0.2, 0.0),
        Rotation3::from_euler_angles(0.1, 0.2, 0.3).matrix(),
    );
    model.set_pose(
        &mut state,
        r2,
        p(0.3, -0.1, 0.2),
        Rotation3::from_euler_angles(-0.4, 0.1, 1.3).matrix(),
    );
    model.set_pose(
        &mut state,
        f,
        p(0.0, 0.1, -0.1),
        Rotation3::from_euler_angles(0.5, -0.3, 0.2).matrix(),
    );
    model.set_velocity(&mut state, r1, p(1.0, -2.0, 0.5), p(3.0, -1.0, 2.0));
    model.set_velocity(&mut state, r2, p(-1.0, 0.5, 2.0), p(-2.0, 4.0, 1.0));
    model.set_velocity(&mut state, f, p(0.3, 0.2, -0.5), p(1.0, 2.0, -3.0));
    model.set_modal(
        &mut state,
        f,
        &[1e-3, -2e-3, 5e-4, 1e-3],
        &[0.5, 0.3, -0.8, 0.2],
    );
    (model, state.q, state.v)
}

#[test]
fn every_joint_kind_has_rates_and_gamma_consistent_with_its_constraint() {
    joint_rates_and_gamma_are_consistent(false);
}

/// The nodes' second-order displacement `½ Q(w, w)` enters the markers' `Φ̇` and `γ`
/// consistently (its Jacobian columns `Q(w)` and acceleration `Q(ẇ, ẇ)`).
#[test]
fn with_a_second_order_field_rates_and_gamma_stay_consistent() {
    joint_rates_and_gamma_are_consistent(true);
    // and the field shows: the constraints move
    let (a, q, v) = model_with_every_joint(false);
    let (b, ..) = model_with_every_joint(true);
    let (ca, cb) = (a.constraints(0.3, &q, &v), b.constraints(0.3, &q, &v));
    let moved = |x: &[f64], y: &[f64]| {
        x.iter()
            .zip(y)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max)
    };
    assert!(moved(&ca.phi, &cb.phi) > 1e-5);
    assert!(moved(&ca.phi_dot, &cb.phi_dot) > 1e-3);
    assert!(moved(&ca.gamma, &cb.gamma) > 1.0);
}

fn joint_rates_and_gamma_are_consistent(second_order: bool) {
    let (model, q, v) = model_with_every_joint(second_order);
    assert_eq!(model.n_constraints(), 3 + 5 + 4 + 4 + 5 + 6 + 1 + 1);
    let t = 0.3;
    let h = 1e-5;
    let c0 = model.constraints(t, &q, &v);
    let cp = model.constraints(t + h, &flow(&model, &q, &v, h), &v);
    let cm = model.constraints(t - h, &flow(&model, &q, &v, -h), &v);
    for i in 0..model.n_constraints() {
        let joint = &model.joint(model.joint_of_row(i)).name;
        let d1 = (cp.phi[i] - cm.phi[i]) / (2.0 * h);
        let d2 = (cp.phi[i] - 2.0 * c0.phi[i] + cm.phi[i]) / (h * h);
        let s1 = c0.phi_dot[i].abs().max(1.0);
        let s2 = c0.gamma[i].abs().max(1.0);
        assert!(
            (d1 - c0.phi_dot[i]).abs() < 1e-7 * s1,
            "{joint} row {i}: Φ̇ {} vs {d1}",
            c0.phi_dot[i]
        );
        assert!(
            (d2 + c0.gamma[i]).abs() < 1e-4 * s2,
            "{joint} row {i}: −γ {} vs {d2}",
            -c0.gamma[i]
        );
        assert!(
            c0.phi[i].abs() > 0.0 || c0.phi_dot[i].abs() > 0.0 || i < 3,
            "{joint} row {i} is trivially zero"
        );
    }
}

#[test]
fn time_functions_have_consistent_derivatives() {
    let fs = [
        TimeFunction::ConstantSpeed {
            initial: 0.3,
            rate: 150.0,
        },
        TimeFunction::Polynomial(vec![0.1, 2.0, -3.0, 0.5]),
        TimeFunction::SmoothRamp {
            from: -1.0,
            to: 2.0,
            t0: 0.2,
            t1: 0.7,
        },
    ];
    let h = 1e-5;
    for f in &fs {
        for &t in &[0.0, 0.25, 0.45, 0.6, 1.0] {
            let [_, d, dd] = f.eval(t);
            let (p, m) = (f.eval(t + h), f.eval(t - h));
            assert!(
                (d - (p[0] - m[0]) / (2.0 * h)).abs() < 1e-6 * d.abs().max(1.0),
                "{f:?} at {t}"
            );
            assert!(
                (dd - (p[1] - m[1]) / (2.0 * h)).abs() < 1e-5 * dd.abs().max(1.0),
                "{f:?} at {t}"
            );
        }
    }
    let ramp = &fs[2];
    assert_eq!(ramp.eval(0.1), [-1.0, 0.0, 0.0]);
    assert_eq!(ramp.eval(0.8), [2.0, 0.0, 0.0]);
    assert!((ramp.eval(0.45)[0] - 0.5).abs() < 1e-12);
}

#[test]
fn invalid_markers_are_rejected_with_the_joint_name() {
    let mut model = Model::<f64>::new();
    let r = model
        .add_rigid_body(RigidBody::new("r", 1.0, Matrix3::identity()))
        .unwrap();
    let err = model
        .add_joint(Joint::new(
            "bad node",
            JointKind::Spherical,
            Marker::ground(Vector3::zeros()),
            Marker::node(r, 0),
        ))
        .unwrap_err();
    assert!(err.to_string().contains("bad node"), "{err}");
    let err = model
        .add_joint(Joint::new(
            "self",
            JointKind::Spherical,
            Marker::on(r, Vector3::zeros()),
            Marker::on(r, Vector3::x()),
        ))
        .unwrap_err();
    assert!(err.to_string().contains("self"), "{err}");
    assert!(
        model
            .add_rigid_body(RigidBody::new("massless", 0.0, Matrix3::identity()))
            .is_err()
    );
    let ramp = TimeFunction::SmoothRamp {
        from: 0.0,
        to: 1.0,
        t0: 1.0,
        t1: 1.0,
    };
    let err = model
        .add_joint(Joint::new(
            "ramp",
            JointKind::AngleDriver(ramp),
            Marker::ground(Vector3::zeros()),
            Marker::on(r, Vector3::zeros()),
        ))
        .unwrap_err();
    assert!(err.to_string().contains("t1 > t0"), "{err}");
}

/// A field whose eigenmodes leave out the products of later modes must hold zeros there (the
/// loops skip them): one with nonzero entries is refused, naming the body and why; the same
/// field with those entries zeroed (`without_correction_products`) is taken.
#[test]
fn a_field_with_products_past_its_eigenmodes_is_refused() {
    let beam = Beam::slider_crank_rod(8);
    let full = second_order_field(beam.n_nodes(), 4);
    let body = |g: fem::GeometricStiffness<f64>| {
        FlexibleBody::new("f", beam.modal_body(-0.152, 4, 4, 0.01)).with_geometric_stiffness(g)
    };
    let claimed = fem::GeometricStiffness {
        eigenmodes: 2,
        ..full.clone()
    };
    let err = Model::new().add_flexible_body(body(claimed)).unwrap_err();
    let message = err.to_string();
    assert!(
        message.contains("f") && message.contains("products of modes past its eigenmodes"),
        "{message}"
    );
    let zeroed = full.without_correction_products(2);
    assert_eq!(zeroed.eigenmodes, 2);
    assert!(Model::new().add_flexible_body(body(zeroed)).is_ok());
}
