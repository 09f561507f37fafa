//! The discrete adjoint of a run: the gradient of one objective with respect to every design
//! variable by one backward sweep over the accepted steps (docs/design.md §3, "The adjoint
//! method").
//!
//! The forward run takes, at step `n` of order `k`, `Σ_{j=0..k} c_{n,j} y_{n−j} = f(y_n, b)`.
//! For an objective `J = Σ_n Σ_r w_{r,n} ψ_r(t_n, y_n, b)` of response histories on its
//! recorded points, the adjoints `λ_n` solve, from the last step back,
//!
//! ```text
//! (c_{n,0} I − f_y(y_n))ᵀ λ_n = ∂J/∂y_n − Σ_{m>n} c_{m,m−n} λ_m
//! ```
//!
//! and `dJ/db = ∂J/∂b + Σ_n λ_nᵀ f_b(y_n) + (∂J/∂y_0 − Σ_m c_{m,m} λ_m)ᵀ S_0`: the same number
//! the direct method gives (`Σ_n ∂J/∂y_n S_n + ∂J/∂b` with `S_n` the exact derivative of the
//! discrete solution), for every variable at once.
//!
//! The products with `f_b` and `∂ψ/∂b` are not formed per variable: the model's data (modes,
//! frequencies, masses, the invariants made from them) are inputs of a reverse-mode tape
//! ([`TapedModel`], [`sens::Rev`]); each step's evaluation, swept backwards, adds `λ_nᵀ ∂f/∂p`
//! to the data's adjoint `p̄`, and at the end `p̄` is contracted once with each variable's
//! derivative of the data, which the [`DesignModel`]'s chunks carry as their tangents.

use std::cell::Cell;

use nalgebra::DMatrix;
use sens::{DenseLu, Dual, Rev, Scalar, Tape};

use crate::bdf::{OdeSystem, bdf_coefficients};
use crate::model::Model;
use crate::response::Response;
use crate::sensitivity::{DesignModel, SensitivityError, SensitivityRun};
use crate::system::{MultibodySystem, Solution};

/// A model whose data are inputs of the current thread's reverse-mode tape, with the data's
/// adjoints accumulated over the evaluations swept so far.
///
/// The data and the inertia invariants made from them stay on the tape for the model's life
/// (it is rewound to where it began when the model is dropped); each evaluation is recorded
/// above them, swept, and rewound, its adjoints on the data part kept. Models on one thread
/// must be dropped in the reverse order of their making (the tape is a stack).
pub struct TapedModel {
    model: Model<Rev>,
    /// The tape's length before the data: the data are nodes `base..base + n_data`.
    base: usize,
    n_data: usize,
    /// The tape's length after the data and the invariants: each evaluation starts here.
    top: usize,
    /// Adjoints by tape node; below `top` accumulated over the evaluations.
    adjoints: Vec<f64>,
}

impl TapedModel {
    /// `model` with each datum a new input of the tape (its value kept).
    pub fn new<P: Scalar>(model: &Model<P>) -> Self {
        let base = Tape::len();
        let model = model.map(|x| Rev::input(x.value()));
        let n_data = Tape::len() - base;
        model.cache_invariants();
        let top = Tape::len();
        Self {
            model,
            base,
            n_data,
            top,
            adjoints: Vec::new(),
        }
    }

    /// The number of data (inputs of the tape).
    pub fn n_data(&self) -> usize {
        self.n_data
    }

    /// `(q, v)` of `y` as new inputs of the tape.
    fn inputs(&self, y: &[f64]) -> (Vec<Rev>, Vec<Rev>) {
        let nq = self.model.n_q();
        let q = y[..nq].iter().map(|&x| Rev::input(x)).collect();
        let v = y[nq..].iter().map(|&x| Rev::input(x)).collect();
        (q, v)
    }

    /// The adjoints of the inputs `(q, v)` after a sweep; the evaluation rewound, the data
    /// part's adjoints kept.
    fn finish_evaluation(&mut self, q: &[Rev], v: &[Rev]) -> Vec<f64> {
        let out = q
            .iter()
            .chain(v)
            .map(|x| x.adjoint(&self.adjoints))
            .collect();
        self.adjoints.truncate(self.top);
        Tape::rewind(self.top);
        out
    }

