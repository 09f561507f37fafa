//! Seeding design variables and chunked evaluation of gradients and Jacobians.
//!
//! Forward mode carries `N` tangents per evaluation. A function of `M > N` design variables is
//! evaluated `ceil(M / N)` times, each time seeding the next chunk of `N` variables with unit
//! tangents; the chunks' tangent columns are assembled into the full Jacobian. The result does
//! not depend on the chunk width (each column comes from exactly one chunk).

use std::ops::Range;

use nalgebra::DMatrix;

use crate::Dual;

/// The chunks of width `width` that cover design variables `0..m`.
///
/// # Panics
/// If `width == 0`.
pub fn chunk_ranges(m: usize, width: usize) -> impl Iterator<Item = Range<usize>> {
    assert!(width > 0, "chunk width must be positive");
    (0..m.div_ceil(width)).map(move |c| c * width..((c + 1) * width).min(m))
}

/// The design vector `b` as duals, with variables `start .. start + N` (those that exist) seeded
/// with unit tangents `0 .. N` and every other variable a constant.
pub fn seed_chunk<const N: usize>(b: &[f64], start: usize) -> Vec<Dual<N>> {
    b.iter()
        .enumerate()
        .map(|(i, &v)| {
            if i >= start && i < start + N {
                Dual::variable(v, i - start)
            } else {
                Dual::constant(v)
            }
        })
        .collect()
}

/// Value and Jacobian of a vector function.
#[derive(Clone, Debug)]
pub struct Jacobian {
    /// `f(b)`.
    pub value: Vec<f64>,
    /// `∂f_i/∂b_j`, one row per output, one column per design variable.
    pub jacobian: DMatrix<f64>,
}

/// Value and Jacobian of `f` at `b`, evaluated in chunks of `N` design variables.
///
/// `f` must return the same number of outputs on every call.
///
/// # Panics
/// If `f` returns outputs of different lengths for different chunks (a programming error).
pub fn jacobian<const N: usize, F>(b: &[f64], mut f: F) -> Jacobian
where
    F: FnMut(&[Dual<N>]) -> Vec<Dual<N>>,
{
    assert!(N > 0, "Dual<0> carries no tangents");
    let m = b.len();
    if m == 0 {
        let value: Vec<f64> = f(&seed_chunk::<N>(b, 0)).iter().map(|x| x.v).collect();
        let rows = value.len();
        return Jacobian {
            value,
            jacobian: DMatrix::zeros(rows, 0),
        };
    }
    let mut value = Vec::new();
    let mut jac = DMatrix::zeros(0, m);
    for range in chunk_ranges(m, N) {
        let out = f(&seed_chunk::<N>(b, range.start));
        if range.start == 0 {
            value = out.iter().map(|x| x.v).collect();
            jac = DMatrix::zeros(out.len(), m);
        }
        assert_eq!(
            out.len(),
            value.len(),
            "function output length changed between chunks"
        );
        for (i, y) in out.iter().enumerate() {
            for (k, j) in range.clone().enumerate() {
                jac[(i, j)] = y.d[k];
            }
        }
    }
    Jacobian {
        value,
        jacobian: jac,
    }
}

/// Value and gradient of a scalar function, evaluated in chunks of `N` design variables.
pub fn gradient<const N: usize, F>(b: &[f64], mut f: F) -> (f64, Vec<f64>)
where
    F: FnMut(&[Dual<N>]) -> Dual<N>,
{
    let j = jacobian::<N, _>(b, |x| vec![f(x)]);
    (j.value[0], j.jacobian.row(0).iter().copied().collect())
}
