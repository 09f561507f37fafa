//! The nodal sums of a body with a second-order field from a Gram table instead of a loop over
//! its nodes (docs/geometric-stiffening.md, "Cost").
//!
//! Every per-node vector the inertia of a second-order body needs is a combination, with
//! coefficients that do not depend on the node, of the same `B = 1 + n_modes + nf(nf + 1)/2`
//! node vectors: the undeformed position `u0_k`, the mode translations `X_kj` and the field's
//! vectors `N_k,jl` (`j ≤ l < nf`, `Q_k = −N_k`):
//!
//! - `u_k = u0_k + Σ_j w_j X_kj − ½ Σ_jl w_j w_l N_k,jl`;
//! - `X̃_kj = X_kj − Σ_l w_l N_k,jl` (`j < nf`; the other modes' columns are `X_kj`);
//! - `u̇_k = Σ_j ẇ_j X̃_kj`, and `ρ_k = Q_k(ẇ, ẇ) = −Σ_jl ẇ_j ẇ_l N_k,jl`.
//!
//! So every mass-weighted sum of products of two of them is a bilinear form in their
//! coefficients with the body's Gram table `G_αβ = Σ_k m_k e_kα e_kβᵀ` and first moments
//! `F_α = Σ_k m_k e_kα`: an evaluation costs `O(B²)` whatever the number of nodes, instead of
//! `O(n_nodes · (nf² + n_modes))`. [`FrameSums`] are the same sums either way (to round-off;
//! the node loop stays for bodies with few nodes, where it is cheaper).

use std::ops::Range;

use fem::{GeometricStiffness, ModalBody};
use nalgebra::{Matrix3, Vector3};
use sens::{Rev, Scalar};

use crate::nodal::{axial, dot_rows, lift, mode_vec, outer, vec3f};

/// The sums over a second-order body's nodes that its mass matrix block and inertia forces
/// take (body components): `total = Σ m`, `first = Σ m u`, `m_oo = Σ m ũᵀũ` (the nodal
/// rotary inertias not included), `m_rw[j] = Σ m X̃_j`, `m_ow[j] = Σ μ∘T_j + Σ m u × X̃_j`,
/// `qc = Σ m c`, `s_o = Σ m u × c` and `s_w[j] = Σ m X̃_j · (g' − c)`, where
/// `c = ω × (ω × u) + 2 ω × u̇ + ρ` is a node's acceleration at zero accelerations beyond the
/// frame's and `g'` gravity in body components.
pub(crate) struct FrameSums<S: Scalar> {
    pub total: S,
    pub first: Vector3<S>,
    pub m_oo: Matrix3<S>,
    pub m_rw: Vec<Vector3<S>>,
    pub m_ow: Vec<Vector3<S>>,
    pub qc: Vector3<S>,
    pub s_o: Vector3<S>,
    pub s_w: Vec<S>,
    /// `Σ m C_j · C_l` of the field's columns `C_kj = Q_k(w)_j`, for `j ≤ l` at `j · nf + l`,
    /// when the sums are taken node by node (`None` from the Gram table: the modal mass then
    /// contracts the field invariants' fourth-order table with `w` twice).
    pub field_cc: Option<Vec<S>>,
}

/// The Gram table of a body with a second-order field (see the module documentation).
#[derive(Clone, Debug)]
pub(crate) struct FieldGram<P: Scalar> {
    n_modes: usize,
    field_modes: usize,
    /// `Σ m_k`.
    total: P,
    /// `F_α = Σ_k m_k e_kα`.
    first: Vec<Vector3<P>>,
    /// `G_αβ = Σ_k m_k e_kα e_kβᵀ`, its entry `i` (column major) at `(9 β + i) · B + α`: the
    /// rows the sums contract with a coefficient vector over `α` are contiguous.
    gram: Vec<P>,
    /// `tr G_αβ` at `β · B + α` (symmetric in `α`, `β`).
    trace: Vec<P>,
}

/// Index of the field pair `(j, l)`, `j ≤ l < nf`, among the pairs.
fn pair(nf: usize, j: usize, l: usize) -> usize {
    let (j, l) = if j <= l { (j, l) } else { (l, j) };
    j * nf - j * (j + 1) / 2 + l
}

impl<P: Scalar> FieldGram<P> {
    /// The same table with its scalars converted, in a fixed order.
    pub(crate) fn map<Q: Scalar>(&self, f: &impl Fn(P) -> Q) -> FieldGram<Q> {
        FieldGram {
            n_modes: self.n_modes,
            field_modes: self.field_modes,
            total: f(self.total),
            first: self.first.iter().map(|v| v.map(f)).collect(),
            gram: self.gram.iter().map(|&x| f(x)).collect(),
            trace: self.trace.iter().map(|&x| f(x)).collect(),
        }
    }
}

