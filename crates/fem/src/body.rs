//! Modal analysis of one flexible body: reference conditions (paper §2.3), Rayleigh damping,
//! design derivatives through dual numbers, and the [`ModalBody`] handed to `mbs`.

use nalgebra::{DMatrix, Vector3};
use sens::{Dual, Scalar, seed_chunk};

use crate::assembly::{
    Assembly, Constraints, ElementOptions, MassKind, Properties, dof, lumped_nodal_masses,
};
use crate::correction::{
    Coupling, Distribution, StaticCorrection, distribution, interface_loads, static_correction,
};
use crate::eigen::{EigenOptions, Eigenpairs, lowest_modes_of_nodes};
use crate::error::FemError;
use crate::mesh::{Mesh, NodeId};
use crate::modal::ModalBody;
use crate::sensitivity::{
    DesignMatrices, ModeDerivatives, cluster_second_derivatives, eigenvalue_derivatives,
    has_repeated, mode_derivatives, splits_clusters,
};

/// How the body frame is attached for the modal analysis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ReferenceCondition {
    /// The paper's default: the node nearest the centre of mass is clamped (all six dof) and the
    /// body frame sits there, parallel to the mesh axes. On a Mindlin shell a point support is
    /// singular (the lowest frequencies fall with mesh refinement): use
    /// [`Self::ClampedSectionAtCentre`] there.
    ClampedAtCentreOfMass,
    /// Free-free: the six rigid-body modes are computed and discarded; the frame sits at the
    /// centre of mass.
    FreeFree,
    /// A clamped cross-section line (for shells; the paper's condition, a point support on a
    /// Mindlin shell, is singular): every node whose coordinate along the body's long axis
    /// equals that of the node nearest the centre of mass is clamped (all six dof). The long
    /// axis is the global axis of the largest extent of the mesh's bounding box (it must be
    /// unique); the line of nodes must pass through the centre of mass (e.g. an even element
    /// count along the length), otherwise the analysis fails with [`FemError::Reference`]. The
    /// body frame sits at the node nearest the centre of mass (on that line), parallel to the
    /// mesh axes. On a beam the line is a single node: the same as [`Self::ClampedAtCentreOfMass`].
    ClampedSectionAtCentre,
    /// Pinned ends: node `a` has its translations and the rotation about the a–b axis fixed,
    /// node `b` its translations normal to the a–b axis. The axis must be parallel to a global
    /// axis. The frame sits at node `a`.
    PinnedEnds { a: NodeId, b: NodeId },
    /// One node clamped (all six dof), the body frame there, parallel to the mesh axes: a
    /// cantilever's root (e.g. a blade on its hub).
    ClampedNode(NodeId),
    /// Only the [`ModalOptions::supports`] hold the body (edges, lines, symmetry planes, single
    /// dof); the body frame sits at the node nearest the centre of mass, parallel to the mesh
    /// axes. The supports must hold every rigid motion, else the analysis fails naming the
    /// motions they leave free ([`crate::free_rigid_motions`]).
    Supports,
    /// The [`ModalOptions::supports`] hold some rigid motions and leave the others free, as
    /// free-free leaves all six (a strip held only in its deflection along its end lines moves
    /// freely in its plane): the zero-frequency modes of the free motions are computed and
    /// discarded, so the elastic modes carry no momentum along them, and the body frame sits at
    /// the centre of mass, parallel to the mesh axes. Supports are needed (a body held by
    /// nothing is [`Self::FreeFree`]); supports that hold every rigid motion make it
    /// [`Self::Supports`] with the frame at the centre of mass.
    PartlyFree,
}

/// Dof fixed at a set of nodes: local dof indices `0..6` (`[u_x, u_y, u_z, θ_x, θ_y, θ_z]`,
/// global axes) at every node of `nodes`.
#[derive(Clone, Debug, PartialEq)]
pub struct Support {
    pub nodes: Vec<NodeId>,
    pub dofs: Vec<usize>,
}

/// Proportional damping `C = αM + βK` fitted to two modal damping ratios.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayleighDamping {
    /// Zero-based indices of the two (elastic, retained) modes.
    pub modes: [usize; 2],
    /// The damping ratios `ζ` at those modes.
    pub ratios: [f64; 2],
}

impl RayleighDamping {
    /// `(α, β)` from the two eigenvalues `λ = ω²`: `ζ = α/(2ω) + βω/2` at both modes.
    pub fn coefficients<S: Scalar>(&self, lambda_i: S, lambda_j: S) -> Result<(S, S), FemError> {
        let (wi, wj) = (lambda_i.sqrt(), lambda_j.sqrt());
        let den = lambda_j - lambda_i;
        if !(den.value().abs() > 1e-12 * lambda_j.value().abs()) || !(wi.value() > 0.0) {
            return Err(FemError::Damping(
                "Rayleigh damping needs two distinct, non-zero frequencies".into(),
            ));
        }
        let [zi, zj] = self.ratios;
        let alpha = wi * wj * (wj * zi - wi * zj) * 2.0 / den;
        let beta = (wj * zj - wi * zi) * 2.0 / den;
        Ok((alpha, beta))
    }
}

/// Proportional damping `C = αM + βK` of a body's elastic modes: modal damping
/// `2ζ_k ω_k = α + β λ_k`.
///
/// `β` (stiffness-proportional) damps strain rates and is the same whatever the body frame;
/// `α` (mass-proportional) damps the velocity of the elastic motion relative to the body frame,
/// which depends on the reference condition. For results that do not depend on the frame, use
/// [`Damping::Coefficients`] with `α = 0`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Damping {
    /// `α`, `β` fitted to damping ratios at two modes (the paper's way).
    Ratios(RayleighDamping),
    /// `α` (1/s) and `β` (s) given.
    Coefficients { alpha: f64, beta: f64 },
}

impl From<RayleighDamping> for Damping {
    fn from(d: RayleighDamping) -> Self {
        Damping::Ratios(d)
    }
}

impl Damping {
    /// `(α, β)` given the eigenvalues `lambdas` of the computed modes (a fit refers to their
    /// numbers).
    pub fn coefficients<S: Scalar>(&self, lambdas: &[S]) -> Result<(S, S), FemError> {
        match *self {
            Damping::Ratios(d) => {
                let [i, j] = d.modes;
                if i >= lambdas.len() || j >= lambdas.len() {
                    return Err(FemError::Damping(format!(
                        "Rayleigh damping refers to modes {} and {}, only {} computed",
                        i + 1,
                        j + 1,
                        lambdas.len()
                    )));
                }
                d.coefficients(lambdas[i], lambdas[j])
            }
            Damping::Coefficients { alpha, beta } => {
                if !(alpha.is_finite() && alpha >= 0.0 && beta.is_finite() && beta >= 0.0) {
                    return Err(FemError::Damping(format!(
                        "damping coefficients alpha = {alpha}, beta = {beta} must be finite and ≥ 0"
                    )));
                }
                Ok((S::from_f64(alpha), S::from_f64(beta)))
            }
        }
    }

    /// Modal damping `2ζ_k ω_k = α + β λ_k` of every mode.
    pub fn modal_damping<S: Scalar>(&self, lambdas: &[S]) -> Result<Vec<S>, FemError> {
        let (a, b) = self.coefficients(lambdas)?;
        Ok(lambdas.iter().map(|&l| a + b * l).collect())
    }
}

/// Damping of a body's static correction modes ([`ModalOptions::correction`]).
///
/// A correction mode is a static shape (the response to a load at an interface), not a
/// vibration mode of the body: its Ritz frequency lies above the retained eigenmodes', where
/// the truncated basis does not represent the body's dynamics, and left to the body's own
/// damping (none, or the light damping a Rayleigh fit gives there) it rings at that frequency
/// after every sudden change of its load. That ringing is an artefact of the basis, and,
/// lightly damped, it holds an adaptive BDF integrator to short steps and low orders (orders
/// 3–5 are unstable for lightly damped modes over a band of `ωh`). Damped more, a correction
/// mode follows its quasi-static response to its load, with a lag of `2ζ/μ^½` (5 µs at
/// `ζ = 0.1` and 6 kHz) that slightly smooths the local deformation it carries.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum CorrectionDamping {
    /// The body's proportional damping, as for its eigenmodes (undamped without one).
    #[default]
    Proportional,
    /// Damping ratios of at least `ζ` at the correction modes' Ritz frequencies `μ^½`: the
    /// body's proportional damping where it damps them more. The modal damping is
    /// `M # f(K)` over the basis (`f(M^-½ K M^-½)` pulled back by `M^½`), with
    /// `f(μ) = max(α + βμ, 2ζ μ^½)` at the correction modes and `α + βλ` at the eigenmodes: a
    /// function of the body's modal mass and stiffness, whatever the basis of a cluster of
    /// equal Ritz values. The deck's default is `ζ = 0.1`.
    AtLeast(f64),
}

