//! `[objective.*]` and `[finite_differences]`: what the run reports with gradients, and the
//! finite differences it compares them with.

use super::*;

/// How an objective is written in tables and summaries.
pub fn objective_label(o: &Objective, window: Option<(f64, f64)>) -> String {
    let kind = match o {
        Objective::Integral => "integral".into(),
        Objective::Mean => "mean".into(),
        Objective::Rms => "rms".into(),
        Objective::Max => "max".into(),
        Objective::Min => "min".into(),
        Objective::Final => "final".into(),
        Objective::Ks(rho) => format!("ks (rho = {rho})"),
        Objective::At(t) => format!("at {t} s"),
    };
    match window {
        Some((a, b)) => format!("{kind} in [{a}, {b}] s"),
        None => kind,
    }
}

/// A validated objective.
#[derive(Debug, Clone, PartialEq)]
pub struct ObjectiveDef {
    pub name: String,
    pub response: String,
    pub kind: Objective,
    /// The times `[t0, t1]` (s) of the history it is taken over (the whole run when none).
    pub window: Option<(f64, f64)>,
}

/// Where the perturbed runs of a finite-difference comparison take their steps.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FdSteps {
    Replay,
    Adaptive,
}

/// A validated finite-difference request.
#[derive(Debug, Clone, PartialEq)]
pub struct FdDef {
    pub central: bool,
    pub relative: bool,
    pub sizes: Vec<f64>,
    pub steps: Vec<FdSteps>,
}

/// How the sensitivities are integrated (`[sensitivity] method`, see `mbs::SensitivityMethod`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SensitivityScheme {
    /// Staggered direct: the exact derivative of the discrete solution.
    Direct,
    /// Staggered corrector with the integrator's Newton matrix.
    Corrector,
    /// Simultaneous corrector inside the state's Newton iteration (the cheapest; the default).
    Simultaneous,
    /// The discrete adjoint (`mbs::adjoint_gradient`): the objectives' gradients only, each by
    /// one backward sweep whatever the number of variables; no response sensitivities.
    Adjoint,
}

impl SensitivityScheme {
    /// The method a deck's `sensitivity.method` names (`"simultaneous"` when it names none),
    /// for its numbers of design variables and objectives (`"auto"`: [`Self::cheaper`]).
    pub fn of_deck(name: Option<&str>, variables: usize, objectives: usize) -> Self {
        match name {
            Some("corrector") => Self::Corrector,
            Some("direct") => Self::Direct,
            Some("adjoint") => Self::Adjoint,
            Some("auto") => Self::cheaper(variables, objectives),
            _ => Self::Simultaneous,
        }
    }

    /// The adjoint method where it gives the objectives' gradients for less than the default
    /// (simultaneous) method gives every response's sensitivities, else the simultaneous one:
    /// measured on the paper's beam deck and the tailored rod (docs/performance.md), the
    /// simultaneous method costs about 0.3 analyses per variable, the adjoint about 5 per
    /// objective whatever the number of variables, plus its set-up (the run computes every
    /// objective of the deck). A deck without objectives keeps the simultaneous method.
    pub fn cheaper(variables: usize, objectives: usize) -> Self {
        if objectives > 0
            && ADJOINT_ANALYSES * (objectives as f64) < DIRECT_ANALYSES * (variables as f64)
        {
            Self::Adjoint
        } else {
            Self::Simultaneous
        }
    }

    /// The deck's name of the method.
    pub fn name(self) -> &'static str {
        match self {
            Self::Direct => "direct",
            Self::Corrector => "corrector",
            Self::Simultaneous => "simultaneous",
            Self::Adjoint => "adjoint",
        }
    }
}

/// `sensitivity.adjoint_memory` in bytes: 16 MiB unless set (a positive number of MiB).
pub(super) fn adjoint_memory(
    src: &Source,
    s: Option<&crate::deck::raw::RawSensitivity>,
) -> Result<usize, DeckError> {
    let mib = match s.and_then(|s| s.adjoint_memory.as_ref()) {
        None => 16.0,
        Some(m) => crate::deck::check::positive(src, "sensitivity.adjoint_memory", m, "MiB")?,
    };
    Ok((mib * 1024.0 * 1024.0).min(usize::MAX as f64) as usize)
}

/// The adjoint method's cost per objective, in analyses ([`SensitivityScheme::cheaper`]).
const ADJOINT_ANALYSES: f64 = 5.0;
/// The simultaneous direct method's cost per variable, in analyses.
const DIRECT_ANALYSES: f64 = 0.3;