impl<P: Scalar> FieldGram<P> {
    /// The basis size `B`.
    fn size(&self) -> usize {
        1 + self.n_modes + self.field_modes * (self.field_modes + 1) / 2
    }

    /// Whether the table is cheaper than the node loop for `modal` with the field `g`
    /// (operation counts only, so that a body takes the same path in every scalar).
    pub(crate) fn pays(modal: &ModalBody<P>, g: &GeometricStiffness<P>) -> bool {
        let (nm, nf) = (modal.n_modes(), g.field_modes);
        let b = 1 + nm + nf * (nf + 1) / 2;
        let nodes = modal
            .node_masses
            .iter()
            .filter(|m| **m != P::zero())
            .count();
        // the loop: the node's field columns and rates (from its three nodal matrices, or
        // accumulated along a beam's elements, two products each), their products, then its
        // mode sums; the table: about three contractions of B² 3 × 3 blocks
        let field = match &g.elements {
            None => nodes * 6 * nf * nf,
            Some(els) => els.len() * 2 * nf * nf + nodes * 2 * nf * nf,
        };
        field + nodes * 40 * nm > 27 * b * b
    }

    /// The table of the sums over the nodes `nodes` of `modal`.
    pub(crate) fn new(
        modal: &ModalBody<P>,
        g: &GeometricStiffness<P>,
        nodes: Range<usize>,
    ) -> Self {
        let (nm, nf) = (modal.n_modes(), g.field_modes);
        let mut out = Self {
            n_modes: nm,
            field_modes: nf,
            total: P::zero(),
            first: Vec::new(),
            gram: Vec::new(),
            trace: Vec::new(),
        };
        let b = out.size();
        out.first = vec![Vector3::zeros(); b];
        let mut gram = vec![Matrix3::<P>::zeros(); b * b];
        let mut e = vec![Vector3::<P>::zeros(); b];
        for k in nodes {
            let m = modal.node_masses[k];
            if m == P::zero() {
                continue;
            }
            basis(modal, g, k, &mut e);
            out.total += m;
            for a in 0..b {
                out.first[a] += e[a] * m;
                let ea = e[a] * m;
                for c in a..b {
                    gram[a * b + c] += outer(&ea, &e[c]);
                }
            }
        }
        for a in 0..b {
            for c in 0..a {
                gram[a * b + c] = gram[c * b + a].transpose();
            }
        }
        out.gram = (0..9 * b * b)
            .map(|x| {
                let (ci, a) = (x / b, x % b);
                gram[a * b + ci / 9][ci % 9]
            })
            .collect();
        out.trace = (0..b * b)
            .map(|x| gram[(x % b) * b + x / b].trace())
            .collect();
        out
    }

    /// The coefficients of `u`, `u̇` and `ρ` on the basis at modal coordinates `w` and rates
    /// `wd`.
    fn coefficients<S: Scalar>(&self, w: &[S], wd: &[S]) -> [Vec<S>; 3] {
        let (nm, nf, b) = (self.n_modes, self.field_modes, self.size());
        let mut cu = vec![S::zero(); b];
        let mut cud = vec![S::zero(); b];
        let mut crho = vec![S::zero(); b];
        cu[0] = S::one();
        cu[1..=nm].copy_from_slice(&w[..nm]);
        cud[1..=nm].copy_from_slice(&wd[..nm]);
        let half = S::from_f64(0.5);
        for j in 0..nf {
            for l in j..nf {
                let p = 1 + nm + pair(nf, j, l);
                if j == l {
                    cu[p] = -(w[j] * w[j] * half);
                    cud[p] = -(wd[j] * w[j]);
                    crho[p] = -(wd[j] * wd[j]);
                } else {
                    cu[p] = -(w[j] * w[l]);
                    cud[p] = -(wd[j] * w[l] + wd[l] * w[j]);
                    crho[p] = -((wd[j] * wd[l]) * S::from_f64(2.0));
                }
            }
        }
        [cu, cud, crho]
    }

    /// The sparse coefficients `(α, c)` of the mode column `X̃_j` at `w`.
    fn column<S: Scalar>(&self, j: usize, w: &[S], out: &mut Vec<(usize, S)>) {
        out.clear();
        out.push((1 + j, S::one()));
        if j < self.field_modes {
            for (l, &wl) in w.iter().enumerate().take(self.field_modes) {
                out.push((1 + self.n_modes + pair(self.field_modes, j, l), -wl));
            }
        }
    }

