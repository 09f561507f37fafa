//! The nodal sums of a beam body with a second-order field on the reverse-mode tape as one
//! operation ([`sens::Rev::external`]) with its reverse written by hand.
//!
//! The loop over the nodes ([`crate::body`]'s `node_sums`, the field accumulated along the
//! beam's elements) is a few thousand multiply-adds per node with few inputs (the modal
//! coordinates and rates, the angular velocity, gravity, and the body's data) and few outputs
//! ([`FrameSums`]): recorded node by node it was most of the tape of a step of the adjoint
//! sweep, which sweeps each step's tape five to six times (docs/design.md §3, "The adjoint
//! method"). Here the sums are evaluated in `f64`, their intermediate vectors kept, and each
//! sweep runs the reverse below: the same derivatives to round-off (the `crate::body` test
//! `the_taped_sums_reverse_as_the_node_loop_does`), in about a third of the time the sweeps of
//! its recording took on the tailored rod (docs/performance.md).
//!
//! The sums, per node `k` of mass `m` (massless nodes skipped), with the field's columns
//! `C_j`, half displacement `H` and rates' term `R` accumulated from the clamp along the
//! elements (`C_j ← C_j − t g_j`, `H ← H − t ½ Σ g_j w_j`, `R ← R − t Σ h_j ẇ_j` with
//! `g_j = Σ_l G_lj w_l`, `h_j = Σ_l G_lj ẇ_l` of the element's unit geometric stiffness `G`):
//!
//! ```text
//! u = u0 + H + Σ X_j w_j,  x_j = X_j + C_j,  u̇ = Σ x_j ẇ_j,  c = ω × (ω × u) + 2 ω × u̇ + R
//! total += m, first += m u, m_oo += m ũᵀũ, qc += m c, s_o += m u × c,
//! m_rw_j += m x_j, m_ow_j += m u × x_j, s_w_j += m x_j · (g − c), cc_jl += m C_j · C_l (j ≤ l)
//! ```
//!
//! with `m_ow_j` starting at `Σ μ∘T_j`.
//!
//! A marker at a node of a body with a second-order field reads the node's field from its
//! three nodal matrices ([`crate::body::second_order_node`]); on the tape that is one operation
//! too ([`taped_second_order_node`]).

use std::any::Any;

use fem::{GeometricStiffness, ModalBody};
use nalgebra::{Matrix3, Vector3};
use sens::{ExternalReverse, InputAdjoints, Rev, Scalar};

use super::SecondOrderNode;
use crate::field_gram::FrameSums;
use crate::kin::skew;
use crate::nodal::{cast, taped};

/// [`FrameSums`] of a beam body with a second-order field recorded as one tape operation, when
/// the evaluation is on the tape (`P` and `S` are [`Rev`]) and the field is accumulated along
/// the body's elements; `None` otherwise (the caller's node loop then records them).
pub(crate) fn taped_node_sums<P: Scalar, S: Scalar>(
    (modal, field): (&ModalBody<P>, &GeometricStiffness<P>),
    mode_spin: &[Vector3<P>],
    (w, wd): (&[S], &[S]),
    om: &Vector3<S>,
    g_body: &Vector3<S>,
) -> Option<FrameSums<S>> {
    let modal = (modal as &dyn Any).downcast_ref::<ModalBody<Rev>>()?;
    let field = (field as &dyn Any).downcast_ref::<GeometricStiffness<Rev>>()?;
    let mode_spin: Vec<Vector3<Rev>> = taped(mode_spin)?;
    let state: Vec<Rev> = taped(w.iter().chain(wd).chain(om.iter()).chain(g_body.iter()))?;
    cast(record(modal, field, &mode_spin, &state)?)
}

