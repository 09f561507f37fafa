//! Derivatives of eigenvalues and mass-normalised eigenvectors (paper §4.4).
//!
//! For a design variable `b` with `K_b`, `M_b` (assembled from dual numbers, [`crate::Assembly`]):
//! - distinct eigenvalue: `λ_b = xᵀ(K_b − λM_b)x`; Nelson's method (1976): the particular
//!   solution `v` of `(K − λM)v = −(K_b − λM_b − λ_b M)x` with the component of largest `|x_k|`
//!   set to zero (row and column `k` of `K − λM` replaced by the identity, which keeps the sparse
//!   pattern), then `x_b = v + c x`, `c = −xᵀMv − ½ xᵀM_b x`;
//! - repeated eigenvalues (a cluster of `r`): only directional derivatives exist. The cluster
//!   basis `Z` is rotated to `ZΓ`, the eigenvectors of `D = Zᵀ(K_b − λM_b)Z` (Dailey 1989); the
//!   `λ_b` are the eigenvalues of `D`; the eigenvector derivatives use `r` removed components
//!   and the coupling coefficients `c_ij` of Dailey, which need second derivatives
//!   `Zᵀ(K_bb − λ M_bb)Z` ([`SecondDerivatives`]); without them those terms are omitted.

use faer::Mat;
use faer::sparse::SparseColMat;
use faer::sparse::linalg::solvers::{Lu, SymbolicLu};
use nalgebra::DMatrix;
use sens::LinearSolver;

pub use crate::eigen::{CLUSTER_RTOL, clusters};
use crate::eigen::{Eigenpairs, project, spmv};
use crate::error::FemError;

/// Derivative matrices for one design variable.
#[derive(Clone, Debug)]
pub struct DesignMatrices {
    /// `∂K/∂b`: the entries of the assembly pattern it moves.
    pub k: SparseColMat<usize, f64>,
    /// `∂M/∂b`: the entries of the assembly pattern it moves (none for ply angles).
    pub m: SparseColMat<usize, f64>,
}

/// Projected second derivatives `Zᵀ(K_bb − λ M_bb)Z` of a cluster, for Dailey's coupling terms.
pub type SecondDerivatives = DMatrix<f64>;

/// Eigenvalue (and optionally eigenvector) derivatives for every design variable.
#[derive(Clone, Debug)]
pub struct ModeDerivatives {
    /// `λ_b[var][mode]`.
    pub eigenvalues: Vec<Vec<f64>>,
    /// `X_b[var]` (`n × p`), when eigenvector derivatives were requested. Within a cluster of
    /// repeated eigenvalues these belong to the rotated basis [`Self::rotations`].
    pub eigenvectors: Option<Vec<DMatrix<f64>>>,
    /// For each variable, the `p × p` block-diagonal rotation `Γ` of the mode basis (identity
    /// outside clusters): the derivatives refer to the modes `X Γ`.
    pub rotations: Vec<DMatrix<f64>>,
    /// The clusters of repeated eigenvalues (indices into the modes).
    pub clusters: Vec<Vec<usize>>,
    /// The eigenvector derivatives are left to the adjoint method (`eigenvectors` is `None`):
    /// an updated-mode dual body made from these derivatives leaves their part out of its
    /// tangents ([`crate::modal_body_dual`]), and [`crate::eigenvector_adjoints`] with
    /// [`eigenvector_adjoint`] contract it.
    pub eigenvectors_by_adjoint: bool,
}

enum Factor {
    Dense(faer::linalg::solvers::PartialPivLu<f64>),
    Sparse(Lu<usize, f64>),
    Ldlt(SparseLdlt),
}

impl Factor {
    fn solve(&self, rhs: &mut [f64]) {
        match self {
            Factor::Dense(f) => f.solve_columns(rhs, 1),
            Factor::Sparse(f) => f.solve_columns(rhs, 1),
            Factor::Ldlt(f) => f.solve(rhs),
        }
    }
}

/// Sparse symmetric `LDLᵀ` (faer's supernodal factorisation, no pivoting) of the symmetric
/// indefinite Nelson matrix: about as fast as a Cholesky factorisation and several times faster
/// than a sparse LU. Without pivoting it can meet a tiny pivot; every solve is therefore
/// checked by its residual and the caller falls back to LU when it is poor.
struct SparseLdlt {
    symbolic: std::sync::Arc<faer::sparse::linalg::cholesky::SymbolicCholesky<usize>>,
    values: Vec<f64>,
}

