//! Elastic assembly: a start whose joints the rigid-body coordinates alone cannot meet (a
//! misaligned joint that locks a mechanism of rigid bars) is assembled with the flexible
//! bodies' elastic coordinates too, at the least strain energy the joints allow — the static
//! equilibrium of the locked frame, its joint forces the prestress it needs.

use nalgebra::{DMatrix, DVector};
use sens::Scalar;

use crate::body::Body;
use crate::error::ConstraintError;
use crate::model::{Model, State};
use crate::system::{
    ASSEMBLY_DEPENDENCE_TOL, ElasticStart, MultibodySystem, independent_rows_of, max_abs,
};

/// Iterations of the elastic assembly's sequential quadratic steps.
const MAX_ITERATIONS: usize = 50;

impl MultibodySystem {
    /// The elastic coordinate at velocity column `col` of `state` (a body's modal coordinates
    /// follow its 7 position coordinates, its velocity columns its 6 rigid rates).
    pub(crate) fn elastic_value(&self, state: &State, col: usize) -> f64 {
        let model = self.model();
        let id = model
            .body_ids()
            .find(|&id| model.v_range(id).contains(&col))
            .expect("a column of a body");
        state.q[model.q_range(id).start + 1 + (col - model.v_range(id).start)]
    }

    /// The velocity columns of the flexible bodies' elastic coordinates, in order.
    pub(crate) fn elastic_columns(&self) -> Vec<usize> {
        let model = self.model();
        (model.body_ids())
            .filter(|&id| matches!(model.body(id), Body::Flexible(_)))
            .flat_map(|id| {
                let r = model.v_range(id);
                r.start + 6..r.end
            })
            .collect()
    }

    /// Positions that meet the constraints at `t` with the rigid and the elastic coordinates
    /// together, at the least strain energy `½ wᵀK̄w` of the flexible bodies: sequential
    /// quadratic steps `d` minimising `½ d_rᵀ W d_r + ½ (w + d_w)ᵀ K̄ (w + d_w)` (`W` the
    /// rigid-coordinate block of the mass matrix, which only makes the rigid steps definite)
    /// subject to the linearised constraints, until `max |Φ| ≤ tol` and the elastic step is
    /// round-off. At the solution the multipliers are the joint forces that hold the frame
    /// deformed (`K̄w + J_wᵀλ = 0`) and put no net load on any body (`J_rᵀλ = 0`).
    pub(crate) fn assemble_elastic(
        &self,
        t: f64,
        state: &mut State,
        tol: f64,
    ) -> Result<ElasticStart, ConstraintError> {
        let model = self.model();
        let (elastic, k) = (self.elastic_columns(), stiffness_of(model));
        let nv = model.n_v();
        let mut lambda = Vec::new();
        let mut rows = Vec::new();
        for it in 0..=MAX_ITERATIONS {
            let c = model.constraints(t, &state.q, &state.v);
            let (x, w);
            (x, rows, w) = self.elastic_step(t, state, &c, &elastic, &k)?;
            let d = &x.as_slice()[..nv];
            lambda = x.as_slice()[nv..].to_vec();
            let step = elastic.iter().fold(0.0f64, |s, &i| s.max(d[i].abs()));
            let size = w.amax().max(f64::MIN_POSITIVE);
            if max_abs(&c.phi) <= tol && step <= 1e-9 * size {
                break;
            }
            if it == MAX_ITERATIONS || !x.iter().all(|v| v.is_finite()) {
                return Err(self.inconsistent_elastically(&c.phi));
            }
            self.apply_increment(&mut state.q, d);
        }
        let c = model.constraints(t, &state.q, &state.v);
        if !(max_abs(&c.phi) <= tol) {
            return Err(self.inconsistent_elastically(&c.phi));
        }
        let mut full = vec![0.0; model.n_constraints()];
        for (&r, &l) in rows.iter().zip(&lambda) {
            full[r] = l;
        }
        Ok(self.prestress(state, &c, &full))
    }

    /// One step of the elastic assembly at `state` (constraints `c` there): `(d, λ)` over every
    /// velocity column with `H = (W, K̄)` (the mass matrix's rigid block, the modal stiffness
    /// `k` over the `elastic` columns) and `g = (0, −K̄w)`, the independent rows `I` it kept,
    /// and the elastic coordinates `w`.
    #[allow(clippy::type_complexity)]
    fn elastic_step(
        &self,
        t: f64,
        state: &State,
        c: &crate::model::ConstraintValues<f64>,
        elastic: &[usize],
        k: &DMatrix<f64>,
    ) -> Result<(DVector<f64>, Vec<usize>, DVector<f64>), ConstraintError> {
        let model = self.model();
        let nv = model.n_v();
        let rigid = self.rigid_columns();
        let w = DVector::from_iterator(
            elastic.len(),
            elastic.iter().map(|&i| self.elastic_value(state, i)),
        );
        let (mass, _) = model.mass_and_forces(t, &state.q, &vec![0.0; nv]);
        let mut h = DMatrix::zeros(nv, nv);
        for &i in &rigid {
            for &j in &rigid {
                h[(i, j)] = mass[(i, j)];
            }
        }
        let kw = k * &w;
        let mut g = DVector::zeros(nv);
        for (a, &i) in elastic.iter().enumerate() {
            g[i] = -kw[a];
            for (b, &j) in elastic.iter().enumerate() {
                h[(i, j)] = k[(a, b)];
            }
        }
        let (x, rows) = saddle_point(&h, &c.jacobian, &g, &c.phi)
            .ok_or(ConstraintError::SingularStart { t })?;
        Ok((x, rows, w))
    }

