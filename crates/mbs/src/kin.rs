//! Rotation helpers (Euler parameters) and the kinematic algebra used by constraints and
//! forces.
//!
//! A [`Kin`] (scalar) or [`Kin3`] (vector) carries a quantity `Φ(q, t)` together with
//! - `rate`: its total time derivative `Φ̇ = Φ_v v + Φ_t`,
//! - `quad`: its second time derivative with the accelerations held at zero,
//!   `Φ̈ − Φ_v v̇` (so that `γ = −quad` in Eq. 9),
//! - `jac`: `Φ_v`, the row(s) multiplying the velocity variables `v`, stored only on the
//!   velocity columns of the (at most two) bodies involved ([`Jac`]): a marker touches its
//!   body's columns, a joint those of its two bodies, whatever the size of the system.
//!
//! Products and sums follow the product rule, so every joint built from marker points and
//! axes gets its Jacobian and `γ` consistent with `Φ` by construction.

use std::ops::Range;

use nalgebra::{Matrix3, Matrix3x4, Vector3, Vector4};
use sens::Scalar;

/// Skew-symmetric (cross-product) matrix `ã` with `ã b = a × b`.
pub fn skew<S: Scalar>(a: &Vector3<S>) -> Matrix3<S> {
    let z = S::zero();
    Matrix3::new(z, -a.z, a.y, a.z, z, -a.x, -a.y, a.x, z)
}

/// Rotation matrix `A` (body → global) of the Euler parameters `p = (e0, e1, e2, e3)`,
/// normalised first, so that a drift of `|p|` never distorts the kinematics.
pub fn rotation<S: Scalar>(p: &Vector4<S>) -> Matrix3<S> {
    let n = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2] + p[3] * p[3]).sqrt();
    let (e0, e1, e2, e3) = (p[0] / n, p[1] / n, p[2] / n, p[3] / n);
    let one = S::one();
    let two = S::from_f64(2.0);
    Matrix3::new(
        two * (e0 * e0 + e1 * e1) - one,
        two * (e1 * e2 - e0 * e3),
        two * (e1 * e3 + e0 * e2),
        two * (e1 * e2 + e0 * e3),
        two * (e0 * e0 + e2 * e2) - one,
        two * (e2 * e3 - e0 * e1),
        two * (e1 * e3 - e0 * e2),
        two * (e2 * e3 + e0 * e1),
        two * (e0 * e0 + e3 * e3) - one,
    )
}

/// `a · b` by [`Scalar::dot`]: one node on the reverse-mode tape instead of five.
#[inline]
pub(crate) fn dot3<S: Scalar>(a: &Vector3<S>, b: &Vector3<S>) -> S {
    S::dot(a.as_slice(), b.as_slice())
}

/// `A x` written out (nalgebra's generic product goes through a slow path for dual numbers),
/// a row at a time by [`Scalar::dot`].
#[inline]
pub(crate) fn mv<S: Scalar>(a: &Matrix3<S>, x: &Vector3<S>) -> Vector3<S> {
    let row = |i: usize| [a[(i, 0)], a[(i, 1)], a[(i, 2)]];
    Vector3::from_fn(|i, _| S::dot(&row(i), x.as_slice()))
}

/// `Aᵀ x` written out.
#[inline]
pub(crate) fn mtv<S: Scalar>(a: &Matrix3<S>, x: &Vector3<S>) -> Vector3<S> {
    Vector3::from_fn(|i, _| dot3(&a.column(i).into_owned(), x))
}

/// `L(p)` of Nikravesh: `ω' = 2 L ṗ` (body-frame angular velocity), `ṗ = ½ Lᵀ ω'`.
pub fn l_matrix<S: Scalar>(p: &Vector4<S>) -> Matrix3x4<S> {
    let (e0, e1, e2, e3) = (p[0], p[1], p[2], p[3]);
    Matrix3x4::new(-e1, e0, e3, -e2, -e2, -e3, e0, e1, -e3, e2, -e1, e0)
}

