//! The validation of `shape = "mesh"`: a mesh file, gmsh with its regions given in the deck or
//! the simple format.

use super::shapes::Shape;
use super::*;

impl Shape<'_> {
    /// `shape = "mesh"`: a mesh file (gmsh, with its regions given here, or the simple format).
    pub(super) fn mesh_file(
        &self,
        tags: &mut HashMap<String, PlyRef>,
        materials: &mut HashMap<String, String>,
    ) -> Result<SectionMesh, DeckError> {
        let Shape {
            src,
            name,
            raw,
            ref table,
            model,
            deck_dir,
            ..
        } = *self;
        let k = |key: &str| self.k(key);
        Ok({
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
                            crate::deck::keys::MESH_FORMAT.unknown("mesh format", other),
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
                    let frame = region_frame(src, &rk, rr)?;
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
        })
    }
}

/// The wall frame of a mesh region (`frame`, with `tangent_angle` or `centre`); `key` gives
/// the region's keys.
fn region_frame(
    src: &Source,
    key: &dyn Fn(&str) -> String,
    rr: &RawRegion,
) -> Result<WallFrame, DeckError> {
    let rk = key;
    Ok(match rr.frame.as_ref().map(|f| f.get_ref().as_str()) {
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
            return Err(src.error(
                span(f),
                Some(rk("frame")),
                crate::deck::keys::WALL_FRAME.unknown("wall frame", other),
            ));
        }
    })
}