impl SparseLdlt {
    fn symbolic(
        a: &SparseColMat<usize, f64>,
    ) -> Result<std::sync::Arc<faer::sparse::linalg::cholesky::SymbolicCholesky<usize>>, FemError>
    {
        faer::sparse::linalg::cholesky::factorize_symbolic_cholesky(
            a.symbolic(),
            faer::Side::Lower,
            Default::default(),
            Default::default(),
        )
        .map(std::sync::Arc::new)
        .map_err(|e| FemError::Eigen(format!("symbolic LDLᵀ: {e:?}")))
    }

    fn new(
        symbolic: std::sync::Arc<faer::sparse::linalg::cholesky::SymbolicCholesky<usize>>,
        a: &SparseColMat<usize, f64>,
    ) -> Option<Self> {
        let par = faer::Par::Seq;
        let mut values = vec![0.0; symbolic.len_val()];
        let req = symbolic.factorize_numeric_ldlt_scratch::<f64>(par, Default::default());
        let mut mem = faer::dyn_stack::MemBuffer::new(req);
        let stack = faer::dyn_stack::MemStack::new(&mut mem);
        symbolic
            .factorize_numeric_ldlt(
                &mut values,
                a.as_ref(),
                faer::Side::Lower,
                Default::default(),
                par,
                stack,
                Default::default(),
            )
            .ok()?;
        if values.iter().any(|v| !v.is_finite()) {
            return None;
        }
        Some(Self { symbolic, values })
    }

    fn solve(&self, rhs: &mut [f64]) {
        let par = faer::Par::Seq;
        let n = rhs.len();
        let req = self.symbolic.solve_in_place_scratch::<f64>(1, par);
        let mut mem = faer::dyn_stack::MemBuffer::new(req);
        let stack = faer::dyn_stack::MemStack::new(&mut mem);
        let ldlt = faer::sparse::linalg::cholesky::LdltRef::new(&self.symbolic, &self.values);
        ldlt.solve_in_place_with_conj(
            faer::Conj::No,
            faer::MatMut::from_column_major_slice_mut(rhs, n, 1),
            par,
            stack,
        );
    }
}

/// `K − λM` with rows and columns `removed` replaced by the identity.
fn nelson_matrix(
    k: &SparseColMat<usize, f64>,
    m: &SparseColMat<usize, f64>,
    lambda: f64,
    removed: &[usize],
) -> SparseColMat<usize, f64> {
    let cp = k.symbolic().col_ptr();
    let ri = k.symbolic().row_idx();
    let mut val: Vec<f64> = k
        .val()
        .iter()
        .zip(m.val())
        .map(|(a, b)| a - lambda * b)
        .collect();
    let mut is_removed = vec![false; k.nrows()];
    for &r in removed {
        is_removed[r] = true;
    }
    for j in 0..k.ncols() {
        for p in cp[j]..cp[j + 1] {
            let i = ri[p];
            if is_removed[i] || is_removed[j] {
                val[p] = if i == j { 1.0 } else { 0.0 };
            }
        }
    }
    SparseColMat::new(k.symbolic().to_owned().expect("pattern copy"), val)
}

/// `r` rows of `z` (n × r) forming a well-conditioned `r × r` block (greedy pivoting).
fn pivot_rows(z: &DMatrix<f64>) -> Vec<usize> {
    let mut a = z.clone();
    let r = a.ncols();
    let mut rows = Vec::with_capacity(r);
    for c in 0..r {
        // pick the largest remaining entry over columns c.. and all unused rows
        let mut best = (0, c, -1.0);
        for j in c..r {
            for i in 0..a.nrows() {
                if rows.contains(&i) {
                    continue;
                }
                if a[(i, j)].abs() > best.2 {
                    best = (i, j, a[(i, j)].abs());
                }
            }
        }
        let (i, j, _) = best;
        a.swap_columns(c, j);
        rows.push(i);
        // eliminate row i from the other columns
        let piv = a[(i, c)];
        for jj in c + 1..r {
            let f = a[(i, jj)] / piv;
            for ii in 0..a.nrows() {
                let t = a[(ii, c)];
                a[(ii, jj)] -= f * t;
            }
        }
    }
    rows
}

