//! Flexible bodies from their validated deck tables: the mesh, the element properties, the
//! modal options, and the design of each body (how its stiffness moves with the design
//! variables).

use fem::{BeamSection, ModalOptions, Properties, ReferenceCondition};
use laminate::PlyStack;
use section::{DesignMap, SectionSensitivities};
use sens::Dual;

use crate::deck::Source;
use crate::deck::bodies::{
    BodyDef, BodyShape, ElementSet, Reference, ShellLaminate, ShellLaminates,
};
use crate::deck::design::{
    DesignVariable, MaterialLaw, elastic, material_constants, with_material_constants,
};
use crate::deck::sections::SectionDef;
use crate::error::CliError;

mod design;
mod properties;

pub(crate) use design::move_own_section;
pub use design::{
    Design, DesignRequest, LaminateDesign, SectionDesign, section_derivatives,
    section_derivatives_of, section_design, shell_design,
};
use properties::{beam, laminate_regions, shell};

/// Width of the dual-number chunks (results do not depend on it).
pub const CHUNK: usize = 8;

/// What a flexible body's ply stresses are made of, in the design's scalar: a shell body's
/// laminates, or a beam body's sections' stress points (one per element property).
pub enum StressParts<S: sens::Scalar> {
    Shell(Vec<fem::ShellPlies<S>>),
    Beam(Vec<fem::LaminatePoints<S>>),
}

impl<S: sens::Scalar> StressParts<S> {
    /// The same parts converted to another scalar.
    pub fn map<Q: sens::Scalar>(&self, f: &impl Fn(S) -> Q) -> StressParts<Q> {
        match self {
            Self::Shell(p) => StressParts::Shell(p.iter().map(|p| p.map(f)).collect()),
            Self::Beam(p) => StressParts::Beam(p.iter().map(|p| p.map(f)).collect()),
        }
    }
}

impl Built {
    /// The derivatives of the eigenvalues of `analysis` (this body's) with respect to every
    /// design variable, without the eigenvectors' (which `flexsens modes` and the optimiser do
    /// not use): the element matrices' tangents are projected on the modes element by element
    /// (`fem::analysis_eigenvalue_derivatives`), with neither the derivative matrices nor
    /// Nelson's factorisations. The eigenvalue derivatives equal those of
    /// [`Built::mode_derivatives`].
    pub fn eigenvalue_derivatives<const N: usize>(
        &self,
        src: &Source,
        name: &str,
        span: std::ops::Range<usize>,
        analysis: &fem::ModalAnalysis,
    ) -> Result<fem::ModeDerivatives, CliError> {
        self.through_design(src, name, span, |props| {
            fem::analysis_eigenvalue_derivatives::<N, _>(
                &self.mesh,
                analysis,
                self.design.values(),
                props,
            )
        })
    }

    /// The derivatives of the modes of `analysis` (this body's) with respect to every design
    /// variable (`fem::analysis_derivatives` through [`Design::properties`]).
    pub fn mode_derivatives<const N: usize>(
        &self,
        src: &Source,
        name: &str,
        span: std::ops::Range<usize>,
        analysis: &fem::ModalAnalysis,
        update: fem::ModeUpdate,
    ) -> Result<(Vec<fem::DesignMatrices>, fem::ModeDerivatives), CliError> {
        self.through_design(src, name, span, |props| {
            fem::analysis_derivatives::<N, _>(
                &self.mesh,
                analysis,
                self.design.values(),
                props,
                update,
            )
        })
    }

    /// The dual modal body of `analysis` (this body's) for the chunk of `N` design variables
    /// from `start`, from the derivatives of all variables (`mode_derivatives`), with the
    /// element properties of the chunk's seeded design (`fem::design_body_chunk` through
    /// [`Design::properties`]).
    #[allow(clippy::type_complexity)]
    pub fn design_body_chunk<const N: usize>(
        &self,
        src: &Source,
        (name, span): (&str, std::ops::Range<usize>),
        analysis: &fem::ModalAnalysis,
        (matrices, derivatives, start): (&[fem::DesignMatrices], &fem::ModeDerivatives, usize),
        update: fem::ModeUpdate,
    ) -> Result<(fem::ModalBody<Dual<N>>, Properties<Dual<N>>), CliError> {
        self.through_design(src, name, span, |props| {
            fem::design_body_chunk::<N, _>(
                &self.mesh,
                &self.props,
                analysis,
                self.design.values(),
                (matrices, derivatives, start),
                props,
                update,
            )
        })
    }

