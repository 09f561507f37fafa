//! `mbs` — rigid–flexible multibody dynamics and its time integrator (paper §2, Eqs. 1–12).
//!
//! It owns rigid bodies and floating-frame flexible bodies reduced to modes (from
//! [`fem::ModalBody`]), Euler parameters with body-frame angular velocities, joints and drivers
//! between markers (body points or FE nodes), applied forces, the augmented equations of motion
//! of Eq. (12) with Baumgarte stabilisation, redundant-constraint detection, consistent initial
//! conditions, and a variable-order, variable-step BDF integrator of its own.
//!
//! The equations ([`Model::equations`], [`Model::residual`], [`Model::kinematic_rates`]) are
//! written once, generic over [`sens::Scalar`], so that design sensitivities (Eq. 40) evaluate
//! them on dual numbers and push the tangents through the `f64` LU of [`MultibodySystem`].
//! The integrator ([`Bdf`]) exposes every accepted step (order, step, BDF coefficients, history)
//! so that sensitivities can be integrated on the same step sequence.
//!
//! It knows nothing about laminates, cross-sections, finite elements beyond the modal body,
//! decks or files.
//!
//! # Layers
//! - [`Model<P>`]: bodies ([`RigidBody`], [`FlexibleBody`] around a [`fem::ModalBody`]),
//!   [`Joint`]s between [`Marker`]s, [`Force`]s, gravity, [`Baumgarte`] constants. `P` is the
//!   scalar of the model data. State: `q = (r, p, w)` and `v = (ṙ, ω', ẇ)` per body
//!   ([`Model::q_range`], [`Model::v_range`]). A flexible body may carry the second-order part of its
//!   deformation field, the beams' foreshortening ([`FlexibleBody::with_geometric_stiffness`],
//!   docs/geometric-stiffening.md): `u' = X w + ½ Q(w, w)` in its nodes' and markers'
//!   positions, its mass matrix and inertia forces, so that the geometric stiffness of its axial
//!   forces (inertia, joints, applied loads) follows and Eq. (12) keeps its symmetric form.
//! - Generic evaluation, any `S: Scalar + From<P>`: [`Model::kinematic_rates`] (`q̇`),
//!   [`Model::mass_and_forces`], [`Model::constraints`] (`Φ`, `Φ̇`, `γ`, `Φ_v`),
//!   [`Model::equations`] (the matrix and right-hand side of Eq. 12) and [`Model::residual`]
//!   (`rhs − matrix · x̂` with `x̂ = [v̇; λ]` fixed: on `Dual<N>` its tangents are the right-hand
//!   side of Eq. 40).
//! - [`MultibodySystem`]: the `f64` side — redundant rows ([`RedundancyPolicy`]), consistent
//!   initial conditions ([`MultibodySystem::assemble`]; where the rigid-body coordinates
//!   cannot meet the joints, with the flexible bodies deformed at the least strain energy:
//!   [`ElasticStart`]), the solve of Eq. (12)
//!   ([`MultibodySystem::solve`] returns `x̂` and the factorisation, an [`Eq12Factor`]: the dense
//!   LU, or for large mechanisms the body blocks of the [`BodyMass`] and a sparse Schur
//!   complement on the constraints), outputs, and the [`OdeSystem`] `y' = f(t, y)`,
//!   `y = [q; v]`, whose Jacobian comes from the dual path (for large mechanisms as a sparse
//!   Newton system, seeded body colour by body colour; docs/design.md §3).
//! - [`Bdf`]: the integrator. After each accepted step [`Bdf::last_step`] gives the order, step,
//!   coefficients `c_j` of `Σ c_j y_{n+1−j} = f(y_{n+1})`, the states of the formula and the
//!   Newton matrix; [`Bdf::integrate_to`] calls an observer after every accepted step.
//! - [`absolute_tolerances`]: the integrator's absolute tolerance per state component from a
//!   displacement tolerance per body (what moves the body's mass by it; docs/design.md §3).
//!
//! # Sensitivities (paper §4, Eqs. 35–47)
//! - [`DesignModel<N>`]: one `Model<Dual<N>>` per chunk of `N` design variables (e.g. flexible
//!   bodies from `fem::modal_body_dual`, fixed- or updated-mode).
//! - [`simulate_sensitivities`]: state and `S = ∂y/∂b` on the integrator's own steps with the
//!   same BDF formula ([`SensitivityMethod::StaggeredDirect`]: exact derivative of the discrete
//!   solution; [`SensitivityMethod::StaggeredCorrector`]; [`SensitivityMethod::Simultaneous`],
//!   inside the state's Newton iteration, the cheapest), optionally in the error control
//!   ([`SensitivityOptions`]); `f_y S + f_b` is one dual evaluation per chunk
//!   ([`tangent_rhs`]); initial sensitivities consistent with the constraints
//!   ([`initial_sensitivities`], Eq. 44). Integration extensions hook into
//!   [`Bdf::step_with`] ([`StepExtension`]).
//! - [`Response`] (body positions, nodal displacements, the mid-node deflection, reaction
//!   forces, state components) → [`response_history`] (values and `dψ/db`, Eq. 39) →
//!   [`Objective`] (integral, mean, RMS, max/min with time, value at a time) with gradients.
//! - The discrete adjoint ([`adjoint_gradients`], docs/design.md §3): the gradients of
//!   objectives of a recorded run ([`simulate_steps`]) by a backward sweep over its steps,
//!   whatever the number of variables — the model's data and invariants inputs of a
//!   reverse-mode tape ([`TapedModel`], [`sens::Rev`]), the invariants' adjoints taken back
//!   to the data by hand ([`TapedModel::data_adjoints`]), the data's contracted with the
//!   design model's tangents ([`contract_data`]); or the sweep alone ([`adjoint_sweep`]) and
//!   its contraction one chunk of variables at a time ([`AdjointSweep::gradients`]), so that
//!   only one chunk's dual model need exist; each objective's samples weighted by
//!   [`Objective::weights_in`]. A long run's states within a memory budget
//!   ([`simulate_checkpointed`]: snapshots of the integrator, [`BdfSnapshot`], the states
//!   between them recomputed bitwise when the sweep reaches them; any [`StepHistory`]).
//! - Finite differences for comparison ([`finite_differences`], [`simulate_response`]) on
//!   independent adaptive runs or on the nominal step sequence replayed
//!   ([`SensitivityRun::replay_options`], [`StepControl::Replay`]).
//!
//! ```
//! use mbs::{BdfOptions, Joint, JointKind, Marker, Model, MultibodySystem, RedundancyPolicy,
//!           RigidBody, simulate};
//! use nalgebra::{Matrix3, Vector3};
//!
//! // a rod of 1 kg, 1 m hanging from a revolute joint, released horizontally
//! let mut model = Model::new();
//! model.gravity = Vector3::new(0.0, -9.81, 0.0);
//! let inertia = Matrix3::from_diagonal(&Vector3::new(1e-4, 1.0 / 12.0, 1.0 / 12.0));
//! let rod = model.add_rigid_body(RigidBody::new("rod", 1.0, inertia)).unwrap();
//! model.add_joint(Joint::new("pin", JointKind::Revolute,
//!     Marker::ground(Vector3::zeros()), Marker::on(rod, Vector3::new(-0.5, 0.0, 0.0)))).unwrap();
//! let mut state = model.rest_state();
//! model.set_pose(&mut state, rod, Vector3::new(0.5, 0.0, 0.0), &Matrix3::identity());
//! let mut sys = MultibodySystem::new(model, &state, RedundancyPolicy::Remove).unwrap();
//! sys.assemble(0.0, &mut state, 1e-12).unwrap();
//! let sim = simulate(&mut sys, &state, &[0.0, 0.5, 1.0], BdfOptions::adaptive(1e-8, 1e-10)).unwrap();
//! let e = |i: usize| sim.outputs[i].energy.total();
//! assert!((e(2) - e(0)).abs() < 1e-6);
//! ```

