//! A small dense LU factorisation with partial pivoting, row-major and packed.
//!
//! Made for the matrices of a few tens of rows that a multibody step factorises at every
//! right-hand side (the leading matrix of Eq. 12, the Newton matrix of a BDF step): nalgebra's
//! generic LU works column by column through views, and unpacking its factors for the
//! row-by-row tangent solves cost as much again. Here the elimination's inner loops run over
//! contiguous rows, `L` and `U` share one array, and the row interchanges are kept as LAPACK
//! keeps them (`piv[k]`: the row swapped with row `k` at step `k`), so every solve works in
//! place without allocating.

use nalgebra::DMatrix;

use crate::solve::LinearSolver;

/// `P A = L U` of a square matrix, `L` unit lower triangular, `U` upper triangular, the pivot
/// of each column the largest entry below the diagonal (nalgebra's and LAPACK's choice).
#[derive(Clone, Debug, PartialEq)]
pub struct DenseLu {
    n: usize,
    /// `L` (strictly lower part, unit diagonal implied) and `U` (upper part), row-major.
    lu: Vec<f64>,
    /// Row `k` was interchanged with row `piv[k] ≥ k` at elimination step `k`.
    piv: Vec<usize>,
}

impl DenseLu {
    /// Factorise `a` (square).
    pub fn new(a: &DMatrix<f64>) -> Self {
        Self::from_row_major(a.nrows(), rows_of(a))
    }

    /// Factorise `c I − A` (`a` square): the Newton matrix of a BDF step, `c` its leading
    /// coefficient and `A` a Jacobian.
    pub fn shifted(c: f64, a: &DMatrix<f64>) -> Self {
        Self::from_row_major(a.nrows(), shift(c, a.nrows(), rows_of(a)))
    }

    /// Factorise `c I − Aᵀ` (`a` square): `Aᵀ`'s rows are `A`'s columns, contiguous in
    /// nalgebra's storage, so no transpose is formed.
    pub fn shifted_transpose(c: f64, a: &DMatrix<f64>) -> Self {
        let n = a.nrows();
        assert_eq!(a.ncols(), n, "DenseLu needs a square matrix");
        Self::from_row_major(n, shift(c, n, a.as_slice().to_vec()))
    }

    /// Factorise the `n × n` matrix stored row by row in `a`.
    pub fn from_row_major(n: usize, mut a: Vec<f64>) -> Self {
        assert_eq!(a.len(), n * n, "DenseLu: {} entries for {n} × {n}", a.len());
        let mut piv = Vec::with_capacity(n);
        for k in 0..n {
            // pivot: the largest magnitude in column k at or below the diagonal
            let mut p = k;
            let mut best = a[k * n + k].abs();
            for i in k + 1..n {
                let x = a[i * n + k].abs();
                if x > best {
                    best = x;
                    p = i;
                }
            }
            piv.push(p);
            if p != k {
                let (top, bottom) = a.split_at_mut(p * n);
                top[k * n..(k + 1) * n].swap_with_slice(&mut bottom[..n]);
            }
            let d = a[k * n + k];
            if d == 0.0 {
                // a zero column below the diagonal: nothing to eliminate (singular,
                // reported by `is_invertible`)
                continue;
            }
            let inv = 1.0 / d;
            let (head, tail) = a.split_at_mut((k + 1) * n);
            let pivot_row = &head[k * n + k + 1..(k + 1) * n];
            for row in tail.chunks_exact_mut(n) {
                let l = row[k] * inv;
                row[k] = l;
                if l != 0.0 {
                    for (x, &u) in row[k + 1..].iter_mut().zip(pivot_row) {
                        *x -= l * u;
                    }
                }
            }
        }
        Self { n, lu: a, piv }
    }

    /// Order of the matrix.
    pub fn dim(&self) -> usize {
        self.n
    }

    /// Whether every pivot is nonzero (as nalgebra's test: a matrix with non-finite entries
    /// passes, and its solutions come out non-finite for the caller to report).
    pub fn is_invertible(&self) -> bool {
        (0..self.n).all(|i| self.lu[i * self.n + i] != 0.0)
    }

    /// `b ← A⁻¹ b`; `false` (and `b` unspecified) if the matrix is singular.
    pub fn solve_in_place(&self, b: &mut [f64]) -> bool {
        let n = self.n;
        assert_eq!(b.len(), n, "DenseLu: right-hand side of the wrong length");
        if !self.is_invertible() {
            return false;
        }
        self.substitute(b);
        true
    }

    /// `b ← A⁻¹ b` for a factor known to be invertible: the row interchanges, then forward
    /// and back substitution.
    fn substitute(&self, b: &mut [f64]) {
        let n = self.n;
        for (k, &p) in self.piv.iter().enumerate() {
            b.swap(k, p);
        }
        for i in 1..n {
            b[i] -= dot(&self.lu[i * n..i * n + i], &b[..i]);
        }
        for i in (0..n).rev() {
            let s = dot(&self.lu[i * n + i + 1..(i + 1) * n], &b[i + 1..]);
            b[i] = (b[i] - s) / self.lu[i * n + i];
        }
    }

