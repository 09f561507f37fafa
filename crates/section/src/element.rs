//! Quadratic isoparametric section elements: shape functions and integration rules.

/// The quadratic element families (node orders as in Gmsh).
///
/// - `Tri6`: corners `(0,0) (1,0) (0,1)`, then mid-sides of edges 0–1, 1–2, 2–0.
/// - `Quad8`: corners `(−1,−1) (1,−1) (1,1) (−1,1)`, then mid-sides of edges 0–1, 1–2, 2–3, 3–0
///   (serendipity).
/// - `Quad9`: as `Quad8` plus the centre node (Lagrange).
///
/// Corners are numbered counter-clockwise in the `(x₂, x₃)` plane; a clockwise element is
/// reported as inverted.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ElementKind {
    Tri6,
    Quad8,
    Quad9,
}

/// The largest number of nodes of any element kind.
pub const MAX_NODES: usize = 9;

const G3: f64 = 0.774_596_669_241_483_4; // sqrt(3/5)
const W3: [f64; 3] = [5.0 / 9.0, 8.0 / 9.0, 5.0 / 9.0];
const P3: [f64; 3] = [-G3, 0.0, G3];

/// 3×3 Gauss rule on `[−1, 1]²` (exact for bi-quintic integrands).
const QUAD_RULE: [(f64, f64, f64); 9] = {
    let mut r = [(0.0, 0.0, 0.0); 9];
    let mut i = 0;
    while i < 3 {
        let mut j = 0;
        while j < 3 {
            r[3 * i + j] = (P3[i], P3[j], W3[i] * W3[j]);
            j += 1;
        }
        i += 1;
    }
    r
};

// Strang–Fix / Dunavant 6-point rule of degree 4 on the reference triangle (weights sum to ½).
const TA: f64 = 0.445_948_490_915_965;
const TB: f64 = 0.091_576_213_509_771;
const TWA: f64 = 0.223_381_589_678_011 / 2.0;
const TWB: f64 = 0.109_951_743_655_322 / 2.0;
const TRI_RULE: [(f64, f64, f64); 6] = [
    (TA, TA, TWA),
    (1.0 - 2.0 * TA, TA, TWA),
    (TA, 1.0 - 2.0 * TA, TWA),
    (TB, TB, TWB),
    (1.0 - 2.0 * TB, TB, TWB),
    (TB, 1.0 - 2.0 * TB, TWB),
];

impl ElementKind {
    /// Number of nodes.
    pub fn node_count(self) -> usize {
        match self {
            ElementKind::Tri6 => 6,
            ElementKind::Quad8 => 8,
            ElementKind::Quad9 => 9,
        }
    }

    /// Number of corner nodes (the first ones).
    pub fn corner_count(self) -> usize {
        match self {
            ElementKind::Tri6 => 3,
            _ => 4,
        }
    }