/// Derivatives of the eigenpairs `modes` of `(k, m)` for each design variable in `design`.
///
/// `eigenvectors`: also compute `X_b` (Nelson / Dailey); `dense`: factorise `K − λM` densely
/// (small models) instead of with faer's sparse LU. `second[var][cluster]`, when given,
/// supplies Dailey's second-derivative terms for clusters.
pub fn mode_derivatives(
    k: &SparseColMat<usize, f64>,
    m: &SparseColMat<usize, f64>,
    modes: &Eigenpairs,
    design: &[DesignMatrices],
    eigenvectors: bool,
    second: Option<&[Vec<SecondDerivatives>]>,
) -> Result<ModeDerivatives, FemError> {
    let dense = k.nrows() <= crate::eigen::DENSE_LIMIT;
    mode_derivatives_with(k, m, modes, design, eigenvectors, second, dense)
}

/// [`mode_derivatives`] with the factorisation of the Nelson matrices chosen explicitly:
/// `dense` (faer dense LU) or sparse (faer supernodal `LDLᵀ`, residual-checked, sparse LU as
/// fallback).
pub fn mode_derivatives_with(
    k: &SparseColMat<usize, f64>,
    m: &SparseColMat<usize, f64>,
    modes: &Eigenpairs,
    design: &[DesignMatrices],
    eigenvectors: bool,
    second: Option<&[Vec<SecondDerivatives>]>,
    dense: bool,
) -> Result<ModeDerivatives, FemError> {
    let n = k.nrows();
    let p = modes.values.len();
    let groups = clusters(&modes.values, CLUSTER_RTOL);
    let nvar = design.len();
    let mut lam_b = vec![vec![0.0; p]; nvar];
    let mut rot = vec![DMatrix::<f64>::identity(p, p); nvar];
    let mut x_b = if eigenvectors {
        Some(vec![DMatrix::<f64>::zeros(n, p); nvar])
    } else {
        None
    };
    let symbolic_ldlt = if eigenvectors && !dense {
        Some(SparseLdlt::symbolic(k)?)
    } else {
        None
    };
    let mut symbolic_lu: Option<SymbolicLu<usize>> = None;
    let mut tmp = vec![0.0; n];
    for (gi, g) in groups.iter().enumerate() {
        let (lambda, z) = cluster_basis(modes, g);
        // per-variable projected derivative and rotation
        let mut per_var = Vec::with_capacity(nvar);
        for (v, dm) in design.iter().enumerate() {
            let d = ClusterDerivative::of(dm, &z, lambda);
            store_cluster(g, &d.values, &d.rotation, &mut lam_b[v], &mut rot[v]);
            per_var.push(d);
        }
        let Some(xb) = x_b.as_mut() else { continue };
        let mut nelson = NelsonSystem::new(
            k,
            m,
            lambda,
            &z,
            dense,
            symbolic_ldlt.as_ref(),
            &mut symbolic_lu,
        )?;
        for (v, dm) in design.iter().enumerate() {
            let sec = second.and_then(|s| s.get(v)).and_then(|s| s.get(gi));
            let xv = nelson.derivatives(m, dm, (lambda, &z), &per_var[v], sec, &mut tmp)?;
            for (a, &i) in g.iter().enumerate() {
                xb[v].column_mut(i).copy_from(&xv.column(a));
            }
        }
    }
    Ok(ModeDerivatives {
        eigenvalues: lam_b,
        eigenvectors: x_b,
        rotations: rot,
        clusters: groups,
        eigenvectors_by_adjoint: false,
    })
}

