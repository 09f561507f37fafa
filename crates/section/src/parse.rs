//! Section meshes from text: Gmsh `.msh` version 4.1 ASCII, and a simple line format.
//!
//! No file access here: the caller reads the file and passes its text.

use std::collections::HashMap;

use laminate::OrthotropicMaterial;

use crate::SectionError;
use crate::element::ElementKind;
use crate::mesh::{Element, ElementDirection, Region, SectionMesh, WallFrame};

/// Properties of a named region: a Gmsh physical surface group, or a ply.
#[derive(Clone, Debug, PartialEq)]
pub struct RegionSpec {
    pub name: String,
    pub material: OrthotropicMaterial,
    /// Ply angle (radians).
    pub ply_angle: f64,
    pub frame: WallFrame,
}

fn parse_err(line: usize, message: impl Into<String>) -> SectionError {
    SectionError::Parse {
        line,
        message: message.into(),
    }
}

/// Lines with their 1-based numbers, skipping blank ones.
struct Lines<'a> {
    it: std::iter::Peekable<std::iter::Enumerate<std::str::Lines<'a>>>,
    last: usize,
}

impl<'a> Lines<'a> {
    fn new(text: &'a str) -> Self {
        Self {
            it: text.lines().enumerate().peekable(),
            last: 0,
        }
    }

    fn next_line(&mut self) -> Result<(usize, &'a str), SectionError> {
        for (i, l) in self.it.by_ref() {
            self.last = i + 1;
            let t = l.trim();
            if !t.is_empty() {
                return Ok((i + 1, t));
            }
        }
        Err(parse_err(self.last, "unexpected end of the mesh text"))
    }

    /// The next line split into numbers of type `T`.
    fn numbers<T: std::str::FromStr>(&mut self) -> Result<(usize, Vec<T>), SectionError> {
        let (n, l) = self.next_line()?;
        let v = l
            .split_whitespace()
            .map(|w| {
                w.parse::<T>()
                    .map_err(|_| parse_err(n, format!("'{w}' is not a valid number")))
            })
            .collect::<Result<Vec<T>, _>>()?;
        Ok((n, v))
    }
}

fn need<T: Copy>(v: &[T], k: usize, line: usize, what: &str) -> Result<T, SectionError> {
    v.get(k)
        .copied()
        .ok_or_else(|| parse_err(line, format!("missing {what}")))
}

/// Gmsh element type → section element kind.
fn gmsh_kind(t: usize, line: usize) -> Result<Option<ElementKind>, SectionError> {
    Ok(match t {
        9 => Some(ElementKind::Tri6),
        16 => Some(ElementKind::Quad8),
        10 => Some(ElementKind::Quad9),
        2 | 3 => {
            return Err(parse_err(
                line,
                "linear (3-node or 4-node) surface elements are far too stiff for section \
                 analysis: mesh with second-order elements (Gmsh: Mesh.ElementOrder = 2)",
            ));
        }
        // Points, lines and other non-surface elements are ignored.
        15 | 1 | 8 | 26 | 27 | 28 => None,
        other => {
            return Err(parse_err(
                line,
                format!("unsupported Gmsh element type {other}"),
            ));
        }
    })
}

/// A Gmsh surface element as read: its line number, kind, node tags and entity tag.
type GmshElement = (usize, ElementKind, Vec<u64>, i64);

/// The sections of a Gmsh file that the mesh is built from.
#[derive(Default)]
struct GmshContents {
    /// Physical group names by `(dimension, tag)`.
    physical_names: HashMap<(usize, i64), String>,
    /// The physical tags of each surface entity.
    surface_physical: HashMap<i64, Vec<i64>>,
    /// Index into `nodes` of each node tag.
    node_index: HashMap<u64, usize>,
    /// Node coordinates `(x₂, x₃)` (m).
    nodes: Vec<[f64; 2]>,
    /// The surface elements, in the order of the file.
    elements: Vec<GmshElement>,
    /// Whether a `$MeshFormat` section was read.
    seen_format: bool,
}

