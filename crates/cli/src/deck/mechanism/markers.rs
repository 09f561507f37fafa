//! Markers (where joints and forces act) and prescribed motions.

use super::*;

/// A marker from its deck description (global point and axes in the initial configuration).
pub(super) fn marker(
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
        let node = coupling_node(src, key, info, body.get_ref(), c)?;
        return Ok(with_axes(Marker::node(info.id, node), &info.rotation));
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

/// The node that stands for coupling `c` of flexible body `body` (`info`): the couplings'
/// nodes follow the mesh's, in the body's order.
fn coupling_node(
    src: &Source,
    key: &str,
    info: &BodyInfo,
    body: &str,
    c: &Spanned<String>,
) -> Result<usize, DeckError> {
    let k = |s: &str| format!("{key}.{s}");
    let nodes = info.nodes.as_ref().map_or(0, Vec::len);
    let index = info.couplings.iter().position(|x| x == c.get_ref());
    match index {
        Some(i) => Ok(nodes - info.couplings.len() + i),
        None => {
            let known: Vec<&str> = info.couplings.iter().map(String::as_str).collect();
            Err(src.error(
                span(c),
                Some(k("coupling")),
                if known.is_empty() {
                    format!(
                        "body `{}` has no couplings (define them in [body.{}.couplings])",
                        body, body
                    )
                } else {
                    format!(
                        "undefined coupling `{}` of body `{}`{}",
                        c.get_ref(),
                        body,
                        suggestion(c.get_ref(), &known)
                    )
                },
            ))
        }
    }
}

pub(super) fn motion(
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
            return Err(src.error(
                span(kind),
                Some(k("kind")),
                crate::deck::keys::MOTION_KIND.unknown("motion", other),
            ));
        }
    })
}
