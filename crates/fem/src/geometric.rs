//! Geometric (stress) stiffening of beam bodies: modal geometric-stiffness matrices for unit
//! values of the load parameters of a floating frame (docs/geometric-stiffening.md).
//!
//! A beam carrying an axial force `N` gains the stiffness `N ∫ |v'|² dx / 2` of its transverse
//! deflection `v`. In a floating frame the axial forces are those of the body's quasi-static
//! equilibrium under the inertia loads of the frame's motion and the forces at its nodes. Both
//! are linear in a few load parameters (in body components): the frame's effective acceleration
//! `a = Aᵀ(r̈ − g)`, its angular acceleration `α`, the products `ω_i ω_j` of its angular velocity,
//! and the force at each node. So the modal geometric stiffness is
//! `K_G = Σ_c p_c K_c` with one `n_modes × n_modes` matrix `K_c` per parameter, made here once;
//! the multibody layer combines them with the current parameters at every evaluation (the
//! "standard input data" approach of substructure codes, e.g. Wallrapp 1994).
//!
//! The nodal matrices are also the beam's second-order displacement field: `−nodal[3k + i]`
//! is component `i` of `Q_k`, the foreshortening `u_k = ½ Q_k(w, w)` of node `k` towards the
//! clamp along its path (each element keeps its length to second order while it bends), whose
//! work under a force `F` at the node is `−½ wᵀ K_G(F) w`. The multibody layer uses them that
//! way (docs/geometric-stiffening.md), and the inertia cases are their mass-weighted sums.
//!
//! The statics are those of the beam mesh clamped at one node (any node of an isostatic support
//! gives the same stresses under self-equilibrated loads): on a tree-shaped mesh the axial force
//! of an element is the axial component of the loads beyond it, so no stiffness enters and the
//! result is exact in any scalar. Lumped nodal masses carry the inertia loads. Each element's
//! geometric stiffness is the consistent cubic (Hermite) one of a unit axial force, with the
//! nodal slopes taken from the nodal rotations (`θ × t`), projected on the mode shapes.

use nalgebra::{DMatrix, Matrix3, Vector3};
use sens::Scalar;

use crate::error::FemError;
use crate::mesh::{Element, Mesh};
use crate::modal::{ModalBody, NODE_DOFS};

/// The modal geometric-stiffness matrices of a beam body for unit load parameters, all in body
/// components (see the module doc). The geometric stiffness of the body is
///
/// ```text
/// K_G = Σ_i a_i acceleration[i] + Σ_i α_i angular_acceleration[i]
///     + Σ_ij ω_i ω_j spin[3i + j] + Σ_k Σ_i F_ki nodal[3k + i]
/// ```
#[derive(Clone, Debug)]
pub struct GeometricStiffness<S: Scalar> {
    pub n_modes: usize,
    /// The node at which the load cases are reacted (the statics' clamp).
    pub clamp: usize,
    /// Per component of the frame's effective acceleration `Aᵀ(r̈ − g)` (m/s²).
    pub acceleration: [DMatrix<S>; 3],
    /// Per component of the frame's angular acceleration (rad/s²).
    pub angular_acceleration: [DMatrix<S>; 3],
    /// Per product `ω_i ω_j` of the frame's angular velocity, at `3i + j` (symmetric pairs
    /// share the load equally).
    pub spin: Vec<DMatrix<S>>,
    /// Per component `i` of a force at node `k` (N), at `3k + i` (zero at the clamp); minus
    /// component `i` of the node's second-order field `Q_k` (see the module doc).
    pub nodal: Vec<DMatrix<S>>,
}

impl<S: Scalar> GeometricStiffness<S> {
    /// Convert the entries to another scalar.
    pub fn map<Q: Scalar>(&self, f: &impl Fn(S) -> Q) -> GeometricStiffness<Q> {
        let m = |x: &DMatrix<S>| x.map(f);
        GeometricStiffness {
            n_modes: self.n_modes,
            clamp: self.clamp,
            acceleration: [
                m(&self.acceleration[0]),
                m(&self.acceleration[1]),
                m(&self.acceleration[2]),
            ],
            angular_acceleration: [
                m(&self.angular_acceleration[0]),
                m(&self.angular_acceleration[1]),
                m(&self.angular_acceleration[2]),
            ],
            spin: self.spin.iter().map(m).collect(),
            nodal: self.nodal.iter().map(m).collect(),
        }
    }

