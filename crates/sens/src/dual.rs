//! Hand-written forward-mode dual numbers: a value and `N` tangent components.

use std::fmt;
use std::iter::Sum;
use std::ops::{Add, AddAssign, Div, DivAssign, Mul, MulAssign, Neg, Sub, SubAssign};

use num_traits::{One, Zero};

use crate::Scalar;

/// A value `v` with `N` tangent components `d`: the truncated Taylor expansion
/// `v + Σ d_k ε_k` with `ε_j ε_k = 0`.
///
/// Evaluating any function written against [`Scalar`] on duals seeded with unit tangents
/// ([`Dual::variable`], [`crate::seed_chunk`]) gives its partial derivatives exactly, to
/// round-off. Equality and ordering compare the value only.
#[derive(Clone, Copy)]
pub struct Dual<const N: usize> {
    /// The value.
    pub v: f64,
    /// The tangent (derivative) components.
    pub d: [f64; N],
}

impl<const N: usize> Dual<N> {
    /// A value with the given tangents.
    #[inline]
    pub const fn new(v: f64, d: [f64; N]) -> Self {
        Self { v, d }
    }

    /// A constant: all tangents zero.
    #[inline]
    pub const fn constant(v: f64) -> Self {
        Self { v, d: [0.0; N] }
    }

    /// An independent variable: tangent `k` is one, the others zero.
    ///
    /// # Panics
    /// If `k >= N` (a programming error, not a user-input error).
    #[inline]
    pub fn variable(v: f64, k: usize) -> Self {
        assert!(k < N, "tangent index {k} out of range for Dual<{N}>");
        let mut d = [0.0; N];
        d[k] = 1.0;
        Self { v, d }
    }

    /// Chain rule for a unary function with value `f` and derivative `df` at `self.v`.
    #[inline]
    fn chain(self, f: f64, df: f64) -> Self {
        let mut d = self.d;
        for x in &mut d {
            *x *= df;
        }
        Self { v: f, d }
    }

    /// Chain rule where the derivative may be infinite at the point (sqrt at 0, …):
    /// zero tangent components stay zero instead of becoming NaN.
    #[inline]
    fn chain_singular(self, f: f64, df: f64) -> Self {
        let mut d = self.d;
        for x in &mut d {
            *x = if *x == 0.0 { 0.0 } else { *x * df };
        }
        Self { v: f, d }
    }
}

impl<const N: usize> Default for Dual<N> {
    fn default() -> Self {
        Self::constant(0.0)
    }
}

impl<const N: usize> fmt::Debug for Dual<N> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Dual({:?}, {:?})", self.v, self.d)
    }
}

impl<const N: usize> fmt::Display for Dual<N> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(&self.v, f)?;
        if N > 0 {
            write!(f, " + {:?}ε", self.d)?;
        }
        Ok(())
    }
}

impl<const N: usize> PartialEq for Dual<N> {
    fn eq(&self, other: &Self) -> bool {
        self.v == other.v
    }
}

impl<const N: usize> PartialOrd for Dual<N> {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        self.v.partial_cmp(&other.v)
    }
}

impl<const N: usize> From<f64> for Dual<N> {
    fn from(v: f64) -> Self {
        Self::constant(v)
    }
}

// ---- arithmetic between duals -------------------------------------------------------------

