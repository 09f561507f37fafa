//! The deck as written: serde mirrors of the TOML tables. Every key is documented in
//! `docs/decks.md`. The validation modules read these; none of them is read from here.
//!
//! Positions and axes are given in global coordinates in the initial configuration (where the
//! joint is, where the body is); angles are degrees, angular rates degrees per second, unless a
//! string with a unit is given (`"150 rad/s"`, `"30 deg"`).

use std::collections::BTreeMap;

use serde::Deserialize;
use toml::Spanned;

mod body;
pub use body::*;

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
    pub section: BTreeMap<String, Spanned<RawSection>>,
    /// Flexible bodies by name.
    #[serde(default)]
    pub body: BTreeMap<String, Spanned<RawBody>>,
    /// Rigid bodies by name.
    #[serde(default)]
    pub rigid: BTreeMap<String, Spanned<RawRigid>>,
    /// Joints and drivers by name.
    #[serde(default)]
    pub joint: BTreeMap<String, Spanned<RawJoint>>,
    /// Force elements by name.
    #[serde(default)]
    pub force: BTreeMap<String, Spanned<RawForce>>,
    /// Requested responses by name.
    #[serde(default)]
    pub response: BTreeMap<String, Spanned<RawResponse>>,
    /// Time integration settings of `flexsens run`.
    pub analysis: Option<Spanned<RawAnalysis>>,
    /// Design variables by name (ply angles, degrees).
    #[serde(default)]
    pub design: BTreeMap<String, Spanned<RawDesign>>,
    /// Scalar objectives of responses by name.
    #[serde(default)]
    pub objective: BTreeMap<String, Spanned<RawObjective>>,
    /// Settings of the direct sensitivity analysis.
    pub sensitivity: Option<Spanned<RawSensitivity>>,
    /// Finite-difference comparisons.
    pub finite_differences: Option<Spanned<RawFiniteDifferences>>,
    /// The problem of `flexsens optimize`.
    pub optimize: Option<Spanned<RawOptimize>>,
    /// The operating points of `flexsens static`.
    pub operating: Option<Spanned<RawOperating>>,
}

/// `[operating]`: the static equilibrium, or the steady spins about an angle driver's axis,
/// of `flexsens static`, and the modes linearised about them.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawOperating {
    /// The angle driver (one marker on the ground) whose axis the mechanism spins about.
    pub driver: Option<Spanned<String>>,
    /// The spin speeds (numbers in deg/s, or strings with a unit: `"750 rpm"`); default 0.
    pub speeds: Option<Spanned<Vec<Spanned<toml::Value>>>>,
    /// The drivers' time of the operating points (s; default the analysis's start).
    pub time: Option<Spanned<f64>>,
    /// Times of the run (s) about whose states the mechanism is linearised, instead of
    /// equilibria.
    pub at: Option<Spanned<Vec<Spanned<f64>>>>,
    /// How many linearised modes are reported (default 10).
    pub modes: Option<Spanned<i64>>,
    /// The rotor orders drawn on the Campbell diagram (default 1 to 4).
    pub orders: Option<Spanned<Vec<Spanned<i64>>>>,
}

/// `[optimize]`: minimise or maximise one quantity over the `[design.*]` variables (within
/// their `lower`, `upper` bounds) subject to constraints on others.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawOptimize {
    /// The quantity to minimise: `"objective.NAME"`, `"frequency.BODY.K"` or `"mass.BODY"`.
    pub minimize: Option<Spanned<String>>,
    /// The quantity to maximise (instead of `minimize`).
    pub maximize: Option<Spanned<String>>,
    /// Constraints (`[[optimize.constraint]]`).
    #[serde(default)]
    pub constraint: Vec<Spanned<RawConstraint>>,
    /// The largest number of evaluations of the model per start (default 100).
    pub max_evaluations: Option<Spanned<i64>>,
    /// Convergence: the relative change of the objective between iterations (default 1e-8).
    pub tolerance: Option<Spanned<f64>>,
    /// Convergence: a feasible evaluation's KKT stationarity at most this (default: none).
    pub kkt_tolerance: Option<Spanned<f64>>,
    /// More starting designs, each a list of the design variables' values (in the order of
    /// their names); the deck's own values are always the first start.
    pub starts: Option<Spanned<Vec<Vec<f64>>>>,
}

