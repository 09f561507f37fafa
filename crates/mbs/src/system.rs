//! The `f64` solver around a [`Model`]: redundant-constraint handling, consistent initial
//! conditions, the solution of Eq. (12) (dense LU, or by body blocks and a Schur complement
//! for large mechanisms, [`crate::eq12`]), the exact state Jacobian from the dual path (as a
//! sparse Newton system for large mechanisms, [`crate::newton`]), and the outputs per time.

use std::sync::Mutex;

use nalgebra::{DMatrix, DVector, Dyn, LU, Matrix3, Vector3};
use sens::{Dual, Scalar, chunk_ranges};

use crate::bdf::{
    Bdf, BdfOptions, IntegrationError, OdeSystem, RhsError, Statistics, StructuredJacobian,
};
use crate::body::{Body, BodyId};
use crate::eq12::{BodyMass, DENSE_LIMIT, Eq12Factor, SchurPattern};
use crate::error::ConstraintError;
use crate::joint::JointId;
use crate::kin::{Jac, Kin, quat_from_rotation_vector, quat_mul};
use crate::model::{Baumgarte, Energy, Model, State};
use crate::newton::{Colouring, NewtonCache, SparseNewton};
use nalgebra::Vector4;

/// What to do with redundant constraint equations.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum RedundancyPolicy {
    /// Drop the equations dependent at the assembled state for the whole run (their
    /// multipliers are reported as zero). Correct when the redundancy holds in every
    /// configuration (a planar mechanism in 3-D with rigid bodies or in-plane modes); the
    /// dropped rows are not enforced, and their violation is reported apart
    /// ([`Output::removed_position_violation`]).
    #[default]
    Remove,
    /// Fail with [`ConstraintError::Redundant`] naming the joints.
    Error,
    /// Select the independent equations again at every state ([`MultibodySystem::rows_at`]).
    /// Needed when redundancy depends on the configuration: a planar mechanism whose flexible
    /// bodies have out-of-plane modes can have rows that are dependent only in special
    /// configurations (the slider-crank's slide roll equation while the rod lies along the
    /// slide, at crank angles 0 and π); dropped for the whole run they drift freely. The
    /// index-1 equations are then nearly singular near those configurations (smaller steps
    /// there, and design sensitivities that are sensitive to the steps taken through them).
    Reselect,
}

/// Reaction of a joint (from its multipliers), global components.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointReaction {
    /// Force on the body of marker B (N); zero for ground.
    pub force_on_b: Vector3<f64>,
    /// Moment on the body of marker B about B's marker point (N·m).
    pub moment_on_b: Vector3<f64>,
    pub force_on_a: Vector3<f64>,
    pub moment_on_a: Vector3<f64>,
}

/// The prestress of a start assembled elastically ([`MultibodySystem::assemble`]).
#[derive(Clone, Debug, PartialEq)]
pub struct ElasticStart {
    /// The strain energy of each flexible body that takes some (J), by name.
    pub bodies: Vec<(String, f64)>,
    /// The joint with the largest reaction force, and that force's magnitude (N).
    pub joint: String,
    pub force: f64,
}

impl ElasticStart {
    /// The bodies' total strain energy (J).
    pub fn energy(&self) -> f64 {
        self.bodies.iter().map(|(_, e)| e).sum()
    }
}

/// Results at one output time.
#[derive(Clone, Debug)]
pub struct Output {
    pub t: f64,
    pub q: Vec<f64>,
    pub v: Vec<f64>,
    /// `v̇`.
    pub accelerations: Vec<f64>,
    /// Multipliers per constraint row (zero for removed rows).
    pub lambda: Vec<f64>,
    /// Body frame origins (m).
    pub positions: Vec<Vector3<f64>>,
    /// Body rotations (body → global).
    pub orientations: Vec<Matrix3<f64>>,
    /// Modal coordinates per body (empty for rigid bodies).
    pub modal: Vec<Vec<f64>>,
    /// Nodal displacements `X w` per flexible body and node (body frame).
    pub nodal_displacements: Vec<Vec<[f64; 6]>>,
    pub reactions: Vec<JointReaction>,
    /// `max |Φ|` and `max |Φ̇|` over all rows.
    pub position_violation: f64,
    pub velocity_violation: f64,
    /// `max |Φ|` over the rows kept in Eq. (12) at this state (held at the Baumgarte /
    /// integration-tolerance level) and over the rows dropped as dependent (not enforced: with
    /// [`RedundancyPolicy::Remove`] a growing value means redundancy found at assembly does not
    /// hold here; use [`RedundancyPolicy::Reselect`]).
    pub kept_position_violation: f64,
    pub removed_position_violation: f64,
    pub energy: Energy,
}

/// Accelerations and multipliers at one state, with the factorisation of Eq. (12).
pub struct Solution {
    /// `[v̇; λ_active]`.
    pub x: Vec<f64>,
    /// The factorisation of Eq. (12)'s leading matrix, for the tangent solves at this state.
    pub lu: Eq12Factor,
    /// The constraint rows kept in Eq. (12) at this state (the order of `λ_active`). With
    /// [`RedundancyPolicy::Reselect`] they are chosen at every state (see
    /// [`MultibodySystem::solve`]); the tangents of this solution must use the same rows.
    pub rows: Vec<usize>,
}

/// The multibody system as an ODE `y' = f(t, y)`, `y = [q; v]`.
pub struct MultibodySystem {
    model: Model<f64>,
    rows: Vec<usize>,
    removed: Vec<usize>,
    policy: RedundancyPolicy,
    progress: Option<Progress>,
    /// What the last [`MultibodySystem::assemble`] started from.
    start: Option<StartGuess>,
    /// The prestress of the last [`MultibodySystem::assemble`], when it had to deform the
    /// flexible bodies.
    elastic: Option<ElasticStart>,
    /// Whether it gave the flexible bodies elastic rates ([`MultibodySystem::elastic_rates`]).
    elastic_rates: bool,
    guard: StepGuard,
    /// The symbolic analysis of Eq. (12)'s Schur complement, kept while its pattern stays.
    schur: Mutex<Option<SchurPattern>>,
    /// The colouring and symbolic analysis of the sparse Newton matrices (large mechanisms).
    newton: NewtonCache,
    /// Dense Eq. (12) and Newton matrices whatever the size ([`MultibodySystem::set_dense`]).
    dense: bool,
    /// `(t, max |Φ|)` over the guarded rows at the last right-hand side evaluated: the step
    /// check reads the violation there ([`OdeSystem::check_step`] of this system).
    last_violation: Option<(f64, f64)>,
}