/// The body's data in `f64` as the sums read them, and their tape handles.
struct BodyData {
    nm: usize,
    nf: usize,
    masses: Vec<f64>,
    u0: Vec<Vector3<f64>>,
    /// `X_kj` at `k · nm + j`.
    modes: Vec<Vector3<f64>>,
    /// `(parent, child, axis)` of each element, in the order from the clamp.
    elements: Vec<(usize, usize, Vector3<f64>)>,
    /// Each element's `G` (column-major, `nf × nf`).
    units: Vec<f64>,
    /// `len_j`: the entries `l < len_j` of column `j` of `G` that may be nonzero.
    row_len: Vec<usize>,
}

/// The inputs of the operation: `w`, `ẇ` (each `nm`), `ω`, `g` (3 each), then the node masses,
/// the modes' translations (`k`, `j`, component), the elements' `G` and `Σ μ∘T_j`.
fn inputs(
    modal: &ModalBody<Rev>,
    field: &GeometricStiffness<Rev>,
    mode_spin: &[Vector3<Rev>],
    state: &[Rev],
) -> Option<(Vec<Rev>, BodyData)> {
    let elements = field.elements.as_ref()?;
    let (nm, nf, n) = (modal.n_modes(), field.field_modes, modal.n_nodes());
    if elements.iter().any(|e| e.unit.shape() != (nf, nf)) {
        return None;
    }
    let len = state.len() + n * (1 + 3 * nm) + elements.len() * nf * nf + 3 * mode_spin.len();
    let mut handles = Vec::with_capacity(len);
    handles.extend_from_slice(state);
    handles.extend(&modal.node_masses);
    for k in 0..n {
        for j in 0..nm {
            handles.extend((0..3).map(|i| modal.modes[(6 * k + i, j)]));
        }
    }
    for e in elements {
        handles.extend(e.unit.iter());
    }
    handles.extend(mode_spin.iter().flat_map(|v| v.iter().copied()));
    debug_assert_eq!(handles.len(), len, "the operation's inputs");
    let data = BodyData {
        nm,
        nf,
        masses: modal.node_masses.iter().map(|m| m.value()).collect(),
        u0: modal.node_positions.clone(),
        modes: (0..n * nm)
            .map(|kj| {
                let (k, j) = (kj / nm, kj % nm);
                Vector3::from_fn(|i, _| modal.modes[(6 * k + i, j)].value())
            })
            .collect(),
        elements: elements
            .iter()
            .map(|e| (e.parent, e.child, e.axis))
            .collect(),
        units: elements
            .iter()
            .flat_map(|e| e.unit.iter().map(|x| x.value()))
            .collect(),
        row_len: (0..nf).map(|j| field.row_len(j)).collect(),
    };
    Some((handles, data))
}

/// The operation's values and what its reverse reads.
struct Evaluation {
    data: BodyData,
    w: Vec<f64>,
    wd: Vec<f64>,
    om: Vector3<f64>,
    g: Vector3<f64>,
    /// Per element, `g_j` and `h_j`.
    gh: Vec<(Vec<f64>, Vec<f64>)>,
    /// Per node, `C_j` (at `k · nf + j`).
    columns: Vec<Vector3<f64>>,
    /// Per node, `u`, `u̇`, `c` and the columns `x_j` (at `k · nm + j`).
    u: Vec<Vector3<f64>>,
    ud: Vec<Vector3<f64>>,
    c: Vec<Vector3<f64>>,
    x: Vec<Vector3<f64>>,
}

/// The sums as the operation's outputs, in order: `total`, `first`, `m_oo` (column-major),
/// `m_rw`, `m_ow`, `qc`, `s_o`, `s_w`, then `cc_jl` for `j ≤ l` ([`frame_sums`] reads them
/// back, and the outputs' adjoints the same way).
fn flatten<S: Scalar>(s: &FrameSums<S>) -> Vec<S> {
    let mut out = vec![s.total];
    out.extend(s.first.iter().chain(s.m_oo.iter()));
    out.extend(s.m_rw.iter().chain(&s.m_ow).flat_map(|v| v.iter().copied()));
    out.extend(s.qc.iter().chain(s.s_o.iter()).chain(&s.s_w));
    let nf = s.field_cc.as_ref().map_or(0, |cc| cc.len().isqrt());
    for j in 0..nf {
        out.extend(&s.field_cc.as_ref().expect("the field's products")[j * nf + j..(j + 1) * nf]);
    }
    out
}

