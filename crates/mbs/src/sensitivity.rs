//! Direct (forward) design sensitivities of the dynamic response (paper §4.2–4.3, Eqs. 40–44;
//! docs/design.md §3).
//!
//! The design variables `b` live in the model parameters: a [`DesignModel`] holds one
//! `Model<Dual<N>>` per chunk of `N` variables (e.g. flexible bodies from
//! `fem::modal_body_dual`, whose eigenvalues, modes and damping carry `∂/∂b`). The state
//! sensitivities `S = ∂y/∂b` (`n × m`, `y = [q; v]`) obey `S' = f_y S + f_b`, where
//! `f_y S + f_b` is **one** dual evaluation per chunk: `q̇` from [`Model::kinematic_rates`] and
//! `v̇` from [`sens::solve_tangents`] applied to [`Model::residual`] (the right-hand side of
//! Eq. 40, accelerations and multipliers held fixed, `q` and `v` seeded with the columns of
//! `S`), through the `f64` LU of Eq. (12). Baumgarte feedback on the sensitivity constraint
//! violations is part of that residual (the tangent of `γ − 2αΦ̇ − β²Φ`).
//!
//! `S` is integrated on the integrator's own steps with the same BDF formula
//! (`Σ c_j S_{n+1−j} = f_y S_{n+1} + f_b`, a linear system per step):
//! - [`SensitivityMethod::StaggeredDirect`]: the linear system `(c_0 I − f_y) S = f_b − ψ` with
//!   `f_y` exact at the converged state, solved to round-off: the result is the exact derivative
//!   of the discrete solution. It is solved by iterations, each one dual evaluation per chunk,
//!   preconditioned with the LU of `c_0 I − f_y` at the last exact Jacobian (refactorised when
//!   `c_0` changes); a new exact Jacobian (`⌈n/8⌉` evaluations in `Dual<8>`) only when they
//!   converge slowly (measured on the §5.1 slider-crank: 2.9 evaluations per step with the
//!   prediction's, an exact Jacobian every ~190 steps);
//! - [`SensitivityMethod::StaggeredCorrector`]: chord iterations with the integrator's Newton
//!   matrix, each one dual evaluation, to a tolerance in the integrator's error norm (falls
//!   back to the direct solve if they do not converge);
//! - [`SensitivityMethod::Simultaneous`]: the same chord updates made inside the state's Newton
//!   iteration ([`StepExtension::simultaneous`]); the dual evaluation at an iterate gives the
//!   state's right-hand side as its values, with the LU of Eq. (12) the state needs anyway, so
//!   the sensitivities cost only the tangent part of that evaluation and their solves. Without
//!   error control the sensitivities take one update per step, at the first iterate (the
//!   states are bitwise those of the analysis alone), and then, column by column, more chord
//!   updates at the converged state while the column's rate estimate times its last update is
//!   not below [`SIMULTANEOUS_TOLERANCE`] of their error weights; with error control they are
//!   updated at every iterate and join the convergence test. Measured on the §5.1 deck (rtol
//!   1e-6): 1.4 dual evaluations per step, the deflection's derivative within 4e-5 (of its
//!   largest value) of the direct method's and as accurate against a run at rtol 1e-10
//!   (5.05e-3 both, the discretisation error); with the single update alone 1.6e-4 from it.
//!
//! With [`SensitivityOptions::error_control`] the sensitivities' local error estimates join
//! the step-size control (as in the paper, which integrates one vector of states and
//! sensitivities); otherwise the steps are the state's alone.
//!
//! Initial sensitivities (Eq. 44) are consistent with the constraints
//! ([`initial_sensitivities`]).

use std::collections::VecDeque;

use nalgebra::DMatrix;
use sens::{DenseLu, Dual};

use crate::bdf::{
    Bdf, BdfOptions, IntegrationError, IntegrationFailure, NewtonMatrix, OdeSystem, RhsError,
    Statistics, StepExtension, TrialStep, error_estimate_weights, lagrange_weights,
};
use crate::error::ConstraintError;
use crate::model::{Model, State};
use crate::system::{MultibodySystem, Solution, StartProjection};

/// The model with design derivatives: one `Model<Dual<N>>` per chunk of `N` design variables
/// (chunk `c` carries the tangents of variables `c·N .. min((c+1)·N, m)`; unused tangent slots of
/// the last chunk are ignored). Every chunk has the same values.
#[derive(Clone, Debug)]
pub struct DesignModel<const N: usize> {
    chunks: Vec<Model<Dual<N>>>,
    n_variables: usize,
    /// Each variable's scale `b̄_j` in the sensitivities' error weights (1 unless
    /// [`Self::with_variable_scales`] says otherwise).
    scales: Vec<f64>,
}

impl<const N: usize> DesignModel<N> {
    /// Chunks for `n_variables` design variables; their number must be `⌈m / N⌉` and their
    /// layouts equal.
    pub fn new(chunks: Vec<Model<Dual<N>>>, n_variables: usize) -> Result<Self, SensitivityError> {
        if N == 0 || chunks.len() != n_variables.div_ceil(N) || chunks.is_empty() {
            return Err(SensitivityError::Layout(format!(
                "{} design variables in chunks of {N} need {} dual models, got {}",
                n_variables,
                n_variables.div_ceil(N.max(1)),
                chunks.len()
            )));
        }
        let c0 = &chunks[0];
        if chunks.iter().any(|c| {
            c.n_q() != c0.n_q() || c.n_v() != c0.n_v() || c.n_constraints() != c0.n_constraints()
        }) {
            return Err(SensitivityError::Layout(
                "the chunks' models have different layouts".into(),
            ));
        }
        Ok(Self {
            chunks,
            n_variables,
            scales: vec![1.0; n_variables],
        })
    }

    /// The variables' scales `b̄_j`: the sensitivities `∂y/∂b_j` are weighted in the
    /// integrator's error norm as the state's change `b̄_j ∂y/∂b_j` under a change `b̄_j` of the
    /// variable, i.e. with the absolute tolerances `atol / b̄_j` (CVODES's `pbar`). Without
    /// them a variable in small units (a ply thickness in metres) has sensitivities thousands
    /// of times those of an angle in degrees, held to the same absolute tolerance: their
    /// corrector iterates to a far tighter accuracy than the state's. Each scale must be
    /// finite and positive.
    pub fn with_variable_scales(mut self, scales: Vec<f64>) -> Result<Self, SensitivityError> {
        if scales.len() != self.n_variables || scales.iter().any(|b| !(b.is_finite() && *b > 0.0)) {
            return Err(SensitivityError::Layout(format!(
                "{} variable scales for {} design variables, each finite and positive",
                scales.len(),
                self.n_variables
            )));
        }
        self.scales = scales;
        Ok(self)
    }

