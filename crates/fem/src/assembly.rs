//! Element matrices in global axes, boundary conditions and sparse assembly on a fixed pattern.
//!
//! Dof numbering: node-major, six per node, `6 k + [u_x, u_y, u_z, θ_x, θ_y, θ_z]`. Constrained
//! dof are eliminated: the assembled matrices act on the *free* dof only, `u = T u_free`
//! ([`Assembly::expand`]): a fixed dof is zero, the dof of a rigidly tied node set follow the
//! set's rigid motion ([`RigidTie`], an RBE2 element). Values are assembled generically over
//! [`Scalar`], in the fixed CSC order of the pattern, so that a dual evaluation yields `K_b`,
//! `M_b` on the same pattern (one code path).

use std::collections::BTreeSet;

use faer::sparse::{SparseColMat, SymbolicSparseColMat};
use laminate::LaminateStiffness;
use nalgebra::{DMatrix, DVector, Matrix3, Matrix6, Vector3};
use sens::Scalar;

use crate::beam::{BeamSection, beam_frame, beam_local, release_shear, to_global};
use crate::error::FemError;
use crate::mesh::{Element, Mesh, NodeId};
use crate::sensitivity::ProjectedDerivative;
use crate::shell::{
    DEFAULT_DRILLING, Membrane, TriGeometry, shell_lumped, shell_mass_local, shell_stiffness_local,
};

/// Section and laminate properties referenced by the elements, generic over the scalar so that
/// ply angles can be seeded as dual numbers.
#[derive(Clone, Debug, PartialEq)]
pub struct Properties<S: Scalar> {
    /// Beam sections (indexed by [`Element::Beam`]'s `property`).
    pub sections: Vec<BeamSection<S>>,
    /// Laminates (indexed by [`Element::Shell`]'s `property`).
    pub laminates: Vec<LaminateStiffness<S>>,
}

impl<S: Scalar> Properties<S> {
    /// The same properties converted to another scalar.
    pub fn map<Q: Scalar>(&self, f: &impl Fn(S) -> Q) -> Properties<Q> {
        Properties {
            sections: self.sections.iter().map(|s| s.map(f)).collect(),
            laminates: self.laminates.iter().map(|l| l.map(f)).collect(),
        }
    }

    /// Whether element `el`'s property carries a tangent (a missing property does not).
    pub fn moves(&self, el: &Element) -> bool {
        let moving = |x: &S| x.tangents().iter().any(|&t| t != 0.0);
        match *el {
            Element::Beam { property, .. } => self.sections.get(property).is_some_and(|s| {
                (s.stiffness.iter().chain([&s.mass_per_length]))
                    .chain(&s.mass_centre)
                    .chain(&s.inertia)
                    .any(moving)
            }),
            Element::Shell { property, .. } => self.laminates.get(property).is_some_and(|l| {
                (l.a.iter().chain(&l.b).chain(&l.d).chain(&l.shear))
                    .chain([
                        &l.mass_per_area,
                        &l.first_moment,
                        &l.rotary_inertia,
                        &l.thickness,
                    ])
                    .any(moving)
            }),
        }
    }

    /// The laminate `property` of shell element `e` (an error naming both when it is missing).
    pub fn laminate(&self, e: usize, property: usize) -> Result<&LaminateStiffness<S>, FemError> {
        self.laminates
            .get(property)
            .ok_or(FemError::MissingProperty {
                element: e,
                kind: "laminate",
                property,
                available: self.laminates.len(),
            })
    }
}

impl<S: Scalar> Default for Properties<S> {
    fn default() -> Self {
        Self {
            sections: Vec::new(),
            laminates: Vec::new(),
        }
    }
}

/// Consistent or lumped (diagonal) mass matrix.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum MassKind {
    #[default]
    Consistent,
    /// Diagonal: per node `[m, m, m, μ_x, μ_y, μ_z]` ([`lumped_nodal_masses`]).
    Lumped,
}

/// Element options.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ElementOptions {
    /// Drilling penalty factor of the shell triangle (× A₆₆ × area).
    pub drilling: f64,
    /// Membrane formulation of the shell triangle.
    pub membrane: Membrane,
    /// Planar analysis about this global axis (set by [`crate::modal_analysis`] from
    /// [`crate::ModalOptions::planar`]): beam elements release the transverse shear strain out
    /// of the plane ([`crate::beam::release_shear`]), so that fixing the out-of-plane dof at the
    /// nodes does not suppress a section's shear–bending coupling.
    pub planar_axis: Option<usize>,
}

impl Default for ElementOptions {
    fn default() -> Self {
        Self {
            drilling: DEFAULT_DRILLING,
            membrane: Membrane::default(),
            planar_axis: None,
        }
    }
}

