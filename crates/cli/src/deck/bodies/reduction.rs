//! A body's modal reduction settings: its retained modes, reference condition and damping.

use super::*;

/// A body's retained modes: their number, the number of lowest modes computed, the retained
/// ones when the deck lists mode numbers (zero-based), and whether `modes = "auto"`.
#[allow(clippy::type_complexity)]
pub(super) fn modes(
    src: &Source,
    name: &str,
    raw: &RawBody,
    table: Option<std::ops::Range<usize>>,
) -> Result<(usize, usize, Option<Vec<usize>>, bool), DeckError> {
    let k = |key: &str| format!("body.{name}.{key}");
    let modes_value = required(
        src,
        table.clone(),
        &k("modes"),
        &raw.modes,
        "modes (number of elastic modes retained, or a list of mode numbers)",
    )?;
    let modes_error = |m: String| src.error(span(modes_value), Some(k("modes")), m);
    let auto_modes = modes_value.get_ref().as_str() == Some("auto");
    let (modes, computed, kept) = match modes_value.get_ref() {
        v @ toml::Value::Integer(n) => match element_count(v, 1) {
            Some(n) => (n, n, None),
            None => {
                return Err(modes_error(format!(
                    "{n} must be a whole number of at least 1"
                )));
            }
        },
        toml::Value::String(w) if w == "auto" => (AUTO_MODES[0], AUTO_MODES[0], None),
        toml::Value::Array(list) => {
            let numbers: Option<Vec<usize>> = list.iter().map(|v| element_count(v, 1)).collect();
            match numbers {
                Some(n) if !n.is_empty() && n.windows(2).all(|w| w[1] > w[0]) => {
                    let last = *n.last().expect("non-empty");
                    (n.len(), last, Some(n.iter().map(|i| i - 1).collect()))
                }
                _ => {
                    return Err(modes_error(
                        "a list of mode numbers needs whole numbers from 1, strictly ascending, \
                         e.g. [1, 2, 5]"
                            .into(),
                    ));
                }
            }
        }
        _ => {
            return Err(modes_error(
                "expected a number of modes (e.g. 4), a list of mode numbers (e.g. [1, 2, 5]) \
                 or \"auto\""
                    .into(),
            ));
        }
    };
    Ok((modes, computed, kept, auto_modes))
}

/// A body's reference condition (and `pinned` or `clamped`, given only with theirs).
pub(super) fn reference(src: &Source, name: &str, raw: &RawBody) -> Result<Reference, DeckError> {
    let k = |key: &str| format!("body.{name}.{key}");
    let reference = match raw.reference.as_ref().map(|r| (r, r.get_ref().as_str())) {
        None | Some((_, "centre-of-mass")) => Reference::CentreOfMass,
        Some((_, "clamped-section")) => Reference::ClampedSection,
        Some((_, "free-free")) => Reference::FreeFree,
        Some((_, "pinned-ends")) => Reference::PinnedEnds(match &raw.pinned {
            None => None,
            Some(p) => {
                let [a, b] = *p.get_ref();
                if a < 0 || b < 0 || a == b {
                    return Err(src.error(
                        span(p),
                        Some(k("pinned")),
                        "two different node indices (from 0) are needed",
                    ));
                }
                Some([a as usize, b as usize])
            }
        }),
        Some((_, "clamped-node")) => Reference::ClampedNode(match &raw.clamped {
            None => 0,
            Some(c) if *c.get_ref() >= 0 => *c.get_ref() as usize,
            Some(c) => {
                return Err(src.error(
                    span(c),
                    Some(k("clamped")),
                    "a node index (from 0) is needed",
                ));
            }
        }),
        Some((_, "supports")) => Reference::Supports,
        Some((_, "partly-free")) => Reference::PartlyFree,
        Some((r, other)) => {
            return Err(src.error(
                span(r),
                Some(k("reference")),
                super::super::keys::BODY_REFERENCE.unknown("reference condition", other),
            ));
        }
    };
    if let (Some(p), false) = (&raw.pinned, matches!(reference, Reference::PinnedEnds(_))) {
        return Err(src.error(
            span(p),
            Some(k("pinned")),
            "pinned is only used with reference = \"pinned-ends\"",
        ));
    }
    if let (Some(c), false) = (&raw.clamped, matches!(reference, Reference::ClampedNode(_))) {
        return Err(src.error(
            span(c),
            Some(k("clamped")),
            "clamped is only used with reference = \"clamped-node\"",
        ));
    }
    Ok(reference)
}