/// `Σ_i ȳ_iᵀ ∂x_i/∂b` for every design variable of `design`: the eigenvector derivatives of
/// [`mode_derivatives`] contracted with the adjoints `ybar` (`n × p`, one column per mode of
/// `modes`; within a cluster of repeated eigenvalues against the derivatives in the basis of
/// the values, `X_b Γᵀ`, as [`crate::modal_body_dual`] reads them), without one solve per mode
/// and variable (docs/design.md §3, "The adjoint method"). For a distinct eigenvalue `λ` with
/// eigenvector `x`, Nelson's `x_b = v + c x` (`A v = f`, `c = −xᵀMv − ½ xᵀM_b x`) gives, with
/// `s = ȳᵀx` and the Nelson matrix `A` symmetric, `ȳᵀx_b = wᵀf − ½ s xᵀM_b x` for
/// `w = A⁻¹(ȳ − s M x)`: one solve per mode, then per variable
/// `−wᵀ(K_b − λM_b)x + λ_b wᵀMx − ½ s xᵀM_b x` (`w`'s removed component zero). A cluster's
/// derivatives depend on each variable through its rotation `Γ`: they are formed variable by
/// variable, as [`mode_derivatives`] does. Modes whose adjoint is zero cost nothing.
pub fn eigenvector_adjoint(
    k: &SparseColMat<usize, f64>,
    m: &SparseColMat<usize, f64>,
    modes: &Eigenpairs,
    design: &[DesignMatrices],
    ybar: &DMatrix<f64>,
    second: Option<&[Vec<SecondDerivatives>]>,
) -> Result<Vec<f64>, FemError> {
    let n = k.nrows();
    assert_eq!(
        ybar.shape(),
        (n, modes.values.len()),
        "one adjoint per mode"
    );
    let dense = n <= crate::eigen::DENSE_LIMIT;
    let symbolic_ldlt = if dense {
        None
    } else {
        Some(SparseLdlt::symbolic(k)?)
    };
    let mut symbolic_lu: Option<SymbolicLu<usize>> = None;
    let mut out = vec![0.0; design.len()];
    let (mut tmp, mut kx, mut mx) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    for (gi, g) in clusters(&modes.values, CLUSTER_RTOL).iter().enumerate() {
        if g.iter().all(|&i| ybar.column(i).iter().all(|&y| y == 0.0)) {
            continue;
        }
        let (lambda, z) = cluster_basis(modes, g);
        let nelson = NelsonSystem::new(
            k,
            m,
            lambda,
            &z,
            dense,
            symbolic_ldlt.as_ref(),
            &mut symbolic_lu,
        );
        let mut nelson = nelson?;
        if g.len() > 1 {
            let yg = ybar.select_columns(g);
            for (v, dm) in design.iter().enumerate() {
                let d = ClusterDerivative::of(dm, &z, lambda);
                let sec = second.and_then(|s| s.get(v)).and_then(|s| s.get(gi));
                let xv = nelson.derivatives(m, dm, (lambda, &z), &d, sec, &mut tmp)?;
                out[v] += (xv * d.rotation.transpose()).dot(&yg);
            }
            continue;
        }
        let x = z.column(0);
        let y = ybar.column(g[0]);
        let s = y.dot(&x);
        spmv(m, x.as_slice(), &mut mx);
        let mut w: Vec<f64> = y.iter().zip(&mx).map(|(y, mx)| y - s * mx).collect();
        for &q in &nelson.removed {
            w[q] = 0.0;
        }
        nelson.solve_checked(&mut w, &mut tmp)?;
        for &q in &nelson.removed {
            w[q] = 0.0;
        }
        let w_mx: f64 = w.iter().zip(&mx).map(|(a, b)| a * b).sum();
        for (v, dm) in design.iter().enumerate() {
            spmv(&dm.k, x.as_slice(), &mut kx);
            spmv(&dm.m, x.as_slice(), &mut tmp);
            let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(a, b)| a * b).sum::<f64>();
            let x_mb_x = dot(x.as_slice(), &tmp);
            let lambda_b = dot(x.as_slice(), &kx) - lambda * x_mb_x;
            out[v] += -dot(&w, &kx) + lambda * dot(&w, &tmp) + lambda_b * w_mx - 0.5 * s * x_mb_x;
        }
    }
    Ok(out)
}

/// The derivative of a cluster of eigenvalues for one design variable.
struct ClusterDerivative {
    /// The eigenvalue derivatives `λ_b`, ascending.
    values: Vec<f64>,
    /// The rotation `Γ` of the cluster's basis `Z` they belong to.
    rotation: DMatrix<f64>,
    /// `Zᵀ M_b Z` in the unrotated basis.
    mb: DMatrix<f64>,
}

impl ClusterDerivative {
    /// The derivative for the design variable `dm` of the cluster with basis `z` and
    /// eigenvalue `lambda` ([`cluster_derivative`] of the projected `K_b`, `M_b`).
    fn of(dm: &DesignMatrices, z: &DMatrix<f64>, lambda: f64) -> Self {
        let kb = project(&dm.k, z, z);
        let mb = project(&dm.m, z, z);
        let (values, rotation) = cluster_derivative(&kb, &mb, lambda);
        Self {
            values,
            rotation,
            mb,
        }
    }
}

