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
    /// Velocity index of the body's frame (its accelerations are `v̇[frame..frame + 6]`).
    frame: usize,
    /// Coefficients of the frame's six accelerations, one block of `n_modes` each.
    accel: Vec<S>,
    /// Constraint rows (all rows numbering) of the joint forces at the body's nodes.
    lambda_rows: Vec<usize>,
    /// Their coefficients, one block of `n_modes` each.
    lambda: Vec<S>,
}

impl<S: Scalar> Stiffening<S> {
    /// Coefficients of accelerations `v̇[col]` (the body's frame): `(col, c)`.
    pub fn accel(&self) -> impl Iterator<Item = (usize, &[S])> {
        let frame = self.frame;
        self.accel
            .chunks(self.known.len().max(1))
            .enumerate()
            .map(move |(c, x)| (frame + c, x))
    }

    /// Coefficients of multipliers, by constraint row (all rows numbering): `(row, c)`.
    pub fn lambda(&self) -> impl Iterator<Item = (usize, &[S])> {
        self.lambda_rows
            .iter()
            .copied()
            .zip(self.lambda.chunks(self.known.len().max(1)))
    }
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
    // −K_c w into `out`
    let neg_kw = |k: &DMatrix<P>, out: &mut [S]| {
        for (i, o) in out.iter_mut().enumerate() {
            let mut s = S::zero();
            for (j, &wj) in w.iter().enumerate() {
                s -= lift::<P, S>(k[(i, j)]) * wj;
            }
            *o = s;
        }
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
    let mut accel = vec![S::zero(); 6 * nm];
    let mut c = vec![S::zero(); nm];
    for i in 0..3 {
        neg_kw(&g.acceleration[i], &mut c);
        axpy(&mut known, -g_body[i], &c);
        for m in 0..3 {
            axpy(&mut accel[m * nm..(m + 1) * nm], a[(m, i)], &c);
        }
        neg_kw(
            &g.angular_acceleration[i],
            &mut accel[(3 + i) * nm..(4 + i) * nm],
        );
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
    // nodal forces: applied (known) and per unit multiplier; −K_n,i w once per node, kept in
    // `cache` (three blocks of `nm` a node, in the order of `cached`)
    let mut cached: Vec<usize> = Vec::new();
    let mut cache: Vec<S> = Vec::new();
    let mut node_terms = |node: usize| -> usize {
        if let Some(p) = cached.iter().position(|&n| n == node) {
            return p;
        }
        let start = cache.len();
        cache.resize(start + 3 * nm, S::zero());
        for i in 0..3 {
            let block = start + i * nm;
            neg_kw(&g.nodal[3 * node + i], &mut cache[block..block + nm]);
        }
        cached.push(node);
        cached.len() - 1
    };
    let mut applied: Vec<(usize, &Vector3<S>)> = Vec::with_capacity(loads.forces.len());
    for (node, f) in &loads.forces {
        if *node != g.clamp {
            applied.push((node_terms(*node), f));
        }
    }
    let mut joint_terms: Vec<(usize, usize, &Vector3<S>)> = Vec::with_capacity(loads.joints.len());
    for (node, row, f) in &loads.joints {
        if *node != g.clamp {
            joint_terms.push((node_terms(*node), *row, f));
        }
    }
    let terms = |p: usize, i: usize| &cache[(3 * p + i) * nm..(3 * p + i + 1) * nm];
    for (p, f) in applied {
        for i in 0..3 {
            axpy(&mut known, f[i], terms(p, i));
        }
    }
    let mut lambda_rows = Vec::with_capacity(joint_terms.len());
    let mut lambda = vec![S::zero(); joint_terms.len() * nm];
    for (r, (p, row, f)) in joint_terms.into_iter().enumerate() {
        let col = &mut lambda[r * nm..(r + 1) * nm];
        for i in 0..3 {
            axpy(col, f[i], terms(p, i));
        }
        lambda_rows.push(row);
    }
    Stiffening {
        row: v_off + 6,
        known,
        frame: v_off,
        accel,
        lambda_rows,
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
