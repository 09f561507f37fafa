//! The mechanism part of a deck, validated: rigid bodies, joints and drivers, and force
//! elements, with the quantities they are written in (angles, rates, rotations, inertias,
//! markers, motions).

use std::collections::BTreeMap;
use std::ops::Range;

use mbs::{BodyId, Force, Joint, JointKind, Load, LoadFrame, Marker, TimeFunction, TorqueLaw};
use nalgebra::{Matrix3, Rotation3, Unit, Vector3};
use toml::Spanned;

use super::check::suggestion;
use super::check::{direction, finite, positive, required, span, vector};
use super::raw::{RawDeck, RawForce, RawMarker, RawMotion, RawRotation};
use super::{DeckError, Source};

mod actuators;
mod markers;
mod values;

use markers::motion;
pub use markers::{MarkerDef, SiteDef, marker};
pub use values::{angle, angular_rate, inertia, quantity, rotation};

/// A body of the mechanism as markers and responses see it: its id in the model, where it is
/// at the start, and its nodes.
#[derive(Debug, Clone)]
pub struct BodyInfo {
    pub id: BodyId,
    /// Initial frame origin and orientation (body → global).
    pub position: Vector3<f64>,
    pub rotation: Matrix3<f64>,
    /// Flexible bodies: node positions in the body frame.
    pub nodes: Option<Vec<Vector3<f64>>>,
    /// Natural frequencies (Hz) of the retained modes, flexible bodies.
    pub frequencies: Vec<f64>,
    /// Flexible bodies: the names of the couplings, whose nodes are the last of `nodes`.
    pub couplings: Vec<String>,
    /// Flexible bodies: the basis (eigenmodes, correction modes) and its static check (`None`
    /// for a rigid body).
    pub basis: Option<BasisReport>,
}

/// A flexible body's places for markers and responses, from its definition (no analysis): its
/// nodes (the mesh's, then one per coupling at the coupling's point; global coordinates at the
/// start) and its couplings' names.
#[derive(Debug, Clone)]
pub struct FlexibleGeometry {
    pub nodes: Vec<Vector3<f64>>,
    pub couplings: Vec<String>,
    /// The body's plies as its ply responses see them.
    pub plies: PlyMap,
}

/// A flexible body's plies as its ply responses see them: a shell body's laminates and their
/// plies, or a beam body's sections and their regions.
#[derive(Debug, Clone)]
pub struct PlyMap {
    /// A beam body's: `laminates` are its sections, their plies the sections' regions.
    pub beam: bool,
    /// Each mesh element's laminate or section (an index of `laminates`).
    pub element_laminates: Vec<usize>,
    /// Each mesh element's nodes (indices of the body's nodes).
    pub element_nodes: Vec<Vec<usize>>,
    /// Each laminate's (section's) name and, per ply (region), its material's name and
    /// strengths (`None`: the material states none). A section given by its properties has
    /// no regions.
    pub laminates: Vec<(String, Vec<PlyMaterial>)>,
}

/// A ply's material name and strengths (`None`: the material states none; a section region's
/// material that a mesh file defines has the name `""`).
pub type PlyMaterial = (String, Option<laminate::PlyStrength>);

/// A body as the validation of markers and responses sees it: a flexible body's geometry,
/// `None` for a rigid one.
#[derive(Debug, Clone)]
pub struct BodyPlace {
    pub flexible: Option<FlexibleGeometry>,
}

/// A validated joint or driver: its markers placed on the built bodies by
/// [`JointDef::resolve`].
#[derive(Debug, Clone)]
pub struct JointDef {
    pub name: String,
    pub kind: JointKind,
    pub a: MarkerDef,
    pub b: MarkerDef,
    /// The joint's table in the deck.
    pub span: Range<usize>,
}

impl JointDef {
    /// The joint on the built bodies.
    pub fn resolve(&self, bodies: &BTreeMap<String, BodyInfo>) -> Joint {
        Joint::new(
            self.name.clone(),
            self.kind.clone(),
            self.a.resolve(bodies),
            self.b.resolve(bodies),
        )
    }
}

/// A validated force element (other than gravity), its markers placed on the built bodies by
/// [`ForceDef::resolve`].
#[derive(Debug, Clone)]
pub enum ForceDef {
    /// A point force (`torque`: a point torque).
    Point {
        marker: MarkerDef,
        load: Load,
        frame: LoadFrame,
        torque: bool,
    },
    SpringDamper {
        a: MarkerDef,
        b: MarkerDef,
        stiffness: f64,
        damping: f64,
        /// `None`: the markers' distance at the start.
        free_length: Option<f64>,
    },
    /// An actuator: a torque about `a`'s axis between the bodies of `a` and `b`.
    JointTorque {
        a: MarkerDef,
        b: MarkerDef,
        law: TorqueLaw,
    },
    /// An actuator: a force along `a`'s axis between the bodies of `a` and `b`.
    JointForce {
        a: MarkerDef,
        b: MarkerDef,
        law: TorqueLaw,
    },
}

