//! Shared fixtures of the cross-crate tests: models built through the whole chain
//! laminate → section → fem → mbs.
//!
//! # The flexible slider-crank with a composite tube rod (paper §5.1, docs/design.md §4)
//! Crank 0.152 m driven at a constant 150 rad/s about the global z-axis, connecting rod
//! 0.304 m, slider on the x-axis through the crank axis; the mechanism starts at crank angle 0
//! (crank and rod along +x). The rod is a tube of four 0.25 mm plies of the paper's composite
//! (E1 = 128 GPa, E2 = E3 = 10.1 GPa, G = 5.36 GPa, ν = 0.23, ρ = 1586 kg/m³) with inner
//! radius 4.529 mm (area 3.16e-5 m²), analysed by `section`, meshed with an even number of
//! `fem` Timoshenko beam elements, reduced to four modes clamped at the centre node (the
//! centre of mass), and joined to crank and slider at its end nodes.
//!
//! Choices where the paper is silent: crank 0.38 kg (rigid, slender), slider 0.1 kg, no
//! gravity, initial velocities those of the rigid mechanism with `ẇ = 0` (consistent, so the
//! assembly leaves them unchanged and the initial state does not depend on the design).
//!
//! Modes: the paper's model is planar, so by default the rod's modes are those of motion in the
//! mechanism plane xy (`fem::ModalOptions::planar = Some(z)`, [`RodOptions::planar`]). With
//! 3-D modes the rod's out-of-plane modes make the slide's roll equation independent away from
//! the dead centres, and [`RedundancyPolicy::Remove`] (rows chosen at the assembly, crank angle
//! 0) would leave the slider rolling freely; with planar modes that row is dependent in every
//! configuration and `Remove` is right. The restriction also suppresses the bending–twist
//! coupling of off-axis plies and stiffens the rod (15° lay-up, measured 2026-11-21: planar
//! modes 582, 582, 3056, 3056 Hz; 3-D modes 480.5 Hz ×4, then 2621 Hz).
//!
//! Damping (planar modes): clamped at its centre the rod is two cantilevers, so the modes come
//! in pairs of equal frequencies (the two halves); the paper's Rayleigh damping, 1 % at mode 1
//! and 3 % at mode 4 (zero-based 0 and 3, different frequencies), is fitted by `fem` from the
//! retained modes (with their eigenvalue derivatives for the design models). With 3-D modes
//! (`planar: false`) the four lowest modes share one frequency (first bending of each half in
//! each plane); the damping is then fitted at modes 1 and 5 (the next frequency, a guard mode
//! of the analysis when four are retained, with its eigenvalue derivative) and applied to the
//! retained modes.
//!
//! Design variables are ply angles in **degrees**: either one common angle of all plies
//! ([`Design::Common`], the paper's variable) or one per ply ([`Design::PerPly`]).

// Independent co-rotational finite-element reference of the flexible slider-crank (module doc).
#[path = "reference/corotational.rs"]
pub mod corotational;

use fem::{
    BeamSection, Mesh, ModalAnalysis, ModalBody, ModalOptions, ModeUpdate, Properties,
    RayleighDamping, design_bodies, modal_analysis, modal_body,
};
use laminate::OrthotropicMaterial;
use mbs::{
    BodyId, DesignModel, FlexibleBody, Joint, JointId, JointKind, Marker, Model, MultibodySystem,
    RedundancyPolicy, Response, RigidBody, State, TimeFunction,
};
use nalgebra::{Matrix3, Vector3};
use section::{DesignMap, PlySpec, SectionMesh, SectionSensitivities};
use sens::{Dual, Scalar, chunk_ranges};

pub const CRANK: f64 = 0.152;
pub const ROD: f64 = 0.304;
pub const OMEGA: f64 = 150.0;
/// Total wall thickness (four 0.25 mm plies in the paper's lay-up; a lay-up of `n` plies has
/// plies of `WALL / n`, the same area).
pub const WALL: f64 = 1.0e-3;
pub const INNER_RADIUS: f64 = 4.529e-3;
pub const CRANK_MASS: f64 = 0.38;
pub const SLIDER_MASS: f64 = 0.1;

/// The paper's composite.
pub fn composite() -> OrthotropicMaterial {
    let g = 5.36e9;
    OrthotropicMaterial::new([128e9, 10.1e9, 10.1e9], [g, g, g], [0.23; 3], 1586.0)
        .expect("valid material")
}

