//! Finite differences as a comparison tool (paper §5; docs/design.md §3).
//!
//! [`finite_differences`] differentiates any map `b ↦ outputs` (a response history, objective
//! values) by forward or central differences for a list of perturbation sizes. The map decides
//! how each perturbed design is run: independent adaptive runs ([`simulate_response`] with
//! adaptive [`BdfOptions`]: what users would do, with the step-selection noise of §5), or runs
//! that replay the nominal step sequence ([`crate::SensitivityRun::replay_options`]: the
//! derivative of the discrete solution, which the direct method reproduces up to the nominal
//! run's Newton tolerance, see `docs/performance.md`). The perturbed designs are independent:
//! [`finite_difference_designs`] lists them, so that a caller can run them in parallel, and
//! [`finite_differences_from`] makes the derivatives of their values.

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
    f: impl FnMut(&[f64]) -> Result<Vec<f64>, E>,
) -> Result<Vec<FiniteDifference>, E> {
    let values = finite_difference_designs(b, scheme, perturbations)
        .iter()
        .map(|d| d.as_slice())
        .map(f)
        .collect::<Result<Vec<_>, E>>()?;
    Ok(finite_differences_from(b, scheme, perturbations, &values))
}

/// The designs at which [`finite_differences`] evaluates its function, in its order: for the
/// forward scheme `b` first; then for each perturbation and variable `j`, `b + δ_j e_j` and,
/// for the central scheme, `b − δ_j e_j`. The evaluations are independent (e.g. in parallel);
/// [`finite_differences_from`] makes the derivatives of their values.
pub fn finite_difference_designs(
    b: &[f64],
    scheme: FdScheme,
    perturbations: &[Perturbation],
) -> Vec<Vec<f64>> {
    let mut designs = Vec::new();
    if scheme == FdScheme::Forward {
        designs.push(b.to_vec());
    }
    for p in perturbations {
        for (j, &x) in b.iter().enumerate() {
            let d = p.step(x);
            let signs: &[f64] = match scheme {
                FdScheme::Forward => &[1.0],
                FdScheme::Central => &[1.0, -1.0],
            };
            for &sign in signs {
                let mut bj = b.to_vec();
                bj[j] += sign * d;
                designs.push(bj);
            }
        }
    }
    designs
}

/// [`finite_differences`] from the values at [`finite_difference_designs`] (same order).
pub fn finite_differences_from(
    b: &[f64],
    scheme: FdScheme,
    perturbations: &[Perturbation],
    values: &[Vec<f64>],
) -> Vec<FiniteDifference> {
    let mut next = values.iter();
    let base = match scheme {
        FdScheme::Forward => next.next(),
        FdScheme::Central => None,
    };
    let mut out = Vec::with_capacity(perturbations.len());
    for p in perturbations {
        let steps: Vec<f64> = b.iter().map(|&x| p.step(x)).collect();
        let mut derivative = DMatrix::zeros(0, b.len());
        for (j, &d) in steps.iter().enumerate() {
            let fp = next.next().expect("a value for every design");
            let col: Vec<f64> = match base {
                Some(f0) => fp.iter().zip(f0).map(|(a, c)| (a - c) / d).collect(),
                None => {
                    let fm = next.next().expect("a value for every design");
                    fp.iter()
                        .zip(fm)
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
    out
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