impl ForceDef {
    /// The force on the built bodies; `distance(a, b)` is the initial distance between two
    /// markers (a spring's default free length).
    pub fn resolve(
        &self,
        bodies: &BTreeMap<String, BodyInfo>,
        distance: impl Fn(&Marker, &Marker) -> f64,
    ) -> Force {
        match self {
            ForceDef::Point {
                marker,
                load,
                frame,
                torque,
            } => {
                let (marker, load, frame) = (marker.resolve(bodies), load.clone(), *frame);
                if *torque {
                    Force::PointTorque {
                        marker,
                        load,
                        frame,
                    }
                } else {
                    Force::PointForce {
                        marker,
                        load,
                        frame,
                    }
                }
            }
            ForceDef::SpringDamper {
                a,
                b,
                stiffness,
                damping,
                free_length,
            } => {
                let (a, b) = (a.resolve(bodies), b.resolve(bodies));
                let free_length = free_length.unwrap_or_else(|| distance(&a, &b));
                Force::SpringDamper {
                    a,
                    b,
                    stiffness: *stiffness,
                    damping: *damping,
                    free_length,
                }
            }
            ForceDef::JointTorque { a, b, law } => Force::JointTorque {
                a: a.resolve(bodies),
                b: b.resolve(bodies),
                law: law.clone(),
            },
            ForceDef::JointForce { a, b, law } => Force::JointForce {
                a: a.resolve(bodies),
                b: b.resolve(bodies),
                law: law.clone(),
            },
        }
    }
}

/// A flexible body's basis and how completely it takes the mechanism's loads
/// (`fem::static_completeness`).
#[derive(Debug, Clone)]
pub struct BasisReport {
    pub eigenmodes: usize,
    pub correction_modes: usize,
    pub check: Option<fem::Completeness>,
}

impl BasisReport {
    /// One line: the modes and the worst load case.
    pub fn describe(&self) -> String {
        let modes = format!(
            "{} eigenmodes + {} correction modes",
            self.eigenmodes, self.correction_modes
        );
        match self.check.as_ref().and_then(|c| c.worst()) {
            None => format!("{modes}; static check not available (free-free)"),
            Some(w) => format!(
                "{modes}; misses {:.2} % of the largest static compliance at worst ({}, of \
                 which it captures {:.1} %)",
                100.0 * w.missed,
                w.name,
                100.0 * w.captured
            ),
        }
    }
}

/// A validated rigid body.
#[derive(Debug, Clone)]
pub struct RigidDef {
    pub name: String,
    /// kg.
    pub mass: f64,
    /// About the centre of mass, body axes (kg·m²).
    pub inertia: Matrix3<f64>,
    /// Initial position of the centre of mass, orientation (body → global), velocity and
    /// angular velocity (global components, rad/s).
    pub position: Vector3<f64>,
    pub orientation: Matrix3<f64>,
    pub velocity: Vector3<f64>,
    pub angular_velocity: Vector3<f64>,
    /// `atol`: the integrator's absolute tolerance for the body's coordinates, as
    /// `analysis.atol`.
    pub atol: Option<f64>,
    /// The body's table in the deck.
    pub span: Range<usize>,
}

/// Validate the rigid bodies (their names must not clash with the flexible bodies' or
/// `ground`).
pub fn rigid_bodies(src: &Source, raw: &RawDeck) -> Result<Vec<RigidDef>, DeckError> {
    let mut out = Vec::new();
    for (name, r) in &raw.rigid {
        let k = |s: &str| format!("rigid.{name}.{s}");
        if raw.body.contains_key(name) || name == "ground" {
            return Err(src.error(
                Some(r.span()),
                Some(format!("rigid.{name}")),
                "this name is already used (bodies and rigid bodies share names; `ground` is reserved)",
            ));
        }
        let rr = r.get_ref();
        let mass = positive(
            src,
            &k("mass"),
            required(src, span(r), &k("mass"), &rr.mass, "mass (kg)")?,
            "kg",
        )?;
        let j = inertia(
            src,
            &k("inertia"),
            required(src, span(r), &k("inertia"), &rr.inertia, "inertia (kg·m²)")?,
        )?;
        let p = rr
            .position
            .as_ref()
            .map(|p| vector(src, &k("position"), p))
            .transpose()?
            .unwrap_or_else(Vector3::zeros);
        let a = rr
            .orientation
            .as_ref()
            .map(|o| rotation(src, &k("orientation"), o))
            .transpose()?
            .unwrap_or_else(Matrix3::identity);
        let v = rr
            .velocity
            .as_ref()
            .map(|v| vector(src, &k("velocity"), v))
            .transpose()?
            .unwrap_or_else(Vector3::zeros);
        let w = match &rr.angular_velocity {
            None => Vector3::zeros(),
            Some(w) => {
                let mut out = Vector3::zeros();
                for i in 0..3 {
                    let item = Spanned::new(w.span(), w.get_ref()[i].clone());
                    out[i] = angular_rate(src, &format!("{}[{i}]", k("angular_velocity")), &item)?;
                }
                out
            }
        };
        out.push(RigidDef {
            name: name.clone(),
            mass,
            inertia: j,
            position: p,
            orientation: a,
            velocity: v,
            angular_velocity: w,
            atol: rr
                .atol
                .as_ref()
                .map(|a| positive(src, &k("atol"), a, "m, or state units"))
                .transpose()?,
            span: r.span(),
        });
    }
    Ok(out)
}

