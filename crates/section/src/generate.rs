//! Mesh generators: solid rectangle, solid circle, layered circular tube, thin-walled box,
//! channel and I section. All produce 8-node quadrilaterals, centred on the origin.

use std::collections::HashMap;
use std::f64::consts::{FRAC_PI_2, PI};

use laminate::OrthotropicMaterial;
use sens::{Dual, Scalar};

use crate::SectionError;
use crate::element::ElementKind;
use crate::mesh::{Element, Region, SectionMesh, WallFrame};

/// One ply of a wall: material, fibre angle (radians, from the beam axis about the wall
/// normal), thickness (m) and number of elements through its thickness.
#[derive(Clone, Debug, PartialEq)]
pub struct PlySpec {
    pub name: String,
    pub material: OrthotropicMaterial,
    pub angle: f64,
    pub thickness: f64,
    pub elements: usize,
}

impl PlySpec {
    pub fn new(
        name: impl Into<String>,
        material: OrthotropicMaterial,
        angle: f64,
        thickness: f64,
        elements: usize,
    ) -> Self {
        Self {
            name: name.into(),
            material,
            angle,
            thickness,
            elements,
        }
    }

    fn check(&self) -> Result<(), SectionError> {
        if !(self.thickness.is_finite() && self.thickness > 0.0) {
            return Err(SectionError::InvalidInput(format!(
                "ply '{}': thickness {} must be positive and finite (m)",
                self.name, self.thickness
            )));
        }
        if !self.angle.is_finite() {
            return Err(SectionError::InvalidInput(format!(
                "ply '{}': angle {} must be finite (radians)",
                self.name, self.angle
            )));
        }
        if self.elements == 0 {
            return Err(SectionError::InvalidInput(format!(
                "ply '{}': needs at least one element through the thickness",
                self.name
            )));
        }
        Ok(())
    }
}

/// Nodes of a structured Q8 grid addressed by half-indices `(i2, j2)`, with coordinates in
/// the scalar `S` (dual when the node velocities of a thickness variable are wanted).
struct Grid<S, F: Fn(usize, usize) -> [S; 2]> {
    coord: F,
    map: HashMap<(usize, usize), usize>,
    nodes: Vec<[S; 2]>,
    /// Period of `j2` (tubes), if any.
    wrap_j: Option<usize>,
}

impl<S, F: Fn(usize, usize) -> [S; 2]> Grid<S, F> {
    fn new(coord: F, wrap_j: Option<usize>) -> Self {
        Self {
            coord,
            map: HashMap::new(),
            nodes: Vec::new(),
            wrap_j,
        }
    }

    fn node(&mut self, i2: usize, j2: usize) -> usize {
        let j2 = self.wrap_j.map_or(j2, |p| j2 % p);
        if let Some(&n) = self.map.get(&(i2, j2)) {
            return n;
        }
        let n = self.nodes.len();
        self.nodes.push((self.coord)(i2, j2));
        self.map.insert((i2, j2), n);
        n
    }

    /// The Q8 element of cell `(i, j)`; `ξ` runs along `i`, `η` along `j`.
    fn quad8(&mut self, i: usize, j: usize) -> Vec<usize> {
        let (a, b) = (2 * i, 2 * j);
        vec![
            self.node(a, b),
            self.node(a + 2, b),
            self.node(a + 2, b + 2),
            self.node(a, b + 2),
            self.node(a + 1, b),
            self.node(a + 2, b + 1),
            self.node(a + 1, b + 2),
            self.node(a, b + 1),
        ]
    }
}

fn positive(what: &str, v: f64) -> Result<(), SectionError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(SectionError::InvalidInput(format!(
            "{what} = {v} must be positive and finite"
        )))
    }
}

fn at_least(what: &str, v: usize, min: usize) -> Result<(), SectionError> {
    if v >= min {
        Ok(())
    } else {
        Err(SectionError::InvalidInput(format!(
            "{what} = {v} must be at least {min}"
        )))
    }
}