impl<const N: usize> Add for Dual<N> {
    type Output = Self;
    #[inline]
    fn add(mut self, rhs: Self) -> Self {
        self += rhs;
        self
    }
}
impl<const N: usize> AddAssign for Dual<N> {
    #[inline]
    fn add_assign(&mut self, rhs: Self) {
        self.v += rhs.v;
        for (a, b) in self.d.iter_mut().zip(rhs.d) {
            *a += b;
        }
    }
}
impl<const N: usize> Sub for Dual<N> {
    type Output = Self;
    #[inline]
    fn sub(mut self, rhs: Self) -> Self {
        self -= rhs;
        self
    }
}
impl<const N: usize> SubAssign for Dual<N> {
    #[inline]
    fn sub_assign(&mut self, rhs: Self) {
        self.v -= rhs.v;
        for (a, b) in self.d.iter_mut().zip(rhs.d) {
            *a -= b;
        }
    }
}
impl<const N: usize> Mul for Dual<N> {
    type Output = Self;
    #[inline]
    fn mul(mut self, rhs: Self) -> Self {
        self *= rhs;
        self
    }
}
impl<const N: usize> MulAssign for Dual<N> {
    #[inline]
    fn mul_assign(&mut self, rhs: Self) {
        for (a, b) in self.d.iter_mut().zip(rhs.d) {
            *a = *a * rhs.v + self.v * b;
        }
        self.v *= rhs.v;
    }
}
impl<const N: usize> Div for Dual<N> {
    type Output = Self;
    #[inline]
    fn div(mut self, rhs: Self) -> Self {
        self /= rhs;
        self
    }
}
impl<const N: usize> DivAssign for Dual<N> {
    #[inline]
    fn div_assign(&mut self, rhs: Self) {
        // the value is divided exactly as f64 would, so both paths give identical values
        let q = self.v / rhs.v;
        for (a, b) in self.d.iter_mut().zip(rhs.d) {
            *a = (*a - q * b) / rhs.v;
        }
        self.v = q;
    }
}
impl<const N: usize> Neg for Dual<N> {
    type Output = Self;
    #[inline]
    fn neg(mut self) -> Self {
        self.v = -self.v;
        for a in &mut self.d {
            *a = -*a;
        }
        self
    }
}

// ---- arithmetic with f64 ------------------------------------------------------------------

impl<const N: usize> Add<f64> for Dual<N> {
    type Output = Self;
    #[inline]
    fn add(mut self, rhs: f64) -> Self {
        self.v += rhs;
        self
    }
}
impl<const N: usize> AddAssign<f64> for Dual<N> {
    #[inline]
    fn add_assign(&mut self, rhs: f64) {
        self.v += rhs;
    }
}
impl<const N: usize> Sub<f64> for Dual<N> {
    type Output = Self;
    #[inline]
    fn sub(mut self, rhs: f64) -> Self {
        self.v -= rhs;
        self
    }
}
impl<const N: usize> SubAssign<f64> for Dual<N> {
    #[inline]
    fn sub_assign(&mut self, rhs: f64) {
        self.v -= rhs;
    }
}
impl<const N: usize> Mul<f64> for Dual<N> {
    type Output = Self;
    #[inline]
    fn mul(mut self, rhs: f64) -> Self {
        self *= rhs;
        self
    }
}
impl<const N: usize> MulAssign<f64> for Dual<N> {
    #[inline]
    fn mul_assign(&mut self, rhs: f64) {
        self.v *= rhs;
        for a in &mut self.d {
            *a *= rhs;
        }
    }
}
impl<const N: usize> Div<f64> for Dual<N> {
    type Output = Self;
    #[inline]
    fn div(mut self, rhs: f64) -> Self {
        self /= rhs;
        self
    }
}
impl<const N: usize> DivAssign<f64> for Dual<N> {
    #[inline]
    fn div_assign(&mut self, rhs: f64) {
        self.v /= rhs;
        for a in &mut self.d {
            *a /= rhs;
        }
    }
}
impl<const N: usize> Add<Dual<N>> for f64 {
    type Output = Dual<N>;
    #[inline]
    fn add(self, rhs: Dual<N>) -> Dual<N> {
        rhs + self
    }
}
impl<const N: usize> Sub<Dual<N>> for f64 {
    type Output = Dual<N>;
    #[inline]
    fn sub(self, rhs: Dual<N>) -> Dual<N> {
        -rhs + self
    }
}
impl<const N: usize> Mul<Dual<N>> for f64 {
    type Output = Dual<N>;
    #[inline]
    fn mul(self, rhs: Dual<N>) -> Dual<N> {
        rhs * self
    }
}
impl<const N: usize> Div<Dual<N>> for f64 {
    type Output = Dual<N>;
    #[inline]
    fn div(self, rhs: Dual<N>) -> Dual<N> {
        Dual::constant(self) / rhs
    }
}

impl<const N: usize> Sum for Dual<N> {
    fn sum<I: Iterator<Item = Self>>(iter: I) -> Self {
        iter.fold(Self::constant(0.0), |a, b| a + b)
    }
}
impl<'a, const N: usize> Sum<&'a Dual<N>> for Dual<N> {
    fn sum<I: Iterator<Item = &'a Self>>(iter: I) -> Self {
        iter.fold(Self::constant(0.0), |a, b| a + *b)
    }
}