/// Local dof index within a node.
pub mod dof {
    pub const UX: usize = 0;
    pub const UY: usize = 1;
    pub const UZ: usize = 2;
    pub const RX: usize = 3;
    pub const RY: usize = 4;
    pub const RZ: usize = 5;
    pub const TRANSLATIONS: [usize; 3] = [UX, UY, UZ];
    pub const ROTATIONS: [usize; 3] = [RX, RY, RZ];
    pub const ALL: [usize; 6] = [UX, UY, UZ, RX, RY, RZ];
}

/// A rigid tie of a node set to a point (an RBE2 element): the nodes move as one rigid body
/// with the point, `u_k = u + θ × (x_k − p)`, `θ_k = θ`.
#[derive(Clone, Debug, PartialEq)]
pub struct RigidTie {
    pub nodes: Vec<NodeId>,
    pub point: Vector3<f64>,
}

/// The dof a body's matrices act on: fixed (zero) dof eliminated, and the dof of rigidly tied
/// node sets replaced by the rigid motion of each set.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Constraints {
    fixed: BTreeSet<usize>,
    ties: Vec<RigidTie>,
}

impl Constraints {
    /// No constraints.
    pub fn new() -> Self {
        Self::default()
    }
    /// Fix dof `d` (0..6, see [`dof`]) of `node`.
    pub fn fix(&mut self, node: NodeId, d: usize) -> &mut Self {
        assert!(d < 6, "dof index {d} out of range");
        self.fixed.insert(6 * node + d);
        self
    }
    /// Fix the listed dof of every listed node.
    pub fn fix_nodes(&mut self, nodes: &[NodeId], dofs: &[usize]) -> &mut Self {
        for &n in nodes {
            for &d in dofs {
                self.fix(n, d);
            }
        }
        self
    }
    /// Clamp a node (all six dof).
    pub fn clamp(&mut self, node: NodeId) -> &mut Self {
        self.fix_nodes(&[node], &dof::ALL)
    }
    /// Simply supported (pinned) line of a plate along global `axis` (a unit vector in the
    /// plate plane, one of x or y): transverse displacement `u_z` and the rotation about the
    /// in-plane normal to the line fixed (the "hard" support of Mindlin plates); the rotation
    /// about the line stays free. `in_plane`: also fix the in-plane displacements listed.
    pub fn pinned_line(
        &mut self,
        nodes: &[NodeId],
        along_x: bool,
        in_plane: &[usize],
    ) -> &mut Self {
        // a line along x hinges about x: θ_x free, θ_y (rotation about the normal to the line) fixed
        let rot = if along_x { dof::RY } else { dof::RX };
        self.fix_nodes(nodes, &[dof::UZ, rot]);
        self.fix_nodes(nodes, in_plane)
    }
    /// Tie `nodes` rigidly to `point` ([`RigidTie`]). A dof of a tied node that is also fixed
    /// constrains the rigid motion of the whole set (a tied straight edge with `u_z` fixed
    /// at its nodes can still turn about its line, for example).
    pub fn tie(&mut self, nodes: &[NodeId], point: Vector3<f64>) -> &mut Self {
        self.ties.push(RigidTie {
            nodes: nodes.to_vec(),
            point,
        });
        self
    }
    /// Whether a global dof is fixed.
    pub fn is_fixed(&self, global_dof: usize) -> bool {
        self.fixed.contains(&global_dof)
    }
    /// The fixed global dof, ascending.
    pub fn fixed(&self) -> impl Iterator<Item = usize> + '_ {
        self.fixed.iter().copied()
    }
    /// The rigid ties, in the order given.
    pub fn ties(&self) -> &[RigidTie] {
        &self.ties
    }
}

/// What a dof of an [`Assembly`]'s matrices is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReducedDof {
    /// A free dof of a node (its global dof `6 k + d`).
    Node(usize),
    /// Coordinate `coordinate` of the rigid motion of tie `tie` ([`Constraints::ties`]);
    /// `node` is the tie's lowest-numbered node (where a factorisation orders it).
    Tie {
        tie: usize,
        coordinate: usize,
        node: NodeId,
    },
}

impl ReducedDof {
    /// The node the dof belongs to (a tie's lowest-numbered node).
    pub fn node(&self) -> NodeId {
        match *self {
            ReducedDof::Node(g) => g / 6,
            ReducedDof::Tie { node, .. } => node,
        }
    }
}

/// The rigid-motion operator of tie node `x` about `point`: `[u_k; θ_k] = R [u; θ]`.
fn rigid_transfer(x: &Vector3<f64>, point: &Vector3<f64>) -> Matrix6<f64> {
    let r = x - point;
    let mut m = Matrix6::identity();
    // u_k = u + θ × r = u − r × θ
    let skew = Matrix3::new(0.0, r.z, -r.y, -r.z, 0.0, r.x, r.y, -r.x, 0.0);
    m.fixed_view_mut::<3, 3>(0, 3).copy_from(&skew);
    m
}

