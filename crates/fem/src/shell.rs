//! Flat three-node laminated shell triangle with six dof per node (paper §3.2, Eqs. 17–22).
//!
//! - Membrane: Allman's (1984) triangle, whose drilling rotations add quadratic edge-normal
//!   displacements (linear strain: good in in-plane bending), or the constant-strain triangle
//!   ([`Membrane`]); the drilling rotation is also tied to the element's in-plane rotation
//!   `ω = ½(v,ₓ − u,ᵧ)` by a small penalty (`α · A₆₆ · area`, Hughes–Brezzi style), which removes
//!   Allman's spurious equal-rotation mode while rigid rotations cost nothing.
//! - Bending: Reissner–Mindlin with linear rotations (constant curvature), coupled to the
//!   membrane through `B`.
//! - Transverse shear: MITC3 (Lee & Bathe 2004). The assumed shear field is the rotated lowest
//!   Raviart–Thomas (Nédélec) field `γ = a + b(−y, x)` whose tangential component on each edge
//!   equals the displacement-based tangential shear at the edge midpoint (the MITC3 tying
//!   points), which removes shear locking.
//! - Mass: consistent (linear interpolation, `I₀, I₁, I₂` of the laminate) and lumped (`I₀A/3`
//!   per translation, `I₂A/3` per in-plane rotation). The drilling rotation has no inertia in
//!   Mindlin theory; it gets `α I₂` (α the drilling penalty factor), which keeps the drilling
//!   modes at `ω² = A₆₆/I₂ ≈ 12 G/(ρh²)`, the thickness-shear level, far above the modes of
//!   interest, while the mass matrix stays positive definite.
//!
//! Local axes: `e₁` = the material reference axis projected on the element plane (ply angles
//! are measured from it), `e₃` = the normal `(p₂−p₁)×(p₃−p₁)`, `e₂ = e₃ × e₁`. Rotations are a
//! small rotation vector; the plate rotations are `β_x = θ_y`, `β_y = −θ_x`.

use laminate::LaminateStiffness;
use nalgebra::{Matrix3, SMatrix, Vector3};
use sens::Scalar;

/// 18×18 element matrix, dofs node by node `[u, v, w, θx, θy, θz]`.
pub type M18<S> = SMatrix<S, 18, 18>;

/// Default drilling penalty factor `α`.
pub const DEFAULT_DRILLING: f64 = 1e-3;

/// Why a shell element could not be formed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ShellError {
    #[error("shell element {element}: degenerate triangle (area {area})")]
    Degenerate { element: usize, area: f64 },
}

/// Geometry of a flat triangle in its local frame.
#[derive(Clone, Debug)]
pub struct TriGeometry {
    /// Rows: local axes `e₁, e₂, e₃` in global coordinates.
    pub frame: Matrix3<f64>,
    /// Local in-plane coordinates of the three nodes (relative to node 1).
    pub xy: [[f64; 2]; 3],
    /// Area.
    pub area: f64,
    /// Shape-function derivatives `∂Nᵢ/∂x`, `∂Nᵢ/∂y`.
    pub dn: [[f64; 2]; 3],
}

impl TriGeometry {
    /// Local frame and derivatives of a triangle.
    pub fn new(
        p: [Vector3<f64>; 3],
        material_axis: &Vector3<f64>,
        element: usize,
    ) -> Result<Self, ShellError> {
        let n = (p[1] - p[0]).cross(&(p[2] - p[0]));
        let area = 0.5 * n.norm();
        let scale = (p[1] - p[0])
            .norm_squared()
            .max((p[2] - p[0]).norm_squared());
        if !(area > 1e-12 * scale) {
            return Err(ShellError::Degenerate { element, area });
        }
        let e3 = n.normalize();
        let mut a = material_axis - e3 * material_axis.dot(&e3);
        if a.norm() < 1e-6 * material_axis.norm().max(1e-300) {
            a = p[1] - p[0];
        }
        let e1 = a.normalize();
        let e2 = e3.cross(&e1);
        let frame = Matrix3::from_rows(&[e1.transpose(), e2.transpose(), e3.transpose()]);
        let mut xy = [[0.0; 2]; 3];
        for i in 0..3 {
            let d = p[i] - p[0];
            xy[i] = [d.dot(&e1), d.dot(&e2)];
        }
        let mut dn = [[0.0; 2]; 3];
        for i in 0..3 {
            let j = (i + 1) % 3;
            let k = (i + 2) % 3;
            dn[i] = [
                (xy[j][1] - xy[k][1]) / (2.0 * area),
                (xy[k][0] - xy[j][0]) / (2.0 * area),
            ];
        }
        Ok(Self {
            frame,
            xy,
            area,
            dn,
        })
    }
}