/// Hamilton product `p ⊗ q` (so that `A(p ⊗ q) = A(p) A(q)`).
pub fn quat_mul(p: &Vector4<f64>, q: &Vector4<f64>) -> Vector4<f64> {
    let (a0, a) = (p[0], Vector3::new(p[1], p[2], p[3]));
    let (b0, b) = (q[0], Vector3::new(q[1], q[2], q[3]));
    let s = a0 * b0 - a.dot(&b);
    let v = b * a0 + a * b0 + a.cross(&b);
    Vector4::new(s, v.x, v.y, v.z)
}

/// Euler parameters of a rotation by the vector `phi` (axis × angle, rad).
pub fn quat_from_rotation_vector(phi: &Vector3<f64>) -> Vector4<f64> {
    let angle = phi.norm();
    if angle < 1e-300 {
        return Vector4::new(1.0, 0.0, 0.0, 0.0);
    }
    let (s, c) = (0.5 * angle).sin_cos();
    let a = phi / angle * s;
    Vector4::new(c, a.x, a.y, a.z)
}

/// Euler parameters of a rotation matrix (Shepperd's method).
pub fn quat_from_matrix(a: &Matrix3<f64>) -> Vector4<f64> {
    let tr = a.trace();
    let cands = [tr, a[(0, 0)], a[(1, 1)], a[(2, 2)]];
    let mut best = 0;
    for i in 1..4 {
        if cands[i] > cands[best] {
            best = i;
        }
    }
    let p = match best {
        0 => {
            let e0 = 0.5 * (1.0 + tr).sqrt();
            let f = 0.25 / e0;
            Vector4::new(
                e0,
                (a[(2, 1)] - a[(1, 2)]) * f,
                (a[(0, 2)] - a[(2, 0)]) * f,
                (a[(1, 0)] - a[(0, 1)]) * f,
            )
        }
        1 => {
            let e1 = 0.5 * (1.0 + 2.0 * a[(0, 0)] - tr).sqrt();
            let f = 0.25 / e1;
            Vector4::new(
                (a[(2, 1)] - a[(1, 2)]) * f,
                e1,
                (a[(0, 1)] + a[(1, 0)]) * f,
                (a[(0, 2)] + a[(2, 0)]) * f,
            )
        }
        2 => {
            let e2 = 0.5 * (1.0 + 2.0 * a[(1, 1)] - tr).sqrt();
            let f = 0.25 / e2;
            Vector4::new(
                (a[(0, 2)] - a[(2, 0)]) * f,
                (a[(0, 1)] + a[(1, 0)]) * f,
                e2,
                (a[(1, 2)] + a[(2, 1)]) * f,
            )
        }
        _ => {
            let e3 = 0.5 * (1.0 + 2.0 * a[(2, 2)] - tr).sqrt();
            let f = 0.25 / e3;
            Vector4::new(
                (a[(1, 0)] - a[(0, 1)]) * f,
                (a[(0, 2)] + a[(2, 0)]) * f,
                (a[(1, 2)] + a[(2, 1)]) * f,
                e3,
            )
        }
    };
    if p[0] < 0.0 { -p } else { p }
}

/// The velocity columns on which a Jacobian row may be nonzero: at most two disjoint ranges
/// (bodies' velocity blocks), in ascending order; empty ranges are absent.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Cols {
    ranges: [Range<usize>; 2],
}

impl Cols {
    /// No columns (a function of time only, or a ground quantity).
    pub fn none() -> Self {
        Self::default()
    }

    /// The columns `r` (one body's velocity block).
    pub fn of(r: Range<usize>) -> Self {
        Self { ranges: [r, 0..0] }
    }