    /// The strain energies and the largest joint force of an elastically assembled state.
    fn prestress(
        &self,
        state: &State,
        c: &crate::model::ConstraintValues<f64>,
        lambda: &[f64],
    ) -> ElasticStart {
        let model = self.model();
        let mut bodies = Vec::new();
        for id in model.body_ids() {
            if let Body::Flexible(f) = model.body(id) {
                let r = model.v_range(id);
                let w = DVector::from_iterator(
                    r.len() - 6,
                    (r.start + 6..r.end).map(|i| self.elastic_value(state, i)),
                );
                let energy = 0.5 * w.dot(&(modal_stiffness(f) * &w));
                if energy > 0.0 {
                    bodies.push((f.name.clone(), energy));
                }
            }
        }
        let reactions = self.reactions_from(c, &state.q, lambda);
        let (joint, force) = reactions
            .iter()
            .enumerate()
            .map(|(j, r)| (j, r.force_on_a.norm().max(r.force_on_b.norm())))
            .fold(
                (0, 0.0),
                |(bj, bf), (j, f)| if f > bf { (j, f) } else { (bj, bf) },
            );
        ElasticStart {
            bodies,
            joint: model.joints()[joint].name.clone(),
            force,
        }
    }

    /// Velocities that meet `Φ̇ = 0` with every coordinate's rate: the change `Δv` of the
    /// smallest kinetic energy `½ ΔvᵀMΔv` (the impulse of the constraint forces), for a start
    /// assembled elastically, whose locked frame the rigid rates alone may not move.
    pub(crate) fn project_velocities_elastically(
        &self,
        t: f64,
        state: &mut State,
    ) -> Result<(), ConstraintError> {
        let model = self.model();
        let n = model.n_v();
        let c = model.constraints(t, &state.q, &state.v);
        let (mass, _) = model.mass_and_forces(t, &state.q, &vec![0.0; n]);
        let (x, _) = saddle_point(
            &mass.to_dense(),
            &c.jacobian,
            &DVector::zeros(n),
            &c.phi_dot,
        )
        .ok_or(ConstraintError::SingularStart { t })?;
        for (v, dv) in state.v.iter_mut().zip(x.iter()) {
            *v += dv;
        }
        Ok(())
    }

    /// The error for a constraint that even the elastic coordinates cannot meet: the joint
    /// of the largest residual.
    fn inconsistent_elastically(&self, phi: &[f64]) -> ConstraintError {
        match self.inconsistent(phi, "Φ") {
            ConstraintError::Inconsistent {
                joint,
                equation,
                bodies,
                also,
                residual,
                ..
            } => ConstraintError::InconsistentElastically {
                joint,
                equation,
                bodies,
                also,
                residual,
            },
            other => other,
        }
    }
}

/// The solution `(x, μ)` (as one vector) of `H x + J_Iᵀ μ = g`, `J_I x = −r_I` with `J_I` the
/// independent rows `I` of `jac` (returned beside it), or `None` where the matrix is singular.
fn saddle_point(
    h: &DMatrix<f64>,
    jac: &DMatrix<f64>,
    g: &DVector<f64>,
    r: &[f64],
) -> Option<(DVector<f64>, Vec<usize>)> {
    let n = h.nrows();
    let dense: Vec<Vec<f64>> = (0..jac.nrows())
        .map(|i| jac.row(i).iter().copied().collect())
        .collect();
    let (rows, _) =
        independent_rows_of(dense.iter().map(Vec::as_slice), n, ASSEMBLY_DEPENDENCE_TOL);
    let m = rows.len();
    let mut a = DMatrix::zeros(n + m, n + m);
    a.view_mut((0, 0), (n, n)).copy_from(h);
    let mut rhs = DVector::zeros(n + m);
    rhs.rows_mut(0, n).copy_from(g);
    for (i, &row) in rows.iter().enumerate() {
        for j in 0..n {
            a[(n + i, j)] = jac[(row, j)];
            a[(j, n + i)] = jac[(row, j)];
        }
        rhs[n + i] = -r[row];
    }
    a.lu().solve(&rhs).map(|x| (x, rows))
}

/// A flexible body's modal stiffness: its full matrix, or the diagonal of its eigenvalues.
fn modal_stiffness<P: Scalar>(f: &crate::body::FlexibleBody<P>) -> DMatrix<P> {
    match &f.modal.stiffness_matrix {
        Some(k) => (**k).clone(),
        None => {
            let p = f.modal.eigenvalues.len();
            DMatrix::from_fn(p, p, |i, j| {
                if i == j {
                    f.modal.eigenvalues[i]
                } else {
                    P::zero()
                }
            })
        }
    }
}

