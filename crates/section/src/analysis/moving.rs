//! The compliance's derivatives along variables that move nodes (a ply thickness): the
//! adjoints' Lagrangian differentiated through the integration points' geometry, with the
//! fields held ([`SectionAnalysis::compliance_adjoint_dual`]).
//!
//! A point's geometry moves with the node velocities `V_a` of a variable: its position by the
//! interpolated `V`, its weight by `w tr ∇V`, the shape functions' gradients by
//! `d(∂N/∂x)/db = −∇Vᵀ ∂N/∂x` (so a field's gradient `G = Σ u_a ⊗ ∂N_a/∂x` by `−G ∇V`) and
//! the wall frame's angle at the rate of its tangent. The Lagrangian's integrand is bilinear in
//! the strains, so its tangent needs the plain strains, their tangents from `G` and `V`, and
//! the material's tangent `φ̇ (Γ Q + Q Γᵀ)` of a frame turning at the rate `φ̇` (`Γ` the Bond
//! matrices' generator for a rotation about the beam axis) — no dual number runs through a
//! node loop or a Bond matrix.

use super::*;

/// The tangents of an integration point's geometry along the `N` variables of a chunk.
pub(super) struct PointTangents<const N: usize> {
    /// The point's velocity `V_m` along each variable: `v[m][k]`.
    v: [[f64; N]; 2],
    /// The velocity gradient `∂V_m/∂x_j`: `grad_v[m][j][k]`.
    grad_v: [[[f64; N]; 2]; 2],
}

impl<const N: usize> PointTangents<N> {
    /// From the point's dual geometry: `V` from its position, `∇V = J̇ J⁻¹` from its
    /// parametric directions (`J = ∂x/∂ξ`, whose rate is `∇V J`).
    pub(super) fn of(gp: &GaussPoint<Dual<N>>) -> Self {
        // J[i][k] = ∂x_i/∂ξ_k = dx_dxi[k][i]
        let j = |i: usize, k: usize| gp.dx_dxi[k][i];
        let det = j(0, 0).v * j(1, 1).v - j(0, 1).v * j(1, 0).v;
        let inv = [
            [j(1, 1).v / det, -j(0, 1).v / det],
            [-j(1, 0).v / det, j(0, 0).v / det],
        ];
        let mut grad_v = [[[0.0; N]; 2]; 2];
        for (m, row) in grad_v.iter_mut().enumerate() {
            for (c, out) in row.iter_mut().enumerate() {
                for (k, out) in out.iter_mut().enumerate() {
                    *out = j(m, 0).d[k] * inv[0][c] + j(m, 1).d[k] * inv[1][c];
                }
            }
        }
        Self {
            v: [gp.x[0].d, gp.x[1].d],
            grad_v,
        }
    }
}

impl LagrangeFields<'_, f64> {
    /// [`LagrangeFields::at_into`] at the nominal point `gp` with the tangents of the point's
    /// geometry `t`: `[ε, α, e₁, β]` with their tangents along the chunk's variables;
    /// `β = SN λ_X − [BN Z] μ` the strains of the one field set `beta_fields`,
    /// `(−μ_X, λ_X` as the warping rate`, −μ_Y)`.
    pub(super) fn moving_at_into<const N: usize>(
        &self,
        (nodes, gp, t): (&[usize], &GaussPoint, &PointTangents<N>),
        beta_fields: Fields<'_, f64>,
        out: &mut [[[Dual<N>; 6]; 6]; 4],
    ) {
        let [eps, alpha, e1, beta] = out;
        moving_strains_into(nodes, gp, t, self.eps, eps);
        moving_strains_into(nodes, gp, t, self.e1, e1);
        moving_strains_into(nodes, gp, t, self.lambda, alpha);
        moving_strains_into(nodes, gp, t, beta_fields, beta);
        for (a, e) in alpha.iter_mut().zip(eps.iter()) {
            for (a, &e) in a.iter_mut().zip(e) {
                *a = e * 0.5 - *a;
            }
        }
    }
}