const U: usize = 0;
const V: usize = 1;
const W: usize = 2;
const TX: usize = 3;
const TY: usize = 4;
const TZ: usize = 5;

fn dof(node: usize, d: usize) -> usize {
    6 * node + d
}

/// Strain–displacement rows in the local frame: membrane (3×18), curvature (3×18), MITC3 shear
/// field coefficients, drilling rows.
struct ShellB {
    bm: SMatrix<f64, 3, 18>,
    bb: SMatrix<f64, 3, 18>,
    /// shear strain at the three edge midpoints (2×18 each)
    bs: [SMatrix<f64, 2, 18>; 3],
    /// drilling penalty rows θz_i − ω (3×18)
    bd: SMatrix<f64, 3, 18>,
}

fn shell_b(g: &TriGeometry) -> ShellB {
    let mut bm = SMatrix::<f64, 3, 18>::zeros();
    let mut bb = SMatrix::<f64, 3, 18>::zeros();
    let mut omega = SMatrix::<f64, 1, 18>::zeros();
    for i in 0..3 {
        let [nx, ny] = g.dn[i];
        bm[(0, dof(i, U))] = nx;
        bm[(1, dof(i, V))] = ny;
        bm[(2, dof(i, U))] = ny;
        bm[(2, dof(i, V))] = nx;
        // β_x = θ_y, β_y = −θ_x
        bb[(0, dof(i, TY))] = nx;
        bb[(1, dof(i, TX))] = -ny;
        bb[(2, dof(i, TY))] = ny;
        bb[(2, dof(i, TX))] = -nx;
        omega[(0, dof(i, V))] = 0.5 * nx;
        omega[(0, dof(i, U))] = -0.5 * ny;
    }
    let mut bd = SMatrix::<f64, 3, 18>::zeros();
    for i in 0..3 {
        bd.set_row(i, &(-omega));
        bd[(i, dof(i, TZ))] += 1.0;
    }
    // MITC3: edge e joins nodes (i, j); tangential shear e_t = (w_j − w_i)/L + t·(β_i + β_j)/2
    let edges = [(0usize, 1usize), (1, 2), (2, 0)];
    let mut g3 = Matrix3::<f64>::zeros();
    let mut e = SMatrix::<f64, 3, 18>::zeros();
    let mut mids = [[0.0; 2]; 3];
    for (r, &(i, j)) in edges.iter().enumerate() {
        let dx = g.xy[j][0] - g.xy[i][0];
        let dy = g.xy[j][1] - g.xy[i][1];
        let l = (dx * dx + dy * dy).sqrt();
        let (tx, ty) = (dx / l, dy / l);
        let mx = 0.5 * (g.xy[i][0] + g.xy[j][0]);
        let my = 0.5 * (g.xy[i][1] + g.xy[j][1]);
        mids[r] = [mx, my];
        g3[(r, 0)] = tx;
        g3[(r, 1)] = ty;
        g3[(r, 2)] = -my * tx + mx * ty;
        e[(r, dof(j, W))] += 1.0 / l;
        e[(r, dof(i, W))] -= 1.0 / l;
        for n in [i, j] {
            e[(r, dof(n, TY))] += 0.5 * tx;
            e[(r, dof(n, TX))] -= 0.5 * ty;
        }
    }
    let coef = g3.try_inverse().expect("non-degenerate triangle") * e;
    let bs = mids.map(|[x, y]| {
        let p = SMatrix::<f64, 2, 3>::new(1.0, 0.0, -y, 0.0, 1.0, x);
        p * coef
    });
    ShellB { bm, bb, bs, bd }
}