    /// `run` (a derivative computation of `fem`) with [`Design::properties`] as its properties
    /// of a dual design; a failure of the section at a perturbed design lets the nominal
    /// properties stand in and is returned instead of the result.
    fn through_design<const N: usize, T>(
        &self,
        src: &Source,
        name: &str,
        span: std::ops::Range<usize>,
        run: impl FnOnce(&mut dyn FnMut(&[Dual<N>]) -> Properties<Dual<N>>) -> Result<T, fem::FemError>,
    ) -> Result<T, CliError> {
        let mut failed = None;
        let d = run(&mut |bd: &[Dual<N>]| {
            self.design.properties(bd).unwrap_or_else(|e| {
                failed.get_or_insert(e);
                let nominal: Vec<Dual<N>> = bd
                    .iter()
                    .zip(self.design.values())
                    .map(|(x, &b0)| Dual::new(b0, x.d))
                    .collect();
                self.design.properties(&nominal).unwrap_or_default()
            })
        });
        if let Some(e) = failed {
            return Err(CliError::Runtime(format!(
                "{}: body `{name}`: the section at a perturbed design: {e}",
                src.file.display()
            )));
        }
        d.map_err(|e| fem_error(src, name, span, e))
    }
}

/// A body ready for the finite-element analysis.
pub struct Built {
    pub mesh: fem::Mesh,
    pub props: Properties<f64>,
    pub options: ModalOptions,
    pub design: Design,
    pub kind: &'static str,
}

/// The mesh of body `name` as its definition gives it (global coordinates at t = 0).
pub fn mesh(src: &Source, name: &str, def: &BodyDef) -> Result<fem::Mesh, CliError> {
    let input = |key: &str, m: String| {
        CliError::Input(src.error(Some(def.span.clone()), Some(format!("body.{name}{key}")), m))
    };
    Ok(match &def.shape {
        BodyShape::Beam {
            start,
            end,
            orientation,
            segments,
            ..
        } => fem::Mesh::segmented_beam(*start, *end, segments, *orientation)
            .map_err(|e| input(".elements", e.to_string()))?,
        BodyShape::ShellRectangle {
            length,
            width,
            elements,
            axis,
            laminates,
        } => {
            let mut mesh = fem::Mesh::rectangle(*length, *width, elements[0], elements[1], 0)
                .map_err(|e| input(".elements", e.to_string()))?;
            for e in &mut mesh.elements {
                if let fem::Element::Shell { material_axis, .. } = e {
                    *material_axis = *axis;
                }
            }
            laminate_regions(src, laminates, &mut mesh)?;
            mesh
        }
        BodyShape::ShellMesh {
            mesh_text,
            file,
            axis,
            laminates,
        } => {
            let mut mesh = fem::parse_gmsh_v4(mesh_text)
                .map_err(|e| input(".file", format!("in the mesh {file}: {e}")))?
                .to_mesh(0, *axis);
            crate::deck::check::memory_need(
                src,
                &format!("body.{name}.file"),
                Some(def.span.clone()),
                mesh.elements.len(),
                crate::limits::SHELL_BYTES_PER_ELEMENT,
                "modal analysis",
            )
            .map_err(CliError::Input)?;
            laminate_regions(src, laminates, &mut mesh)?;
            mesh
        }
    })
}