fn record(
    modal: &ModalBody<Rev>,
    field: &GeometricStiffness<Rev>,
    mode_spin: &[Vector3<Rev>],
    state: &[Rev],
) -> Option<FrameSums<Rev>> {
    let (handles, data) = inputs(modal, field, mode_spin, state)?;
    let (nm, nf) = (data.nm, data.nf);
    let v: Vec<f64> = state.iter().map(|x| x.value()).collect();
    let spin: Vec<Vector3<f64>> = mode_spin.iter().map(|s| s.map(|x| x.value())).collect();
    let evaluation = Evaluation::new(
        data,
        (&v[..nm], &v[nm..2 * nm]),
        Vector3::new(v[2 * nm], v[2 * nm + 1], v[2 * nm + 2]),
        Vector3::new(v[2 * nm + 3], v[2 * nm + 4], v[2 * nm + 5]),
    );
    let values = flatten(&evaluation.sums(&spin));
    let out = Rev::external(&handles, &values, evaluation);
    Some(frame_sums(&out, nm, nf))
}

/// The [`FrameSums`] of the outputs (in [`flatten`]'s order; `cc_jl` zero for `j > l`).
fn frame_sums<S: Scalar>(out: &[S], nm: usize, nf: usize) -> FrameSums<S> {
    let mut it = out.iter().copied();
    let mut next = || it.next().expect("the operation's outputs");
    let total = next();
    let v3 = |next: &mut dyn FnMut() -> S| Vector3::new(next(), next(), next());
    let first = v3(&mut next);
    let m_oo = Matrix3::from_column_slice(&[(); 9].map(|_| next()));
    let m_rw = (0..nm).map(|_| v3(&mut next)).collect();
    let m_ow = (0..nm).map(|_| v3(&mut next)).collect();
    let qc = v3(&mut next);
    let s_o = v3(&mut next);
    let s_w = (0..nm).map(|_| next()).collect();
    let mut field_cc = vec![S::zero(); nf * nf];
    for j in 0..nf {
        for l in j..nf {
            field_cc[j * nf + l] = next();
        }
    }
    FrameSums {
        total,
        first,
        m_oo,
        m_rw,
        m_ow,
        qc,
        s_o,
        s_w,
        field_cc: Some(field_cc),
    }
}

impl Evaluation {
    /// The field along the elements, then each node's vectors.
    fn new(data: BodyData, (w, wd): (&[f64], &[f64]), om: Vector3<f64>, g: Vector3<f64>) -> Self {
        let (nm, nf, n) = (data.nm, data.nf, data.masses.len());
        let mut columns = vec![Vector3::zeros(); n * nf];
        let mut half = vec![Vector3::zeros(); n];
        let mut rates = vec![Vector3::zeros(); n];
        let mut gh = Vec::with_capacity(data.elements.len());
        for (e, &(p, c, t)) in data.elements.iter().enumerate() {
            let unit = &data.units[e * nf * nf..(e + 1) * nf * nf];
            let (mut g, mut h) = (vec![0.0; nf], vec![0.0; nf]);
            for j in 0..nf {
                let col = &unit[j * nf..j * nf + data.row_len[j]];
                for (l, &a) in col.iter().enumerate() {
                    g[j] += w[l] * a;
                    h[j] += wd[l] * a;
                }
            }
            let (mut hw, mut rate) = (0.0, 0.0);
            for j in 0..nf {
                hw += g[j] * w[j];
                rate += h[j] * wd[j];
            }
            for j in 0..nf {
                columns[c * nf + j] = columns[p * nf + j] - t * g[j];
            }
            half[c] = half[p] - t * (hw * 0.5);
            rates[c] = rates[p] - t * rate;
            gh.push((g, h));
        }
        let (mut u, mut ud, mut cs) = (Vec::with_capacity(n), Vec::with_capacity(n), Vec::new());
        let mut x = vec![Vector3::zeros(); n * nm];
        for k in 0..n {
            let mut uk = data.u0[k] + half[k];
            let mut udk = Vector3::zeros();
            for j in 0..nm {
                let xk = data.modes[k * nm + j];
                uk += xk * w[j];
                x[k * nm + j] = if j < nf { xk + columns[k * nf + j] } else { xk };
                udk += x[k * nm + j] * wd[j];
            }
            cs.push(om.cross(&om.cross(&uk)) + om.cross(&udk) * 2.0 + rates[k]);
            u.push(uk);
            ud.push(udk);
        }
        Self {
            data,
            w: w.to_vec(),
            wd: wd.to_vec(),
            om,
            g,
            gh,
            columns,
            u,
            ud,
            c: cs,
            x,
        }
    }

