//! Finite differences as a comparison tool (paper §5; DESIGN.md §6).
//!
//! [`finite_differences`] differentiates any map `b ↦ outputs` (a response history, objective
//! values) by forward or central differences for a list of perturbation sizes. The map decides
//! how each perturbed design is run: independent adaptive runs ([`simulate_response`] with
//! adaptive [`BdfOptions`]: what users would do, with the step-selection noise of §5), or runs
//! that replay the nominal step sequence ([`crate::SensitivityRun::replay_options`]: the
//! derivative of the discrete solution, which the direct method reproduces to round-off).

use nalgebra::DMatrix;

use crate::bdf::{Bdf, BdfOptions};
use crate::model::State;
use crate::response::{Response, response_values};
use crate::sensitivity::SensitivityError;
use crate::system::MultibodySystem;

/// Difference formula.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FdScheme {
    /// `(f(b + δ) − f(b)) / δ`.
    Forward,
    /// `(f(b + δ) − f(b − δ)) / 2δ`.
    Central,
}

/// Perturbation size of each design variable.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Perturbation {
    /// `δ_j = ρ |b_j|` (`ρ` when `b_j = 0`).
    Relative(f64),
    /// `δ_j = δ`.
    Absolute(f64),
}

impl Perturbation {
    /// The step for a variable of value `b`.
    pub fn step(&self, b: f64) -> f64 {
        match *self {
            Perturbation::Relative(r) => {
                if b != 0.0 {
                    r * b.abs()
                } else {
                    r
                }
            }
            Perturbation::Absolute(d) => d,
        }
    }
}

/// Finite-difference derivatives for one perturbation size.
#[derive(Clone, Debug, PartialEq)]
pub struct FiniteDifference {
    pub perturbation: Perturbation,
    /// `δ_j` used for each variable.
    pub steps: Vec<f64>,
    /// `∂f_i/∂b_j`, one row per output, one column per variable.
    pub derivative: DMatrix<f64>,
}

/// Finite-difference derivatives of `f` at `b` for each perturbation in `perturbations`.
/// `f` must return the same number of outputs for every design.
pub fn finite_differences<E>(
    b: &[f64],
    scheme: FdScheme,
    perturbations: &[Perturbation],
    mut f: impl FnMut(&[f64]) -> Result<Vec<f64>, E>,
) -> Result<Vec<FiniteDifference>, E> {
    let base = match scheme {
        FdScheme::Forward => Some(f(b)?),
        FdScheme::Central => None,
    };
    let mut out = Vec::with_capacity(perturbations.len());
    for p in perturbations {
        let steps: Vec<f64> = b.iter().map(|&x| p.step(x)).collect();
        let mut derivative = DMatrix::zeros(0, b.len());
        for (j, &d) in steps.iter().enumerate() {
            let mut bp = b.to_vec();
            bp[j] += d;
            let fp = f(&bp)?;
            let col: Vec<f64> = match &base {
                Some(f0) => fp.iter().zip(f0).map(|(a, c)| (a - c) / d).collect(),
                None => {
                    let mut bm = b.to_vec();
                    bm[j] -= d;
                    let fm = f(&bm)?;
                    fp.iter()
                        .zip(&fm)
                        .map(|(a, c)| (a - c) / (2.0 * d))
                        .collect()
                }
            };
            if j == 0 {
                derivative = DMatrix::zeros(col.len(), b.len());
            }
            for (i, x) in col.iter().enumerate() {
                derivative[(i, j)] = *x;
            }
        }
        out.push(FiniteDifference {
            perturbation: *p,
            steps,
            derivative,
        });
    }
    Ok(out)
}

/// A plain run of `sys` from `state` at `t_out[0]` with the response at every `t_out` (the
/// integrator's dense output between steps; exact step points when `t_out` are step times, as
/// in a replayed run).
pub fn simulate_response(
    sys: &mut MultibodySystem,
    state: &State,
    t_out: &[f64],
    options: BdfOptions,
    response: &Response,
) -> Result<Vec<f64>, SensitivityError> {
    let t0 = t_out[0];
    let t_end = *t_out.last().expect("at least one output time");
    let mut bdf = Bdf::new(options);
    bdf.init(sys, t0, &state.to_vec())?;
    let ys = bdf.integrate_to(sys, t_end, t_out, |_| {})?;
    response_values(sys, t_out, &ys, response)
}
