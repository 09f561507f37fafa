//! The leading matrix of Eq. (12), `[[M, Jᵀ], [J, 0]]`: the block-diagonal mass matrix
//! ([`BodyMass`]) and the factorisation that solves with it ([`Eq12Factor`]).
//!
//! Small mechanisms factorise the whole matrix (dense LU with partial pivoting). Larger ones
//! use its structure: `M` is block diagonal, one block per body, and a row of `J` touches at
//! most two bodies, so that
//!
//! ```text
//! S λ = J M⁻¹ f − g,   x = M⁻¹ (f − Jᵀ λ),   S = J M⁻¹ Jᵀ,
//! ```
//!
//! with each body's block factorised by Cholesky on its own and the Schur complement `S` —
//! sparse: two rows couple only through a body they share — by sparse Cholesky, its symbolic
//! analysis kept while the pattern stays ([`SchurPattern`]). A chain or tree of bodies then
//! costs a solve linear in the number of bodies where the dense LU is cubic
//! (docs/performance.md). Should a body block or `S` not be numerically positive definite
//! (a singular configuration), the dense LU decides.

use std::ops::Index;
use std::sync::{Arc, Mutex};

use faer::Side;
use faer::sparse::linalg::cholesky::SymbolicCholesky;
use faer::sparse::{Argsort, Pair, SparseColMat, SymbolicSparseColMat};
use nalgebra::{Cholesky, DMatrix, DVectorViewMut, Dyn};
use sens::sparse::SparseCholesky;
use sens::{DenseLu, LinearSolver, Scalar};

use crate::kin::Jac;

/// The mass matrix of Eq. (12): block diagonal, one dense block per body, in the order of the
/// velocities `v`. Indexing outside the blocks gives zero.
#[derive(Clone, Debug)]
pub struct BodyMass<S: Scalar> {
    offsets: Vec<usize>,
    blocks: Vec<DMatrix<S>>,
    dim: usize,
    zero: S,
}

impl<S: Scalar> BodyMass<S> {
    /// Zero blocks of the orders `sizes`, one after the other along `v`.
    pub fn zeros(sizes: impl IntoIterator<Item = usize>) -> Self {
        let mut offsets = Vec::new();
        let mut blocks = Vec::new();
        let mut dim = 0;
        for n in sizes {
            offsets.push(dim);
            blocks.push(DMatrix::zeros(n, n));
            dim += n;
        }
        Self {
            offsets,
            blocks,
            dim,
            zero: S::zero(),
        }
    }

    /// Order of the whole matrix.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// The blocks with the index of their first row.
    pub fn blocks(&self) -> impl Iterator<Item = (usize, &DMatrix<S>)> {
        self.offsets.iter().copied().zip(&self.blocks)
    }

    /// Block `b`.
    pub fn block_mut(&mut self, b: usize) -> &mut DMatrix<S> {
        &mut self.blocks[b]
    }

    /// The block that holds row (and column) `i`.
    pub fn block_of(&self, i: usize) -> usize {
        self.offsets.partition_point(|&o| o <= i) - 1
    }

    /// Every entry converted with `f` (e.g. the values of dual numbers).
    pub fn map<T: Scalar>(&self, f: impl Fn(S) -> T + Copy) -> BodyMass<T> {
        BodyMass {
            offsets: self.offsets.clone(),
            blocks: self.blocks.iter().map(|b| b.map(f)).collect(),
            dim: self.dim,
            zero: f(self.zero),
        }
    }

    /// `M x`.
    pub fn mul(&self, x: &[S]) -> Vec<S> {
        assert_eq!(
            x.len(),
            self.dim,
            "BodyMass::mul: vector of the wrong length"
        );
        let mut y = vec![S::zero(); self.dim];
        for (o, b) in self.blocks() {
            for j in 0..b.ncols() {
                for i in 0..b.nrows() {
                    y[o + i] += b[(i, j)] * x[o + j];
                }
            }
        }
        y
    }

