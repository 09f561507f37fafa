//! How a flexible body's element properties move with the design variables: the section and
//! shell design maps, material links, and the properties at a (dual) design.

use super::*;
use crate::deck::design::Target;

/// [`section::analyse_with_derivatives`] in chunks no wider than the variables that move the
/// section: the work of a dual number grows with its width, and the results do not depend on
/// it (in `Dual<8>` a deck with one angle would do eight times the tangent work it needs, at
/// the nominal design and at each of Dailey's perturbed designs of a variable that splits a
/// repeated pair; a segment of a tailored beam is moved by its own plies' variables alone).
pub fn section_derivatives(
    mesh: &section::SectionMesh,
    map: &section::DesignMap,
) -> Result<section::SectionSensitivities, section::SectionError> {
    section_derivatives_of(&section::SectionAnalysis::for_derivatives(mesh)?, map)
}

/// [`section_derivatives`] of a section already analysed.
pub fn section_derivatives_of(
    analysis: &section::SectionAnalysis,
    map: &section::DesignMap,
) -> Result<section::SectionSensitivities, section::SectionError> {
    match map.widest_chunk() {
        0 | 1 => analysis.sensitivities::<1>(map),
        2 => analysis.sensitivities::<2>(map),
        3 | 4 => analysis.sensitivities::<4>(map),
        _ => analysis.sensitivities::<CHUNK>(map),
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
    /// A beam: each of its sections' designs (in the order of its element properties) with
    /// respect to the variables at the nominal design `values`.
    Beam {
        sections: Vec<SectionDesign>,
        names: Vec<String>,
        values: Vec<f64>,
    },
    /// A shell: each of its laminates' designs (in the order of its element properties) with
    /// respect to the variables at the nominal design `values`.
    Shell {
        laminates: Vec<LaminateDesign>,
        names: Vec<String>,
        values: Vec<f64>,
    },
}

/// One laminate of a shell body: its ply angles move with the variables, `θ_p = θ_p0 + Σ_j f
/// (b_j − b_j0)` for each `(p, f)` of `links[j]` (θ in radians), and so do its plies'
/// thicknesses and materials.
pub struct LaminateDesign {
    pub stack: PlyStack<f64>,
    pub links: Vec<Vec<(usize, f64)>>,
    /// Per variable, `(ply, law)` of the plies whose material it moves.
    pub materials: MaterialLinks,
    /// Per variable, `(ply, dt/db)` of the plies whose thickness it moves.
    pub thicknesses: Vec<Vec<(usize, f64)>>,
}

/// One section of a beam body: its values and derivatives with respect to the variables that
/// change it at the nominal design, and what the section at another design needs (its mesh and
/// design map).
pub struct SectionDesign {
    /// The values, and the derivatives along the variables of `active` (in that order): a
    /// tailored beam's section is changed by its own segment's variables alone, and the others'
    /// zeros are not kept.
    pub sens: Box<SectionSensitivities>,
    /// The variables whose derivatives `sens` holds, in increasing order.
    pub active: Vec<usize>,
    pub mesh: Box<section::SectionMesh>,
    pub map: DesignMap,
    /// Per variable, `(region, law)` of the regions whose material it moves.
    pub materials: MaterialLinks,
}

impl SectionDesign {
    /// Whether variable `j` changes the section.
    fn depends_on(&self, j: usize) -> bool {
        self.active.binary_search(&j).is_ok()
    }

    /// A section's design from its sensitivities along all variables: the derivatives that
    /// are not zero kept (those [`BeamSection::from_sensitivities`] reads).
    pub fn new(
        mut sens: SectionSensitivities,
        mesh: section::SectionMesh,
        map: DesignMap,
        materials: MaterialLinks,
    ) -> Self {
        let moves = |d: &section::SectionProperties| {
            d.stiffness.iter().any(|x| *x != 0.0)
                || d.mass_per_length != 0.0
                || d.mass_centre.iter().any(|x| *x != 0.0)
                || d.mass_inertia.iter().any(|x| *x != 0.0)
        };
        let all = sens.derivatives.len();
        let active: Vec<usize> = (0..all).filter(|&j| moves(&sens.derivatives[j])).collect();
        sens.derivatives = active
            .iter()
            .map(|&j| sens.derivatives[j].clone())
            .collect();
        if sens.variables.len() == all {
            sens.variables = active.iter().map(|&j| sens.variables[j].clone()).collect();
        }
        Self {
            sens: Box::new(sens),
            active,
            mesh: Box::new(mesh),
            map,
            materials,
        }
    }

    /// Whether the section's own map moves anything with variable `j` (its regions' angles or
    /// materials, its nodes).
    fn moved_by(&self, j: usize) -> bool {
        self.map.variables.get(j).is_some_and(|v| {
            !(v.links.is_empty()
                && v.materials.is_empty()
                && v.densities.is_empty()
                && v.nodes.is_empty())
        }) || self.materials.get(j).is_some_and(|m| !m.is_empty())
    }

    /// The section's stiffness and mass at the design `b` (values and tangents): from the
    /// stored derivatives when `b` is the nominal design `values` or differs from it only in
    /// variables that do not move the section; otherwise (Dailey's second-derivative terms
    /// perturb the design) analysed again at `b`.
    fn at<const N: usize>(
        &self,
        b: &[Dual<N>],
        values: &[f64],
    ) -> Result<BeamSection<Dual<N>>, section::SectionError> {
        // a section given by its properties has no mesh, and nothing moves it
        let analysed = !self.mesh.elements.is_empty();
        let moved =
            (b.iter().zip(values).enumerate()).any(|(j, (bj, b0))| bj.v != *b0 && self.moved_by(j));
        if !(analysed && moved) {
            let b_active: Vec<Dual<N>> = self.active.iter().map(|&j| b[j]).collect();
            return Ok(BeamSection::from_sensitivities(&self.sens, &b_active));
        }
        let (at, map_at, b_active) = self.analysed_at(b, values)?;
        Ok(BeamSection::from_sensitivities(
            &section_derivatives(&at, &map_at)?,
            &b_active,
        ))
    }

    /// The section's stress points at the design `b` (values and tangents,
    /// [`fem::section_points`]), analysed at `b`; none for a section given by its properties.
    fn points_at<const N: usize>(
        &self,
        b: &[Dual<N>],
        values: &[f64],
    ) -> Result<fem::LaminatePoints<Dual<N>>, section::SectionError> {
        // a section given by its properties: nothing to move
        if self.mesh.elements.is_empty() {
            return section_points_of(&self.mesh, &DesignMap::new(), &[]);
        }
        let (at, map_at, b_active) = self.analysed_at(b, values)?;
        section_points_of(&at, &map_at, &b_active)
    }

    /// The section's mesh at the design `b` (its plies' angles, thicknesses and materials
    /// moved from the nominal `values`), its design map there along the variables whose
    /// tangents `b` carries, and those variables' values.
    #[allow(clippy::type_complexity)]
    fn analysed_at<const N: usize>(
        &self,
        b: &[Dual<N>],
        values: &[f64],
    ) -> Result<(section::SectionMesh, DesignMap, Vec<Dual<N>>), section::SectionError> {
        let SectionDesign {
            mesh,
            map,
            materials,
            ..
        } = self;
        let steps: Vec<f64> = b.iter().zip(values).map(|(bj, b0)| bj.v - b0).collect();
        let mut at = (**mesh).clone();
        for (j, &step) in steps.iter().enumerate() {
            at = map.step(&at, j, step);
        }
        for (r, c) in moved_constants(mesh.regions.len(), materials, &steps, |r| {
            material_constants(&mesh.regions[r].material)
        }) {
            at.regions[r].material = with_material_constants(&at.regions[r].material, &c)
                .map_err(|e| section::SectionError::InvalidInput(e.to_string()))?;
        }
        // derivatives only along the variables whose tangents `b` carries (a chunk's, or one of
        // them): the others' would be multiplied by zero, and each one that moves nodes costs
        // dual passes of the section's kernel, so that all of them at each of Dailey's
        // perturbed designs made the set-up quadratic in the number of thickness variables
        let active: Vec<usize> = (0..b.len())
            .filter(|&j| b[j].d.iter().any(|&x| x != 0.0))
            .collect();
        let all = with_materials(map, &at, materials);
        let map_at = DesignMap {
            variables: active.iter().map(|&j| all.variables[j].clone()).collect(),
        };
        let b_active: Vec<Dual<N>> = active.iter().map(|&j| b[j]).collect();
        Ok((at, map_at, b_active))
    }
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
            Design::Beam { sections, .. } => sections.iter().any(|s| s.depends_on(j)),
            Design::Shell { laminates, .. } => laminates.iter().any(|l| l.depends_on(j)),
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
                sections, values, ..
            } => Properties {
                sections: sections
                    .iter()
                    .map(|s| s.at(b, values))
                    .collect::<Result<_, _>>()?,
                laminates: Vec::new(),
            },
            Design::Shell {
                laminates, values, ..
            } => Properties {
                sections: Vec::new(),
                laminates: laminates
                    .iter()
                    .map(|l| l.at(b, values))
                    .collect::<Result<_, _>>()?,
            },
        })
    }
}

