//! Chunked Jacobians and tangent solves through an f64 factorisation.

use faer::Mat;
use faer::prelude::*;
use nalgebra::{DMatrix, DVector};
use sens::{
    Dual, LinearSolver, Scalar, chunk_ranges, gradient, jacobian, seed_chunk, solve_tangents,
};

/// f: R⁵ → R³ with a known Jacobian.
fn f<S: Scalar>(b: &[S]) -> Vec<S> {
    vec![
        b[0] * b[1] + b[2].sin(),
        b[3].exp() * b[4] - b[0].powi(2),
        (b[1] * b[1] + b[4] * b[4]).sqrt() + b[2] * b[3],
    ]
}

fn f_jacobian(b: &[f64]) -> DMatrix<f64> {
    let r = (b[1] * b[1] + b[4] * b[4]).sqrt();
    DMatrix::from_row_slice(
        3,
        5,
        &[
            b[1],
            b[0],
            b[2].cos(),
            0.0,
            0.0,
            -2.0 * b[0],
            0.0,
            0.0,
            b[3].exp() * b[4],
            b[3].exp(),
            0.0,
            b[1] / r,
            b[3],
            b[2],
            b[4] / r,
        ],
    )
}

#[test]
fn chunked_jacobian_equals_closed_form_for_every_width() {
    let b = [0.3, -1.2, 0.8, 0.1, 2.0];
    let exact = f_jacobian(&b);
    let j1 = jacobian::<1, _>(&b, f);
    let j2 = jacobian::<2, _>(&b, f);
    let j4 = jacobian::<4, _>(&b, f);
    let j8 = jacobian::<8, _>(&b, f);
    for j in [&j1, &j2, &j4, &j8] {
        assert_eq!(j.value, f::<f64>(&b));
        assert!((&j.jacobian - &exact).abs().max() < 1e-14, "{}", j.jacobian);
    }
    // identical, not merely close: every column comes from one chunk
    assert_eq!(j1.jacobian, j2.jacobian);
    assert_eq!(j1.jacobian, j4.jacobian);
    assert_eq!(j1.jacobian, j8.jacobian);
}

#[test]
fn chunk_ranges_cover_exactly_once() {
    for m in 0..20 {
        for w in 1..6 {
            let covered: Vec<usize> = chunk_ranges(m, w).flatten().collect();
            assert_eq!(covered, (0..m).collect::<Vec<_>>());
            assert!(chunk_ranges(m, w).all(|r| r.len() <= w && !r.is_empty()));
        }
    }
}

#[test]
fn seeding_marks_only_the_chunk() {
    let b = [1.0, 2.0, 3.0, 4.0, 5.0];
    let s = seed_chunk::<2>(&b, 3);
    assert_eq!(s[3].d, [1.0, 0.0]);
    assert_eq!(s[4].d, [0.0, 1.0]);
    assert!(s[..3].iter().all(|x| x.d == [0.0, 0.0]));
    let s = seed_chunk::<4>(&b, 4); // last chunk, partly empty
    assert_eq!(s[4].d, [1.0, 0.0, 0.0, 0.0]);
}

#[test]
fn gradient_of_a_scalar_function() {
    let b = [0.5, 1.5, -0.7];
    let (v, g) = gradient::<2, _>(&b, |x| x[0] * x[1].exp() + x[2].powi(3));
    assert_eq!(v, 0.5 * 1.5f64.exp() + (-0.7f64).powi(3));
    let exact = [1.5f64.exp(), 0.5 * 1.5f64.exp(), 3.0 * 0.49];
    for k in 0..3 {
        assert!((g[k] - exact[k]).abs() < 1e-14);
    }
}

// ---- A(b) x = r(b) -------------------------------------------------------------------------

const N: usize = 6;

fn a_of<S: Scalar>(b: &[S]) -> Vec<Vec<S>> {
    (0..N)
        .map(|i| {
            (0..N)
                .map(|j| {
                    let base = S::from_f64(if i == j {
                        4.0 + i as f64
                    } else {
                        1.0 / (1.0 + (i + 2 * j) as f64)
                    });
                    // nonsymmetric dependence on the design
                    base + b[0] * ((i * j) as f64 * 0.1)
                        + (b[1] * (i as f64 - j as f64)).sin() * 0.3
                })
                .collect()
        })
        .collect()
}