impl CorrectionDamping {
    /// The least ratio, checked: finite and `≥ 0` (`None` for [`Self::Proportional`]).
    pub(crate) fn floor(self) -> Result<Option<f64>, FemError> {
        match self {
            Self::Proportional => Ok(None),
            Self::AtLeast(z) if z.is_finite() && z >= 0.0 => Ok(Some(z)),
            Self::AtLeast(z) => Err(FemError::Damping(format!(
                "the correction modes' damping ratio {z} must be finite and ≥ 0"
            ))),
        }
    }
}

/// Options of a body modal analysis.
#[derive(Clone, Debug, PartialEq)]
pub struct ModalOptions {
    pub reference: ReferenceCondition,
    /// Number of lowest (elastic) modes computed; all of them are retained unless `kept` says
    /// otherwise.
    pub n_modes: usize,
    /// Retain only these of the `n_modes` lowest modes (zero-based, strictly ascending), e.g.
    /// `[0, 1, 4]` to keep an axial mode without the bending modes between; the body's modes
    /// are then these, in this order. `None` (the default): all `n_modes`. Set with
    /// [`ModalOptions::select`]. Damping fitted to two modes ([`Damping::Ratios`]) refers to the
    /// computed modes' numbers.
    pub kept: Option<Vec<usize>>,
    pub damping: Option<Damping>,
    /// Consistent or lumped mass; `ModalBody` requires lumped (the paper's diagonalised mass).
    pub mass: MassKind,
    pub element: ElementOptions,
    pub eigen: EigenOptions,
    /// Restrict the analysis to motion in the plane with this (unit) normal `n`, in mesh (body
    /// frame) axes: at every node the translation along `n` and the two rotations about the
    /// in-plane axes are fixed; the in-plane translations and the rotation about `n` stay free.
    /// For beams in that plane this leaves exactly the planar bending and axial modes (no
    /// out-of-plane bending, no torsion). For shells it keeps the in-plane (membrane) motion
    /// when `n` is the shell normal; when `n` lies in the shell plane (e.g. `n = y` for a strip
    /// along x in the x–y plane) it leaves `u_x, u_z, θ_y`: cylindrical bending without twist or
    /// anticlastic curvature, i.e. the plate-strip (plane-strain in width) modes plus axial ones.
    /// The restriction reproduces modes of the unrestricted body only where in-plane and
    /// out-of-plane motion decouple (e.g. an isotropic beam, or a section symmetric about the
    /// plane); with couplings (bending–twist of off-axis laminates, extension–twist of a
    /// single-angle tube) it is a constraint that suppresses them and stiffens the body — e.g.
    /// the 15° composite plate rod with a line clamp: 342 Hz unrestricted, 422 Hz with `n = y`.
    /// Only normals along a global axis are supported (checked with a 1e-9 tolerance after
    /// normalisation); any other normal is rejected with [`FemError::Planar`]. Free-free bodies
    /// then have 3 rigid-body modes instead of 6. `None` (the default): full 3-D motion.
    pub planar: Option<Vector3<f64>>,
    /// Static correction: nodes (e.g. those the body's joints act at) whose static shapes are
    /// added to the retained modes; a number `n_nodes + c` stands for coupling `c` of
    /// [`Self::couplings`]. For every free dof of these nodes (the six loads of a coupling,
    /// spread over its nodes) the static displacement under a unit load, `ψ = K⁻¹ e`, is made
    /// mass-orthogonal to the retained modes and the span of those shapes is diagonalised
    /// (Ritz vectors): the body then has the retained eigenmodes followed by correction modes,
    /// still mass-normalised with a diagonal modal stiffness (their eigenvalues are Ritz
    /// values). A load at a correction node or coupling is then represented exactly by the
    /// reduced body, as are the deformations its joints impose (the field's static-correction,
    /// or attachment-mode, enrichment). Needs a reference condition that holds the body (not
    /// free-free). Design derivatives through them are exact ([`crate::correction`]). Empty
    /// (the default): none.
    pub correction: Vec<NodeId>,
    /// Damping of the correction modes ([`CorrectionDamping`]); the default keeps the body's.
    pub correction_damping: CorrectionDamping,
    /// Couplings ([`Coupling`], distributing or rigid): each adds a node without mass to the
    /// [`ModalBody`], numbered after the mesh's nodes in this order, at the coupling's point
    /// and moving as the coupling's rigid fit of its nodes (exactly the set's motion for a
    /// rigid one, whose set the analysis ties, [`crate::RigidTie`]). Joints and forces attached
    /// there load the whole node set. Empty (the default): none.
    pub couplings: Vec<Coupling>,
    /// Supports added to the reference condition (with [`ReferenceCondition::Supports`] they
    /// alone hold the body): simply supported or clamped edges, pinned lines, symmetry planes,
    /// single dof. Empty (the default): none.
    pub supports: Vec<Support>,
}

impl ModalOptions {
    /// The paper's setting: clamped at the centre of mass, lumped mass, no damping.
    pub fn new(n_modes: usize) -> Self {
        Self {
            reference: ReferenceCondition::ClampedAtCentreOfMass,
            n_modes,
            kept: None,
            damping: None,
            mass: MassKind::Lumped,
            element: ElementOptions::default(),
            eigen: EigenOptions::default(),
            planar: None,
            correction: Vec::new(),
            correction_damping: CorrectionDamping::Proportional,
            couplings: Vec::new(),
            supports: Vec::new(),
        }
    }

    /// The paper's setting retaining only the modes `kept` (zero-based indices of the lowest
    /// modes, strictly ascending): computes the lowest `max + 1`.
    pub fn select(kept: Vec<usize>) -> Self {
        let mut o = Self::new(kept.iter().max().map_or(0, |m| m + 1));
        o.kept = Some(kept);
        o
    }
}

/// The global axis (0, 1, 2) of a planar-motion normal; errors unless the vector is finite,
/// non-zero and along a global axis.
pub fn planar_axis(normal: &Vector3<f64>) -> Result<usize, FemError> {
    let norm = normal.norm();
    if !(norm > 0.0) || !norm.is_finite() {
        return Err(FemError::Planar(format!(
            "planar normal {normal:?} must be a finite, non-zero vector"
        )));
    }
    let n = normal / norm;
    let axis = n.iamax();
    if (1.0 - n[axis].abs()) > 1e-9 || (n - Vector3::ith(axis, n[axis])).norm() > 1e-9 {
        return Err(FemError::Planar(format!(
            "planar normal ({}, {}, {}) is not along a global axis of the mesh; only x, y or z \
             normals are supported",
            normal.x, normal.y, normal.z
        )));
    }
    Ok(axis)
}

/// Fix, at every node of `mesh`, the translation along global `axis` and the rotations about
/// the two other axes (motion in the plane normal to `axis`, see [`ModalOptions::planar`]).
pub fn add_planar_constraints(mesh: &Mesh, axis: usize, c: &mut Constraints) {
    assert!(axis < 3, "axis {axis} out of range");
    for node in 0..mesh.nodes.len() {
        c.fix(node, axis);
        for r in 0..3 {
            if r != axis {
                c.fix(node, 3 + r);
            }
        }
    }
}

/// The constraints and frame origin of a modal analysis: the reference condition plus the
/// planar restriction of [`ModalOptions::planar`], if any.
pub fn analysis_constraints(
    mesh: &Mesh,
    props: &Properties<f64>,
    opts: &ModalOptions,
) -> Result<(Constraints, Vector3<f64>), FemError> {
    let axis = opts.planar.as_ref().map(planar_axis).transpose()?;
    let (mut c, origin) = reference_constraints(mesh, props, opts.reference, &opts.element)?;
    if let Some(axis) = axis {
        add_planar_constraints(mesh, axis, &mut c);
    }
    if matches!(
        opts.reference,
        ReferenceCondition::Supports | ReferenceCondition::PartlyFree
    ) && opts.supports.is_empty()
    {
        return Err(FemError::Support(format!(
            "reference condition {:?} without any support (a body held by nothing is free-free)",
            opts.reference
        )));
    }
    if opts.reference == ReferenceCondition::FreeFree && !opts.supports.is_empty() {
        return Err(FemError::Support(
            "supports on a free-free body: use the reference condition `supports` (they hold \
             every rigid motion) or `partly-free` (the motions they leave free stay free)"
                .into(),
        ));
    }
    for s in &opts.supports {
        if let Some(&n) = s.nodes.iter().find(|&&n| n >= mesh.nodes.len()) {
            return Err(FemError::Support(format!(
                "support at node {n}: the mesh has {} nodes",
                mesh.nodes.len()
            )));
        }
        if let Some(&d) = s.dofs.iter().find(|&&d| d >= 6) {
            return Err(FemError::Support(format!(
                "support of dof {d}: dof are 0 to 5"
            )));
        }
        c.fix_nodes(&s.nodes, &s.dofs);
    }
    for coupling in opts.couplings.iter().filter(|c| c.rigid) {
        // checks the nodes before they are read
        let d = distribution(mesh, coupling)?;
        c.tie(&d.nodes, d.point);
    }
    Ok((c, origin))
}

