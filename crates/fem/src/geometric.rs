//! The second-order displacement field of flexible bodies, in the form of modal geometric
//! stiffness matrices of unit nodal forces (docs/geometric-stiffening.md): beams here, shells in
//! [`crate::shell_geometric_stiffness`], either through [`second_order_field`].
//!
//! A bent beam's ends come closer: each element keeps its length to second order while it
//! bends, so node `k` moves towards the body's *clamp* (the node at its body frame) by
//! `½ Q_k(w, w)`, `Q_k,jl = −Σ_e t_e ∫_e φ′_j · φ′_l dx` over the elements `e` on the path from
//! the clamp to `k` (axis `t_e`, transverse slopes `φ′` of the modes). A force `F` at the node
//! does the work `½ Fᵀ Q_k(w, w) = −½ wᵀ K_G(F) w` on it: `K_G(F) = Σ_i F_i nodal[3k + i]` is the
//! geometric stiffness of the axial forces `F` causes, which on a tree-shaped beam mesh are the
//! axial components of the loads beyond each element (exact statics, no stiffness enters, exact
//! in any scalar). The multibody layer uses `Q_k = −nodal[3k + i]` as the body's second-order
//! field, from which the geometric stiffness of inertia, joint and applied loads follows.
//!
//! Each element's matrix is the consistent cubic (Hermite) one of `∫ |v′|² dx` for a unit axial
//! force, with the nodal slopes taken from the nodal rotations (`θ × t`), projected on the mode
//! shapes.

use nalgebra::{DMatrix, Vector3};
use sens::Scalar;

use crate::error::FemError;
use crate::mesh::{Element, Mesh};
use crate::modal::{ModalBody, NODE_DOFS};

/// The second-order field of a beam body as the modal geometric stiffness of unit nodal forces,
/// in body components (see the module doc): a force `F_k` at node `k` has the geometric
/// stiffness `Σ_i F_k,i nodal[3k + i]`, and `−nodal[3k + i]` is component `i` of the node's
/// second-order field `Q_k`.
///
/// The field may involve only the body's leading `field_modes` modes (a shell's eigenmodes,
/// not its static correction modes): the matrices are then `field_modes × field_modes`, and the
/// field of every other mode is zero.
#[derive(Clone, Debug)]
pub struct GeometricStiffness<S: Scalar> {
    /// The body's modes.
    pub n_modes: usize,
    /// The leading modes the field involves (`≤ n_modes`), the order of the matrices.
    pub field_modes: usize,
    /// The leading modes whose products with every mode of the field it holds
    /// (`≤ field_modes`); the products of two later modes (a beam's static correction modes
    /// with each other) are left out, zero in every matrix, so that row `j ≥ eigenmodes` has
    /// its entries in the first `eigenmodes` columns only ([`GeometricStiffness::row_len`]).
    pub eigenmodes: usize,
    /// The node the field is measured from (where it is zero).
    pub clamp: usize,
    /// Per component `i` of a force at node `k` (N), at `3k + i` (zero at the clamp).
    pub nodal: Vec<DMatrix<S>>,
    /// A beam body's field by the elements that carry it, parents before children (`None`
    /// for a shell's): `nodal[3k + i] = Σ_e t_e,i G_e` over the elements `e` on the path from
    /// node `k` to the clamp, so that the field at every node costs one product by `G_e` per
    /// element, accumulated along the tree, instead of three per node.
    pub elements: Option<Vec<FieldElement<S>>>,
}

/// A beam element of a [`GeometricStiffness`] ([`GeometricStiffness::elements`]).
#[derive(Clone, Debug)]
pub struct FieldElement<S: Scalar> {
    /// The element's node nearer the clamp.
    pub parent: usize,
    /// Its other node.
    pub child: usize,
    /// The unit vector from `parent` to `child` (body components).
    pub axis: Vector3<f64>,
    /// `G_e`: the modal geometric stiffness of a unit tension in the element
    /// (`field_modes × field_modes`, symmetric).
    pub unit: DMatrix<S>,
}

impl<S: Scalar> GeometricStiffness<S> {
    /// Convert the entries to another scalar.
    pub fn map<Q: Scalar>(&self, f: &impl Fn(S) -> Q) -> GeometricStiffness<Q> {
        GeometricStiffness {
            n_modes: self.n_modes,
            field_modes: self.field_modes,
            eigenmodes: self.eigenmodes,
            clamp: self.clamp,
            nodal: self.nodal.iter().map(|x| x.map(f)).collect(),
            elements: self.elements.as_ref().map(|els| {
                els.iter()
                    .map(|e| FieldElement {
                        parent: e.parent,
                        child: e.child,
                        axis: e.axis,
                        unit: e.unit.map(f),
                    })
                    .collect()
            }),
        }
    }

