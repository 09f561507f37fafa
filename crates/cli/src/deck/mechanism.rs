//! The mechanism part of a deck: rigid bodies, joints and drivers, forces, requested responses
//! and the analysis settings of `flexsens run`.
//!
//! Positions and axes are given in global coordinates in the initial configuration (where the
//! joint is, where the body is); angles are degrees, angular rates degrees per second, unless a
//! string with a unit is given (`"150 rad/s"`, `"30 deg"`).

use serde::Deserialize;
use toml::Spanned;

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
    /// `"constant-speed"`, `"polynomial"` or `"ramp"`.
    pub kind: Option<Spanned<String>>,
    /// Constant speed: value at t = 0.
    pub initial: Option<Spanned<toml::Value>>,
    /// Constant speed: rate (deg/s or m/s; strings with units for angles).
    pub rate: Option<Spanned<toml::Value>>,
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
    /// `"gravity"`, `"point-force"`, `"point-torque"` or `"spring-damper"`.
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
    /// Spring–damper ends.
    pub a: Option<Spanned<RawMarker>>,
    pub b: Option<Spanned<RawMarker>>,
    /// Spring–damper: stiffness (N/m), damping (N·s/m), free length (m, default: the initial
    /// distance).
    pub stiffness: Option<Spanned<f64>>,
    pub damping: Option<Spanned<f64>>,
    pub free_length: Option<Spanned<f64>>,
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
    /// `"reaction"`, `"modal"`, `"energy"` or `"constraint-violation"`.
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
    /// Adaptive: relative and absolute tolerances (defaults 1e-6, 1e-8).
    pub rtol: Option<Spanned<f64>>,
    pub atol: Option<Spanned<f64>>,
    /// Adaptive: highest BDF order (1–5, default 5); fixed: the order (default 2).
    pub order: Option<Spanned<i64>>,
    /// Fixed: the step (s).
    pub step: Option<Spanned<f64>>,
    /// Baumgarte stabilisation `{ alpha, beta }` (1/s, default 1 and 1), or `false`.
    pub baumgarte: Option<Spanned<toml::Value>>,
    /// Redundant constraint equations: `"remove"` (default) or `"error"`.
    pub redundant: Option<Spanned<String>>,
}