/// The area coordinates of the three-point rule (exact for quadratics) that integrates the
/// membrane terms.
pub(crate) const MEMBRANE_POINTS: [[f64; 3]; 3] = [
    [2.0 / 3.0, 1.0 / 6.0, 1.0 / 6.0],
    [1.0 / 6.0, 2.0 / 3.0, 1.0 / 6.0],
    [1.0 / 6.0, 1.0 / 6.0, 2.0 / 3.0],
];

/// The strain operators of the membrane part of a triangle, local frame: the membrane strain
/// at each of [`MEMBRANE_POINTS`] and the (constant) curvature.
pub(crate) struct MembraneOperators {
    pub bm: [SMatrix<f64, 3, 18>; 3],
    pub bb: SMatrix<f64, 3, 18>,
}

pub(crate) fn membrane_operators(g: &TriGeometry, membrane: Membrane) -> MembraneOperators {
    let b = shell_b(g);
    MembraneOperators {
        bm: MEMBRANE_POINTS.map(|l| match membrane {
            Membrane::Allman => b.bm + allman_b(g, l),
            Membrane::Cst => b.bm,
        }),
        bb: b.bb,
    }
}

/// The laminate's deformation at the triangle's centroid per nodal dof, local frame: rows
/// `[ε⁰xx, ε⁰yy, γ⁰xy, κxx, κyy, 2κxy, γxz, γyz]` — the membrane strain (Allman's linear field
/// or the constant one, at the centroid the mean of its three points), the curvature, and the
/// MITC3 shear field (linear: at the centroid the mean of its tying points).
pub(crate) fn centroid_deformation(g: &TriGeometry, membrane: Membrane) -> SMatrix<f64, 8, 18> {
    let b = shell_b(g);
    let ops = membrane_operators(g, membrane);
    let mut out = SMatrix::<f64, 8, 18>::zeros();
    let third = 1.0 / 3.0;
    for r in 0..3 {
        for c in 0..18 {
            out[(r, c)] = (ops.bm[0][(r, c)] + ops.bm[1][(r, c)] + ops.bm[2][(r, c)]) * third;
            out[(3 + r, c)] = ops.bb[(r, c)];
        }
    }
    for r in 0..2 {
        for c in 0..18 {
            out[(6 + r, c)] = (b.bs[0][(r, c)] + b.bs[1][(r, c)] + b.bs[2][(r, c)]) * third;
        }
    }
    out
}

/// Local-frame stiffness (18×18) of a laminated triangle.
pub fn shell_stiffness_local<S: Scalar>(
    g: &TriGeometry,
    lam: &LaminateStiffness<S>,
    drilling: f64,
    membrane: Membrane,
) -> M18<S> {
    let b = shell_b(g);
    let cast3 = |m: &SMatrix<f64, 3, 18>| m.map(S::from_f64);
    let bb = cast3(&b.bb);
    let a = S::from_f64(g.area);
    let bbt = bb.transpose();
    let mut k = bbt * lam.d * bb * a;
    // membrane and membrane–bending coupling: linear membrane strain (Allman), three-point rule
    for bm in membrane_operators(g, membrane).bm {
        let bm = cast3(&bm);
        let bmt = bm.transpose();
        k += (bmt * lam.a * bm + bmt * lam.b * bb + bbt * lam.b * bm) * (a * (1.0 / 3.0));
    }
    for bs in &b.bs {
        let bs = bs.map(S::from_f64);
        k += bs.transpose() * lam.shear * bs * (a * (1.0 / 3.0));
    }
    let bd = cast3(&b.bd);
    k += bd.transpose() * bd * (lam.a[(2, 2)] * a * (drilling / 3.0));
    (k + k.transpose()) * S::from_f64(0.5)
}

