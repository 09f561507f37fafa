//! Markers: points with an attached orthonormal triad, on the ground, on a body, or at an FE
//! node of a flexible body (which then follows the node's translation and rotation through the
//! mode shapes).

use nalgebra::{Matrix3, Vector3};
use sens::Scalar;

use crate::body::{Body, BodyId, Pose, mode_vec, second_order_node, vec3, vec3f};
use crate::kin::{Cols, Jac, Kin3, mv};

/// Where a marker sits on its body.
#[derive(Clone, Debug, PartialEq)]
pub enum Site {
    /// A point fixed in the body frame (m). On a flexible body it follows the floating frame,
    /// not the deformation.
    Point(Vector3<f64>),
    /// FE node `k` of a flexible body: follows the nodal translations and rotations `u' = X w`
    /// (with the body's second-order field, `+ ½ Q_k(w, w)` in the translation).
    Node(usize),
}

/// A point and a triad `(e1, e2, e3)` (columns of `axes`, body components) used by joints and
/// forces. For joints, `e3` is the joint axis.
#[derive(Clone, Debug, PartialEq)]
pub struct Marker {
    /// `None`: the ground (global frame).
    pub body: Option<BodyId>,
    pub site: Site,
    /// Columns `e1, e2, e3`, orthonormal, in body (or global for ground) components.
    pub axes: Matrix3<f64>,
}

impl Marker {
    /// A ground point with axes aligned with the global axes.
    pub fn ground(point: Vector3<f64>) -> Self {
        Self {
            body: None,
            site: Site::Point(point),
            axes: Matrix3::identity(),
        }
    }

    /// A point fixed in the frame of `body`, axes aligned with the body axes.
    pub fn on(body: BodyId, point: Vector3<f64>) -> Self {
        Self {
            body: Some(body),
            site: Site::Point(point),
            axes: Matrix3::identity(),
        }
    }

    /// FE node `node` of flexible body `body`, axes aligned with the body axes.
    pub fn node(body: BodyId, node: usize) -> Self {
        Self {
            body: Some(body),
            site: Site::Node(node),
            axes: Matrix3::identity(),
        }
    }

    /// The same marker with joint axis `e3` along `axis` (any length), `e1`, `e2` completing a
    /// right-handed orthonormal triad.
    pub fn with_axis(mut self, axis: Vector3<f64>) -> Self {
        let e3 = axis.normalize();
        let trial = if e3.x.abs() < 0.9 {
            Vector3::x()
        } else {
            Vector3::y()
        };
        let e1 = (trial - e3 * trial.dot(&e3)).normalize();
        let e2 = e3.cross(&e1);
        self.axes = Matrix3::from_columns(&[e1, e2, e3]);
        self
    }

    /// The same marker with explicit axes `e1, e2` (`e3 = e1 × e2`); orthonormalised.
    pub fn with_axes(mut self, e1: Vector3<f64>, e2: Vector3<f64>) -> Self {
        let e1 = e1.normalize();
        let e2 = (e2 - e1 * e2.dot(&e1)).normalize();
        self.axes = Matrix3::from_columns(&[e1, e2, e1.cross(&e2)]);
        self
    }
}

/// `A (e_i × w)` for `i = 0, 1, 2` into `out` (the Jacobian columns of `A w` with respect to the
/// body-frame angular velocity).
#[inline]
fn omega_columns<S: Scalar>(a: &Matrix3<S>, w: &Vector3<S>, out: &mut [Vector3<S>]) {
    let c = |j: usize| Vector3::new(a[(0, j)], a[(1, j)], a[(2, j)]);
    // e_0 × w = (0, −w2, w1), e_1 × w = (w2, 0, −w0), e_2 × w = (−w1, w0, 0)
    out[0] = c(2) * w[1] - c(1) * w[2];
    out[1] = c(0) * w[2] - c(2) * w[0];
    out[2] = c(1) * w[0] - c(0) * w[1];
}

/// Kinematics of a marker: global point with rate, quadratic term and Jacobian; its axes on
/// demand ([`MarkerKin::axis`], only those a joint uses are computed).
pub(crate) struct MarkerKin<S: Scalar> {
    pub point: Kin3<S>,
    /// Rotation body → global of the body (identity for ground).
    pub a: Matrix3<S>,
    /// Velocity offset of the body, modal rotation columns of the node (body components).
    pub v_off: usize,
    pub node_rot_modes: Vec<Vector3<S>>,
    /// The marker's axes in body (ground: global) components.
    axes0: [Vector3<S>; 3],
    /// Small nodal rotation `θ` and its rate (zero at a point site), body angular velocity.
    th: Vector3<S>,
    thd: Vector3<S>,
    om: Vector3<S>,
    /// The body's velocity columns (empty for ground).
    cols: Cols,
}

impl<S: Scalar> MarkerKin<S> {
    /// Whether the marker is on the ground.
    pub(crate) fn is_ground(&self) -> bool {
        self.cols.is_empty()
    }