/// A solid rectangle `width` (along `x₂`) × `height` (along `x₃`), centred on the origin,
/// `n2 × n3` elements, one region `"solid"` with the material axes along `(x₁, x₂, x₃)`
/// rotated by `ply_angle` about `x₃` (0 for an isotropic section).
pub fn rectangle(
    width: f64,
    height: f64,
    n2: usize,
    n3: usize,
    material: OrthotropicMaterial,
    ply_angle: f64,
) -> Result<SectionMesh, SectionError> {
    positive("rectangle width", width)?;
    positive("rectangle height", height)?;
    at_least("elements along the width", n2, 1)?;
    at_least("elements along the height", n3, 1)?;
    let coord = |i2: usize, j2: usize| {
        [
            -0.5 * width + width * i2 as f64 / (2 * n2) as f64,
            -0.5 * height + height * j2 as f64 / (2 * n3) as f64,
        ]
    };
    let mut grid = Grid::new(coord, None);
    let mut elements = Vec::with_capacity(n2 * n3);
    for j in 0..n3 {
        for i in 0..n2 {
            elements.push(Element {
                kind: ElementKind::Quad8,
                nodes: grid.quad8(i, j),
                region: 0,
            });
        }
    }
    Ok(SectionMesh {
        nodes: grid.nodes,
        elements,
        regions: vec![Region::new(
            "solid",
            material,
            ply_angle,
            WallFrame::Tangent(0.0),
        )],
    })
}

/// A solid circle of `radius` centred on the origin, meshed as an O-grid of 8-node
/// quadrilaterals: a central square of half-side `radius / 2` with `around / 4` cells per side,
/// and four curved patches of `radial` cells blending its sides into the circle (mid-side nodes
/// of the rim on the exact circle). `around` (cells around the rim) must be a multiple of 4,
/// at least 8. One region `"solid"`, material axes along `(x₁, x₂, x₃)` rotated by
/// `ply_angle` about `x₃`, as for [`rectangle`].
pub fn circle(
    radius: f64,
    around: usize,
    radial: usize,
    material: OrthotropicMaterial,
    ply_angle: f64,
) -> Result<SectionMesh, SectionError> {
    positive("circle radius", radius)?;
    at_least("elements around the circle", around, 8)?;
    at_least("elements from the core to the rim", radial, 1)?;
    if !around.is_multiple_of(4) {
        return Err(SectionError::InvalidInput(format!(
            "elements around the circle = {around} must be a multiple of 4"
        )));
    }
    let n = around / 4;
    let half = 0.5 * radius;
    // nodes shared between the core and the patches are found by their coordinates
    let mut nodes: Vec<[f64; 2]> = Vec::new();
    let mut index: HashMap<(i64, i64), usize> = HashMap::new();
    let quantum = radius * 1e-9;
    let mut node = |p: [f64; 2]| -> usize {
        let key = (
            (p[0] / quantum).round() as i64,
            (p[1] / quantum).round() as i64,
        );
        *index.entry(key).or_insert_with(|| {
            nodes.push(p);
            nodes.len() - 1
        })
    };
    let mut elements = Vec::with_capacity(n * n + 4 * n * radial);
    // a Q8 cell of a patch: `at(u, v)` maps the cell's local coordinates in [0, 1]²; corners
    // and mid-sides, counterclockwise
    let mut cell = |at: &dyn Fn(f64, f64) -> [f64; 2]| {
        let uv = [
            (0.0, 0.0),
            (1.0, 0.0),
            (1.0, 1.0),
            (0.0, 1.0),
            (0.5, 0.0),
            (1.0, 0.5),
            (0.5, 1.0),
            (0.0, 0.5),
        ];
        let mut ids: Vec<usize> = uv.iter().map(|&(u, v)| node(at(u, v))).collect();
        let p: Vec<[f64; 2]> = uv.iter().take(4).map(|&(u, v)| at(u, v)).collect();
        let area2: f64 = (0..4)
            .map(|k| {
                let (a, b) = (p[k], p[(k + 1) % 4]);
                a[0] * b[1] - b[0] * a[1]
            })
            .sum();
        if area2 < 0.0 {
            // clockwise in the section plane: reverse the order
            ids = vec![
                ids[0], ids[3], ids[2], ids[1], ids[7], ids[6], ids[5], ids[4],
            ];
        }
        elements.push(Element {
            kind: ElementKind::Quad8,
            nodes: ids,
            region: 0,
        });
    };
    let h = 2.0 * half / n as f64;
    for j in 0..n {
        for i in 0..n {
            let at = |u: f64, v: f64| [-half + h * (i as f64 + u), -half + h * (j as f64 + v)];
            cell(&at);
        }
    }
    for side in 0..4 {
        let rot = FRAC_PI_2 * side as f64;
        let (c, s) = (rot.cos(), rot.sin());
        for j in 0..radial {
            for i in 0..n {
                // ξ along the side (counterclockwise), η from the core to the rim
                let at = |u: f64, v: f64| {
                    let xi = (i as f64 + u) / n as f64;
                    let eta = (j as f64 + v) / radial as f64;
                    let inner = [half, -half + 2.0 * half * xi];
                    let phi = -0.25 * PI + FRAC_PI_2 * xi;
                    let outer = [radius * phi.cos(), radius * phi.sin()];
                    let x = inner[0] + eta * (outer[0] - inner[0]);
                    let y = inner[1] + eta * (outer[1] - inner[1]);
                    [c * x - s * y, s * x + c * y]
                };
                cell(&at);
            }
        }
    }
    Ok(SectionMesh {
        nodes,
        elements,
        regions: vec![Region::new(
            "solid",
            material,
            ply_angle,
            WallFrame::Tangent(0.0),
        )],
    })
}

