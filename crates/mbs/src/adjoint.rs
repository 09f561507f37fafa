//! The discrete adjoint of a run: the gradients of objectives with respect to every design
//! variable, each by one backward sweep over the accepted steps (docs/design.md §3, "The
//! adjoint method").
//!
//! The forward run takes, at step `n` of order `k`, `Σ_{j=0..k} c_{n,j} y_{n−j} = f(y_n, b)`.
//! For an objective `J = Σ_k w_k ψ(t_k, ỹ_k, b)` of responses sampled at times `t_k` of the run
//! (`ỹ_k` the interpolated state there, a combination of recorded states), the adjoints `λ_n`
//! solve, from the last step back,
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
//! to the data's adjoint `p̄`, and at the end `p̄` — the invariants' part first taken back to
//! the data they are made from ([`TapedModel::data_adjoints`]) — is contracted once with each
//! variable's derivative of the data, which the [`DesignModel`]'s chunks carry as their
//! tangents.

use std::cell::Cell;

use nalgebra::{DMatrix, DVector};
use sens::{DenseLu, Dual, Rev, Scalar, Tape};

use crate::bdf::{OdeSystem, bdf_coefficients};
use crate::error::ConstraintError;
use crate::model::Model;
use crate::response::Response;
use crate::sensitivity::{
    DesignModel, SensitivityError, SensitivityRun, interpolation, mix as mix_states,
    start_increment,
};
use crate::system::{MultibodySystem, Solution};

/// A model whose data are inputs of the current thread's reverse-mode tape.
///
/// The data are the model's parameters and its flexible bodies' inertia invariants (made from
/// them, each an input of its own: [`Model::map_with_invariants`]), so that no evaluation
/// records more than its own operations and the tape below them is one node per datum. They
/// stay on the tape for the model's life (it is rewound to where it began when the model is
/// dropped); each evaluation is recorded above them, swept into [`Adjoints`], and rewound.
/// Models on one thread must be dropped in the reverse order of their making (the tape is a
/// stack).
pub struct TapedModel {
    model: Model<Rev>,
    /// The tape's length before the data: the data are nodes `base..top`, the model's
    /// parameters (`base..base + parameters`), then its invariants.
    base: usize,
    parameters: usize,
    /// The tape's length after the data: each evaluation starts here.
    top: usize,
}

/// Adjoints by tape node of a [`TapedModel`]'s data, accumulated over the sweeps made into
/// them (one set per objective), with room for the evaluation being swept.
#[derive(Clone, Debug)]
pub struct Adjoints(Vec<f64>);

impl TapedModel {
    /// `model` with each datum a new input of the tape (its value kept), its invariants made
    /// (in `f64`, from the values) and taken as inputs too.
    pub fn new<P: Scalar>(model: &Model<P>) -> Self {
        let values = model.values();
        let parameters = values.n_parameters();
        let base = Tape::len();
        let model = values.map_with_invariants(Rev::input);
        let top = Tape::len();
        Self {
            model,
            base,
            parameters,
            top,
        }
    }

    /// The number of data (inputs of the tape).
    pub fn n_data(&self) -> usize {
        self.top - self.base
    }

    /// Zero adjoints of the data.
    pub fn adjoints(&self) -> Adjoints {
        Adjoints(vec![0.0; self.top])
    }

    /// The adjoint of each of the model's parameters, in the order [`Model::map`] visits
    /// them, those of the flexible bodies' invariants taken back to the parameters they are
    /// made from (node by node, by a reverse written by hand): what [`contract_data`]
    /// contracts with the parameters' derivatives, so that no chunk of variables makes its
    /// invariants in dual numbers.
    pub fn data_adjoints(&self, adjoints: &Adjoints) -> Vec<f64> {
        let mut all = self.parameter_adjoints(&[adjoints]);
        all.pop().expect("one set")
    }

    /// [`Self::data_adjoints`] of several sets of adjoints (one per objective).
    pub fn parameter_adjoints(&self, adjoints: &[&Adjoints]) -> Vec<Vec<f64>> {
        let mut all: Vec<Vec<f64>> = (adjoints.iter())
            .map(|a| a.0[..self.top].to_vec())
            .collect();
        self.model.invariants_to_parameters(&mut all);
        (all.iter())
            .map(|a| a[self.base..self.base + self.parameters].to_vec())
            .collect()
    }

