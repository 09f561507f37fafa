//! Hyper-dual numbers: two first-order tangents and their mixed second-order part, for the
//! derivative of a directional derivative (the design derivative of a linearised operator
//! applied to a mode, docs/operating-points.md).

use std::fmt;
use std::iter::Sum;
use std::ops::{Add, AddAssign, Div, DivAssign, Mul, MulAssign, Neg, Sub, SubAssign};

use num_traits::{One, Zero};

use crate::Scalar;

/// `v + d₁ ε₁ + d₂ ε₂ + d₁₂ ε₁ε₂` with `ε₁² = ε₂² = 0`: evaluating a function `f` on
/// `x + u ε₁ + w ε₂` gives `f`, its derivatives along `u` and `w`, and `uᵀ f'' w` exactly.
///
/// As a [`Scalar`] it carries two tangents (`d₁`, `d₂`); the mixed part `d₁₂` is read with
/// [`HyperDual::mixed`]. Comparisons look at the value only.
#[derive(Clone, Copy, Default)]
pub struct HyperDual {
    pub v: f64,
    /// `[d₁, d₂]`.
    pub d: [f64; 2],
    /// `d₁₂`.
    pub dd: f64,
}

impl HyperDual {
    /// A value with first-order parts `d1`, `d2` and no mixed part.
    #[inline]
    pub const fn new(v: f64, d1: f64, d2: f64) -> Self {
        Self {
            v,
            d: [d1, d2],
            dd: 0.0,
        }
    }

    /// The mixed second-order part `d₁₂`.
    #[inline]
    pub fn mixed(self) -> f64 {
        self.dd
    }

    /// `f(self)` from `f`, `f'` and `f''` at the value.
    #[inline]
    fn chain(self, f: f64, df: f64, ddf: f64) -> Self {
        Self {
            v: f,
            d: [df * self.d[0], df * self.d[1]],
            dd: df * self.dd + ddf * self.d[0] * self.d[1],
        }
    }
}

impl fmt::Debug for HyperDual {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} + {}ε₁ + {}ε₂ + {}ε₁ε₂",
            self.v, self.d[0], self.d[1], self.dd
        )
    }
}

impl fmt::Display for HyperDual {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(&self.v, f)
    }
}

impl PartialEq for HyperDual {
    fn eq(&self, other: &Self) -> bool {
        self.v == other.v
    }
}

impl PartialOrd for HyperDual {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        self.v.partial_cmp(&other.v)
    }
}

impl From<f64> for HyperDual {
    fn from(v: f64) -> Self {
        Self::new(v, 0.0, 0.0)
    }
}

impl AddAssign for HyperDual {
    #[inline]
    fn add_assign(&mut self, r: Self) {
        self.v += r.v;
        self.d[0] += r.d[0];
        self.d[1] += r.d[1];
        self.dd += r.dd;
    }
}
impl SubAssign for HyperDual {
    #[inline]
    fn sub_assign(&mut self, r: Self) {
        self.v -= r.v;
        self.d[0] -= r.d[0];
        self.d[1] -= r.d[1];
        self.dd -= r.dd;
    }
}
impl MulAssign for HyperDual {
    #[inline]
    fn mul_assign(&mut self, r: Self) {
        let dd = self.v * r.dd + self.dd * r.v + self.d[0] * r.d[1] + self.d[1] * r.d[0];
        self.d = [
            self.d[0] * r.v + self.v * r.d[0],
            self.d[1] * r.v + self.v * r.d[1],
        ];
        self.dd = dd;
        self.v *= r.v;
    }
}
impl DivAssign for HyperDual {
    #[inline]
    fn div_assign(&mut self, r: Self) {
        let inv = 1.0 / r.v;
        let reciprocal = r.chain(inv, -inv * inv, 2.0 * inv * inv * inv);
        let v = self.v / r.v;
        *self *= reciprocal;
        // the value divided exactly as f64 would
        self.v = v;
    }
}