impl GmshContents {
    /// Read the sections of the text of a Gmsh file; unknown sections are skipped.
    fn read(text: &str) -> Result<Self, SectionError> {
        let mut lines = Lines::new(text);
        let mut contents = Self::default();
        while let Ok((n, l)) = lines.next_line() {
            match l {
                "$MeshFormat" => {
                    check_gmsh_format(&mut lines)?;
                    contents.seen_format = true;
                }
                "$PhysicalNames" => contents.read_physical_names(&mut lines, n)?,
                "$Entities" => contents.read_entities(&mut lines)?,
                "$Nodes" => contents.read_nodes(&mut lines)?,
                "$Elements" => contents.read_elements(&mut lines)?,
                s if s.starts_with('$') && !s.starts_with("$End") => {
                    skip_gmsh_section(&mut lines, s)?
                }
                s if s.starts_with("$End") => {}
                other => return Err(parse_err(n, format!("unexpected line '{other}'"))),
            }
        }
        Ok(contents)
    }

    /// The body of a `$PhysicalNames` section whose header is on line `n`.
    fn read_physical_names(&mut self, lines: &mut Lines<'_>, n: usize) -> Result<(), SectionError> {
        let (_, c) = lines.numbers::<usize>()?;
        for _ in 0..need(&c, 0, n, "number of physical names")? {
            let (n, l) = lines.next_line()?;
            let mut w = l.splitn(3, char::is_whitespace);
            let dim: usize = w
                .next()
                .and_then(|s| s.parse().ok())
                .ok_or_else(|| parse_err(n, "bad physical-name dimension"))?;
            let tag: i64 = w
                .next()
                .and_then(|s| s.trim().parse().ok())
                .ok_or_else(|| parse_err(n, "bad physical tag"))?;
            let name = w.next().unwrap_or("").trim().trim_matches('"').to_string();
            self.physical_names.insert((dim, tag), name);
        }
        Ok(())
    }

    /// The body of an `$Entities` section: the physical tags of the surfaces.
    fn read_entities(&mut self, lines: &mut Lines<'_>) -> Result<(), SectionError> {
        let (n0, c) = lines.numbers::<usize>()?;
        let (np, nc, ns, nv) = (
            need(&c, 0, n0, "number of points")?,
            need(&c, 1, n0, "number of curves")?,
            need(&c, 2, n0, "number of surfaces")?,
            need(&c, 3, n0, "number of volumes")?,
        );
        // counts from the file: their sum must not overflow (each line is read, so a
        // count beyond the file ends with a missing line)
        for _ in 0..np.saturating_add(nc) {
            lines.next_line()?;
        }
        for _ in 0..ns {
            let (n, v) = lines.numbers::<f64>()?;
            let tag = need(&v, 0, n, "surface tag")? as i64;
            let count = need(&v, 7, n, "number of physical tags")? as usize;
            let tags = (0..count)
                .map(|k| need(&v, 8 + k, n, "physical tag").map(|t| t as i64))
                .collect::<Result<Vec<_>, _>>()?;
            self.surface_physical.insert(tag, tags);
        }
        for _ in 0..nv {
            lines.next_line()?;
        }
        Ok(())
    }

    /// The body of a `$Nodes` section: node tags and coordinates `(x₂, x₃)` (m).
    fn read_nodes(&mut self, lines: &mut Lines<'_>) -> Result<(), SectionError> {
        let (n0, c) = lines.numbers::<usize>()?;
        let blocks = need(&c, 0, n0, "number of node blocks")?;
        for _ in 0..blocks {
            let (n, b) = lines.numbers::<usize>()?;
            // Parametric coordinates, if any, follow x y z on the same line.
            let count = need(&b, 3, n, "number of nodes in the block")?;
            // the count comes from the file: no allocation before the nodes are read
            let mut tags = Vec::new();
            for _ in 0..count {
                let (n, t) = lines.numbers::<u64>()?;
                tags.push(need(&t, 0, n, "node tag")?);
            }
            for tag in tags {
                let (n, x) = lines.numbers::<f64>()?;
                let (x2, x3) = (need(&x, 0, n, "x")?, need(&x, 1, n, "y")?);
                if self.node_index.insert(tag, self.nodes.len()).is_some() {
                    return Err(parse_err(n, format!("node tag {tag} defined twice")));
                }
                self.nodes.push([x2, x3]);
            }
        }
        Ok(())
    }

