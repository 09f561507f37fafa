//! Bodies: rigid bodies and floating-frame flexible (modal) bodies (paper §2.1, Eqs. 1–6, 11–12).
//!
//! Coordinates of one body: `q_b = (r, p, w)` — origin of the body frame in the global frame,
//! Euler parameters of the body frame, modal coordinates (flexible bodies only). Velocity
//! variables: `v_b = (ṙ, ω', ẇ)` — global velocity of the origin, angular velocity in body
//! components, modal velocities.

use fem::{FieldElement, GeometricStiffness, ModalBody, ModalStresses};
use laminate::PlyStrength;
use std::ops::Range;
use std::sync::OnceLock;

use nalgebra::{DMatrix, Matrix3, Vector3, Vector4};
use sens::{Rev, Scalar, Tape};

use crate::field_gram::{FieldGram, FrameSums, GramSeeds};
use crate::kin::{mtv, mv, rotation, skew};

pub(crate) mod taped_sums;
pub(crate) use crate::nodal::{
    axial, dot_rows, dot_scaled, lift, mode_vec, mode_vec_times, outer, scaled, vec3, vec3f,
};

/// Handle of a body in a [`crate::Model`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct BodyId(pub(crate) usize);

impl From<usize> for BodyId {
    /// The body at position `i` in the order of creation.
    fn from(i: usize) -> Self {
        Self(i)
    }
}

impl BodyId {
    /// Position of the body in the model's body list.
    pub fn index(self) -> usize {
        self.0
    }
}

/// A rigid body; its body frame sits at the centre of mass.
#[derive(Clone, Debug)]
pub struct RigidBody<P: Scalar> {
    pub name: String,
    /// Mass (kg).
    pub mass: P,
    /// Inertia tensor about the centre of mass, body axes (kg·m²).
    pub inertia: Matrix3<P>,
}

impl<P: Scalar> RigidBody<P> {
    pub fn new(name: impl Into<String>, mass: P, inertia: Matrix3<P>) -> Self {
        Self {
            name: name.into(),
            mass,
            inertia,
        }
    }
}

/// A flexible body in the floating frame of reference, reduced to the modes of a [`ModalBody`].
///
/// Its body frame is the frame of the modal model. Nodal displacements are `u' = X w` (Eq. 11);
/// the mass matrix is the modal form of Eq. (2) built from the lumped nodal masses and
/// inertias, evaluated at the deformed nodal positions; the elastic and damping forces are
/// `Λ w` and `diag(2ζω) ẇ`.
///
/// With [`FlexibleBody::geometric`] the deformation field carries its second-order part, the
/// foreshortening of the beams (docs/geometric-stiffening.md): `u' = X w + ½ Q(w, w)`, with
/// `Q_k,i = −nodal[3k + i]` of the [`GeometricStiffness`]. It enters the nodes' and markers'
/// positions, the mass matrix and the inertia forces, and the Jacobians through which joint
/// and applied forces act, so the geometric stiffness of the body's axial forces (inertia,
/// joints, applied loads) follows from the same field.
#[derive(Clone, Debug)]
pub struct FlexibleBody<P: Scalar> {
    pub name: String,
    pub modal: ModalBody<P>,
    /// The second-order field of the beams, as the modal geometric stiffness of unit nodal
    /// forces (`None`: the linear floating frame).
    pub geometric: Option<Box<GeometricStiffness<P>>>,
    /// The plies' stresses of a shell body's modes and the plies' strengths, for the ply
    /// stress and failure responses (`None`: the body has none).
    pub stresses: Option<Box<PlyStresses<P>>>,
}

/// The plies' stresses of a shell body's modes ([`fem::shell_modal_stresses`]) with each
/// ply's strengths, `strengths[l][p]` for ply `p` of laminate `l` (`None`: not given, no
/// failure index).
#[derive(Clone, Debug)]
pub struct PlyStresses<P: Scalar> {
    pub modal: ModalStresses<P>,
    pub strengths: Vec<Vec<Option<PlyStrength>>>,
}

impl<P: Scalar> FlexibleBody<P> {
    pub fn new(name: impl Into<String>, modal: ModalBody<P>) -> Self {
        Self {
            name: name.into(),
            modal,
            geometric: None,
            stresses: None,
        }
    }

    /// The same body with its plies' stresses (the ply stress and failure responses).
    pub fn with_ply_stresses(mut self, s: PlyStresses<P>) -> Self {
        self.stresses = Some(Box::new(s));
        self
    }

    /// The same body with its second-order field and so geometric stiffening
    /// ([`fem::geometric_stiffness`] of its modes).
    pub fn with_geometric_stiffness(mut self, g: GeometricStiffness<P>) -> Self {
        self.geometric = Some(Box::new(g));
        self
    }
}

/// A body of the model.
#[derive(Clone, Debug)]
pub enum Body<P: Scalar> {
    Rigid(RigidBody<P>),
    Flexible(FlexibleBody<P>),
}

impl<P: Scalar> Body<P> {
    pub fn name(&self) -> &str {
        match self {
            Body::Rigid(b) => &b.name,
            Body::Flexible(b) => &b.name,
        }
    }

    /// Number of modal coordinates (0 for a rigid body).
    pub fn n_modes(&self) -> usize {
        match self {
            Body::Rigid(_) => 0,
            Body::Flexible(b) => b.modal.n_modes(),
        }
    }

    /// Total mass (kg), value only.
    pub fn mass(&self) -> f64 {
        match self {
            Body::Rigid(b) => b.mass.value(),
            Body::Flexible(b) => b.modal.total_mass(),
        }
    }

    /// Convert the parameters to another scalar type.
    pub fn map<Q: Scalar>(&self, f: &impl Fn(P) -> Q) -> Body<Q> {
        match self {
            Body::Rigid(b) => Body::Rigid(RigidBody {
                name: b.name.clone(),
                mass: f(b.mass),
                inertia: b.inertia.map(f),
            }),
            Body::Flexible(b) => Body::Flexible(FlexibleBody {
                name: b.name.clone(),
                modal: ModalBody {
                    node_positions: b.modal.node_positions.clone(),
                    node_masses: b.modal.node_masses.iter().map(|&x| f(x)).collect(),
                    node_inertias: b.modal.node_inertias.iter().map(|x| x.map(f)).collect(),
                    modes: b.modal.modes.map(f),
                    eigenvalues: b.modal.eigenvalues.iter().map(|&x| f(x)).collect(),
                    modal_damping: b.modal.modal_damping.iter().map(|&x| f(x)).collect(),
                    stiffness_matrix: b
                        .modal
                        .stiffness_matrix
                        .as_ref()
                        .map(|k| Box::new(k.map(f))),
                    damping_matrix: b.modal.damping_matrix.as_ref().map(|c| Box::new(c.map(f))),
                },
                geometric: b.geometric.as_ref().map(|g| Box::new(g.map(f))),
                stresses: b.stresses.as_ref().map(|s| {
                    Box::new(PlyStresses {
                        modal: s.modal.map(f),
                        strengths: s.strengths.clone(),
                    })
                }),
            }),
        }
    }
}

/// The second-order displacement of node `k` of a body with field `g` (docs/geometric-stiffening.md)
/// at modal coordinates `w` and rates `wd`: with `Q_k,i = −nodal[3k + i]`,
/// - `half`: `½ Q_k(w, w)`, the node's foreshortening (body components);
/// - `columns[j]`: `Q_k(w)_j = Σ_l Q_k,jl w_l`, what the mode columns of the node gain
///   (`∂u'/∂w_j = X_j + Q_k(w)_j`), so that the node's rate gains `Σ_j columns[j] ẇ_j`;
/// - `rates`: `Q_k(ẇ, ẇ)`, its acceleration at zero modal accelerations.
pub(crate) struct SecondOrderNode<S: Scalar> {
    pub half: Vector3<S>,
    /// One per mode of the field (`field_modes`); the other modes' columns gain nothing.
    pub columns: Vec<Vector3<S>>,
    pub rates: Vector3<S>,
}

pub(crate) fn second_order_node<P: Scalar, S: Scalar + From<P>>(
    g: &GeometricStiffness<P>,
    k: usize,
    w: &[S],
    wd: &[S],
) -> SecondOrderNode<S> {
    let mut out = SecondOrderNode {
        half: Vector3::zeros(),
        columns: vec![Vector3::zeros(); g.field_modes],
        rates: Vector3::zeros(),
    };
    second_order_node_into(g, k, w, wd, &mut out);
    out
}

/// `Σ_l A_jl w_l` over the `n × n` symmetric `A`'s row `j` ([`symmetric_row_products`] without
/// its second vector, the same operations), `l < len`.
#[inline]
fn symmetric_row_product<P: Scalar, S: Scalar + From<P>>(
    a: &DMatrix<P>,
    (j, len): (usize, usize),
    w: &[S],
) -> S {
    let n = a.nrows();
    dot_scaled(&a.as_slice()[j * n..j * n + len], w)
}

/// `(Σ_l A_jl w_l, Σ_l A_jl ẇ_l)` over the `n × n` symmetric `A`'s row `j` (its column `j`,
/// contiguous), `l < len` (the row's entries that may be nonzero,
/// [`GeometricStiffness::row_len`]); `w` and `ẇ` scaled by the entries' values when they are
/// plain (as [`crate::nodal::dot_scaled`]). One pass over the column for both vectors:
/// [`symmetric_row_product`] twice gives the same numbers and took 2 % more of the spatial
/// four-bar's instructions.
#[inline]
fn symmetric_row_products<P: Scalar, S: Scalar + From<P>>(
    a: &DMatrix<P>,
    (j, len): (usize, usize),
    w: &[S],
    wd: &[S],
) -> (S, S) {
    let col = a.column(j);
    let (mut x_w, mut x_wd) = (S::zero(), S::zero());
    if P::PLAIN {
        for l in 0..len {
            let x = col[l].value();
            x_w += w[l] * x;
            x_wd += wd[l] * x;
        }
    } else {
        for l in 0..len {
            let x: S = lift(col[l]);
            x_w += x * w[l];
            x_wd += x * wd[l];
        }
    }
    (x_w, x_wd)
}

/// [`second_order_node`] into `out` (whose `columns` has `g.field_modes` entries).
pub(crate) fn second_order_node_into<P: Scalar, S: Scalar + From<P>>(
    g: &GeometricStiffness<P>,
    k: usize,
    w: &[S],
    wd: &[S],
    out: &mut SecondOrderNode<S>,
) {
    let nf = g.field_modes;
    out.rates = Vector3::zeros();
    for i in 0..3 {
        for j in 0..nf {
            let (c, r) = symmetric_row_products(&g.nodal[3 * k + i], (j, g.row_len(j)), w, wd);
            out.columns[j][i] = -c;
            out.rates[i] -= r * wd[j];
        }
    }
    out.half = Vector3::zeros();
    for (j, c) in out.columns.iter().enumerate() {
        out.half += c * (w[j] * S::from_f64(0.5));
    }
}

/// [`SecondOrderNode`]s of every node of a beam body's field from its elements
/// ([`GeometricStiffness::elements`]), accumulated from the clamp along the tree: each
/// element's `G_e w` and `G_e ẇ` once, where [`second_order_node_into`] takes the three
/// nodal matrices of every node (their sums over the path). Nodes off the tree (a coupling's,
/// massless) stay zero.
pub(crate) struct FieldAtNodes<S: Scalar> {
    nf: usize,
    /// `Q_k(w)_j` at `k · nf + j`.
    columns: Vec<Vector3<S>>,
    half: Vec<Vector3<S>>,
    rates: Vec<Vector3<S>>,
}

impl<S: Scalar> FieldAtNodes<S> {
    pub(crate) fn new<P: Scalar>(
        elements: &[FieldElement<P>],
        (nf, eigenmodes): (usize, usize),
        n_nodes: usize,
        w: &[S],
        wd: &[S],
    ) -> Self
    where
        S: From<P>,
    {
        let mut out = Self {
            nf,
            columns: vec![Vector3::zeros(); n_nodes * nf],
            half: vec![Vector3::zeros(); n_nodes],
            rates: vec![Vector3::zeros(); n_nodes],
        };
        let (mut g, mut h) = (vec![S::zero(); nf], vec![S::zero(); nf]);
        for e in elements {
            for j in 0..nf {
                let len = if j < eigenmodes { nf } else { eigenmodes };
                (g[j], h[j]) = symmetric_row_products(&e.unit, (j, len), w, wd);
            }
            let (mut half, mut rate) = (S::zero(), S::zero());
            for j in 0..nf {
                half += g[j] * w[j];
                rate += h[j] * wd[j];
            }
            let t: Vector3<S> = vec3f(&e.axis);
            let (p, c) = (e.parent, e.child);
            for j in 0..nf {
                out.columns[c * nf + j] = out.columns[p * nf + j] - t * g[j];
            }
            out.half[c] = out.half[p] - t * (half * S::from_f64(0.5));
            out.rates[c] = out.rates[p] - t * rate;
        }
        out
    }

    /// Node `k`'s [`SecondOrderNode`] into `out`.
    pub(crate) fn node_into(&self, k: usize, out: &mut SecondOrderNode<S>) {
        out.columns
            .copy_from_slice(&self.columns[k * self.nf..(k + 1) * self.nf]);
        out.half = self.half[k];
        out.rates = self.rates[k];
    }
}

/// `½ Q_k(w, w)`: the second-order displacement of node `k` at modal coordinates `w`
/// ([`second_order_node`]'s `half`, in the same order of operations, without its columns'
/// products with the rates).
pub(crate) fn foreshortening<P: Scalar, S: Scalar + From<P>>(
    g: &GeometricStiffness<P>,
    k: usize,
    w: &[S],
) -> Vector3<S> {
    let mut half = Vector3::<S>::zeros();
    for j in 0..g.field_modes {
        let row = (j, g.row_len(j));
        let column = Vector3::from_fn(|i, _| -symmetric_row_product(&g.nodal[3 * k + i], row, w));
        half += column * (w[j] * S::from_f64(0.5));
    }
    half
}

/// Body pose read from the body's coordinate slice.
pub(crate) struct Pose<S: Scalar> {
    pub r: Vector3<S>,
    pub a: Matrix3<S>,
}

pub(crate) fn pose<S: Scalar>(q: &[S]) -> Pose<S> {
    Pose {
        r: vec3(&q[0..3]),
        a: rotation(&Vector4::new(q[3], q[4], q[5], q[6])),
    }
}

