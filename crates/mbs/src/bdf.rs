//! A variable-order (1–5), variable-step BDF integrator in variable-coefficient form.
//!
//! Step `n → n+1` of order `k` solves `Σ_{j=0..k} c_j y_{n+1−j} = f(t_{n+1}, y_{n+1})`, where
//! `c_j = ℓ_j'(t_{n+1})` are the derivatives of the Lagrange basis through
//! `t_{n+1}, t_n, …, t_{n+1−k}`, by Newton's method with the matrix `c_0 I − J` (`J = f_y`,
//! kept and reused while Newton converges; dense, or in a structure of the system's own for
//! large systems, [`OdeSystem::structured_jacobian`]). The local error of order `j` is estimated from
//! the divided difference of order `j+1` through the new point and the history,
//! `err_j ≈ |y[t_{n+1}, …, t_{n−j}]| Π_{i=1..j} h_i / Σ_{i=1..j} 1/h_i` with
//! `h_i = t_{n+1} − t_{n+1−i}` (exact leading term of the variable-grid local error).
//!
//! After every accepted step [`Bdf::last_step`] describes it (order, step, coefficients, the
//! times and states of the formula and the factorised Newton matrix): the
//! sensitivity integration ([`crate::sensitivity`]) solves
//! `(c_0 I − f_y) s_{n+1} = −Σ_{j≥1} c_j s_{n+1−j} + f_b` on exactly this step sequence.

use std::collections::VecDeque;

use nalgebra::{Complex, DMatrix};
use sens::{DenseLu, LinearSolver};

/// An ODE `y' = f(t, y)` with an exact Jacobian.
pub trait OdeSystem {
    fn dim(&self) -> usize;
    /// `dy = f(t, y)`.
    fn rhs(&mut self, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), RhsError>;
    /// `jac = ∂f/∂y (t, y)`.
    fn jacobian(&mut self, t: f64, y: &[f64], jac: &mut DMatrix<f64>) -> Result<(), RhsError>;
    /// `∂f/∂y (t, y)` in a structure of the system's own, for systems too large for the dense
    /// Jacobian and its LU; `None` (the default): the integrator uses
    /// [`OdeSystem::jacobian`].
    fn structured_jacobian(
        &mut self,
        _t: f64,
        _y: &[f64],
    ) -> Option<Result<Box<dyn StructuredJacobian>, RhsError>> {
        None
    }
    /// A state that passed the error test, before it is accepted: `Err(why)` refuses a state
    /// that no tolerance would allow (a broken constraint, a deformation far outside the
    /// model's range). The step is retried at order 1 with a quarter of the step; a refusal
    /// that persists ends the integration with [`IntegrationFailure::Refused`].
    fn check_step(&mut self, _t: f64, _y: &[f64]) -> Result<(), String> {
        Ok(())
    }
    /// Times where `f` has a kink or a jump in time (the points of a forcing table, the ends
    /// of a ramp): adaptive steps land on them instead of stepping across, so that no change
    /// of the forcing falls between two evaluations.
    fn breakpoints(&self) -> Vec<f64> {
        Vec::new()
    }
}

/// `∂f/∂y` kept in a structure of the system's own ([`OdeSystem::structured_jacobian`]).
pub trait StructuredJacobian {
    /// `c0 · I − ∂f/∂y`, factorised; `None` if it is singular.
    fn factor(&self, c0: f64) -> Option<Box<dyn LinearSolver>>;
    /// The eigenvalues of `∂f/∂y` the stability limit keeps inside the stability region (see
    /// [`StepControl::Adaptive`]): the oscillatory ones, `Im λ > |Re λ|`, `Re λ ≤ 0`, or
    /// estimates of them.
    fn oscillatory_eigenvalues(&self) -> Vec<Complex<f64>>;
}

/// `∂f/∂y` as the integrator keeps it between refreshes.
enum Jacobian {
    Dense(DMatrix<f64>),
    Structured(Box<dyn StructuredJacobian>),
}

/// The matrix of the integrator's Newton iterations, `c0 · I − ∂f/∂y`, factorised.
pub enum NewtonMatrix {
    /// The LU of the dense matrix.
    Dense(DenseLu),
    /// The system's factorisation ([`StructuredJacobian::factor`]).
    Structured(Box<dyn LinearSolver>),
}

impl std::fmt::Debug for NewtonMatrix {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Dense(lu) => f.debug_tuple("Dense").field(lu).finish(),
            Self::Structured(s) => write!(f, "Structured({} unknowns)", s.dim()),
        }
    }
}

impl NewtonMatrix {
    /// `b ← N⁻¹ b`; `false` if the dense matrix is singular (a structured factorisation
    /// refused singular matrices when it was made).
    pub fn solve_in_place(&self, b: &mut [f64]) -> bool {
        match self {
            Self::Dense(lu) => lu.solve_in_place(b),
            Self::Structured(s) => {
                s.solve_columns(b, 1);
                true
            }
        }
    }

    /// `B ← N⁻¹ B`; `false` if the dense matrix is singular.
    pub fn solve_matrix(&self, b: &mut DMatrix<f64>) -> bool {
        match self {
            Self::Dense(lu) => lu.solve_matrix(b),
            Self::Structured(s) => {
                let n = b.ncols();
                s.solve_columns(b.as_mut_slice(), n);
                true
            }
        }
    }
}

/// A right-hand side that could not be evaluated.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct RhsError(pub String);

/// How steps are chosen.
#[derive(Clone, Debug, PartialEq)]
pub enum StepControl {
    /// Local error control with `rtol`, `atol` of [`BdfOptions`], orders `1..=max_order`.
    Adaptive {
        max_order: usize,
        /// First step (s); estimated when `None`.
        initial_step: Option<f64>,
        min_step: f64,
        max_step: f64,
        /// Keep every oscillatory eigenvalue of the Jacobian inside the stability region of
        /// the order used (see [`stable_step`]): orders 3–5 are not A-stable, and on lightly
        /// damped modes that the tolerance leaves unresolved they grow by up to 4 % (order 3)
        /// to 37 % (order 5) a step until the error test notices, rejects, and the cycle
        /// starts again. The eigenvalues are computed at every new Jacobian.
        stability_limit: bool,
    },
    /// Constant step `step` (s) and order `order` (lower orders while the history fills,
    /// unless a history is supplied with [`Bdf::init_with_history`]). `rtol`/`atol` only
    /// set the Newton convergence test.
    Fixed { step: f64, order: usize },
    /// Replay a recorded step sequence: step `i` ends at `times[i]` and uses the BDF formula of
    /// order `orders[i]` (e.g. those of a nominal run, [`AcceptedStep`]), with no error test.
    /// Newton iterates until its weighted update norm is below `newton_tol` (with `rtol`,
    /// `atol` as weights), so that runs of perturbed designs on the same steps differ only by
    /// the design (finite differences of the discrete solution).
    Replay {
        times: Vec<f64>,
        orders: Vec<usize>,
        newton_tol: f64,
    },
}

/// Integrator settings.
#[derive(Clone, Debug, PartialEq)]
pub struct BdfOptions {
    pub rtol: f64,
    /// Absolute tolerance per component (one value is broadcast to all components).
    pub atol: Vec<f64>,
    pub control: StepControl,
    /// Maximum number of step attempts.
    pub max_steps: usize,
    /// Newton iterations per attempt.
    pub max_newton_iterations: usize,
    /// Recompute the Jacobian after this many steps even if Newton converges.
    pub jacobian_age: usize,
    /// Fixed steps only: the `(rtol, atol)` the run is meant to meet (`atol` as
    /// [`BdfOptions::atol`]). Each step's local error is estimated against them as the
    /// adaptive control would (the steps do not change), and the largest ratio is reported in
    /// [`Statistics::max_error_ratio`].
    pub accuracy: Option<(f64, Vec<f64>)>,
}

/// The order and step limits of a step control ([`Bdf::step_with`]).
struct StepLimits {
    replay: bool,
    fixed: bool,
    max_order: usize,
    min_step: f64,
    max_step: f64,
}

/// A replayed step's Newton iteration ([`StepControl::Replay`]) that stops converging (an
/// update no smaller than 0.9 of the last) within this factor of its threshold is accepted:
/// the replays' thresholds are tight (1e-6 of the error weights at `rtol = 1e-6`), and with
/// small absolute tolerances some components' updates reach the round-off of their
/// equations first (the undamped steel slider-crank of `examples/time_to_accuracy` under
/// displacement weights, whose absolute tolerances are 4.6e-11: its replays failed).
pub const REPLAY_STALL: f64 = 1e3;