    /// `(q, v)` of `y` as new inputs of the tape.
    fn inputs(&self, y: &[f64]) -> (Vec<Rev>, Vec<Rev>) {
        let nq = self.model.n_q();
        let q = y[..nq].iter().map(|&x| Rev::input(x)).collect();
        let v = y[nq..].iter().map(|&x| Rev::input(x)).collect();
        (q, v)
    }

    /// The sweep of the evaluation above the data, seeded in `adjoints`: the adjoints of
    /// `inputs`, the evaluation's part of `adjoints` left zero. Inputs that are the
    /// evaluation's first nodes (as [`TapedModel::record`] makes them) are left out of the
    /// sweep and the part above them zeroed by it, without a refill.
    fn sweep_into(&self, adjoints: &mut Adjoints, inputs: &[Rev]) -> Vec<f64> {
        let a = &mut adjoints.0;
        let (top, n) = (self.top, inputs.len());
        if (inputs.iter().enumerate()).all(|(k, x)| x.node() == Some(top + k)) {
            Tape::backpropagate_clearing(a, top + n);
            let out = a[top..top + n].to_vec();
            a[top..top + n].fill(0.0);
            out
        } else {
            Tape::backpropagate(a, top);
            let out = inputs.iter().map(|x| x.adjoint(a)).collect();
            a.truncate(top);
            out
        }
    }

    /// `f_yᵀ λ` at `(t, y)` for the state's right-hand side `f = [q̇; v̇]` (`v̇` from Eq. 12
    /// there), and `λᵀ f_p` added to the data's `adjoints`: one [`TapedModel::record`],
    /// [`RecordedRhs::sweep`].
    pub fn pullback(
        &self,
        sys: &MultibodySystem,
        (t, y): (f64, &[f64]),
        adjoints: &mut Adjoints,
        lambda: &[f64],
    ) -> Result<Vec<f64>, ConstraintError> {
        Ok(self.record(sys, t, y)?.sweep(adjoints, lambda))
    }

