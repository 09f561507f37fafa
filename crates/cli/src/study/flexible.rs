//! Flexible bodies from their validated deck tables: the mesh, the element properties, the
//! modal options, and the design of each body (how its stiffness moves with the design
//! variables).

use fem::{BeamSection, ModalOptions, Properties, ReferenceCondition};
use laminate::PlyStack;
use section::{DesignMap, SectionSensitivities};
use sens::Dual;

use crate::deck::Source;
use crate::deck::bodies::{BodyDef, BodyShape, Reference};
use crate::deck::design::{
    DesignVariable, MaterialLaw, elastic, material_constants, with_material_constants,
};
use crate::deck::sections::SectionDef;
use crate::error::CliError;

/// Width of the dual-number chunks (results do not depend on it).
pub const CHUNK: usize = 8;

/// [`section::analyse_with_derivatives`] in chunks no wider than the map's variables: the work
/// of a dual number grows with its width, and the results do not depend on it. (A deck with one
/// angle analysed its sections in `Dual<8>`, eight times the tangent work it needs; with
/// Dailey's terms the §5.1 rod's section is analysed three times, and that deck's run with
/// sensitivities went from 370 to 343 ms.)
pub fn section_derivatives(
    mesh: &section::SectionMesh,
    map: &section::DesignMap,
) -> Result<section::SectionSensitivities, section::SectionError> {
    match map.variables.len() {
        0 | 1 => section::analyse_with_derivatives::<1>(mesh, map),
        2 => section::analyse_with_derivatives::<2>(mesh, map),
        3 | 4 => section::analyse_with_derivatives::<4>(mesh, map),
        _ => section::analyse_with_derivatives::<CHUNK>(mesh, map),
    }
}

/// The design variables a body's derivatives are taken with respect to.
#[derive(Clone, Copy)]
pub enum DesignRequest<'a> {
    /// None: the plain analysis.
    None,
    /// One variable per ply (section region) angle, per radian (`flexsens modes --derivatives`).
    EachPly,
    /// The deck's `[design.*]` variables (per degree).
    Variables(&'a [DesignVariable]),
}

/// Per design variable, `(part, law)` of the parts (plies, section regions) whose material's
/// nine elastic constants and density it moves (`deck::design::material_constants` order).
pub type MaterialLinks = Vec<Vec<(usize, MaterialLaw)>>;

/// The design of a body: how its stiffness depends on the design variables.
pub enum Design {
    /// A beam: the section's values and derivatives with respect to each variable at the
    /// nominal design `values`, and what the section at another design needs (its mesh and
    /// design map).
    Beam {
        sens: Box<SectionSensitivities>,
        names: Vec<String>,
        values: Vec<f64>,
        mesh: Box<section::SectionMesh>,
        map: DesignMap,
        /// Per variable, `(region, law)` of the regions whose material it moves.
        materials: MaterialLinks,
    },
    /// A shell: the laminate's ply angles move with the variables, `θ_p = θ_p0 + Σ_j f (b_j −
    /// b_j0)` for each `(p, f)` of `links[j]` (θ in radians).
    Shell {
        stack: PlyStack<f64>,
        names: Vec<String>,
        values: Vec<f64>,
        links: Vec<Vec<(usize, f64)>>,
        /// Per variable, `(ply, law)` of the plies whose material it moves.
        materials: MaterialLinks,
        /// Per variable, `(ply, dt/db)` of the plies whose thickness it moves.
        thicknesses: Vec<Vec<(usize, f64)>>,
    },
}

impl Design {
    pub fn names(&self) -> &[String] {
        match self {
            Design::Beam { names, .. } | Design::Shell { names, .. } => names,
        }
    }

    /// The nominal values of the design variables.
    pub fn values(&self) -> &[f64] {
        match self {
            Design::Beam { values, .. } | Design::Shell { values, .. } => values,
        }
    }

