//! Operating points against closed forms: a pendulum's static equilibrium under a side load
//! and its small-oscillation frequency, a spring-held slider on a spinning arm (the steady
//! radius, the radial frequency softened by the spin, ω² = k/m − Ω²), and the equilibria's
//! design derivatives against the closed forms' and central differences.

use mbs::{
    DesignModel, EquilibriumOptions, Force, Joint, JointId, JointKind, Load, LoadFrame, Marker,
    Model, MultibodySystem, OperatingError, RedundancyPolicy, RigidBody, Spin, TimeFunction,
    equilibrium,
};
use nalgebra::{Matrix3, Vector3};
use sens::{Dual, Scalar};

const G: f64 = 9.81;

/// A rod of mass `m` (1 m) hanging from a pin at the origin, pushed sideways by `side` N at
/// its centre, drawn tilted by `tilt` rad.
fn pendulum<P: Scalar>(m: P, side: f64, tilt: f64) -> (Model<P>, mbs::State) {
    let mut model = Model::new();
    model.gravity = Vector3::new(0.0, -G, 0.0);
    let i = m * (1.0 / 12.0);
    let inertia = Matrix3::from_diagonal(&Vector3::new(m * 1e-4, i, i));
    let rod = model
        .add_rigid_body(RigidBody::new("rod", m, inertia))
        .unwrap();
    model
        .add_joint(Joint::new(
            "pin",
            JointKind::Revolute,
            Marker::ground(Vector3::zeros()),
            Marker::on(rod, Vector3::new(-0.5, 0.0, 0.0)),
        ))
        .unwrap();
    model
        .add_force(Force::PointForce {
            marker: Marker::on(rod, Vector3::zeros()),
            load: Load::Constant(Vector3::new(side, 0.0, 0.0)),
            frame: LoadFrame::Global,
        })
        .unwrap();
    let mut state = model.rest_state();
    // the rod along its body x axis, pointing down from the pin (rotated by −90° + tilt)
    let a = nalgebra::Rotation3::from_axis_angle(
        &Vector3::z_axis(),
        -std::f64::consts::FRAC_PI_2 + tilt,
    );
    let centre = a * Vector3::new(0.5, 0.0, 0.0);
    model.set_pose(&mut state, rod, centre, a.matrix());
    (model, state)
}

/// The operating point of `model` from `state` (assembled first), static or at `spin`.
fn solve(
    model: &Model<f64>,
    mut state: mbs::State,
    spin: Option<Spin>,
) -> Result<mbs::OperatingPoint, OperatingError> {
    let mut sys = MultibodySystem::new(model.clone(), &state, RedundancyPolicy::Remove).unwrap();
    sys.assemble(0.0, &mut state, 1e-12).unwrap();
    let options = EquilibriumOptions::default();
    equilibrium(model, sys.active_rows(), 0.0, &state, spin, &options)
}

#[test]
fn pendulum_hangs_at_the_closed_form_angle_and_swings_at_its_frequency() {
    let (m, side) = (2.0, 5.0);
    let (model, state) = pendulum(m, side, 0.6);
    let op = solve(&model, state, None).unwrap();
    // tan φ = F / (m g): the centre at (½ sin φ, −½ cos φ)
    let phi = (side / (m * G)).atan();
    let (x, y) = (op.state.q[0], op.state.q[1]);
    assert!((x - 0.5 * phi.sin()).abs() < 1e-12, "x = {x}");
    assert!((y + 0.5 * phi.cos()).abs() < 1e-12, "y = {y}");
    // the pin's force balances the weight and the side load
    let lin = op.linearise(&model);
    assert_eq!(lin.dim(), 1, "one independent coordinate");
    let modes = lin.modes().unwrap();
    // small oscillations about the tilted equilibrium: I_pin ω² = ½ √((mg)² + F²)
    let i_pin = m / 12.0 + m * 0.25;
    let omega = (0.5 * ((m * G).powi(2) + side * side).sqrt() / i_pin).sqrt();
    let f = modes[0].frequency_hz() * 2.0 * std::f64::consts::PI;
    assert!(
        (f / omega - 1.0).abs() < 1e-9,
        "ω = {f}, closed form {omega}"
    );
    assert!(modes[0].damping_ratio().abs() < 1e-9);
}