fn r_of<S: Scalar>(b: &[S]) -> Vec<S> {
    (0..N)
        .map(|i| (b[0] * (i as f64 + 1.0)).cos() + b[1] * b[1] * (i as f64))
        .collect()
}

fn dense(a: &[Vec<f64>]) -> Mat<f64> {
    Mat::from_fn(N, N, |i, j| a[i][j])
}

fn solve_f64(b: &[f64]) -> Vec<f64> {
    let lu = dense(&a_of(b)).partial_piv_lu();
    let r = r_of(b);
    let mut x = Mat::from_fn(N, 1, |i, _| r[i]);
    lu.solve_in_place(x.as_mut());
    (0..N).map(|i| x[(i, 0)]).collect()
}

/// Residual r(b) − A(b) x̂ on duals with x̂ held fixed.
fn residual<const K: usize>(b: &[Dual<K>], x_hat: &[f64]) -> Vec<Dual<K>> {
    let a = a_of(b);
    let r = r_of(b);
    (0..N)
        .map(|i| {
            let mut s = r[i];
            for j in 0..N {
                s -= a[i][j] * x_hat[j];
            }
            s
        })
        .collect()
}

fn central_differences(b: &[f64]) -> Vec<[f64; 2]> {
    let mut out = vec![[0.0; 2]; N];
    for k in 0..2 {
        let h = 1e-6;
        let mut bp = b.to_vec();
        let mut bm = b.to_vec();
        bp[k] += h;
        bm[k] -= h;
        let (xp, xm) = (solve_f64(&bp), solve_f64(&bm));
        for i in 0..N {
            out[i][k] = (xp[i] - xm[i]) / (2.0 * h);
        }
    }
    out
}

fn assert_tangents(x: &[Dual<2>], x_hat: &[f64], fd: &[[f64; 2]], what: &str) {
    for i in 0..N {
        assert_eq!(x[i].v, x_hat[i]);
        for k in 0..2 {
            let err = (x[i].d[k] - fd[i][k]).abs() / fd[i][k].abs().max(1e-3);
            assert!(
                err < 1e-7,
                "{what}: x[{i}] tangent {k}: {} vs FD {}",
                x[i].d[k],
                fd[i][k]
            );
        }
    }
}

#[test]
fn tangent_solve_matches_central_differences_dense_faer() {
    let b = [0.37, -0.8];
    let x_hat = solve_f64(&b);
    let lu = dense(&a_of(&b)).partial_piv_lu();
    let bd = seed_chunk::<2>(&b, 0);
    let x = solve_tangents(&lu, &x_hat, &residual(&bd, &x_hat));
    assert_tangents(&x, &x_hat, &central_differences(&b), "faer PartialPivLu");
}

#[test]
fn tangent_solve_matches_central_differences_nalgebra() {
    let b = [0.37, -0.8];
    let x_hat = solve_f64(&b);
    let a = a_of(&b);
    let lu = DMatrix::from_fn(N, N, |i, j| a[i][j]).lu();
    // the primal solve with nalgebra agrees with faer
    let x2 = lu.solve(&DVector::from_vec(r_of(&b))).unwrap();
    assert!((0..N).all(|i| (x2[i] - x_hat[i]).abs() < 1e-13));
    assert_eq!(lu.dim(), N);
    let bd = seed_chunk::<2>(&b, 0);
    let x = solve_tangents(&lu, &x_hat, &residual(&bd, &x_hat));
    assert_tangents(&x, &x_hat, &central_differences(&b), "nalgebra LU");
}

#[test]
fn tangent_solve_matches_central_differences_sparse_faer() {
    use faer::sparse::{SparseColMat, Triplet};
    let b = [0.37, -0.8];
    let x_hat = solve_f64(&b);
    let a = a_of(&b);
    let trip: Vec<Triplet<usize, usize, f64>> = (0..N)
        .flat_map(|i| (0..N).map(move |j| (i, j)))
        .map(|(i, j)| Triplet::new(i, j, a[i][j]))
        .collect();
    let sp = SparseColMat::<usize, f64>::try_new_from_triplets(N, N, &trip).unwrap();
    let lu = sp.sp_lu().unwrap();
    let bd = seed_chunk::<2>(&b, 0);
    let x = solve_tangents(&lu, &x_hat, &residual(&bd, &x_hat));
    assert_tangents(&x, &x_hat, &central_differences(&b), "faer sparse LU");
}