/// Result of a body modal analysis in `f64`.
#[derive(Clone, Debug)]
pub struct ModalAnalysis {
    pub assembly: Assembly,
    /// Free-dof stiffness and mass.
    pub k: faer::sparse::SparseColMat<usize, f64>,
    pub m: faer::sparse::SparseColMat<usize, f64>,
    /// Retained elastic eigenpairs on the free dof (plus guard modes beyond `n_modes`, kept so
    /// that clusters are complete: use [`Self::n_modes`]).
    pub pairs: Eigenpairs,
    /// Number of lowest modes computed (the retained ones are [`Self::kept`] of them).
    pub n_modes: usize,
    /// The retained modes: zero-based indices into `pairs`, ascending (all `0..n_modes` unless
    /// [`ModalOptions::kept`] selects some).
    pub kept: Vec<usize>,
    /// Static correction modes ([`ModalOptions::correction`]), after the retained eigenmodes:
    /// their Ritz values `μ` and shapes on the free dof (`n_free × s`, mass-normalised,
    /// mass-orthogonal to the retained modes).
    pub correction: Option<StaticCorrection>,
    /// The couplings of [`ModalOptions::couplings`] resolved on the mesh.
    pub couplings: Vec<Distribution>,
    /// Rigid-body modes discarded (free-free, partly free).
    pub n_rigid: usize,
    /// Body-frame origin (mesh coordinates).
    pub origin: Vector3<f64>,
    pub constraints: Constraints,
    pub options: ModalOptions,
}

impl ModalAnalysis {
    /// Eigenvalues `ω²` of the body's modes: the retained eigenmodes, then the Ritz values of
    /// the static correction modes, if any.
    pub fn eigenvalues(&self) -> Vec<f64> {
        let mut l: Vec<f64> = self.kept.iter().map(|&i| self.pairs.values[i]).collect();
        if let Some(c) = &self.correction {
            l.extend(&c.values);
        }
        l
    }
    /// The body's mode shapes on the free dof: retained eigenvectors, then correction modes.
    pub(crate) fn free_shapes(&self) -> DMatrix<f64> {
        let x = self.pairs.vectors.select_columns(&self.kept);
        match &self.correction {
            None => x,
            Some(c) => {
                let phi = &c.shapes;
                let mut out = DMatrix::zeros(x.nrows(), x.ncols() + phi.ncols());
                out.columns_mut(0, x.ncols()).copy_from(&x);
                out.columns_mut(x.ncols(), phi.ncols()).copy_from(phi);
                out
            }
        }
    }
    /// Eigenvalues `ω²` of all `n_modes` lowest modes computed (retained or not).
    pub fn computed_eigenvalues(&self) -> &[f64] {
        &self.pairs.values[..self.n_modes]
    }
    /// Modal damping `2ζω` of the retained modes, then of the correction modes
    /// ([`CorrectionDamping`]; `None` without damping); a fit to two modes refers to the
    /// computed modes' numbers.
    pub fn modal_damping(&self) -> Result<Option<Vec<f64>>, FemError> {
        let lambdas = self.eigenvalues();
        let mut damping = match self.options.damping {
            Some(d) => {
                let (a, b) = d.coefficients(self.computed_eigenvalues())?;
                Some(lambdas.iter().map(|l| a + b * l).collect::<Vec<_>>())
            }
            None => None,
        };
        let eigenmodes = self.kept.len();
        if let Some(z) = self.options.correction_damping.floor()?
            && lambdas.len() > eigenmodes
        {
            let c = damping.get_or_insert_with(|| vec![0.0; lambdas.len()]);
            for (c, l) in c.iter_mut().zip(&lambdas).skip(eigenmodes) {
                *c = c.max(2.0 * z * l.max(0.0).sqrt());
            }
        }
        Ok(damping)
    }
    /// Natural frequencies in Hz.
    pub fn frequencies_hz(&self) -> Vec<f64> {
        self.eigenvalues()
            .iter()
            .map(|l| l.max(0.0).sqrt() / (2.0 * std::f64::consts::PI))
            .collect()
    }
    /// Modal masses `xᵢᵀ M xᵢ` (1 for mass-normalised modes; kept for reporting).
    pub fn modal_masses(&self) -> Vec<f64> {
        let x = self.free_shapes();
        let mm = crate::eigen::project(&self.m, &x, &x);
        (0..x.ncols()).map(|i| mm[(i, i)]).collect()
    }
    /// The body's mode shapes on all dof (retained eigenmodes, then correction modes),
    /// `6 n_nodes × modes`, node by node `[u, θ]`.
    pub fn mode_shapes(&self) -> DMatrix<f64> {
        self.expand(&self.free_shapes())
    }
    /// The damping matrix `C = αM + βK` on the free dof (`None` without damping).
    pub fn damping_matrix(
        &self,
    ) -> Result<Option<faer::sparse::SparseColMat<usize, f64>>, FemError> {
        let Some(d) = self.options.damping else {
            return Ok(None);
        };
        let (alpha, beta) = d.coefficients(self.computed_eigenvalues())?;
        let v = self
            .m
            .val()
            .iter()
            .zip(self.k.val())
            .map(|(m, k)| alpha * m + beta * k)
            .collect();
        Ok(Some(self.assembly.matrix(v)))
    }

    /// Expand free-dof columns to all dof ([`Assembly::expand_columns`]).
    pub fn expand(&self, x: &DMatrix<f64>) -> DMatrix<f64> {
        self.assembly.expand_columns(x)
    }
}

/// The constraints and frame origin of a reference condition.
pub fn reference_constraints(
    mesh: &Mesh,
    props: &Properties<f64>,
    rc: ReferenceCondition,
    element: &ElementOptions,
) -> Result<(Constraints, Vector3<f64>), FemError> {
    let (masses, _) = lumped_nodal_masses(mesh, props, element)?;
    let total: f64 = masses.iter().sum();
    if !(total > 0.0) {
        return Err(FemError::NoMass);
    }
    let com = mesh
        .nodes
        .iter()
        .zip(&masses)
        .fold(Vector3::zeros(), |a, (p, m)| a + p * *m)
        / total;
    let mut c = Constraints::new();
    match rc {
        ReferenceCondition::ClampedAtCentreOfMass => {
            let node = mesh.closest_node(&com).ok_or(FemError::EmptyMesh)?;
            c.clamp(node);
            Ok((c, mesh.nodes[node]))
        }
        ReferenceCondition::ClampedSectionAtCentre => {
            let node = mesh.closest_node(&com).ok_or(FemError::EmptyMesh)?;
            let (lo, hi) = mesh.bounding_box();
            let ext = hi - lo;
            let axis = ext.iamax();
            let length = ext[axis];
            if !(length > 0.0) {
                return Err(FemError::Reference(
                    "a clamped section needs a mesh with a non-zero length".into(),
                ));
            }
            if (0..3).any(|a| a != axis && (ext[a] - length).abs() <= 1e-9 * length) {
                return Err(FemError::Reference(format!(
                    "clamped section at the centre: the long axis is ambiguous (bounding box \
                     {} × {} × {})",
                    ext.x, ext.y, ext.z
                )));
            }
            let x0 = mesh.nodes[node][axis];
            if (x0 - com[axis]).abs() > 1e-6 * length {
                let name = ["x", "y", "z"][axis];
                return Err(FemError::Reference(format!(
                    "clamped section at the centre: no line of nodes crosses the body at the \
                     centre of mass ({name} = {}; the nearest node is at {name} = {x0}); use an \
                     even number of elements along the length",
                    com[axis]
                )));
            }
            let tol = 1e-9 * ext.norm();
            let line: Vec<NodeId> = (0..mesh.nodes.len())
                .filter(|&k| (mesh.nodes[k][axis] - x0).abs() <= tol)
                .collect();
            c.fix_nodes(&line, &dof::ALL);
            Ok((c, mesh.nodes[node]))
        }
        ReferenceCondition::FreeFree | ReferenceCondition::PartlyFree => Ok((c, com)),
        ReferenceCondition::Supports => {
            let node = mesh.closest_node(&com).ok_or(FemError::EmptyMesh)?;
            Ok((c, mesh.nodes[node]))
        }
        ReferenceCondition::ClampedNode(node) => {
            if node >= mesh.nodes.len() {
                return Err(FemError::Reference(format!(
                    "clamped node {node} does not exist ({} nodes)",
                    mesh.nodes.len()
                )));
            }
            c.clamp(node);
            Ok((c, mesh.nodes[node]))
        }
        ReferenceCondition::PinnedEnds { a, b } => {
            let n = mesh.nodes.len();
            if a >= n || b >= n || a == b {
                return Err(FemError::Reference(format!(
                    "pinned ends {a}, {b} are not two nodes of the mesh"
                )));
            }
            let d = mesh.nodes[b] - mesh.nodes[a];
            let axis = d.iamax();
            if (d.norm() - d[axis].abs()) > 1e-9 * d.norm() {
                return Err(FemError::Reference(
                    "pinned ends must lie on a line parallel to a global axis".into(),
                ));
            }
            c.fix_nodes(&[a], &dof::TRANSLATIONS);
            c.fix(a, 3 + axis);
            for t in 0..3 {
                if t != axis {
                    c.fix(b, t);
                }
            }
            Ok((c, mesh.nodes[a]))
        }
    }
}

