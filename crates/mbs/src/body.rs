//! Bodies: rigid bodies and floating-frame flexible (modal) bodies (paper §2.1, Eqs. 1–6, 11–12).
//!
//! Coordinates of one body: `q_b = (r, p, w)` — origin of the body frame in the global frame,
//! Euler parameters of the body frame, modal coordinates (flexible bodies only). Velocity
//! variables: `v_b = (ṙ, ω', ẇ)` — global velocity of the origin, angular velocity in body
//! components, modal velocities.

use fem::ModalBody;
use nalgebra::{DMatrix, Matrix3, Vector3, Vector4};
use sens::Scalar;

use crate::kin::{rotation, skew};

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
#[derive(Clone, Debug)]
pub struct FlexibleBody<P: Scalar> {
    pub name: String,
    pub modal: ModalBody<P>,
}

impl<P: Scalar> FlexibleBody<P> {
    pub fn new(name: impl Into<String>, modal: ModalBody<P>) -> Self {
        Self {
            name: name.into(),
            modal,
        }
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
                    node_masses: b.modal.node_masses.clone(),
                    node_inertias: b.modal.node_inertias.clone(),
                    modes: b.modal.modes.map(f),
                    eigenvalues: b.modal.eigenvalues.iter().map(|&x| f(x)).collect(),
                    modal_damping: b.modal.modal_damping.iter().map(|&x| f(x)).collect(),
                },
            }),
        }
    }
}

/// Convert a parameter to the evaluation scalar.
#[inline]
pub(crate) fn lift<P: Scalar, S: Scalar + From<P>>(x: P) -> S {
    S::from(x)
}

#[inline]
pub(crate) fn vec3<S: Scalar>(s: &[S]) -> Vector3<S> {
    Vector3::new(s[0], s[1], s[2])
}

#[inline]
pub(crate) fn vec3f<S: Scalar>(a: &Vector3<f64>) -> Vector3<S> {
    Vector3::new(S::from_f64(a.x), S::from_f64(a.y), S::from_f64(a.z))
}

/// Translation (rows 0..3) and rotation (rows 3..6) of node `k` in mode `j`, as evaluation
/// scalars.
#[inline]
pub(crate) fn mode_vec<P: Scalar, S: Scalar + From<P>>(
    modal: &ModalBody<P>,
    k: usize,
    j: usize,
    rot: bool,
) -> Vector3<S> {
    let r = 6 * k + if rot { 3 } else { 0 };
    Vector3::new(
        lift(modal.modes[(r, j)]),
        lift(modal.modes[(r + 1, j)]),
        lift(modal.modes[(r + 2, j)]),
    )
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
pub(crate) fn body_dynamics<P: Scalar, S: Scalar + From<P>>(
    body: &Body<P>,
    q: &[S],
    v: &[S],
    gravity: &Vector3<f64>,
    mass: &mut DMatrix<S>,
    off: usize,
    force: &mut [S],
) {
    let Pose { a, .. } = pose(q);
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
            let modal = &b.modal;
            let nm = modal.n_modes();
            let w = &q[7..7 + nm];
            let wd = &v[6..6 + nm];
            let om = rd_omega;
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
                let mk: S = S::from_f64(modal.node_masses[k]);
                let jk: Vector3<S> = vec3f(&modal.node_inertias[k]);
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
    }
}
