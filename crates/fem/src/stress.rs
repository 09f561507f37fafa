//! The plies' stresses in a flexible body's modes (docs/failure-criteria.md, "In a run").
//!
//! Both steps are linear: an element's load is linear in the body's modal coordinates `w`
//! (`d = E w`, [`ElementDeformation`]) — a shell element's laminate deformation at its
//! centroid, a beam element's section forces at its ends and middle — and each ply point's
//! stress in its material axes is linear in that load (`σ = P d`, [`PlyStressPoint`]): the
//! laminate's recovery through the thickness, or the section analysis's at its integration
//! points. So the ply stresses of a body in motion are `P E w`, with `E` and `P` formed once,
//! in the design's scalar: on dual numbers their tangents are the derivatives of the modes and
//! section stiffnesses (through `E`) and of the plies' angles, thicknesses and materials
//! (through `P`), and a response evaluated with seeded `w` has its total derivative.

use laminate::{OrthotropicMaterial, PlateState, PlyPosition, PlyStack};
use nalgebra::{DMatrix, Matrix6, SMatrix, Vector3};
use sens::Scalar;

use crate::assembly::{Properties, beam_element_section};
use crate::beam::{beam_frame, beam_station_forces};
use crate::error::FemError;
use crate::mesh::{Element, Mesh};
use crate::modal::{ModalBody, NODE_DOFS};
use crate::shell::{Membrane, TriGeometry, centroid_deformation};

/// The size of an element's load: a shell's laminate deformation `[ε⁰xx, ε⁰yy, γ⁰xy, κxx,
/// κyy, 2κxy, Qx, Qy]` — reference-surface strains and curvatures (laminate axes, engineering
/// shear, twisting curvature `2κxy`) and the transverse shear forces (N/m) — or a beam's
/// section forces `[F₁, F₂, F₃, M₁, M₂, M₃]` (N, N·m; section axes) and two zeros.
pub const DEFORMATION: usize = 8;

/// A laminate of a shell body as its ply stresses need it: the stack and each ply's material
/// stiffness `C̄` (material axes), in the design's scalar (a material design variable moves
/// `C̄`).
#[derive(Clone, Debug)]
pub struct ShellPlies<S: Scalar> {
    pub stack: PlyStack<S>,
    pub c_bar: Vec<Matrix6<S>>,
}

impl<S: Scalar> ShellPlies<S> {
    /// The same plies converted to another scalar.
    pub fn map<Q: Scalar>(&self, f: &impl Fn(S) -> Q) -> ShellPlies<Q> {
        ShellPlies {
            stack: self.stack.map(f),
            c_bar: self.c_bar.iter().map(|c| c.map(f)).collect(),
        }
    }

    /// The stack with its plies' own materials.
    pub fn new(stack: PlyStack<S>) -> Self {
        let c_bar = (stack.plies().iter())
            .map(|p| p.material.stiffness().map(S::from_f64))
            .collect();
        Self { stack, c_bar }
    }
}

/// Where a stress point is: through the thickness of a shell's ply, or at an integration point
/// `(x₂, x₃)` (m) of a beam's section.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PointPlace {
    Ply(PlyPosition),
    Section([f64; 2]),
}

/// A stress point of a laminate's ply or of a section's region and the stress there, material
/// axes `[11, 22, 33, 23, 13, 12]` (Pa), per unit of each component of its element's load
/// ([`DEFORMATION`]).
#[derive(Clone, Debug)]
pub struct PlyStressPoint<S: Scalar> {
    /// The ply of a shell's laminate (from 0, bottom first), or the region of a beam's section.
    pub ply: usize,
    pub place: PointPlace,
    pub per_deformation: SMatrix<S, 6, DEFORMATION>,
}

/// The stress points of one laminate (bottom ply first) or one beam section (its integration
/// points, as [`section::SectionAnalysis::stresses`] orders them), and the materials of its
/// plies or regions.
#[derive(Clone, Debug)]
pub struct LaminatePoints<S: Scalar> {
    pub points: Vec<PlyStressPoint<S>>,
    pub materials: Vec<OrthotropicMaterial>,
}

impl<S: Scalar> LaminatePoints<S> {
    /// The same points converted to another scalar.
    pub fn map<Q: Scalar>(&self, f: &impl Fn(S) -> Q) -> LaminatePoints<Q> {
        LaminatePoints {
            points: (self.points.iter())
                .map(|p| PlyStressPoint {
                    ply: p.ply,
                    place: p.place,
                    per_deformation: p.per_deformation.map(f),
                })
                .collect(),
            materials: self.materials.clone(),
        }
    }
}