    /// Whether variable `j` changes this body's stiffness.
    pub fn depends_on(&self, j: usize) -> bool {
        match self {
            Design::Beam { sens, .. } => sens.derivatives.get(j).is_some_and(|d| {
                d.stiffness.iter().any(|x| *x != 0.0)
                    || d.mass_per_length != 0.0
                    || d.mass_inertia.iter().any(|x| *x != 0.0)
            }),
            Design::Shell {
                links,
                materials,
                thicknesses,
                ..
            } => {
                links.get(j).is_some_and(|l| !l.is_empty())
                    || materials.get(j).is_some_and(|m| !m.is_empty())
                    || thicknesses.get(j).is_some_and(|t| !t.is_empty())
            }
        }
    }

    /// Element properties at the design `b` (values and tangents): at the nominal design from
    /// the stored derivatives; elsewhere (Dailey's second-derivative terms perturb the design)
    /// beams analyse their section at `b` again.
    pub fn properties<const N: usize>(
        &self,
        b: &[Dual<N>],
    ) -> Result<Properties<Dual<N>>, section::SectionError> {
        Ok(match self {
            Design::Beam {
                sens,
                values,
                mesh,
                map,
                materials,
                ..
            } => {
                let steps: Vec<f64> = b.iter().zip(values).map(|(bj, b0)| bj.v - b0).collect();
                let section = if steps.iter().any(|&s| s != 0.0) {
                    let mut at = (**mesh).clone();
                    for (j, &step) in steps.iter().enumerate() {
                        at = map.step(&at, j, step);
                    }
                    for (r, c) in moved_constants(mesh.regions.len(), materials, &steps, |r| {
                        material_constants(&mesh.regions[r].material)
                    }) {
                        at.regions[r].material =
                            with_material_constants(&at.regions[r].material, &c)
                                .map_err(|e| section::SectionError::InvalidInput(e.to_string()))?;
                    }
                    let map_at = with_materials(map, &at, materials);
                    BeamSection::from_sensitivities(&section_derivatives(&at, &map_at)?, b)
                } else {
                    BeamSection::from_sensitivities(sens, b)
                };
                Properties {
                    sections: vec![section],
                    laminates: Vec::new(),
                }
            }
            Design::Shell {
                stack,
                links,
                values,
                materials,
                thicknesses,
                ..
            } => {
                let mut thickness: Vec<Dual<N>> = stack
                    .plies()
                    .iter()
                    .map(|p| Dual::constant(p.thickness))
                    .collect();
                for ((bj, l), b0) in b.iter().zip(thicknesses).zip(values) {
                    let step = *bj - Dual::constant(*b0);
                    for &(p, f) in l {
                        thickness[p] += step * Dual::constant(f);
                    }
                }
                let mut angles: Vec<Dual<N>> = stack
                    .plies()
                    .iter()
                    .map(|p| Dual::constant(p.angle))
                    .collect();
                for ((bj, l), b0) in b.iter().zip(links).zip(values) {
                    let step = *bj - Dual::constant(*b0);
                    for &(p, f) in l {
                        angles[p] += step * Dual::constant(f);
                    }
                }
                let bad =
                    |e: laminate::LaminateError| section::SectionError::InvalidInput(e.to_string());
                // each ply's material at b, with its tangents dC̄/db · db
                let steps: Vec<f64> = b.iter().zip(values).map(|(bj, b0)| bj.v - b0).collect();
                let plies = stack.plies();
                let mut at: Vec<laminate::OrthotropicMaterial> =
                    plies.iter().map(|p| p.material).collect();
                for (p, c) in moved_constants(plies.len(), materials, &steps, |p| {
                    material_constants(&plies[p].material)
                }) {
                    at[p] = with_material_constants(&at[p], &c).map_err(bad)?;
                }
                let mut c_bar: Vec<nalgebra::Matrix6<Dual<N>>> = at
                    .iter()
                    .map(|m| m.stiffness().map(Dual::constant))
                    .collect();
                let mut density: Vec<Dual<N>> =
                    at.iter().map(|m| Dual::constant(m.density())).collect();
                for (bj, m) in b.iter().zip(materials) {
                    let db = *bj - Dual::constant(bj.v);
                    for (p, law) in m {
                        let dc = law.tangent(&material_constants(&at[*p]));
                        let d = at[*p].stiffness_derivative(&elastic(&dc));
                        for (x, y) in c_bar[*p].iter_mut().zip(d.iter()) {
                            *x += db * Dual::constant(*y);
                        }
                        density[*p] += db * Dual::constant(dc[9]);
                    }
                }
                let dual = stack.with_plies(&angles, &thickness).map_err(bad)?;
                Properties {
                    sections: Vec::new(),
                    laminates: vec![dual.stiffness_with_materials(&c_bar, &density)],
                }
            }
        })
    }
}

