//! `[response.*]`: the quantities recorded at every output time, as `mbs::Response`s.

use std::collections::BTreeMap;
use std::ops::Range;

use mbs::{JointId, Model, Response};
use nalgebra::Vector3;
use toml::Spanned;

use super::check::{direction, required, span};
use super::laminates::suggestion;
use super::mechanism::BodyInfo;
use super::raw::{RawDeck, RawResponse};
use super::{DeckError, Source};

/// A validated response.
#[derive(Debug, Clone)]
pub struct ResponseDef {
    pub name: String,
    pub response: Response,
    /// Unit of its values (`"1"` for dimensionless).
    pub unit: &'static str,
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

/// Validate the responses: each as an `mbs::Response` of `model` with its name and unit.
pub fn validate(
    src: &Source,
    raw: &RawDeck,
    model: &Model<f64>,
    bodies: &BTreeMap<String, BodyInfo>,
    joints: &[(String, JointId)],
) -> Result<Vec<ResponseDef>, DeckError> {
    let mut out = Vec::new();
    for (name, r) in &raw.response {
        let t = Table {
            src,
            name,
            raw: r.get_ref(),
            span: span(r),
            model,
            bodies,
        };
        let kind = required(src, t.span.clone(), &t.key("kind"), &t.raw.kind, "kind")?;
        let (response, unit) = match kind.get_ref().as_str() {
            "position" => t.position()?,
            "velocity" => t.velocity()?,
            "nodal-displacement" => t.nodal_displacement()?,
            "mid-node-deflection" => t.mid_node_deflection()?,
            "reaction" => t.reaction(joints)?,
            "modal" => t.modal()?,
            "energy" => (Response::Energy, "J"),
            "constraint-violation" => (Response::ConstraintViolation, "m"),
            other => {
                return Err(src.error(
                    span(kind),
                    Some(t.key("kind")),
                    super::keys::RESPONSE_KIND.unknown("response", other),
                ));
            }
        };
        out.push(ResponseDef {
            name: name.clone(),
            response,
            unit,
        });
    }
    Ok(out)
}

/// One `[response.NAME]` table being validated, with what its kinds refer to.
struct Table<'a> {
    src: &'a Source,
    name: &'a str,
    raw: &'a RawResponse,
    span: Option<Range<usize>>,
    model: &'a Model<f64>,
    bodies: &'a BTreeMap<String, BodyInfo>,
}

