//! `flexsens run`: the dynamic analysis of the deck's mechanism and, when the deck declares
//! design variables, the direct sensitivities of every response, objectives with gradients
//! and finite-difference comparisons ([`super::sensitivity`]); written as a result file (HDF5)
//! and CSV tables.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::ops::Range;
use std::path::{Path, PathBuf};

use mbs::{
    Baumgarte, BdfOptions, BodyId, FlexibleBody, Force, Joint, JointKind, Load, LoadFrame, Marker,
    Model, MultibodySystem, Output, RedundancyPolicy, RigidBody, State, StepControl, TimeFunction,
};
use nalgebra::{DMatrix, Matrix3, Rotation3, Unit, Vector3};
use toml::Spanned;

use super::modes::DesignRequest;
use super::sensitivity::{self, FdCase, ObjectiveResult, Sensitivities};
use crate::deck::bodies::validate_one as validate_body;
use crate::deck::check::{count, direction, finite, positive, required, span, vector};
use crate::deck::design::FdSteps;
use crate::deck::design::{DesignDef, validate as validate_design};
use crate::deck::laminates::{suggestion, validate as validate_laminates};
use crate::deck::raw::{RawAnalysis, RawMarker, RawMotion, RawResponse, RawRotation};
use crate::deck::{self, DeckError, RawDeck, Source};
use crate::error::CliError;
use crate::files::write_atomic;
use crate::progress::RunProgress;
use crate::results::{Attr, Group};

/// What `flexsens run` was asked for.
pub struct RunRequest<'a> {
    /// Output directory (default: `<deck stem>.out` beside the deck).
    pub out: Option<&'a Path>,
    /// A one-line JSON summary on stdout instead of the table.
    pub json: bool,
    /// A progress bar on stderr for runs longer than a second.
    pub progress: bool,
}

/// A body of the mechanism: where it is in the model and what the responses need of it.
pub(crate) struct BodyInfo {
    pub(crate) id: BodyId,
    /// Initial frame origin and orientation.
    position: Vector3<f64>,
    rotation: Matrix3<f64>,
    /// Flexible bodies: node positions in the body frame.
    nodes: Option<Vec<Vector3<f64>>>,
    /// Natural frequencies (Hz), flexible bodies.
    pub(crate) frequencies: Vec<f64>,
}

/// A response to evaluate at every output time.
pub(crate) enum Response {
    Position {
        body: BodyId,
        component: usize,
    },
    Velocity {
        component: usize,
        nv: Range<usize>,
    },
    NodalDisplacement {
        body: usize,
        node: usize,
        component: usize,
    },
    /// `body` is the model's body index; `undeformed`: the three nodes' positions in the body
    /// frame.
    MidNodeDeflection {
        body: usize,
        nodes: [usize; 3],
        undeformed: [Vector3<f64>; 3],
        normal: Vector3<f64>,
        length: f64,
    },
    Reaction {
        joint: usize,
        component: usize,
    },
    Modal {
        body: usize,
        mode: usize,
    },
    Energy,
    ConstraintViolation,
}

impl Response {
    /// The same response in the sensitivity analysis (`mbs::Response`), when it has one:
    /// energies, constraint violations and reaction moments have none.
    pub(crate) fn differentiable(
        &self,
        model: &Model<f64>,
        joints: &[mbs::JointId],
    ) -> Option<mbs::Response> {
        let body = |i: usize| model.body_ids().nth(i).expect("a body of the model");
        Some(match self {
            Response::Position { body, component } => mbs::Response::BodyPosition {
                body: *body,
                axis: *component,
            },
            Response::Velocity { component, nv } => {
                mbs::Response::State(model.n_q() + nv.start + component)
            }
            Response::NodalDisplacement {
                body: b,
                node,
                component,
            } => mbs::Response::NodalDisplacement {
                body: body(*b),
                node: *node,
                dof: *component,
            },
            Response::MidNodeDeflection {
                body: b,
                nodes,
                normal,
                ..
            } => mbs::Response::MidNodeDeflection {
                body: body(*b),
                first: nodes[0],
                mid: nodes[1],
                last: nodes[2],
                normal: *normal,
            },
            Response::Reaction { joint, component } if *component < 3 => {
                mbs::Response::ReactionForce {
                    joint: joints[*joint],
                    axis: *component,
                }
            }
            Response::Modal { body: b, mode } => {
                mbs::Response::State(model.q_range(body(*b)).start + 7 + mode)
            }
            Response::Reaction { .. } | Response::Energy | Response::ConstraintViolation => {
                return None;
            }
        })
    }
}

/// A body's initial state: id, frame origin, orientation (body → global), velocity of the
/// origin, angular velocity (global components).
type Placement = (
    BodyId,
    Vector3<f64>,
    Matrix3<f64>,
    Vector3<f64>,
    Vector3<f64>,
);

/// A flexible body of the mechanism with what its design derivatives need.
pub(crate) struct FlexiblePart {
    pub(crate) id: BodyId,
    pub(crate) name: String,
    pub(crate) built: super::modes::Built,
    pub(crate) analysis: fem::ModalAnalysis,
    /// The body's table in the deck.
    pub(crate) span: Range<usize>,
}