/// A body's damping: Rayleigh coefficients, or ratios at two modes (which `computed`, the
/// number of modes computed, then includes with `modes = "auto"`).
pub(super) fn damping(
    src: &Source,
    name: &str,
    raw: &RawBody,
    auto_modes: bool,
    computed: &mut usize,
) -> Result<Option<fem::Damping>, DeckError> {
    let dk = |key: &str| format!("body.{name}.damping.{key}");
    Ok(match &raw.damping {
        None => None,
        Some(d) if d.get_ref().alpha.is_some() || d.get_ref().beta.is_some() => {
            let rd = d.get_ref();
            if let Some(m) = &rd.modes {
                return Err(src.error(
                    span(m),
                    Some(dk("modes")),
                    "give either modes and ratios, or alpha and beta, not both",
                ));
            }
            if let Some(r) = &rd.ratios {
                return Err(src.error(
                    span(r),
                    Some(dk("ratios")),
                    "give either modes and ratios, or alpha and beta, not both",
                ));
            }
            let coefficient = |key: &str, v: &Option<Spanned<f64>>, unit: &str| {
                let Some(v) = v else { return Ok(0.0) };
                let x = *v.get_ref();
                if x.is_finite() && x >= 0.0 {
                    Ok(x)
                } else {
                    Err(src.error(
                        span(v),
                        Some(dk(key)),
                        format!("{x} must be a finite coefficient ≥ 0 ({unit})"),
                    ))
                }
            };
            Some(fem::Damping::Coefficients {
                alpha: coefficient("alpha", &rd.alpha, "1/s")?,
                beta: coefficient("beta", &rd.beta, "s")?,
            })
        }
        Some(d) => {
            let m = required(
                src,
                span(d),
                &dk("modes"),
                &d.get_ref().modes,
                "modes = [i, j] (counted from 1)",
            )?;
            let r = required(
                src,
                span(d),
                &dk("ratios"),
                &d.get_ref().ratios,
                "ratios = [ζi, ζj]",
            )?;
            let [i, j] = *m.get_ref();
            if auto_modes && i >= 1 && j >= 1 {
                // the automatic choice computes at least the modes the fit refers to
                *computed = (*computed).max(i.max(j) as usize);
            }
            if i < 1 || j < 1 || i == j || i as usize > *computed || j as usize > *computed {
                return Err(src.error(
                    span(m),
                    Some(dk("modes")),
                    format!("two different mode numbers, between 1 and {computed}, are needed"),
                ));
            }
            let ratios = *r.get_ref();
            for (n, z) in ratios.iter().enumerate() {
                if !(z.is_finite() && *z >= 0.0) {
                    return Err(src.error(
                        span(r),
                        Some(format!("{}[{n}]", dk("ratios"))),
                        format!("{z} must be a finite damping ratio ≥ 0"),
                    ));
                }
            }
            Some(fem::Damping::Ratios(fem::RayleighDamping {
                modes: [i as usize - 1, j as usize - 1],
                ratios,
            }))
        }
    })
}

/// The correction modes' least damping ratio when the deck does not say: enough that they stop
/// ringing at their Ritz frequencies within a few periods, which an undamped body otherwise
/// resolves at great cost, small enough that their quasi-static response barely lags
/// ([`fem::CorrectionDamping`]; docs/design.md, "Damping of the correction modes").
pub const CORRECTION_DAMPING_DEFAULT: f64 = 0.1;

/// A body's `correction_damping`: the least damping ratio of its correction modes (≥ 0), or
/// `"proportional"` (the body's damping alone, as its eigenmodes').
pub(super) fn correction_damping(
    src: &Source,
    name: &str,
    raw: &RawBody,
) -> Result<fem::CorrectionDamping, DeckError> {
    let Some(value) = &raw.correction_damping else {
        return Ok(fem::CorrectionDamping::AtLeast(CORRECTION_DAMPING_DEFAULT));
    };
    let ratio = match value.get_ref() {
        toml::Value::String(s) if s == "proportional" => {
            return Ok(fem::CorrectionDamping::Proportional);
        }
        toml::Value::Float(x) => Some(*x),
        toml::Value::Integer(i) => Some(*i as f64),
        _ => None,
    };
    match ratio {
        Some(z) if z.is_finite() && z >= 0.0 => Ok(fem::CorrectionDamping::AtLeast(z)),
        _ => Err(src.error(
            span(value),
            Some(format!("body.{name}.correction_damping")),
            format!(
                "{} is not a damping ratio ≥ 0 (e.g. 0.1, the default; 1 is critical) or \"proportional\"",
                value.get_ref()
            ),
        )),
    }
}
