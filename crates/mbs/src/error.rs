//! Errors of model building, constraint handling and time integration.

use fem::ModalBodyError;

/// An inconsistent model.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ModelError {
    #[error("body `{name}`: {reason}")]
    BadBody { name: String, reason: &'static str },
    #[error("flexible body `{name}`: {source}")]
    BadModalBody {
        name: String,
        #[source]
        source: ModalBodyError,
    },
    #[error("{owner}: {reason}")]
    BadMarker { owner: String, reason: &'static str },
}

/// Failure of the constraint machinery (redundancy, assembly, initial conditions, solve).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ConstraintError {
    #[error("redundant constraint equations: {}", describe(.equations))]
    Redundant {
        /// `(joint name, equation index within the joint)` of each dependent equation.
        equations: Vec<(String, usize)>,
    },
    #[error(
        "position assembly did not converge: |Φ| = {residual:.3e} after {iterations} iterations"
    )]
    AssemblyFailed { residual: f64, iterations: usize },
    /// The initial state cannot satisfy a constraint by moving the rigid-body coordinates
    /// alone (the elastic coordinates are held at their stated values).
    #[error(
        "the constraints cannot be met with the stated elastic state: joint `{joint}` equation \
         {equation} ({bodies}) keeps |{quantity}| = {residual:.3e} after the rigid-body \
         coordinates were adjusted; {also}check the joint's points and the initial modal \
         coordinates and rates of its flexible bodies"
    )]
    Inconsistent {
        joint: String,
        equation: usize,
        /// The bodies the joint connects, e.g. "bodies `crank` and `rod`".
        bodies: String,
        /// The other joints between the same bodies, which may contradict this one, as the
        /// start of a sentence ("joint `drive` also connects them and may contradict it;
        /// else "), or empty.
        also: String,
        /// `Φ` (positions) or `Φ̇` (velocities).
        quantity: &'static str,
        residual: f64,
    },
    /// An angle driver's equation holds half a turn from its angle too: the assembly reached
    /// that solution.
    #[error(
        "angle driver `{joint}` would hold its body half a turn from its angle at t = {t} s: \
         assembling from the mechanism as drawn reached the other solution of its equation \
         (ρ sin(f − θ) = 0 holds at θ = f + 180° too); draw the mechanism nearer the driver's \
         angle at the start, or start its motion at the drawn angle"
    )]
    ReversedDriver { joint: String, t: f64 },
    /// Neither the rigid-body coordinates nor, after them, the flexible bodies' elastic
    /// coordinates at the least strain energy can satisfy a constraint.
    #[error(
        "the constraints cannot be met even with the flexible bodies deformed: joint `{joint}` \
         equation {equation} ({bodies}) keeps |Φ| = {residual:.3e} after the rigid-body and the \
         elastic coordinates were adjusted (at the least strain energy); {also}the misfit may be \
         more than the bodies' modes can take up: check the joint's points and axes"
    )]
    InconsistentElastically {
        joint: String,
        equation: usize,
        bodies: String,
        also: String,
        residual: f64,
    },
    #[error(
        "the initial state cannot be projected onto the joints at t = {t} s: the mass matrix of \
         the rigid-body coordinates is singular on the motion the joints leave free (a body with \
         a zero mass or a zero principal inertia?)"
    )]
    SingularStart { t: f64 },
    #[error("Baumgarte stabilisation α = {alpha}, β = {beta}: both must be finite and ≥ 0 (1/s)")]
    BadStabilisation { alpha: f64, beta: f64 },
    #[error("the augmented matrix of Eq. (12) is singular at t = {t} s")]
    Singular { t: f64 },
    /// `cause`: what was found wrong, when something was (starts with "; ").
    #[error("non-finite accelerations at t = {t} s{cause}")]
    NonFinite { t: f64, cause: String },
}

fn describe(eqs: &[(String, usize)]) -> String {
    eqs.iter()
        .map(|(j, i)| format!("joint `{j}` equation {i}"))
        .collect::<Vec<_>>()
        .join(", ")
}
