//! Tangents through a linear solve factorised once in `f64` (docs/design.md §1).
//!
//! For `A(b) x = r(b)`: factorise `A` in `f64` and solve for `x̂`; evaluate the residual
//! `r(b) − A(b) x̂` in dual numbers with `x̂` held fixed; its tangent part is the right-hand side
//! of `A x_b = r_b − A_b x̂`, solved with the same factorisation, one triangular solve per
//! tangent. No LU is ever run on dual numbers.

use faer::MatMut;
use faer::linalg::solvers::SolveCore;

use crate::Dual;

/// A linear system `A x = y` whose matrix has been factorised once, in `f64`.
///
/// Implemented for faer's dense and sparse factorisations, nalgebra's LU and [`crate::DenseLu`].
pub trait LinearSolver {
    /// Order of `A`.
    fn dim(&self) -> usize;
    /// Replace each of the `ncols` columns of `rhs` (column-major, `dim × ncols`) by `A⁻¹` times
    /// that column.
    fn solve_columns(&self, rhs: &mut [f64], ncols: usize);
}

fn faer_solve(solver: &impl SolveCore<f64>, rhs: &mut [f64], ncols: usize) {
    let n = solver.nrows();
    assert_eq!(rhs.len(), n * ncols, "right-hand side has the wrong size");
    if n == 0 || ncols == 0 {
        return;
    }
    let m = MatMut::from_column_major_slice_mut(rhs, n, ncols);
    solver.solve_in_place_with_conj(faer::Conj::No, m);
}

macro_rules! faer_dense_solver {
    ($($t:ty),*) => {$(
        impl LinearSolver for $t {
            fn dim(&self) -> usize {
                faer::linalg::solvers::ShapeCore::nrows(self)
            }
            fn solve_columns(&self, rhs: &mut [f64], ncols: usize) {
                faer_solve(self, rhs, ncols)
            }
        }
    )*};
}
faer_dense_solver!(
    faer::linalg::solvers::PartialPivLu<f64>,
    faer::linalg::solvers::FullPivLu<f64>,
    faer::linalg::solvers::Llt<f64>,
    faer::linalg::solvers::Ldlt<f64>,
    faer::sparse::linalg::solvers::Lu<usize, f64>,
    faer::sparse::linalg::solvers::Llt<usize, f64>
);

impl LinearSolver for nalgebra::LU<f64, nalgebra::Dyn, nalgebra::Dyn> {
    fn dim(&self) -> usize {
        self.l().nrows()
    }
    fn solve_columns(&self, rhs: &mut [f64], ncols: usize) {
        let n = self.dim();
        assert_eq!(rhs.len(), n * ncols, "right-hand side has the wrong size");
        let mut m = nalgebra::DMatrixViewMut::from_slice(rhs, n, ncols);
        // `solve_mut` returns false only for a singular factor, which the caller has ruled out
        // when it accepted the factorisation for the primal solve.
        let ok = self.solve_mut(&mut m);
        debug_assert!(ok, "tangent solve with a singular LU factor");
    }
}

/// Tangents of the solution of `A(b) x = r(b)` from the `f64` factorisation of `A`.
///
/// `x_hat` is the solution already obtained with `solver`; `residual` is `r(b) − A(b) x̂`
/// evaluated in dual numbers with `x̂` held constant (its value is ≈ 0; only its tangents are
/// used). Returns `x` as duals: value `x̂`, tangent `k` the solution of `A x_k = residual_k`.
pub fn solve_tangents<const N: usize>(
    solver: &impl LinearSolver,
    x_hat: &[f64],
    residual: &[Dual<N>],
) -> Vec<Dual<N>> {
    let n = solver.dim();
    assert_eq!(x_hat.len(), n, "x̂ has the wrong length");
    assert_eq!(residual.len(), n, "residual has the wrong length");
    let mut rhs = vec![0.0; n * N];
    for (i, r) in residual.iter().enumerate() {
        for k in 0..N {
            rhs[k * n + i] = r.d[k];
        }
    }
    solver.solve_columns(&mut rhs, N);
    (0..n)
        .map(|i| {
            let mut d = [0.0; N];
            for k in 0..N {
                d[k] = rhs[k * n + i];
            }
            Dual::new(x_hat[i], d)
        })
        .collect()
}