/// The default [`BdfOptions::jacobian_age`]. A Newton iteration that fails refreshes the
/// Jacobian anyway; the age is the safety net for a slowly drifting one (and for the
/// oscillatory eigenvalues of the stability limit, computed with it). 100 steps instead of 50:
/// the Jacobians and their eigenvalues were 19 % of the §5.1 deck's analysis; with half as many
/// it is 9 % faster (the plate deck 6 %, the steel slider-crank 10 %, the spin-up unchanged)
/// for 3 % more right-hand sides, the printed results within their discretisation error
/// (docs/performance.md).
pub const JACOBIAN_AGE: usize = 100;

impl BdfOptions {
    /// Adaptive control with the given tolerances.
    pub fn adaptive(rtol: f64, atol: f64) -> Self {
        Self {
            rtol,
            atol: vec![atol],
            control: StepControl::Adaptive {
                max_order: 5,
                initial_step: None,
                min_step: 1e-14,
                max_step: f64::INFINITY,
                stability_limit: true,
            },
            max_steps: 1_000_000,
            max_newton_iterations: 4,
            jacobian_age: JACOBIAN_AGE,
            accuracy: None,
        }
    }

    /// Replay of a recorded step sequence (see [`StepControl::Replay`]); `rtol`, `atol` weigh
    /// the Newton test `‖Δy‖ < newton_tol`.
    pub fn replay(
        times: Vec<f64>,
        orders: Vec<usize>,
        rtol: f64,
        atol: Vec<f64>,
        newton_tol: f64,
    ) -> Self {
        Self {
            rtol,
            atol,
            control: StepControl::Replay {
                times,
                orders,
                newton_tol,
            },
            max_steps: 10_000_000,
            max_newton_iterations: 30,
            jacobian_age: JACOBIAN_AGE,
            accuracy: None,
        }
    }

    /// Fixed step and order; Newton tolerances `rtol = 1e-10`, `atol = 1e-12`.
    pub fn fixed(step: f64, order: usize) -> Self {
        Self {
            rtol: 1e-10,
            atol: vec![1e-12],
            control: StepControl::Fixed { step, order },
            max_steps: 10_000_000,
            max_newton_iterations: 8,
            jacobian_age: JACOBIAN_AGE,
            accuracy: None,
        }
    }
}

/// Work counters.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Statistics {
    /// Accepted steps.
    pub steps: usize,
    /// Steps rejected by the error test.
    pub rejected_steps: usize,
    /// Step attempts abandoned because Newton did not converge.
    pub newton_failures: usize,
    pub newton_iterations: usize,
    pub rhs_evaluations: usize,
    pub jacobians: usize,
    pub factorizations: usize,
    /// Steps whose order was lowered to keep an oscillatory eigenvalue stable
    /// ([`StepControl::Adaptive::stability_limit`]).
    pub stability_limited: usize,
    /// Steps refused by [`OdeSystem::check_step`] (and retried).
    pub refused_steps: usize,
    /// A fixed-step run with [`BdfOptions::accuracy`]: the largest estimated local error of a
    /// step relative to those tolerances (above 1: the steps are too long for them); 0
    /// otherwise.
    pub max_error_ratio: f64,
}

/// Why integration stopped.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum IntegrationFailure {
    #[error("step size fell below the minimum {min_step:e} s")]
    StepTooSmall { min_step: f64 },
    #[error("Newton iteration failed to converge {attempts} times in a row")]
    NewtonFailed { attempts: usize },
    #[error("error test failed {attempts} times in a row")]
    ErrorTestFailed { attempts: usize },
    #[error("more than {max_steps} step attempts")]
    TooManySteps { max_steps: usize },
    #[error("the Newton matrix c0·I − J is singular")]
    SingularNewtonMatrix,
    #[error("non-finite solution")]
    NonFinite,
    #[error("right-hand side failed: {0}")]
    Rhs(#[from] RhsError),
    #[error("invalid settings: {0}")]
    Settings(&'static str),
    /// [`OdeSystem::check_step`] refused the state again at the smallest steps tried.
    #[error("{0}")]
    Refused(String),
}

/// Integration failure with the time and step size where it happened.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("integration failed at t = {t} s with step h = {h:e} s: {reason}")]
pub struct IntegrationError {
    pub t: f64,
    pub h: f64,
    pub reason: IntegrationFailure,
}

/// One accepted step: what a sensitivity integrator needs to follow it.
#[derive(Debug)]
pub struct AcceptedStep<'a> {
    /// Order `k` of the formula used.
    pub order: usize,
    /// Step `h = t_{n+1} − t_n` (s).
    pub step: f64,
    /// `t_{n+1}, t_n, …, t_{n+1−k}` (most recent first).
    pub times: &'a [f64],
    /// `c_0 … c_k` of `Σ c_j y_{n+1−j} = f(t_{n+1}, y_{n+1})`.
    pub coefficients: &'a [f64],
    /// `y_{n+1}, y_n, …` (most recent first; at least `k+1` entries).
    pub states: Vec<&'a [f64]>,
    /// `newton_c0 · I − J`, factorised, with the Jacobian `J` of an earlier state when
    /// reused.
    pub newton_matrix: &'a NewtonMatrix,
    pub newton_c0: f64,
}

/// A trial step whose Newton iteration converged: what variables integrated alongside the
/// state (sensitivities) need to take the same step with the same formula.
#[derive(Debug)]
pub struct TrialStep<'a> {
    /// Order `k` of the formula.
    pub order: usize,
    /// `t_{n+1}, t_n, …, t_{n+1−k}`.
    pub times: Vec<f64>,
    /// `c_0 … c_k` of `Σ c_j y_{n+1−j} = f(t_{n+1}, y_{n+1})`.
    pub coefficients: Vec<f64>,
    /// The converged `y_{n+1}`.
    pub y_new: Vec<f64>,
    /// Accepted states `y_n, y_{n−1}, …` (most recent first) and their times.
    pub history: Vec<&'a [f64]>,
    pub history_times: Vec<f64>,
    /// `newton_c0 · I − J`, factorised, with the Jacobian `J` possibly of an older state.
    pub newton_matrix: &'a NewtonMatrix,
    pub newton_c0: f64,
    /// Error weights of the state: `rtol·|y| + atol_i`.
    pub rtol: f64,
    pub atol: &'a [f64],
}

