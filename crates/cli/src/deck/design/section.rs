//! A section's own numbers as design variables: an entry of a section given by its properties
//! (`kind = "section-property"`), the material angle of a solid section
//! (`kind = "section-angle"`).

use super::*;
use crate::deck::sections::{SECTION_ENTRIES, SectionEntry, validate_one};

/// A `section-property` variable: `section` (a `shape = "properties"` section) and `entry`
/// (`EA` … `EI3` of a section given by them, `mass_per_length`, `I22` or `I33`), its nominal
/// value the section's; with `angle`, a `section-angle` variable: the material angle of a
/// solid section (`shape = "rectangle"` or `"circle"`), in degrees.
pub(super) fn section_variable(
    src: &Source,
    raw: &RawDeck,
    name: &str,
    d: &Spanned<RawDesign>,
    model: &LaminateModel,
    angle: bool,
) -> Result<DesignVariable, DeckError> {
    let k = |s: &str| format!("design.{name}.{s}");
    let rd = d.get_ref();
    let section = required(
        src,
        span(d),
        &k("section"),
        &rd.section,
        "section (a [section.*] given by its properties)",
    )?;
    let sname = section.get_ref();
    let Some(raw_section) = raw.section.get(sname) else {
        let known: Vec<&str> = raw.section.keys().map(String::as_str).collect();
        return Err(src.error(
            span(section),
            Some(k("section")),
            format!("undefined section `{sname}`{}", suggestion(sname, &known)),
        ));
    };
    let def = validate_one(src, sname, raw_section, model)?;
    if angle {
        if !matches!(def.shape.as_str(), "rectangle" | "circle") {
            return Err(src.error(
                span(section),
                Some(k("section")),
                format!(
                    "section `{sname}` has shape = \"{}\": a section-angle variable turns the \
                     material of a solid rectangle or circle (a laminate's plies turn with \
                     ply-angle variables)",
                    def.shape
                ),
            ));
        }
        if rd.entry.is_some() {
            return Err(src.error(
                rd.entry.as_ref().and_then(span),
                Some(k("entry")),
                "this key does not apply to kind = \"section-angle\"",
            ));
        }
        let value = raw_section
            .get_ref()
            .angle
            .as_ref()
            .map_or(0.0, |a| *a.get_ref());
        return Ok(DesignVariable {
            name: name.to_string(),
            target: Target::SectionAngle {
                section: sname.clone(),
            },
            value,
            unit: "deg",
        });
    }
    let Some(given) = def.given else {
        return Err(src.error(
            span(section),
            Some(k("section")),
            format!(
                "section `{sname}` is analysed (shape = \"{}\"): its ply angles, ply \
                 thicknesses and materials are the design variables that move it; \
                 section-property variables move sections given by their properties",
                def.shape
            ),
        ));
    };
    let e = required(
        src,
        span(d),
        &k("entry"),
        &rd.entry,
        &format!("entry ({})", SECTION_ENTRIES.join(", ")),
    )?;
    let Some(entry) = SectionEntry::named(e.get_ref()) else {
        return Err(src.error(
            span(e),
            Some(k("entry")),
            format!(
                "unknown entry `{}`: expected one of {}{}",
                e.get_ref(),
                SECTION_ENTRIES.join(", "),
                suggestion(e.get_ref(), &SECTION_ENTRIES)
            ),
        ));
    };
    if raw_section.get_ref().mass_matrix.is_some() && !matches!(entry, SectionEntry::Stiffness(_)) {
        return Err(src.error(
            span(e),
            Some(k("entry")),
            format!(
                "section `{sname}` is given by its 6×6 mass matrix: give it by mass_per_length, \
                 mass_centre and inertia to vary {}",
                entry.name()
            ),
        ));
    }
    let Some(value) = given.value(entry) else {
        return Err(src.error(
            span(e),
            Some(k("entry")),
            format!(
                "section `{sname}` is given by its 6×6 stiffness: give it by EA, GA2, GA3, GJ, \
                 EI2 and EI3 to vary {}",
                entry.name()
            ),
        ));
    };
    Ok(DesignVariable {
        name: name.to_string(),
        target: Target::SectionProperty {
            section: sname.clone(),
            entry,
        },
        value,
        unit: entry.unit(),
    })
}