/// One constraint of `[optimize]`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawConstraint {
    /// The constrained quantity (as `minimize`).
    pub quantity: Option<Spanned<String>>,
    /// The quantity must be at least this.
    pub min: Option<Spanned<f64>>,
    /// The quantity must be at most this.
    pub max: Option<Spanned<f64>>,
    /// The quantity must equal this number, or `"nominal"`: its value at the deck's design.
    pub equals: Option<Spanned<toml::Value>>,
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
    /// Strengths (Pa, compressive ones as magnitudes): along the fibres, across them in the
    /// plane, through the thickness, and in shear.
    #[serde(rename = "Xt")]
    pub xt: Option<Spanned<f64>>,
    #[serde(rename = "Xc")]
    pub xc: Option<Spanned<f64>>,
    #[serde(rename = "Yt")]
    pub yt: Option<Spanned<f64>>,
    #[serde(rename = "Yc")]
    pub yc: Option<Spanned<f64>>,
    #[serde(rename = "Zt")]
    pub zt: Option<Spanned<f64>>,
    #[serde(rename = "Zc")]
    pub zc: Option<Spanned<f64>>,
    #[serde(rename = "S12")]
    pub s12: Option<Spanned<f64>>,
    #[serde(rename = "S13")]
    pub s13: Option<Spanned<f64>>,
    #[serde(rename = "S23")]
    pub s23: Option<Spanned<f64>>,
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