/// A circular tube centred on the origin: `plies` stacked outwards from `inner_radius` (the
/// first ply is innermost), each with its own thickness, angle and elements through its
/// thickness, and `circumferential` elements around. Mid-side nodes lie on the exact circles.
/// Region `k` is ply `k` (named after it) with a [`WallFrame::Radial`] frame: normal outward.
pub fn tube(
    inner_radius: f64,
    plies: &[PlySpec],
    circumferential: usize,
) -> Result<SectionMesh, SectionError> {
    let (nodes, elements, regions) =
        tube_of(inner_radius, plies, circumferential, &|p: &PlySpec| {
            p.thickness
        })?;
    Ok(SectionMesh {
        nodes,
        elements,
        regions,
    })
}

/// The parts of a mesh: nodes (in any scalar), elements, regions.
type Parts<S> = (Vec<[S; 2]>, Vec<Element>, Vec<Region>);

/// [`tube`] with the ply thicknesses `thickness(ply)` in the scalar `S`.
fn tube_of<S: Scalar>(
    inner_radius: f64,
    plies: &[PlySpec],
    circumferential: usize,
    thickness: &dyn Fn(&PlySpec) -> S,
) -> Result<Parts<S>, SectionError> {
    positive("tube inner radius", inner_radius)?;
    at_least("elements around the tube", circumferential, 3)?;
    if plies.is_empty() {
        return Err(SectionError::InvalidInput(
            "a tube needs at least one ply".into(),
        ));
    }
    // Radii of the element layers at half-index steps, and the region of each layer.
    let mut radii2 = vec![S::from_f64(inner_radius)];
    let mut layer_region = Vec::new();
    for (k, p) in plies.iter().enumerate() {
        p.check()?;
        let r0 = *radii2.last().expect("non-empty");
        for e in 0..p.elements {
            let h = thickness(p) / p.elements as f64;
            radii2.push(r0 + h * (e as f64 + 0.5));
            radii2.push(r0 + h * (e as f64 + 1.0));
            layer_region.push(k);
        }
    }
    let nc = circumferential;
    let coord = |i2: usize, j2: usize| {
        let phi = 2.0 * PI * j2 as f64 / (2 * nc) as f64;
        let r = radii2[i2];
        [r * phi.cos(), r * phi.sin()]
    };
    let mut grid = Grid::new(coord, Some(2 * nc));
    let mut elements = Vec::with_capacity(nc * layer_region.len());
    for j in 0..nc {
        for (i, &region) in layer_region.iter().enumerate() {
            elements.push(Element {
                kind: ElementKind::Quad8,
                nodes: grid.quad8(i, j),
                region,
            });
        }
    }
    let regions = plies
        .iter()
        .map(|p| {
            Region::new(
                p.name.clone(),
                p.material,
                p.angle,
                WallFrame::Radial { centre: [0.0, 0.0] },
            )
        })
        .collect();
    Ok((grid.nodes, elements, regions))
}

