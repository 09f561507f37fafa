//! Interface bases: distributing couplings over node sets and static correction (attachment)
//! modes, with their design derivatives.
//!
//! A [`Coupling`] ties a reference point to a set of nodes the way an RBE3 element does: the
//! point moves as the least-squares rigid motion of the set, and a force or moment at the point
//! is spread over the set by the transpose of that operator (so it has the same resultant and
//! moment). It adds no stiffness. A joint attached to an edge of a shell through a coupling
//! loads the whole edge instead of one node, whose local displacement under a point load is
//! singular on a Mindlin plate.
//!
//! Static correction modes ([`StaticCorrection`]) are the static responses `Ψ = K⁻¹E` to unit
//! loads `E` at the body's interfaces (nodes or couplings), made mass-orthogonal to the retained
//! eigenmodes and diagonalised. Their design derivatives follow from
//! `Ψ_b = −K⁻¹K_bΨ` through the factorised stiffness, the derivative of the projection away
//! from the eigenmodes, and a fixed combination of the columns (the Gram–Schmidt and Ritz
//! coefficients of the nominal design): the derivative of the reduced model's span is exact,
//! and the modal stiffness the body then needs is full ([`crate::ModalBody::stiffness_matrix`]).

use faer::sparse::SparseColMat;
use nalgebra::{DMatrix, DVector, Matrix3, Vector3};
use sens::SparseCholesky;

use crate::assembly::Assembly;
use crate::error::FemError;
use crate::mesh::{Mesh, NodeId};

/// A coupling of a reference point to a set of nodes: distributing (an RBE3 element) or rigid
/// (an RBE2 element).
///
/// Distributing: every node of the set has the same weight. The point's translation and
/// rotation are those of the rigid motion closest to the set's nodal translations (least
/// squares); a rotation the translations do not determine (about the line of a straight set,
/// or every rotation of a single node) is the mean of the nodal rotations about that axis. It
/// adds no stiffness.
///
/// Rigid: the set moves as one rigid body with the point ([`crate::RigidTie`]), which stiffens
/// the body where it is attached (an end edge of a plate keeps its shape). The same fit then
/// gives the point's motion exactly, and a load at the point reaches the set as its resultant
/// and moment.
#[derive(Clone, Debug, PartialEq)]
pub struct Coupling {
    pub nodes: Vec<NodeId>,
    /// The reference point (mesh coordinates); `None`: the centroid of the nodes.
    pub point: Option<Vector3<f64>>,
    /// A rigid coupling (RBE2); `false`: distributing (RBE3).
    pub rigid: bool,
}

/// A coupling resolved on its mesh: the point and the operator `W` (`6 × 6·nodes`) that gives
/// the point's `[u, θ]` from the nodes' `[u_k, θ_k]`, node by node.
#[derive(Clone, Debug, PartialEq)]
pub struct Distribution {
    pub nodes: Vec<NodeId>,
    pub point: Vector3<f64>,
    pub weights: DMatrix<f64>,
}

/// Relative weight of the nodal rotations in a coupling's fit, against the translations at the
/// set's radius of gyration: small enough to leave every rotation the translations determine
/// unchanged (to this order), large enough to fix the ones they do not.
const ROTATION_WEIGHT: f64 = 1e-6;

fn skew(r: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -r.z, r.y, r.z, 0.0, -r.x, -r.y, r.x, 0.0)
}

