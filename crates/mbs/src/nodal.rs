//! Small helpers for the nodal sums of the bodies: parameters lifted to the evaluation scalar,
//! node vectors of a modal body, outer products and their axial vectors, and the dispatch to
//! the reverse-mode tape's operations.

use std::any::{Any, TypeId};

use fem::ModalBody;
use nalgebra::{Matrix3, SMatrix, Vector3};
use sens::{Rev, Scalar};

/// Convert a parameter to the evaluation scalar.
#[inline]
pub(crate) fn lift<P: Scalar, S: Scalar + From<P>>(x: P) -> S {
    S::from(x)
}

/// `Σ_p c_p w_p` for parameters `c`: with plain parameters (`P::PLAIN`), `w` scaled by their
/// values (a product with a lifted constant would multiply its zero tangents too, twice the
/// work for a dual `w`).
#[inline]
pub(crate) fn dot_scaled<P: Scalar, S: Scalar + From<P>>(c: &[P], w: &[S]) -> S {
    if P::PLAIN {
        c.iter()
            .zip(w)
            .fold(S::zero(), |acc, (x, &wp)| acc + wp * x.value())
    } else {
        c.iter()
            .zip(w)
            .fold(S::zero(), |acc, (x, &wp)| acc + lift::<P, S>(*x) * wp)
    }
}

/// [`dot_scaled`] of each of `rows` (each no longer than `w`) with `w`; on the reverse-mode tape
/// (parameters and evaluation both [`Rev`]) one operation ([`Rev::dot_rows`]): a contraction
/// of a table of invariants with the modal coordinates, recorded product by product, would be
/// two tape nodes per entry of the table at every evaluation.
pub(crate) fn dot_rows<P: Scalar, S: Scalar + From<P>>(rows: &[&[P]], w: &[S]) -> Vec<S> {
    let one_operation = || {
        if !on_tape::<P, S>() {
            return None;
        }
        let entries: Vec<Rev> = taped(rows.iter().flat_map(|r| r.iter()))?;
        let lens: Vec<usize> = rows.iter().map(|r| r.len()).collect();
        let longest = lens.iter().copied().max().unwrap_or(0);
        let x: Vec<Rev> = taped(&w[..longest])?;
        cast(Rev::dot_rows(&entries, &lens, &x))
    };
    one_operation().unwrap_or_else(|| rows.iter().map(|r| dot_scaled(r, w)).collect())
}

/// Whether an evaluation with parameters `P` and scalars `S` is recorded on the reverse-mode
/// tape (both are [`Rev`]).
pub(crate) fn on_tape<P: 'static, S: 'static>() -> bool {
    TypeId::of::<P>() == TypeId::of::<Rev>() && TypeId::of::<S>() == TypeId::of::<Rev>()
}

/// The values of `x` as `T`s (`None` unless they are: the evaluation is not on the tape).
pub(crate) fn taped<'a, S: 'static, T: Copy + 'static>(
    x: impl IntoIterator<Item = &'a S>,
) -> Option<Vec<T>> {
    (x.into_iter())
        .map(|x| (x as &dyn Any).downcast_ref::<T>().copied())
        .collect()
}

/// `x` as a `U`, if it is one (the generic caller's type, [`Rev`]'s on the tape).
pub(crate) fn cast<T: 'static, U: 'static>(x: T) -> Option<U> {
    (Box::new(x) as Box<dyn Any>)
        .downcast::<U>()
        .ok()
        .map(|b| *b)
}

/// `v p` for a parameter `p`: `v` scaled by its value when it is plain (as
/// [`dot_scaled`]).
#[inline]
pub(crate) fn scaled<P: Scalar, S: Scalar + From<P>, const R: usize, const C: usize>(
    v: SMatrix<S, R, C>,
    p: P,
) -> SMatrix<S, R, C> {
    if P::PLAIN {
        let x = p.value();
        v.map(|a| a * x)
    } else {
        v * lift::<P, S>(p)
    }
}

#[inline]
pub(crate) fn vec3<S: Scalar>(s: &[S]) -> Vector3<S> {
    Vector3::new(s[0], s[1], s[2])
}

#[inline]
pub(crate) fn vec3f<S: Scalar>(a: &Vector3<f64>) -> Vector3<S> {
    Vector3::new(S::from_f64(a.x), S::from_f64(a.y), S::from_f64(a.z))
}

