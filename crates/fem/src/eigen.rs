//! The generalised symmetric eigenproblem `K x = λ M x` for the lowest modes, mass-normalised.
//!
//! Two paths:
//! - dense (small models): Cholesky `K − σM = LLᵀ`, symmetric eigen of `L⁻¹ML⁻ᵀ` (faer);
//! - sparse (large models): shift-invert block Lanczos in the `M` inner product with full
//!   re-orthogonalisation and thick restarts (Krylov–Schur for symmetric problems), on a
//!   sparse Cholesky factorisation of `K − σM` ([`sens::SparseCholesky`], ordered on the node
//!   graph when the caller names the nodes) with a shift `σ` just below zero, so rigid
//!   (zero-frequency) modes are found like any other and `K − σM` stays positive definite.
//!
//! Both end with a Rayleigh–Ritz step on the original `K`, `M`, so that `XᵀMX = I` and
//! `XᵀKX = Λ` hold to round-off.

use faer::sparse::SparseColMat;
use faer::{Mat, Side};
use nalgebra::DMatrix;
use sens::{LinearSolver, SparseCholesky};

use crate::error::FemError;

/// Which eigen solver to use.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum EigenMethod {
    /// Dense for at most [`DENSE_LIMIT`] free dof, sparse Lanczos above.
    #[default]
    Auto,
    Dense,
    Lanczos,
}

/// Largest model solved densely by [`EigenMethod::Auto`]. The dense path computes every
/// eigenpair (its cost grows as n³); shift-invert Lanczos only the few asked for. Measured with
/// `flexsens modes` on the §5.2 plate rod refined from 72 to 720 free dof: equal at 72, Lanczos
/// 1.7 × faster at 144, 3.2 × at 360 and 8.8 × at 720 (11.5 ms against 101 ms), with the same
/// frequencies and frequency derivatives to 5e-13.
pub const DENSE_LIMIT: usize = 100;

/// Eigen solver options.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EigenOptions {
    pub method: EigenMethod,
    /// Relative residual tolerance of the Lanczos Ritz pairs.
    pub tol: f64,
    /// Maximum number of Lanczos restarts.
    pub max_restarts: usize,
    /// Vectors the Lanczos iteration adds at a time; `None`: [`LANCZOS_BLOCK`] on models of
    /// at least [`BLOCK_MIN_DOF`] free dof, one below. The modes do not depend on it beyond
    /// the tolerance.
    pub block: Option<usize>,
}

impl Default for EigenOptions {
    fn default() -> Self {
        Self {
            method: EigenMethod::Auto,
            tol: 1e-11,
            max_restarts: 300,
            block: None,
        }
    }
}

/// Lowest eigenpairs, ascending, mass-normalised.
#[derive(Clone, Debug)]
pub struct Eigenpairs {
    /// `λ_i = ω_i²`.
    pub values: Vec<f64>,
    /// `n × p`, `XᵀMX = I`.
    pub vectors: DMatrix<f64>,
}

/// `y = A x` for a CSC matrix.
pub fn spmv(a: &SparseColMat<usize, f64>, x: &[f64], y: &mut [f64]) {
    y.iter_mut().for_each(|v| *v = 0.0);
    let cp = a.symbolic().col_ptr();
    let ri = a.symbolic().row_idx();
    let val = a.val();
    for j in 0..a.ncols() {
        let xj = x[j];
        if xj == 0.0 {
            continue;
        }
        for p in cp[j]..cp[j + 1] {
            y[ri[p]] += val[p] * xj;
        }
    }
}

/// `Y = A X` for a CSC matrix and `cols` column-major columns of `n` entries: the matrix is read
/// once for all of them.
pub fn spmv_columns(a: &SparseColMat<usize, f64>, x: &[f64], y: &mut [f64], cols: usize) {
    let n = a.nrows();
    assert!(
        x.len() == a.ncols() * cols && y.len() == n * cols,
        "spmv_columns: sizes"
    );
    y.iter_mut().for_each(|v| *v = 0.0);
    let cp = a.symbolic().col_ptr();
    let ri = a.symbolic().row_idx();
    let val = a.val();
    for j in 0..a.ncols() {
        for p in cp[j]..cp[j + 1] {
            let (i, v) = (ri[p], val[p]);
            for c in 0..cols {
                y[c * n + i] += v * x[c * a.ncols() + j];
            }
        }
    }
}

