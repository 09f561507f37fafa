//! Validation of `[section.*]` into `section` meshes.

use std::collections::{BTreeMap, HashMap};
use std::path::Path;

use laminate::OrthotropicMaterial;
use section::{BoxWalls, ElementDirection, PlySpec, RegionSpec, SectionMesh, WallFrame};
use toml::Spanned;

use super::check::suggestion;
use super::check::{count, finite, mesh_size, not_applicable, positive, required, span};
use super::laminates::LaminateModel;
use super::raw::{RawRegion, RawSection};
use super::{DeckError, Source};

mod given;
mod mesh_file;

pub use given::{GivenSection, GivenStiffness, SECTION_ENTRIES, SectionEntry};
mod shapes;

use shapes::Shape;

/// Fewer elements around a tube than this draw a warning (see [`validate_one`]).
const COARSE_AROUND: usize = 8;

/// Warn about nodes of a section mesh that no element uses and regions without elements:
/// legal, but usually a meshing mistake (a stray point, a physical group left empty).
fn warn_unused(src: &Source, at: Option<std::ops::Range<usize>>, key: &str, mesh: &SectionMesh) {
    let mut used = vec![false; mesh.nodes.len()];
    let mut filled = vec![false; mesh.regions.len()];
    for e in &mesh.elements {
        filled[e.region] = true;
        for &n in &e.nodes {
            used[n] = true;
        }
    }
    let unused: Vec<usize> = (0..used.len()).filter(|&n| !used[n]).collect();
    if let Some(first) = unused.first() {
        src.warn(
            at.clone(),
            Some(key.into()),
            format!(
                "{} node(s) of the mesh belong to no element (the first at ({:e}, {:e})); they \
                 are left out",
                unused.len(),
                mesh.nodes[*first][0],
                mesh.nodes[*first][1]
            ),
        );
    }
    for (r, _) in filled.iter().enumerate().filter(|(_, f)| !**f) {
        src.warn(
            at.clone(),
            Some(key.into()),
            format!("region `{}` has no elements", mesh.regions[r].name),
        );
    }
}

/// A ply of a laminate: the laminate's name and the ply's index in its stack (bottom first,
/// the mirrored plies of a symmetric laminate included).
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct PlyRef {
    pub laminate: String,
    pub ply: usize,
}

/// A validated section.
#[derive(Debug, Clone)]
pub struct SectionDef {
    pub shape: String,
    pub mesh: SectionMesh,
    /// For each region of the mesh, the laminate ply it is (regions of a laminate's tube or
    /// box walls, mesh regions given as `laminate` and `ply`), or `None` (a material of its
    /// own). Design variables move the regions through these.
    pub plies: Vec<Option<PlyRef>>,
    /// For each region, the name of its `[material.*]` (`None` for the materials a
    /// simple-format mesh defines itself): material design variables move it.
    pub materials: Vec<Option<String>>,
    /// The generator that made the mesh (tubes, boxes, channels, I beams), so that a ply
    /// thickness can move its nodes; `None` for mesh files and solid shapes (geometry fixed).
    pub generated: Option<Box<section::GeneratedSection>>,
    /// The laminate ply each of the generator's plies is, by the ply's name.
    pub generator_plies: BTreeMap<String, PlyRef>,
    /// A section given by its properties (`shape = "properties"`), not analysed: its mesh is
    /// empty, and only `section-property` design variables move it.
    pub given: Option<Box<GivenSection>>,
}

impl SectionDef {
    /// The section at the laminates and materials of `model` (a design moved by its variables):
    /// every region made of a laminate ply takes that ply's material and angle, every region of
    /// a deck material that material, and a generated section (tube, box, channel, I beam) is
    /// generated again with its plies' new thicknesses. What [`validate_one`] would build from
    /// the same deck with `model`, without reading the deck again.
    pub fn at(&self, model: &LaminateModel) -> Result<SectionDef, section::SectionError> {
        let ply = |t: &PlyRef| model.laminates[&t.laminate].stack.plies()[t.ply];
        let material_of = |r: usize| self.materials[r].as_ref().map(|m| model.materials[m]);
        let mut out = self.clone();
        match &self.generated {
            Some(g) => {
                let moved = g.with_plies(|wall, p| {
                    let region = if wall.is_empty() {
                        p.name.clone()
                    } else {
                        format!("{wall}/{}", p.name)
                    };
                    let mut p = p.clone();
                    if let Some(t) = self.generator_plies.get(&p.name) {
                        let q = ply(t);
                        (p.material, p.angle, p.thickness) = (q.material, q.angle, q.thickness);
                    } else if let Some(m) = self
                        .mesh
                        .regions
                        .iter()
                        .position(|r| r.name == region)
                        .and_then(material_of)
                    {
                        p.material = m;
                    }
                    p
                });
                out.mesh = moved.mesh()?;
                out.generated = Some(Box::new(moved));
            }
            None => {
                for (r, region) in out.mesh.regions.iter_mut().enumerate() {
                    if let Some(t) = &self.plies[r] {
                        let q = ply(t);
                        (region.material, region.ply_angle) = (q.material, q.angle);
                    } else if let Some(m) = material_of(r) {
                        region.material = m;
                    }
                }
            }
        }
        Ok(out)
    }
}