    pub fn n_variables(&self) -> usize {
        self.n_variables
    }
    pub fn chunks(&self) -> &[Model<Dual<N>>] {
        &self.chunks
    }
    /// The plain model (values of the first chunk).
    pub fn values(&self) -> Model<f64> {
        self.chunks[0].values()
    }
    /// `(chunk model, variable range)` pairs.
    pub fn chunk_ranges(&self) -> impl Iterator<Item = (&Model<Dual<N>>, std::ops::Range<usize>)> {
        let m = self.n_variables;
        self.chunks
            .iter()
            .enumerate()
            .map(move |(c, model)| (model, c * N..((c + 1) * N).min(m)))
    }

    fn check(&self, sys: &MultibodySystem) -> Result<(), SensitivityError> {
        let m = sys.model();
        let c = &self.chunks[0];
        if c.n_q() != m.n_q() || c.n_v() != m.n_v() || c.n_constraints() != m.n_constraints() {
            return Err(SensitivityError::Layout(
                "the design model and the system have different layouts".into(),
            ));
        }
        Ok(())
    }
}

/// How the linear sensitivity system of each step is solved.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SensitivityMethod {
    /// The linear system of each step with the exact `f_y` at the converged state, solved to
    /// round-off (see the module docs): the exact derivative of the discrete solution.
    StaggeredDirect,
    /// Chord iterations with the integrator's Newton matrix until the weighted RMS update is
    /// below `tol` (in the integrator's error norm); direct solve after `max_iterations`.
    StaggeredCorrector { tol: f64, max_iterations: usize },
    /// Simultaneous corrector: the sensitivities are corrected inside the state's Newton
    /// iteration with its matrix, `f_y S + f_b` evaluated at a Newton iterate by the same dual
    /// evaluation that gives the state's right-hand side (its values) and with the same LU of
    /// Eq. (12). Without error control the sensitivities take one chord update per step, at
    /// the predicted state (the first iterate); the state's further iterations use plain
    /// evaluations. With error control they are updated at every iterate and join the
    /// convergence test. The cheapest method (no evaluation or factorisation of its own); its
    /// iteration error is bounded by the chord rate times its first update, the same order as
    /// the local truncation error, so it agrees with the direct method to the discretisation
    /// error rather than to round-off.
    Simultaneous,
}

/// The estimated remaining iteration error (weighted RMS, in the sensitivities' error weights)
/// a column of the simultaneous corrector may keep when the sensitivities stay out of the error
/// test: one error weight, the size of their local error tolerance, so the iteration adds no
/// more than the discretisation already allows (the state's own Newton iteration stops at
/// 0.05, since its iterate feeds the error estimate).
pub const SIMULTANEOUS_TOLERANCE: f64 = 1.0;

/// Settings of the sensitivity integration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SensitivityOptions {
    pub method: SensitivityMethod,
    /// Include the sensitivities in the local error test (`max(err_y, err_S)`).
    pub error_control: bool,
    /// Absolute tolerance of the sensitivities = this factor × the state's `atol` (component
    /// by component), over each variable's scale ([`DesignModel::with_variable_scales`]).
    pub atol_scale: f64,
}

impl Default for SensitivityOptions {
    fn default() -> Self {
        Self {
            method: SensitivityMethod::StaggeredDirect,
            error_control: false,
            atol_scale: 1.0,
        }
    }
}

impl SensitivityOptions {
    /// The simultaneous corrector ([`SensitivityMethod::Simultaneous`]).
    pub fn simultaneous() -> Self {
        Self {
            method: SensitivityMethod::Simultaneous,
            ..Self::default()
        }
    }

    /// Staggered corrector with the integrator's Newton tolerance (0.05 of the error norm).
    pub fn corrector() -> Self {
        Self {
            method: SensitivityMethod::StaggeredCorrector {
                tol: 0.05,
                max_iterations: 6,
            },
            ..Self::default()
        }
    }
}

/// Failure of a sensitivity analysis.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SensitivityError {
    #[error(transparent)]
    Constraint(#[from] ConstraintError),
    #[error(transparent)]
    Integration(#[from] IntegrationError),
    #[error("design model: {0}")]
    Layout(String),
    #[error("response: {0}")]
    Response(String),
    /// A dropped segment of a checkpointed run recomputed to other steps than the run's.
    #[error("checkpoint recomputation: {0}")]
    Recomputation(String),
}

/// Work counters of the sensitivity integration.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SensitivityStatistics {
    /// Dual evaluations of `f_y S + f_b` (one per chunk each).
    pub dual_evaluations: usize,
    pub corrector_iterations: usize,
    /// Exact Jacobians with an LU of `c_0 I − f_y` (direct method and corrector fallbacks).
    pub direct_solves: usize,
}

/// State and sensitivity histories at the accepted steps (and the initial point).
#[derive(Clone, Debug)]
pub struct SensitivityRun {
    pub n_q: usize,
    /// `t_0, t_1, …` (the integrator's steps).
    pub times: Vec<f64>,
    /// `y_i = [q; v]`.
    pub states: Vec<Vec<f64>>,
    /// `S_i = ∂y_i/∂b`, `n × m`.
    pub sensitivities: Vec<DMatrix<f64>>,
    /// Order of the step that ended at `times[i]` (0 for the initial point).
    pub orders: Vec<usize>,
    pub statistics: Statistics,
    pub sensitivity_statistics: SensitivityStatistics,
}

impl SensitivityRun {
    /// Options that replay this run's step sequence (orders and times), e.g. for finite
    /// differences of the discrete solution ([`StepControl::Replay`](crate::StepControl)).
    pub fn replay_options(&self, rtol: f64, atol: &[f64], newton_tol: f64) -> BdfOptions {
        BdfOptions::replay(
            self.times[1..].to_vec(),
            self.orders[1..].to_vec(),
            rtol,
            atol.to_vec(),
            newton_tol,
        )
    }

    /// State and sensitivities at `t` (within the run): the interpolant of the BDF formula of
    /// the step containing `t` (as [`Bdf::interpolate`]), the same weights for both, so the
    /// interpolated sensitivities are the derivatives of the interpolated state.
    pub fn interpolate(&self, t: f64) -> (Vec<f64>, DMatrix<f64>) {
        let (i, w) = self.interpolation(t);
        let y = mix(&w, |j| &self.states[i - j]);
        let mut s = DMatrix::zeros(self.sensitivities[i].nrows(), self.sensitivities[i].ncols());
        for (j, wj) in w.iter().enumerate() {
            s += &self.sensitivities[i - j] * *wj;
        }
        (y, s)
    }

