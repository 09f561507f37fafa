//! `section` — finite-element cross-section analysis of composite beams (paper §3.3 and §4.6,
//! Eqs. 24–34 and 52–61; docs/design.md §2).
//!
//! It owns the 2-D section mesh ([`SectionMesh`]: quadratic elements, each in a [`Region`] with
//! a material, a ply angle and a local wall frame), its generators ([`rectangle`], [`circle`],
//! [`tube`], [`thin_walled_box`], [`channel`], [`i_section`]) and text parsers
//! ([`parse_gmsh`], [`parse_simple`]), the warping analysis that yields the 6×6 Timoshenko
//! stiffness with all couplings, the 4×4 classical stiffness, mass properties and the mass,
//! tension and shear centres ([`SectionProperties`]), and their exact derivatives with respect
//! to design variables ([`DesignMap`], [`SectionSensitivities`]): ply angles, material
//! constants and densities, and node positions — a generated section ([`GeneratedSection`])
//! gives the node velocities of a ply thickness from the same code that places its nodes. It
//! recovers the 3-D strains and stresses at the section's points under given section forces
//! ([`SectionAnalysis::stresses`]). A
//! section can also be given by its published properties instead of analysed
//! ([`SectionProperties::given`], [`stiffness_from_centres`],
//! [`SectionProperties::mass_of_matrix`]). It knows nothing about beam elements, multibody
//! systems, decks or files: text comes in as `&str`.
//!
//! # Conventions
//! - Beam axis `x₁`; section plane `(x₂, x₃)`; right-handed. SI units, radians.
//! - Generalised strains `ψ = [ε, γ₂, γ₃, κ₁, κ₂, κ₃]` (axial strain, shear strains in `x₂` and
//!   `x₃`, twist, bending curvatures about `x₂` and `x₃`) and section forces
//!   `θ = [F₁, F₂, F₃, M₁, M₂, M₃]`, `θ = K ψ`, both referred to the origin of the section
//!   coordinates ([`SectionProperties::stiffness_at`] refers them to any point).
//! - With `t(x₁)` the displacement and `φ(x₁)` the rotation vector of the reference axis:
//!   `ε = t₁'`, `γ₂ = t₂' − φ₃`, `γ₃ = t₃' + φ₂`, `κ = φ'`. The axial strain of the fibre at
//!   `(x₂, x₃)` is `ε + x₃ κ₂ − x₂ κ₃`; so for bending in the `x₁x₂` plane with deflection
//!   `v(x₁)`, `κ₃ = v''` (positive `κ₃` shortens fibres at positive `x₂`), and in the `x₁x₃`
//!   plane with deflection `w`, `κ₂ = −w''`.
//! - Forces are the resultants of the axial stresses `(σ₁₁, σ₁₂, σ₁₃)`: `F = ∫σ₁ⱼ`,
//!   `M₁ = ∫(x₂σ₁₃ − x₃σ₁₂)`, `M₂ = ∫x₃σ₁₁`, `M₃ = −∫x₂σ₁₁` (`M = ∫ p × σ₁`). An isotropic
//!   section about its centroid has `K = diag(EA, k₂GA, k₃GA, GJ, EI₂₂, EI₃₃)` with
//!   `I₂₂ = ∫x₃²`, `I₃₃ = ∫x₂²`.
//! - Voigt order of 3-D stresses and strains `[11, 22, 33, 23, 13, 12]`, engineering shears (as
//!   in `laminate`).
//! - Ply angle `θ`: fibre direction from the beam axis, rotated about the wall normal `n` of
//!   the region's [`WallFrame`] (`(x₁, t, n)` right-handed); the element stiffness in section
//!   axes is `rotate_stiffness(C̄, R_wall · R_ply(θ))`.
//!
//! # Formulation
//! Giavotto et al. (1983) / BECAS (Blasques 2012): two linear systems with one sparse matrix,
//! factorised once by sparse Cholesky; the equations are on [`SectionAnalysis`]. Derivatives
//! follow docs/design.md §1.
//!
//! # Use
//! ```
//! use section::{DesignMap, PlySpec, analyse_with_derivatives, tube};
//! let cfrp = laminate::OrthotropicMaterial::new(
//!     [128e9, 10.1e9, 10.1e9], [5.36e9; 3], [0.23; 3], 1586.0).unwrap();
//! let deg = std::f64::consts::PI / 180.0;
//! let plies = [
//!     PlySpec::new("inner", cfrp, 30.0 * deg, 0.0005, 1),
//!     PlySpec::new("outer", cfrp, -30.0 * deg, 0.0005, 1),
//! ];
//! let mesh = tube(0.01, &plies, 32)?;
//! // One design variable θ drives the lay-up [θ/−θ].
//! let design = DesignMap::new().with_named_variable(&mesh, "theta", &[("inner", 1.0), ("outer", -1.0)])?;
//! let s = analyse_with_derivatives::<4>(&mesh, &design)?;
//! let ea = s.properties.stiffness[(0, 0)];
//! let dea_dtheta = s.derivatives[0].stiffness[(0, 0)]; // per radian
//! assert!(ea > 0.0 && dea_dtheta < 0.0); // turning the fibres away from the axis softens it
//! # Ok::<(), section::SectionError>(())
//! ```
//!
//! Errors are [`SectionError`] values whose messages name the element, node, region or text
//! line at fault.

mod analysis;
mod design;
mod element;
mod error;
mod generate;
mod mesh;
mod parse;
mod properties;

pub use analysis::{
    SectionAnalysis, SectionPoint, StressDerivative, analyse, analyse_with_derivatives,
};
pub use design::{DesignMap, DesignVariable};
pub use element::ElementKind;
pub use error::SectionError;
pub use generate::{
    BoxWalls, GeneratedSection, IWalls, PlySpec, channel, circle, i_section, rectangle,
    thin_walled_box, tube,
};
pub use mesh::{Element, ElementDirection, Region, SectionMesh, WallFrame};
pub use parse::{RegionSpec, parse_gmsh, parse_simple, write_simple};
pub use properties::{
    Entry, ReferencePoint, SectionProperties, SectionSensitivities, stiffness_from_centres,
};
