//! `[analysis]`: the output times, the integrator's settings, Baumgarte stabilisation and the
//! handling of redundant constraints.

use mbs::{Baumgarte, BdfOptions, RedundancyPolicy, StepControl};

use super::check::{count, finite, positive, required, span};
use super::raw::{RawAnalysis, RawDeck};
use super::{DeckError, Source};

/// The validated analysis settings.
#[derive(Debug, Clone)]
pub struct AnalysisDef {
    /// Output times (s), increasing, the first the start time.
    pub times: Vec<f64>,
    pub options: BdfOptions,
    pub baumgarte: Baumgarte,
    pub policy: RedundancyPolicy,
    /// `analysis.max_violation` (m), when given.
    pub max_violation: Option<f64>,
    /// `analysis.atol`, when given. Until the mechanism is built, the `atol` of `options` is
    /// NaN.
    pub atol: Option<f64>,
    /// `analysis.error_weights = "displacement"`: `atol` is a displacement (m), turned into a
    /// tolerance per coordinate ([`mbs::absolute_tolerances`]); otherwise it applies to every
    /// state component as it is.
    pub displacement_weights: bool,
}

/// Validate `[analysis]`.
pub fn validate(src: &Source, raw: &RawDeck) -> Result<AnalysisDef, DeckError> {
    let a = raw.analysis.as_ref();
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
    if (t_end - t0).is_infinite() {
        return Err(src.error(
            span(t_end_v),
            Some(k("t_end")),
            format!("the span t_end − t_start = {t_end:e} − ({t0:e}) s overflows"),
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
        .map(|r| positive(src, &k("atol"), r, "m, or state units"))
        .transpose()?;
    let displacement_weights = match raw.error_weights.as_ref() {
        None => true,
        Some(w) => match w.get_ref().as_str() {
            "uniform" => false,
            "displacement" => true,
            other => {
                return Err(src.error(
                    span(w),
                    Some(k("error_weights")),
                    super::keys::ERROR_WEIGHTS.unknown("error_weights", other),
                ));
            }
        },
    };
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
    let options = integrator(src, raw, span(a), (t0, t_end), rtol, f64::NAN, order)?;
    let baumgarte = baumgarte(src, raw)?;
    let policy = policy(src, raw)?;
    let max_violation = raw
        .max_violation
        .as_ref()
        .map(|v| positive(src, &k("max_violation"), v, "m"))
        .transpose()?;
    Ok(AnalysisDef {
        times,
        options,
        baumgarte,
        policy,
        max_violation,
        atol,
        displacement_weights,
    })
}

/// The integrator's options: adaptive (tolerances, steps, order) or fixed steps over the span
/// `(t0, t_end)` (`table`: the `[analysis]` table, where a missing step points).
fn integrator(
    src: &Source,
    raw: &RawAnalysis,
    table: Option<std::ops::Range<usize>>,
    (t0, t_end): (f64, f64),
    rtol: f64,
    atol: f64,
    order: Option<usize>,
) -> Result<BdfOptions, DeckError> {
    let k = |s: &str| format!("analysis.{s}");
    Ok(
        match raw.integrator.as_ref().map(|i| (i, i.get_ref().as_str())) {
            None | Some((_, "adaptive")) => {
                if let Some(s) = &raw.step {
                    return Err(src.error(
                        span(s),
                        Some(k("step")),
                        "step is for integrator = \"fixed\"",
                    ));
                }
                let max_step_v = raw
                    .max_step
                    .as_ref()
                    .map(|h| positive(src, &k("max_step"), h, "s"))
                    .transpose()?;
                let initial = raw
                    .initial_step
                    .as_ref()
                    .map(|h| positive(src, &k("initial_step"), h, "s"))
                    .transpose()?;
                if let (Some(h0), Some(hm), Some(v)) = (initial, max_step_v, &raw.initial_step)
                    && h0 > hm
                {
                    return Err(src.error(
                        span(v),
                        Some(k("initial_step")),
                        format!("initial_step = {h0} s is larger than max_step = {hm} s"),
                    ));
                }
                let mut o = BdfOptions::adaptive(rtol, atol);
                o.max_steps = crate::limits::get().steps;
                if let StepControl::Adaptive {
                    max_order,
                    max_step,
                    initial_step,
                    stability_limit,
                    ..
                } = &mut o.control
                {
                    *max_order = order.unwrap_or(5);
                    *max_step = max_step_v.unwrap_or(f64::INFINITY);
                    *initial_step = initial;
                    *stability_limit = raw.stability_limit.as_ref().is_none_or(|b| *b.get_ref());
                }
                o
            }
            Some((_, "fixed")) => {
                for (key, v) in [
                    ("max_step", raw.max_step.as_ref().map(|v| v.span())),
                    ("initial_step", raw.initial_step.as_ref().map(|v| v.span())),
                    (
                        "stability_limit",
                        raw.stability_limit.as_ref().map(|v| v.span()),
                    ),
                ] {
                    if let Some(sp) = v {
                        return Err(src.error(
                            Some(sp),
                            Some(k(key)),
                            format!("{key} is for integrator = \"adaptive\""),
                        ));
                    }
                }
                let h = positive(
                    src,
                    &k("step"),
                    required(
                        src,
                        table,
                        &k("step"),
                        &raw.step,
                        "step (s) for a fixed-step run",
                    )?,
                    "s",
                )?;
                let max_steps = crate::limits::get().steps;
                let steps = ((t_end - t0) / h).ceil();
                if steps > max_steps as f64 {
                    return Err(src.error(
                        raw.step.as_ref().map(|s| s.span()),
                        Some(k("step")),
                        format!(
                            "step = {h} s takes {steps:.3e} steps over the span of {} s, more than \
                         the limit of {max_steps} (--max-steps raises it)",
                            t_end - t0
                        ),
                    ));
                }
                let mut o = BdfOptions::fixed(h, order.unwrap_or(2));
                o.rtol = rtol.min(1e-10);
                // the deck's tolerances: each step's local error is estimated against them
                o.accuracy = Some((rtol, vec![atol]));
                o.max_steps = max_steps;
                o
            }
            Some((i, other)) => {
                return Err(src.error(
                    span(i),
                    Some(k("integrator")),
                    super::keys::INTEGRATOR.unknown("integrator", other),
                ));
            }
        },
    )
}

/// Baumgarte stabilisation: `{ alpha, beta }` (1/s, 1 when left out) or `false`.
fn baumgarte(src: &Source, raw: &RawAnalysis) -> Result<Baumgarte, DeckError> {
    let k = |s: &str| format!("analysis.{s}");
    Ok(match raw.baumgarte.as_ref().map(|b| (b, b.get_ref())) {
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
    })
}

/// What to do with redundant constraint equations.
fn policy(src: &Source, raw: &RawAnalysis) -> Result<RedundancyPolicy, DeckError> {
    let k = |s: &str| format!("analysis.{s}");
    Ok(
        match raw.redundant.as_ref().map(|r| (r, r.get_ref().as_str())) {
            None | Some((_, "remove")) => RedundancyPolicy::Remove,
            Some((_, "error")) => RedundancyPolicy::Error,
            Some((_, "reselect")) => RedundancyPolicy::Reselect,
            Some((r, other)) => {
                return Err(src.error(
                    span(r),
                    Some(k("redundant")),
                    super::keys::REDUNDANT.unknown("policy", other),
                ));
            }
        },
    )
}