#[test]
fn pendulum_equilibrium_derivative_equals_the_closed_form_and_differences() {
    let (m, side) = (2.0, 5.0);
    let (model, state) = pendulum(m, side, 0.3);
    let op = solve(&model, state, None).unwrap();
    let (dual, _) = pendulum(Dual::<1>::variable(m, 0), side, 0.3);
    let design = DesignModel::new(vec![dual], 1).unwrap();
    let s = op.sensitivities(&design).unwrap();
    // x = ½ sin φ, φ = atan(F/(mg)): dx/dm = ½ cos φ · dφ/dm, dφ/dm = −F g / ((mg)² + F²)
    let phi = (side / (m * G)).atan();
    let dphi = -side * G / ((m * G).powi(2) + side * side);
    let exact = 0.5 * phi.cos() * dphi;
    assert!(
        (s.q[(0, 0)] / exact - 1.0).abs() < 1e-9,
        "{} vs {exact}",
        s.q[(0, 0)]
    );
    let at = |mm: f64| {
        let (model, state) = pendulum(mm, side, 0.3);
        solve(&model, state, None).unwrap().state.q
    };
    let h = 1e-5;
    let (qp, qm) = (at(m + h), at(m - h));
    for i in 0..7 {
        let fd = (qp[i] - qm[i]) / (2.0 * h);
        assert!(
            (s.q[(i, 0)] - fd).abs() < 1e-8,
            "q[{i}]: {} vs {fd}",
            s.q[(i, 0)]
        );
    }
}

/// A hub driven about z at `speed`, a slider of mass `m` in a radial slot (translational
/// joint along the hub's x axis), held by a spring of stiffness `k` and free length `l0` from
/// the axis.
fn spinning_slider<P: Scalar>(
    m: P,
    k: f64,
    l0: f64,
    speed: f64,
) -> (Model<P>, mbs::State, JointId) {
    let mut model = Model::new();
    let one = P::from_f64(1.0);
    let hub = model
        .add_rigid_body(RigidBody::new(
            "hub",
            one,
            Matrix3::<f64>::identity().map(|x| one * x),
        ))
        .unwrap();
    let slider = model
        .add_rigid_body(RigidBody::new(
            "slider",
            m,
            Matrix3::<f64>::identity().map(|x| m * (1e-3 * x)),
        ))
        .unwrap();
    let z = Vector3::z();
    model
        .add_joint(Joint::new(
            "bearing",
            JointKind::Revolute,
            Marker::ground(Vector3::zeros()).with_axis(z),
            Marker::on(hub, Vector3::zeros()).with_axis(z),
        ))
        .unwrap();
    let motor = model
        .add_joint(Joint::new(
            "motor",
            JointKind::AngleDriver(TimeFunction::ConstantSpeed {
                initial: 0.0,
                rate: speed,
            }),
            Marker::ground(Vector3::zeros()).with_axes(Vector3::x(), Vector3::y()),
            Marker::on(hub, Vector3::zeros()).with_axes(Vector3::x(), Vector3::y()),
        ))
        .unwrap();
    model
        .add_joint(Joint::new(
            "slot",
            JointKind::Translational,
            Marker::on(hub, Vector3::zeros()).with_axes(Vector3::y(), Vector3::z()),
            Marker::on(slider, Vector3::zeros()).with_axes(Vector3::y(), Vector3::z()),
        ))
        .unwrap();
    model
        .add_force(Force::SpringDamper {
            a: Marker::on(hub, Vector3::zeros()),
            b: Marker::on(slider, Vector3::zeros()),
            stiffness: k,
            damping: 0.0,
            free_length: l0,
        })
        .unwrap();
    let mut state = model.rest_state();
    model.set_pose(
        &mut state,
        slider,
        Vector3::new(l0, 0.0, 0.0),
        &Matrix3::identity(),
    );
    (model, state, motor)
}

#[test]
fn spinning_slider_settles_at_the_closed_form_radius_and_softens_by_the_spin() {
    let (m, k, l0) = (0.5, 200.0, 0.2);
    for speed in [0.0, 5.0, 12.0, 18.0] {
        let (model, state, motor) = spinning_slider(m, k, l0, speed);
        let spin = Spin::of_driver(&model, motor, speed).unwrap();
        let op = solve(&model, state, Some(spin)).unwrap();
        // k (r − l0) = m Ω² r
        let r = k * l0 / (k - m * speed * speed);
        let slider = 7;
        assert!(
            (op.state.q[slider] - r).abs() < 1e-11,
            "Ω = {speed}: r = {}",
            op.state.q[slider]
        );
        // the slider's velocity is the spin's
        assert!((op.state.v[6 + 1] - speed * r).abs() < 1e-9);
        let lin = op.linearise(&model);
        assert_eq!(lin.dim(), 1);
        let modes = lin.modes().unwrap();
        let omega = (k / m - speed * speed).sqrt();
        let f = modes[0].frequency_hz() * 2.0 * std::f64::consts::PI;
        assert!(
            (f / omega - 1.0).abs() < 1e-9,
            "Ω = {speed}: ω = {f}, closed form {omega}"
        );
    }
}