    /// The sums, `m_ow_j` starting at `spin_j`.
    fn sums(&self, spin: &[Vector3<f64>]) -> FrameSums<f64> {
        let (nm, nf) = (self.data.nm, self.data.nf);
        let mut total = 0.0;
        let mut first = Vector3::zeros();
        let mut m_oo = Matrix3::zeros();
        let mut m_rw = vec![Vector3::zeros(); nm];
        let mut m_ow = spin.to_vec();
        let mut qc = Vector3::zeros();
        let mut s_o = Vector3::zeros();
        let mut s_w = vec![0.0; nm];
        let mut cc = vec![0.0; nf * nf];
        for (k, &m) in self.data.masses.iter().enumerate() {
            if m == 0.0 {
                continue;
            }
            let col = &self.columns[k * nf..(k + 1) * nf];
            for j in 0..nf {
                let cj = col[j] * m;
                for l in j..nf {
                    cc[j * nf + l] += cj.dot(&col[l]);
                }
            }
            let (u, c) = (self.u[k], self.c[k]);
            total += m;
            first += u * m;
            let ut = skew(&u);
            m_oo += (ut.transpose() * ut) * m;
            qc += c * m;
            s_o += u.cross(&c) * m;
            let gc = (self.g - c) * m;
            for j in 0..nm {
                let x = self.x[k * nm + j];
                m_rw[j] += x * m;
                m_ow[j] += u.cross(&x) * m;
                s_w[j] += x.dot(&gc);
            }
        }
        FrameSums {
            total,
            first,
            m_oo,
            m_rw,
            m_ow,
            qc,
            s_o,
            s_w,
            field_cc: Some(cc),
        }
    }
}