fn material<'m>(
    src: &Source,
    key: &str,
    name: &Spanned<String>,
    model: &'m LaminateModel,
) -> Result<&'m OrthotropicMaterial, DeckError> {
    model.materials.get(name.get_ref()).ok_or_else(|| {
        let known: Vec<&str> = model.materials.keys().map(String::as_str).collect();
        src.error(
            span(name),
            Some(key.into()),
            format!(
                "undefined material `{}`{}",
                name.get_ref(),
                suggestion(name.get_ref(), &known)
            ),
        )
    })
}

/// The plies of a named laminate as section plies (`elements` through each).
fn laminate_plies(
    src: &Source,
    key: &str,
    name: &Spanned<String>,
    model: &LaminateModel,
    elements: usize,
    tags: &mut HashMap<String, PlyRef>,
) -> Result<Vec<PlySpec>, DeckError> {
    let def = model.laminates.get(name.get_ref()).ok_or_else(|| {
        let known: Vec<&str> = model.laminates.keys().map(String::as_str).collect();
        src.error(
            span(name),
            Some(key.into()),
            format!(
                "undefined laminate `{}`{}",
                name.get_ref(),
                suggestion(name.get_ref(), &known)
            ),
        )
    })?;
    Ok(def
        .stack
        .plies()
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let region = format!("{}.plies.{i}", name.get_ref());
            tags.insert(
                region.clone(),
                PlyRef {
                    laminate: name.get_ref().clone(),
                    ply: i,
                },
            );
            PlySpec::new(region, p.material, p.angle, p.thickness, elements)
        })
        .collect())
}

/// A mesh region given as a laminate ply: the ply, its material and its angle (radians).
/// `key` is the region's key with a trailing dot.
fn laminate_ply(
    src: &Source,
    key: &str,
    r: &RawRegion,
    lam: &Spanned<String>,
    model: &LaminateModel,
) -> Result<(PlyRef, OrthotropicMaterial, f64), DeckError> {
    for (k, given) in [
        ("material", r.material.as_ref().and_then(span)),
        ("angle", r.angle.as_ref().and_then(span)),
    ] {
        if given.is_some() {
            return Err(src.error(
                given,
                Some(format!("{key}{k}")),
                "a region given as a laminate ply takes the ply's material and angle: give either material and angle, or laminate and ply",
            ));
        }
    }
    let def = model.laminates.get(lam.get_ref()).ok_or_else(|| {
        let known: Vec<&str> = model.laminates.keys().map(String::as_str).collect();
        src.error(
            span(lam),
            Some(format!("{key}laminate")),
            format!(
                "undefined laminate `{}`{}",
                lam.get_ref(),
                suggestion(lam.get_ref(), &known)
            ),
        )
    })?;
    let plies = def.stack.plies();
    let ply = r.ply.as_ref().ok_or_else(|| {
        src.error(
            span(lam),
            Some(format!("{key}ply")),
            format!(
                "missing value: ply (the ply's index in laminate `{}`, 0 to {})",
                lam.get_ref(),
                plies.len() - 1
            ),
        )
    })?;
    let i = *ply.get_ref();
    if i < 0 || i as usize >= plies.len() {
        return Err(src.error(
            span(ply),
            Some(format!("{key}ply")),
            format!(
                "ply {i} does not exist: laminate `{}` has plies 0 to {} (counting the mirrored plies of a symmetric laminate)",
                lam.get_ref(),
                plies.len() - 1
            ),
        ));
    }
    let p = &plies[i as usize];
    Ok((
        PlyRef {
            laminate: lam.get_ref().clone(),
            ply: i as usize,
        },
        p.material,
        p.angle,
    ))
}