    /// The body of an `$Elements` section: the surface elements (others are ignored).
    fn read_elements(&mut self, lines: &mut Lines<'_>) -> Result<(), SectionError> {
        let (n0, c) = lines.numbers::<usize>()?;
        let blocks = need(&c, 0, n0, "number of element blocks")?;
        for _ in 0..blocks {
            let (n, b) = lines.numbers::<i64>()?;
            let dim = need(&b, 0, n, "entity dimension")?;
            let entity = need(&b, 1, n, "entity tag")?;
            let etype = need(&b, 2, n, "element type")? as usize;
            let count = need(&b, 3, n, "number of elements in the block")? as usize;
            let kind = if dim == 2 { gmsh_kind(etype, n)? } else { None };
            for _ in 0..count {
                let (n, v) = lines.numbers::<u64>()?;
                if let Some(kind) = kind {
                    if v.len() != kind.node_count() + 1 {
                        return Err(parse_err(
                            n,
                            format!("a {} needs {} node tags", kind.name(), kind.node_count()),
                        ));
                    }
                    self.elements.push((n, kind, v[1..].to_vec(), entity));
                }
            }
        }
        Ok(())
    }

    /// The section mesh: each surface's region from its first physical group, named in
    /// `regions`.
    fn into_mesh(self, regions: &[RegionSpec]) -> Result<SectionMesh, SectionError> {
        let mut mesh = SectionMesh {
            nodes: self.nodes,
            ..Default::default()
        };
        let mut region_of_entity: HashMap<i64, usize> = HashMap::new();
        for (line, kind, tags, entity) in self.elements {
            let region = match region_of_entity.get(&entity) {
                Some(&r) => r,
                None => {
                    let r = gmsh_region(
                        entity,
                        line,
                        &self.physical_names,
                        &self.surface_physical,
                        regions,
                        &mut mesh.regions,
                    )?;
                    region_of_entity.insert(entity, r);
                    r
                }
            };
            let nodes = tags
                .iter()
                .map(|t| {
                    self.node_index
                        .get(t)
                        .copied()
                        .ok_or_else(|| parse_err(line, format!("node tag {t} is not defined")))
                })
                .collect::<Result<Vec<_>, _>>()?;
            mesh.elements.push(Element {
                kind,
                nodes,
                region,
            });
        }
        Ok(mesh)
    }
}

/// The line after `$MeshFormat`: version 4.1, ASCII.
fn check_gmsh_format(lines: &mut Lines<'_>) -> Result<(), SectionError> {
    let (n, v) = lines.next_line()?;
    let w: Vec<&str> = v.split_whitespace().collect();
    if w.first() != Some(&"4.1") {
        return Err(parse_err(
            n,
            format!(
                "Gmsh format version {} is not supported (need 4.1)",
                w.first().unwrap_or(&"?")
            ),
        ));
    }
    if w.get(1) != Some(&"0") {
        return Err(parse_err(
            n,
            "binary Gmsh files are not supported (save as ASCII)",
        ));
    }
    Ok(())
}

/// Skip an unknown section that starts with the line `header`, up to its `$End` line.
fn skip_gmsh_section(lines: &mut Lines<'_>, header: &str) -> Result<(), SectionError> {
    let end = format!("$End{}", &header[1..]);
    loop {
        let (_, l) = lines.next_line()?;
        if l == end {
            return Ok(());
        }
    }
}

/// Index in `mesh_regions` of the region of surface `entity` (first read on line `line`),
/// appended from its spec in `regions` when the surface is the first of its physical group.
fn gmsh_region(
    entity: i64,
    line: usize,
    physical_names: &HashMap<(usize, i64), String>,
    surface_physical: &HashMap<i64, Vec<i64>>,
    regions: &[RegionSpec],
    mesh_regions: &mut Vec<Region>,
) -> Result<usize, SectionError> {
    let phys = surface_physical.get(&entity).and_then(|t| t.first()).ok_or_else(|| {
        parse_err(line, format!("surface {entity} belongs to no physical group (name the plies with physical groups)"))
    })?;
    let name = physical_names
        .get(&(2, *phys))
        .cloned()
        .unwrap_or_else(|| phys.to_string());
    let spec =
        regions
            .iter()
            .find(|r| r.name == name)
            .ok_or_else(|| SectionError::UnknownRegion {
                name: name.clone(),
                line: Some(line),
            })?;
    Ok(match mesh_regions.iter().position(|r| r.name == name) {
        Some(r) => r,
        None => {
            mesh_regions.push(Region::new(name, spec.material, spec.ply_angle, spec.frame));
            mesh_regions.len() - 1
        }
    })
}