    /// The union of two column sets, each range either equal to or disjoint from the others.
    ///
    /// # Panics
    /// If the union has more than two distinct ranges (quantities of more than two bodies).
    pub fn union(&self, o: &Self) -> Self {
        if self == o || o.is_empty() {
            return self.clone();
        }
        if self.is_empty() {
            return o.clone();
        }
        // the distinct non-empty ranges, on the stack (this runs at every kinematic product)
        let mut out: [Range<usize>; 4] = Default::default();
        let mut n = 0;
        for r in self.ranges.iter().chain(&o.ranges) {
            if !r.is_empty() && !out[..n].contains(r) {
                out[n] = r.clone();
                n += 1;
            }
        }
        let out = &mut out[..n];
        out.sort_by_key(|r| r.start);
        match out {
            [a] => Self::of(a.clone()),
            [a, b] => {
                debug_assert!(a.end <= b.start, "overlapping velocity blocks");
                Self {
                    ranges: [a.clone(), b.clone()],
                }
            }
            _ => panic!("kinematic quantity of more than two bodies"),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.ranges[0].is_empty() && self.ranges[1].is_empty()
    }

    /// Number of columns.
    pub fn len(&self) -> usize {
        self.ranges[0].len() + self.ranges[1].len()
    }

    /// The columns, ascending.
    pub fn iter(&self) -> impl Iterator<Item = usize> + '_ {
        self.ranges[0].clone().chain(self.ranges[1].clone())
    }

    /// Position of column `c` in the stored entries.
    #[inline]
    fn position(&self, c: usize) -> Option<usize> {
        let [a, b] = &self.ranges;
        if a.contains(&c) {
            Some(c - a.start)
        } else if b.contains(&c) {
            Some(a.len() + c - b.start)
        } else {
            None
        }
    }
}

/// A velocity-Jacobian row stored on its [`Cols`] only (zero elsewhere).
#[derive(Clone, Debug, PartialEq)]
pub struct Jac<T> {
    cols: Cols,
    entries: Vec<T>,
}

impl<T: Copy> Jac<T> {
    /// No nonzero columns.
    pub fn empty() -> Self {
        Self {
            cols: Cols::none(),
            entries: Vec::new(),
        }
    }

    /// Entries `f(c)` for the columns `c` of `cols`.
    pub fn from_fn(cols: Cols, f: impl FnMut(usize) -> T) -> Self {
        let entries = cols.iter().map(f).collect();
        Self { cols, entries }
    }

    /// Entries given in the order of `cols`.
    pub fn from_entries(cols: Cols, entries: Vec<T>) -> Self {
        assert_eq!(cols.len(), entries.len(), "one entry per column");
        Self { cols, entries }
    }

    pub fn cols(&self) -> &Cols {
        &self.cols
    }

    /// The entry of column `c` (`zero` outside the stored columns).
    #[inline]
    pub fn get(&self, c: usize, zero: T) -> T {
        match self.cols.position(c) {
            Some(i) => self.entries[i],
            None => zero,
        }
    }

    /// `(column, entry)` pairs, ascending columns.
    pub fn iter(&self) -> impl Iterator<Item = (usize, &T)> + '_ {
        self.cols.iter().zip(&self.entries)
    }

    /// The same row with `f` applied to each entry.
    pub fn map<U: Copy>(&self, f: impl FnMut(&T) -> U) -> Jac<U> {
        Jac {
            cols: self.cols.clone(),
            entries: self.entries.iter().map(f).collect(),
        }
    }

    /// The full row of length `n`.
    pub fn dense(&self, n: usize, zero: T) -> Vec<T> {
        let mut out = vec![zero; n];
        for (c, &x) in self.iter() {
            out[c] = x;
        }
        out
    }

    /// `f(x_c, y_c)` on the union of the columns of `x` and `y`; where only one of them has
    /// the column, `fx(x_c)` or `fy(y_c)`: `f` with the other entry zero, written without the
    /// zero term (the same value up to the sign of a zero).
    fn combine<U: Copy, V: Copy>(
        x: &Self,
        y: &Jac<U>,
        fx: impl Fn(T) -> V,
        fy: impl Fn(U) -> V,
        f: impl Fn(T, U) -> V,
    ) -> Jac<V> {
        if x.cols == y.cols {
            return Jac {
                cols: x.cols.clone(),
                entries: x
                    .entries
                    .iter()
                    .zip(&y.entries)
                    .map(|(&a, &b)| f(a, b))
                    .collect(),
            };
        }
        let cols = x.cols.union(&y.cols);
        Jac::from_fn(cols, |c| match (x.cols.position(c), y.cols.position(c)) {
            (Some(i), Some(j)) => f(x.entries[i], y.entries[j]),
            (Some(i), None) => fx(x.entries[i]),
            (None, Some(j)) => fy(y.entries[j]),
            (None, None) => unreachable!("a column of the union"),
        })
    }
}

