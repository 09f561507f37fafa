//! What a design variable moves.

use super::MaterialLaw;
use crate::deck::sections::SectionEntry;

/// What a design variable moves.
#[derive(Debug, Clone, PartialEq)]
pub enum Target {
    /// Ply angles of a laminate: `(ply index in the stack, dθ/db)`, θ in radians and b in
    /// degrees (mirrored plies of a symmetric laminate included). Every section built from the
    /// laminate (tube, box, mesh regions given as its plies) and every shell body laminated
    /// with it follows.
    PlyAngle {
        laminate: String,
        stack_plies: Vec<(usize, f64)>,
        /// `(ply index in the deck, θ_i0 in degrees, f_i)`: the plies as written.
        deck_plies: Vec<(usize, f64, f64)>,
    },
    /// Ply thicknesses of a laminate: `(ply index in the stack, dt/db)` (m per m; mirrored
    /// plies of a symmetric laminate included). Shells laminated with it follow, and so do
    /// the nodes of generated beam sections (tubes, boxes, channels, I beams) made of it; a
    /// mesh-file section made of it is refused (its geometry is fixed).
    PlyThickness {
        laminate: String,
        stack_plies: Vec<(usize, f64)>,
        /// `(ply index in the deck, t_i0 in m, f_i)`.
        deck_plies: Vec<(usize, f64, f64)>,
    },
    /// An elastic constant or the density of a material: `law` says how its nine elastic
    /// constants (`OrthotropicMaterial::constants` order) and its density move with the
    /// variable ([`material_constants`](super::material_constants)). Every ply and section region of the material
    /// follows. `constant` is the deck's name of the constant (`"E1"`, `"nu12"`, `"E"`,
    /// `"nu"`, `"density"`).
    Material {
        material: String,
        constant: &'static str,
        law: MaterialLaw,
    },
    /// The mass of a rigid body (kg).
    RigidMass { body: String },
    /// A principal moment of inertia of a rigid body (`axis` 0, 1, 2: the diagonal entry of
    /// its inertia tensor in body axes, kg·m²); `key` is the entry's `--set` path.
    RigidInertia {
        body: String,
        axis: usize,
        key: String,
    },
    /// An entry of a section given by its properties (`shape = "properties"`): `EA` … `EI3`,
    /// the mass per length or a mass inertia. Every beam body of the section follows.
    SectionProperty {
        section: String,
        entry: SectionEntry,
    },
    /// The fibre angle of a solid section's material (`shape = "rectangle"` or `"circle"`),
    /// in degrees. Every beam body of the section follows.
    SectionAngle { section: String },
    /// A gain of an actuator's PD law: `gain` 0 for `kp`, 1 for `kd`.
    ActuatorGain { force: String, gain: usize },
}

impl Target {
    /// The actuator and gain (0: `kp`, 1: `kd`) this target sets; `None` for the others.
    pub fn gain(&self) -> Option<(&str, usize)> {
        match self {
            Target::ActuatorGain { force, gain } => Some((force, *gain)),
            _ => None,
        }
    }

    /// The rigid body's entry this target sets: the body, and `None` for its mass or the
    /// axis of a principal inertia; `None` for a laminate or material target.
    pub fn rigid(&self) -> Option<(&str, Option<usize>)> {
        match self {
            Target::RigidMass { body } => Some((body, None)),
            Target::RigidInertia { body, axis, .. } => Some((body, Some(*axis))),
            Target::PlyAngle { .. }
            | Target::PlyThickness { .. }
            | Target::Material { .. }
            | Target::SectionProperty { .. }
            | Target::SectionAngle { .. }
            | Target::ActuatorGain { .. } => None,
        }
    }
}
