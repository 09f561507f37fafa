//! `[body.*]` as written: a flexible body, its segments or regions, couplings, supports and
//! damping.

use std::collections::BTreeMap;

use serde::Deserialize;
use toml::Spanned;

/// A flexible body as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawBody {
    /// `"beam"` or `"shell"`.
    pub kind: Option<Spanned<String>>,
    /// Beam: a `[section.*]` name.
    pub section: Option<Spanned<String>>,
    /// Beam: first end (m).
    pub start: Option<Spanned<[f64; 3]>>,
    /// Beam: second end (m).
    pub end: Option<Spanned<[f64; 3]>>,
    /// Beam: direction of the section's x₂ axis (its part normal to the beam is used).
    pub orientation: Option<Spanned<[f64; 3]>>,
    /// Shell: a `[laminate.*]` name.
    pub laminate: Option<Spanned<String>>,
    /// Shell rectangle: extent along x (m).
    pub length: Option<Spanned<f64>>,
    /// Shell rectangle: extent along y (m).
    pub width: Option<Spanned<f64>>,
    /// Shell: a Gmsh `.msh` v4 triangle mesh, relative to the deck (instead of length/width).
    pub file: Option<Spanned<String>>,
    /// Shell: the laminate's reference axis (ply angles are measured from it), default x.
    pub material_axis: Option<Spanned<[f64; 3]>>,
    /// Beam: number of elements; shell rectangle: `[along x, along y]`.
    pub elements: Option<Spanned<toml::Value>>,
    /// Beam: the segments from `start` to `end`, each with its own section (instead of
    /// `section` and `elements`).
    pub segments: Option<Spanned<Vec<Spanned<RawSegment>>>>,
    /// Shell: regions of elements with their own laminates.
    pub regions: Option<Spanned<Vec<Spanned<RawShellRegion>>>>,
    /// Number of elastic modes retained (the lowest), the mode numbers retained, e.g.
    /// `[1, 2, 5]` (counted from 1, ascending), or `"auto"`.
    pub modes: Option<Spanned<toml::Value>>,
    /// `"centre-of-mass"` (default), `"clamped-section"`, `"free-free"`, `"pinned-ends"`,
    /// `"clamped-node"`, `"supports"` or `"partly-free"`.
    pub reference: Option<Spanned<String>>,
    /// Clamped node: the node index (default 0, a generated beam's start).
    pub clamped: Option<Spanned<i64>>,
    /// Geometric (stress) stiffening from the body's axial forces (beams).
    pub stiffening: Option<Spanned<bool>>,
    /// Supports: dof fixed at sets of nodes (with `reference = "supports"` they alone hold the
    /// body; otherwise they add to the reference condition).
    pub supports: Option<Vec<Spanned<RawSupport>>>,
    /// Keep only modes of motion in the plane with this normal (a global axis): translations
    /// in the plane and rotations about the normal.
    pub planar: Option<Spanned<[f64; 3]>>,
    /// Pinned ends: the two node indices (default: the beam's end nodes).
    pub pinned: Option<Spanned<[i64; 2]>>,
    /// Proportional damping: two modal damping ratios, or the coefficients `alpha`, `beta`.
    pub damping: Option<Spanned<RawDamping>>,
    /// `"lumped"` (default; the floating frame needs it) or `"consistent"`.
    pub mass: Option<Spanned<String>>,
    /// Static correction: node indices (from 0) whose static shapes are added to the modes,
    /// typically the nodes the body's joints act at; replaces the interface basis's choice.
    pub correction: Option<Spanned<Vec<i64>>>,
    /// `"interface"` (static correction modes at every coupling and every node a joint or
    /// force acts at; the default, but for free and partly free bodies) or `"modes"`
    /// (eigenmodes only).
    pub basis: Option<Spanned<String>>,
    /// The correction modes' least damping ratio (default 0.1), or `"proportional"` (the
    /// body's `damping` alone, as its eigenmodes').
    pub correction_damping: Option<Spanned<toml::Value>>,
    /// The largest share of the static compliance under the mechanism's loads that the basis
    /// may miss before a warning (and the target of `modes = "auto"`); default 0.02.
    pub basis_tolerance: Option<Spanned<f64>>,
    /// The integrator's absolute tolerance for this body's coordinates, as `analysis.atol` (m
    /// with displacement weights); default `analysis.atol`.
    pub atol: Option<Spanned<f64>>,
    /// Distributing couplings by name: node sets that joints and forces attach to
    /// (`coupling = "name"` in a marker).
    pub couplings: Option<BTreeMap<String, Spanned<RawCoupling>>>,
    /// Initial modal coordinates of the retained modes in order (missing ones are zero),
    /// in the mass-normalised coordinates of `flexsens modes` (√kg·m). Default: undeformed.
    pub initial_modal: Option<Spanned<Vec<f64>>>,
    /// Initial modal rates of the retained modes in order (√kg·m/s). Default: at rest in the
    /// body frame.
    pub initial_modal_rates: Option<Spanned<Vec<f64>>>,
}