/// Ply stacks of the four walls of a box, each listed along the outward wall normal (first ply
/// innermost).
#[derive(Clone, Debug, PartialEq)]
pub struct BoxWalls {
    pub top: Vec<PlySpec>,
    pub bottom: Vec<PlySpec>,
    pub left: Vec<PlySpec>,
    pub right: Vec<PlySpec>,
}

impl BoxWalls {
    /// The same stack on all four walls.
    pub fn uniform(plies: Vec<PlySpec>) -> Self {
        Self {
            top: plies.clone(),
            bottom: plies.clone(),
            left: plies.clone(),
            right: plies,
        }
    }
}

/// The regions of a walled section, one per (wall, ply), made when first used and named
/// `"<wall>/<ply>"`.
#[derive(Default)]
struct WallRegions {
    regions: Vec<Region>,
    index: HashMap<(&'static str, usize), usize>,
}

impl WallRegions {
    /// The region of ply `k` of `stack` on `wall`, with the wall's frame.
    fn of(&mut self, wall: &'static str, k: usize, stack: &[PlySpec], frame: WallFrame) -> usize {
        let regions = &mut self.regions;
        *self.index.entry((wall, k)).or_insert_with(|| {
            let p = &stack[k];
            regions.push(Region::new(
                format!("{wall}/{}", p.name),
                p.material,
                p.angle,
                frame,
            ));
            regions.len() - 1
        })
    }
}

/// The grid line `i2 / 2` of the breaks `v`, or half way between two for odd `i2` (the
/// mid-side nodes of a structured Q8 grid).
fn at_half_index<S: Scalar>(v: &[S], i2: usize) -> S {
    if i2.is_multiple_of(2) {
        v[i2 / 2]
    } else {
        (v[i2 / 2] + v[i2 / 2 + 1]) * 0.5
    }
}

/// Position of a cell along one axis of the box grid.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Band {
    Low(usize),
    Mid,
    High(usize),
}

/// The walls across one axis of a walled section, for messages: the size that holds them
/// (`"width"`, `"height"`), the low and the high wall, and what lies between them.
struct AxisWalls {
    size: &'static str,
    low: &'static str,
    high: &'static str,
    between: &'static str,
}

/// Grid breaks along one axis: low wall (plies outermost first), `n_mid` cells, high wall;
/// the ply thicknesses are `thickness(ply)`.
fn box_axis<S: Scalar>(
    extent: f64,
    (low, high): (&[PlySpec], &[PlySpec]),
    names: AxisWalls,
    n_mid: usize,
    thickness: &dyn Fn(&PlySpec) -> S,
) -> Result<(Vec<S>, Vec<Band>), SectionError> {
    let tl: f64 = low.iter().map(|p| p.thickness).sum();
    let th: f64 = high.iter().map(|p| p.thickness).sum();
    if tl + th >= extent {
        let AxisWalls {
            size,
            low,
            high,
            between,
        } = names;
        return Err(SectionError::InvalidInput(format!(
            "the {low} wall ({tl} m thick) and the {high} wall ({th} m) leave no room for the \
             {between} in a {size} of {extent} m: the {size} must exceed {} m",
            tl + th
        )));
    }
    let sum = |plies: &[PlySpec]| plies.iter().map(thickness).sum::<S>();
    let mut x = vec![S::from_f64(-0.5 * extent)];
    let mut bands = Vec::new();
    for (k, p) in low.iter().enumerate().rev() {
        let x0 = *x.last().expect("non-empty");
        for e in 0..p.elements {
            x.push(x0 + thickness(p) * (e + 1) as f64 / p.elements as f64);
            bands.push(Band::Low(k));
        }
    }
    let x0 = *x.last().expect("non-empty");
    let inner = S::from_f64(extent) - sum(low) - sum(high);
    for e in 0..n_mid {
        x.push(x0 + inner * (e + 1) as f64 / n_mid as f64);
        bands.push(Band::Mid);
    }
    for (k, p) in high.iter().enumerate() {
        let x0 = *x.last().expect("non-empty");
        for e in 0..p.elements {
            x.push(x0 + thickness(p) * (e + 1) as f64 / p.elements as f64);
            bands.push(Band::High(k));
        }
    }
    Ok((x, bands))
}