/// `a` without its stored zeros (a consistent shell mass on the stiffness pattern stores the
/// translation–rotation couplings as zeros; a variable of one segment or region moves the
/// entries of its elements alone): the same products at a fraction of the reads and memory.
pub(crate) fn without_zeros(a: &SparseColMat<usize, f64>) -> SparseColMat<usize, f64> {
    let cp = a.symbolic().col_ptr();
    let ri = a.symbolic().row_idx();
    let val = a.val();
    let mut ptr = Vec::with_capacity(a.ncols() + 1);
    let (mut idx, mut v) = (Vec::new(), Vec::new());
    ptr.push(0);
    for j in 0..a.ncols() {
        for p in cp[j]..cp[j + 1] {
            if val[p] != 0.0 {
                idx.push(ri[p]);
                v.push(val[p]);
            }
        }
        ptr.push(idx.len());
    }
    let pattern =
        faer::sparse::SymbolicSparseColMat::new_checked(a.nrows(), a.ncols(), ptr, None, idx);
    SparseColMat::new(pattern, v)
}

/// `Xᵀ A Y` for a sparse `A` and dense `X`, `Y`.
pub fn project(a: &SparseColMat<usize, f64>, x: &DMatrix<f64>, y: &DMatrix<f64>) -> DMatrix<f64> {
    let n = a.nrows();
    let mut ay = DMatrix::zeros(n, y.ncols());
    let mut tmp = vec![0.0; n];
    for j in 0..y.ncols() {
        spmv(a, y.column(j).as_slice(), &mut tmp);
        ay.column_mut(j).copy_from_slice(&tmp);
    }
    x.transpose() * ay
}

fn dense(a: &SparseColMat<usize, f64>) -> Mat<f64> {
    let n = a.nrows();
    let mut m = Mat::zeros(n, a.ncols());
    let cp = a.symbolic().col_ptr();
    let ri = a.symbolic().row_idx();
    for j in 0..a.ncols() {
        for p in cp[j]..cp[j + 1] {
            m[(ri[p], j)] += a.val()[p];
        }
    }
    m
}

/// Values of `a + c b` for two matrices on the same pattern.
pub fn combine(
    a: &SparseColMat<usize, f64>,
    c: f64,
    b: &SparseColMat<usize, f64>,
) -> SparseColMat<usize, f64> {
    assert_eq!(
        a.val().len(),
        b.val().len(),
        "matrices on different patterns"
    );
    let v = a
        .val()
        .iter()
        .zip(b.val())
        .map(|(x, y)| x + c * y)
        .collect();
    SparseColMat::new(a.symbolic().to_owned().expect("pattern copy"), v)
}

/// The lowest `p` eigenpairs of `K x = λ M x`.
pub fn lowest_modes(
    k: &SparseColMat<usize, f64>,
    m: &SparseColMat<usize, f64>,
    p: usize,
    opts: &EigenOptions,
) -> Result<Eigenpairs, FemError> {
    lowest_modes_of_nodes(k, m, p, opts, None)
}

/// [`lowest_modes`] of matrices whose unknown `i` belongs to node `node_of[i]` (an
/// assembly's [`free_dof_nodes`](crate::Assembly::free_dof_nodes)): the sparse factorisation
/// is then ordered on the node graph ([`sens::sparse`]), the same fill at a fraction of the
/// ordering's cost. `None` orders the matrix graph.
pub fn lowest_modes_of_nodes(
    k: &SparseColMat<usize, f64>,
    m: &SparseColMat<usize, f64>,
    p: usize,
    opts: &EigenOptions,
    node_of: Option<&[usize]>,
) -> Result<Eigenpairs, FemError> {
    let n = k.nrows();
    if p == 0 || p > n {
        return Err(FemError::Modes(format!(
            "asked for {p} modes of a model with {n} free dof"
        )));
    }
    let use_dense = match opts.method {
        EigenMethod::Dense => true,
        EigenMethod::Lanczos => false,
        EigenMethod::Auto => n <= DENSE_LIMIT,
    };
    let raw = if use_dense {
        match dense_modes(k, m, p) {
            Ok(r) => r,
            Err(_) if opts.method == EigenMethod::Auto => lanczos(k, m, p, opts, node_of)?,
            Err(e) => return Err(e),
        }
    } else {
        lanczos(k, m, p, opts, node_of)?
    };
    rayleigh_ritz(k, m, &raw)
}