/// A scalar kinematic quantity with its rate, quadratic acceleration term and velocity
/// Jacobian row (see the module docs).
#[derive(Clone, Debug)]
pub struct Kin<S: Scalar> {
    pub val: S,
    pub rate: S,
    pub quad: S,
    pub jac: Jac<S>,
}

/// A vector kinematic quantity (global components); `jac` column `i` is `∂(rate)/∂v_i`.
#[derive(Clone, Debug)]
pub struct Kin3<S: Scalar> {
    pub val: Vector3<S>,
    pub rate: Vector3<S>,
    pub quad: Vector3<S>,
    pub jac: Jac<Vector3<S>>,
}

impl<S: Scalar> Kin<S> {
    /// A function of time only: value, first and second derivative; no Jacobian.
    pub fn of_time(f: [S; 3]) -> Self {
        Self {
            val: f[0],
            rate: f[1],
            quad: f[2],
            jac: Jac::empty(),
        }
    }

    pub fn add(&self, o: &Self) -> Self {
        Self {
            val: self.val + o.val,
            rate: self.rate + o.rate,
            quad: self.quad + o.quad,
            jac: Jac::combine(&self.jac, &o.jac, |a| a, |b| b, |a, b| a + b),
        }
    }

    pub fn sub(&self, o: &Self) -> Self {
        Self {
            val: self.val - o.val,
            rate: self.rate - o.rate,
            quad: self.quad - o.quad,
            jac: Jac::combine(&self.jac, &o.jac, |a| a, |b| -b, |a, b| a - b),
        }
    }

    /// Product rule.
    pub fn mul(&self, o: &Self) -> Self {
        Self {
            val: self.val * o.val,
            rate: self.rate * o.val + self.val * o.rate,
            quad: self.quad * o.val + S::from_f64(2.0) * self.rate * o.rate + self.val * o.quad,
            jac: Jac::combine(
                &self.jac,
                &o.jac,
                |a| a * o.val,
                |b| self.val * b,
                |a, b| a * o.val + self.val * b,
            ),
        }
    }
}

impl<S: Scalar> Kin3<S> {
    /// A constant vector: no rate, no Jacobian.
    pub fn constant(val: Vector3<S>) -> Self {
        Self {
            val,
            rate: Vector3::zeros(),
            quad: Vector3::zeros(),
            jac: Jac::empty(),
        }
    }

    pub fn sub(&self, o: &Self) -> Self {
        Self {
            val: self.val - o.val,
            rate: self.rate - o.rate,
            quad: self.quad - o.quad,
            jac: Jac::combine(&self.jac, &o.jac, |a| a, |b| -b, |a, b| a - b),
        }
    }