/// Limits of the check of every integration step ([`OdeSystem::check_step`]): states that no
/// tolerance would allow, refused so that a diverged integration stops with a message instead
/// of returning garbage.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepGuard {
    /// Largest position-constraint violation `max |Φ|` (m, or rad for angular rows) over the
    /// rows kept in Eq. (12).
    pub max_violation: f64,
    /// Largest nodal translation of a flexible body, as a fraction of its size (the diagonal
    /// of its nodes' box): far beyond the small deformations of a modal model.
    pub max_deformation: f64,
}

impl StepGuard {
    /// 5 % of `size` for the violation (a joint opened by a twentieth of the mechanism), half
    /// a body's size for its deformation. Measured on the slider-cranks: converged runs stay
    /// below 1e-6 of their size, runs at `rtol = 1e-2` reach 1.5–2 %, diverged ones pass 10 %.
    pub fn for_size(size: f64) -> Self {
        Self {
            max_violation: 0.05 * size,
            max_deformation: 0.5,
        }
    }
}

/// A progress observer: called with the time of every right-hand-side evaluation.
pub type Progress = std::sync::Arc<dyn Fn(f64) + Send + Sync>;

/// Width of the dual chunks used for the state Jacobian.
const CHUNK: usize = 8;

/// Relative tolerance of the redundancy check at assembly (reported rows, policy `Error`).
pub(crate) const ASSEMBLY_DEPENDENCE_TOL: f64 = 1e-8;

/// Relative tolerance of the row selection at every state. Near a configuration where rows
/// lose rank (a flexible slider-crank whose rod passes through the line of the slide) the kept
/// rows make Eq. (12) ill-conditioned and its index-1 form nearly singular; rows within 1e-6 of
/// dependence are dropped there. Measured on the flexible slider-crank with out-of-plane modes:
/// 1e-8 and 1e-6 give the same response to 4 digits and `|Φ| ≤ 2e-8`, 1e-6 in a quarter of the
/// steps; 1e-3 and above leave the row out long enough to drift (`|Φ|` 3e-5 … 0.6).
const STATE_DEPENDENCE_TOL: f64 = 1e-6;

impl MultibodySystem {
    /// Wrap `model`, checking the constraint Jacobian at `state` (t = 0) for redundant
    /// equations.
    pub fn new(
        model: Model<f64>,
        state: &State,
        policy: RedundancyPolicy,
    ) -> Result<Self, ConstraintError> {
        Self::new_at(model, 0.0, state, policy)
    }

    /// As [`MultibodySystem::new`], with the redundancy check at time `t` (drivers).
    ///
    /// Redundancy can depend on the configuration: on a mechanism with flexible bodies whose
    /// modes move the joints out of the mechanism's plane, equations that are dependent in one
    /// configuration (e.g. with a rod aligned with a slide) are independent in all others.
    /// The rows found here ([`MultibodySystem::active_rows`]) describe this configuration;
    /// [`RedundancyPolicy::Remove`] keeps them for the whole run, [`RedundancyPolicy::Reselect`]
    /// selects the independent rows again at every state.
    pub fn new_at(
        model: Model<f64>,
        t: f64,
        state: &State,
        policy: RedundancyPolicy,
    ) -> Result<Self, ConstraintError> {
        let Baumgarte { alpha, beta } = model.baumgarte;
        if !(alpha.is_finite() && beta.is_finite() && alpha >= 0.0 && beta >= 0.0) {
            return Err(ConstraintError::BadStabilisation { alpha, beta });
        }
        let c = model.constraints(t, &state.q, &state.v);
        let (rows, removed) = independent_rows(&c.jacobian);
        if !removed.is_empty() && policy == RedundancyPolicy::Error {
            return Err(ConstraintError::Redundant {
                equations: describe_rows(&model, &removed),
            });
        }
        let guard = StepGuard::for_size(crate::mechanism_size(&model, &state.q));
        Ok(Self {
            model,
            rows,
            removed,
            policy,
            progress: None,
            start: None,
            elastic: None,
            elastic_rates: false,
            guard,
            schur: Mutex::new(None),
            newton: NewtonCache::default(),
            dense: false,
            last_violation: None,
        })
    }

    /// Solve Eq. (12) and the integrator's Newton iterations with dense matrices whatever the
    /// size of the mechanism (`true`), or with the body blocks, the Schur complement and the
    /// sparse Newton system above 80 unknowns in Eq. (12) (`false`, the default; docs/design.md
    /// §3): the same solutions, the dense path slower for large mechanisms. For comparisons.
    pub fn set_dense(&mut self, dense: bool) {
        self.dense = dense;
    }

    /// Whether Eq. (12) and the Newton matrix are solved by their structure: above the size
    /// limit, unless [`MultibodySystem::set_dense`].
    fn structured(&self) -> bool {
        !self.dense && self.model.n_v() + self.rows.len() > DENSE_LIMIT
    }

    /// Report progress: `observer(t)` is called at every right-hand-side evaluation (times of
    /// trial steps included), e.g. to drive a progress bar.
    pub fn set_progress(&mut self, observer: Option<Progress>) {
        self.progress = observer;
    }

    /// The progress observer, taken off (e.g. while steps already reported are recomputed).
    pub(crate) fn take_progress(&mut self) -> Option<Progress> {
        self.progress.take()
    }

    /// Call the progress observer, if any, with `t` (for evaluations made outside
    /// [`OdeSystem::rhs`]).
    pub(crate) fn report_progress(&self, t: f64) {
        if let Some(p) = &self.progress {
            p(t);
        }
    }

    /// The same system (same active constraint rows) with other model parameters, e.g. a
    /// perturbed design for finite-difference checks. The layout must be unchanged.
    pub fn with_model(&self, model: Model<f64>) -> Self {
        assert_eq!(
            model.n_constraints(),
            self.model.n_constraints(),
            "constraint layout changed"
        );
        assert_eq!(model.n_v(), self.model.n_v(), "state layout changed");
        Self {
            model,
            rows: self.rows.clone(),
            removed: self.removed.clone(),
            policy: self.policy,
            progress: self.progress.clone(),
            start: self.start.clone(),
            elastic: self.elastic.clone(),
            elastic_rates: self.elastic_rates,
            guard: self.guard,
            schur: Mutex::new(None),
            newton: NewtonCache::default(),
            dense: self.dense,
            last_violation: None,
        }
    }