/// Everything the equations of motion need from one body at one state: its mass matrix block
/// and the generalised forces `g + s − Λw − Dẇ` (Eq. 12), written into the system arrays at
/// velocity offset `off`.
///
/// `invariants` caches a flexible body's [`ModalInvariants`] (made at the first call).
#[allow(clippy::too_many_arguments)]
pub(crate) fn body_dynamics<P: Scalar, S: Scalar + From<P>>(
    body: &Body<P>,
    invariants: &OnceLock<ModalInvariants<P>>,
    q: &[S],
    v: &[S],
    gravity: &Vector3<f64>,
    mass: &mut DMatrix<S>,
    off: usize,
    force: &mut [S],
) {
    let rd_omega = vec3(&v[3..6]);
    let g: Vector3<S> = vec3f(gravity);
    match body {
        Body::Rigid(b) => {
            let m: S = lift(b.mass);
            let j: Matrix3<S> = b.inertia.map(lift);
            for i in 0..3 {
                mass[(off + i, off + i)] = m;
                for k in 0..3 {
                    mass[(off + 3 + i, off + 3 + k)] = j[(i, k)];
                }
            }
            let s_w = -rd_omega.cross(&(j * rd_omega));
            for i in 0..3 {
                force[off + i] += g[i] * m;
                force[off + 3 + i] += s_w[i];
            }
        }
        Body::Flexible(b) => {
            let Pose { a, .. } = pose(q);
            let inv =
                invariants.get_or_init(|| ModalInvariants::new(&b.modal, b.geometric.as_deref()));
            if let Some(second_order) = &b.geometric {
                second_order_dynamics(&b.modal, second_order, inv, &a, q, v, g, mass, off, force);
                return;
            }
            flexible_dynamics(&b.modal, inv, &a, q, v, g, mass, off, force);
        }
    }
}

/// Sums over the nodes of a flexible body that do not depend on the state (the inertia
/// invariants of the floating frame of reference): with `u_k = u0_k + Σ_j X_kj w_j` the
/// deformed position of node `k` (mass `m_k`, rotary inertias `μ_k`, rotation mode vectors
/// `T_kj`), every nodal sum of the mass matrix and the inertia forces is a polynomial in `w`
/// and `ẇ` with these coefficients, so an evaluation costs `O(n_modes²)` whatever the number
/// of nodes.
#[derive(Clone, Debug)]
pub(crate) struct ModalInvariants<P: Scalar> {
    n_modes: usize,
    /// `Σ m_k`.
    total: P,
    /// `Σ m_k u0_k`.
    first: Vector3<P>,
    /// `Σ μ_k`.
    inertia: Vector3<P>,
    /// `Σ m_k u0_k u0_kᵀ`.
    second: Matrix3<P>,
    /// `Σ_k m_k X_kj` for each mode `j`.
    mode_first: Vec<Vector3<P>>,
    /// `Σ_k m_k u0_k X_kjᵀ` for each mode `j`.
    mode_cross: Vec<Matrix3<P>>,
    /// `Σ_k m_k X_kj X_klᵀ` at `j · n_modes + l`.
    mode_second: Vec<Matrix3<P>>,
    /// `Σ_k μ_k ∘ T_kj` for each mode `j`.
    mode_spin: Vec<Vector3<P>>,
    /// The modal mass matrix `Σ_k m_k X_kjᵀ X_kl + T_kjᵀ diag(μ_k) T_kl` (row-major).
    modal_mass: Vec<P>,
    /// The sums of the second-order field, when the body has one.
    field: Option<FieldInvariants<P>>,
    /// The second-order rotation of the nodes' rotary inertia, with the field.
    rotary: Option<RotaryInvariants<P>>,
    /// The Gram table of the second-order field, when the body has one with enough nodes that
    /// it is cheaper than the loop over them ([`FieldGram::pays`]).
    gram: Option<FieldGram<P>>,
    /// `max_k |X_kj|` (translations) for each mode `j`, values.
    reach: Vec<f64>,
    /// `max_k |Q_k,jl|` at `j · nf + l` for the field's modes, values (empty without a field).
    field_reach: Vec<f64>,
}

/// Sums over the nodes of a body's second-order field `Q` (`Q_k,i = −nodal[3k + i]`, of the
/// leading `nf` modes) that the modal mass matrix needs: with the columns `C_kl = Q_k(w)_l`,
/// `Σ m X_j · C_l = Σ_p R[j, l, p] w_p` and `Σ m C_j · C_l = Σ_pq T[j, p, l, q] w_p w_q`.
#[derive(Clone, Debug)]
pub(crate) struct FieldInvariants<P: Scalar> {
    /// `R[j, l, p] = Σ_k m_k X_kj · Q_k,lp` at `(j · nf + l) · nf + p`.
    r: Vec<P>,
    /// `T[j, p, l, q] = Σ_k m_k Q_k,jp · Q_k,lq` at `((j · nf + p) · nf + l) · nf + q`, for a
    /// body whose sums come from its Gram table (empty otherwise: the loop over the nodes sums
    /// `Σ m C_j · C_l` itself, and `nf⁴` sums a node are not made for nothing).
    t: Vec<P>,
}

/// The rotary inertia of the nodes turned by their own rotations `θ_k = Σ_j T_kj w_j` to
/// the second order: with `Θ_kj = [T_kj]×` and `R_k = I + Θ_k + ½ Θ_k²`,
/// `Σ_k R_k μ_k R_kᵀ = Σ μ + Σ_j w_j L_j + Σ_jl w_j w_l S_jl + O(w³)`. It enters the kinetic
/// energy as `½ ωᵀ (Σ R μ Rᵀ) ω`: the restoring moment of a spinning blade's chordwise mass
/// against twist (the propeller moment, docs/operating-points.md).
#[derive(Clone, Debug)]
pub(crate) struct RotaryInvariants<P: Scalar> {
    /// `L_j = Σ_k Θ_kj μ_k + μ_k Θ_kjᵀ`.
    l: Vec<Matrix3<P>>,
    /// The symmetric part `½ (S_jl + S_lj)` of
    /// `S_jl = Σ_k Θ_kj μ_k Θ_klᵀ + ½ (Θ_kj Θ_kl μ_k + μ_k Θ_klᵀ Θ_kjᵀ)`, entry `i` (column
    /// major) at `(9 j + i) · n_modes + l`: the rows contracted with `w` are contiguous
    /// (`ΔJ` takes only that part, and its derivatives are then `L_j + 2 Σ_l S_jl w_l`).
    s: Vec<P>,
}

impl<P: Scalar> RotaryInvariants<P> {
    fn map<Q: Scalar>(&self, f: &impl Fn(P) -> Q) -> RotaryInvariants<Q> {
        RotaryInvariants {
            l: self.l.iter().map(|m| m.map(f)).collect(),
            s: self.s.iter().map(|&x| f(x)).collect(),
        }
    }
}

impl<P: Scalar> FieldInvariants<P> {
    fn map<Q: Scalar>(&self, f: &impl Fn(P) -> Q) -> FieldInvariants<Q> {
        FieldInvariants {
            r: self.r.iter().map(|&x| f(x)).collect(),
            t: self.t.iter().map(|&x| f(x)).collect(),
        }
    }
}

impl<P: Scalar> ModalInvariants<P> {
    /// The same invariants with their scalars converted, visited in a fixed order (the sums'
    /// fields in their declared order, each entry by entry; the values `reach` kept).
    pub(crate) fn map<Q: Scalar>(&self, f: &impl Fn(P) -> Q) -> ModalInvariants<Q> {
        let m3 = |m: &Matrix3<P>| m.map(f);
        let v3 = |v: &Vector3<P>| v.map(f);
        ModalInvariants {
            n_modes: self.n_modes,
            total: f(self.total),
            first: v3(&self.first),
            inertia: v3(&self.inertia),
            second: m3(&self.second),
            mode_first: self.mode_first.iter().map(v3).collect(),
            mode_cross: self.mode_cross.iter().map(m3).collect(),
            mode_second: self.mode_second.iter().map(m3).collect(),
            mode_spin: self.mode_spin.iter().map(v3).collect(),
            modal_mass: self.modal_mass.iter().map(|&x| f(x)).collect(),
            field: self.field.as_ref().map(|x| x.map(f)),
            rotary: self.rotary.as_ref().map(|x| x.map(f)),
            gram: self.gram.as_ref().map(|x| x.map(f)),
            reach: self.reach.clone(),
            field_reach: self.field_reach.clone(),
        }
    }
}

impl ModalInvariants<Rev> {
    /// Add to each of `adjoints` (by tape node) the adjoints of the data of `body` that these
    /// invariants of it (inputs of the tape of their own, made from that data's values)
    /// carry back, from the invariants' adjoints in it: the reverse of [`Self::new`] written
    /// by hand, node by node ([`ModalInvariants::seed_node`], [`GramSeeds::seed_node`]), its
    /// cost a few times that of the invariants in `f64` (recorded on the tape, a shell's
    /// would cost twenty times that of making them in `Dual<8>`).
    pub(crate) fn pull_back_to(&self, body: &FlexibleBody<Rev>, adjoints: &mut [Vec<f64>]) {
        let field = body.geometric.as_deref();
        let mark = Tape::len();
        for a in adjoints.iter_mut() {
            let bar = self.map(&|x: Rev| x.adjoint(a));
            let gram = bar.gram.as_ref().map(GramSeeds::new);
            let rotary = bar.rotary.as_ref().map(RotaryInvariants::raw_adjoints);
            for k in 0..body.modal.n_nodes() {
                bar.seed_node(&body.modal, field, rotary.as_deref(), k, a);
                if let (Some(g), Some(field)) = (&gram, field) {
                    g.seed_node(&body.modal, field, k, a);
                }
            }
            // (the data are the tape's inputs: nothing was recorded above them)
            Tape::backpropagate(a, mark);
            a.truncate(mark);
        }
        Tape::rewind(mark);
    }
}

impl ModalInvariants<f64> {
    /// With these the adjoints of a body's invariants, seed in `adjoints` those of node `k`'s
    /// data (its mass, rotary inertias, mode vectors and field: `modal` and `field` on the
    /// tape) that its terms in the sums carry back; `rotary` the rotary sums' adjoints before
    /// their symmetrisation ([`RotaryInvariants::raw_adjoints`]). The node's terms are
    /// those [`Self::of_nodes`] adds, nodes skipped where it skips them; the Gram table's are
    /// [`GramSeeds::seed_node`]'s.
    fn seed_node(
        &self,
        modal: &ModalBody<Rev>,
        field: Option<&GeometricStiffness<Rev>>,
        rotary: Option<&[Matrix3<f64>]>,
        k: usize,
        adjoints: &mut Vec<f64>,
    ) {
        let nm = self.n_modes;
        let value = |v: Vector3<Rev>| v.map(|x| x.value());
        let m = modal.node_masses[k].value();
        let mu = value(modal.node_inertias[k]);
        let u0 = modal.node_positions[k];
        let x: Vec<Vector3<f64>> = (0..nm)
            .map(|j| value(mode_vec(modal, k, j, false)))
            .collect();
        let t: Vec<Vector3<f64>> = (0..nm)
            .map(|j| value(mode_vec(modal, k, j, true)))
            .collect();
        let mut m_bar = self.total + self.first.dot(&u0) + u0.dot(&(self.second * u0));
        let mut mu_bar = self.inertia;
        let mut x_bar = vec![Vector3::<f64>::zeros(); nm];
        let mut t_bar = vec![Vector3::<f64>::zeros(); nm];
        for j in 0..nm {
            m_bar += self.mode_first[j].dot(&x[j]) + u0.dot(&(self.mode_cross[j] * x[j]));
            x_bar[j] += (self.mode_first[j] + self.mode_cross[j].tr_mul(&u0)) * m;
            t_bar[j] += self.mode_spin[j].component_mul(&mu);
            mu_bar += self.mode_spin[j].component_mul(&t[j]);
            for l in 0..nm {
                let (second, mass) = (&self.mode_second[j * nm + l], self.modal_mass[j * nm + l]);
                m_bar += x[j].dot(&(second * x[l])) + mass * x[j].dot(&x[l]);
                x_bar[j] += (second * x[l] + x[l] * mass) * m;
                x_bar[l] += (second.tr_mul(&x[j]) + x[j] * mass) * m;
                t_bar[j] += t[l].component_mul(&mu) * mass;
                t_bar[l] += t[j].component_mul(&mu) * mass;
                mu_bar += t[j].component_mul(&t[l]) * mass;
            }
        }
        if let (Some(sums), Some(g)) = (&self.field, field) {
            m_bar += sums.seed_node(modal, g, k, (m, &x, &mut x_bar), adjoints);
        }
        if let Some(raw) = rotary
            && mu != Vector3::zeros()
        {
            let l_bar = &self.rotary.as_ref().expect("the rotary sums' adjoints").l;
            let mu_m = Matrix3::from_diagonal(&mu);
            let theta: Vec<Matrix3<f64>> = t.iter().map(crate::kin::skew).collect();
            let mut theta_bar = vec![Matrix3::<f64>::zeros(); nm];
            let mut mu_m_bar = Matrix3::<f64>::zeros();
            for j in 0..nm {
                // L_j = Θ_j μ + μ Θ_jᵀ
                let lb = &l_bar[j];
                theta_bar[j] += (lb + lb.transpose()) * mu_m;
                mu_m_bar += theta[j].tr_mul(lb) + lb * theta[j];
                for p in 0..nm {
                    // S_jp = Θ_j μ Θ_pᵀ + B + Bᵀ, B = ½ Θ_j Θ_p μ
                    let a = &raw[j * nm + p];
                    let a_sym = (a + a.transpose()) * 0.5;
                    theta_bar[j] += a * theta[p] * mu_m + a_sym * mu_m * theta[p].transpose();
                    theta_bar[p] += a.tr_mul(&theta[j]) * mu_m + theta[j].tr_mul(&a_sym) * mu_m;
                    mu_m_bar +=
                        theta[j].tr_mul(a) * theta[p] + (theta[j] * theta[p]).tr_mul(&a_sym);
                }
            }
            for j in 0..nm {
                let tb = &theta_bar[j];
                t_bar[j] += Vector3::new(
                    tb[(2, 1)] - tb[(1, 2)],
                    tb[(0, 2)] - tb[(2, 0)],
                    tb[(1, 0)] - tb[(0, 1)],
                );
            }
            mu_bar += mu_m_bar.diagonal();
        }
        modal.node_masses[k].seed(adjoints, m_bar);
        for i in 0..3 {
            modal.node_inertias[k][i].seed(adjoints, mu_bar[i]);
            for j in 0..nm {
                modal.modes[(fem::NODE_DOFS * k + i, j)].seed(adjoints, x_bar[j][i]);
                modal.modes[(fem::NODE_DOFS * k + 3 + i, j)].seed(adjoints, t_bar[j][i]);
            }
        }
    }
}