    /// Axis `e_i` of the marker (global components) with its rate, quadratic term and
    /// Jacobian: `A e'` with `e' = e0 + θ × e0` (small nodal rotation).
    pub(crate) fn axis(&self, i: usize) -> Kin3<S> {
        let e0 = self.axes0[i];
        if self.cols.is_empty() {
            return Kin3::constant(e0);
        }
        let (a, om) = (&self.a, &self.om);
        let two = S::from_f64(2.0);
        let ep = e0 + self.th.cross(&e0);
        let epd = self.thd.cross(&e0);
        // no translation columns (kept, zero, so that all the marker's quantities share its
        // columns)
        let mut jac = vec![Vector3::zeros(); self.cols.len()];
        // ω columns: A (e_i × e'); mode columns (zero at a point site, which has no modes)
        omega_columns(a, &ep, &mut jac[3..6]);
        for (j, t) in self.node_rot_modes.iter().enumerate() {
            jac[6 + j] = mv(a, &t.cross(&e0));
        }
        Kin3 {
            val: mv(a, &ep),
            rate: mv(a, &(om.cross(&ep) + epd)),
            quad: mv(a, &(om.cross(&om.cross(&ep)) + om.cross(&epd) * two)),
            jac: Jac::from_entries(self.cols.clone(), jac),
        }
    }
}

/// Marker kinematics at the state `(q, v)`. `body` is the marker's body with its coordinate
/// and velocity offsets and `pose` its pose at `q` (both `None` for ground).
pub(crate) fn marker_kin<P: Scalar, S: Scalar + From<P>>(
    marker: &Marker,
    body: Option<(&Body<P>, usize, usize)>,
    pose: Option<&Pose<S>>,
    q: &[S],
    v: &[S],
) -> MarkerKin<S> {
    let axes0: [Vector3<S>; 3] =
        std::array::from_fn(|i| vec3f(&marker.axes.column(i).into_owned()));
    let Some((body, qo, vo)) = body else {
        let p = match &marker.site {
            Site::Point(p) => vec3f(p),
            Site::Node(_) => unreachable!("validated: ground markers are points"),
        };
        return MarkerKin {
            point: Kin3::constant(p),
            a: Matrix3::identity(),
            v_off: 0,
            node_rot_modes: Vec::new(),
            axes0,
            th: Vector3::zeros(),
            thd: Vector3::zeros(),
            om: Vector3::zeros(),
            cols: Cols::none(),
        };
    };
    let ps = pose.expect("a body marker comes with its body's pose");
    let a = ps.a;
    let om = vec3(&v[vo + 3..vo + 6]);
    let rd = vec3(&v[vo..vo + 3]);
    let nm = body.n_modes();
    // body-frame position u, deformation rate, rotation θ and its rate, mode columns
    let mut u;
    let mut ud = Vector3::<S>::zeros();
    let mut th = Vector3::<S>::zeros();
    let mut thd = Vector3::<S>::zeros();
    let mut xd = Vec::with_capacity(nm);
    let mut xt = Vec::with_capacity(nm);
    // the node's acceleration at zero modal accelerations, beyond the frame's terms
    let mut udd = Vector3::<S>::zeros();
    match (&marker.site, body) {
        (Site::Point(p), _) => u = vec3f(p),
        (Site::Node(k), Body::Flexible(fb)) => {
            u = vec3f(&fb.modal.node_positions[*k]);
            for j in 0..nm {
                let d: Vector3<S> = mode_vec(&fb.modal, *k, j, false);
                let t: Vector3<S> = mode_vec(&fb.modal, *k, j, true);
                u += d * q[qo + 7 + j];
                ud += d * v[vo + 6 + j];
                th += t * q[qo + 7 + j];
                thd += t * v[vo + 6 + j];
                xd.push(d);
                xt.push(t);
            }
            if let Some(g) = &fb.geometric {
                let w = &q[qo + 7..qo + 7 + nm];
                let wd = &v[vo + 6..vo + 6 + nm];
                // on the reverse-mode tape, one operation
                let second = crate::body::taped_sums::taped_second_order_node(g, *k, w, wd)
                    .unwrap_or_else(|| second_order_node(g, *k, w, wd));
                u += second.half;
                for (j, c) in second.columns.iter().enumerate() {
                    ud += c * wd[j];
                    xd[j] += c;
                }
                udd = second.rates;
            }
        }
        (Site::Node(_), Body::Rigid(_)) => unreachable!("validated: nodes only on flexible bodies"),
    }
    let two = S::from_f64(2.0);
    // the body's velocity columns: translation, rotation (ω'), modes
    let cols = Cols::of(vo..vo + 6 + nm);
    let mut jac = vec![Vector3::zeros(); 6 + nm];
    for (i, e) in jac.iter_mut().take(3).enumerate() {
        e[i] = S::one();
    }
    // ω columns: A (e_i × u)
    omega_columns(&a, &u, &mut jac[3..6]);
    for j in 0..xd.len() {
        jac[6 + j] = mv(&a, &xd[j]);
    }
    let point = Kin3 {
        val: ps.r + mv(&a, &u),
        rate: rd + mv(&a, &(om.cross(&u) + ud)),
        quad: mv(&a, &(om.cross(&om.cross(&u)) + om.cross(&ud) * two + udd)),
        jac: Jac::from_entries(cols.clone(), jac),
    };
    MarkerKin {
        point,
        a,
        v_off: vo,
        node_rot_modes: xt,
        axes0,
        th,
        thd,
        om,
        cols,
    }
}