/// The number of rigid-body modes the reference condition `rc` discards: the rigid motions
/// `constraints` leave free, which only a free-free or partly free body may have; any other
/// condition that leaves one free is refused, naming the motions.
fn rigid_modes(
    mesh: &Mesh,
    constraints: &Constraints,
    origin: &Vector3<f64>,
    rc: ReferenceCondition,
) -> Result<usize, FemError> {
    let free = crate::rigid::free_rigid_motions(mesh, constraints, origin);
    if free.is_empty()
        || matches!(
            rc,
            ReferenceCondition::FreeFree | ReferenceCondition::PartlyFree
        )
    {
        return Ok(free.len());
    }
    let list: Vec<String> = free.iter().map(|m| m.to_string()).collect();
    Err(FemError::Support(format!(
        "the supports leave {} rigid-body motion(s) free: {}. Hold each with a support (one that \
         holds only the deflection, `uz` along a line, leaves the in-plane translations and the \
         rotation about the normal free: hold them at two nodes of one line, e.g. `fix = \
         [\"ux\", \"uy\"]` at one end of it and `fix = [\"uy\"]` at the other), or leave them \
         free and let the body frame follow them with reference = \"partly-free\"",
        free.len(),
        list.join("; ")
    )))
}

/// Drop the `rigid` zero-frequency modes from the bottom of `pairs`; an error unless exactly
/// that many frequencies are zero (more is a mechanism: a part moves without deforming).
fn discard_rigid_modes(pairs: &mut Eigenpairs, rigid: usize) -> Result<(), FemError> {
    let lmax = pairs.values.iter().fold(0.0f64, |a, b| a.max(b.abs()));
    let zeros = pairs
        .values
        .iter()
        .take_while(|l| l.abs() <= 1e-8 * lmax)
        .count();
    if zeros != rigid {
        return Err(FemError::Eigen(format!(
            "the body has {zeros} zero frequencies where its constraints leave {rigid} rigid-body \
             motion(s) free{}",
            if zeros > rigid {
                ": part of it moves without deforming (elements not connected to the rest, or \
                 a node without stiffness)"
            } else {
                ""
            }
        )));
    }
    pairs.values.drain(..rigid);
    pairs.vectors = pairs
        .vectors
        .columns(rigid, pairs.vectors.ncols() - rigid)
        .into_owned();
    Ok(())
}

/// Number of extra modes computed beyond those requested, so that a cluster of repeated
/// eigenvalues straddling the last retained mode is seen whole.
pub const GUARD_MODES: usize = 4;

/// Modal analysis of a body in `f64`.
pub fn modal_analysis(
    mesh: &Mesh,
    props: &Properties<f64>,
    opts: &ModalOptions,
) -> Result<ModalAnalysis, FemError> {
    let (constraints, origin) = analysis_constraints(mesh, props, opts)?;
    // beams of a planar analysis release their out-of-plane shear (`beam::release_shear`);
    // the options kept in the analysis carry it to every later assembly (derivatives)
    let mut opts = opts.clone();
    opts.element.planar_axis = opts.planar.as_ref().map(planar_axis).transpose()?;
    let opts = &opts;
    let assembly = Assembly::new(mesh, &constraints)?;
    let (kv, mv) = assembly.values(mesh, props, &opts.element, opts.mass)?;
    let k = assembly.matrix(kv);
    let m = assembly.matrix(mv);
    let rigid = rigid_modes(mesh, &constraints, &origin, opts.reference)?;
    let kept = match &opts.kept {
        None => (0..opts.n_modes).collect(),
        Some(k) => {
            if k.is_empty()
                || k.windows(2).any(|w| w[1] <= w[0])
                || k.last().is_some_and(|&m| m >= opts.n_modes)
            {
                return Err(FemError::Modes(format!(
                    "retained modes {:?}: strictly ascending mode indices below the {} computed \
                     are needed",
                    k.iter().map(|i| i + 1).collect::<Vec<_>>(),
                    opts.n_modes
                )));
            }
            k.clone()
        }
    };
    let want = (opts.n_modes + rigid + GUARD_MODES).min(assembly.n_free());
    if opts.n_modes + rigid > assembly.n_free() {
        return Err(FemError::Modes(format!(
            "{} modes requested, {} free dof",
            opts.n_modes,
            assembly.n_free()
        )));
    }
    let node_of = assembly.free_dof_nodes();
    let mut pairs = lowest_modes_of_nodes(&k, &m, want, &opts.eigen, Some(&node_of))?;
    discard_rigid_modes(&mut pairs, rigid)?;
    crate::eigen::canonical_cluster_bases(&mut pairs, crate::sensitivity::CLUSTER_RTOL);
    let couplings = opts
        .couplings
        .iter()
        .map(|c| distribution(mesh, c))
        .collect::<Result<Vec<_>, _>>()?;
    let correction = if opts.correction.is_empty() {
        None
    } else {
        if rigid > 0 {
            return Err(FemError::Correction(
                "static correction needs a reference condition that holds every rigid motion \
                 (not free-free or partly-free): its static shapes are K⁻¹ of unit loads"
                    .into(),
            ));
        }
        let loads = interface_loads(&assembly, mesh.nodes.len(), &couplings, &opts.correction)?;
        Some(static_correction(
            &assembly,
            &k,
            &m,
            &pairs.vectors.select_columns(&kept),
            &loads,
        )?)
    };
    Ok(ModalAnalysis {
        assembly,
        k,
        m,
        pairs,
        n_modes: opts.n_modes,
        kept,
        correction,
        couplings,
        n_rigid: rigid,
        origin,
        constraints,
        options: opts.clone(),
    })
}

/// `K_b`, `M_b` of the free dof for every design variable, evaluating the element matrices on
/// `Dual<N>` numbers in chunks of `N` variables: `props(b)` builds the properties from the
/// (dual) design vector.
pub fn design_matrices<const N: usize, F>(
    mesh: &Mesh,
    assembly: &Assembly,
    b: &[f64],
    mut props: F,
    element: &ElementOptions,
    mass: MassKind,
) -> Result<Vec<DesignMatrices>, FemError>
where
    F: FnMut(&[Dual<N>]) -> Properties<Dual<N>>,
{
    let mut out = Vec::with_capacity(b.len());
    for range in sens::chunk_ranges(b.len(), N) {
        let seeded = seed_chunk::<N>(b, range.start);
        let p = props(&seeded);
        let (kv, mv) = assembly.tangent_values(mesh, &p, element, mass)?;
        for t in 0..range.len() {
            // the entries the variable moves (a segment's or region's variable: its
            // elements'), not the whole pattern's zeros
            out.push(DesignMatrices {
                k: crate::eigen::without_zeros(&assembly.tangent_matrix(&kv, t)),
                m: crate::eigen::without_zeros(&assembly.tangent_matrix(&mv, t)),
            });
        }
    }
    Ok(out)
}

/// Fixed-mode (`X_b = 0`, Eq. 47) or updated-mode (Nelson's `X_b`, Eq. 46) derivatives.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum ModeUpdate {
    #[default]
    Fixed,
    Updated,
}

/// The f64 [`ModalBody`] of an analysis (requires lumped mass): the mesh's nodes, then one
/// node without mass for each coupling ([`ModalOptions::couplings`]).
pub fn modal_body(
    mesh: &Mesh,
    props: &Properties<f64>,
    analysis: &ModalAnalysis,
) -> Result<ModalBody<f64>, FemError> {
    let mut body = mesh_modal_body(mesh, props, analysis)?;
    add_coupling_nodes(analysis, &mut body);
    Ok(body)
}