/// The elastic constants of the parts (plies, regions) that material variables move, at the
/// design steps `b − b0` ([`MaterialLaw::moved`]), for each part moved.
fn moved_constants(
    parts: usize,
    materials: &[Vec<(usize, MaterialLaw)>],
    steps: &[f64],
    nominal: impl Fn(usize) -> [f64; 10],
) -> Vec<(usize, [f64; 10])> {
    let mut moves: Vec<Vec<(&MaterialLaw, f64)>> = vec![Vec::new(); parts];
    for (m, &step) in materials.iter().zip(steps) {
        if step == 0.0 {
            continue;
        }
        for (part, law) in m {
            moves[*part].push((law, step));
        }
    }
    moves
        .into_iter()
        .enumerate()
        .filter(|(_, m)| !m.is_empty())
        .map(|(p, m)| (p, MaterialLaw::moved(nominal(p), m)))
        .collect()
}

/// The section design map `map` (ply-angle links) with the material links of `materials`,
/// their `dC̄/db` taken at the materials of `mesh`.
fn with_materials(
    map: &DesignMap,
    mesh: &section::SectionMesh,
    materials: &[Vec<(usize, MaterialLaw)>],
) -> DesignMap {
    let mut out = map.clone();
    for (v, m) in out.variables.iter_mut().zip(materials) {
        // dc/db where each region's material is
        let tangents: Vec<(usize, [f64; 10])> = m
            .iter()
            .map(|(r, law)| {
                (
                    *r,
                    law.tangent(&material_constants(&mesh.regions[*r].material)),
                )
            })
            .collect();
        v.materials = tangents
            .iter()
            .filter(|(_, dc)| dc[..9].iter().any(|&x| x != 0.0))
            .map(|(r, dc)| {
                let d = mesh.regions[*r].material.stiffness_derivative(&elastic(dc));
                (*r, d)
            })
            .collect();
        v.densities = tangents
            .iter()
            .filter(|(_, dc)| dc[9] != 0.0)
            .map(|(r, dc)| (*r, dc[9]))
            .collect();
    }
    out
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
        let mut failed = None;
        let d = fem::analysis_eigenvalue_derivatives::<N, _>(
            &self.mesh,
            analysis,
            self.design.values(),
            |bd| self.properties_or_nominal(bd, &mut failed),
        );
        self.finish(src, name, span, d, failed)
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
        let mut failed = None;
        let d = fem::analysis_derivatives::<N, _>(
            &self.mesh,
            analysis,
            self.design.values(),
            |bd| self.properties_or_nominal(bd, &mut failed),
            update,
        );
        self.finish(src, name, span, d, failed)
    }

    /// The dual modal bodies of `analysis` (this body's) for every chunk of `N` design
    /// variables, with their mode derivatives (`fem::design_bodies` through
    /// [`Design::properties`]).
    pub fn design_bodies<const N: usize>(
        &self,
        src: &Source,
        name: &str,
        span: std::ops::Range<usize>,
        analysis: &fem::ModalAnalysis,
        update: fem::ModeUpdate,
    ) -> Result<fem::DesignBodies<N>, CliError> {
        let mut failed = None;
        let d = fem::design_bodies::<N, _>(
            &self.mesh,
            &self.props,
            analysis,
            self.design.values(),
            |bd| self.properties_or_nominal(bd, &mut failed),
            update,
        );
        self.finish(src, name, span, d, failed)
    }

    /// [`Design::properties`] at `bd`; on a failure the nominal properties stand in and the
    /// error is kept in `failed` (returned by [`Built::finish`]).
    fn properties_or_nominal<const N: usize>(
        &self,
        bd: &[Dual<N>],
        failed: &mut Option<section::SectionError>,
    ) -> Properties<Dual<N>> {
        self.design.properties(bd).unwrap_or_else(|e| {
            failed.get_or_insert(e);
            let nominal: Vec<Dual<N>> = bd
                .iter()
                .zip(self.design.values())
                .map(|(x, &b0)| Dual::new(b0, x.d))
                .collect();
            self.design.properties(&nominal).unwrap_or_default()
        })
    }

    /// The result of a derivative computation, or the first failure of the section at a
    /// perturbed design.
    fn finish<T>(
        &self,
        src: &Source,
        name: &str,
        span: std::ops::Range<usize>,
        d: Result<T, fem::FemError>,
        failed: Option<section::SectionError>,
    ) -> Result<T, CliError> {
        if let Some(e) = failed {
            return Err(CliError::Runtime(format!(
                "{}: body `{name}`: the section at a perturbed design: {e}",
                src.file.display()
            )));
        }
        d.map_err(|e| fem_error(src, name, span, e))
    }
}

