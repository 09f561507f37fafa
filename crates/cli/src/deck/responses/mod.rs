//! `[response.*]`: the quantities recorded at every output time, as `mbs::Response`s.

use std::collections::BTreeMap;
use std::ops::Range;

use laminate::{Criterion, PlyPosition};
use mbs::{ForceId, JointId, Model, Response};
use nalgebra::Vector3;
use toml::Spanned;

use super::check::suggestion;
use super::check::{direction, required, span};
use super::mechanism::{BodyInfo, BodyPlace, MarkerDef};
use super::raw::{RawDeck, RawResponse};
use super::{DeckError, Source};

mod ply;

/// A response of the built mechanism.
#[derive(Debug, Clone)]
pub struct ResponseDef {
    pub name: String,
    pub response: Response,
    /// Unit of its values (`"1"` for dimensionless).
    pub unit: &'static str,
}

/// A validated response in the deck's terms (bodies and joints by name), made an
/// `mbs::Response` of the built mechanism by [`ResponseSpec::resolve`] (the state indices of
/// velocities and modal coordinates follow the bodies' numbers of modes).
#[derive(Debug, Clone)]
pub struct ResponseSpec {
    pub name: String,
    /// Unit of its values (`"1"` for dimensionless).
    pub unit: &'static str,
    kind: SpecKind,
}

#[derive(Debug, Clone)]
enum SpecKind {
    Position {
        body: String,
        axis: usize,
    },
    Velocity {
        body: String,
        axis: usize,
    },
    NodalDisplacement {
        body: String,
        node: usize,
        dof: usize,
    },
    MidNodeDeflection {
        body: String,
        nodes: [usize; 3],
        normal: Vector3<f64>,
    },
    /// Component `c` of `[fx, fy, fz, mx, my, mz]`.
    Reaction {
        joint: String,
        c: usize,
    },
    /// Modal coordinate `mode` (from 1, as the deck gives it), checked against the body's
    /// modes when resolved.
    Modal {
        body: String,
        mode: i64,
        key: String,
        span: Option<Range<usize>>,
    },
    Energy,
    ConstraintViolation,
    /// An actuator's torque or force, or (`power`) its power.
    Actuator {
        force: String,
        power: bool,
    },
    /// Component `axis` of a marker point's position (`order` 0), velocity (1) or
    /// acceleration (2), global, less that of `relative_to`'s.
    Point {
        at: MarkerDef,
        relative_to: Option<MarkerDef>,
        order: usize,
        axis: usize,
    },
    /// Component `component` of the stress (with `strain`, the strain) of `ply` (a beam
    /// section's region) at `place` of element `element`.
    PlyStress {
        body: String,
        element: usize,
        ply: usize,
        place: fem::PointPlace,
        component: usize,
        strain: bool,
    },
    /// A failure index over the ply points selected (`None`: every one).
    PlyFailure {
        body: String,
        elements: Option<Vec<usize>>,
        ply: Option<usize>,
        position: Option<PlyPosition>,
        criterion: Criterion,
        rho: Option<f64>,
    },
}