    /// The limits of the step check ([`StepGuard`]; by default from the size of the mechanism
    /// at construction: the diagonal of the box around the body origins, the flexible bodies'
    /// nodes and the joints' points).
    pub fn guard(&self) -> StepGuard {
        self.guard
    }

    pub fn set_guard(&mut self, guard: StepGuard) {
        self.guard = guard;
    }

    /// `Err(why)` if the state breaks a limit of the [`StepGuard`].
    pub fn check_state(&self, t: f64, q: &[f64], v: &[f64]) -> Result<(), String> {
        self.check_violation(&self.model.constraint_kin(t, q, v))?;
        self.check_deformation(q)
    }

    /// The guarded rows' largest position violation `(row, |Φ|)` (NaN above every number).
    fn worst_violation<S: Scalar>(&self, k: &[Kin<S>]) -> Option<(usize, f64)> {
        let all: Vec<usize>;
        let rows = match self.policy {
            RedundancyPolicy::Reselect => {
                all = (0..k.len()).collect();
                &all
            }
            _ => &self.rows,
        };
        rows.iter()
            .map(|&r| (r, k[r].val.value().abs()))
            .max_by(|a, b| a.1.total_cmp(&b.1))
    }

    /// `max |Φ|` over the guarded rows ([`Self::worst_violation`]; 0 without rows).
    fn largest_violation<S: Scalar>(&self, k: &[Kin<S>]) -> f64 {
        self.worst_violation(k).map_or(0.0, |(_, phi)| phi)
    }

    /// Keep the guarded rows' largest violation `phi` at a right-hand side at time `t` for the
    /// step check ([`OdeSystem::check_step`] of this system).
    pub(crate) fn note_violation(&mut self, t: f64, phi: f64) {
        self.last_violation = Some((t, phi));
    }

    /// The violation limit of the [`StepGuard`] at the rows' kinematics `k`.
    fn check_violation(&self, k: &[Kin<f64>]) -> Result<(), String> {
        if let Some((r, phi)) = self.worst_violation(k)
            && !(phi <= self.guard.max_violation)
        {
            let j = self.model.joint_of_row(r);
            return Err(format!(
                "the position-constraint violation {phi:.3e} of joint `{}` (equation {}) \
                 passed the limit {:.3e} (5 % of the mechanism's size unless set): the \
                 integration has diverged; tighter tolerances, a lower maximum order or a \
                 maximum step keep it on the solution",
                self.model.joint(j).name,
                r - self.model.joint_rows(j).start + 1,
                self.guard.max_violation
            ));
        }
        Ok(())
    }

    /// The deformation limit of the [`StepGuard`] at positions `q`.
    fn check_deformation(&self, q: &[f64]) -> Result<(), String> {
        for id in self.model.body_ids() {
            let Body::Flexible(b) = self.model.body(id) else {
                continue;
            };
            let size = b.modal.size();
            if size <= 0.0 {
                // a one-node body has no size to measure its deformation against
                continue;
            }
            // the bound is cheap, the exact largest translation a loop over the nodes
            if self
                .model
                .deformation_bound(id, q)
                .is_some_and(|b| b <= self.guard.max_deformation * size)
            {
                continue;
            }
            let largest = self
                .model
                .nodal_displacements(id, q)
                .iter()
                .map(|u| Vector3::new(u[0], u[1], u[2]).norm())
                .max_by(f64::total_cmp)
                .unwrap_or(0.0);
            if !(largest <= self.guard.max_deformation * size) {
                return Err(format!(
                    "flexible body `{}` deflects {largest:.3e} m, more than {} of its size \
                     {size:.3e} m: far outside the small deformations of its modes (a diverged \
                     integration, or a load the modal model cannot carry)",
                    b.name, self.guard.max_deformation
                ));
            }
        }
        Ok(())
    }

    pub fn model(&self) -> &Model<f64> {
        &self.model
    }
    /// Constraint rows kept in Eq. (12) at the state of the last redundancy check
    /// ([`MultibodySystem::new_at`], [`MultibodySystem::assemble`]). With
    /// [`RedundancyPolicy::Reselect`] the rows during a run are those of each state
    /// ([`Solution::rows`], [`MultibodySystem::rows_at`]).
    pub fn active_rows(&self) -> &[usize] {
        &self.rows
    }
    /// Dependent equations dropped at the state of the last redundancy check:
    /// `(joint, equation index within the joint)`.
    pub fn removed_equations(&self) -> Vec<(JointId, usize)> {
        self.removed
            .iter()
            .map(|&r| {
                let j = self.model.joint_of_row(r);
                (j, r - self.model.joint_rows(j).start)
            })
            .collect()
    }

    /// The constraint rows of Eq. (12) at `(t, q)`: with [`RedundancyPolicy::Reselect`] a
    /// greedy selection in row order at this state (a row is dropped when it lies within a
    /// relative 1e-6 of the span of the rows before it); otherwise
    /// [`MultibodySystem::active_rows`].
    pub fn rows_at(&self, t: f64, q: &[f64]) -> Vec<usize> {
        let v = vec![0.0; self.model.n_v()];
        let k = self.model.constraint_kin(t, q, &v);
        self.select_rows(&k)
    }

    /// The rows of Eq. (12) for the constraint kinematics `k` (their values).
    fn select_rows<S: Scalar>(&self, k: &[Kin<S>]) -> Vec<usize> {
        match self.policy {
            RedundancyPolicy::Error | RedundancyPolicy::Remove => self.rows.clone(),
            RedundancyPolicy::Reselect => {
                let n_v = self.model.n_v();
                let dense: Vec<Vec<f64>> = k
                    .iter()
                    .map(|r| r.jac.map(|x| x.value()).dense(n_v, 0.0))
                    .collect();
                independent_rows_of(dense.iter().map(Vec::as_slice), n_v, STATE_DEPENDENCE_TOL).0
            }
        }
    }