/// Membrane formulation of the triangle.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Membrane {
    /// Allman (1984) triangle: the drilling rotations add quadratic edge-normal displacements
    /// `(L/8)(θ_j − θ_i) n` at the edge midpoints (linear strain); far better in in-plane bending.
    #[default]
    Allman,
    /// Constant-strain triangle (drilling rotation only through the penalty).
    Cst,
}

/// The drilling-rotation part of the Allman membrane strain at area coordinates `l`
/// (`u = Σ Lᵢuᵢ + Σ_edges 4LᵢLⱼ (ℓ/8)(θⱼ − θᵢ) n`, `n` the outward edge normal).
fn allman_b(g: &TriGeometry, l: [f64; 3]) -> SMatrix<f64, 3, 18> {
    let mut out = SMatrix::<f64, 3, 18>::zeros();
    for (i, j) in [(0usize, 1usize), (1, 2), (2, 0)] {
        let dx = g.xy[j][0] - g.xy[i][0];
        let dy = g.xy[j][1] - g.xy[i][1];
        let len = (dx * dx + dy * dy).sqrt();
        // outward normal of a counter-clockwise triangle: the tangent turned by −90°
        let (nx, ny) = (dy / len, -dx / len);
        // N_e = 4 L_i L_j and its derivatives
        let nex = 4.0 * (l[j] * g.dn[i][0] + l[i] * g.dn[j][0]);
        let ney = 4.0 * (l[j] * g.dn[i][1] + l[i] * g.dn[j][1]);
        let c = len / 8.0;
        for (node, sign) in [(j, 1.0), (i, -1.0)] {
            let col = dof(node, TZ);
            out[(0, col)] += sign * c * nx * nex;
            out[(1, col)] += sign * c * ny * ney;
            out[(2, col)] += sign * c * (nx * ney + ny * nex);
        }
    }
    out
}

/// Local-frame consistent mass (18×18).
pub fn shell_mass_local<S: Scalar>(
    g: &TriGeometry,
    lam: &LaminateStiffness<S>,
    drilling: f64,
) -> M18<S> {
    let mut m = M18::<S>::zeros();
    let (i0, i1, i2) = (lam.mass_per_area, lam.first_moment, lam.rotary_inertia);
    for i in 0..3 {
        for j in 0..3 {
            let nn = S::from_f64(g.area / 12.0 * if i == j { 2.0 } else { 1.0 });
            for d in [U, V, W] {
                m[(dof(i, d), dof(j, d))] += i0 * nn;
            }
            // rotary: β_x = θ_y, β_y = −θ_x
            m[(dof(i, TX), dof(j, TX))] += i2 * nn;
            m[(dof(i, TY), dof(j, TY))] += i2 * nn;
            m[(dof(i, TZ), dof(j, TZ))] += i2 * nn * drilling;
            // coupling I₁ (u β_x + v β_y)
            m[(dof(i, U), dof(j, TY))] += i1 * nn;
            m[(dof(j, TY), dof(i, U))] += i1 * nn;
            m[(dof(i, V), dof(j, TX))] -= i1 * nn;
            m[(dof(j, TX), dof(i, V))] -= i1 * nn;
        }
    }
    m
}

/// Lumped nodal mass and rotary inertia (global axes, diagonal) of one node's share of the
/// element: `I₀A/3` and the diagonal of `R diag(I₂, I₂, α I₂) Rᵀ A/3`.
pub fn shell_lumped<S: Scalar>(
    g: &TriGeometry,
    lam: &LaminateStiffness<S>,
    drilling: f64,
) -> (S, [S; 3]) {
    let a3 = S::from_f64(g.area / 3.0);
    let mu = lam.rotary_inertia * a3;
    let local = [1.0, 1.0, drilling];
    let mut out = [S::zero(); 3];
    for (d, o) in out.iter_mut().enumerate() {
        // (Rᵀ diag Λ R)_dd with frame rows e_k: Σ_k e_k[d]² local_k
        let w: f64 = (0..3).map(|k| g.frame[(k, d)].powi(2) * local[k]).sum();
        *o = mu * w;
    }
    (lam.mass_per_area * a3, out)
}