/// [`modal_body`] on the mesh's nodes alone.
fn mesh_modal_body(
    mesh: &Mesh,
    props: &Properties<f64>,
    analysis: &ModalAnalysis,
) -> Result<ModalBody<f64>, FemError> {
    let lam: Vec<f64> = analysis.eigenvalues();
    let damping = analysis
        .modal_damping()?
        .unwrap_or_else(|| vec![0.0; lam.len()]);
    let (masses, inertias) = lumped_nodal_masses(mesh, props, &analysis.options.element)?;
    Ok(ModalBody {
        node_positions: mesh.nodes.iter().map(|p| p - analysis.origin).collect(),
        node_masses: masses,
        node_inertias: inertias
            .iter()
            .map(|m| Vector3::new(m[0], m[1], m[2]))
            .collect(),
        modes: analysis.mode_shapes(),
        eigenvalues: lam,
        modal_damping: damping,
        stiffness_matrix: None,
        damping_matrix: None,
    })
}

/// Append the couplings' nodes to a body of the mesh's nodes: at the coupling's point, without
/// mass, their mode rows the coupling's fit of its nodes' rows.
fn add_coupling_nodes<S: Scalar>(analysis: &ModalAnalysis, body: &mut ModalBody<S>) {
    if analysis.couplings.is_empty() {
        return;
    }
    let n = body.modes.nrows();
    let p = body.modes.ncols();
    let mut modes = DMatrix::from_element(n + 6 * analysis.couplings.len(), p, S::zero());
    modes.rows_mut(0, n).copy_from(&body.modes);
    for (c, d) in analysis.couplings.iter().enumerate() {
        let rows = d.rows(&body.modes);
        modes.rows_mut(n + 6 * c, 6).copy_from(&rows);
        body.node_positions.push(d.point - analysis.origin);
        body.node_masses.push(S::zero());
        body.node_inertias.push(Vector3::from_element(S::zero()));
    }
    body.modes = modes;
}

/// The dual [`ModalBody`] whose tangents are the derivatives with respect to design variables
/// `chunk_start .. chunk_start + N` of `derivs` (and of `matrices`, the `K_b`, `M_b` of every
/// variable, which static correction modes need): eigenvalues always, mode shapes for
/// [`ModeUpdate::Updated`] (zero for fixed-mode), modal damping through the eigenvalues.
///
/// Within clusters of repeated eigenvalues the derivatives are directional (one rotation of the
/// cluster basis per variable, [`ModeDerivatives::rotations`]) and are rotated back to the
/// basis of the values, which is exact for clusters that stay together; the mode values stay those of
/// `analysis`.
///
/// With static correction modes the body carries its full modal stiffness `BᵀKB` (and damping
/// `αBᵀMB + βBᵀKB`), diagonal at the analysed design but not in its derivatives: `B` are the
/// eigenmodes (their block stays `diag(λ)`) and the correction shapes, whose derivatives
/// follow from `Ψ_b = −K⁻¹K_bΨ` ([`crate::correction`]); for fixed modes the shapes keep
/// their values and only `K_b`, `M_b` enter.
pub fn modal_body_dual<const N: usize>(
    mesh: &Mesh,
    props: &Properties<f64>,
    analysis: &ModalAnalysis,
    matrices: &[DesignMatrices],
    derivs: &ModeDerivatives,
    chunk_start: usize,
    update: ModeUpdate,
) -> Result<ModalBody<Dual<N>>, FemError> {
    let base = mesh_modal_body(mesh, props, analysis)?;
    let p = analysis.n_modes;
    let kept = &analysis.kept;
    let nvar = derivs.eigenvalues.len();
    let vars: Vec<usize> = (chunk_start..(chunk_start + N).min(nvar)).collect();
    let split = split_clusters(analysis, derivs, &vars)?;
    if let Some(&v) = vars
        .iter()
        .find(|&&v| !split.is_empty() && v >= matrices.len())
    {
        return Err(FemError::Derivatives(format!(
            "a variable splits repeated eigenvalues: the body's modal stiffness needs the design \
             matrices of every variable ({} given, variable {} asked for)",
            matrices.len(),
            v + 1
        )));
    }
    let x = analysis.pairs.vectors.select_columns(kept);
    // every computed mode (a damping fit refers to their numbers), then the retained ones
    let computed: Vec<Dual<N>> = (0..p)
        .map(|i| {
            let mut d = [0.0; N];
            for (t, &v) in vars.iter().enumerate() {
                d[t] = derivs.eigenvalues[v][i];
            }
            Dual::new(analysis.pairs.values[i], d)
        })
        .collect();
    let lam: Vec<Dual<N>> = kept.iter().map(|&i| computed[i]).collect();
    let mut modes = base.modes.map(Dual::<N>::constant);
    // the retained eigenvectors' derivatives on the free dof, per variable of the chunk
    let mut x_b: Vec<DMatrix<f64>> = Vec::new();
    if update == ModeUpdate::Updated && derivs.eigenvectors_by_adjoint {
        // the eigenvectors' part of the tangents is the adjoint's ([`eigenvector_adjoints`])
        x_b = vec![DMatrix::zeros(x.nrows(), kept.len()); vars.len()];
    } else if update == ModeUpdate::Updated {
        let xb = derivs.eigenvectors.as_ref().ok_or_else(|| {
            FemError::Derivatives("updated-mode needs eigenvector derivatives".into())
        })?;
        for (t, &v) in vars.iter().enumerate() {
            // Within a cluster of repeated eigenvalues `xb[v]` differentiates the rotated basis
            // `X Γ_v`; `X(b) = X'(b) Γ_vᵀ` is a smooth eigenbasis through the values `X` when
            // the cluster stays together (e.g. the two halves of a rod clamped at its middle),
            // and its derivative is `xb[v] Γ_vᵀ`.
            let back = match derivs.rotations.get(v) {
                Some(g) if g.nrows() == xb[v].ncols() => &xb[v] * g.transpose(),
                _ => xb[v].clone(),
            };
            let free = without_cluster_rotation(back.select_columns(kept), &x, &analysis.m, &split);
            let full = analysis.expand(&free);
            for i in 0..full.nrows() {
                for j in 0..kept.len() {
                    modes[(i, j)].d[t] = full[(i, j)];
                }
            }
            x_b.push(free);
        }
    }
    let fit = analysis
        .options
        .damping
        .map(|d| d.coefficients(&computed))
        .transpose()?;
    let (eigen_k, eigen_c) = eigen_blocks(&x, &lam, &split, matrices, &vars, fit);
    let lam: Vec<Dual<N>> = (0..lam.len()).map(|i| eigen_k[(i, i)]).collect();
    let damping: Vec<Dual<N>> = (0..lam.len()).map(|i| eigen_c[(i, i)]).collect();
    let mut body = ModalBody {
        node_positions: base.node_positions,
        // constant masses ([`crate::design_bodies`] gives them their derivatives)
        node_masses: base
            .node_masses
            .iter()
            .map(|&m| Dual::constant(m))
            .collect(),
        node_inertias: base
            .node_inertias
            .iter()
            .map(|m| m.map(Dual::constant))
            .collect(),
        modes,
        eigenvalues: lam,
        modal_damping: damping,
        stiffness_matrix: None,
        damping_matrix: None,
    };
    if let Some(correction) = &analysis.correction {
        let eigen = (&eigen_k, &eigen_c);
        correction_dual(
            analysis, correction, matrices, &vars, &x_b, fit, eigen, &mut body,
        )?;
    } else if !split.is_empty() {
        body.stiffness_matrix = Some(Box::new(eigen_k));
        body.damping_matrix = fit.map(|_| Box::new(eigen_c));
    }
    add_coupling_nodes(analysis, &mut body);
    Ok(body)
}

