//! The section mesh: nodes in the `(x₂, x₃)` plane, quadratic elements, and regions (plies)
//! that carry a material, a ply angle and a local wall frame.

use laminate::OrthotropicMaterial;
use nalgebra::Matrix3;
use sens::Scalar;

use crate::SectionError;
use crate::element::{ElementKind, MAX_NODES};

/// The local wall frame of a region: the laminate axes `(x, y, z) = (x₁, t, n)` in which the ply
/// angle is measured. `x₁` is the beam axis, `t` the in-plane wall tangent and `n = x₁ × t` the
/// wall normal, so the frame is right-handed.
///
/// The ply's fibre direction is `cos θ x₁ + sin θ t` (rotation by `θ` about `n`), its transverse
/// direction `−sin θ x₁ + cos θ t`, its through-thickness direction `n`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum WallFrame {
    /// A straight wall whose tangent makes the angle `β` (radians) with `x₂`, counted towards
    /// `x₃`: `t = (cos β, sin β)`, `n = (−sin β, cos β)`. `Tangent(0.0)` puts the material
    /// axes 1, 2, 3 along `x₁, x₂, x₃` (solid sections).
    Tangent(f64),
    /// A wall curved around `centre` (tubes): at every point the normal points radially away
    /// from the centre, `n = (p − c)/|p − c|`, and `t = n × x₁ = (n₃, −n₂)` (clockwise when
    /// `x₁` points at the viewer).
    Radial { centre: [f64; 2] },
    /// A wall whose tangent follows each element's own parametric direction (at every
    /// integration point `t = ∂x/∂ξ / |∂x/∂ξ|`, or `∂x/∂η` for [`ElementDirection::Eta`]), so
    /// curved walls of any shape meshed with elements aligned with the wall (e.g. structured
    /// Gmsh meshes) get their local frame without per-element input. For quadrilaterals `ξ`
    /// runs from the edge 3–0 to the edge 1–2 (along the edge 0→1), `η` along the edge 0→3;
    /// for triangles along the edges 0→1 and 0→2.
    AlongElement(ElementDirection),
}

/// A parametric direction of an element (see [`WallFrame::AlongElement`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ElementDirection {
    Xi,
    Eta,
}

impl WallFrame {
    /// The in-plane tangent `t` at the point `p`, where the element's parametric directions
    /// are `dx_dxi = [∂x/∂ξ, ∂x/∂η]` (used only by [`WallFrame::AlongElement`]). Generic so
    /// that moving nodes (a ply thickness as a design variable) turn the frame with them.
    pub fn tangent_at<S: Scalar>(&self, p: [S; 2], dx_dxi: [[S; 2]; 2]) -> [S; 2] {
        match *self {
            WallFrame::AlongElement(dir) => {
                let v = dx_dxi[match dir {
                    ElementDirection::Xi => 0,
                    ElementDirection::Eta => 1,
                }];
                let l = v[0].hypot(v[1]);
                [v[0] / l, v[1] / l]
            }
            WallFrame::Tangent(beta) => [S::from_f64(beta.cos()), S::from_f64(beta.sin())],
            WallFrame::Radial { centre } => {
                let (d2, d3) = (p[0] - centre[0], p[1] - centre[1]);
                let r = d2.hypot(d3);
                if r.value() == 0.0 {
                    [S::one(), S::zero()]
                } else {
                    [d3 / r, -d2 / r]
                }
            }
        }
    }

    /// The rotation whose columns are the wall axes `(x₁, t, n)` in section axes
    /// `(x₁, x₂, x₃)`, at the point `p` (see [`WallFrame::tangent_at`]).
    pub fn rotation_at<S: Scalar>(&self, p: [S; 2], dx_dxi: [[S; 2]; 2]) -> Matrix3<S> {
        let [t2, t3] = self.tangent_at(p, dx_dxi);
        let (o, z) = (S::one(), S::zero());
        // n = x₁ × t = (0, −t₃, t₂).
        Matrix3::new(o, z, z, z, t2, -t3, z, t3, t2)
    }

    fn rotated(&self, alpha: f64) -> WallFrame {
        match *self {
            WallFrame::Tangent(beta) => WallFrame::Tangent(beta + alpha),
            WallFrame::Radial { centre } => WallFrame::Radial {
                centre: rotate2(centre, alpha),
            },
            WallFrame::AlongElement(d) => WallFrame::AlongElement(d),
        }
    }

    fn translated(&self, d: [f64; 2]) -> WallFrame {
        match *self {
            WallFrame::Tangent(beta) => WallFrame::Tangent(beta),
            WallFrame::Radial { centre } => WallFrame::Radial {
                centre: [centre[0] + d[0], centre[1] + d[1]],
            },
            WallFrame::AlongElement(dir) => WallFrame::AlongElement(dir),
        }
    }
}

fn rotate2(p: [f64; 2], alpha: f64) -> [f64; 2] {
    let (s, c) = alpha.sin_cos();
    [c * p[0] - s * p[1], s * p[0] + c * p[1]]
}

