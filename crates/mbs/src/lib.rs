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

// Checks that must also reject NaN are written `!(x > 0.0)` on purpose.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

mod bdf;
mod body;
mod error;
mod force;
mod joint;
pub mod kin;
mod marker;
mod model;
mod system;

pub use bdf::{
    AcceptedStep, Bdf, BdfOptions, IntegrationError, IntegrationFailure, OdeSystem, RhsError,
    Statistics, StepControl, lagrange_weights,
};
pub use body::{Body, BodyId, FlexibleBody, RigidBody};
pub use error::{ConstraintError, ModelError};
pub use force::{Force, ForceId, Load, LoadFrame};
pub use joint::{JointId, JointKind, TimeFunction};
pub use marker::{Marker, Site};
pub use model::{Baumgarte, ConstraintValues, Energy, Equations, Joint, Model, State};
pub use system::{
    JointReaction, MultibodySystem, Output, RedundancyPolicy, Simulation, SimulationError,
    Solution, simulate,
};