/// The modal stiffness of `model`'s flexible bodies over their elastic columns, block diagonal
/// by body ([`MultibodySystem::elastic_columns`]), in its parameters' scalar.
fn stiffness_of<P: Scalar>(model: &Model<P>) -> DMatrix<P> {
    let blocks: Vec<DMatrix<P>> = (model.body_ids())
        .filter_map(|id| match model.body(id) {
            Body::Flexible(f) => Some(modal_stiffness(f)),
            _ => None,
        })
        .collect();
    let n = blocks.iter().map(|b| b.nrows()).sum();
    let mut k = DMatrix::from_element(n, n, P::zero());
    let mut at = 0;
    for b in blocks {
        let m = b.nrows();
        k.view_mut((at, at), (m, m)).copy_from(&b);
        at += m;
    }
    k
}

impl MultibodySystem {
    /// The positions' sensitivities (`n_q × m`) of a start assembled elastically
    /// ([`MultibodySystem::assemble_elastic`]): its optimality conditions `J_rᵀλ = 0`,
    /// `K̄w + J_wᵀλ = 0`, `Φ_I = 0` differentiated, `[H J_Iᵀ; J_I 0] [d_b; λ_b] =
    /// −[∂_b(J_Iᵀλ) + (0, K̄_b w); Φ_I,b]` with `H = ∂_d(J_Iᵀλ) + (0, K̄)` (the constraints'
    /// curvature under the prestress, by dual numbers along each velocity direction, and the
    /// modal stiffness); `q_b` from the increments `d_b`.
    pub(crate) fn prestress_sensitivities<const N: usize>(
        &self,
        design: &crate::sensitivity::DesignModel<N>,
        t: f64,
        state: &State,
    ) -> Result<DMatrix<f64>, ConstraintError> {
        let model = self.model();
        let (nq, nv) = (model.n_q(), model.n_v());
        let (elastic, k) = (self.elastic_columns(), stiffness_of(model));
        let c = model.constraints(t, &state.q, &state.v);
        // the multipliers at the assembled state: one more step of the assembly's
        let (x, rows, w) = self.elastic_step(t, state, &c, &elastic, &k)?;
        let lambda = &x.as_slice()[nv..];
        // H: the curvature of λᵀΦ along each velocity direction, and K̄ on the elastic block
        let mut h = DMatrix::zeros(nv, nv);
        let mut dq = vec![0.0; nq];
        let qd0: Vec<sens::Dual<N>> = state.q.iter().map(|&x| sens::Dual::constant(x)).collect();
        let vd0: Vec<sens::Dual<N>> = state.v.iter().map(|&x| sens::Dual::constant(x)).collect();
        for start in (0..nv).step_by(N) {
            let dirs: Vec<usize> = (start..(start + N).min(nv)).collect();
            let mut qd = qd0.clone();
            for (tn, &kd) in dirs.iter().enumerate() {
                let mut e = vec![0.0; nv];
                e[kd] = 1.0;
                model.kinematic_rates(&state.q, &e, &mut dq);
                for (qi, dqi) in qd.iter_mut().zip(&dq) {
                    qi.d[tn] = *dqi;
                }
            }
            let cd = model.constraints(t, &qd, &vd0);
            for col in 0..nv {
                for (tn, &kd) in dirs.iter().enumerate() {
                    h[(col, kd)] = rows
                        .iter()
                        .zip(lambda)
                        .map(|(&r, l)| cd.jacobian[(r, col)].d[tn] * l)
                        .sum();
                }
            }
        }
        for (a, &i) in elastic.iter().enumerate() {
            for (b, &j) in elastic.iter().enumerate() {
                h[(i, j)] += k[(a, b)];
            }
        }
        // the right-hand sides, one dual evaluation per chunk of variables at the state held
        let mut s = DMatrix::zeros(nq, design.n_variables());
        for (dm, range) in design.chunk_ranges() {
            let cd = dm.constraints(t, &qd0, &vd0);
            let kd = stiffness_of(dm);
            for (tn, j) in range.enumerate() {
                let mut rhs_g = DVector::zeros(nv);
                for col in 0..nv {
                    rhs_g[col] = -rows
                        .iter()
                        .zip(lambda)
                        .map(|(&r, l)| cd.jacobian[(r, col)].d[tn] * l)
                        .sum::<f64>();
                }
                let kbw = kd.map(|x| x.d[tn]) * &w;
                for (a, &i) in elastic.iter().enumerate() {
                    rhs_g[i] -= kbw[a];
                }
                let phi_b: Vec<f64> = (0..c.phi.len()).map(|r| cd.phi[r].d[tn]).collect();
                let (x, _) = saddle_point(&h, &c.jacobian, &rhs_g, &phi_b)
                    .ok_or(ConstraintError::SingularStart { t })?;
                let db: Vec<f64> = x.as_slice()[..nv].to_vec();
                model.kinematic_rates(&state.q, &db, &mut dq);
                for i in 0..nq {
                    s[(i, j)] = dq[i];
                }
            }
        }
        Ok(s)
    }
}
