//! `[optimize]`: the problem of `flexsens optimize` — one quantity to minimise or maximise
//! over the `[design.*]` variables within their bounds (`lower`, `upper` in each variable's
//! table), subject to constraints on other quantities.
//!
//! A quantity is named by a string: `"objective.NAME"` (an `[objective.*]` of the run),
//! `"frequency.BODY.K"` (the K-th retained mode of a flexible body, Hz), `"mass.BODY"` (a
//! flexible or rigid body's mass, kg), `"areal_mass.LAMINATE"` (a laminate's mass per unit
//! area, kg/m²), `"operating_frequency.I.K"` (the K-th linearised mode's frequency at the I-th
//! speed of `[operating]`, Hz) or `"order_margin.I.K.N"` (that frequency over the N-th rotor
//! order there, minus one).

use toml::Spanned;

use super::check::suggestion;
use super::check::{finite, required, span};
use super::design::DesignDef;
use super::laminates::LaminateModel;
use super::raw::RawConstraint;
use super::{DeckError, RawDeck, Source};

/// A quantity the optimiser can read with its gradient.
#[derive(Debug, Clone, PartialEq)]
pub enum Quantity {
    /// An `[objective.*]` of the run (its unit).
    Objective { name: String },
    /// The frequency of the `mode`-th (from 0) retained mode of a flexible body (Hz).
    Frequency { body: String, mode: usize },
    /// The mass of a flexible or rigid body (kg).
    Mass { body: String },
    /// The mass per unit area of a laminate (kg/m²).
    ArealMass { laminate: String },
    /// The frequency of the `mode`-th (from 0) linearised mode at the `point`-th (from 0)
    /// operating point of `[operating]` (Hz).
    OperatingFrequency { point: usize, mode: usize },
    /// `f / (N Ω / 2π) − 1` of that mode against the rotor order `N` at that point's speed `Ω`.
    OrderMargin {
        point: usize,
        mode: usize,
        order: u32,
    },
}

impl Quantity {
    /// The name as the deck writes it.
    pub fn label(&self) -> String {
        match self {
            Quantity::Objective { name } => format!("objective.{name}"),
            Quantity::Frequency { body, mode } => format!("frequency.{body}.{}", mode + 1),
            Quantity::Mass { body } => format!("mass.{body}"),
            Quantity::ArealMass { laminate } => format!("areal_mass.{laminate}"),
            Quantity::OperatingFrequency { point, mode } => {
                format!("operating_frequency.{}.{}", point + 1, mode + 1)
            }
            Quantity::OrderMargin { point, mode, order } => {
                format!("order_margin.{}.{}.{order}", point + 1, mode + 1)
            }
        }
    }

    /// Whether it is read at the `[operating]` points.
    pub fn operating(&self) -> bool {
        matches!(
            self,
            Quantity::OperatingFrequency { .. } | Quantity::OrderMargin { .. }
        )
    }
}

/// What a constraint asks of its quantity.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Bound {
    AtLeast(f64),
    AtMost(f64),
    Equals(f64),
    /// Equal to its value at the deck's design.
    EqualsNominal,
}

/// One constraint.
#[derive(Debug, Clone)]
pub struct ConstraintDef {
    pub quantity: Quantity,
    pub bound: Bound,
}

/// The validated problem.
#[derive(Debug, Clone)]
pub struct OptimizeDef {
    pub objective: Quantity,
    /// Maximise instead of minimise.
    pub maximize: bool,
    pub constraints: Vec<ConstraintDef>,
    /// `(lower, upper)` of each design variable (in `DesignDef::variables` order).
    pub bounds: Vec<(f64, f64)>,
    pub max_evaluations: usize,
    pub tolerance: f64,
    /// Converged at a feasible evaluation whose KKT stationarity is at most this.
    pub kkt_tolerance: Option<f64>,
    /// Starting designs; the first is the deck's own.
    pub starts: Vec<Vec<f64>>,
}

