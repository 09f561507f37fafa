//! An actuator's gain as a design variable (`kind = "actuator-gain"`): `kp` or `kd` of a
//! joint torque's or joint force's PD law.

use super::*;

/// An `actuator-gain` variable: `force` (a `[force.NAME]` of kind `"joint-torque"` or
/// `"joint-force"` with `control = { kind = "pd", … }`) and `gain` (`"kp"` or `"kd"`), its
/// nominal value the deck's gain.
pub(super) fn actuator_variable(
    src: &Source,
    raw: &RawDeck,
    name: &str,
    d: &Spanned<RawDesign>,
) -> Result<DesignVariable, DeckError> {
    let k = |s: &str| format!("design.{name}.{s}");
    let rd = d.get_ref();
    let force = required(
        src,
        span(d),
        &k("force"),
        &rd.force,
        "force (an actuator's [force.NAME])",
    )?;
    let fname = force.get_ref();
    let Some(raw_force) = raw.force.get(fname) else {
        let known: Vec<&str> = raw.force.keys().map(String::as_str).collect();
        return Err(src.error(
            span(force),
            Some(k("force")),
            format!("undefined force `{fname}`{}", suggestion(fname, &known)),
        ));
    };
    let rf = raw_force.get_ref();
    let kind = rf.kind.as_ref().map(|k| k.get_ref().as_str());
    let linear = match kind {
        Some("joint-torque") => false,
        Some("joint-force") => true,
        _ => {
            return Err(src.error(
                span(force),
                Some(k("force")),
                format!(
                    "force `{fname}` is no actuator: a gain is a design variable of a \
                     [force.NAME] of kind \"joint-torque\" or \"joint-force\""
                ),
            ));
        }
    };
    let gain = required(
        src,
        span(d),
        &k("gain"),
        &rd.gain,
        "gain (\"kp\" or \"kd\")",
    )?;
    let which = super::super::keys::ACTUATOR_GAIN
        .words
        .iter()
        .position(|w| w == gain.get_ref())
        .ok_or_else(|| {
            src.error(
                span(gain),
                Some(k("gain")),
                super::super::keys::ACTUATOR_GAIN.unknown("gain", gain.get_ref()),
            )
        })?;
    let control = rf.control.as_ref().map(|c| c.get_ref());
    let value = control
        .and_then(|c| {
            if which == 0 {
                c.kp.as_ref()
            } else {
                c.kd.as_ref()
            }
        })
        .map(|v| *v.get_ref());
    let Some(value) = value else {
        return Err(src.error(
            span(force),
            Some(k("force")),
            format!(
                "actuator `{fname}` has no {}: a gain is a design variable of a PD law \
                 (control = {{ kind = \"pd\", kp, kd, motion }})",
                gain.get_ref()
            ),
        ));
    };
    let unit = match (linear, which) {
        (false, 0) => "N*m/rad",
        (false, _) => "N*m*s/rad",
        (true, 0) => "N/m",
        (true, _) => "N*s/m",
    };
    Ok(DesignVariable {
        name: name.to_string(),
        target: Target::ActuatorGain {
            force: fname.clone(),
            gain: which,
        },
        value,
        unit,
    })
}
