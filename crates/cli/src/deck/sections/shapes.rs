//! The validation of each generated section shape: solid circles and rectangles, tubes,
//! thin-walled boxes, channels and I beams (mesh files: `mesh_file.rs`).

use super::*;

/// One `[section.NAME]` table being validated: what every shape's validation reads.
pub(super) struct Shape<'a> {
    pub(super) src: &'a Source,
    pub(super) name: &'a str,
    pub(super) raw: &'a RawSection,
    pub(super) table: Option<std::ops::Range<usize>>,
    pub(super) model: &'a LaminateModel,
    pub(super) shape_name: &'a str,
    pub(super) deck_dir: &'a Path,
}

impl Shape<'_> {
    pub(super) fn k(&self, key: &str) -> String {
        format!("section.{}.{key}", self.name)
    }

    /// A section error as bad input at the table.
    pub(super) fn bad(&self, e: section::SectionError) -> DeckError {
        self.src.error(
            self.table.clone(),
            Some(format!("section.{}", self.name)),
            e.to_string(),
        )
    }

    /// Only the keys of this shape are given.
    pub(super) fn check_keys(&self) -> Result<(), DeckError> {
        let Shape {
            src,
            raw,
            shape_name,
            ..
        } = *self;
        let k = |key: &str| self.k(key);
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
            ("stiffness", raw.stiffness.as_ref().map(|x| x.span())),
            ("EA", raw.ea.as_ref().map(|x| x.span())),
            ("GA2", raw.ga2.as_ref().map(|x| x.span())),
            ("GA3", raw.ga3.as_ref().map(|x| x.span())),
            ("GJ", raw.gj.as_ref().map(|x| x.span())),
            ("EI2", raw.ei2.as_ref().map(|x| x.span())),
            ("EI3", raw.ei3.as_ref().map(|x| x.span())),
            (
                "tension_centre",
                raw.tension_centre.as_ref().map(|x| x.span()),
            ),
            ("shear_centre", raw.shear_centre.as_ref().map(|x| x.span())),
            ("mass_matrix", raw.mass_matrix.as_ref().map(|x| x.span())),
            (
                "mass_per_length",
                raw.mass_per_length.as_ref().map(|x| x.span()),
            ),
            ("mass_centre", raw.mass_centre.as_ref().map(|x| x.span())),
            ("inertia", raw.inertia.as_ref().map(|x| x.span())),
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
            "properties" => &[
                "stiffness",
                "EA",
                "GA2",
                "GA3",
                "GJ",
                "EI2",
                "EI3",
                "tension_centre",
                "shear_centre",
                "mass_matrix",
                "mass_per_length",
                "mass_centre",
                "inertia",
            ],
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
        Ok(())
    }

    /// The `elements` pair of the shape, or `default`.
    pub(super) fn elements_pair(&self, default: [usize; 2]) -> Result<[usize; 2], DeckError> {
        let Shape {
            src,
            raw,
            shape_name,
            ..
        } = *self;
        let k = |key: &str| self.k(key);
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
    }

    /// The material and fibre angle (degrees) of a solid section.
    pub(super) fn solid(&self) -> Result<(&OrthotropicMaterial, f64), DeckError> {
        let Shape {
            src,
            raw,
            ref table,
            model,
            ..
        } = *self;
        let k = |key: &str| self.k(key);
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
        Ok((m, angle))
    }

    /// `shape = "circle"`: a solid circle.
    pub(super) fn circle(&self) -> Result<SectionMesh, DeckError> {
        let Shape {
            src,
            raw,
            ref table,
            ..
        } = *self;
        let k = |key: &str| self.k(key);
        let bad = |e: section::SectionError| self.bad(e);
        let elements_pair = |default: [usize; 2]| self.elements_pair(default);
        let solid = || self.solid();
        Ok({
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
        })
    }

    /// `shape = "rectangle"`: a solid rectangle.
    pub(super) fn rectangle(&self) -> Result<SectionMesh, DeckError> {
        let Shape {
            src,
            raw,
            ref table,
            ..
        } = *self;
        let k = |key: &str| self.k(key);
        let bad = |e: section::SectionError| self.bad(e);
        let elements_pair = |default: [usize; 2]| self.elements_pair(default);
        let solid = || self.solid();
        Ok({
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
        })
    }

    /// `shape = "tube"`: a tube of a laminate's plies or of plies given here.
    pub(super) fn tube(
        &self,
        tags: &mut HashMap<String, PlyRef>,
        materials: &mut HashMap<String, String>,
    ) -> Result<Generated, DeckError> {
        let Shape {
            src,
            name,
            raw,
            ref table,
            model,
            ..
        } = *self;
        let k = |key: &str| self.k(key);
        let bad = |e: section::SectionError| self.bad(e);
        let generated;
        let mesh = {
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
                    laminate_plies(src, &k("laminate"), l, model, n, tags)?
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
        };
        Ok((mesh, generated))
    }

    /// `shape = "box"`, `"channel"` or `"i-beam"`: thin walls of laminates.
    pub(super) fn walled(
        &self,
        tags: &mut HashMap<String, PlyRef>,
    ) -> Result<Generated, DeckError> {
        let Shape {
            src,
            raw,
            ref table,
            shape_name,
            ..
        } = *self;
        let k = |key: &str| self.k(key);
        let bad = |e: section::SectionError| self.bad(e);
        let elements_pair = |default: [usize; 2]| self.elements_pair(default);
        let generated;
        let mesh = {
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
            let walls = self.walls(n, tags)?;
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
        };
        Ok((mesh, generated))
    }

    /// The walls of a box, channel or I beam: one laminate for all (`laminate`) or one per wall
    /// (`walls`), `n` elements through each ply (an I beam's web as the left wall).
    pub(super) fn walls(
        &self,
        n: usize,
        tags: &mut HashMap<String, PlyRef>,
    ) -> Result<BoxWalls, DeckError> {
        let Shape {
            src,
            name,
            raw,
            ref table,
            model,
            shape_name,
            ..
        } = *self;
        let k = |key: &str| self.k(key);
        let (open, ibeam) = (shape_name == "channel", shape_name == "i-beam");
        Ok(match (&raw.walls, &raw.laminate) {
            (Some(_), Some(l)) => {
                return Err(src.error(
                    span(l),
                    Some(k("laminate")),
                    "give either walls or laminate, not both",
                ));
            }
            (None, Some(l)) => {
                BoxWalls::uniform(laminate_plies(src, &k("laminate"), l, model, n, tags)?)
            }
            (Some(wt), None) => {
                let wr = wt.get_ref();
                let mut wall =
                    |key: &str, f: &Option<Spanned<String>>| -> Result<Vec<PlySpec>, DeckError> {
                        let wk = format!("section.{name}.walls.{key}");
                        let l = required(src, span(wt), &wk, f, "a laminate name")?;
                        laminate_plies(src, &wk, l, model, n, tags)
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
        })
    }
}

/// A mesh and the generator that made it (`None`: read or solid).
pub(super) type Generated = (SectionMesh, Option<Box<section::GeneratedSection>>);