impl FieldInvariants<f64> {
    /// With these the adjoints of a body's field sums, seed in `adjoints` those of node `k`'s
    /// field `g` (on the tape) and add to `x_bar` those of its mode vectors `x` (mass `m`)
    /// that its terms carry back; the mass's adjoint returned. `R[j, l, p] −= m X_j,i
    /// Q_i,lp`, `T[j, p, l, q] += m Q_i,jp Q_i,lq` for each of the node's three nodal matrices
    /// `Q_i` (none for a node without mass, as [`FieldInvariants::new`]).
    fn seed_node(
        &self,
        modal: &ModalBody<Rev>,
        g: &GeometricStiffness<Rev>,
        k: usize,
        (m, x, x_bar): (f64, &[Vector3<f64>], &mut [Vector3<f64>]),
        adjoints: &mut Vec<f64>,
    ) -> f64 {
        if modal.node_masses[k].value() == 0.0 {
            return 0.0;
        }
        let (nm, nf) = (x.len(), g.field_modes);
        let mut m_bar = 0.0;
        for i in 0..3 {
            let q = &g.nodal[3 * k + i];
            let qv = q.map(|a| a.value());
            let mut q_bar = DMatrix::<f64>::zeros(nf, nf);
            for j in 0..nm {
                for l in 0..nf {
                    for p in 0..nf {
                        let r = self.r[(j * nf + l) * nf + p];
                        m_bar -= r * x[j][i] * qv[(l, p)];
                        x_bar[j][i] -= r * m * qv[(l, p)];
                        q_bar[(l, p)] -= r * m * x[j][i];
                    }
                }
            }
            if !self.t.is_empty() {
                for j in 0..nf {
                    for p in 0..nf {
                        for l in 0..nf {
                            for qq in 0..nf {
                                let t = self.t[((j * nf + p) * nf + l) * nf + qq];
                                m_bar += t * qv[(j, p)] * qv[(l, qq)];
                                q_bar[(j, p)] += t * m * qv[(l, qq)];
                                q_bar[(l, qq)] += t * m * qv[(j, p)];
                            }
                        }
                    }
                }
            }
            for (a, &b) in q.iter().zip(q_bar.iter()) {
                a.seed(adjoints, b);
            }
        }
        m_bar
    }
}

impl RotaryInvariants<f64> {
    /// With these the adjoints of the rotary sums, the adjoints of the sums `S_jp` before
    /// their symmetrisation (at `j · n_modes + p`): `½ (S̄_jp + S̄_pj)` of the stored ones.
    fn raw_adjoints(&self) -> Vec<Matrix3<f64>> {
        let nm = self.l.len();
        let stored =
            |j: usize, p: usize| Matrix3::from_fn(|r, c| self.s[(9 * j + r + 3 * c) * nm + p]);
        (0..nm * nm)
            .map(|jp| {
                let (j, p) = (jp / nm, jp % nm);
                (stored(j, p) + stored(p, j)) * 0.5
            })
            .collect()
    }
}

impl<P: Scalar> RotaryInvariants<P> {
    /// The sums over the nodes `nodes` of `modal`.
    fn new(modal: &ModalBody<P>, nodes: Range<usize>) -> Self {
        let nm = modal.n_modes();
        let mut l = vec![Matrix3::zeros(); nm];
        let mut s = vec![Matrix3::<P>::zeros(); nm * nm];
        let half = P::from_f64(0.5);
        for k in nodes {
            let mu = Matrix3::from_diagonal(&modal.node_inertias[k]);
            if mu == Matrix3::zeros() {
                continue;
            }
            let theta: Vec<Matrix3<P>> = (0..nm)
                .map(|j| crate::kin::skew(&mode_vec::<P, P>(modal, k, j, true)))
                .collect();
            for j in 0..nm {
                let tm = theta[j] * mu;
                l[j] += tm + tm.transpose();
                for p in 0..nm {
                    let b = theta[j] * theta[p] * mu * half;
                    s[j * nm + p] += tm * theta[p].transpose() + b + b.transpose();
                }
            }
        }
        for j in 0..nm {
            for p in j + 1..nm {
                let sym = (s[j * nm + p] + s[p * nm + j]) * half;
                s[j * nm + p] = sym;
                s[p * nm + j] = sym;
            }
        }
        let s = (0..9 * nm * nm)
            .map(|x| {
                let (ji, p) = (x / nm, x % nm);
                s[ji / 9 * nm + p][ji % 9]
            })
            .collect();
        Self { l, s }
    }

    /// `ΔJ(w) = Σ_j w_j L_j + Σ_jl w_j w_l S_jl` and its derivatives `∂ΔJ/∂w_j`: with
    /// `E_j = Σ_l S_jl w_l`, `ΔJ = Σ_j (L_j + E_j) w_j` and `∂ΔJ/∂w_j = L_j + 2 E_j` (`S`
    /// symmetric), one product of the table with `w`.
    fn at<S: Scalar + From<P>>(&self, w: &[S]) -> (Matrix3<S>, Vec<Matrix3<S>>) {
        let nm = self.l.len();
        let mut dj = Matrix3::<S>::zeros();
        let two = S::from_f64(2.0);
        let rows: Vec<&[P]> = self.s.chunks(nm).collect();
        let e_all = dot_rows(&rows, &w[..nm]);
        let d = (0..nm)
            .map(|j| {
                let e = Matrix3::from_column_slice(&e_all[9 * j..9 * j + 9]);
                let lj: Matrix3<S> = self.l[j].map(lift);
                dj += (lj + e) * w[j];
                lj + e * two
            })
            .collect();
        (dj, d)
    }
}

impl<P: Scalar> FieldInvariants<P> {
    /// The sums of `modal`'s field `g` over the nodes `nodes`, `T` only with `fourth_order`.
    fn new(
        modal: &ModalBody<P>,
        g: &GeometricStiffness<P>,
        fourth_order: bool,
        nodes: Range<usize>,
    ) -> Self {
        let (nm, nf) = (modal.n_modes(), g.field_modes);
        let mut r = vec![P::zero(); nm * nf * nf];
        let mut t = vec![P::zero(); if fourth_order { nf * nf * nf * nf } else { 0 }];
        for k in nodes {
            let m = modal.node_masses[k];
            if m == P::zero() {
                continue;
            }
            for i in 0..3 {
                let q = &g.nodal[3 * k + i];
                for j in 0..nm {
                    let x = modal.modes[(fem::NODE_DOFS * k + i, j)] * m;
                    for l in 0..nf {
                        for p in 0..nf {
                            r[(j * nf + l) * nf + p] -= x * q[(l, p)];
                        }
                    }
                }
                if !fourth_order {
                    continue;
                }
                for j in 0..nf {
                    for p in 0..nf {
                        let a = q[(j, p)] * m;
                        for l in 0..nf {
                            for qq in 0..nf {
                                t[((j * nf + p) * nf + l) * nf + qq] += a * q[(l, qq)];
                            }
                        }
                    }
                }
            }
        }
        Self { r, t }
    }
}

impl<P: Scalar> ModalInvariants<P> {
    /// The invariants of `modal`, with those of its second-order field `field` if any.
    pub(crate) fn new(modal: &ModalBody<P>, field: Option<&GeometricStiffness<P>>) -> Self {
        let gram = field.is_some_and(|g| FieldGram::pays(modal, g));
        Self::of_nodes(modal, field, (gram, gram), 0..modal.n_nodes())
    }

    /// [`Self::new`]'s sums over the nodes `nodes` alone: with `fourth_order`, the field's
    /// fourth-order sums `T`, which a body whose sums come from its Gram table reads
    /// ([`FieldGram::pays`] of the whole body), and with `gram` that table. Every invariant is
    /// a sum over the nodes of terms made from that node's data alone (the symmetrised and
    /// reordered tables too: those steps are linear), so the whole body's invariants are the
    /// sums of its nodes', and their adjoints go back to the data one node at a time
    /// ([`ModalInvariants::pull_back_to`]). (`reach` and `field_reach`, values only, are the
    /// nodes' own.)
    pub(crate) fn of_nodes(
        modal: &ModalBody<P>,
        field: Option<&GeometricStiffness<P>>,
        (fourth_order, gram): (bool, bool),
        nodes: Range<usize>,
    ) -> Self {
        let nm = modal.n_modes();
        let gram = field
            .filter(|_| gram)
            .map(|g| FieldGram::new(modal, g, nodes.clone()));
        let mut inv = Self {
            n_modes: nm,
            total: P::zero(),
            first: Vector3::zeros(),
            inertia: Vector3::zeros(),
            second: Matrix3::zeros(),
            mode_first: vec![Vector3::zeros(); nm],
            mode_cross: vec![Matrix3::zeros(); nm],
            mode_second: vec![Matrix3::zeros(); nm * nm],
            mode_spin: vec![Vector3::zeros(); nm],
            modal_mass: vec![P::zero(); nm * nm],
            field: field.map(|g| FieldInvariants::new(modal, g, fourth_order, nodes.clone())),
            rotary: field.map(|_| RotaryInvariants::new(modal, nodes.clone())),
            gram,
            reach: (0..nm)
                .map(|j| {
                    (nodes.clone())
                        .map(|k| {
                            mode_vec::<P, P>(modal, k, j, false)
                                .map(|x| x.value())
                                .norm()
                        })
                        .fold(0.0, f64::max)
                })
                .collect(),
            field_reach: field.map_or(Vec::new(), |g| {
                let nf = g.field_modes;
                (0..nf * nf)
                    .map(|jl| {
                        (nodes.clone())
                            .map(|k| {
                                let c = |i: usize| g.nodal[3 * k + i][(jl / nf, jl % nf)].value();
                                Vector3::new(c(0), c(1), c(2)).norm()
                            })
                            .fold(0.0, f64::max)
                    })
                    .collect()
            }),
        };
        for k in nodes {
            let m = modal.node_masses[k];
            let mu = modal.node_inertias[k];
            let u0 = modal.node_positions[k];
            let x: Vec<Vector3<P>> = (0..nm).map(|j| mode_vec(modal, k, j, false)).collect();
            let t: Vec<Vector3<P>> = (0..nm).map(|j| mode_vec(modal, k, j, true)).collect();
            let u0p: Vector3<P> = vec3f(&u0);
            let (mp, mup) = (m, mu);
            inv.total += m;
            inv.first += u0p * m;
            inv.inertia += mu;
            inv.second += outer(&u0p, &u0p) * m;
            for j in 0..nm {
                inv.mode_first[j] += x[j] * mp;
                inv.mode_cross[j] += outer(&u0p, &x[j]) * mp;
                inv.mode_spin[j] += t[j].component_mul(&mup);
                for l in 0..nm {
                    inv.mode_second[j * nm + l] += outer(&x[j], &x[l]) * mp;
                    inv.modal_mass[j * nm + l] +=
                        x[j].dot(&x[l]) * mp + t[j].dot(&t[l].component_mul(&mup));
                }
            }
        }
        inv
    }
}

impl<P: Scalar> ModalInvariants<P> {
    /// An upper bound of the largest nodal translation `|X_k w + ½ Q_k(w, w)|` at modal
    /// coordinates `w` (values), from the largest translation of each mode and field pair:
    /// `Σ_j r_j |w_j| + ½ Σ_jl r_jl |w_j| |w_l|`.
    pub(crate) fn deformation_bound(&self, w: &[f64]) -> f64 {
        let linear: f64 = self.reach.iter().zip(w).map(|(r, x)| r * x.abs()).sum();
        let nf = (self.field_reach.len() as f64).sqrt() as usize;
        let mut second = 0.0;
        for j in 0..nf {
            for l in 0..nf {
                second += self.field_reach[j * nf + l] * (w[j] * w[l]).abs();
            }
        }
        linear + 0.5 * second
    }
}

/// The mass matrix block and generalised forces of a flexible body from its invariants:
/// the nodal sums of Eq. (2) (lumped masses and rotary inertias at the deformed nodes)
/// written as polynomials in `w` and `ẇ`.
#[allow(clippy::too_many_arguments)]
fn flexible_dynamics<P: Scalar, S: Scalar + From<P>>(
    modal: &ModalBody<P>,
    inv: &ModalInvariants<P>,
    a: &Matrix3<S>,
    q: &[S],
    v: &[S],
    g: Vector3<S>,
    mass: &mut DMatrix<S>,
    off: usize,
    force: &mut [S],
) {
    let nm = inv.n_modes;
    let w = &q[7..7 + nm];
    let wd = &v[6..6 + nm];
    let om = vec3(&v[3..6]);
    let two = S::from_f64(2.0);
    let total: S = lift(inv.total);
    let c2: Vec<Vector3<S>> = inv.mode_first.iter().map(|x| x.map(lift)).collect();
    let q2 = |j: usize, l: usize| -> Matrix3<S> { inv.mode_second[j * nm + l].map(lift) };
    // Σ m u = Σ m u0 + Σ_j (Σ m X_j) w_j
    let mut first: Vector3<S> = inv.first.map(lift);
    for j in 0..nm {
        first += c2[j] * w[j];
    }
    // G_j = Σ m u X_jᵀ = Σ m u0 X_jᵀ + Σ_l w_l Σ m X_l X_jᵀ
    let mut gj: Vec<Matrix3<S>> = inv.mode_cross.iter().map(|x| x.map(lift)).collect();
    let mut second: Matrix3<S> = inv.second.map(lift); // Σ m u uᵀ
    for j in 0..nm {
        let pj = gj[j];
        second += (pj + pj.transpose()) * w[j];
    }
    for l in 0..nm {
        for j in 0..nm {
            let qlj = q2(l, j);
            gj[j] += qlj * w[l];
            second += qlj * (w[l] * w[j]);
        }
    }
    // Σ m u u̇ᵀ = Σ_j ẇ_j G_j
    let mut u_ud = Matrix3::<S>::zeros();
    for j in 0..nm {
        u_ud += gj[j] * wd[j];
    }
    // rotational inertia: Σ m ũᵀũ + Σ μ = (tr Σ m u uᵀ) I − Σ m u uᵀ + diag(Σ μ)
    let tr = second.trace();
    let mut m_oo = -second;
    for i in 0..3 {
        m_oo[(i, i)] += tr + lift::<P, S>(inv.inertia[i]);
    }
    // coupling ω–ẇ: Σ m u × X_j + Σ μ ∘ T_j
    let m_ow: Vec<Vector3<S>> = (0..nm)
        .map(|j| axial(&gj[j]) + inv.mode_spin[j].map(lift))
        .collect();
    // Σ m ω × (ω × u) + 2 ω × u̇
    let c2_wd = (0..nm).fold(Vector3::<S>::zeros(), |acc, j| acc + c2[j] * wd[j]);
    let qc = om.cross(&om.cross(&first)) + om.cross(&c2_wd) * two;
    // Σ m u × c: (Σ m u uᵀ ω) × ω + 2 (ω tr(Σ m u u̇ᵀ) − Σ m u̇ uᵀ ω)
    let s_o = mv(&second, &om).cross(&om) + (om * u_ud.trace() - mtv(&u_ud, &om)) * two;
    // Σ μ ∘ (ω + θ̇_k)
    let mut hj = om.component_mul(&inv.inertia.map(lift));
    for j in 0..nm {
        hj += inv.mode_spin[j].map(lift) * wd[j];
    }
    let g_body = mtv(a, &g);
    let gu = first.cross(&g_body);
    // mass matrix blocks
    frame_blocks(mass, off, a, total, &first, &m_oo, &c2, &m_ow);
    for j in 0..nm {
        for l in j..nm {
            let x: S = lift(inv.modal_mass[j * nm + l]);
            mass[(off + 6 + j, off + 6 + l)] = x;
            mass[(off + 6 + l, off + 6 + j)] = x;
        }
    }
    // forces: gravity, quadratic velocity terms, elastic and damping
    let s_r = mv(a, &qc);
    let s_om = s_o + om.cross(&hj);
    for i in 0..3 {
        force[off + i] += g[i] * total - s_r[i];
        force[off + 3 + i] += gu[i] - s_om[i];
    }
    let om2 = om.dot(&om);
    for j in 0..nm {
        // Σ m X_j · (g' − ω × (ω × u) − 2 ω × u̇)
        let centripetal = mv(&gj[j], &om).dot(&om) - om2 * gj[j].trace();
        let mut coriolis = S::zero();
        for l in 0..nm {
            coriolis += om.dot(&axial(&q2(l, j))) * wd[l];
        }
        force[off + 6 + j] += c2[j].dot(&g_body) - centripetal - coriolis * two;
    }
    elastic_forces(modal, w, wd, &mut force[off + 6..off + 6 + nm]);
}

