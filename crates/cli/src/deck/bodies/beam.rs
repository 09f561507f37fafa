//! A beam body's line and its sections: one section over its whole length, or `segments` with
//! their own sections (a tailored link, a reinforced root).

use super::shape::{element_count, elements_error};
use super::*;
use crate::deck::raw::RawSegment;

/// Elements of a beam body when the deck does not say: over its whole length, or shared by its
/// segments in proportion to their lengths (at least one each).
pub(super) const DEFAULT_BEAM_ELEMENTS: usize = 10;

/// A beam body: its end points, the orientation of its sections, and its sections along it.
pub(super) fn beam_shape(
    src: &Source,
    deck: &RawDeck,
    name: &str,
    raw: &RawBody,
    table: Option<std::ops::Range<usize>>,
    model: &LaminateModel,
) -> Result<BodyShape, DeckError> {
    let k = |key: &str| format!("body.{name}.{key}");
    let start = vector(
        src,
        &k("start"),
        required(
            src,
            table.clone(),
            &k("start"),
            &raw.start,
            "start [x, y, z] (m)",
        )?,
    )?;
    let end = vector(
        src,
        &k("end"),
        required(src, table.clone(), &k("end"), &raw.end, "end [x, y, z] (m)")?,
    )?;
    let axis = end - start;
    // below a nanometre (or a billionth of the coordinates) a length is round-off, and the
    // element matrices would not be finite
    let negligible = 1e-9 * start.norm().max(end.norm()).max(1.0);
    if axis.norm() <= negligible {
        return Err(src.error(
            raw.end.as_ref().map(|e| e.span()),
            Some(k("end")),
            format!(
                "the beam's length |end − start| = {:e} m is zero or negligible (at least \
                 {negligible:e} m)",
                axis.norm()
            ),
        ));
    }
    let orientation = match &raw.orientation {
        Some(o) => nonzero_vector(src, &k("orientation"), o)?,
        None if axis.normalize().cross(&Vector3::y()).norm() > 1e-6 => Vector3::y(),
        None => Vector3::z(),
    };
    if orientation.normalize().cross(&axis.normalize()).norm() < 1e-6 {
        return Err(src.error(
            raw.orientation.as_ref().map(|o| o.span()),
            Some(k("orientation")),
            "must not be parallel to the beam axis",
        ));
    }
    let mut sections = Vec::new();
    let segments = match &raw.segments {
        None => {
            let sname = required(
                src,
                table,
                &k("section"),
                &raw.section,
                "section (a [section.*] name), or segments",
            )?;
            let property = named_section(src, deck, &k("section"), sname, model, &mut sections)?;
            let elements = match &raw.elements {
                None => DEFAULT_BEAM_ELEMENTS,
                Some(e) => element_count(e.get_ref(), 1).ok_or_else(|| {
                    elements_error(
                        src,
                        name,
                        raw,
                        &format!(
                            "a whole number of beam elements, from 1 to the limit of {} \
                             (--max-elements raises it)",
                            crate::limits::get().elements
                        ),
                    )
                })?,
            };
            vec![fem::BeamSegment {
                length: axis.norm(),
                elements,
                property,
            }]
        }
        Some(list) => {
            let conflict = (raw.section.as_ref().map(|s| ("section", s.span())))
                .or(raw.elements.as_ref().map(|e| ("elements", e.span())));
            if let Some((key, at)) = conflict {
                return Err(src.error(
                    Some(at),
                    Some(k(key)),
                    format!(
                        "a beam with `segments` takes its sections and elements from them: leave \
                         out `{key}`"
                    ),
                ));
            }
            let whole = BeamLine {
                length: axis.norm(),
                negligible,
            };
            segments(src, deck, name, list, whole, model, &mut sections)?
        }
    };
    let total: usize = segments.iter().map(|s| s.elements).sum();
    let at = raw
        .segments
        .as_ref()
        .map(|s| s.span())
        .or(raw.elements.as_ref().map(|e| e.span()));
    let key = if raw.segments.is_some() {
        "segments"
    } else {
        "elements"
    };
    crate::deck::check::memory_need(
        src,
        &k(key),
        at,
        total,
        crate::limits::BEAM_BYTES_PER_ELEMENT,
        "modal analysis",
    )?;
    Ok(BodyShape::Beam {
        sections,
        segments,
        start,
        end,
        orientation,
    })
}