/// The stress points of the section `mesh` ([`fem::section_points`]) with their derivatives
/// along the variables of `map` carried by the tangents of their values `b`; none for a
/// section given by its properties (no mesh).
fn section_points_of<S: sens::Scalar>(
    mesh: &section::SectionMesh,
    map: &DesignMap,
    b: &[S],
) -> Result<fem::LaminatePoints<S>, section::SectionError> {
    if mesh.elements.is_empty() {
        return Ok(fem::LaminatePoints {
            points: Vec::new(),
            materials: Vec::new(),
        });
    }
    let analysis = section::SectionAnalysis::new(mesh)?;
    // in chunks no wider than the variables, as `section_derivatives_of`
    let derivatives = match map.variables.len() {
        0 => Vec::new(),
        1 => analysis.unit_stress_derivatives::<1>(map)?,
        2 => analysis.unit_stress_derivatives::<2>(map)?,
        3 | 4 => analysis.unit_stress_derivatives::<4>(map)?,
        _ => analysis.unit_stress_derivatives::<CHUNK>(map)?,
    };
    Ok(fem::section_points(&analysis, &derivatives, b))
}

impl Design {
    /// The body's laminates or sections at the design `b` as its ply stresses need them.
    pub fn stress_parts<const N: usize>(
        &self,
        b: &[Dual<N>],
    ) -> Result<StressParts<Dual<N>>, section::SectionError> {
        Ok(match self {
            Design::Shell { .. } => StressParts::Shell(self.shell_plies(b)?),
            Design::Beam {
                sections, values, ..
            } => StressParts::Beam(
                (sections.iter())
                    .map(|s| s.points_at(b, values))
                    .collect::<Result<_, _>>()?,
            ),
        })
    }