    /// `B ← A⁻¹ B` for the `n × m` matrix `B` stored row by row; `false` if singular. The
    /// updates run along the rows of `B`, which suits many narrow right-hand sides (the
    /// tangents of a dual chunk).
    pub fn solve_rows(&self, b: &mut [f64], m: usize) -> bool {
        let n = self.n;
        assert_eq!(
            b.len(),
            n * m,
            "DenseLu: right-hand sides of the wrong size"
        );
        if !self.is_invertible() {
            return false;
        }
        if m == 0 {
            return true;
        }
        // the widths of the dual chunks with fixed-size rows, which the compiler unrolls
        match m {
            8 => self.substitute_rows(b, m, axpy_fixed::<8>),
            4 => self.substitute_rows(b, m, axpy_fixed::<4>),
            _ => self.substitute_rows(b, m, axpy),
        }
        true
    }

    /// [`Self::solve_rows`]'s interchanges and substitutions, with `update(row, other, a)`
    /// doing `row −= a · other` on rows of `m` entries.
    fn substitute_rows(&self, b: &mut [f64], m: usize, update: impl Fn(&mut [f64], &[f64], f64)) {
        let n = self.n;
        for (k, &p) in self.piv.iter().enumerate() {
            if p != k {
                let (top, bottom) = b.split_at_mut(p * m);
                top[k * m..(k + 1) * m].swap_with_slice(&mut bottom[..m]);
            }
        }
        // L Y = P B
        for i in 1..n {
            let (done, rest) = b.split_at_mut(i * m);
            let row = &mut rest[..m];
            for (j, &l) in self.lu[i * n..i * n + i].iter().enumerate() {
                if l != 0.0 {
                    update(row, &done[j * m..(j + 1) * m], l);
                }
            }
        }
        // U X = Y
        for i in (0..n).rev() {
            let (head, tail) = b.split_at_mut((i + 1) * m);
            let row = &mut head[i * m..];
            for (j, &u) in self.lu[i * n + i + 1..(i + 1) * n].iter().enumerate() {
                if u != 0.0 {
                    update(row, &tail[j * m..(j + 1) * m], u);
                }
            }
            let inv = 1.0 / self.lu[i * n + i];
            for r in row.iter_mut() {
                *r *= inv;
            }
        }
    }

    /// `B ← A⁻¹ B`; `false` if singular. Several columns are solved side by side, row by row
    /// ([`Self::solve_rows`] on a row-major copy): substituting them one at a time took about
    /// three times the instructions for the eight columns of a dual chunk.
    pub fn solve_matrix(&self, b: &mut DMatrix<f64>) -> bool {
        assert_eq!(
            b.nrows(),
            self.n,
            "DenseLu: right-hand sides of the wrong size"
        );
        if !self.is_invertible() {
            return false;
        }
        let m = b.ncols();
        if m == 1 {
            self.substitute(b.as_mut_slice());
            return true;
        }
        let mut rows: Vec<f64> = b.transpose().as_slice().to_vec();
        self.solve_rows(&mut rows, m);
        b.copy_from(&DMatrix::from_row_slice(self.n, m, &rows));
        true
    }
}

/// `row −= a · other`.
fn axpy(row: &mut [f64], other: &[f64], a: f64) {
    for (r, y) in row.iter_mut().zip(other) {
        *r -= a * y;
    }
}

/// [`axpy`] on rows of `M` entries.
fn axpy_fixed<const M: usize>(row: &mut [f64], other: &[f64], a: f64) {
    let row: &mut [f64; M] = row.try_into().expect("a row of M entries");
    let other: &[f64; M] = other.try_into().expect("a row of M entries");
    for k in 0..M {
        row[k] -= a * other[k];
    }
}

/// `Σ a_i b_i` with four independent partial sums: a single running sum waits on its previous
/// addition at every term, which made the single right-hand-side solves latency-bound.
/// The rows of the square `a`, one after another (nalgebra stores it column by column).
fn rows_of(a: &DMatrix<f64>) -> Vec<f64> {
    let n = a.nrows();
    assert_eq!(a.ncols(), n, "DenseLu needs a square matrix");
    let mut rows = vec![0.0; n * n];
    for (j, column) in a.as_slice().chunks_exact(n.max(1)).enumerate() {
        for (i, &x) in column.iter().enumerate() {
            rows[i * n + j] = x;
        }
    }
    rows
}

/// `c I − A` of the `n × n` `A` stored row by row, in place.
fn shift(c: f64, n: usize, mut rows: Vec<f64>) -> Vec<f64> {
    rows.iter_mut().for_each(|x| *x = -*x);
    for d in 0..n {
        rows[d * n + d] += c;
    }
    rows
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    let mut acc = [0.0; 4];
    let (ac, ar) = a.split_at(a.len() - a.len() % 4);
    let (bc, br) = b.split_at(ac.len());
    for (x, y) in ac.chunks_exact(4).zip(bc.chunks_exact(4)) {
        for k in 0..4 {
            acc[k] += x[k] * y[k];
        }
    }
    let tail: f64 = ar.iter().zip(br).map(|(x, y)| x * y).sum();
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail
}

impl LinearSolver for DenseLu {
    fn dim(&self) -> usize {
        self.n
    }
    fn solve_columns(&self, rhs: &mut [f64], ncols: usize) {
        assert_eq!(
            rhs.len(),
            self.n * ncols,
            "right-hand side has the wrong size"
        );
        // a singular factor the caller ruled out when it accepted the factorisation for the
        // primal solve; the right-hand sides are left as they are, as by `solve_in_place`
        if !self.is_invertible() {
            debug_assert!(false, "tangent solve with a singular LU factor");
            return;
        }
        for col in rhs.chunks_exact_mut(self.n.max(1)).take(ncols) {
            self.substitute(col);
        }
    }
}
