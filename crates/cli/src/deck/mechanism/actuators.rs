//! Joint actuators: `kind = "joint-torque"`, a torque about a joint's axis between two bodies,
//! and `kind = "joint-force"`, a force along it; constant, tabulated in time, or a PD law
//! tracking a motion.

use std::collections::BTreeMap;

use mbs::TorqueLaw;
use toml::Spanned;

use super::super::check::{finite, required, span};
use super::super::raw::RawForce;
use super::super::{DeckError, Source};
use super::markers::motion;
use super::{BodyPlace, ForceDef, two_markers};

/// The units and words of an actuator: a torque about `a`'s axis, or (`linear`) a force along
/// it.
struct Effort {
    /// The key of its constant or table, `torque` or `force`.
    key: &'static str,
    unit: &'static str,
    kp: &'static str,
    kd: &'static str,
}

const TORQUE: Effort = Effort {
    key: "torque",
    unit: "N·m",
    kp: "N·m/rad",
    kd: "N·m·s/rad",
};

const FORCE: Effort = Effort {
    key: "force",
    unit: "N",
    kp: "N/m",
    kd: "N·s/m",
};

/// A `joint-torque` element (`linear`: a `joint-force` one): its two markers (the torque
/// about, or the force along, `a`'s axis, on `b`'s body and reversed on `a`'s) and its law,
/// exactly one of `torque` (`force`) and `control`.
pub(super) fn joint_actuator(
    src: &Source,
    name: &str,
    f: &Spanned<RawForce>,
    bodies: &BTreeMap<String, BodyPlace>,
    linear: bool,
) -> Result<ForceDef, DeckError> {
    let k = |s: &str| format!("force.{name}.{s}");
    let effort = if linear { &FORCE } else { &TORQUE };
    let rf = f.get_ref();
    let (a, b) = two_markers(src, name, f, bodies)?;
    if a.body == b.body {
        return Err(src.error(
            rf.b.as_ref().map(|b| b.span()),
            Some(k("b")),
            format!(
                "an actuator acts between two bodies: `a` and `b` are both on {}",
                a.body
                    .as_deref()
                    .map_or("the ground".to_string(), |n| format!("`{n}`"))
            ),
        ));
    }
    // the other kind's key
    let (given, other) = if linear {
        (&rf.force, rf.torque.as_ref().map(|t| ("torque", t.span())))
    } else {
        (&rf.torque, rf.force.as_ref().map(|t| ("force", t.span())))
    };
    if let Some((key, at)) = other {
        return Err(src.error(
            Some(at),
            Some(k(key)),
            format!(
                "a {} takes `{}`, not `{key}`",
                if linear {
                    "joint-force"
                } else {
                    "joint-torque"
                },
                effort.key
            ),
        ));
    }
    let law = match (given, &rf.control) {
        (Some(t), None) => table(src, &k(effort.key), t, effort)?,
        (None, Some(c)) => control(src, &k("control"), c, effort, linear)?,
        (Some(_), Some(c)) => {
            return Err(src.error(
                span(c),
                Some(k("control")),
                format!("give either {} or control, not both", effort.key),
            ));
        }
        (None, None) => {
            return Err(src.error(
                span(f),
                Some(k(effort.key)),
                format!(
                    "missing {key}: {key} ({unit}, or {{ times = [...], values = [...] }}) or \
                     control = {{ kind = \"pd\", kp, kd, motion }}",
                    key = effort.key,
                    unit = effort.unit
                ),
            ));
        }
    };
    Ok(if linear {
        ForceDef::JointForce { a, b, law }
    } else {
        ForceDef::JointTorque { a, b, law }
    })
}

/// `torque = τ` (N·m) or `torque = { times = [s…], values = [N·m…] }` (a force's in N).
fn table(
    src: &Source,
    key: &str,
    t: &Spanned<toml::Value>,
    effort: &Effort,
) -> Result<TorqueLaw, DeckError> {
    let bad = |msg: String| src.error(span(t), Some(key.to_string()), msg);
    let number = |v: &toml::Value| v.as_float().or_else(|| v.as_integer().map(|i| i as f64));
    let (times, values) = match t.get_ref() {
        toml::Value::Table(table) => {
            if let Some(other) = table.keys().find(|k| *k != "times" && *k != "values") {
                return Err(bad(format!(
                    "unknown key `{other}` in the {} table (expected times and values)",
                    effort.key
                )));
            }
            let list = |name: &str, unit: &str| -> Result<Vec<f64>, DeckError> {
                let arr = table
                    .get(name)
                    .and_then(|v| v.as_array())
                    .ok_or_else(|| bad(format!("missing {name} = [...] ({unit})")))?;
                arr.iter()
                    .map(|v| {
                        number(v)
                            .filter(|x| x.is_finite())
                            .ok_or_else(|| bad(format!("{name} must be finite numbers ({unit})")))
                    })
                    .collect()
            };
            (list("times", "s")?, list("values", effort.unit)?)
        }
        v => match number(v) {
            Some(x) if x.is_finite() => (vec![0.0], vec![x]),
            _ => {
                return Err(bad(format!(
                    "{} must be a finite number ({}) or {{ times = [...], values = [...] }}",
                    effort.key, effort.unit
                )));
            }
        },
    };
    if times.is_empty() || times.windows(2).any(|w| w[1] <= w[0]) {
        return Err(bad(format!(
            "the {} table's times must be strictly increasing, at least one",
            effort.key
        )));
    }
    if values.len() != times.len() {
        return Err(bad(format!(
            "{} values for {} times",
            values.len(),
            times.len()
        )));
    }
    Ok(TorqueLaw::Table { times, values })
}

/// `control = { kind = "pd", kp = N·m/rad, kd = N·m·s/rad, motion = {…} }` (a force's: N/m,
/// N·s/m, a distance driver's motion).
fn control(
    src: &Source,
    key: &str,
    c: &Spanned<super::super::raw::RawControl>,
    effort: &Effort,
    linear: bool,
) -> Result<TorqueLaw, DeckError> {
    let k = |s: &str| format!("{key}.{s}");
    let rc = c.get_ref();
    let kind = required(src, span(c), &k("kind"), &rc.kind, "kind (\"pd\")")?;
    if kind.get_ref() != "pd" {
        return Err(src.error(
            span(kind),
            Some(k("kind")),
            super::super::keys::CONTROL_KIND.unknown("control", kind.get_ref()),
        ));
    }
    let gain = |name: &str, v: &Option<Spanned<f64>>, unit: &str| -> Result<f64, DeckError> {
        let g = required(src, span(c), &k(name), v, &format!("{name} ({unit})"))?;
        let x = finite(src, &k(name), g, unit)?;
        if x < 0.0 {
            return Err(src.error(
                span(g),
                Some(k(name)),
                format!("{x} must not be negative ({unit})"),
            ));
        }
        Ok(x)
    };
    let kp = gain("kp", &rc.kp, effort.kp)?;
    let kd = gain("kd", &rc.kd, effort.kd)?;
    let m = motion(
        src,
        &k("motion"),
        required(src, span(c), &k("motion"), &rc.motion, "motion")?,
        !linear,
    )?;
    Ok(TorqueLaw::Pd { kp, kd, motion: m })
}