    /// `ẏ = [q̇; v̇]` at `y = [q; v]` into `dy`, with `v̇` from the solution of Eq. (12) there.
    pub(crate) fn write_rates(&self, y: &[f64], sol: &Solution, dy: &mut [f64]) {
        let nq = self.model.n_q();
        let (q, v) = y.split_at(nq);
        self.model.kinematic_rates(q, v, &mut dy[..nq]);
        dy[nq..].copy_from_slice(&sol.x[..self.model.n_v()]);
    }

    /// [`MultibodySystem::solve`] and the residual of `model` (this system's model with design
    /// tangents, or on the reverse-mode tape) at the state `(q, v)` (seeded, or tape inputs)
    /// from one evaluation: the `f64` equations are the values of the differentiated ones.
    /// Returns the solution, the residual ([`Model::residual`] at its `x̂`) and the guarded rows'
    /// largest position violation.
    pub(crate) fn solve_dual<P: Scalar, S: Scalar + From<P>>(
        &self,
        model: &Model<P>,
        t: f64,
        q: &[S],
        v: &[S],
    ) -> Result<(Solution, Vec<S>, f64), ConstraintError> {
        let k = model.constraint_kin(t, q, v);
        let violation = self.largest_violation(&k);
        let (m, f) = model.mass_and_forces(t, q, v);
        let rows = self.select_rows(&k);
        let mass = m.map(|x| x.value());
        let jac: Vec<Jac<f64>> = rows.iter().map(|&r| k[r].jac.map(|x| x.value())).collect();
        let rhs = self.model.rhs_as(&f, &k, &rows, |x| x.value());
        let sol = self.factor_and_solve(t, &mass, jac.iter().collect(), rhs, rows)?;
        let res = model.residual_from(&m, &f, &k, &sol.rows, &sol.x);
        Ok((sol, res, violation))
    }

    /// Solve Eq. (12) at `(t, q, v)`.
    ///
    /// The constraint rows are [`MultibodySystem::rows_at`] (returned in [`Solution::rows`]):
    /// with [`RedundancyPolicy::Reselect`] those independent at this state, otherwise those of
    /// the assembly.
    pub fn solve(&self, t: f64, q: &[f64], v: &[f64]) -> Result<Solution, ConstraintError> {
        let k = self.model.constraint_kin(t, q, v);
        let (m, f) = self.model.mass_and_forces(t, q, v);
        self.solve_with(t, (q, v), &k, (&m, &f))
    }

    /// [`MultibodySystem::solve`] with the constraint rows' kinematics at the state.
    fn solve_with(
        &self,
        t: f64,
        (q, v): (&[f64], &[f64]),
        k: &[Kin<f64>],
        (m, f): (&BodyMass<f64>, &[f64]),
    ) -> Result<Solution, ConstraintError> {
        let rows = self.select_rows(k);
        let rhs = self.model.rhs_as(f, k, &rows, |x| x);
        let jac = rows.iter().map(|&r| &k[r].jac).collect();
        self.factor_and_solve(t, m, jac, rhs, rows)
            .map_err(|e| match e {
                ConstraintError::NonFinite { t, .. } => ConstraintError::NonFinite {
                    t,
                    cause: self.non_finite_cause(q, v),
                },
                e => e,
            })
    }

