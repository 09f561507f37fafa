//! Small dense helpers generic over [`Scalar`] (inverse of a fixed-size matrix by Gauss–Jordan).

use nalgebra::SMatrix;
use sens::Scalar;

/// Inverse of a small square matrix by Gauss–Jordan elimination with partial pivoting on the
/// values (the pivot order is decided by the values, so duals follow the same branch as their
/// values). Returns `None` when a pivot vanishes.
pub fn invert<S: Scalar, const D: usize>(a: &SMatrix<S, D, D>) -> Option<SMatrix<S, D, D>> {
    let mut m = *a;
    let mut inv = SMatrix::<S, D, D>::identity();
    let scale = a.iter().map(|x| x.value().abs()).fold(0.0, f64::max);
    for c in 0..D {
        let mut p = c;
        for r in c + 1..D {
            if m[(r, c)].value().abs() > m[(p, c)].value().abs() {
                p = r;
            }
        }
        if !(m[(p, c)].value().abs() > 1e-300 * scale.max(1e-300)) {
            return None;
        }
        if p != c {
            m.swap_rows(p, c);
            inv.swap_rows(p, c);
        }
        let piv = S::one() / m[(c, c)];
        for j in 0..D {
            m[(c, j)] *= piv;
            inv[(c, j)] *= piv;
        }
        for r in 0..D {
            if r != c {
                let f = m[(r, c)];
                if f.value() != 0.0 || f.tangents().iter().any(|&t| t != 0.0) {
                    for j in 0..D {
                        let mc = m[(c, j)];
                        let ic = inv[(c, j)];
                        m[(r, j)] -= f * mc;
                        inv[(r, j)] -= f * ic;
                    }
                }
            }
        }
    }
    Some(inv)
}

/// Cross-product matrix `[a×]` with `[a×] b = a × b`.
pub fn skew<S: Scalar>(a: [S; 3]) -> nalgebra::Matrix3<S> {
    let z = S::zero();
    nalgebra::Matrix3::new(z, -a[2], a[1], a[2], z, -a[0], -a[1], a[0], z)
}

/// Gauss–Legendre points and weights on `[0, 1]` for `n ∈ {1, 2, 3, 4}`.
pub fn gauss01(n: usize) -> &'static [(f64, f64)] {
    const G1: [(f64, f64); 1] = [(0.5, 1.0)];
    const G2: [(f64, f64); 2] = [
        (0.211_324_865_405_187_1, 0.5),
        (0.788_675_134_594_812_9, 0.5),
    ];
    const G3: [(f64, f64); 3] = [
        (0.112_701_665_379_258_3, 5.0 / 18.0),
        (0.5, 8.0 / 18.0),
        (0.887_298_334_620_741_7, 5.0 / 18.0),
    ];
    const G4: [(f64, f64); 4] = [
        (0.069_431_844_202_973_71, 0.173_927_422_568_726_9),
        (0.330_009_478_207_571_9, 0.326_072_577_431_273_1),
        (0.669_990_521_792_428_1, 0.326_072_577_431_273_1),
        (0.930_568_155_797_026_3, 0.173_927_422_568_726_9),
    ];
    match n {
        1 => &G1,
        2 => &G2,
        3 => &G3,
        _ => &G4,
    }
}
