//! The [`Scalar`] trait: the one numeric generic of flexsens.

use std::fmt::{Debug, Display};
use std::iter::Sum;
use std::ops::{Add, AddAssign, Div, DivAssign, Mul, MulAssign, Neg, Sub, SubAssign};
use std::rc::Rc;

use num_traits::{One, Zero};

use crate::LinearSolver;

/// Real arithmetic that every numerical routine of flexsens is generic over.
///
/// Implemented for `f64` (plain analysis) and for [`crate::Dual<N>`] (value plus `N` tangents).
/// Comparisons (`==`, `<`, …) look at the value only, so that branches take the same path for a
/// dual number as for its value. Mixed arithmetic with `f64` on the right (`x * 2.0`) is
/// available; write constants on the left as `S::from_f64(2.0) * x`.
///
/// The supertraits make the type usable inside nalgebra matrices for products (`Zero`, `One`,
/// closed `+`/`*`), which is all the design needs: decompositions are done in `f64` and tangents
/// pushed through them with [`crate::solve_tangents`].
pub trait Scalar:
    Copy
    + Debug
    + Display
    + Default
    + PartialEq
    + PartialOrd
    + Send
    + Sync
    + 'static
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + AddAssign
    + SubAssign
    + MulAssign
    + DivAssign
    + Add<f64, Output = Self>
    + Sub<f64, Output = Self>
    + Mul<f64, Output = Self>
    + Div<f64, Output = Self>
    + AddAssign<f64>
    + SubAssign<f64>
    + MulAssign<f64>
    + DivAssign<f64>
    + From<f64>
    + Zero
    + One
    + Sum
{
    /// Number of tangent components carried (0 for `f64` and for the taped [`crate::Rev`]).
    const TANGENTS: usize;
    /// Whether the type is a plain number with no derivative information of any kind (`f64`):
    /// code may then use a value in its place, e.g. scale by a parameter's value rather than
    /// multiply by the lifted parameter. `false` for every differentiating type, the taped
    /// [`crate::Rev`] included (which carries no tangents, yet a value in its place would cut it
    /// from the tape).
    const PLAIN: bool;

    /// A constant (all tangents zero).
    fn from_f64(x: f64) -> Self;
    /// A value with given tangents, e.g. a result whose derivatives were computed elsewhere
    /// (chain rule through a precomputed Jacobian). Tangents beyond [`Scalar::TANGENTS`] are
    /// ignored, missing ones are zero; `f64` keeps the value only.
    fn from_parts(value: f64, tangents: &[f64]) -> Self;
    /// The value, without tangents.
    fn value(self) -> f64;
    /// The tangent components (empty for `f64`).
    fn tangents(&self) -> &[f64];
    /// Tangent component `k`, 0 when `k` is beyond [`Scalar::TANGENTS`].
    fn tangent(&self, k: usize) -> f64 {
        self.tangents().get(k).copied().unwrap_or(0.0)
    }

    fn sqrt(self) -> Self;
    fn sin(self) -> Self;
    fn cos(self) -> Self;
    fn tan(self) -> Self;
    fn asin(self) -> Self;
    fn acos(self) -> Self;
    fn atan(self) -> Self;
    /// Four-quadrant arctangent of `self / x` (`self` is `y`).
    fn atan2(self, x: Self) -> Self;
    fn exp(self) -> Self;
    /// Natural logarithm.
    fn ln(self) -> Self;
    fn powi(self, n: i32) -> Self;
    fn powf(self, p: Self) -> Self;
    fn abs(self) -> Self;
    /// `sqrt(self² + other²)` without needless overflow.
    fn hypot(self, other: Self) -> Self;

    /// `a_0 b_0 + a_1 b_1 + …`, added left to right (`a`, `b` of one length, zero if empty):
    /// one node on the reverse-mode tape whatever the length ([`crate::Rev`]), the operations
    /// as written out for the other types.
    #[inline]
    fn dot(a: &[Self], b: &[Self]) -> Self {
        debug_assert_eq!(a.len(), b.len(), "dot of two slices of one length");
        match (a.split_first(), b.split_first()) {
            (Some((&a0, a)), Some((&b0, b))) => {
                (a.iter().zip(b)).fold(a0 * b0, |s, (&x, &y)| s + x * y)
            }
            _ => Self::zero(),
        }
    }
    /// `init − a_0 x_0 − a_1 x_1 − …`, subtracted left to right (`a`, `x` of one length): one
    /// node on the reverse-mode tape ([`crate::Rev`]), as written out for the other types.
    #[inline]
    fn sub_scaled(init: Self, a: &[Self], x: &[f64]) -> Self {
        debug_assert_eq!(a.len(), x.len(), "sub_scaled of two slices of one length");
        (a.iter().zip(x)).fold(init, |s, (&a, &x)| s - a * x)
    }
    /// `sin` and `cos` together.
    fn sin_cos(self) -> (Self, Self) {
        (self.sin(), self.cos())
    }
    /// The larger by value (the first on a tie).
    fn max(self, other: Self) -> Self {
        if other.value() > self.value() {
            other
        } else {
            self
        }
    }
    /// The smaller by value (the first on a tie).
    fn min(self, other: Self) -> Self {
        if other.value() < self.value() {
            other
        } else {
            self
        }
    }
    /// Whether the value and every tangent are finite.
    fn is_finite(self) -> bool {
        self.value().is_finite() && self.tangents().iter().all(|t| t.is_finite())
    }
    /// Whether this is a constant: no tangent (and for [`crate::Rev`] no node on the tape).
    fn is_constant(&self) -> bool {
        self.tangents().iter().all(|&t| t == 0.0)
    }
    /// `x = A⁻¹ g` for the `ncols` right-hand sides `g` (column-major, `A`'s order each) in
    /// this scalar, `A` a constant symmetric matrix whose solves `solver` makes, `x_values` the
    /// solutions of the values of `g` (solved already): the tangents solved by `solver` one
    /// after another ([`crate::Dual`]), or one operation on the reverse-mode tape whose reverse
    /// is `ḡ = A⁻¹ x̄` ([`crate::Rev`]); `f64` keeps the values. A matrix with tangents of its own
    /// enters through `g`: `g = f − (A − A₀) x₀` has the tangents `f' − A' x₀`.
    fn symmetric_solution(
        g: &[Self],
        x_values: Vec<f64>,
        ncols: usize,
        solver: &Rc<dyn LinearSolver>,
    ) -> Vec<Self> {
        check_solution_sizes(g.len(), x_values.len(), solver.dim(), ncols);
        let tangents: Vec<Vec<f64>> = (0..Self::TANGENTS)
            .map(|t| {
                let mut r: Vec<f64> = g.iter().map(|x| x.tangent(t)).collect();
                solver.solve_columns(&mut r, ncols);
                r
            })
            .collect();
        let mut buf = vec![0.0; Self::TANGENTS];
        (x_values.iter().enumerate())
            .map(|(i, &v)| {
                buf.iter_mut().zip(&tangents).for_each(|(b, t)| *b = t[i]);
                Self::from_parts(v, &buf)
            })
            .collect()
    }
}

