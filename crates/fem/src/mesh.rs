//! Meshes: nodes, beam and shell elements, structured generators and a Gmsh `.msh` v4 ASCII
//! reader (from text: this crate does no file I/O).

use nalgebra::Vector3;

/// Index of a node in [`Mesh::nodes`].
pub type NodeId = usize;

/// One finite element. `property` indexes [`crate::Properties::sections`] (beams) or
/// [`crate::Properties::laminates`] (shells).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Element {
    /// Two-node Timoshenko beam; `orientation` gives the section's x₂ axis (its part normal to
    /// the beam axis).
    Beam {
        nodes: [NodeId; 2],
        property: usize,
        orientation: Vector3<f64>,
    },
    /// Three-node flat shell; `material_axis` is the laminate's reference x axis (projected on
    /// the element plane), from which ply angles are measured.
    Shell {
        nodes: [NodeId; 3],
        property: usize,
        material_axis: Vector3<f64>,
    },
}

impl Element {
    /// The element's nodes.
    pub fn nodes(&self) -> &[NodeId] {
        match self {
            Element::Beam { nodes, .. } => nodes,
            Element::Shell { nodes, .. } => nodes,
        }
    }
}

/// A stretch of a [`Mesh::segmented_beam`]: its length (in any unit: the segments divide the
/// beam in the proportions of their lengths), its number of equal elements and their section
/// (an index of [`crate::Properties::sections`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BeamSegment {
    pub length: f64,
    pub elements: usize,
    pub property: usize,
}

/// Nodes and elements of one flexible body.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    /// Node positions (m).
    pub nodes: Vec<Vector3<f64>>,
    /// Elements.
    pub elements: Vec<Element>,
}

/// Why a mesh is unusable.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MeshError {
    #[error("element {element} refers to node {node}, but the mesh has {n_nodes} nodes")]
    BadNode {
        element: usize,
        node: usize,
        n_nodes: usize,
    },
    #[error("a mesh needs at least {what}")]
    TooSmall { what: &'static str },
    #[error("gmsh line {line}: {reason}")]
    Gmsh { line: usize, reason: String },
}

impl Mesh {
    /// Number of dof (6 per node).
    pub fn n_dofs(&self) -> usize {
        6 * self.nodes.len()
    }

    /// Check that every element refers to existing nodes.
    pub fn validate(&self) -> Result<(), MeshError> {
        let n = self.nodes.len();
        for (e, el) in self.elements.iter().enumerate() {
            for &node in el.nodes() {
                if node >= n {
                    return Err(MeshError::BadNode {
                        element: e,
                        node,
                        n_nodes: n,
                    });
                }
            }
        }
        Ok(())
    }

    /// A straight beam from `start` to `end` split into `n` equal elements (nodes `0..=n` in
    /// order), section `property`, section x₂ axis along `orientation`.
    pub fn straight_beam(
        start: Vector3<f64>,
        end: Vector3<f64>,
        n: usize,
        property: usize,
        orientation: Vector3<f64>,
    ) -> Result<Self, MeshError> {
        let whole = BeamSegment {
            length: 1.0,
            elements: n,
            property,
        };
        Self::segmented_beam(start, end, &[whole], orientation)
    }

    /// A straight beam from `start` to `end` made of `segments` in order, each split into its
    /// number of equal elements of its section (nodes numbered from `start`, one node shared
    /// where two segments meet). The segments divide `start`–`end` in the proportions of their
    /// lengths (node `i` of a single segment of `n` elements at `start + (end − start) i/n`).
    pub fn segmented_beam(
        start: Vector3<f64>,
        end: Vector3<f64>,
        segments: &[BeamSegment],
        orientation: Vector3<f64>,
    ) -> Result<Self, MeshError> {
        if segments.iter().all(|s| s.elements == 0) {
            return Err(MeshError::TooSmall {
                what: "one beam element",
            });
        }
        let total: f64 = segments.iter().map(|s| s.length).sum();
        if segments
            .iter()
            .any(|s| s.elements == 0 || !(s.length > 0.0))
            || !total.is_finite()
        {
            return Err(MeshError::TooSmall {
                what: "one element and a positive, finite length in each beam segment",
            });
        }
        let mut nodes = vec![start];
        let mut elements = Vec::new();
        let mut covered = 0.0;
        for s in segments {
            for i in 1..=s.elements {
                // as a fraction of the whole: i / n exactly for a single segment
                let along = covered / total + (s.length / total) * (i as f64 / s.elements as f64);
                let k = nodes.len();
                nodes.push(start + (end - start) * along);
                elements.push(Element::Beam {
                    nodes: [k - 1, k],
                    property: s.property,
                    orientation,
                });
            }
            covered += s.length;
        }
        Ok(Self { nodes, elements })
    }