    /// The right-hand side at `(t, y)` recorded on the tape (above the data), to be swept with
    /// as many seeds as needed; rewound when the recording is dropped. Eq. (12) is solved with
    /// the values of the recorded evaluation ([`MultibodySystem`]'s rows and factorisation).
    pub fn record(
        &self,
        sys: &MultibodySystem,
        t: f64,
        y: &[f64],
    ) -> Result<RecordedRhs<'_>, ConstraintError> {
        let nq = self.model.n_q();
        let (q, v) = self.inputs(y);
        let (sol, residual, _) = sys.solve_dual(&self.model, t, &q, &v)?;
        let mut qdot = vec![Rev::constant(0.0); nq];
        self.model.kinematic_rates(&q, &v, &mut qdot);
        Ok(RecordedRhs {
            taped: self,
            sol,
            inputs: q.into_iter().chain(v).collect(),
            residual,
            qdot,
        })
    }

    /// `w ∂ψ/∂y` at `(t, y)` for a response `ψ`, and `w ∂ψ/∂p` added to the data's
    /// `adjoints`. A response that reads the multipliers or accelerations (a reaction force,
    /// a marker's acceleration) reads them from the solution of Eq. (12) at `(t, y)`: their
    /// adjoint `x̄` goes back through it as `f_b`'s does, `μ = A⁻ᵀ x̄` seeding the residual.
    pub fn response_pullback(
        &self,
        sys: &MultibodySystem,
        response: &Response,
        (t, y): (f64, &[f64]),
        adjoints: &mut Adjoints,
        w: f64,
    ) -> Result<Vec<f64>, SensitivityError> {
        let (nv, nc) = (self.model.n_v(), self.model.n_constraints());
        let (q, v) = self.inputs(y);
        let inputs: Vec<Rev> = q.iter().chain(&v).copied().collect();
        let out = if !response.needs_solution() {
            let psi = response.evaluate(&self.model, t, &q, &v, &vec![Rev::constant(0.0); nc])?;
            psi.seed(&mut adjoints.0, w);
            self.sweep_into(adjoints, &inputs)
        } else {
            // Eq. (12) solved with the values of the recorded residual (one evaluation)
            let (sol, res, _) = sys.solve_dual(&self.model, t, &q, &v)?;
            let residual_top = Tape::len();
            // the multipliers and accelerations as inputs of their own
            let x: Vec<Rev> = sol.x.iter().map(|&a| Rev::input(a)).collect();
            let mut lambda = vec![Rev::constant(0.0); nc];
            for (a, &r) in sol.rows.iter().enumerate() {
                lambda[r] = x[nv + a];
            }
            let psi = response.evaluate_with(&self.model, t, (&q, &v), &lambda, &x[..nv])?;
            psi.seed(&mut adjoints.0, w);
            Tape::backpropagate(&mut adjoints.0, residual_top);
            let mut mu: Vec<f64> = x.iter().map(|a| a.adjoint(&adjoints.0)).collect();
            // the response's part is swept: only the residual's remains, seeded with
            // μ = A⁻ᵀ x̄
            adjoints.0.truncate(residual_top);
            Tape::rewind(residual_top);
            sol.lu.solve_in_place(&mut mu);
            for (r, &m) in res.iter().zip(&mu) {
                r.seed(&mut adjoints.0, m);
            }
            self.sweep_into(adjoints, &inputs)
        };
        Tape::rewind(self.top);
        Ok(out)
    }

    /// `w_0ᵀ S_0` for the initial sensitivities `S_0` of [`crate::initial_sensitivities`]
    /// by reverse mode, its `w_0ᵀ S_0 = p̄_0ᵀ p_b` added to the data's `adjoints`: the
    /// projections' systems solved once with `w_0`'s parts (their matrix is symmetric), the
    /// constraints and mass matrix swept once. `false` (nothing added) where the start deformed
    /// the flexible bodies or gave them elastic rates: their rules are left to the forward
    /// `S_0`.
    fn initial_pullback(
        &self,
        sys: &MultibodySystem,
        (t0, y0): (f64, &[f64]),
        w0: &[f64],
        adjoints: &mut Adjoints,
    ) -> Result<bool, SensitivityError> {
        if sys.elastic_start().is_some() || sys.elastic_rates() {
            return Ok(false);
        }
        let model = sys.model();
        let nq = model.n_q();
        let (q, v) = y0.split_at(nq);
        let cols = sys.rigid_columns();
        let c = model.constraints(t0, q, v);
        let kkt = sys.start_projection(t0, q, &c.jacobian, &cols)?;
        let rows = kkt.rows.clone();
        let zero_rows = vec![0.0; rows.len()];
        // the velocities' projection increment and multipliers from the guess (as S_0's)
        let (dv, mu) = start_increment(sys, t0, (q, v), &kkt, cols.len());
        // velocities: w_vᵀ v_b = αᵀ ∂r₁ + βᵀ ∂(−Φ̇_I), (α, β) = K⁻¹ [w_v; 0], along q_b and p_b
        let wv: Vec<f64> = cols.iter().map(|&ci| w0[nq + ci]).collect();
        let (alpha, beta) = kkt.solve(&wv, &zero_rows);
        let qr: Vec<Rev> = q.iter().map(|&x| Rev::input(x)).collect();
        let vr: Vec<Rev> = v.iter().map(|&x| Rev::constant(x)).collect();
        let cd = self.model.constraints(t0, &qr, &vr);
        let (md, _) = self.model.mass_and_forces(t0, &qr, &vr);
        for (&ca, &al) in cols.iter().zip(&alpha) {
            for (&cb, &x) in cols.iter().zip(&dv) {
                md[(ca, cb)].seed(&mut adjoints.0, -al * x);
            }
            for (&r, &u) in rows.iter().zip(&mu) {
                cd.jacobian[(r, ca)].seed(&mut adjoints.0, -al * u);
            }
        }
        for (&r, &be) in rows.iter().zip(&beta) {
            cd.phi_dot[r].seed(&mut adjoints.0, -be);
        }
        let q_bar = self.sweep_into(adjoints, &qr);
        Tape::rewind(self.top);
        // positions: (w_q + q̄)ᵀ q_b = (Bᵀ(w_q + q̄))ᵀ d, d from K⁻¹ [0; −Φ_b]: −zᵀ Φ_b with
        // z the multipliers of K⁻¹ [Bᵀ(w_q + q̄); 0] (B the kinematic rates' map)
        let qc: Vec<Rev> = q.iter().map(|&x| Rev::constant(x)).collect();
        let d: Vec<Rev> = (0..model.n_v()).map(|_| Rev::input(0.0)).collect();
        let mut rates = vec![Rev::constant(0.0); nq];
        self.model.kinematic_rates(&qc, &d, &mut rates);
        for ((r, w), qb) in rates.iter().zip(&w0[..nq]).zip(&q_bar) {
            r.seed(&mut adjoints.0, w + qb);
        }
        let d_bar = self.sweep_into(adjoints, &d);
        Tape::rewind(self.top);
        let g: Vec<f64> = cols.iter().map(|&ci| d_bar[ci]).collect();
        let (_, z) = kkt.solve(&g, &zero_rows);
        let phi = self.model.constraints(t0, &qc, &vr).phi;
        for (&r, &zk) in rows.iter().zip(&z) {
            phi[r].seed(&mut adjoints.0, -zk);
        }
        self.sweep_into(adjoints, &[]);
        Tape::rewind(self.top);
        Ok(true)
    }
}