macro_rules! binary {
    ($tr:ident, $f:ident, $assign:ident, $fa:ident) => {
        impl $tr for HyperDual {
            type Output = Self;
            #[inline]
            fn $f(mut self, r: Self) -> Self {
                self.$fa(r);
                self
            }
        }
        impl $tr<f64> for HyperDual {
            type Output = Self;
            #[inline]
            fn $f(mut self, r: f64) -> Self {
                self.$fa(HyperDual::from(r));
                self
            }
        }
        impl $assign<f64> for HyperDual {
            #[inline]
            fn $fa(&mut self, r: f64) {
                self.$fa(HyperDual::from(r));
            }
        }
    };
}
binary!(Add, add, AddAssign, add_assign);
binary!(Sub, sub, SubAssign, sub_assign);
binary!(Mul, mul, MulAssign, mul_assign);
binary!(Div, div, DivAssign, div_assign);

impl Neg for HyperDual {
    type Output = Self;
    #[inline]
    fn neg(self) -> Self {
        Self {
            v: -self.v,
            d: [-self.d[0], -self.d[1]],
            dd: -self.dd,
        }
    }
}

impl Sum for HyperDual {
    fn sum<I: Iterator<Item = Self>>(iter: I) -> Self {
        iter.fold(Self::zero(), |a, b| a + b)
    }
}

impl Zero for HyperDual {
    fn zero() -> Self {
        Self::from(0.0)
    }
    fn is_zero(&self) -> bool {
        self.v == 0.0 && self.is_constant()
    }
}

impl One for HyperDual {
    fn one() -> Self {
        Self::from(1.0)
    }
}

impl Scalar for HyperDual {
    const TANGENTS: usize = 2;
    const PLAIN: bool = false;

