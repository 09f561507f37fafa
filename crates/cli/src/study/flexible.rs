//! Flexible bodies from their validated deck tables: the mesh, the element properties, the
//! modal options, and the design of each body (how its stiffness moves with the design
//! variables).

use fem::{BeamSection, ModalOptions, Properties, ReferenceCondition};
use laminate::PlyStack;
use section::{DesignMap, SectionSensitivities};
use sens::Dual;

use crate::deck::Source;
use crate::deck::bodies::{BodyDef, BodyShape, Reference};
use crate::deck::design::DesignVariable;
use crate::error::CliError;

/// Width of the dual-number chunks (results do not depend on it).
pub const CHUNK: usize = 8;
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

/// The design of a body: how its stiffness depends on the design variables.
pub enum Design {
    /// A beam: the section's values and derivatives with respect to each variable.
    Beam {
        sens: Box<SectionSensitivities>,
        names: Vec<String>,
        values: Vec<f64>,
    },
    /// A shell: the laminate's ply angles move with the variables, `θ_p = θ_p0 + Σ_j f (b_j −
    /// b_j0)` for each `(p, f)` of `links[j]` (θ in radians).
    Shell {
        stack: PlyStack<f64>,
        names: Vec<String>,
        values: Vec<f64>,
        links: Vec<Vec<(usize, f64)>>,
    },
}

impl Design {
    pub fn names(&self) -> &[String] {
        match self {
            Design::Beam { names, .. } | Design::Shell { names, .. } => names,
        }
    }

    /// The design variables' values (beams: only their tangents enter, see
    /// `BeamSection::from_sensitivities`).
    pub fn values(&self) -> &[f64] {
        match self {
            Design::Beam { values, .. } | Design::Shell { values, .. } => values,
        }
    }

    /// Whether variable `j` changes this body's stiffness.
    pub fn depends_on(&self, j: usize) -> bool {
        match self {
            Design::Beam { sens, .. } => sens
                .derivatives
                .get(j)
                .is_some_and(|d| d.stiffness.iter().any(|x| *x != 0.0)),
            Design::Shell { links, .. } => links.get(j).is_some_and(|l| !l.is_empty()),
        }
    }

    /// Element properties on dual numbers seeded with the design variables `b`.
    pub fn properties<const N: usize>(&self, b: &[Dual<N>]) -> Properties<Dual<N>> {
        match self {
            Design::Beam { sens, .. } => Properties {
                sections: vec![BeamSection::from_sensitivities(sens, b)],
                laminates: Vec::new(),
            },
            Design::Shell { stack, links, .. } => {
                let mut angles: Vec<Dual<N>> = stack
                    .plies()
                    .iter()
                    .map(|p| Dual::constant(p.angle))
                    .collect();
                for (bj, l) in b.iter().zip(links) {
                    let step = *bj - Dual::constant(bj.v);
                    for &(p, f) in l {
                        angles[p] += step * Dual::constant(f);
                    }
                }
                let dual = stack
                    .with_angles(&angles)
                    .expect("angles of a validated stack stay valid");
                Properties {
                    sections: Vec::new(),
                    laminates: vec![dual.stiffness()],
                }
            }
        }
    }
}

/// The section design map of the deck's variables: region `r` moves with variable `j` when it
/// is a ply of `j`'s laminate (regions of sections built from a laminate are named
/// `<laminate>.plies[i]`, or `<wall>/<laminate>.plies[i]` in a box).
fn section_design(mesh: &section::SectionMesh, vars: &[DesignVariable]) -> DesignMap {
    let mut map = DesignMap::new();
    for v in vars {
        let mut links = Vec::new();
        for &(p, f) in &v.stack_plies {
            let tag = format!("{}.plies[{p}]", v.laminate);
            let nested = format!("/{tag}");
            for (r, region) in mesh.regions.iter().enumerate() {
                if region.name == tag || region.name.ends_with(&nested) {
                    links.push((r, f));
                }
            }
        }
        map = map.with_variable(v.name.clone(), links);
    }
    map
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
    request: DesignRequest,
) -> (fem::Mesh, Properties<f64>, Design, &'static str) {
    let props = Properties {
        sections: Vec::new(),
        laminates: vec![stack.stiffness()],
    };
    let plies = stack.plies();
    let (names, values, links) = match request {
        DesignRequest::None => (Vec::new(), Vec::new(), Vec::new()),
        DesignRequest::EachPly => (
            (0..plies.len())
                .map(|i| format!("{laminate}.plies[{i}].angle"))
                .collect(),
            plies.iter().map(|p| p.angle).collect(),
            (0..plies.len()).map(|i| vec![(i, 1.0)]).collect(),
        ),
        DesignRequest::Variables(vars) => (
            vars.iter().map(|v| v.name.clone()).collect(),
            vars.iter().map(|v| v.value).collect(),
            vars.iter()
                .map(|v| {
                    if v.laminate == laminate {
                        v.stack_plies.clone()
                    } else {
                        Vec::new()
                    }
                })
                .collect(),
        ),
    };
    (
        mesh,
        props,
        Design::Shell {
            stack: stack.clone(),
            names,
            values,
            links,
        },
        "shell",
    )
}

pub fn build(
    src: &Source,
    name: &str,
    def: &BodyDef,
    request: DesignRequest,
) -> Result<Built, CliError> {
    let input = |key: &str, m: String| {
        CliError::Input(src.error(None, Some(format!("body.{name}{key}")), m))
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
            let map = match request {
                DesignRequest::None => None,
                DesignRequest::EachPly => Some(DesignMap::each_region(&section.mesh)),
                DesignRequest::Variables(vars) => Some(section_design(&section.mesh, vars)),
            };
            let s = match &map {
                Some(map) => section::analyse_with_derivatives::<CHUNK>(&section.mesh, map),
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
            };
            (mesh, props, design, "beam")
        }
        BodyShape::ShellRectangle {
            laminate,
            stack,
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
            shell(mesh, stack, laminate, request)
        }
        BodyShape::ShellMesh {
            laminate,
            stack,
            mesh_text,
            file,
            axis,
        } => {
            let tri = fem::parse_gmsh_v4(mesh_text)
                .map_err(|e| input(".file", format!("in the mesh {file}: {e}")))?;
            shell(tri.to_mesh(0, *axis), stack, laminate, request)
        }
    };
    let reference = match def.reference {
        Reference::CentreOfMass => ReferenceCondition::ClampedAtCentreOfMass,
        Reference::ClampedSection => ReferenceCondition::ClampedSectionAtCentre,
        Reference::FreeFree => ReferenceCondition::FreeFree,
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
    let mut options = ModalOptions::new(def.computed);
    options.kept = def.kept.clone();
    options.correction = def.correction.clone();
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