    /// The modal geometric stiffness `K_G` of the nodal forces `(node, force)` (body
    /// components), `n_modes × n_modes`.
    pub fn at(&self, forces: &[(usize, Vector3<S>)]) -> DMatrix<S> {
        let n = self.field_modes;
        let mut k = DMatrix::zeros(self.n_modes, self.n_modes);
        for (node, f) in forces {
            for i in 0..3 {
                let mut block = k.view_mut((0, 0), (n, n));
                block += &self.nodal[3 * node + i] * f[i];
            }
        }
        k
    }
}

impl<S: Scalar> GeometricStiffness<S> {
    /// The number of leading entries of row `j` of each matrix that may be nonzero: all
    /// `field_modes` for an eigenmode's row, the `eigenmodes` for a later mode's
    /// ([`GeometricStiffness::eigenmodes`]).
    #[inline]
    pub fn row_len(&self, j: usize) -> usize {
        if j < self.eigenmodes {
            self.field_modes
        } else {
            self.eigenmodes
        }
    }

    /// The field without the products of two modes past the leading `eigenmodes` (a beam's
    /// static correction modes, whose amplitudes are the joints' local deformation): their
    /// entries zeroed in every matrix. Their products with the eigenmodes stay: on the steel
    /// slider-crank with four eigenmodes (`tests/second_order_slider_crank.rs`) leaving out
    /// these moves the history by 7e-5 of its peak after a spin-up (3.7e-4 after a sudden
    /// start), where leaving out those too took its error against the geometrically exact beam
    /// from 3.2e-3 to 5.4e-3 of the peak (docs/geometric-stiffening.md, "Cost").
    pub fn without_correction_products(mut self, eigenmodes: usize) -> Self {
        let e = eigenmodes.min(self.field_modes);
        let zero = |m: &mut DMatrix<S>| {
            for j in e..m.ncols() {
                for i in e..m.nrows() {
                    m[(i, j)] = S::zero();
                }
            }
        };
        self.nodal.iter_mut().for_each(zero);
        if let Some(elements) = self.elements.as_mut() {
            elements.iter_mut().for_each(|el| zero(&mut el.unit));
        }
        self.eigenmodes = e;
        self
    }

    /// Whether every matrix is zero where both modes are past [`GeometricStiffness::eigenmodes`]
    /// (values and tangents), as [`GeometricStiffness::without_correction_products`] leaves
    /// them: the entries [`GeometricStiffness::row_len`] lets the multibody layer's loops skip.
    pub fn leaves_out_correction_products(&self) -> bool {
        let e = self.eigenmodes;
        let zero =
            |m: &DMatrix<S>| (e..m.ncols()).all(|j| (e..m.nrows()).all(|i| m[(i, j)].is_zero()));
        e <= self.field_modes
            && self.nodal.iter().all(zero)
            && (self.elements.iter().flatten()).all(|el| zero(&el.unit))
    }

