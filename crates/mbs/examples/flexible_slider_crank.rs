//! The paper's §5.1 slider-crank built in Rust, without a deck: a rigid crank driven at
//! 150 rad/s, a connecting rod of composite tube (four plies at a common angle θ) reduced to
//! four planar modes, and a slider. The whole chain from the ply angle up is one code path:
//! `section` gives the tube's stiffness and its derivative, `fem::design_bodies` the rod's dual
//! modal body, and `mbs` integrates the motion with its direct sensitivities. The sensitivity
//! of the rod's mid-node deflection is checked against central differences of two more runs on
//! the same steps.
//!
//! Run: `cargo run --release -p mbs --example flexible_slider_crank`

use fem::{
    BeamSection, Mesh, ModalBody, ModalOptions, ModeUpdate, Properties, RayleighDamping,
    design_bodies, modal_analysis, modal_body,
};
use laminate::OrthotropicMaterial;
use mbs::{
    BdfOptions, DesignModel, FlexibleBody, Joint, JointKind, Marker, Model, MultibodySystem,
    RedundancyPolicy, Response, RigidBody, SensitivityOptions, State, TimeFunction,
    response_history, simulate_sensitivities,
};
use nalgebra::{Matrix3, Vector3};
use section::{DesignMap, PlySpec};
use sens::{Dual, Scalar};

const CRANK: f64 = 0.152;
const ROD: f64 = 0.304;
const OMEGA: f64 = 150.0;
const ELEMENTS: usize = 8;
const T_END: f64 = 0.005;

/// The rod's section and its derivatives with respect to the common ply angle (per degree).
fn tube(theta: f64) -> section::SectionSensitivities {
    let cfrp = OrthotropicMaterial::new([128e9, 10.1e9, 10.1e9], [5.36e9; 3], [0.23; 3], 1586.0)
        .expect("a valid material");
    let plies: Vec<PlySpec> = (0..4)
        .map(|i| PlySpec::new(format!("ply{i}"), cfrp, theta.to_radians(), 0.25e-3, 1))
        .collect();
    let mesh = section::tube(4.529e-3, &plies, 24).expect("a valid tube");
    let per_degree = std::f64::consts::PI / 180.0;
    let design = DesignMap::new().with_variable("theta", (0..4).map(|r| (r, per_degree)).collect());
    section::analyse_with_derivatives::<1>(&mesh, &design).expect("the section analysis")
}

/// The rod: `ELEMENTS` Timoshenko beam elements, clamped at its centre node, four modes in the
/// mechanism plane, damped 1 % at mode 1 and 3 % at mode 4. Its nominal body and its dual body.
fn rod(theta: f64) -> (ModalBody<f64>, ModalBody<Dual<1>>) {
    let sens = tube(theta);
    let mesh = Mesh::straight_beam(
        Vector3::zeros(),
        Vector3::new(ROD, 0.0, 0.0),
        ELEMENTS,
        0,
        Vector3::y(),
    )
    .expect("a valid mesh");
    let props = Properties {
        sections: vec![BeamSection::from_section(&sens.properties)],
        laminates: vec![],
    };
    let options = ModalOptions {
        planar: Some(Vector3::z()),
        damping: Some(
            RayleighDamping {
                modes: [0, 3],
                ratios: [0.01, 0.03],
            }
            .into(),
        ),
        ..ModalOptions::new(4)
    };
    let analysis = modal_analysis(&mesh, &props, &options).expect("the modal analysis");
    let body = modal_body(&mesh, &props, &analysis).expect("the modal body");
    let dual = design_bodies::<1, _>(
        &mesh,
        &props,
        &analysis,
        &[theta],
        |b| Properties {
            sections: vec![BeamSection::from_sensitivities(&sens, b)],
            laminates: vec![],
        },
        ModeUpdate::Updated,
    )
    .expect("the design bodies");
    (body, dual.chunks.into_iter().next().expect("one chunk"))
}