/// The rigid motions a tie leaves free (`6 × k`, orthonormal columns in scaled coordinates
/// `[u; L θ]`, `L` the set's size, divided back to `[u; θ]`): the null space of the tied nodes'
/// fixed dof.
fn tie_motions(
    mesh: &Mesh,
    tie: &RigidTie,
    constraints: &Constraints,
) -> Result<DMatrix<f64>, FemError> {
    let size = tie
        .nodes
        .iter()
        .map(|&k| (mesh.nodes[k] - tie.point).norm())
        .fold(0.0f64, f64::max);
    let l = if size > 0.0 { size } else { 1.0 };
    let scale = Matrix6::from_diagonal(&nalgebra::Vector6::new(
        1.0,
        1.0,
        1.0,
        1.0 / l,
        1.0 / l,
        1.0 / l,
    ));
    let mut rows: Vec<f64> = Vec::new();
    for &k in &tie.nodes {
        let r = rigid_transfer(&mesh.nodes[k], &tie.point) * scale;
        for d in 0..6 {
            if constraints.is_fixed(6 * k + d) {
                rows.extend(r.row(d).iter());
            }
        }
    }
    if rows.is_empty() {
        return Ok(DMatrix::from_iterator(6, 6, scale.iter().copied()));
    }
    // null space from the eigenvectors of CᵀC with (relatively) zero eigenvalues
    let c = DMatrix::from_row_slice(rows.len() / 6, 6, &rows);
    let ctc = c.transpose() * &c;
    let eig = ctc.symmetric_eigen();
    let top = eig.eigenvalues.amax().max(f64::MIN_POSITIVE);
    let free: Vec<usize> = (0..6)
        .filter(|&i| eig.eigenvalues[i] <= 1e-12 * top)
        .collect();
    let n = eig.eigenvectors.select_columns(&free);
    let s = DMatrix::from_iterator(6, 6, scale.iter().copied());
    Ok(s * n)
}

/// Global dof indices of an element's nodes.
fn element_dofs(el: &Element) -> Vec<usize> {
    el.nodes()
        .iter()
        .flat_map(|&n| (0..6).map(move |d| 6 * n + d))
        .collect()
}

/// The section beam element `e` (of section `property`, frame `lam`) is formed with: its
/// property's, with the out-of-plane shear released in a planar analysis about `planar_axis`
/// ([`crate::beam::release_shear`]).
pub fn beam_element_section<'a, S: Scalar>(
    props: &'a Properties<S>,
    (e, property): (usize, usize),
    lam: &nalgebra::Matrix3<f64>,
    planar_axis: Option<usize>,
) -> Result<std::borrow::Cow<'a, BeamSection<S>>, FemError> {
    let sec = props
        .sections
        .get(property)
        .ok_or(FemError::MissingProperty {
            element: e,
            kind: "beam section",
            property,
            available: props.sections.len(),
        })?;
    Ok(match planar_axis {
        Some(axis) => std::borrow::Cow::Owned(release_shear(sec, lam, axis, e)?),
        None => std::borrow::Cow::Borrowed(sec),
    })
}

/// Element stiffness and mass in global axes, as dense row-major `nd × nd` (nd = 12 or 18).
pub fn element_matrices<S: Scalar>(
    mesh: &Mesh,
    e: usize,
    props: &Properties<S>,
    opts: &ElementOptions,
    mass: MassKind,
) -> Result<(DMatrix<S>, DMatrix<S>), FemError> {
    let el = &mesh.elements[e];
    match *el {
        Element::Beam {
            nodes,
            property,
            orientation,
        } => {
            let (l, lam) = beam_frame(&mesh.nodes[nodes[0]], &mesh.nodes[nodes[1]], &orientation);
            let sec = &*beam_element_section(props, (e, property), &lam, opts.planar_axis)?;
            let loc = beam_local(sec, l, e)?;
            let k = to_global(&loc.stiffness, &lam);
            let m = match mass {
                MassKind::Consistent => {
                    DMatrix::from_iterator(12, 12, to_global(&loc.mass, &lam).iter().copied())
                }
                MassKind::Lumped => lumped_matrix(2, beam_lumped(sec, l, &lam)),
            };
            Ok((DMatrix::from_iterator(12, 12, k.iter().copied()), m))
        }
        Element::Shell {
            nodes,
            property,
            material_axis,
        } => {
            let lam = props.laminate(e, property)?;
            let p = nodes.map(|n| mesh.nodes[n]);
            let g = TriGeometry::new(p, &material_axis, e)?;
            let k = linear_in_laminate(lam, |l| {
                to_global(
                    &shell_stiffness_local(&g, l, opts.drilling, opts.membrane),
                    &g.frame,
                )
            });
            let m = match mass {
                MassKind::Consistent => DMatrix::from_iterator(
                    18,
                    18,
                    linear_in_laminate(lam, |l| {
                        to_global(&shell_mass_local(&g, l, opts.drilling), &g.frame)
                    })
                    .iter()
                    .copied(),
                ),
                MassKind::Lumped => lumped_matrix(3, shell_lumped(&g, lam, opts.drilling)),
            };
            Ok((DMatrix::from_iterator(18, 18, k.iter().copied()), m))
        }
    }
}