    /// A rectangular plate `[0, a] × [0, b]` in the x–y plane meshed with `nx × ny` cells, each
    /// split into two triangles with alternating diagonals (a symmetric, refinable pattern).
    /// Node `(i, j)` (i along x, j along y) is `j (nx + 1) + i`.
    pub fn rectangle(
        a: f64,
        b: f64,
        nx: usize,
        ny: usize,
        property: usize,
    ) -> Result<Self, MeshError> {
        if nx == 0 || ny == 0 {
            return Err(MeshError::TooSmall {
                what: "one cell in each direction",
            });
        }
        let mut nodes = Vec::with_capacity((nx + 1) * (ny + 1));
        for j in 0..=ny {
            for i in 0..=nx {
                nodes.push(Vector3::new(
                    a * i as f64 / nx as f64,
                    b * j as f64 / ny as f64,
                    0.0,
                ));
            }
        }
        let id = |i: usize, j: usize| j * (nx + 1) + i;
        let axis = Vector3::x();
        let mut elements = Vec::with_capacity(2 * nx * ny);
        for j in 0..ny {
            for i in 0..nx {
                let (p00, p10, p01, p11) = (id(i, j), id(i + 1, j), id(i, j + 1), id(i + 1, j + 1));
                let tris = if (i + j) % 2 == 0 {
                    [[p00, p10, p11], [p00, p11, p01]]
                } else {
                    [[p00, p10, p01], [p10, p11, p01]]
                };
                for t in tris {
                    elements.push(Element::Shell {
                        nodes: t,
                        property,
                        material_axis: axis,
                    });
                }
            }
        }
        Ok(Self { nodes, elements })
    }

    /// Nodes within `tol` of the line through `a` and `b` (between them).
    pub fn nodes_on_segment(&self, a: Vector3<f64>, b: Vector3<f64>, tol: f64) -> Vec<NodeId> {
        let d = b - a;
        let l2 = d.norm_squared();
        self.nodes
            .iter()
            .enumerate()
            .filter(|(_, p)| {
                let t = ((*p - a).dot(&d) / l2).clamp(0.0, 1.0);
                (a + d * t - *p).norm() <= tol
            })
            .map(|(k, _)| k)
            .collect()
    }

    /// The node closest to `p`.
    pub fn closest_node(&self, p: &Vector3<f64>) -> Option<NodeId> {
        closest(&self.nodes, p)
    }

    /// The lowest and highest coordinates of the nodes (infinite bounds for an empty mesh).
    pub fn bounding_box(&self) -> (Vector3<f64>, Vector3<f64>) {
        bounding_box(&self.nodes)
    }
}

/// The lowest and highest coordinates of `points` (infinite bounds for none).
pub fn bounding_box(points: &[Vector3<f64>]) -> (Vector3<f64>, Vector3<f64>) {
    points.iter().fold(
        (
            Vector3::repeat(f64::INFINITY),
            Vector3::repeat(f64::NEG_INFINITY),
        ),
        |(lo, hi), p| (lo.inf(p), hi.sup(p)),
    )
}

/// The index of the point of `points` nearest `p`.
pub(crate) fn closest(points: &[Vector3<f64>], p: &Vector3<f64>) -> Option<NodeId> {
    points
        .iter()
        .enumerate()
        .min_by(|x, y| (x.1 - p).norm().total_cmp(&(y.1 - p).norm()))
        .map(|(k, _)| k)
}

/// A triangle mesh read from Gmsh: nodes, triangles with the tag of the entity (surface) each
/// belongs to, so that properties can be assigned per surface.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct GmshTriangles {
    pub nodes: Vec<Vector3<f64>>,
    pub triangles: Vec<[NodeId; 3]>,
    pub entity: Vec<i64>,
}

impl GmshTriangles {
    /// Shell mesh with every triangle using `property` and material axis `axis`.
    pub fn to_mesh(&self, property: usize, axis: Vector3<f64>) -> Mesh {
        Mesh {
            nodes: self.nodes.clone(),
            elements: self
                .triangles
                .iter()
                .map(|&nodes| Element::Shell {
                    nodes,
                    property,
                    material_axis: axis,
                })
                .collect(),
        }
    }
}

impl GmshTriangles {
    /// Shell mesh with the property of each triangle chosen from its Gmsh entity tag.
    pub fn to_mesh_by_entity(&self, property: impl Fn(i64) -> usize, axis: Vector3<f64>) -> Mesh {
        Mesh {
            nodes: self.nodes.clone(),
            elements: self
                .triangles
                .iter()
                .zip(&self.entity)
                .map(|(&nodes, &e)| Element::Shell {
                    nodes,
                    property: property(e),
                    material_axis: axis,
                })
                .collect(),
        }
    }
}