/// The blocks of a flexible body's mass matrix that involve its frame: mass `total`, first
/// moment `first` (`Σ m u`, body components), rotational inertia `m_oo`, and per mode the
/// translation coupling `c[j]` (`Σ m X_j`, body components) and rotation coupling `m_ow[j]`.
#[allow(clippy::too_many_arguments)]
fn frame_blocks<S: Scalar>(
    mass: &mut DMatrix<S>,
    off: usize,
    a: &Matrix3<S>,
    total: S,
    first: &Vector3<S>,
    m_oo: &Matrix3<S>,
    c: &[Vector3<S>],
    m_ow: &[Vector3<S>],
) {
    let a_first = a * skew(first); // A Σ m ũ
    for i in 0..3 {
        mass[(off + i, off + i)] = total;
        for k in 0..3 {
            mass[(off + i, off + 3 + k)] = -a_first[(i, k)];
            mass[(off + 3 + k, off + i)] = -a_first[(i, k)];
            mass[(off + 3 + i, off + 3 + k)] = m_oo[(i, k)];
        }
    }
    for (j, (cj, oj)) in c.iter().zip(m_ow).enumerate() {
        let acol = mv(a, cj);
        for i in 0..3 {
            mass[(off + i, off + 6 + j)] = acol[i];
            mass[(off + 6 + j, off + i)] = acol[i];
            mass[(off + 3 + i, off + 6 + j)] = oj[i];
            mass[(off + 6 + j, off + 3 + i)] = oj[i];
        }
    }
}