    /// Why accelerations came out non-finite, as far as can be told: a non-finite state, or a
    /// spring–damper of zero length.
    fn non_finite_cause(&self, q: &[f64], v: &[f64]) -> String {
        if !q.iter().chain(v).all(|x| x.is_finite()) {
            return "; the state itself is not finite".into();
        }
        match self.model.zero_length_springs(q).as_slice() {
            [] => String::new(),
            s => format!(
                "; spring-damper {} (force {} in the order added) has zero length, so its line of \
                 action is undefined",
                if s.len() > 1 { "forces" } else { "force" },
                s.iter()
                    .map(|i| i.to_string())
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        }
    }

    fn factor_and_solve(
        &self,
        t: f64,
        mass: &BodyMass<f64>,
        jac: Vec<&Jac<f64>>,
        mut x: Vec<f64>,
        rows: Vec<usize>,
    ) -> Result<Solution, ConstraintError> {
        let schur = (!self.dense).then_some(&self.schur);
        let Some(lu) = Eq12Factor::new(mass, &jac, schur) else {
            return Err(ConstraintError::Singular { t });
        };
        lu.solve_in_place(&mut x);
        if x.iter().any(|a| !a.is_finite()) {
            return Err(ConstraintError::NonFinite {
                t,
                cause: String::new(),
            });
        }
        Ok(Solution { x, lu, rows })
    }

    /// Make `state` consistent with the constraints at time `t`, moving only the rigid-body
    /// coordinates: every body's frame position, orientation and velocity `(ṙ, ω')`. The
    /// elastic (modal) coordinates and their rates are the user's and are held at their values
    /// in `state` (zero: undeformed and at rest in the body frame).
    ///
    /// Positions: Gauss–Newton steps `Δ` of the rigid coordinates, each the smallest in the
    /// mass (kinetic-energy) metric `ΔᵀWΔ` that satisfies the linearised constraints, until
    /// `max |Φ| ≤ tol`. Velocities: `Δv` minimising `Δvᵀ W Δv` with `Φ̇ = 0`, i.e. the
    /// velocity change an impulse of the constraint forces would make (momentum is conserved
    /// by it, and no rigid motion is put into the modes). `W` is the rigid-coordinate block of
    /// the mass matrix at the state. Both solve `[W J_Iᵀ; J_I 0]` with `J_I` the independent
    /// rows of the constraint Jacobian's rigid-coordinate columns; the dependent rows must then
    /// hold too, else the error names the joint ([`ConstraintError::Inconsistent`]), as it does
    /// when a constraint cannot be met with the stated elastic state.
    ///
    /// Where the rigid-body coordinates cannot meet the positions' constraints and the model
    /// has flexible bodies (a misaligned joint locks the frame), the positions are assembled
    /// with their elastic coordinates too, at the least strain energy
    /// ([`MultibodySystem::elastic_start`] reports the prestress), and the velocities with every
    /// coordinate's rate at the least kinetic energy of the change; so are the velocities alone
    /// where the rigid rates cannot meet the drivers' speeds (a mechanism locked when rigid:
    /// [`MultibodySystem::elastic_rates`]).
    ///
    /// Redundancy is then re-checked at the assembled state (with the policy given at
    /// construction), since rows dependent there may differ from those at an inconsistent
    /// starting guess. The velocities before the projection are kept, so that
    /// [`crate::initial_sensitivities`] differentiates the same projection.
    pub fn assemble(&mut self, t: f64, state: &mut State, tol: f64) -> Result<(), ConstraintError> {
        self.elastic = None;
        self.elastic_rates = false;
        // the elastic coordinates and rates take part only where the deck leaves them at
        // zero: a stated elastic state that the joints forbid stays an error
        let elastic = self.elastic_columns();
        let undeformed = elastic.iter().all(|&c| self.elastic_value(state, c) == 0.0);
        let at_rest = elastic.iter().all(|&c| state.v[c] == 0.0);
        match self.assemble_rigidly(t, state, tol) {
            Ok(()) => {}
            Err(rigid @ ConstraintError::Inconsistent { .. }) => {
                if elastic.is_empty() || !undeformed {
                    return Err(rigid);
                }
                self.elastic = Some(self.assemble_elastic(t, state, tol)?);
            }
            Err(e) => return Err(e),
        }
        if let Some(j) = self.model.reversed_drivers(t, &state.q).first() {
            return Err(ConstraintError::ReversedDriver {
                joint: self.model.joint(*j).name.clone(),
                t,
            });
        }
        let cols = self.rigid_columns();
        let c = self.model.constraints(t, &state.q, &state.v);
        let (rows, removed) = independent_rows(&c.jacobian);
        if !removed.is_empty() && self.policy == RedundancyPolicy::Error {
            return Err(ConstraintError::Redundant {
                equations: describe_rows(&self.model, &removed),
            });
        }
        self.rows = rows;
        self.removed = removed;
        let guess = state.v.clone();
        if self.elastic.is_some() {
            self.project_velocities_elastically(t, state)?;
        } else {
            let kkt = self.start_projection(t, &state.q, &c.jacobian, &cols)?;
            let b: Vec<f64> = kkt.rows.iter().map(|&r| -c.phi_dot[r]).collect();
            let (dv, _) = kkt.solve(&vec![0.0; cols.len()], &b);
            for (&col, x) in cols.iter().zip(dv) {
                state.v[col] += x;
            }
        }
        let met = |sys: &Self, state: &State| {
            let c = sys.model.constraints(t, &state.q, &state.v);
            let scale = state.v.iter().fold(1.0f64, |m, x| m.max(x.abs()));
            (max_abs(&c.phi_dot) <= tol.max(1e-9 * scale), c.phi_dot)
        };
        let (mut ok, mut phi_dot) = met(self, state);
        if !ok && self.elastic.is_none() && !elastic.is_empty() && at_rest {
            // a mechanism locked when its bodies are rigid: they move by deforming
            state.v.clone_from(&guess);
            self.project_velocities_elastically(t, state)?;
            self.elastic_rates = true;
            (ok, phi_dot) = met(self, state);
        }
        if !ok {
            return Err(self.inconsistent(&phi_dot, "Φ̇"));
        }
        self.start = Some(StartGuess {
            t,
            q: state.q.clone(),
            v: guess,
        });
        Ok(())
    }

    /// The prestress of the last [`MultibodySystem::assemble`] when the rigid-body coordinates
    /// alone could not meet the joints and it deformed the flexible bodies
    /// ([`ElasticStart`]); `None` after a rigid assembly.
    pub fn elastic_start(&self) -> Option<&ElasticStart> {
        self.elastic.as_ref()
    }

    /// Whether the last [`MultibodySystem::assemble`] gave the flexible bodies elastic rates:
    /// the drivers' speeds could not be met by the bodies moving rigidly (a mechanism locked
    /// when its bodies are rigid), or the positions needed them deformed.
    pub fn elastic_rates(&self) -> bool {
        self.elastic_rates || self.elastic.is_some()
    }

    /// The positions of [`MultibodySystem::assemble`] by the rigid-body coordinates alone.
    fn assemble_rigidly(&self, t: f64, state: &mut State, tol: f64) -> Result<(), ConstraintError> {
        let max_it = 50;
        let cols = self.rigid_columns();
        let mut stalled = 0;
        let mut last = f64::INFINITY;
        for it in 0..=max_it {
            let c = self.model.constraints(t, &state.q, &state.v);
            let res = max_abs(&c.phi);
            if res <= tol {
                break;
            }
            if !res.is_finite() {
                return Err(ConstraintError::AssemblyFailed {
                    residual: res,
                    iterations: it,
                });
            }
            // Gauss–Newton converges quadratically on consistent equations; a residual that
            // stops falling belongs to an equation the rigid coordinates cannot satisfy
            stalled = if res > 0.9 * last { stalled + 1 } else { 0 };
            last = res;
            if it == max_it || stalled >= 5 {
                return Err(self.inconsistent(&c.phi, "Φ"));
            }
            let kkt = self.start_projection(t, &state.q, &c.jacobian, &cols)?;
            let b: Vec<f64> = kkt.rows.iter().map(|&r| -c.phi[r]).collect();
            let (dr, _) = kkt.solve(&vec![0.0; cols.len()], &b);
            let mut d = vec![0.0; self.model.n_v()];
            for (&col, x) in cols.iter().zip(dr) {
                d[col] = x;
            }
            self.apply_increment(&mut state.q, &d);
        }
        Ok(())
    }

    /// The velocity variables of the rigid-body coordinates: `(ṙ, ω')` of every body.
    pub(crate) fn rigid_columns(&self) -> Vec<usize> {
        self.model
            .body_ids()
            .flat_map(|b| {
                let r = self.model.v_range(b);
                r.start..r.start + 6
            })
            .collect()
    }

    /// The assembly's projection matrix at `q`: `[W J_Iᵀ; J_I 0]` with `W` the mass matrix's
    /// rigid-coordinate block and `J_I` the independent rows of `jac`'s columns `cols`.
    pub(crate) fn start_projection(
        &self,
        t: f64,
        q: &[f64],
        jac: &DMatrix<f64>,
        cols: &[usize],
    ) -> Result<StartProjection, ConstraintError> {
        let v = vec![0.0; self.model.n_v()];
        let (m, _) = self.model.mass_and_forces(t, q, &v);
        let w = DMatrix::from_fn(cols.len(), cols.len(), |i, j| m[(cols[i], cols[j])]);
        let jr = jac.select_columns(cols);
        let dense: Vec<Vec<f64>> = (0..jr.nrows())
            .map(|r| jr.row(r).iter().copied().collect())
            .collect();
        let (rows, _) = independent_rows_of(
            dense.iter().map(Vec::as_slice),
            cols.len(),
            ASSEMBLY_DEPENDENCE_TOL,
        );
        let (n, k) = (cols.len(), rows.len());
        let mut a = DMatrix::zeros(n + k, n + k);
        a.view_mut((0, 0), (n, n)).copy_from(&w);
        for (i, &r) in rows.iter().enumerate() {
            for j in 0..n {
                a[(n + i, j)] = jr[(r, j)];
                a[(j, n + i)] = jr[(r, j)];
            }
        }
        let lu = a.lu();
        if !lu.is_invertible() {
            return Err(ConstraintError::SingularStart { t });
        }
        Ok(StartProjection { rows, lu, n })
    }

    /// The error for the constraint row with the largest `|values|`.
    pub(crate) fn inconsistent(&self, values: &[f64], quantity: &'static str) -> ConstraintError {
        let (row, residual) = values
            .iter()
            .enumerate()
            .fold((0, -1.0), |(br, bv), (r, &x)| {
                let a = if x.is_nan() { f64::INFINITY } else { x.abs() };
                if a > bv { (r, a) } else { (br, bv) }
            });
        let j = self.model.joint_of_row(row);
        let joint = self.model.joint(j);
        let name = |m: &crate::Marker| match m.body {
            Some(b) => format!("`{}`", self.model.body(b).name()),
            None => "ground".to_string(),
        };
        // other joints on the same pair of bodies: the usual cause of a contradiction (a
        // driver on a welded pair)
        let pair = |jt: &crate::Joint| {
            let (a, b) = (jt.a.body, jt.b.body);
            if a <= b { (a, b) } else { (b, a) }
        };
        let others: Vec<String> = self
            .model
            .joints()
            .iter()
            .filter(|o| o.name != joint.name && pair(o) == pair(joint))
            .map(|o| format!("`{}`", o.name))
            .collect();
        let also = match others.len() {
            0 => String::new(),
            1 => format!(
                "joint {} also connects them and may contradict it; else ",
                others[0]
            ),
            _ => format!(
                "joints {} also connect them and may contradict it; else ",
                others.join(", ")
            ),
        };
        ConstraintError::Inconsistent {
            joint: joint.name.clone(),
            equation: row - self.model.joint_rows(j).start,
            bodies: format!("between {} and {}", name(&joint.a), name(&joint.b)),
            also,
            quantity,
            residual,
        }
    }

    /// The time, assembled positions and velocities before the projection of the last
    /// [`MultibodySystem::assemble`].
    pub(crate) fn start_guess(&self) -> Option<&StartGuess> {
        self.start.as_ref()
    }

    /// `q ← q ⊕ Δ` for an increment `Δ` in the velocity variables (rotations exact).
    pub fn apply_increment(&self, q: &mut [f64], d: &[f64]) {
        apply_increment(&self.model, q, d);
    }

    /// Full-length multipliers of a solution (zero for the rows it dropped).
    fn full_lambda(&self, sol: &Solution) -> Vec<f64> {
        let nv = self.model.n_v();
        let mut l = vec![0.0; self.model.n_constraints()];
        for (i, &r) in sol.rows.iter().enumerate() {
            l[r] = sol.x[nv + i];
        }
        l
    }

    /// Joint reactions from the multipliers `lambda` (all rows).
    pub fn reactions(&self, t: f64, q: &[f64], v: &[f64], lambda: &[f64]) -> Vec<JointReaction> {
        self.reactions_from(&self.model.constraints(t, q, v), q, lambda)
    }

    /// [`MultibodySystem::reactions`] with the constraints at the state already evaluated.
    pub(crate) fn reactions_from(
        &self,
        c: &crate::model::ConstraintValues<f64>,
        q: &[f64],
        lambda: &[f64],
    ) -> Vec<JointReaction> {
        (0..self.model.joints().len())
            .map(|ji| {
                let id = JointId(ji);
                let rows = self.model.joint_rows(id);
                let joint = self.model.joint(id);
                let generalized: Vec<f64> = (0..self.model.n_v())
                    .map(|col| {
                        -rows
                            .clone()
                            .map(|r| c.jacobian[(r, col)] * lambda[r])
                            .sum::<f64>()
                    })
                    .collect();
                let on = |m: &crate::Marker| -> (Vector3<f64>, Vector3<f64>) {
                    let Some(b) = m.body else {
                        return (Vector3::zeros(), Vector3::zeros());
                    };
                    let vr = self.model.v_range(b);
                    let f = Vector3::new(
                        generalized[vr.start],
                        generalized[vr.start + 1],
                        generalized[vr.start + 2],
                    );
                    let mb = Vector3::new(
                        generalized[vr.start + 3],
                        generalized[vr.start + 4],
                        generalized[vr.start + 5],
                    );
                    let qr = self.model.q_range(b);
                    let r = Vector3::new(q[qr.start], q[qr.start + 1], q[qr.start + 2]);
                    let a = self.model.rotation_of(b, q);
                    let x = self.model.marker_position(m, q);
                    (f, a * mb - (x - r).cross(&f))
                };
                let (fb, mb) = on(&joint.b);
                let (fa, ma) = on(&joint.a);
                JointReaction {
                    force_on_b: fb,
                    moment_on_b: mb,
                    force_on_a: fa,
                    moment_on_a: ma,
                }
            })
            .collect()
    }

    /// Outputs at `(t, y)`.
    pub fn output(&self, t: f64, y: &[f64]) -> Result<Output, ConstraintError> {
        let nq = self.model.n_q();
        let (q, v) = y.split_at(nq);
        let k = self.model.constraint_kin(t, q, v);
        let (m, f) = self.model.mass_and_forces(t, q, v);
        let sol = self.solve_with(t, (q, v), &k, (&m, &f))?;
        let nv = self.model.n_v();
        let lambda = self.full_lambda(&sol);
        let c = self.model.constraint_values(&k);
        let ids: Vec<BodyId> = self.model.body_ids().collect();
        Ok(Output {
            t,
            q: q.to_vec(),
            v: v.to_vec(),
            accelerations: sol.x[..nv].to_vec(),
            reactions: self.reactions_from(&c, q, &lambda),
            lambda,
            positions: ids
                .iter()
                .map(|&b| {
                    let r = self.model.q_range(b).start;
                    Vector3::new(q[r], q[r + 1], q[r + 2])
                })
                .collect(),
            orientations: ids.iter().map(|&b| self.model.rotation_of(b, q)).collect(),
            modal: ids
                .iter()
                .map(|&b| {
                    let r = self.model.q_range(b);
                    q[r.start + 7..r.end].to_vec()
                })
                .collect(),
            nodal_displacements: ids
                .iter()
                .map(|&b| self.model.nodal_displacements(b, q))
                .collect(),
            position_violation: max_abs(&c.phi),
            kept_position_violation: sol
                .rows
                .iter()
                .fold(0.0, |m: f64, &r| m.max(c.phi[r].abs())),
            removed_position_violation: (0..c.phi.len())
                .filter(|r| !sol.rows.contains(r))
                .fold(0.0, |m: f64, r| m.max(c.phi[r].abs())),
            velocity_violation: max_abs(&c.phi_dot),
            energy: self.model.energy_with_mass(q, v, &m),
        })
    }
}

/// `q ← q ⊕ Δ` for an increment `Δ` in the velocity variables of `model` (rotations exact).
pub(crate) fn apply_increment(model: &Model<f64>, q: &mut [f64], d: &[f64]) {
    for id in model.body_ids() {
        let qr = model.q_range(id);
        let vr = model.v_range(id);
        for i in 0..3 {
            q[qr.start + i] += d[vr.start + i];
        }
        let p = Vector4::new(
            q[qr.start + 3],
            q[qr.start + 4],
            q[qr.start + 5],
            q[qr.start + 6],
        );
        let dq = quat_from_rotation_vector(&Vector3::new(
            d[vr.start + 3],
            d[vr.start + 4],
            d[vr.start + 5],
        ));
        let pn = quat_mul(&p, &dq).normalize();
        q[qr.start + 3..qr.start + 7].copy_from_slice(pn.as_slice());
        for j in 6..vr.len() {
            q[qr.start + 1 + j] += d[vr.start + j];
        }
    }
}

/// [`sens::solve_tangents`] through the factorisation of Eq. (12) ([`Eq12Factor`]): the `N`
/// tangents of each row side by side, as the dual numbers hold them.
pub(crate) fn lu_tangents<const N: usize>(
    lu: &Eq12Factor,
    x_hat: &[f64],
    residual: &[Dual<N>],
) -> Vec<Dual<N>> {
    let n = x_hat.len();
    assert_eq!(residual.len(), n, "residual has the wrong length");
    let mut rhs: Vec<f64> = residual.iter().flat_map(|r| r.d).collect();
    lu.solve_rows(&mut rhs, N);
    (0..n)
        .map(|i| Dual::new(x_hat[i], std::array::from_fn(|k| rhs[i * N + k])))
        .collect()
}

/// The assembly's projection `[W J_Iᵀ; J_I 0]`, factorised ([`MultibodySystem::start_projection`]).
pub(crate) struct StartProjection {
    /// The independent constraint rows `I`.
    pub(crate) rows: Vec<usize>,
    lu: LU<f64, Dyn, Dyn>,
    /// Number of rigid-coordinate columns.
    n: usize,
}

impl StartProjection {
    /// `(x, μ)` with `W x + J_Iᵀ μ = a`, `J_I x = b`.
    pub(crate) fn solve(&self, a: &[f64], b: &[f64]) -> (Vec<f64>, Vec<f64>) {
        let mut r = DVector::from_iterator(self.n + b.len(), a.iter().chain(b).copied());
        if r.is_empty() {
            // nothing to move (no rigid coordinates, no rows); nalgebra's solve underflows on 0 × 0
            return (Vec::new(), Vec::new());
        }
        self.lu.solve_mut(&mut r);
        let (x, mu) = r.as_slice().split_at(self.n);
        (x.to_vec(), mu.to_vec())
    }
}

/// What [`MultibodySystem::assemble`] started from.
#[derive(Clone, Debug)]
pub(crate) struct StartGuess {
    pub(crate) t: f64,
    /// The assembled positions.
    pub(crate) q: Vec<f64>,
    /// The velocities before the projection.
    pub(crate) v: Vec<f64>,
}

/// Greedy modified Gram–Schmidt on the rows of `jac`: `(independent, dependent)` row indices.
fn independent_rows(jac: &DMatrix<f64>) -> (Vec<usize>, Vec<usize>) {
    let rows: Vec<Vec<f64>> = (0..jac.nrows())
        .map(|r| jac.row(r).iter().copied().collect())
        .collect();
    independent_rows_of(
        rows.iter().map(Vec::as_slice),
        jac.ncols(),
        ASSEMBLY_DEPENDENCE_TOL,
    )
}

/// Greedy modified Gram–Schmidt on rows of length `n`: `(independent, dependent)` indices. A
/// row is dependent when its component orthogonal to the independent rows before it is below
/// `tol` times its norm (or it is zero).
pub(crate) fn independent_rows_of<'a>(
    rows: impl Iterator<Item = &'a [f64]>,
    n: usize,
    tol: f64,
) -> (Vec<usize>, Vec<usize>) {
    // orthonormal basis, row after row
    let mut basis: Vec<f64> = Vec::new();
    let mut x = vec![0.0; n];
    let (mut keep, mut drop) = (Vec::new(), Vec::new());
    for (r, row) in rows.enumerate() {
        x.copy_from_slice(row);
        let norm0 = x.iter().map(|a| a * a).sum::<f64>().sqrt();
        for b in basis.chunks_exact(n) {
            let p: f64 = b.iter().zip(&x).map(|(a, c)| a * c).sum();
            for (xi, bi) in x.iter_mut().zip(b) {
                *xi -= p * bi;
            }
        }
        let nx = x.iter().map(|a| a * a).sum::<f64>().sqrt();
        if nx > tol * norm0.max(1e-300) && norm0 > 0.0 {
            basis.extend(x.iter().map(|a| a / nx));
            keep.push(r);
        } else {
            drop.push(r);
        }
    }
    (keep, drop)
}