/// The section design map of the deck's variables: region `r` turns with variable `j` when it
/// is a ply of `j` ([`SectionDef::plies`]), its material moves with `j` when `j` is a
/// constant of its material ([`SectionDef::materials`]), and the nodes of a generated section
/// move with `j` when `j` is the thickness of one of its plies
/// ([`SectionDef::generator_plies`]); with, per variable, the `(region, dc/db)` of those
/// materials.
pub fn section_design(
    section: &SectionDef,
    vars: &[DesignVariable],
) -> Result<(DesignMap, MaterialLinks), String> {
    let mut map = DesignMap::new();
    let mut materials = Vec::new();
    for v in vars {
        // dt/db of a ply of the section's generator
        let dthickness = |p: &section::PlySpec| {
            section.generator_plies.get(&p.name).map_or(0.0, |tag| {
                v.thickness_links(&tag.laminate)
                    .iter()
                    .filter(|&&(ply, _)| ply == tag.ply)
                    .map(|&(_, f)| f)
                    .sum()
            })
        };
        // a ply of the section whose thickness the variable moves
        let thickened = section.plies.iter().flatten().find(|t| {
            v.thickness_links(&t.laminate)
                .iter()
                .any(|&(p, _)| p == t.ply)
        });
        let velocities = match (thickened, &section.generated) {
            (None, _) => Vec::new(),
            (Some(_), Some(g)) => g
                .node_velocities(dthickness)
                .map_err(|e| format!("design variable `{}`: {e}", v.name))?,
            (Some(tag), None) => {
                return Err(format!(
                    "design variable `{}` moves the thickness of ply {} of laminate `{}`, which \
                     builds this {} section: a ply thickness can move the nodes of a generated \
                     section (tube, box, channel, I beam) or a shell, not of a mesh file, whose \
                     geometry is fixed",
                    v.name, tag.ply, tag.laminate, section.shape
                ));
            }
        };
        let mut links = Vec::new();
        for (r, tag) in section.plies.iter().enumerate() {
            let Some(tag) = tag else { continue };
            for &(p, f) in v.ply_links(&tag.laminate) {
                if p == tag.ply {
                    links.push((r, f));
                }
            }
        }
        map = map.with_variable(v.name.clone(), links);
        if let Some(last) = map.variables.last_mut() {
            last.nodes = section::DesignVariable::node_links(&velocities);
        }
        materials.push(
            section
                .materials
                .iter()
                .enumerate()
                .filter_map(|(r, m)| Some((r, *v.material_links(m.as_deref()?)?)))
                .collect(),
        );
    }
    let map = with_materials(&map, &section.mesh, &materials);
    Ok((map, materials))
}

/// A body ready for the finite-element analysis.
pub struct Built {
    pub mesh: fem::Mesh,
    pub props: Properties<f64>,
    pub options: ModalOptions,
    pub design: Design,
    pub kind: &'static str,
}