/// Where the markers and responses of the deck can sit on a flexible body: its nodes (the
/// mesh's, then one per coupling at the coupling's point; global coordinates at t = 0) and its
/// couplings' names, from its definition (no analysis).
pub fn geometry(
    src: &Source,
    name: &str,
    def: &BodyDef,
    strengths: &std::collections::BTreeMap<String, laminate::PlyStrength>,
) -> Result<crate::deck::mechanism::FlexibleGeometry, CliError> {
    let mesh = mesh(src, name, def)?;
    let material = |m: &str| (m.to_string(), strengths.get(m).copied());
    let laminates = match &def.shape {
        BodyShape::Beam { sections, .. } => (sections.iter())
            .map(|(name, s)| {
                let regions = match s.given {
                    Some(_) => Vec::new(),
                    None => (s.materials.iter())
                        .map(|m| m.as_deref().map_or((String::new(), None), material))
                        .collect(),
                };
                (name.clone(), regions)
            })
            .collect(),
        BodyShape::ShellRectangle { laminates, .. } | BodyShape::ShellMesh { laminates, .. } => {
            (laminates.laminates.iter())
                .map(|l| {
                    (
                        l.name.clone(),
                        l.ply_materials.iter().map(|m| material(m)).collect(),
                    )
                })
                .collect()
        }
    };
    let plies = crate::deck::mechanism::PlyMap {
        beam: matches!(def.shape, BodyShape::Beam { .. }),
        element_laminates: (mesh.elements.iter())
            .map(|e| match e {
                fem::Element::Shell { property, .. } => *property,
                fem::Element::Beam { property, .. } => *property,
            })
            .collect(),
        element_nodes: (mesh.elements.iter()).map(|e| e.nodes().to_vec()).collect(),
        laminates,
    };
    let couplings = couplings(src, def, &mesh)?;
    let mut nodes = mesh.nodes.clone();
    for c in &couplings {
        nodes.push(c.point.unwrap_or_else(|| {
            let sum = c
                .nodes
                .iter()
                .fold(nalgebra::Vector3::zeros(), |s, &k| s + mesh.nodes[k]);
            sum / c.nodes.len().max(1) as f64
        }));
    }
    Ok(crate::deck::mechanism::FlexibleGeometry {
        nodes,
        couplings: def.couplings.iter().map(|c| c.name.clone()).collect(),
        plies,
    })
}

/// Body `name` ready for the finite-element analysis: its mesh, element properties, modal
/// options and design (with the derivatives `request` asks for).
pub fn build(
    src: &Source,
    name: &str,
    def: &BodyDef,
    request: DesignRequest,
) -> Result<Built, CliError> {
    let input = |key: &str, m: String| {
        CliError::Input(src.error(Some(def.span.clone()), Some(format!("body.{name}{key}")), m))
    };
    let mesh = mesh(src, name, def)?;
    let (mesh, props, design, kind) = match &def.shape {
        BodyShape::Beam { sections, .. } => {
            let (props, design) = beam(sections, request).map_err(|(key, m)| input(key, m))?;
            (mesh, props, design, "beam")
        }
        BodyShape::ShellRectangle { laminates, .. } | BodyShape::ShellMesh { laminates, .. } => {
            let (props, design) = shell(&laminates.laminates, request);
            (mesh, props, design, "shell")
        }
    };
    let reference = reference_condition(def, mesh.nodes.len()).map_err(|(key, m)| input(key, m))?;
    let supports = def
        .supports
        .iter()
        .map(|sd| support_nodes(src, sd, &mesh))
        .collect::<Result<Vec<_>, _>>()?;
    let mut options = ModalOptions::new(def.computed);
    options.supports = supports;
    options.kept = def.kept.clone();
    options.couplings = couplings(src, def, &mesh)?;
    options.correction = def.correction.clone();
    if def.interface {
        // the joints' and forces' nodes that the reference condition leaves free, then every
        // coupling (numbered after the mesh's nodes)
        if let ReferenceCondition::ClampedNode(c) = reference {
            options.correction.retain(|&n| n != c);
        }
        let n = mesh.nodes.len();
        options.correction.retain(|&k| k < n);
        options.correction.extend(n..n + def.couplings.len());
    }
    options.reference = reference;
    options.planar = def.planar;
    options.damping = def.damping;
    options.correction_damping = def.correction_damping;
    options.mass = if def.lumped {
        fem::MassKind::Lumped
    } else {
        fem::MassKind::Consistent
    };
    Ok(Built {
        mesh,
        props,
        options,
        design,
        kind,
    })
}

/// The reference condition of `def` on a mesh of `n_nodes` nodes; an error names the key at
/// fault.
fn reference_condition(
    def: &BodyDef,
    n_nodes: usize,
) -> Result<ReferenceCondition, (&'static str, String)> {
    Ok(match def.reference {
        Reference::CentreOfMass => ReferenceCondition::ClampedAtCentreOfMass,
        Reference::ClampedSection => ReferenceCondition::ClampedSectionAtCentre,
        Reference::FreeFree => ReferenceCondition::FreeFree,
        Reference::Supports => ReferenceCondition::Supports,
        Reference::PartlyFree => ReferenceCondition::PartlyFree,
        Reference::ClampedNode(node) => {
            if node >= n_nodes {
                return Err((
                    ".clamped",
                    format!(
                        "node {node} does not exist (the mesh has {} nodes)",
                        n_nodes
                    ),
                ));
            }
            ReferenceCondition::ClampedNode(node)
        }
        Reference::PinnedEnds(Some([a, b])) => {
            if a.max(b) >= n_nodes {
                return Err((
                    ".pinned",
                    format!(
                        "node {} does not exist (the mesh has {} nodes)",
                        a.max(b),
                        n_nodes
                    ),
                ));
            }
            ReferenceCondition::PinnedEnds { a, b }
        }
        Reference::PinnedEnds(None) => match &def.shape {
            shape @ BodyShape::Beam { .. } => ReferenceCondition::PinnedEnds {
                a: 0,
                b: shape.beam_elements().unwrap_or(0),
            },
            _ => {
                return Err((
                    ".pinned",
                    "a shell with reference = \"pinned-ends\" needs pinned = [node a, node b]"
                        .to_string(),
                ));
            }
        },
    })
}