/// The operator of `coupling` on `mesh` ([`Distribution`]).
pub fn distribution(mesh: &Mesh, coupling: &Coupling) -> Result<Distribution, FemError> {
    let n = mesh.nodes.len();
    if coupling.nodes.is_empty() {
        return Err(FemError::Coupling(
            "a coupling needs at least one node".into(),
        ));
    }
    let mut seen = std::collections::BTreeSet::new();
    for &k in &coupling.nodes {
        if k >= n {
            return Err(FemError::Coupling(format!(
                "coupling node {k} does not exist (the mesh has {n} nodes)"
            )));
        }
        if !seen.insert(k) {
            return Err(FemError::Coupling(format!(
                "coupling node {k} is listed twice"
            )));
        }
    }
    let centroid = coupling
        .nodes
        .iter()
        .fold(Vector3::zeros(), |a, &k| a + mesh.nodes[k])
        / coupling.nodes.len() as f64;
    let point = coupling.point.unwrap_or(centroid);
    if !point.iter().all(|x| x.is_finite()) {
        return Err(FemError::Coupling(format!(
            "coupling point {point:?} must be finite"
        )));
    }
    // the fit about the centroid c, where translations and rotations decouple:
    // u_c = mean u_k, θ_c = J⁻¹ Σ (r_k × u_k + l² θ_k), J = Σ (|r_k|² I − r_k r_kᵀ) + n l² I;
    // then carried to the point p: u = u_c + θ_c × (p − c), θ = θ_c
    let r: Vec<Vector3<f64>> = coupling
        .nodes
        .iter()
        .map(|&k| mesh.nodes[k] - centroid)
        .collect();
    let count = r.len() as f64;
    let gyration = r.iter().map(|r| r.norm_squared()).sum::<f64>() / count;
    let l2 = if gyration > 0.0 {
        ROTATION_WEIGHT * gyration
    } else {
        1.0
    };
    let j = r.iter().fold(Matrix3::identity() * (count * l2), |a, r| {
        a + Matrix3::identity() * r.norm_squared() - r * r.transpose()
    });
    let j_inv = j.try_inverse().ok_or_else(|| {
        FemError::Coupling("coupling: the fit of its rigid motion is singular".into())
    })?;
    let carry = -skew(&(point - centroid));
    let mut weights = DMatrix::zeros(6, 6 * r.len());
    for (i, rk) in r.iter().enumerate() {
        // θ_c from u_k and θ_k
        let rot_u = j_inv * skew(rk);
        let rot_t = j_inv * l2;
        // u from u_k and θ_k
        let tr_u = Matrix3::identity() / count + carry * rot_u;
        let tr_t = carry * rot_t;
        weights.view_mut((0, 6 * i), (3, 3)).copy_from(&tr_u);
        weights.view_mut((0, 6 * i + 3), (3, 3)).copy_from(&tr_t);
        weights.view_mut((3, 6 * i), (3, 3)).copy_from(&rot_u);
        weights.view_mut((3, 6 * i + 3), (3, 3)).copy_from(&rot_t);
    }
    Ok(Distribution {
        nodes: coupling.nodes.clone(),
        point,
        weights,
    })
}

impl Distribution {
    /// The point's `[u, θ]` rows of a mode matrix `x` (`6·n_nodes × p`, node by node).
    pub fn rows<S: sens::Scalar>(&self, x: &DMatrix<S>) -> DMatrix<S> {
        let p = x.ncols();
        let mut out = DMatrix::from_element(6, p, S::zero());
        for (i, &k) in self.nodes.iter().enumerate() {
            for d in 0..6 {
                for r in 0..6 {
                    let w = self.weights[(r, 6 * i + d)];
                    if w != 0.0 {
                        for j in 0..p {
                            out[(r, j)] += x[(6 * k + d, j)] * w;
                        }
                    }
                }
            }
        }
        out
    }

    /// The adjoint of [`Self::rows`]: `x_bar += Wᵀ rows_bar` for the adjoint `rows_bar` (6 × p)
    /// of the point's rows.
    pub fn rows_adjoint(&self, rows_bar: &DMatrix<f64>, x_bar: &mut DMatrix<f64>) {
        for (i, &k) in self.nodes.iter().enumerate() {
            for d in 0..6 {
                for r in 0..6 {
                    let w = self.weights[(r, 6 * i + d)];
                    if w != 0.0 {
                        for j in 0..rows_bar.ncols() {
                            x_bar[(6 * k + d, j)] += rows_bar[(r, j)] * w;
                        }
                    }
                }
            }
        }
    }

    /// The nodal loads (`6·n_nodes`, node by node) of a unit load `e_c` (force `c < 3`, moment
    /// `c ≥ 3`) at the point: column `c` of `Wᵀ`.
    pub fn load(&self, c: usize, n_nodes: usize) -> DVector<f64> {
        let mut f = DVector::zeros(6 * n_nodes);
        for (i, &k) in self.nodes.iter().enumerate() {
            for d in 0..6 {
                f[6 * k + d] = self.weights[(c, 6 * i + d)];
            }
        }
        f
    }
}

/// Static correction modes of an analysis ([`crate::ModalOptions::correction`]).
///
/// With `G = Ψ − X XᵀMΨ` (the static shapes `Ψ = K⁻¹E` without their part along the retained
/// eigenmodes `X`), the shapes are `Φ = G C`: `C` holds the Gram–Schmidt and Ritz coefficients,
/// so that `ΦᵀMΦ = I` and `ΦᵀKΦ = diag(μ)` at the analysed design.
#[derive(Clone, Debug)]
pub struct StaticCorrection {
    /// Ritz values `μ` (rad²/s²), ascending.
    pub values: Vec<f64>,
    /// `Φ` on the free dof (`n_free × s`).
    pub shapes: DMatrix<f64>,
    /// `Ψ` on the free dof (`n_free × r`).
    psi: DMatrix<f64>,
    /// `C` (`r × s`).
    coefficients: DMatrix<f64>,
}

