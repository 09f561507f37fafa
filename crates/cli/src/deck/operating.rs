//! `[operating]`: the operating points of `flexsens static` — a static equilibrium, or steady
//! spins about an angle driver's axis at a list of speeds — the drivers' time, how many
//! linearised modes are reported, and the rotor orders of the Campbell diagram.

use super::check::{count, finite, span, suggestion};
use super::mechanism::angular_rate;
use super::{DeckError, RawDeck, Source};

/// The validated `[operating]` table (defaults where it is absent).
#[derive(Clone, Debug, PartialEq)]
pub struct OperatingDef {
    /// The angle driver of the spin, with the span of its name.
    pub driver: Option<(String, Option<std::ops::Range<usize>>)>,
    /// Spin speeds (rad/s), increasing; `[0]` for a static equilibrium.
    pub speeds: Vec<f64>,
    /// The drivers' time (s); `None`: the analysis's start.
    pub time: Option<f64>,
    /// Times of the run (s), increasing, with their spans: the operating points are the run's
    /// states there instead of equilibria (then `speeds` is `[0]` and `driver`, `time` none).
    pub at: Vec<RunTime>,
    /// Linearised modes reported.
    pub modes: usize,
    /// Rotor orders of the Campbell diagram.
    pub orders: Vec<u32>,
}

/// Modes reported by default.
pub const DEFAULT_MODES: usize = 10;
/// Rotor orders drawn by default.
pub const DEFAULT_ORDERS: [u32; 4] = [1, 2, 3, 4];

/// Validate `[operating]`.
pub fn validate(src: &Source, raw: &RawDeck) -> Result<OperatingDef, DeckError> {
    let Some(table) = &raw.operating else {
        return Ok(OperatingDef {
            driver: None,
            speeds: vec![0.0],
            time: None,
            at: Vec::new(),
            modes: DEFAULT_MODES,
            orders: DEFAULT_ORDERS.to_vec(),
        });
    };
    let o = table.get_ref();
    let driver = match &o.driver {
        Some(d) => {
            let name = d.get_ref();
            let Some(joint) = raw.joint.get(name) else {
                let known: Vec<&str> = raw.joint.keys().map(String::as_str).collect();
                return Err(src.error(
                    span(d),
                    Some("operating.driver".into()),
                    format!("no joint `{name}`{}", suggestion(name, &known)),
                ));
            };
            let kind = joint.get_ref().kind.as_ref().map(|k| k.get_ref().as_str());
            if kind != Some("angle-driver") {
                return Err(src.error(
                    span(d),
                    Some("operating.driver".into()),
                    format!(
                        "joint `{name}` is a {} joint, not an angle driver: the mechanism spins \
                         about an angle driver's axis",
                        kind.unwrap_or("(kindless)")
                    ),
                ));
            }
            Some((name.clone(), span(d)))
        }
        None => None,
    };
    let speeds = match &o.speeds {
        Some(list) => {
            if list.get_ref().is_empty() {
                return Err(src.error(
                    span(list),
                    Some("operating.speeds".into()),
                    "the list of speeds is empty",
                ));
            }
            let mut speeds = Vec::new();
            for (i, v) in list.get_ref().iter().enumerate() {
                let key = format!("operating.speeds.{i}");
                let w = angular_rate(src, &key, v)?;
                if let Some(&last) = speeds.last()
                    && w <= last
                {
                    return Err(src.error(
                        span(v),
                        Some(key),
                        "the speeds must increase from one to the next (the sweep follows its \
                         operating points)",
                    ));
                }
                if w != 0.0 && driver.is_none() {
                    return Err(src.error(
                        span(v),
                        Some(key),
                        "a speed other than zero needs `operating.driver`, the angle driver \
                         whose axis the mechanism spins about",
                    ));
                }
                speeds.push(w);
            }
            speeds
        }
        None => vec![0.0],
    };
    let time = match &o.time {
        Some(t) => Some(finite(src, "operating.time", t, "s")?),
        None => None,
    };
    let at = run_times(src, o)?;
    let modes = match &o.modes {
        Some(m) => count(src, "operating.modes", m, 1)?,
        None => DEFAULT_MODES,
    };
    let orders = match &o.orders {
        Some(list) => list
            .get_ref()
            .iter()
            .enumerate()
            .map(|(i, k)| {
                let key = format!("operating.orders.{i}");
                count(src, &key, k, 1).and_then(|n| {
                    u32::try_from(n).map_err(|_| src.error(span(k), Some(key), "too large"))
                })
            })
            .collect::<Result<Vec<_>, _>>()?,
        None => DEFAULT_ORDERS.to_vec(),
    };
    Ok(OperatingDef {
        driver,
        speeds,
        time,
        at,
        modes,
        orders,
    })
}

/// A time of `operating.at` with its span in the deck.
pub type RunTime = (f64, Option<std::ops::Range<usize>>);

/// `operating.at`: finite, increasing times, alone of the keys that choose the operating
/// points.
fn run_times(src: &Source, o: &super::raw::RawOperating) -> Result<Vec<RunTime>, DeckError> {
    let Some(list) = &o.at else {
        return Ok(Vec::new());
    };
    if list.get_ref().is_empty() {
        return Err(src.error(
            span(list),
            Some("operating.at".into()),
            "the list of times is empty",
        ));
    }
    let others = [
        ("driver", o.driver.is_some()),
        ("speeds", o.speeds.is_some()),
        ("time", o.time.is_some()),
    ];
    if let Some((key, _)) = others.iter().find(|(_, given)| *given) {
        return Err(src.error(
            span(list),
            Some("operating.at".into()),
            format!(
                "`at` linearises about the run's states at these times, so `{key}` (of an \
                 equilibrium or a steady spin) cannot be given with it"
            ),
        ));
    }
    let mut at: Vec<RunTime> = Vec::new();
    for (i, t) in list.get_ref().iter().enumerate() {
        let key = format!("operating.at.{i}");
        let x = finite(src, &key, t, "s")?;
        if at.last().is_some_and(|&(last, _)| x <= last) {
            return Err(src.error(
                span(t),
                Some(key),
                "the times must increase from one to the next",
            ));
        }
        at.push((x, span(t)));
    }
    Ok(at)
}

/// `operating.at` within the analysis's span `times` (its output times).
pub fn check_times(src: &Source, def: &OperatingDef, times: &[f64]) -> Result<(), DeckError> {
    let (t0, t1) = (times[0], times[times.len() - 1]);
    for (i, (t, span)) in def.at.iter().enumerate() {
        if *t < t0 || *t > t1 {
            return Err(src.error(
                span.clone(),
                Some(format!("operating.at.{i}")),
                format!("{t} s is outside the analysis's span, {t0} to {t1} s"),
            ));
        }
    }
    Ok(())
}