/// A mesh from the text of a Gmsh `.msh` file, format 4.1 ASCII, with second-order surface
/// elements (6-node triangles, 8- or 9-node quadrilaterals) in the `z = 0` plane (`x → x₂`,
/// `y → x₃`). Every surface must belong to a physical group whose name is one of `regions`;
/// the first physical group of a surface decides its region. Curves and points are ignored.
pub fn parse_gmsh(text: &str, regions: &[RegionSpec]) -> Result<SectionMesh, SectionError> {
    let contents = GmshContents::read(text)?;
    if !contents.seen_format {
        return Err(parse_err(1, "not a Gmsh mesh: no $MeshFormat section"));
    }
    contents.into_mesh(regions)
}

/// A line of the simple format: its 1-based number and its words.
type SimpleLine<'t> = (usize, Vec<&'t str>);

/// The items of the simple line format, collected before regions and elements are resolved
/// (regions refer to materials, and elements to regions and nodes, by name).
struct SimpleItems<'t> {
    /// Materials by name: the caller's, overridden by the text's.
    materials: HashMap<String, OrthotropicMaterial>,
    /// The `region` lines.
    regions: Vec<SimpleLine<'t>>,
    /// The `element` lines.
    elements: Vec<SimpleLine<'t>>,
    /// Index into `nodes` of each node id.
    node_index: HashMap<u64, usize>,
    /// Node coordinates `(x₂, x₃)` (m).
    nodes: Vec<[f64; 2]>,
}

/// Word `k` of the line `w` (number `line`) as a number; `what` names it in errors.
fn word_number(w: &[&str], line: usize, k: usize, what: &str) -> Result<f64, SectionError> {
    let s = w
        .get(k)
        .ok_or_else(|| parse_err(line, format!("missing {what}")))?;
    s.parse::<f64>()
        .map_err(|_| parse_err(line, format!("{what}: '{s}' is not a number")))
}

/// Read the materials and nodes of the simple format, and collect its region and element
/// lines.
fn collect_simple_items<'t>(
    text: &'t str,
    materials: &[(&str, OrthotropicMaterial)],
) -> Result<SimpleItems<'t>, SectionError> {
    let mut items = SimpleItems {
        materials: materials.iter().map(|(n, m)| (n.to_string(), *m)).collect(),
        regions: Vec::new(),
        elements: Vec::new(),
        node_index: HashMap::new(),
        nodes: Vec::new(),
    };
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let l = raw.split('#').next().unwrap_or("").trim();
        if l.is_empty() {
            continue;
        }
        let w: Vec<&str> = l.split_whitespace().collect();
        match w[0] {
            "material" => {
                let name = w
                    .get(1)
                    .ok_or_else(|| parse_err(line, "missing material name"))?;
                let m = simple_material(line, &w)?;
                items.materials.insert(name.to_string(), m);
            }
            "region" => items.regions.push((line, w)),
            "element" => items.elements.push((line, w)),
            "node" => {
                let id = w
                    .get(1)
                    .and_then(|s| s.parse::<u64>().ok())
                    .ok_or_else(|| parse_err(line, "node id must be a non-negative integer"))?;
                let p = [
                    word_number(&w, line, 2, "x2")?,
                    word_number(&w, line, 3, "x3")?,
                ];
                if items.node_index.insert(id, items.nodes.len()).is_some() {
                    return Err(parse_err(line, format!("node {id} defined twice")));
                }
                items.nodes.push(p);
            }
            other => return Err(parse_err(line, format!("unknown item '{other}'"))),
        }
    }
    Ok(items)
}