    /// The nodal cases of the couplings' nodes (numbered after the mesh's, in the order of
    /// `couplings`): a force at a coupling's point is spread over its nodes as the coupling
    /// spreads it (`Wᵀ`), and so are its cases. Moments at a coupling, as at a node, are left
    /// out.
    pub fn with_couplings(mut self, couplings: &[crate::correction::Distribution]) -> Self {
        for c in couplings {
            for axis in 0..3 {
                let mut k = DMatrix::<S>::zeros(self.field_modes, self.field_modes);
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

/// The [`GeometricStiffness`] (second-order field) of the flexible body `body` (the modes of
/// `analysis`) whose FE mesh is `mesh`, with the element properties `props`, measured from
/// node `clamp`: [`geometric_stiffness`] on a beam mesh (exact statics along the tree, every
/// mode, without the products of two static correction modes:
/// [`GeometricStiffness::without_correction_products`]), [`crate::shell_geometric_stiffness`]
/// on a shell mesh (the membrane's quadratic modes, of the eigenmodes).
pub fn second_order_field<S: Scalar>(
    mesh: &Mesh,
    props: &crate::Properties<S>,
    analysis: &crate::ModalAnalysis,
    body: &ModalBody<S>,
    clamp: usize,
) -> Result<GeometricStiffness<S>, FemError> {
    if mesh
        .elements
        .iter()
        .any(|e| matches!(e, Element::Shell { .. }))
    {
        // the eigenmodes carry the field; the static correction modes after them, whose
        // amplitudes are the joints' local deformation, do not
        let eigenmodes = analysis.kept.len().min(body.n_modes());
        crate::shell_geometric_stiffness(mesh, props, &analysis.options, body, clamp, eigenmodes)
    } else {
        // every mode's products with the eigenmodes; the static correction modes' products with
        // each other left out
        let eigenmodes = analysis.kept.len().min(body.n_modes());
        Ok(geometric_stiffness(mesh, body, clamp)?.without_correction_products(eigenmodes))
    }
}

/// The [`GeometricStiffness`] (second-order field) of the beam body `body` whose FE mesh is
/// `mesh` (node positions of `body` are the mesh's, moved to the body frame), measured from
/// node `clamp`.
///
/// Errors: a mesh with shell elements ([`crate::shell_geometric_stiffness`] is theirs), a mesh
/// that is not a tree connected to `clamp` (closed loops make the axial forces depend on the
/// stiffness; a node with mass that the clamp does not reach has no path along which to
/// foreshorten), a zero-length element.
pub fn geometric_stiffness<S: Scalar>(
    mesh: &Mesh,
    body: &ModalBody<S>,
    clamp: usize,
) -> Result<GeometricStiffness<S>, FemError> {
    let n_nodes = check_body(mesh, body, clamp)?;
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
                    "this second-order field is for beam bodies only (a shell body's comes from \
                     its membrane: shell_geometric_stiffness, or second_order_field for either)"
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
    let mut out = GeometricStiffness {
        n_modes: nm,
        field_modes: nm,
        eigenmodes: nm,
        clamp,
        nodal: vec![DMatrix::<S>::zeros(nm, nm); 3 * n_nodes],
        elements: None,
    };
    // each element's modal geometric stiffness for a unit tension, and its axial unit vector
    let mut unit: Vec<Option<(DMatrix<S>, Vector3<f64>)>> = vec![None; mesh.elements.len()];
    let mut elements = Vec::with_capacity(order.len());
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
        elements.push(FieldElement {
            parent: p,
            child: c,
            axis: t,
            unit: g.clone(),
        });
        unit[e] = Some((g, t));
    }
    out.elements = Some(elements);
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

/// The number of mesh nodes, after checking that `body` holds the mesh's nodes (then possibly
/// the couplings' nodes, which carry no mass) and `clamp` is one of them.
pub(crate) fn check_body<S: Scalar>(
    mesh: &Mesh,
    body: &ModalBody<S>,
    clamp: usize,
) -> Result<usize, FemError> {
    let n_nodes = mesh.nodes.len();
    let extra_massless = (n_nodes..body.n_nodes()).all(|k| body.node_masses[k].value() == 0.0);
    if body.n_nodes() < n_nodes
        || !extra_massless
        || body.modes.nrows() != NODE_DOFS * body.n_nodes()
    {
        return Err(FemError::Stiffening(format!(
            "second-order field: the modal body has {} nodes, the mesh {n_nodes}",
            body.n_nodes()
        )));
    }
    if clamp >= n_nodes {
        return Err(FemError::Stiffening(format!(
            "second-order field: clamp node {clamp} does not exist ({n_nodes} nodes)"
        )));
    }
    Ok(n_nodes)
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

    /// A tension at the tip stiffens every mode; forces at the clamp do nothing (the field is
    /// zero there).
    #[test]
    fn a_tip_tension_stiffens_and_the_clamp_carries_nothing() {
        let (mesh, body) = cantilever(10);
        let g = geometric_stiffness(&mesh, &body, 0).unwrap();
        let n = body.n_modes();
        assert!((0..n).all(|j| g.nodal[3 * 10][(j, j)] > 0.0));
        assert!(g.nodal[..3].iter().all(|k| k.amax() == 0.0));
    }

    /// The elements' form of the field is the nodal one: every node's matrices are the sums of
    /// `t_e,i G_e` over the elements on its path to the clamp (clamped mid-span here, so that
    /// the tree has two branches), and the elements come parents first.
    #[test]
    fn the_elements_sum_to_the_nodal_matrices_along_the_paths() {
        let (mesh, body) = cantilever(10);
        let g = geometric_stiffness(&mesh, &body, 4).unwrap();
        let els = g
            .elements
            .as_ref()
            .expect("a beam body's field has its elements");
        assert_eq!(els.len(), 10);
        let mut reached = [false; 11];
        reached[4] = true;
        for e in els {
            assert!(reached[e.parent] && !reached[e.child], "parents first");
            reached[e.child] = true;
        }
        for k in 0..11 {
            let mut sum = vec![DMatrix::<f64>::zeros(g.field_modes, g.field_modes); 3];
            let mut node = k;
            while let Some(e) = els.iter().find(|e| e.child == node) {
                for (i, s) in sum.iter_mut().enumerate() {
                    *s += &e.unit * e.axis[i];
                }
                node = e.parent;
            }
            for (i, s) in sum.iter().enumerate() {
                let nodal = &g.nodal[3 * k + i];
                assert!(
                    (s - nodal).amax() <= 1e-14 * nodal.amax().max(1.0),
                    "node {k}"
                );
            }
        }
        assert!(g.nodal[3 * 10].amax() > 0.0 && g.nodal[0].amax() > 0.0);
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