impl Drop for TapedModel {
    fn drop(&mut self) {
        Tape::rewind(self.base);
    }
}

/// One evaluation of the right-hand side on the tape ([`TapedModel::record`]).
pub struct RecordedRhs<'a> {
    taped: &'a TapedModel,
    sol: Solution,
    /// `(q, v)`.
    inputs: Vec<Rev>,
    /// `r − A x̂` of Eq. (12) at the solution's `x̂`.
    residual: Vec<Rev>,
    qdot: Vec<Rev>,
}

impl RecordedRhs<'_> {
    /// `f_yᵀ λ`, and `λᵀ f_p` added to the data's `adjoints`.
    ///
    /// `λ_vᵀ v̇_p = μᵀ ∂(r − A x̂)/∂p` with `μ = A⁻ᵀ [λ_v; 0]` (one solve with the
    /// factorisation of Eq. 12, whose matrix is symmetric): the reverse of
    /// [`Model::residual`] and [`Model::kinematic_rates`], seeded with `μ` and `λ_q`. Linear
    /// in `λ`: sweeps with `λ₁` and `λ₂` add to the data what one with `λ₁ + λ₂` would.
    pub fn sweep(&self, adjoints: &mut Adjoints, lambda: &[f64]) -> Vec<f64> {
        let nq = self.qdot.len();
        let mut mu = vec![0.0; self.sol.x.len()];
        mu[..lambda.len() - nq].copy_from_slice(&lambda[nq..]);
        self.sol.lu.solve_in_place(&mut mu);
        for (r, &m) in self.residual.iter().zip(&mu) {
            r.seed(&mut adjoints.0, m);
        }
        for (r, &l) in self.qdot.iter().zip(&lambda[..nq]) {
            r.seed(&mut adjoints.0, l);
        }
        self.taped.sweep_into(adjoints, &self.inputs)
    }
}

impl Drop for RecordedRhs<'_> {
    fn drop(&mut self) {
        Tape::rewind(self.taped.top);
    }
}

/// `Σ_i p̄_i ∂p_i/∂b_j` for every design variable `j`: the parameters' adjoints
/// ([`TapedModel::data_adjoints`], in the order [`Model::map`] visits the parameters)
/// contracted with their derivatives, the tangents of the design model's chunks.
pub fn contract_data<const N: usize>(design: &DesignModel<N>, data_adjoints: &[f64]) -> Vec<f64> {
    let mut gradient = vec![0.0; design.n_variables()];
    for (chunk, range) in design.chunk_ranges() {
        let sums = contract_chunk(chunk, data_adjoints);
        for (k, j) in range.enumerate() {
            gradient[j] = sums[k];
        }
    }
    gradient
}

/// [`contract_data`] for one chunk: `Σ_i p̄_i ∂p_i/∂b_k` for its `N` tangent directions.
fn contract_chunk<const N: usize>(chunk: &Model<Dual<N>>, data_adjoints: &[f64]) -> [f64; N] {
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
    sums.get()
}

/// One term of an objective: `Σ_k w_k ψ(t_k)` for a response `ψ` sampled at times `t_k`
/// within the run, each sample the response at the run's interpolated state there
/// ([`SensitivityRun::interpolate`], as [`SensitivityRun::resample`] samples it); `w_k` e.g.
/// from [`crate::Objective::weights_in`] of the sampled history.
#[derive(Clone, Debug)]
pub struct ObjectiveTerm {
    pub response: Response,
    /// The sample times `t_k`, within the run (its recorded points, or output times).
    pub times: Vec<f64>,
    /// `∂J/∂ψ(t_k)`, one per sample.
    pub weights: Vec<f64>,
}

/// The accepted steps of a run as the backward sweep reads them: every step's time and
/// order, and the states, which [`StepHistory::load`] may have to make readable first (a
/// [`crate::CheckpointedRun`] recomputes them from a checkpoint).
pub trait StepHistory {
    /// `t_0, t_1, …`.
    fn times(&self) -> &[f64];
    /// The order of the step that ended at each time (0 for the initial point).
    fn orders(&self) -> &[usize];
    /// Make points `i − 5 ..= i` readable by [`StepHistory::state`]; called with `i`
    /// decreasing.
    fn load(&mut self, sys: &mut MultibodySystem, i: usize) -> Result<(), SensitivityError>;
    /// `y_i` (a point [`StepHistory::load`] made readable).
    fn state(&self, i: usize) -> &[f64];
}