impl ResponseSpec {
    /// The body whose ply stresses the response reads, and when the response takes strains
    /// through the plies' nominal compliance, `[what does, its key, what to use instead]`.
    pub fn ply_body(&self) -> Option<(&str, Option<[&'static str; 3]>)> {
        match &self.kind {
            SpecKind::PlyStress { body, strain, .. } => Some((
                body,
                strain.then_some(["a ply strain", "component", "constrain a stress component"]),
            )),
            SpecKind::PlyFailure {
                body, criterion, ..
            } => Some((
                body,
                (*criterion == Criterion::MaxStrain).then_some([
                    "the max-strain index",
                    "criterion",
                    "use another criterion (max-stress, tsai-wu, …)",
                ]),
            )),
            _ => None,
        }
    }

    /// The response of the built `model` (`bodies` and `joints`: its bodies and joints by
    /// name); a modal coordinate beyond the body's modes is an error at its key.
    pub fn resolve(
        &self,
        src: &Source,
        model: &Model<f64>,
        bodies: &BTreeMap<String, BodyInfo>,
        joints: &[(String, JointId)],
        actuators: &[(String, ForceId)],
    ) -> Result<ResponseDef, DeckError> {
        let id = |b: &String| bodies[b].id;
        let response = match &self.kind {
            SpecKind::Position { body, axis } => Response::BodyPosition {
                body: id(body),
                axis: *axis,
            },
            SpecKind::Velocity { body, axis } => {
                Response::State(model.n_q() + model.v_range(id(body)).start + axis)
            }
            SpecKind::NodalDisplacement { body, node, dof } => Response::NodalDisplacement {
                body: id(body),
                node: *node,
                dof: *dof,
            },
            SpecKind::MidNodeDeflection {
                body,
                nodes,
                normal,
            } => Response::MidNodeDeflection {
                body: id(body),
                first: nodes[0],
                mid: nodes[1],
                last: nodes[2],
                normal: *normal,
            },
            SpecKind::Reaction { joint, c } => {
                let joint = joints
                    .iter()
                    .find(|(n, _)| n == joint)
                    .map(|(_, j)| *j)
                    .expect("validated joint name");
                if *c < 3 {
                    Response::ReactionForce { joint, axis: *c }
                } else {
                    Response::ReactionMoment { joint, axis: c - 3 }
                }
            }
            SpecKind::Modal {
                body,
                mode,
                key,
                span,
            } => {
                let nm = model.body(id(body)).n_modes();
                if *mode < 1 || *mode as usize > nm {
                    return Err(src.error(
                        span.clone(),
                        Some(key.clone()),
                        format!("mode {mode}: the body keeps modes 1 to {nm}"),
                    ));
                }
                Response::State(model.q_range(id(body)).start + 7 + *mode as usize - 1)
            }
            SpecKind::Point {
                at,
                relative_to,
                order,
                axis,
            } => Response::MarkerPoint {
                marker: at.resolve(bodies),
                relative_to: relative_to.as_ref().map(|m| m.resolve(bodies)),
                order: *order,
                axis: *axis,
            },
            SpecKind::PlyStress {
                body,
                element,
                ply,
                place,
                component,
                strain,
            } => Response::PlyStress {
                body: id(body),
                element: *element,
                ply: *ply,
                place: *place,
                component: *component,
                strain: *strain,
            },
            SpecKind::PlyFailure {
                body,
                elements,
                ply,
                position,
                criterion,
                rho,
            } => Response::PlyFailure {
                body: id(body),
                elements: elements.clone(),
                ply: *ply,
                position: *position,
                criterion: *criterion,
                rho: *rho,
            },
            SpecKind::Energy => Response::Energy,
            SpecKind::ConstraintViolation => Response::ConstraintViolation,
            SpecKind::Actuator { force, power } => {
                let force = actuators
                    .iter()
                    .find(|(n, _)| n == force)
                    .map(|(_, f)| *f)
                    .expect("validated actuator name");
                if *power {
                    Response::ActuatorPower { force }
                } else {
                    Response::ActuatorTorque { force }
                }
            }
        };
        Ok(ResponseDef {
            name: self.name.clone(),
            response,
            unit: self.unit,
        })
    }
}

const XYZ: [&str; 3] = ["x", "y", "z"];
const NODE_DOF: [&str; 6] = ["ux", "uy", "uz", "rx", "ry", "rz"];
const REACTION: [&str; 6] = ["fx", "fy", "fz", "mx", "my", "mz"];

fn component(
    src: &Source,
    key: &str,
    c: Option<&Spanned<String>>,
    table: Option<Range<usize>>,
    names: &[&str],
) -> Result<usize, DeckError> {
    let c = c.ok_or_else(|| {
        src.error(
            table,
            Some(key.into()),
            format!("missing value: component ({})", names.join(", ")),
        )
    })?;
    names.iter().position(|n| *n == c.get_ref()).ok_or_else(|| {
        src.error(
            span(c),
            Some(key.into()),
            format!(
                "unknown component `{}`: expected one of {}{}",
                c.get_ref(),
                names.join(", "),
                suggestion(c.get_ref(), names)
            ),
        )
    })
}

/// Validate the responses: each with its name and unit, in the deck's terms
/// ([`ResponseSpec::resolve`] makes them responses of the built mechanism). `joints`: the
/// joints' names; `actuators`: the names of the forces of kind `"joint-torque"` (`false`) or
/// `"joint-force"` (`true`).
pub fn validate(
    src: &Source,
    raw: &RawDeck,
    bodies: &BTreeMap<String, BodyPlace>,
    joints: &[String],
    actuators: &[(String, bool)],
) -> Result<Vec<ResponseSpec>, DeckError> {
    let mut out = Vec::new();
    for (name, r) in &raw.response {
        let t = Table {
            src,
            name,
            raw: r.get_ref(),
            span: span(r),
            bodies,
        };
        let kind = required(src, t.span.clone(), &t.key("kind"), &t.raw.kind, "kind")?;
        let (kind, unit) = match kind.get_ref().as_str() {
            "position" => t.position()?,
            "velocity" => t.velocity()?,
            "nodal-displacement" => t.nodal_displacement()?,
            "mid-node-deflection" => t.mid_node_deflection()?,
            "reaction" => t.reaction(joints)?,
            "modal" => t.modal()?,
            "energy" => (SpecKind::Energy, "J"),
            "constraint-violation" => (SpecKind::ConstraintViolation, "m"),
            "actuator-torque" => (t.actuator(actuators, Some(false), false)?, "N·m"),
            "actuator-force" => (t.actuator(actuators, Some(true), false)?, "N"),
            "actuator-power" => (t.actuator(actuators, None, true)?, "W"),
            "point-position" => (t.point(0)?, "m"),
            "point-velocity" => (t.point(1)?, "m/s"),
            "point-acceleration" => (t.point(2)?, "m/s²"),
            "ply-stress" => t.ply_stress()?,
            "ply-failure" => (t.ply_failure()?, "1"),
            other => {
                return Err(src.error(
                    span(kind),
                    Some(t.key("kind")),
                    super::keys::RESPONSE_KIND.unknown("response", other),
                ));
            }
        };
        out.push(ResponseSpec {
            name: name.clone(),
            unit,
            kind,
        });
    }
    Ok(out)
}

/// One `[response.NAME]` table being validated, with the bodies it can name.
struct Table<'a> {
    src: &'a Source,
    name: &'a str,
    raw: &'a RawResponse,
    span: Option<Range<usize>>,
    bodies: &'a BTreeMap<String, BodyPlace>,
}