/// A beam cross-section: a generated shape or a mesh file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawSection {
    /// `"rectangle"`, `"circle"`, `"tube"`, `"box"`, `"channel"`, `"i-beam"`, `"mesh"` or
    /// `"properties"`.
    pub shape: Option<Spanned<String>>,
    /// Circle: radius (m).
    pub radius: Option<Spanned<f64>>,
    /// Rectangle and box: width along x₂ (m).
    pub width: Option<Spanned<f64>>,
    /// Rectangle and box: height along x₃ (m).
    pub height: Option<Spanned<f64>>,
    /// Rectangle and circle: material name.
    pub material: Option<Spanned<String>>,
    /// Rectangle and circle: fibre angle from the beam axis about x₃ (degrees, default 0).
    pub angle: Option<Spanned<f64>>,
    /// Rectangle and box: elements `[along the width, along the height]`; circle: `[around the
    /// rim, from the core to the rim]`.
    pub elements: Option<Spanned<Vec<Spanned<i64>>>>,
    /// Tube: inner radius (m).
    pub inner_radius: Option<Spanned<f64>>,
    /// Tube: elements around the circumference (default 48).
    pub elements_around: Option<Spanned<i64>>,
    /// Tube: plies from the inside out.
    pub plies: Option<Spanned<Vec<Spanned<RawSectionPly>>>>,
    /// Tube (instead of `plies`) and box (all four walls): a `[laminate.*]` name, bottom ply
    /// innermost.
    pub laminate: Option<Spanned<String>>,
    /// Tube with `laminate`, and box: elements through each ply's thickness (default 2 / 1).
    pub elements_per_ply: Option<Spanned<i64>>,
    /// Box: a laminate name per wall (`top`, `bottom`, `left`, `right`), innermost ply first.
    pub walls: Option<Spanned<RawWalls>>,
    /// Mesh: path of a Gmsh `.msh` (v4.1 ASCII) or simple-format file, relative to the deck.
    pub file: Option<Spanned<String>>,
    /// Mesh: `"gmsh"` or `"simple"` (default from the extension: `.msh` is Gmsh).
    pub format: Option<Spanned<String>>,
    /// Mesh (Gmsh): the properties of each physical surface group, by name.
    pub regions: Option<Spanned<BTreeMap<String, Spanned<RawRegion>>>>,
    /// Properties: the 6×6 stiffness about the origin, row by row (N, N·m, N·m²).
    pub stiffness: Option<Spanned<Vec<Vec<f64>>>>,
    /// Properties: axial stiffness about the tension centre (N).
    #[serde(rename = "EA")]
    pub ea: Option<Spanned<f64>>,
    /// Properties: shear stiffness along x₂ at the shear centre (N).
    #[serde(rename = "GA2")]
    pub ga2: Option<Spanned<f64>>,
    /// Properties: shear stiffness along x₃ at the shear centre (N).
    #[serde(rename = "GA3")]
    pub ga3: Option<Spanned<f64>>,
    /// Properties: torsion stiffness about the shear centre (N·m²).
    #[serde(rename = "GJ")]
    pub gj: Option<Spanned<f64>>,
    /// Properties: bending stiffness about x₂ through the tension centre (N·m²).
    #[serde(rename = "EI2")]
    pub ei2: Option<Spanned<f64>>,
    /// Properties: bending stiffness about x₃ through the tension centre (N·m²).
    #[serde(rename = "EI3")]
    pub ei3: Option<Spanned<f64>>,
    /// Properties: tension centre `[x₂, x₃]` (m, default the origin).
    pub tension_centre: Option<Spanned<[f64; 2]>>,
    /// Properties: shear centre `[x₂, x₃]` (m, default the origin).
    pub shear_centre: Option<Spanned<[f64; 2]>>,
    /// Properties: the 6×6 mass matrix about the origin, row by row (instead of the mass per
    /// length, mass centre and inertias).
    pub mass_matrix: Option<Spanned<Vec<Vec<f64>>>>,
    /// Properties: mass per unit length (kg/m).
    pub mass_per_length: Option<Spanned<f64>>,
    /// Properties: mass centre `[x₂, x₃]` (m, default the origin).
    pub mass_centre: Option<Spanned<[f64; 2]>>,
    /// Properties: mass moments of inertia per unit length about the mass centre,
    /// `[I₂₂, I₃₃]` or `[I₂₂, I₃₃, I₂₃]` (kg·m).
    pub inertia: Option<Spanned<Vec<f64>>>,
}

/// A ply of a tube wall.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawSectionPly {
    pub material: Option<Spanned<String>>,
    pub thickness: Option<Spanned<f64>>,
    /// Fibre angle from the beam axis about the wall normal (degrees).
    pub angle: Option<Spanned<f64>>,
    /// Elements through the thickness (default 2).
    pub elements: Option<Spanned<i64>>,
}

/// Laminates of the walls of a box (four), a channel (no right wall) or an I beam (top,
/// bottom, web).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawWalls {
    pub top: Option<Spanned<String>>,
    pub bottom: Option<Spanned<String>>,
    pub left: Option<Spanned<String>>,
    pub right: Option<Spanned<String>>,
    pub web: Option<Spanned<String>>,
}

/// A Gmsh physical group's material, ply angle and wall frame.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawRegion {
    pub material: Option<Spanned<String>>,
    /// Ply angle (degrees, default 0).
    pub angle: Option<Spanned<f64>>,
    /// Instead of `material` and `angle`: the region is ply `ply` of this laminate (its
    /// material and angle, moved by the laminate's design variables).
    pub laminate: Option<Spanned<String>>,
    /// With `laminate`: the ply's index in the laminate's stack (from 0, bottom first, the
    /// mirrored plies of a symmetric laminate included).
    pub ply: Option<Spanned<i64>>,
    /// `"tangent"` (straight wall, default) or `"radial"` (wall curved around `centre`).
    pub frame: Option<Spanned<String>>,
    /// With `frame = "tangent"`: angle of the wall tangent from x₂ towards x₃ (degrees, default 0).
    pub tangent_angle: Option<Spanned<f64>>,
    /// With `frame = "radial"`: the centre `[x₂, x₃]` (m, default `[0, 0]`).
    pub centre: Option<Spanned<[f64; 2]>>,
}