/// The Nelson system `(K − λM) v = f` of one cluster, rows and columns of its removed
/// components replaced by the identity, factorised once for every design variable.
struct NelsonSystem<'s> {
    /// The removed components, one per mode of the cluster.
    removed: Vec<usize>,
    /// The Nelson matrix.
    a: SparseColMat<usize, f64>,
    factor: Factor,
    /// Whether a solve with the sparse `LDLᵀ` factor has been checked by its residual.
    checked: bool,
    /// The symbolic sparse LU shared by the clusters, for the fallback.
    symbolic_lu: &'s mut Option<SymbolicLu<usize>>,
}

impl<'s> NelsonSystem<'s> {
    /// Factorise the Nelson matrix of the cluster with eigenvalue `lambda` and basis `z`:
    /// dense LU when `dense`, else sparse `LDLᵀ` on `symbolic_ldlt` (sparse LU if it fails).
    fn new(
        k: &SparseColMat<usize, f64>,
        m: &SparseColMat<usize, f64>,
        lambda: f64,
        z: &DMatrix<f64>,
        dense: bool,
        symbolic_ldlt: Option<
            &std::sync::Arc<faer::sparse::linalg::cholesky::SymbolicCholesky<usize>>,
        >,
        symbolic_lu: &'s mut Option<SymbolicLu<usize>>,
    ) -> Result<Self, FemError> {
        let n = k.nrows();
        let removed = pivot_rows(z);
        let a = nelson_matrix(k, m, lambda, &removed);
        let factor = if dense {
            let ad = Mat::from_fn(n, n, |_, _| 0.0);
            let mut ad = ad;
            let cp = a.symbolic().col_ptr();
            let ri = a.symbolic().row_idx();
            for j in 0..n {
                for q in cp[j]..cp[j + 1] {
                    ad[(ri[q], j)] += a.val()[q];
                }
            }
            Factor::Dense(ad.partial_piv_lu())
        } else {
            match SparseLdlt::new(symbolic_ldlt.expect("symbolic LDLᵀ").clone(), &a) {
                Some(f) => Factor::Ldlt(f),
                None => sparse_lu(&a, symbolic_lu)?,
            }
        };
        Ok(Self {
            removed,
            a,
            factor,
            checked: false,
            symbolic_lu,
        })
    }

    /// The derivatives of the cluster's eigenvectors (basis `z`, eigenvalue `lambda`) for the
    /// design variable `dm` with eigenvalue derivatives and rotation `d`: `V + ZΓ c`, in the
    /// rotated basis `ZΓ`.
    fn derivatives(
        &mut self,
        m: &SparseColMat<usize, f64>,
        dm: &DesignMatrices,
        (lambda, z): (f64, &DMatrix<f64>),
        d: &ClusterDerivative,
        second: Option<&SecondDerivatives>,
        tmp: &mut [f64],
    ) -> Result<DMatrix<f64>, FemError> {
        let zr = z * &d.rotation;
        let vs = self.particular_solutions(m, dm, lambda, &zr, &d.values, tmp)?;
        let c = eigenvector_coefficients(m, dm, lambda, &zr, &vs, d, second);
        Ok(vs + &zr * c)
    }

    /// Nelson's particular solutions `V` (n × r) of the design variable `dm` for the rotated
    /// cluster basis `zr` with eigenvalue `lambda` and derivatives `values`; `tmp`: n scratch.
    fn particular_solutions(
        &mut self,
        m: &SparseColMat<usize, f64>,
        dm: &DesignMatrices,
        lambda: f64,
        zr: &DMatrix<f64>,
        values: &[f64],
        tmp: &mut [f64],
    ) -> Result<DMatrix<f64>, FemError> {
        let (n, r) = (zr.nrows(), zr.ncols());
        let mut vs = DMatrix::<f64>::zeros(n, r);
        for j in 0..r {
            // f = −(K_b − λ M_b − λ_b M) z_j
            let zj = zr.column(j);
            let mut f = vec![0.0; n];
            spmv(&dm.k, zj.as_slice(), tmp);
            axpy(-1.0, tmp, &mut f);
            spmv(&dm.m, zj.as_slice(), tmp);
            axpy(lambda, tmp, &mut f);
            spmv(m, zj.as_slice(), tmp);
            axpy(values[j], tmp, &mut f);
            for &q in &self.removed {
                f[q] = 0.0;
            }
            self.solve_checked(&mut f, tmp)?;
            vs.column_mut(j).copy_from_slice(&f);
        }
        Ok(vs)
    }