/// The first row whose entry of `norms` is within a relative 1e-6 of their largest: a pivot
/// that round-off does not move between rows tied by a symmetry.
fn pivot_row(norms: impl Iterator<Item = f64> + Clone) -> usize {
    let max = norms.clone().fold(0.0, f64::max);
    norms
        .into_iter()
        .position(|v| v >= max * (1.0 - 1e-6))
        .unwrap_or(0)
}

/// Sign every mode, and rotate the modes of every cluster of repeated eigenvalues (relative
/// spread below `rtol`, [`clusters`]) to a basis fixed by their span
/// alone, so that results in modal coordinates do not depend on the basis an eigen solver
/// happened to return (nor change with round-off, as a golden file would see).
///
/// Within a cluster `Z` (`n × r`, M-orthonormal): the first mode is the combination largest
/// at the dof where the span is largest (`i₁ = argmax_i ‖Z_i‖`, mode `Z Z_i₁ᵀ/‖Z_i₁‖`), the
/// next likewise within the rest of the span, and so on; each mode positive at its pivot dof.
/// A pivot is the first dof within a relative 1e-6 of the largest, so dof tied by a symmetry
/// (the two halves of a rod clamped at its middle) do not trade places with round-off; for
/// such a pair the modes come out localised, one on each half. A single mode is only signed
/// by the same rule (an antisymmetric mode's equal and opposite extremes would otherwise give
/// its sign to round-off). The rotation is orthogonal: `XᵀMX = I` and `XᵀKX = Λ` are kept.
pub fn canonical_cluster_bases(pairs: &mut Eigenpairs, rtol: f64) {
    let n = pairs.vectors.nrows();
    for g in clusters(&pairs.values, rtol) {
        let r = g.len();
        let mut z = DMatrix::from_fn(n, r, |i, j| pairs.vectors[(i, g[j])]);
        for k in 0..r {
            let rest = r - k;
            let sub = z.columns(k, rest).into_owned();
            let i1 = pivot_row((0..n).map(|i| sub.row(i).norm()));
            let q = sub.row(i1).transpose() / sub.row(i1).norm();
            // Householder reflection taking e₁ to ∓q: its other columns span q's complement
            let mut v = q.clone();
            v[0] += if q[0] >= 0.0 { 1.0 } else { -1.0 };
            let vv = v.dot(&v);
            let h = DMatrix::<f64>::identity(rest, rest) - (2.0 / vv) * &v * v.transpose();
            let mut rotated = &sub * h;
            // the first column is ∓Z q: positive at its pivot
            if rotated[(i1, 0)] < 0.0 {
                rotated.column_mut(0).neg_mut();
            }
            z.columns_mut(k, rest).copy_from(&rotated);
        }
        for (j, &c) in g.iter().enumerate() {
            pairs.vectors.column_mut(c).copy_from(&z.column(j));
        }
    }
}

/// Rayleigh–Ritz on the span of `x`: returns sorted, `M`-orthonormal pairs.
pub fn rayleigh_ritz(
    k: &SparseColMat<usize, f64>,
    m: &SparseColMat<usize, f64>,
    x: &DMatrix<f64>,
) -> Result<Eigenpairs, FemError> {
    let kr = project(k, x, x);
    let mr = project(m, x, x);
    let kr = (&kr + kr.transpose()) * 0.5;
    let mr = (&mr + mr.transpose()) * 0.5;
    let chol = mr
        .clone()
        .cholesky()
        .ok_or_else(|| FemError::Eigen("Ritz basis is rank deficient in M".into()))?;
    let l = chol.l();
    let linv = l
        .clone()
        .try_inverse()
        .ok_or_else(|| FemError::Eigen("singular Ritz basis".into()))?;
    let c = &linv * kr * linv.transpose();
    let c = (&c + c.transpose()) * 0.5;
    let eig = c.symmetric_eigen();
    let mut order: Vec<usize> = (0..eig.eigenvalues.len()).collect();
    order.sort_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]));
    let y = linv.transpose() * &eig.eigenvectors;
    let mut vectors = DMatrix::zeros(x.nrows(), order.len());
    let mut values = Vec::with_capacity(order.len());
    for (c, &i) in order.iter().enumerate() {
        let v = x * y.column(i);
        // sign convention: the largest-magnitude component positive (the first within a
        // relative 1e-6 of it, as in `canonical_cluster_bases`: equal and opposite extremes
        // do not hand the sign to round-off)
        let imax = pivot_row(v.iter().map(|x| x.abs()));
        let s = if v[imax] < 0.0 { -1.0 } else { 1.0 };
        vectors.column_mut(c).copy_from(&(v * s));
        values.push(eig.eigenvalues[i]);
    }
    Ok(Eigenpairs { values, vectors })
}