/// Validate the joints and drivers (markers on the bodies of `bodies`), in deck order.
pub fn joints(
    src: &Source,
    raw: &RawDeck,
    bodies: &BTreeMap<String, BodyPlace>,
) -> Result<Vec<JointDef>, DeckError> {
    let mut out = Vec::new();
    for (name, j) in &raw.joint {
        let k = |s: &str| format!("joint.{name}.{s}");
        let rj = j.get_ref();
        let kind_v = required(src, span(j), &k("kind"), &rj.kind, "kind")?;
        let driver = matches!(
            kind_v.get_ref().as_str(),
            "angle-driver" | "distance-driver"
        );
        if !driver && let Some(m) = &rj.motion {
            return Err(src.error(span(m), Some(k("motion")), "motion is only used by drivers"));
        }
        let kind = match kind_v.get_ref().as_str() {
            "spherical" => JointKind::Spherical,
            "revolute" => JointKind::Revolute,
            "universal" => JointKind::Universal,
            "cylindrical" => JointKind::Cylindrical,
            "translational" => JointKind::Translational,
            "fixed" => JointKind::Fixed,
            "angle-driver" => JointKind::AngleDriver(motion(
                src,
                &k("motion"),
                required(src, span(j), &k("motion"), &rj.motion, "motion")?,
                true,
            )?),
            "distance-driver" => JointKind::DistanceDriver(motion(
                src,
                &k("motion"),
                required(src, span(j), &k("motion"), &rj.motion, "motion")?,
                false,
            )?),
            other => {
                return Err(src.error(
                    span(kind_v),
                    Some(k("kind")),
                    super::keys::JOINT_KIND.unknown("joint kind", other),
                ));
            }
        };
        let a = marker(
            src,
            &k("a"),
            required(
                src,
                span(j),
                &k("a"),
                &rj.a,
                "a (a marker: { body, point | node, axis })",
            )?,
            bodies,
        )?;
        let b = marker(
            src,
            &k("b"),
            required(
                src,
                span(j),
                &k("b"),
                &rj.b,
                "b (a marker: { body, point | node, axis })",
            )?,
            bodies,
        )?;
        out.push(JointDef {
            name: name.clone(),
            kind,
            a,
            b,
            span: j.span(),
        });
    }
    Ok(out)
}

/// The validated force elements.
#[derive(Debug, Clone)]
pub struct ForceDefs {
    /// The sum of the `gravity` elements (m/s²).
    pub gravity: Vector3<f64>,
    /// The other forces by name, in deck order, with their tables in the deck.
    pub forces: Vec<(String, ForceDef, Range<usize>)>,
}

/// Validate the force elements.
pub fn forces(
    src: &Source,
    raw: &RawDeck,
    bodies: &BTreeMap<String, BodyPlace>,
) -> Result<ForceDefs, DeckError> {
    let mut gravity = Vector3::zeros();
    let mut out = Vec::new();
    for (name, f) in &raw.force {
        let k = |s: &str| format!("force.{name}.{s}");
        let rf = f.get_ref();
        let kind = required(
            src,
            span(f),
            &k("kind"),
            &rf.kind,
            "kind (\"gravity\", \"point-force\", \"point-torque\", \"spring-damper\" or \
             \"joint-torque\")",
        )?;
        let force = match kind.get_ref().as_str() {
            "gravity" => {
                gravity += vector(
                    src,
                    &k("acceleration"),
                    required(
                        src,
                        span(f),
                        &k("acceleration"),
                        &rf.acceleration,
                        "acceleration [x, y, z] (m/s²)",
                    )?,
                )?;
                continue;
            }
            "point-force" | "point-torque" => {
                point_load(src, name, f, bodies, kind.get_ref() == "point-force")?
            }
            "spring-damper" => spring_damper(src, name, f, bodies)?,
            "joint-torque" => actuators::joint_actuator(src, name, f, bodies, false)?,
            "joint-force" => actuators::joint_actuator(src, name, f, bodies, true)?,
            other => {
                return Err(src.error(
                    span(kind),
                    Some(k("kind")),
                    super::keys::FORCE_KIND.unknown("force kind", other),
                ));
            }
        };
        out.push((name.clone(), force, f.span()));
    }
    Ok(ForceDefs {
        gravity,
        forces: out,
    })
}