    /// `self · o` with the product rule.
    pub fn dot(&self, o: &Self) -> Kin<S> {
        Kin {
            val: dot3(&self.val, &o.val),
            rate: dot3(&self.rate, &o.val) + dot3(&self.val, &o.rate),
            quad: dot3(&self.quad, &o.val)
                + S::from_f64(2.0) * dot3(&self.rate, &o.rate)
                + dot3(&self.val, &o.quad),
            jac: Jac::combine(
                &self.jac,
                &o.jac,
                |a| dot3(&a, &o.val),
                |b| dot3(&self.val, &b),
                |a, b| dot3(&a, &o.val) + dot3(&self.val, &b),
            ),
        }
    }

    /// Component `i` as a scalar.
    pub fn component(&self, i: usize) -> Kin<S> {
        Kin {
            val: self.val[i],
            rate: self.rate[i],
            quad: self.quad[i],
            jac: self.jac.map(|a| a[i]),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn kin3(cols: Range<usize>, seed: f64) -> Kin3<f64> {
        let c = Cols::of(cols);
        Kin3 {
            val: Vector3::new(seed, 2.0 * seed, -seed),
            rate: Vector3::new(0.5, -seed, 1.5),
            quad: Vector3::new(seed * seed, 0.25, -1.0),
            jac: Jac::from_fn(c, |i| {
                Vector3::new(i as f64 + seed, -(i as f64), seed * i as f64)
            }),
        }
    }

    #[test]
    fn column_union_is_ascending_and_merges_equal_blocks() {
        let a = Cols::of(6..16);
        let b = Cols::of(0..6);
        let u = a.union(&b);
        assert_eq!(u.iter().collect::<Vec<_>>(), (0..16).collect::<Vec<_>>());
        assert_eq!(a.union(&a), a);
        assert_eq!(a.union(&Cols::none()), a);
        assert_eq!(Cols::none().union(&b), b);
        let c = Cols::of(20..26).union(&b);
        assert_eq!(c.len(), 12);
        assert_eq!(c.iter().collect::<Vec<_>>()[6], 20);
        assert_eq!(c.union(&Cols::of(20..26)), c);
    }

    #[test]
    #[should_panic(expected = "more than two bodies")]
    fn three_bodies_in_one_row_are_refused() {
        let _ = Cols::of(0..6).union(&Cols::of(6..12).union(&Cols::of(12..18)));
    }

    /// Sparse products equal the same products on dense rows.
    #[test]
    fn sparse_rows_match_dense_algebra() {
        let n = 30;
        let a = kin3(3..9, 0.7);
        let b = kin3(20..30, -1.3);
        let dense = |j: &Jac<f64>| j.dense(n, 0.0);
        let dense3 = |j: &Jac<Vector3<f64>>| j.dense(n, Vector3::zeros());
        let (ja, jb) = (dense3(&a.jac), dense3(&b.jac));
        let d = b.sub(&a);
        let dd = dense3(&d.jac);
        for c in 0..n {
            assert_eq!(dd[c], jb[c] - ja[c]);
        }
        let p = a.dot(&b);
        let dp = dense(&p.jac);
        for c in 0..n {
            assert_eq!(dp[c], ja[c].dot(&b.val) + a.val.dot(&jb[c]));
        }
        let comp = d.component(2);
        let m = comp.mul(&p);
        let dm = dense(&m.jac);
        let dc = dense(&comp.jac);
        for c in 0..n {
            assert_eq!(dm[c], dc[c] * p.val + comp.val * dp[c]);
        }
        assert_eq!(m.rate, comp.rate * p.val + comp.val * p.rate);
        let of_time = Kin::of_time([1.0, 2.0, 3.0]);
        let s = m.sub(&of_time);
        assert_eq!(s.jac, m.jac);
        assert_eq!(
            (s.val, s.rate, s.quad),
            (m.val - 1.0, m.rate - 2.0, m.quad - 3.0)
        );
        // entries outside the stored columns read as zero
        assert_eq!(a.jac.get(0, Vector3::zeros()), Vector3::zeros());
        assert_eq!(a.jac.get(4, Vector3::zeros()), Vector3::new(4.7, -4.0, 2.8));
    }
}
