//! The deck as written: serde mirrors of the TOML tables. Every key is documented in
//! `docs/decks.md`.

use std::collections::BTreeMap;

use serde::Deserialize;
use toml::Spanned;

/// A whole deck.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawDeck {
    /// Free text describing the deck.
    pub title: Option<String>,
    /// Materials by name.
    #[serde(default)]
    pub material: BTreeMap<String, Spanned<RawMaterial>>,
    /// Ply stacks by name.
    #[serde(default)]
    pub laminate: BTreeMap<String, Spanned<RawLaminate>>,
    /// Beam cross-sections by name.
    #[serde(default)]
    pub section: BTreeMap<String, Spanned<super::sections::RawSection>>,
    /// Flexible bodies by name.
    #[serde(default)]
    pub body: BTreeMap<String, Spanned<super::bodies::RawBody>>,
    /// Rigid bodies by name.
    #[serde(default)]
    pub rigid: BTreeMap<String, Spanned<super::mechanism::RawRigid>>,
    /// Joints and drivers by name.
    #[serde(default)]
    pub joint: BTreeMap<String, Spanned<super::mechanism::RawJoint>>,
    /// Force elements by name.
    #[serde(default)]
    pub force: BTreeMap<String, Spanned<super::mechanism::RawForce>>,
    /// Requested responses by name.
    #[serde(default)]
    pub response: BTreeMap<String, Spanned<super::mechanism::RawResponse>>,
    /// Time integration settings of `flexsens run`.
    pub analysis: Option<Spanned<super::mechanism::RawAnalysis>>,
    /// Design variables by name (ply angles, degrees).
    #[serde(default)]
    pub design: BTreeMap<String, Spanned<super::design::RawDesign>>,
    /// Scalar objectives of responses by name.
    #[serde(default)]
    pub objective: BTreeMap<String, Spanned<super::design::RawObjective>>,
    /// Settings of the direct sensitivity analysis.
    pub sensitivity: Option<Spanned<super::design::RawSensitivity>>,
    /// Finite-difference comparisons.
    pub finite_differences: Option<Spanned<super::design::RawFiniteDifferences>>,
}

/// A material: isotropic (`E`, `nu`) or orthotropic (the nine constants), with `density`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawMaterial {
    #[serde(rename = "E")]
    pub e: Option<Spanned<f64>>,
    pub nu: Option<Spanned<f64>>,
    #[serde(rename = "E1")]
    pub e1: Option<Spanned<f64>>,
    #[serde(rename = "E2")]
    pub e2: Option<Spanned<f64>>,
    #[serde(rename = "E3")]
    pub e3: Option<Spanned<f64>>,
    #[serde(rename = "G12")]
    pub g12: Option<Spanned<f64>>,
    #[serde(rename = "G13")]
    pub g13: Option<Spanned<f64>>,
    #[serde(rename = "G23")]
    pub g23: Option<Spanned<f64>>,
    pub nu12: Option<Spanned<f64>>,
    pub nu13: Option<Spanned<f64>>,
    pub nu23: Option<Spanned<f64>>,
    pub density: Option<Spanned<f64>>,
}

/// A ply stack, bottom ply first.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawLaminate {
    pub plies: Option<Spanned<Vec<Spanned<RawPly>>>>,
    /// Mirror the plies about the top face (`[0, 45]` becomes `[0, 45, 45, 0]`).
    pub symmetric: Option<Spanned<bool>>,
    /// `"mid-plane"` (default), `"bottom"`, `"top"`, or `"offset"` with `offset`.
    pub reference: Option<Spanned<String>>,
    /// Height of the reference surface above the mid-plane (m), with `reference = "offset"`.
    pub offset: Option<Spanned<f64>>,
    /// Transverse shear correction factor (default 5/6).
    pub shear_correction: Option<Spanned<f64>>,
}

/// One ply.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawPly {
    pub material: Option<Spanned<String>>,
    /// Thickness (m).
    pub thickness: Option<Spanned<f64>>,
    /// Fibre angle from the reference axis (degrees).
    pub angle: Option<Spanned<f64>>,
}