    /// The modal geometric stiffness `K_G` for given load parameters (body components): the
    /// frame's effective acceleration `a`, angular acceleration `alpha`, angular velocity
    /// `omega` and nodal forces `(node, force)`.
    pub fn at(
        &self,
        a: &Vector3<S>,
        alpha: &Vector3<S>,
        omega: &Vector3<S>,
        forces: &[(usize, Vector3<S>)],
    ) -> DMatrix<S> {
        let n = self.n_modes;
        let mut k = DMatrix::zeros(n, n);
        for i in 0..3 {
            k += &self.acceleration[i] * a[i] + &self.angular_acceleration[i] * alpha[i];
            for j in 0..3 {
                k += &self.spin[3 * i + j] * (omega[i] * omega[j]);
            }
        }
        for (node, f) in forces {
            for i in 0..3 {
                k += &self.nodal[3 * node + i] * f[i];
            }
        }
        k
    }
}

impl<S: Scalar> GeometricStiffness<S> {
    /// The nodal cases of the couplings' nodes (numbered after the mesh's, in the order of
    /// `couplings`): a force at a coupling's point is spread over its nodes as the coupling
    /// spreads it (`Wᵀ`), and so are its cases. Moments at a coupling, as at a node, are left
    /// out.
    pub fn with_couplings(mut self, couplings: &[crate::correction::Distribution]) -> Self {
        for c in couplings {
            for axis in 0..3 {
                let mut k = DMatrix::<S>::zeros(self.n_modes, self.n_modes);
                for (i, &node) in c.nodes.iter().enumerate() {
                    for d in 0..3 {
                        let w = c.weights[(axis, 6 * i + d)];
                        if w != 0.0 {
                            k += &self.nodal[3 * node + d] * S::from_f64(w);
                        }
                    }
                }
                self.nodal.push(k);
            }
        }
        self
    }
}

/// The [`GeometricStiffness`] of the beam body `body` whose FE mesh is `mesh` (node positions
/// of `body` are the mesh's, moved to the body frame), its load cases reacted at node `clamp`.
///
/// Errors: a mesh with shell elements (not available for shells yet), a mesh that is not a
/// tree connected to `clamp` (closed loops make the axial forces depend on the stiffness; a
/// node with mass that the clamp does not reach carries no load path), a zero-length element.
pub fn geometric_stiffness<S: Scalar>(
    mesh: &Mesh,
    body: &ModalBody<S>,
    clamp: usize,
) -> Result<GeometricStiffness<S>, FemError> {
    let n_nodes = mesh.nodes.len();
    // the mesh's nodes, then possibly the couplings' nodes, which carry no mass
    let extra_massless = (n_nodes..body.n_nodes()).all(|k| body.node_masses[k].value() == 0.0);
    if body.n_nodes() < n_nodes
        || !extra_massless
        || body.modes.nrows() != NODE_DOFS * body.n_nodes()
    {
        return Err(FemError::Stiffening(format!(
            "geometric stiffening: the modal body has {} nodes, the mesh {n_nodes}",
            body.n_nodes()
        )));
    }
    if clamp >= n_nodes {
        return Err(FemError::Stiffening(format!(
            "geometric stiffening: clamp node {clamp} does not exist ({n_nodes} nodes)"
        )));
    }
    // adjacency of the beam elements
    let mut adjacent: Vec<Vec<(usize, usize)>> = vec![Vec::new(); n_nodes];
    for (e, el) in mesh.elements.iter().enumerate() {
        match el {
            Element::Beam { nodes, .. } => {
                adjacent[nodes[0]].push((e, nodes[1]));
                adjacent[nodes[1]].push((e, nodes[0]));
            }
            Element::Shell { .. } => {
                return Err(FemError::Stiffening(
                    "geometric stiffening is available for beam bodies only (a shell body's \
                     membrane stresses are not computed yet)"
                        .into(),
                ));
            }
        }
    }
    // breadth-first tree from the clamp: the element to each node's parent
    let mut parent: Vec<Option<(usize, usize)>> = vec![None; n_nodes];
    let mut seen = vec![false; n_nodes];
    let mut order = vec![clamp];
    seen[clamp] = true;
    let mut used = vec![false; mesh.elements.len()];
    let mut head = 0;
    while head < order.len() {
        let p = order[head];
        head += 1;
        for &(e, c) in &adjacent[p] {
            if used[e] {
                continue;
            }
            used[e] = true;
            if seen[c] {
                return Err(FemError::Stiffening(format!(
                    "geometric stiffening needs a beam mesh without closed loops: element {e} \
                     closes one (its axial forces would depend on the stiffness)"
                )));
            }
            seen[c] = true;
            parent[c] = Some((e, p));
            order.push(c);
        }
    }
    if let Some(k) = (0..n_nodes).find(|&k| !seen[k] && body.node_masses[k].value() != 0.0) {
        return Err(FemError::Stiffening(format!(
            "geometric stiffening: node {k} has mass but no beam path to the clamp node {clamp}"
        )));
    }
    let nm = body.n_modes();
    let x = &body.node_positions;
    // mass and first moment of the subtree beyond each node
    let mut s0: Vec<S> = body.node_masses.clone();
    let mut s1: Vec<Vector3<S>> = (0..n_nodes)
        .map(|k| x[k].map(S::from_f64) * body.node_masses[k])
        .collect();
    for &c in order.iter().rev() {
        if let Some((_, p)) = parent[c] {
            let (m, f) = (s0[c], s1[c]);
            s0[p] += m;
            s1[p] += f;
        }
    }
    let zero = || DMatrix::<S>::zeros(nm, nm);
    let mut out = GeometricStiffness {
        n_modes: nm,
        clamp,
        acceleration: [zero(), zero(), zero()],
        angular_acceleration: [zero(), zero(), zero()],
        spin: vec![zero(); 9],
        nodal: vec![zero(); 3 * n_nodes],
    };
    // each element's modal geometric stiffness for a unit tension, and its axial unit vector
    let mut unit: Vec<Option<(DMatrix<S>, Vector3<f64>)>> = vec![None; mesh.elements.len()];
    for &c in &order {
        let Some((e, p)) = parent[c] else { continue };
        let d = x[c] - x[p];
        let length = d.norm();
        if !(length > 0.0) {
            return Err(FemError::Stiffening(format!(
                "geometric stiffening: beam element {e} has zero length"
            )));
        }
        let t = d / length;
        let g = element_modal(body, p, c, &t, length);
        // the axial force of the element is the axial component of the loads beyond it
        let (m, f) = (s0[c], s1[c]);
        let tt: Vector3<S> = t.map(S::from_f64);
        let fxt = f.cross(&tt);
        let ft = f.dot(&tt);
        let spin = Matrix3::<S>::from_fn(|i, j| {
            let diag = if i == j { ft } else { S::zero() };
            diag - (f[i] * tt[j] + f[j] * tt[i]) * S::from_f64(0.5)
        });
        for i in 0..3 {
            out.acceleration[i] -= &g * (m * tt[i]);
            out.angular_acceleration[i] -= &g * fxt[i];
            for j in 0..3 {
                out.spin[3 * i + j] += &g * spin[(i, j)];
            }
        }
        unit[e] = Some((g, t));
    }
    // a force at node k is carried by every element on the path from k to the clamp
    for k in 0..n_nodes {
        let mut node = k;
        while let Some((e, p)) = parent[node] {
            let (g, t) = unit[e].as_ref().expect("every tree element has its matrix");
            for i in 0..3 {
                out.nodal[3 * k + i] += g * S::from_f64(t[i]);
            }
            node = p;
        }
    }
    Ok(out)
}