impl ExternalReverse for Evaluation {
    fn reverse(&self, y_bar: &[f64], x_bar: &mut InputAdjoints<'_>) {
        let d = &self.data;
        let (nm, nf, n) = (d.nm, d.nf, d.masses.len());
        let b = frame_sums(y_bar, nm, nf);
        let cc = b.field_cc.as_deref().expect("the field's products");
        // the inputs: w, ẇ, ω, g, then from these offsets the masses, modes, units, spin
        let masses_at = 2 * nm + 6;
        let modes_at = masses_at + n;
        let units_at = modes_at + n * nm * 3;
        let spin_at = units_at + d.elements.len() * nf * nf;
        let (mut w_bar, mut wd_bar) = (vec![0.0; nm], vec![0.0; nm]);
        let (mut om_bar, mut g_bar) = (Vector3::zeros(), Vector3::zeros());
        for j in 0..nm {
            for i in 0..3 {
                x_bar.add(spin_at + 3 * j + i, b.m_ow[j][i]);
            }
        }
        let mut columns_bar = vec![Vector3::<f64>::zeros(); n * nf];
        let mut half_bar = vec![Vector3::<f64>::zeros(); n];
        let mut rates_bar = vec![Vector3::<f64>::zeros(); n];
        let m_oo_sym = b.m_oo + b.m_oo.transpose();
        let mut cc_sym = vec![0.0; nf * nf];
        for j in 0..nf {
            for l in j..nf {
                let c = cc[j * nf + l];
                cc_sym[j * nf + l] += c;
                cc_sym[l * nf + j] += c;
            }
        }
        let mut sc = vec![Vector3::<f64>::zeros(); nf];
        let trace = b.m_oo.trace();
        let om = self.om;
        for (k, &m) in d.masses.iter().enumerate() {
            if m == 0.0 {
                continue;
            }
            let (u, ud, c) = (self.u[k], self.ud[k], self.c[k]);
            let x = &self.x[k * nm..(k + 1) * nm];
            let col = &self.columns[k * nf..(k + 1) * nf];
            let g_c = self.g - c;
            // the mass's adjoint: every sum is linear in it
            let ut = skew(&u);
            let mut m_bar = b.total
                + b.first.dot(&u)
                + b.m_oo.dot(&(ut.transpose() * ut))
                + b.qc.dot(&c)
                + b.s_o.dot(&u.cross(&c));
            let mut sw_x = Vector3::zeros(); // Σ_j s̄_w_j x_j
            let mut x_ow = Vector3::zeros(); // Σ_j x_j × m̄_ow_j
            for (((xj, rw), ow), &sw) in x.iter().zip(&b.m_rw).zip(&b.m_ow).zip(&b.s_w) {
                m_bar += rw.dot(xj) + ow.dot(&u.cross(xj));
                m_bar += sw * xj.dot(&g_c);
                sw_x += xj * sw;
                x_ow += xj.cross(ow);
            }
            // (S C)_j, S the symmetric form of c̄c: Σ_{j ≤ l} c̄c_jl C_j · C_l = ½ Σ_j C_j · (S C)_j
            for (sc, row) in sc.iter_mut().zip(cc_sym.chunks_exact(nf)) {
                let mut acc = Vector3::zeros();
                for (c, &s) in col.iter().zip(row) {
                    acc += c * s;
                }
                *sc = acc;
            }
            m_bar += 0.5 * (0..nf).map(|j| col[j].dot(&sc[j])).sum::<f64>();
            x_bar.add(masses_at + k, m_bar);
            g_bar += sw_x * m;
            // c̄, then ū (directly and through c), u̇ through c
            let c_bar = (b.qc + b.s_o.cross(&u) - sw_x) * m;
            let mut u_bar =
                (b.first + u * (2.0 * trace) - m_oo_sym * u + c.cross(&b.s_o) + x_ow) * m;
            u_bar += om * om.dot(&c_bar) - c_bar * om.dot(&om);
            om_bar += c_bar * om.dot(&u) + u * om.dot(&c_bar) - om * (2.0 * u.dot(&c_bar));
            om_bar += ud.cross(&c_bar) * 2.0;
            let ud_bar = c_bar.cross(&om) * 2.0;
            rates_bar[k] += c_bar;
            half_bar[k] += u_bar;
            // the columns x_j = X_j + C_j, and u = u0 + H + Σ X_j w_j
            let modes = &d.modes[k * nm..(k + 1) * nm];
            let state = (self.w.iter().zip(&self.wd)).zip(w_bar.iter_mut().zip(&mut wd_bar));
            let sums = (b.m_rw.iter().zip(&b.m_ow)).zip(&b.s_w);
            for (j, (((xj, xk), ((&w, &wd), (wb, wdb))), ((rw, ow), &sw))) in
                (x.iter().zip(modes).zip(state).zip(sums)).enumerate()
            {
                let xj_bar = (rw + ow.cross(&u) + g_c * sw) * m + ud_bar * wd;
                *wdb += xj.dot(&ud_bar);
                *wb += xk.dot(&u_bar);
                let at = modes_at + (k * nm + j) * 3;
                for i in 0..3 {
                    x_bar.add(at + i, xj_bar[i] + u_bar[i] * w);
                }
                if j < nf {
                    columns_bar[k * nf + j] += xj_bar;
                }
            }
            // Σ_{j ≤ l} c̄c_jl m C_j · C_l
            for (bar, sc) in columns_bar[k * nf..(k + 1) * nf].iter_mut().zip(&sc) {
                *bar += sc * m;
            }
        }
        // back along the elements, from the tips to the clamp
        for (e, &(p, c, t)) in d.elements.iter().enumerate().rev() {
            let (g, h) = &self.gh[e];
            let hw_bar = -0.5 * t.dot(&half_bar[c]);
            let rate_bar = -t.dot(&rates_bar[c]);
            let hb = half_bar[c];
            half_bar[p] += hb;
            let rb = rates_bar[c];
            rates_bar[p] += rb;
            for j in 0..nf {
                let cb = columns_bar[c * nf + j];
                columns_bar[p * nf + j] += cb;
                let g_bar = -t.dot(&cb) + hw_bar * self.w[j];
                let h_bar = rate_bar * self.wd[j];
                w_bar[j] += hw_bar * g[j];
                wd_bar[j] += rate_bar * h[j];
                let len = d.row_len[j];
                let unit = &d.units[e * nf * nf + j * nf..][..len];
                let at = units_at + e * nf * nf + j * nf;
                let bars = w_bar[..len].iter_mut().zip(&mut wd_bar[..len]);
                let values = unit.iter().zip(&self.w[..len]).zip(&self.wd[..len]);
                for (l, ((w_bar, wd_bar), ((&a, &w), &wd))) in bars.zip(values).enumerate() {
                    x_bar.add(at + l, g_bar * w + h_bar * wd);
                    *w_bar += g_bar * a;
                    *wd_bar += h_bar * a;
                }
            }
        }
        for (j, (&w, &wd)) in w_bar.iter().zip(&wd_bar).enumerate() {
            x_bar.add(j, w);
            x_bar.add(nm + j, wd);
        }
        for i in 0..3 {
            x_bar.add(2 * nm + i, om_bar[i]);
            x_bar.add(2 * nm + 3 + i, g_bar[i]);
        }
    }
}