/// Every state kept.
impl StepHistory for &SensitivityRun {
    fn times(&self) -> &[f64] {
        &self.times
    }

    fn orders(&self) -> &[usize] {
        &self.orders
    }

    fn load(&mut self, _: &mut MultibodySystem, _: usize) -> Result<(), SensitivityError> {
        Ok(())
    }

    fn state(&self, i: usize) -> &[f64] {
        &self.states[i]
    }
}

/// The adjoint's right-hand sides are needed for the recorded points a step's formula reaches
/// back to (order ≤ 5): a ring of them.
const RING: usize = 6;

/// Work counters of an adjoint sweep.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct AdjointStatistics {
    /// Steps swept back.
    pub steps: usize,
    /// Exact Jacobians `f_y` (each `⌈n/8⌉` evaluations in `Dual<8>`), the preconditioner of
    /// the steps' systems.
    pub jacobians: usize,
    /// Reverse-mode recordings of the right-hand side (one per step) and of the responses.
    pub reverse_evaluations: usize,
    /// Reverse sweeps of the recorded right-hand sides (one per iteration of the steps'
    /// systems).
    pub sweeps: usize,
}

/// Iterations of a step's adjoint system before a new exact Jacobian.
const MAX_ITERATIONS: usize = 6;
/// The iterations stop when the error left in the adjoint (estimated from the updates' rate
/// of convergence) is below this fraction of it (largest components), or stagnate at the
/// round-off floor above it (then an exact Jacobian solves the step): the step's system solved
/// to round-off, as the direct method solves its own by LU.
/// The residual a looser stop leaves is multiplied by the stiff step matrix, and a gradient
/// carries it summed over the steps: at 1e-12 the gradient of a peak (one sample's
/// derivative) on a stiff run differed from the direct method's by 5e-7 relative, at 1e-15 by
/// 3e-12 (every kind of objective by at most 4e-11), for about one sweep more in ten
/// (docs/design.md §3).
const ADJOINT_TOL: f64 = 1e-15;
/// The largest last update, relative to the adjoint, added to `λ` without its sweep: its
/// `f_yᵀ δ` is not read again (the earlier steps' right-hand sides take `λ` only), and its
/// share `δᵀ f_p` of the data's adjoints, at most this fraction of the step's, is left out. At
/// 1e-11 the gradients moved by 1e-13 relative, for one sweep in six fewer.
const UNSWEPT_TOL: f64 = 1e-11;

/// The adjoint's step systems `(c_0 I − f_y)ᵀ λ = r`, solved by iterations preconditioned
/// with `(c_0 I − J)ᵀ` at the last exact Jacobian `J` (refactorised, not re-evaluated, when
/// `c_0` changes), each one reverse sweep for `f_yᵀ λ` — the direct method's scheme
/// transposed.
#[derive(Default)]
struct StepSolver {
    /// `J` and the LU of `c_0 I − Jᵀ` at `c_0`.
    exact: Option<(DMatrix<f64>, f64, DenseLu)>,
}

impl StepSolver {
    fn refresh(
        &mut self,
        sys: &mut MultibodySystem,
        (t, y): (f64, &[f64]),
        c0: f64,
        stats: &mut AdjointStatistics,
    ) -> Result<(), SensitivityError> {
        let n = y.len();
        let mut jac = DMatrix::zeros(n, n);
        sys.jacobian(t, y, &mut jac)
            .map_err(|e| SensitivityError::Response(e.0))?;
        stats.jacobians += 1;
        let lu = DenseLu::shifted_transpose(c0, &jac);
        self.exact = Some((jac, c0, lu));
        Ok(())
    }

    /// `P⁻¹ x` in place; an error where `P` is singular.
    fn precondition(&self, t: f64, x: &mut [f64]) -> Result<(), SensitivityError> {
        let (_, _, lu) = self.exact.as_ref().expect("a preconditioner");
        match lu.solve_in_place(x) {
            true => Ok(()),
            false => Err(SensitivityError::Response(format!(
                "singular step matrix at t = {t} in the adjoint sweep"
            ))),
        }
    }