/// The material of a `material` line `w` (number `line`): isotropic or orthotropic, moduli in
/// Pa, density in kg/m³.
fn simple_material(line: usize, w: &[&str]) -> Result<OrthotropicMaterial, SectionError> {
    let num = |k: usize, what: &str| word_number(w, line, k, what);
    Ok(match w.get(2).copied() {
        Some("isotropic") => {
            OrthotropicMaterial::isotropic(num(3, "E")?, num(4, "nu")?, num(5, "rho")?)?
        }
        Some("orthotropic") => OrthotropicMaterial::new(
            [num(3, "E1")?, num(4, "E2")?, num(5, "E3")?],
            [num(6, "G12")?, num(7, "G13")?, num(8, "G23")?],
            [num(9, "nu12")?, num(10, "nu13")?, num(11, "nu23")?],
            num(12, "rho")?,
        )?,
        other => {
            return Err(parse_err(
                line,
                format!("material kind {other:?}: expected 'isotropic' or 'orthotropic'"),
            ));
        }
    })
}

/// The region of a `region` line `w` (number `line`), its material from `materials`, angles
/// converted from degrees to radians; its name must not be one of `defined`.
fn simple_region(
    line: usize,
    w: &[&str],
    materials: &HashMap<String, OrthotropicMaterial>,
    defined: &[Region],
) -> Result<Region, SectionError> {
    let num = |k: usize, what: &str| word_number(w, line, k, what);
    if w.len() < 5 {
        return Err(parse_err(
            line,
            "region needs: <name> <material> <angle> <frame> ...",
        ));
    }
    let material = *materials
        .get(w[2])
        .ok_or_else(|| SectionError::UnknownMaterial {
            name: w[2].to_string(),
            line: Some(line),
        })?;
    // angles are written in degrees; a non-finite one is named in the unit it was written in
    let degrees = |k: usize, what: &str| -> Result<f64, SectionError> {
        let x = num(k, what)?;
        if x.is_finite() {
            Ok(x.to_radians())
        } else {
            Err(parse_err(
                line,
                format!("{what} {x} is not a finite number (degrees)"),
            ))
        }
    };
    let angle = degrees(3, "ply angle")?;
    let frame = match w[4] {
        "tangent" => WallFrame::Tangent(degrees(5, "tangent angle")?),
        "radial" => WallFrame::Radial {
            centre: [num(5, "centre x2")?, num(6, "centre x3")?],
        },
        "xi" => WallFrame::AlongElement(ElementDirection::Xi),
        "eta" => WallFrame::AlongElement(ElementDirection::Eta),
        other => {
            return Err(parse_err(
                line,
                format!("frame '{other}': expected 'tangent', 'radial', 'xi' or 'eta'"),
            ));
        }
    };
    if defined.iter().any(|r| r.name == w[1]) {
        return Err(parse_err(line, format!("region '{}' defined twice", w[1])));
    }
    Ok(Region::new(w[1], material, angle, frame))
}

/// The element of an `element` line `w` (number `line`), its region one of `regions` and its
/// nodes indices through `node_index`.
fn simple_element(
    line: usize,
    w: &[&str],
    regions: &[Region],
    node_index: &HashMap<u64, usize>,
) -> Result<Element, SectionError> {
    let kind = match w.get(1).copied() {
        Some("tri6") => ElementKind::Tri6,
        Some("quad8") => ElementKind::Quad8,
        Some("quad9") => ElementKind::Quad9,
        other => {
            return Err(parse_err(
                line,
                format!(
                    "element kind {other:?}: expected tri6, quad8 or quad9 (quadratic elements)"
                ),
            ));
        }
    };
    let rname = w
        .get(2)
        .ok_or_else(|| parse_err(line, "missing region name"))?;
    let region = regions
        .iter()
        .position(|r| r.name == *rname)
        .ok_or_else(|| SectionError::UnknownRegion {
            name: rname.to_string(),
            line: Some(line),
        })?;
    if w.len() != 3 + kind.node_count() {
        return Err(parse_err(
            line,
            format!(
                "a {} needs {} node ids, {} given",
                kind.name(),
                kind.node_count(),
                w.len() - 3
            ),
        ));
    }
    let nodes = w[3..]
        .iter()
        .map(|s| {
            let id = s
                .parse::<u64>()
                .map_err(|_| parse_err(line, format!("node id '{s}' is not an integer")))?;
            node_index
                .get(&id)
                .copied()
                .ok_or_else(|| parse_err(line, format!("node {id} is not defined")))
        })
        .collect::<Result<Vec<_>, _>>()?;
    Ok(Element {
        kind,
        nodes,
        region,
    })
}