/// An element's load per modal coordinate (`DEFORMATION × n_modes`) at one of its stations: a
/// shell element's laminate deformation at its centroid, in the element's laminate axes (`e₁`
/// the material axis on the element plane); a beam element's section forces at its start, its
/// middle or its end ([`BEAM_STATIONS`]).
#[derive(Clone, Debug)]
pub struct ElementDeformation<S: Scalar> {
    /// The element's index in the mesh.
    pub element: usize,
    /// Its laminate or section (an index of [`ModalStresses::laminates`]).
    pub laminate: usize,
    /// A beam element's station, the fraction of its length from its first node (`None`: a
    /// shell element's centroid).
    pub station: Option<f64>,
    /// Where the station is in the body frame (m).
    pub centroid: Vector3<f64>,
    pub per_mode: DMatrix<S>,
}

/// The ply stresses of a flexible body's modes ([`shell_modal_stresses`],
/// [`beam_modal_stresses`]).
#[derive(Clone, Debug)]
pub struct ModalStresses<S: Scalar> {
    pub n_modes: usize,
    pub laminates: Vec<LaminatePoints<S>>,
    /// The shell (or beam) elements' stations, in mesh order (a beam element's from its first
    /// node).
    pub elements: Vec<ElementDeformation<S>>,
}

impl<S: Scalar> ModalStresses<S> {
    /// Convert the scalars (e.g. the values of a dual set).
    pub fn map<Q: Scalar>(&self, f: &impl Fn(S) -> Q) -> ModalStresses<Q> {
        ModalStresses {
            n_modes: self.n_modes,
            laminates: self.laminates.iter().map(|l| l.map(f)).collect(),
            elements: (self.elements.iter())
                .map(|e| ElementDeformation {
                    element: e.element,
                    laminate: e.laminate,
                    station: e.station,
                    centroid: e.centroid,
                    per_mode: e.per_mode.map(f),
                })
                .collect(),
        }
    }

    /// The positions in [`Self::elements`] of mesh element `element`'s stations (empty: not an
    /// element of the body's kind).
    pub fn element_stations(&self, element: usize) -> std::ops::Range<usize> {
        let start = self.elements.partition_point(|e| e.element < element);
        let end = self.elements.partition_point(|e| e.element <= element);
        start..end
    }

    /// The position in [`Self::elements`] of mesh element `element` at its centroid (a shell)
    /// or middle (a beam) (`None`: not an element of the body's kind).
    pub fn element_index(&self, element: usize) -> Option<usize> {
        self.element_stations(element)
            .find(|&i| self.elements[i].station.is_none_or(|x| x == 0.5))
    }

    /// The deformation of [`Self::elements`]`[i]` at the modal coordinates `w`.
    pub fn deformation<T: Scalar + From<S>>(&self, i: usize, w: &[T]) -> [T; DEFORMATION] {
        let e = &self.elements[i].per_mode;
        std::array::from_fn(|r| {
            (w.iter().enumerate()).fold(T::zero(), |acc, (j, &wj)| acc + T::from(e[(r, j)]) * wj)
        })
    }

    /// [`Self::deformation`] on the values alone.
    pub fn deformation_value(&self, i: usize, w: &[f64]) -> [f64; DEFORMATION] {
        let e = &self.elements[i].per_mode;
        std::array::from_fn(|r| {
            (w.iter().enumerate())
                .map(|(j, &wj)| e[(r, j)].value() * wj)
                .sum()
        })
    }

    /// [`Self::stress`] on the values alone.
    pub fn stress_value(&self, i: usize, point: usize, d: &[f64; DEFORMATION]) -> [f64; 6] {
        let p = &self.laminates[self.elements[i].laminate].points[point].per_deformation;
        std::array::from_fn(|r| {
            (d.iter().enumerate())
                .map(|(c, &dc)| p[(r, c)].value() * dc)
                .sum()
        })
    }

    /// The stress at ply point `point` of [`Self::elements`]`[i]`'s laminate under its
    /// deformation `d`, material axes (Pa).
    pub fn stress<T: Scalar + From<S>>(
        &self,
        i: usize,
        point: usize,
        d: &[T; DEFORMATION],
    ) -> [T; 6] {
        let p = &self.laminates[self.elements[i].laminate].points[point].per_deformation;
        std::array::from_fn(|r| {
            (d.iter().enumerate()).fold(T::zero(), |acc, (c, &dc)| acc + T::from(p[(r, c)]) * dc)
        })
    }
}