    /// A short name for messages.
    pub fn name(self) -> &'static str {
        match self {
            ElementKind::Tri6 => "6-node triangle",
            ElementKind::Quad8 => "8-node quadrilateral",
            ElementKind::Quad9 => "9-node quadrilateral",
        }
    }

    /// Integration points `(ξ, η, weight)` in the reference element.
    pub(crate) fn rule(self) -> &'static [(f64, f64, f64)] {
        match self {
            ElementKind::Tri6 => &TRI_RULE,
            _ => &QUAD_RULE,
        }
    }

    /// Shape functions `n[a]` and their reference derivatives `dn[a] = [∂/∂ξ, ∂/∂η]` at
    /// `(xi, eta)`.
    pub(crate) fn shape(self, xi: f64, eta: f64, n: &mut [f64], dn: &mut [[f64; 2]]) {
        match self {
            ElementKind::Tri6 => {
                let l = [1.0 - xi - eta, xi, eta];
                // dL/dξ, dL/dη
                let dl = [[-1.0, -1.0], [1.0, 0.0], [0.0, 1.0]];
                for a in 0..3 {
                    n[a] = l[a] * (2.0 * l[a] - 1.0);
                    for k in 0..2 {
                        dn[a][k] = (4.0 * l[a] - 1.0) * dl[a][k];
                    }
                }
                const EDGES: [(usize, usize); 3] = [(0, 1), (1, 2), (2, 0)];
                for (m, &(i, j)) in EDGES.iter().enumerate() {
                    n[3 + m] = 4.0 * l[i] * l[j];
                    for k in 0..2 {
                        dn[3 + m][k] = 4.0 * (dl[i][k] * l[j] + l[i] * dl[j][k]);
                    }
                }
            }
            ElementKind::Quad8 => {
                const C: [(f64, f64); 4] = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)];
                for (a, &(xa, ya)) in C.iter().enumerate() {
                    let (p, q) = (1.0 + xi * xa, 1.0 + eta * ya);
                    let s = xi * xa + eta * ya - 1.0;
                    n[a] = 0.25 * p * q * s;
                    dn[a][0] = 0.25 * xa * q * (s + p);
                    dn[a][1] = 0.25 * ya * p * (s + q);
                }
                // Mid-sides on η = ∓1 (nodes 4, 6) and ξ = ±1 (nodes 5, 7).
                for (a, ya) in [(4, -1.0), (6, 1.0)] {
                    n[a] = 0.5 * (1.0 - xi * xi) * (1.0 + eta * ya);
                    dn[a][0] = -xi * (1.0 + eta * ya);
                    dn[a][1] = 0.5 * (1.0 - xi * xi) * ya;
                }
                for (a, xa) in [(5, 1.0), (7, -1.0)] {
                    n[a] = 0.5 * (1.0 + xi * xa) * (1.0 - eta * eta);
                    dn[a][0] = 0.5 * xa * (1.0 - eta * eta);
                    dn[a][1] = -eta * (1.0 + xi * xa);
                }
            }
            ElementKind::Quad9 => {
                // 1-D quadratic Lagrange polynomials at −1, 0, 1 and their derivatives.
                let l = |s: f64| [0.5 * s * (s - 1.0), 1.0 - s * s, 0.5 * s * (s + 1.0)];
                let dl = |s: f64| [s - 0.5, -2.0 * s, s + 0.5];
                let (lx, ly, dlx, dly) = (l(xi), l(eta), dl(xi), dl(eta));
                // Node a ↦ (index in ξ, index in η).
                const IJ: [(usize, usize); 9] = [
                    (0, 0),
                    (2, 0),
                    (2, 2),
                    (0, 2),
                    (1, 0),
                    (2, 1),
                    (1, 2),
                    (0, 1),
                    (1, 1),
                ];
                for (a, &(i, j)) in IJ.iter().enumerate() {
                    n[a] = lx[i] * ly[j];
                    dn[a][0] = dlx[i] * ly[j];
                    dn[a][1] = lx[i] * dly[j];
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Partition of unity and exact reproduction of x and y at every integration point.
    #[test]
    fn shape_functions_reproduce_linear_fields() {
        let coords: &[(ElementKind, &[[f64; 2]])] = &[
            (
                ElementKind::Tri6,
                &[
                    [0.0, 0.0],
                    [1.0, 0.0],
                    [0.0, 1.0],
                    [0.5, 0.0],
                    [0.5, 0.5],
                    [0.0, 0.5],
                ],
            ),
            (
                ElementKind::Quad8,
                &[
                    [-1.0, -1.0],
                    [1.0, -1.0],
                    [1.0, 1.0],
                    [-1.0, 1.0],
                    [0.0, -1.0],
                    [1.0, 0.0],
                    [0.0, 1.0],
                    [-1.0, 0.0],
                ],
            ),
            (
                ElementKind::Quad9,
                &[
                    [-1.0, -1.0],
                    [1.0, -1.0],
                    [1.0, 1.0],
                    [-1.0, 1.0],
                    [0.0, -1.0],
                    [1.0, 0.0],
                    [0.0, 1.0],
                    [-1.0, 0.0],
                    [0.0, 0.0],
                ],
            ),
        ];
        for &(kind, xs) in coords {
            let mut n = [0.0; MAX_NODES];
            let mut dn = [[0.0; 2]; MAX_NODES];
            for &(xi, eta, _) in kind.rule() {
                kind.shape(xi, eta, &mut n, &mut dn);
                let nn = kind.node_count();
                let sum: f64 = n[..nn].iter().sum();
                assert!((sum - 1.0).abs() < 1e-14, "{kind:?}");
                let x: f64 = (0..nn).map(|a| n[a] * xs[a][0]).sum();
                let y: f64 = (0..nn).map(|a| n[a] * xs[a][1]).sum();
                assert!(
                    (x - xi).abs() < 1e-14 && (y - eta).abs() < 1e-14,
                    "{kind:?}"
                );
                let dxdxi: f64 = (0..nn).map(|a| dn[a][0] * xs[a][0]).sum();
                let dydeta: f64 = (0..nn).map(|a| dn[a][1] * xs[a][1]).sum();
                let dxdeta: f64 = (0..nn).map(|a| dn[a][1] * xs[a][0]).sum();
                assert!((dxdxi - 1.0).abs() < 1e-13 && (dydeta - 1.0).abs() < 1e-13);
                assert!(dxdeta.abs() < 1e-13);
            }
        }
    }
}