/// [`strains_into`] of plain fields at the nominal point `gp`, with the strains' tangents along
/// the variables that move the point (`t`): the generalised strains' positions move by `V`,
/// the warping's gradient `G` by `−G ∇V`, and the shape functions of the warping rate stay.
/// `out[column][component]`.
#[inline(always)]
fn moving_strains_into<const N: usize>(
    nodes: &[usize],
    gp: &GaussPoint,
    t: &PointTangents<N>,
    f: Fields<'_, f64>,
    out: &mut [[Dual<N>; 6]; 6],
) {
    let [x2, x3] = gp.x;
    let [v2, v3] = &t.v;
    for column in out.iter_mut() {
        *column = [Dual::constant(0.0); 6];
    }
    if let Some(psi) = f.psi {
        for (c, e) in out.iter_mut().enumerate() {
            let p = |i: usize| psi[i * 6 + c];
            e[0].v += p(0) + p(4) * x3 - p(5) * x2;
            e[4].v += p(2) + p(3) * x2;
            e[5].v += p(1) - p(3) * x3;
            for k in 0..N {
                e[0].d[k] += p(4) * v3[k] - p(5) * v2[k];
                e[4].d[k] += p(3) * v2[k];
                e[5].d[k] -= p(3) * v3[k];
            }
        }
    }
    if let Some(u) = f.u {
        // g[i][j][c] = ∂u_i/∂x_j of column c (the columns innermost, as in the fields)
        let mut g = [[[0.0; 6]; 2]; 3];
        for (a, &node) in nodes.iter().enumerate() {
            let [d2, d3] = gp.dx[a];
            for (i, g) in g.iter_mut().enumerate() {
                let row = &u[(3 * node + i) * 6..(3 * node + i) * 6 + 6];
                for c in 0..6 {
                    g[0][c] += row[c] * d2;
                    g[1][c] += row[c] * d3;
                }
            }
        }
        let gv = &t.grad_v;
        for (c, e) in out.iter_mut().enumerate() {
            let g = |i: usize, j: usize| g[i][j][c];
            e[1].v += g(1, 0);
            e[2].v += g(2, 1);
            e[3].v += g(1, 1) + g(2, 0);
            e[4].v += g(0, 1);
            e[5].v += g(0, 0);
            for k in 0..N {
                // Ġ_ij = −Σ_m G_im ∂V_m/∂x_j
                let gd = |i: usize, j: usize| -(g(i, 0) * gv[0][j][k] + g(i, 1) * gv[1][j][k]);
                e[1].d[k] += gd(1, 0);
                e[2].d[k] += gd(2, 1);
                e[3].d[k] += gd(1, 1) + gd(2, 0);
                e[4].d[k] += gd(0, 1);
                e[5].d[k] += gd(0, 0);
            }
        }
    }
    if let Some(u1) = f.u1 {
        for (a, &node) in nodes.iter().enumerate() {
            let g = 3 * node;
            let na = gp.n[a];
            for (c, e) in out.iter_mut().enumerate() {
                e[0].v += u1[g * 6 + c] * na;
                e[5].v += u1[(g + 1) * 6 + c] * na;
                e[4].v += u1[(g + 2) * 6 + c] * na;
            }
        }
    }
}

/// Add the integrand `Σ_i (Q ε_c)_i α_d,i + (Q e₁_c)_i β_d,i` of the Lagrangian at a point
/// (without its weight) to `acc[c][d]`, for the plain material `q`: its value and its tangents
/// from the strains'.
#[inline(always)]
pub(super) fn contract_strains<const N: usize>(
    q: &Matrix6<f64>,
    strains: &[[[Dual<N>; 6]; 6]; 4],
    acc: &mut [[Dual<N>; 6]; 6],
) {
    let [eps, alpha, e1, beta] = strains;
    let times_q = |a: &[Dual<N>; 6]| -> [Dual<N>; 6] {
        std::array::from_fn(|i| {
            let mut s = a[0] * q[(i, 0)];
            for k in 1..6 {
                s += a[k] * q[(i, k)];
            }
            s
        })
    };
    for (c, acc) in acc.iter_mut().enumerate() {
        let (q_eps, q_e1) = (times_q(&eps[c]), times_q(&e1[c]));
        for (acc, (alpha, beta)) in acc.iter_mut().zip(alpha.iter().zip(beta)) {
            let mut s = q_eps[0] * alpha[0] + q_e1[0] * beta[0];
            for i in 1..6 {
                s += q_eps[i] * alpha[i] + q_e1[i] * beta[i];
            }
            *acc += s;
        }
    }
}

/// The generator `Γ = dT/dφ T⁻¹` of the Bond stress matrices of rotations about the beam axis
/// (`T(φ + δ) = T(δ) T(φ)`, so `dT/dφ = Γ T` whatever `φ`).
pub(super) fn frame_generator() -> Matrix6<f64> {
    let (o, z) = (Dual::<1>::constant(1.0), Dual::<1>::constant(0.0));
    let s = Dual::<1>::new(0.0, [1.0]);
    let r = nalgebra::Matrix3::new(o, z, z, z, o, -s, z, s, o);
    bond_stress_matrix(&r).map(|x| x.d[0])
}

/// The rates `φ̇_k` at which the wall frame turns at a point along the chunk's variables, from
/// its dual tangent `(t₂, t₃) = (cos φ, sin φ)`; `None` when it does not turn.
pub(super) fn frame_rates<const N: usize>(tangent: [Dual<N>; 2]) -> Option<[f64; N]> {
    let [t2, t3] = tangent;
    let rates: [f64; N] = std::array::from_fn(|k| t2.v * t3.d[k] - t3.v * t2.d[k]);
    rates.iter().any(|&r| r != 0.0).then_some(rates)
}

/// The Lagrangian's integrand `Σ_i (H ε_c)_i α_d,i + (H e₁_c)_i β_d,i` at a point (without
/// its weight) for a plain material tangent `H` (a turning frame's `Γ Q + Q Γᵀ`, or a ply
/// stiffness's tangent in section axes), of the strains' values: `(c, d)`.
pub(super) fn strain_form<const N: usize>(
    h: &Matrix6<f64>,
    strains: &[[[Dual<N>; 6]; 6]; 4],
) -> Matrix6<f64> {
    let [eps, alpha, e1, beta] = strains;
    let times_h = |a: &[Dual<N>; 6]| -> [f64; 6] {
        std::array::from_fn(|i| (0..6).map(|k| h[(i, k)] * a[k].v).sum())
    };
    let mut out = Matrix6::zeros();
    for c in 0..6 {
        let (h_eps, h_e1) = (times_h(&eps[c]), times_h(&e1[c]));
        for d in 0..6 {
            out[(c, d)] = (0..6)
                .map(|i| h_eps[i] * alpha[d][i].v + h_e1[i] * beta[d][i].v)
                .sum();
        }
    }
    out
}
