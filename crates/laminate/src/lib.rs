//! `laminate` — lamina and laminate constitutive theory (paper §3.1–3.2, Eqs. 13–21 and 50).
//!
//! It owns the orthotropic material ([`OrthotropicMaterial`]: nine engineering constants and
//! density, validated), the 3-D stiffness in material axes (Eq. 13) and its rotation to any frame
//! (Bond matrix, Eqs. 14–15), the plane-stress reduced stiffness and transverse-shear pair, and
//! the ply stack ([`PlyStack`]) with its A, B, D and transverse shear stiffness (Eqs. 20–21) and
//! mass per unit area; the plies' stresses and strains through the thickness at a point
//! ([`PlyStack::ply_points`]) and the ply strengths with their failure criteria
//! ([`PlyStrength`], [`Criterion`]; docs/failure-criteria.md).
//!
//! Everything that depends on ply angles (or thicknesses) is generic over [`sens::Scalar`]:
//! evaluated on `Dual<N>` it yields exact derivatives with respect to the seeded plies. The
//! closed-form angle derivative of Eq. (50) ([`rotated_stiffness_angle_derivative`],
//! [`PlyStack::angle_derivative`]) is kept as an independent cross-check.
//! Angles are radians here; conversion from degrees belongs to the deck layer.
//! It knows nothing about sections, elements or decks.

mod error;
mod material;
mod recovery;
mod rotation;
mod stack;
mod strength;

pub use error::LaminateError;
pub use material::OrthotropicMaterial;
pub use recovery::{PlateState, PlyPoint, PlyPosition};
pub use rotation::{
    bond_stress_matrix, plane_stress, rotate_stiffness, rotate_stiffness_of,
    rotated_stiffness_angle_derivative, rotation_about_normal, transverse_shear,
};
pub use stack::{DEFAULT_SHEAR_CORRECTION, LaminateStiffness, Ply, PlyStack, ReferenceSurface};
pub use strength::{Criterion, PlyStrength, TSAI_WU_INTERACTION};