/// `f(lam)` for a laminate in any scalar, where `f` (a shell element's stiffness or mass
/// matrix) is linear in the laminate's matrices and inertias: the value and each tangent are
/// `f` of the laminate's values and of its tangents, evaluated in `f64` (with dual numbers
/// `f` would multiply 18 × 18 matrices of duals, nine times the work for eight tangents).
///
/// # Panics
/// If the laminate is on the reverse-mode tape ([`sens::Rev`]) other than as constants.
fn linear_in_laminate<S: Scalar, const R: usize>(
    lam: &LaminateStiffness<S>,
    f: impl Fn(&LaminateStiffness<f64>) -> nalgebra::SMatrix<f64, R, R>,
) -> nalgebra::SMatrix<S, R, R> {
    let value = f(&lam.values());
    if S::PLAIN {
        return value.map(S::from_f64);
    }
    if S::TANGENTS == 0 {
        // the reverse-mode tape, where the set-up's data are rebuilt from the modes with the
        // element properties held (the chunks' dual bodies carry the properties' tangents)
        let constant = std::cell::Cell::new(true);
        let _ = lam.map(&|x: S| {
            constant.set(constant.get() && x.is_constant());
            0.0
        });
        assert!(
            constant.get(),
            "a shell element's matrices of a laminate on the reverse-mode tape are not supported"
        );
        return value.map(S::from_f64);
    }
    let tangents: Vec<_> = (0..S::TANGENTS).map(|k| f(&lam.tangent(k))).collect();
    let mut buf = Vec::with_capacity(S::TANGENTS);
    nalgebra::SMatrix::from_fn(|i, j| {
        buf.clear();
        buf.extend(tangents.iter().map(|t| t[(i, j)]));
        S::from_parts(value[(i, j)], &buf)
    })
}

/// Lumped share of a beam element at each node: `(mL/2, diag(Λᵀ J_ref Λ) L/2)`.
fn beam_lumped<S: Scalar>(
    sec: &BeamSection<S>,
    l: f64,
    lam: &nalgebra::Matrix3<f64>,
) -> (S, [S; 3]) {
    let half = S::from_f64(0.5 * l);
    let j = sec.rotary_inertia();
    let lm = lam.map(S::from_f64);
    let jg = lm.transpose() * j * lm;
    (
        sec.mass_per_length * half,
        [jg[(0, 0)] * half, jg[(1, 1)] * half, jg[(2, 2)] * half],
    )
}

/// Lumped nodal masses `m_k` and rotary inertias `μ_k` (diagonal, global axes) of the whole
/// mesh: the diagonal of the [`MassKind::Lumped`] mass matrix (Eq. 2).
pub fn lumped_nodal_masses<S: Scalar>(
    mesh: &Mesh,
    props: &Properties<S>,
    opts: &ElementOptions,
) -> Result<(Vec<S>, Vec<[S; 3]>), FemError> {
    let n = mesh.nodes.len();
    let mut m = vec![S::zero(); n];
    let mut mu = vec![[S::zero(); 3]; n];
    for e in 0..mesh.elements.len() {
        let (me, mue) = element_lumped_mass(mesh, e, props, opts)?;
        for &node in mesh.elements[e].nodes() {
            m[node] += me;
            for d in 0..3 {
                mu[node][d] += mue[d];
            }
        }
    }
    Ok((m, mu))
}

/// Each node's share of element `e`'s lumped mass and rotary inertias (diagonal, global
/// axes): the diagonal of its [`MassKind::Lumped`] mass matrix ([`element_matrices`]),
/// without its stiffness.
fn element_lumped_mass<S: Scalar>(
    mesh: &Mesh,
    e: usize,
    props: &Properties<S>,
    opts: &ElementOptions,
) -> Result<(S, [S; 3]), FemError> {
    match mesh.elements[e] {
        Element::Beam {
            nodes,
            property,
            orientation,
        } => {
            let (l, lam) = beam_frame(&mesh.nodes[nodes[0]], &mesh.nodes[nodes[1]], &orientation);
            let sec = &*beam_element_section(props, (e, property), &lam, opts.planar_axis)?;
            Ok(beam_lumped(sec, l, &lam))
        }
        Element::Shell {
            nodes,
            property,
            material_axis,
        } => {
            let lam = props.laminate(e, property)?;
            let g = TriGeometry::new(nodes.map(|n| mesh.nodes[n]), &material_axis, e)?;
            Ok(shell_lumped(&g, lam, opts.drilling))
        }
    }
}