    /// The recorded points [`SensitivityRun::interpolate`] mixes at `t`: `(i, w)`, the value at
    /// `t` being `Σ_j w_j y_{i−j}` (one weight 1 at a recorded point).
    pub fn interpolation(&self, t: f64) -> (usize, Vec<f64>) {
        interpolation(&self.times, &self.orders, t)
    }

    /// The run sampled at `t_out` (interpolated between steps, see
    /// [`SensitivityRun::interpolate`]); `orders` of the result are 0.
    pub fn resample(&self, t_out: &[f64]) -> SensitivityRun {
        let (states, sensitivities) = t_out.iter().map(|&t| self.interpolate(t)).unzip();
        SensitivityRun {
            n_q: self.n_q,
            times: t_out.to_vec(),
            states,
            sensitivities,
            orders: vec![0; t_out.len()],
            statistics: self.statistics,
            sensitivity_statistics: self.sensitivity_statistics,
        }
    }

    /// The state at point `i` as `(q, v)`.
    pub fn state(&self, i: usize) -> State {
        State::from_vec(&self.states[i], self.n_q)
    }
}

/// [`SensitivityRun::interpolation`] of a run's recorded `times` and `orders`.
pub(crate) fn interpolation(times: &[f64], orders: &[usize], t: f64) -> (usize, Vec<f64>) {
    let last = times.len() - 1;
    let i = times.partition_point(|&x| x < t).clamp(1.min(last), last);
    if times[i] == t || last == 0 {
        return (i, vec![1.0]);
    }
    let k = orders[i].max(1).min(i);
    let nodes: Vec<f64> = (0..=k).map(|j| times[i - j]).collect();
    (i, lagrange_weights(&nodes, t))
}

/// `Σ_j w_j y_j` of the states `y_j = state(j)` that [`interpolation`]'s weights `w` mix
/// (`j` back from the point it returns), summed in that order: the one way a sample of a run
/// is made from its recorded states, so that every sample of the same point is bitwise the same
/// whichever store the states come from.
pub(crate) fn mix<'a>(w: &[f64], state: impl Fn(usize) -> &'a [f64]) -> Vec<f64> {
    let mut y = vec![0.0; state(0).len()];
    for (j, wj) in w.iter().enumerate() {
        (y.iter_mut().zip(state(j))).for_each(|(a, b)| *a += wj * b);
    }
    y
}

fn rhs_failure(e: impl std::fmt::Display) -> IntegrationFailure {
    IntegrationFailure::Rhs(RhsError(e.to_string()))
}

/// A state (or any vector `y`) of a chunk as duals: value `y_i`, tangent `k` =
/// `s[(i, range.start + k)]` (`s` one column per design variable).
pub fn seeded<const N: usize>(
    y: &[f64],
    s: &DMatrix<f64>,
    range: &std::ops::Range<usize>,
) -> Vec<Dual<N>> {
    y.iter()
        .enumerate()
        .map(|(i, &x)| {
            let mut d = [0.0; N];
            for (k, j) in range.clone().enumerate() {
                d[k] = s[(i, j)];
            }
            Dual::new(x, d)
        })
        .collect()
}

/// `f_y S + f_b` at `(t, y)` for all design variables (`n × m`), one dual evaluation per
/// chunk; `sol` is the `f64` solution of Eq. (12) at `(t, y)`.
pub fn tangent_rhs<const N: usize>(
    sys: &MultibodySystem,
    design: &DesignModel<N>,
    t: f64,
    y: &[f64],
    sol: &Solution,
    s: &DMatrix<f64>,
) -> DMatrix<f64> {
    let nq = sys.model().n_q();
    let nv = sys.model().n_v();
    let mut out = DMatrix::zeros(nq + nv, design.n_variables());
    for (model, range) in design.chunk_ranges() {
        let yd = seeded::<N>(y, s, &range);
        let (qd, vd) = yd.split_at(nq);
        let res = model.residual(t, qd, vd, &sol.rows, &sol.x);
        let x = crate::system::lu_tangents(&sol.lu, &sol.x, &res);
        write_rates(&mut out, model, qd, vd, &x[..nv], range);
    }
    out
}

/// Columns `range` of `f_y S + f_b`: the tangents of `q̇` (from `(q, v)`) and of `v̇ = x`.
fn write_rates<const N: usize>(
    out: &mut DMatrix<f64>,
    model: &Model<Dual<N>>,
    q: &[Dual<N>],
    v: &[Dual<N>],
    vdot: &[Dual<N>],
    range: std::ops::Range<usize>,
) {
    let nq = q.len();
    let mut qdot = vec![Dual::<N>::constant(0.0); nq];
    model.kinematic_rates(q, v, &mut qdot);
    for (k, j) in range.enumerate() {
        for (i, x) in qdot.iter().chain(vdot).enumerate() {
            out[(i, j)] = x.d[k];
        }
    }
}

/// Eq. (12) solved at `(t, y)` from the values of the first chunk's dual evaluation
/// ([`MultibodySystem::solve_dual`]), and `f_y S + f_b` there (`n × m`); the guarded rows'
/// largest position violation is kept for the step check
/// ([`MultibodySystem::note_violation`]).
fn fused_rhs<const N: usize>(
    sys: &mut MultibodySystem,
    design: &DesignModel<N>,
    t: f64,
    y: &[f64],
    s: &DMatrix<f64>,
) -> Result<(Solution, DMatrix<f64>), ConstraintError> {
    let nq = sys.model().n_q();
    let nv = sys.model().n_v();
    let mut out = DMatrix::zeros(nq + nv, design.n_variables());
    let mut sol: Option<Solution> = None;
    for (model, range) in design.chunk_ranges() {
        let yd = seeded::<N>(y, s, &range);
        let (qd, vd) = yd.split_at(nq);
        let (sl, res) = match &sol {
            None => {
                let (sl, res, violation) = sys.solve_dual(model, t, qd, vd)?;
                sys.note_violation(t, violation);
                (&*sol.insert(sl), res)
            }
            Some(sl) => (sl, model.residual(t, qd, vd, &sl.rows, &sl.x)),
        };
        let x = crate::system::lu_tangents(&sl.lu, &sl.x, &res);
        write_rates(&mut out, model, qd, vd, &x[..nv], range);
    }
    Ok((sol.expect("at least one chunk"), out))
}