/// The validated mechanism.
pub(crate) struct Mechanism {
    pub(crate) model: Model<f64>,
    pub(crate) flexible: Vec<FlexiblePart>,
    pub(crate) design: DesignDef,
    pub(crate) state: State,
    pub(crate) bodies: BTreeMap<String, BodyInfo>,
    pub(crate) body_order: Vec<String>,
    joint_names: Vec<String>,
    pub(crate) joint_ids: Vec<mbs::JointId>,
    pub(crate) responses: Vec<(String, Response, &'static str)>,
    pub(crate) times: Vec<f64>,
    pub(crate) options: BdfOptions,
    pub(crate) policy: RedundancyPolicy,
    /// The progress bar, when one is wanted.
    pub(crate) progress: Option<RunProgress>,
}

/// An angle: a number in degrees, or a string `"<number> deg|rad"`; radians out.
fn angle(src: &Source, key: &str, v: &Spanned<toml::Value>) -> Result<f64, DeckError> {
    quantity(
        src,
        key,
        v,
        &[("deg", std::f64::consts::PI / 180.0), ("rad", 1.0)],
        "degrees",
    )
}

/// An angular rate: a number in deg/s, or a string `"<number> deg/s|rad/s|rpm"`; rad/s out.
fn angular_rate(src: &Source, key: &str, v: &Spanned<toml::Value>) -> Result<f64, DeckError> {
    let deg = std::f64::consts::PI / 180.0;
    quantity(
        src,
        key,
        v,
        &[
            ("deg/s", deg),
            ("rad/s", 1.0),
            ("rpm", std::f64::consts::PI / 30.0),
        ],
        "deg/s",
    )
}

fn quantity(
    src: &Source,
    key: &str,
    v: &Spanned<toml::Value>,
    units: &[(&str, f64)],
    default: &str,
) -> Result<f64, DeckError> {
    let bad = |m: String| src.error(span(v), Some(key.to_string()), m);
    let x = match v.get_ref() {
        toml::Value::Float(x) => *x * units[0].1,
        toml::Value::Integer(i) => *i as f64 * units[0].1,
        toml::Value::String(s) => {
            let (num, unit) = s
                .trim()
                .split_once(char::is_whitespace)
                .unwrap_or((s.as_str(), ""));
            let factor = units.iter().find(|(u, _)| *u == unit.trim()).map(|(_, f)| *f).ok_or_else(|| {
                let known: Vec<&str> = units.iter().map(|(u, _)| *u).collect();
                bad(format!("`{s}`: expected a number ({default}) or \"<number> <unit>\" with a unit of {}", known.join(", ")))
            })?;
            num.parse::<f64>()
                .map_err(|_| bad(format!("`{num}` is not a number")))?
                * factor
        }
        other => {
            return Err(bad(format!(
                "expected a number ({default}) or a string with a unit, found {}",
                other.type_str()
            )));
        }
    };
    if x.is_finite() {
        Ok(x)
    } else {
        Err(bad(format!("{x} must be finite")))
    }
}

fn rotation(src: &Source, key: &str, r: &Spanned<RawRotation>) -> Result<Matrix3<f64>, DeckError> {
    let raw = r.get_ref();
    let axis = direction(
        src,
        &format!("{key}.axis"),
        required(
            src,
            span(r),
            &format!("{key}.axis"),
            &raw.axis,
            "axis [x, y, z]",
        )?,
    )?;
    let a = angle(
        src,
        &format!("{key}.angle"),
        required(
            src,
            span(r),
            &format!("{key}.angle"),
            &raw.angle,
            "angle (degrees)",
        )?,
    )?;
    Ok(*Rotation3::from_axis_angle(&Unit::new_normalize(axis), a).matrix())
}

fn inertia(src: &Source, key: &str, v: &Spanned<toml::Value>) -> Result<Matrix3<f64>, DeckError> {
    let bad = || {
        src.error(
            span(v),
            Some(key.into()),
            "expected [Ixx, Iyy, Izz] or a 3×3 matrix [[…], […], […]] (kg·m²)",
        )
    };
    let num = |x: &toml::Value| x.as_float().or_else(|| x.as_integer().map(|i| i as f64));
    let arr = v.get_ref().as_array().ok_or_else(bad)?;
    let m = if arr.len() == 3 && arr.iter().all(|x| num(x).is_some()) {
        Matrix3::from_diagonal(&Vector3::new(
            num(&arr[0]).unwrap_or(0.0),
            num(&arr[1]).unwrap_or(0.0),
            num(&arr[2]).unwrap_or(0.0),
        ))
    } else if arr.len() == 3 {
        let mut m = Matrix3::zeros();
        for (i, row) in arr.iter().enumerate() {
            let row = row.as_array().filter(|r| r.len() == 3).ok_or_else(bad)?;
            for (j, x) in row.iter().enumerate() {
                m[(i, j)] = num(x).ok_or_else(bad)?;
            }
        }
        m
    } else {
        return Err(bad());
    };
    let symmetric = (m - m.transpose()).abs().max() <= 1e-12 * m.abs().max();
    let pd = m.cholesky().is_some();
    if !(m.iter().all(|x| x.is_finite()) && symmetric && pd) {
        return Err(src.error(
            span(v),
            Some(key.into()),
            "the inertia must be symmetric positive definite",
        ));
    }
    Ok(m)
}

/// A marker from its deck description (global point and axes in the initial configuration).
fn marker(
    src: &Source,
    key: &str,
    m: &Spanned<RawMarker>,
    bodies: &BTreeMap<String, BodyInfo>,
) -> Result<Marker, DeckError> {
    let raw = m.get_ref();
    let k = |s: &str| format!("{key}.{s}");
    let body = required(
        src,
        span(m),
        &k("body"),
        &raw.body,
        "body (a body name or \"ground\")",
    )?;
    let axis = raw
        .axis
        .as_ref()
        .map(|a| direction(src, &k("axis"), a))
        .transpose()?
        .unwrap_or(Vector3::z());
    let reference = raw
        .reference
        .as_ref()
        .map(|r| direction(src, &k("reference"), r))
        .transpose()?;
    if let Some(r) = reference
        && r.cross(&axis).norm() < 1e-6
    {
        return Err(src.error(
            raw.reference.as_ref().map(|x| x.span()),
            Some(k("reference")),
            "must not be parallel to the axis",
        ));
    }
    // axes in the body's (or global) components
    let with_axes = |mk: Marker, rot: &Matrix3<f64>| {
        let a = rot.transpose() * axis;
        match reference {
            Some(r) => {
                let e1 = rot.transpose() * r;
                mk.with_axes(e1, a.cross(&e1))
            }
            None => mk.with_axis(a),
        }
    };
    if body.get_ref() == "ground" {
        if let Some(n) = &raw.node {
            return Err(src.error(span(n), Some(k("node")), "the ground has no nodes"));
        }
        let p = vector(
            src,
            &k("point"),
            required(src, span(m), &k("point"), &raw.point, "point [x, y, z] (m)")?,
        )?;
        return Ok(with_axes(Marker::ground(p), &Matrix3::identity()));
    }
    let info = bodies.get(body.get_ref()).ok_or_else(|| {
        let mut known: Vec<&str> = bodies.keys().map(String::as_str).collect();
        known.push("ground");
        src.error(
            span(body),
            Some(k("body")),
            format!(
                "undefined body `{}`{}",
                body.get_ref(),
                suggestion(body.get_ref(), &known)
            ),
        )
    })?;
    match (&raw.point, &raw.node) {
        (Some(p), None) => {
            let p = vector(src, &k("point"), p)?;
            Ok(with_axes(
                Marker::on(info.id, info.rotation.transpose() * (p - info.position)),
                &info.rotation,
            ))
        }
        (None, Some(n)) => {
            let count = info.nodes.as_ref().map(Vec::len).ok_or_else(|| {
                src.error(
                    span(n),
                    Some(k("node")),
                    format!("`{}` is a rigid body: give a point", body.get_ref()),
                )
            })?;
            let node = *n.get_ref();
            if node < 0 || node as usize >= count {
                return Err(src.error(
                    span(n),
                    Some(k("node")),
                    format!(
                        "node {node} does not exist (the body has nodes 0 to {})",
                        count - 1
                    ),
                ));
            }
            Ok(with_axes(
                Marker::node(info.id, node as usize),
                &info.rotation,
            ))
        }
        (Some(_), Some(n)) => Err(src.error(
            span(n),
            Some(k("node")),
            "give either point or node, not both",
        )),
        (None, None) => Err(src.error(
            span(m),
            Some(k("point")),
            "missing value: point [x, y, z] or node",
        )),
    }
}

fn motion(
    src: &Source,
    key: &str,
    m: &Spanned<RawMotion>,
    angular: bool,
) -> Result<TimeFunction, DeckError> {
    let raw = m.get_ref();
    let k = |s: &str| format!("{key}.{s}");
    let kind = required(
        src,
        span(m),
        &k("kind"),
        &raw.kind,
        "kind (\"constant-speed\", \"polynomial\" or \"ramp\")",
    )?;
    let value = |key: &str, v: &Spanned<toml::Value>| -> Result<f64, DeckError> {
        if angular {
            angle(src, key, v)
        } else {
            quantity(src, key, v, &[("m", 1.0)], "m")
        }
    };
    let rate = |key: &str, v: &Spanned<toml::Value>| -> Result<f64, DeckError> {
        if angular {
            angular_rate(src, key, v)
        } else {
            quantity(src, key, v, &[("m/s", 1.0)], "m/s")
        }
    };
    Ok(match kind.get_ref().as_str() {
        "constant-speed" => TimeFunction::ConstantSpeed {
            initial: raw
                .initial
                .as_ref()
                .map(|v| value(&k("initial"), v))
                .transpose()?
                .unwrap_or(0.0),
            rate: rate(
                &k("rate"),
                required(src, span(m), &k("rate"), &raw.rate, "rate")?,
            )?,
        },
        "polynomial" => {
            let c = required(
                src,
                span(m),
                &k("coefficients"),
                &raw.coefficients,
                "coefficients [c0, c1, …]",
            )?;
            let scale = if angular {
                std::f64::consts::PI / 180.0
            } else {
                1.0
            };
            if c.get_ref().iter().any(|x| !x.is_finite()) {
                return Err(src.error(
                    span(c),
                    Some(k("coefficients")),
                    "coefficients must be finite",
                ));
            }
            TimeFunction::Polynomial(c.get_ref().iter().map(|x| x * scale).collect())
        }
        "ramp" => {
            let t0 = finite(
                src,
                &k("t0"),
                required(src, span(m), &k("t0"), &raw.t0, "t0 (s)")?,
                "s",
            )?;
            let t1v = required(src, span(m), &k("t1"), &raw.t1, "t1 (s)")?;
            let t1 = finite(src, &k("t1"), t1v, "s")?;
            if t1 <= t0 {
                return Err(src.error(
                    span(t1v),
                    Some(k("t1")),
                    format!("t1 = {t1} must be later than t0 = {t0}"),
                ));
            }
            TimeFunction::SmoothRamp {
                from: value(
                    &k("from"),
                    required(src, span(m), &k("from"), &raw.from, "from")?,
                )?,
                to: value(&k("to"), required(src, span(m), &k("to"), &raw.to, "to")?)?,
                t0,
                t1,
            }
        }
        other => {
            let c = ["constant-speed", "polynomial", "ramp"];
            return Err(src.error(
                span(kind),
                Some(k("kind")),
                format!(
                    "unknown motion `{other}`: expected one of {}{}",
                    c.join(", "),
                    suggestion(other, &c)
                ),
            ));
        }
    })
}

fn analysis(
    src: &Source,
    a: Option<&Spanned<RawAnalysis>>,
) -> Result<(Vec<f64>, BdfOptions, Baumgarte, RedundancyPolicy), DeckError> {
    let a = a.ok_or_else(|| {
        src.error(
            None,
            Some("analysis".into()),
            "missing table [analysis] (at least t_end)",
        )
    })?;
    let raw = a.get_ref();
    let k = |s: &str| format!("analysis.{s}");
    let t0 = raw
        .t_start
        .as_ref()
        .map(|t| finite(src, &k("t_start"), t, "s"))
        .transpose()?
        .unwrap_or(0.0);
    let t_end_v = required(src, span(a), &k("t_end"), &raw.t_end, "t_end (s)")?;
    let t_end = finite(src, &k("t_end"), t_end_v, "s")?;
    if t_end <= t0 {
        return Err(src.error(
            span(t_end_v),
            Some(k("t_end")),
            format!("t_end = {t_end} must be later than t_start = {t0}"),
        ));
    }
    let dt = raw
        .output_step
        .as_ref()
        .map(|d| positive(src, &k("output_step"), d, "s"))
        .transpose()?
        .unwrap_or((t_end - t0) / 500.0);
    let n = ((t_end - t0) / dt).round().max(1.0) as usize;
    if n > 10_000_000 {
        return Err(src.error(
            raw.output_step.as_ref().map(|d| d.span()),
            Some(k("output_step")),
            format!("{n} output times: choose a larger output_step"),
        ));
    }
    let times: Vec<f64> = (0..=n)
        .map(|i| {
            if i == n {
                t_end
            } else {
                t0 + i as f64 * (t_end - t0) / n as f64
            }
        })
        .collect();
    let rtol = raw
        .rtol
        .as_ref()
        .map(|r| positive(src, &k("rtol"), r, "1"))
        .transpose()?
        .unwrap_or(1e-6);
    let atol = raw
        .atol
        .as_ref()
        .map(|r| positive(src, &k("atol"), r, "state units"))
        .transpose()?
        .unwrap_or(1e-8);
    let order = raw
        .order
        .as_ref()
        .map(|o| count(src, &k("order"), o, 1))
        .transpose()?;
    if let (Some(o), Some(ov)) = (order, &raw.order)
        && o > 5
    {
        return Err(src.error(
            span(ov),
            Some(k("order")),
            format!("{o}: BDF orders are 1 to 5"),
        ));
    }
    let options = match raw.integrator.as_ref().map(|i| (i, i.get_ref().as_str())) {
        None | Some((_, "adaptive")) => {
            if let Some(s) = &raw.step {
                return Err(src.error(
                    span(s),
                    Some(k("step")),
                    "step is for integrator = \"fixed\"",
                ));
            }
            let mut o = BdfOptions::adaptive(rtol, atol);
            if let StepControl::Adaptive { max_order, .. } = &mut o.control {
                *max_order = order.unwrap_or(5);
            }
            o
        }
        Some((_, "fixed")) => {
            let h = positive(
                src,
                &k("step"),
                required(
                    src,
                    span(a),
                    &k("step"),
                    &raw.step,
                    "step (s) for a fixed-step run",
                )?,
                "s",
            )?;
            let mut o = BdfOptions::fixed(h, order.unwrap_or(2));
            o.rtol = rtol.min(1e-10);
            o
        }
        Some((i, other)) => {
            return Err(src.error(
                span(i),
                Some(k("integrator")),
                format!("unknown integrator `{other}`: expected \"adaptive\" or \"fixed\""),
            ));
        }
    };
    let baumgarte = match raw.baumgarte.as_ref().map(|b| (b, b.get_ref())) {
        None => Baumgarte::default(),
        Some((_, toml::Value::Boolean(false))) => Baumgarte::off(),
        Some((_, toml::Value::Boolean(true))) => Baumgarte::default(),
        Some((b, toml::Value::Table(t))) => {
            let get = |name: &str| -> Result<f64, DeckError> {
                match t.get(name) {
                    None => Ok(1.0),
                    Some(v) => v
                        .as_float()
                        .or_else(|| v.as_integer().map(|i| i as f64))
                        .filter(|x| x.is_finite() && *x >= 0.0)
                        .ok_or_else(|| {
                            src.error(
                                span(b),
                                Some(k(&format!("baumgarte.{name}"))),
                                "must be a finite number ≥ 0 (1/s)",
                            )
                        }),
                }
            };
            if let Some(extra) = t.keys().find(|n| *n != "alpha" && *n != "beta") {
                return Err(src.error(
                    span(b),
                    Some(k(&format!("baumgarte.{extra}"))),
                    "unknown key: expected alpha and beta",
                ));
            }
            Baumgarte {
                alpha: get("alpha")?,
                beta: get("beta")?,
            }
        }
        Some((b, _)) => {
            return Err(src.error(
                span(b),
                Some(k("baumgarte")),
                "expected { alpha, beta } or false",
            ));
        }
    };
    let policy = match raw.redundant.as_ref().map(|r| (r, r.get_ref().as_str())) {
        None | Some((_, "remove")) => RedundancyPolicy::Remove,
        Some((_, "error")) => RedundancyPolicy::Error,
        Some((_, "reselect")) => RedundancyPolicy::Reselect,
        Some((r, other)) => {
            let choices = ["remove", "reselect", "error"];
            return Err(src.error(
                span(r),
                Some(k("redundant")),
                format!(
                    "unknown policy `{other}`: expected \"remove\", \"reselect\" or \"error\"{}",
                    suggestion(other, &choices)
                ),
            ));
        }
    };
    Ok((times, options, baumgarte, policy))
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

/// Build the deck's mechanism; with `derivatives`, each flexible body also gets its
/// derivatives with respect to the deck's design variables ready (section derivatives).
pub(crate) fn build_mechanism(
    src: &Source,
    raw: &RawDeck,
    derivatives: bool,
) -> Result<Mechanism, CliError> {
    let lam = validate_laminates(src, raw)?;
    let design = validate_design(src, raw, &lam)?;
    let request = if derivatives && design.enabled {
        DesignRequest::Variables(&design.variables)
    } else {
        DesignRequest::None
    };
    let mut flexible = Vec::new();
    let mut model = Model::<f64>::new();
    let mut bodies = BTreeMap::new();
    let mut body_order = Vec::new();
    let mut placements = Vec::new();
    let mut modal_starts = Vec::new();
    // flexible bodies: modes of the mesh as given (global coordinates at t = 0)
    for (name, b) in &raw.body {
        let def = validate_body(src, raw, name, b, &lam)?;
        let built = super::modes::build(src, name, &def, request)?;
        if built.options.mass != fem::MassKind::Lumped {
            return Err(CliError::Input(src.error(
                Some(b.span()),
                Some(format!("body.{name}.mass")),
                "the floating frame of reference needs mass = \"lumped\"",
            )));
        }
        let analysis = fem::modal_analysis(&built.mesh, &built.props, &built.options)
            .map_err(|e| super::modes::fem_error(src, name, b.span(), e))?;
        let modal = fem::modal_body(&built.mesh, &built.props, &analysis)
            .map_err(|e| super::modes::fem_error(src, name, b.span(), e))?;
        let nodes = modal.node_positions.clone();
        let id = model
            .add_flexible_body(FlexibleBody::new(name.clone(), modal))
            .map_err(|e| {
                CliError::Input(src.error(
                    Some(b.span()),
                    Some(format!("body.{name}")),
                    e.to_string(),
                ))
            })?;
        let origin = analysis.origin;
        let frequencies = analysis.frequencies_hz();
        modal_starts.push((
            id,
            def.initial_modal.clone(),
            def.initial_modal_rates.clone(),
        ));
        placements.push((
            id,
            analysis.origin,
            Matrix3::identity(),
            Vector3::zeros(),
            Vector3::zeros(),
        ));
        bodies.insert(
            name.clone(),
            BodyInfo {
                id,
                position: origin,
                rotation: Matrix3::identity(),
                nodes: Some(nodes),
                frequencies,
            },
        );
        body_order.push(name.clone());
        flexible.push(FlexiblePart {
            id,
            name: name.clone(),
            built,
            analysis,
            span: b.span(),
        });
    }
    for (name, r) in &raw.rigid {
        let k = |s: &str| format!("rigid.{name}.{s}");
        if raw.body.contains_key(name) || name == "ground" {
            return Err(CliError::Input(src.error(Some(r.span()), Some(format!("rigid.{name}")), "this name is already used (bodies and rigid bodies share names; `ground` is reserved)")));
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
        let id = model
            .add_rigid_body(RigidBody::new(name.clone(), mass, j))
            .map_err(|e| {
                CliError::Input(src.error(
                    Some(r.span()),
                    Some(format!("rigid.{name}")),
                    e.to_string(),
                ))
            })?;
        placements.push((id, p, a, v, w));
        bodies.insert(
            name.clone(),
            BodyInfo {
                id,
                position: p,
                rotation: a,
                nodes: None,
                frequencies: Vec::new(),
            },
        );
        body_order.push(name.clone());
    }
    let (times, options, baumgarte, policy) = analysis(src, raw.analysis.as_ref())?;
    model.baumgarte = baumgarte;
    let mut joint_names = Vec::new();
    let mut joint_ids = Vec::new();
    for (name, j) in &raw.joint {
        let k = |s: &str| format!("joint.{name}.{s}");
        let rj = j.get_ref();
        let kind_v = required(src, span(j), &k("kind"), &rj.kind, "kind")?;
        let kinds = [
            "spherical",
            "revolute",
            "universal",
            "cylindrical",
            "translational",
            "fixed",
            "angle-driver",
            "distance-driver",
        ];
        let driver = matches!(
            kind_v.get_ref().as_str(),
            "angle-driver" | "distance-driver"
        );
        if !driver && let Some(m) = &rj.motion {
            return Err(CliError::Input(src.error(
                span(m),
                Some(k("motion")),
                "motion is only used by drivers",
            )));
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
                return Err(CliError::Input(src.error(
                    span(kind_v),
                    Some(k("kind")),
                    format!("unknown joint kind `{other}`{}", suggestion(other, &kinds)),
                )));
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
            &bodies,
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
            &bodies,
        )?;
        let id = model
            .add_joint(Joint::new(name.clone(), kind, a, b))
            .map_err(|e| {
                CliError::Input(src.error(
                    Some(j.span()),
                    Some(format!("joint.{name}")),
                    e.to_string(),
                ))
            })?;
        joint_names.push(name.clone());
        joint_ids.push(id);
    }
    for (name, f) in &raw.force {
        let k = |s: &str| format!("force.{name}.{s}");
        let rf = f.get_ref();
        let kind = required(
            src,
            span(f),
            &k("kind"),
            &rf.kind,
            "kind (\"gravity\", \"point-force\", \"point-torque\" or \"spring-damper\")",
        )?;
        let force = match kind.get_ref().as_str() {
            "gravity" => {
                model.gravity += vector(
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
                let at = marker(
                    src,
                    &k("at"),
                    required(src, span(f), &k("at"), &rf.at, "at (a marker)")?,
                    &bodies,
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
                            return Err(CliError::Input(src.error(
                                span(times),
                                Some(k("table.times")),
                                "times must be finite and strictly increasing",
                            )));
                        }
                        if values.get_ref().len() != ts.len() {
                            return Err(CliError::Input(src.error(
                                span(values),
                                Some(k("table.values")),
                                format!("{} values for {} times", values.get_ref().len(), ts.len()),
                            )));
                        }
                        Load::Table {
                            times: ts,
                            values: values.get_ref().iter().map(|v| Vector3::from(*v)).collect(),
                        }
                    }
                    (Some(_), Some(t)) => {
                        return Err(CliError::Input(src.error(
                            span(t),
                            Some(k("table")),
                            "give either value or table",
                        )));
                    }
                    (None, None) => {
                        return Err(CliError::Input(src.error(
                            span(f),
                            Some(k("value")),
                            "missing value: value [x, y, z] or table",
                        )));
                    }
                };
                let frame = match rf.frame.as_ref().map(|x| (x, x.get_ref().as_str())) {
                    None | Some((_, "global")) => LoadFrame::Global,
                    Some((_, "body")) => LoadFrame::Body,
                    Some((x, other)) => {
                        return Err(CliError::Input(src.error(
                            span(x),
                            Some(k("frame")),
                            format!("unknown frame `{other}`: expected \"global\" or \"body\""),
                        )));
                    }
                };
                if kind.get_ref() == "point-force" {
                    Force::PointForce {
                        marker: at,
                        load,
                        frame,
                    }
                } else {
                    Force::PointTorque {
                        marker: at,
                        load,
                        frame,
                    }
                }
            }
            "spring-damper" => {
                let a = marker(
                    src,
                    &k("a"),
                    required(src, span(f), &k("a"), &rf.a, "a (a marker)")?,
                    &bodies,
                )?;
                let b = marker(
                    src,
                    &k("b"),
                    required(src, span(f), &k("b"), &rf.b, "b (a marker)")?,
                    &bodies,
                )?;
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
                let free_length = match &rf.free_length {
                    Some(l) => finite(src, &k("free_length"), l, "m")?,
                    None => {
                        let q = initial_state(&model, &placements).q;
                        (model.marker_position(&a, &q) - model.marker_position(&b, &q)).norm()
                    }
                };
                Force::SpringDamper {
                    a,
                    b,
                    stiffness,
                    damping,
                    free_length,
                }
            }
            other => {
                let c = ["gravity", "point-force", "point-torque", "spring-damper"];
                return Err(CliError::Input(src.error(
                    span(kind),
                    Some(k("kind")),
                    format!("unknown force kind `{other}`{}", suggestion(other, &c)),
                )));
            }
        };
        model.add_force(force).map_err(|e| {
            CliError::Input(src.error(Some(f.span()), Some(format!("force.{name}")), e.to_string()))
        })?;
    }
    let mut state = initial_state(&model, &placements);
    // the elastic state is the user's; the assembly moves only the rigid-body coordinates
    for (id, w, wd) in &modal_starts {
        // static correction modes (after the retained ones) start at zero
        let n = model.body(*id).n_modes();
        let pad = |x: &Vec<f64>| {
            let mut x = x.clone();
            x.resize(n, 0.0);
            x
        };
        model.set_modal(&mut state, *id, &pad(w), &pad(wd));
    }
    let responses = responses(src, raw, &model, &bodies, &joint_names)?;
    check_design(
        src,
        raw,
        &design,
        &flexible,
        &responses,
        &model,
        &joint_ids,
        derivatives,
    )?;
    Ok(Mechanism {
        model,
        flexible,
        design,
        state,
        bodies,
        body_order,
        joint_names,
        joint_ids,
        responses,
        times,
        options,
        policy,
        progress: None,
    })
}

/// Design variables must move some flexible body; objectives of a run with sensitivities need
/// responses that have them.
fn check_design(
    src: &Source,
    raw: &RawDeck,
    design: &DesignDef,
    flexible: &[FlexiblePart],
    responses: &[(String, Response, &'static str)],
    model: &Model<f64>,
    joints: &[mbs::JointId],
    derivatives: bool,
) -> Result<(), DeckError> {
    if !(derivatives && design.enabled) {
        return Ok(());
    }
    for (j, v) in design.variables.iter().enumerate() {
        if !flexible.iter().any(|p| p.built.design.depends_on(j)) {
            return Err(src.error(
                Some(raw.design[&v.name].span()),
                Some(format!("design.{}", v.name)),
                format!(
                    "the design variable changes no flexible body: laminate `{}` laminates no \
                     shell body and builds no beam body's section",
                    v.laminate
                ),
            ));
        }
    }
    for o in &design.objectives {
        let (_, r, _) = responses
            .iter()
            .find(|(n, _, _)| *n == o.response)
            .expect("objective responses are validated");
        if r.differentiable(model, joints).is_none() {
            let ro = raw.objective[&o.name].get_ref();
            return Err(src.error(
                ro.response.as_ref().and_then(span),
                Some(format!("objective.{}.response", o.name)),
                format!(
                    "response `{}` has no design sensitivities (energies, constraint violations \
                     and reaction moments have none), so its objective has no gradient",
                    o.response
                ),
            ));
        }
    }
    Ok(())
}

fn initial_state(model: &Model<f64>, placements: &[Placement]) -> State {
    let mut s = model.rest_state();
    for (id, p, a, v, w) in placements {
        model.set_pose(&mut s, *id, *p, a);
        // ω' in body components from the global angular velocity
        model.set_velocity(&mut s, *id, *v, a.transpose() * w);
    }
    s
}

fn responses(
    src: &Source,
    raw: &RawDeck,
    model: &Model<f64>,
    bodies: &BTreeMap<String, BodyInfo>,
    joints: &[String],
) -> Result<Vec<(String, Response, &'static str)>, DeckError> {
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
                        Response::Position {
                            body: info.id,
                            component: c,
                        },
                        "m",
                    )
                } else {
                    (
                        Response::Velocity {
                            component: c,
                            nv: model.v_range(info.id),
                        },
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
                        body: info.id.index(),
                        node,
                        component: c,
                    },
                    if c < 3 { "m" } else { "rad" },
                )
            }
            "mid-node-deflection" => {
                let (_, info) = body(true)?;
                let count = info.nodes.as_ref().map_or(0, Vec::len);
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
                        body: info.id.index(),
                        nodes,
                        undeformed: [x[nodes[0]], x[nodes[1]], x[nodes[2]]],
                        normal,
                        length,
                    },
                    "1",
                )
            }
            "reaction" => {
                let j = required(src, span(r), &k("joint"), &rr.joint, "joint")?;
                let idx = joints
                    .iter()
                    .position(|x| x == j.get_ref())
                    .ok_or_else(|| {
                        let known: Vec<&str> = joints.iter().map(String::as_str).collect();
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
                    Response::Reaction {
                        joint: idx,
                        component: c,
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
                    Response::Modal {
                        body: info.id.index(),
                        mode: mode as usize - 1,
                    },
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
        out.push((name.clone(), resp, unit));
    }
    Ok(out)
}

/// The value of a response at one output.
pub(crate) fn evaluate(r: &Response, o: &Output) -> f64 {
    match r {
        Response::Position { body, component } => o.positions[body.index()][*component],
        Response::Velocity { nv, component } => o.v[nv.start + component],
        Response::NodalDisplacement {
            body,
            node,
            component,
        } => o.nodal_displacements[*body][*node][*component],
        Response::MidNodeDeflection {
            body,
            nodes,
            undeformed,
            normal,
            length,
        } => {
            let i = *body;
            let p = |k: usize| {
                let u = o.nodal_displacements[i][nodes[k]];
                o.positions[i]
                    + o.orientations[i] * (undeformed[k] + Vector3::new(u[0], u[1], u[2]))
            };
            let (pa, pm, pb) = (p(0), p(1), p(2));
            let t = (pb - pa).normalize();
            let e = normal.cross(&t);
            (pm - pa).dot(&e) / length
        }
        Response::Reaction { joint, component } => {
            let rj = &o.reactions[*joint];
            if *component < 3 {
                rj.force_on_b[*component]
            } else {
                rj.moment_on_b[*component - 3]
            }
        }
        Response::Modal { body, mode } => o.modal[*body][*mode],
        Response::Energy => o.energy.total(),
        Response::ConstraintViolation => o.position_violation,
    }
}

/// The default output directory: `<deck stem>.out` beside the deck.
fn default_out(deck: &Path) -> PathBuf {
    let stem = deck
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "flexsens".into());
    deck.with_file_name(format!("{stem}.out"))
}

/// Everything a run computed, ready to be written.
pub(crate) struct Computed {
    pub(crate) outputs: Vec<Output>,
    pub(crate) statistics: mbs::Statistics,
    /// Per response: its history at the output times.
    pub(crate) values: Vec<Vec<f64>>,
    pub(crate) sensitivities: Option<Sensitivities>,
    pub(crate) objectives: Vec<ObjectiveResult>,
    pub(crate) fd: Vec<FdCase>,
}

/// The output files a run may write; those a run does not write are removed, so that a
/// directory never mixes two runs.
const OUTPUT_FILES: [&str; 4] = [
    "history.csv",
    "sensitivities.csv",
    "gradients.csv",
    "results.h5",
];

/// Run the command; the returned text goes to stdout.
pub fn run(path: &Path, overrides: &[String], req: &RunRequest) -> Result<String, CliError> {
    let (src, raw) = deck::load(path, overrides)?;
    let mut mech = build_mechanism(&src, &raw, true)?;
    if req.progress {
        let t_end = *mech.times.last().expect("output times");
        mech.progress = Some(RunProgress::new(mech.times[0], t_end));
    }
    let out = req
        .out
        .map(Path::to_path_buf)
        .unwrap_or_else(|| default_out(path));
    // a failed run must not leave the previous run's files looking like its own
    for f in OUTPUT_FILES {
        match std::fs::remove_file(out.join(f)) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                return Err(CliError::Runtime(format!(
                    "cannot remove the old {}: {e}",
                    out.join(f).display()
                )));
            }
            _ => {}
        }
    }
    let computed = compute(&src, &mech);
    if let Some(p) = &mech.progress {
        p.finish();
    }
    let computed = computed?;
    let g = results(&src, &mech, &computed);
    let bytes = g
        .to_hdf5()
        .map_err(|e| CliError::Runtime(format!("cannot encode the results: {e}")))?;
    write_atomic(
        &out.join("history.csv"),
        history_csv(&mech, &computed).as_bytes(),
    )?;
    let mut written = vec![out.join("history.csv")];
    if let Some(csv) = sensitivities_csv(&mech, &computed) {
        write_atomic(&out.join("sensitivities.csv"), csv.as_bytes())?;
        written.push(out.join("sensitivities.csv"));
    }
    if !computed.objectives.is_empty() {
        write_atomic(
            &out.join("gradients.csv"),
            gradients_csv(&mech, &computed).as_bytes(),
        )?;
        written.push(out.join("gradients.csv"));
    }
    // results.h5 last: its presence means the run completed
    write_atomic(&out.join("results.h5"), &bytes)?;
    written.push(out.join("results.h5"));
    let summary = summary(&src, &mech, &computed, &out);
    if req.json {
        return Ok(summary.to_string() + "\n");
    }
    Ok(summary_text(&raw, &mech, &computed, &summary, &written))
}