    fn from_f64(x: f64) -> Self {
        Self::from(x)
    }
    fn from_parts(value: f64, tangents: &[f64]) -> Self {
        let t = |k: usize| tangents.get(k).copied().unwrap_or(0.0);
        Self::new(value, t(0), t(1))
    }
    fn is_constant(&self) -> bool {
        self.d == [0.0, 0.0] && self.dd == 0.0
    }
    /// The first-order parts and the mixed part each solved ([`Scalar::symmetric_solution`]
    /// is linear in the right-hand sides).
    fn symmetric_solution(
        g: &[Self],
        x_values: Vec<f64>,
        ncols: usize,
        solver: &std::rc::Rc<dyn crate::LinearSolver>,
    ) -> Vec<Self> {
        crate::scalar::check_solution_sizes(g.len(), x_values.len(), solver.dim(), ncols);
        let part = |f: &dyn Fn(&Self) -> f64| {
            let mut r: Vec<f64> = g.iter().map(f).collect();
            solver.solve_columns(&mut r, ncols);
            r
        };
        let (d1, d2, dd) = (part(&|x| x.d[0]), part(&|x| x.d[1]), part(&|x| x.dd));
        (x_values.iter().enumerate())
            .map(|(i, &v)| Self {
                v,
                d: [d1[i], d2[i]],
                dd: dd[i],
            })
            .collect()
    }
    fn value(self) -> f64 {
        self.v
    }
    fn tangents(&self) -> &[f64] {
        &self.d
    }
    fn sqrt(self) -> Self {
        if self.v == 0.0 && self.is_constant() {
            return self;
        }
        let s = self.v.sqrt();
        self.chain(s, 0.5 / s, -0.25 / (s * self.v))
    }
    fn sin(self) -> Self {
        let (s, c) = self.v.sin_cos();
        self.chain(s, c, -s)
    }
    fn cos(self) -> Self {
        let (s, c) = self.v.sin_cos();
        self.chain(c, -s, -c)
    }
    fn tan(self) -> Self {
        let t = self.v.tan();
        let sec2 = 1.0 + t * t;
        self.chain(t, sec2, 2.0 * t * sec2)
    }
    fn asin(self) -> Self {
        let r = 1.0 - self.v * self.v;
        self.chain(self.v.asin(), 1.0 / r.sqrt(), self.v / (r * r.sqrt()))
    }
    fn acos(self) -> Self {
        let r = 1.0 - self.v * self.v;
        self.chain(self.v.acos(), -1.0 / r.sqrt(), -self.v / (r * r.sqrt()))
    }
    fn atan(self) -> Self {
        let r = 1.0 + self.v * self.v;
        self.chain(self.v.atan(), 1.0 / r, -2.0 * self.v / (r * r))
    }
    fn atan2(self, x: Self) -> Self {
        // the derivatives of atan of the better-conditioned ratio; the value atan2's
        let mut a = if x.v.abs() >= self.v.abs() {
            (self / x).atan()
        } else {
            -(x / self).atan()
        };
        a.v = self.v.atan2(x.v);
        a
    }
    fn exp(self) -> Self {
        let e = self.v.exp();
        self.chain(e, e, e)
    }
    fn ln(self) -> Self {
        self.chain(self.v.ln(), 1.0 / self.v, -1.0 / (self.v * self.v))
    }
    fn powi(self, n: i32) -> Self {
        match n {
            0 => Self::one(),
            1 => self,
            _ => {
                let nf = n as f64;
                self.chain(
                    self.v.powi(n),
                    nf * self.v.powi(n - 1),
                    nf * (nf - 1.0) * self.v.powi(n - 2),
                )
            }
        }
    }
    fn powf(self, p: Self) -> Self {
        if p.is_constant() {
            let e = p.v;
            return self.chain(
                self.v.powf(e),
                e * self.v.powf(e - 1.0),
                e * (e - 1.0) * self.v.powf(e - 2.0),
            );
        }
        let mut r = (self.ln() * p).exp();
        r.v = self.v.powf(p.v);
        r
    }
    fn abs(self) -> Self {
        if self.v < 0.0 { -self } else { self }
    }
    fn hypot(self, other: Self) -> Self {
        let mut h = (self * self + other * other).sqrt();
        h.v = self.v.hypot(other.v);
        h
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `f(x, y)` written against `Scalar`.
    fn f<S: Scalar>(x: S, y: S) -> S {
        (x * y).sin() + x.powi(3) / y + (x * x + y * y).sqrt() * y.exp() + y.atan2(x)
            - x.hypot(y).ln()
            + x.powf(y)
    }

    #[test]
    fn the_mixed_part_is_the_second_derivative_along_both_directions() {
        let (x, y) = (0.7, 1.3);
        let (u, w) = ([0.3, -0.8], [1.1, 0.4]);
        let r = f(
            HyperDual {
                v: x,
                d: [u[0], w[0]],
                dd: 0.0,
            },
            HyperDual {
                v: y,
                d: [u[1], w[1]],
                dd: 0.0,
            },
        );
        assert_eq!(r.v, f(x, y));
        // central differences of f along u and w
        let h = 1e-4;
        let g = |a: f64, b: f64| f(x + a * u[0] + b * w[0], y + a * u[1] + b * w[1]);
        let du = (g(h, 0.0) - g(-h, 0.0)) / (2.0 * h);
        let dw = (g(0.0, h) - g(0.0, -h)) / (2.0 * h);
        let duw = (g(h, h) - g(h, -h) - g(-h, h) + g(-h, -h)) / (4.0 * h * h);
        assert!((r.d[0] - du).abs() < 1e-7, "{} vs {du}", r.d[0]);
        assert!((r.d[1] - dw).abs() < 1e-7, "{} vs {dw}", r.d[1]);
        assert!(
            (r.dd - duw).abs() < 1e-5 * duw.abs().max(1.0),
            "{} vs {duw}",
            r.dd
        );
    }
}