/// Parse a quantity name, checking that what it names exists.
fn quantity(
    src: &Source,
    raw: &RawDeck,
    key: &str,
    v: &Spanned<String>,
) -> Result<Quantity, DeckError> {
    let text = v.get_ref();
    let bad = |m: String| src.error(span(v), Some(key.to_string()), m);
    let parts: Vec<&str> = text.split('.').collect();
    match parts.as_slice() {
        ["objective", name] => {
            if !raw.objective.contains_key(*name) {
                let known: Vec<&str> = raw.objective.keys().map(String::as_str).collect();
                return Err(bad(format!(
                    "no [objective.{name}] in the deck{}",
                    suggestion(name, &known)
                )));
            }
            Ok(Quantity::Objective {
                name: name.to_string(),
            })
        }
        ["frequency", body, k] => {
            if !raw.body.contains_key(*body) {
                let known: Vec<&str> = raw.body.keys().map(String::as_str).collect();
                return Err(bad(format!(
                    "no flexible body `{body}`{}",
                    suggestion(body, &known)
                )));
            }
            let mode = k
                .parse::<usize>()
                .ok()
                .filter(|&m| m >= 1)
                .ok_or_else(|| bad(format!("`{k}` is not a mode number (from 1)")))?;
            Ok(Quantity::Frequency {
                body: body.to_string(),
                mode: mode - 1,
            })
        }
        ["mass", body] => {
            if !raw.body.contains_key(*body) && !raw.rigid.contains_key(*body) {
                let known: Vec<&str> = raw
                    .body
                    .keys()
                    .chain(raw.rigid.keys())
                    .map(String::as_str)
                    .collect();
                return Err(bad(format!("no body `{body}`{}", suggestion(body, &known))));
            }
            Ok(Quantity::Mass {
                body: body.to_string(),
            })
        }
        ["areal_mass", laminate] => {
            if !raw.laminate.contains_key(*laminate) {
                let known: Vec<&str> = raw.laminate.keys().map(String::as_str).collect();
                return Err(bad(format!(
                    "no laminate `{laminate}`{}",
                    suggestion(laminate, &known)
                )));
            }
            Ok(Quantity::ArealMass {
                laminate: laminate.to_string(),
            })
        }
        ["operating_frequency", i, k] => {
            let (point, mode, _) = operating_point(src, raw, &bad, i, k)?;
            Ok(Quantity::OperatingFrequency { point, mode })
        }
        ["order_margin", i, k, n] => {
            let (point, mode, speed) = operating_point(src, raw, &bad, i, k)?;
            let order = n
                .parse::<u32>()
                .ok()
                .filter(|&o| o >= 1)
                .ok_or_else(|| bad(format!("`{n}` is not a rotor order (from 1)")))?;
            if speed == 0.0 {
                return Err(bad(format!(
                    "operating point {i} is at rest: a margin to a rotor order needs a speed"
                )));
            }
            Ok(Quantity::OrderMargin { point, mode, order })
        }
        _ => Err(bad(format!(
            "`{text}`: expected \"objective.NAME\", \"frequency.BODY.K\", \"mass.BODY\", \
             \"areal_mass.LAMINATE\", \"operating_frequency.I.K\" or \"order_margin.I.K.N\""
        ))),
    }
}

/// The operating point `i` (from 1, of `[operating]`'s speeds) and mode `k` (from 1) of an
/// operating quantity, from 0, and the point's speed (rad/s).
fn operating_point(
    src: &Source,
    raw: &RawDeck,
    bad: &dyn Fn(String) -> DeckError,
    i: &str,
    k: &str,
) -> Result<(usize, usize, f64), DeckError> {
    let def = super::operating::validate(src, raw)?;
    if !def.at.is_empty() {
        return Err(bad(
            "operating quantities are of equilibria and steady spins: `[operating] at` \
             linearises about states of the run, which have no design derivatives"
                .into(),
        ));
    }
    let n = def.speeds.len();
    let point = i
        .parse::<usize>()
        .ok()
        .filter(|&p| (1..=n).contains(&p))
        .ok_or_else(|| {
            bad(format!(
                "`{i}` is not an operating point: [operating] has {n} speed{} (from 1)",
                if n == 1 { "" } else { "s" }
            ))
        })?;
    let mode = k
        .parse::<usize>()
        .ok()
        .filter(|&m| (1..=def.modes).contains(&m))
        .ok_or_else(|| {
            bad(format!(
                "`{k}` is not a reported mode: [operating] reports modes 1 to {} (modes)",
                def.modes
            ))
        })?;
    Ok((point - 1, mode - 1, def.speeds[point - 1]))
}

fn constraint(
    src: &Source,
    raw: &RawDeck,
    i: usize,
    c: &Spanned<RawConstraint>,
) -> Result<ConstraintDef, DeckError> {
    let k = |s: &str| format!("optimize.constraint[{i}].{s}");
    let rc = c.get_ref();
    let q = required(
        src,
        span(c),
        &k("quantity"),
        &rc.quantity,
        "quantity (e.g. \"frequency.rod.1\")",
    )?;
    let quantity = quantity(src, raw, &k("quantity"), q)?;
    let given = [rc.min.is_some(), rc.max.is_some(), rc.equals.is_some()];
    if given.iter().filter(|&&g| g).count() != 1 {
        return Err(src.error(
            span(c),
            Some(format!("optimize.constraint[{i}]")),
            "give exactly one of min, max and equals",
        ));
    }
    let bound = if let Some(v) = &rc.min {
        Bound::AtLeast(finite(src, &k("min"), v, "the quantity's unit")?)
    } else if let Some(v) = &rc.max {
        Bound::AtMost(finite(src, &k("max"), v, "the quantity's unit")?)
    } else {
        let v = rc.equals.as_ref().expect("one of the three");
        match v.get_ref() {
            toml::Value::String(s) if s == "nominal" => Bound::EqualsNominal,
            toml::Value::Float(x) if x.is_finite() => Bound::Equals(*x),
            toml::Value::Integer(n) => Bound::Equals(*n as f64),
            _ => {
                return Err(src.error(
                    span(v),
                    Some(k("equals")),
                    "expected a finite number or \"nominal\" (the value at the deck's design)",
                ));
            }
        }
    };
    Ok(ConstraintDef { quantity, bound })
}