/// The tube section with the given ply angles (degrees, innermost first), each ply
/// `WALL / angles_deg.len()` thick.
pub fn tube_section(angles_deg: &[f64]) -> SectionMesh {
    let thickness = WALL / angles_deg.len() as f64;
    let plies: Vec<PlySpec> = angles_deg
        .iter()
        .enumerate()
        .map(|(i, a)| PlySpec::new(format!("ply{i}"), composite(), a.to_radians(), thickness, 1))
        .collect();
    section::tube(INNER_RADIUS, &plies, 24).expect("valid tube")
}

/// What the design variables are.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Design {
    /// One variable: the common angle of all plies (all plies must start at that angle).
    Common,
    /// One variable per ply.
    PerPly,
    /// One variable for each of the first `n` plies (the others fixed).
    FirstPlies(usize),
}

impl Design {
    /// The design map (variables in degrees).
    pub fn map(self, mesh: &SectionMesh) -> DesignMap {
        let deg = std::f64::consts::PI / 180.0;
        match self {
            Design::Common => DesignMap::new()
                .with_variable("angle", (0..mesh.regions.len()).map(|r| (r, deg)).collect()),
            Design::PerPly => (0..mesh.regions.len()).fold(DesignMap::new(), |m, r| {
                m.with_variable(format!("ply{r}"), vec![(r, deg)])
            }),
            Design::FirstPlies(n) => (0..n).fold(DesignMap::new(), |m, r| {
                m.with_variable(format!("ply{r}"), vec![(r, deg)])
            }),
        }
    }

    /// The design vector of a lay-up.
    pub fn values(self, angles_deg: &[f64]) -> Vec<f64> {
        match self {
            Design::Common => vec![angles_deg[0]],
            Design::PerPly => angles_deg.to_vec(),
            Design::FirstPlies(n) => angles_deg[..n].to_vec(),
        }
    }

    /// The lay-up of a design vector, the plies not in the design taken from `base`.
    pub fn layup(self, b: &[f64], base: &[f64]) -> Vec<f64> {
        match self {
            Design::Common => vec![b[0]; base.len()],
            Design::PerPly | Design::FirstPlies(_) => {
                let mut l = base.to_vec();
                l[..b.len()].copy_from_slice(b);
                l
            }
        }
    }
}

/// Settings of the rod model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RodOptions {
    /// Beam elements (even: the centre node is the reference node).
    pub elements: usize,
    pub modes: usize,
    pub update: ModeUpdate,
    /// Modes of motion in the mechanism plane xy only (the paper's planar model, the default);
    /// `false`: 3-D modes (out-of-plane bending too).
    pub planar: bool,
}

impl Default for RodOptions {
    fn default() -> Self {
        Self {
            elements: 8,
            modes: 4,
            update: ModeUpdate::Updated,
            planar: true,
        }
    }
}

/// Bodies of the mechanism and the rod's nodes.
#[derive(Clone, Copy, Debug)]
pub struct Ids {
    pub crank: BodyId,
    pub rod: BodyId,
    pub slider: BodyId,
    pub rod_first: usize,
    pub rod_mid: usize,
    pub rod_last: usize,
    /// The revolute joint between the rod's last node (marker a) and the slider (marker b).
    pub wrist_pin: JointId,
}

impl Ids {
    /// The normalised mid-node deflection of docs/design.md §4 (in the mechanism plane xy).
    pub fn mid_deflection(&self) -> Response {
        Response::MidNodeDeflection {
            body: self.rod,
            first: self.rod_first,
            mid: self.rod_mid,
            last: self.rod_last,
            normal: Vector3::z(),
        }
    }
}

/// The paper's damping of the planar rod: 1 % at mode 1, 3 % at mode 4.
fn rayleigh_planar() -> RayleighDamping {
    RayleighDamping {
        modes: [0, 3],
        ratios: [0.01, 0.03],
    }
}

/// The damping of the 3-D rod: 1 % at mode 1, 3 % at mode 5 (see the module docs).
fn rayleigh_3d() -> RayleighDamping {
    RayleighDamping {
        modes: [0, 4],
        ratios: [0.01, 0.03],
    }
}

fn beam_mesh(elements: usize) -> Mesh {
    Mesh::straight_beam(
        Vector3::zeros(),
        Vector3::new(ROD, 0.0, 0.0),
        elements,
        0,
        Vector3::y(),
    )
    .expect("valid beam mesh")
}

