//! The consistent initial state of `MultibodySystem::assemble`: only the rigid-body coordinates
//! move, the elastic state is the user's, and velocities are projected in the mass metric.
//! Checked against independent physics: the kinetic energy of the rigid mechanism at a dead
//! centre, conservation of momentum by a constraint impulse, and equations that rigid motion
//! cannot satisfy.

mod common;

use common::{CRANK, ROD, slider_crank_framed};
use fem::ModalBody;
use mbs::{
    Body, ConstraintError, DesignModel, FlexibleBody, Joint, JointKind, Marker, Model,
    MultibodySystem, RedundancyPolicy, RigidBody,
};
use nalgebra::{DMatrix, Matrix3, Vector3};
use sens::{Dual, Scalar};

/// The flexible slider-crank at crank angle 0 (a dead centre: the slider is at rest, the rod
/// turns about the wrist pin) starts with rigid-body motion only, whatever node carries the rod's
/// frame: modal coordinates and rates exactly zero, and the kinetic energy that of the rigid
/// mechanism with the rod's mass and inertia, computed here from the crank speed alone.
#[test]
fn slider_crank_starts_with_rigid_motion_only_for_every_frame() {
    let omega = 150.0;
    for node in [0, 3, 5, 10] {
        let (model, mut state, _) = slider_crank_framed(omega, Some((4, node)));
        let mut sys = MultibodySystem::new(model, &state, RedundancyPolicy::Remove).unwrap();
        sys.assemble(0.0, &mut state, 1e-13).unwrap();
        let model = sys.model();
        let ids: Vec<_> = model.body_ids().collect();
        let (crank, rod) = (ids[0], ids[1]);
        let rq = model.q_range(rod);
        let rv = model.v_range(rod);
        assert!(
            state.q[rq.start + 7..rq.end].iter().all(|&w| w == 0.0),
            "node {node}: modal coordinates moved"
        );
        assert!(
            state.v[rv.start + 6..rv.end].iter().all(|&w| w == 0.0),
            "node {node}: modal rates {:?}",
            &state.v[rv.start + 6..rv.end]
        );
        // the rigid mechanism: crank about its pivot, rod about the wrist pin (slider at rest)
        let Body::Rigid(c) = model.body(crank) else {
            panic!("rigid crank")
        };
        let Body::Flexible(f) = model.body(rod) else {
            panic!("flexible rod")
        };
        let i_pivot = c.inertia[(2, 2)] + c.mass * (CRANK / 2.0).powi(2);
        let m = &f.modal;
        let mass: f64 = m.node_masses.iter().sum();
        let xc = m
            .node_positions
            .iter()
            .zip(&m.node_masses)
            .map(|(p, mk)| p.x * mk)
            .sum::<f64>()
            / mass;
        let i_centre: f64 = m
            .node_positions
            .iter()
            .zip(&m.node_masses)
            .zip(&m.node_inertias)
            .map(|((p, mk), mu)| mk * (p.x - xc).powi(2) + mu.z)
            .sum();
        let omega_rod = omega * CRANK / ROD;
        let v_centre = omega * CRANK / 2.0;
        let exact = 0.5 * i_pivot * omega * omega
            + 0.5 * mass * v_centre * v_centre
            + 0.5 * i_centre * omega_rod * omega_rod;
        let ke = model.energy(0.0, &state.q, &state.v).kinetic;
        assert!(
            ((ke - exact) / exact).abs() < 1e-10,
            "node {node}: kinetic energy {ke} vs rigid mechanism {exact}"
        );
        // the rod's frame moves as a point of the rigid rod
        let x_frame = state.q[rq.start];
        let along = (x_frame - CRANK) / ROD;
        let vy = state.v[rv.start + 1];
        assert!(
            (vy - omega * CRANK * (1.0 - along)).abs() < 1e-9 * omega * CRANK,
            "node {node}: frame velocity {vy}"
        );
    }
}