/// A beam's length and the least length of a segment along it (m).
#[derive(Clone, Copy)]
struct BeamLine {
    length: f64,
    negligible: f64,
}

/// The segments of a beam body as `list` writes them, their sections added to `sections`.
fn segments(
    src: &Source,
    deck: &RawDeck,
    name: &str,
    list: &Spanned<Vec<Spanned<RawSegment>>>,
    whole: BeamLine,
    model: &LaminateModel,
    sections: &mut Vec<(String, SectionDef)>,
) -> Result<Vec<fem::BeamSegment>, DeckError> {
    let items = list.get_ref();
    if items.is_empty() {
        return Err(src.error(
            span(list),
            Some(format!("body.{name}.segments")),
            "at least one segment { section, length, elements }",
        ));
    }
    let mut out = Vec::with_capacity(items.len());
    let mut covered = 0.0;
    for (i, item) in items.iter().enumerate() {
        let key = format!("body.{name}.segments[{i}]");
        let sk = |s: &str| format!("{key}.{s}");
        let seg = item.get_ref();
        let sname = required(
            src,
            Some(item.span()),
            &sk("section"),
            &seg.section,
            "section (a [section.*] name)",
        )?;
        let property = named_section(src, deck, &sk("section"), sname, model, sections)?;
        let last = i + 1 == items.len();
        let length = match &seg.length {
            Some(l) => positive(src, &sk("length"), l, "m")?,
            None if last => whole.length - covered,
            None => {
                return Err(src.error(
                    Some(item.span()),
                    Some(sk("length")),
                    "missing value: length along the beam (m); only the last segment may leave \
                     it out (it then takes the rest of the beam)",
                ));
            }
        };
        covered += length;
        let rest = whole.length - covered;
        if length <= whole.negligible || rest < -1e-9 * whole.length {
            let at = seg.length.as_ref().map(span).unwrap_or(Some(item.span()));
            let message = if length <= whole.negligible {
                format!(
                    "the segments before this one cover {:.6e} m of the beam's {:.6e} m: \
                     nothing is left for it",
                    covered - length,
                    whole.length
                )
            } else {
                format!(
                    "the segments up to this one are {covered:.6e} m long, longer than the beam \
                     (|end − start| = {:.6e} m)",
                    whole.length
                )
            };
            return Err(src.error(at, Some(sk("length")), message));
        }
        if last && rest > 1e-9 * whole.length {
            return Err(src.error(
                span(list),
                Some(format!("body.{name}.segments")),
                format!(
                    "the segments are {covered:.6e} m long, shorter than the beam (|end − \
                     start| = {:.6e} m): leave out the last one's length to let it take the rest",
                    whole.length
                ),
            ));
        }
        let limit = crate::limits::get().elements;
        let elements = match &seg.elements {
            None => {
                let share = DEFAULT_BEAM_ELEMENTS as f64 * length / whole.length;
                (share.round() as usize).max(1)
            }
            Some(e) => usize::try_from(*e.get_ref())
                .ok()
                .filter(|&n| n >= 1 && n <= limit)
                .ok_or_else(|| {
                    src.error(
                        span(e),
                        Some(sk("elements")),
                        format!(
                            "expected a whole number of beam elements, from 1 to the limit of \
                             {limit} (--max-elements raises it)"
                        ),
                    )
                })?,
        };
        out.push(fem::BeamSegment {
            length,
            elements,
            property,
        });
    }
    Ok(out)
}

/// The index in `sections` of the section `sname` that the key `key` names, validated and
/// added when it is not there yet.
fn named_section(
    src: &Source,
    deck: &RawDeck,
    key: &str,
    sname: &Spanned<String>,
    model: &LaminateModel,
    sections: &mut Vec<(String, SectionDef)>,
) -> Result<usize, DeckError> {
    if let Some(i) = sections.iter().position(|(n, _)| n == sname.get_ref()) {
        return Ok(i);
    }
    let s = deck.section.get(sname.get_ref()).ok_or_else(|| {
        let known: Vec<&str> = deck.section.keys().map(String::as_str).collect();
        src.error(
            span(sname),
            Some(key.to_string()),
            format!(
                "undefined section `{}`{}",
                sname.get_ref(),
                suggestion(sname.get_ref(), &known)
            ),
        )
    })?;
    let section = sections::validate_one(src, sname.get_ref(), s, model)?;
    sections.push((sname.get_ref().clone(), section));
    Ok(sections.len() - 1)
}