fn modal_setup(
    sens: &SectionSensitivities,
    opts: &RodOptions,
) -> (Mesh, Properties<f64>, ModalAnalysis) {
    assert!(
        opts.elements.is_multiple_of(2),
        "an even number of elements"
    );
    let mesh = beam_mesh(opts.elements);
    let props = Properties {
        sections: vec![BeamSection::from_section(&sens.properties)],
        laminates: vec![],
    };
    // planar: `fem` fits the damping from the retained modes; 3-D: `damping_3d`
    let mo = if opts.planar {
        ModalOptions {
            planar: Some(Vector3::z()),
            damping: Some(rayleigh_planar().into()),
            ..ModalOptions::new(opts.modes)
        }
    } else {
        ModalOptions::new(opts.modes)
    };
    let analysis = modal_analysis(&mesh, &props, &mo).expect("modal analysis");
    (mesh, props, analysis)
}

/// Modal damping `α + βλ_k` of the 3-D rod with `(α, β)` fitted at modes 1 and 5 (see the
/// module docs).
fn damping_3d<S: Scalar>(lambdas: &[S], lambda5: S) -> Vec<S> {
    let (a, b) = rayleigh_3d()
        .coefficients(lambdas[0], lambda5)
        .expect("distinct frequencies");
    lambdas.iter().map(|&l| a + b * l).collect()
}

/// The mechanism around a rod body, generic over the parameter scalar; the returned state is
/// the rigid mechanism's at t = 0 (consistent, not yet assembled).
pub fn mechanism<P: Scalar>(rod_body: ModalBody<P>, elements: usize) -> (Model<P>, State, Ids) {
    let mut model = Model::new();
    let inertia = |m: f64, l: f64| {
        let t = m * l * l / 12.0;
        Matrix3::from_diagonal(&Vector3::new(0.05 * t, t, t)).map(P::from_f64)
    };
    let crank = model
        .add_rigid_body(RigidBody::new(
            "crank",
            P::from_f64(CRANK_MASS),
            inertia(CRANK_MASS, CRANK),
        ))
        .expect("crank");
    let rod = model
        .add_flexible_body(FlexibleBody::new("rod", rod_body))
        .expect("rod");
    let slider = model
        .add_rigid_body(RigidBody::new(
            "slider",
            P::from_f64(SLIDER_MASS),
            Matrix3::identity().map(|x: f64| P::from_f64(x * 1e-4)),
        ))
        .expect("slider");
    let x_axis = Vector3::x();
    let joints = [
        Joint::new(
            "crank pivot",
            JointKind::Revolute,
            Marker::ground(Vector3::zeros()),
            Marker::on(crank, Vector3::new(-CRANK / 2.0, 0.0, 0.0)),
        ),
        Joint::new(
            "crank driver",
            JointKind::AngleDriver(TimeFunction::ConstantSpeed {
                initial: 0.0,
                rate: OMEGA,
            }),
            Marker::ground(Vector3::zeros()),
            Marker::on(crank, Vector3::new(-CRANK / 2.0, 0.0, 0.0)),
        ),
        Joint::new(
            "crank pin",
            JointKind::Revolute,
            Marker::on(crank, Vector3::new(CRANK / 2.0, 0.0, 0.0)),
            Marker::node(rod, 0),
        ),
        Joint::new(
            "wrist pin",
            JointKind::Revolute,
            Marker::node(rod, elements),
            Marker::on(slider, Vector3::zeros()),
        ),
        Joint::new(
            "slide",
            JointKind::Translational,
            Marker::ground(Vector3::zeros()).with_axis(x_axis),
            Marker::on(slider, Vector3::zeros()).with_axis(x_axis),
        ),
    ];
    let joint_ids: Vec<JointId> = joints
        .into_iter()
        .map(|j| model.add_joint(j).expect("joint"))
        .collect();
    let mut state = model.rest_state();
    let id = Matrix3::identity();
    model.set_pose(&mut state, crank, Vector3::new(CRANK / 2.0, 0.0, 0.0), &id);
    model.set_pose(
        &mut state,
        rod,
        Vector3::new(CRANK + ROD / 2.0, 0.0, 0.0),
        &id,
    );
    model.set_pose(&mut state, slider, Vector3::new(CRANK + ROD, 0.0, 0.0), &id);
    // rigid kinematics at crank angle 0: crank tip moves at ωr along y, the rod turns at
    // −ωr/L, the slider is at rest
    model.set_velocity(
        &mut state,
        crank,
        Vector3::new(0.0, OMEGA * CRANK / 2.0, 0.0),
        Vector3::new(0.0, 0.0, OMEGA),
    );
    model.set_velocity(
        &mut state,
        rod,
        Vector3::new(0.0, OMEGA * CRANK / 2.0, 0.0),
        Vector3::new(0.0, 0.0, -OMEGA * CRANK / ROD),
    );
    let ids = Ids {
        crank,
        rod,
        slider,
        rod_first: 0,
        rod_mid: elements / 2,
        rod_last: elements,
        wrist_pin: joint_ids[3],
    };
    (model, state, ids)
}