/// The analysis, its sensitivities, objectives and finite-difference comparisons.
pub(crate) fn compute(src: &Source, mech: &Mechanism) -> Result<Computed, CliError> {
    let runtime = |m: String| CliError::Runtime(format!("{}: {m}", src.file.display()));
    let mut system =
        MultibodySystem::new_at(mech.model.clone(), mech.times[0], &mech.state, mech.policy)
            .map_err(|e| runtime(e.to_string()))?;
    let mut state = mech.state.clone();
    system
        .assemble(mech.times[0], &mut state, 1e-10)
        .map_err(|e| {
            runtime(format!(
                "the initial configuration cannot be assembled: {e}"
            ))
        })?;
    if let Some(p) = &mech.progress {
        system.set_progress(Some(p.observer()));
        if mech.design.enabled
            && let Some(fd) = &mech.design.finite_differences
        {
            let m = mech.design.variables.len();
            let k = fd.sizes.len();
            let per_steps = if fd.central { 2 * m * k } else { 1 + m * k };
            p.add_phases(per_steps * fd.steps.len());
        }
    }
    let (outputs, statistics, sens) = if mech.design.enabled {
        let s = sensitivity::analyse(src, mech, &mut system, &state)?;
        (s.outputs.clone(), s.statistics, Some(s))
    } else {
        let sim = mbs::simulate(&mut system, &state, &mech.times, mech.options.clone())
            .map_err(|e| runtime(e.to_string()))?;
        (sim.outputs, sim.statistics, None)
    };
    let values: Vec<Vec<f64>> = mech
        .responses
        .iter()
        .map(|(_, r, _)| outputs.iter().map(|o| evaluate(r, o)).collect())
        .collect();
    let objectives = sensitivity::objectives(
        src,
        mech,
        &values,
        sens.as_ref().map(|s| s.responses.as_slice()),
    )?;
    let fd = match &sens {
        Some(s) => sensitivity::finite_differences(src, mech, &system, &state, &s.replay)?,
        None => Vec::new(),
    };
    Ok(Computed {
        outputs,
        statistics,
        values,
        sensitivities: sens,
        objectives,
        fd,
    })
}