    /// [`Design::stress_parts`] at the nominal design, values only.
    pub fn nominal_stress_parts(&self) -> Result<StressParts<f64>, section::SectionError> {
        Ok(match self {
            Design::Shell { laminates, .. } => StressParts::Shell(
                (laminates.iter())
                    .map(|l| fem::ShellPlies::new(l.stack.clone()))
                    .collect(),
            ),
            Design::Beam { sections, .. } => StressParts::Beam(
                (sections.iter())
                    .map(|s| section_points_of(&s.mesh, &DesignMap::new(), &[]))
                    .collect::<Result<_, _>>()?,
            ),
        })
    }

    /// A shell body's laminates at the design `b` as its ply stresses need them (none for a
    /// beam body).
    pub fn shell_plies<const N: usize>(
        &self,
        b: &[Dual<N>],
    ) -> Result<Vec<fem::ShellPlies<Dual<N>>>, section::SectionError> {
        let Design::Shell {
            laminates, values, ..
        } = self
        else {
            return Ok(Vec::new());
        };
        (laminates.iter())
            .map(|l| {
                let (stack, c_bar, _) = l.plies_at(b, values)?;
                Ok(fem::ShellPlies { stack, c_bar })
            })
            .collect()
    }
}

impl LaminateDesign {
    /// Whether variable `j` changes the laminate.
    fn depends_on(&self, j: usize) -> bool {
        self.links.get(j).is_some_and(|l| !l.is_empty())
            || self.materials.get(j).is_some_and(|m| !m.is_empty())
            || self.thicknesses.get(j).is_some_and(|t| !t.is_empty())
    }

    /// The laminate's stiffness at the design `b` (values and tangents) from the nominal
    /// `values`: its plies turned, thickened and of moved materials.
    fn at<const N: usize>(
        &self,
        b: &[Dual<N>],
        values: &[f64],
    ) -> Result<laminate::LaminateStiffness<Dual<N>>, section::SectionError> {
        let (stack, c_bar, density) = self.plies_at(b, values)?;
        Ok(stack.stiffness_with_materials(&c_bar, &density))
    }