/// Initial sensitivities consistent with the constraints (Eq. 44), by the rule of
/// [`MultibodySystem::assemble`]: the elastic coordinates and rates are the user's (design
/// independent, so their sensitivities are zero) and only the rigid-body coordinates move.
///
/// - Positions: `Φ_q q_b = −Φ_b` solved for the rigid coordinates with the smallest
///   `q_bᵀ W q_b` (`W` the mass matrix's rigid block), the first-order change of the assembly
///   started from the assembled positions.
/// - Velocities: the derivative of the assembly's velocity projection started from the
///   velocities it was given (kept by [`MultibodySystem::assemble`]): with `Δ̂ = v̂ − v_guess`
///   and the projection's multipliers `μ̂`, `[W J_Iᵀ; J_I 0] [v_b; μ_b] = −∂/∂b [W Δ̂ + J_Iᵀ μ̂;
///   Φ̇_I(q(b), v̂)]`, the tangents evaluated by one dual evaluation per chunk (paper §4, the
///   pattern of Eq. 40). Exact for designs that change masses and joint geometry too.
///
/// Where the assembly gave the flexible bodies elastic rates (a mechanism locked when rigid,
/// [`MultibodySystem::elastic_rates`]), the velocities' rule runs over every rate with `W` the
/// whole mass matrix, as that projection did; the positions of a start with the bodies
/// deformed ([`MultibodySystem::elastic_start`]) by its optimality conditions differentiated
/// (the curvature of the joints under the prestress included).
///
/// `state` must be the state assembled by `sys` (if `sys` assembled another state, or none,
/// the velocities are taken as given: `Δ̂ = 0`). Returns `n × m`.
pub fn initial_sensitivities<const N: usize>(
    sys: &MultibodySystem,
    design: &DesignModel<N>,
    t0: f64,
    state: &State,
) -> Result<DMatrix<f64>, SensitivityError> {
    let model = sys.model();
    let (nq, nv) = (model.n_q(), model.n_v());
    let m = design.n_variables();
    let cols = sys.rigid_columns();
    let nr = cols.len();
    let c = model.constraints(t0, &state.q, &state.v);
    let kkt = sys.start_projection(t0, &state.q, &c.jacobian, &cols)?;
    let y = state.to_vec();
    let mut s = DMatrix::zeros(nq + nv, m);
    // positions: Φ_b with the state held, then the W-smallest rigid q_b; of a prestressed
    // start, its optimality conditions differentiated
    let mut col = vec![0.0; nq];
    if sys.elastic_start().is_some() {
        let sq = sys.prestress_sensitivities(design, t0, state)?;
        s.view_mut((0, 0), (nq, m)).copy_from(&sq);
    }
    for (dm, range) in design
        .chunk_ranges()
        .filter(|_| sys.elastic_start().is_none())
    {
        let yd = seeded::<N>(&y, &s, &range);
        let (qd, vd) = yd.split_at(nq);
        let phi = dm.constraints(t0, qd, vd).phi;
        for (t, j) in range.enumerate() {
            let b: Vec<f64> = kkt.rows.iter().map(|&r| -phi[r].d[t]).collect();
            let (dr, _) = kkt.solve(&vec![0.0; nr], &b);
            let mut d = vec![0.0; nv];
            for (&ci, x) in cols.iter().zip(dr) {
                d[ci] = x;
            }
            model.kinematic_rates(&state.q, &d, &mut col);
            for i in 0..nq {
                s[(i, j)] = col[i];
            }
        }
    }
    // velocities: the projection's increment and multipliers from the guess, over the rigid
    // rates, or every rate where the start gave the flexible bodies elastic rates (`W` is then
    // the whole mass matrix)
    let (cols, kkt) = if sys.elastic_rates() {
        let all: Vec<usize> = (0..nv).collect();
        let kkt = sys.start_projection(t0, &state.q, &c.jacobian, &all)?;
        (all, kkt)
    } else {
        (cols, kkt)
    };
    let nr = cols.len();
    let (dv, mu) = start_increment(sys, t0, (&state.q, &state.v), &kkt, nr);
    for (dm, range) in design.chunk_ranges() {
        let yd = seeded::<N>(&y, &s, &range);
        let (qd, vd) = yd.split_at(nq);
        let cd = dm.constraints(t0, qd, vd);
        let (md, _) = dm.mass_and_forces(t0, qd, vd);
        // −(W Δ̂ + J_Iᵀ μ̂) on the rigid columns, −Φ̇_I
        let r1: Vec<Dual<N>> = cols
            .iter()
            .map(|&ci| {
                let mut a = Dual::<N>::constant(0.0);
                for (&cj, &x) in cols.iter().zip(&dv) {
                    a += md[(ci, cj)] * x;
                }
                for (&r, &u) in kkt.rows.iter().zip(&mu) {
                    a += cd.jacobian[(r, ci)] * u;
                }
                -a
            })
            .collect();
        for (t, j) in range.enumerate() {
            let a: Vec<f64> = r1.iter().map(|x| x.d[t]).collect();
            let b: Vec<f64> = kkt.rows.iter().map(|&r| -cd.phi_dot[r].d[t]).collect();
            let (vb, _) = kkt.solve(&a, &b);
            for (&ci, x) in cols.iter().zip(vb) {
                s[(nq + ci, j)] = x;
            }
        }
    }
    Ok(s)
}

/// The velocity projection of [`MultibodySystem::assemble`] at `(q, v)` (its result) from the
/// velocities it was given (kept by the assembly; `v` itself if it assembled another state):
/// `(Δ̂, μ̂)`, its increment over the `n_cols` columns of `kkt` and its multipliers.
pub(crate) fn start_increment(
    sys: &MultibodySystem,
    t0: f64,
    (q, v): (&[f64], &[f64]),
    kkt: &StartProjection,
    n_cols: usize,
) -> (Vec<f64>, Vec<f64>) {
    let guess = match sys.start_guess() {
        Some(g) if g.t == t0 && g.q == q => g.v.clone(),
        _ => v.to_vec(),
    };
    let cg = sys.model().constraints(t0, q, &guess);
    let b: Vec<f64> = kkt.rows.iter().map(|&r| -cg.phi_dot[r]).collect();
    kkt.solve(&vec![0.0; n_cols], &b)
}

/// The sensitivities as a [`StepExtension`] of the integrator.
struct Extension<'d, const N: usize> {
    design: &'d DesignModel<N>,
    options: SensitivityOptions,
    /// `S_n, S_{n−1}, …` (most recent first).
    hist: VecDeque<DMatrix<f64>>,
    trial: Option<(f64, Vec<f64>, DMatrix<f64>, usize)>,
    stats: SensitivityStatistics,
    record: SensitivityRun,
    /// Corrector convergence-rate estimate and the Newton matrix's `c_0` it belongs to.
    rate: f64,
    last_c0: f64,
    /// Simultaneous corrector: each variable's convergence-rate estimate of its chord updates
    /// and the Newton matrix's `c_0` they belong to.
    column_rates: Vec<f64>,
    column_rates_c0: f64,
    /// Direct method: the last exact Jacobian and the LU of `c_0 I − f_y` with it.
    exact: Option<ExactMatrix>,
    /// Simultaneous corrector: the Newton iterate of the current trial step.
    newton: Option<NewtonIterate>,
}