/// Translation (rows 0..3) and rotation (rows 3..6) of node `k` in mode `j`, as evaluation
/// scalars.
#[inline]
pub(crate) fn mode_vec<P: Scalar, S: Scalar + From<P>>(
    modal: &ModalBody<P>,
    k: usize,
    j: usize,
    rot: bool,
) -> Vector3<S> {
    let r = 6 * k + if rot { 3 } else { 0 };
    Vector3::new(
        lift(modal.modes[(r, j)]),
        lift(modal.modes[(r + 1, j)]),
        lift(modal.modes[(r + 2, j)]),
    )
}

/// [`mode_vec`] times `s`: `s` scaled by the mode's entries when they are plain (as
/// [`dot_scaled`]).
#[inline]
pub(crate) fn mode_vec_times<P: Scalar, S: Scalar + From<P>>(
    modal: &ModalBody<P>,
    k: usize,
    j: usize,
    s: S,
) -> Vector3<S> {
    if P::PLAIN {
        let r = 6 * k;
        Vector3::new(
            s * modal.modes[(r, j)].value(),
            s * modal.modes[(r + 1, j)].value(),
            s * modal.modes[(r + 2, j)].value(),
        )
    } else {
        mode_vec::<P, S>(modal, k, j, false) * s
    }
}

/// `a bᵀ`.
#[inline]
pub(crate) fn outer<S: Scalar>(a: &Vector3<S>, b: &Vector3<S>) -> Matrix3<S> {
    Matrix3::from_fn(|i, j| a[i] * b[j])
}

/// `Σ m a × b` from `M = Σ m a bᵀ`.
#[inline]
pub(crate) fn axial<S: Scalar>(m: &Matrix3<S>) -> Vector3<S> {
    Vector3::new(
        m[(1, 2)] - m[(2, 1)],
        m[(2, 0)] - m[(0, 2)],
        m[(0, 1)] - m[(1, 0)],
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use sens::{Dual, Tape};

    #[test]
    fn rows_dot_alike_in_every_scalar_and_take_one_tape_node_each_on_the_tape() {
        let table = [0.5, -1.5, 2.0, 0.25, 3.0, -0.75];
        let w = [0.3, -0.7, 1.1];
        let plain = rows_of(&table);
        let plain_rows: Vec<&[f64]> = plain.iter().map(|r| r.as_slice()).collect();
        let expected = dot_rows::<f64, f64>(&plain_rows, &w);
        assert_eq!(expected.len(), 3);
        assert_eq!(expected[1], 0.25 * 0.3 + 3.0 * -0.7);
        assert_eq!(expected[2], 0.0);
        // dual: the same values, and the derivative along w₁ is the rows' second entries
        let wd: Vec<Dual<1>> = (0..3)
            .map(|k| Dual::from_parts(w[k], &[(k == 1) as u8 as f64]))
            .collect();
        let d = dot_rows::<f64, Dual<1>>(&plain_rows, &wd);
        for (i, y) in d.iter().enumerate() {
            assert_eq!(y.value(), expected[i]);
            assert_eq!(y.tangents()[0], plain[i].get(1).copied().unwrap_or(0.0));
        }
        // on the tape: one node per row, the same values, and the adjoints of the table and of
        // w those of the products
        let mark = Tape::len();
        let t: Vec<Rev> = table.iter().map(|&x| Rev::input(x)).collect();
        let x: Vec<Rev> = w.iter().map(|&x| Rev::input(x)).collect();
        let taped = rows_of(&t);
        let taped_rows: Vec<&[Rev]> = taped.iter().map(|r| r.as_slice()).collect();
        let before = Tape::len();
        let y = dot_rows::<Rev, Rev>(&taped_rows, &x);
        assert_eq!(Tape::len() - before, 3, "one node per row");
        let mut adj = Vec::new();
        for (i, yi) in y.iter().enumerate() {
            assert_eq!(yi.value(), expected[i]);
            yi.seed(&mut adj, [1.0, 2.0, 3.0][i]);
        }
        Tape::backpropagate(&mut adj, mark);
        // ∂/∂w of y₀ + 2 y₁, and ∂/∂(table) = the weight times w
        let w_bar = [0.5 + 2.0 * 0.25, -1.5 + 2.0 * 3.0, 2.0];
        for k in 0..3 {
            assert_eq!(x[k].adjoint(&adj), w_bar[k]);
        }
        let t_bar = [0.3, -0.7, 1.1, 2.0 * 0.3, 2.0 * -0.7, 0.0];
        for k in 0..6 {
            assert_eq!(t[k].adjoint(&adj), t_bar[k]);
        }
        Tape::rewind(mark);

        fn rows_of<T: Copy>(t: &[T]) -> Vec<Vec<T>> {
            vec![t[..3].to_vec(), t[3..5].to_vec(), vec![]]
        }
    }
}