    /// `λ` of `(c_0 I − f_y)ᵀ λ = r` at `(t, y)`, `f_y` that of `recorded`, whose sweeps add
    /// `λᵀ f_p` to the data's adjoints (the sweeps of the updates, which sum to `λ`).
    fn solve(
        &mut self,
        sys: &mut MultibodySystem,
        (t, y): (f64, &[f64]),
        c0: f64,
        r: &[f64],
        (recorded, adjoints): (&RecordedRhs<'_>, &mut Adjoints),
        stats: &mut AdjointStatistics,
    ) -> Result<Vec<f64>, SensitivityError> {
        if self.exact.is_none() {
            self.refresh(sys, (t, y), c0, stats)?;
        }
        if let Some((jac, c, lu)) = self.exact.as_mut()
            && *c != c0
        {
            *lu = DenseLu::shifted_transpose(c0, jac);
            *c = c0;
        }
        let n = r.len();
        let size = |x: &[f64]| x.iter().fold(0.0f64, |m, a| m.max(a.abs()));
        let (mut lambda, mut ft_lambda) = (vec![0.0; n], vec![0.0; n]);
        let mut delta = r.to_vec();
        self.precondition(t, &mut delta)?;
        let mut applied = f64::INFINITY;
        let mut exact_here = false;
        for it in 1.. {
            // apply the update: λ and, by one sweep, f_yᵀ λ and the data's adjoints
            let norm = size(&delta);
            if !norm.is_finite() {
                return Err(SensitivityError::Response(format!(
                    "non-finite adjoint at t = {t}"
                )));
            }
            let ft_delta = recorded.sweep(adjoints, &delta);
            stats.sweeps += 1;
            for ((l, f), (d, fd)) in lambda
                .iter_mut()
                .zip(&mut ft_lambda)
                .zip(delta.iter().zip(&ft_delta))
            {
                *l += d;
                *f += fd;
            }
            let rate = norm / applied;
            applied = norm;
            // the remaining error after this update, about rate × its size (linear
            // convergence)
            let remaining = if it > 1 {
                norm * rate / (1.0 - rate)
            } else {
                f64::INFINITY
            };
            if exact_here || (rate < 0.5 && remaining <= ADJOINT_TOL * size(&lambda)) {
                return Ok(lambda);
            }
            // the next update: the residual r − (c_0 λ − f_yᵀ λ), preconditioned
            delta = (0..n)
                .map(|i| r[i] - c0 * lambda[i] + ft_lambda[i])
                .collect();
            if it >= MAX_ITERATIONS || (it > 1 && rate >= 0.5) {
                // the exact Jacobian here: one more update solves the system
                self.refresh(sys, (t, y), c0, stats)?;
                exact_here = true;
            }
            self.precondition(t, &mut delta)?;
            let (next, scale) = (size(&delta), size(&lambda));
            let next_rate = next / applied;
            let converging = next_rate < 0.5
                && next <= UNSWEPT_TOL * scale
                && next * next_rate / (1.0 - next_rate) <= ADJOINT_TOL * scale;
            if !exact_here && (converging || next <= ADJOINT_TOL * scale) {
                // converged with this update, too small to need its sweep (UNSWEPT_TOL), or
                // at the round-off floor
                lambda.iter_mut().zip(&delta).for_each(|(l, d)| *l += d);
                return Ok(lambda);
            }
        }
        unreachable!("the loop returns")
    }
}

/// A sample of an objective's term: `(objective, term, t, w, mix)`, its state `Σ_j mix_j
/// y_{i−j}` for the recorded point `i` it is filed under (`SensitivityRun::interpolation`).
type Sample = (usize, usize, f64, f64, Vec<f64>);

/// The objectives' samples with nonzero weights, by the last recorded point of `run` each
/// mixes (as [`SensitivityRun::interpolation`]).
fn samples_by_point(
    run: &impl StepHistory,
    objectives: &[Vec<ObjectiveTerm>],
) -> Result<Vec<Vec<Sample>>, SensitivityError> {
    let times = run.times();
    let points = times.len();
    let (t0, t1) = (times[0], times[points - 1]);
    let mut samples: Vec<Vec<Sample>> = vec![Vec::new(); points];
    for (a, terms) in objectives.iter().enumerate() {
        for (b, term) in terms.iter().enumerate() {
            if term.weights.len() != term.times.len() {
                return Err(SensitivityError::Response(format!(
                    "{} weights of {:?} for {} samples",
                    term.weights.len(),
                    term.response,
                    term.times.len()
                )));
            }
            for (&t, &w) in term.times.iter().zip(&term.weights) {
                if !(t >= t0 && t <= t1) {
                    return Err(SensitivityError::Response(format!(
                        "sample at t = {t} outside the run [{t0}, {t1}]"
                    )));
                }
                if w != 0.0 {
                    let (i, mix) = interpolation(times, run.orders(), t);
                    samples[i].push((a, b, t, w, mix));
                }
            }
        }
    }
    Ok(samples)
}

/// One objective's backward sweep: the right-hand sides of its adjoints (`rhs[i % RING]`:
/// `∂J/∂y_i` minus the later steps' formula terms) and its data's adjoints.
struct Sweep {
    rhs: Vec<Vec<f64>>,
    adjoints: Adjoints,
}

/// The gradients `dJ_a/db` of objectives `J_a = Σ_terms Σ_k w_k ψ(t_k)` (each a list of
/// [`ObjectiveTerm`]s) over `run` (a run of `sys`'s model from the initial sensitivities `s0`,
/// every accepted step recorded: [`crate::simulate_steps`] or
/// [`crate::simulate_sensitivities`]) by the discrete adjoint (module documentation): the
/// derivatives of the same discrete solution the direct method differentiates, at the cost of
/// one backward sweep whatever the number of variables ([`adjoint_sweep`], then
/// [`AdjointSweep::gradients`] of every chunk of `design`).
pub fn adjoint_gradients<const N: usize>(
    sys: &mut MultibodySystem,
    design: &DesignModel<N>,
    run: &SensitivityRun,
    s0: &DMatrix<f64>,
    objectives: &[Vec<ObjectiveTerm>],
) -> Result<(Vec<Vec<f64>>, AdjointStatistics), SensitivityError> {
    let n = run.states[0].len();
    if s0.nrows() != n || s0.ncols() != design.n_variables() {
        return Err(SensitivityError::Layout(format!(
            "initial sensitivities are {}×{}, expected {n}×{}",
            s0.nrows(),
            s0.ncols(),
            design.n_variables()
        )));
    }
    let sweep = adjoint_sweep(sys, &design.chunks()[0], &mut { run }, objectives)?;
    let mut gradients = vec![vec![0.0; design.n_variables()]; objectives.len()];
    for (chunk, range) in design.chunk_ranges() {
        let s0 = s0.columns(range.start, range.len()).into_owned();
        for (g, chunk_g) in gradients.iter_mut().zip(sweep.gradients(chunk, &s0)) {
            g[range.clone()].copy_from_slice(&chunk_g);
        }
    }
    Ok((gradients, sweep.statistics))
}

/// What the backward sweep of [`adjoint_sweep`] leaves for the gradients: per objective, the
/// adjoints of the model's data and of the initial state; contracted with any chunk of design
/// variables' derivatives ([`Self::gradients`]), one chunk at a time if the caller builds them
/// so (the memory of one chunk's dual model instead of all).
#[derive(Clone, Debug)]
pub struct AdjointSweep {
    /// Per objective, `p̄`: the adjoint of each datum of the model.
    data: Vec<Vec<f64>>,
    /// Per objective, `w_0 = ∂J/∂y_0 − Σ_m c_{m,m} λ_m`: the adjoint of the initial state,
    /// zero where the sweep took it back through the start's projections into `data`.
    initial: Vec<DVector<f64>>,
    /// The sweep's work.
    pub statistics: AdjointStatistics,
}

impl AdjointSweep {
    /// Whether [`Self::gradients`] reads the initial sensitivities: only where the start
    /// deformed the flexible bodies or gave them elastic rates (elsewhere the initial state's
    /// adjoint went back through the start's projections in the sweep, and `s0` may be zero).
    pub fn needs_initial_sensitivities(&self) -> bool {
        (self.initial.iter()).any(|w| w.iter().any(|&x| x != 0.0))
    }