    /// The whole matrix.
    pub fn to_dense(&self) -> DMatrix<S> {
        let mut m = DMatrix::zeros(self.dim, self.dim);
        for (o, b) in self.blocks() {
            m.view_mut((o, o), b.shape()).copy_from(b);
        }
        m
    }
}

impl<S: Scalar> Index<(usize, usize)> for BodyMass<S> {
    type Output = S;

    fn index(&self, (i, j): (usize, usize)) -> &S {
        assert!(i < self.dim && j < self.dim, "BodyMass: index out of range");
        let b = self.block_of(i);
        let o = self.offsets[b];
        if j >= o && j < o + self.blocks[b].ncols() {
            &self.blocks[b][(i - o, j - o)]
        } else {
            &self.zero
        }
    }
}

/// Above this order of Eq. (12) (`n_v` plus the kept constraint rows) the body blocks, the
/// Schur complement and the sparse Newton system cost less than the dense LUs. Measured on
/// chains of flexible tubes (1 s simulated): at 75 unknowns both paths take the same time, at
/// 120 the structured one half; the paper decks (about 50) are 15–40 % faster dense.
pub(crate) const DENSE_LIMIT: usize = 80;

/// Up to this many constraint rows the Schur complement is factorised dense.
const DENSE_SCHUR_LIMIT: usize = 48;

/// A factorisation of the leading matrix of Eq. (12).
#[derive(Clone, Debug)]
pub enum Eq12Factor {
    /// LU with partial pivoting of the whole matrix.
    Dense(DenseLu),
    /// The body blocks and the Schur complement on the constraints.
    Bodies(BodySchur),
}

impl Eq12Factor {
    /// Factorise `[[mass, Jᵀ], [J, 0]]` with the rows `rows` of `J`: the structured form
    /// above [`DENSE_LIMIT`] (if `pattern` is given), else (or if that fails) the dense LU.
    /// `None` if the matrix is singular.
    pub(crate) fn new(
        mass: &BodyMass<f64>,
        rows: &[&Jac<f64>],
        pattern: Option<&Mutex<Option<SchurPattern>>>,
    ) -> Option<Self> {
        if let Some(pattern) = pattern
            && mass.dim() + rows.len() > DENSE_LIMIT
            && let Some(f) = BodySchur::new(mass, rows, pattern)
        {
            return Some(Self::Bodies(f));
        }
        let lu = dense_lu(mass, rows);
        lu.is_invertible().then_some(Self::Dense(lu))
    }

    /// `b ← A⁻¹ b`.
    pub fn solve_in_place(&self, b: &mut [f64]) {
        self.solve_columns(b, 1);
    }

    /// `B ← A⁻¹ B` for the `n × m` matrix `B` stored row by row (the tangents of a dual
    /// chunk side by side).
    pub fn solve_rows(&self, b: &mut [f64], m: usize) {
        match self {
            Self::Dense(lu) => {
                let ok = lu.solve_rows(b, m);
                debug_assert!(ok, "solve with a singular factor");
            }
            Self::Bodies(_) => {
                let n = self.dim();
                let mut cols = vec![0.0; n * m];
                for i in 0..n {
                    for k in 0..m {
                        cols[k * n + i] = b[i * m + k];
                    }
                }
                self.solve_columns(&mut cols, m);
                for i in 0..n {
                    for k in 0..m {
                        b[i * m + k] = cols[k * n + i];
                    }
                }
            }
        }
    }
}

impl LinearSolver for Eq12Factor {
    fn dim(&self) -> usize {
        match self {
            Self::Dense(lu) => lu.dim(),
            Self::Bodies(s) => s.n_v + s.row_ptr.len() - 1,
        }
    }

    fn solve_columns(&self, rhs: &mut [f64], ncols: usize) {
        match self {
            Self::Dense(lu) => lu.solve_columns(rhs, ncols),
            Self::Bodies(s) => {
                let n = self.dim();
                assert_eq!(rhs.len(), n * ncols, "right-hand side has the wrong size");
                let mut work = vec![0.0; s.n_v];
                for col in rhs.chunks_exact_mut(n.max(1)).take(ncols) {
                    s.solve(col, &mut work);
                }
            }
        }
    }
}

