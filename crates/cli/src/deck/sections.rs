//! Validation of `[section.*]` into `section` meshes.

use std::collections::{BTreeMap, HashMap};
use std::path::Path;

use laminate::OrthotropicMaterial;
use section::{BoxWalls, ElementDirection, PlySpec, RegionSpec, SectionMesh, WallFrame};
use toml::Spanned;

use super::check::{count, finite, mesh_size, not_applicable, positive, required, span};
use super::laminates::{LaminateModel, suggestion};
use super::raw::{RawRegion, RawSection};
use super::{DeckError, Source};

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
        "shape (\"rectangle\", \"circle\", \"tube\", \"box\" or \"mesh\")",
    )?;
    let shape_name = shape.get_ref().as_str();
    // keys that belong to some shapes only
    let sp = |x: Option<std::ops::Range<usize>>| x;
    let specific = [
        ("width", sp(raw.width.as_ref().map(|x| x.span()))),
        ("radius", raw.radius.as_ref().map(|x| x.span())),
        ("height", raw.height.as_ref().map(|x| x.span())),
        ("material", raw.material.as_ref().map(|x| x.span())),
        ("angle", raw.angle.as_ref().map(|x| x.span())),
        ("elements", raw.elements.as_ref().map(|x| x.span())),
        ("inner_radius", raw.inner_radius.as_ref().map(|x| x.span())),
        (
            "elements_around",
            raw.elements_around.as_ref().map(|x| x.span()),
        ),
        ("plies", raw.plies.as_ref().map(|x| x.span())),
        ("laminate", raw.laminate.as_ref().map(|x| x.span())),
        (
            "elements_per_ply",
            raw.elements_per_ply.as_ref().map(|x| x.span()),
        ),
        ("walls", raw.walls.as_ref().map(|x| x.span())),
        ("file", raw.file.as_ref().map(|x| x.span())),
        ("format", raw.format.as_ref().map(|x| x.span())),
        ("regions", raw.regions.as_ref().map(|x| x.span())),
    ];
    let allowed: &[&str] = match shape_name {
        "rectangle" => &["width", "height", "material", "angle", "elements"],
        "circle" => &["radius", "material", "angle", "elements"],
        "tube" => &[
            "inner_radius",
            "elements_around",
            "plies",
            "laminate",
            "elements_per_ply",
        ],
        "box" | "channel" | "i-beam" => &[
            "width",
            "height",
            "laminate",
            "walls",
            "elements",
            "elements_per_ply",
        ],
        "mesh" => &["file", "format", "regions"],
        _ => &[],
    };
    if !allowed.is_empty() {
        for (key, at) in specific {
            if at.is_some() && !allowed.contains(&key) {
                return Err(src.error(
                    at,
                    Some(k(key)),
                    format!("this key does not apply to shape = \"{shape_name}\""),
                ));
            }
        }
    }
    let elements_pair = |default: [usize; 2]| -> Result<[usize; 2], DeckError> {
        match &raw.elements {
            None => Ok(default),
            Some(e) if e.get_ref().len() == 2 => {
                let n = [
                    count(src, &k("elements[0]"), &e.get_ref()[0], 1)?,
                    count(src, &k("elements[1]"), &e.get_ref()[1], 1)?,
                ];
                mesh_size(src, &k("elements"), span(e), n[0].saturating_mul(n[1]))?;
                Ok(n)
            }
            Some(e) => Err(src.error(
                span(e),
                Some(k("elements")),
                if shape_name == "circle" {
                    "expected two counts: [around the rim, from the core to the rim]"
                } else if shape_name == "i-beam" {
                    "expected two counts: [along each flange beside the web, along the web]"
                } else {
                    "expected two counts: [along the width, along the height]"
                },
            )),
        }
    };
    let bad = |e: section::SectionError| {
        src.error(
            table.clone(),
            Some(format!("section.{name}")),
            e.to_string(),
        )
    };
    // the material and fibre angle (degrees) of a solid section
    let solid = || {
        let m = material(
            src,
            &k("material"),
            required(
                src,
                table.clone(),
                &k("material"),
                &raw.material,
                "material",
            )?,
            model,
        )?;
        let angle = raw
            .angle
            .as_ref()
            .map(|a| finite(src, &k("angle"), a, "degrees"))
            .transpose()?
            .unwrap_or(0.0);
        Ok::<_, DeckError>((m, angle))
    };
    // region name → laminate ply, for the regions made of laminate plies; region name → deck
    // material for the others (a solid section: one material for all)
    let mut tags: HashMap<String, PlyRef> = HashMap::new();
    let mut materials: HashMap<String, String> = HashMap::new();
    let solid_material = raw.material.as_ref().map(|m| m.get_ref().clone());
    let mut generated = None;
    let mesh = match shape_name {
        "circle" => {
            let r = positive(
                src,
                &k("radius"),
                required(src, table.clone(), &k("radius"), &raw.radius, "radius (m)")?,
                "m",
            )?;
            let (m, angle) = solid()?;
            let [around, radial] = elements_pair([16, 4])?;
            if !around.is_multiple_of(4) || around < 8 {
                return Err(src.error(
                    raw.elements.as_ref().map(|e| e.span()),
                    Some(k("elements[0]")),
                    format!(
                        "{around} elements around the circle: a multiple of 4, at least 8, is \
                         needed (the mesh is a square core with four curved patches)"
                    ),
                ));
            }
            section::circle(r, around, radial, *m, angle.to_radians()).map_err(bad)?
        }
        "rectangle" => {
            let w = positive(
                src,
                &k("width"),
                required(src, table.clone(), &k("width"), &raw.width, "width (m)")?,
                "m",
            )?;
            let h = positive(
                src,
                &k("height"),
                required(src, table.clone(), &k("height"), &raw.height, "height (m)")?,
                "m",
            )?;
            let (m, angle) = solid()?;
            // default: about square elements, 8 along the longer side
            let (n2, n3) = if w >= h {
                (8, ((8.0 * h / w).round() as usize).max(2))
            } else {
                (((8.0 * w / h).round() as usize).max(2), 8)
            };
            let [n2, n3] = elements_pair([n2, n3])?;
            section::rectangle(w, h, n2, n3, *m, angle.to_radians()).map_err(bad)?
        }
        "tube" => {
            let r = positive(
                src,
                &k("inner_radius"),
                required(
                    src,
                    table.clone(),
                    &k("inner_radius"),
                    &raw.inner_radius,
                    "inner_radius (m)",
                )?,
                "m",
            )?;
            let around = raw
                .elements_around
                .as_ref()
                .map(|n| count(src, &k("elements_around"), n, 3))
                .transpose()?
                .unwrap_or(48);
            if let (Some(n), true) = (&raw.elements_around, around < COARSE_AROUND) {
                src.warn(
                    span(n),
                    Some(k("elements_around")),
                    format!(
                        "{around} elements around the tube is coarse: on the paper's tube the \
                         stiffness is 2.4 % low with 4, 0.5 % with 6, 0.16 % with 8 (48 is the \
                         default)"
                    ),
                );
            }
            let plies = match (&raw.plies, &raw.laminate) {
                (Some(_), Some(l)) => {
                    return Err(src.error(
                        span(l),
                        Some(k("laminate")),
                        "give either plies or laminate, not both",
                    ));
                }
                (None, Some(l)) => {
                    let n = raw
                        .elements_per_ply
                        .as_ref()
                        .map(|n| count(src, &k("elements_per_ply"), n, 1))
                        .transpose()?
                        .unwrap_or(2);
                    laminate_plies(src, &k("laminate"), l, model, n, &mut tags)?
                }
                (Some(plies), None) => {
                    not_applicable(
                        src,
                        &k("elements_per_ply"),
                        &raw.elements_per_ply,
                        "a tube with plies (use plies[i].elements)",
                    )?;
                    if plies.get_ref().is_empty() {
                        return Err(src.error(
                            span(plies),
                            Some(k("plies")),
                            "a tube needs at least one ply",
                        ));
                    }
                    let mut out = Vec::new();
                    for (i, p) in plies.get_ref().iter().enumerate() {
                        let pk = |key: &str| format!("section.{name}.plies[{i}].{key}");
                        let r = p.get_ref();
                        let mname =
                            required(src, span(p), &pk("material"), &r.material, "material")?;
                        let m = material(src, &pk("material"), mname, model)?;
                        materials.insert(format!("plies.{i}"), mname.get_ref().clone());
                        let t = positive(
                            src,
                            &pk("thickness"),
                            required(
                                src,
                                span(p),
                                &pk("thickness"),
                                &r.thickness,
                                "thickness (m)",
                            )?,
                            "m",
                        )?;
                        let a = finite(
                            src,
                            &pk("angle"),
                            required(src, span(p), &pk("angle"), &r.angle, "angle (degrees)")?,
                            "degrees",
                        )?;
                        let n = r
                            .elements
                            .as_ref()
                            .map(|n| count(src, &pk("elements"), n, 1))
                            .transpose()?
                            .unwrap_or(2);
                        out.push(PlySpec::new(format!("plies.{i}"), *m, a.to_radians(), t, n));
                    }
                    out
                }
                (None, None) => {
                    return Err(src.error(
                        table.clone(),
                        Some(k("plies")),
                        "missing value: plies (or laminate) for a tube",
                    ));
                }
            };
            let through: usize = plies.iter().map(|p| p.elements).sum();
            mesh_size(
                src,
                &k("elements_around"),
                table.clone(),
                around.saturating_mul(through),
            )?;
            let g = section::GeneratedSection::Tube {
                inner_radius: r,
                plies,
                circumferential: around,
            };
            let mesh = g.mesh().map_err(bad)?;
            generated = Some(Box::new(g));
            mesh
        }
        "box" | "channel" | "i-beam" => {
            let open = shape_name == "channel";
            let ibeam = shape_name == "i-beam";
            let w = positive(
                src,
                &k("width"),
                required(
                    src,
                    table.clone(),
                    &k("width"),
                    &raw.width,
                    "width (m), outer",
                )?,
                "m",
            )?;
            let h = positive(
                src,
                &k("height"),
                required(
                    src,
                    table.clone(),
                    &k("height"),
                    &raw.height,
                    "height (m), outer",
                )?,
                "m",
            )?;
            let n = raw
                .elements_per_ply
                .as_ref()
                .map(|n| count(src, &k("elements_per_ply"), n, 1))
                .transpose()?
                .unwrap_or(1);
            let walls = match (&raw.walls, &raw.laminate) {
                (Some(_), Some(l)) => {
                    return Err(src.error(
                        span(l),
                        Some(k("laminate")),
                        "give either walls or laminate, not both",
                    ));
                }
                (None, Some(l)) => {
                    BoxWalls::uniform(laminate_plies(src, &k("laminate"), l, model, n, &mut tags)?)
                }
                (Some(wt), None) => {
                    let wr = wt.get_ref();
                    let mut wall = |key: &str,
                                    f: &Option<Spanned<String>>|
                     -> Result<Vec<PlySpec>, DeckError> {
                        let wk = format!("section.{name}.walls.{key}");
                        let l = required(src, span(wt), &wk, f, "a laminate name")?;
                        laminate_plies(src, &wk, l, model, n, &mut tags)
                    };
                    // which walls the shape has
                    for (key, f, has) in [
                        ("left", &wr.left, !ibeam),
                        ("right", &wr.right, !ibeam && !open),
                        ("web", &wr.web, ibeam),
                    ] {
                        if let (Some(f), false) = (f, has) {
                            return Err(src.error(
                                span(f),
                                Some(format!("section.{name}.walls.{key}")),
                                match (key, ibeam) {
                                    ("right", false) => {
                                        "a channel is open on its right (+x2) \
                                                         side: it has no right wall"
                                    }
                                    (_, true) => "an I beam's walls are top, bottom and web",
                                    _ => "only an I beam (shape = \"i-beam\") has a web",
                                },
                            ));
                        }
                    }
                    if ibeam {
                        BoxWalls {
                            top: wall("top", &wr.top)?,
                            bottom: wall("bottom", &wr.bottom)?,
                            left: wall("web", &wr.web)?,
                            right: Vec::new(),
                        }
                    } else {
                        let right = if open {
                            Vec::new()
                        } else {
                            wall("right", &wr.right)?
                        };
                        BoxWalls {
                            top: wall("top", &wr.top)?,
                            bottom: wall("bottom", &wr.bottom)?,
                            left: wall("left", &wr.left)?,
                            right,
                        }
                    }
                }
                (None, None) => {
                    return Err(src.error(
                        table.clone(),
                        Some(k("walls")),
                        format!("missing value: walls (or laminate) for a {shape_name}"),
                    ));
                }
            };
            let [nw, nh] = elements_pair(if ibeam { [4, 8] } else { [8, 8] })?;
            let g = if ibeam {
                // an I beam's web came as the left wall
                section::GeneratedSection::I {
                    width: w,
                    height: h,
                    walls: section::IWalls {
                        top: walls.top,
                        bottom: walls.bottom,
                        web: walls.left,
                    },
                    n_side: nw,
                    n_web: nh,
                }
            } else {
                section::GeneratedSection::Walled {
                    width: w,
                    height: h,
                    walls: if open {
                        BoxWalls {
                            right: Vec::new(),
                            ..walls
                        }
                    } else {
                        walls
                    },
                    n_width: nw,
                    n_height: nh,
                    open,
                }
            };
            let mesh = g.mesh().map_err(bad)?;
            generated = Some(Box::new(g));
            mesh
        }
        "mesh" => {
            let file = required(
                src,
                table.clone(),
                &k("file"),
                &raw.file,
                "file (path of the mesh, relative to the deck)",
            )?;
            let path = deck_dir.join(file.get_ref());
            let text = crate::limits::read_text(&path).map_err(|e| {
                src.error(
                    span(file),
                    Some(k("file")),
                    format!("cannot read the mesh {}: {e}", path.display()),
                )
            })?;
            let format = match &raw.format {
                Some(f) => match f.get_ref().as_str() {
                    "gmsh" | "simple" => f.get_ref().clone(),
                    other => {
                        return Err(src.error(
                            span(f),
                            Some(k("format")),
                            format!(
                                "unknown mesh format `{other}`: expected \"gmsh\" or \"simple\""
                            ),
                        ));
                    }
                },
                None if file.get_ref().ends_with(".msh") => "gmsh".into(),
                None => "simple".into(),
            };
            let in_mesh = |e: section::SectionError| {
                let where_ = match &e {
                    section::SectionError::Parse { line, .. } => {
                        format!("{}:{line}", path.display())
                    }
                    _ => path.display().to_string(),
                };
                src.error(
                    span(file),
                    Some(k("file")),
                    format!("in the mesh {where_}: {e}"),
                )
            };
            if format == "gmsh" {
                let regions = raw.regions.as_ref().ok_or_else(|| {
                    src.error(
                        table.clone(),
                        Some(k("regions")),
                        "missing value: regions (material and angle of each physical group)",
                    )
                })?;
                let mut specs = Vec::new();
                for (rname, r) in regions.get_ref() {
                    let rk = |key: &str| format!("section.{name}.regions.{rname}.{key}");
                    let rr = r.get_ref();
                    let (m, angle) = match &rr.laminate {
                        Some(l) => {
                            let p = laminate_ply(src, &rk(""), rr, l, model)?;
                            tags.insert(rname.clone(), p.0);
                            (p.1, p.2)
                        }
                        None => {
                            not_applicable(src, &rk("ply"), &rr.ply, "a region without laminate")?;
                            let mname = required(
                                src,
                                span(r),
                                &rk("material"),
                                &rr.material,
                                "material (or laminate and ply)",
                            )?;
                            let m = material(src, &rk("material"), mname, model)?;
                            materials.insert(rname.clone(), mname.get_ref().clone());
                            let angle = rr
                                .angle
                                .as_ref()
                                .map(|a| finite(src, &rk("angle"), a, "degrees"))
                                .transpose()?
                                .unwrap_or(0.0)
                                .to_radians();
                            (*m, angle)
                        }
                    };
                    let frame = match rr.frame.as_ref().map(|f| f.get_ref().as_str()) {
                        None | Some("tangent") => {
                            not_applicable(src, &rk("centre"), &rr.centre, "frame = \"tangent\"")?;
                            let b = rr
                                .tangent_angle
                                .as_ref()
                                .map(|a| finite(src, &rk("tangent_angle"), a, "degrees"))
                                .transpose()?
                                .unwrap_or(0.0);
                            WallFrame::Tangent(b.to_radians())
                        }
                        Some("radial") => {
                            not_applicable(
                                src,
                                &rk("tangent_angle"),
                                &rr.tangent_angle,
                                "frame = \"radial\"",
                            )?;
                            WallFrame::Radial {
                                centre: rr.centre.as_ref().map_or([0.0, 0.0], |c| *c.get_ref()),
                            }
                        }
                        Some(dir @ ("xi" | "eta")) => {
                            let context = format!("frame = \"{dir}\"");
                            not_applicable(src, &rk("tangent_angle"), &rr.tangent_angle, &context)?;
                            not_applicable(src, &rk("centre"), &rr.centre, &context)?;
                            WallFrame::AlongElement(if dir == "xi" {
                                ElementDirection::Xi
                            } else {
                                ElementDirection::Eta
                            })
                        }
                        Some(other) => {
                            let f = rr.frame.as_ref().expect("matched Some");
                            return Err(src.error(span(f), Some(rk("frame")), format!("unknown wall frame `{other}`: expected \"tangent\", \"radial\", \"xi\" or \"eta\"")));
                        }
                    };
                    specs.push(RegionSpec {
                        name: rname.clone(),
                        material: m,
                        ply_angle: angle,
                        frame,
                    });
                }
                let mesh = section::parse_gmsh(&text, &specs).map_err(in_mesh)?;
                warn_unused(src, span(file), &k("file"), &mesh);
                mesh
            } else {
                if let Some(r) = &raw.regions {
                    return Err(src.error(
                        span(r),
                        Some(k("regions")),
                        "a simple-format mesh defines its regions itself",
                    ));
                }
                let mats: Vec<(&str, OrthotropicMaterial)> = model
                    .materials
                    .iter()
                    .map(|(n, m)| (n.as_str(), *m))
                    .collect();
                let mesh = section::parse_simple(&text, &mats).map_err(in_mesh)?;
                warn_unused(src, span(file), &k("file"), &mesh);
                mesh
            }
        }
        other => {
            return Err(src.error(
                span(shape),
                Some(k("shape")),
                format!(
                    "unknown shape `{other}`: expected \"rectangle\", \"circle\", \"tube\", \"box\", \"channel\", \"i-beam\" or \"mesh\"{}",
                    suggestion(
                        other,
                        &["rectangle", "circle", "tube", "box", "channel", "i-beam", "mesh"]
                    )
                ),
            ));
        }
    };
    mesh.validate().map_err(bad)?;
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