    /// `Σ_α c_α x_α` of per-basis 3 × 3 blocks `x`.
    fn combine<S: Scalar>(c: &[S], x: &[Matrix3<S>]) -> Matrix3<S> {
        let mut out = Matrix3::zeros();
        for (ca, xa) in c.iter().zip(x) {
            out += xa * *ca;
        }
        out
    }

    /// The [`FrameSums`] at modal coordinates `w`, rates `wd`, angular velocity `om` and
    /// gravity `g_body` (body components); `mode_spin` holds `Σ μ∘T_j`.
    pub(crate) fn sums<S: Scalar + From<P>>(
        &self,
        mode_spin: &[Vector3<P>],
        w: &[S],
        wd: &[S],
        om: &Vector3<S>,
        g_body: &Vector3<S>,
    ) -> FrameSums<S> {
        let (nm, b) = (self.n_modes, self.size());
        let [cu, cud, crho] = self.coefficients(w, wd);
        let lift3 = |v: &Vector3<P>| v.map(lift::<P, S>);
        let first_of = |c: &[S]| {
            let mut out = Vector3::<S>::zeros();
            for (ca, f) in c.iter().zip(&self.first) {
                out += lift3(f) * *ca;
            }
            out
        };
        // T_β = Σ_α c^u_α G_αβ = Σ m u e_βᵀ and U_β = Σ_α c^u̇_α G_αβ = Σ m u̇ e_βᵀ, and
        // r_β = Σ_α c^ρ_α tr G_αβ = Σ m ρ · e_β, each entry a row of the table dotted with the
        // coefficients (on the reverse-mode tape one operation per table rather than two nodes
        // per product, which would be most of a step's tape on a shell); the coefficients of
        // u̇ vanish on u0, those of ρ on u0 and the modes (structurally, whatever the values of
        // dual numbers)
        let rows = |from: usize| -> Vec<&[P]> {
            (0..9 * b)
                .map(|ci| &self.gram[ci * b + from..(ci + 1) * b])
                .collect()
        };
        let blocks = |entries: Vec<S>| -> Vec<Matrix3<S>> {
            entries.chunks(9).map(Matrix3::from_column_slice).collect()
        };
        let t = blocks(dot_rows(&rows(0), &cu));
        let u = blocks(dot_rows(&rows(1), &cud[1..]));
        let trace_rows: Vec<&[P]> = (0..b)
            .map(|c| &self.trace[c * b + nm + 1..(c + 1) * b])
            .collect();
        let r = dot_rows(&trace_rows, &crho[nm + 1..]);
        let first = first_of(&cu);
        let s_uu = Self::combine(&cu, &t);
        let s_uud = Self::combine(&cud, &t);
        let s_urho = Self::combine(&crho, &t);
        let m_oo = Matrix3::identity() * s_uu.trace() - s_uu;
        let two = S::from_f64(2.0);
        let omega = crate::kin::skew(om);
        let omega2 = omega * omega;
        let sum_ud = first_of(&cud);
        let sum_rho = first_of(&crho);
        let qc = om.cross(&om.cross(&first)) + om.cross(&sum_ud) * two + sum_rho;
        // Σ m u × (Ω² u) + 2 Σ m u × (Ω u̇) + Σ m u × ρ
        let s_o =
            axial(&(s_uu * omega2)) + axial(&(s_uud * omega.transpose())) * two + axial(&s_urho);
        let mut m_rw = Vec::with_capacity(nm);
        let mut m_ow = Vec::with_capacity(nm);
        let mut s_w = Vec::with_capacity(nm);
        let mut col = Vec::new();
        for j in 0..nm {
            self.column(j, w, &mut col);
            let mut rw = Vector3::<S>::zeros();
            let mut p = Matrix3::<S>::zeros(); // Σ m u X̃_jᵀ
            let mut q = Matrix3::<S>::zeros(); // Σ m u̇ X̃_jᵀ
            let mut rho_x = S::zero(); // Σ m ρ · X̃_j
            for &(a, c) in &col {
                rw += lift3(&self.first[a]) * c;
                p += t[a] * c;
                q += u[a] * c;
                rho_x += r[a] * c;
            }
            m_ow.push(lift3(&mode_spin[j]) + axial(&p));
            // Σ m X̃_j · c = tr(Ω² Σ m u X̃ᵀ) + 2 tr(Ω Σ m u̇ X̃ᵀ) + Σ m ρ · X̃
            let xc = (omega2 * p).trace() + (omega * q).trace() * two + rho_x;
            s_w.push(rw.dot(g_body) - xc);
            m_rw.push(rw);
        }
        FrameSums {
            total: lift(self.total),
            first,
            m_oo,
            m_rw,
            m_ow,
            qc,
            s_o,
            s_w,
            field_cc: None,
        }
    }
}