/// The dense LU of the whole matrix, assembled row by row.
fn dense_lu(mass: &BodyMass<f64>, rows: &[&Jac<f64>]) -> DenseLu {
    let nv = mass.dim();
    let n = nv + rows.len();
    let mut a = vec![0.0; n * n];
    for (o, b) in mass.blocks() {
        for i in 0..b.nrows() {
            for j in 0..b.ncols() {
                a[(o + i) * n + o + j] = b[(i, j)];
            }
        }
    }
    for (r, row) in rows.iter().enumerate() {
        for (c, &x) in row.iter() {
            a[(nv + r) * n + c] = x;
            a[c * n + nv + r] = x;
        }
    }
    DenseLu::from_row_major(n, a)
}

/// The symbolic part of a sparse Schur complement: the order of its entries as they are
/// assembled, the pattern they make and its symbolic Cholesky factorisation. Kept between
/// factorisations while the entries come in the same order (the same kept rows).
pub struct SchurPattern {
    entries: Vec<(usize, usize)>,
    pattern: SymbolicSparseColMat<usize>,
    argsort: Argsort<usize>,
    cholesky: Arc<SymbolicCholesky<usize>>,
}

impl std::fmt::Debug for SchurPattern {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "SchurPattern({} entries)", self.entries.len())
    }
}

/// `M` by body blocks, `J` by rows and the factor of `S = J M⁻¹ Jᵀ` ([`Eq12Factor::Bodies`]).
#[derive(Clone, Debug)]
pub struct BodySchur {
    n_v: usize,
    /// Each body block's first row and Cholesky factor.
    blocks: Vec<(usize, Cholesky<f64, Dyn>)>,
    /// The rows of `J`, compressed: row `r`'s columns and values at `row_ptr[r]..row_ptr[r + 1]`.
    row_ptr: Vec<usize>,
    cols: Vec<usize>,
    vals: Vec<f64>,
    schur: SchurFactor,
}

#[derive(Clone, Debug)]
enum SchurFactor {
    Dense(Cholesky<f64, Dyn>),
    Sparse(SparseCholesky),
}

impl BodySchur {
    /// `None` if a body block or `S` is not numerically positive definite.
    fn new(
        mass: &BodyMass<f64>,
        rows: &[&Jac<f64>],
        pattern: &Mutex<Option<SchurPattern>>,
    ) -> Option<Self> {
        let blocks = mass
            .blocks()
            .map(|(o, b)| Cholesky::new(b.clone()).map(|c| (o, c)))
            .collect::<Option<Vec<_>>>()?;
        let nnz: usize = rows.iter().map(|r| r.cols().len()).sum();
        let mut row_ptr = Vec::with_capacity(rows.len() + 1);
        row_ptr.push(0);
        let mut cols = Vec::with_capacity(nnz);
        let mut vals = Vec::with_capacity(nnz);
        // the rows that touch each body
        let mut touching: Vec<Vec<usize>> = vec![Vec::new(); blocks.len()];
        for (r, row) in rows.iter().enumerate() {
            for (c, &x) in row.iter() {
                cols.push(c);
                vals.push(x);
                let b = mass.block_of(c);
                if touching[b].last() != Some(&r) {
                    touching[b].push(r);
                }
            }
            row_ptr.push(cols.len());
        }
        let rows_j = RowsOfJ {
            row_ptr: &row_ptr,
            cols: &cols,
            vals: &vals,
        };
        let entries = schur_entries(&blocks, &rows_j, &touching);
        let m = rows.len();
        let schur = if m <= DENSE_SCHUR_LIMIT {
            let mut a = DMatrix::zeros(m, m);
            for &((i, j), x) in &entries {
                a[(i, j)] += x;
                if i != j {
                    a[(j, i)] += x;
                }
            }
            SchurFactor::Dense(Cholesky::new(a)?)
        } else {
            SchurFactor::Sparse(sparse_schur(m, &entries, pattern)?)
        };
        Some(Self {
            n_v: mass.dim(),
            blocks,
            row_ptr,
            cols,
            vals,
            schur,
        })
    }