impl Table<'_> {
    fn key(&self, s: &str) -> String {
        format!("response.{}.{s}", self.name)
    }

    /// The body the response names (`flexible`: it must be a flexible one).
    fn body(&self, flexible: bool) -> Result<&BodyInfo, DeckError> {
        let (src, k) = (self.src, |s: &str| self.key(s));
        let b = required(src, self.span.clone(), &k("body"), &self.raw.body, "body")?;
        let (n, info) = self.bodies.get_key_value(b.get_ref()).ok_or_else(|| {
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
        if flexible && info.nodes.is_none() {
            return Err(src.error(
                span(b),
                Some(k("body")),
                format!("`{n}` is a rigid body; this response needs a flexible one"),
            ));
        }
        Ok(info)
    }

    /// A node index of the flexible body `info` (`key`: where the deck gives it).
    fn node_index(&self, info: &BodyInfo, v: &Spanned<i64>, key: &str) -> Result<usize, DeckError> {
        let n = info.nodes.as_ref().map_or(0, Vec::len);
        let x = *v.get_ref();
        if x < 0 || x as usize >= n {
            return Err(self.src.error(
                span(v),
                Some(self.key(key)),
                format!(
                    "node {x} does not exist (nodes 0 to {})",
                    n.saturating_sub(1)
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

    /// `kind = "position"`: a component of a body frame's origin.
    fn position(&self) -> Result<(Response, &'static str), DeckError> {
        let info = self.body(false)?;
        let axis = self.component(&XYZ)?;
        Ok((
            Response::BodyPosition {
                body: info.id,
                axis,
            },
            "m",
        ))
    }

    /// `kind = "velocity"`: a component of a body frame origin's velocity.
    fn velocity(&self) -> Result<(Response, &'static str), DeckError> {
        let info = self.body(false)?;
        let c = self.component(&XYZ)?;
        let model = self.model;
        Ok((
            Response::State(model.n_q() + model.v_range(info.id).start + c),
            "m/s",
        ))
    }

    /// `kind = "nodal-displacement"`: a nodal dof's elastic displacement or rotation.
    fn nodal_displacement(&self) -> Result<(Response, &'static str), DeckError> {
        let info = self.body(true)?;
        let raw_node = required(
            self.src,
            self.span.clone(),
            &self.key("node"),
            &self.raw.node,
            "node",
        )?;
        let node = self.node_index(info, raw_node, "node")?;
        let c = self.component(&NODE_DOF)?;
        Ok((
            Response::NodalDisplacement {
                body: info.id,
                node,
                dof: c,
            },
            if c < 3 { "m" } else { "rad" },
        ))
    }

    /// `kind = "mid-node-deflection"`: the paper's deflection of a middle node from the chord
    /// of two others, relative to the chord's length.
    fn mid_node_deflection(&self) -> Result<(Response, &'static str), DeckError> {
        let info = self.body(true)?;
        // the mesh's nodes (couplings' nodes follow them)
        let count = info.nodes.as_ref().map_or(0, Vec::len) - info.couplings.len();
        let nodes = match &self.raw.nodes {
            Some(v) => {
                let mut out = [0; 3];
                for i in 0..3 {
                    out[i] =
                        self.node_index(info, &Spanned::new(v.span(), v.get_ref()[i]), "nodes")?;
                }
                out
            }
            None => [0, (count - 1) / 2, count - 1],
        };
        let x = info.nodes.as_ref().expect("flexible");
        let length = (x[nodes[2]] - x[nodes[0]]).norm();
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
            Response::MidNodeDeflection {
                body: info.id,
                first: nodes[0],
                mid: nodes[1],
                last: nodes[2],
                normal,
            },
            "1",
        ))
    }

    /// `kind = "reaction"`: a component of a joint's reaction force or moment.
    fn reaction(
        &self,
        joints: &[(String, JointId)],
    ) -> Result<(Response, &'static str), DeckError> {
        let (src, k) = (self.src, |s: &str| self.key(s));
        let j = required(
            src,
            self.span.clone(),
            &k("joint"),
            &self.raw.joint,
            "joint",
        )?;
        let joint = joints
            .iter()
            .find(|(x, _)| x == j.get_ref())
            .map(|(_, id)| *id)
            .ok_or_else(|| {
                let known: Vec<&str> = joints.iter().map(|(n, _)| n.as_str()).collect();
                src.error(
                    span(j),
                    Some(k("joint")),
                    format!(
                        "undefined joint `{}`{}",
                        j.get_ref(),
                        suggestion(j.get_ref(), &known)
                    ),
                )
            })?;
        let c = self.component(&REACTION)?;
        Ok((
            if c < 3 {
                Response::ReactionForce { joint, axis: c }
            } else {
                Response::ReactionMoment { joint, axis: c - 3 }
            },
            if c < 3 { "N" } else { "N*m" },
        ))
    }

    /// `kind = "modal"`: a retained mode's coordinate.
    fn modal(&self) -> Result<(Response, &'static str), DeckError> {
        let info = self.body(true)?;
        let m = required(
            self.src,
            self.span.clone(),
            &self.key("mode"),
            &self.raw.mode,
            "mode (from 1)",
        )?;
        let nm = self.model.body(info.id).n_modes();
        let mode = *m.get_ref();
        if mode < 1 || mode as usize > nm {
            return Err(self.src.error(
                span(m),
                Some(self.key("mode")),
                format!("mode {mode}: the body keeps modes 1 to {nm}"),
            ));
        }
        Ok((
            Response::State(self.model.q_range(info.id).start + 7 + mode as usize - 1),
            "1",
        ))
    }
}