/// A region of the section: a ply of one wall, or a solid part. Every element belongs to one.
#[derive(Clone, Debug, PartialEq)]
pub struct Region {
    /// Name (ply or physical-group name), used in messages and by design maps.
    pub name: String,
    /// The material, in its principal axes.
    pub material: OrthotropicMaterial,
    /// Ply angle `θ` (radians): fibre direction from the beam axis, about the wall normal.
    pub ply_angle: f64,
    /// The local wall frame in which `θ` is measured.
    pub frame: WallFrame,
}

impl Region {
    /// A region with the given properties.
    pub fn new(
        name: impl Into<String>,
        material: OrthotropicMaterial,
        ply_angle: f64,
        frame: WallFrame,
    ) -> Self {
        Self {
            name: name.into(),
            material,
            ply_angle,
            frame,
        }
    }

    /// The rotation `R_ply(θ)` of the material axes in the wall axes, generic so that a dual
    /// angle carries its derivative.
    pub(crate) fn ply_rotation<S: Scalar>(angle: S) -> Matrix3<S> {
        laminate::rotation_about_normal(angle)
    }
}

/// One quadratic element: its kind, node indices (Gmsh order, see [`ElementKind`]) and region.
#[derive(Clone, Debug, PartialEq)]
pub struct Element {
    pub kind: ElementKind,
    pub nodes: Vec<usize>,
    pub region: usize,
}

/// A 2-D finite-element mesh of a beam cross-section in the `(x₂, x₃)` plane (m).
#[derive(Clone, Debug, PartialEq, Default)]
pub struct SectionMesh {
    pub nodes: Vec<[f64; 2]>,
    pub elements: Vec<Element>,
    pub regions: Vec<Region>,
}

impl SectionMesh {
    /// Index of the region with this name.
    pub fn region_index(&self, name: &str) -> Result<usize, SectionError> {
        self.regions
            .iter()
            .position(|r| r.name == name)
            .ok_or_else(|| SectionError::UnknownRegion {
                name: name.to_string(),
                line: None,
            })
    }

    /// The same section rotated by `alpha` (radians, from `x₂` towards `x₃`) about the origin:
    /// nodes and wall frames turn together, so the material turns with the geometry.
    pub fn rotated(&self, alpha: f64) -> SectionMesh {
        let mut m = self.clone();
        for p in &mut m.nodes {
            *p = rotate2(*p, alpha);
        }
        for r in &mut m.regions {
            r.frame = r.frame.rotated(alpha);
        }
        m
    }

    /// How thin the section's walls are for its size: twice its area over its boundary length
    /// (a thin wall's thickness; corner to corner, straight), over the diagonal of its bounding
    /// box. About `h/w` for a `w × h` strip, `t/(2r)` for a thin tube.
    pub fn thinness(&self) -> f64 {
        let mut edges: std::collections::HashMap<(usize, usize), usize> = Default::default();
        let mut area = 0.0;
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for el in &self.elements {
            let c = el.kind.corner_count();
            let mut element_area = 0.0;
            for k in 0..c {
                let (a, b) = (el.nodes[k], el.nodes[(k + 1) % c]);
                *edges.entry((a.min(b), a.max(b))).or_default() += 1;
                let (p, q) = (self.nodes[a], self.nodes[b]);
                element_area += 0.5 * (p[0] * q[1] - q[0] * p[1]);
                for i in 0..2 {
                    lo[i] = lo[i].min(p[i]);
                    hi[i] = hi[i].max(p[i]);
                }
            }
            area += f64::abs(element_area);
        }
        let boundary: f64 = edges
            .iter()
            .filter(|(_, n)| **n == 1)
            .map(|(&(a, b), _)| {
                let (p, q) = (self.nodes[a], self.nodes[b]);
                (p[0] - q[0]).hypot(p[1] - q[1])
            })
            .sum();
        let size = (hi[0] - lo[0]).hypot(hi[1] - lo[1]);
        2.0 * area / boundary / size
    }

    /// The same section moved by `d` in its plane.
    pub fn translated(&self, d: [f64; 2]) -> SectionMesh {
        let mut m = self.clone();
        for p in &mut m.nodes {
            *p = [p[0] + d[0], p[1] + d[1]];
        }
        for r in &mut m.regions {
            r.frame = r.frame.translated(d);
        }
        m
    }