/// The ply stresses of the modes of `body`, a shell body on `mesh` whose element properties
/// index `plies` (one [`ShellPlies`] per laminate; the body's modes in the mesh's axes, its
/// first nodes the mesh's). Beam elements have none.
pub fn shell_modal_stresses<S: Scalar>(
    mesh: &Mesh,
    plies: &[ShellPlies<S>],
    membrane: Membrane,
    body: &ModalBody<S>,
) -> Result<ModalStresses<S>, FemError> {
    let nm = body.n_modes();
    check_nodes(mesh, body)?;
    let laminates: Vec<LaminatePoints<S>> = plies.iter().map(laminate_points).collect();
    let shear: Vec<_> = (plies.iter())
        .map(|p| {
            let density = vec![S::zero(); p.c_bar.len()];
            p.stack.stiffness_with_materials(&p.c_bar, &density).shear
        })
        .collect();
    let mut elements = Vec::new();
    for (e, el) in mesh.elements.iter().enumerate() {
        let Element::Shell {
            nodes,
            property,
            material_axis,
        } = *el
        else {
            continue;
        };
        if property >= plies.len() {
            return Err(FemError::MissingProperty {
                element: e,
                kind: "laminate",
                property,
                available: plies.len(),
            });
        }
        let p = nodes.map(|n| mesh.nodes[n]);
        let g = TriGeometry::new(p, &material_axis, e)?;
        let b = centroid_deformation(&g, membrane);
        let r = g.frame;
        // the element's local nodal dof per mode (18 × nm), then E = B U
        let u = local_dof(body, &nodes, &r);
        let mut per_mode = DMatrix::<S>::zeros(DEFORMATION, nm);
        for j in 0..nm {
            let mut d = [S::zero(); DEFORMATION];
            for (row, dr) in d.iter_mut().enumerate() {
                for c in 0..18 {
                    *dr += u[(c, j)] * b[(row, c)];
                }
            }
            // the shear forces of the shear strains, Q = A_s γ
            let a_s = &shear[property];
            let q = [
                a_s[(0, 0)] * d[6] + a_s[(0, 1)] * d[7],
                a_s[(1, 0)] * d[6] + a_s[(1, 1)] * d[7],
            ];
            (d[6], d[7]) = (q[0], q[1]);
            for (row, dr) in d.iter().enumerate() {
                per_mode[(row, j)] = *dr;
            }
        }
        let centroid = nodes
            .iter()
            .map(|&n| body.node_positions[n])
            .sum::<Vector3<f64>>()
            / 3.0;
        elements.push(ElementDeformation {
            element: e,
            laminate: property,
            station: None,
            centroid,
            per_mode,
        });
    }
    Ok(ModalStresses {
        n_modes: nm,
        laminates,
        elements,
    })
}

/// Each ply point's stress per unit deformation: the stack's recovery
/// ([`PlyStack::ply_points_with_materials`], linear in the deformation) of each unit
/// deformation.
fn laminate_points<S: Scalar>(plies: &ShellPlies<S>) -> LaminatePoints<S> {
    let unit = |k: usize| -> PlateState<S> {
        let one = |i: usize| if i == k { S::one() } else { S::zero() };
        PlateState {
            membrane: [one(0), one(1), one(2)],
            curvature: [one(3), one(4), one(5)],
            shear_forces: [one(6), one(7)],
        }
    };
    let columns: Vec<_> = (0..DEFORMATION)
        .map(|k| {
            plies
                .stack
                .ply_points_with_materials(&unit(k), &plies.c_bar)
        })
        .collect();
    let points = (0..columns[0].len())
        .map(|i| PlyStressPoint {
            ply: columns[0][i].ply,
            place: PointPlace::Ply(columns[0][i].position),
            per_deformation: SMatrix::from_fn(|r, c| columns[c][i].stress[r]),
        })
        .collect();
    LaminatePoints {
        points,
        materials: plies.stack.plies().iter().map(|p| p.material).collect(),
    }
}

/// Where a beam element's stresses are sampled, as fractions of its length from its first
/// node: its ends, where the joints' and supports' loads peak, and its middle.
pub const BEAM_STATIONS: [f64; 3] = [0.0, 0.5, 1.0];