/// `J(p) = wᵀ A⁻¹ g(p)` over two columns, `A` a constant symmetric positive-definite matrix
/// and `g` nonlinear in `p`, in any scalar through [`Scalar::symmetric_solution`].
fn solved_objective<S: Scalar>(p: &[S], lu: &std::rc::Rc<dyn LinearSolver>) -> S {
    let (n, ncols) = (3, 2);
    let g: Vec<S> = (0..n * ncols)
        .map(|i| {
            let c = S::from_f64(1.0 + i as f64);
            p[0].sin() * p[1] * c + p[1] * p[1] / c - p[0]
        })
        .collect();
    let values: Vec<f64> = {
        let mut v: Vec<f64> = g.iter().map(|x| x.value()).collect();
        lu.solve_columns(&mut v, ncols);
        v
    };
    let x = S::symmetric_solution(&g, values, ncols, lu);
    (x.iter().enumerate()).fold(S::zero(), |s, (i, &xi)| s + xi * (0.5 + i as f64))
}

#[test]
fn a_symmetric_solution_differentiates_as_central_differences_in_every_scalar() {
    let a = DMatrix::from_row_slice(3, 3, &[4.0, 1.0, 0.5, 1.0, 3.0, 0.2, 0.5, 0.2, 2.0]);
    let lu: std::rc::Rc<dyn LinearSolver> = std::rc::Rc::new(sens::DenseLu::new(&a));
    let p = [0.7, -1.3];
    let at = |q: [f64; 2]| solved_objective(&q, &lu);
    let h = 1e-5;
    let central = |k: usize| {
        let (mut up, mut down) = (p, p);
        up[k] += h;
        down[k] -= h;
        (at(up) - at(down)) / (2.0 * h)
    };
    let fd = [central(0), central(1)];
    // the mixed second derivative by central differences of central differences
    let mixed = {
        let at2 = |s0: f64, s1: f64| at([p[0] + s0 * h, p[1] + s1 * h]);
        (at2(1.0, 1.0) - at2(1.0, -1.0) - at2(-1.0, 1.0) + at2(-1.0, -1.0)) / (4.0 * h * h)
    };
    let close = |a: f64, b: f64, tol: f64| (a - b).abs() <= tol * b.abs().max(1.0);

    // forward: the value and both tangents
    let d = solved_objective(
        &[
            Dual::<2>::new(p[0], [1.0, 0.0]),
            Dual::new(p[1], [0.0, 1.0]),
        ],
        &lu,
    );
    assert!(close(d.value(), at(p), 1e-15));
    for k in 0..2 {
        assert!(
            close(d.d[k], fd[k], 1e-8),
            "Dual tangent {k}: {} vs {}",
            d.d[k],
            fd[k]
        );
    }

    // reverse: one sweep through the solve's operation
    let mark = sens::Tape::len();
    let inputs: Vec<sens::Rev> = p.iter().map(|&v| sens::Rev::input(v)).collect();
    let y = solved_objective(&inputs, &lu);
    let mut adj = Vec::new();
    y.seed(&mut adj, 1.0);
    sens::Tape::backpropagate(&mut adj, mark);
    for k in 0..2 {
        let g = inputs[k].adjoint(&adj);
        assert!(
            close(g, d.d[k], 1e-13),
            "Rev gradient {k}: {g} vs {}",
            d.d[k]
        );
    }
    sens::Tape::rewind(mark);

    // second order: the hyper-dual's mixed part is solved too
    let hd = solved_objective(
        &[
            sens::HyperDual::new(p[0], 1.0, 0.0),
            sens::HyperDual::new(p[1], 0.0, 1.0),
        ],
        &lu,
    );
    assert!(close(hd.d[0], d.d[0], 1e-14) && close(hd.d[1], d.d[1], 1e-14));
    assert!(
        close(hd.mixed(), mixed, 1e-5),
        "mixed {} vs {mixed}",
        hd.mixed()
    );
}
