//! Markers (where joints and forces act) and prescribed motions.

use super::*;

/// A validated marker in the deck's terms (global point and axes at the start), placed on the
/// built bodies by [`MarkerDef::resolve`].
#[derive(Debug, Clone, PartialEq)]
pub struct MarkerDef {
    /// The body's name; `None`: the ground.
    pub body: Option<String>,
    pub site: SiteDef,
    /// The joint axis `e3` (global, unit).
    pub axis: Vector3<f64>,
    /// The reference direction `e1` (global, unit), when given.
    pub reference: Option<Vector3<f64>>,
}

/// Where a validated marker sits.
#[derive(Debug, Clone, PartialEq)]
pub enum SiteDef {
    /// A point, global coordinates at the start.
    Point(Vector3<f64>),
    /// A node of a flexible body (its mesh's, or a coupling's numbered after them).
    Node(usize),
    /// The `i`-th coupling of a flexible body.
    Coupling(usize),
}

impl MarkerDef {
    /// The marker on the built bodies: a point in its body's frame, a node, or a coupling's
    /// node (the couplings' nodes follow the mesh's, in the body's order); the axes in the
    /// body's components.
    pub fn resolve(&self, bodies: &BTreeMap<String, BodyInfo>) -> Marker {
        let with_axes = |mk: Marker, rot: &Matrix3<f64>| {
            let a = rot.transpose() * self.axis;
            match self.reference {
                Some(r) => {
                    let e1 = rot.transpose() * r;
                    mk.with_axes(e1, a.cross(&e1))
                }
                None => mk.with_axis(a),
            }
        };
        let Some(body) = &self.body else {
            let SiteDef::Point(p) = self.site else {
                unreachable!("a ground marker is a point")
            };
            return with_axes(Marker::ground(p), &Matrix3::identity());
        };
        let info = &bodies[body];
        let marker = match self.site {
            SiteDef::Point(p) => {
                Marker::on(info.id, info.rotation.transpose() * (p - info.position))
            }
            SiteDef::Node(k) => Marker::node(info.id, k),
            SiteDef::Coupling(i) => {
                let nodes = info.nodes.as_ref().map_or(0, Vec::len);
                Marker::node(info.id, nodes - info.couplings.len() + i)
            }
        };
        with_axes(marker, &info.rotation)
    }
}

/// A marker from its deck description (global point and axes in the initial configuration).
pub fn marker(
    src: &Source,
    key: &str,
    m: &Spanned<RawMarker>,
    bodies: &BTreeMap<String, BodyPlace>,
) -> Result<MarkerDef, DeckError> {
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
    let def = |body: Option<String>, site: SiteDef| MarkerDef {
        body,
        site,
        axis,
        reference,
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
        return Ok(def(None, SiteDef::Point(p)));
    }
    let place = bodies.get(body.get_ref()).ok_or_else(|| {
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
    let on = |site| Ok(def(Some(body.get_ref().clone()), site));
    if let Some(c) = &raw.coupling {
        if raw.point.is_some() || raw.node.is_some() {
            return Err(src.error(
                span(c),
                Some(k("coupling")),
                "give one of point, node or coupling",
            ));
        }
        return on(SiteDef::Coupling(coupling_index(
            src,
            key,
            place,
            body.get_ref(),
            c,
        )?));
    }
    match (&raw.point, &raw.node) {
        (Some(p), None) => on(SiteDef::Point(vector(src, &k("point"), p)?)),
        (None, Some(n)) => {
            let count = place
                .flexible
                .as_ref()
                .map(|g| g.nodes.len())
                .ok_or_else(|| {
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
            on(SiteDef::Node(node as usize))
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

/// The index of coupling `c` among the couplings of body `body` (`place`).
fn coupling_index(
    src: &Source,
    key: &str,
    place: &BodyPlace,
    body: &str,
    c: &Spanned<String>,
) -> Result<usize, DeckError> {
    let k = |s: &str| format!("{key}.{s}");
    let couplings = place
        .flexible
        .as_ref()
        .map_or(&[][..], |g| &g.couplings[..]);
    match couplings.iter().position(|x| x == c.get_ref()) {
        Some(i) => Ok(i),
        None => {
            let known: Vec<&str> = couplings.iter().map(String::as_str).collect();
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