pub(super) fn objective(
    src: &Source,
    raw: &RawDeck,
    name: &str,
    o: &Spanned<RawObjective>,
) -> Result<ObjectiveDef, DeckError> {
    let k = |s: &str| format!("objective.{name}.{s}");
    let ro = o.get_ref();
    let resp = ro.response.as_ref().ok_or_else(|| {
        src.error(
            span(o),
            Some(k("response")),
            "missing value: response (a [response.*] name)",
        )
    })?;
    if !raw.response.contains_key(resp.get_ref()) {
        let known: Vec<&str> = raw.response.keys().map(String::as_str).collect();
        return Err(src.error(
            span(resp),
            Some(k("response")),
            format!(
                "undefined response `{}`{}",
                resp.get_ref(),
                suggestion(resp.get_ref(), &known)
            ),
        ));
    }
    let kinds = crate::deck::keys::OBJECTIVE_KIND.words;
    let kind_v = ro.kind.as_ref().ok_or_else(|| {
        src.error(
            span(o),
            Some(k("kind")),
            format!(
                "missing value: kind ({})",
                crate::deck::keys::OBJECTIVE_KIND.listed()
            ),
        )
    })?;
    let kind = match choice(src, &k("kind"), Some(kind_v), kinds)?.unwrap_or_default() {
        "integral" => Objective::Integral,
        "mean" => Objective::Mean,
        "rms" => Objective::Rms,
        "max" => Objective::Max,
        "min" => Objective::Min,
        "final" => Objective::Final,
        "ks" => {
            let rho = ro.rho.as_ref().ok_or_else(|| {
                src.error(
                    span(o),
                    Some(k("rho")),
                    "missing value: rho, the aggregation parameter (in the inverse of the \
                     response's unit) for kind = \"ks\"",
                )
            })?;
            let x = finite(src, &k("rho"), rho, "1/unit")?;
            if x <= 0.0 {
                return Err(src.error(
                    span(rho),
                    Some(k("rho")),
                    format!("rho = {x} must be positive"),
                ));
            }
            Objective::Ks(x)
        }
        _ => {
            let t = ro.time.as_ref().ok_or_else(|| {
                src.error(
                    span(o),
                    Some(k("time")),
                    "missing value: time (s) for kind = \"at\"",
                )
            })?;
            Objective::At(finite(src, &k("time"), t, "s")?)
        }
    };
    if !matches!(kind, Objective::Ks(_))
        && let Some(r) = &ro.rho
    {
        return Err(src.error(
            span(r),
            Some(k("rho")),
            "rho is only used with kind = \"ks\"",
        ));
    }
    if !matches!(kind, Objective::At(_))
        && let Some(t) = &ro.time
    {
        return Err(src.error(
            span(t),
            Some(k("time")),
            "time is only used with kind = \"at\"",
        ));
    }
    let window = match &ro.window {
        Some(w) => Some(window(src, &k("window"), w, &kind)?),
        None => None,
    };
    Ok(ObjectiveDef {
        name: name.to_string(),
        response: resp.get_ref().clone(),
        kind,
        window,
    })
}

/// `window = [t0, t1]`: two finite, increasing times, not with `kind = "at"`.
fn window(
    src: &Source,
    key: &str,
    w: &Spanned<Vec<Spanned<f64>>>,
    kind: &Objective,
) -> Result<(f64, f64), DeckError> {
    if matches!(kind, Objective::At(_)) {
        return Err(src.error(
            span(w),
            Some(key.to_string()),
            "a window is for the kinds over time; kind = \"at\" takes its one time",
        ));
    }
    let [a, b] = w.get_ref().as_slice() else {
        return Err(src.error(
            span(w),
            Some(key.to_string()),
            format!("expected [t0, t1] (s), found {} values", w.get_ref().len()),
        ));
    };
    let (a, b) = (finite(src, key, a, "s")?, finite(src, key, b, "s")?);
    if a >= b {
        return Err(src.error(
            span(w),
            Some(key.to_string()),
            format!("the window [{a}, {b}] s must end after it starts"),
        ));
    }
    Ok((a, b))
}

pub(super) fn finite_differences(
    src: &Source,
    r: &Spanned<RawFiniteDifferences>,
) -> Result<FdDef, DeckError> {
    let k = |s: &str| format!("finite_differences.{s}");
    let rf = r.get_ref();
    let central = choice(
        src,
        &k("scheme"),
        rf.scheme.as_ref(),
        crate::deck::keys::FD_SCHEME.words,
    )? == Some("central");
    let relative = choice(
        src,
        &k("perturbation"),
        rf.perturbation.as_ref(),
        crate::deck::keys::FD_PERTURBATION.words,
    )? != Some("absolute");
    let sizes = match &rf.sizes {
        None => vec![if relative { 0.01 } else { 0.1 }],
        Some(s) => {
            if s.get_ref().is_empty() {
                return Err(src.error(span(s), Some(k("sizes")), "no sizes given"));
            }
            for (i, x) in s.get_ref().iter().enumerate() {
                positive(
                    src,
                    &format!("{}[{i}]", k("sizes")),
                    &Spanned::new(s.span(), *x),
                    if relative { "1" } else { "degrees" },
                )?;
            }
            s.get_ref().clone()
        }
    };
    let steps = match choice(
        src,
        &k("steps"),
        rf.steps.as_ref(),
        crate::deck::keys::FD_STEPS.words,
    )? {
        None | Some("replay") => vec![FdSteps::Replay],
        Some("adaptive") => vec![FdSteps::Adaptive],
        _ => vec![FdSteps::Replay, FdSteps::Adaptive],
    };
    Ok(FdDef {
        central,
        relative,
        sizes,
        steps,
    })
}