/// The sensitivities' Newton iterate of the simultaneous corrector.
struct NewtonIterate {
    /// The current iterate `S`.
    s: DMatrix<f64>,
    /// `Σ_{j≥1} c_j S_{n+1−j}` of the step's formula and its `c_0`.
    psi: DMatrix<f64>,
    c0: f64,
    /// `f_y S + f_b` at the last Newton right-hand side, if it corrects the sensitivities.
    g: Option<DMatrix<f64>>,
    /// Weighted RMS norm of each column's last update (without error control).
    update_norms: Vec<f64>,
    /// Corrections applied so far in this step.
    corrections: usize,
}

/// An exact state Jacobian `f_y` (at some earlier step) and the LU of `c0 I − f_y`.
struct ExactMatrix {
    jac: DMatrix<f64>,
    c0: f64,
    lu: DenseLu,
    /// `(t, y)` where `jac` was evaluated.
    t: f64,
    y: Vec<f64>,
}

/// `acc += a x`, in place.
fn add_scaled(acc: &mut DMatrix<f64>, a: f64, x: &DMatrix<f64>) {
    for (y, x) in acc.as_mut_slice().iter_mut().zip(x.as_slice()) {
        *y += x * a;
    }
}

/// The absolute tolerances of the sensitivities: `atol_i · column_j` for component `i` of
/// variable `j`'s column (the state's `atol` times [`SensitivityOptions::atol_scale`], over the
/// variable's scale, [`DesignModel::with_variable_scales`]).
struct SensitivityAtol {
    atol: Vec<f64>,
    column: Vec<f64>,
}

impl SensitivityAtol {
    /// The error weight of entry `(i, j)` with the reference value `r`.
    fn weight(&self, rtol: f64, r: f64, i: usize, j: usize) -> f64 {
        rtol * r.abs() + self.atol[i] * self.column[j]
    }
}

/// [`wrms_matrix`] of each column alone.
fn column_norms(
    e: &DMatrix<f64>,
    reference: &DMatrix<f64>,
    rtol: f64,
    atol: &SensitivityAtol,
) -> Vec<f64> {
    (0..e.ncols())
        .map(|j| {
            let sum: f64 = (0..e.nrows())
                .map(|i| (e[(i, j)] / atol.weight(rtol, reference[(i, j)], i, j)).powi(2))
                .sum();
            (sum / e.nrows().max(1) as f64).sqrt()
        })
        .collect()
}

fn wrms_matrix(
    e: &DMatrix<f64>,
    reference: &DMatrix<f64>,
    rtol: f64,
    atol: &SensitivityAtol,
) -> f64 {
    let n = e.nrows();
    let mut sum = 0.0;
    for j in 0..e.ncols() {
        for i in 0..n {
            sum += (e[(i, j)] / atol.weight(rtol, reference[(i, j)], i, j)).powi(2);
        }
    }
    (sum / (e.len().max(1) as f64)).sqrt()
}

/// Convergence test of the iterations of [`SensitivityMethod::StaggeredDirect`]: estimated
/// remaining error (rate × last update, weighted RMS in the integrator's error norm) below 1e-6
/// of `rtol·|S| + atol`, i.e. about 1e-12 of `S` at `rtol = 1e-6`: the exact discrete
/// derivative to a few hundred round-offs. (At 1e-9 the test chased the round-off of `S`
/// itself: 3.4 dual evaluations a step on the §5.1 deck, results the same to 7 digits.)
const DIRECT_TOL: f64 = 1e-6;
/// Further chord updates of [`SensitivityMethod::Simultaneous`] (without error control) after
/// the state's Newton iteration, before the step's direct solve.
const SIMULTANEOUS_MAX_ITERATIONS: usize = 4;
/// Iterations of [`SensitivityMethod::StaggeredDirect`] before a new exact Jacobian.
const DIRECT_MAX_ITERATIONS: usize = 6;