    /// `f ← A⁻¹ f`. The first solve with a sparse `LDLᵀ` factor is checked by its residual;
    /// a poorly pivoted factor is replaced by a sparse LU one, for this and later solves.
    fn solve_checked(&mut self, f: &mut [f64], tmp: &mut [f64]) -> Result<(), FemError> {
        let rhs = f.to_vec();
        self.factor.solve(f);
        if !self.checked && matches!(self.factor, Factor::Ldlt(_)) {
            self.checked = true;
            spmv(&self.a, f, tmp);
            let num: f64 = tmp
                .iter()
                .zip(&rhs)
                .map(|(x, y)| (x - y).powi(2))
                .sum::<f64>()
                .sqrt();
            let den: f64 = rhs.iter().map(|y| y * y).sum::<f64>().sqrt();
            if !(num <= 1e-8 * den) {
                self.factor = sparse_lu(&self.a, self.symbolic_lu)?;
                f.copy_from_slice(&rhs);
                self.factor.solve(f);
            }
        }
        Ok(())
    }
}

/// The coefficients `c` (r × r) of `x_b = V + Z c` in the rotated cluster basis `zr`, `V` the
/// particular solutions `vs`: normalisation terms, and Dailey's coupling terms within a cluster
/// (with the projected second derivatives `second`, unrotated, when given).
fn eigenvector_coefficients(
    m: &SparseColMat<usize, f64>,
    dm: &DesignMatrices,
    lambda: f64,
    zr: &DMatrix<f64>,
    vs: &DMatrix<f64>,
    derivative: &ClusterDerivative,
    second: Option<&SecondDerivatives>,
) -> DMatrix<f64> {
    let (vals, gam, mb) = (&derivative.values, &derivative.rotation, &derivative.mb);
    let r = zr.ncols();
    let mv = project(m, zr, vs); // Zᵀ M V
    let mbr = gam.transpose() * mb * gam; // Zᵀ M_b Z (rotated)
    let mut c = DMatrix::<f64>::zeros(r, r);
    for j in 0..r {
        c[(j, j)] = -mv[(j, j)] - 0.5 * mbr[(j, j)];
    }
    if r > 1 {
        let kbv = project(&dm.k, zr, vs);
        let mbv = project(&dm.m, zr, vs);
        let sec = second.map(|s| gam.transpose() * s * gam);
        for i in 0..r {
            for j in 0..r {
                if i == j {
                    continue;
                }
                let gap = vals[j] - vals[i];
                if gap.abs() <= 1e-12 * vals.iter().fold(0.0f64, |a, b| a.max(b.abs())).max(1e-300)
                {
                    // the cluster stays together: the first-order equations leave the
                    // rotation within it free; take none, so that `Zᵀ M x_b` keeps only
                    // the symmetric part the normalisation fixes, `−Zᵀ M_b Z / 2` (the
                    // convention of mode tracking, `ModalBody::align_to`)
                    c[(i, j)] = -mv[(i, j)] - 0.5 * mbr[(i, j)];
                    continue;
                }
                let mut num = kbv[(i, j)] - vals[j] * mv[(i, j)] - lambda * mbv[(i, j)];
                num -= vals[j] * mbr[(i, j)];
                if let Some(s) = &sec {
                    num += 0.5 * s[(i, j)];
                }
                c[(i, j)] = num / gap;
            }
        }
    }
    c
}

/// The eigenvalue derivatives of a cluster of eigenvalues `λ` (one or repeated) with the
/// projected derivative matrices `kb = Zᵀ K_b Z`, `mb = Zᵀ M_b Z`: the eigenvalues of
/// `kb − λ mb` in increasing order and the rotation `Γ` of the cluster's basis they belong to
/// (identity for a single eigenvalue, or when the change keeps the cluster together).
fn cluster_derivative(
    kb: &DMatrix<f64>,
    mb: &DMatrix<f64>,
    lambda: f64,
) -> (Vec<f64>, DMatrix<f64>) {
    let r = kb.nrows();
    let d = kb - mb * lambda;
    let d = (&d + d.transpose()) * 0.5;
    if r == 1 {
        return (vec![d[(0, 0)]], DMatrix::identity(1, 1));
    }
    let e = d.symmetric_eigen();
    let mut order: Vec<usize> = (0..r).collect();
    order.sort_by(|&a, &b| e.eigenvalues[a].total_cmp(&e.eigenvalues[b]));
    let vals: Vec<f64> = order.iter().map(|&i| e.eigenvalues[i]).collect();
    let spread = vals[r - 1] - vals[0];
    let scale = vals.iter().fold(0.0f64, |a, b| a.max(b.abs()));
    if spread <= 1e-9 * scale + 1e-14 * lambda.abs() {
        // the change keeps the cluster together (e.g. a symmetric design change of a
        // symmetric body): no rotation is singled out, keep the basis as it is
        let mean = vals.iter().sum::<f64>() / r as f64;
        (vec![mean; r], DMatrix::identity(r, r))
    } else {
        (
            vals,
            DMatrix::from_fn(r, r, |i, j| e.eigenvectors[(i, order[j])]),
        )
    }
}