/// The couplings of `def` resolved on `mesh`; a node in two rigid couplings is refused.
fn couplings(
    src: &Source,
    def: &BodyDef,
    mesh: &fem::Mesh,
) -> Result<Vec<fem::Coupling>, CliError> {
    let couplings = def
        .couplings
        .iter()
        .map(|c| {
            Ok(fem::Coupling {
                nodes: node_set(src, &c.nodes, &c.key, c.span.clone(), mesh)?,
                point: c.point,
                rigid: c.rigid,
            })
        })
        .collect::<Result<Vec<_>, CliError>>()?;
    // a node follows one rigid coupling only
    let mut rigid_owner: std::collections::BTreeMap<usize, &str> = Default::default();
    for (c, def_c) in couplings.iter().zip(&def.couplings) {
        if !c.rigid {
            continue;
        }
        for &k in &c.nodes {
            if let Some(other) = rigid_owner.insert(k, &def_c.name) {
                return Err(CliError::Input(src.error(
                    Some(def_c.span.clone()),
                    Some(def_c.key.clone()),
                    format!(
                        "node {k} is also in the rigid coupling `{other}`: a node can follow \
                     one rigid coupling only (merge the two sets, or make one distributing)"
                    ),
                )));
            }
        }
    }
    Ok(couplings)
}

/// The modal analysis of the built body `def`, and with `with_check` its basis check
/// ([`basis_check`]; `None` without it, or for a free-free body). With `modes = "auto"` the
/// fewest eigenmodes of [`crate::deck::bodies::AUTO_MODES`] (at least `def.computed`) whose
/// check meets `def.basis_tolerance`, or the most the body has dof for (`built.options` are
/// left at that number); the check is then always made.
pub fn analyse(
    src: &Source,
    name: &str,
    span: std::ops::Range<usize>,
    def: &BodyDef,
    built: &mut Built,
    with_check: bool,
) -> Result<(fem::ModalAnalysis, Option<fem::Completeness>), CliError> {
    let run = |built: &Built| -> Result<_, CliError> {
        let a = fem::modal_analysis(&built.mesh, &built.props, &built.options)
            .map_err(|e| fem_error(src, name, span.clone(), e))?;
        let check = if with_check || def.auto_modes {
            basis_check(def, built, &a).map_err(|e| fem_error(src, name, span.clone(), e))?
        } else {
            None
        };
        Ok((a, check))
    };
    if !def.auto_modes {
        return run(built);
    }
    let mut counts: Vec<usize> = std::iter::once(def.computed)
        .chain(crate::deck::bodies::AUTO_MODES)
        .filter(|&n| n >= def.computed)
        .collect();
    counts.dedup();
    let mut best = None;
    for n in counts {
        built.options.n_modes = n;
        let result = match run(built) {
            Ok(r) => r,
            // more modes than the body has dof for: keep the last that worked
            Err(_) if best.is_some() => break,
            Err(e) => return Err(e),
        };
        let met = result
            .1
            .as_ref()
            .and_then(|c| c.worst())
            .is_none_or(|w| w.missed <= def.basis_tolerance);
        best = Some(result);
        if met {
            break;
        }
    }
    let (a, check) = best.expect("at least one count tried");
    built.options.n_modes = a.n_modes;
    Ok((a, check))
}