impl<const N: usize> Extension<'_, N> {
    /// The predictor of a step to `t` of order `k`: the interpolant through the last `k + 1`
    /// accepted sensitivities (at `history_times`, most recent first).
    fn predictor(&self, history_times: &[f64], t: f64, k: usize) -> DMatrix<f64> {
        let np = (k + 1).min(self.hist.len());
        let w = lagrange_weights(&history_times[..np], t);
        let mut s = &self.hist[0] * w[0];
        for i in 1..np {
            add_scaled(&mut s, w[i], &self.hist[i]);
        }
        s
    }

    /// The constant part `ψ = Σ_{j≥1} c_j S_{n+1−j}` of the BDF formula with `coefficients`.
    fn formula_constant(&self, coefficients: &[f64]) -> DMatrix<f64> {
        let mut psi = &self.hist[0] * coefficients[1];
        for j in 2..coefficients.len() {
            add_scaled(&mut psi, coefficients[j], &self.hist[j - 1]);
        }
        psi
    }

    /// The sensitivities' absolute tolerances from the state's.
    fn sensitivity_atol(&self, atol: &[f64]) -> SensitivityAtol {
        SensitivityAtol {
            atol: atol.to_vec(),
            column: (self.design.scales.iter())
                .map(|b| self.options.atol_scale / b)
                .collect(),
        }
    }

    /// The weighted RMS local error estimate of the sensitivities `s` of a trial step (0 without
    /// error control, and in the start-up steps, which the state controls alone).
    fn error_estimate(
        &self,
        step: &TrialStep<'_>,
        s: &DMatrix<f64>,
        atol: &SensitivityAtol,
    ) -> f64 {
        if !self.options.error_control {
            return 0.0;
        }
        let k = step.order;
        match error_estimate_weights(step.times[0], &step.history_times, k) {
            Some(w) if self.hist.len() > k => {
                let mut e = s * w[0];
                for i in 1..w.len() {
                    add_scaled(&mut e, w[i], &self.hist[i - 1]);
                }
                wrms_matrix(&e, &self.hist[0], step.rtol, atol)
            }
            _ => 0.0,
        }
    }

    /// The staggered corrector: chord iterations `S ← S + s·M⁻¹(f_y S + f_b − c_0 S − ψ)`
    /// with the integrator's Newton matrix `M` from the interpolated predictor, until the
    /// weighted RMS update times the convergence-rate estimate is below `tol`; `None` after
    /// `max_iterations` or on a non-finite update.
    #[allow(clippy::too_many_arguments)]
    fn chord(
        &mut self,
        sys: &mut MultibodySystem,
        step: &TrialStep<'_>,
        sol: &Solution,
        psi: &DMatrix<f64>,
        atol: &SensitivityAtol,
        tol: f64,
        max_iterations: usize,
        mut s: DMatrix<f64>,
        g0: DMatrix<f64>,
    ) -> Result<Option<DMatrix<f64>>, IntegrationFailure> {
        let t = step.times[0];
        let c0 = step.coefficients[0];
        let y = &step.y_new;
        let mut g0 = Some(g0);
        let scale = if step.newton_c0 != c0 {
            2.0 * step.newton_c0 / (c0 + step.newton_c0)
        } else {
            1.0
        };
        // convergence-rate estimate as in the integrator's Newton iteration: carried over from
        // earlier steps, reset with every new Newton matrix
        if step.newton_c0 != self.last_c0 {
            self.rate = 1.0;
            self.last_c0 = step.newton_c0;
        }
        let mut previous = f64::INFINITY;
        for it in 0..max_iterations {
            let g = match g0.take() {
                Some(g) => g,
                None => {
                    self.stats.dual_evaluations += self.design.chunks.len();
                    tangent_rhs(sys, self.design, t, y, sol, &s)
                }
            };
            self.stats.corrector_iterations += 1;
            let mut r = g - &s * c0 - psi;
            if !step.newton_matrix.solve_matrix(&mut r) {
                return Err(IntegrationFailure::SingularNewtonMatrix);
            }
            r *= scale;
            let norm = wrms_matrix(&r, &self.hist[0], step.rtol, atol);
            s += r;
            if !norm.is_finite() {
                return Ok(None);
            }
            if it > 0 {
                self.rate = (norm / previous).max(0.3 * self.rate);
            }
            if norm * self.rate.min(1.0) < tol || norm < 1e-3 * tol {
                return Ok(Some(s));
            }
            previous = norm;
        }
        Ok(None)
    }

    /// The simultaneous corrector without error control, after the state's Newton iteration:
    /// a column whose estimated remaining iteration error (its rate estimate times its last
    /// update) is not below [`SIMULTANEOUS_TOLERANCE`] takes further chord updates at the
    /// converged state, each a dual evaluation, until it is (or, if they stall, the step's
    /// direct solve).
    ///
    /// Each column keeps its own rate estimate, as the integrator's Newton iteration does
    /// (CVODE's): 1 with every new Newton matrix, then `max(ratio, 0.3 · rate)` from the ratios
    /// of its successive updates. The state's rate is no guide: the chord operator is the
    /// same, but the sensitivities' updates lie along other directions (on the §5.1 rod a
    /// state rate of 8e-3 where the sensitivities contracted by 0.12 a step). Column by
    /// column, so a variable's sensitivities do not depend on which other variables are
    /// declared.
    fn converge_columns(
        &mut self,
        sys: &mut MultibodySystem,
        step: &TrialStep<'_>,
        atol: &SensitivityAtol,
        it: NewtonIterate,
    ) -> Result<DMatrix<f64>, IntegrationFailure> {
        let tol = SIMULTANEOUS_TOLERANCE;
        if step.newton_c0 != self.column_rates_c0 || self.column_rates.len() != it.s.ncols() {
            self.column_rates = vec![1.0; it.s.ncols()];
            self.column_rates_c0 = step.newton_c0;
        }
        let unconverged = |norm: f64, rate: f64| norm * rate >= tol && norm >= 1e-3 * tol;
        let mut pending: Vec<(usize, f64)> = it
            .update_norms
            .iter()
            .enumerate()
            .filter(|&(j, &n)| unconverged(n, self.column_rates[j]))
            .map(|(j, &n)| (j, n))
            .collect();
        let mut s = it.s;
        if pending.is_empty() {
            return Ok(s);
        }
        let (t, c0, y) = (step.times[0], step.coefficients[0], &step.y_new);
        let scale = if step.newton_c0 != c0 {
            2.0 * step.newton_c0 / (c0 + step.newton_c0)
        } else {
            1.0
        };
        // Eq. (12) at the converged state, solved by the first evaluation and kept for the
        // others (and for the direct solve)
        let mut solution: Option<Solution> = None;
        for _ in 0..SIMULTANEOUS_MAX_ITERATIONS {
            let g = match &solution {
                None => {
                    let (sol, g) = fused_rhs(sys, self.design, t, y, &s).map_err(rhs_failure)?;
                    solution = Some(sol);
                    g
                }
                Some(sol) => tangent_rhs(sys, self.design, t, y, sol, &s),
            };
            let sol = solution.as_ref().expect("solved above");
            self.stats.dual_evaluations += self.design.chunks.len();
            self.stats.corrector_iterations += 1;
            let mut r = g - &s * c0 - &it.psi;
            if !step.newton_matrix.solve_matrix(&mut r) {
                return Err(IntegrationFailure::SingularNewtonMatrix);
            }
            r *= scale;
            let norms = column_norms(&r, &self.hist[0], step.rtol, atol);
            let mut stalled = false;
            let rates = &mut self.column_rates;
            pending.retain_mut(|(j, previous)| {
                s.column_mut(*j).axpy(1.0, &r.column(*j), 1.0);
                let norm = norms[*j];
                let ratio = norm / *previous;
                stalled |= !(ratio <= 0.9);
                rates[*j] = ratio.max(0.3 * rates[*j]);
                *previous = norm;
                unconverged(norm, rates[*j])
            });
            if stalled {
                return self.direct(sys, t, y, sol, c0, &it.psi);
            }
            if pending.is_empty() {
                return Ok(s);
            }
        }
        let sol = solution.expect("at least one iteration");
        self.direct(sys, t, y, &sol, c0, &it.psi)
    }

    /// The step's linear system `(c_0 I − f_y) S = f_b − ψ` of the direct method, solved to
    /// round-off: chord iterations preconditioned with the LU of `c_0 I − f_y` at the last
    /// exact Jacobian (refactorised, not re-evaluated, when `c_0` changes), from the
    /// interpolated predictor, until the weighted RMS update is below [`DIRECT_TOL`]. When they
    /// converge slowly the exact Jacobian is evaluated at this state, and one more iteration
    /// with it is the exact solution.
    fn direct_step(
        &mut self,
        sys: &mut MultibodySystem,
        step: &TrialStep<'_>,
        sol: &Solution,
        psi: &DMatrix<f64>,
        atol: &SensitivityAtol,
        mut s: DMatrix<f64>,
        g0: DMatrix<f64>,
    ) -> Result<DMatrix<f64>, IntegrationFailure> {
        let t = step.times[0];
        let c0 = step.coefficients[0];
        let y = &step.y_new;
        let mut g0 = Some(g0);
        if self.exact.is_none() {
            self.refresh_exact(sys, t, y, c0)?;
        }
        if let Some(e) = self.exact.as_mut()
            && e.c0 != c0
        {
            e.lu = DenseLu::shifted(c0, &e.jac);
            e.c0 = c0;
        }
        let mut first = f64::INFINITY;
        for it in 0..DIRECT_MAX_ITERATIONS {
            let here = self.exact.as_ref().is_some_and(|e| e.t == t && e.y == *y);
            let norm = self.direct_iteration(sys, step, sol, psi, atol, &mut s, g0.take())?;
            if here || norm == 0.0 {
                return Ok(s);
            }
            if !norm.is_finite() {
                break;
            }
            if it == 0 {
                first = norm;
            } else {
                // the remaining error is about rate × the last update (linear convergence)
                let rate = (norm / first).powf(1.0 / it as f64);
                if rate < 0.5 && norm * rate / (1.0 - rate) < DIRECT_TOL {
                    return Ok(s);
                }
                // iterations still needed at the observed rate
                let needed = (DIRECT_TOL / (norm * rate)).ln() / rate.ln();
                if !(rate < 0.5 && needed <= (DIRECT_MAX_ITERATIONS - it - 1) as f64) {
                    break;
                }
            }
        }
        // the exact Jacobian here: one iteration with it solves the system
        self.refresh_exact(sys, t, y, c0)?;
        if s.iter().any(|x| !x.is_finite()) {
            s = self.hist[0].clone();
        }
        self.direct_iteration(sys, step, sol, psi, atol, &mut s, None)?;
        Ok(s)
    }

    /// `S ← S + (c_0 I − f_y,exact)⁻¹ (f_y S + f_b − c_0 S − ψ)`; returns the weighted RMS norm
    /// of the update.
    fn direct_iteration(
        &mut self,
        sys: &mut MultibodySystem,
        step: &TrialStep<'_>,
        sol: &Solution,
        psi: &DMatrix<f64>,
        atol: &SensitivityAtol,
        s: &mut DMatrix<f64>,
        g: Option<DMatrix<f64>>,
    ) -> Result<f64, IntegrationFailure> {
        let t = step.times[0];
        let c0 = step.coefficients[0];
        let g = match g {
            Some(g) => g,
            None => {
                self.stats.dual_evaluations += self.design.chunks.len();
                tangent_rhs(sys, self.design, t, &step.y_new, sol, s)
            }
        };
        self.stats.corrector_iterations += 1;
        let mut r = g - &*s * c0 - psi;
        let e = self.exact.as_ref().expect("an exact Jacobian");
        if !e.lu.is_invertible() {
            return Err(IntegrationFailure::SingularNewtonMatrix);
        }
        e.lu.solve_matrix(&mut r);
        let norm = wrms_matrix(&r, &self.hist[0], step.rtol, atol);
        *s += r;
        Ok(norm)
    }

    fn refresh_exact(
        &mut self,
        sys: &mut MultibodySystem,
        t: f64,
        y: &[f64],
        c0: f64,
    ) -> Result<(), IntegrationFailure> {
        let n = y.len();
        let mut jac = DMatrix::zeros(n, n);
        sys.jacobian(t, y, &mut jac)?;
        self.stats.direct_solves += 1;
        let lu = DenseLu::shifted(c0, &jac);
        self.exact = Some(ExactMatrix {
            jac,
            c0,
            lu,
            t,
            y: y.to_vec(),
        });
        Ok(())
    }

    fn direct(
        &mut self,
        sys: &mut MultibodySystem,
        t: f64,
        y: &[f64],
        sol: &Solution,
        c0: f64,
        psi: &DMatrix<f64>,
    ) -> Result<DMatrix<f64>, IntegrationFailure> {
        let n = y.len();
        let mut jac = DMatrix::zeros(n, n);
        sys.jacobian(t, y, &mut jac)?;
        let lu = DenseLu::shifted(c0, &jac);
        let fb = tangent_rhs(sys, self.design, t, y, sol, &DMatrix::zeros(n, psi.ncols()));
        self.stats.dual_evaluations += self.design.chunks.len();
        self.stats.direct_solves += 1;
        let mut s = fb - psi;
        if !lu.solve_matrix(&mut s) {
            return Err(IntegrationFailure::SingularNewtonMatrix);
        }
        Ok(s)
    }
}

