//! The reduced (component-mode-synthesis) description of a flexible body, handed to `mbs`.

use nalgebra::{DMatrix, Vector3};
use sens::Scalar;

/// Degrees of freedom per node in [`ModalBody::modes`]: three translations then three rotations
/// (small rotation vector), all in the body frame.
pub const NODE_DOFS: usize = 6;

/// A flexible body reduced to a few vibration modes, in its body (floating) frame.
///
/// Conventions (paper §2.1–2.3, Eqs. 2, 11, 12):
/// - the body frame is the one the modes were computed in: for the paper's default reference
///   condition it sits at the node at the centre of mass, whose six dof were clamped;
/// - `modes` has `6 · n_nodes` rows ordered node by node as `[u_x, u_y, u_z, θ_x, θ_y, θ_z]`
///   and one column per retained mode, so the nodal displacements are `u' = X w` (Eq. 11);
/// - the lumped (diagonalised) nodal masses `m_k` and rotary inertias `μ_k` are those of Eq. (2);
///   the modes are mass-normalised with respect to that lumped mass matrix, so `XᵀMX = I`;
/// - `eigenvalues` are `ω_i²` (rad²/s²), `modal_damping` is the diagonal of `XᵀCX`,
///   `2 ζ_i ω_i` (1/s) for proportional damping.
///
/// With `S = Dual<N>` the entries of `modes`, `eigenvalues` and `modal_damping` carry their
/// derivatives with respect to the design variables (zero mode tangents for the fixed-mode
/// approach, Eq. 47; Nelson's derivatives for the updated-mode approach, Eq. 46).
#[derive(Clone, Debug)]
pub struct ModalBody<S: Scalar> {
    /// Undeformed node positions in the body frame (m).
    pub node_positions: Vec<Vector3<f64>>,
    /// Lumped nodal masses `m_k` (kg), in the scalar of the design (a material's density or a
    /// ply's thickness moves them).
    pub node_masses: Vec<S>,
    /// Lumped nodal rotary inertias `μ_k` about the body axes through the node (kg·m²).
    pub node_inertias: Vec<Vector3<S>>,
    /// Mode shapes `X`, `6 · n_nodes × n_modes`.
    pub modes: DMatrix<S>,
    /// `ω_i²` for each retained mode (rad²/s²).
    pub eigenvalues: Vec<S>,
    /// Diagonal modal damping `2 ζ_i ω_i` for each retained mode (1/s).
    pub modal_damping: Vec<S>,
    /// The full modal stiffness `XᵀKX` (rad²/s², `n_modes × n_modes`) where the modes do not
    /// keep it diagonal: the design derivatives of a body with static correction modes
    /// (`crate::correction`). Its diagonal is `eigenvalues`. `None`: `diag(eigenvalues)`.
    pub stiffness_matrix: Option<Box<DMatrix<S>>>,
    /// The full modal damping `XᵀCX` (1/s) in the same case; its diagonal is `modal_damping`.
    /// `None`: `diag(modal_damping)`.
    pub damping_matrix: Option<Box<DMatrix<S>>>,
}

/// Why a [`ModalBody`] is inconsistent.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ModalBodyError {
    #[error(
        "modal body has {positions} node positions but {masses} masses and {inertias} inertias"
    )]
    NodeCount {
        positions: usize,
        masses: usize,
        inertias: usize,
    },
    #[error("mode matrix has {rows} rows, expected 6 × {nodes} nodes = {expected}")]
    ModeRows {
        rows: usize,
        nodes: usize,
        expected: usize,
    },
    #[error("{modes} modes but {eigenvalues} eigenvalues and {damping} damping values")]
    ModeCount {
        modes: usize,
        eigenvalues: usize,
        damping: usize,
    },
    #[error("cannot align modal bodies of different layouts ({0})")]
    Layout(String),
    #[error("node {node}: {what} = {value} must be finite and non-negative")]
    BadMass {
        node: usize,
        what: &'static str,
        value: f64,
    },
}