/// Variables integrated alongside the state on the same steps ([`Bdf::step_with`]), e.g.
/// forward sensitivities.
///
/// Staggered extensions solve their variables once the state's Newton iteration has converged
/// ([`StepExtension::trial`]). Simultaneous ones ([`StepExtension::simultaneous`]) are corrected
/// inside it: every Newton iteration evaluates the state's right-hand side through
/// [`StepExtension::newton_rhs`] (which may share work with the extension's own right-hand
/// side) and then applies [`StepExtension::newton_correct`]; the iteration stops when the
/// state and the extension have both converged.
pub trait StepExtension<Sys: ?Sized> {
    /// Whether the extension's error estimate joins the step-size control (then
    /// [`StepExtension::trial`] is called for every trial step before the error test).
    fn controls_error(&self) -> bool {
        false
    }
    /// Whether the extension is corrected inside the state's Newton iteration.
    fn simultaneous(&self) -> bool {
        false
    }
    /// Simultaneous extensions: a Newton iteration starts for the formula `coefficients` over
    /// `times` (`t_{n+1}, t_n, …`), the accepted points being at `history_times`.
    fn newton_begin(&mut self, _times: &[f64], _coefficients: &[f64], _history_times: &[f64]) {}
    /// Simultaneous extensions: `f(t, y)` into `dy` (with the extension's own right-hand side
    /// at its current iterate, kept for [`StepExtension::newton_correct`]).
    fn newton_rhs(
        &mut self,
        _sys: &mut Sys,
        _t: f64,
        _y: &[f64],
        _dy: &mut [f64],
    ) -> Result<(), RhsError> {
        Err(RhsError(
            "a staggered extension has no Newton right-hand side".into(),
        ))
    }
    /// Simultaneous extensions: one chord update with the Newton matrix `newton_matrix`
    /// (`= newton_c0 · I − J`, scaled by `scale` for the step's `c0`); returns the update's
    /// weighted RMS norm in the integrator's error weights (`rtol`, `atol` of the state).
    fn newton_correct(
        &mut self,
        _newton_matrix: &NewtonMatrix,
        _scale: f64,
        _rtol: f64,
        _atol: &[f64],
    ) -> Result<f64, IntegrationFailure> {
        Ok(0.0)
    }
    /// Solve the extension's variables on the trial step (simultaneous extensions: take their
    /// converged iterate); return their weighted RMS local error estimate (used only when
    /// [`StepExtension::controls_error`]).
    fn trial(&mut self, sys: &mut Sys, step: &TrialStep<'_>) -> Result<f64, IntegrationFailure>;
    /// The last trial step was accepted.
    fn accept(&mut self);
}

/// No extension.
pub struct NoExtension;

impl<Sys: ?Sized> StepExtension<Sys> for NoExtension {
    fn trial(&mut self, _sys: &mut Sys, _step: &TrialStep<'_>) -> Result<f64, IntegrationFailure> {
        Ok(0.0)
    }
    fn accept(&mut self) {}
}

/// Weights `w_i` of the local error estimate of order `order` for the new point at `t_new` and
/// the past points at `past` (most recent first): `err ≈ w_0 y_{n+1} + Σ_{i≥1} w_i y_{n+1−i}`
/// (the integrator's own estimate). `None` without enough history.
pub fn error_estimate_weights(t_new: f64, past: &[f64], order: usize) -> Option<Vec<f64>> {
    if order == 0 || past.len() < order + 1 {
        return None;
    }
    let mut pn = vec![t_new];
    pn.extend(past.iter().take(order + 1));
    let w = divided_difference_weights(&pn);
    let mut prod = 1.0;
    let mut sum = 0.0;
    for x in &pn[1..=order] {
        prod *= t_new - x;
        sum += 1.0 / (t_new - x);
    }
    Some(w.iter().map(|w| w * prod / sum).collect())
}

/// Lagrange interpolation weights through `nodes` at `t`: `p(t) = Σ w_i y_i`.
pub fn lagrange_weights(nodes: &[f64], t: f64) -> Vec<f64> {
    (0..nodes.len())
        .map(|i| {
            let mut w = 1.0;
            for (m, &x) in nodes.iter().enumerate() {
                if m != i {
                    w *= (t - x) / (nodes[i] - x);
                }
            }
            w
        })
        .collect()
}

/// Growth per step that the stability limit tolerates: a mode may grow by at most 0.1 % a
/// step (10 % over a hundred steps). Resolved modes stay far below it (order 3 at 20 steps a
/// period of an undamped oscillation: 0.18 %, which the error test sees as truncation error);
/// unresolved ones above it grow by 1–37 % a step.
pub const STABILITY_GROWTH: f64 = 1e-3;

/// Whether constant-step BDF of order `k` is stable for `z = hλ`: every root `ζ` of
/// `Σ_j α_j ζ^{k−j} = z ζ^k` has `|ζ| ≤ 1 +` [`STABILITY_GROWTH`] (the Schur–Cohn test on
/// the polynomial with its roots scaled by that radius). Orders 1 and 2 are A-stable; orders
/// 3–5 are unstable on a lobe of the left half-plane along the imaginary axis, undamped
/// oscillations with `ωh` up to 1.93 (order 3), 4.71 (4) and 9.39 (5). `false` for an order
/// outside 1–5.
pub fn bdf_stable(k: usize, z: Complex<f64>) -> bool {
    if !(1..=5).contains(&k) {
        // the integrator's orders are 1 to 5
        return false;
    }
    // the constant-step coefficients of orders 0..=5, made once
    static ALPHA: std::sync::OnceLock<Vec<Vec<f64>>> = std::sync::OnceLock::new();
    let alpha = &ALPHA.get_or_init(|| {
        (0..=5)
            .map(|k| bdf_coefficients(&(0..=k).map(|j| -(j as f64)).collect::<Vec<_>>()))
            .collect()
    })[k];
    // a[i]: coefficient of w^i of p((1 + growth) w); fixed arrays, since the step control
    // calls this in its bisections at every step
    let radius = 1.0 + STABILITY_GROWTH;
    let mut a = [Complex::new(0.0, 0.0); 6];
    let mut scale = 1.0;
    for (i, ai) in a.iter_mut().enumerate().take(k + 1) {
        let c = if i == k {
            Complex::new(alpha[0], 0.0) - z
        } else {
            Complex::new(alpha[k - i], 0.0)
        };
        *ai = c * scale;
        scale *= radius;
    }
    // Schur–Cohn: with |a_0| < |a_n|, p has its roots in the open unit disk iff
    // (conj(a_n) p − a_0 p*) / w does, p* being p with reversed conjugated coefficients. That
    // polynomial's leading coefficient is |a_n|² − |a_0|² > 0; dividing by it keeps the
    // coefficients near 1 (they would square at every level), so squared moduli compare safely.
    let mut n = k;
    while n > 0 {
        let lead = a[n].norm_sqr() - a[0].norm_sqr();
        if lead.is_nan() || lead <= 0.0 {
            return false;
        }
        let (an, a0) = (a[n].conj(), a[0]);
        let mut next = [Complex::new(0.0, 0.0); 6];
        for i in 1..n {
            next[i - 1] = (an * a[i] - a0 * a[n - i].conj()) / lead;
        }
        next[n - 1] = Complex::new(1.0, 0.0);
        a = next;
        n -= 1;
    }
    true
}

/// The largest step `≤ h` at which constant-step BDF of order `q` is stable
/// ([`bdf_stable`]) for every eigenvalue in `eigenvalues`: `h` itself for the A-stable orders
/// 1 and 2. Along the ray of an eigenvalue of the left half-plane the orders 3–5 are stable
/// from the origin up to the lobe of instability (and again beyond it), so the first crossing
/// below `h` is found by bisection.
pub fn stable_step(q: usize, h: f64, eigenvalues: &[Complex<f64>]) -> f64 {
    stable_step_cached(q, h, eigenvalues, None)
}

/// [`stable_step`] remembering, per eigenvalue and order, the edge of the lobe a bisection
/// found (`edges[i][q]`, NaN while unknown): a step inside eigenvalue `i`'s lobe is cut to that
/// edge again, one stability test instead of a bisection (the step control asks at every step
/// for several orders, with the eigenvalues fixed until the next Jacobian). The lobe along a
/// ray is one interval starting at its edge, so a step inside it is cut to the same point.
fn stable_step_cached(
    q: usize,
    h: f64,
    eigenvalues: &[Complex<f64>],
    mut edges: Option<&mut [[f64; 6]]>,
) -> f64 {
    if q <= 2 {
        return h;
    }
    let mut step = h;
    // a cut for one eigenvalue can move another (stable beyond its lobe) into its lobe
    while let Some(i) = eigenvalues.iter().position(|&l| !bdf_stable(q, l * step)) {
        let l = eigenvalues[i];
        let known = edges.as_ref().map_or(f64::NAN, |e| e[i][q]);
        if known < step && bdf_stable(q, l * known) {
            step = known;
            continue;
        }
        let (mut lo, mut hi) = (0.0, step);
        for _ in 0..30 {
            let mid = 0.5 * (lo + hi);
            if bdf_stable(q, l * mid) {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        step = lo;
        if let Some(e) = edges.as_mut() {
            e[i][q] = lo;
        }
    }
    step
}

/// The eigenvalues of `jac` that can leave the stability region of orders 3–5: those of the
/// upper half-plane within 45° of the imaginary axis, `Im λ > |Re λ|`, with `Re λ ≤ 0`
/// (growing physical modes grow under any method). Every BDF order up to 5 is stable within
/// 51° of the negative real axis. Empty if the eigenvalues cannot be computed.
pub(crate) fn oscillatory_eigenvalues(jac: &DMatrix<f64>) -> Vec<Complex<f64>> {
    if jac.iter().any(|x| !x.is_finite()) {
        return Vec::new();
    }
    let n = jac.nrows();
    let a = faer::Mat::<f64>::from_fn(n, jac.ncols(), |i, j| jac[(i, j)]);
    let Ok(eigenvalues) = a.eigenvalues() else {
        return Vec::new();
    };
    eigenvalues
        .iter()
        .filter(|l| l.re <= 0.0 && l.im > l.re.abs())
        .map(|l| Complex::new(l.re, l.im))
        .collect()
}

/// Derivatives at `nodes[0]` of the Lagrange basis through `nodes`.
pub(crate) fn bdf_coefficients(nodes: &[f64]) -> Vec<f64> {
    let x0 = nodes[0];
    let mut c = vec![0.0; nodes.len()];
    c[0] = nodes[1..].iter().map(|&x| 1.0 / (x0 - x)).sum();
    for j in 1..nodes.len() {
        let mut num = 1.0;
        let mut den = 1.0;
        for (m, &x) in nodes.iter().enumerate() {
            if m != j {
                den *= nodes[j] - x;
                if m != 0 {
                    num *= x0 - x;
                }
            }
        }
        c[j] = num / den;
    }
    c
}

/// Weights of the divided difference of top order through `nodes`.
fn divided_difference_weights(nodes: &[f64]) -> Vec<f64> {
    (0..nodes.len())
        .map(|i| {
            let mut p = 1.0;
            for (m, &x) in nodes.iter().enumerate() {
                if m != i {
                    p *= nodes[i] - x;
                }
            }
            1.0 / p
        })
        .collect()
}

const HISTORY: usize = 8;

/// A [`Bdf`] between two steps ([`Bdf::snapshot`]): its history, step and order control, and
/// the point its Jacobian was evaluated at instead of the matrix.
pub struct BdfSnapshot {
    bdf: Bdf,
    /// Whether the Newton matrix was factorised (at the snapshot's `lu_c0`).
    factorised: bool,
}

impl BdfSnapshot {
    /// The integrator as it was: its Jacobian evaluated again at the same point with `sys`
    /// and factorised again, then its counters and estimates set back to what they were. The
    /// steps it takes are bitwise those of the integrator the snapshot was taken of if `sys`
    /// evaluates the same numbers at the same points (a [`crate::MultibodySystem`] of the same
    /// model and assembly: its right-hand side, Jacobian and step check depend on `(t, y)`
    /// alone, the check on the right-hand side the step's Newton iteration evaluated at the
    /// same `t`).
    pub fn restore(&self, sys: &mut impl OdeSystem) -> Result<Bdf, IntegrationError> {
        let was = &self.bdf;
        let mut bdf = was.clone_without_matrices();
        if was.jac_age.is_some() {
            let (t, y) = &was.jac_point;
            bdf.refresh_jacobian(sys, *t, y)?;
            if self.factorised {
                bdf.factorize(was.lu_c0)?;
            }
            bdf.stats = was.stats;
            bdf.jac_age = was.jac_age;
            bdf.newton_rate = was.newton_rate;
            bdf.oscillatory = was.oscillatory.clone();
            *bdf.stability_edges.borrow_mut() = was.stability_edges.borrow().clone();
        }
        Ok(bdf)
    }

    /// The time of the snapshot (of the integrator's current state).
    pub fn time(&self) -> f64 {
        self.bdf.hist[0].0
    }

    /// The accepted state `back` points before the current one (0: the current one), where
    /// the integrator's history still holds it (up to 7 back).
    pub fn history(&self, back: usize) -> Option<&[f64]> {
        self.bdf.hist.get(back).map(|(_, y)| y.as_slice())
    }

    /// The snapshot's size in bytes (its vectors).
    pub fn bytes(&self) -> usize {
        let b = &self.bdf;
        let vectors = b.hist.len() + 3 + usize::from(b.jac_age.is_some());
        8 * b.n * vectors + 8 * (b.last_times.len() + b.last_coeffs.len())
    }
}

/// The BDF integrator. See the module documentation.
pub struct Bdf {
    opts: BdfOptions,
    stats: Statistics,
    /// `(t, y)` most recent first.
    hist: VecDeque<(f64, Vec<f64>)>,
    /// `f(t0, y0)` for the start-up predictor.
    f0: Vec<f64>,
    order: usize,
    h: f64,
    steps_at_order: usize,
    jac: Jacobian,
    /// Where `jac` was evaluated: a [`BdfSnapshot`] keeps this instead of the matrix.
    jac_point: (f64, Vec<f64>),
    jac_age: Option<usize>,
    lu: Option<NewtonMatrix>,
    lu_c0: f64,
    /// Newton convergence-rate estimate (reset to 1 with every new matrix).
    newton_rate: f64,
    last_rhs_error: Option<RhsError>,
    last_times: Vec<f64>,
    last_coeffs: Vec<f64>,
    last_order: usize,
    n: usize,
    atol: Vec<f64>,
    /// Next step of a [`StepControl::Replay`] sequence.
    replay_pos: usize,
    /// Oscillatory eigenvalues of the last Jacobian (stability limit).
    oscillatory: Vec<Complex<f64>>,
    /// The lobe edges found for them, per order ([`stable_step_cached`]).
    stability_edges: std::cell::RefCell<Vec<[f64; 6]>>,
    /// The system's breakpoints (adaptive control), increasing.
    breakpoints: Vec<f64>,
    /// No step taken yet from an estimated first step (it is then also held to 1 % of the
    /// span to the first stop).
    first_step: bool,
}

impl Bdf {
    pub fn new(opts: BdfOptions) -> Self {
        Self {
            opts,
            stats: Statistics::default(),
            hist: VecDeque::new(),
            f0: Vec::new(),
            order: 1,
            h: 0.0,
            steps_at_order: 0,
            jac: Jacobian::Dense(DMatrix::zeros(0, 0)),
            jac_point: (0.0, Vec::new()),
            jac_age: None,
            lu: None,
            lu_c0: 0.0,
            newton_rate: 1.0,
            last_rhs_error: None,
            last_times: Vec::new(),
            last_coeffs: Vec::new(),
            last_order: 0,
            n: 0,
            atol: Vec::new(),
            replay_pos: 0,
            oscillatory: Vec::new(),
            stability_edges: std::cell::RefCell::new(Vec::new()),
            breakpoints: Vec::new(),
            first_step: false,
        }
    }

    pub fn statistics(&self) -> Statistics {
        self.stats
    }

    /// Current time and state.
    pub fn current(&self) -> (f64, &[f64]) {
        let (t, y) = &self.hist[0];
        (*t, y)
    }

    /// Order and step size planned for the next step.
    pub fn next_order_and_step(&self) -> (usize, f64) {
        (self.order, self.h)
    }

    fn fail(&self, reason: IntegrationFailure) -> IntegrationError {
        IntegrationError {
            t: self.hist.front().map_or(f64::NAN, |x| x.0),
            h: self.h,
            reason,
        }
    }

    fn check_options(&self) -> Result<(), IntegrationError> {
        let o = &self.opts;
        let bad = |s| {
            Err(IntegrationError {
                t: f64::NAN,
                h: 0.0,
                reason: IntegrationFailure::Settings(s),
            })
        };
        if !(o.rtol >= 0.0) {
            return bad("rtol must be non-negative");
        }
        // a zero absolute tolerance makes the weight of a vanishing component zero and the
        // error norm 0/0 (as in CVODE, every entry must be positive)
        for atol in std::iter::once(&o.atol).chain(o.accuracy.as_ref().map(|(_, a)| a)) {
            if atol.iter().any(|&a| !(a > 0.0 && a.is_finite())) {
                return bad("every atol entry must be positive and finite");
            }
            if atol.len() != 1 && atol.len() != self.n {
                return bad("atol must have one entry or one per component");
            }
        }
        match o.control {
            StepControl::Adaptive {
                max_order,
                min_step,
                max_step,
                ..
            } => {
                if !(1..=5).contains(&max_order) {
                    return bad("order must be 1..=5");
                }
                if !(min_step > 0.0 && max_step > min_step) {
                    return bad("need 0 < min_step < max_step");
                }
            }
            StepControl::Fixed { step, order } => {
                if !(1..=5).contains(&order) {
                    return bad("order must be 1..=5");
                }
                if !(step > 0.0 && step.is_finite()) {
                    return bad("step must be positive");
                }
            }
            StepControl::Replay {
                ref times,
                ref orders,
                newton_tol,
            } => {
                if times.len() != orders.len() {
                    return bad("replay needs one order per step");
                }
                if orders.iter().any(|o| !(1..=5).contains(o)) {
                    return bad("order must be 1..=5");
                }
                if times.windows(2).any(|w| !(w[1] > w[0])) {
                    return bad("replay times must increase");
                }
                if !(newton_tol > 0.0) {
                    return bad("newton_tol must be positive");
                }
            }
        }
        Ok(())
    }

    /// Start at `(t0, y0)`.
    pub fn init(
        &mut self,
        sys: &mut impl OdeSystem,
        t0: f64,
        y0: &[f64],
    ) -> Result<(), IntegrationError> {
        self.init_with_history(sys, &[t0], &[y0.to_vec()])
    }

    /// Start from a history `(times[i], states[i])` in increasing time (the last one is the
    /// current state): BDF of order up to `times.len()` can be used from the first step.
    pub fn init_with_history(
        &mut self,
        sys: &mut impl OdeSystem,
        times: &[f64],
        states: &[Vec<f64>],
    ) -> Result<(), IntegrationError> {
        self.n = sys.dim();
        self.check_options()?;
        self.hist.clear();
        for (t, y) in times.iter().zip(states).rev().take(HISTORY) {
            self.hist.push_back((*t, y.clone()));
        }
        self.atol = per_component(&self.opts.atol, self.n).collect();
        let (t0, y0) = self.hist[0].clone();
        let mut f0 = vec![0.0; self.n];
        sys.rhs(t0, &y0, &mut f0).map_err(|e| self.fail(e.into()))?;
        self.stats.rhs_evaluations += 1;
        self.f0 = f0;
        self.steps_at_order = 0;
        self.lu = None;
        self.jac_age = None;
        self.replay_pos = 0;
        match self.opts.control {
            StepControl::Fixed { step, order } => {
                self.h = step;
                self.order = order.min(self.hist.len());
            }
            StepControl::Replay {
                ref times,
                ref orders,
                ..
            } => {
                // skip recorded steps at or before the start
                while self.replay_pos < times.len() && times[self.replay_pos] <= t0 {
                    self.replay_pos += 1;
                }
                if let Some(&t1) = times.get(self.replay_pos) {
                    self.h = t1 - t0;
                    self.order = orders[self.replay_pos];
                }
            }
            StepControl::Adaptive {
                initial_step,
                max_step,
                min_step,
                ..
            } => {
                self.order = 1.min(self.hist.len());
                if let StepControl::Adaptive { max_order, .. } = self.opts.control
                    && self.hist.len() > 1
                {
                    self.order = (self.hist.len() - 1).clamp(1, max_order);
                }
                let mut bp = sys.breakpoints();
                bp.retain(|t| t.is_finite());
                bp.sort_by(f64::total_cmp);
                self.breakpoints = bp;
                self.h = if self.hist.len() > 1 {
                    // a supplied history sets the step
                    self.hist[0].0 - self.hist[1].0
                } else {
                    match initial_step {
                        Some(h) => h,
                        None => {
                            self.first_step = true;
                            self.estimate_first_step(sys, t0, &y0)?
                        }
                    }
                    .clamp(min_step, max_step)
                };
            }
        }
        Ok(())
    }

    /// The first step from the problem's own time scales: the step of an explicit Euler step
    /// whose local error `½ h² ‖ÿ‖` is 1 % of the tolerance, `ÿ` measured by a difference of
    /// `f` over a trial step (the starting-step algorithm of Hairer, Nørsett & Wanner, Solving
    /// ODEs I, §II.4): forcing that changes near the start shows in that difference. It is
    /// held to one radian of the fastest oscillation of the Jacobian at the start (computed
    /// here, and used by the first step), and the first step itself to 1 % of the span to the
    /// first stop and to the first breakpoint.
    fn estimate_first_step(
        &mut self,
        sys: &mut impl OdeSystem,
        t0: f64,
        y0: &[f64],
    ) -> Result<f64, IntegrationError> {
        let d0 = self.wrms(y0, y0);
        let d1 = self.wrms(&self.f0, y0);
        let h0 = if d0 < 1e-5 || d1 < 1e-5 {
            1e-6
        } else {
            0.01 * d0 / d1
        };
        let y1: Vec<f64> = y0.iter().zip(&self.f0).map(|(y, f)| y + h0 * f).collect();
        let mut f1 = vec![0.0; self.n];
        sys.rhs(t0 + h0, &y1, &mut f1)
            .map_err(|e| self.fail(e.into()))?;
        self.stats.rhs_evaluations += 1;
        let df: Vec<f64> = f1.iter().zip(&self.f0).map(|(a, b)| (a - b) / h0).collect();
        let d2 = self.wrms(&df, y0);
        let h1 = if d1.max(d2) <= 1e-15 {
            (h0 * 1e-3).max(1e-6)
        } else {
            (0.01 / d1.max(d2)).sqrt()
        };
        let mut h = (100.0 * h0).min(h1);
        self.refresh_jacobian(sys, t0, y0)?;
        let fastest = self
            .oscillatory
            .iter()
            .map(|l| l.norm())
            .fold(0.0, f64::max);
        if fastest > 0.0 {
            h = h.min(1.0 / fastest);
        }
        Ok(h)
    }

    fn wrms(&self, e: &[f64], y: &[f64]) -> f64 {
        weighted_rms(e, y, self.opts.rtol, self.atol.iter().copied())
    }

    fn refresh_jacobian(
        &mut self,
        sys: &mut impl OdeSystem,
        t: f64,
        y: &[f64],
    ) -> Result<(), IntegrationError> {
        match sys.structured_jacobian(t, y) {
            Some(j) => self.jac = Jacobian::Structured(j.map_err(|e| self.fail(e.into()))?),
            None => {
                if !matches!(&self.jac, Jacobian::Dense(j) if j.nrows() == self.n) {
                    self.jac = Jacobian::Dense(DMatrix::zeros(self.n, self.n));
                }
                let Jacobian::Dense(jac) = &mut self.jac else {
                    unreachable!("made dense above")
                };
                let r = sys.jacobian(t, y, jac);
                r.map_err(|e| self.fail(e.into()))?;
            }
        }
        self.stats.jacobians += 1;
        self.jac_point = (t, y.to_vec());
        if let StepControl::Adaptive {
            stability_limit: true,
            ..
        } = self.opts.control
        {
            self.oscillatory = match &self.jac {
                Jacobian::Dense(j) => oscillatory_eigenvalues(j),
                Jacobian::Structured(j) => j.oscillatory_eigenvalues(),
            };
            *self.stability_edges.borrow_mut() = vec![[f64::NAN; 6]; self.oscillatory.len()];
        }
        self.jac_age = Some(0);
        self.lu = None;
        Ok(())
    }

    fn factorize(&mut self, c0: f64) -> Result<(), IntegrationError> {
        let lu = match &self.jac {
            Jacobian::Dense(jac) => {
                let lu = DenseLu::shifted(c0, jac);
                lu.is_invertible().then_some(NewtonMatrix::Dense(lu))
            }
            Jacobian::Structured(j) => j.factor(c0).map(NewtonMatrix::Structured),
        };
        self.stats.factorizations += 1;
        let Some(lu) = lu else {
            return Err(self.fail(IntegrationFailure::SingularNewtonMatrix));
        };
        self.lu = Some(lu);
        self.lu_c0 = c0;
        self.newton_rate = 1.0;
        Ok(())
    }

    fn trial_info(&self, k: usize, nodes: &[f64], coeffs: &[f64], y_new: &[f64]) -> TrialStep<'_> {
        TrialStep {
            order: k,
            times: nodes.to_vec(),
            coefficients: coeffs.to_vec(),
            y_new: y_new.to_vec(),
            history: self.hist.iter().map(|x| x.1.as_slice()).collect(),
            history_times: self.hist.iter().map(|x| x.0).collect(),
            newton_matrix: self.lu.as_ref().expect("factorised"),
            newton_c0: self.lu_c0,
            rtol: self.opts.rtol,
            atol: &self.atol,
        }
    }

    /// Take one accepted step (retrying with smaller steps as needed), not beyond `t_stop`.
    pub fn step(&mut self, sys: &mut impl OdeSystem, t_stop: f64) -> Result<(), IntegrationError> {
        self.step_with(sys, t_stop, &mut NoExtension)
    }

    /// [`Bdf::step`] with variables integrated alongside on the same steps (see
    /// [`StepExtension`]): `ext.trial` is called for every trial step that Newton solved, before
    /// the error test when `ext.controls_error()` (its error norm then joins the test as
    /// `max(err_state, err_ext)`), otherwise once the step is accepted; `ext.accept` follows
    /// every accepted step.
    pub fn step_with<Sys: OdeSystem, E: StepExtension<Sys>>(
        &mut self,
        sys: &mut Sys,
        t_stop: f64,
        ext: &mut E,
    ) -> Result<(), IntegrationError> {
        let limits = self.limits();
        let (fixed, min_step) = (limits.fixed, limits.min_step);
        let mut newton_fails = 0;
        let mut error_fails = 0;
        let mut refusals = 0;
        loop {
            let Some((h, t_new)) = self.plan_step(t_stop, &limits)? else {
                return Ok(());
            };
            let k = self.order.min(self.hist.len()).max(1);
            let (nodes, coeffs, y_pred, psi) = self.predict(k, t_new, h);
            let Some(y_new) = self.solve_step(sys, ext, &nodes, &coeffs, &y_pred, &psi)? else {
                self.stats.newton_failures += 1;
                newton_fails += 1;
                let reason = match self.last_rhs_error.take() {
                    Some(e) => IntegrationFailure::Rhs(e),
                    None if self.h * 0.25 < min_step => {
                        IntegrationFailure::StepTooSmall { min_step }
                    }
                    None => IntegrationFailure::NewtonFailed {
                        attempts: newton_fails,
                    },
                };
                if fixed || newton_fails >= 10 || h * 0.25 < min_step {
                    return Err(self.fail(reason));
                }
                self.h = h * 0.25;
                continue;
            };
            let mut err = self.local_error(k, t_new, &y_new, &y_pred, fixed);
            self.observe_accuracy(k, t_new, &y_new, &y_pred);
            if !err.is_finite() {
                return Err(self.fail(IntegrationFailure::NonFinite));
            }
            if ext.controls_error() {
                let info = self.trial_info(k, &nodes, &coeffs, &y_new);
                let e = ext.trial(sys, &info).map_err(|r| self.fail(r))?;
                if !e.is_finite() {
                    return Err(self.fail(IntegrationFailure::NonFinite));
                }
                if !fixed {
                    err = err.max(e);
                }
            }
            if err > 1.0 {
                error_fails += 1;
                self.reject(err, k, h, error_fails, min_step)?;
                continue;
            }
            if let Err(why) = sys.check_step(t_new, &y_new) {
                self.stats.refused_steps += 1;
                refusals += 1;
                let h_next = h * 0.25;
                if fixed || refusals >= 4 || h_next < min_step {
                    return Err(IntegrationError {
                        t: t_new,
                        h,
                        reason: IntegrationFailure::Refused(why),
                    });
                }
                self.h = h_next;
                self.order = 1;
                self.steps_at_order = 0;
                continue;
            }
            if !ext.controls_error() {
                let info = self.trial_info(k, &nodes, &coeffs, &y_new);
                ext.trial(sys, &info).map_err(|r| self.fail(r))?;
            }
            ext.accept();
            if self.accept(k, nodes, coeffs, t_new, y_new) {
                self.choose_next(k, h, err, error_fails, &limits);
            }
            return Ok(());
        }
    }

    /// The step control's order and step limits.
    fn limits(&self) -> StepLimits {
        let replay = matches!(self.opts.control, StepControl::Replay { .. });
        let fixed = replay || matches!(self.opts.control, StepControl::Fixed { .. });
        let (max_order, min_step, max_step) = match self.opts.control {
            StepControl::Adaptive {
                max_order,
                min_step,
                max_step,
                ..
            } => (max_order, min_step, max_step),
            StepControl::Fixed { order, step } => (order, step * 1e-12, f64::INFINITY),
            StepControl::Replay { .. } => (5, 0.0, f64::INFINITY),
        };
        StepLimits {
            replay,
            fixed,
            max_order,
            min_step,
            max_step,
        }
    }

    /// The next trial step `(h, t_new)` towards `t_stop` (or the next breakpoint): the replayed
    /// one, or the current step cut to land on `t_stop` without a sliver; `None` at `t_stop`.
    fn plan_step(
        &mut self,
        t_stop: f64,
        limits: &StepLimits,
    ) -> Result<Option<(f64, f64)>, IntegrationError> {
        let (replay, fixed, min_step) = (limits.replay, limits.fixed, limits.min_step);
        if self.stats.steps + self.stats.rejected_steps + self.stats.newton_failures
            >= self.opts.max_steps
        {
            return Err(self.fail(IntegrationFailure::TooManySteps {
                max_steps: self.opts.max_steps,
            }));
        }
        let (tn, _) = self.current();
        // adaptive steps stop at the next breakpoint
        let next = self.breakpoints[self
            .breakpoints
            .partition_point(|&b| b <= tn + 1e-12 * tn.abs())..]
            .first();
        let t_stop = match next {
            Some(&b) if !fixed && b < t_stop => b,
            _ => t_stop,
        };
        if self.first_step {
            self.h = self.h.min(0.01 * (t_stop - tn));
        }
        let mut h = self.h;
        let remaining = t_stop - tn;
        if remaining <= 0.0 {
            return Ok(None);
        }
        let mut t_new = tn + h;
        if let StepControl::Replay {
            ref times,
            ref orders,
            ..
        } = self.opts.control
        {
            let Some(&t1) = times.get(self.replay_pos) else {
                return Err(self.fail(IntegrationFailure::Settings(
                    "the replayed step sequence ends before t_stop",
                )));
            };
            t_new = t1.min(t_stop);
            h = t_new - tn;
            self.order = orders[self.replay_pos];
        } else if h >= remaining - 1e-8 * h {
            h = remaining;
            t_new = t_stop;
        } else if !fixed && h > 0.5 * remaining && h < remaining {
            // avoid a sliver step before t_stop
            h = 0.5 * remaining;
        }
        if h < min_step && h < remaining {
            return Err(self.fail(IntegrationFailure::StepTooSmall { min_step }));
        }
        if !replay {
            t_new = tn + h;
        }
        Ok(Some((h, t_new)))
    }

    /// The nodes and coefficients of the BDF formula of order `k` for the step to `t_new`,
    /// the predictor (the interpolant through up to `k + 1` past points, or explicit Euler at
    /// the start) and the constant part `ψ` of the formula.
    #[allow(clippy::type_complexity)]
    fn predict(&self, k: usize, t_new: f64, h: f64) -> (Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>) {
        let mut nodes = Vec::with_capacity(k + 1);
        nodes.push(t_new);
        nodes.extend(self.hist.iter().take(k).map(|x| x.0));
        let coeffs = bdf_coefficients(&nodes);
        // predictor: interpolant through up to k+1 past points, or explicit Euler at start
        let y_pred: Vec<f64> = if self.hist.len() >= 2 {
            let np = (k + 1).min(self.hist.len());
            let pn: Vec<f64> = self.hist.iter().take(np).map(|x| x.0).collect();
            let w = lagrange_weights(&pn, t_new);
            let mut y = vec![0.0; self.n];
            for (wi, (_, yi)) in w.iter().zip(&self.hist) {
                for (a, b) in y.iter_mut().zip(yi) {
                    *a += wi * b;
                }
            }
            y
        } else {
            self.hist[0]
                .1
                .iter()
                .zip(&self.f0)
                .map(|(y, f)| y + h * f)
                .collect()
        };
        // constant part of the formula
        let mut psi = vec![0.0; self.n];
        for j in 1..=k {
            for (a, b) in psi.iter_mut().zip(&self.hist[j - 1].1) {
                *a += coeffs[j] * b;
            }
        }
        (nodes, coeffs, y_pred, psi)
    }

    /// Newton's method on the step's formula, with a Jacobian refreshed when it is old or
    /// when Newton fails on an older one; `None` when it does not converge.
    fn solve_step<Sys: OdeSystem, E: StepExtension<Sys>>(
        &mut self,
        sys: &mut Sys,
        ext: &mut E,
        nodes: &[f64],
        coeffs: &[f64],
        y_pred: &[f64],
        psi: &[f64],
    ) -> Result<Option<Vec<f64>>, IntegrationError> {
        let t_new = nodes[0];
        let c0 = coeffs[0];
        if self.jac_age.is_none() || self.jac_age.unwrap() >= self.opts.jacobian_age {
            self.refresh_jacobian(sys, t_new, y_pred)?;
        }
        let mut jac_fresh = self.jac_age == Some(0);
        let mut result = None;
        for _attempt in 0..2 {
            if self.lu.is_none() || ((c0 / self.lu_c0) - 1.0).abs() > 0.2 {
                self.factorize(c0)?;
            }
            match self.newton(sys, ext, nodes, coeffs, y_pred, psi)? {
                Some(y) => {
                    result = Some(y);
                    break;
                }
                None if !jac_fresh => {
                    self.refresh_jacobian(sys, t_new, y_pred)?;
                    jac_fresh = true;
                }
                None => break,
            }
        }
        if result.is_some() {
            self.last_rhs_error = None;
        }
        Ok(result)
    }

    /// The local error norm of the trial point `(t_new, y_new)` of order `k` (0 for fixed
    /// steps).
    fn local_error(&self, k: usize, t_new: f64, y_new: &[f64], y_pred: &[f64], fixed: bool) -> f64 {
        if fixed {
            return 0.0;
        }
        self.wrms(
            &self.error_estimate(k, t_new, y_new, y_pred),
            &self.hist[0].1,
        )
    }

    /// A fixed-step run with [`BdfOptions::accuracy`]: the trial point's estimated local error
    /// against those tolerances, the largest kept in the statistics.
    fn observe_accuracy(&mut self, k: usize, t_new: f64, y_new: &[f64], y_pred: &[f64]) {
        let (StepControl::Fixed { .. }, Some((rtol, atol))) =
            (&self.opts.control, &self.opts.accuracy)
        else {
            return;
        };
        let e = self.error_estimate(k, t_new, y_new, y_pred);
        let ratio = weighted_rms(&e, &self.hist[0].1, *rtol, per_component(atol, e.len()));
        if ratio.is_finite() {
            self.stats.max_error_ratio = self.stats.max_error_ratio.max(ratio);
        }
    }

    /// The estimated local error of the trial point `(t_new, y_new)` of order `k`, per
    /// component (at the start, backward against explicit Euler).
    fn error_estimate(&self, k: usize, t_new: f64, y_new: &[f64], y_pred: &[f64]) -> Vec<f64> {
        if self.hist.len() < k + 1 {
            // start-up: backward vs explicit Euler, LTE ≈ ½ |difference|
            return y_new
                .iter()
                .zip(y_pred)
                .map(|(a, b)| 0.5 * (a - b))
                .collect();
        }
        // the divided difference of order k + 1 through the new point and the history
        let mut pn = vec![t_new];
        pn.extend(self.hist.iter().take(k + 1).map(|x| x.0));
        let w = divided_difference_weights(&pn);
        let mut dd = y_new.iter().map(|y| w[0] * y).collect::<Vec<_>>();
        for (wi, (_, yi)) in w[1..].iter().zip(&self.hist) {
            for (a, b) in dd.iter_mut().zip(yi) {
                *a += wi * b;
            }
        }
        let mut prod = 1.0;
        let mut sum = 0.0;
        for x in &pn[1..=k] {
            prod *= t_new - x;
            sum += 1.0 / (t_new - x);
        }
        let scale = prod / sum;
        dd.iter().map(|d| d * scale).collect()
    }

    /// A trial step rejected by the error test (the `error_fails`-th in a row): the next step
    /// cut, down to order 1 after three rejections; an error after twelve, or below the
    /// smallest step.
    fn reject(
        &mut self,
        err: f64,
        k: usize,
        h: f64,
        error_fails: usize,
        min_step: f64,
    ) -> Result<(), IntegrationError> {
        self.stats.rejected_steps += 1;
        if error_fails >= 12 {
            return Err(self.fail(IntegrationFailure::ErrorTestFailed {
                attempts: error_fails,
            }));
        }
        let factor = (0.9 * err.powf(-1.0 / (k as f64 + 1.0))).clamp(0.1, 0.9);
        self.h = h * if error_fails >= 3 {
            factor.min(0.25)
        } else {
            factor
        };
        if error_fails >= 3 {
            self.order = 1;
            self.steps_at_order = 0;
        }
        if self.h < min_step {
            return Err(self.fail(IntegrationFailure::StepTooSmall { min_step }));
        }
        Ok(())
    }

    /// Accept the step of order `k` to `(t_new, y_new)`; the next step and order of a fixed
    /// or replayed sequence. Whether the step control still has to choose them (adaptive).
    fn accept(
        &mut self,
        k: usize,
        nodes: Vec<f64>,
        coeffs: Vec<f64>,
        t_new: f64,
        y_new: Vec<f64>,
    ) -> bool {
        self.first_step = false;
        self.stats.steps += 1;
        if let Some(a) = self.jac_age.as_mut() {
            *a += 1;
        }
        self.hist.push_front((t_new, y_new));
        if self.hist.len() > HISTORY {
            self.hist.pop_back();
        }
        self.last_times = nodes;
        self.last_coeffs = coeffs;
        self.last_order = k;
        self.steps_at_order += 1;
        match self.opts.control {
            StepControl::Fixed { order, step } => {
                self.order = order.min(self.hist.len());
                self.h = step;
                false
            }
            StepControl::Replay {
                ref times,
                ref orders,
                ..
            } => {
                self.replay_pos += 1;
                if let Some(&t1) = times.get(self.replay_pos) {
                    self.h = t1 - self.hist[0].0;
                    self.order = orders[self.replay_pos];
                }
                false
            }
            StepControl::Adaptive { .. } => true,
        }
    }

    /// The order and step after an accepted adaptive step of order `k` and step `h` with error
    /// norm `err`: the candidate orders `k − 1`, `k`, `k + 1` with the steps their error
    /// estimates allow, each cut to keep every oscillatory eigenvalue of the Jacobian in its
    /// order's stability region (the orders down to 2 joining when that cut something).
    fn choose_next(&mut self, k: usize, h: f64, err: f64, error_fails: usize, limits: &StepLimits) {
        let (max_order, min_step, max_step) = (limits.max_order, limits.min_step, limits.max_step);
        // order and step for the next step (estimates relative to the accepted step)
        let safety = |e: f64, q: usize, s: f64| {
            if e <= 0.0 {
                10.0
            } else {
                (e.powf(-1.0 / (q as f64 + 1.0))) / s
            }
        };
        let limit = |f: f64| {
            let mut f = f.min(if self.stats.steps < 5 { 10.0 } else { 5.0 });
            if (1.0..1.5).contains(&f) || (error_fails > 0 && f > 1.0) {
                // no growth right after a rejection; small growth is not worth a new matrix
                f = 1.0;
            }
            f.max(0.2)
        };
        // candidate orders with the steps their error estimates allow
        let mut candidates = vec![(k, safety(err, k, 1.4))];
        if self.steps_at_order > k {
            // the estimates need the previous state set; recompute on the shifted history
            let (t_acc, y_acc) = self.hist.pop_front().unwrap();
            if k > 1
                && let Some(e) = est_shift(self, t_acc, &y_acc, k - 1)
            {
                candidates.push((k - 1, safety(e, k - 1, 1.5)));
            }
            if k < max_order
                && let Some(e) = est_shift(self, t_acc, &y_acc, k + 1)
            {
                candidates.push((k + 1, safety(e, k + 1, 1.7)));
            }
            self.hist.push_front((t_acc, y_acc));
        }
        let by_error = |&(q, f): &(usize, f64)| (q, (h * limit(f)).clamp(min_step, max_step));
        let longest = |a: (usize, f64), b: (usize, f64)| if b.1 > a.1 { b } else { a };
        let unlimited = candidates.iter().map(by_error).fold((k, 0.0), longest);
        let mut next = unlimited;
        if !self.oscillatory.is_empty() {
            // every oscillatory eigenvalue must stay in the stability region of the order
            // used: each candidate's step is cut to where its order holds them all, and the
            // orders below, down to the A-stable order 2, join when that cut something
            let within = |(q, hq): (usize, f64)| {
                let mut edges = self.stability_edges.borrow_mut();
                (
                    q,
                    stable_step_cached(q, hq, &self.oscillatory, Some(&mut edges)),
                )
            };
            next = candidates
                .iter()
                .map(by_error)
                .map(within)
                .fold((k, 0.0), longest);
            if next.1 < unlimited.1 && k > 2 {
                let (t_acc, y_acc) = self.hist.pop_front().unwrap();
                for q in 2..k.saturating_sub(1) {
                    if let Some(e) = est_shift(self, t_acc, &y_acc, q) {
                        next = longest(next, within(by_error(&(q, safety(e, q, 1.5)))));
                    }
                }
                self.hist.push_front((t_acc, y_acc));
            }
            if next != unlimited {
                self.stats.stability_limited += 1;
            }
        }
        if next.0 != k {
            self.order = next.0;
            self.steps_at_order = 0;
        }
        self.h = next.1.clamp(min_step, max_step);
    }

    /// Newton iteration for `c0 y + ψ = f(t, y)` (`t = nodes[0]`, `c0 = coeffs[0]`), with a
    /// simultaneous extension corrected alongside; `None` if it does not converge.
    fn newton<Sys: OdeSystem, E: StepExtension<Sys>>(
        &mut self,
        sys: &mut Sys,
        ext: &mut E,
        nodes: &[f64],
        coeffs: &[f64],
        y_pred: &[f64],
        psi: &[f64],
    ) -> Result<Option<Vec<f64>>, IntegrationError> {
        let (t, c0) = (nodes[0], coeffs[0]);
        let simultaneous = ext.simultaneous();
        if simultaneous {
            let past: Vec<f64> = self.hist.iter().map(|x| x.0).collect();
            ext.newton_begin(nodes, coeffs, &past);
        }
        let mut y = y_pred.to_vec();
        let mut f = vec![0.0; self.n];
        let mut prev_norm = f64::INFINITY;
        let y_ref = self.hist[0].1.clone();
        let tol = match self.opts.control {
            StepControl::Fixed { .. } => 1.0,
            StepControl::Replay { newton_tol, .. } => newton_tol,
            StepControl::Adaptive { .. } => 0.05,
        };
        for it in 0..self.opts.max_newton_iterations {
            self.stats.newton_iterations += 1;
            let evaluated = if simultaneous {
                ext.newton_rhs(sys, t, &y, &mut f)
            } else {
                sys.rhs(t, &y, &mut f)
            };
            if let Err(e) = evaluated {
                // a convergence failure (the step will be reduced); reported if it persists
                self.last_rhs_error = Some(e);
                return Ok(None);
            }
            self.stats.rhs_evaluations += 1;
            let mut r: Vec<f64> = (0..self.n).map(|i| f[i] - c0 * y[i] - psi[i]).collect();
            let lu = self.lu.as_ref().expect("factorised");
            if !lu.solve_in_place(&mut r) {
                return Err(self.fail(IntegrationFailure::SingularNewtonMatrix));
            }
            // a matrix factorised with another c0: scale the chord step (CVODE's 2/(1+γ ratio))
            let scale = if self.lu_c0 != c0 {
                2.0 * self.lu_c0 / (c0 + self.lu_c0)
            } else {
                1.0
            };
            if scale != 1.0 {
                r.iter_mut().for_each(|x| *x *= scale);
            }
            for i in 0..self.n {
                y[i] += r[i];
            }
            let mut norm = self.wrms(&r, &y_ref);
            if simultaneous {
                let e = ext
                    .newton_correct(lu, scale, self.opts.rtol, &self.atol)
                    .map_err(|r| self.fail(r))?;
                norm = norm.max(e);
            }
            if !norm.is_finite() {
                return Ok(None);
            }
            // convergence-rate estimate, carried over from earlier steps for the first iterate
            if it > 0 {
                let ratio = norm / prev_norm;
                if ratio > 0.9 {
                    // a replay's tight iteration that stalls within REPLAY_STALL of its
                    // threshold has met the round-off of its equations
                    let replay = matches!(self.opts.control, StepControl::Replay { .. });
                    if replay && norm < REPLAY_STALL * tol {
                        return Ok(Some(y));
                    }
                    return Ok(None);
                }
                self.newton_rate = ratio.max(0.3 * self.newton_rate);
            }
            if norm * self.newton_rate.min(1.0) < tol || norm < 1e-3 * tol {
                return Ok(Some(y));
            }
            prev_norm = norm;
        }
        Ok(None)
    }

    /// The last accepted step (see [`AcceptedStep`]).
    ///
    /// # Panics
    /// Before the first accepted step.
    pub fn last_step(&self) -> AcceptedStep<'_> {
        assert!(self.last_order > 0, "no accepted step yet");
        AcceptedStep {
            order: self.last_order,
            step: self.last_times[0] - self.last_times[1],
            times: &self.last_times,
            coefficients: &self.last_coeffs,
            states: self
                .hist
                .iter()
                .take(self.last_order + 1)
                .map(|x| x.1.as_slice())
                .collect(),
            newton_matrix: self.lu.as_ref().expect("factorised"),
            newton_c0: self.lu_c0,
        }
    }

    /// The integrator's state between two steps, small enough to keep many of: the Jacobian
    /// and the Newton matrix are kept as the point the Jacobian was evaluated at, and
    /// [`BdfSnapshot::restore`] evaluates and factorises them again there — the same numbers,
    /// so that the restored integrator takes bitwise the steps this one takes from here,
    /// given the system in the same state (see [`BdfSnapshot::restore`]).
    pub fn snapshot(&self) -> BdfSnapshot {
        BdfSnapshot {
            bdf: self.clone_without_matrices(),
            factorised: self.lu.is_some(),
        }
    }

    /// A copy without the Jacobian and Newton matrix (the point of the Jacobian kept).
    fn clone_without_matrices(&self) -> Bdf {
        Bdf {
            opts: self.opts.clone(),
            stats: self.stats,
            hist: self.hist.clone(),
            f0: self.f0.clone(),
            order: self.order,
            h: self.h,
            steps_at_order: self.steps_at_order,
            jac: Jacobian::Dense(DMatrix::zeros(0, 0)),
            jac_point: self.jac_point.clone(),
            jac_age: self.jac_age,
            lu: None,
            lu_c0: self.lu_c0,
            newton_rate: self.newton_rate,
            last_rhs_error: self.last_rhs_error.clone(),
            last_times: self.last_times.clone(),
            last_coeffs: self.last_coeffs.clone(),
            last_order: self.last_order,
            n: self.n,
            atol: self.atol.clone(),
            replay_pos: self.replay_pos,
            oscillatory: self.oscillatory.clone(),
            stability_edges: std::cell::RefCell::new(self.stability_edges.borrow().clone()),
            breakpoints: self.breakpoints.clone(),
            first_step: self.first_step,
        }
    }

    /// Dense output at `t` within the last step: the interpolant of the last formula.
    pub fn interpolate(&self, t: f64) -> Vec<f64> {
        let k = self.last_order.max(1).min(self.hist.len() - 1);
        if self.hist.len() == 1 {
            return self.hist[0].1.clone();
        }
        let nodes: Vec<f64> = self.hist.iter().take(k + 1).map(|x| x.0).collect();
        let w = lagrange_weights(&nodes, t);
        let mut y = vec![0.0; self.n];
        for (wi, (_, yi)) in w.iter().zip(&self.hist) {
            for (a, b) in y.iter_mut().zip(yi) {
                *a += wi * b;
            }
        }
        y
    }

    /// Integrate from the current state to `t_end`, returning the states at `t_out` (which must
    /// be non-decreasing and within the range) and calling `observer` after every accepted
    /// step.
    pub fn integrate_to(
        &mut self,
        sys: &mut impl OdeSystem,
        t_end: f64,
        t_out: &[f64],
        mut observer: impl FnMut(&Bdf),
    ) -> Result<Vec<Vec<f64>>, IntegrationError> {
        let bad = |s| IntegrationError {
            t: self.current().0,
            h: self.h,
            reason: IntegrationFailure::Settings(s),
        };
        if t_out.iter().any(|t| !t.is_finite()) || !t_end.is_finite() {
            return Err(bad("output times and the end time must be finite"));
        }
        if t_out.windows(2).any(|w| w[1] < w[0]) {
            return Err(bad("output times must be non-decreasing"));
        }
        if t_out.last().is_some_and(|&t| t > t_end) {
            return Err(bad("output times must not pass the end time"));
        }
        let mut out = Vec::with_capacity(t_out.len());
        let mut next = 0;
        let t0 = self.current().0;
        while next < t_out.len() && t_out[next] <= t0 {
            out.push(self.current().1.to_vec());
            next += 1;
        }
        while self.current().0 < t_end {
            self.step(sys, t_end)?;
            observer(self);
            let t = self.current().0;
            while next < t_out.len() && t_out[next] <= t + 1e-14 * t.abs().max(1.0) {
                out.push(if (t_out[next] - t).abs() <= 1e-14 * t.abs().max(1.0) {
                    self.current().1.to_vec()
                } else {
                    self.interpolate(t_out[next])
                });
                next += 1;
            }
        }
        Ok(out)
    }
}

/// The weighted root mean square of the error `e` of the state `y`: each component over
/// `rtol |y_i| + atol_i`.
/// An absolute tolerance of [`BdfOptions`] for each of `n` components: one entry broadcast, or
/// one per component as given.
fn per_component(atol: &[f64], n: usize) -> impl Iterator<Item = f64> + '_ {
    let n = if atol.len() == 1 { n } else { atol.len() };
    atol.iter().copied().cycle().take(n)
}