impl<const N: usize> StepExtension<MultibodySystem> for Extension<'_, N> {
    fn controls_error(&self) -> bool {
        self.options.error_control
    }

    fn simultaneous(&self) -> bool {
        self.options.method == SensitivityMethod::Simultaneous
    }

    fn newton_begin(&mut self, times: &[f64], coefficients: &[f64], history_times: &[f64]) {
        let k = coefficients.len() - 1;
        self.newton = Some(NewtonIterate {
            s: self.predictor(history_times, times[0], k),
            psi: self.formula_constant(coefficients),
            c0: coefficients[0],
            g: None,
            update_norms: Vec::new(),
            corrections: 0,
        });
    }

    fn newton_rhs(
        &mut self,
        sys: &mut MultibodySystem,
        t: f64,
        y: &[f64],
        dy: &mut [f64],
    ) -> Result<(), RhsError> {
        let it = self
            .newton
            .as_mut()
            .expect("newton_begin precedes newton_rhs");
        if !self.options.error_control && it.corrections > 0 {
            // one correction per step without error control: the state's further iterations
            // take plain evaluations
            it.g = None;
            return OdeSystem::rhs(sys, t, y, dy);
        }
        sys.report_progress(t);
        let (sol, g) =
            fused_rhs(sys, self.design, t, y, &it.s).map_err(|e| RhsError(e.to_string()))?;
        self.stats.dual_evaluations += self.design.chunks.len();
        sys.write_rates(y, &sol, dy);
        it.g = Some(g);
        Ok(())
    }

    fn newton_correct(
        &mut self,
        newton_matrix: &NewtonMatrix,
        scale: f64,
        rtol: f64,
        atol: &[f64],
    ) -> Result<f64, IntegrationFailure> {
        let atol = self.sensitivity_atol(atol);
        let it = self
            .newton
            .as_mut()
            .expect("newton_begin precedes newton_correct");
        let Some(g) = it.g.take() else {
            return Ok(0.0); // the state's iteration alone (see `newton_rhs`)
        };
        it.corrections += 1;
        // r = g − c_0 S − ψ, in place
        let mut r = g;
        for ((x, s), p) in r
            .as_mut_slice()
            .iter_mut()
            .zip(it.s.as_slice())
            .zip(it.psi.as_slice())
        {
            *x = *x - s * it.c0 - p;
        }
        if !newton_matrix.solve_matrix(&mut r) {
            return Err(IntegrationFailure::SingularNewtonMatrix);
        }
        if scale != 1.0 {
            r *= scale;
        }
        self.stats.corrector_iterations += 1;
        it.s += &r;
        // in the convergence test with error control; otherwise a single update, whose
        // remaining iteration error the trial step checks column by column (see
        // `converge_columns`); non-finite updates still fail the iteration
        Ok(if self.options.error_control {
            wrms_matrix(&r, &self.hist[0], rtol, &atol)
        } else {
            it.update_norms = column_norms(&r, &self.hist[0], rtol, &atol);
            if it.update_norms.iter().all(|x| x.is_finite()) {
                0.0
            } else {
                f64::INFINITY
            }
        })
    }

    fn trial(
        &mut self,
        sys: &mut MultibodySystem,
        step: &TrialStep<'_>,
    ) -> Result<f64, IntegrationFailure> {
        let t = step.times[0];
        let k = step.order;
        let c = &step.coefficients;
        let y = &step.y_new;
        let atol = self.sensitivity_atol(step.atol);
        if self.options.method == SensitivityMethod::Simultaneous {
            let it = self
                .newton
                .take()
                .expect("a Newton iteration precedes the trial");
            let s = if self.options.error_control {
                it.s
            } else {
                self.converge_columns(sys, step, &atol, it)?
            };
            let err = self.error_estimate(step, &s, &atol);
            self.trial = Some((t, y.clone(), s, k));
            return Ok(err);
        }
        // predictor: the interpolant through the past sensitivities; the first evaluation of
        // `f_y S + f_b` there also gives the solution of Eq. (12) at the new state
        let s_pred = self.predictor(&step.history_times, t, k);
        let (sol, g0) = fused_rhs(sys, self.design, t, y, &s_pred).map_err(rhs_failure)?;
        self.stats.dual_evaluations += self.design.chunks.len();
        let psi = self.formula_constant(c);
        let c0 = c[0];
        let s = match self.options.method {
            SensitivityMethod::StaggeredDirect => {
                self.direct_step(sys, step, &sol, &psi, &atol, s_pred, g0)?
            }
            SensitivityMethod::StaggeredCorrector {
                tol,
                max_iterations,
            } => match self.chord(
                sys,
                step,
                &sol,
                &psi,
                &atol,
                tol,
                max_iterations,
                s_pred,
                g0,
            )? {
                Some(s) => s,
                None => self.direct(sys, t, y, &sol, c0, &psi)?,
            },
            SensitivityMethod::Simultaneous => unreachable!("handled above"),
        };
        if s.iter().any(|x| !x.is_finite()) {
            return Err(IntegrationFailure::NonFinite);
        }
        let err = self.error_estimate(step, &s, &atol);
        self.trial = Some((t, y.clone(), s, k));
        Ok(err)
    }

    fn accept(&mut self) {
        let (t, y, s, k) = self.trial.take().expect("a trial step precedes acceptance");
        self.hist.push_front(s.clone());
        self.hist.truncate(8);
        self.record.times.push(t);
        self.record.states.push(y);
        self.record.sensitivities.push(s);
        self.record.orders.push(k);
    }
}