impl Scalar for f64 {
    const TANGENTS: usize = 0;
    const PLAIN: bool = true;

    #[inline]
    fn from_f64(x: f64) -> Self {
        x
    }
    #[inline]
    fn from_parts(value: f64, _tangents: &[f64]) -> Self {
        value
    }
    #[inline]
    fn value(self) -> f64 {
        self
    }
    #[inline]
    fn tangents(&self) -> &[f64] {
        &[]
    }
    #[inline]
    fn sqrt(self) -> Self {
        f64::sqrt(self)
    }
    #[inline]
    fn sin(self) -> Self {
        f64::sin(self)
    }
    #[inline]
    fn cos(self) -> Self {
        f64::cos(self)
    }
    #[inline]
    fn tan(self) -> Self {
        f64::tan(self)
    }
    #[inline]
    fn asin(self) -> Self {
        f64::asin(self)
    }
    #[inline]
    fn acos(self) -> Self {
        f64::acos(self)
    }
    #[inline]
    fn atan(self) -> Self {
        f64::atan(self)
    }
    #[inline]
    fn atan2(self, x: Self) -> Self {
        f64::atan2(self, x)
    }
    #[inline]
    fn exp(self) -> Self {
        f64::exp(self)
    }
    #[inline]
    fn ln(self) -> Self {
        f64::ln(self)
    }
    #[inline]
    fn powi(self, n: i32) -> Self {
        f64::powi(self, n)
    }
    #[inline]
    fn powf(self, p: Self) -> Self {
        f64::powf(self, p)
    }
    #[inline]
    fn abs(self) -> Self {
        f64::abs(self)
    }
    #[inline]
    fn hypot(self, other: Self) -> Self {
        f64::hypot(self, other)
    }
    #[inline]
    fn sin_cos(self) -> (Self, Self) {
        f64::sin_cos(self)
    }
}

/// # Panics
/// Unless there are as many solutions as right-hand sides, `ncols` columns of the matrix's
/// order `dim` ([`Scalar::symmetric_solution`]).
pub(crate) fn check_solution_sizes(rhs: usize, solutions: usize, dim: usize, ncols: usize) {
    assert_eq!(rhs, solutions, "as many solutions as right-hand sides");
    assert_eq!(rhs, dim * ncols, "right-hand sides of the matrix's order");
}