/// The lumped mass matrix of an element of `nodes` nodes (six dof each) whose nodes each
/// carry the mass `mk` and the rotary inertias `mu`.
fn lumped_matrix<S: Scalar>(nodes: usize, (mk, mu): (S, [S; 3])) -> DMatrix<S> {
    let mut m = DMatrix::zeros(6 * nodes, 6 * nodes);
    for n in 0..nodes {
        for d in 0..3 {
            m[(6 * n + d, 6 * n + d)] = mk;
            m[(6 * n + 3 + d, 6 * n + 3 + d)] = mu[d];
        }
    }
    m
}

/// The rigid tie of every node (`None`: untied) and each tie's free rigid motions
/// ([`tie_motions`]).
type TieMembership = (Vec<Option<usize>>, Vec<DMatrix<f64>>);

/// [`TieMembership`] of the constraints' ties; an error for a tie without nodes, with a node
/// that does not exist or that another tie holds, or with a point that is not finite.
fn tie_membership(mesh: &Mesh, constraints: &Constraints) -> Result<TieMembership, FemError> {
    let n_nodes = mesh.nodes.len();
    let mut tie_of = vec![None; n_nodes];
    let mut motions = Vec::new();
    for (t, tie) in constraints.ties().iter().enumerate() {
        if tie.nodes.is_empty() {
            return Err(FemError::RigidTie(format!("rigid tie {t} has no node")));
        }
        if !tie.point.iter().all(|x| x.is_finite()) {
            return Err(FemError::RigidTie(format!(
                "rigid tie {t}: its point {:?} must be finite",
                tie.point
            )));
        }
        for &k in &tie.nodes {
            match tie_of.get(k) {
                None => {
                    return Err(FemError::RigidTie(format!(
                        "rigid tie {t}: node {k} does not exist (the mesh has {n_nodes} nodes)"
                    )));
                }
                Some(Some(other)) => {
                    return Err(FemError::RigidTie(format!(
                        "node {k} is in rigid ties {other} and {t} (a node can follow one rigid \
                         tie only; merge the two sets)"
                    )));
                }
                Some(None) => tie_of[k] = Some(t),
            }
        }
        motions.push(tie_motions(mesh, tie, constraints)?);
    }
    Ok((tie_of, motions))
}

/// `T` by rows (CSR: `map_ptr`, `map` of `(dof, coefficient)` terms per global dof) and what
/// each of the matrices' dof is: node by node, the free dof of an untied node, a tie's
/// coordinates at its first node.
fn dof_map(
    mesh: &Mesh,
    constraints: &Constraints,
    tie_of: &[Option<usize>],
    motions: &[DMatrix<f64>],
) -> (Vec<usize>, Vec<(usize, f64)>, Vec<ReducedDof>) {
    let n_nodes = mesh.nodes.len();
    let mut dofs = Vec::new();
    let mut tie_start = vec![usize::MAX; motions.len()];
    let mut map_ptr = Vec::with_capacity(6 * n_nodes + 1);
    let mut map = Vec::new();
    map_ptr.push(0);
    for k in 0..n_nodes {
        let Some(t) = tie_of[k] else {
            for g in 6 * k..6 * k + 6 {
                if !constraints.is_fixed(g) {
                    map.push((dofs.len(), 1.0));
                    dofs.push(ReducedDof::Node(g));
                }
                map_ptr.push(map.len());
            }
            continue;
        };
        if tie_start[t] == usize::MAX {
            tie_start[t] = dofs.len();
            dofs.extend((0..motions[t].ncols()).map(|coordinate| ReducedDof::Tie {
                tie: t,
                coordinate,
                node: k,
            }));
        }
        let r = rigid_transfer(&mesh.nodes[k], &constraints.ties()[t].point) * &motions[t];
        for d in 0..6 {
            if !constraints.is_fixed(6 * k + d) {
                map.extend(
                    (0..r.ncols())
                        .map(|j| (tie_start[t] + j, r[(d, j)]))
                        .filter(|&(_, c)| c != 0.0),
                );
            }
            map_ptr.push(map.len());
        }
    }
    (map_ptr, map, dofs)
}

/// The CSC pattern (`col_ptr`, `row_idx`) of `n` dof that the elements of `mesh` couple through
/// the terms of their global dof; every diagonal entry included.
fn pattern<'a>(
    mesh: &Mesh,
    n: usize,
    terms: &dyn Fn(usize) -> &'a [(usize, f64)],
) -> (Vec<usize>, Vec<usize>) {
    let mut cols: Vec<Vec<usize>> = (0..n).map(|j| vec![j]).collect();
    for el in &mesh.elements {
        let mut touched: Vec<usize> = element_dofs(el)
            .iter()
            .flat_map(|&g| terms(g).iter().map(|&(i, _)| i))
            .collect();
        touched.sort_unstable();
        touched.dedup();
        for &c in &touched {
            cols[c].extend_from_slice(&touched);
        }
    }
    let mut col_ptr = Vec::with_capacity(n + 1);
    let mut row_idx = Vec::new();
    col_ptr.push(0);
    for c in cols.iter_mut() {
        c.sort_unstable();
        c.dedup();
        row_idx.extend_from_slice(c);
        col_ptr.push(row_idx.len());
    }
    (col_ptr, row_idx)
}

