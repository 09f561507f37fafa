//! Rotation helpers (Euler parameters) and the kinematic algebra used by constraints and
//! forces.
//!
//! A [`Kin`] (scalar) or [`Kin3`] (vector) carries a quantity `Φ(q, t)` together with
//! - `rate`: its total time derivative `Φ̇ = Φ_v v + Φ_t`,
//! - `quad`: its second time derivative with the accelerations held at zero,
//!   `Φ̈ − Φ_v v̇` (so that `γ = −quad` in Eq. 9),
//! - `jac`: `Φ_v`, the row(s) multiplying the velocity variables `v` (one entry per velocity
//!   variable of the whole system).
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

/// A scalar kinematic quantity with its rate, quadratic acceleration term and velocity
/// Jacobian row (see the module docs).
#[derive(Clone, Debug)]
pub struct Kin<S: Scalar> {
    pub val: S,
    pub rate: S,
    pub quad: S,
    pub jac: Vec<S>,
}

/// A vector kinematic quantity (global components); `jac[i]` is `∂(rate)/∂v_i`.
#[derive(Clone, Debug)]
pub struct Kin3<S: Scalar> {
    pub val: Vector3<S>,
    pub rate: Vector3<S>,
    pub quad: Vector3<S>,
    pub jac: Vec<Vector3<S>>,
}

impl<S: Scalar> Kin<S> {
    /// A function of time only: value, first and second derivative; no Jacobian.
    pub fn of_time(f: [S; 3], n_v: usize) -> Self {
        Self {
            val: f[0],
            rate: f[1],
            quad: f[2],
            jac: vec![S::zero(); n_v],
        }
    }

    pub fn add(&self, o: &Self) -> Self {
        Self {
            val: self.val + o.val,
            rate: self.rate + o.rate,
            quad: self.quad + o.quad,
            jac: self.jac.iter().zip(&o.jac).map(|(&a, &b)| a + b).collect(),
        }
    }

    pub fn sub(&self, o: &Self) -> Self {
        Self {
            val: self.val - o.val,
            rate: self.rate - o.rate,
            quad: self.quad - o.quad,
            jac: self.jac.iter().zip(&o.jac).map(|(&a, &b)| a - b).collect(),
        }
    }

    /// Product rule.
    pub fn mul(&self, o: &Self) -> Self {
        Self {
            val: self.val * o.val,
            rate: self.rate * o.val + self.val * o.rate,
            quad: self.quad * o.val + S::from_f64(2.0) * self.rate * o.rate + self.val * o.quad,
            jac: self
                .jac
                .iter()
                .zip(&o.jac)
                .map(|(&a, &b)| a * o.val + self.val * b)
                .collect(),
        }
    }
}

/// Columns `cols` (velocity ranges of the bodies involved) of a Jacobian row of length `n`,
/// zero elsewhere: the kinematics of a joint touch only its two bodies' columns.
fn sparse_row<T: Clone>(
    n: usize,
    zero: T,
    cols: &[Range<usize>],
    f: impl Fn(usize) -> T,
) -> Vec<T> {
    let mut jac = vec![zero; n];
    for r in cols {
        for i in r.clone() {
            jac[i] = f(i);
        }
    }
    jac
}

impl<S: Scalar> Kin<S> {
    /// [`Kin::sub`] computing only the Jacobian columns `cols` (the others must be zero in
    /// both operands).
    pub(crate) fn sub_on(&self, o: &Self, cols: &[Range<usize>]) -> Self {
        Self {
            val: self.val - o.val,
            rate: self.rate - o.rate,
            quad: self.quad - o.quad,
            jac: sparse_row(self.jac.len(), S::zero(), cols, |i| self.jac[i] - o.jac[i]),
        }
    }

    /// [`Kin::mul`] computing only the Jacobian columns `cols`.
    pub(crate) fn mul_on(&self, o: &Self, cols: &[Range<usize>]) -> Self {
        Self {
            val: self.val * o.val,
            rate: self.rate * o.val + self.val * o.rate,
            quad: self.quad * o.val + S::from_f64(2.0) * self.rate * o.rate + self.val * o.quad,
            jac: sparse_row(self.jac.len(), S::zero(), cols, |i| {
                self.jac[i] * o.val + self.val * o.jac[i]
            }),
        }
    }
}

impl<S: Scalar> Kin3<S> {
    /// [`Kin3::sub`] computing only the Jacobian columns `cols`.
    pub(crate) fn sub_on(&self, o: &Self, cols: &[Range<usize>]) -> Self {
        Self {
            val: self.val - o.val,
            rate: self.rate - o.rate,
            quad: self.quad - o.quad,
            jac: sparse_row(self.jac.len(), Vector3::zeros(), cols, |i| {
                self.jac[i] - o.jac[i]
            }),
        }
    }

    /// [`Kin3::dot`] computing only the Jacobian columns `cols`.
    pub(crate) fn dot_on(&self, o: &Self, cols: &[Range<usize>]) -> Kin<S> {
        Kin {
            val: self.val.dot(&o.val),
            rate: self.rate.dot(&o.val) + self.val.dot(&o.rate),
            quad: self.quad.dot(&o.val)
                + S::from_f64(2.0) * self.rate.dot(&o.rate)
                + self.val.dot(&o.quad),
            jac: sparse_row(self.jac.len().max(o.jac.len()), S::zero(), cols, |i| {
                self.jac[i].dot(&o.val) + self.val.dot(&o.jac[i])
            }),
        }
    }

    /// [`Kin3::component`] computing only the Jacobian columns `cols`.
    pub(crate) fn component_on(&self, i: usize, cols: &[Range<usize>]) -> Kin<S> {
        Kin {
            val: self.val[i],
            rate: self.rate[i],
            quad: self.quad[i],
            jac: sparse_row(self.jac.len(), S::zero(), cols, |c| self.jac[c][i]),
        }
    }

    pub fn sub(&self, o: &Self) -> Self {
        Self {
            val: self.val - o.val,
            rate: self.rate - o.rate,
            quad: self.quad - o.quad,
            jac: self.jac.iter().zip(&o.jac).map(|(a, b)| a - b).collect(),
        }
    }

    /// `self · o` with the product rule.
    pub fn dot(&self, o: &Self) -> Kin<S> {
        Kin {
            val: self.val.dot(&o.val),
            rate: self.rate.dot(&o.val) + self.val.dot(&o.rate),
            quad: self.quad.dot(&o.val)
                + S::from_f64(2.0) * self.rate.dot(&o.rate)
                + self.val.dot(&o.quad),
            jac: self
                .jac
                .iter()
                .zip(&o.jac)
                .map(|(a, b)| a.dot(&o.val) + self.val.dot(b))
                .collect(),
        }
    }

    /// Component `i` as a scalar.
    pub fn component(&self, i: usize) -> Kin<S> {
        Kin {
            val: self.val[i],
            rate: self.rate[i],
            quad: self.quad[i],
            jac: self.jac.iter().map(|a| a[i]).collect(),
        }
    }
}