impl<S: Scalar> ModalBody<S> {
    /// Number of FE nodes.
    pub fn n_nodes(&self) -> usize {
        self.node_positions.len()
    }

    /// Number of retained modes.
    pub fn n_modes(&self) -> usize {
        self.modes.ncols()
    }

    /// The node nearest the point `p` (body frame, m); `None` without nodes.
    pub fn closest_node(&self, p: &Vector3<f64>) -> Option<usize> {
        crate::mesh::closest(&self.node_positions, p)
    }

    /// The diagonal of the box around the undeformed nodes (m; 0 without nodes).
    pub fn size(&self) -> f64 {
        let (lo, hi) = crate::mesh::bounding_box(&self.node_positions);
        let d = (hi - lo).norm();
        if d.is_finite() { d } else { 0.0 }
    }

    /// Total mass `Σ m_k` (kg), value only.
    pub fn total_mass(&self) -> f64 {
        self.node_masses.iter().map(|m| m.value()).sum()
    }

    /// Check that the sizes agree and the masses are physical.
    pub fn validate(&self) -> Result<(), ModalBodyError> {
        let n = self.n_nodes();
        if self.node_masses.len() != n || self.node_inertias.len() != n {
            return Err(ModalBodyError::NodeCount {
                positions: n,
                masses: self.node_masses.len(),
                inertias: self.node_inertias.len(),
            });
        }
        if self.modes.nrows() != NODE_DOFS * n {
            return Err(ModalBodyError::ModeRows {
                rows: self.modes.nrows(),
                nodes: n,
                expected: NODE_DOFS * n,
            });
        }
        let m = self.n_modes();
        let square = |a: &Option<Box<DMatrix<S>>>| a.as_ref().is_none_or(|a| a.shape() == (m, m));
        if self.eigenvalues.len() != m
            || self.modal_damping.len() != m
            || !square(&self.stiffness_matrix)
            || !square(&self.damping_matrix)
        {
            return Err(ModalBodyError::ModeCount {
                modes: m,
                eigenvalues: self.eigenvalues.len(),
                damping: self.modal_damping.len(),
            });
        }
        for (k, (mk, mu)) in self.node_masses.iter().zip(&self.node_inertias).enumerate() {
            let mk = mk.value();
            if !(mk.is_finite() && mk >= 0.0) {
                return Err(ModalBodyError::BadMass {
                    node: k,
                    what: "mass",
                    value: mk,
                });
            }
            for v in mu.iter().map(|x| x.value()) {
                if !(v.is_finite() && v >= 0.0) {
                    return Err(ModalBodyError::BadMass {
                        node: k,
                        what: "inertia",
                        value: v,
                    });
                }
            }
        }
        Ok(())
    }
}