/// The ply stresses of the modes of `body`, a beam body on `mesh` whose element properties
/// index `sections` (each one's stress points per unit section force, [`section_points`]) and
/// `props` (the section stiffnesses its modes were computed with, in the design's scalar;
/// `planar_axis` that of a planar analysis, whose beams release their out-of-plane shear).
/// Each element's loads are its section forces at its [`BEAM_STATIONS`]
/// ([`beam_station_forces`]), from its nodes' modal displacements in its frame. Shell elements
/// have none.
pub fn beam_modal_stresses<S: Scalar>(
    mesh: &Mesh,
    (props, planar_axis): (&Properties<S>, Option<usize>),
    sections: &[LaminatePoints<S>],
    body: &ModalBody<S>,
) -> Result<ModalStresses<S>, FemError> {
    let nm = body.n_modes();
    check_nodes(mesh, body)?;
    let mut elements = Vec::new();
    for (e, el) in mesh.elements.iter().enumerate() {
        let Element::Beam {
            nodes,
            property,
            orientation,
        } = *el
        else {
            continue;
        };
        if property >= sections.len() {
            return Err(FemError::MissingProperty {
                element: e,
                kind: "section's stress points",
                property,
                available: sections.len(),
            });
        }
        let (l, lam) = beam_frame(&mesh.nodes[nodes[0]], &mesh.nodes[nodes[1]], &orientation);
        let section = beam_element_section(props, (e, property), &lam, planar_axis)?;
        let at = BEAM_STATIONS.map(|x| x * l);
        let forces = beam_station_forces(&section, l, e, &at)?;
        let u = local_dof(body, &nodes, &lam);
        let [p1, p2] = nodes.map(|n| body.node_positions[n]);
        for (station, forces) in BEAM_STATIONS.iter().zip(&forces) {
            let mut per_mode = DMatrix::<S>::zeros(DEFORMATION, nm);
            for j in 0..nm {
                for r in 0..6 {
                    let mut x = S::zero();
                    for c in 0..12 {
                        x += forces[(r, c)] * u[(c, j)];
                    }
                    per_mode[(r, j)] = x;
                }
            }
            elements.push(ElementDeformation {
                element: e,
                laminate: property,
                station: Some(*station),
                centroid: p1 + (p2 - p1) * *station,
                per_mode,
            });
        }
    }
    Ok(ModalStresses {
        n_modes: nm,
        laminates: sections.to_vec(),
        elements,
    })
}

/// The stress points of a beam section: each integration point of `analysis` (region,
/// position) with its material-axis stress per unit section force, the derivatives
/// `derivatives` (per variable, per point,
/// [`section::SectionAnalysis::unit_stress_derivatives`]) carried by the tangents of the
/// variables' values `b` (none: values only).
pub fn section_points<S: Scalar>(
    analysis: &section::SectionAnalysis,
    derivatives: &[Vec<[[f64; 6]; 6]>],
    b: &[S],
) -> LaminatePoints<S> {
    let unit: Vec<Vec<section::SectionPoint>> = (0..6)
        .map(|k| analysis.stresses(std::array::from_fn(|i| f64::from(i == k))))
        .collect();
    // each variable's tangent part, `b_j − value(b_j)`
    let tangents: Vec<S> = b.iter().map(|&bj| bj - S::from_f64(bj.value())).collect();
    let points = (0..unit[0].len())
        .map(|p| PlyStressPoint {
            ply: unit[0][p].region,
            place: PointPlace::Section(unit[0][p].position),
            per_deformation: SMatrix::from_fn(|r, c| {
                if c >= 6 {
                    return S::zero();
                }
                (derivatives.iter().zip(&tangents))
                    .fold(S::from_f64(unit[c][p].material_stress[r]), |x, (d, &t)| {
                        x + t * d[p][c][r]
                    })
            }),
        })
        .collect();
    LaminatePoints {
        points,
        materials: (analysis.mesh().regions.iter())
            .map(|r| r.material)
            .collect(),
    }
}

fn check_nodes<S: Scalar>(mesh: &Mesh, body: &ModalBody<S>) -> Result<(), FemError> {
    if body.modes.nrows() < NODE_DOFS * mesh.nodes.len() {
        return Err(FemError::Stresses(format!(
            "ply stresses: the modal body has {} nodes, the mesh {}",
            body.modes.nrows() / NODE_DOFS,
            mesh.nodes.len()
        )));
    }
    Ok(())
}

/// The element's local nodal dof per mode (`6·nodes × n_modes`): each node's translation and
/// rotation of each mode in the frame `r` (rows: the local axes).
fn local_dof<S: Scalar>(
    body: &ModalBody<S>,
    nodes: &[usize],
    r: &nalgebra::Matrix3<f64>,
) -> DMatrix<S> {
    let nm = body.n_modes();
    let mut u = DMatrix::<S>::zeros(6 * nodes.len(), nm);
    for (i, &n) in nodes.iter().enumerate() {
        for block in 0..2 {
            let row = NODE_DOFS * n + 3 * block;
            for j in 0..nm {
                for a in 0..3 {
                    let mut x = S::zero();
                    for c in 0..3 {
                        x += body.modes[(row + c, j)] * r[(a, c)];
                    }
                    u[(6 * i + 3 * block + a, j)] = x;
                }
            }
        }
    }
    u
}