/// Unit of a derivative per degree.
fn per_degree(unit: &str) -> String {
    if unit == "1" {
        "1/deg".into()
    } else {
        format!("{unit}/deg")
    }
}

/// A row-major copy of a matrix.
fn row_major(m: &DMatrix<f64>) -> Vec<f64> {
    m.transpose().iter().copied().collect()
}

/// The result file's contents.
fn results(src: &Source, mech: &Mechanism, c: &Computed) -> Group {
    let n = mech.times.len();
    let outputs = &c.outputs;
    let mut g = Group::default();
    g.attrs.insert(
        "flexsens_version".into(),
        Attr::Text(env!("CARGO_PKG_VERSION").into()),
    );
    g.put("time", &[n], mech.times.clone()).units("s");
    for ((name, _, unit), v) in mech.responses.iter().zip(&c.values) {
        g.put(&format!("responses/{name}"), &[n], v.clone())
            .units(unit);
    }
    for name in &mech.body_order {
        let b = &mech.bodies[name];
        let i = b.id.index();
        g.put(
            &format!("bodies/{name}/position"),
            &[n, 3],
            outputs
                .iter()
                .flat_map(|o| o.positions[i].iter().copied().collect::<Vec<_>>())
                .collect(),
        )
        .units("m");
        g.put(
            &format!("bodies/{name}/orientation"),
            &[n, 3, 3],
            outputs
                .iter()
                .flat_map(|o| {
                    o.orientations[i]
                        .transpose()
                        .iter()
                        .copied()
                        .collect::<Vec<_>>()
                })
                .collect(),
        )
        .units("1");
        if b.nodes.is_some() {
            let m = outputs[0].modal[i].len();
            g.put(
                &format!("bodies/{name}/modal_coordinates"),
                &[n, m],
                outputs.iter().flat_map(|o| o.modal[i].clone()).collect(),
            )
            .units("1");
            g.put(
                &format!("bodies/{name}/frequencies"),
                &[b.frequencies.len()],
                b.frequencies.clone(),
            )
            .units("Hz");
        }
    }
    for (j, name) in mech.joint_names.iter().enumerate() {
        g.put(
            &format!("joints/{name}/reaction_on_b"),
            &[n, 6],
            outputs
                .iter()
                .flat_map(|o| {
                    let r = &o.reactions[j];
                    [
                        r.force_on_b[0],
                        r.force_on_b[1],
                        r.force_on_b[2],
                        r.moment_on_b[0],
                        r.moment_on_b[1],
                        r.moment_on_b[2],
                    ]
                })
                .collect(),
        )
        .units("N, N*m");
    }
    g.put(
        "constraints/position_violation",
        &[n],
        outputs.iter().map(|o| o.position_violation).collect(),
    )
    .units("m");
    g.put(
        "constraints/removed_position_violation",
        &[n],
        outputs
            .iter()
            .map(|o| o.removed_position_violation)
            .collect(),
    )
    .units("m");
    g.put(
        "constraints/velocity_violation",
        &[n],
        outputs.iter().map(|o| o.velocity_violation).collect(),
    )
    .units("m/s");
    g.put(
        "energy/total",
        &[n],
        outputs.iter().map(|o| o.energy.total()).collect(),
    )
    .units("J");
    let st = &c.statistics;
    let mut counters = vec![
        ("steps", st.steps),
        ("rejected_steps", st.rejected_steps),
        ("newton_failures", st.newton_failures),
        ("newton_iterations", st.newton_iterations),
        ("rhs_evaluations", st.rhs_evaluations),
        ("jacobians", st.jacobians),
        ("factorizations", st.factorizations),
    ];
    if let Some(s) = &c.sensitivities {
        let ss = &s.sensitivity_statistics;
        counters.extend([
            ("sensitivity_dual_evaluations", ss.dual_evaluations),
            ("sensitivity_corrector_iterations", ss.corrector_iterations),
            ("sensitivity_direct_solves", ss.direct_solves),
        ]);
    }
    for (k, v) in counters {
        g.group("statistics")
            .attrs
            .insert(k.into(), Attr::I64(v as i64));
    }
    let vars = &mech.design.variables;
    let m = vars.len();
    if m > 0 {
        g.put_text(
            "design/names",
            vars.iter().map(|v| v.name.clone()).collect(),
        );
        g.put(
            "design/values",
            &[m],
            vars.iter().map(|v| v.value).collect(),
        )
        .units("deg");
        g.put_text(
            "design/laminates",
            vars.iter().map(|v| v.laminate.clone()).collect(),
        );
    }
    if let Some(s) = &c.sensitivities {
        let method = format!(
            "{}, {} modes",
            mech.design.method.name(),
            if mech.design.fixed_modes {
                "fixed"
            } else {
                "updated"
            }
        );
        g.group("sensitivities")
            .attrs
            .insert("method".into(), Attr::Text(method));
        for ((name, _, unit), d) in mech.responses.iter().zip(&s.responses) {
            if let Some(d) = d {
                g.put(&format!("sensitivities/{name}"), &[n, m], row_major(d))
                    .units(&per_degree(unit));
            }
        }
        for (body, df) in &s.frequencies {
            g.put(
                &format!("bodies/{body}/frequency_derivatives"),
                &[df.nrows(), m],
                row_major(df),
            )
            .units("Hz/deg");
        }
    }
    for o in &c.objectives {
        let base = format!("objectives/{}", o.name);
        g.put(&format!("{base}/value"), &[1], vec![o.value])
            .units(o.unit);
        if let Some(t) = o.time {
            g.put(&format!("{base}/time"), &[1], vec![t]).units("s");
        }
        if !o.gradient.is_empty() {
            g.put(&format!("{base}/gradient"), &[m], o.gradient.clone())
                .units(&per_degree(o.unit));
        }
        let og = g.group(&base);
        og.attrs
            .insert("response".into(), Attr::Text(o.response.clone()));
        og.attrs.insert("kind".into(), Attr::Text(o.kind.label()));
    }
    for case in &c.fd {
        let base = format!("finite_differences/{}", case.label);
        for ((name, _, unit), d) in mech.responses.iter().zip(&case.responses) {
            if let Some(d) = d {
                g.put(&format!("{base}/{name}"), &[n, m], row_major(d))
                    .units(&per_degree(unit));
            }
        }
        for (o, d) in c.objectives.iter().zip(&case.objectives) {
            g.put(&format!("{base}/objectives/{}", o.name), &[m], d.clone())
                .units(&per_degree(o.unit));
        }
        g.put(&format!("{base}/perturbations"), &[m], case.deltas.clone())
            .units("deg");
        let cg = g.group(&base);
        for (k, v) in [
            ("scheme", if case.central { "central" } else { "forward" }),
            (
                "perturbation",
                if case.relative {
                    "relative"
                } else {
                    "absolute"
                },
            ),
            (
                "steps",
                match case.steps {
                    FdSteps::Replay => "replay",
                    FdSteps::Adaptive => "adaptive",
                },
            ),
        ] {
            cg.attrs.insert(k.into(), Attr::Text(v.into()));
        }
        cg.attrs.insert("size".into(), Attr::F64(case.size));
    }
    g.put_text("meta/deck", vec![src.text.clone()]);
    g.put_text("meta/deck_path", vec![src.file.display().to_string()]);
    g.put_text("meta/overrides", src.overrides.clone());
    g
}