/// A coupling: a set of nodes (`nodes`, `plane` or `box`), optionally its point (global
/// coordinates at the start, m; default the nodes' centroid) and its kind (`"distributing"`,
/// the default, or `"rigid"`).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawCoupling {
    pub nodes: Option<Spanned<Vec<i64>>>,
    pub plane: Option<Spanned<RawPlane>>,
    #[serde(rename = "box")]
    pub inside: Option<Spanned<[[f64; 3]; 2]>>,
    pub point: Option<Spanned<[f64; 3]>>,
    pub kind: Option<Spanned<String>>,
}

/// A segment of a beam body: its section, length and number of elements.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawSegment {
    /// A `[section.*]` name.
    pub section: Option<Spanned<String>>,
    /// Length along the beam (m); the last segment's defaults to the rest.
    pub length: Option<Spanned<f64>>,
    /// Number of equal elements.
    pub elements: Option<Spanned<i64>>,
}

/// A region of a shell body: its laminate and its elements (a list, or those on a plane or in
/// a box).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawShellRegion {
    /// A `[laminate.*]` name.
    pub laminate: Option<Spanned<String>>,
    /// Element indices (from 0).
    pub elements: Option<Spanned<Vec<i64>>>,
    /// The elements whose nodes all lie on a plane normal to a global axis.
    pub plane: Option<Spanned<RawPlane>>,
    /// The elements whose nodes all lie in the box `[[x0, y0, z0], [x1, y1, z1]]` (m).
    #[serde(rename = "box")]
    pub inside: Option<Spanned<[[f64; 3]; 2]>>,
}

/// A support: a set of nodes (`nodes`, `plane` or `box`) and the dof fixed there (`fix`).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawSupport {
    /// Node indices (from 0).
    pub nodes: Option<Spanned<Vec<i64>>>,
    /// The nodes on a plane normal to a global axis: `{ x = 0.0 }`, `{ y = … }` or `{ z = … }`.
    pub plane: Option<Spanned<RawPlane>>,
    /// The nodes inside the box `[[x0, y0, z0], [x1, y1, z1]]` (m).
    #[serde(rename = "box")]
    pub inside: Option<Spanned<[[f64; 3]; 2]>>,
    /// `"clamped"` (all six dof), `"pinned"` (the three translations) or a list of dof names
    /// `["ux", "uy", "uz", "rx", "ry", "rz"]` (global axes).
    pub fix: Option<Spanned<toml::Value>>,
}

/// A plane normal to a global axis: one of `x`, `y`, `z` (m).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawPlane {
    pub x: Option<f64>,
    pub y: Option<f64>,
    pub z: Option<f64>,
}

/// `{ modes = [i, j], ratios = [ζi, ζj] }` (modes counted from 1), or
/// `{ alpha = α, beta = β }` (`C = αM + βK`; either may be left out, meaning 0).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawDamping {
    pub modes: Option<Spanned<[i64; 2]>>,
    pub ratios: Option<Spanned<[f64; 2]>>,
    /// Mass-proportional coefficient (1/s).
    pub alpha: Option<Spanned<f64>>,
    /// Stiffness-proportional coefficient (s).
    pub beta: Option<Spanned<f64>>,
}
