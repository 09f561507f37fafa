//! Operating points against closed forms: a pendulum's static equilibrium under a side load
//! and its small-oscillation frequency, a spring-held slider on a spinning arm (the steady
//! radius, the radial frequency softened by the spin, ω² = k/m − Ω²), and the equilibria's
//! design derivatives against the closed forms' and central differences. The linearisation
//! about states of a run: a swinging pendulum against its angle equation, a steadily spinning
//! slider and a driven flexible beam against their steady spins, a free spinning top against
//! its nutation frequency in the body frame.

use mbs::{
    BdfOptions, DesignModel, EquilibriumOptions, Force, Joint, JointId, JointKind, Load, LoadFrame,
    Marker, Model, MultibodySystem, OperatingError, RedundancyPolicy, RigidBody, Spin,
    TimeFunction, equilibrium, linearise_state, simulate,
};
use nalgebra::{Matrix3, Vector3};

mod common;
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
    let motion = TimeFunction::ConstantSpeed {
        initial: 0.0,
        rate: speed,
    };
    let motor = common::drive_about_z(&mut model, hub, motion);
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

/// The linearisation about states of a run, each the state of `sys` at an output time.
fn run_and_linearise(
    sys: &mut MultibodySystem,
    state: &mbs::State,
    times: &[f64],
) -> Vec<mbs::StateLinearisation> {
    let sim = simulate(sys, state, times, BdfOptions::adaptive(1e-10, 1e-12)).unwrap();
    (sim.outputs.iter())
        .map(|o| {
            let s = mbs::State {
                q: o.q.clone(),
                v: o.v.clone(),
            };
            linearise_state(sys, o.t, &s).unwrap()
        })
        .collect()
}

#[test]
fn a_swinging_pendulum_linearises_to_its_angle_equation_whatever_its_speed() {
    let (m, side) = (2.0, 5.0);
    let (model, mut state) = pendulum(m, side, 0.3);
    let rod = model.body_ids().next().unwrap();
    // swinging hard: through 3 rad/s at the start, past the horizontal
    let w = 6.0;
    let a = model.rotation_of(rod, &state.q);
    let centre = Vector3::new(state.q[0], state.q[1], 0.0);
    model.set_velocity(
        &mut state,
        rod,
        Vector3::z().cross(&centre) * w,
        Vector3::z() * w,
    );
    let mut sys = MultibodySystem::new(model.clone(), &state, RedundancyPolicy::Remove).unwrap();
    sys.assemble(0.0, &mut state, 1e-12).unwrap();
    assert!((a - model.rotation_of(rod, &state.q)).amax() < 1e-12);
    let times: Vec<f64> = (0..=12).map(|i| 0.1 * i as f64).collect();
    let i_pin = m / 12.0 + m * 0.25;
    let mut fastest: f64 = 0.0;
    let mut beyond_horizontal = false;
    for lin in run_and_linearise(&mut sys, &state, &times) {
        assert_eq!(
            lin.independent,
            vec![5],
            "the angle about the pin is the coordinate"
        );
        let (x, y) = (lin.state.q[0], lin.state.q[1]);
        let theta = x.atan2(-y);
        fastest = fastest.max(lin.state.v[5].abs());
        beyond_horizontal |= theta.cos() < 0.0;
        // I θ̈ = −½ m g sin θ + ½ F cos θ
        let exact = -0.5 * (m * G * theta.cos() + side * theta.sin()) / i_pin;
        let s = lin.linearisation.modes().unwrap()[0].eigenvalue;
        let s2 = (s * s).re;
        assert!(
            (s2 - exact).abs() < 1e-9 * exact.abs().max(1.0),
            "θ = {theta}: s² = {s2}, closed form {exact}"
        );
    }
    assert!(fastest > 5.0 && beyond_horizontal, "ω up to {fastest}");
}