/// `history.csv`: time and every response.
fn history_csv(mech: &Mechanism, c: &Computed) -> String {
    let mut csv = String::from("time [s]");
    for (name, _, unit) in &mech.responses {
        let _ = write!(csv, ",{name} [{unit}]");
    }
    csv.push('\n');
    for (i, t) in mech.times.iter().enumerate() {
        let _ = write!(csv, "{t:e}");
        for v in &c.values {
            let _ = write!(csv, ",{:e}", v[i]);
        }
        csv.push('\n');
    }
    csv
}

/// `sensitivities.csv`: time and `d(response)/d(variable)` for every response that has
/// sensitivities and every design variable.
fn sensitivities_csv(mech: &Mechanism, c: &Computed) -> Option<String> {
    let s = c.sensitivities.as_ref()?;
    let vars = &mech.design.variables;
    let mut csv = String::from("time [s]");
    let mut columns = Vec::new();
    for ((name, _, unit), d) in mech.responses.iter().zip(&s.responses) {
        if let Some(d) = d {
            for (j, v) in vars.iter().enumerate() {
                let _ = write!(csv, ",d {name}/d {} [{}]", v.name, per_degree(unit));
                columns.push((d, j));
            }
        }
    }
    csv.push('\n');
    for (i, t) in mech.times.iter().enumerate() {
        let _ = write!(csv, "{t:e}");
        for (d, j) in &columns {
            let _ = write!(csv, ",{:e}", d[(i, *j)]);
        }
        csv.push('\n');
    }
    Some(csv)
}