/// A design variable as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawDesign {
    /// `"ply-angle"` (the default), `"ply-thickness"`, `"material"`, `"rigid-mass"`,
    /// `"rigid-inertia"`, `"section-property"`, `"section-angle"` or `"actuator-gain"`.
    pub kind: Option<Spanned<String>>,
    /// The laminate whose plies move.
    pub laminate: Option<Spanned<String>>,
    /// Indices of the plies (as listed in the deck, from 0); default: all of them.
    pub plies: Option<Spanned<Vec<i64>>>,
    /// `dθ_i/db` of each listed ply (default 1; e.g. `[1, -1]` for a `[θ/−θ]` pair).
    pub factors: Option<Spanned<Vec<f64>>>,
    /// Rigid-body kinds: the rigid body.
    pub body: Option<Spanned<String>>,
    /// `"rigid-inertia"`: the principal axis (`"x"`, `"y"` or `"z"`, body axes).
    pub axis: Option<Spanned<String>>,
    /// `"material"`: the material.
    pub material: Option<Spanned<String>>,
    /// `"material"`: the constant (`"E1"` … `"nu23"`, `"E"` of an isotropic one, `"density"`).
    pub constant: Option<Spanned<String>>,
    /// `"section-property"`: the section (given by its properties).
    pub section: Option<Spanned<String>>,
    /// `"section-property"`: the entry (`"EA"` … `"EI3"`, `"mass_per_length"`, `"I22"`,
    /// `"I33"`).
    pub entry: Option<Spanned<String>>,
    /// `"actuator-gain"`: the actuator (a `[force.NAME]` with a PD law).
    pub force: Option<Spanned<String>>,
    /// `"actuator-gain"`: `"kp"` or `"kd"`.
    pub gain: Option<Spanned<String>>,
    /// `flexsens optimize`: the variable's lower bound (its unit).
    pub lower: Option<Spanned<f64>>,
    /// `flexsens optimize`: the variable's upper bound (its unit).
    pub upper: Option<Spanned<f64>>,
}

/// A scalar objective of a response history.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawObjective {
    /// A `[response.*]` name.
    pub response: Option<Spanned<String>>,
    /// `"integral"`, `"mean"`, `"rms"`, `"max"`, `"min"`, `"final"`, `"ks"` or `"at"`.
    pub kind: Option<Spanned<String>>,
    /// With `kind = "at"`: the time (s).
    pub time: Option<Spanned<f64>>,
    /// `[t0, t1]` (s): the objective of the history within these times only.
    pub window: Option<Spanned<Vec<Spanned<f64>>>>,
    /// With `kind = "ks"`: the aggregation parameter ρ (in the inverse of the response's unit).
    pub rho: Option<Spanned<f64>>,
}

/// Settings of the direct sensitivity analysis.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawSensitivity {
    /// `false` skips the sensitivities (e.g. in a sweep); default `true` when the deck declares
    /// design variables.
    pub enabled: Option<Spanned<bool>>,
    /// `"simultaneous"` (default), `"direct"` (exact derivative of the discrete solution),
    /// `"corrector"`, `"adjoint"` (the objectives' gradients alone) or `"auto"` (the adjoint
    /// where it is the cheaper, else `"simultaneous"`).
    pub method: Option<Spanned<String>>,
    /// Mode derivatives: `"updated"` (default) or `"fixed"`.
    pub modes: Option<Spanned<String>>,
    /// Include the sensitivities in the step-size control (default `false`).
    pub error_control: Option<Spanned<bool>>,
    /// The adjoint method's memory for the run's states (MiB; default 16): beyond it the
    /// states are recomputed from checkpoints.
    pub adjoint_memory: Option<Spanned<f64>>,
}