fn dense_modes(
    k: &SparseColMat<usize, f64>,
    m: &SparseColMat<usize, f64>,
    p: usize,
) -> Result<DMatrix<f64>, FemError> {
    // shift-invert in dense form: A = K − σM = LLᵀ, C = L⁻¹ M L⁻ᵀ, μ = 1/(λ − σ); the largest μ
    // are the lowest λ and carry relative accuracy even when λ_max/λ_1 is huge (stiff drilling
    // or membrane dof with tiny inertia), unlike a Cholesky of M.
    let n = k.nrows();
    let md = dense(m);
    let mut s = shift_scale(k, m)?;
    let mut factor = None;
    for _ in 0..6 {
        if let Ok(llt) = dense(&combine(k, s, m)).llt(Side::Lower) {
            factor = Some(llt.L().to_owned());
            break;
        }
        s *= 100.0;
    }
    let l = factor.ok_or_else(|| {
        FemError::Eigen("K − σM is not positive definite (is K indefinite?)".into())
    })?;
    let mut x1 = md;
    l.solve_lower_triangular_in_place(&mut x1);
    let mut c = x1.transpose().to_owned();
    l.solve_lower_triangular_in_place(&mut c);
    let eig = c
        .self_adjoint_eigen(Side::Lower)
        .map_err(|e| FemError::Eigen(format!("{e:?}")))?;
    let u = eig.U();
    // eigenvalues ascending: the largest μ are the last columns
    let mut y = Mat::from_fn(n, p, |i, j| u[(i, n - 1 - j)]);
    l.transpose().solve_upper_triangular_in_place(&mut y);
    Ok(DMatrix::from_fn(n, p, |i, j| y[(i, j)]))
}