/// [`crate::body::second_order_node`] of node `k` recorded as one tape operation when the
/// evaluation is on the tape (`P` and `S` are [`Rev`]); `None` otherwise. Its reverse, with
/// `c_ij = Σ_l A_i,lj w_l` and `r_ij = Σ_l A_i,lj ẇ_l` over the node's nodal matrices `A_i`
/// (`C_j = −c_·j`, `R = −Σ_j r_·j ẇ_j`, `H = ½ Σ_j C_j w_j`), is [`NodeField`]'s.
pub(crate) fn taped_second_order_node<P: Scalar, S: Scalar>(
    g: &GeometricStiffness<P>,
    k: usize,
    w: &[S],
    wd: &[S],
) -> Option<SecondOrderNode<S>> {
    let g = (g as &dyn Any).downcast_ref::<GeometricStiffness<Rev>>()?;
    let nf = g.field_modes;
    let matrices = &g.nodal[3 * k..3 * k + 3];
    if matrices.iter().any(|a| a.shape() != (nf, nf)) {
        return None;
    }
    let mut handles: Vec<Rev> = taped(w[..nf].iter().chain(&wd[..nf]))?;
    handles.extend(matrices.iter().flat_map(|a| a.iter().copied()));
    let op = NodeField {
        nf,
        w: w[..nf].iter().map(|x| x.value()).collect(),
        wd: wd[..nf].iter().map(|x| x.value()).collect(),
        matrices: matrices
            .iter()
            .flat_map(|a| a.iter().map(|x| x.value()))
            .collect(),
        row_len: (0..nf).map(|j| g.row_len(j)).collect(),
        products: Vec::new(),
    };
    let (op, values) = op.evaluate();
    let out = Rev::external(&handles, &values, op);
    let v3 = |i: usize| Vector3::new(out[i], out[i + 1], out[i + 2]);
    let node = SecondOrderNode {
        half: v3(0),
        columns: (0..nf).map(|j| v3(3 + 3 * j)).collect(),
        rates: v3(3 + 3 * nf),
    };
    cast(node)
}

