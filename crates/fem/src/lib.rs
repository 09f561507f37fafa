//! `fem` — composite beam and shell finite elements, assembly, vibration modes, proportional
//! damping and mode sensitivities (paper §2.3, §3.2–3.3, §4.4–4.6).
//!
//! It owns the element formulations ([`beam`]: exact-flexibility 3-D Timoshenko beam with a
//! fully coupled 6×6 section; [`shell`]: flat MITC3 laminated triangle with drilling dof),
//! meshes ([`Mesh`], Gmsh v4 text), sparse assembly on a fixed pattern ([`Assembly`]), the
//! lowest modes ([`eigen`]), Rayleigh damping, mode derivatives by Nelson/Dailey
//! ([`sensitivity`]) and the reduced body handed to the multibody layer ([`ModalBody`]),
//! generic over [`sens::Scalar`] so that design derivatives travel as dual tangents.
//! Element matrices are written once over `Scalar`: evaluating them on `Dual<N>` gives `K_b`.
//! It knows nothing about joints, time integration, files or decks.
//!
//! Typical use: build a [`Mesh`] (generators, or [`parse_gmsh_v4`] on text) and
//! [`Properties`] (beam sections, laminates from `laminate::PlyStack::stiffness`); run
//! [`modal_analysis`] with [`ModalOptions`] (reference condition — clamped node or clamped
//! cross-section line at the centre of mass, free-free, pinned ends, a clamped node of one's
//! choice, or [`Support`]s alone: dof fixed at node sets, holding every rigid motion or
//! leaving some free as free-free leaves all six ([`free_rigid_motions`] names them) — number of modes, Rayleigh
//! damping, lumped or consistent mass, optional restriction to motion in a plane normal to a
//! global axis); [`modal_body`] gives the `ModalBody<f64>`;
//! [`analysis_derivatives`] evaluates the properties on `Dual<N>` numbers seeded with the design
//! variables (in chunks of `N`), assembles `K_b`, `M_b` on the same sparse pattern and returns
//! eigenvalue and (Nelson/Dailey) eigenvector derivatives; [`modal_body_dual`] packs them into a
//! `ModalBody<Dual<N>>` (fixed-mode or updated-mode); [`geometric_stiffness`] gives a beam
//! body's second-order field (the foreshortening of its beams), as the modal geometric
//! stiffness of unit nodal forces.
//! [`correction`] adds distributing couplings over node sets and static correction modes at a
//! body's interfaces (with exact derivatives); [`completeness`] checks how much of the static
//! compliance under a mechanism's loads a body's basis misses. [`stress`] gives the plies'
//! stresses of a shell or beam body's modes, linear in its modal coordinates.
//!
//! Conventions: dof node by node `[u_x, u_y, u_z, θ_x, θ_y, θ_z]` (small rotation vector),
//! global axes; matrices act on the free dof of an [`Assembly`] (constrained dof eliminated);
//! eigenvalues are `ω²` ascending, modes `M`-normalised; angles in radians.

// `!(x > 0.0)` is used on purpose: it also rejects NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod assembly;
pub mod beam;
pub mod body;
pub mod completeness;
pub mod correction;
mod design_body;
pub mod eigen;
mod error;
pub mod geometric;
mod geometric_shell;
pub mod mesh;
mod modal;
mod modal_adjoint;
mod rigid;
pub mod sensitivity;
pub mod shell;
mod small;
pub mod stress;

pub use assembly::{
    Assembly, Constraints, ElementOptions, MassKind, Properties, ReducedDof, RigidTie, dof,
    element_matrices, lumped_nodal_masses,
};
pub use beam::BeamSection;
pub use body::{
    CorrectionDamping, Damping, ModalAnalysis, ModalOptions, ModeUpdate, RayleighDamping,
    ReferenceCondition, Support, add_planar_constraints, analysis_constraints,
    analysis_derivatives, analysis_eigenvalue_derivatives, design_matrices, modal_analysis,
    modal_body, modal_body_dual, planar_axis, reference_constraints, second_derivative_terms,
};
pub use completeness::{Completeness, InterfaceLoads, LoadCase, static_completeness};
pub use correction::{Coupling, Distribution, StaticCorrection, distribution};
pub use design_body::{DesignBodies, design_bodies, design_body_chunk};
pub use eigen::{EigenMethod, EigenOptions, Eigenpairs, lowest_modes, lowest_modes_of_nodes};
pub use error::FemError;
pub use geometric::{FieldElement, GeometricStiffness, geometric_stiffness, second_order_field};
pub use geometric_shell::shell_geometric_stiffness;
pub use mesh::{
    BeamSegment, Element, GmshTriangles, Mesh, MeshError, NodeId, bounding_box, parse_gmsh_v4,
};
pub use modal::{ModalBody, ModalBodyError, NODE_DOFS};
pub use modal_adjoint::eigenvector_adjoints;
pub use rigid::{RigidMotion, free_rigid_motions};
pub use sensitivity::{
    DesignMatrices, ModeDerivatives, ProjectedDerivative, cluster_second_derivatives,
    directional_eigenvalue_derivatives, eigenvalue_derivatives, eigenvector_adjoint,
    mode_derivatives, mode_derivatives_with, splits_clusters,
};
pub use shell::Membrane;
pub use stress::{
    LaminatePoints, ModalStresses, PointPlace, ShellPlies, beam_modal_stresses, section_points,
    shell_modal_stresses,
};