/// A mesh in the simple line format. One item per line, `#` starts a comment; lengths in m,
/// moduli in Pa, density in kg/m³, angles in DEGREES (converted to radians):
///
/// ```text
/// material <name> isotropic <E> <nu> <rho>
/// material <name> orthotropic <E1> <E2> <E3> <G12> <G13> <G23> <nu12> <nu13> <nu23> <rho>
/// region <name> <material> <ply angle> tangent <beta>       # straight wall, tangent at beta
/// region <name> <material> <ply angle> radial <c2> <c3>     # curved wall around (c2, c3)
/// region <name> <material> <ply angle> xi                    # tangent along each element's ξ
/// region <name> <material> <ply angle> eta                   # … or η (see WallFrame)
/// node <id> <x2> <x3>
/// element <tri6|quad8|quad9> <region> <node id> ...         # Gmsh node order
/// ```
///
/// Materials may also be supplied by the caller in `materials` (the text's own definitions take
/// precedence). Node ids are any non-negative integers; items may come in any order.
pub fn parse_simple(
    text: &str,
    materials: &[(&str, OrthotropicMaterial)],
) -> Result<SectionMesh, SectionError> {
    let items = collect_simple_items(text, materials)?;
    let mut mesh = SectionMesh {
        nodes: items.nodes,
        ..Default::default()
    };
    for (line, w) in items.regions {
        let region = simple_region(line, &w, &items.materials, &mesh.regions)?;
        mesh.regions.push(region);
    }
    for (line, w) in items.elements {
        let element = simple_element(line, &w, &mesh.regions, &items.node_index)?;
        mesh.elements.push(element);
    }
    Ok(mesh)
}

/// The mesh in the simple line format of [`parse_simple`] (material `m<k>` belongs to region
/// `k`; node ids are the node indices). `parse_simple(&write_simple(m), &[])` gives `m` back
/// up to round-off in the angles.
pub fn write_simple(mesh: &SectionMesh) -> String {
    use std::fmt::Write;
    let mut s = String::from("# flexsens section mesh\n");
    for (k, r) in mesh.regions.iter().enumerate() {
        let m = &r.material;
        let ([e1, e2, e3], [g12, g13, g23], [n12, n13, n23]) =
            (m.young_moduli(), m.shear_moduli(), m.poisson_ratios());
        let _ = writeln!(
            s,
            "material m{k} orthotropic {e1:e} {e2:e} {e3:e} {g12:e} {g13:e} {g23:e} {n12:e} {n13:e} {n23:e} {:e}",
            m.density()
        );
        let frame = match r.frame {
            WallFrame::Tangent(b) => format!("tangent {:e}", b.to_degrees()),
            WallFrame::Radial { centre } => format!("radial {:e} {:e}", centre[0], centre[1]),
            WallFrame::AlongElement(ElementDirection::Xi) => "xi".to_string(),
            WallFrame::AlongElement(ElementDirection::Eta) => "eta".to_string(),
        };
        let _ = writeln!(
            s,
            "region {} m{k} {:e} {frame}",
            r.name,
            r.ply_angle.to_degrees()
        );
    }
    for (i, p) in mesh.nodes.iter().enumerate() {
        let _ = writeln!(s, "node {i} {:e} {:e}", p[0], p[1]);
    }
    for e in &mesh.elements {
        let kind = match e.kind {
            ElementKind::Tri6 => "tri6",
            ElementKind::Quad8 => "quad8",
            ElementKind::Quad9 => "quad9",
        };
        let ids: Vec<String> = e.nodes.iter().map(|n| n.to_string()).collect();
        let _ = writeln!(
            s,
            "element {kind} {} {}",
            mesh.regions[e.region].name,
            ids.join(" ")
        );
    }
    s
}