#[test]
fn spinning_slider_radius_derivative_equals_the_closed_form() {
    let (m, k, l0, speed) = (0.5, 200.0, 0.2, 12.0);
    let (model, state, motor) = spinning_slider(m, k, l0, speed);
    let spin = Spin::of_driver(&model, motor, speed).unwrap();
    let op = solve(&model, state, Some(spin)).unwrap();
    let (dual, _, _) = spinning_slider(Dual::<1>::variable(m, 0), k, l0, speed);
    let s = op
        .sensitivities(&DesignModel::new(vec![dual], 1).unwrap())
        .unwrap();
    // r = k l0 / (k − m Ω²): dr/dm = k l0 Ω² / (k − m Ω²)²
    let exact = k * l0 * speed * speed / (k - m * speed * speed).powi(2);
    assert!(
        (s.q[(7, 0)] / exact - 1.0).abs() < 1e-9,
        "{} vs {exact}",
        s.q[(7, 0)]
    );
    // and the velocity's: v = Ω r
    assert!((s.v[(7, 0)] / (speed * exact) - 1.0).abs() < 1e-9);
}

#[test]
fn a_spin_with_gravity_across_its_axis_is_refused() {
    let (mut model, state, motor) = spinning_slider(0.5, 200.0, 0.2, 5.0);
    model.gravity = Vector3::new(0.0, -G, 0.0);
    let spin = Spin::of_driver(&model, motor, 5.0).unwrap();
    let err = solve(&model, state, Some(spin)).unwrap_err();
    assert!(matches!(err, OperatingError::Spin(_)), "{err}");
    // and a spin about a joint that is not an angle driver
    let bearing = model.joint_of_row(0);
    let err = Spin::of_driver(&model, bearing, 5.0).unwrap_err();
    assert!(err.to_string().contains("not an angle driver"), "{err}");
}

#[test]
fn a_free_mechanism_has_no_equilibrium() {
    // the pendulum without gravity nor load: any angle is an equilibrium
    let (mut model, state) = pendulum(1.0, 0.0, 0.3);
    model.gravity = Vector3::zeros();
    let err = solve(&model, state, None).unwrap_err();
    assert!(matches!(err, OperatingError::Singular { .. }), "{err}");
}

/// The first frequency (rad/s) of an operating point and its derivative with respect to the
/// one design variable of `design`.
fn frequency_and_derivative(
    model: &Model<f64>,
    design: &DesignModel<1>,
    op: &mbs::OperatingPoint,
) -> (f64, f64) {
    let lin = op.linearise(model);
    let modes = lin.modes().unwrap();
    let s = op.sensitivities(design).unwrap();
    let ds = op.eigenvalue_derivatives(&lin, &modes[..1], design, &s);
    let two_pi = 2.0 * std::f64::consts::PI;
    (
        modes[0].frequency_hz() * two_pi,
        modes[0].frequency_derivative(ds[(0, 0)]) * two_pi,
    )
}

#[test]
fn spinning_slider_frequency_derivative_equals_the_closed_form() {
    let (m, k, l0, speed) = (0.5, 200.0, 0.2, 12.0);
    let (model, state, motor) = spinning_slider(m, k, l0, speed);
    let spin = Spin::of_driver(&model, motor, speed).unwrap();
    let op = solve(&model, state, Some(spin)).unwrap();
    let (dual, _, _) = spinning_slider(Dual::<1>::variable(m, 0), k, l0, speed);
    let design = DesignModel::new(vec![dual], 1).unwrap();
    let (omega, d_omega) = frequency_and_derivative(&model, &design, &op);
    // ω = √(k/m − Ω²): dω/dm = −k / (2 m² ω)
    let exact = -k / (2.0 * m * m * omega);
    assert!((d_omega / exact - 1.0).abs() < 1e-8, "{d_omega} vs {exact}");
}

#[test]
fn pendulum_frequency_derivative_through_its_equilibrium_equals_the_closed_form() {
    let (m, side) = (2.0, 5.0);
    let (model, state) = pendulum(m, side, 0.3);
    let op = solve(&model, state, None).unwrap();
    let (dual, _) = pendulum(Dual::<1>::variable(m, 0), side, 0.3);
    let design = DesignModel::new(vec![dual], 1).unwrap();
    let (omega, d_omega) = frequency_and_derivative(&model, &design, &op);
    // ω² = ½ √((mg)² + F²) / (m/3): the mass moves the angle (the pin force) and the inertia
    let w2 = |m: f64| 1.5 * ((m * G).powi(2) + side * side).sqrt() / m;
    let dw2 = 1.5
        * (m * G * G / ((m * G).powi(2) + side * side).sqrt() / m
            - ((m * G).powi(2) + side * side).sqrt() / (m * m));
    assert!((omega * omega / w2(m) - 1.0).abs() < 1e-9);
    let exact = dw2 / (2.0 * omega);
    assert!((d_omega / exact - 1.0).abs() < 1e-8, "{d_omega} vs {exact}");
}