/// Finite-difference comparisons to run.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawFiniteDifferences {
    /// `false` skips the comparisons (default `true`).
    pub enabled: Option<Spanned<bool>>,
    /// `"forward"` (default) or `"central"`.
    pub scheme: Option<Spanned<String>>,
    /// `"relative"` (default: δ = size·|b|) or `"absolute"` (δ = size, degrees).
    pub perturbation: Option<Spanned<String>>,
    /// Perturbation sizes.
    pub sizes: Option<Spanned<Vec<f64>>>,
    /// `"replay"` (the nominal step sequence, default), `"adaptive"` (independent runs) or
    /// `"both"`.
    pub steps: Option<Spanned<String>>,
}

/// A rigid body.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawRigid {
    /// Mass (kg).
    pub mass: Option<Spanned<f64>>,
    /// Inertia about the centre of mass in body axes (kg·m²): `[Ixx, Iyy, Izz]` or a 3×3 matrix.
    pub inertia: Option<Spanned<toml::Value>>,
    /// Initial position of the centre of mass (m).
    pub position: Option<Spanned<[f64; 3]>>,
    /// Initial orientation: rotation about `axis` by `angle` (body axes → global).
    pub orientation: Option<Spanned<RawRotation>>,
    /// Initial velocity of the centre of mass (m/s).
    pub velocity: Option<Spanned<[f64; 3]>>,
    /// Initial angular velocity, global components (deg/s, or strings with units).
    pub angular_velocity: Option<Spanned<[toml::Value; 3]>>,
    /// The integrator's absolute tolerance for this body's coordinates, as `analysis.atol` (m
    /// with displacement weights); default `analysis.atol`.
    pub atol: Option<Spanned<f64>>,
}

/// A rotation by `angle` about `axis`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawRotation {
    pub axis: Option<Spanned<[f64; 3]>>,
    pub angle: Option<Spanned<toml::Value>>,
}

/// Where a joint or force acts.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawMarker {
    /// A rigid or flexible body name, or `"ground"`.
    pub body: Option<Spanned<String>>,
    /// A point, global coordinates in the initial configuration (m).
    pub point: Option<Spanned<[f64; 3]>>,
    /// A node of a flexible body (index from 0), instead of `point`.
    pub node: Option<Spanned<i64>>,
    /// A coupling of a flexible body (`[body.*.couplings]`), instead of `point` or `node`.
    pub coupling: Option<Spanned<String>>,
    /// The joint axis, global components (default z).
    pub axis: Option<Spanned<[f64; 3]>>,
    /// A direction normal to the axis from which driver angles are measured (default: any).
    pub reference: Option<Spanned<[f64; 3]>>,
}

/// A joint or driver between two markers.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawJoint {
    /// `"spherical"`, `"revolute"`, `"universal"`, `"cylindrical"`, `"translational"`,
    /// `"fixed"`, `"angle-driver"` or `"distance-driver"`.
    pub kind: Option<Spanned<String>>,
    pub a: Option<Spanned<RawMarker>>,
    pub b: Option<Spanned<RawMarker>>,
    /// Drivers: the prescribed relative angle (degrees) or distance (m) in time.
    pub motion: Option<Spanned<RawMotion>>,
}

/// A prescribed motion `f(t)`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawMotion {
    /// `"constant-speed"`, `"polynomial"`, `"ramp"` or `"spin-up"`.
    pub kind: Option<Spanned<String>>,
    /// Constant speed: value at t = 0.
    pub initial: Option<Spanned<toml::Value>>,
    /// Constant speed, spin-up: rate (deg/s or m/s; strings with units for angles); the final
    /// rate of a spin-up.
    pub rate: Option<Spanned<toml::Value>>,
    /// Spin-up: time to reach the rate from rest (s).
    pub duration: Option<Spanned<f64>>,
    /// Polynomial: `f = Σ c_i tⁱ` (degrees·s⁻ⁱ or m·s⁻ⁱ).
    pub coefficients: Option<Spanned<Vec<f64>>>,
    /// Ramp: from `from` (held until `t0`) to `to` (reached at `t1`) with zero end velocity and
    /// acceleration.
    pub from: Option<Spanned<toml::Value>>,
    pub to: Option<Spanned<toml::Value>>,
    pub t0: Option<Spanned<f64>>,
    pub t1: Option<Spanned<f64>>,
}