    /// Per objective, `p̄`: the adjoint of each datum of the swept model, in the order
    /// [`Model::map`] visits them (the flexible bodies' invariants taken back to the data they
    /// are made from).
    pub fn data_adjoints(&self) -> &[Vec<f64>] {
        &self.data
    }

    /// Per objective, its gradient with respect to a chunk's variables: `chunk` a model of the
    /// swept system's layout whose tangents are the derivatives of its data with respect to
    /// those variables, `s0` their initial sensitivities (`n × k`, `k ≤ N` the chunk's
    /// variables: [`crate::initial_sensitivities`] of a one-chunk [`DesignModel`]).
    pub fn gradients<const N: usize>(
        &self,
        chunk: &Model<Dual<N>>,
        s0: &DMatrix<f64>,
    ) -> Vec<Vec<f64>> {
        let k = s0.ncols().min(N);
        (self.data.iter().zip(&self.initial))
            .map(|(data, w0)| {
                let sums = contract_chunk(chunk, data);
                (0..k).map(|j| sums[j] + s0.column(j).dot(w0)).collect()
            })
            .collect()
    }
}

/// The backward sweep of the discrete adjoint over `run` (a run of `sys`'s model, every
/// accepted step recorded: [`crate::simulate_steps`] or [`crate::simulate_sensitivities`]) for
/// objectives `J_a = Σ_terms Σ_k w_k ψ(t_k)` (each a list of [`ObjectiveTerm`]s), at the data
/// of `model` (module documentation): `sys`'s model with the layout of the design chunks the
/// sweep will be contracted with (one of them: their data are what the adjoints are of). No
/// design variable enters; [`AdjointSweep::gradients`] turns the sweep into the gradients. The
/// objectives share each step's recording and the preconditioner; each adds its own sweeps.
/// The memory beyond the run's states is a few state vectors per objective (the ring of
/// right-hand sides), its data's adjoints and the tape of one step.
pub fn adjoint_sweep<P: Scalar>(
    sys: &mut MultibodySystem,
    model: &Model<P>,
    run: &mut impl StepHistory,
    objectives: &[Vec<ObjectiveTerm>],
) -> Result<AdjointSweep, SensitivityError> {
    let points = run.times().len();
    let n = model.n_q() + model.n_v();
    let samples = samples_by_point(run, objectives)?;
    let taped = TapedModel::new(model);
    let mut stats = AdjointStatistics::default();
    let mut sweeps: Vec<Sweep> = (0..objectives.len())
        .map(|_| Sweep {
            rhs: vec![vec![0.0; n]; RING],
            adjoints: taped.adjoints(),
        })
        .collect();
    let mut step = StepSolver::default();
    for i in (0..points).rev() {
        run.load(sys, i)?;
        for (a, b, t, w, mix) in &samples[i] {
            let (a, b, t, w) = (*a, *b, *t, *w);
            // the response at the interpolated state, its adjoint spread by the weights
            let y = mix_states(mix, |j| run.state(i - j));
            let sweep = &mut sweeps[a];
            let response = &objectives[a][b].response;
            let g = taped.response_pullback(sys, response, (t, &y), &mut sweep.adjoints, w)?;
            stats.reverse_evaluations += 1;
            for (j, m) in mix.iter().enumerate() {
                (sweep.rhs[(i - j) % RING].iter_mut())
                    .zip(&g)
                    .for_each(|(r, g)| *r += m * g);
            }
        }
        if i == 0 {
            break;
        }
        let (t, y) = (run.times()[i], run.state(i));
        let k = run.orders()[i];
        let nodes: Vec<f64> = (0..=k).map(|j| run.times()[i - j]).collect();
        let c = bdf_coefficients(&nodes);
        let recorded = taped.record(sys, t, y)?;
        stats.reverse_evaluations += 1;
        for sweep in &mut sweeps {
            // (c_0 I − f_y)ᵀ λ_i = rhs_i
            let r = std::mem::replace(&mut sweep.rhs[i % RING], vec![0.0; n]);
            let seen = (&recorded, &mut sweep.adjoints);
            let lambda = step.solve(sys, (t, y), c[0], &r, seen, &mut stats)?;
            for j in 1..=k {
                (sweep.rhs[(i - j) % RING].iter_mut())
                    .zip(&lambda)
                    .for_each(|(r, l)| *r -= c[j] * l);
            }
        }
        stats.steps += 1;
    }
    // the initial state's adjoint through the start's projections, where reverse mode can
    let (t0, y0) = (run.times()[0], run.state(0));
    for sweep in &mut sweeps {
        if taped.initial_pullback(sys, (t0, y0), &sweep.rhs[0], &mut sweep.adjoints)? {
            sweep.rhs[0].fill(0.0);
        }
    }
    Ok(AdjointSweep {
        data: taped.parameter_adjoints(&sweeps.iter().map(|s| &s.adjoints).collect::<Vec<_>>()),
        initial: (sweeps.iter())
            .map(|sweep| DVector::from_column_slice(&sweep.rhs[0]))
            .collect(),
        statistics: stats,
    })
}