/// The unit loads on the free dof of `assembly` at `targets`: every free dof of a node
/// (`target < n_nodes`), or those of the six loads of coupling `target − n_nodes` of
/// `couplings` that fall on free dof.
pub(crate) fn interface_loads(
    assembly: &Assembly,
    n_nodes: usize,
    couplings: &[Distribution],
    targets: &[NodeId],
) -> Result<DMatrix<f64>, FemError> {
    let mut cols: Vec<DVector<f64>> = Vec::new();
    for &t in targets {
        if t < n_nodes {
            cols.extend((0..6).filter_map(|d| assembly.unit_load(6 * t + d)));
        } else if let Some(c) = couplings.get(t - n_nodes) {
            for load in 0..6 {
                let e = assembly.restrict(c.load(load, n_nodes).as_slice());
                if e.amax() > 0.0 {
                    cols.push(e);
                }
            }
        } else {
            return Err(FemError::Correction(format!(
                "static correction at node {t}: the mesh has {n_nodes} nodes and {} couplings \
                 (numbered from {n_nodes})",
                couplings.len()
            )));
        }
    }
    if cols.is_empty() {
        return Err(FemError::Correction(
            "static correction: every dof of the correction nodes is fixed by the reference \
             condition"
                .into(),
        ));
    }
    Ok(DMatrix::from_columns(&cols))
}

/// The Cholesky factor of the free-dof stiffness `k` (an error when the reference condition
/// does not hold the body).
pub(crate) fn stiffness_factor(
    assembly: &Assembly,
    k: &SparseColMat<usize, f64>,
) -> Result<SparseCholesky, FemError> {
    factor_held(assembly, k, || {
        FemError::Correction(
            "static correction: the stiffness matrix is not positive definite (the reference \
             condition must hold the body)"
                .into(),
        )
    })
}

/// The Cholesky factor of the free-dof stiffness `k`, or `not_held()` when it is not positive
/// definite (the constraints leave a motion free).
pub(crate) fn factor_held(
    assembly: &Assembly,
    k: &SparseColMat<usize, f64>,
    not_held: impl FnOnce() -> FemError,
) -> Result<SparseCholesky, FemError> {
    let symbolic =
        SparseCholesky::symbolic(k.symbolic(), faer::Side::Lower, &assembly.free_dof_nodes())
            .map_err(|e| FemError::Eigen(format!("{e:?}")))?;
    SparseCholesky::new(symbolic, k.as_ref(), faer::Side::Lower).map_err(|_| not_held())
}

fn solve(llt: &SparseCholesky, rhs: &DMatrix<f64>) -> DMatrix<f64> {
    use sens::LinearSolver;
    let mut out = rhs.clone();
    llt.solve_columns(out.as_mut_slice(), rhs.ncols());
    out
}

/// `A X`, column by column.
pub(crate) fn times(a: &SparseColMat<usize, f64>, x: &DMatrix<f64>) -> DMatrix<f64> {
    let mut out = DMatrix::zeros(a.nrows(), x.ncols());
    crate::eigen::spmv_columns(a, x.as_slice(), out.as_mut_slice(), x.ncols());
    out
}