    /// Check the topology and geometry: node and region indices, node counts, finite
    /// coordinates and angles, positive Jacobians (no inverted or zero-area elements) and
    /// connectivity.
    pub fn validate(&self) -> Result<(), SectionError> {
        if self.elements.is_empty() {
            return Err(SectionError::Empty);
        }
        for (i, p) in self.nodes.iter().enumerate() {
            if !(p[0].is_finite() && p[1].is_finite()) {
                return Err(SectionError::NonFiniteNode {
                    node: i,
                    x2: p[0],
                    x3: p[1],
                });
            }
        }
        for r in &self.regions {
            if !r.ply_angle.is_finite() {
                return Err(SectionError::NonFiniteAngle {
                    region: r.name.clone(),
                    angle: r.ply_angle,
                });
            }
            let frame_ok = match r.frame {
                WallFrame::Tangent(b) => b.is_finite(),
                WallFrame::Radial { centre } => centre.iter().all(|c| c.is_finite()),
                WallFrame::AlongElement(_) => true,
            };
            if !frame_ok {
                return Err(SectionError::InvalidInput(format!(
                    "region '{}': its wall frame {:?} is not finite",
                    r.name, r.frame
                )));
            }
        }
        for (e, el) in self.elements.iter().enumerate() {
            let nn = el.kind.node_count();
            if el.nodes.len() != nn {
                return Err(SectionError::WrongNodeCount {
                    element: e,
                    kind: el.kind.name(),
                    expected: nn,
                    got: el.nodes.len(),
                });
            }
            for (a, &n) in el.nodes.iter().enumerate() {
                if n >= self.nodes.len() {
                    return Err(SectionError::NodeOutOfRange {
                        element: e,
                        node: n,
                        count: self.nodes.len(),
                    });
                }
                if el.nodes[..a].contains(&n) {
                    return Err(SectionError::RepeatedNode {
                        element: e,
                        node: n,
                    });
                }
            }
            if el.region >= self.regions.len() {
                return Err(SectionError::RegionOutOfRange {
                    element: e,
                    region: el.region,
                    count: self.regions.len(),
                });
            }
            self.check_jacobian(e)?;
        }
        self.check_connected()
    }

    fn check_jacobian(&self, e: usize) -> Result<(), SectionError> {
        let el = &self.elements[e];
        let xs: Vec<[f64; 2]> = el.nodes.iter().map(|&n| self.nodes[n]).collect();
        let nc = el.kind.corner_count();
        let mut size2: f64 = 0.0;
        for a in 0..nc {
            let b = (a + 1) % nc;
            size2 = size2.max((xs[a][0] - xs[b][0]).powi(2) + (xs[a][1] - xs[b][1]).powi(2));
        }
        let size = size2.sqrt();
        let mut n = [0.0; MAX_NODES];
        let mut dn = [[0.0; 2]; MAX_NODES];
        // Integration points and corners (a folded mid-side node shows up at the corners first).
        let corners: &[(f64, f64)] = match el.kind {
            ElementKind::Tri6 => &[(0.0, 0.0), (1.0, 0.0), (0.0, 1.0)],
            _ => &[(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)],
        };
        let pts = el
            .kind
            .rule()
            .iter()
            .map(|&(x, y, _)| (x, y))
            .chain(corners.iter().copied());
        for (xi, eta) in pts {
            el.kind.shape(xi, eta, &mut n, &mut dn);
            let j = jacobian(&xs, &dn);
            let det = j[0][0] * j[1][1] - j[0][1] * j[1][0];
            // The reference element has size ~2 (quads) or ~1 (triangles).
            let scale = if el.kind == ElementKind::Tri6 {
                size2
            } else {
                0.25 * size2
            };
            if !det.is_finite() || det.abs() <= 1e-10 * scale {
                return Err(SectionError::DegenerateElement {
                    element: e,
                    det_j: det,
                    size,
                });
            }
            if det < 0.0 {
                return Err(SectionError::InvertedElement {
                    element: e,
                    det_j: det,
                });
            }
        }
        Ok(())
    }

    fn check_connected(&self) -> Result<(), SectionError> {
        // Union–find over nodes used by elements.
        let mut parent: Vec<usize> = (0..self.nodes.len()).collect();
        fn find(p: &mut [usize], mut i: usize) -> usize {
            while p[i] != i {
                p[i] = p[p[i]];
                i = p[i];
            }
            i
        }
        for el in &self.elements {
            let a = find(&mut parent, el.nodes[0]);
            for &n in &el.nodes[1..] {
                let b = find(&mut parent, n);
                if a != b {
                    parent[b] = a;
                }
            }
        }
        let root0 = find(&mut parent, self.elements[0].nodes[0]);
        let mut roots: Vec<usize> = self
            .elements
            .iter()
            .map(|el| find(&mut parent, el.nodes[0]))
            .collect();
        let first_other = roots.iter().position(|&r| r != root0);
        if let Some(element) = first_other {
            roots.sort_unstable();
            roots.dedup();
            return Err(SectionError::Disconnected {
                parts: roots.len(),
                element,
            });
        }
        Ok(())
    }
}

/// `J[i][k] = ∂x_i/∂ξ_k` from nodal coordinates and reference derivatives.
pub(crate) fn jacobian(xs: &[[f64; 2]], dn: &[[f64; 2]]) -> [[f64; 2]; 2] {
    let mut j = [[0.0; 2]; 2];
    for (x, d) in xs.iter().zip(dn) {
        for i in 0..2 {
            for k in 0..2 {
                j[i][k] += x[i] * d[k];
            }
        }
    }
    j
}