/// The initial shift magnitude `s` (σ = −s): `10⁻¹²` of the largest `K_ii/M_ii`.
fn shift_scale(
    k: &SparseColMat<usize, f64>,
    m: &SparseColMat<usize, f64>,
) -> Result<f64, FemError> {
    let diag = |a: &SparseColMat<usize, f64>| -> Vec<f64> {
        let mut d = vec![0.0; a.nrows()];
        let cp = a.symbolic().col_ptr();
        let ri = a.symbolic().row_idx();
        for j in 0..a.ncols() {
            for p in cp[j]..cp[j + 1] {
                if ri[p] == j {
                    d[j] += a.val()[p];
                }
            }
        }
        d
    };
    let (kd, md) = (diag(k), diag(m));
    let scale = kd
        .iter()
        .zip(&md)
        .filter(|(_, m)| **m > 0.0)
        .map(|(k, m)| k / m)
        .fold(0.0, f64::max);
    if !(scale > 0.0 && scale.is_finite()) {
        return Err(FemError::Eigen(
            "stiffness or mass diagonal is not positive".into(),
        ));
    }
    Ok(1e-12 * scale)
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

fn axpy(a: f64, x: &[f64], y: &mut [f64]) {
    y.iter_mut().zip(x).for_each(|(yi, xi)| *yi += a * xi);
}

/// The factorised shift-invert operator `x ↦ (K − σM)⁻¹ M x`.
pub struct ShiftInvert {
    /// `M` without its stored zeros.
    m: SparseColMat<usize, f64>,
    llt: SparseCholesky,
    /// The shift σ (negative).
    pub sigma: f64,
}

impl ShiftInvert {
    /// Factorise `K − σM` with `σ = −s`, `s` a tiny fraction of the largest `K_ii/M_ii`, raised
    /// until the Cholesky factorisation succeeds. `node_of` as in [`lowest_modes_of_nodes`].
    pub fn new(
        k: &SparseColMat<usize, f64>,
        m: &SparseColMat<usize, f64>,
        node_of: Option<&[usize]>,
    ) -> Result<Self, FemError> {
        let s0 = shift_scale(k, m)?;
        let each: Vec<usize>;
        let group = match node_of {
            Some(g) => g,
            None => {
                each = (0..k.nrows()).collect();
                &each
            }
        };
        let symbolic = SparseCholesky::symbolic(k.symbolic(), Side::Lower, group)
            .map_err(|e| FemError::Eigen(format!("{e:?}")))?;
        let mut s = s0;
        for _ in 0..6 {
            let a = combine(k, s, m);
            if let Ok(llt) = SparseCholesky::new(symbolic.clone(), a.as_ref(), Side::Lower) {
                return Ok(Self {
                    m: without_zeros(m),
                    llt,
                    sigma: -s,
                });
            }
            s *= 100.0;
        }
        Err(FemError::Eigen(
            "K − σM is not positive definite for any small negative shift (is K indefinite?)"
                .into(),
        ))
    }

    /// `y = (K − σM)⁻¹ M x`.
    pub fn apply(&self, x: &[f64], y: &mut [f64]) {
        spmv(&self.m, x, y);
        self.solve(y);
    }

    /// `y ← (K − σM)⁻¹ y`: [`Self::apply`] when `M x` is at hand.
    pub fn solve(&self, y: &mut [f64]) {
        self.llt.solve_columns(y, 1);
    }
}

/// Number of vectors the block Lanczos iteration adds at a time on models of at least
/// [`BLOCK_MIN_DOF`] free dof. The triangular solves of a large factor and the products by
/// `M` are bound by reading the matrix from memory, which a block does once for all its
/// columns, and the re-orthogonalisation reads the basis once a block. Measured on the
/// 98 000-dof plate's 10 modes (20 with the rigid and guard modes): 18 four-column solves
/// instead of 57 one-column ones, the whole analysis 3.8 → 3.0 s (docs/performance.md).
pub const LANCZOS_BLOCK: usize = 4;

/// Smallest model solved by Lanczos in blocks of [`LANCZOS_BLOCK`]; smaller ones add one
/// vector at a time (the basis is then a large part of the space).
pub const BLOCK_MIN_DOF: usize = 200;

/// Column-major `n × cols` storage of a basis and of its products by `M`.
struct Basis {
    n: usize,
    v: Vec<f64>,
    mv: Vec<f64>,
}

impl Basis {
    fn col(&self, j: usize) -> &[f64] {
        &self.v[j * self.n..(j + 1) * self.n]
    }
    fn mcol(&self, j: usize) -> &[f64] {
        &self.mv[j * self.n..(j + 1) * self.n]
    }
    fn v_ref(&self, cols: std::ops::Range<usize>) -> faer::MatRef<'_, f64> {
        faer::MatRef::from_column_major_slice(
            &self.v[cols.start * self.n..cols.end * self.n],
            self.n,
            cols.len(),
        )
    }
    fn mv_ref(&self, cols: std::ops::Range<usize>) -> faer::MatRef<'_, f64> {
        faer::MatRef::from_column_major_slice(
            &self.mv[cols.start * self.n..cols.end * self.n],
            self.n,
            cols.len(),
        )
    }

    /// Restart with the Ritz vectors `nv` and their products by M `nmv` (`n × nkeep` each) as
    /// the first columns, followed by the next block (columns `mdim..mdim + b` before).
    fn keep_ritz_vectors(&mut self, nv: &[f64], nmv: &[f64], nkeep: usize, mdim: usize, b: usize) {
        let n = self.n;
        // [Ritz vectors, next block]
        self.v.copy_within(mdim * n..(mdim + b) * n, nkeep * n);
        self.mv.copy_within(mdim * n..(mdim + b) * n, nkeep * n);
        self.v[..nkeep * n].copy_from_slice(nv);
        self.mv[..nkeep * n].copy_from_slice(nmv);
    }
}