/// Where the entries of an element with global dof `ed` go ([`ElementSlots`]): direct slots
/// when none of its nodes is tied (a free dof has one term of coefficient 1, a fixed one none),
/// the products of the terms otherwise.
fn element_slots<'a>(
    ed: &[usize],
    tie_of: &[Option<usize>],
    terms: &dyn Fn(usize) -> &'a [(usize, f64)],
    slot: &dyn Fn(usize, usize) -> usize,
) -> ElementSlots {
    let nd = ed.len();
    if ed.iter().all(|&g| tie_of[g / 6].is_none()) {
        let idx: Vec<Option<usize>> = ed.iter().map(|&g| terms(g).first().map(|t| t.0)).collect();
        let mut s = Vec::with_capacity(nd * nd);
        for &r in &idx {
            for &c in &idx {
                s.push(match (r, c) {
                    (Some(r), Some(c)) => slot(r, c),
                    _ => usize::MAX,
                });
            }
        }
        return ElementSlots::Direct(s);
    }
    let mut s = Vec::new();
    for (a, &ga) in ed.iter().enumerate() {
        for (b, &gb) in ed.iter().enumerate() {
            for &(r, cr) in terms(ga) {
                for &(c, cc) in terms(gb) {
                    s.push((a * nd + b, slot(r, c), cr * cc));
                }
            }
        }
    }
    ElementSlots::Mapped(s)
}

/// Where an element's `(a, b)` entry goes in the CSC values.
#[derive(Clone, Debug)]
enum ElementSlots {
    /// Every dof of the element is a free node dof or fixed: the slot of each pair (row-major),
    /// `usize::MAX` when one of the two is fixed.
    Direct(Vec<usize>),
    /// Some dof of the element are tied: `(pair, slot, coefficient)` terms.
    Mapped(Vec<(usize, usize, f64)>),
}

/// The fixed sparsity pattern of the matrices of a mesh under given constraints, on the dof
/// they leave ([`ReducedDof`]): `K = TᵀK_full T`, `M = TᵀM_full T` with `u_full = T u`.
#[derive(Clone, Debug)]
pub struct Assembly {
    n_full: usize,
    /// `T` by rows: the terms `(dof, coefficient)` of every global dof (CSR).
    map_ptr: Vec<usize>,
    map: Vec<(usize, f64)>,
    dofs: Vec<ReducedDof>,
    symbolic: SymbolicSparseColMat<usize>,
    slots: Vec<ElementSlots>,
}

impl Assembly {
    /// Pattern of the dof of `mesh` left by `constraints` (fixed dof eliminated, tied sets
    /// replaced by their rigid motions).
    pub fn new(mesh: &Mesh, constraints: &Constraints) -> Result<Self, FemError> {
        mesh.validate()?;
        let n_full = mesh.n_dofs();
        if let Some(d) = constraints.fixed().find(|&d| d >= n_full) {
            return Err(FemError::BadDof {
                dof: d,
                n_dofs: n_full,
            });
        }
        let (tie_of, motions) = tie_membership(mesh, constraints)?;
        let (map_ptr, map, dofs) = dof_map(mesh, constraints, &tie_of, &motions);
        let n = dofs.len();
        if n == 0 {
            return Err(FemError::NoFreeDof);
        }
        let terms = |g: usize| &map[map_ptr[g]..map_ptr[g + 1]];
        let (col_ptr, row_idx) = pattern(mesh, n, &terms);
        let slot = |r: usize, c: usize| {
            col_ptr[c]
                + row_idx[col_ptr[c]..col_ptr[c + 1]]
                    .binary_search(&r)
                    .expect("in pattern")
        };
        let slots = mesh
            .elements
            .iter()
            .map(|el| element_slots(&element_dofs(el), &tie_of, &terms, &slot))
            .collect();
        let symbolic = SymbolicSparseColMat::new_checked(n, n, col_ptr, None, row_idx);
        Ok(Self {
            n_full,
            map_ptr,
            map,
            dofs,
            symbolic,
            slots,
        })
    }