/// Two free rigid bodies joined by a spherical joint, with velocities the joint forbids.
fn impact_pair<S: Scalar>(heavy_mass: S) -> Model<S> {
    let mut model = Model::new();
    let a = model
        .add_rigid_body(RigidBody::new(
            "light",
            S::from_f64(1.0),
            Matrix3::from_diagonal(&Vector3::new(0.01, 0.02, 0.03)).map(S::from_f64),
        ))
        .unwrap();
    let b = model
        .add_rigid_body(RigidBody::new(
            "heavy",
            heavy_mass,
            Matrix3::from_diagonal(&Vector3::new(0.2, 0.1, 0.15)).map(S::from_f64),
        ))
        .unwrap();
    model
        .add_joint(Joint::new(
            "ball",
            JointKind::Spherical,
            Marker::on(a, Vector3::new(0.3, 0.0, 0.0)),
            Marker::on(b, Vector3::new(-0.2, 0.1, 0.0)),
        ))
        .unwrap();
    model
}

/// The pair's poses, and velocities its joint forbids.
fn impact_start(model: &Model<f64>) -> mbs::State {
    let mut state = model.rest_state();
    let ids: Vec<_> = model.body_ids().collect();
    let id = Matrix3::identity();
    model.set_pose(&mut state, ids[0], Vector3::zeros(), &id);
    model.set_pose(&mut state, ids[1], Vector3::new(0.5, -0.1, 0.0), &id);
    model.set_velocity(
        &mut state,
        ids[0],
        Vector3::new(1.0, -2.0, 0.5),
        Vector3::new(0.3, 0.0, 2.0),
    );
    model.set_velocity(
        &mut state,
        ids[1],
        Vector3::new(-0.5, 1.0, 0.0),
        Vector3::new(0.0, -1.0, 0.4),
    );
    state
}

/// The initial sensitivities differentiate the mass-metric projection exactly, the metric's
/// own dependence on the design included: the heavy body's mass is the design variable, and
/// the velocities after the projection (a plastic impact) depend on it.
#[test]
fn initial_sensitivities_differentiate_the_mass_metric() {
    let m = 5.0;
    let design = DesignModel::new(vec![impact_pair(Dual::<1>::new(m, [1.0]))], 1).unwrap();
    let plain = design.values();
    let mut state = impact_start(&plain);
    let mut sys = MultibodySystem::new(plain, &state, RedundancyPolicy::Remove).unwrap();
    sys.assemble(0.0, &mut state, 1e-14).unwrap();
    let s0 = mbs::initial_sensitivities(&sys, &design, 0.0, &state).unwrap();
    let assembled = |mm: f64| {
        let model = impact_pair(mm);
        let mut st = impact_start(&model);
        let mut p = MultibodySystem::new(model, &st, RedundancyPolicy::Remove).unwrap();
        p.assemble(0.0, &mut st, 1e-15).unwrap();
        st.to_vec()
    };
    let d = 1e-4;
    let (yp, ym) = (assembled(m + d), assembled(m - d));
    let fd: Vec<f64> = yp
        .iter()
        .zip(&ym)
        .map(|(a, c)| (a - c) / (2.0 * d))
        .collect();
    let scale = fd.iter().fold(0.0f64, |a, x| a.max(x.abs()));
    let err = fd
        .iter()
        .zip(s0.column(0).iter())
        .fold(0.0f64, |a, (x, y)| a.max((x - y).abs()));
    eprintln!("mass-metric projection: max |S0 − FD| {err:.2e}, max |FD| {scale:.2e}");
    assert!(
        scale > 1e-2,
        "the projection must depend on the mass: {scale:e}"
    );
    assert!(err < 1e-8 * scale, "{err:e}");
}