/// A `point-force` (`force`) or `point-torque` element: its marker, load (constant or a table
/// of times) and the frame the load is given in.
fn point_load(
    src: &Source,
    name: &str,
    f: &Spanned<RawForce>,
    bodies: &BTreeMap<String, BodyPlace>,
    force: bool,
) -> Result<ForceDef, DeckError> {
    let k = |s: &str| format!("force.{name}.{s}");
    let rf = f.get_ref();
    let at = marker(
        src,
        &k("at"),
        required(src, span(f), &k("at"), &rf.at, "at (a marker)")?,
        bodies,
    )?;
    let load = match (&rf.value, &rf.table) {
        (Some(v), None) => Load::Constant(vector(src, &k("value"), v)?),
        (None, Some(t)) => {
            let times = required(
                src,
                span(t),
                &k("table.times"),
                &t.get_ref().times,
                "times [s]",
            )?;
            let values = required(
                src,
                span(t),
                &k("table.values"),
                &t.get_ref().values,
                "values [[x, y, z], …]",
            )?;
            let ts = times.get_ref().clone();
            if ts.is_empty()
                || ts.windows(2).any(|w| w[1] <= w[0])
                || ts.iter().any(|x| !x.is_finite())
            {
                return Err(src.error(
                    span(times),
                    Some(k("table.times")),
                    "times must be finite and strictly increasing",
                ));
            }
            if values.get_ref().len() != ts.len() {
                return Err(src.error(
                    span(values),
                    Some(k("table.values")),
                    format!("{} values for {} times", values.get_ref().len(), ts.len()),
                ));
            }
            Load::Table {
                times: ts,
                values: values.get_ref().iter().map(|v| Vector3::from(*v)).collect(),
            }
        }
        (Some(_), Some(t)) => {
            return Err(src.error(span(t), Some(k("table")), "give either value or table"));
        }
        (None, None) => {
            return Err(src.error(
                span(f),
                Some(k("value")),
                "missing value: value [x, y, z] or table",
            ));
        }
    };
    let frame = match rf.frame.as_ref().map(|x| (x, x.get_ref().as_str())) {
        None | Some((_, "global")) => LoadFrame::Global,
        Some((_, "body")) => LoadFrame::Body,
        Some((x, other)) => {
            return Err(src.error(
                span(x),
                Some(k("frame")),
                super::keys::FORCE_FRAME.unknown("frame", other),
            ));
        }
    };
    Ok(ForceDef::Point {
        marker: at,
        load,
        frame,
        torque: !force,
    })
}

/// A `spring-damper` element between two markers (its free length, when not given, the
/// markers' distance at the start: [`ForceDef::resolve`]).
fn spring_damper(
    src: &Source,
    name: &str,
    f: &Spanned<RawForce>,
    bodies: &BTreeMap<String, BodyPlace>,
) -> Result<ForceDef, DeckError> {
    let k = |s: &str| format!("force.{name}.{s}");
    let rf = f.get_ref();
    let (a, b) = two_markers(src, name, f, bodies)?;
    let stiffness = rf
        .stiffness
        .as_ref()
        .map(|s| finite(src, &k("stiffness"), s, "N/m"))
        .transpose()?
        .unwrap_or(0.0);
    let damping = rf
        .damping
        .as_ref()
        .map(|s| finite(src, &k("damping"), s, "N·s/m"))
        .transpose()?
        .unwrap_or(0.0);
    let free_length = rf
        .free_length
        .as_ref()
        .map(|l| finite(src, &k("free_length"), l, "m"))
        .transpose()?;
    Ok(ForceDef::SpringDamper {
        a,
        b,
        stiffness,
        damping,
        free_length,
    })
}

/// The markers `a` and `b` of a force element between two bodies (a spring–damper, an
/// actuator).
fn two_markers(
    src: &Source,
    name: &str,
    f: &Spanned<RawForce>,
    bodies: &BTreeMap<String, BodyPlace>,
) -> Result<(MarkerDef, MarkerDef), DeckError> {
    let k = |s: &str| format!("force.{name}.{s}");
    let rf = f.get_ref();
    let a = marker(
        src,
        &k("a"),
        required(src, span(f), &k("a"), &rf.a, "a (a marker)")?,
        bodies,
    )?;
    let b = marker(
        src,
        &k("b"),
        required(src, span(f), &k("b"), &rf.b, "b (a marker)")?,
        bodies,
    )?;
    Ok((a, b))
}
