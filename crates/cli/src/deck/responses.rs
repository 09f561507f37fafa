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
        let k = |s: &str| format!("response.{name}.{s}");
        let rr: &RawResponse = r.get_ref();
        let kind = required(src, span(r), &k("kind"), &rr.kind, "kind")?;
        let body = |flexible: bool| -> Result<(&String, &BodyInfo), DeckError> {
            let b = required(src, span(r), &k("body"), &rr.body, "body")?;
            let (n, info) = bodies.get_key_value(b.get_ref()).ok_or_else(|| {
                let known: Vec<&str> = bodies.keys().map(String::as_str).collect();
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
            Ok((n, info))
        };
        let node_index =
            |info: &BodyInfo, v: &Spanned<i64>, key: &str| -> Result<usize, DeckError> {
                let n = info.nodes.as_ref().map_or(0, Vec::len);
                let x = *v.get_ref();
                if x < 0 || x as usize >= n {
                    return Err(src.error(
                        span(v),
                        Some(k(key)),
                        format!(
                            "node {x} does not exist (nodes 0 to {})",
                            n.saturating_sub(1)
                        ),
                    ));
                }
                Ok(x as usize)
            };
        let (resp, unit) = match kind.get_ref().as_str() {
            "position" | "velocity" => {
                let (_, info) = body(false)?;
                let c = component(src, &k("component"), rr.component.as_ref(), span(r), &XYZ)?;
                if kind.get_ref() == "position" {
                    (
                        Response::BodyPosition {
                            body: info.id,
                            axis: c,
                        },
                        "m",
                    )
                } else {
                    (
                        Response::State(model.n_q() + model.v_range(info.id).start + c),
                        "m/s",
                    )
                }
            }
            "nodal-displacement" => {
                let (_, info) = body(true)?;
                let node = node_index(
                    info,
                    required(src, span(r), &k("node"), &rr.node, "node")?,
                    "node",
                )?;
                let c = component(
                    src,
                    &k("component"),
                    rr.component.as_ref(),
                    span(r),
                    &NODE_DOF,
                )?;
                (
                    Response::NodalDisplacement {
                        body: info.id,
                        node,
                        dof: c,
                    },
                    if c < 3 { "m" } else { "rad" },
                )
            }
            "mid-node-deflection" => {
                let (_, info) = body(true)?;
                // the mesh's nodes (couplings' nodes follow them)
                let count = info.nodes.as_ref().map_or(0, Vec::len) - info.couplings.len();
                let nodes = match &rr.nodes {
                    Some(v) => {
                        let mut out = [0; 3];
                        for i in 0..3 {
                            out[i] =
                                node_index(info, &Spanned::new(v.span(), v.get_ref()[i]), "nodes")?;
                        }
                        out
                    }
                    None => [0, (count - 1) / 2, count - 1],
                };
                let x = info.nodes.as_ref().expect("flexible");
                let length = (x[nodes[2]] - x[nodes[0]]).norm();
                if length == 0.0 {
                    return Err(src.error(
                        span(r),
                        Some(k("nodes")),
                        "the first and last nodes coincide",
                    ));
                }
                let normal = rr
                    .normal
                    .as_ref()
                    .map(|v| direction(src, &k("normal"), v))
                    .transpose()?
                    .unwrap_or(Vector3::z());
                (
                    Response::MidNodeDeflection {
                        body: info.id,
                        first: nodes[0],
                        mid: nodes[1],
                        last: nodes[2],
                        normal,
                    },
                    "1",
                )
            }
            "reaction" => {
                let j = required(src, span(r), &k("joint"), &rr.joint, "joint")?;
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
                let c = component(
                    src,
                    &k("component"),
                    rr.component.as_ref(),
                    span(r),
                    &REACTION,
                )?;
                (
                    if c < 3 {
                        Response::ReactionForce { joint, axis: c }
                    } else {
                        Response::ReactionMoment { joint, axis: c - 3 }
                    },
                    if c < 3 { "N" } else { "N*m" },
                )
            }
            "modal" => {
                let (_, info) = body(true)?;
                let m = required(src, span(r), &k("mode"), &rr.mode, "mode (from 1)")?;
                let nm = model.body(info.id).n_modes();
                let mode = *m.get_ref();
                if mode < 1 || mode as usize > nm {
                    return Err(src.error(
                        span(m),
                        Some(k("mode")),
                        format!("mode {mode}: the body keeps modes 1 to {nm}"),
                    ));
                }
                (
                    Response::State(model.q_range(info.id).start + 7 + mode as usize - 1),
                    "1",
                )
            }
            "energy" => (Response::Energy, "J"),
            "constraint-violation" => (Response::ConstraintViolation, "m"),
            other => {
                let c = [
                    "position",
                    "velocity",
                    "nodal-displacement",
                    "mid-node-deflection",
                    "reaction",
                    "modal",
                    "energy",
                    "constraint-violation",
                ];
                return Err(src.error(
                    span(kind),
                    Some(k("kind")),
                    format!("unknown response `{other}`{}", suggestion(other, &c)),
                ));
            }
        };
        out.push(ResponseDef {
            name: name.clone(),
            response: resp,
            unit,
        });
    }
    Ok(out)
}