    /// One right-hand side `[f; g]` → `[x; λ]`; `work` has length `n_v`.
    fn solve(&self, b: &mut [f64], work: &mut [f64]) {
        let (f, g) = b.split_at_mut(self.n_v);
        self.solve_blocks(f);
        for (r, gr) in g.iter_mut().enumerate() {
            let e = self.row_ptr[r]..self.row_ptr[r + 1];
            let jy: f64 = self.cols[e.clone()]
                .iter()
                .zip(&self.vals[e])
                .map(|(&c, &x)| x * f[c])
                .sum();
            *gr = jy - *gr;
        }
        match &self.schur {
            SchurFactor::Dense(c) => {
                let m = g.len();
                c.solve_mut(&mut DVectorViewMut::from_slice(g, m));
            }
            SchurFactor::Sparse(c) => c.solve_columns(g, 1),
        }
        work.fill(0.0);
        for (r, &l) in g.iter().enumerate() {
            for e in self.row_ptr[r]..self.row_ptr[r + 1] {
                work[self.cols[e]] += self.vals[e] * l;
            }
        }
        self.solve_blocks(work);
        for (x, t) in f.iter_mut().zip(work.iter()) {
            *x -= t;
        }
    }

    /// `x ← M⁻¹ x`, block by block.
    fn solve_blocks(&self, x: &mut [f64]) {
        for (o, c) in &self.blocks {
            let n = c.l_dirty().nrows();
            c.solve_mut(&mut DVectorViewMut::from_slice(&mut x[*o..o + n], n));
        }
    }
}

/// The rows of `J`, compressed ([`BodySchur`]'s storage).
struct RowsOfJ<'a> {
    row_ptr: &'a [usize],
    cols: &'a [usize],
    vals: &'a [f64],
}

/// The entries `((i, j), S_ij)`, `i ≤ j`, of `S = J M⁻¹ Jᵀ` body by body (repeated pairs add
/// up): `J_b M_b⁻¹ J_bᵀ` over the rows `touching[b]` that touch body `b`.
fn schur_entries(
    blocks: &[(usize, Cholesky<f64, Dyn>)],
    rows: &RowsOfJ<'_>,
    touching: &[Vec<usize>],
) -> Vec<((usize, usize), f64)> {
    let mut entries = Vec::with_capacity(
        touching
            .iter()
            .map(|rs| rs.len() * (rs.len() + 1) / 2)
            .sum(),
    );
    for ((o, chol), rs) in blocks.iter().zip(touching) {
        let n = chol.l_dirty().nrows();
        let mut jt = DMatrix::zeros(n, rs.len());
        for (k, &r) in rs.iter().enumerate() {
            for e in rows.row_ptr[r]..rows.row_ptr[r + 1] {
                let c = rows.cols[e];
                if c >= *o && c < o + n {
                    jt[(c - o, k)] += rows.vals[e];
                }
            }
        }
        let w = chol.solve(&jt);
        let sb = jt.transpose() * w;
        for (a, &ra) in rs.iter().enumerate() {
            for (b, &rb) in rs.iter().enumerate().skip(a) {
                entries.push(((ra, rb), sb[(a, b)]));
            }
        }
    }
    entries
}