/// The plain (`f64`) slider-crank for a lay-up (degrees).
pub fn slider_crank(angles_deg: &[f64], opts: &RodOptions) -> (Model<f64>, State, Ids) {
    let mesh = tube_section(angles_deg);
    let props = section::analyse(&mesh).expect("section analysis");
    let sens = SectionSensitivities {
        properties: props,
        variables: vec![],
        derivatives: vec![],
    };
    let (beam, bprops, analysis) = modal_setup(&sens, opts);
    let mut body = modal_body(&beam, &bprops, &analysis).expect("modal body");
    if !opts.planar {
        body.modal_damping = damping_3d(&body.eigenvalues, analysis.pairs.values[4]);
    }
    mechanism(body, opts.elements)
}

/// The slider-crank with design derivatives in chunks of `N` for the variables `design` of a
/// lay-up (degrees).
pub fn slider_crank_design<const N: usize>(
    angles_deg: &[f64],
    design: Design,
    opts: &RodOptions,
) -> (DesignModel<N>, State, Ids) {
    let mesh = tube_section(angles_deg);
    let map = design.map(&mesh);
    let sens = section::analyse_with_derivatives::<N>(&mesh, &map).expect("section analysis");
    let (beam, bprops, analysis) = modal_setup(&sens, opts);
    let b = design.values(angles_deg);
    let bodies = design_bodies::<N, _>(
        &beam,
        &bprops,
        &analysis,
        &b,
        |bd: &[Dual<N>]| Properties {
            sections: vec![BeamSection::from_sensitivities(&sens, bd)],
            laminates: vec![],
        },
        opts.update,
    )
    .expect("mode derivatives");
    let mut chunks = Vec::new();
    let mut state = None;
    let mut ids = None;
    for (range, mut body) in chunk_ranges(b.len(), N).zip(bodies.chunks) {
        if !opts.planar {
            let mut d5 = [0.0; N];
            for (k, v) in range.clone().enumerate() {
                d5[k] = bodies.derivatives.eigenvalues[v][4];
            }
            let lambda5 = Dual::new(analysis.pairs.values[4], d5);
            body.modal_damping = damping_3d(&body.eigenvalues, lambda5);
        }
        let (model, s, i) = mechanism(body, opts.elements);
        chunks.push(model);
        state = Some(s);
        ids = Some(i);
    }
    (
        DesignModel::new(chunks, b.len()).expect("design model"),
        state.expect("at least one chunk"),
        ids.expect("at least one chunk"),
    )
}

/// System with redundant equations removed and the initial state assembled.
pub fn assembled(model: Model<f64>, state: State) -> (MultibodySystem, State) {
    assembled_with(model, state, RedundancyPolicy::Remove)
}

/// As [`assembled`] with a redundancy policy.
pub fn assembled_with(
    model: Model<f64>,
    mut state: State,
    policy: RedundancyPolicy,
) -> (MultibodySystem, State) {
    let mut sys = MultibodySystem::new(model, &state, policy).expect("valid system");
    sys.assemble(0.0, &mut state, 1e-13).expect("assembly");
    (sys, state)
}

/// A perturbed design's system assembled from the nominal state (as the initial
/// sensitivities assume, `mbs::initial_sensitivities`).
pub fn perturbed(
    nominal: &MultibodySystem,
    nominal_state: &State,
    model: Model<f64>,
) -> (MultibodySystem, State) {
    let mut sys = nominal.with_model(model);
    let mut state = nominal_state.clone();
    sys.assemble(0.0, &mut state, 1e-13).expect("assembly");
    (sys, state)
}

/// The gradient of the integral of `response` over the recorded points of `run` (a run of
/// `sys` from its assembled `state`) by the adjoint method.
pub fn adjoint_integral<const N: usize>(
    sys: &mut MultibodySystem,
    design: &DesignModel<N>,
    (run, state): (&mbs::SensitivityRun, &State),
    response: &Response,
) -> Vec<f64> {
    let s0 = mbs::initial_sensitivities(sys, design, run.times[0], state).unwrap();
    let values = mbs::response_values(sys, &run.times, &run.states, response).unwrap();
    let weights = mbs::Objective::Integral
        .weights(&run.times, &values)
        .unwrap();
    let term = mbs::ObjectiveTerm {
        response: response.clone(),
        times: run.times.clone(),
        weights: weights.weights,
    };
    let (mut g, _) = mbs::adjoint_gradients(sys, design, run, &s0, &[vec![term]]).unwrap();
    g.remove(0)
}