/// A shell body's mesh, properties and design from its laminate.
fn shell(
    mesh: fem::Mesh,
    stack: &PlyStack<f64>,
    laminate: &str,
    ply_materials: &[String],
    request: DesignRequest,
) -> (fem::Mesh, Properties<f64>, Design, &'static str) {
    let props = Properties {
        sections: Vec::new(),
        laminates: vec![stack.stiffness()],
    };
    let design = shell_design(stack, laminate, ply_materials, request);
    (mesh, props, design, "shell")
}

/// The design of a laminate `laminate` (a shell body's, or the `laminate` command's): how its
/// plies turn, thicken and change material with the requested variables.
pub fn shell_design(
    stack: &PlyStack<f64>,
    laminate: &str,
    ply_materials: &[String],
    request: DesignRequest,
) -> Design {
    let plies = stack.plies();
    let (names, values, links) = match request {
        DesignRequest::None => (Vec::new(), Vec::new(), Vec::new()),
        DesignRequest::EachPly => (
            (0..plies.len())
                .map(|i| format!("{laminate}.plies.{i}.angle"))
                .collect(),
            plies.iter().map(|p| p.angle).collect(),
            (0..plies.len()).map(|i| vec![(i, 1.0)]).collect(),
        ),
        DesignRequest::Variables(vars) => (
            vars.iter().map(|v| v.name.clone()).collect(),
            vars.iter().map(|v| v.value).collect(),
            vars.iter()
                .map(|v| v.ply_links(laminate).to_vec())
                .collect(),
        ),
    };
    let materials = match request {
        DesignRequest::Variables(vars) => vars
            .iter()
            .map(|v| {
                ply_materials
                    .iter()
                    .enumerate()
                    .filter_map(|(p, m)| Some((p, *v.material_links(m)?)))
                    .collect()
            })
            .collect(),
        _ => vec![Vec::new(); links.len()],
    };
    let thicknesses = match request {
        DesignRequest::Variables(vars) => vars
            .iter()
            .map(|v| v.thickness_links(laminate).to_vec())
            .collect(),
        _ => vec![Vec::new(); links.len()],
    };
    Design::Shell {
        stack: stack.clone(),
        names,
        values,
        links,
        materials,
        thicknesses,
    }
}