/// Parse the `$Nodes` and `$Elements` sections of a Gmsh `.msh` version 4 ASCII text. Node tags
/// are mapped to consecutive indices; 3-node triangles (type 2) are kept, other element types
/// (points, lines, …) ignored.
pub fn parse_gmsh_v4(text: &str) -> Result<GmshTriangles, MeshError> {
    let lines: Vec<(usize, &str)> = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty())
        .collect();
    let err = |line: usize, reason: String| MeshError::Gmsh { line, reason };
    let nums = |line: usize, s: &str| -> Result<Vec<f64>, MeshError> {
        s.split_whitespace()
            .map(|t| {
                t.parse::<f64>()
                    .map_err(|_| err(line, format!("expected a number, found {t:?}")))
            })
            .collect()
    };
    let mut pos = 0;
    let mut out = GmshTriangles::default();
    let mut tag_to_index = std::collections::HashMap::new();
    let mut saw_format = false;
    let mut saw_nodes = false;
    while pos < lines.len() {
        let (ln, l) = lines[pos];
        pos += 1;
        let mut next = |what: &str| -> Result<(usize, &str), MeshError> {
            let r = lines
                .get(pos)
                .copied()
                .ok_or_else(|| err(ln, format!("unexpected end of file in {what}")))?;
            pos += 1;
            Ok(r)
        };
        match l {
            "$MeshFormat" => {
                let (fl, f) = next("$MeshFormat")?;
                let v = nums(fl, f)?;
                if v.len() < 3 || !(4.0..5.0).contains(&v[0]) {
                    return Err(err(
                        fl,
                        format!("unsupported mesh format {f:?} (need 4.x ASCII)"),
                    ));
                }
                if v[1] != 0.0 {
                    return Err(err(fl, "binary .msh files are not supported".into()));
                }
                saw_format = true;
            }
            "$Nodes" => {
                let (hl, h) = next("$Nodes")?;
                let hdr = nums(hl, h)?;
                if hdr.len() < 4 {
                    return Err(err(hl, "malformed $Nodes header".into()));
                }
                for _ in 0..hdr[0] as usize {
                    let (bl, b) = next("$Nodes")?;
                    let blk = nums(bl, b)?;
                    if blk.len() < 4 {
                        return Err(err(bl, "malformed node block header".into()));
                    }
                    let parametric = blk[2] != 0.0;
                    let count = blk[3] as usize;
                    // grown as the tags are read: the count comes from the file and must not
                    // reserve memory before the lines are there
                    let mut tags = Vec::new();
                    for _ in 0..count {
                        let (tl, t) = next("$Nodes")?;
                        let v = nums(tl, t)?;
                        tags.push(
                            *v.first()
                                .ok_or_else(|| err(tl, "missing node tag".into()))?
                                as i64,
                        );
                    }
                    for &tag in &tags {
                        let (cl, c) = next("$Nodes")?;
                        let v = nums(cl, c)?;
                        if v.len() < 3 || (parametric && v.len() < 4) {
                            return Err(err(cl, "expected x y z coordinates".into()));
                        }
                        tag_to_index.insert(tag, out.nodes.len());
                        out.nodes.push(Vector3::new(v[0], v[1], v[2]));
                    }
                }
                saw_nodes = true;
            }
            "$Elements" => {
                if !saw_nodes {
                    return Err(err(ln, "$Elements before $Nodes".into()));
                }
                let (hl, h) = next("$Elements")?;
                let hdr = nums(hl, h)?;
                if hdr.len() < 4 {
                    return Err(err(hl, "malformed $Elements header".into()));
                }
                for _ in 0..hdr[0] as usize {
                    let (bl, b) = next("$Elements")?;
                    let blk = nums(bl, b)?;
                    if blk.len() < 4 {
                        return Err(err(bl, "malformed element block header".into()));
                    }
                    let entity = blk[1] as i64;
                    let ty = blk[2] as i64;
                    for _ in 0..blk[3] as usize {
                        let (el, e) = next("$Elements")?;
                        if ty != 2 {
                            continue;
                        }
                        let v = nums(el, e)?;
                        if v.len() < 4 {
                            return Err(err(el, "a triangle needs a tag and three nodes".into()));
                        }
                        let mut tri = [0; 3];
                        for k in 0..3 {
                            let tag = v[k + 1] as i64;
                            tri[k] = *tag_to_index
                                .get(&tag)
                                .ok_or_else(|| err(el, format!("unknown node tag {tag}")))?;
                        }
                        out.triangles.push(tri);
                        out.entity.push(entity);
                    }
                }
            }
            _ => {}
        }
    }
    if !saw_format {
        return Err(err(1, "no $MeshFormat section".into()));
    }
    if out.triangles.is_empty() {
        return Err(MeshError::TooSmall {
            what: "one triangle (element type 2)",
        });
    }
    Ok(out)
}