/// Write a cluster's eigenvalue derivatives and rotation into the per-mode arrays.
fn store_cluster(
    g: &[usize],
    vals: &[f64],
    gam: &DMatrix<f64>,
    lam_b: &mut [f64],
    rot: &mut DMatrix<f64>,
) {
    for (a, &i) in g.iter().enumerate() {
        lam_b[i] = vals[a];
        for (b, &j) in g.iter().enumerate() {
            rot[(i, j)] = gam[(a, b)];
        }
    }
}

/// A design variable's derivative matrices projected on the modes `X`: `Xᵀ K_b X` and
/// `Xᵀ M_b X` (`p × p`; from [`crate::Assembly::projected_tangents`], within the blocks it was
/// asked for).
#[derive(Clone, Debug, PartialEq)]
pub struct ProjectedDerivative {
    pub k: DMatrix<f64>,
    pub m: DMatrix<f64>,
}

/// The eigenvalue derivatives alone (no eigenvectors'), from the derivative matrices projected
/// on the modes, one [`ProjectedDerivative`] per variable
/// ([`crate::Assembly::projected_tangents`], which never assembles `K_b`; only the blocks of
/// the clusters of `modes`, [`clusters`] with [`CLUSTER_RTOL`], are read). Equal to those of
/// [`mode_derivatives`].
pub fn eigenvalue_derivatives(
    modes: &Eigenpairs,
    projected: &[ProjectedDerivative],
) -> ModeDerivatives {
    let p = modes.values.len();
    let groups = clusters(&modes.values, CLUSTER_RTOL);
    let nvar = projected.len();
    let mut lam_b = vec![vec![0.0; p]; nvar];
    let mut rot = vec![DMatrix::<f64>::identity(p, p); nvar];
    for g in &groups {
        let (r, lambda) = (g.len(), cluster_mean(modes, g));
        for (v, pd) in projected.iter().enumerate() {
            let kb = DMatrix::from_fn(r, r, |a, b| pd.k[(g[a], g[b])]);
            let mb = DMatrix::from_fn(r, r, |a, b| pd.m[(g[a], g[b])]);
            let (vals, gam) = cluster_derivative(&kb, &mb, lambda);
            store_cluster(g, &vals, &gam, &mut lam_b[v], &mut rot[v]);
        }
    }
    ModeDerivatives {
        eigenvalues: lam_b,
        eigenvectors: None,
        rotations: rot,
        clusters: groups,
        eigenvectors_by_adjoint: false,
    }
}

fn sparse_lu(
    a: &SparseColMat<usize, f64>,
    symbolic: &mut Option<SymbolicLu<usize>>,
) -> Result<Factor, FemError> {
    if symbolic.is_none() {
        *symbolic =
            Some(SymbolicLu::try_new(a.symbolic()).map_err(|e| FemError::Eigen(format!("{e:?}")))?);
    }
    let lu = Lu::try_new_with_symbolic(symbolic.clone().expect("set above"), a.as_ref())
        .map_err(|e| FemError::Eigen(format!("Nelson factorisation: {e:?}")))?;
    Ok(Factor::Sparse(lu))
}

fn axpy(a: f64, x: &[f64], y: &mut [f64]) {
    y.iter_mut().zip(x).for_each(|(yi, xi)| *yi += a * xi);
}