fn describe_rows(model: &Model<f64>, rows: &[usize]) -> Vec<(String, usize)> {
    rows.iter()
        .map(|&r| {
            let j = model.joint_of_row(r);
            (model.joint(j).name.clone(), r - model.joint_rows(j).start)
        })
        .collect()
}

impl OdeSystem for MultibodySystem {
    fn dim(&self) -> usize {
        self.model.n_q() + self.model.n_v()
    }

    /// [`MultibodySystem::check_state`], reading the constraint violation at the step's last
    /// Newton iterate, the last right-hand side at `t`, while it is below half the limit: the
    /// accepted state differs from that iterate by the last Newton correction, below the error
    /// weights, and the limit (5 % of the mechanism's size) is a divergence detector, so the
    /// check needs no second pass of the constraint kinematics (7 % of the beam deck's
    /// analysis). A violation above half the limit, or one from another time, is evaluated
    /// again at the state itself.
    fn check_step(&mut self, t: f64, y: &[f64]) -> Result<(), String> {
        let (q, v) = y.split_at(self.model.n_q());
        let near = self
            .last_violation
            .is_some_and(|(tl, phi)| tl == t && phi <= 0.5 * self.guard.max_violation);
        if near {
            self.check_deformation(q)
        } else {
            self.check_state(t, q, v)
        }
    }