    /// `f_yᵀ λ` at `(t, y)` for the state's right-hand side `f = [q̇; v̇]` (`v̇` of Eq. 12 at
    /// the solution `sol` there), and `λᵀ f_p` added to the data's adjoints.
    ///
    /// `λ_vᵀ v̇_p = μᵀ ∂(r − A x̂)/∂p` with `μ = A⁻ᵀ [λ_v; 0]` (one solve with the factorisation
    /// of Eq. 12, whose matrix is symmetric): the reverse of [`Model::residual`] and
    /// [`Model::kinematic_rates`], seeded with `μ` and `λ_q`.
    pub fn pullback(&mut self, t: f64, y: &[f64], sol: &Solution, lambda: &[f64]) -> Vec<f64> {
        let (nq, nv) = (self.model.n_q(), self.model.n_v());
        let (q, v) = self.inputs(y);
        let res = self.model.residual(t, &q, &v, &sol.rows, &sol.x);
        let mut qdot = vec![Rev::constant(0.0); nq];
        self.model.kinematic_rates(&q, &v, &mut qdot);
        let mut mu = vec![0.0; sol.x.len()];
        mu[..nv].copy_from_slice(&lambda[nq..]);
        sol.lu.solve_in_place(&mut mu);
        for (r, &m) in res.iter().zip(&mu) {
            r.seed(&mut self.adjoints, m);
        }
        for (r, &l) in qdot.iter().zip(&lambda[..nq]) {
            r.seed(&mut self.adjoints, l);
        }
        Tape::backpropagate(&mut self.adjoints, self.top);
        self.finish_evaluation(&q, &v)
    }

    /// `w ∂ψ/∂y` at `(t, y)` for a response `ψ`, and `w ∂ψ/∂p` added to the data's adjoints.
    /// A response that reads the multipliers or accelerations (a reaction force, a marker's
    /// acceleration) reads them from the solution of Eq. (12) at `(t, y)`: their adjoint `x̄`
    /// goes back through it as `f_b`'s does, `μ = A⁻ᵀ x̄` seeding the residual.
    pub fn response_pullback(
        &mut self,
        sys: &MultibodySystem,
        response: &Response,
        t: f64,
        y: &[f64],
        w: f64,
    ) -> Result<Vec<f64>, SensitivityError> {
        let (nv, nc) = (self.model.n_v(), self.model.n_constraints());
        let (q, v) = self.inputs(y);
        if !response.needs_solution() {
            let psi = response.evaluate(&self.model, t, &q, &v, &vec![Rev::constant(0.0); nc])?;
            psi.seed(&mut self.adjoints, w);
            Tape::backpropagate(&mut self.adjoints, self.top);
            return Ok(self.finish_evaluation(&q, &v));
        }
        let sol = sys.solve(t, &y[..q.len()], &y[q.len()..])?;
        let res = self.model.residual(t, &q, &v, &sol.rows, &sol.x);
        let residual_top = Tape::len();
        // the multipliers and accelerations as inputs of their own
        let x: Vec<Rev> = sol.x.iter().map(|&a| Rev::input(a)).collect();
        let mut lambda = vec![Rev::constant(0.0); nc];
        for (a, &r) in sol.rows.iter().enumerate() {
            lambda[r] = x[nv + a];
        }
        let psi = response.evaluate_with(&self.model, t, (&q, &v), &lambda, &x[..nv])?;
        psi.seed(&mut self.adjoints, w);
        Tape::backpropagate(&mut self.adjoints, residual_top);
        let mut mu: Vec<f64> = x.iter().map(|a| a.adjoint(&self.adjoints)).collect();
        // the response's part is swept: only the residual's remains, seeded with μ = A⁻ᵀ x̄
        self.adjoints.truncate(residual_top);
        Tape::rewind(residual_top);
        sol.lu.solve_in_place(&mut mu);
        for (r, &m) in res.iter().zip(&mu) {
            r.seed(&mut self.adjoints, m);
        }
        Tape::backpropagate(&mut self.adjoints, self.top);
        Ok(self.finish_evaluation(&q, &v))
    }

    /// The adjoint of each datum, in the order [`Model::map`] visits them: the data part of
    /// the tape swept once, carrying the adjoints accumulated on the invariants to the data.
    pub fn data_adjoints(&mut self) -> Vec<f64> {
        let mut adjoints = self.adjoints.clone();
        Tape::backpropagate(&mut adjoints, self.base);
        adjoints.resize(self.base + self.n_data, 0.0);
        adjoints[self.base..self.base + self.n_data].to_vec()
    }
}

impl Drop for TapedModel {
    fn drop(&mut self) {
        Tape::rewind(self.base);
    }
}

/// `Σ_i p̄_i ∂p_i/∂b_j` for every design variable `j`: the data's adjoints (in the order
/// [`Model::map`] visits the data) contracted with their derivatives, the tangents of the
/// design model's chunks.
pub fn contract_data<const N: usize>(design: &DesignModel<N>, data_adjoints: &[f64]) -> Vec<f64> {
    let mut gradient = vec![0.0; design.n_variables()];
    for (chunk, range) in design.chunk_ranges() {
        let next = Cell::new(0);
        let sums = Cell::new([0.0; N]);
        let _ = chunk.map(|x: Dual<N>| {
            let i = next.get();
            next.set(i + 1);
            let a = data_adjoints[i];
            if a != 0.0 {
                let mut s = sums.get();
                for (sk, dk) in s.iter_mut().zip(&x.d) {
                    *sk += a * dk;
                }
                sums.set(s);
            }
            x.v
        });
        assert_eq!(next.get(), data_adjoints.len(), "data of another model");
        for (k, j) in range.enumerate() {
            gradient[j] = sums.get()[k];
        }
    }
    gradient
}