/// The correction modes' part of a dual body ([`modal_body_dual`]): their shapes' tangents,
/// the eigenvalue and damping entries of their Ritz values, and the full modal stiffness and
/// damping. `x_b` are the retained eigenvectors' derivatives (empty for fixed modes), `eigen`
/// the eigenmodes' blocks of the modal stiffness and damping ([`eigen_blocks`]).
fn correction_dual<const N: usize>(
    analysis: &ModalAnalysis,
    correction: &StaticCorrection,
    matrices: &[DesignMatrices],
    vars: &[usize],
    x_b: &[DMatrix<f64>],
    fit: Option<(Dual<N>, Dual<N>)>,
    eigen: (&DMatrix<Dual<N>>, &DMatrix<Dual<N>>),
    body: &mut ModalBody<Dual<N>>,
) -> Result<(), FemError> {
    if let Some(&v) = vars.iter().find(|&&v| v >= matrices.len()) {
        return Err(FemError::Derivatives(format!(
            "static correction modes need the design matrices of every variable ({} given, \
             variable {} asked for)",
            matrices.len(),
            v + 1
        )));
    }
    let (k, m) = (&analysis.k, &analysis.m);
    let x = analysis.pairs.vectors.select_columns(&analysis.kept);
    let k_b: Vec<_> = vars.iter().map(|&v| &matrices[v].k).collect();
    let m_b: Vec<_> = vars.iter().map(|&v| &matrices[v].m).collect();
    let updated = !x_b.is_empty();
    let phi_b = if updated {
        correction.shape_derivatives(&analysis.assembly, k, m, &x, &k_b, &m_b, Some(x_b))?
    } else {
        vec![DMatrix::zeros(correction.shapes.nrows(), correction.shapes.ncols()); vars.len()]
    };
    let (pe, s) = (x.ncols(), correction.shapes.ncols());
    let r = pe + s;
    // B = [X, Φ] on the free dof and its tangents
    let mut b = DMatrix::zeros(x.nrows(), r);
    b.columns_mut(0, pe).copy_from(&x);
    b.columns_mut(pe, s).copy_from(&correction.shapes);
    // at the analysed design B is mass-orthonormal and diagonalises K: BᵀMB = I and
    // BᵀKB = diag(λ, μ), the Ritz values μ of the correction modes on the diagonal
    let mut kr = DMatrix::from_fn(r, r, |i, j| {
        let v = match (i == j, i.checked_sub(pe)) {
            (true, Some(c)) => correction.values[c],
            _ => 0.0,
        };
        Dual::<N>::constant(v)
    });
    let mut mr = DMatrix::from_fn(r, r, |i, j| {
        Dual::<N>::constant(if i == j { 1.0 } else { 0.0 })
    });
    debug_assert!(
        (crate::eigen::project(m, &b, &b) - DMatrix::identity(r, r)).amax() < 1e-6,
        "the basis is mass-orthonormal"
    );
    for (t, (kbv, mbv)) in k_b.iter().zip(&m_b).enumerate() {
        let mut bb = DMatrix::zeros(x.nrows(), r);
        if updated {
            bb.columns_mut(0, pe).copy_from(&x_b[t]);
        }
        bb.columns_mut(pe, s).copy_from(&phi_b[t]);
        // d(BᵀAB) = B_bᵀAB + BᵀA_bB + BᵀAB_b
        let ka = crate::eigen::project(k, &bb, &b);
        let dk = &ka + ka.transpose() + crate::eigen::project(kbv, &b, &b);
        let ma = crate::eigen::project(m, &bb, &b);
        let dm = &ma + ma.transpose() + crate::eigen::project(mbv, &b, &b);
        for i in 0..r {
            for j in 0..r {
                kr[(i, j)].d[t] = dk[(i, j)];
                mr[(i, j)].d[t] = dm[(i, j)];
            }
        }
    }
    // the eigenmodes' block is theirs ([`eigen_blocks`]: diag(λ) by Nelson's derivatives, but
    // where a variable splits repeated eigenvalues), its damping α + βλ
    let (eigen_k, eigen_c) = eigen;
    kr.view_mut((0, 0), (pe, pe)).copy_from(eigen_k);
    let cr = match analysis.options.correction_damping.floor()? {
        Some(z) => Some(floored_damping(&kr, &mr, eigen_c, fit, z)),
        None => fit.map(|(a, beta)| {
            let mut c = DMatrix::from_fn(r, r, |i, j| mr[(i, j)] * a + kr[(i, j)] * beta);
            c.view_mut((0, 0), (pe, pe)).copy_from(eigen_c);
            c
        }),
    };
    // the correction columns of the modes
    let shapes = analysis.expand(&correction.shapes);
    let shapes_b: Vec<DMatrix<f64>> = phi_b.iter().map(|d| analysis.expand(d)).collect();
    let mut modes = DMatrix::from_element(body.modes.nrows(), r, Dual::<N>::constant(0.0));
    modes
        .columns_mut(0, pe)
        .copy_from(&body.modes.columns(0, pe));
    for i in 0..shapes.nrows() {
        for j in 0..s {
            let mut d = [0.0; N];
            for (t, sb) in shapes_b.iter().enumerate() {
                d[t] = sb[(i, j)];
            }
            modes[(i, pe + j)] = Dual::new(shapes[(i, j)], d);
        }
    }
    body.modes = modes;
    body.eigenvalues = (0..r).map(|i| kr[(i, i)]).collect();
    body.modal_damping = match &cr {
        Some(c) => (0..r).map(|i| c[(i, i)]).collect(),
        None => vec![Dual::constant(0.0); r],
    };
    body.stiffness_matrix = Some(Box::new(kr));
    body.damping_matrix = cr.map(Box::new);
    Ok(())
}

/// The modal damping of a body whose correction modes are damped at least at the ratio `z`
/// ([`CorrectionDamping::AtLeast`]): `M # f(K)` over the dual modal stiffness `kr` and mass
/// `mr` of the whole basis, whose values are `I` and `diag(λ, μ)` at the analysed design; the
/// eigenmodes' block is `eigen`, their proportional damping (zero without one), as in the
/// proportional case. `f` is `α + βλ` at the eigenmodes and `max(α + βμ, 2zμ^½)` at the
/// correction modes (`α`, `β` from `fit`, zero without one). To first order about the design
/// (`M = I + M'`, `K = diag(λ) + K'`) the entries are
/// `fᵢ δᵢⱼ + (K'ᵢⱼ − M'ᵢⱼ (λᵢ + λⱼ)/2) f[λᵢ, λⱼ] + M'ᵢⱼ (fᵢ + fⱼ)/2 + δᵢⱼ (α' + β'λᵢ)`, with
/// `f[λᵢ, λⱼ]` the divided difference (`f′(λᵢ)` for equal values) and the last term only where
/// the proportional law holds.
fn floored_damping<const N: usize>(
    kr: &DMatrix<Dual<N>>,
    mr: &DMatrix<Dual<N>>,
    eigen: &DMatrix<Dual<N>>,
    fit: Option<(Dual<N>, Dual<N>)>,
    z: f64,
) -> DMatrix<Dual<N>> {
    let (r, pe) = (kr.nrows(), eigen.nrows());
    let lambda: Vec<f64> = (0..r).map(|i| kr[(i, i)].value()).collect();
    let (alpha, beta) = fit.unwrap_or((Dual::constant(0.0), Dual::constant(0.0)));
    let laws = damping_laws(&lambda, pe, (alpha.value(), beta.value()), z);
    DMatrix::from_fn(r, r, |i, j| {
        if i < pe && j < pe {
            return eigen[(i, j)];
        }
        let (wk, wm) = floored_weights(&laws, &lambda, i, j);
        let (k, m) = (&kr[(i, j)], &mr[(i, j)]);
        let mut d = [0.0; N];
        for (t, d) in d.iter_mut().enumerate() {
            *d = k.d[t] * wk + m.d[t] * wm;
            // the proportional law's design tangent (of α, β)
            if i == j && laws[i].2 {
                *d += alpha.d[t] + beta.d[t] * lambda[i];
            }
        }
        Dual::new(if i == j { laws[i].0 } else { 0.0 }, d)
    })
}

/// Each mode's damping law in [`floored_damping`] at the modal stiffness's values `lambda`
/// (the first `pe` eigenmodes, then the correction modes): its value `f`, its slope `f′` and
/// whether it is the proportional law `α + βλ` (the floor `2zλ^½` otherwise).
pub(crate) fn damping_laws(
    lambda: &[f64],
    pe: usize,
    (alpha, beta): (f64, f64),
    z: f64,
) -> Vec<(f64, f64, bool)> {
    (lambda.iter().enumerate())
        .map(|(i, &l)| {
            let proportional = alpha + beta * l;
            let floor = 2.0 * z * l.max(0.0).sqrt();
            if i < pe || proportional >= floor {
                (proportional, beta, true)
            } else {
                (floor, z / l.max(f64::MIN_POSITIVE).sqrt(), false)
            }
        })
        .collect()
}

/// The weights of `K'ᵢⱼ` and `M'ᵢⱼ` in the entry `(i, j)` of [`floored_damping`]'s tangent:
/// `f[λᵢ, λⱼ]` and `(fᵢ + fⱼ)/2 − f[λᵢ, λⱼ] (λᵢ + λⱼ)/2`.
pub(crate) fn floored_weights(
    laws: &[(f64, f64, bool)],
    lambda: &[f64],
    i: usize,
    j: usize,
) -> (f64, f64) {
    let ((fi, si, _), (fj, _, _)) = (laws[i], laws[j]);
    let gap = lambda[i] - lambda[j];
    let slope = if gap.abs() > 1e-12 * lambda[i].abs().max(lambda[j].abs()) {
        (fi - fj) / gap
    } else {
        si
    };
    let mean = (lambda[i] + lambda[j]) / 2.0;
    (slope, (fi + fj) / 2.0 - mean * slope)
}