/// Integrate the state and its sensitivities from the (assembled) `state` at `t0` to `t_end`:
/// histories at every accepted step. The initial sensitivities are
/// [`initial_sensitivities`].
pub fn simulate_sensitivities<const N: usize>(
    sys: &mut MultibodySystem,
    design: &DesignModel<N>,
    state: &State,
    t0: f64,
    t_end: f64,
    bdf_options: BdfOptions,
    options: &SensitivityOptions,
) -> Result<SensitivityRun, SensitivityError> {
    design.check(sys)?;
    let s0 = initial_sensitivities(sys, design, t0, state)?;
    simulate_sensitivities_from(sys, design, state, &s0, t0, t_end, bdf_options, options)
}

/// As [`simulate_sensitivities`] with given initial sensitivities `s0` (`n × m`).
pub fn simulate_sensitivities_from<const N: usize>(
    sys: &mut MultibodySystem,
    design: &DesignModel<N>,
    state: &State,
    s0: &DMatrix<f64>,
    t0: f64,
    t_end: f64,
    bdf_options: BdfOptions,
    options: &SensitivityOptions,
) -> Result<SensitivityRun, SensitivityError> {
    design.check(sys)?;
    let y0 = state.to_vec();
    if s0.nrows() != y0.len() || s0.ncols() != design.n_variables() {
        return Err(SensitivityError::Layout(format!(
            "initial sensitivities are {}×{}, expected {}×{}",
            s0.nrows(),
            s0.ncols(),
            y0.len(),
            design.n_variables()
        )));
    }
    let mut bdf = Bdf::new(bdf_options);
    bdf.init(sys, t0, &y0)?;
    let mut ext = Extension {
        design,
        options: *options,
        hist: VecDeque::from([s0.clone()]),
        trial: None,
        stats: SensitivityStatistics::default(),
        rate: 1.0,
        last_c0: f64::NAN,
        column_rates: Vec::new(),
        column_rates_c0: f64::NAN,
        exact: None,
        newton: None,
        record: SensitivityRun {
            n_q: sys.model().n_q(),
            times: vec![t0],
            states: vec![y0],
            sensitivities: vec![s0.clone()],
            orders: vec![0],
            statistics: Statistics::default(),
            sensitivity_statistics: SensitivityStatistics::default(),
        },
    };
    while bdf.current().0 < t_end {
        bdf.step_with(sys, t_end, &mut ext)?;
    }
    let mut run = ext.record;
    run.statistics = bdf.statistics();
    run.sensitivity_statistics = ext.stats;
    Ok(run)
}

/// A plain run recording every accepted step (the nominal analysis, e.g. to time it or to
/// record a step sequence for replay): times, states and orders.
pub fn simulate_steps(
    sys: &mut MultibodySystem,
    state: &State,
    t0: f64,
    t_end: f64,
    bdf_options: BdfOptions,
) -> Result<SensitivityRun, SensitivityError> {
    let y0 = state.to_vec();
    let mut bdf = Bdf::new(bdf_options);
    bdf.init(sys, t0, &y0)?;
    let n = y0.len();
    let mut run = SensitivityRun {
        n_q: sys.model().n_q(),
        times: vec![t0],
        states: vec![y0],
        sensitivities: vec![DMatrix::zeros(n, 0)],
        orders: vec![0],
        statistics: Statistics::default(),
        sensitivity_statistics: SensitivityStatistics::default(),
    };
    while bdf.current().0 < t_end {
        bdf.step(sys, t_end)?;
        let st = bdf.last_step();
        run.times.push(st.times[0]);
        run.states.push(st.states[0].to_vec());
        run.sensitivities.push(DMatrix::zeros(n, 0));
        run.orders.push(st.order);
    }
    run.statistics = bdf.statistics();
    Ok(run)
}