/// One term of an objective: a response's derivative weights at each recorded point of the run
/// (e.g. [`crate::Objective::weights_in`] of its history there).
#[derive(Clone, Debug)]
pub struct ObjectiveTerm {
    pub response: Response,
    /// `∂J/∂ψ(t_n)`, one per recorded point.
    pub weights: Vec<f64>,
}

/// Work counters of an adjoint sweep.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct AdjointStatistics {
    /// Steps swept back.
    pub steps: usize,
    /// Exact Jacobians `f_y` (each `⌈n/8⌉` evaluations in `Dual<8>`).
    pub jacobians: usize,
    /// Reverse-mode evaluations of the right-hand side and of the responses.
    pub reverse_evaluations: usize,
}

/// The gradient `dJ/db` of `J = Σ_terms Σ_n w_n ψ(t_n)` over the recorded points of `run` (a
/// run of `sys`'s model from the initial sensitivities `s0`, every accepted step recorded:
/// [`crate::simulate_steps`] or [`crate::simulate_sensitivities`]) by the discrete adjoint
/// (module documentation): the derivative of the same discrete solution the direct method
/// differentiates, at the cost of one backward sweep whatever the number of variables.
pub fn adjoint_gradient<const N: usize>(
    sys: &mut MultibodySystem,
    design: &DesignModel<N>,
    run: &SensitivityRun,
    s0: &DMatrix<f64>,
    terms: &[ObjectiveTerm],
) -> Result<(Vec<f64>, AdjointStatistics), SensitivityError> {
    let points = run.times.len();
    let n = run.states[0].len();
    if s0.nrows() != n || s0.ncols() != design.n_variables() {
        return Err(SensitivityError::Layout(format!(
            "initial sensitivities are {}×{}, expected {n}×{}",
            s0.nrows(),
            s0.ncols(),
            design.n_variables()
        )));
    }
    if let Some(t) = terms.iter().find(|t| t.weights.len() != points) {
        return Err(SensitivityError::Response(format!(
            "{} weights of {:?} for {points} recorded points",
            t.weights.len(),
            t.response
        )));
    }
    let mut taped = TapedModel::new(&design.chunks()[0]);
    let mut stats = AdjointStatistics::default();
    // `rhs[i]`: ∂J/∂y_i minus the later steps' formula terms, the right-hand side of λ_i
    let mut rhs = vec![vec![0.0; n]; points];
    let mut jac = DMatrix::zeros(n, n);
    for i in (0..points).rev() {
        let (t, y) = (run.times[i], &run.states[i]);
        for term in terms.iter().filter(|term| term.weights[i] != 0.0) {
            let g = taped.response_pullback(sys, &term.response, t, y, term.weights[i])?;
            stats.reverse_evaluations += 1;
            rhs[i].iter_mut().zip(&g).for_each(|(r, g)| *r += g);
        }
        if i == 0 {
            break;
        }
        let k = run.orders[i];
        let nodes: Vec<f64> = (0..=k).map(|j| run.times[i - j]).collect();
        let c = bdf_coefficients(&nodes);
        // (c_0 I − f_y)ᵀ λ_i = rhs_i
        sys.jacobian(t, y, &mut jac)
            .map_err(|e| SensitivityError::Response(e.0))?;
        stats.jacobians += 1;
        let mut a = -jac.transpose();
        for d in 0..n {
            a[(d, d)] += c[0];
        }
        let mut lambda = std::mem::take(&mut rhs[i]);
        if !DenseLu::new(&a).solve_in_place(&mut lambda) {
            return Err(SensitivityError::Response(format!(
                "singular step matrix at t = {t} in the adjoint sweep"
            )));
        }
        for j in 1..=k {
            rhs[i - j]
                .iter_mut()
                .zip(&lambda)
                .for_each(|(r, l)| *r -= c[j] * l);
        }
        let sol = sys.solve(t, &y[..run.n_q], &y[run.n_q..])?;
        taped.pullback(t, y, &sol, &lambda);
        stats.reverse_evaluations += 1;
        stats.steps += 1;
    }
    let mut gradient = contract_data(design, &taped.data_adjoints());
    for (j, g) in gradient.iter_mut().enumerate() {
        *g += s0
            .column(j)
            .dot(&nalgebra::DVector::from_column_slice(&rhs[0]));
    }
    Ok((gradient, stats))
}