/// Shift-invert block Lanczos in the `M` inner product with full re-orthogonalisation and
/// thick restarts: returns `p` vectors spanning the lowest modes (the caller's Rayleigh–Ritz
/// step makes them the eigenvectors).
///
/// With blocks of `b` vectors, `V` (M-orthonormal) and the operator `A = (K − σM)⁻¹M` satisfy
/// `A V_J = V C + V_{J+1} R` for the block `J` just processed: `C` are the Gram–Schmidt
/// coefficients against the whole basis (twice, for round-off), `R` the upper triangular
/// factor of the new block's M-orthonormalisation. `T = VᵀMAV` (symmetric, `A` being
/// self-adjoint in the M inner product) is built from the coefficients' upper triangle; a Ritz
/// pair `(θ, V y)` has the residual `‖R y_last‖` (`y_last` its last block's rows). A restart
/// keeps the best Ritz vectors (their `T` becomes `diag θ`) and the next block, whose coupling
/// to them the next coefficients recover (Krylov–Schur for symmetric problems).
fn lanczos(
    k: &SparseColMat<usize, f64>,
    m: &SparseColMat<usize, f64>,
    p: usize,
    opts: &EigenOptions,
    node_of: Option<&[usize]>,
) -> Result<DMatrix<f64>, FemError> {
    let n = k.nrows();
    let op = ShiftInvert::new(k, m, node_of)?;
    let b = match opts.block {
        Some(b) => b.max(1),
        None if n >= BLOCK_MIN_DOF => LANCZOS_BLOCK,
        None => 1,
    };
    // subspace dimension, a multiple of the block (blocks converge a little more slowly per
    // vector: eight blocks beyond p keep the 98 000-dof plate at one restart); a model too
    // small for it is spanned whole, one vector at a time
    let target = (2 * p).max(p + 24).max(p + 8 * b).next_multiple_of(b);
    let (mdim, b) = if target + b <= n { (target, b) } else { (n, 1) };
    // kept Ritz vectors at a restart: about half-way between p and mdim, a whole number of
    // blocks below mdim
    let keep_target = {
        let half = (p + mdim).div_ceil(2).min(mdim - 1).max(p.min(mdim - 1));
        mdim - ((mdim - half) / b).max(1) * b
    };
    let mut iteration = BlockLanczos::new(op, n, b, mdim);
    let mut coef = Mat::<f64>::zeros(iteration.cap, b);
    let mut h = DMatrix::<f64>::zeros(mdim, mdim);
    let mut r_last = DMatrix::<f64>::zeros(b, b);
    iteration.start();

    let mut kept = 0;
    for restart in 0..=opts.max_restarts {
        iteration.extend(kept, mdim, &mut coef, &mut h, &mut r_last);
        let (theta, y) = ritz_pairs(&h);
        let converged = (0..p).all(|i| ritz_residual(&r_last, &y, i) <= opts.tol * theta[i].abs());
        let done = converged || mdim == n;
        let nkeep = if done { p } else { keep_target };
        // the new basis V Y[:, 0..nkeep], and its products by M
        let yk = Mat::<f64>::from_fn(mdim, nkeep, |r, c| y[(r, c)]);
        let nv = basis_combination(iteration.basis.v_ref(0..mdim), yk.as_ref(), iteration.par);
        if done {
            return Ok(DMatrix::from_column_slice(n, p, &nv));
        }
        if restart == opts.max_restarts {
            break;
        }
        let nmv = basis_combination(iteration.basis.mv_ref(0..mdim), yk.as_ref(), iteration.par);
        iteration.basis.keep_ritz_vectors(&nv, &nmv, nkeep, mdim, b);
        h.fill(0.0);
        for i in 0..nkeep {
            h[(i, i)] = theta[i];
        }
        kept = nkeep;
    }
    Err(FemError::Eigen(format!(
        "Lanczos did not converge in {} restarts",
        opts.max_restarts
    )))
}

/// The operator, basis and work block of [`lanczos`].
struct BlockLanczos {
    op: ShiftInvert,
    /// Vectors added at a time.
    b: usize,
    /// Basis columns held: the subspace dimension and one block beyond it.
    cap: usize,
    par: faer::Par,
    basis: Basis,
    /// State of the deterministic random numbers ([`xorshift_fill`]).
    seed: u64,
    /// The block being built (`n × b`, column-major).
    w: Vec<f64>,
    /// Its product by `M`.
    mw: Vec<f64>,
}

impl BlockLanczos {
    /// An empty basis for a subspace of dimension `mdim` of an `n`-dof model, built `b`
    /// vectors at a time.
    fn new(op: ShiftInvert, n: usize, b: usize, mdim: usize) -> Self {
        let cap = mdim + b;
        Self {
            op,
            b,
            cap,
            par: faer::get_global_parallelism(),
            basis: Basis {
                n,
                v: vec![0.0; n * cap],
                mv: vec![0.0; n * cap],
            },
            seed: 0x2545_f491_4f6c_dd1du64,
            w: vec![0.0; n * b],
            mw: vec![0.0; n * b],
        }
    }