impl Table<'_> {
    fn key(&self, s: &str) -> String {
        format!("response.{}.{s}", self.name)
    }

    /// The body the response names (`flexible`: it must be a flexible one): its name and
    /// geometry (`None` for a rigid body).
    fn body(
        &self,
        flexible: bool,
    ) -> Result<(String, Option<&super::mechanism::FlexibleGeometry>), DeckError> {
        let (src, k) = (self.src, |s: &str| self.key(s));
        let b = required(src, self.span.clone(), &k("body"), &self.raw.body, "body")?;
        let (n, place) = self.bodies.get_key_value(b.get_ref()).ok_or_else(|| {
            let known: Vec<&str> = self.bodies.keys().map(String::as_str).collect();
            src.error(
                span(b),
                Some(k("body")),
                format!(
                    "undefined body `{}`{}",
                    b.get_ref(),
                    suggestion(b.get_ref(), &known)
                ),
            )
        })?;
        if flexible && place.flexible.is_none() {
            return Err(src.error(
                span(b),
                Some(k("body")),
                format!("`{n}` is a rigid body; this response needs a flexible one"),
            ));
        }
        Ok((n.clone(), place.flexible.as_ref()))
    }

    /// A node index of a flexible body of `count` nodes (`key`: where the deck gives it).
    fn node_index(&self, count: usize, v: &Spanned<i64>, key: &str) -> Result<usize, DeckError> {
        let x = *v.get_ref();
        if x < 0 || x as usize >= count {
            return Err(self.src.error(
                span(v),
                Some(self.key(key)),
                format!(
                    "node {x} does not exist (nodes 0 to {})",
                    count.saturating_sub(1)
                ),
            ));
        }
        Ok(x as usize)
    }

    /// The response's `component` among `names`.
    fn component(&self, names: &[&str]) -> Result<usize, DeckError> {
        component(
            self.src,
            &self.key("component"),
            self.raw.component.as_ref(),
            self.span.clone(),
            names,
        )
    }

    /// `kind = "point-position"` (`order` 0), `"point-velocity"` (1) or
    /// `"point-acceleration"` (2): a component of a marker point's kinematics.
    fn point(&self, order: usize) -> Result<SpecKind, DeckError> {
        let (src, k) = (self.src, |s: &str| self.key(s));
        let at = required(
            src,
            self.span.clone(),
            &k("at"),
            &self.raw.at,
            "at (a marker: { body, point | node | coupling })",
        )?;
        let at = super::mechanism::marker(src, &k("at"), at, self.bodies)?;
        let relative_to = (self.raw.relative_to.as_ref())
            .map(|m| super::mechanism::marker(src, &k("relative_to"), m, self.bodies))
            .transpose()?;
        let axis = self.component(&XYZ)?;
        Ok(SpecKind::Point {
            at,
            relative_to,
            order,
            axis,
        })
    }

    /// `kind = "position"`: a component of a body frame's origin.
    fn position(&self) -> Result<(SpecKind, &'static str), DeckError> {
        let (body, _) = self.body(false)?;
        let axis = self.component(&XYZ)?;
        Ok((SpecKind::Position { body, axis }, "m"))
    }

    /// `kind = "velocity"`: a component of a body frame origin's velocity.
    fn velocity(&self) -> Result<(SpecKind, &'static str), DeckError> {
        let (body, _) = self.body(false)?;
        let axis = self.component(&XYZ)?;
        Ok((SpecKind::Velocity { body, axis }, "m/s"))
    }

    /// `kind = "nodal-displacement"`: a nodal dof's elastic displacement or rotation.
    fn nodal_displacement(&self) -> Result<(SpecKind, &'static str), DeckError> {
        let (body, geometry) = self.body(true)?;
        let raw_node = required(
            self.src,
            self.span.clone(),
            &self.key("node"),
            &self.raw.node,
            "node",
        )?;
        let count = geometry.map_or(0, |g| g.nodes.len());
        let node = self.node_index(count, raw_node, "node")?;
        let dof = self.component(&NODE_DOF)?;
        Ok((
            SpecKind::NodalDisplacement { body, node, dof },
            if dof < 3 { "m" } else { "rad" },
        ))
    }

    /// `kind = "mid-node-deflection"`: the paper's deflection of a middle node from the chord
    /// of two others, relative to the chord's length.
    fn mid_node_deflection(&self) -> Result<(SpecKind, &'static str), DeckError> {
        let (body, geometry) = self.body(true)?;
        let g = geometry.expect("flexible");
        // the mesh's nodes (couplings' nodes follow them)
        let count = g.nodes.len() - g.couplings.len();
        let nodes = match &self.raw.nodes {
            Some(v) => {
                let mut out = [0; 3];
                for i in 0..3 {
                    out[i] = self.node_index(
                        g.nodes.len(),
                        &Spanned::new(v.span(), v.get_ref()[i]),
                        "nodes",
                    )?;
                }
                out
            }
            None => [0, (count - 1) / 2, count - 1],
        };
        let length = (g.nodes[nodes[2]] - g.nodes[nodes[0]]).norm();
        if length == 0.0 {
            return Err(self.src.error(
                self.span.clone(),
                Some(self.key("nodes")),
                "the first and last nodes coincide",
            ));
        }
        let normal = self
            .raw
            .normal
            .as_ref()
            .map(|v| direction(self.src, &self.key("normal"), v))
            .transpose()?
            .unwrap_or(Vector3::z());
        Ok((
            SpecKind::MidNodeDeflection {
                body,
                nodes,
                normal,
            },
            "1",
        ))
    }

    /// `kind = "actuator-torque"` (`linear` false), `"actuator-force"` (true) or (`power`)
    /// `"actuator-power"` (either): of the actuator `force`.
    fn actuator(
        &self,
        actuators: &[(String, bool)],
        linear: Option<bool>,
        power: bool,
    ) -> Result<SpecKind, DeckError> {
        let names: Vec<String> = (actuators.iter())
            .filter(|(_, l)| linear.is_none_or(|want| *l == want))
            .map(|(n, _)| n.clone())
            .collect();
        let kinds = match linear {
            Some(false) => "\"joint-torque\"",
            Some(true) => "\"joint-force\"",
            None => "\"joint-torque\" or \"joint-force\"",
        };
        let force = self.one_of(
            "force",
            &self.raw.force,
            "force (an actuator's [force.NAME])",
            &names,
            |f| format!("`{f}` is not an actuator of its kind (a [force.NAME] of kind {kinds})"),
        )?;
        Ok(SpecKind::Actuator { force, power })
    }

    /// The name at key `name` (`raw`, described by `what` when missing), one of `names`; an
    /// error by `unknown` otherwise, with the nearest name suggested.
    fn one_of(
        &self,
        name: &str,
        raw: &Option<Spanned<String>>,
        what: &str,
        names: &[String],
        unknown: impl Fn(&str) -> String,
    ) -> Result<String, DeckError> {
        let key = self.key(name);
        let v = required(self.src, self.span.clone(), &key, raw, what)?;
        if !names.contains(v.get_ref()) {
            let known: Vec<&str> = names.iter().map(String::as_str).collect();
            return Err(self.src.error(
                span(v),
                Some(key),
                format!(
                    "{}{}",
                    unknown(v.get_ref()),
                    suggestion(v.get_ref(), &known)
                ),
            ));
        }
        Ok(v.get_ref().clone())
    }

    /// `kind = "reaction"`: a component of a joint's reaction force or moment.
    fn reaction(&self, joints: &[String]) -> Result<(SpecKind, &'static str), DeckError> {
        let joint = self.one_of("joint", &self.raw.joint, "joint", joints, |j| {
            format!("undefined joint `{j}`")
        })?;
        let c = self.component(&REACTION)?;
        Ok((
            SpecKind::Reaction { joint, c },
            if c < 3 { "N" } else { "N*m" },
        ))
    }

    /// `kind = "modal"`: a retained mode's coordinate (checked against the body's modes when
    /// the mechanism is built).
    fn modal(&self) -> Result<(SpecKind, &'static str), DeckError> {
        let (body, _) = self.body(true)?;
        let m = required(
            self.src,
            self.span.clone(),
            &self.key("mode"),
            &self.raw.mode,
            "mode (from 1)",
        )?;
        Ok((
            SpecKind::Modal {
                body,
                mode: *m.get_ref(),
                key: self.key("mode"),
                span: span(m),
            },
            "1",
        ))
    }
}