/// Static correction modes for the unit loads `loads` (free dof), against the retained
/// eigenvectors `x`: shapes whose part outside the span of the others is below 1e-8 of
/// themselves (in the mass norm) are dropped.
pub(crate) fn static_correction(
    assembly: &Assembly,
    k: &SparseColMat<usize, f64>,
    m: &SparseColMat<usize, f64>,
    x: &DMatrix<f64>,
    loads: &DMatrix<f64>,
) -> Result<StaticCorrection, FemError> {
    let llt = stiffness_factor(assembly, k)?;
    let psi = solve(&llt, loads);
    let mx = times(m, x);
    let g = if x.ncols() > 0 {
        &psi - x * (mx.transpose() * &psi)
    } else {
        psi.clone()
    };
    let r = g.ncols();
    // modified Gram–Schmidt in the mass metric (twice, for round-off), with the coefficients of
    // each basis vector in the columns of G kept beside it
    let mg = times(m, &g);
    let mut basis: Vec<DVector<f64>> = Vec::new();
    let mut m_basis: Vec<DVector<f64>> = Vec::new();
    let mut coef: Vec<DVector<f64>> = Vec::new();
    for c in 0..r {
        let mut v = g.column(c).into_owned();
        let mut a = DVector::zeros(r);
        a[c] = 1.0;
        let norm0 = v.dot(&mg.column(c)).max(0.0).sqrt();
        for _ in 0..2 {
            if x.ncols() > 0 {
                // round-off only: G is orthogonal to X already
                v -= x * mx.tr_mul(&v);
            }
            for ((b, mb), cb) in basis.iter().zip(&m_basis).zip(&coef) {
                let s = mb.dot(&v);
                v -= b * s;
                a -= cb * s;
            }
        }
        let mut mv = DVector::zeros(v.len());
        crate::eigen::spmv(m, v.as_slice(), mv.as_mut_slice());
        let norm = v.dot(&mv).max(0.0).sqrt();
        if norm > 1e-8 * norm0 && norm > 0.0 {
            basis.push(v / norm);
            m_basis.push(mv / norm);
            coef.push(a / norm);
        }
    }
    let q = DMatrix::from_columns(&basis);
    let kr = crate::eigen::project(k, &q, &q);
    let kr = (&kr + kr.transpose()) * 0.5;
    let eig = kr.symmetric_eigen();
    let mut order: Vec<usize> = (0..eig.eigenvalues.len()).collect();
    order.sort_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]));
    let values: Vec<f64> = order.iter().map(|&i| eig.eigenvalues[i]).collect();
    let z = eig.eigenvectors.select_columns(&order);
    Ok(StaticCorrection {
        values,
        shapes: &q * &z,
        psi,
        coefficients: DMatrix::from_columns(&coef) * z,
    })
}

impl StaticCorrection {
    /// The adjoint of the retained eigenvectors' derivatives `X_b` (`n_free × p`) through the
    /// shapes' derivatives of [`Self::shape_derivatives`], given the shapes' adjoint `phi_bar`
    /// (`n_free × s`): `Φ_b = G_b C` takes `X_b` in as `G_b = −X_b A − X X_bᵀMΨ + …`
    /// (`A = XᵀMΨ`), so that `X̄ = −Ḡ Aᵀ − MΨ (XᵀḠ)ᵀ` with `Ḡ = Φ̄ Cᵀ`.
    pub(crate) fn eigenvector_adjoint(
        &self,
        m: &SparseColMat<usize, f64>,
        x: &DMatrix<f64>,
        phi_bar: &DMatrix<f64>,
    ) -> DMatrix<f64> {
        let g_bar = phi_bar * self.coefficients.transpose();
        let m_psi = times(m, &self.psi);
        let a = x.transpose() * &m_psi;
        -(&g_bar * a.transpose()) - m_psi * (g_bar.transpose() * x)
    }

    /// `Φ_b` for each design variable (`n_free × s` each), given `K_b`, `M_b` and the
    /// eigenvectors' derivatives `x_b` (zero for fixed modes: `None`), at the analysis of
    /// `assembly`, `k`, `m`, `x`. The loads do not depend on the design.
    pub(crate) fn shape_derivatives(
        &self,
        assembly: &Assembly,
        k: &SparseColMat<usize, f64>,
        m: &SparseColMat<usize, f64>,
        x: &DMatrix<f64>,
        k_b: &[&SparseColMat<usize, f64>],
        m_b: &[&SparseColMat<usize, f64>],
        x_b: Option<&[DMatrix<f64>]>,
    ) -> Result<Vec<DMatrix<f64>>, FemError> {
        let llt = stiffness_factor(assembly, k)?;
        let psi = &self.psi;
        let m_psi = times(m, psi);
        // A = XᵀMΨ
        let a = x.transpose() * &m_psi;
        let mut out = Vec::with_capacity(k_b.len());
        for (v, (kb, mb)) in k_b.iter().zip(m_b).enumerate() {
            // Ψ_b = −K⁻¹ K_b Ψ
            let psi_b = -solve(&llt, &times(kb, psi));
            // G_b = Ψ_b − X_b A − X (X_bᵀMΨ + XᵀM_bΨ + XᵀMΨ_b)
            let mut a_b = x.transpose() * (times(mb, psi) + times(m, &psi_b));
            let mut g_b = psi_b;
            if let Some(xb) = x_b {
                a_b += xb[v].transpose() * &m_psi;
                g_b -= &xb[v] * &a;
            }
            if x.ncols() > 0 {
                g_b -= x * a_b;
            }
            out.push(g_b * &self.coefficients);
        }
        Ok(out)
    }
}