/// The clusters of repeated eigenvalues among the retained modes that a variable of `vars`
/// splits (its derivatives of their eigenvalues differ), as positions in `analysis.kept`.
/// Within such a cluster the modes are not differentiable one by one, only their subspace: the
/// body then carries the cluster's block of its modal stiffness ([`eigen_blocks`]). A cluster
/// retained in part is refused (its subspace would mix with the modes left out).
pub(crate) fn split_clusters(
    analysis: &ModalAnalysis,
    derivs: &ModeDerivatives,
    vars: &[usize],
) -> Result<Vec<Vec<usize>>, FemError> {
    let mut out = Vec::new();
    let fitted = match analysis.options.damping {
        Some(Damping::Ratios(d)) => d.modes.to_vec(),
        _ => Vec::new(),
    };
    for c in derivs.clusters.iter().filter(|c| c.len() > 1) {
        let at: Vec<usize> = c
            .iter()
            .filter_map(|i| analysis.kept.iter().position(|k| k == i))
            .collect();
        let lambda = analysis.pairs.values[c[0]].abs();
        let splitter = vars.iter().find(|&&v| {
            let d: Vec<f64> = c.iter().map(|&i| derivs.eigenvalues[v][i]).collect();
            let spread = d.iter().fold(f64::MIN, |a, &x| a.max(x))
                - d.iter().fold(f64::MAX, |a, &x| a.min(x));
            let size = derivs.eigenvalues[v]
                .iter()
                .fold(0.0f64, |a, x| a.max(x.abs()));
            // a split against the variable's derivatives of the body, above the round-off of
            // derivatives that vanish by symmetry (1e-9 λ per unit of the variable)
            spread > (1e-6 * size).max(1e-9 * lambda)
        });
        let Some(&v) = splitter else { continue };
        let modes: Vec<String> = c.iter().map(|i| (i + 1).to_string()).collect();
        let splits = format!(
            "design variable {} (in the order given) splits the repeated frequencies of modes {}",
            v + 1,
            modes.join(", ")
        );
        if let Some(i) = fitted.iter().find(|i| c.contains(i)) {
            return Err(FemError::Derivatives(format!(
                "{splits}: the damping is fitted to mode {}, whose frequency has no derivative \
                 there (the lower of the pair follows one branch on one side and the other on \
                 the other); give the damping as `alpha` and `beta`, or fit it to modes outside \
                 the pair",
                i + 1
            )));
        }
        if at.is_empty() {
            continue;
        }
        if at.len() < c.len() {
            return Err(FemError::Derivatives(format!(
                "{splits}, of which only some are retained: retain all of them, or none"
            )));
        }
        out.push(at);
    }
    Ok(out)
}

/// `free` (derivatives of the retained eigenvectors `x` on the free dof) without the
/// antisymmetric part of their component within each `split` cluster (positions of `x`'s
/// columns): that part, Dailey's rotation of the cluster's eigenvectors, is the derivative of
/// an eigenbasis that does not exist where a variable splits the cluster. What is left,
/// `Y − ½ X (XᵀM_bX)` with `Y` out of the cluster, differentiates a mass-orthonormal basis of
/// the cluster's subspace, in which the modal stiffness is not diagonal ([`eigen_blocks`]).
fn without_cluster_rotation(
    mut free: DMatrix<f64>,
    x: &DMatrix<f64>,
    m: &faer::sparse::SparseColMat<usize, f64>,
    split: &[Vec<usize>],
) -> DMatrix<f64> {
    for cluster in split {
        let xc = x.select_columns(cluster);
        let fc = free.select_columns(cluster);
        let within = crate::eigen::project(m, &xc, &fc);
        let rotation = (&within - within.transpose()) / 2.0;
        let fixed = fc - &xc * rotation;
        for (k, &j) in cluster.iter().enumerate() {
            free.set_column(j, &fixed.column(k));
        }
    }
    free
}

/// The eigenmodes' blocks of a dual body's modal stiffness and damping: `diag(lam)` and its
/// proportional damping `α + βλ` (zero without a `fit`), but in each `split` cluster, whose
/// modes are a mass-orthonormal basis `X` of their subspace, the full block
/// `λI + Xᵀ(K_b − λM_b)X` (the subspace's derivative; its eigenvalues are the cluster's
/// eigenvalue derivatives) and `αI + β` of it.
fn eigen_blocks<const N: usize>(
    x: &DMatrix<f64>,
    lam: &[Dual<N>],
    split: &[Vec<usize>],
    matrices: &[DesignMatrices],
    vars: &[usize],
    fit: Option<(Dual<N>, Dual<N>)>,
) -> (DMatrix<Dual<N>>, DMatrix<Dual<N>>) {
    let pe = lam.len();
    let mut k = DMatrix::from_fn(
        pe,
        pe,
        |i, j| {
            if i == j { lam[i] } else { Dual::constant(0.0) }
        },
    );
    for cluster in split {
        let xc = x.select_columns(cluster);
        let lambda = lam[cluster[0]].value();
        for (t, &v) in vars.iter().enumerate() {
            let dk = crate::eigen::project(&matrices[v].k, &xc, &xc)
                - crate::eigen::project(&matrices[v].m, &xc, &xc) * lambda;
            for (a, &i) in cluster.iter().enumerate() {
                for (b, &j) in cluster.iter().enumerate() {
                    k[(i, j)].d[t] = (dk[(a, b)] + dk[(b, a)]) / 2.0;
                }
            }
        }
    }
    let c = match fit {
        Some((a, beta)) => DMatrix::from_fn(pe, pe, |i, j| {
            let diagonal = if i == j { a } else { Dual::constant(0.0) };
            diagonal + beta * k[(i, j)]
        }),
        None => DMatrix::from_element(pe, pe, Dual::constant(0.0)),
    };
    (k, c)
}

/// Derivatives of the retained (and guard) modes of an analysis for all design variables.
///
/// For [`ModeUpdate::Updated`] and clusters of repeated eigenvalues, Dailey's second-derivative
/// terms are obtained by central differences (step [`second_derivative_step`]) of the exact dual
/// `K_b` ([`second_derivative_terms`]), for the variables that split a cluster
/// ([`crate::sensitivity::splits_clusters`]; the others do not read them).
pub fn analysis_derivatives<const N: usize, F>(
    mesh: &Mesh,
    analysis: &ModalAnalysis,
    b: &[f64],
    mut props: F,
    update: ModeUpdate,
) -> Result<(Vec<DesignMatrices>, ModeDerivatives), FemError>
where
    F: FnMut(&[Dual<N>]) -> Properties<Dual<N>>,
{
    let (el, mass) = (&analysis.options.element, analysis.options.mass);
    let dm = design_matrices::<N, _>(mesh, &analysis.assembly, b, &mut props, el, mass)?;
    let updated = update == ModeUpdate::Updated;
    let second = if updated && has_repeated(&analysis.pairs) {
        // only the variables that split a cluster read them (each costs the properties at
        // two more designs: a beam's section analysed twice)
        let needed = splits_clusters(&analysis.pairs, &dm);
        Some(second_derivative_terms::<N, _>(
            mesh,
            &analysis.assembly,
            (b, &needed),
            &mut props,
            el,
            mass,
            &analysis.pairs,
        )?)
    } else {
        None
    };
    let d = mode_derivatives(
        &analysis.k,
        &analysis.m,
        &analysis.pairs,
        &dm,
        updated,
        second.as_deref(),
    )?;
    Ok((dm, d))
}

/// The eigenvalue derivatives of `analysis` with respect to the design variables at `b` (no
/// eigenvector derivatives): the element matrices' tangents projected on the modes element by
/// element ([`Assembly::projected_tangents`], [`eigenvalue_derivatives`]). Equal to the
/// eigenvalues of [`analysis_derivatives`], at a fraction of its time and memory.
pub fn analysis_eigenvalue_derivatives<const N: usize, F>(
    mesh: &Mesh,
    analysis: &ModalAnalysis,
    b: &[f64],
    mut props: F,
) -> Result<ModeDerivatives, FemError>
where
    F: FnMut(&[Dual<N>]) -> Properties<Dual<N>>,
{
    let (el, mass) = (&analysis.options.element, analysis.options.mass);
    let mut projected = Vec::with_capacity(b.len());
    let blocks =
        crate::sensitivity::clusters(&analysis.pairs.values, crate::sensitivity::CLUSTER_RTOL);
    for range in sens::chunk_ranges(b.len(), N) {
        let p = props(&seed_chunk::<N>(b, range.start));
        let chunk = analysis.assembly.projected_tangents(
            mesh,
            &p,
            el,
            mass,
            &analysis.pairs.vectors,
            &blocks,
        )?;
        projected.extend(chunk.into_iter().take(range.len()));
    }
    Ok(eigenvalue_derivatives(&analysis.pairs, &projected))
}

