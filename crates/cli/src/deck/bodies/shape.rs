//! A shell body's mesh (a rectangle or a mesh file), and the element counts of beams and
//! shells.

use super::*;

/// A shell body's mesh: a rectangle or a mesh file, of a laminate.
pub(super) fn shell_shape(
    src: &Source,
    name: &str,
    raw: &RawBody,
    table: Option<std::ops::Range<usize>>,
    model: &LaminateModel,
) -> Result<BodyShape, DeckError> {
    let k = |key: &str| format!("body.{name}.{key}");
    let elements_value = raw.elements.as_ref();
    let lname = required(
        src,
        table.clone(),
        &k("laminate"),
        &raw.laminate,
        "laminate (a [laminate.*] name)",
    )?;
    let laminates = super::regions::shell_laminates(src, name, raw, lname, model)?;
    let axis = raw
        .material_axis
        .as_ref()
        .map(|a| nonzero_vector(src, &k("material_axis"), a))
        .transpose()?
        .unwrap_or(Vector3::x());
    Ok(match &raw.file {
        Some(f) => {
            for (key, v) in [("length", &raw.length), ("width", &raw.width)] {
                if let Some(v) = v {
                    return Err(src.error(
                        span(v),
                        Some(k(key)),
                        "a shell read from a file takes its size from the mesh",
                    ));
                }
            }
            if let Some(e) = elements_value {
                return Err(src.error(
                    span(e),
                    Some(k("elements")),
                    "a shell read from a file takes its elements from the mesh",
                ));
            }
            let path = src
                .file
                .parent()
                .unwrap_or(std::path::Path::new("."))
                .join(f.get_ref());
            let mesh_text = crate::limits::read_text(&path).map_err(|e| {
                src.error(
                    span(f),
                    Some(k("file")),
                    format!("cannot read the mesh {}: {e}", path.display()),
                )
            })?;
            BodyShape::ShellMesh {
                laminates,
                mesh_text,
                file: path.display().to_string(),
                axis,
            }
        }
        None => {
            let length = positive(
                src,
                &k("length"),
                required(
                    src,
                    table.clone(),
                    &k("length"),
                    &raw.length,
                    "length along x (m), or file",
                )?,
                "m",
            )?;
            let width = positive(
                src,
                &k("width"),
                required(
                    src,
                    table.clone(),
                    &k("width"),
                    &raw.width,
                    "width along y (m)",
                )?,
                "m",
            )?;
            let elements = rectangle_elements(src, name, raw, length, width)?;
            BodyShape::ShellRectangle {
                laminates,
                length,
                width,
                elements,
                axis,
            }
        }
    })
}

/// The cells `[along x, along y]` of a shell rectangle `length × width` (16 along x by
/// default, square cells), checked against the element and memory limits.
fn rectangle_elements(
    src: &Source,
    name: &str,
    raw: &RawBody,
    length: f64,
    width: f64,
) -> Result<[usize; 2], DeckError> {
    let k = |key: &str| format!("body.{name}.{key}");
    let elements_value = raw.elements.as_ref();
    let elements = match elements_value {
        None => {
            let nx = 16usize;
            [nx, ((nx as f64 * width / length).round() as usize).max(2)]
        }
        Some(e) => match e.get_ref().as_array().map(|a| a.as_slice()) {
            Some([a, b]) => {
                let count = |v: &toml::Value| {
                    element_count(v, 1).ok_or_else(|| {
                        elements_error(
                            src,
                            name,
                            raw,
                            &format!(
                                "[along x, along y], whole numbers from 1 to the limit of {} \
                                 (--max-elements raises it)",
                                crate::limits::get().elements
                            ),
                        )
                    })
                };
                [count(a)?, count(b)?]
            }
            _ => {
                return Err(elements_error(
                    src,
                    name,
                    raw,
                    "[along x, along y] for a shell rectangle",
                ));
            }
        },
    };
    crate::deck::check::mesh_size(
        src,
        &k("elements"),
        elements_value.map(|e| e.span()),
        elements[0].saturating_mul(elements[1]),
    )?;
    // two triangles a cell
    crate::deck::check::memory_need(
        src,
        &k("elements"),
        elements_value.map(|e| e.span()),
        elements[0].saturating_mul(elements[1]).saturating_mul(2),
        crate::limits::SHELL_BYTES_PER_ELEMENT,
        "modal analysis",
    )?;
    Ok(elements)
}

/// A count of elements or modes: a whole number from `min` up to the element limit.
pub(super) fn element_count(v: &toml::Value, min: i64) -> Option<usize> {
    v.as_integer()
        .filter(|&n| n >= min && n <= crate::limits::get().elements as i64)
        .map(|n| n as usize)
}

/// The error of a malformed `elements` value of body `name`.
pub(super) fn elements_error(src: &Source, name: &str, raw: &RawBody, what: &str) -> DeckError {
    src.error(
        raw.elements.as_ref().map(|e| e.span()),
        Some(format!("body.{name}.elements")),
        format!("expected {what}"),
    )
}