    /// The laminate's plies at the design `b`: the stack turned and thickened, and each ply's
    /// material stiffness `C̄` and density, with their tangents along the material variables.
    #[allow(clippy::type_complexity)]
    fn plies_at<const N: usize>(
        &self,
        b: &[Dual<N>],
        values: &[f64],
    ) -> Result<
        (
            PlyStack<Dual<N>>,
            Vec<nalgebra::Matrix6<Dual<N>>>,
            Vec<Dual<N>>,
        ),
        section::SectionError,
    > {
        let LaminateDesign {
            stack,
            links,
            materials,
            thicknesses,
        } = self;
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
        let bad = |e: laminate::LaminateError| section::SectionError::InvalidInput(e.to_string());
        // each ply's material at b, with its tangents dC̄/db · db
        let steps: Vec<f64> = b.iter().zip(values).map(|(bj, b0)| bj.v - b0).collect();
        let plies = stack.plies();
        let mut at: Vec<laminate::OrthotropicMaterial> = plies.iter().map(|p| p.material).collect();
        for (p, c) in moved_constants(plies.len(), materials, &steps, |p| {
            material_constants(&plies[p].material)
        }) {
            at[p] = with_material_constants(&at[p], &c).map_err(bad)?;
        }
        let mut c_bar: Vec<nalgebra::Matrix6<Dual<N>>> = at
            .iter()
            .map(|m| m.stiffness().map(Dual::constant))
            .collect();
        let mut density: Vec<Dual<N>> = at.iter().map(|m| Dual::constant(m.density())).collect();
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
        Ok((dual, c_bar, density))
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

/// The section design map of the deck's variables for the section `section_name`: region `r`
/// turns with variable `j` when it is a ply of `j` ([`SectionDef::plies`]) or `j` is the
/// section's material angle, its material moves with `j` when `j` is a
/// constant of its material ([`SectionDef::materials`]), and the nodes of a generated section
/// move with `j` when `j` is the thickness of one of its plies
/// ([`SectionDef::generator_plies`]); with, per variable, the `(region, dc/db)` of those
/// materials.
pub fn section_design(
    section_name: &str,
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
        // a solid section's material angle turns all its regions
        if matches!(&v.target, Target::SectionAngle { section: s } if s == section_name) {
            let rad = std::f64::consts::PI / 180.0;
            links.extend((0..section.mesh.regions.len()).map(|r| (r, rad)));
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

/// The design of the laminates of a shell body (or the one of the `laminate` command): how
/// each one's plies turn, thicken and change material with the requested variables (with
/// [`DesignRequest::EachPly`], one variable per ply of each laminate, turning it alone).
pub fn shell_design(laminates: &[ShellLaminate], request: DesignRequest) -> Design {
    // each ply of each laminate: (laminate, ply)
    let each_ply: Vec<(usize, usize)> = laminates
        .iter()
        .enumerate()
        .flat_map(|(l, lam)| (0..lam.stack.plies().len()).map(move |i| (l, i)))
        .collect();
    let (names, values) = match request {
        DesignRequest::None => (Vec::new(), Vec::new()),
        DesignRequest::EachPly => each_ply
            .iter()
            .map(|&(l, i)| {
                let lam = &laminates[l];
                (
                    format!("{}.plies.{i}.angle", lam.name),
                    lam.stack.plies()[i].angle,
                )
            })
            .unzip(),
        DesignRequest::Variables(vars) => vars.iter().map(|v| (v.name.clone(), v.value)).unzip(),
    };
    let n = names.len();
    let designs = laminates
        .iter()
        .enumerate()
        .map(|(l, lam)| {
            let (links, materials, thicknesses) = match request {
                DesignRequest::Variables(vars) => (
                    vars.iter()
                        .map(|v| v.ply_links(&lam.name).to_vec())
                        .collect(),
                    vars.iter()
                        .map(|v| {
                            lam.ply_materials
                                .iter()
                                .enumerate()
                                .filter_map(|(p, m)| Some((p, *v.material_links(m)?)))
                                .collect()
                        })
                        .collect(),
                    vars.iter()
                        .map(|v| v.thickness_links(&lam.name).to_vec())
                        .collect(),
                ),
                DesignRequest::EachPly | DesignRequest::None => (
                    each_ply
                        .iter()
                        .map(|&(owner, i)| if owner == l { vec![(i, 1.0)] } else { vec![] })
                        .collect(),
                    vec![Vec::new(); n],
                    vec![Vec::new(); n],
                ),
            };
            LaminateDesign {
                stack: lam.stack.clone(),
                links,
                materials,
                thicknesses,
            }
        })
        .collect();
    Design::Shell {
        laminates: designs,
        names,
        values,
    }
}

/// A beam body's section moved by the variables of its own among `variables` at their values
/// `b`: the entries of a section given by its properties (`section-property`), the material
/// angle of a solid section (`section-angle`); the rest of the body moves with the laminates
/// ([`BodyDef::at`]).
pub(crate) fn move_own_section(
    def: &mut BodyDef,
    variables: &[crate::deck::design::DesignVariable],
    b: &[f64],
) {
    let BodyShape::Beam { sections, .. } = &mut def.shape else {
        return;
    };
    for (section_name, section) in sections {
        for (v, &bj) in variables.iter().zip(b) {
            match &v.target {
                Target::SectionProperty {
                    section: name,
                    entry,
                } if name == &*section_name => {
                    if let Some(given) = &mut section.given {
                        **given = given.with(*entry, bj);
                    }
                }
                Target::SectionAngle { section: name } if name == &*section_name => {
                    for region in &mut section.mesh.regions {
                        region.ply_angle = bj.to_radians();
                    }
                }
                _ => {}
            }
        }
    }
}