/// Directional derivative of the eigenvalues along `direction` (one weight per design
/// variable): within clusters, the eigenvalues of `Σ_k d_k Zᵀ(K_{b_k} − λM_{b_k})Z`, ascending
/// (the one-sided derivatives of the sorted eigenvalues for a step along `+direction`).
pub fn directional_eigenvalue_derivatives(
    modes: &Eigenpairs,
    design: &[DesignMatrices],
    direction: &[f64],
) -> Vec<f64> {
    assert_eq!(
        design.len(),
        direction.len(),
        "one weight per design variable"
    );
    let mut out = vec![0.0; modes.values.len()];
    for g in clusters(&modes.values, CLUSTER_RTOL) {
        let r = g.len();
        let (lambda, z) = cluster_basis(modes, &g);
        let mut d = DMatrix::<f64>::zeros(r, r);
        for (dm, &w) in design.iter().zip(direction) {
            if w != 0.0 {
                d += (project(&dm.k, &z, &z) - project(&dm.m, &z, &z) * lambda) * w;
            }
        }
        let d = (&d + d.transpose()) * 0.5;
        let mut e: Vec<f64> = d.symmetric_eigen().eigenvalues.iter().copied().collect();
        e.sort_by(f64::total_cmp);
        for (a, &i) in g.iter().enumerate() {
            out[i] = e[a];
        }
    }
    out
}

/// Dailey's second-derivative terms `Zᵀ(K_bb − λM_bb)Z` of every cluster of repeated
/// eigenvalues (`[var][cluster]`, 0×0 for distinct eigenvalues), by central differences of the
/// exact first derivatives: `plus[v]`, `minus[v]` are `K_b`, `M_b` of variable `v` evaluated at
/// `b ± h[v] e_v`. Truncation error O(h²) on top of the exact first derivatives.
pub fn cluster_second_derivatives(
    modes: &Eigenpairs,
    plus: &[DesignMatrices],
    minus: &[DesignMatrices],
    h: &[f64],
) -> Vec<Vec<SecondDerivatives>> {
    let groups = clusters(&modes.values, CLUSTER_RTOL);
    plus.iter()
        .zip(minus)
        .zip(h)
        .map(|((p, q), &h)| {
            groups
                .iter()
                .map(|g| {
                    let r = g.len();
                    if r == 1 {
                        return DMatrix::zeros(0, 0);
                    }
                    let (lambda, z) = cluster_basis(modes, g);
                    let dk = project(&p.k, &z, &z) - project(&q.k, &z, &z);
                    let dm = project(&p.m, &z, &z) - project(&q.m, &z, &z);
                    let s = (dk - dm * lambda) / (2.0 * h);
                    (&s + s.transpose()) * 0.5
                })
                .collect()
        })
        .collect()
}

/// The mean eigenvalue of the cluster `g` (indices into the modes of `modes`).
fn cluster_mean(modes: &Eigenpairs, g: &[usize]) -> f64 {
    g.iter().map(|&i| modes.values[i]).sum::<f64>() / g.len() as f64
}

/// The cluster `g`'s mean eigenvalue `λ` and basis `Z` (its eigenvectors as columns).
fn cluster_basis(modes: &Eigenpairs, g: &[usize]) -> (f64, DMatrix<f64>) {
    let z = DMatrix::from_fn(modes.vectors.nrows(), g.len(), |i, j| {
        modes.vectors[(i, g[j])]
    });
    (cluster_mean(modes, g), z)
}

/// Whether any cluster of repeated eigenvalues has more than one member.
pub fn has_repeated(modes: &Eigenpairs) -> bool {
    clusters(&modes.values, CLUSTER_RTOL)
        .iter()
        .any(|g| g.len() > 1)
}

/// For each design variable of `design`, whether its change splits a cluster of repeated
/// eigenvalues of `modes` at first order (the eigenvalues of `Zᵀ(K_b − λM_b)Z` differ). Only
/// those variables' eigenvector derivatives read Dailey's second-derivative terms
/// ([`mode_derivatives`]): a change that keeps every cluster together (a symmetric design change
/// of a symmetric body, such as a ply of a tube whose two halves form the pairs) leaves the
/// rotation within the cluster free and takes none, so its terms need not be computed.
pub fn splits_clusters(modes: &Eigenpairs, design: &[DesignMatrices]) -> Vec<bool> {
    let bases: Vec<(f64, DMatrix<f64>)> = clusters(&modes.values, CLUSTER_RTOL)
        .iter()
        .filter(|g| g.len() > 1)
        .map(|g| cluster_basis(modes, g))
        .collect();
    design
        .iter()
        .map(|dm| {
            bases.iter().any(|(lambda, z)| {
                let (kb, mb) = (project(&dm.k, z, z), project(&dm.m, z, z));
                let (values, _) = cluster_derivative(&kb, &mb, *lambda);
                values.iter().any(|&x| x != values[0])
            })
        })
        .collect()
}