pub fn build(
    src: &Source,
    name: &str,
    def: &BodyDef,
    request: DesignRequest,
) -> Result<Built, CliError> {
    let input = |key: &str, m: String| {
        CliError::Input(src.error(Some(def.span.clone()), Some(format!("body.{name}{key}")), m))
    };
    let (mesh, props, design, kind) = match &def.shape {
        BodyShape::Beam {
            section_name,
            section,
            start,
            end,
            orientation,
            elements,
        } => {
            let mesh = fem::Mesh::straight_beam(*start, *end, *elements, 0, *orientation)
                .map_err(|e| input(".elements", e.to_string()))?;
            let (map, materials) = match request {
                DesignRequest::None => (None, Vec::new()),
                DesignRequest::EachPly => {
                    let map = DesignMap::each_region(&section.mesh);
                    let none = vec![Vec::new(); map.variables.len()];
                    (Some(map), none)
                }
                DesignRequest::Variables(vars) => {
                    let (map, materials) = section_design(section, vars)
                        .map_err(|e| input(".section", format!("section `{section_name}`: {e}")))?;
                    (Some(map), materials)
                }
            };
            let s = match &map {
                Some(map) => section_derivatives(&section.mesh, map),
                None => section::analyse(&section.mesh).map(|p| SectionSensitivities {
                    properties: p,
                    ..Default::default()
                }),
            }
            .map_err(|e| input("", format!("section `{section_name}`: {e}")))?;
            let props = Properties {
                sections: vec![BeamSection::from_section(&s.properties)],
                laminates: Vec::new(),
            };
            let (names, values) = match request {
                DesignRequest::None => (Vec::new(), Vec::new()),
                DesignRequest::EachPly => (
                    s.variables.iter().map(|n| format!("{n}.angle")).collect(),
                    vec![0.0; s.variables.len()],
                ),
                DesignRequest::Variables(vars) => (
                    vars.iter().map(|v| v.name.clone()).collect(),
                    vars.iter().map(|v| v.value).collect(),
                ),
            };
            let design = Design::Beam {
                sens: Box::new(s),
                names,
                values,
                mesh: Box::new(section.mesh.clone()),
                map: map.unwrap_or_default(),
                materials,
            };
            (mesh, props, design, "beam")
        }
        BodyShape::ShellRectangle {
            laminate,
            stack,
            ply_materials,
            length,
            width,
            elements,
            axis,
        } => {
            let mut mesh = fem::Mesh::rectangle(*length, *width, elements[0], elements[1], 0)
                .map_err(|e| input(".elements", e.to_string()))?;
            for e in &mut mesh.elements {
                if let fem::Element::Shell { material_axis, .. } = e {
                    *material_axis = *axis;
                }
            }
            shell(mesh, stack, laminate, ply_materials, request)
        }
        BodyShape::ShellMesh {
            laminate,
            stack,
            ply_materials,
            mesh_text,
            file,
            axis,
        } => {
            let tri = fem::parse_gmsh_v4(mesh_text)
                .map_err(|e| input(".file", format!("in the mesh {file}: {e}")))?;
            shell(
                tri.to_mesh(0, *axis),
                stack,
                laminate,
                ply_materials,
                request,
            )
        }
    };
    let reference = match def.reference {
        Reference::CentreOfMass => ReferenceCondition::ClampedAtCentreOfMass,
        Reference::ClampedSection => ReferenceCondition::ClampedSectionAtCentre,
        Reference::FreeFree => ReferenceCondition::FreeFree,
        Reference::Supports => ReferenceCondition::Supports,
        Reference::ClampedNode(node) => {
            if node >= mesh.nodes.len() {
                return Err(input(
                    ".clamped",
                    format!(
                        "node {node} does not exist (the mesh has {} nodes)",
                        mesh.nodes.len()
                    ),
                ));
            }
            ReferenceCondition::ClampedNode(node)
        }
        Reference::PinnedEnds(Some([a, b])) => {
            if a.max(b) >= mesh.nodes.len() {
                return Err(input(
                    ".pinned",
                    format!(
                        "node {} does not exist (the mesh has {} nodes)",
                        a.max(b),
                        mesh.nodes.len()
                    ),
                ));
            }
            ReferenceCondition::PinnedEnds { a, b }
        }
        Reference::PinnedEnds(None) => match &def.shape {
            BodyShape::Beam { elements, .. } => {
                ReferenceCondition::PinnedEnds { a: 0, b: *elements }
            }
            _ => {
                return Err(input(
                    ".pinned",
                    "a shell with reference = \"pinned-ends\" needs pinned = [node a, node b]"
                        .into(),
                ));
            }
        },
    };
    let supports = def
        .supports
        .iter()
        .map(|sd| support_nodes(src, sd, &mesh))
        .collect::<Result<Vec<_>, _>>()?;
    let mut options = ModalOptions::new(def.computed);
    options.supports = supports;
    options.kept = def.kept.clone();
    options.couplings = def
        .couplings
        .iter()
        .map(|c| {
            Ok(fem::Coupling {
                nodes: node_set(src, &c.nodes, &c.key, c.span.clone(), &mesh)?,
                point: c.point,
                rigid: c.rigid,
            })
        })
        .collect::<Result<Vec<_>, CliError>>()?;
    // a node follows one rigid coupling only
    let mut rigid_owner: std::collections::BTreeMap<usize, &str> = Default::default();
    for (c, def_c) in options.couplings.iter().zip(&def.couplings) {
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
            CliError::Input(src.error(Some(span), Some(format!("body.{name}")), other.to_string()))
        }
    }
}

#[cfg(test)]
mod tests {
    //! Dailey's second-derivative terms through the deck's own properties: a splitting pair of
    //! repeated frequencies, its eigenvector derivatives against central differences of the
    //! tracked branches of perturbed decks.

    use nalgebra::DMatrix;

    use super::*;
    use crate::deck::bodies::validate_one;
    use crate::deck::design::validate as validate_design;
    use crate::deck::laminates::validate as validate_laminates;