/// The sparse Cholesky factor of the `m × m` matrix with the upper-triangle `entries`,
/// reusing `pattern` when the entries come in its order.
fn sparse_schur(
    m: usize,
    entries: &[((usize, usize), f64)],
    pattern: &Mutex<Option<SchurPattern>>,
) -> Option<SparseCholesky> {
    let mut cache = pattern.lock().unwrap_or_else(|e| e.into_inner());
    let same = cache.as_ref().is_some_and(|p| {
        p.entries.len() == entries.len() && p.entries.iter().zip(entries).all(|(a, b)| *a == b.0)
    });
    if !same {
        let (sym, argsort) = SymbolicSparseColMat::try_new_from_indices(
            m,
            m,
            &entries
                .iter()
                .map(|&((i, j), _)| Pair::new(i, j))
                .collect::<Vec<_>>(),
        )
        .ok()?;
        let group: Vec<usize> = (0..m).collect();
        let cholesky = SparseCholesky::symbolic(sym.as_ref(), Side::Upper, &group).ok()?;
        *cache = Some(SchurPattern {
            entries: entries.iter().map(|e| e.0).collect(),
            pattern: sym,
            argsort,
            cholesky,
        });
    }
    let p = cache.as_ref()?;
    let values: Vec<f64> = entries.iter().map(|e| e.1).collect();
    let a = SparseColMat::new_from_argsort(p.pattern.clone(), &p.argsort, &values).ok()?;
    let symbolic = p.cholesky.clone();
    drop(cache);
    SparseCholesky::new(symbolic, a.as_ref(), Side::Upper).ok()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kin::Cols;

    /// A deterministic pseudo-random number in (−1, 1).
    fn rand(state: &mut u64) -> f64 {
        *state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((*state >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }

    /// A chain of `nb` bodies (orders 6 … 6 + 4) with SPD blocks and `per_joint` rows per
    /// joint between neighbours (the first joint to the ground).
    fn chain(nb: usize, per_joint: usize, seed: u64) -> (BodyMass<f64>, Vec<Jac<f64>>) {
        let mut s = seed;
        let sizes: Vec<usize> = (0..nb).map(|b| 6 + b % 5).collect();
        let mut mass = BodyMass::zeros(sizes.iter().copied());
        for (b, &n) in sizes.iter().enumerate() {
            let a = DMatrix::from_fn(n, n, |_, _| rand(&mut s));
            *mass.block_mut(b) = &a * a.transpose() + DMatrix::identity(n, n) * 0.5;
        }
        let offsets: Vec<usize> = mass.blocks().map(|(o, _)| o).collect();
        let range = |b: usize| offsets[b]..offsets[b] + sizes[b];
        let mut rows = Vec::new();
        for b in 0..nb {
            let cols = if b == 0 {
                Cols::of(range(0))
            } else {
                Cols::of(range(b - 1)).union(&Cols::of(range(b)))
            };
            for _ in 0..per_joint {
                rows.push(Jac::from_fn(cols.clone(), |_| rand(&mut s)));
            }
        }
        (mass, rows)
    }

    fn dense_matrix(mass: &BodyMass<f64>, rows: &[Jac<f64>]) -> DMatrix<f64> {
        let nv = mass.dim();
        let n = nv + rows.len();
        let mut a = DMatrix::zeros(n, n);
        a.view_mut((0, 0), (nv, nv)).copy_from(&mass.to_dense());
        for (r, row) in rows.iter().enumerate() {
            for (c, &x) in row.iter() {
                a[(nv + r, c)] = x;
                a[(c, nv + r)] = x;
            }
        }
        a
    }

    /// The structured solve against the residual of the whole matrix, one column and a
    /// row-major block of tangents.
    fn check_solves(mass: &BodyMass<f64>, rows: &[Jac<f64>], f: &Eq12Factor, seed: u64) {
        let a = dense_matrix(mass, rows);
        let n = a.nrows();
        let mut s = seed;
        let b: Vec<f64> = (0..n).map(|_| rand(&mut s)).collect();
        let mut x = b.clone();
        f.solve_in_place(&mut x);
        let r = &a * nalgebra::DVector::from_column_slice(&x) - nalgebra::DVector::from_vec(b);
        let scale = x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(
            r.amax() < 1e-11 * scale * a.amax(),
            "residual {:e}",
            r.amax()
        );
        let m = 3;
        let bb: Vec<f64> = (0..n * m).map(|_| rand(&mut s)).collect();
        let mut xx = bb.clone();
        f.solve_rows(&mut xx, m);
        for k in 0..m {
            let xk: Vec<f64> = (0..n).map(|i| xx[i * m + k]).collect();
            let bk: Vec<f64> = (0..n).map(|i| bb[i * m + k]).collect();
            let r = &a * nalgebra::DVector::from_vec(xk) - nalgebra::DVector::from_vec(bk);
            assert!(
                r.amax() < 1e-10 * a.amax(),
                "tangent {k}: residual {:e}",
                r.amax()
            );
        }
    }

    #[test]
    fn body_blocks_and_schur_complement_solve_the_whole_matrix() {
        // dense and sparse Schur complements (12 and 150 rows)
        for (nb, per_joint) in [(4, 3), (30, 5)] {
            let (mass, rows) = chain(nb, per_joint, 7 + nb as u64);
            let refs: Vec<&Jac<f64>> = rows.iter().collect();
            let cache = Mutex::new(None);
            let f = BodySchur::new(&mass, &refs, &cache).expect("positive definite");
            assert_eq!(
                matches!(f.schur, SchurFactor::Sparse(_)),
                rows.len() > DENSE_SCHUR_LIMIT
            );
            check_solves(&mass, &rows, &Eq12Factor::Bodies(f), 11);
            // the same dense factorisation as the whole matrix's LU
            let dense = Eq12Factor::new(&mass, &refs, None).unwrap();
            assert!(matches!(dense, Eq12Factor::Dense(_)));
            check_solves(&mass, &rows, &dense, 13);
        }
    }

    #[test]
    fn the_schur_pattern_is_kept_while_the_rows_stay_and_made_anew_when_they_change() {
        let cache = Mutex::new(None);
        let (mass, rows) = chain(30, 5, 3);
        let refs: Vec<&Jac<f64>> = rows.iter().collect();
        let f = Eq12Factor::new(&mass, &refs, Some(&cache)).unwrap();
        assert!(matches!(f, Eq12Factor::Bodies(_)));
        let first = Arc::clone(&cache.lock().unwrap().as_ref().unwrap().cholesky);
        // other values, the same pattern: the symbolic part is reused
        let (mass2, rows2) = chain(30, 5, 4);
        let refs2: Vec<&Jac<f64>> = rows2.iter().collect();
        let f2 = Eq12Factor::new(&mass2, &refs2, Some(&cache)).unwrap();
        check_solves(&mass2, &rows2, &f2, 5);
        assert!(Arc::ptr_eq(
            &first,
            &cache.lock().unwrap().as_ref().unwrap().cholesky
        ));
        // a row left out: a new pattern
        let refs3: Vec<&Jac<f64>> = rows2.iter().skip(1).collect();
        let f3 = Eq12Factor::new(&mass2, &refs3, Some(&cache)).unwrap();
        check_solves(&mass2, &rows2[1..], &f3, 6);
        assert!(!Arc::ptr_eq(
            &first,
            &cache.lock().unwrap().as_ref().unwrap().cholesky
        ));
    }

    #[test]
    fn dependent_rows_fall_back_to_the_dense_lu_which_reports_them_singular() {
        let (mass, mut rows) = chain(30, 5, 9);
        rows[40] = rows[41].clone();
        let refs: Vec<&Jac<f64>> = rows.iter().collect();
        assert!(BodySchur::new(&mass, &refs, &Mutex::new(None)).is_none());
        assert!(Eq12Factor::new(&mass, &refs, Some(&Mutex::new(None))).is_none());
    }

    #[test]
    fn body_mass_indexes_products_and_densifies_by_blocks() {
        let (mass, _) = chain(5, 1, 2);
        let dense = mass.to_dense();
        for i in 0..mass.dim() {
            for j in 0..mass.dim() {
                assert_eq!(mass[(i, j)], dense[(i, j)]);
            }
        }
        let x: Vec<f64> = (0..mass.dim()).map(|i| i as f64 - 7.0).collect();
        let y = &dense * nalgebra::DVector::from_column_slice(&x);
        for (a, b) in mass.mul(&x).iter().zip(y.iter()) {
            assert!((a - b).abs() < 1e-12 * b.abs().max(1.0));
        }
    }
}
