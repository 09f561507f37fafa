//! Geometric stiffening of flexible bodies (docs/geometric-stiffening.md): the forces
//! `−K_G w` of each stiffened body, where `K_G` ([`fem::GeometricStiffness`]) is linear in the
//! frame's acceleration and angular acceleration (unknowns of Eq. 12), its angular velocity,
//! the applied forces at its nodes, and the joint forces there (the multipliers, unknowns of
//! Eq. 12). So the forces are affine in `x̂ = [v̇; λ]`: they add a known part to the right-hand
//! side and coupling terms to the leading matrix of Eq. (12), which stays square and is still
//! factorised by LU (it is no longer symmetric).

use fem::{GeometricStiffness, ModalBody};
use nalgebra::{DMatrix, Matrix3, Vector3};
use sens::Scalar;

use crate::body::{lift, vec3f};

/// The geometric-stiffness forces of one body on its modal rows, `f_G = f0 + Σ c · x̂[col]`.
pub(crate) struct Stiffening<S: Scalar> {
    /// Velocity index of the body's first modal coordinate.
    pub row: usize,
    /// The part known at the state (gravity, spin, applied forces).
    pub known: Vec<S>,
    /// Coefficients of accelerations `v̇[col]` (the body's frame).
    pub accel: Vec<(usize, Vec<S>)>,
    /// Coefficients of multipliers, by constraint row (all rows numbering).
    pub lambda: Vec<(usize, Vec<S>)>,
}

/// The loads on one stiffened body at a state, in body components.
pub(crate) struct BodyLoads<S: Scalar> {
    /// Body → global rotation.
    pub a: Matrix3<S>,
    /// Applied forces at nodes.
    pub forces: Vec<(usize, Vector3<S>)>,
    /// Joint forces at nodes per unit multiplier: `(node, constraint row, force)`.
    pub joints: Vec<(usize, usize, Vector3<S>)>,
}

/// [`Stiffening`] of a body with geometric stiffness `g`, modal coordinates `w`, body angular
/// velocity `omega`, velocity offset `v_off`, under `loads` and `gravity` (global).
pub(crate) fn body_stiffening<P: Scalar, S: Scalar + From<P>>(
    g: &GeometricStiffness<P>,
    w: &[S],
    omega: &Vector3<S>,
    v_off: usize,
    gravity: &Vector3<f64>,
    loads: &BodyLoads<S>,
) -> Stiffening<S> {
    let nm = g.n_modes;
    // −K_c w
    let neg_kw = |k: &DMatrix<P>| -> Vec<S> {
        (0..nm)
            .map(|i| {
                let mut s = S::zero();
                for (j, &wj) in w.iter().enumerate() {
                    s -= lift::<P, S>(k[(i, j)]) * wj;
                }
                s
            })
            .collect()
    };
    let axpy = |y: &mut [S], a: S, x: &[S]| {
        for (yi, &xi) in y.iter_mut().zip(x) {
            *yi += a * xi;
        }
    };
    let a = &loads.a;
    // effective acceleration Aᵀ r̈ − Aᵀ g: the gravity part is known, r̈ is an unknown
    let g_body = a.transpose() * vec3f::<S>(gravity);
    let mut known = vec![S::zero(); nm];
    let mut accel: Vec<(usize, Vec<S>)> =
        (0..6).map(|c| (v_off + c, vec![S::zero(); nm])).collect();
    for i in 0..3 {
        let c = neg_kw(&g.acceleration[i]);
        axpy(&mut known, -g_body[i], &c);
        for m in 0..3 {
            axpy(&mut accel[m].1, a[(m, i)], &c);
        }
        accel[3 + i].1 = neg_kw(&g.angular_acceleration[i]);
    }
    // spin: K(ω) = Σ ω_i ω_j K_ij, then one product with w
    let mut spin = DMatrix::<S>::zeros(nm, nm);
    for i in 0..3 {
        for j in 0..3 {
            let f = omega[i] * omega[j];
            spin.zip_apply(&g.spin[3 * i + j], |s, k| *s += lift::<P, S>(k) * f);
        }
    }
    for i in 0..nm {
        for (j, &wj) in w.iter().enumerate() {
            known[i] -= spin[(i, j)] * wj;
        }
    }
    // nodal forces: applied (known) and per unit multiplier; −K_n,i w once per node
    let mut cache: Vec<(usize, [Vec<S>; 3])> = Vec::new();
    let mut node_terms = |node: usize| -> [Vec<S>; 3] {
        if let Some((_, c)) = cache.iter().find(|(n, _)| *n == node) {
            return c.clone();
        }
        let c = [0, 1, 2].map(|i| neg_kw(&g.nodal[3 * node + i]));
        cache.push((node, c.clone()));
        c
    };
    for (node, f) in &loads.forces {
        if *node == g.clamp {
            continue;
        }
        let c = node_terms(*node);
        for i in 0..3 {
            axpy(&mut known, f[i], &c[i]);
        }
    }
    let mut lambda = Vec::with_capacity(loads.joints.len());
    for (node, row, f) in &loads.joints {
        if *node == g.clamp {
            continue;
        }
        let c = node_terms(*node);
        let mut col = vec![S::zero(); nm];
        for i in 0..3 {
            axpy(&mut col, f[i], &c[i]);
        }
        lambda.push((*row, col));
    }
    Stiffening {
        row: v_off + 6,
        known,
        accel,
        lambda,
    }
}

/// The node a marker's force acts at: its node, or the node nearest its point.
pub(crate) fn load_node<P: Scalar>(modal: &ModalBody<P>, site: &crate::marker::Site) -> usize {
    match site {
        crate::marker::Site::Node(k) => *k,
        crate::marker::Site::Point(p) => modal.closest_node(p).unwrap_or(0),
    }
}