    /// A free square plate of a [0/90] cross-ply: a 90° turn with a flip is a symmetry, so it
    /// has repeated pairs; turning ply 0 alone breaks the symmetry and splits them.
    const DECK: &str = r#"
[material.ud]
E1 = 128.0e9
E2 = 10.1e9
E3 = 10.1e9
G12 = 5.36e9
G13 = 5.36e9
G23 = 3.0e9
nu12 = 0.23
nu13 = 0.23
nu23 = 0.3
density = 1586.0
[laminate.plate]
plies = [
  { material = "ud", thickness = 1e-3, angle = 0.0 },
  { material = "ud", thickness = 1e-3, angle = 90.0 },
]
[body.p]
kind = "shell"
laminate = "plate"
length = 0.2
width = 0.2
elements = [8, 8]
modes = 8
reference = "free-free"
mass = "consistent"
[design.a]
laminate = "plate"
plies = [0]
"#;

    fn source() -> (Source, crate::deck::RawDeck) {
        let src = Source::new("square.toml", DECK);
        let raw = src.parse().unwrap();
        (src, raw)
    }

    /// The body's modal analysis with ply 0 turned by `delta` degrees (from the laminates moved
    /// by the design variable, as finite differences of a run do).
    fn analysis_at(delta: f64, request: DesignRequest) -> (Built, fem::ModalAnalysis) {
        let (src, raw) = source();
        let mut lam = validate_laminates(&src, &raw).unwrap();
        let design = validate_design(&src, &raw, &lam).unwrap();
        let v = &design.variables[0];
        v.apply(&mut lam, v.value + delta).unwrap();
        let def = validate_one(&src, &raw, "p", &raw.body["p"], &lam).unwrap();
        let request = match request {
            DesignRequest::Variables(_) => DesignRequest::Variables(&design.variables),
            other => other,
        };
        let built = build(&src, "p", &def, request).unwrap();
        let a = fem::modal_analysis(&built.mesh, &built.props, &built.options).unwrap();
        (built, a)
    }

    #[test]
    fn eigenvector_derivatives_of_a_splitting_pair_follow_the_branches() {
        let (src, _) = source();
        let (built, a) = analysis_at(0.0, DesignRequest::Variables(&[]));
        let lam = &a.pairs.values;
        // modes 4 and 5 (from 1) are a repeated pair
        assert!((lam[4] - lam[3]).abs() < 1e-9 * lam[3], "{lam:?}");
        let (_, d) = built
            .mode_derivatives::<1>(&src, "p", 0..1, &a, fem::ModeUpdate::Updated)
            .unwrap();
        let dl = &d.eigenvalues[0];
        assert!(
            (dl[4] - dl[3]).abs() > 0.5 * dl[3].abs().max(dl[4].abs()),
            "the pair splits: {dl:?}"
        );
        let z = &a.pairs.vectors * &d.rotations[0];
        let xb = &d.eigenvectors.as_ref().unwrap()[0];
        // the branches at ±h (degrees), matched to the rotated nominal basis by M-overlap
        let branch = |h: f64| -> DMatrix<f64> {
            let (_, p) = analysis_at(h, DesignRequest::None);
            let overlap = fem::eigen::project(&a.m, &z, &p.pairs.vectors);
            let mut out = DMatrix::zeros(z.nrows(), 2);
            for (c, j) in [3, 4].into_iter().enumerate() {
                let i = if overlap[(j, 3)].abs() > overlap[(j, 4)].abs() {
                    3
                } else {
                    4
                };
                let sign = overlap[(j, i)].signum();
                out.column_mut(c)
                    .copy_from(&(p.pairs.vectors.column(i) * sign));
            }
            out
        };
        let h = 0.05;
        let (p1, m1, p2, m2) = (branch(h), branch(-h), branch(2.0 * h), branch(-2.0 * h));
        let fd = ((&p1 - &m1) / (2.0 * h) * 4.0 - (&p2 - &m2) / (4.0 * h)) / 3.0;
        for (c, j) in [3, 4].into_iter().enumerate() {
            let exact = xb.column(j);
            let err = (exact - fd.column(c)).norm() / exact.norm();
            eprintln!("mode {}: |x_b − FD| / |x_b| = {err:.1e}", j + 1);
            assert!(err < 1e-6, "mode {}: {err:e}", j + 1);
        }
    }