fn weighted_rms(e: &[f64], y: &[f64], rtol: f64, atol: impl Iterator<Item = f64>) -> f64 {
    let s: f64 = e
        .iter()
        .zip(y)
        .zip(atol)
        .map(|((&e, &y), a)| {
            let w = rtol * y.abs() + a;
            (e / w) * (e / w)
        })
        .sum();
    (s / e.len().max(1) as f64).sqrt()
}

/// Error estimate of order `q` for the just-accepted point `(t_new, y_new)`, with the
/// history (without it) in `this`.
fn est_shift(this: &Bdf, t_new: f64, y_new: &[f64], q: usize) -> Option<f64> {
    if this.hist.len() < q + 1 {
        return None;
    }
    let mut pn = vec![t_new];
    pn.extend(this.hist.iter().take(q + 1).map(|x| x.0));
    let w = divided_difference_weights(&pn);
    let mut dd: Vec<f64> = y_new.iter().map(|y| w[0] * y).collect();
    for (wi, (_, yi)) in w[1..].iter().zip(&this.hist) {
        for (a, b) in dd.iter_mut().zip(yi) {
            *a += wi * b;
        }
    }
    let mut prod = 1.0;
    let mut sum = 0.0;
    for x in &pn[1..=q] {
        prod *= t_new - x;
        sum += 1.0 / (t_new - x);
    }
    let e: Vec<f64> = dd.iter().map(|d| d * prod / sum).collect();
    Some(this.wrms(&e, &this.hist[0].1))
}

