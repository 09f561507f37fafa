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
    #[error("invalid request: {0}")]
    Invalid(String),
}