/// The modal geometric stiffness of the element from node `a` to node `b` (axis `t`, length
/// `l`) for a unit tension: the consistent cubic matrix of `∫ |v'|² dx` on the transverse
/// nodal displacements `v_k = (I − t tᵀ) u_k` and slopes `s_k = θ_k × t`, projected on the modes.
fn element_modal<S: Scalar>(
    body: &ModalBody<S>,
    a: usize,
    b: usize,
    t: &Vector3<f64>,
    l: f64,
) -> DMatrix<S> {
    let nm = body.n_modes();
    let tt: Vector3<S> = t.map(S::from_f64);
    // (v_a, s_a, v_b, s_b) of each mode
    let shape = |j: usize| -> [Vector3<S>; 4] {
        let node = |k: usize| {
            let r = NODE_DOFS * k;
            let u = Vector3::new(
                body.modes[(r, j)],
                body.modes[(r + 1, j)],
                body.modes[(r + 2, j)],
            );
            let th = Vector3::new(
                body.modes[(r + 3, j)],
                body.modes[(r + 4, j)],
                body.modes[(r + 5, j)],
            );
            (u - tt * u.dot(&tt), th.cross(&tt))
        };
        let (va, sa) = node(a);
        let (vb, sb) = node(b);
        [va, sa, vb, sb]
    };
    // ∫ H_i' H_j' dx for the Hermite functions of (v_a, s_a, v_b, s_b)
    let h = [
        [6.0 / 5.0, l / 10.0, -6.0 / 5.0, l / 10.0],
        [l / 10.0, 2.0 * l * l / 15.0, -l / 10.0, -l * l / 30.0],
        [-6.0 / 5.0, -l / 10.0, 6.0 / 5.0, -l / 10.0],
        [l / 10.0, -l * l / 30.0, -l / 10.0, 2.0 * l * l / 15.0],
    ];
    let shapes: Vec<[Vector3<S>; 4]> = (0..nm).map(shape).collect();
    let mut g = DMatrix::zeros(nm, nm);
    for i in 0..nm {
        for j in i..nm {
            let mut s = S::zero();
            for (p, row) in h.iter().enumerate() {
                for (q, &c) in row.iter().enumerate() {
                    s += shapes[i][p].dot(&shapes[j][q]) * (c / l);
                }
            }
            g[(i, j)] = s;
            g[(j, i)] = s;
        }
    }
    g
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{BeamSection, ModalOptions, Properties, ReferenceCondition, modal_analysis};

    fn cantilever(n: usize) -> (Mesh, ModalBody<f64>) {
        let mesh = Mesh::straight_beam(Vector3::zeros(), Vector3::x(), n, 0, Vector3::y()).unwrap();
        let props = Properties {
            sections: vec![BeamSection::diagonal(
                [1e6, 1e6, 1e6, 1e3, 1.0, 2.0],
                1.0,
                1e-6,
                1e-6,
            )],
            laminates: vec![],
        };
        let mut options = ModalOptions::new(4);
        options.reference = ReferenceCondition::ClampedNode(0);
        let analysis = modal_analysis(&mesh, &props, &options).unwrap();
        let body = crate::modal_body(&mesh, &props, &analysis).unwrap();
        (mesh, body)
    }

    /// The inertia load cases are sums of nodal force cases: a uniform acceleration `a` is the
    /// force `−m_k a` at every node, a spin `Ω` about z the force `m_k Ω² x_k` along x.
    #[test]
    fn inertia_load_cases_are_the_sums_of_their_nodal_forces() {
        let (mesh, body) = cantilever(10);
        let g = geometric_stiffness(&mesh, &body, 0).unwrap();
        let n = body.n_modes();
        for i in 0..3 {
            let mut sum = DMatrix::zeros(n, n);
            for (k, m) in body.node_masses.iter().enumerate() {
                sum -= &g.nodal[3 * k + i] * *m;
            }
            assert!((&sum - &g.acceleration[i]).amax() < 1e-12 * sum.amax().max(1.0));
        }
        let mut spin = DMatrix::zeros(n, n);
        for (k, m) in body.node_masses.iter().enumerate() {
            spin += &g.nodal[3 * k] * (m * body.node_positions[k].x);
        }
        assert!((&spin - &g.spin[8]).amax() < 1e-12 * spin.amax());
        assert!(spin.amax() > 0.0);
        // a tension at the tip stiffens every mode; loads at the clamp do nothing
        assert!((0..n).all(|j| g.nodal[3 * 10][(j, j)] > 0.0));
        assert!(g.nodal[..3].iter().all(|k| k.amax() == 0.0));
    }

    /// The unit-tension matrix of a straight beam pulled at its tip is `∫ X'ᵀ X' dx` of the
    /// modes: for the first mode of a uniform cantilever, `∫ φ'² dx / ∫ φ² dx = 4.6477 / L²`
    /// (the closed-form mode; mass-normalised here with m = L = 1, so `∫ φ² dx = 1`).
    #[test]
    fn tip_tension_matrix_is_the_slope_integral_of_the_modes() {
        let (mesh, body) = cantilever(40);
        let g = geometric_stiffness(&mesh, &body, 0).unwrap();
        let tip = 40;
        // the first mode bends in x–z (EI₂ = 1 < EI₃ = 2)
        let value = g.nodal[3 * tip][(0, 0)];
        // 40 lumped-mass elements: 4.6457
        assert!((value / 4.6477 - 1.0).abs() < 1e-3, "{value}");
    }

    #[test]
    fn shells_and_closed_loops_are_refused() {
        let (mut mesh, body) = cantilever(4);
        mesh.elements.push(Element::Beam {
            nodes: [0, 4],
            property: 0,
            orientation: Vector3::y(),
        });
        let e = geometric_stiffness(&mesh, &body, 0)
            .unwrap_err()
            .to_string();
        assert!(e.contains("closed loops"), "{e}");
        let (mut mesh, body) = cantilever(4);
        mesh.elements.push(Element::Shell {
            nodes: [0, 1, 2],
            property: 0,
            material_axis: Vector3::x(),
        });
        let e = geometric_stiffness(&mesh, &body, 0)
            .unwrap_err()
            .to_string();
        assert!(e.contains("beam bodies only"), "{e}");
    }
}
