//! The errors of the finite-element layer.

use crate::beam::BeamError;
use crate::mesh::MeshError;
use crate::shell::ShellError;

/// Every way the finite-element layer can fail.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FemError {
    #[error(transparent)]
    Mesh(#[from] MeshError),
    #[error(transparent)]
    Beam(#[from] BeamError),
    #[error(transparent)]
    Shell(#[from] ShellError),
    #[error("element {element} uses {kind} property {property}, but only {available} are defined")]
    MissingProperty {
        element: usize,
        kind: &'static str,
        property: usize,
        available: usize,
    },
    #[error("dof {dof} is out of range ({n_dofs} dof)")]
    BadDof { dof: usize, n_dofs: usize },
    #[error("every dof is constrained")]
    NoFreeDof,
    #[error("eigen solver: {0}")]
    Eigen(String),
    #[error("the body has no mass")]
    NoMass,
    #[error("empty mesh")]
    EmptyMesh,
    /// The reference condition cannot hold the mesh (a clamped section, node or pinned ends).
    #[error("{0}")]
    Reference(String),
    /// A support names a node or dof that does not exist, or the supports leave the body free.
    #[error("{0}")]
    Support(String),
    /// A coupling (distributing: its nodes, point or rigid-motion fit).
    #[error("{0}")]
    Coupling(String),
    /// A rigid tie (its nodes, point, or a node in two ties).
    #[error("{0}")]
    RigidTie(String),
    /// The number or choice of modes.
    #[error("{0}")]
    Modes(String),
    /// Proportional damping (its modes or coefficients).
    #[error("{0}")]
    Damping(String),
    /// The normal of planar modes.
    #[error("{0}")]
    Planar(String),
    /// Static correction modes (their nodes, or a body the reference condition does not hold).
    #[error("{0}")]
    Correction(String),
    /// The basis check (its load targets, a singular modal stiffness).
    #[error("{0}")]
    BasisCheck(String),
    /// Geometric stiffening (a mesh it does not apply to).
    #[error("{0}")]
    Stiffening(String),
    /// A derivative request the body cannot meet (missing design matrices, repeated
    /// frequencies that split).
    #[error("{0}")]
    Derivatives(String),
    /// Ply stresses the body cannot give (a body of beams, a modal body of another mesh).
    #[error("{0}")]
    Stresses(String),
}
