//! `DenseLu` against the definition `A x = b` (residuals at round-off for well-conditioned
//! matrices), against nalgebra's LU (the same pivots, so the same solution to round-off), and
//! its three solves against each other; singular matrices are reported, not solved.

use nalgebra::{DMatrix, DVector};
use proptest::prelude::*;
use sens::{DenseLu, LinearSolver};

/// A matrix whose leading entries are zero or tiny, so that pivoting is needed.
fn needs_pivoting() -> DMatrix<f64> {
    DMatrix::from_row_slice(
        4,
        4,
        &[
            0.0, 2.0, 1.0, 0.0, //
            1e-14, 1.0, 0.0, 3.0, //
            4.0, 0.0, 1.0, 1.0, //
            1.0, 1.0, 5.0, 2.0,
        ],
    )
}

fn residual(a: &DMatrix<f64>, x: &[f64], b: &[f64]) -> f64 {
    let r = a * DVector::from_column_slice(x) - DVector::from_column_slice(b);
    r.amax()
        / (a.amax() * x.iter().fold(0.0f64, |m, v| m.max(v.abs()))
            + b.iter().fold(0.0f64, |m, v| m.max(v.abs())))
}

#[test]
fn pivoting_solves_a_matrix_with_a_zero_leading_entry() {
    let a = needs_pivoting();
    let lu = DenseLu::new(&a);
    assert!(lu.is_invertible());
    let b = [1.0, -2.0, 3.0, 0.5];
    let mut x = b;
    assert!(lu.solve_in_place(&mut x));
    assert!(residual(&a, &x, &b) < 1e-15, "{}", residual(&a, &x, &b));
    // the same solution as nalgebra's LU (same pivot rule)
    let reference = a
        .clone()
        .lu()
        .solve(&DVector::from_column_slice(&b))
        .unwrap();
    for (u, v) in x.iter().zip(reference.iter()) {
        assert!((u - v).abs() <= 1e-14 * v.abs().max(1.0), "{u} vs {v}");
    }
}

#[test]
fn singular_matrices_are_reported() {
    // a zero column, and two equal rows
    let mut a = needs_pivoting();
    a.column_mut(2).fill(0.0);
    let lu = DenseLu::new(&a);
    assert!(!lu.is_invertible());
    let mut b = [1.0; 4];
    assert!(!lu.solve_in_place(&mut b));
    let mut a = needs_pivoting();
    let r = a.row(3).into_owned();
    a.row_mut(1).copy_from(&r);
    assert!(!DenseLu::new(&a).is_invertible());
    let mut m = DMatrix::from_element(4, 2, 1.0);
    assert!(!DenseLu::new(&a).solve_matrix(&mut m));
}

#[test]
fn an_empty_matrix_solves_to_nothing() {
    let lu = DenseLu::new(&DMatrix::zeros(0, 0));
    assert!(lu.is_invertible());
    assert!(lu.solve_in_place(&mut []));
    assert!(lu.solve_rows(&mut [], 3));
}

fn matrix(n: usize) -> impl Strategy<Value = DMatrix<f64>> {
    proptest::collection::vec(-1.0f64..1.0, n * n).prop_map(move |v| {
        // diagonally weighted so that the condition number stays modest, with the diagonal
        // entry not always the largest in its column (pivoting exercised)
        let mut a = DMatrix::from_vec(n, n, v);
        for i in 0..n {
            a[(i, (i + 1) % n)] += 0.5 * n as f64;
        }
        a
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn every_solve_meets_its_equations(
        (a, b) in (1usize..48).prop_flat_map(|n| (matrix(n), proptest::collection::vec(-1.0f64..1.0, n * 8)))
    ) {
        let n = a.nrows();
        let lu = DenseLu::new(&a);
        prop_assert!(lu.is_invertible());
        prop_assert_eq!(lu.dim(), n);
        // one right-hand side
        let mut x = b[..n].to_vec();
        prop_assert!(lu.solve_in_place(&mut x));
        prop_assert!(residual(&a, &x, &b[..n]) < 1e-13);
        // nalgebra's LU gives the same solution to round-off
        let reference = a.clone().lu().solve(&DVector::from_column_slice(&b[..n])).unwrap();
        for (u, v) in x.iter().zip(reference.iter()) {
            prop_assert!((u - v).abs() <= 1e-11 * (1.0 + v.abs()));
        }
        // several right-hand sides (the widths of the dual chunks among them, solved with
        // fixed-size rows): row-major, column-major and the LinearSolver trait (one column at
        // a time) agree
        for m in [3, 4, 8] {
            let cols = DMatrix::from_column_slice(n, m, &b[..n * m]);
            let mut by_columns = cols.clone();
            prop_assert!(lu.solve_matrix(&mut by_columns));
            let mut rows: Vec<f64> = (0..n).flat_map(|i| (0..m).map(move |j| (i, j))).map(|(i, j)| cols[(i, j)]).collect();
            prop_assert!(lu.solve_rows(&mut rows, m));
            let mut trait_cols = b[..n * m].to_vec();
            lu.solve_columns(&mut trait_cols, m);
            for i in 0..n {
                for j in 0..m {
                    let c = trait_cols[j * n + i];
                    prop_assert!((rows[i * m + j] - c).abs() <= 1e-12 * (1.0 + c.abs()));
                    prop_assert!((by_columns[(i, j)] - c).abs() <= 1e-12 * (1.0 + c.abs()));
                }
                prop_assert!((trait_cols[i] - x[i]).abs() <= 1e-12 * (1.0 + x[i].abs()));
            }
            for j in 0..m {
                let xj: Vec<f64> = (0..n).map(|i| by_columns[(i, j)]).collect();
                prop_assert!(residual(&a, &xj, &b[j * n..(j + 1) * n]) < 1e-13);
            }
        }
    }
}

#[test]
fn shifted_factorisations_are_those_of_the_shifted_matrices() {
    let a = needs_pivoting();
    let n = a.nrows();
    for c in [0.0, 2.5, -7.0] {
        let explicit = |m: &DMatrix<f64>| {
            DMatrix::from_fn(n, n, |i, j| if i == j { c - m[(i, j)] } else { -m[(i, j)] })
        };
        // the same matrix, so the same elimination to the last bit
        assert_eq!(DenseLu::shifted(c, &a), DenseLu::new(&explicit(&a)));
        assert_eq!(
            DenseLu::shifted_transpose(c, &a),
            DenseLu::new(&explicit(&a.transpose()))
        );
        // and it solves c I − A
        let b = [1.0, -2.0, 3.0, 0.5];
        let mut x = b;
        assert!(DenseLu::shifted(c, &a).solve_in_place(&mut x));
        assert!(residual(&explicit(&a), &x, &b) < 1e-14);
    }
    assert!(DenseLu::shifted(1.0, &DMatrix::zeros(0, 0)).is_invertible());
}
