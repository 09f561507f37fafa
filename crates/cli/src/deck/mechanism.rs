//! The mechanism part of a deck, validated: rigid bodies, joints and drivers, and force
//! elements, with the quantities they are written in (angles, rates, rotations, inertias,
//! markers, motions).

use std::collections::BTreeMap;
use std::ops::Range;

use mbs::{BodyId, Force, Joint, JointKind, Load, LoadFrame, Marker, TimeFunction};
use nalgebra::{Matrix3, Rotation3, Unit, Vector3};
use toml::Spanned;

use super::check::{direction, finite, positive, required, span, vector};
use super::laminates::suggestion;
use super::raw::{RawDeck, RawMarker, RawMotion, RawRotation};
use super::{DeckError, Source};

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
    /// The body's table in the deck.
    pub span: Range<usize>,
}

/// An angle: a number in degrees, or a string `"<number> deg|rad"`; radians out.
pub fn angle(src: &Source, key: &str, v: &Spanned<toml::Value>) -> Result<f64, DeckError> {
    quantity(
        src,
        key,
        v,
        &[("deg", std::f64::consts::PI / 180.0), ("rad", 1.0)],
        "degrees",
    )
}

/// An angular rate: a number in deg/s, or a string `"<number> deg/s|rad/s|rpm"`; rad/s out.
pub fn angular_rate(src: &Source, key: &str, v: &Spanned<toml::Value>) -> Result<f64, DeckError> {
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

pub fn quantity(
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

pub fn rotation(
    src: &Source,
    key: &str,
    r: &Spanned<RawRotation>,
) -> Result<Matrix3<f64>, DeckError> {
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

pub fn inertia(
    src: &Source,
    key: &str,
    v: &Spanned<toml::Value>,
) -> Result<Matrix3<f64>, DeckError> {
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
        if let Some(c) = &raw.coupling {
            return Err(src.error(span(c), Some(k("coupling")), "the ground has no couplings"));
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
    if let Some(c) = &raw.coupling {
        if raw.point.is_some() || raw.node.is_some() {
            return Err(src.error(
                span(c),
                Some(k("coupling")),
                "give one of point, node or coupling",
            ));
        }
        let nodes = info.nodes.as_ref().map_or(0, Vec::len);
        let index = info.couplings.iter().position(|x| x == c.get_ref());
        return match index {
            Some(i) => Ok(with_axes(
                Marker::node(info.id, nodes - info.couplings.len() + i),
                &info.rotation,
            )),
            None => {
                let known: Vec<&str> = info.couplings.iter().map(String::as_str).collect();
                Err(src.error(
                    span(c),
                    Some(k("coupling")),
                    if known.is_empty() {
                        format!(
                            "body `{}` has no couplings (define them in [body.{}.couplings])",
                            body.get_ref(),
                            body.get_ref()
                        )
                    } else {
                        format!(
                            "undefined coupling `{}` of body `{}`{}",
                            c.get_ref(),
                            body.get_ref(),
                            suggestion(c.get_ref(), &known)
                        )
                    },
                ))
            }
        };
    }
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
            "missing value: point [x, y, z], node or coupling",
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
        "kind (\"constant-speed\", \"polynomial\", \"ramp\" or \"spin-up\")",
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
        "spin-up" => {
            let dv = required(src, span(m), &k("duration"), &raw.duration, "duration (s)")?;
            let duration = finite(src, &k("duration"), dv, "s")?;
            if duration <= 0.0 {
                return Err(src.error(
                    span(dv),
                    Some(k("duration")),
                    format!("duration = {duration} must be positive"),
                ));
            }
            TimeFunction::SpinUp {
                speed: rate(
                    &k("rate"),
                    required(src, span(m), &k("rate"), &raw.rate, "rate")?,
                )?,
                duration,
            }
        }
        other => {
            let c = ["constant-speed", "polynomial", "ramp", "spin-up"];
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
            span: r.span(),
        });
    }
    Ok(out)
}

/// Validate the joints and drivers (markers on the bodies of `bodies`), in deck order.
pub fn joints(
    src: &Source,
    raw: &RawDeck,
    bodies: &BTreeMap<String, BodyInfo>,
) -> Result<Vec<Joint>, DeckError> {
    let mut out = Vec::new();
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
                    format!("unknown joint kind `{other}`{}", suggestion(other, &kinds)),
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
        out.push(Joint::new(name.clone(), kind, a, b));
    }
    Ok(out)
}

/// The validated force elements.
pub struct ForceDefs {
    /// The sum of the `gravity` elements (m/s²).
    pub gravity: Vector3<f64>,
    /// The other forces by name, in deck order.
    pub forces: Vec<(String, Force)>,
}

/// Validate the force elements. `distance(a, b)` is the initial distance between two markers (a spring's default
/// free length).
pub fn forces(
    src: &Source,
    raw: &RawDeck,
    bodies: &BTreeMap<String, BodyInfo>,
    distance: impl Fn(&Marker, &Marker) -> f64,
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
            "kind (\"gravity\", \"point-force\", \"point-torque\" or \"spring-damper\")",
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
                        return Err(src.error(
                            span(t),
                            Some(k("table")),
                            "give either value or table",
                        ));
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
                            format!("unknown frame `{other}`: expected \"global\" or \"body\""),
                        ));
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
                    bodies,
                )?;
                let b = marker(
                    src,
                    &k("b"),
                    required(src, span(f), &k("b"), &rf.b, "b (a marker)")?,
                    bodies,
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
                    None => distance(&a, &b),
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
                return Err(src.error(
                    span(kind),
                    Some(k("kind")),
                    format!("unknown force kind `{other}`{}", suggestion(other, &c)),
                ));
            }
        };
        out.push((name.clone(), force));
    }
    Ok(ForceDefs {
        gravity,
        forces: out,
    })
}