/// A thin-walled rectangular box, outer size `width` (along `x₂`) × `height` (along `x₃`),
/// centred on the origin, with a ply stack per wall and `n_width`, `n_height` elements along
/// the flat part of the horizontal and vertical walls. Regions are named `"top/<ply>"`,
/// `"bottom/<ply>"`, `"left/<ply>"`, `"right/<ply>"`; wall frames have outward normals
/// (tangents run clockwise).
///
/// Corners: where the two walls meeting there have as many plies, the plies **wrap round the
/// corner** as L-shaped bands (ply `k`, counted from the inside, takes the corner cells whose
/// larger ply index is `k`): the cells along a wall keep that wall's ply and frame, and the
/// cell at the bend of the L takes the horizontal wall's ply with the frame turned half way
/// (regions `"bottom-left/<ply>"` etc.). Otherwise the top and bottom walls (flanges) own the
/// corners.
pub fn thin_walled_box(
    width: f64,
    height: f64,
    walls: &BoxWalls,
    n_width: usize,
    n_height: usize,
) -> Result<SectionMesh, SectionError> {
    let (nodes, elements, regions) =
        walled(width, height, walls, n_width, n_height, false, &|p| {
            p.thickness
        })?;
    Ok(SectionMesh {
        nodes,
        elements,
        regions,
    })
}

/// A channel (C section) open towards `+x₂`: the box of [`thin_walled_box`] without its right
/// wall (`walls.right` must be empty), the flanges (top, bottom) running to `x₂ = width/2` and
/// the web on the left; the plies wrap round its two corners as in the box.
pub fn channel(
    width: f64,
    height: f64,
    walls: &BoxWalls,
    n_width: usize,
    n_height: usize,
) -> Result<SectionMesh, SectionError> {
    if !walls.right.is_empty() {
        return Err(SectionError::InvalidInput(
            "a channel has no right wall: it is open towards +x2".into(),
        ));
    }
    let (nodes, elements, regions) = walled(width, height, walls, n_width, n_height, true, &|p| {
        p.thickness
    })?;
    Ok(SectionMesh {
        nodes,
        elements,
        regions,
    })
}