/// A force element.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawForce {
    /// `"gravity"`, `"point-force"`, `"point-torque"`, `"spring-damper"`, `"joint-torque"` or
    /// `"joint-force"`.
    pub kind: Option<Spanned<String>>,
    /// Gravity: acceleration (m/s²).
    pub acceleration: Option<Spanned<[f64; 3]>>,
    /// Point force/torque: where.
    pub at: Option<Spanned<RawMarker>>,
    /// Point force/torque: constant value (N or N·m).
    pub value: Option<Spanned<[f64; 3]>>,
    /// Point force/torque: piecewise-linear table.
    pub table: Option<Spanned<RawTable>>,
    /// Point force/torque: `"global"` (default) or `"body"` components.
    pub frame: Option<Spanned<String>>,
    /// Spring–damper ends; a joint torque's markers (the torque about `a`'s axis).
    pub a: Option<Spanned<RawMarker>>,
    pub b: Option<Spanned<RawMarker>>,
    /// Spring–damper: stiffness (N/m), damping (N·s/m), free length (m, default: the initial
    /// distance).
    pub stiffness: Option<Spanned<f64>>,
    pub damping: Option<Spanned<f64>>,
    pub free_length: Option<Spanned<f64>>,
    /// Joint torque: a constant (N·m) or `{ times = [...], values = [...] }`.
    pub torque: Option<Spanned<toml::Value>>,
    /// Joint force: a constant (N) or `{ times = [...], values = [...] }`.
    pub force: Option<Spanned<toml::Value>>,
    /// Joint torque or force: a control law tracking a motion.
    pub control: Option<Spanned<RawControl>>,
}

/// A joint actuator's control law: `{ kind = "pd", kp, kd, motion }`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawControl {
    pub kind: Option<Spanned<String>>,
    /// Gains (N·m/rad, N·m·s/rad for a torque; N/m, N·s/m for a force).
    pub kp: Option<Spanned<f64>>,
    pub kd: Option<Spanned<f64>>,
    /// The tracked relative angle or displacement (as an angle or distance driver's motion).
    pub motion: Option<Spanned<RawMotion>>,
}

/// `{ times = [...], values = [[x, y, z], ...] }`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawTable {
    pub times: Option<Spanned<Vec<f64>>>,
    pub values: Option<Spanned<Vec<[f64; 3]>>>,
}