    fn breakpoints(&self) -> Vec<f64> {
        self.model.breakpoints()
    }

    fn rhs(&mut self, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), RhsError> {
        self.report_progress(t);
        let (q, v) = y.split_at(self.model.n_q());
        let k = self.model.constraint_kin(t, q, v);
        self.note_violation(t, self.largest_violation(&k));
        let (m, f) = self.model.mass_and_forces(t, q, v);
        let sol = self
            .solve_with(t, (q, v), &k, (&m, &f))
            .map_err(|e| RhsError(e.to_string()))?;
        self.write_rates(y, &sol, dy);
        Ok(())
    }

    /// `∂f/∂y` of a mechanism whose Eq. (12) has more than 80 unknowns, as the sparse Newton
    /// system of docs/design.md §3; `None` (the dense Jacobian) for smaller ones, or
    /// should its symbolic analysis fail.
    fn structured_jacobian(
        &mut self,
        t: f64,
        y: &[f64],
    ) -> Option<Result<Box<dyn StructuredJacobian>, RhsError>> {
        if !self.structured() {
            return None;
        }
        let (q, v) = y.split_at(self.model.n_q());
        let k = self.model.constraint_kin(t, q, v);
        let (m, f) = self.model.mass_and_forces(t, q, v);
        let sol = match self.solve_with(t, (q, v), &k, (&m, &f)) {
            Ok(sol) => sol,
            Err(e) => return Some(Err(RhsError(e.to_string()))),
        };
        let colouring = self
            .newton
            .colouring
            .get_or_init(|| Colouring::new(&self.model));
        let j = SparseNewton::new(
            &self.model,
            colouring,
            t,
            (q, v),
            (&m, &k),
            (&sol.rows, &sol.x),
            &self.newton.pattern,
        )?;
        Some(Ok(Box::new(j)))
    }