/// The box, or with `open` the channel without its right wall, with the ply thicknesses
/// `thickness(ply)` in the scalar `S`.
fn walled<S: Scalar>(
    width: f64,
    height: f64,
    walls: &BoxWalls,
    n_width: usize,
    n_height: usize,
    open: bool,
    thickness: &dyn Fn(&PlySpec) -> S,
) -> Result<Parts<S>, SectionError> {
    positive("box width", width)?;
    positive("box height", height)?;
    at_least("elements along the box width", n_width, 1)?;
    at_least("elements along the box height", n_height, 1)?;
    for (name, stack) in [
        ("top", &walls.top),
        ("bottom", &walls.bottom),
        ("left", &walls.left),
        ("right", &walls.right),
    ] {
        if name == "right" && open {
            continue;
        }
        if stack.is_empty() {
            return Err(SectionError::InvalidInput(format!(
                "the {name} wall has no plies"
            )));
        }
        for p in stack {
            p.check()?;
        }
    }
    let (xs, cols) = box_axis(
        width,
        (&walls.left, &walls.right),
        AxisWalls {
            size: "width",
            low: "left",
            high: "right",
            between: "section's inside",
        },
        n_width,
        thickness,
    )?;
    let (ys, rows) = box_axis(
        height,
        (&walls.bottom, &walls.top),
        AxisWalls {
            size: "height",
            low: "bottom",
            high: "top",
            between: "section's inside",
        },
        n_height,
        thickness,
    )?;
    let coord = |i2: usize, j2: usize| [at_half_index(&xs, i2), at_half_index(&ys, j2)];
    let mut grid = Grid::new(coord, None);
    let mut walls_regions = WallRegions::default();
    let mut region = |wall: &'static str, k: usize, stack: &[PlySpec], frame: WallFrame| {
        walls_regions.of(wall, k, stack, frame)
    };
    // the frames of the walls, and of the bends of the wrapped plies (half way between)
    let bottom = WallFrame::Tangent(PI);
    let top = WallFrame::Tangent(0.0);
    let left = WallFrame::Tangent(FRAC_PI_2);
    let right = WallFrame::Tangent(-FRAC_PI_2);
    let wraps = |h: &[PlySpec], v: &[PlySpec]| h.len() == v.len();
    let mut elements = Vec::new();
    for (j, &row) in rows.iter().enumerate() {
        for (i, &col) in cols.iter().enumerate() {
            // corners: (row ply, column ply, horizontal wall, vertical wall, bend frame)
            let corner = match (row, col) {
                (Band::Low(kr), Band::Low(kc)) => Some((kr, kc, "bottom", "left", 0.75 * PI)),
                (Band::Low(kr), Band::High(kc)) => Some((kr, kc, "bottom", "right", -0.75 * PI)),
                (Band::High(kr), Band::Low(kc)) => Some((kr, kc, "top", "left", 0.25 * PI)),
                (Band::High(kr), Band::High(kc)) => Some((kr, kc, "top", "right", -0.25 * PI)),
                _ => None,
            };
            if let Some((kr, kc, h, v, bend)) = corner {
                let (hs, hf) = if h == "bottom" {
                    (&walls.bottom, bottom)
                } else {
                    (&walls.top, top)
                };
                let (vs, vf) = if v == "left" {
                    (&walls.left, left)
                } else {
                    (&walls.right, right)
                };
                if wraps(hs, vs) {
                    let r = if kr > kc {
                        region(h, kr, hs, hf)
                    } else if kc > kr {
                        region(v, kc, vs, vf)
                    } else {
                        let name = if h == "bottom" {
                            if v == "left" {
                                "bottom-left"
                            } else {
                                "bottom-right"
                            }
                        } else if v == "left" {
                            "top-left"
                        } else {
                            "top-right"
                        };
                        region(name, kr, hs, WallFrame::Tangent(bend))
                    };
                    elements.push(Element {
                        kind: ElementKind::Quad8,
                        nodes: grid.quad8(i, j),
                        region: r,
                    });
                    continue;
                }
            }
            let r = match (row, col) {
                (Band::Low(k), _) => region("bottom", k, &walls.bottom, bottom),
                (Band::High(k), _) => region("top", k, &walls.top, top),
                (Band::Mid, Band::Low(k)) => region("left", k, &walls.left, left),
                (Band::Mid, Band::High(k)) => region("right", k, &walls.right, right),
                (Band::Mid, Band::Mid) => continue,
            };
            elements.push(Element {
                kind: ElementKind::Quad8,
                nodes: grid.quad8(i, j),
                region: r,
            });
        }
    }
    Ok((grid.nodes, elements, walls_regions.regions))
}

/// Ply stacks of an I section: each flange listed from the web outwards (first ply
/// innermost), the web from `−x₂` to `+x₂`.
#[derive(Clone, Debug, PartialEq)]
pub struct IWalls {
    pub top: Vec<PlySpec>,
    pub bottom: Vec<PlySpec>,
    pub web: Vec<PlySpec>,
}