    /// Away from the nominal design a beam's properties are its section analysed at that
    /// design (values and derivatives), as a deck with the turned plies gives them.
    #[test]
    fn beam_properties_at_a_perturbed_design_are_those_of_the_perturbed_deck() {
        let text = std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../decks/modes_beam_rod.toml"
        ))
        .unwrap()
            + "\n[design.theta]\nlaminate = \"tube_wall\"\n";
        let at = |delta: f64| {
            let src = Source::new("rod.toml", text.clone());
            let raw = src.parse().unwrap();
            let mut lam = validate_laminates(&src, &raw).unwrap();
            let design = validate_design(&src, &raw, &lam).unwrap();
            let nominal = lam.clone();
            let v = &design.variables[0];
            v.apply(&mut lam, v.value + delta).unwrap();
            let built = |lam| {
                let def = validate_one(&src, &raw, "rod", &raw.body["rod"], lam).unwrap();
                build(
                    &src,
                    "rod",
                    &def,
                    DesignRequest::Variables(&design.variables),
                )
                .unwrap()
            };
            (built(&nominal), built(&lam), v.value)
        };
        let delta = 3.0;
        let (nominal, moved, b0) = at(delta);
        let b = [Dual::<1>::new(b0 + delta, [1.0])];
        let p = nominal.design.properties(&b).unwrap();
        // `moved` was built from the turned laminates: its stored derivatives are at b0 + δ
        let q = moved
            .design
            .properties(&[Dual::<1>::new(b0, [1.0])])
            .unwrap();
        let (s, t) = (&p.sections[0], &q.sections[0]);
        let scale = t.stiffness.map(|x| x.v.abs()).max();
        let dscale = t.stiffness.map(|x| x.d[0].abs()).max();
        for (x, y) in s.stiffness.iter().zip(t.stiffness.iter()) {
            assert!((x.v - y.v).abs() < 1e-9 * scale, "{} vs {}", x.v, y.v);
            assert!(
                (x.d[0] - y.d[0]).abs() < 1e-8 * dscale,
                "{} vs {}",
                x.d[0],
                y.d[0]
            );
        }
        // and the move is not nothing: 3° changes the stiffness
        let p0 = nominal
            .design
            .properties(&[Dual::<1>::new(b0, [1.0])])
            .unwrap();
        let moved_by = p0.sections[0]
            .stiffness
            .iter()
            .zip(s.stiffness.iter())
            .fold(0.0f64, |m, (x, y)| m.max((x.v - y.v).abs()));
        assert!(moved_by > 1e-3 * scale, "{moved_by:e}");
    }

    /// A body whose repeated modes a variable splits would need an off-diagonal modal
    /// stiffness derivative: its dual body is refused rather than silently wrong.
    #[test]
    fn a_dual_body_whose_repeated_modes_split_is_refused() {
        let (src, raw) = source();
        let lam = validate_laminates(&src, &raw).unwrap();
        let design = validate_design(&src, &raw, &lam).unwrap();
        let mut def = validate_one(&src, &raw, "p", &raw.body["p"], &lam).unwrap();
        def.lumped = true;
        let built = build(&src, "p", &def, DesignRequest::Variables(&design.variables)).unwrap();
        let a = fem::modal_analysis(&built.mesh, &built.props, &built.options).unwrap();
        let lam = &a.pairs.values;
        assert!((lam[4] - lam[3]).abs() < 1e-9 * lam[3], "{lam:?}");
        let (dm, d) = built
            .mode_derivatives::<1>(&src, "p", 0..1, &a, fem::ModeUpdate::Updated)
            .unwrap();
        let e = fem::modal_body_dual::<1>(
            &built.mesh,
            &built.props,
            &a,
            &dm,
            &d,
            0,
            fem::ModeUpdate::Updated,
        )
        .unwrap_err();
        assert!(
            e.to_string()
                .contains("splits the repeated frequencies of modes 4, 5"),
            "{e}"
        );
    }
}