    /// Exact `∂f/∂y`: the residual of Eq. (12) in `Dual<8>` seeded with chunks of the state,
    /// its tangents pushed through the `f64` LU ([`sens::solve_tangents`]).
    fn jacobian(&mut self, t: f64, y: &[f64], jac: &mut DMatrix<f64>) -> Result<(), RhsError> {
        let nq = self.model.n_q();
        let nv = self.model.n_v();
        let n = nq + nv;
        let (q, v) = y.split_at(nq);
        let sol = self.solve(t, q, v).map_err(|e| RhsError(e.to_string()))?;
        for range in chunk_ranges(n, CHUNK) {
            let seed = |i: usize, x: f64| -> Dual<CHUNK> {
                if range.contains(&i) {
                    Dual::variable(x, i - range.start)
                } else {
                    Dual::constant(x)
                }
            };
            let qd: Vec<Dual<CHUNK>> = q.iter().enumerate().map(|(i, &x)| seed(i, x)).collect();
            let vd: Vec<Dual<CHUNK>> = v
                .iter()
                .enumerate()
                .map(|(i, &x)| seed(nq + i, x))
                .collect();
            let res = self.model.residual(t, &qd, &vd, &sol.rows, &sol.x);
            let x = lu_tangents(&sol.lu, &sol.x, &res);
            let mut qdot = vec![Dual::<CHUNK>::constant(0.0); nq];
            self.model.kinematic_rates(&qd, &vd, &mut qdot);
            for (k, col) in range.clone().enumerate() {
                for i in 0..nq {
                    jac[(i, col)] = qdot[i].tangent(k);
                }
                for i in 0..nv {
                    jac[(nq + i, col)] = x[i].tangent(k);
                }
            }
        }
        Ok(())
    }
}

/// Failure of a simulation.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SimulationError {
    #[error(transparent)]
    Constraint(#[from] ConstraintError),
    #[error(transparent)]
    Integration(#[from] IntegrationError),
}

/// Outputs and work statistics of a run.
#[derive(Clone, Debug)]
pub struct Simulation {
    pub outputs: Vec<Output>,
    pub statistics: Statistics,
}

/// Integrate `system` from `state` at `t_out[0]` to the last output time, returning the
/// outputs at every `t_out` (dense output between steps).
pub fn simulate(
    system: &mut MultibodySystem,
    state: &State,
    t_out: &[f64],
    options: BdfOptions,
) -> Result<Simulation, SimulationError> {
    let (Some(&t0), Some(&t_end)) = (t_out.first(), t_out.last()) else {
        return Err(IntegrationError {
            t: f64::NAN,
            h: 0.0,
            reason: crate::bdf::IntegrationFailure::Settings("at least one output time is needed"),
        }
        .into());
    };
    let mut bdf = Bdf::new(options);
    bdf.init(system, t0, &state.to_vec())?;
    let ys = bdf.integrate_to(system, t_end, t_out, |_| {})?;
    let outputs = t_out
        .iter()
        .zip(&ys)
        .map(|(&t, y)| system.output(t, y))
        .collect::<Result<Vec<_>, _>>()?;
    Ok(Simulation {
        outputs,
        statistics: bdf.statistics(),
    })
}

/// `max |x_i|`, NaN if any entry is NaN (`f64::max` would drop it and hide a broken state).
pub(crate) fn max_abs(x: &[f64]) -> f64 {
    x.iter().fold(0.0, |m: f64, v| {
        if v.is_nan() || m.is_nan() {
            f64::NAN
        } else {
            m.max(v.abs())
        }
    })
}