/// `gradients.csv`: one row per objective, its value and one column per design variable.
fn gradients_csv(mech: &Mechanism, c: &Computed) -> String {
    let mut csv = String::from("objective,response,kind,value,unit,time [s]");
    let with_gradients = c.sensitivities.is_some();
    if with_gradients {
        for v in &mech.design.variables {
            let _ = write!(csv, ",d/d {} [unit/deg]", v.name);
        }
    }
    csv.push('\n');
    for o in &c.objectives {
        let _ = write!(
            csv,
            "{},{},{},{:e},{},{}",
            o.name,
            o.response,
            o.kind.label(),
            o.value,
            o.unit,
            o.time.map(|t| format!("{t:e}")).unwrap_or_default()
        );
        for g in &o.gradient {
            let _ = write!(csv, ",{g:e}");
        }
        csv.push('\n');
    }
    csv
}

/// The machine-readable summary (`--json`), also the source of the table.
fn summary(src: &Source, mech: &Mechanism, c: &Computed, out: &Path) -> serde_json::Value {
    use serde_json::json;
    let st = &c.statistics;
    let responses: serde_json::Map<_, _> = mech
        .responses
        .iter()
        .zip(&c.values)
        .map(|((name, _, unit), v)| {
            (
                name.clone(),
                json!({
                    "unit": unit,
                    "final": v.last(),
                    "min": v.iter().copied().fold(f64::INFINITY, f64::min),
                    "max": v.iter().copied().fold(f64::NEG_INFINITY, f64::max),
                }),
            )
        })
        .collect();
    let design: Vec<_> = mech
        .design
        .variables
        .iter()
        .map(|v| json!({"name": v.name, "laminate": v.laminate, "value": v.value, "unit": "deg"}))
        .collect();
    let objectives: Vec<_> = c
        .objectives
        .iter()
        .map(|o| {
            json!({
                "name": o.name, "response": o.response, "kind": o.kind.label(),
                "value": o.value, "unit": o.unit, "time": o.time, "gradient": o.gradient,
            })
        })
        .collect();
    let fd: Vec<_> =
        c.fd.iter()
            .map(|case| {
                let s = c
                    .sensitivities
                    .as_ref()
                    .expect("comparisons need sensitivities");
                let worst: serde_json::Map<_, _> = mech
                    .responses
                    .iter()
                    .zip(case.responses.iter().zip(&s.responses))
                    .filter_map(|((name, _, _), (f, d))| {
                        Some((
                            name.clone(),
                            json!(sensitivity::relative_difference(f.as_ref()?, d.as_ref()?)),
                        ))
                    })
                    .collect();
                let absolute: serde_json::Map<_, _> = mech
                    .responses
                    .iter()
                    .zip(case.responses.iter().zip(&s.responses))
                    .filter_map(|((name, _, _), (f, d))| {
                        let (f, d) = (f.as_ref()?, d.as_ref()?);
                        Some((
                            name.clone(),
                            json!({"difference": (f - d).amax(), "sensitivity": d.amax()}),
                        ))
                    })
                    .collect();
                json!({
                    "case": case.label,
                    "max_relative_difference": worst,
                    "max_absolute": absolute,
                })
            })
            .collect();
    json!({
        "deck": src.file.display().to_string(),
        "output": out.display().to_string(),
        "t_end": mech.times.last(),
        "outputs": mech.times.len(),
        "steps": st.steps,
        "rejected_steps": st.rejected_steps,
        "rhs_evaluations": st.rhs_evaluations,
        "max_position_violation": c.outputs.iter().map(|o| o.position_violation).fold(0.0, f64::max),
        "max_removed_position_violation": c.outputs.iter().map(|o| o.removed_position_violation).fold(0.0, f64::max),
        "responses": responses,
        "design": design,
        "objectives": objectives,
        "finite_differences": fd,
    })
}