/// One node's field from its nodal matrices, as a tape operation: inputs `w`, `ẇ` (the
/// field's `nf` each) and the three matrices (column-major); outputs `H`, the `C_j` and `R`.
struct NodeField {
    nf: usize,
    w: Vec<f64>,
    wd: Vec<f64>,
    matrices: Vec<f64>,
    row_len: Vec<usize>,
    /// `(c_ij, r_ij)` at `i · nf + j`.
    products: Vec<(f64, f64)>,
}

impl NodeField {
    /// The operation with its products, and its outputs (in [`second_order_node_into`]'s
    /// order of operations).
    ///
    /// [`second_order_node_into`]: crate::body::second_order_node_into
    fn evaluate(mut self) -> (Self, Vec<f64>) {
        let nf = self.nf;
        let mut columns = vec![Vector3::<f64>::zeros(); nf];
        let mut rates = Vector3::<f64>::zeros();
        for i in 0..3 {
            for j in 0..nf {
                let col = &self.matrices[i * nf * nf + j * nf..][..self.row_len[j]];
                let (mut c, mut r) = (0.0, 0.0);
                for (l, &a) in col.iter().enumerate() {
                    c += self.w[l] * a;
                    r += self.wd[l] * a;
                }
                self.products.push((c, r));
                columns[j][i] = -c;
                rates[i] -= r * self.wd[j];
            }
        }
        let mut half = Vector3::<f64>::zeros();
        for (j, c) in columns.iter().enumerate() {
            half += c * (self.w[j] * 0.5);
        }
        let mut out: Vec<f64> = half.iter().copied().collect();
        out.extend(columns.iter().flat_map(|c| c.iter().copied()));
        out.extend(rates.iter());
        (self, out)
    }
}

impl ExternalReverse for NodeField {
    fn reverse(&self, y_bar: &[f64], x_bar: &mut InputAdjoints<'_>) {
        let nf = self.nf;
        let (mut w_bar, mut wd_bar) = (vec![0.0; nf], vec![0.0; nf]);
        let half_bar = Vector3::new(y_bar[0], y_bar[1], y_bar[2]);
        let rates_bar = &y_bar[3 + 3 * nf..6 + 3 * nf];
        for j in 0..nf {
            let column = |i: usize| -self.products[i * nf + j].0;
            let c = Vector3::from_fn(|i, _| column(i));
            w_bar[j] += 0.5 * c.dot(&half_bar);
        }
        for i in 0..3 {
            for j in 0..nf {
                let (_, r) = self.products[i * nf + j];
                // C_j = −c_ij (its adjoint with ½ w_j H̄ from the half), R_i −= r_ij ẇ_j
                let c_bar = -(y_bar[3 + 3 * j + i] + 0.5 * self.w[j] * half_bar[i]);
                let r_bar = -rates_bar[i] * self.wd[j];
                wd_bar[j] -= rates_bar[i] * r;
                let at = i * nf * nf + j * nf;
                let col = &self.matrices[at..at + self.row_len[j]];
                for (l, &a) in col.iter().enumerate() {
                    x_bar.add(2 * nf + at + l, c_bar * self.w[l] + r_bar * self.wd[l]);
                    w_bar[l] += c_bar * a;
                    wd_bar[l] += r_bar * a;
                }
            }
        }
        for (j, (&w, &wd)) in w_bar.iter().zip(&wd_bar).enumerate() {
            x_bar.add(j, w);
            x_bar.add(nf + j, wd);
        }
    }
}