/// Two free rigid bodies of unequal mass, given velocities that a spherical joint between them
/// forbids: the projection is the impulse of the joint's reaction, so linear momentum and the
/// angular momentum about the joint are unchanged and kinetic energy is lost (a plastic
/// impact). A Euclidean projection would create momentum.
#[test]
fn velocity_projection_is_a_constraint_impulse() {
    let model = impact_pair(5.0);
    let mut state = impact_start(&model);
    let (a, b) = (mbs::BodyId::from(0), mbs::BodyId::from(1));
    let momentum = |m: &Model<f64>, s: &mbs::State| {
        // linear momentum and angular momentum about the joint point (0.3, 0, 0)
        let p0 = Vector3::new(0.3, 0.0, 0.0);
        let mut p = Vector3::zeros();
        let mut h = Vector3::zeros();
        for (id, mass, inertia) in [
            (a, 1.0, Vector3::new(0.01, 0.02, 0.03)),
            (b, 5.0, Vector3::new(0.2, 0.1, 0.15)),
        ] {
            let q = m.q_range(id).start;
            let v = m.v_range(id).start;
            let r = Vector3::new(s.q[q], s.q[q + 1], s.q[q + 2]);
            let rd = Vector3::new(s.v[v], s.v[v + 1], s.v[v + 2]);
            let w = Vector3::new(s.v[v + 3], s.v[v + 4], s.v[v + 5]);
            let rot = m.rotation_of(id, &s.q);
            p += rd * mass;
            h += (r - p0).cross(&(rd * mass)) + rot * inertia.component_mul(&w);
        }
        (p, h)
    };
    let (p0, h0) = momentum(&model, &state);
    let e0 = model.energy(0.0, &state.q, &state.v).kinetic;
    let mut sys = MultibodySystem::new(model, &state, RedundancyPolicy::Remove).unwrap();
    sys.assemble(0.0, &mut state, 1e-13).unwrap();
    let model = sys.model();
    let (p1, h1) = momentum(model, &state);
    let e1 = model.energy(0.0, &state.q, &state.v).kinetic;
    let c = model.constraints(0.0, &state.q, &state.v);
    assert!(c.phi_dot.iter().all(|x| x.abs() < 1e-12), "{:?}", c.phi_dot);
    assert!((p1 - p0).norm() < 1e-12 * p0.norm(), "{p0} → {p1}");
    assert!((h1 - h0).norm() < 1e-12 * h0.norm(), "{h0} → {h1}");
    assert!(e1 < e0, "a plastic impact loses energy: {e0} → {e1}");
}

/// A bar held at both ends by ground spherical joints, given an initial stretch (an axial
/// mode's coordinate) or stretch rate: no rigid motion can meet the joints, and the error names
/// a joint, its bodies and the quantity, instead of moving the modes back.
#[test]
fn an_elastic_state_the_joints_forbid_is_an_error_that_names_the_joint() {
    let mut modes = DMatrix::zeros(12, 1);
    modes[(6, 0)] = 1.0; // node 1 moves along the bar
    let modal = ModalBody {
        node_positions: vec![Vector3::new(-0.5, 0.0, 0.0), Vector3::new(0.5, 0.0, 0.0)],
        node_masses: vec![1.0, 1.0],
        node_inertias: vec![Vector3::new(1e-3, 1e-3, 1e-3); 2],
        modes,
        eigenvalues: vec![1e4],
        modal_damping: vec![0.0],
        stiffness_matrix: None,
        damping_matrix: None,
    };
    let mut model = Model::new();
    let bar = model
        .add_flexible_body(FlexibleBody::new("bar", modal))
        .unwrap();
    for (name, node, x) in [("left", 0, -0.5), ("right", 1, 0.5)] {
        model
            .add_joint(Joint::new(
                name,
                JointKind::Spherical,
                Marker::ground(Vector3::new(x, 0.0, 0.0)),
                Marker::node(bar, node),
            ))
            .unwrap();
    }
    let cases = [([0.01], [0.0], "Φ"), ([0.0], [0.5], "Φ̇")];
    for (w, wd, quantity) in cases {
        let mut state = model.rest_state();
        model.set_modal(&mut state, bar, &w, &wd);
        let mut sys =
            MultibodySystem::new(model.clone(), &state, RedundancyPolicy::Remove).unwrap();
        let err = sys.assemble(0.0, &mut state, 1e-12).unwrap_err();
        match &err {
            ConstraintError::Inconsistent {
                joint,
                bodies,
                quantity: q,
                residual,
                ..
            } => {
                assert!(joint == "left" || joint == "right", "{err}");
                assert!(
                    bodies.contains("`bar`") && bodies.contains("ground"),
                    "{err}"
                );
                assert_eq!(*q, quantity);
                assert!(*residual > 1e-3, "{err}");
            }
            other => panic!("expected Inconsistent, got {other:?}"),
        }
        let text = err.to_string();
        assert!(text.contains("stated elastic state"), "{text}");
    }
    // a rigid-compatible elastic state (a uniform translation of both nodes) is accepted and
    // kept: the frame moves instead
    let mut modes = DMatrix::zeros(12, 1);
    modes[(1, 0)] = 1.0;
    modes[(7, 0)] = 1.0;
    let Body::Flexible(f) = model.body(bar) else {
        panic!("flexible")
    };
    let mut m2 = Model::new();
    let bar2 = m2
        .add_flexible_body(FlexibleBody::new(
            "bar",
            ModalBody {
                modes,
                ..f.modal.clone()
            },
        ))
        .unwrap();
    for (name, node, x) in [("left", 0, -0.5), ("right", 1, 0.5)] {
        m2.add_joint(Joint::new(
            name,
            JointKind::Spherical,
            Marker::ground(Vector3::new(x, 0.0, 0.0)),
            Marker::node(bar2, node),
        ))
        .unwrap();
    }
    let mut state = m2.rest_state();
    m2.set_modal(&mut state, bar2, &[0.02], &[0.3]);
    let mut sys = MultibodySystem::new(m2, &state, RedundancyPolicy::Remove).unwrap();
    sys.assemble(0.0, &mut state, 1e-13).unwrap();
    let q = sys.model().q_range(bar2);
    let v = sys.model().v_range(bar2);
    assert_eq!(state.q[q.start + 7], 0.02);
    assert_eq!(state.v[v.start + 6], 0.3);
    assert!(
        (state.q[q.start + 1] + 0.02).abs() < 1e-12,
        "frame y {}",
        state.q[q.start + 1]
    );
    assert!(
        (state.v[v.start + 1] + 0.3).abs() < 1e-12,
        "frame ẏ {}",
        state.v[v.start + 1]
    );
}