#[test]
fn a_steadily_spinning_slider_linearises_as_its_steady_spin_at_any_time_of_its_run() {
    let (m, k, l0, speed) = (0.5, 200.0, 0.2, 12.0);
    let (model, state, motor) = spinning_slider(m, k, l0, speed);
    let spin = Spin::of_driver(&model, motor, speed).unwrap();
    let op = solve(&model, state, Some(spin)).unwrap();
    let steady = op.linearise(&model).modes().unwrap();
    // ω² = k/m − Ω² along the slot
    let omega = (k / m - speed * speed).sqrt();
    assert!((steady[0].eigenvalue.im / omega - 1.0).abs() < 1e-9);
    let mut sys = MultibodySystem::new(model.clone(), &op.state, RedundancyPolicy::Remove).unwrap();
    let mut start = op.state.clone();
    sys.assemble(0.0, &mut start, 1e-12).unwrap();
    // the run stays on the steady spin: every time point linearises to it
    for lin in run_and_linearise(&mut sys, &start, &[0.0, 0.13, 0.4]) {
        let modes = lin.linearisation.modes().unwrap();
        assert_eq!(modes.len(), 1, "one coordinate: the slider along its slot");
        let s = modes[0].eigenvalue;
        assert!(
            (s.im / omega - 1.0).abs() < 1e-7 && s.re.abs() < 1e-7 * omega,
            "s = {s}, steady spin {omega}"
        );
    }
}

/// A uniform beam along x (`EI = m = L = 1` flapwise, chordwise 4× stiffer), clamped to a hub
/// turned about z at `speed` by an angle driver; the modes of both planes, stiffened.
fn driven_beam(speed: f64) -> (Model<f64>, mbs::State, JointId) {
    let mut model = Model::new();
    let beam = model
        .add_flexible_body(common::fem_cantilever(16, 6, [1.0, 4.0], true))
        .unwrap();
    let motion = TimeFunction::ConstantSpeed {
        initial: 0.0,
        rate: speed,
    };
    let motor = common::drive_about_z(&mut model, beam, motion);
    let state = model.rest_state();
    (model, state, motor)
}

#[test]
fn a_driven_flexible_beam_linearises_at_a_time_of_its_run_as_its_steady_spin() {
    let speed = 3.0;
    let (model, state, motor) = driven_beam(speed);
    let spin = Spin::of_driver(&model, motor, speed).unwrap();
    let op = solve(&model, state, Some(spin)).unwrap();
    let steady = op.linearise(&model).modes().unwrap();
    // the published first flapwise frequency at Ω̄ = 3 (Wright et al. 1982)
    assert!((steady[0].frequency_hz() * 2.0 * std::f64::consts::PI / 4.7973 - 1.0).abs() < 1e-3);
    let mut sys = MultibodySystem::new(model.clone(), &op.state, RedundancyPolicy::Remove).unwrap();
    let mut start = op.state.clone();
    sys.assemble(0.0, &mut start, 1e-12).unwrap();
    for lin in run_and_linearise(&mut sys, &start, &[0.0, 0.7]) {
        assert_eq!(lin.independent.len(), 6, "the modal coordinates");
        let modes = lin.linearisation.modes().unwrap();
        assert_eq!(modes.len(), steady.len());
        for (a, b) in modes.iter().zip(&steady) {
            let rel = (a.eigenvalue - b.eigenvalue).norm() / b.eigenvalue.norm();
            assert!(rel < 1e-7, "{} vs steady {}", a.eigenvalue, b.eigenvalue);
        }
    }
}

#[test]
fn a_free_spinning_top_shows_its_nutation_and_the_turning_of_space_in_its_frame() {
    // axisymmetric, C = 1.8 A, spinning about its axis at Ω, no gravity
    let (a, c, spin) = (2.0, 3.6, 7.0);
    let mut model = Model::new();
    let top = model
        .add_rigid_body(RigidBody::new(
            "top",
            1.0,
            Matrix3::from_diagonal(&Vector3::new(a, a, c)),
        ))
        .unwrap();
    let mut state = model.rest_state();
    model.set_velocity(&mut state, top, Vector3::zeros(), Vector3::z() * spin);
    let mut sys = MultibodySystem::new(model.clone(), &state, RedundancyPolicy::Remove).unwrap();
    for lin in run_and_linearise(&mut sys, &state, &[0.0, 0.3]) {
        assert_eq!(lin.independent.len(), 6);
        let mut f: Vec<f64> = (lin.linearisation.modes().unwrap().iter())
            .map(|m| m.eigenvalue.norm())
            .filter(|&s| s > 1e-6 * spin)
            .collect();
        f.sort_by(f64::total_cmp);
        // the nutation (C − A)/A Ω in the body frame; a fixed tilt and the translations seen
        // from the body turning at Ω (the translations' pair defective)
        let expected = [(c - a) / a * spin, spin, spin, spin];
        assert_eq!(f.len(), 4, "{f:?}");
        for (x, e) in f.iter().zip(expected) {
            assert!((x / e - 1.0).abs() < 1e-6, "{f:?} against {expected:?}");
        }
    }
}