    /// Number of dof of the matrices.
    pub fn n_free(&self) -> usize {
        self.dofs.len()
    }
    /// Number of dof before elimination (6 × nodes).
    pub fn n_full(&self) -> usize {
        self.n_full
    }
    /// What each dof of the matrices is.
    pub fn dofs(&self) -> &[ReducedDof] {
        &self.dofs
    }
    /// The node of each dof: the groups by which a sparse factorisation orders the matrices of
    /// this assembly ([`sens::sparse::grouped_ordering`]).
    pub fn free_dof_nodes(&self) -> Vec<usize> {
        self.dofs.iter().map(ReducedDof::node).collect()
    }
    /// The terms `(dof, coefficient)` of global dof `g` in the dof of the matrices (one term
    /// of coefficient 1 for a free node dof, none for a fixed one, the set's rigid motion for
    /// a tied one).
    pub fn terms(&self, global_dof: usize) -> &[(usize, f64)] {
        &self.map[self.map_ptr[global_dof]..self.map_ptr[global_dof + 1]]
    }
    /// The sparsity pattern.
    pub fn symbolic(&self) -> &SymbolicSparseColMat<usize> {
        &self.symbolic
    }
    /// Number of stored entries.
    pub fn nnz(&self) -> usize {
        self.symbolic.row_idx().len()
    }

    /// Stiffness and mass values (CSC order of [`Self::symbolic`]) for the given properties.
    pub fn values<S: Scalar>(
        &self,
        mesh: &Mesh,
        props: &Properties<S>,
        opts: &ElementOptions,
        mass: MassKind,
    ) -> Result<(Vec<S>, Vec<S>), FemError> {
        self.sum_elements(mesh, props, opts, mass, |_| true)
    }

    /// The tangents of [`Self::values`] (the values of its result are the sums of those
    /// elements alone): the elements whose properties carry no tangent, which would add zeros
    /// to them, are left out — a design variable moves one segment's or region's elements,
    /// and each element's matrices in dual numbers cost as many products as its tangents.
    pub fn tangent_values<S: Scalar>(
        &self,
        mesh: &Mesh,
        props: &Properties<S>,
        opts: &ElementOptions,
        mass: MassKind,
    ) -> Result<(Vec<S>, Vec<S>), FemError> {
        self.sum_elements(mesh, props, opts, mass, |el| props.moves(el))
    }

    /// The assembled `K` and `M` entries of the elements `include` takes.
    fn sum_elements<S: Scalar>(
        &self,
        mesh: &Mesh,
        props: &Properties<S>,
        opts: &ElementOptions,
        mass: MassKind,
        include: impl Fn(&Element) -> bool,
    ) -> Result<(Vec<S>, Vec<S>), FemError> {
        let nnz = self.nnz();
        let mut k = vec![S::zero(); nnz];
        let mut m = vec![S::zero(); nnz];
        for e in 0..mesh.elements.len() {
            if !include(&mesh.elements[e]) {
                continue;
            }
            let (ke, me) = element_matrices(mesh, e, props, opts, mass)?;
            let nd = ke.nrows();
            match &self.slots[e] {
                ElementSlots::Direct(slots) => {
                    for a in 0..nd {
                        for b in 0..nd {
                            let s = slots[a * nd + b];
                            if s != usize::MAX {
                                k[s] += ke[(a, b)];
                                m[s] += me[(a, b)];
                            }
                        }
                    }
                }
                ElementSlots::Mapped(terms) => {
                    for &(pair, s, c) in terms {
                        let (a, b) = (pair / nd, pair % nd);
                        k[s] += ke[(a, b)] * c;
                        m[s] += me[(a, b)] * c;
                    }
                }
            }
        }
        Ok((k, m))
    }