/// Step of the central differences of `K_b` for Dailey's terms, relative to each variable's
/// magnitude (in its units where it is zero): [`second_derivative_step`].
pub const SECOND_DERIVATIVE_STEP: f64 = 1e-4;

/// The central-difference step of Dailey's terms for a variable of value `b`:
/// [`SECOND_DERIVATIVE_STEP`] of `|b|`, or of one unit if `b` is zero. A step in the
/// variable's units would be 40 % of a 0.25 mm ply's thickness in metres (and more than a
/// 0.08 mm ply, whose perturbed section then inverts), and a few round-offs of a modulus in
/// pascals.
pub fn second_derivative_step(b: f64) -> f64 {
    SECOND_DERIVATIVE_STEP
        * if b != 0.0 && b.is_finite() {
            b.abs()
        } else {
            1.0
        }
}

/// `Zᵀ(K_bb − λM_bb)Z` for every cluster (`[var][cluster]`) of each design variable `v` with
/// `needed[v]` (a variable past the end of `needed` is needed; the others get none), from the
/// dual `K_b` of variable `v` at `b ± h_v e_v` ([`second_derivative_step`]), seeded along `v`
/// alone ([`cluster_second_derivatives`]).
pub fn second_derivative_terms<const N: usize, F>(
    mesh: &Mesh,
    assembly: &Assembly,
    (b, needed): (&[f64], &[bool]),
    mut props: F,
    element: &ElementOptions,
    mass: MassKind,
    pairs: &Eigenpairs,
) -> Result<Vec<Vec<crate::sensitivity::SecondDerivatives>>, FemError>
where
    F: FnMut(&[Dual<N>]) -> Properties<Dual<N>>,
{
    let mut out = Vec::with_capacity(b.len());
    for v in 0..b.len() {
        if !needed.get(v).copied().unwrap_or(true) {
            out.push(Vec::new());
            continue;
        }
        let h = second_derivative_step(b[v]);
        let mut at = |sign: f64| -> Result<DesignMatrices, FemError> {
            // variable v alone seeded, in its slot of the chunk that contains it: only its
            // tangent is read, and a section analysed again at the perturbed design then
            // differentiates along it alone, not along the whole chunk
            let start = v - v % N;
            let seeded: Vec<Dual<N>> = (b.iter().enumerate())
                .map(|(i, &x)| match i == v {
                    true => Dual::variable(x + sign * h, v - start),
                    false => Dual::constant(x),
                })
                .collect();
            let p = props(&seeded);
            let (kv, mv) = assembly.tangent_values(mesh, &p, element, mass)?;
            Ok(DesignMatrices {
                k: assembly.tangent_matrix(&kv, v - start),
                m: assembly.tangent_matrix(&mv, v - start),
            })
        };
        let (plus, minus) = (at(1.0)?, at(-1.0)?);
        out.extend(cluster_second_derivatives(pairs, &[plus], &[minus], &[h]));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `M # f(K)` by eigendecompositions: `M^½ f(M^-½ K M^-½) M^½`.
    fn matrix_function(m: &DMatrix<f64>, k: &DMatrix<f64>, f: impl Fn(f64) -> f64) -> DMatrix<f64> {
        let power = |a: &DMatrix<f64>, g: &dyn Fn(f64) -> f64| {
            let e = a.clone().symmetric_eigen();
            let d = DMatrix::from_diagonal(&e.eigenvalues.map(g));
            &e.eigenvectors * d * e.eigenvectors.transpose()
        };
        let (half, inv_half) = (power(m, &|x| x.sqrt()), power(m, &|x| 1.0 / x.sqrt()));
        &half * power(&(&inv_half * k * &inv_half), &f) * &half
    }

    /// The tangents of [`floored_damping`] are the central differences of `M # f(K)` computed
    /// by eigendecompositions, with `f(λ) = max(α + βλ, 2ζλ^½)` and `α`, `β` moving with the
    /// design: two eigenmodes (proportional), a repeated pair of correction modes on the floor
    /// (where the tangent couples the pair) and one above it (proportional).
    #[test]
    fn floored_damping_tangents_equal_central_differences() {
        let lambda = [1.0e6, 2.5e7, 4.0e8, 4.0e8, 9.0e10];
        let (pe, r, z) = (2, lambda.len(), 0.2);
        let (alpha, beta) = ([2000.0, 50.0], [3.0e-6, -4.0e-7]);
        let f = |a: f64, b: f64| move |l: f64| (a + b * l).max(2.0 * z * l.sqrt());
        // the law: proportional at the eigenmodes and the last mode, the floor at the pair
        for (i, l) in lambda.iter().enumerate() {
            let floor = (alpha[0] + beta[0] * l) < 2.0 * z * l.sqrt();
            assert_eq!(floor, i == 2 || i == 3, "mode {i}");
        }
        let sym = |a: DMatrix<f64>| (&a + a.transpose()) / 2.0;
        let dk = [
            sym(DMatrix::from_fn(r, r, |i, j| {
                3e5 * ((i + 2 * j + i * j) % 5) as f64 * lambda[i.max(j)].sqrt()
            })),
            sym(DMatrix::from_fn(r, r, |i, j| {
                2e3 * ((3 * i + j) % 4) as f64 * lambda[i.min(j)].sqrt()
            })),
        ];
        let mut dm = [
            sym(DMatrix::from_fn(r, r, |i, j| {
                0.01 * ((i * j + 1) % 3) as f64
            })),
            sym(DMatrix::from_fn(r, r, |i, j| {
                0.02 * ((i + j) % 2) as f64 - 0.005
            })),
        ];
        // the eigenmodes keep their block diagonal and mass-normalised (Nelson's derivatives)
        let mut dk = dk;
        for t in 0..2 {
            for i in 0..pe {
                for j in 0..pe {
                    dm[t][(i, j)] = 0.0;
                    if i != j {
                        dk[t][(i, j)] = 0.0;
                    }
                }
            }
        }
        let value_k = DMatrix::from_diagonal(&nalgebra::DVector::from_row_slice(&lambda));
        let dual = |v: &DMatrix<f64>, d: &[DMatrix<f64>; 2]| {
            DMatrix::from_fn(r, r, |i, j| {
                Dual::<2>::new(v[(i, j)], [d[0][(i, j)], d[1][(i, j)]])
            })
        };
        let (kr, mr) = (dual(&value_k, &dk), dual(&DMatrix::identity(r, r), &dm));
        let (a, b) = (
            Dual::<2>::new(alpha[0], [alpha[1], 0.0]),
            Dual::new(beta[0], [0.0, beta[1]]),
        );
        let eigen = DMatrix::from_fn(pe, pe, |i, j| {
            if i == j {
                a + b * kr[(i, i)]
            } else {
                Dual::constant(0.0)
            }
        });
        let c = floored_damping(&kr, &mr, &eigen, Some((a, b)), z);
        let h = 1e-6;
        for t in 0..2 {
            let at = |e: f64| {
                let k = &value_k + &dk[t] * e;
                let m = DMatrix::identity(r, r) + &dm[t] * e;
                let (a, b) = if t == 0 {
                    (alpha[0] + e * alpha[1], beta[0])
                } else {
                    (alpha[0], beta[0] + e * beta[1])
                };
                matrix_function(&m, &k, f(a, b))
            };
            let fd = (at(h) - at(-h)) / (2.0 * h);
            let base = at(0.0);
            for i in 0..r {
                for j in 0..r {
                    let scale = (base[(i, i)] * base[(j, j)]).sqrt();
                    assert!((c[(i, j)].value() - base[(i, j)]).abs() < 1e-9 * scale);
                    let err = (c[(i, j)].d[t] - fd[(i, j)]).abs();
                    assert!(
                        err < 1e-5 * fd.amax().max(1e-300),
                        "direction {t}, entry ({i}, {j}): tangent {} against {}",
                        c[(i, j)].d[t],
                        fd[(i, j)]
                    );
                }
            }
            // the floor couples the pair, and the pair to the others
            assert!(fd[(2, 3)].abs() > 1e-3 * fd.amax(), "{fd}");
        }
    }
}