/// Validate one section (building its mesh; mesh files are read relative to the deck).
pub fn validate_one(
    src: &Source,
    name: &str,
    s: &Spanned<RawSection>,
    model: &LaminateModel,
) -> Result<SectionDef, DeckError> {
    let deck_dir = src.file.parent().unwrap_or(Path::new("."));
    let k = |key: &str| format!("section.{name}.{key}");
    let raw = s.get_ref();
    let table = span(s);
    let shape = required(
        src,
        table.clone(),
        &k("shape"),
        &raw.shape,
        &format!("shape ({})", super::keys::SECTION_SHAPE.listed()),
    )?;
    let shape_name = shape.get_ref().as_str();
    let shape_ctx = Shape {
        src,
        name,
        raw,
        table: table.clone(),
        model,
        shape_name,
        deck_dir,
    };
    shape_ctx.check_keys()?;
    let bad = |e: section::SectionError| shape_ctx.bad(e);
    // region name → laminate ply, for the regions made of laminate plies; region name → deck
    // material for the others (a solid section: one material for all)
    let mut tags: HashMap<String, PlyRef> = HashMap::new();
    let mut materials: HashMap<String, String> = HashMap::new();
    let solid_material = raw.material.as_ref().map(|m| m.get_ref().clone());
    let mut generated = None;
    if shape_name == "properties" {
        return Ok(SectionDef {
            shape: shape_name.to_string(),
            mesh: SectionMesh::default(),
            plies: Vec::new(),
            materials: Vec::new(),
            generated: None,
            generator_plies: BTreeMap::new(),
            given: Some(Box::new(shape_ctx.given()?)),
        });
    }
    let mesh = match shape_name {
        "circle" => shape_ctx.circle()?,
        "rectangle" => shape_ctx.rectangle()?,
        "tube" => {
            let (mesh, g) = shape_ctx.tube(&mut tags, &mut materials)?;
            generated = g;
            mesh
        }
        "box" | "channel" | "i-beam" => {
            let (mesh, g) = shape_ctx.walled(&mut tags)?;
            generated = g;
            mesh
        }
        "mesh" => shape_ctx.mesh_file(&mut tags, &mut materials)?,
        other => {
            return Err(src.error(
                span(shape),
                Some(k("shape")),
                super::keys::SECTION_SHAPE.unknown("shape", other),
            ));
        }
    };
    mesh.validate().map_err(bad)?;
    // the warping analysis's memory, estimated before anything is allocated for it
    crate::deck::check::memory_need(
        src,
        &format!("section.{name}"),
        table.clone(),
        mesh.elements.len(),
        crate::limits::SECTION_BYTES_PER_ELEMENT,
        "analysis",
    )?;
    // a box names its regions "<wall>/<ply name>"
    let plies: Vec<Option<PlyRef>> = mesh
        .regions
        .iter()
        .map(|r| {
            let ply = r.name.rsplit_once('/').map_or(r.name.as_str(), |(_, p)| p);
            tags.get(&r.name).or_else(|| tags.get(ply)).cloned()
        })
        .collect();
    let materials = mesh
        .regions
        .iter()
        .zip(&plies)
        .map(|(r, tag): (_, &Option<PlyRef>)| match tag {
            Some(t) => Some(model.laminates[&t.laminate].ply_materials[t.ply].clone()),
            None if shape_name == "mesh" => materials.get(&r.name).cloned(),
            None => materials
                .get(&r.name)
                .cloned()
                .or_else(|| solid_material.clone()),
        })
        .collect();
    let generator_plies = if generated.is_some() {
        tags.into_iter().collect()
    } else {
        BTreeMap::new()
    };
    Ok(SectionDef {
        shape: shape_name.to_string(),
        mesh,
        plies,
        materials,
        generated,
        generator_plies,
        given: None,
    })
}

/// Validate the sections of a deck.
pub fn validate(
    src: &Source,
    sections: &BTreeMap<String, Spanned<RawSection>>,
    model: &LaminateModel,
) -> Result<BTreeMap<String, SectionDef>, DeckError> {
    sections
        .iter()
        .map(|(n, s)| Ok((n.clone(), validate_one(src, n, s, model)?)))
        .collect()
}
