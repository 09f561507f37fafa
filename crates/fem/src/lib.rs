//! `fem` — composite beam and shell finite elements, assembly, vibration modes, proportional
//! damping and mode sensitivities (paper §2.3, §3.2–3.3, §4.4–4.6).
//!
//! Its output to the multibody layer is the [`ModalBody`]: everything a floating-frame flexible
//! body needs (lumped nodal masses and inertias, mode shapes, eigenvalues, modal damping), generic
//! over [`sens::Scalar`] so that design derivatives travel as dual tangents.
//! It knows nothing about joints, time integration or decks.

mod modal;

pub use modal::{ModalBody, ModalBodyError, NODE_DOFS};