/// The adjoint takes the initial state's adjoint back through the same projection by reverse
/// mode: on the impact pair (the heavy body's mass the variable, which moves the projected
/// velocities), the gradients of the final value and of the integral of velocity components
/// equal the direct method's (the forward `S_0`) to 1e-9, with no initial sensitivities read.
#[test]
fn the_adjoint_takes_the_initial_state_back_through_the_projection() {
    use mbs::{
        BdfOptions, Objective, ObjectiveTerm, Response, SensitivityOptions, adjoint_sweep,
        response_history, simulate_sensitivities,
    };
    let design = DesignModel::new(vec![impact_pair(Dual::<1>::new(5.0, [1.0]))], 1).unwrap();
    let plain = design.values();
    let mut state = impact_start(&plain);
    let mut sys = MultibodySystem::new(plain, &state, RedundancyPolicy::Remove).unwrap();
    sys.assemble(0.0, &mut state, 1e-14).unwrap();
    let opts = BdfOptions::adaptive(1e-8, 1e-10);
    let direct = SensitivityOptions::default();
    let run = simulate_sensitivities(&mut sys, &design, &state, 0.0, 0.2, opts, &direct).unwrap();
    let nq = sys.model().n_q();
    let chunk = &design.chunks()[0];
    for k in [nq, nq + 1, nq + 5, nq + 8] {
        let response = Response::State(k);
        let h = response_history(&sys, &design, &run, &response).unwrap();
        for objective in [Objective::Final, Objective::Integral] {
            let d = objective.evaluate(&h.times, &h.values, Some(&h.gradients));
            let expected = d.unwrap().gradient[0];
            let weights = objective.weights(&h.times, &h.values).unwrap();
            let terms = [vec![ObjectiveTerm {
                response: response.clone(),
                times: h.times.clone(),
                weights: weights.weights,
            }]];
            let sweep = adjoint_sweep(&mut sys, chunk, &mut &run, &terms).unwrap();
            assert!(!sweep.needs_initial_sensitivities());
            let zero = DMatrix::zeros(run.states[0].len(), 1);
            let g = sweep.gradients(chunk, &zero)[0][0];
            assert!(
                expected.abs() > 1e-6 && (g - expected).abs() < 1e-9 * expected.abs(),
                "v[{}] {objective:?}: adjoint {g} vs direct {expected}",
                k - nq
            );
        }
    }
}