/// The mass matrix block and generalised forces of a flexible body with a second-order field
/// `u' = X w + ½ Q(w, w)`: the nodal sums of Eq. (2) at the field's positions, node by node
/// and exact in `w` (a truncation of the field's terms would leave the equations of motion
/// without an energy they conserve, which lets a large deflection run away). With the mode
/// columns `X̃ = X + Q(w)` of the field, each node's acceleration is
/// `r̈ + A(α × u + ω × (ω × u) + 2 ω × u̇ + X̃ ẅ + Q(ẇ, ẇ))`, and its rotary inertia follows the
/// linear rotations as in [`flexible_dynamics`]. The sums that are polynomials of low degree
/// come from the invariants `inv` (the rotary terms, and the modal mass
/// `Σ m X̃_jᵀ X̃_l` through [`FieldInvariants`]); the rest is summed node by node.
/// The [`FrameSums`] of a second-order body by a loop over its nodes (the reference form;
/// [`FieldGram::sums`] gives the same from the body's Gram table).
#[allow(clippy::too_many_arguments)]
pub(crate) fn node_sums<P: Scalar, S: Scalar + From<P>>(
    modal: &ModalBody<P>,
    field: &GeometricStiffness<P>,
    inv: &ModalInvariants<P>,
    w: &[S],
    wd: &[S],
    om: &Vector3<S>,
    g_body: &Vector3<S>,
) -> FrameSums<S> {
    let nm = modal.n_modes();
    let nf = field.field_modes;
    let two = S::from_f64(2.0);
    let mut total = S::zero();
    let mut first = Vector3::<S>::zeros(); // Σ m u
    let mut m_oo = Matrix3::<S>::zeros();
    let mut m_rw = vec![Vector3::<S>::zeros(); nm]; // Σ m X̃_j
    let mut m_ow: Vec<Vector3<S>> = inv.mode_spin.iter().map(|x| x.map(lift)).collect();
    let mut qc = Vector3::<S>::zeros(); // Σ m c
    let mut s_o = Vector3::<S>::zeros(); // Σ m u × c
    let mut s_w = vec![S::zero(); nm]; // Σ m X̃_j · (g' − c)
    let mut x = vec![Vector3::<S>::zeros(); nm];
    let mut second = SecondOrderNode {
        half: Vector3::zeros(),
        columns: vec![Vector3::zeros(); nf],
        rates: Vector3::zeros(),
    };
    let mut field_cc = vec![S::zero(); nf * nf];
    let by_elements = field.elements.as_ref().map(|els| {
        FieldAtNodes::new(
            els,
            (nf, field.eigenmodes),
            modal.n_nodes(),
            &w[..nf],
            &wd[..nf],
        )
    });
    for k in 0..modal.n_nodes() {
        // the node's mass scales duals by its value when it is plain
        let mk = modal.node_masses[k];
        if lift::<P, S>(mk) == S::zero() {
            continue;
        }
        match &by_elements {
            Some(f) => f.node_into(k, &mut second),
            None => second_order_node_into(field, k, w, wd, &mut second),
        }
        for j in 0..nf {
            let cj = scaled(second.columns[j], mk);
            for l in j..nf {
                field_cc[j * nf + l] += cj.dot(&second.columns[l]);
            }
        }
        let mut u: Vector3<S> = vec3f(&modal.node_positions[k]);
        u += second.half;
        let mut ud = Vector3::<S>::zeros();
        for j in 0..nm {
            u += mode_vec_times(modal, k, j, w[j]);
            let d: Vector3<S> = mode_vec(modal, k, j, false);
            x[j] = if j < nf { d + second.columns[j] } else { d };
            ud += x[j] * wd[j];
        }
        total += lift::<P, S>(mk);
        first += scaled(u, mk);
        let ut = skew(&u);
        m_oo += scaled(ut.transpose() * ut, mk);
        // the node's acceleration at zero accelerations, beyond the frame's r̈
        let c = om.cross(&om.cross(&u)) + om.cross(&ud) * two + second.rates;
        qc += scaled(c, mk);
        s_o += scaled(u.cross(&c), mk);
        let gc = scaled(g_body - c, mk);
        for j in 0..nm {
            m_rw[j] += scaled(x[j], mk);
            m_ow[j] += scaled(u.cross(&x[j]), mk);
            s_w[j] += x[j].dot(&gc);
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

#[allow(clippy::too_many_arguments)]
fn second_order_dynamics<P: Scalar, S: Scalar + From<P>>(
    modal: &ModalBody<P>,
    field: &GeometricStiffness<P>,
    inv: &ModalInvariants<P>,
    a: &Matrix3<S>,
    q: &[S],
    v: &[S],
    g: Vector3<S>,
    mass: &mut DMatrix<S>,
    off: usize,
    force: &mut [S],
) {
    let nm = modal.n_modes();
    let nf = field.field_modes;
    let w = &q[7..7 + nm];
    let wd = &v[6..6 + nm];
    let om = vec3(&v[3..6]);
    let g_body = mtv(a, &g);
    let FrameSums {
        total,
        first,
        mut m_oo,
        m_rw,
        m_ow,
        qc,
        s_o,
        s_w,
        field_cc,
    } = match &inv.gram {
        Some(gram) => gram.sums(&inv.mode_spin, w, wd, &om, &g_body),
        // on the reverse-mode tape, a beam's sums as one operation
        None => taped_sums::taped_node_sums((modal, field), &inv.mode_spin, (w, wd), &om, &g_body)
            .unwrap_or_else(|| node_sums(modal, field, inv, w, wd, &om, &g_body)),
    };
    let inertia: Vector3<S> = inv.inertia.map(lift);
    for i in 0..3 {
        m_oo[(i, i)] += inertia[i];
    }
    // Σ μ ∘ (ω + θ̇): the rotary inertia follows the rotations' rates linearly
    let mut hj = om.component_mul(&inertia);
    for j in 0..nm {
        hj += inv.mode_spin[j].map(lift) * wd[j];
    }
    // and is turned by them to the second order in the frame's rotation, `½ ωᵀ ΔJ(w) ω`:
    // `ΔJ` in the mass matrix, `(dΔJ/dt) ω + ω × ΔJ ω` on the frame, `½ ωᵀ ∂ΔJ/∂w_j ω` on
    // the modes
    let mut rotary = Vector3::<S>::zeros();
    let mut rotary_w = vec![S::zero(); nm];
    if let Some(r) = &inv.rotary {
        let (dj, d) = r.at(w);
        m_oo += dj;
        hj += mv(&dj, &om);
        for j in 0..nm {
            let dom = mv(&d[j], &om);
            rotary += dom * wd[j];
            rotary_w[j] = dom.dot(&om) * S::from_f64(0.5);
        }
    }
    frame_blocks(mass, off, a, total, &first, &m_oo, &m_rw, &m_ow);
    // Σ m X̃_jᵀ X̃_l = modal mass + Σ m (X_j · C_l + C_j · X_l + C_j · C_l)
    let fi = inv
        .field
        .as_ref()
        .expect("the invariants of a body with a field have the field's");
    let mut m_ww = DMatrix::<S>::from_fn(nm, nm, |j, l| lift(inv.modal_mass[j * nm + l]));
    let rows: Vec<&[P]> = (0..nm * nf)
        .map(|jl| {
            let (start, len) = (jl * nf, field.row_len(jl % nf));
            &fi.r[start..start + len]
        })
        .collect();
    for (jl, x) in dot_rows(&rows, w).into_iter().enumerate() {
        let (j, l) = (jl / nf, jl % nf);
        m_ww[(j, l)] += x;
        m_ww[(l, j)] += x;
    }
    // Σ m C_j · C_l = Σ_pq T[j, p, l, q] w_p w_q: summed with the nodes when they were (a
    // third of the contraction's work), else contracted; `T[j, p, l, q]` is zero where `Q_jp`
    // or `Q_lq` is
    let t_rows = field_cc.is_none().then(|| {
        let rows: Vec<&[P]> = (0..nf)
            .flat_map(|j| (j..nf).flat_map(move |l| (0..field.row_len(j)).map(move |p| (j, l, p))))
            .map(|(j, l, p)| {
                let start = ((j * nf + p) * nf + l) * nf;
                &fi.t[start..start + field.row_len(l)]
            })
            .collect();
        dot_rows(&rows, w)
    });
    let mut t_row = 0;
    for j in 0..nf {
        for l in j..nf {
            let x = match (&field_cc, &t_rows) {
                (Some(cc), _) => cc[j * nf + l],
                (None, Some(t)) => {
                    let mut x = S::zero();
                    for &wp in &w[..field.row_len(j)] {
                        x += t[t_row] * wp;
                        t_row += 1;
                    }
                    x
                }
                (None, None) => unreachable!("contracted without the nodal sums"),
            };
            m_ww[(j, l)] += x;
            if l != j {
                m_ww[(l, j)] += x;
            }
        }
    }
    for j in 0..nm {
        for l in 0..nm {
            mass[(off + 6 + j, off + 6 + l)] = m_ww[(j, l)];
        }
    }
    let s_r = mv(a, &qc);
    let s_om = s_o + om.cross(&hj) + rotary;
    let gu = first.cross(&g_body);
    for i in 0..3 {
        force[off + i] += g[i] * total - s_r[i];
        force[off + 3 + i] += gu[i] - s_om[i];
    }
    for j in 0..nm {
        force[off + 6 + j] += s_w[j] + rotary_w[j];
    }
    elastic_forces(modal, w, wd, &mut force[off + 6..off + 6 + nm]);
}

/// Subtract the elastic and damping forces `K_r w + C_r ẇ` of the modal coordinates `w` and
/// rates `wd` from `force`: diagonal (`eigenvalues`, `modal_damping`) unless the body carries
/// full modal matrices.
fn elastic_forces<P: Scalar, S: Scalar + From<P>>(
    modal: &ModalBody<P>,
    w: &[S],
    wd: &[S],
    force: &mut [S],
) {
    for (j, f) in force.iter_mut().enumerate() {
        match &modal.stiffness_matrix {
            None => *f -= lift::<P, S>(modal.eigenvalues[j]) * w[j],
            Some(k) => {
                for l in 0..w.len() {
                    *f -= lift::<P, S>(k[(j, l)]) * w[l];
                }
            }
        }
        match &modal.damping_matrix {
            None => *f -= lift::<P, S>(modal.modal_damping[j]) * wd[j],
            Some(c) => {
                for l in 0..wd.len() {
                    *f -= lift::<P, S>(c[(j, l)]) * wd[l];
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use sens::Dual;

    /// The straightforward node-by-node sums of a body with a second-order field (the reference
    /// of `second_order_dynamics`): every term at every node, with a field
    /// `u' = X w + ½ Q(w, w)`: the nodal sums of Eq. (2) at the field's positions, node by node
    /// and exact in `w` (a truncation of the field's terms would leave the equations of motion
    /// without an energy they conserve, which lets a large deflection run away). With the mode
    /// columns `X̃ = X + Q(w)` of the field, each node's acceleration is
    /// `r̈ + A(α × u + ω × (ω × u) + 2 ω × u̇ + X̃ ẅ + Q(ẇ, ẇ))`, and its rotary inertia follows the
    /// linear rotations as in [`flexible_dynamics`].
    #[allow(clippy::too_many_arguments)]
    fn nodal_second_order_dynamics<P: Scalar, S: Scalar + From<P>>(
        modal: &ModalBody<P>,
        field: &GeometricStiffness<P>,
        a: &Matrix3<S>,
        q: &[S],
        v: &[S],
        g: Vector3<S>,
        mass: &mut DMatrix<S>,
        off: usize,
        force: &mut [S],
    ) {
        let nm = modal.n_modes();
        let w = &q[7..7 + nm];
        let wd = &v[6..6 + nm];
        let om = vec3(&v[3..6]);
        let two = S::from_f64(2.0);
        let g_body = mtv(a, &g);
        let mut total = S::zero();
        let mut first = Vector3::<S>::zeros(); // Σ m u
        let mut m_oo = Matrix3::<S>::zeros();
        let mut m_rw = vec![Vector3::<S>::zeros(); nm]; // Σ m X̃_j
        let mut m_ow = vec![Vector3::<S>::zeros(); nm];
        let mut m_ww = DMatrix::<S>::zeros(nm, nm);
        let mut qc = Vector3::<S>::zeros(); // Σ m c
        let mut s_o = Vector3::<S>::zeros(); // Σ m u × c
        let mut hj = Vector3::<S>::zeros(); // Σ μ ∘ (ω + θ̇)
        let mut s_w = vec![S::zero(); nm]; // Σ m X̃_j · (g' − c)
        let mut x = vec![Vector3::<S>::zeros(); nm];
        let mut t = vec![Vector3::<S>::zeros(); nm];
        let mut rotary = Vector3::<S>::zeros(); // Σ (dΔJ_k/dt) ω
        let mut rotary_w = vec![S::zero(); nm]; // Σ ½ ωᵀ ∂ΔJ_k/∂w_j ω
        for k in 0..modal.n_nodes() {
            let mk: S = lift(modal.node_masses[k]);
            let jk: Vector3<S> = modal.node_inertias[k].map(lift);
            let second = second_order_node(field, k, w, wd);
            let mut u: Vector3<S> = vec3f(&modal.node_positions[k]);
            u += second.half;
            let mut ud = Vector3::<S>::zeros();
            let mut th_d = Vector3::<S>::zeros();
            for j in 0..nm {
                let d: Vector3<S> = mode_vec(modal, k, j, false);
                u += d * w[j];
                x[j] = d + second.columns.get(j).copied().unwrap_or_default();
                t[j] = mode_vec(modal, k, j, true);
                ud += x[j] * wd[j];
                th_d += t[j] * wd[j];
            }
            total += mk;
            first += u * mk;
            let ut = skew(&u);
            m_oo += ut.transpose() * ut * mk;
            for i in 0..3 {
                m_oo[(i, i)] += jk[i];
            }
            // the node's acceleration at zero accelerations, beyond the frame's r̈
            let c = om.cross(&om.cross(&u)) + om.cross(&ud) * two + second.rates;
            qc += c * mk;
            s_o += u.cross(&c) * mk;
            hj += (om + th_d).component_mul(&jk);
            // the rotary inertia turned by the node's rotation to the second order
            let (dj, d) = node_rotary(modal, k, w);
            m_oo += dj;
            hj += dj * om;
            for j in 0..nm {
                rotary += d[j] * om * wd[j];
                rotary_w[j] += (d[j] * om).dot(&om) * S::from_f64(0.5);
            }
            let gc = (g_body - c) * mk;
            for j in 0..nm {
                m_rw[j] += x[j] * mk;
                m_ow[j] += u.cross(&x[j]) * mk + t[j].component_mul(&jk);
                s_w[j] += x[j].dot(&gc);
                for l in j..nm {
                    m_ww[(j, l)] += x[j].dot(&x[l]) * mk + t[j].dot(&t[l].component_mul(&jk));
                }
            }
        }
        frame_blocks(mass, off, a, total, &first, &m_oo, &m_rw, &m_ow);
        for j in 0..nm {
            for l in j..nm {
                mass[(off + 6 + j, off + 6 + l)] = m_ww[(j, l)];
                mass[(off + 6 + l, off + 6 + j)] = m_ww[(j, l)];
            }
        }
        let s_r = mv(a, &qc);
        let s_om = s_o + om.cross(&hj) + rotary;
        let gu = first.cross(&g_body);
        for i in 0..3 {
            force[off + i] += g[i] * total - s_r[i];
            force[off + 3 + i] += gu[i] - s_om[i];
        }
        for j in 0..nm {
            force[off + 6 + j] += s_w[j] + rotary_w[j];
        }
        elastic_forces(modal, w, wd, &mut force[off + 6..off + 6 + nm]);
    }

    /// Node `k`'s rotary inertia turned by its rotation `θ = Σ_j T_j w_j` to the second
    /// order, less the unturned one: `ΔJ = Θμ + μΘᵀ + ΘμΘᵀ + ½ Θ²μ + ½ μ(Θ²)ᵀ` with
    /// `Θ = [θ]×`, and `∂ΔJ/∂w_j` (`Θ → Θ_j = [T_j]×` in each factor in turn): the reference
    /// of [`RotaryInvariants`], written out node by node.
    fn node_rotary<P: Scalar, S: Scalar + From<P>>(
        modal: &ModalBody<P>,
        k: usize,
        w: &[S],
    ) -> (Matrix3<S>, Vec<Matrix3<S>>) {
        let nm = modal.n_modes();
        let mu = Matrix3::from_diagonal(&modal.node_inertias[k].map(lift::<P, S>));
        let tj: Vec<Matrix3<S>> = (0..nm)
            .map(|j| skew(&mode_vec::<P, S>(modal, k, j, true)))
            .collect();
        let mut th = Matrix3::<S>::zeros();
        for j in 0..nm {
            th += tj[j] * w[j];
        }
        let half = S::from_f64(0.5);
        let turned = |a: &Matrix3<S>, b: &Matrix3<S>| {
            // the bilinear form whose diagonal is ΔJ's second-order part
            a * mu * b.transpose() + (a * b * mu + mu * (a * b).transpose()) * half
        };
        let dj = th * mu + mu * th.transpose() + turned(&th, &th);
        let d = (0..nm)
            .map(|j| {
                tj[j] * mu + mu * tj[j].transpose() + turned(&tj[j], &th) + turned(&th, &tj[j])
            })
            .collect();
        (dj, d)
    }

    /// The nodal sums of Eq. (2), node by node (the reference for the invariants).
    fn nodal_dynamics<P: Scalar, S: Scalar + From<P>>(
        modal: &ModalBody<P>,
        q: &[S],
        v: &[S],
        gravity: &Vector3<f64>,
        mass: &mut DMatrix<S>,
        off: usize,
        force: &mut [S],
    ) {
        let Pose { a, .. } = pose(q);
        let g: Vector3<S> = vec3f(gravity);

        let nm = modal.n_modes();
        let w = &q[7..7 + nm];
        let wd = &v[6..6 + nm];
        let om = vec3(&v[3..6]);
        let g_body = a.transpose() * g;
        let mut total = S::zero();
        let mut first = Vector3::<S>::zeros(); // Σ m_k u_k
        let mut m_oo = Matrix3::<S>::zeros();
        let mut s_d = DMatrix::<S>::zeros(3, nm); // Σ m_k Xδ_k
        let mut m_ow = DMatrix::<S>::zeros(3, nm);
        let mut m_ww = DMatrix::<S>::zeros(nm, nm);
        let mut qc = Vector3::<S>::zeros(); // Σ m_k c'_k
        let mut s_o = Vector3::<S>::zeros(); // Σ m_k u_k × c'_k + ω × Σ J Ω_k
        let mut hj = Vector3::<S>::zeros(); // Σ J_k Ω_k
        let mut s_w = vec![S::zero(); nm];
        let mut xd = vec![Vector3::<S>::zeros(); nm];
        let mut xt = vec![Vector3::<S>::zeros(); nm];
        for k in 0..modal.n_nodes() {
            let mk: S = lift(modal.node_masses[k]);
            let jk: Vector3<S> = modal.node_inertias[k].map(lift);
            let mut u: Vector3<S> = vec3f(&modal.node_positions[k]);
            let mut ud = Vector3::<S>::zeros();
            let mut th_d = Vector3::<S>::zeros();
            for j in 0..nm {
                xd[j] = mode_vec(modal, k, j, false);
                xt[j] = mode_vec(modal, k, j, true);
                u += xd[j] * w[j];
                ud += xd[j] * wd[j];
                th_d += xt[j] * wd[j];
            }
            total += mk;
            first += u * mk;
            let ut = skew(&u);
            m_oo += ut.transpose() * ut * mk;
            for i in 0..3 {
                m_oo[(i, i)] += jk[i];
            }
            for j in 0..nm {
                let uxd = u.cross(&xd[j]) * mk;
                for i in 0..3 {
                    s_d[(i, j)] += xd[j][i] * mk;
                    m_ow[(i, j)] += uxd[i] + jk[i] * xt[j][i];
                }
                for l in j..nm {
                    let mut x = xd[j].dot(&xd[l]) * mk;
                    for i in 0..3 {
                        x += xt[j][i] * jk[i] * xt[l][i];
                    }
                    m_ww[(j, l)] += x;
                }
            }
            let c = om.cross(&om.cross(&u)) + om.cross(&ud) * S::from_f64(2.0);
            qc += c * mk;
            s_o += u.cross(&c) * mk;
            let omega_k = om + th_d;
            hj += omega_k.component_mul(&jk);
            // gravity on the ω and ẇ rows
            let gu = u.cross(&g_body) * mk;
            for i in 0..3 {
                force[off + 3 + i] += gu[i];
            }
            for j in 0..nm {
                s_w[j] += xd[j].dot(&(g_body - c)) * mk;
            }
        }
        // mass matrix blocks
        let a_first = a * skew(&first); // A Σ m ũ
        for i in 0..3 {
            mass[(off + i, off + i)] = total;
            for k in 0..3 {
                mass[(off + i, off + 3 + k)] = -a_first[(i, k)];
                mass[(off + 3 + k, off + i)] = -a_first[(i, k)];
                mass[(off + 3 + i, off + 3 + k)] = m_oo[(i, k)];
            }
        }
        for j in 0..nm {
            let col = Vector3::new(s_d[(0, j)], s_d[(1, j)], s_d[(2, j)]);
            let acol = a * col;
            for i in 0..3 {
                mass[(off + i, off + 6 + j)] = acol[i];
                mass[(off + 6 + j, off + i)] = acol[i];
                mass[(off + 3 + i, off + 6 + j)] = m_ow[(i, j)];
                mass[(off + 6 + j, off + 3 + i)] = m_ow[(i, j)];
            }
            for l in j..nm {
                mass[(off + 6 + j, off + 6 + l)] = m_ww[(j, l)];
                mass[(off + 6 + l, off + 6 + j)] = m_ww[(j, l)];
            }
        }
        // forces: gravity on r, quadratic velocity terms, elastic and damping
        let s_r = a * qc;
        let s_om = s_o + om.cross(&hj);
        for i in 0..3 {
            force[off + i] += g[i] * total - s_r[i];
            force[off + 3 + i] -= s_om[i];
        }
        for j in 0..nm {
            let lam: S = lift(modal.eigenvalues[j]);
            let damp: S = lift(modal.modal_damping[j]);
            force[off + 6 + j] += s_w[j] - lam * w[j] - damp * wd[j];
        }
    }

    /// A free-free beam-like body: 7 nodes along x with arbitrary (non-orthogonal) modes.
    fn body() -> ModalBody<f64> {
        let nodes = 7;
        let nm = 3;
        let modes = DMatrix::from_fn(6 * nodes, nm, |r, j| {
            ((r * 7 + j * 13) as f64 * 0.37).sin() * if r % 6 < 3 { 0.05 } else { 0.3 }
        });
        ModalBody {
            node_positions: (0..nodes)
                .map(|k| Vector3::new(0.1 * k as f64, 0.01 * (k as f64).cos(), -0.02))
                .collect(),
            node_masses: (0..nodes).map(|k| 0.2 + 0.03 * k as f64).collect(),
            node_inertias: (0..nodes)
                .map(|k| Vector3::new(1e-4, 2e-4 + 1e-5 * k as f64, 3e-4))
                .collect(),
            modes,
            eigenvalues: vec![100.0, 400.0, 900.0],
            modal_damping: vec![0.1, 0.2, 0.3],
            stiffness_matrix: None,
            damping_matrix: None,
        }
    }

    fn state(nm: usize) -> (Vec<f64>, Vec<f64>) {
        let p = Vector4::new(0.9, 0.2, -0.3, 0.1).normalize();
        let mut q = vec![0.3, -0.2, 0.1, p[0], p[1], p[2], p[3]];
        q.extend((0..nm).map(|j| 0.02 * (j as f64 + 1.0) * if j % 2 == 0 { 1.0 } else { -1.0 }));
        let mut v = vec![1.0, -2.0, 0.5, 3.0, -1.5, 2.5];
        v.extend((0..nm).map(|j| 0.7 - 0.4 * j as f64));
        (q, v)
    }

    type Dynamics<S> = (DMatrix<S>, Vec<S>);

    /// `(invariants, nodal sums)`.
    fn both<P: Scalar, S: Scalar + From<P>>(
        modal: &ModalBody<P>,
        q: &[S],
        v: &[S],
    ) -> (Dynamics<S>, Dynamics<S>) {
        let n = 6 + modal.n_modes();
        let gravity = Vector3::new(0.0, -9.81, 1.0);
        let body = Body::Flexible(FlexibleBody::new("rod", modal.clone()));
        let (mut m1, mut f1) = (DMatrix::zeros(n, n), vec![S::zero(); n]);
        body_dynamics(&body, &OnceLock::new(), q, v, &gravity, &mut m1, 0, &mut f1);
        let (mut m2, mut f2) = (DMatrix::zeros(n, n), vec![S::zero(); n]);
        nodal_dynamics(modal, q, v, &gravity, &mut m2, 0, &mut f2);
        ((m1, f1), (m2, f2))
    }

    /// An arbitrary second-order field of [`body`]'s nodes (symmetric in the mode pair).
    fn field(modal: &ModalBody<f64>) -> GeometricStiffness<f64> {
        let nm = modal.n_modes();
        let nodal = (0..3 * modal.n_nodes())
            .map(|r| {
                DMatrix::from_fn(nm, nm, |j, l| {
                    0.8 * ((r * 5 + (j + l) * 3 + j * l) as f64 * 0.61).cos()
                })
            })
            .collect();
        GeometricStiffness {
            n_modes: nm,
            field_modes: nm,
            eigenmodes: nm,
            clamp: 0,
            nodal,
            elements: None,
        }
    }

    /// `(q, v)` as dual numbers with tangents along arbitrary directions of `q` (first) and `v`
    /// (second).
    fn dual_state(q: &[f64], v: &[f64]) -> (Vec<Dual<2>>, Vec<Dual<2>>) {
        let qd = q
            .iter()
            .enumerate()
            .map(|(i, &x)| Dual::new(x, [0.1 * (i as f64).sin(), 0.0]))
            .collect();
        let vd = v
            .iter()
            .enumerate()
            .map(|(i, &x)| Dual::new(x, [0.0, 0.3 * (i as f64).cos()]))
            .collect();
        (qd, vd)
    }

    /// [`field`] of the leading `nf` modes only (a shell's eigenmodes).
    fn leading_field(modal: &ModalBody<f64>, nf: usize) -> GeometricStiffness<f64> {
        let mut g = field(modal);
        g.field_modes = nf;
        for k in g.nodal.iter_mut() {
            *k = k.view((0, 0), (nf, nf)).into_owned();
        }
        g
    }

    /// The mass matrix and forces of `body` with second-order field `field` at `(q, v)`.
    fn with_field<S: Scalar + From<f64>>(
        modal: &ModalBody<f64>,
        field: &GeometricStiffness<f64>,
        q: &[S],
        v: &[S],
        gravity: &Vector3<f64>,
    ) -> Dynamics<S> {
        let n = 6 + modal.n_modes();
        let body = Body::Flexible(
            FlexibleBody::new("rod", modal.clone()).with_geometric_stiffness(field.clone()),
        );
        let (mut m, mut f) = (DMatrix::zeros(n, n), vec![S::zero(); n]);
        body_dynamics(&body, &OnceLock::new(), q, v, gravity, &mut m, 0, &mut f);
        (m, f)
    }

    /// A zero second-order field takes the node-by-node path: it gives what the invariants
    /// give, with the nodes' rotary inertia turned by their rotations to the second order
    /// (summed node by node here: [`node_rotary`]).
    #[test]
    fn a_zero_field_gives_the_linear_dynamics() {
        let modal = body();
        let nm = modal.n_modes();
        let mut zero = field(&modal);
        zero.nodal.iter_mut().for_each(|k| k.fill(0.0));
        let (q, v) = state(nm);
        let gravity = Vector3::new(0.0, -9.81, 1.0);
        let ((mut m1, mut f1), _) = both(&modal, &q, &v);
        let (w, wd, om) = (&q[7..], &v[6..], vec3::<f64>(&v[3..6]));
        for k in 0..modal.n_nodes() {
            let (dj, d) = node_rotary::<f64, f64>(&modal, k, w);
            for i in 0..3 {
                for l in 0..3 {
                    m1[(3 + i, 3 + l)] += dj[(i, l)];
                }
            }
            let mut h = om.cross(&(dj * om));
            for j in 0..nm {
                h += d[j] * om * wd[j];
                f1[6 + j] += 0.5 * (d[j] * om).dot(&om);
            }
            for i in 0..3 {
                f1[3 + i] -= h[i];
            }
        }
        let (m2, f2) = with_field(&modal, &zero, &q, &v, &gravity);
        assert!((&m1 - &m2).amax() <= 1e-14 * m1.amax());
        let scale = f1.iter().fold(0.0f64, |a, x| a.max(x.abs()));
        for (a, b) in f1.iter().zip(&f2) {
            assert!((a - b).abs() <= 1e-13 * scale, "{a} vs {b}");
        }
    }

    /// With a second-order field, `vᵀ M v / 2` is the kinetic energy of the lumped masses at
    /// the field's velocities `ṙ + A (ω × u + (X + Q(w)) ẇ)`, and the inertia forces do no work
    /// on the body's own motion: `vᵀ f = −½ vᵀ Ṁ v` (`Ṁ` along the motion, from dual numbers),
    /// which is what makes the kinetic energy a conserved quantity of the free body.
    #[test]
    fn second_order_field_keeps_the_kinetic_energy_and_its_balance() {
        let mut modal = body();
        // no elastic or damping forces: only inertia
        modal.eigenvalues.fill(0.0);
        modal.modal_damping.fill(0.0);
        let g = field(&modal);
        let nm = modal.n_modes();
        let (q, v) = state(nm);
        let none = Vector3::zeros();
        let (m, f) = with_field(&modal, &g, &q, &v, &none);
        let vv = nalgebra::DVector::from_column_slice(&v);
        let t = 0.5 * vv.dot(&(&m * &vv));
        let a = pose(&q).a;
        let om = vec3(&v[3..6]);
        let (w, wd) = (&q[7..], &v[6..]);
        let mut expected = 0.0;
        for k in 0..modal.n_nodes() {
            let second = second_order_node(&g, k, w, wd);
            let mut u = modal.node_positions[k] + second.half;
            let mut ud = Vector3::zeros();
            let mut thd = Vector3::zeros();
            for j in 0..nm {
                let x: Vector3<f64> = mode_vec(&modal, k, j, false);
                let r: Vector3<f64> = mode_vec(&modal, k, j, true);
                u += x * w[j];
                ud += (x + second.columns[j]) * wd[j];
                thd += r * wd[j];
            }
            let vel = vec3(&v[0..3]) + a * (om.cross(&u) + ud);
            let spin = om + thd;
            // the rotary inertia turned to the second order acts on the frame's rotation
            let (dj, _) = node_rotary::<f64, f64>(&modal, k, w);
            expected += 0.5 * modal.node_masses[k] * vel.norm_squared()
                + 0.5 * spin.dot(&spin.component_mul(&modal.node_inertias[k]))
                + 0.5 * om.dot(&(dj * om));
        }
        assert!(
            (t - expected).abs() <= 1e-13 * expected,
            "{t} vs {expected}"
        );
        // Ṁ along q̇ = (ṙ, ½ Lᵀ ω', ẇ)
        let p = Vector4::new(q[3], q[4], q[5], q[6]);
        let pd = crate::kin::l_matrix(&p).transpose() * om * 0.5;
        let mut qd = v[0..3].to_vec();
        qd.extend(pd.iter());
        qd.extend_from_slice(wd);
        let qs: Vec<Dual<1>> = q
            .iter()
            .zip(&qd)
            .map(|(&x, &d)| Dual::new(x, [d]))
            .collect();
        let vs: Vec<Dual<1>> = v.iter().map(|&x| Dual::constant(x)).collect();
        let (md, _) = with_field(&modal, &g, &qs, &vs, &none);
        let m_dot = md.map(|x| x.d[0]);
        let work: f64 = v.iter().zip(&f).map(|(a, b)| a * b).sum();
        let half = 0.5 * vv.dot(&(&m_dot * &vv));
        let scale = f.iter().zip(&v).map(|(a, b)| (a * b).abs()).sum::<f64>();
        assert!(
            (work + half).abs() <= 1e-12 * scale,
            "vᵀf {work} against −½ vᵀṀv {}",
            -half
        );
        // and the field shows in both
        let (m0, f0) = {
            let mut zero = g.clone();
            zero.nodal.iter_mut().for_each(|k| k.fill(0.0));
            with_field(&modal, &zero, &q, &v, &none)
        };
        assert!((&m - &m0).amax() > 1e-3 * m.amax());
        assert!(f.iter().zip(&f0).any(|(a, b)| (a - b).abs() > 1e-3 * scale));
    }

    /// The second-order dynamics (invariants for the rotary terms and the modal mass, nodes
    /// for the rest) equal the straightforward node-by-node sums, values and tangents, for a
    /// field of every mode and of the leading ones only (a shell's eigenmodes).
    #[test]
    fn second_order_dynamics_equal_the_nodal_sums() {
        let modal = body();
        let nm = modal.n_modes();
        let (q, v) = state(nm);
        let gravity = Vector3::new(0.0, -9.81, 1.0);
        let (qd, vd) = dual_state(&q, &v);
        for nf in [nm, nm - 2] {
            let g = leading_field(&modal, nf);
            let (m1, f1) = with_field(&modal, &g, &qd, &vd, &gravity);
            let n = 6 + nm;
            let (mut m2, mut f2) = (DMatrix::zeros(n, n), vec![Dual::<2>::constant(0.0); n]);
            let a = pose(&qd).a;
            let gs: Vector3<Dual<2>> = vec3f(&gravity);
            nodal_second_order_dynamics(&modal, &g, &a, &qd, &vd, gs, &mut m2, 0, &mut f2);
            let scale_m = m2.iter().fold(0.0f64, |a, x| a.max(x.v.abs()));
            let scale_f = f2.iter().fold(0.0f64, |a, x| a.max(x.v.abs()));
            let close = |a: &[Dual<2>], b: &[Dual<2>], tol: f64| {
                for (a, b) in a.iter().zip(b) {
                    assert!((a.v - b.v).abs() <= tol, "field of {nf} modes: {a} vs {b}");
                    for k in 0..2 {
                        assert!((a.d[k] - b.d[k]).abs() <= tol, "field of {nf}: {a} vs {b}");
                    }
                }
            };
            close(m1.as_slice(), m2.as_slice(), 1e-13 * scale_m);
            close(&f1, &f2, 1e-12 * scale_f);
        }
    }

    /// `modal` in dual numbers: its node masses and modes with the tangents `mass(k, m_k)` and
    /// `mode(row, j)`, the rest constant.
    fn dual_body(
        modal: &ModalBody<f64>,
        mass: impl Fn(usize, f64) -> [f64; 2],
        mode: impl Fn(usize, usize) -> [f64; 2],
    ) -> ModalBody<Dual<2>> {
        ModalBody {
            node_positions: modal.node_positions.clone(),
            node_masses: (modal.node_masses.iter().enumerate())
                .map(|(k, &m)| Dual::new(m, mass(k, m)))
                .collect(),
            node_inertias: (modal.node_inertias.iter())
                .map(|x| x.map(Dual::constant))
                .collect(),
            modes: DMatrix::from_fn(modal.modes.nrows(), modal.n_modes(), |r, j| {
                Dual::new(modal.modes[(r, j)], mode(r, j))
            }),
            eigenvalues: constant(&modal.eigenvalues),
            modal_damping: constant(&modal.modal_damping),
            stiffness_matrix: None,
            damping_matrix: None,
        }
    }

    /// `x` as dual constants.
    fn constant(x: &[f64]) -> Vec<Dual<2>> {
        x.iter().map(|&x| Dual::constant(x)).collect()
    }

    /// The dynamics of `modal` with field `field` through the Gram table (`gram`) or the node
    /// loop, whichever [`FieldGram::pays`] would choose.
    fn with_path<P: Scalar, S: Scalar + From<P>>(
        modal: &ModalBody<P>,
        field: &GeometricStiffness<P>,
        gram: bool,
        q: &[S],
        v: &[S],
        gravity: &Vector3<f64>,
    ) -> Dynamics<S> {
        let n = 6 + modal.n_modes();
        let body = Body::Flexible(
            FlexibleBody::new("rod", modal.clone()).with_geometric_stiffness(field.clone()),
        );
        let mut inv = ModalInvariants::new(modal, Some(field));
        let nodes = 0..modal.n_nodes();
        inv.gram = gram.then(|| FieldGram::new(modal, field, nodes.clone()));
        inv.field = Some(FieldInvariants::new(modal, field, gram, nodes));
        let lock = OnceLock::new();
        assert!(lock.set(inv).is_ok());
        let (mut m, mut f) = (DMatrix::zeros(n, n), vec![S::zero(); n]);
        body_dynamics(&body, &lock, q, v, gravity, &mut m, 0, &mut f);
        (m, f)
    }

    /// The Gram table gives what the loop over the nodes gives, values and tangents: with
    /// dual states, and with design-dependent modes, masses and field (dual parameters).
    #[test]
    fn the_gram_table_gives_the_node_sums() {
        let modal = body();
        let nm = modal.n_modes();
        let (q, v) = state(nm);
        let gravity = Vector3::new(0.0, -9.81, 1.0);
        let (qd, vd) = dual_state(&q, &v);
        let close = |a: &[Dual<2>], b: &[Dual<2>], tol: f64, what: &str| {
            for (a, b) in a.iter().zip(b) {
                assert!((a.v - b.v).abs() <= tol, "{what}: {a} vs {b}");
                for k in 0..2 {
                    assert!((a.d[k] - b.d[k]).abs() <= tol, "{what}: {a} vs {b}");
                }
            }
        };
        let scale = |x: &[Dual<2>]| x.iter().fold(0.0f64, |a, x| a.max(x.v.abs()));
        for nf in [nm, nm - 2] {
            let g = leading_field(&modal, nf);
            let (m1, f1) = with_path(&modal, &g, true, &qd, &vd, &gravity);
            let (m2, f2) = with_path(&modal, &g, false, &qd, &vd, &gravity);
            let what = format!("field of {nf} modes");
            close(
                m1.as_slice(),
                m2.as_slice(),
                1e-13 * scale(m2.as_slice()),
                &what,
            );
            close(&f1, &f2, 1e-12 * scale(&f2), &what);
            // design tangents: masses, modes and field on dual numbers
            let dm = dual_body(
                &modal,
                |k, m| [0.1 * m * (1.0 + (k as f64).sin()), 0.0],
                |r, j| [0.0, 0.05 * ((r + 3 * j) as f64).cos()],
            );
            let dg = g.map(&|x| Dual::<2>::new(x, [0.02 * x, -0.01 * x]));
            let (q2, v2) = (constant(&q), constant(&v));
            let (m1, f1) = with_path(&dm, &dg, true, &q2, &v2, &gravity);
            let (m2, f2) = with_path(&dm, &dg, false, &q2, &v2, &gravity);
            let what = format!("dual parameters, field of {nf} modes");
            close(
                m1.as_slice(),
                m2.as_slice(),
                1e-13 * scale(m2.as_slice()),
                &what,
            );
            close(&f1, &f2, 1e-12 * scale(&f2), &what);
        }
    }

    /// A change of size `h` of one datum of a body or of its field.
    type Perturbation = Box<dyn Fn(&mut ModalBody<f64>, &mut GeometricStiffness<f64>, f64)>;

    /// The invariants' reverse written by hand ([`ModalInvariants::pull_back_to`]) gives the
    /// data's adjoints that the invariants recorded on the tape operation by operation give —
    /// with and without the field's fourth-order sums and Gram table, a node without mass and
    /// one without rotary inertia among them — and those equal central differences of a
    /// weighted sum of the invariants in `f64`.
    #[test]
    fn the_invariants_reverse_by_hand_as_the_tape_does() {
        use sens::{Rev, Tape};
        let mut modal = body();
        modal.node_masses[4] = 0.0;
        modal.node_inertias[2] = Vector3::zeros();
        let n = modal.n_nodes();
        let field = leading_field(&modal, modal.n_modes() - 1);
        let weight = |i: usize| ((i * 7 + 3) as f64 * 0.37).sin();
        // Σ_i weight_i inv_i over the invariants' scalars in their visiting order
        let weighted = |inv: &ModalInvariants<f64>| {
            let (sum, i) = (std::cell::Cell::new(0.0), std::cell::Cell::new(0));
            let _ = inv.map(&|x: f64| {
                sum.set(sum.get() + weight(i.get()) * x);
                i.set(i.get() + 1);
                x
            });
            sum.get()
        };
        for flags in [(false, false), (true, false), (true, true)] {
            let mark = Tape::len();
            let body =
                FlexibleBody::new("rod", modal.clone()).with_geometric_stiffness(field.clone());
            let Body::Flexible(taped) = Body::Flexible(body).map(&Rev::input) else {
                unreachable!("a flexible body")
            };
            let top = Tape::len();
            let g = taped.geometric.as_deref();
            // the oracle: the invariants recorded on the tape, swept
            let recorded = ModalInvariants::of_nodes(&taped.modal, g, flags, 0..n);
            let (mut oracle, i) = (Vec::new(), std::cell::Cell::new(0));
            let seeds = std::cell::RefCell::new(&mut oracle);
            let _ = recorded.map(&|x: Rev| {
                x.seed(&mut seeds.borrow_mut(), weight(i.get()));
                i.set(i.get() + 1);
                x
            });
            Tape::backpropagate(&mut oracle, mark);
            oracle.resize(top, 0.0);
            // by hand: the invariants as inputs of their own, seeded alike
            let values = recorded.map(&|x: Rev| x.value());
            let inputs = values.map(&Rev::input);
            let by_hand = std::cell::RefCell::new(vec![0.0; Tape::len()]);
            let i = std::cell::Cell::new(0);
            let _ = inputs.map(&|x: Rev| {
                by_hand.borrow_mut()[x.node().expect("an input")] += weight(i.get());
                i.set(i.get() + 1);
                x
            });
            let mut sets = vec![by_hand.into_inner()];
            inputs.pull_back_to(&taped, &mut sets);
            let scale = oracle[mark..top].iter().fold(0.0f64, |m, x| m.max(x.abs()));
            assert!(scale > 0.0);
            for k in mark..top {
                assert!(
                    (sets[0][k] - oracle[k]).abs() <= 1e-12 * scale,
                    "{flags:?}: input {k}: {} vs {}",
                    sets[0][k],
                    oracle[k]
                );
            }
            // against central differences: a mass, an inertia, a translation and a rotation
            // entry of a mode, a field entry
            let adjoint_of = |x: Rev| sets[0][x.node().expect("an input")];
            let of = |modal: &ModalBody<f64>, field: &GeometricStiffness<f64>| {
                weighted(&ModalInvariants::of_nodes(modal, Some(field), flags, 0..n))
            };
            let cases: [(Rev, Perturbation); 5] = [
                (
                    taped.modal.node_masses[3],
                    Box::new(|m, _, h| m.node_masses[3] += h),
                ),
                (
                    taped.modal.node_inertias[5][1],
                    Box::new(|m, _, h| m.node_inertias[5][1] += h),
                ),
                (
                    taped.modal.modes[(6 * 2 + 1, 1)],
                    Box::new(|m, _, h| m.modes[(6 * 2 + 1, 1)] += h),
                ),
                (
                    taped.modal.modes[(6 * 5 + 4, 2)],
                    Box::new(|m, _, h| m.modes[(6 * 5 + 4, 2)] += h),
                ),
                (
                    g.expect("a field").nodal[3 * 6 + 2][(1, 0)],
                    Box::new(|_, f, h| f.nodal[3 * 6 + 2][(1, 0)] += h),
                ),
            ];
            for (c, (x, step)) in cases.iter().enumerate() {
                let h = 1e-6;
                let at = |s: f64| {
                    let (mut m, mut f) = (modal.clone(), field.clone());
                    step(&mut m, &mut f, s);
                    of(&m, &f)
                };
                let fd = (at(h) - at(-h)) / (2.0 * h);
                let got = adjoint_of(*x);
                assert!(
                    (got - fd).abs() <= 1e-7 * fd.abs().max(scale),
                    "{flags:?}: case {c}: {got} vs {fd}"
                );
            }
            drop((recorded, inputs, taped));
            Tape::rewind(mark);
        }
    }

    /// The dynamics through the Gram table on the reverse-mode tape (its contractions one
    /// operation each, [`FieldGram`]) reverse as the node loop recorded operation by operation
    /// does: the same mass matrix and forces, the same adjoints of every input (the state, the
    /// body's modes, masses, inertias and field), for a field of every mode and of the leading
    /// ones; and the state's adjoints equal central differences in `f64`.
    #[test]
    fn the_gram_table_on_the_tape_reverses_as_the_node_loop_does() {
        use sens::{Rev, Tape};
        let modal = body();
        let nm = modal.n_modes();
        let (q, v) = state(nm);
        let gravity = Vector3::new(0.0, -9.81, 1.0);
        let flat = |(m, f): &Dynamics<Rev>| -> Vec<Rev> { m.iter().chain(f).copied().collect() };
        let seed = |i: usize| ((i * 5 + 2) as f64 * 0.61).cos();
        for nf in [nm, nm - 1] {
            let field = leading_field(&modal, nf);
            let mark = Tape::len();
            let body =
                FlexibleBody::new("rod", modal.clone()).with_geometric_stiffness(field.clone());
            let Body::Flexible(taped) = Body::Flexible(body).map(&Rev::input) else {
                unreachable!("a flexible body")
            };
            let (mr, fr) = (&taped.modal, taped.geometric.as_deref().expect("a field"));
            let state: Vec<Rev> = q.iter().chain(&v).map(|&x| Rev::input(x)).collect();
            let top = Tape::len();
            let (qr, vr) = state.split_at(q.len());
            let a = flat(&with_path(mr, fr, true, qr, vr, &gravity));
            let b = flat(&with_path(mr, fr, false, qr, vr, &gravity));
            let scale = b.iter().fold(0.0f64, |m, x| m.max(x.value().abs()));
            for (i, (x, y)) in a.iter().zip(&b).enumerate() {
                assert!(
                    (x.value() - y.value()).abs() <= 1e-13 * scale,
                    "field of {nf} modes: output {i}: {x} vs {y}"
                );
            }
            let (mut ga, mut gb) = (swept(&a, mark, seed), swept(&b, mark, seed));
            // the table reads a nodal matrix's symmetric pairs once, the loop both: their
            // adjoints compare summed (the derivative along a symmetric change of the field)
            for m in &fr.nodal {
                for j in 0..nf {
                    for l in j + 1..nf {
                        let node = |j: usize, l: usize| m[(j, l)].node().expect("an input");
                        let (x, y) = (node(j, l), node(l, j));
                        for g in [&mut ga, &mut gb] {
                            g[x] += g[y];
                            g[y] = 0.0;
                        }
                    }
                }
            }
            let scale = gb[mark..top].iter().fold(0.0f64, |m, x| m.max(x.abs()));
            assert!(scale > 0.0);
            for i in mark..top {
                assert!(
                    (ga[i] - gb[i]).abs() <= 1e-12 * scale,
                    "field of {nf} modes: input {i}: {} vs {}",
                    ga[i],
                    gb[i]
                );
            }
            let functional = |x: &[f64]| {
                let (m, f) =
                    with_path(&modal, &field, true, &x[..q.len()], &x[q.len()..], &gravity);
                (m.iter().chain(&f).enumerate())
                    .map(|(i, y)| seed(i) * y)
                    .sum::<f64>()
            };
            let x0: Vec<f64> = q.iter().chain(&v).copied().collect();
            for (k, r) in state.iter().enumerate() {
                let fd = central(functional, &x0, k, 1e-6 * x0[k].abs().max(1.0));
                let got = r.adjoint(&ga);
                assert!(
                    (got - fd).abs() <= 1e-7 * scale.max(fd.abs()),
                    "field of {nf} modes: state {k}: {got} vs {fd}"
                );
            }
            drop((a, b, state, taped));
            Tape::rewind(mark);
        }
    }

    /// A field given by beam elements on a tree with a branch (clamp at node 3, the branch at
    /// node 4), arbitrary symmetric element matrices (with arbitrary design tangents) and
    /// axes, its nodal matrices the sums over the paths; without `elements`, the nodal
    /// matrices alone.
    fn element_field(nm: usize, n_nodes: usize, elements: bool) -> GeometricStiffness<Dual<2>> {
        let tree = [(3, 2), (2, 1), (1, 0), (3, 4), (4, 5), (4, 6)];
        let els: Vec<FieldElement<Dual<2>>> = tree
            .iter()
            .enumerate()
            .map(|(e, &(parent, child))| FieldElement {
                parent,
                child,
                axis: Vector3::new(1.0, 0.3 * e as f64, -0.2).normalize(),
                unit: DMatrix::from_fn(nm, nm, |j, l| {
                    let x = (e * 5 + (j + l) * 3 + j * l) as f64;
                    Dual::new(3.0 * (x * 0.47).cos(), [(x * 0.31).sin(), 0.2 * x.cos()])
                }),
            })
            .collect();
        let mut nodal = vec![DMatrix::zeros(nm, nm); 3 * n_nodes];
        for k in 0..n_nodes {
            let mut node = k;
            while let Some(e) = els.iter().find(|e| e.child == node) {
                for i in 0..3 {
                    nodal[3 * k + i] += &e.unit * Dual::constant(e.axis[i]);
                }
                node = e.parent;
            }
        }
        GeometricStiffness {
            n_modes: nm,
            field_modes: nm,
            eigenmodes: nm,
            clamp: 3,
            nodal,
            elements: elements.then_some(els),
        }
    }

    /// The adjoint of every tape node from `mark` up after one sweep seeded with `seed(i)` on
    /// output `i`.
    fn swept(outputs: &[sens::Rev], mark: usize, seed: impl Fn(usize) -> f64) -> Vec<f64> {
        let mut adj = Vec::new();
        for (i, y) in outputs.iter().enumerate() {
            y.seed(&mut adj, seed(i));
        }
        sens::Tape::backpropagate(&mut adj, mark);
        adj.resize(sens::Tape::len(), 0.0);
        adj
    }

    /// The central difference of `f` at `x` along coordinate `k`, step `h`.
    fn central(f: impl Fn(&[f64]) -> f64, x: &[f64], k: usize, h: f64) -> f64 {
        let (mut xp, mut xm) = (x.to_vec(), x.to_vec());
        xp[k] += h;
        xm[k] -= h;
        (f(&xp) - f(&xm)) / (2.0 * h)
    }

    /// The nodal sums of a beam body recorded on the tape as one operation
    /// ([`taped_sums`]) reverse as the node loop recorded operation by operation does:
    /// the same values, and the same adjoints of every input (state and data) for arbitrary
    /// output adjoints, with a field of every mode and of the leading ones, with the products
    /// of correction modes left out, and with a massless node; and the adjoints of the state
    /// equal central differences of the loop in `f64`.
    #[test]
    fn the_taped_sums_reverse_as_the_node_loop_does() {
        use sens::{Rev, Tape};
        // every sum, the field's products whole (written here, not by the code under test)
        fn flat<S: Scalar>(s: &FrameSums<S>) -> Vec<S> {
            let mut out = vec![s.total];
            out.extend(s.first.iter().chain(s.m_oo.iter()));
            out.extend(s.m_rw.iter().chain(&s.m_ow).flat_map(|x| x.iter().copied()));
            out.extend(s.qc.iter().chain(s.s_o.iter()).chain(&s.s_w));
            out.extend(s.field_cc.as_ref().expect("node sums"));
            out
        }
        let mut modal = body();
        modal.node_masses[5] = 0.0;
        let (nm, n_nodes) = (modal.n_modes(), modal.n_nodes());
        let (q, v) = state(nm);
        let full = element_field(nm, n_nodes, true).map(&|x| x.v);
        let leading = |nf: usize| {
            let mut g = full.clone();
            g.field_modes = nf;
            g.eigenmodes = nf;
            for e in g.elements.as_mut().expect("elements") {
                e.unit = e.unit.view((0, 0), (nf, nf)).into_owned();
            }
            g
        };
        let fields = [
            ("every mode", full.clone()),
            ("leading modes", leading(nm - 1)),
            (
                "no correction products",
                full.clone().without_correction_products(1),
            ),
        ];
        let om = Vector3::new(3.0, -1.5, 2.5);
        let g_body = Vector3::new(0.4, -9.7, 1.1);
        // the outputs' adjoints, arbitrary
        let seed = |i: usize| ((i * 7 + 3) as f64 * 0.43).sin();
        for (what, field) in fields {
            let mark = Tape::len();
            let body =
                FlexibleBody::new("rod", modal.clone()).with_geometric_stiffness(field.clone());
            let Body::Flexible(taped) = Body::Flexible(body).map(&Rev::input) else {
                unreachable!("a flexible body")
            };
            let (mr, fr) = (&taped.modal, taped.geometric.as_deref().expect("a field"));
            let inv = ModalInvariants::new(mr, Some(fr));
            let state_in: Vec<Rev> = (q[7..].iter().chain(&v[6..]).chain(om.iter()))
                .chain(g_body.iter())
                .map(|&x| Rev::input(x))
                .collect();
            let (w, rest) = state_in.split_at(nm);
            let (wd, rest) = rest.split_at(nm);
            let (omr, gr) = (vec3(&rest[..3]), vec3(&rest[3..]));
            let sums = [
                taped_sums::taped_node_sums((mr, fr), &inv.mode_spin, (w, wd), &omr, &gr)
                    .expect("a beam's sums on the tape"),
                node_sums(mr, fr, &inv, w, wd, &omr, &gr),
            ];
            let (a, b) = (flat(&sums[0]), flat(&sums[1]));
            let scale = b.iter().fold(0.0f64, |m, x| m.max(x.value().abs()));
            for (i, (x, y)) in a.iter().zip(&b).enumerate() {
                let err = (x.value() - y.value()).abs();
                assert!(err <= 1e-14 * scale, "{what}: output {i}: {x} vs {y}");
            }
            // every input's adjoint: the state, then all the data on the tape
            let top = state_in.last().and_then(|x| x.node()).expect("on the tape") + 1;
            let (ga, gb) = (swept(&a, mark, seed), swept(&b, mark, seed));
            let scale = gb[mark..top].iter().fold(0.0f64, |m, x| m.max(x.abs()));
            assert!(scale > 0.0);
            for i in mark..top {
                let err = (ga[i] - gb[i]).abs();
                assert!(
                    err <= 1e-12 * scale,
                    "{what}: input {i}: {} vs {}",
                    ga[i],
                    gb[i]
                );
            }
            // the state's adjoints against central differences of the f64 loop
            let inv64 = ModalInvariants::new(&modal, Some(&field));
            let functional = |x: &[f64]| {
                let (w, rest) = x.split_at(nm);
                let (wd, rest) = rest.split_at(nm);
                let s = node_sums(
                    &modal,
                    &field,
                    &inv64,
                    w,
                    wd,
                    &vec3(&rest[..3]),
                    &vec3(&rest[3..]),
                );
                flat(&s)
                    .iter()
                    .enumerate()
                    .map(|(i, y)| seed(i) * y)
                    .sum::<f64>()
            };
            let x0: Vec<f64> = state_in.iter().map(|x| x.value()).collect();
            for (k, r) in state_in.iter().enumerate() {
                let fd = central(functional, &x0, k, 1e-6 * x0[k].abs().max(1.0));
                let got = r.adjoint(&ga);
                assert!(
                    (got - fd).abs() <= 1e-7 * scale.max(fd.abs()),
                    "{what}: state {k}: {got} vs {fd}"
                );
            }
            drop((sums, a, b, inv, taped));
            Tape::rewind(mark);
        }
    }

    /// A node's field from its nodal matrices recorded as one tape operation
    /// ([`taped_sums::taped_second_order_node`]) reverses as the loop recorded
    /// operation by operation: the same values, the same adjoints of `w`, `ẇ` and every entry
    /// of the matrices, for fields of every mode, of the leading ones and without the
    /// correction products; and the adjoints of `w`, `ẇ` equal central differences.
    #[test]
    fn a_taped_node_field_reverses_as_its_loop_does() {
        use sens::{Rev, Tape};
        let modal = body();
        let nm = modal.n_modes();
        let (q, v) = state(nm);
        let seed = |i: usize| ((i * 5 + 2) as f64 * 0.71).cos();
        let flat = |s: &SecondOrderNode<Rev>| -> Vec<Rev> {
            let mut out: Vec<Rev> = s.half.iter().copied().collect();
            out.extend(s.columns.iter().flat_map(|c| c.iter().copied()));
            out.extend(s.rates.iter());
            out
        };
        let fields = [
            ("every mode", field(&modal)),
            ("leading modes", leading_field(&modal, nm - 1)),
            (
                "no correction products",
                field(&modal).without_correction_products(1),
            ),
        ];
        for (what, g) in fields {
            for k in [0, 4] {
                let mark = Tape::len();
                let gr = g.map(&Rev::input);
                let state_in: Vec<Rev> = q[7..]
                    .iter()
                    .chain(&v[6..])
                    .map(|&x| Rev::input(x))
                    .collect();
                let (w, wd) = state_in.split_at(nm);
                let taped =
                    taped_sums::taped_second_order_node(&gr, k, w, wd).expect("on the tape");
                let looped = second_order_node(&gr, k, w, wd);
                let (a, b) = (flat(&taped), flat(&looped));
                for (x, y) in a.iter().zip(&b) {
                    assert!((x.value() - y.value()).abs() <= 1e-15, "{what}: {x} vs {y}");
                }
                let top = state_in.last().and_then(|x| x.node()).expect("on the tape") + 1;
                let (ga, gb) = (swept(&a, mark, seed), swept(&b, mark, seed));
                for i in mark..top {
                    assert!(
                        (ga[i] - gb[i]).abs() <= 1e-14,
                        "{what}: input {i}: {} vs {}",
                        ga[i],
                        gb[i]
                    );
                }
                let functional = |x: &[f64]| {
                    let s = second_order_node(&g, k, &x[..nm], &x[nm..]);
                    let mut out: Vec<f64> = s.half.iter().copied().collect();
                    out.extend(s.columns.iter().flat_map(|c| c.iter().copied()));
                    out.extend(s.rates.iter());
                    out.iter()
                        .enumerate()
                        .map(|(i, y)| seed(i) * y)
                        .sum::<f64>()
                };
                let x0: Vec<f64> = state_in.iter().map(|x| x.value()).collect();
                for (i, r) in state_in.iter().enumerate() {
                    let fd = central(functional, &x0, i, 1e-6);
                    let got = r.adjoint(&ga);
                    assert!(
                        (got - fd).abs() <= 1e-8 * fd.abs().max(1.0),
                        "{what}: {i}: {got} vs {fd}"
                    );
                }
                drop((taped, looped, a, b, gr));
                Tape::rewind(mark);
            }
        }
    }

    /// The field accumulated along a beam body's elements gives what its nodal matrices give,
    /// values and tangents: with dual states, and with a design-dependent field.
    #[test]
    fn the_field_by_elements_gives_the_nodal_field() {
        let modal = body();
        let (nm, n_nodes) = (modal.n_modes(), modal.n_nodes());
        let (q, v) = state(nm);
        let gravity = Vector3::new(0.0, -9.81, 1.0);
        let scale = |x: &[Dual<2>]| x.iter().fold(0.0f64, |a, x| a.max(x.v.abs()));
        let close = |a: &[Dual<2>], b: &[Dual<2>], what: &str| {
            let tol = 1e-13 * scale(b);
            for (a, b) in a.iter().zip(b) {
                assert!((a.v - b.v).abs() <= tol, "{what}: {a} vs {b}");
                for k in 0..2 {
                    assert!((a.d[k] - b.d[k]).abs() <= tol, "{what}: {a} vs {b}");
                }
            }
        };
        // dual states, the field's values
        let value = |g: GeometricStiffness<Dual<2>>| g.map(&|x: Dual<2>| x.v);
        let (by_elements, by_nodes) = (
            value(element_field(nm, n_nodes, true)),
            value(element_field(nm, n_nodes, false)),
        );
        assert!(by_elements.elements.is_some() && by_nodes.elements.is_none());
        let (qd, vd) = dual_state(&q, &v);
        let (m1, f1) = with_path(&modal, &by_elements, false, &qd, &vd, &gravity);
        let (m2, f2) = with_path(&modal, &by_nodes, false, &qd, &vd, &gravity);
        close(m1.as_slice(), m2.as_slice(), "mass, dual state");
        close(&f1, &f2, "forces, dual state");
        // the field matters at this amplitude: without it the modal forces differ
        let none = GeometricStiffness {
            nodal: vec![DMatrix::zeros(nm, nm); 3 * n_nodes],
            ..by_nodes.clone()
        };
        let (_, f0) = with_path(&modal, &none, false, &qd, &vd, &gravity);
        assert!((6..6 + nm).any(|j| (f0[j].v - f2[j].v).abs() > 1e-2 * scale(&f2)));
        // design tangents of the field
        let dm = dual_body(&modal, |_, _| [0.0; 2], |_, _| [0.0; 2]);
        let (q2, v2) = (constant(&q), constant(&v));
        let (de, dn) = (
            element_field(nm, n_nodes, true),
            element_field(nm, n_nodes, false),
        );
        let (m1, f1) = with_path(&dm, &de, false, &q2, &v2, &gravity);
        let (m2, f2) = with_path(&dm, &dn, false, &q2, &v2, &gravity);
        assert!(f2.iter().any(|x| x.d[0] != 0.0 && x.d[1] != 0.0));
        close(m1.as_slice(), m2.as_slice(), "mass, dual field");
        close(&f1, &f2, "forces, dual field");
    }

    /// A field without the products of two correction modes
    /// ([`GeometricStiffness::without_correction_products`]) skips their zero entries in every
    /// loop (rows past the eigenmodes read the eigenmodes' columns only): the dynamics through
    /// the node loop (nodal matrices and elements) and the Gram table, and the foreshortening,
    /// equal those of the same zeroed matrices read whole, bit for bit, values and tangents; and
    /// leaving the products out changes the dynamics (the test would see a skipped nonzero).
    #[test]
    fn skipping_the_correction_products_reads_only_zeros() {
        let modal = body();
        let (nm, n_nodes) = (modal.n_modes(), modal.n_nodes());
        let (q, v) = state(nm);
        let gravity = Vector3::new(0.0, -9.81, 1.0);
        let (qd, vd) = dual_state(&q, &v);
        let dm = dual_body(&modal, |_, _| [0.0; 2], |_, _| [0.0; 2]);
        let (q2, v2) = (constant(&q), constant(&v));
        // one eigenmode, two correction modes
        let e = 1;
        // values and tangents, bit for bit (dual numbers compare by value)
        let bits = |x: &[Dual<2>]| -> Vec<[u64; 3]> {
            x.iter()
                .map(|x| [x.v.to_bits(), x.d[0].to_bits(), x.d[1].to_bits()])
                .collect()
        };
        let same = |a: &Dynamics<Dual<2>>, b: &Dynamics<Dual<2>>, what: &str| {
            assert_eq!(bits(a.0.as_slice()), bits(b.0.as_slice()), "{what}: mass");
            assert_eq!(bits(&a.1), bits(&b.1), "{what}: forces");
        };
        for elements in [true, false] {
            let full = element_field(nm, n_nodes, elements);
            let skipped = full.clone().without_correction_products(e);
            assert_eq!(
                (
                    skipped.eigenmodes,
                    skipped.row_len(e - 1),
                    skipped.row_len(e)
                ),
                (e, nm, e)
            );
            let read_whole = GeometricStiffness {
                eigenmodes: nm,
                ..skipped.clone()
            };
            for gram in [false, true] {
                let what = format!("elements {elements}, Gram table {gram}");
                // dual parameters (the field's tangents), and dual states with the values
                let a = with_path(&dm, &skipped, gram, &q2, &v2, &gravity);
                let b = with_path(&dm, &read_whole, gram, &q2, &v2, &gravity);
                same(&a, &b, &what);
                let value = |g: &GeometricStiffness<Dual<2>>| g.map(&|x: Dual<2>| x.v);
                let a = with_path(&modal, &value(&skipped), gram, &qd, &vd, &gravity);
                let b = with_path(&modal, &value(&read_whole), gram, &qd, &vd, &gravity);
                same(&a, &b, &format!("{what}, dual state"));
                let c = with_path(&modal, &value(&full), gram, &qd, &vd, &gravity);
                assert_ne!(
                    bits(&a.1),
                    bits(&c.1),
                    "{what}: the products left out matter"
                );
            }
            for k in 0..n_nodes {
                let w: Vec<Dual<2>> = qd[7..7 + nm].to_vec();
                let (a, b) = (
                    foreshortening(&skipped, k, &w),
                    foreshortening(&read_whole, k, &w),
                );
                assert_eq!(
                    bits(a.as_slice()),
                    bits(b.as_slice()),
                    "elements {elements}, node {k}"
                );
            }
        }
    }

    /// The deformation bound of the step guard is at least the largest nodal translation, and
    /// within a small factor of it.
    #[test]
    fn the_deformation_bound_bounds_the_largest_translation() {
        let modal = body();
        let g = field(&modal);
        let inv = ModalInvariants::new(&modal, Some(&g));
        let nm = modal.n_modes();
        for s in 0..20 {
            let w: Vec<f64> = (0..nm)
                .map(|j| 0.3 * ((s * 7 + j * 3) as f64 * 0.37).sin() * 10f64.powi(-(s as i32 % 4)))
                .collect();
            let largest = (0..modal.n_nodes())
                .map(|k| {
                    let mut u: Vector3<f64> = foreshortening(&g, k, &w);
                    for (j, wj) in w.iter().enumerate() {
                        u += mode_vec::<f64, f64>(&modal, k, j, false) * *wj;
                    }
                    u.norm()
                })
                .fold(0.0, f64::max);
            let bound = inv.deformation_bound(&w);
            assert!(
                bound >= largest && bound <= 50.0 * largest,
                "{bound} for {largest}"
            );
        }
    }

    /// The invariants give the nodal sums' mass matrix and forces (values and tangents).
    #[test]
    fn invariants_reproduce_the_nodal_sums() {
        let modal = body();
        let (q, v) = state(modal.n_modes());
        let ((m1, f1), (m2, f2)) = both(&modal, &q, &v);
        let scale_m = m2.amax();
        assert!(
            (&m1 - &m2).amax() <= 1e-14 * scale_m,
            "{}",
            (&m1 - &m2).amax()
        );
        let scale_f = f2.iter().fold(0.0f64, |a, x| a.max(x.abs()));
        for (a, b) in f1.iter().zip(&f2) {
            assert!((a - b).abs() <= 1e-13 * scale_f, "{a} vs {b}");
        }
        // tangents along arbitrary directions of q and v
        let (qd, vd) = dual_state(&q, &v);
        let ((m1, f1), (m2, f2)) = both(&modal, &qd, &vd);
        let close = |a: &[Dual<2>], b: &[Dual<2>], tol: f64| {
            for (a, b) in a.iter().zip(b) {
                for k in 0..2 {
                    assert!((a.d[k] - b.d[k]).abs() <= tol, "{a} vs {b}");
                }
            }
        };
        close(m1.as_slice(), m2.as_slice(), 1e-13 * scale_m);
        close(&f1, &f2, 1e-12 * scale_f);
        // design-dependent modes (as in updated-mode sensitivities) and masses (a density or a
        // thickness as a design variable): the tangents of the invariants carry their
        // derivatives
        let dual_modal = ModalBody {
            node_positions: modal.node_positions.clone(),
            node_masses: modal
                .node_masses
                .iter()
                .enumerate()
                .map(|(k, &m)| Dual::new(m, [0.0, 0.1 * m * (1.0 + (k as f64).sin())]))
                .collect(),
            node_inertias: modal
                .node_inertias
                .iter()
                .map(|mu| mu.map(|x| Dual::new(x, [0.0, 0.2 * x])))
                .collect(),
            modes: modal
                .modes
                .map_with_location(|r, j, x| Dual::new(x, [0.0, 0.2 * ((r + 3 * j) as f64).cos()])),
            eigenvalues: modal
                .eigenvalues
                .iter()
                .map(|&x| Dual::new(x, [0.0, 5.0]))
                .collect(),
            modal_damping: modal
                .modal_damping
                .iter()
                .map(|&x| Dual::new(x, [0.0, 0.1]))
                .collect(),
            stiffness_matrix: None,
            damping_matrix: None,
        };
        let ((m1, f1), (m2, f2)) = both(&dual_modal, &qd, &vd);
        close(m1.as_slice(), m2.as_slice(), 1e-13 * scale_m);
        close(&f1, &f2, 1e-12 * scale_f);
        assert!(m1.iter().any(|x| x.d[1].abs() > 1e-3 * scale_m));
    }

    /// `vᵀ M v / 2` is the kinetic energy of the lumped nodal masses and rotary inertias.
    #[test]
    fn mass_matrix_gives_the_nodal_kinetic_energy() {
        let modal = body();
        let nm = modal.n_modes();
        let (q, v) = state(nm);
        let ((m, _), _) = both(&modal, &q, &v);
        let vv = nalgebra::DVector::from_column_slice(&v);
        let t = 0.5 * vv.dot(&(&m * &vv));
        let a = pose(&q).a;
        let om = vec3(&v[3..6]);
        let mut expected = 0.0;
        for k in 0..modal.n_nodes() {
            let mut u = modal.node_positions[k];
            let mut ud = Vector3::zeros();
            let mut thd = Vector3::zeros();
            for j in 0..nm {
                let x: Vector3<f64> = mode_vec(&modal, k, j, false);
                let r: Vector3<f64> = mode_vec(&modal, k, j, true);
                u += x * q[7 + j];
                ud += x * v[6 + j];
                thd += r * v[6 + j];
            }
            let vel = vec3(&v[0..3]) + a * (om.cross(&u) + ud);
            let spin = om + thd;
            expected += 0.5 * modal.node_masses[k] * vel.norm_squared()
                + 0.5 * spin.dot(&spin.component_mul(&modal.node_inertias[k]));
        }
        assert!(
            (t - expected).abs() <= 1e-13 * expected,
            "{t} vs {expected}"
        );
    }
}