/// The mechanism around a rod body, on any scalar, and its state at crank angle 0 (the rigid
/// mechanism's velocities; the rod undeformed).
fn mechanism<P: Scalar>(rod: ModalBody<P>) -> (Model<P>, State, Response) {
    let mut model = Model::new();
    let c = |x: f64| P::from_f64(x);
    let crank = model
        .add_rigid_body(RigidBody::new(
            "crank",
            c(0.038),
            Matrix3::from_diagonal(&Vector3::new(1e-7, 7.32e-5, 7.32e-5)).map(c),
        ))
        .expect("the crank");
    let rod = model
        .add_flexible_body(FlexibleBody::new("rod", rod))
        .expect("the rod");
    let slider = model
        .add_rigid_body(RigidBody::new(
            "slider",
            c(0.038),
            Matrix3::identity().map(|x: f64| c(1e-6 * x)),
        ))
        .expect("the slider");
    let pivot = Vector3::new(-CRANK / 2.0, 0.0, 0.0);
    for joint in [
        Joint::new(
            "crank pivot",
            JointKind::Revolute,
            Marker::ground(Vector3::zeros()),
            Marker::on(crank, pivot),
        ),
        Joint::new(
            "crank drive",
            JointKind::AngleDriver(TimeFunction::ConstantSpeed {
                initial: 0.0,
                rate: OMEGA,
            }),
            Marker::ground(Vector3::zeros()),
            Marker::on(crank, pivot),
        ),
        Joint::new(
            "crank pin",
            JointKind::Revolute,
            Marker::on(crank, -pivot),
            Marker::node(rod, 0),
        ),
        Joint::new(
            "wrist pin",
            JointKind::Revolute,
            Marker::node(rod, ELEMENTS),
            Marker::on(slider, Vector3::zeros()),
        ),
        Joint::new(
            "slide",
            JointKind::Translational,
            Marker::ground(Vector3::zeros()).with_axis(Vector3::x()),
            Marker::on(slider, Vector3::zeros()).with_axis(Vector3::x()),
        ),
    ] {
        model.add_joint(joint).expect("a joint");
    }
    let mut state = model.rest_state();
    let id = Matrix3::identity();
    model.set_pose(&mut state, crank, -pivot, &id);
    model.set_pose(
        &mut state,
        rod,
        Vector3::new(CRANK + ROD / 2.0, 0.0, 0.0),
        &id,
    );
    model.set_pose(&mut state, slider, Vector3::new(CRANK + ROD, 0.0, 0.0), &id);
    let tip = Vector3::new(0.0, OMEGA * CRANK / 2.0, 0.0);
    model.set_velocity(&mut state, crank, tip, Vector3::new(0.0, 0.0, OMEGA));
    model.set_velocity(
        &mut state,
        rod,
        tip,
        Vector3::new(0.0, 0.0, -OMEGA * CRANK / ROD),
    );
    let deflection = Response::MidNodeDeflection {
        body: rod,
        first: 0,
        mid: ELEMENTS / 2,
        last: ELEMENTS,
        normal: Vector3::z(),
    };
    (model, state, deflection)
}

/// The assembled system of a model from `state` (redundant equations removed).
fn assembled(model: Model<f64>, mut state: State) -> (MultibodySystem, State) {
    let mut sys =
        MultibodySystem::new(model, &state, RedundancyPolicy::Remove).expect("a valid system");
    sys.assemble(0.0, &mut state, 1e-13).expect("the assembly");
    (sys, state)
}

pub fn main() {
    let theta = 15.0;
    let (_, dual) = rod(theta);
    let (model, state, deflection) = mechanism(dual);
    let design = DesignModel::new(vec![model], 1).expect("a design model");
    let (mut sys, state) = assembled(design.values(), state);
    let run = simulate_sensitivities(
        &mut sys,
        &design,
        &state,
        0.0,
        T_END,
        BdfOptions::adaptive(1e-6, 1e-9),
        &SensitivityOptions::default(),
    )
    .expect("the run with sensitivities");
    let history = response_history(&sys, &design, &run, &deflection).expect("the response");
    // central differences of two more runs on the nominal steps, Newton converged tightly
    let replay = run.replay_options(1e-6, &[1e-9], 1e-7);
    let step = 1e-3;
    let at = |t: f64| {
        let (body, _) = rod(t);
        let (model, state, deflection) = mechanism(body);
        let (mut sys, state) = assembled(model, state);
        mbs::simulate_response(&mut sys, &state, &run.times, replay.clone(), &deflection)
            .expect("a perturbed run")
    };
    let (plus, minus) = (at(theta + step), at(theta - step));
    let largest = history.gradients.amax();
    let mut worst = 0.0f64;
    for i in 0..run.times.len() {
        let fd = (plus[i] - minus[i]) / (2.0 * step);
        worst = worst.max((history.gradients[(i, 0)] - fd).abs() / largest);
    }
    let peak = history.values.iter().fold(0.0f64, |a, x| a.max(x.abs()));
    println!(
        "{} steps to {T_END} s: peak mid-node deflection {peak:.4e} (of the rod's length), \
         largest d/dθ {largest:.4e} per degree; against central differences {worst:.1e}",
        run.statistics.steps
    );
    assert!(
        worst < 1e-5,
        "sensitivities against central differences: {worst:e}"
    );
}