/// The basis check of `analysis` (`fem::static_completeness`) under the loads the deck's
/// joints and forces put on the body.
pub fn basis_check(
    def: &BodyDef,
    built: &Built,
    analysis: &fem::ModalAnalysis,
) -> Result<Option<fem::Completeness>, fem::FemError> {
    use crate::deck::bodies::InterfaceSite;
    let n = built.mesh.nodes.len();
    let interfaces: Vec<fem::InterfaceLoads> = def
        .interfaces
        .iter()
        .filter_map(|i| {
            let target = match &i.site {
                InterfaceSite::Node(k) => Some(*k).filter(|&k| k < n),
                InterfaceSite::Coupling(c) => def
                    .couplings
                    .iter()
                    .position(|x| &x.name == c)
                    .map(|p| n + p),
            }?;
            Some(fem::InterfaceLoads {
                target,
                forces: i.forces.clone(),
                moments: i.moments.clone(),
            })
        })
        .collect();
    fem::static_completeness(&built.mesh, &built.props, analysis, &interfaces)
}

/// The nodes of `mesh` a support holds (an error naming the support when there are none).
fn support_nodes(
    src: &Source,
    sd: &crate::deck::bodies::SupportDef,
    mesh: &fem::Mesh,
) -> Result<fem::Support, CliError> {
    Ok(fem::Support {
        nodes: node_set(src, &sd.nodes, &sd.key, sd.span.clone(), mesh)?,
        dofs: sd.dofs.clone(),
    })
}

/// The nodes of `mesh` in `set` (an error naming the table `key` when there are none).
fn node_set(
    src: &Source,
    set: &crate::deck::bodies::NodeSet,
    key: &str,
    span: std::ops::Range<usize>,
    mesh: &fem::Mesh,
) -> Result<Vec<usize>, CliError> {
    use crate::deck::bodies::NodeSet;
    let fail = |m: String| CliError::Input(src.error(Some(span.clone()), Some(key.to_string()), m));
    let n = mesh.nodes.len();
    let (lo, hi) = mesh.bounding_box();
    // coordinates within 1e-9 of the mesh's size count as on a plane or in a box
    let tol = 1e-9 * (hi - lo).norm().max(f64::MIN_POSITIVE);
    let nodes: Vec<usize> = match set {
        NodeSet::Nodes(list) => {
            if let Some(&k) = list.iter().find(|&&k| k >= n) {
                return Err(fail(format!(
                    "node {k} does not exist (the mesh has {n} nodes)"
                )));
            }
            if let Some(w) = list
                .iter()
                .enumerate()
                .find(|(i, k)| list[..*i].contains(k))
            {
                return Err(fail(format!("node {} is listed twice", w.1)));
            }
            list.clone()
        }
        NodeSet::Plane { axis, value } => (0..n)
            .filter(|&k| (mesh.nodes[k][*axis] - value).abs() <= tol)
            .collect(),
        NodeSet::Inside([a, b]) => (0..n)
            .filter(|&k| {
                (0..3).all(|i| mesh.nodes[k][i] >= a[i] - tol && mesh.nodes[k][i] <= b[i] + tol)
            })
            .collect(),
    };
    if nodes.is_empty() {
        return Err(fail(format!(
            "no node of the body lies there (its mesh spans [{:e}, {:e}, {:e}] to [{:e}, {:e}, \
             {:e}] m)",
            lo.x, lo.y, lo.z, hi.x, hi.y, hi.z
        )));
    }
    Ok(nodes)
}

/// A failed eigen solution is a runtime failure; every other error of the finite-element layer
/// (too many modes, a degenerate element, a bad mesh, …) is bad input.
pub fn fem_error(
    src: &Source,
    name: &str,
    span: std::ops::Range<usize>,
    e: fem::FemError,
) -> CliError {
    match e {
        fem::FemError::Eigen(m) => CliError::Runtime(format!(
            "{}: body `{name}`: the eigen solution failed: {m}",
            src.file.display()
        )),
        other => {
            use fem::FemError as E;
            // the key of the body table the failure is about
            let key = match &other {
                E::Modes(_) => Some("modes"),
                E::Damping(_) => Some("damping"),
                E::Planar(_) => Some("planar"),
                E::Support(_) => Some("supports"),
                E::Reference(_) => Some("reference"),
                E::Coupling(_) | E::RigidTie(_) => Some("couplings"),
                E::Correction(_) => Some("correction"),
                E::Stiffening(_) => Some("stiffening"),
                _ => None,
            };
            let key = key.map_or(format!("body.{name}"), |k| format!("body.{name}.{k}"));
            CliError::Input(src.error(Some(span), Some(key), other.to_string()))
        }
    }
}

#[cfg(test)]
mod tests;