/// An I section (two flanges and a web), outer size `width` (the flanges, along `x₂`) ×
/// `height` (along `x₃`), centred on the origin, with `n_side` elements along each flange on
/// either side of the web and `n_web` along the web between the flanges. The flanges run the
/// full width and own the two junctions with the web. Regions are named `"top/<ply>"`,
/// `"bottom/<ply>"` and `"web/<ply>"`; the flanges' frames have outward normals (`±x₃`), the
/// web's normal is `+x₂`.
pub fn i_section(
    width: f64,
    height: f64,
    walls: &IWalls,
    n_side: usize,
    n_web: usize,
) -> Result<SectionMesh, SectionError> {
    let (nodes, elements, regions) =
        i_section_of(width, height, walls, n_side, n_web, &|p: &PlySpec| {
            p.thickness
        })?;
    Ok(SectionMesh {
        nodes,
        elements,
        regions,
    })
}

/// [`i_section`] with the ply thicknesses `thickness(ply)` in the scalar `S`.
fn i_section_of<S: Scalar>(
    width: f64,
    height: f64,
    walls: &IWalls,
    n_side: usize,
    n_web: usize,
    thickness: &dyn Fn(&PlySpec) -> S,
) -> Result<Parts<S>, SectionError> {
    positive("I-section width", width)?;
    positive("I-section height", height)?;
    at_least("elements along each flange beside the web", n_side, 1)?;
    at_least("elements along the web", n_web, 1)?;
    for (name, stack) in [
        ("top", &walls.top),
        ("bottom", &walls.bottom),
        ("web", &walls.web),
    ] {
        if stack.is_empty() {
            return Err(SectionError::InvalidInput(format!(
                "the {name} wall of the I section has no plies"
            )));
        }
        for p in stack {
            p.check()?;
        }
    }
    let tw: f64 = walls.web.iter().map(|p| p.thickness).sum();
    if tw >= width {
        return Err(SectionError::InvalidInput(format!(
            "an I-section web of thickness {tw} m does not fit in a width of {width} m"
        )));
    }
    // x: one side of a flange, the web's plies, the other side; y: as a box's flanges
    let side = (S::from_f64(width) - walls.web.iter().map(thickness).sum::<S>()) * 0.5;
    let mut xs = vec![S::from_f64(-0.5 * width)];
    let mut web_of = Vec::new();
    let mut push = |dx: S, web: Option<usize>| {
        let x0 = *xs.last().expect("non-empty");
        xs.push(x0 + dx);
        web_of.push(web);
    };
    for _ in 0..n_side {
        push(side / n_side as f64, None);
    }
    for (k, p) in walls.web.iter().enumerate() {
        for _ in 0..p.elements {
            push(thickness(p) / p.elements as f64, Some(k));
        }
    }
    for _ in 0..n_side {
        push(side / n_side as f64, None);
    }
    let (ys, rows) = box_axis(
        height,
        (&walls.bottom, &walls.top),
        AxisWalls {
            size: "height",
            low: "bottom flange",
            high: "top flange",
            between: "web",
        },
        n_web,
        thickness,
    )?;
    let coord = |i2: usize, j2: usize| [at_half_index(&xs, i2), at_half_index(&ys, j2)];
    let mut grid = Grid::new(coord, None);
    let mut walls_regions = WallRegions::default();
    let mut region = |wall: &'static str, k: usize, stack: &[PlySpec], frame: WallFrame| {
        walls_regions.of(wall, k, stack, frame)
    };
    let mut elements = Vec::new();
    for (j, &row) in rows.iter().enumerate() {
        for (i, &web) in web_of.iter().enumerate() {
            let r = match (row, web) {
                (Band::Low(k), _) => region("bottom", k, &walls.bottom, WallFrame::Tangent(PI)),
                (Band::High(k), _) => region("top", k, &walls.top, WallFrame::Tangent(0.0)),
                (Band::Mid, Some(k)) => {
                    region("web", k, &walls.web, WallFrame::Tangent(-FRAC_PI_2))
                }
                (Band::Mid, None) => continue,
            };
            elements.push(Element {
                kind: ElementKind::Quad8,
                nodes: grid.quad8(i, j),
                region: r,
            });
        }
    }
    Ok((grid.nodes, elements, walls_regions.regions))
}

