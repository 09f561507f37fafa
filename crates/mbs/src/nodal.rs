//! Small helpers for the nodal sums of the bodies: parameters lifted to the evaluation scalar,
//! node vectors of a modal body, outer products and their axial vectors.

use fem::ModalBody;
use nalgebra::{Matrix3, SMatrix, Vector3};
use sens::Scalar;

/// Convert a parameter to the evaluation scalar.
#[inline]
pub(crate) fn lift<P: Scalar, S: Scalar + From<P>>(x: P) -> S {
    S::from(x)
}

/// `acc += m s` for a matrix `m` of parameters: with plain parameters (`P::PLAIN`), `s`
/// scaled by their values (a product with a lifted constant would multiply its zero tangents
/// too, twice the work for a dual `s`).
#[inline]
pub(crate) fn add_scaled<P: Scalar, S: Scalar + From<P>>(
    acc: &mut Matrix3<S>,
    m: &Matrix3<P>,
    s: S,
) {
    if P::PLAIN {
        for (a, x) in acc.iter_mut().zip(m.iter()) {
            *a += s * x.value();
        }
    } else {
        for (a, x) in acc.iter_mut().zip(m.iter()) {
            *a += lift::<P, S>(*x) * s;
        }
    }
}

/// `Σ_p c_p w_p` for parameters `c`, scaled by their values when they are plain (as
/// [`add_scaled`]).
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

/// `v p` for a parameter `p`: `v` scaled by its value when it is plain (as
/// [`add_scaled`]).
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
/// [`add_scaled`]).
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