/// The basis vectors `e_kα` of node `k` (`e` of [`FieldGram::size`]): its position, its modes'
/// translations, then its field's columns `Q_k,jl` (`j ≤ l`).
fn basis<P: Scalar>(
    modal: &ModalBody<P>,
    g: &GeometricStiffness<P>,
    k: usize,
    e: &mut [Vector3<P>],
) {
    let (nm, nf) = (modal.n_modes(), g.field_modes);
    e[0] = vec3f(&modal.node_positions[k]);
    for j in 0..nm {
        e[1 + j] = mode_vec(modal, k, j, false);
    }
    for j in 0..nf {
        for l in j..nf {
            e[1 + nm + pair(nf, j, l)] = Vector3::from_fn(|i, _| g.nodal[3 * k + i][(j, l)]);
        }
    }
}

/// The adjoints of a [`FieldGram`]'s scalars, arranged for the reverse of one node's terms
/// ([`Self::seed_node`]): `total̄`, `F̄_α` and the blocks `Ḡ_αβ` (the table's adjoint plus its
/// trace's times the identity) at `α · B + β`.
pub(crate) struct GramSeeds {
    total: f64,
    first: Vec<Vector3<f64>>,
    blocks: Vec<Matrix3<f64>>,
}

impl GramSeeds {
    /// The seeds of a table whose adjoints are `bar` (a table of the same layout).
    pub(crate) fn new(bar: &FieldGram<f64>) -> Self {
        let b = bar.size();
        let blocks = (0..b * b)
            .map(|x| {
                let (a, c) = (x / b, x % b);
                Matrix3::from_fn(|r, col| bar.gram[(9 * c + r + 3 * col) * b + a])
                    + Matrix3::identity() * bar.trace[c * b + a]
            })
            .collect();
        Self {
            total: bar.total,
            first: bar.first.clone(),
            blocks,
        }
    }

    /// Seed, in `adjoints`, node `k`'s mass and basis vectors (their tape nodes: `modal` and
    /// `g` are on the tape) with the adjoints these seeds carry back through that node's terms
    /// `m e_α`, `m e_α e_βᵀ` (every block: the lower ones are the upper's transposes) and
    /// `m`: `ē_γ = m (F̄_γ + Σ_β Ḡ_γβ e_β + Ḡ_βγᵀ e_β)`, `m̄ = total̄ + Σ_α F̄_α · e_α +
    /// Σ_αβ e_αᵀ Ḡ_αβ e_β`.
    pub(crate) fn seed_node(
        &self,
        modal: &ModalBody<Rev>,
        g: &GeometricStiffness<Rev>,
        k: usize,
        adjoints: &mut Vec<f64>,
    ) {
        let m = modal.node_masses[k];
        if m.value() == 0.0 {
            return;
        }
        let b = self.first.len();
        let mut e = vec![Vector3::<Rev>::zeros(); b];
        basis(modal, g, k, &mut e);
        let ev: Vec<Vector3<f64>> = e.iter().map(|v| v.map(|x| x.value())).collect();
        let mv = m.value();
        let mut e_bar: Vec<Vector3<f64>> = self.first.iter().map(|f| f * mv).collect();
        let mut m_bar = self.total;
        for a in 0..b {
            m_bar += self.first[a].dot(&ev[a]);
            for c in 0..b {
                let block = &self.blocks[a * b + c];
                let ge = block * ev[c];
                m_bar += ev[a].dot(&ge);
                e_bar[a] += ge * mv;
                e_bar[c] += block.tr_mul(&ev[a]) * mv;
            }
        }
        m.seed(adjoints, m_bar);
        for (v, bar) in e.iter().zip(&e_bar) {
            for i in 0..3 {
                v[i].seed(adjoints, bar[i]);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::pair;

    #[test]
    fn pairs_are_numbered_in_order() {
        let nf = 5;
        let mut k = 0;
        for j in 0..nf {
            for l in j..nf {
                assert_eq!(pair(nf, j, l), k, "({j}, {l})");
                assert_eq!(pair(nf, l, j), k);
                k += 1;
            }
        }
    }
}