/// The one-screen summary for people.
fn summary_text(
    raw: &RawDeck,
    mech: &Mechanism,
    c: &Computed,
    summary: &serde_json::Value,
    written: &[PathBuf],
) -> String {
    let n = mech.times.len();
    let st = &c.statistics;
    let mut s = String::new();
    if let Some(t) = &raw.title {
        let _ = writeln!(s, "{t}");
    }
    let _ = writeln!(
        s,
        "{} bodies, {} joints; t = {} … {} s, {} output times",
        mech.body_order.len(),
        mech.joint_names.len(),
        mech.times[0],
        mech.times[n - 1],
        n
    );
    let _ = writeln!(
        s,
        "integrator: {} steps ({} rejected), {} right-hand sides, {} Jacobians",
        st.steps, st.rejected_steps, st.rhs_evaluations, st.jacobians
    );
    let _ = writeln!(
        s,
        "largest position-constraint violation: {:.3e} (equations dropped as redundant: {:.3e})",
        summary["max_position_violation"].as_f64().unwrap_or(0.0),
        summary["max_removed_position_violation"]
            .as_f64()
            .unwrap_or(0.0)
    );
    if !c.values.is_empty() {
        let _ = writeln!(
            s,
            "{:<24} {:>14} {:>14} {:>14}  unit",
            "response", "min", "max", "final"
        );
        for ((name, _, unit), v) in mech.responses.iter().zip(&c.values) {
            let r = &summary["responses"][name];
            let _ = writeln!(
                s,
                "{name:<24} {:>14.6e} {:>14.6e} {:>14.6e}  {unit}",
                r["min"].as_f64().unwrap_or(0.0),
                r["max"].as_f64().unwrap_or(0.0),
                v.last().copied().unwrap_or(0.0)
            );
        }
    }
    let vars = &mech.design.variables;
    if c.sensitivities.is_some() {
        let names: Vec<String> = vars
            .iter()
            .map(|v| format!("{} = {}°", v.name, v.value))
            .collect();
        let _ = writeln!(
            s,
            "sensitivities with respect to {} ({})",
            names.join(", "),
            if mech.design.fixed_modes {
                "fixed modes"
            } else {
                "updated modes"
            }
        );
    }
    if !c.objectives.is_empty() {
        let _ = write!(s, "{:<24} {:>14}", "objective", "value");
        if c.sensitivities.is_some() {
            for v in vars {
                let _ = write!(s, " {:>14}", format!("d/d {}", v.name));
            }
        }
        let _ = writeln!(s, "  unit");
        for o in &c.objectives {
            let _ = write!(s, "{:<24} {:>14.6e}", o.name, o.value);
            for g in &o.gradient {
                let _ = write!(s, " {g:>14.6e}");
            }
            let at = o
                .time
                .map(|t| format!(" (at {t:.6} s)"))
                .unwrap_or_default();
            let _ = writeln!(s, "  {}{at}", o.unit);
        }
    }
    if let Some(cases) = summary["finite_differences"].as_array()
        && !cases.is_empty()
    {
        let _ = writeln!(
            s,
            "finite differences: largest |FD − direct| / max |direct| per response"
        );
        for case in cases {
            let worst = case["max_relative_difference"]
                .as_object()
                .map(|m| {
                    m.iter()
                        .map(|(k, v)| format!("{k} {:.2e}", v.as_f64().unwrap_or(f64::NAN)))
                        .collect::<Vec<_>>()
                        .join(", ")
                })
                .unwrap_or_default();
            let _ = writeln!(s, "  {:<36} {worst}", case["case"].as_str().unwrap_or(""));
        }
    }
    let files: Vec<String> = written.iter().map(|p| p.display().to_string()).collect();
    let _ = writeln!(s, "written: {}", files.join(", "));
    s
}