impl<const N: usize> Zero for Dual<N> {
    fn zero() -> Self {
        Self::constant(0.0)
    }
    fn is_zero(&self) -> bool {
        self.v == 0.0 && self.d.iter().all(|&x| x == 0.0)
    }
}
impl<const N: usize> One for Dual<N> {
    fn one() -> Self {
        Self::constant(1.0)
    }
}

// ---- elementary functions ------------------------------------------------------------------

impl<const N: usize> Scalar for Dual<N> {
    const TANGENTS: usize = N;
    const PLAIN: bool = false;

    #[inline]
    fn from_f64(x: f64) -> Self {
        Self::constant(x)
    }
    #[inline]
    fn from_parts(value: f64, tangents: &[f64]) -> Self {
        let mut d = [0.0; N];
        for (a, b) in d.iter_mut().zip(tangents) {
            *a = *b;
        }
        Self { v: value, d }
    }
    #[inline]
    fn value(self) -> f64 {
        self.v
    }
    #[inline]
    fn tangents(&self) -> &[f64] {
        &self.d
    }
    #[inline]
    fn sqrt(self) -> Self {
        let s = self.v.sqrt();
        self.chain_singular(s, 0.5 / s)
    }
    #[inline]
    fn sin(self) -> Self {
        let (s, c) = self.v.sin_cos();
        self.chain(s, c)
    }
    #[inline]
    fn cos(self) -> Self {
        let (s, c) = self.v.sin_cos();
        self.chain(c, -s)
    }
    #[inline]
    fn tan(self) -> Self {
        let t = self.v.tan();
        self.chain(t, 1.0 + t * t)
    }
    #[inline]
    fn asin(self) -> Self {
        self.chain_singular(self.v.asin(), 1.0 / (1.0 - self.v * self.v).sqrt())
    }
    #[inline]
    fn acos(self) -> Self {
        self.chain_singular(self.v.acos(), -1.0 / (1.0 - self.v * self.v).sqrt())
    }
    #[inline]
    fn atan(self) -> Self {
        self.chain(self.v.atan(), 1.0 / (1.0 + self.v * self.v))
    }
    #[inline]
    fn atan2(self, x: Self) -> Self {
        // d atan2(y, x) = (x dy - y dx) / (x² + y²)
        let y = self;
        let r2 = x.v * x.v + y.v * y.v;
        let mut d = [0.0; N];
        if r2 > 0.0 {
            for k in 0..N {
                d[k] = (x.v * y.d[k] - y.v * x.d[k]) / r2;
            }
        }
        Self {
            v: y.v.atan2(x.v),
            d,
        }
    }
    #[inline]
    fn exp(self) -> Self {
        let e = self.v.exp();
        self.chain(e, e)
    }
    #[inline]
    fn ln(self) -> Self {
        self.chain_singular(self.v.ln(), 1.0 / self.v)
    }
    #[inline]
    fn powi(self, n: i32) -> Self {
        match n {
            0 => Self::constant(1.0),
            1 => self,
            _ => self.chain_singular(self.v.powi(n), f64::from(n) * self.v.powi(n - 1)),
        }
    }
    #[inline]
    fn powf(self, p: Self) -> Self {
        let f = self.v.powf(p.v);
        if p.d.iter().all(|&x| x == 0.0) {
            // constant exponent: valid for a negative base with an integral exponent too
            if p.v == 0.0 {
                return Self::constant(1.0);
            }
            return self.chain_singular(f, p.v * self.v.powf(p.v - 1.0));
        }
        // d(a^p) = a^p (p' ln a + p a'/a)
        let ln_a = self.v.ln();
        let mut d = [0.0; N];
        for k in 0..N {
            let base = if self.d[k] == 0.0 {
                0.0
            } else {
                p.v * self.d[k] / self.v
            };
            d[k] = f * (p.d[k] * ln_a + base);
        }
        Self { v: f, d }
    }
    #[inline]
    fn abs(self) -> Self {
        if self.v < 0.0 { -self } else { self }
    }
    #[inline]
    fn hypot(self, other: Self) -> Self {
        let h = self.v.hypot(other.v);
        let mut d = [0.0; N];
        if h > 0.0 {
            for k in 0..N {
                d[k] = (self.v * self.d[k] + other.v * other.d[k]) / h;
            }
        }
        Self { v: h, d }
    }
    #[inline]
    fn sin_cos(self) -> (Self, Self) {
        let (s, c) = self.v.sin_cos();
        (self.chain(s, c), self.chain(c, -s))
    }
}