/// A requested response (time history).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawResponse {
    /// `"position"`, `"velocity"`, `"nodal-displacement"`, `"mid-node-deflection"`,
    /// `"reaction"`, `"modal"`, `"energy"`, `"constraint-violation"`, `"actuator-torque"`,
    /// `"actuator-force"`, `"actuator-power"`, `"point-position"`, `"point-velocity"`,
    /// `"point-acceleration"`, `"ply-stress"` or `"ply-failure"`.
    pub kind: Option<Spanned<String>>,
    pub body: Option<Spanned<String>>,
    pub joint: Option<Spanned<String>>,
    /// `"x"`, `"y"`, `"z"` (positions, velocities, forces), `"ux"`…`"rz"` (nodal
    /// displacements), `"fx"`…`"mz"` (reactions).
    pub component: Option<Spanned<String>>,
    pub node: Option<Spanned<i64>>,
    /// Mid-node deflection: `[first, middle, last]` nodes (default for a beam: ends and middle).
    pub nodes: Option<Spanned<[i64; 3]>>,
    /// Mid-node deflection: normal of the mechanism plane (default z).
    pub normal: Option<Spanned<[f64; 3]>>,
    /// Modal coordinate: mode number from 1.
    pub mode: Option<Spanned<i64>>,
    /// Actuator torque, force and power: the `[force.NAME]` of kind `"joint-torque"` or
    /// `"joint-force"`.
    pub force: Option<Spanned<String>>,
    /// Point kinematics: the marker whose point is followed.
    pub at: Option<Spanned<RawMarker>>,
    /// Point kinematics: the marker whose point's position, velocity or acceleration is
    /// subtracted.
    pub relative_to: Option<Spanned<RawMarker>>,
    /// Ply stress and failure: the element (from 0; a failure index's default: every
    /// element).
    pub element: Option<Spanned<i64>>,
    /// Ply failure: the elements whose nodes all lie in the box `[[x0, y0, z0], [x1, y1,
    /// z1]]` (m; instead of `element`).
    #[serde(rename = "box")]
    pub inside: Option<Spanned<[[f64; 3]; 2]>>,
    /// Ply stress and failure of a shell body: the ply (from 0, bottom first; a failure
    /// index's default: every ply).
    pub ply: Option<Spanned<i64>>,
    /// Ply stress and failure of a shell body: `"bottom"`, `"middle"` or `"top"` of the ply (a
    /// failure index's default: all three).
    pub position: Option<Spanned<String>>,
    /// Ply stress and failure of a beam body: the section's region (from 0; a failure index's
    /// default: every region).
    pub region: Option<Spanned<i64>>,
    /// Ply stress of a beam body: the point `[x₂, x₃]` of the section (m) whose nearest
    /// integration point in the region is read.
    pub section_point: Option<Spanned<[f64; 2]>>,
    /// Ply failure: the criterion (`"tsai-wu"`, `"max-stress"`, …).
    pub criterion: Option<Spanned<String>>,
    /// Ply failure over several points: the Kreisselmeier–Steinhauser parameter of their
    /// aggregate (default: their largest).
    pub rho: Option<Spanned<f64>>,
}

/// Settings of the time integration.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawAnalysis {
    /// Start time (s, default 0).
    pub t_start: Option<Spanned<f64>>,
    /// End time (s).
    pub t_end: Option<Spanned<f64>>,
    /// Interval of the output times (s, default (t_end − t_start)/500).
    pub output_step: Option<Spanned<f64>>,
    /// `"adaptive"` (default) or `"fixed"`.
    pub integrator: Option<Spanned<String>>,
    /// Relative and absolute tolerances (defaults 1e-6; 1e-4 · rtol · the mechanism's size in
    /// m, or 1e-8 with `error_weights = "uniform"`).
    pub rtol: Option<Spanned<f64>>,
    pub atol: Option<Spanned<f64>>,
    /// `"displacement"` (default: `atol` a displacement, each coordinate's tolerance what
    /// moves its body by it) or `"uniform"` (`atol` on every state component).
    pub error_weights: Option<Spanned<String>>,
    /// Adaptive: highest BDF order (1–5, default 5); fixed: the order (default 2).
    pub order: Option<Spanned<i64>>,
    /// Fixed: the step (s).
    pub step: Option<Spanned<f64>>,
    /// Baumgarte stabilisation `{ alpha, beta }` (1/s, default 1 and 1), or `false`.
    pub baumgarte: Option<Spanned<toml::Value>>,
    /// Redundant constraint equations: `"remove"` (default), `"reselect"` or `"error"`.
    pub redundant: Option<Spanned<String>>,
    /// Adaptive: the largest step (s, default unlimited).
    pub max_step: Option<Spanned<f64>>,
    /// Adaptive: the first step (s, default estimated).
    pub initial_step: Option<Spanned<f64>>,
    /// Adaptive: hold every oscillatory eigenvalue inside the stability region of the order
    /// used (default true).
    pub stability_limit: Option<Spanned<bool>>,
    /// The largest position-constraint violation a step may reach (m, default 5 % of the
    /// mechanism's size).
    pub max_violation: Option<Spanned<f64>>,
}

#[cfg(test)]
mod tests;