#[cfg(test)]
mod tests {
    use super::{Complex, stable_step, stable_step_cached};

    /// The remembered lobe edges cut every step to the point the bisection finds, over a
    /// sequence of steps inside, below and beyond the lobes of several lightly damped modes:
    /// the rod's two pairs and a slower mode, and two modes a hundred times apart, so that a
    /// cut for the slow one lands beyond the fast one's lobe (an edge remembered for the wrong
    /// mode would show there).
    #[test]
    fn remembered_lobe_edges_give_the_bisections_cut() {
        let eigenvalues: Vec<Complex<f64>> = [
            (0.03, 1e5),
            (0.01, 1e3),
            (0.01, 3055.0),
            (0.03, 16833.0),
            (0.002, 900.0),
        ]
        .iter()
        .map(|&(zeta, w): &(f64, f64)| Complex::new(-zeta * w, w * (1.0 - zeta * zeta).sqrt()))
        .collect();
        let mut edges = vec![[f64::NAN; 6]; eigenvalues.len()];
        let mut cut = 0;
        for q in [3, 4, 5, 3, 5] {
            for i in 0..400 {
                let h = 1e-6 * 1.02f64.powi(i);
                let plain = stable_step(q, h, &eigenvalues);
                let cached = stable_step_cached(q, h, &eigenvalues, Some(&mut edges));
                assert!(
                    (cached - plain).abs() <= 1e-8 * h,
                    "order {q}, h = {h:e}: {cached:e} vs {plain:e}"
                );
                cut += usize::from(plain < h);
            }
        }
        // the sequence did cut steps, and the edges were remembered
        assert!(cut > 100, "{cut}");
        assert!(edges.iter().flatten().filter(|e| e.is_finite()).count() >= 3);
    }
}