/// A section made by one of the generators, kept with its inputs so that its node velocities
/// for a ply-thickness design variable can be made by the same code that places the nodes.
#[derive(Clone, Debug, PartialEq)]
pub enum GeneratedSection {
    /// [`tube`].
    Tube {
        inner_radius: f64,
        plies: Vec<PlySpec>,
        circumferential: usize,
    },
    /// [`thin_walled_box`], or with `open` the [`channel`].
    Walled {
        width: f64,
        height: f64,
        walls: BoxWalls,
        n_width: usize,
        n_height: usize,
        open: bool,
    },
    /// [`i_section`].
    I {
        width: f64,
        height: f64,
        walls: IWalls,
        n_side: usize,
        n_web: usize,
    },
}

impl GeneratedSection {
    /// The mesh.
    pub fn mesh(&self) -> Result<SectionMesh, SectionError> {
        let (nodes, elements, regions) = self.parts(&|p: &PlySpec| p.thickness)?;
        Ok(SectionMesh {
            nodes,
            elements,
            regions,
        })
    }

    /// The same section with every ply replaced by `f(ply)` (its wall given as the prefix of
    /// its region's name, `"top"`, `"bottom"`, `"left"`, `"right"` or `"web"`, empty for a tube):
    /// a design moved to other ply angles, thicknesses or materials.
    pub fn with_plies(&self, f: impl Fn(&str, &PlySpec) -> PlySpec) -> Self {
        let map = |wall: &str, plies: &[PlySpec]| -> Vec<PlySpec> {
            plies.iter().map(|p| f(wall, p)).collect()
        };
        let mut out = self.clone();
        match &mut out {
            GeneratedSection::Tube { plies, .. } => *plies = map("", plies),
            GeneratedSection::Walled { walls, .. } => {
                walls.top = map("top", &walls.top);
                walls.bottom = map("bottom", &walls.bottom);
                walls.left = map("left", &walls.left);
                walls.right = map("right", &walls.right);
            }
            GeneratedSection::I { walls, .. } => {
                walls.top = map("top", &walls.top);
                walls.bottom = map("bottom", &walls.bottom);
                walls.web = map("web", &walls.web);
            }
        }
        out
    }

    /// The velocity `dX/db` of every node of [`GeneratedSection::mesh`] for a design variable
    /// `b` that moves the thickness of each ply `p` at the rate `dthickness(p)` (m per unit of
    /// `b`; 0 for plies it does not move). The nodes are generated again with dual thicknesses,
    /// so the velocities are exact (and the positions affine in the thicknesses).
    pub fn node_velocities(
        &self,
        dthickness: impl Fn(&PlySpec) -> f64,
    ) -> Result<Vec<[f64; 2]>, SectionError> {
        let (nodes, _, _) = self.parts(&|p: &PlySpec| Dual::new(p.thickness, [dthickness(p)]))?;
        Ok(nodes.iter().map(|x| [x[0].d[0], x[1].d[0]]).collect())
    }

    fn parts<S: Scalar>(
        &self,
        thickness: &dyn Fn(&PlySpec) -> S,
    ) -> Result<Parts<S>, SectionError> {
        match self {
            GeneratedSection::Tube {
                inner_radius,
                plies,
                circumferential,
            } => tube_of(*inner_radius, plies, *circumferential, thickness),
            GeneratedSection::Walled {
                width,
                height,
                walls,
                n_width,
                n_height,
                open,
            } => {
                if *open && !walls.right.is_empty() {
                    return Err(SectionError::InvalidInput(
                        "a channel has no right wall: it is open towards +x2".into(),
                    ));
                }
                walled(
                    *width, *height, walls, *n_width, *n_height, *open, thickness,
                )
            }
            GeneratedSection::I {
                width,
                height,
                walls,
                n_side,
                n_web,
            } => i_section_of(*width, *height, walls, *n_side, *n_web, thickness),
        }
    }
}