/// Validate `[optimize]` against the deck's design variables.
pub fn validate(
    src: &Source,
    raw: &RawDeck,
    design: &DesignDef,
    laminates: &LaminateModel,
) -> Result<OptimizeDef, DeckError> {
    let table = raw.optimize.as_ref().ok_or_else(|| {
        src.error(
            None,
            Some("optimize".into()),
            "missing table [optimize] (the quantity to minimise or maximise, constraints)",
        )
    })?;
    let o = table.get_ref();
    let (objective, maximize) = match (&o.minimize, &o.maximize) {
        (Some(q), None) => (quantity(src, raw, "optimize.minimize", q)?, false),
        (None, Some(q)) => (quantity(src, raw, "optimize.maximize", q)?, true),
        _ => {
            return Err(src.error(
                span(table),
                Some("optimize".into()),
                "give exactly one of minimize and maximize",
            ));
        }
    };
    if design.variables.is_empty() {
        return Err(src.error(
            span(table),
            Some("optimize".into()),
            "the deck has no [design.*] variables to optimise",
        ));
    }
    let mut bounds = Vec::new();
    for v in &design.variables {
        let d = raw.design[&v.name].get_ref();
        let k = |s: &str| format!("design.{}.{s}", v.name);
        let get = |key: &str, f: &Option<Spanned<f64>>| -> Result<f64, DeckError> {
            let x = required(
                src,
                span(&raw.design[&v.name]),
                &k(key),
                f,
                &format!("{key} ({}): flexsens optimize needs both bounds", v.unit),
            )?;
            finite(src, &k(key), x, v.unit)
        };
        let (lo, hi) = (get("lower", &d.lower)?, get("upper", &d.upper)?);
        if lo >= hi {
            return Err(src.error(
                d.upper.as_ref().map(|u| u.span()),
                Some(k("upper")),
                format!("upper = {hi} must be above lower = {lo}"),
            ));
        }
        // a bound must be a design the model can take: a positive mass, inertia and thickness,
        // a material that stays physical (between the bounds too: each moves linearly)
        for (key, x) in [("lower", lo), ("upper", hi)] {
            let bad = if v.target.rigid().is_some() {
                (x <= 0.0).then(|| format!("a {} must be positive", v.describe()))
            } else {
                v.apply(&mut laminates.clone(), x)
                    .err()
                    .map(|e| e.to_string())
            };
            if let Some(why) = bad {
                let at = if key == "lower" { &d.lower } else { &d.upper };
                return Err(src.error(
                    at.as_ref().map(|s| s.span()),
                    Some(k(key)),
                    format!(
                        "{key} = {x} {}: the design there is not physical: {why}",
                        v.unit
                    ),
                ));
            }
        }
        if v.value < lo || v.value > hi {
            return Err(src.error(
                span(&raw.design[&v.name]),
                Some(format!("design.{}", v.name)),
                format!(
                    "the deck's value {} {} lies outside [lower, upper] = [{lo}, {hi}]",
                    v.value, v.unit
                ),
            ));
        }
        bounds.push((lo, hi));
    }
    let constraints = o
        .constraint
        .iter()
        .enumerate()
        .map(|(i, c)| constraint(src, raw, i, c))
        .collect::<Result<Vec<_>, _>>()?;
    let max_evaluations = match &o.max_evaluations {
        None => 100,
        Some(n) => super::check::count(src, "optimize.max_evaluations", n, 1)?,
    };
    let tolerance = match &o.tolerance {
        None => 1e-8,
        Some(t) => super::check::positive(src, "optimize.tolerance", t, "1")?,
    };
    let kkt_tolerance = (o.kkt_tolerance.as_ref())
        .map(|t| super::check::positive(src, "optimize.kkt_tolerance", t, "1"))
        .transpose()?;
    let mut starts = vec![design.variables.iter().map(|v| v.value).collect::<Vec<_>>()];
    if let Some(s) = &o.starts {
        for (j, x) in s.get_ref().iter().enumerate() {
            let ok = x.len() == bounds.len()
                && x.iter()
                    .zip(&bounds)
                    .all(|(x, (lo, hi))| x.is_finite() && lo <= x && x <= hi);
            if !ok {
                let names: Vec<&str> = design.variables.iter().map(|v| v.name.as_str()).collect();
                return Err(src.error(
                    span(s),
                    Some(format!("optimize.starts[{j}]")),
                    format!(
                        "{x:?}: a start gives one value per design variable ({}), within its \
                         bounds",
                        names.join(", ")
                    ),
                ));
            }
            starts.push(x.clone());
        }
    }
    Ok(OptimizeDef {
        objective,
        maximize,
        constraints,
        bounds,
        max_evaluations,
        tolerance,
        kkt_tolerance,
        starts,
    })
}