    /// The starting block: the operator applied to random vectors, M-orthonormalised into
    /// basis columns `0..b`.
    fn start(&mut self) {
        let b = self.b;
        xorshift_fill(&mut self.seed, &mut self.mw);
        spmv_columns(&self.op.m, &self.mw, &mut self.w, b);
        self.op.llt.solve_columns(&mut self.w, b);
        let mut r0 = DMatrix::<f64>::zeros(b, b);
        self.finish_block(0, &mut r0, 0.0);
    }

    /// Extend the basis from `from` to `mdim` columns (and the next block beyond), a block at
    /// a time: the coefficients go to `h`, the last block's triangular factor to `r_last`.
    fn extend(
        &mut self,
        from: usize,
        mdim: usize,
        coef: &mut Mat<f64>,
        h: &mut DMatrix<f64>,
        r_last: &mut DMatrix<f64>,
    ) {
        let (n, b) = (self.basis.n, self.b);
        let mut j = from;
        while j < mdim {
            // A V_J: one solve for the block's columns, from the kept products by M
            self.w.copy_from_slice(&self.basis.mv[j * n..(j + b) * n]);
            self.op.llt.solve_columns(&mut self.w, b);
            orthogonalise(&self.basis, &mut self.w, j + b, coef, self.par);
            for a in 0..b {
                for i in 0..j + b {
                    h[(i, j + a)] += coef[(i, a)];
                }
            }
            let hn = (0..j + b)
                .flat_map(|i| (0..b).map(move |a| (i, a)))
                .map(|(i, a)| coef[(i, a)].abs())
                .fold(0.0, f64::max);
            self.finish_block(j + b, r_last, hn);
            j += b;
        }
    }

    /// M-orthonormalise the block `w` (already orthogonal to basis columns `0..at`) into basis
    /// columns `at..at + b`: modified Gram–Schmidt within the block, twice, `r` its upper
    /// triangular factor. A direction the block has lost (an invariant subspace) is replaced
    /// by a fresh vector orthogonal to everything, its diagonal entry of `r` zero (the lost
    /// vector was a combination of the ones before it).
    fn finish_block(&mut self, at: usize, r: &mut DMatrix<f64>, scale: f64) {
        let Self {
            op,
            b,
            cap,
            par,
            basis,
            seed,
            w,
            mw,
        } = self;
        let (n, b) = (basis.n, *b);
        r.fill(0.0);
        // M W for the whole block; the Gram–Schmidt updates below carry it along
        spmv_columns(&op.m, w, mw, b);
        for a in 0..b {
            let (wa, ma) = (&mut w[a * n..(a + 1) * n], &mut mw[a * n..(a + 1) * n]);
            for _pass in 0..2 {
                for c in 0..a {
                    let q = at + c;
                    let rc = dot(basis.mcol(q), wa);
                    r[(c, a)] += rc;
                    axpy(-rc, basis.col(q), wa);
                    axpy(-rc, basis.mcol(q), ma);
                }
            }
            let mut nrm = dot(wa, ma).max(0.0).sqrt();
            if nrm <= 1e-13 * scale.max(1e-300) {
                // invariant subspace: continue with a fresh direction
                let mut fresh = vec![0.0; n];
                xorshift_fill(seed, &mut fresh);
                op.apply(&fresh, wa);
                let mut dummy = Mat::<f64>::zeros(*cap, 1);
                orthogonalise(basis, wa, at + a, &mut dummy, *par);
                spmv(&op.m, wa, ma);
                nrm = dot(wa, ma).max(0.0).sqrt();
            } else {
                r[(a, a)] = nrm;
            }
            let dst = at + a;
            for (x, y) in basis.v[dst * n..(dst + 1) * n].iter_mut().zip(wa.iter()) {
                *x = y / nrm;
            }
            for (x, y) in basis.mv[dst * n..(dst + 1) * n].iter_mut().zip(ma.iter()) {
                *x = y / nrm;
            }
        }
    }
}