impl ModalBody<f64> {
    /// Track the modes of `reference` (mode tracking): within every group of repeated
    /// eigenvalues of `reference` (relative gap ≤ `cluster_tol`), replace this body's modes by
    /// the mass-orthonormal combination closest to the reference modes (orthogonal Procrustes
    /// in the lumped-mass metric); isolated modes get the reference's sign.
    ///
    /// Eigenvalue solvers return any basis of a repeated eigenvalue and any sign, so modal
    /// coordinates of two analyses (e.g. a nominal and a perturbed design) mean the same only
    /// after this. The tracked basis of a perturbed design differs from the reference by
    /// `O(δ)` and its derivative has no rotation within the clusters, the convention of the
    /// updated-mode derivatives (Nelson's method with the in-cluster rotation removed). Where a
    /// cluster splits, the rotated modes are no longer eigenvectors: the body then carries its
    /// full modal stiffness and damping in the rotated basis (the same reduced model).
    pub fn align_to(
        &mut self,
        reference: &ModalBody<f64>,
        cluster_tol: f64,
    ) -> Result<(), ModalBodyError> {
        let p = self.n_modes();
        if self.n_nodes() != reference.n_nodes()
            || p != reference.n_modes()
            || self.modes.nrows() != reference.modes.nrows()
        {
            return Err(ModalBodyError::Layout(format!(
                "{} nodes and {} modes against {} nodes and {} modes",
                self.n_nodes(),
                p,
                reference.n_nodes(),
                reference.n_modes()
            )));
        }
        // C = X_selfᵀ M X_ref with the lumped mass of the reference
        let mut weighted = reference.modes.clone();
        for (k, (m, mu)) in reference
            .node_masses
            .iter()
            .zip(&reference.node_inertias)
            .enumerate()
        {
            let w = [*m, *m, *m, mu.x, mu.y, mu.z];
            for (d, wd) in w.iter().enumerate() {
                weighted.row_mut(NODE_DOFS * k + d).scale_mut(*wd);
            }
        }
        let c = self.modes.transpose() * weighted;
        let lam = &reference.eigenvalues;
        let mut start = 0;
        while start < p {
            let mut end = start + 1;
            while end < p
                && (lam[end] - lam[end - 1]).abs()
                    <= cluster_tol * lam[end].abs().max(lam[end - 1].abs())
            {
                end += 1;
            }
            let r = end - start;
            let block = c.view((start, start), (r, r)).into_owned();
            // X_self R closest to X_ref: R = U Vᵀ of the SVD of X_selfᵀ M X_ref
            let svd = block.svd(true, true);
            let (u, vt) = (svd.u.expect("u"), svd.v_t.expect("v_t"));
            let rot = u * vt;
            let cols = self.modes.columns(start, r) * &rot;
            self.modes.columns_mut(start, r).copy_from(&cols);
            self.rotate_modal_matrices(start, &rot);
            start = end;
        }
        Ok(())
    }

    /// The modal stiffness and damping in the basis whose columns `start..start + r` are turned
    /// by `rot` (`r × r`): `Rᵀ A R` on that block, `A R` and `Rᵀ A` beside it. Where the turned
    /// block is not a multiple of the identity to 1e-10 (a cluster of the reference that is
    /// split here), the body then carries full matrices; otherwise they are left as they are.
    fn rotate_modal_matrices(&mut self, start: usize, rot: &DMatrix<f64>) {
        let r = rot.nrows();
        let p = self.eigenvalues.len();
        // equal to round-off (a symmetric body's pairs): the turn leaves them as they are
        let uniform = |v: &[f64]| {
            let size = v.iter().fold(0.0f64, |a, x| a.max(x.abs()));
            v.iter().all(|&x| (x - v[0]).abs() <= 1e-10 * size)
        };
        let block = start..start + r;
        if self.stiffness_matrix.is_none()
            && self.damping_matrix.is_none()
            && uniform(&self.eigenvalues[block.clone()])
            && uniform(&self.modal_damping[block])
        {
            return;
        }
        let turn = |a: &DMatrix<f64>| {
            let mut t = DMatrix::<f64>::identity(p, p);
            t.view_mut((start, start), (r, r)).copy_from(rot);
            t.transpose() * a * t
        };
        let full = |given: &Option<Box<DMatrix<f64>>>, diagonal: &[f64]| {
            given.as_deref().cloned().unwrap_or_else(|| {
                DMatrix::from_diagonal(&nalgebra::DVector::from_row_slice(diagonal))
            })
        };
        let k = turn(&full(&self.stiffness_matrix, &self.eigenvalues));
        let c = turn(&full(&self.damping_matrix, &self.modal_damping));
        self.eigenvalues = k.diagonal().iter().copied().collect();
        self.modal_damping = c.diagonal().iter().copied().collect();
        self.stiffness_matrix = Some(Box::new(k));
        self.damping_matrix = Some(Box::new(c));
    }
}
