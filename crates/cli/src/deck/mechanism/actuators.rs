//! Joint actuators: `kind = "joint-torque"`, a torque about a joint's axis between two bodies,
//! constant, tabulated in time, or a PD law tracking a motion.

use std::collections::BTreeMap;

use mbs::TorqueLaw;
use toml::Spanned;

use super::super::check::{finite, required, span};
use super::super::raw::RawForce;
use super::super::{DeckError, Source};
use super::markers::motion;
use super::{BodyPlace, ForceDef, two_markers};

/// A `joint-torque` element: its two markers (the torque about `a`'s axis, on `b`'s body and
/// reversed on `a`'s) and its law, exactly one of `torque` and `control`.
pub(super) fn joint_torque(
    src: &Source,
    name: &str,
    f: &Spanned<RawForce>,
    bodies: &BTreeMap<String, BodyPlace>,
) -> Result<ForceDef, DeckError> {
    let k = |s: &str| format!("force.{name}.{s}");
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
    let law = match (&rf.torque, &rf.control) {
        (Some(t), None) => torque(src, &k("torque"), t)?,
        (None, Some(c)) => control(src, &k("control"), c)?,
        (Some(_), Some(c)) => {
            return Err(src.error(
                span(c),
                Some(k("control")),
                "give either torque or control, not both",
            ));
        }
        (None, None) => {
            return Err(src.error(
                span(f),
                Some(k("torque")),
                "missing torque: torque (N·m, or { times = [...], values = [...] }) or \
                 control = { kind = \"pd\", kp, kd, motion }",
            ));
        }
    };
    Ok(ForceDef::JointTorque { a, b, law })
}

/// `torque = τ` (N·m) or `torque = { times = [s…], values = [N·m…] }`.
fn torque(src: &Source, key: &str, t: &Spanned<toml::Value>) -> Result<TorqueLaw, DeckError> {
    let bad = |msg: String| src.error(span(t), Some(key.to_string()), msg);
    let number = |v: &toml::Value| v.as_float().or_else(|| v.as_integer().map(|i| i as f64));
    let (times, values) = match t.get_ref() {
        toml::Value::Table(table) => {
            if let Some(other) = table.keys().find(|k| *k != "times" && *k != "values") {
                return Err(bad(format!(
                    "unknown key `{other}` in the torque table (expected times and values)"
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
            (list("times", "s")?, list("values", "N·m")?)
        }
        v => match number(v) {
            Some(x) if x.is_finite() => (vec![0.0], vec![x]),
            _ => {
                return Err(bad(
                    "torque must be a finite number (N·m) or { times = [...], values = [...] }"
                        .into(),
                ));
            }
        },
    };
    if times.is_empty() || times.windows(2).any(|w| w[1] <= w[0]) {
        return Err(bad(
            "the torque table's times must be strictly increasing, at least one".into(),
        ));
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

/// `control = { kind = "pd", kp = N·m/rad, kd = N·m·s/rad, motion = {…} }`.
fn control(
    src: &Source,
    key: &str,
    c: &Spanned<super::super::raw::RawControl>,
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
    let kp = gain("kp", &rc.kp, "N·m/rad")?;
    let kd = gain("kd", &rc.kd, "N·m·s/rad")?;
    let m = motion(
        src,
        &k("motion"),
        required(src, span(c), &k("motion"), &rc.motion, "motion")?,
        true,
    )?;
    Ok(TorqueLaw::Pd { kp, kd, motion: m })
}