// Checks that must also reject NaN are written `!(x > 0.0)` on purpose.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

mod adjoint;
mod bdf;
mod body;
mod checkpoint;
mod elastic_start;
mod eq12;
mod error;
mod fd;
mod field_gram;
mod force;
mod frozen;
mod joint;
pub mod kin;
mod marker;
mod model;
mod newton;
mod nodal;
mod operating;
mod ply;
mod reduced_newton;
mod response;
mod sensitivity;
mod system;
mod tolerance;

pub use adjoint::{
    AdjointStatistics, AdjointSweep, Adjoints, ObjectiveTerm, RecordedRhs, StepHistory, TapedModel,
    adjoint_gradients, adjoint_sweep, contract_data,
};
pub use bdf::{
    AcceptedStep, Bdf, BdfOptions, BdfSnapshot, IntegrationError, IntegrationFailure, JACOBIAN_AGE,
    NewtonMatrix, NoExtension, OdeSystem, RhsError, STABILITY_GROWTH, Statistics, StepControl,
    StepExtension, StructuredJacobian, TrialStep, bdf_stable, error_estimate_weights,
    lagrange_weights, stable_step,
};
pub use body::{Body, BodyId, FlexibleBody, PlyStresses, RigidBody};
pub use checkpoint::{CheckpointStatistics, CheckpointedRun, simulate_checkpointed};
pub use eq12::{BodyMass, BodySchur, Eq12Factor};
pub use error::{ConstraintError, ModelError};
pub use fd::{
    FdScheme, FiniteDifference, Perturbation, finite_difference_designs, finite_differences,
    finite_differences_from, simulate_response,
};
pub use force::{Force, ForceId, Load, LoadFrame, TorqueLaw};
pub use frozen::{StateLinearisation, linearise_state};
pub use joint::{JointId, JointKind, TimeFunction};
pub use marker::{Marker, Site};
pub use model::{Baumgarte, ConstraintValues, Energy, Equations, Joint, Model, State};
pub use operating::{
    EquilibriumOptions, LinearMode, Linearisation, OperatingError, OperatingPoint,
    OperatingSensitivities, Spin, equilibrium,
};
pub use response::{
    Objective, ObjectiveValue, Response, ResponseHistory, SampleWeights, response_history,
    response_values,
};
pub use sensitivity::{
    DesignModel, SIMULTANEOUS_TOLERANCE, SensitivityError, SensitivityMethod, SensitivityOptions,
    SensitivityRun, SensitivityStatistics, initial_sensitivities, seeded, simulate_sensitivities,
    simulate_sensitivities_from, simulate_steps, tangent_rhs,
};
pub use system::{
    ElasticStart, JointReaction, MultibodySystem, Output, Progress, RedundancyPolicy, Simulation,
    SimulationError, Solution, StepGuard, simulate,
};
pub use tolerance::{absolute_tolerances, mechanism_size};