    /// `Xᵀ K_t X` and `Xᵀ M_t X` for each tangent `t` of the properties (`S::TANGENTS` of them),
    /// `x` holding vectors on the free dof as columns, within the diagonal `blocks` of mode
    /// indices (zero elsewhere; the eigenvalue derivatives need the blocks of the clusters of
    /// repeated eigenvalues, [`crate::sensitivity::clusters`]; one block of all the columns gives
    /// the whole product): the derivative matrices projected element by element, never
    /// assembled.
    ///
    /// Per element, `K_t X_e` for every tangent in one pass over the element matrices, then
    /// only the blocks' dot products: with 20 modes, mostly single, that is half the work of
    /// the whole `X_eᵀ K_t X_e`.
    pub fn projected_tangents<S: Scalar>(
        &self,
        mesh: &Mesh,
        props: &Properties<S>,
        opts: &ElementOptions,
        mass: MassKind,
        x: &DMatrix<f64>,
        blocks: &[Vec<usize>],
    ) -> Result<Vec<ProjectedDerivative>, FemError> {
        let p = x.ncols();
        let nt = S::TANGENTS;
        let zero = ProjectedDerivative {
            k: DMatrix::zeros(p, p),
            m: DMatrix::zeros(p, p),
        };
        let mut out = vec![zero; nt];
        // per element: X_eᵀ (p × nd, so that a dof's row of X_e is a contiguous column) and
        // (K_t X_e)ᵀ, (M_t X_e)ᵀ for every tangent t
        let (mut xet, mut kx, mut mx) = (Vec::new(), Vec::new(), Vec::new());
        for (e, el) in mesh.elements.iter().enumerate() {
            let (ke, me) = element_matrices(mesh, e, props, opts, mass)?;
            let dofs = element_dofs(el);
            let nd = dofs.len();
            // X_e = T_e X
            xet.clear();
            xet.resize(nd * p, 0.0);
            for (a, &g) in dofs.iter().enumerate() {
                for &(f, c) in self.terms(g) {
                    for j in 0..p {
                        xet[a * p + j] += c * x[(f, j)];
                    }
                }
            }
            kx.clear();
            kx.resize(nt * nd * p, 0.0);
            mx.clear();
            mx.resize(nt * nd * p, 0.0);
            for a in 0..nd {
                for b in 0..nd {
                    let (kab, mab) = (ke[(a, b)], me[(a, b)]);
                    let xb = &xet[b * p..(b + 1) * p];
                    for t in 0..nt {
                        let (kt, mt) = (kab.tangent(t), mab.tangent(t));
                        let at = (t * nd + a) * p;
                        if kt != 0.0 {
                            for (y, xv) in kx[at..at + p].iter_mut().zip(xb) {
                                *y += kt * xv;
                            }
                        }
                        if mt != 0.0 {
                            for (y, xv) in mx[at..at + p].iter_mut().zip(xb) {
                                *y += mt * xv;
                            }
                        }
                    }
                }
            }
            for (t, pd) in out.iter_mut().enumerate() {
                for g in blocks {
                    for &i in g {
                        for &j in g {
                            let (mut k, mut m) = (0.0, 0.0);
                            for a in 0..nd {
                                let xi = xet[a * p + i];
                                k += xi * kx[(t * nd + a) * p + j];
                                m += xi * mx[(t * nd + a) * p + j];
                            }
                            pd.k[(i, j)] += k;
                            pd.m[(i, j)] += m;
                        }
                    }
                }
            }
        }
        Ok(out)
    }

    /// A sparse matrix on the pattern from values.
    pub fn matrix(&self, values: Vec<f64>) -> SparseColMat<usize, f64> {
        SparseColMat::new(self.symbolic.clone(), values)
    }

    /// Tangent `k` of dual values as a sparse matrix on the pattern.
    pub fn tangent_matrix<S: Scalar>(&self, values: &[S], k: usize) -> SparseColMat<usize, f64> {
        self.matrix(values.iter().map(|x| x.tangent(k)).collect())
    }

    /// Expand a vector on the dof of the matrices to all dof, `T x` (zeros at fixed dof, the
    /// rigid motion of tied sets).
    pub fn expand(&self, x: &[f64]) -> Vec<f64> {
        (0..self.n_full)
            .map(|g| self.terms(g).iter().map(|&(i, c)| c * x[i]).sum())
            .collect()
    }

    /// The transpose of [`Self::expand_columns`]: `Tᵀ x` of columns on all dof, to the dof of
    /// the matrices (the adjoint of an expansion).
    pub fn restrict_columns(&self, x: &DMatrix<f64>) -> DMatrix<f64> {
        let mut out = DMatrix::zeros(self.n_free(), x.ncols());
        for g in 0..self.n_full {
            for &(i, c) in self.terms(g) {
                for j in 0..x.ncols() {
                    out[(i, j)] += c * x[(g, j)];
                }
            }
        }
        out
    }

    /// [`Self::expand`] column by column.
    pub fn expand_columns(&self, x: &DMatrix<f64>) -> DMatrix<f64> {
        let mut out = DMatrix::zeros(self.n_full, x.ncols());
        for g in 0..self.n_full {
            for &(i, c) in self.terms(g) {
                for j in 0..x.ncols() {
                    out[(g, j)] += c * x[(i, j)];
                }
            }
        }
        out
    }

    /// A load on all dof carried to the dof of the matrices, `Tᵀ f` (the work-equivalent load:
    /// a fixed dof takes nothing, a tied set the resultant and moment of its loads).
    pub fn restrict(&self, f: &[f64]) -> DVector<f64> {
        let mut out = DVector::zeros(self.n_free());
        for (g, &fg) in f.iter().enumerate().take(self.n_full) {
            if fg != 0.0 {
                for &(i, c) in self.terms(g) {
                    out[i] += c * fg;
                }
            }
        }
        out
    }

    /// The load of a unit value at global dof `g` ([`Self::restrict`]); `None` when the dof
    /// is fixed (or a tie's fixed motion).
    pub fn unit_load(&self, global_dof: usize) -> Option<DVector<f64>> {
        let terms = self.terms(global_dof);
        if terms.is_empty() {
            return None;
        }
        let mut out = DVector::zeros(self.n_free());
        for &(i, c) in terms {
            out[i] += c;
        }
        Some(out)
    }
}