/// Fill `x` with deterministic pseudo-random numbers in `[−½, ½)` (xorshift), advancing
/// `seed`.
fn xorshift_fill(seed: &mut u64, x: &mut [f64]) {
    for v in x {
        *seed ^= *seed << 13;
        *seed ^= *seed >> 7;
        *seed ^= *seed << 17;
        *v = (*seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
    }
}

/// Orthogonalise the block `w` (whose products by M are not needed yet) against basis
/// columns `0..upto`, twice; the coefficients accumulate in `coef[0..upto, ..]`.
fn orthogonalise(basis: &Basis, w: &mut [f64], upto: usize, coef: &mut Mat<f64>, par: faer::Par) {
    use faer::Accum;
    use faer::linalg::matmul::matmul;
    let n = basis.n;
    let cols = w.len() / n;
    coef.as_mut().submatrix_mut(0, 0, upto, cols).fill(0.0);
    if upto == 0 {
        return;
    }
    let mut c = Mat::<f64>::zeros(upto, cols);
    for _pass in 0..2 {
        let mut wm = faer::MatMut::from_column_major_slice_mut(w, n, cols);
        matmul(
            c.as_mut(),
            Accum::Replace,
            basis.mv_ref(0..upto).transpose(),
            wm.as_ref(),
            1.0,
            par,
        );
        matmul(
            wm.as_mut(),
            Accum::Add,
            basis.v_ref(0..upto),
            c.as_ref(),
            -1.0,
            par,
        );
        let mut dst = coef.as_mut().submatrix_mut(0, 0, upto, cols);
        for j in 0..cols {
            for i in 0..upto {
                dst[(i, j)] += c[(i, j)];
            }
        }
    }
}

/// The Ritz values `θ` of the projected matrix whose upper triangle is `h`, descending (the
/// lowest modes first), and their eigenvectors `Y` as columns.
fn ritz_pairs(h: &DMatrix<f64>) -> (Vec<f64>, DMatrix<f64>) {
    let mdim = h.nrows();
    // symmetric projected matrix from the upper triangle
    let mut t = DMatrix::<f64>::zeros(mdim, mdim);
    for j in 0..mdim {
        for i in 0..=j {
            t[(i, j)] = h[(i, j)];
            t[(j, i)] = h[(i, j)];
        }
    }
    let eig = t.symmetric_eigen();
    let mut order: Vec<usize> = (0..mdim).collect();
    order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
    let theta: Vec<f64> = order.iter().map(|&i| eig.eigenvalues[i]).collect();
    let y = DMatrix::from_fn(mdim, mdim, |r, c| eig.eigenvectors[(r, order[c])]);
    (theta, y)
}

/// The residual norm `‖R y_last‖` of Ritz pair `i`: `r_last` the last block's triangular
/// factor `R`, `y_last` the last block's rows of column `i` of `y`.
fn ritz_residual(r_last: &DMatrix<f64>, y: &DMatrix<f64>, i: usize) -> f64 {
    let (b, mdim) = (r_last.nrows(), y.nrows());
    (0..b)
        .map(|a| {
            (0..b)
                .map(|c| r_last[(a, c)] * y[(mdim - b + c, i)])
                .sum::<f64>()
                .powi(2)
        })
        .sum::<f64>()
        .sqrt()
}

/// `of · yk` (`n × nkeep`, column-major): basis columns combined into Ritz vectors.
fn basis_combination(
    of: faer::MatRef<'_, f64>,
    yk: faer::MatRef<'_, f64>,
    par: faer::Par,
) -> Vec<f64> {
    use faer::Accum;
    use faer::linalg::matmul::matmul;
    let (n, nkeep) = (of.nrows(), yk.ncols());
    let mut out = vec![0.0; n * nkeep];
    let dst = faer::MatMut::from_column_major_slice_mut(&mut out, n, nkeep);
    matmul(dst, Accum::Replace, of, yk, 1.0, par);
    out
}

/// Groups of (nearly) equal eigenvalues: `|λ_i − λ_j| ≤ rtol·max(|λ_i|, |λ_j|) + atol`.
pub fn clusters(values: &[f64], rtol: f64) -> Vec<Vec<usize>> {
    let scale = values.iter().fold(0.0f64, |a, &b| a.max(b.abs()));
    let atol = 1e-9 * scale;
    let mut out: Vec<Vec<usize>> = Vec::new();
    for (i, &v) in values.iter().enumerate() {
        if let Some(last) = out.last_mut() {
            let j = *last.last().unwrap();
            if (v - values[j]).abs() <= rtol * v.abs().max(values[j].abs()) + atol {
                last.push(i);
                continue;
            }
        }
        out.push(vec![i]);
    }
    out
}

/// Default relative tolerance below which eigenvalues count as repeated.
pub const CLUSTER_RTOL: f64 = 1e-6;
