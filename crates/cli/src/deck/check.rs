//! Small validation helpers shared by the deck tables: required keys, positive numbers, counts.

use std::ops::Range;

use nalgebra::Vector3;
use toml::Spanned;

use super::{DeckError, Source};

/// The span of a spanned value.
pub fn span<T>(s: &Spanned<T>) -> Option<Range<usize>> {
    Some(s.span())
}

/// A required key of a table spanning `table`.
pub fn required<'a, T>(
    src: &Source,
    table: Option<Range<usize>>,
    key: &str,
    field: &'a Option<Spanned<T>>,
    what: &str,
) -> Result<&'a Spanned<T>, DeckError> {
    field.as_ref().ok_or_else(|| {
        src.error(
            table,
            Some(key.to_string()),
            format!("missing value: {what}"),
        )
    })
}

/// A positive, finite number (with its unit for the message).
pub fn positive(src: &Source, key: &str, v: &Spanned<f64>, unit: &str) -> Result<f64, DeckError> {
    let x = *v.get_ref();
    if x.is_finite() && x > 0.0 {
        Ok(x)
    } else {
        Err(src.error(
            span(v),
            Some(key.to_string()),
            format!(
                "{} must be a positive, finite number ({unit})",
                as_written(x)
            ),
        ))
    }
}

/// `x` as a deck would write it: plainly between 1e-4 and 1e9 in magnitude (and 0), in
/// exponent form outside (`-1e-9`, not `-0.000000001`).
fn as_written(x: f64) -> String {
    if x == 0.0 || !x.is_finite() || (1e-4..1e9).contains(&x.abs()) {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

/// A finite number.
pub fn finite(src: &Source, key: &str, v: &Spanned<f64>, unit: &str) -> Result<f64, DeckError> {
    let x = *v.get_ref();
    if x.is_finite() {
        Ok(x)
    } else {
        Err(src.error(
            span(v),
            Some(key.to_string()),
            format!("{x} must be a finite number ({unit})"),
        ))
    }
}

/// A count of at least `min`.
pub fn count(src: &Source, key: &str, v: &Spanned<i64>, min: i64) -> Result<usize, DeckError> {
    let x = *v.get_ref();
    let max = crate::limits::get().elements;
    if x > max as i64 {
        return Err(src.error(span(v), Some(key.to_string()), over_limit(x, max)));
    }
    if x >= min {
        usize::try_from(x)
            .map_err(|_| src.error(span(v), Some(key.to_string()), format!("{x} is too large")))
    } else {
        Err(src.error(
            span(v),
            Some(key.to_string()),
            format!("{x} must be a whole number of at least {min}"),
        ))
    }
}

/// The message for an element count `n` above the limit `max` ([`crate::limits`]).
pub fn over_limit(n: impl std::fmt::Display, max: usize) -> String {
    format!(
        "{n} elements is more than the limit of {max} (--max-elements raises it; the mesh may \
         not fit in memory)"
    )
}

/// Refuse a mesh of `n` elements above the element limit ([`crate::limits`]), naming `key`;
/// the element count of one direction of a generated mesh is checked by [`count`].
pub fn mesh_size(
    src: &Source,
    key: &str,
    at: Option<std::ops::Range<usize>>,
    n: usize,
) -> Result<(), DeckError> {
    let max = crate::limits::get().elements;
    if n > max {
        return Err(src.error(at, Some(key.to_string()), over_limit(n, max)));
    }
    Ok(())
}

/// Refuse an analysis of a mesh of `n` elements whose memory, estimated at `per_element`
/// bytes an element, is above the memory limit ([`crate::limits`]), naming `key`. Checked
/// before anything of the size is allocated; `what` names the analysis.
pub fn memory_need(
    src: &Source,
    key: &str,
    at: Option<std::ops::Range<usize>>,
    n: usize,
    per_element: u64,
    what: &str,
) -> Result<(), DeckError> {
    let limit = crate::limits::get().memory;
    let need = (n as u64).saturating_mul(per_element);
    if need <= limit {
        return Ok(());
    }
    let size = |b: u64| {
        if b >= 1 << 30 {
            format!("{:.1} GiB", b as f64 / (1u64 << 30) as f64)
        } else if b >= 1 << 20 {
            format!("{:.1} MiB", b as f64 / (1u64 << 20) as f64)
        } else {
            format!("{:.1} KiB", b as f64 / 1024.0)
        }
    };
    Err(src.error(
        at,
        Some(key.to_string()),
        format!(
            "the mesh of {n} elements needs about {} for its {what} (about {} KiB an element), \
             more than the memory limit of {} (--max-memory raises it)",
            size(need),
            per_element / 1024,
            size(limit)
        ),
    ))
}

/// A key that does not apply in this context (e.g. `inner_radius` of a rectangle).
pub fn not_applicable<T>(
    src: &Source,
    key: &str,
    field: &Option<Spanned<T>>,
    context: &str,
) -> Result<(), DeckError> {
    match field {
        Some(f) => Err(src.error(
            span(f),
            Some(key.to_string()),
            format!("this key does not apply to {context}"),
        )),
        None => Ok(()),
    }
}

/// A vector with finite components.
pub fn vector(src: &Source, key: &str, v: &Spanned<[f64; 3]>) -> Result<Vector3<f64>, DeckError> {
    let a = *v.get_ref();
    if a.iter().all(|x| x.is_finite()) {
        Ok(Vector3::from(a))
    } else {
        Err(src.error(
            span(v),
            Some(key.into()),
            format!("{a:?} must have finite components"),
        ))
    }
}

/// A finite vector that is not zero, as given (not normalised).
pub fn nonzero_vector(
    src: &Source,
    key: &str,
    v: &Spanned<[f64; 3]>,
) -> Result<Vector3<f64>, DeckError> {
    let d = vector(src, key, v)?;
    if d.norm() > 0.0 {
        Ok(d)
    } else {
        Err(src.error(span(v), Some(key.into()), "must not be the zero vector"))
    }
}

/// A direction: a finite, non-zero vector, normalised.
pub fn direction(
    src: &Source,
    key: &str,
    v: &Spanned<[f64; 3]>,
) -> Result<Vector3<f64>, DeckError> {
    nonzero_vector(src, key, v).map(|d| d / d.norm())
}

/// ", did you mean `x`?" for the closest known name, or "; defined: a, b" when none is close.
pub fn suggestion(word: &str, known: &[&str]) -> String {
    let best = known.iter().map(|k| (edit_distance(word, k), *k)).min();
    match best {
        Some((d, k)) if d <= 2.max(word.chars().count() / 3 + 1) => {
            format!(", did you mean `{k}`?")
        }
        _ if known.is_empty() => " (none defined)".to_string(),
        _ => format!(" (defined: {})", known.join(", ")),
    }
}

/// Levenshtein distance.
fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut prev: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut cur = vec![i + 1];
        for (j, cb) in b.iter().enumerate() {
            let sub = prev[j] + usize::from(ca != *cb);
            cur.push(sub.min(prev[j + 1] + 1).min(cur[j] + 1));
        }
        prev = cur;
    }
    prev[b.len()]
}
