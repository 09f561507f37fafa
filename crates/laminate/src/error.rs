//! Errors of the laminate layer.

/// Why a material, ply or stack is not physically valid.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LaminateError {
    /// An engineering constant that must be positive and finite is not.
    #[error("{constant} = {value} must be a positive, finite number")]
    NotPositive { constant: &'static str, value: f64 },
    /// An engineering constant is not finite.
    #[error("{constant} = {value} must be a finite number")]
    NotFinite { constant: &'static str, value: f64 },
    /// The compliance matrix is not positive definite (no strain-energy minimum).
    #[error(
        "the compliance matrix is not positive definite: {reason} \
         (check the Poisson ratios against the moduli)"
    )]
    NotPositiveDefinite { reason: String },
    /// A ply has a non-positive or non-finite thickness.
    #[error("ply {ply}: thickness = {value} must be a positive, finite number (m)")]
    PlyThickness { ply: usize, value: f64 },
    /// A ply angle is not finite.
    #[error("ply {ply}: angle = {value} must be a finite number")]
    PlyAngle { ply: usize, value: f64 },
    /// A ply stack with no plies.
    #[error("a laminate needs at least one ply")]
    Empty,
    /// The shear correction factor is outside (0, 1].
    #[error("shear correction factor = {value} must lie in (0, 1]")]
    ShearCorrection { value: f64 },
    /// The reference-surface offset is not finite.
    #[error("reference surface offset = {value} must be a finite number (m)")]
    ReferenceOffset { value: f64 },
}
