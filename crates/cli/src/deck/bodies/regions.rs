//! A shell body's laminates: its own, and `regions` of elements laminated otherwise (a
//! reinforced patch, a tailored skin).

use super::super::check::suggestion;
use super::sets::node_set;
use super::*;

/// The laminates of the shell body `name`: `lname` (its `laminate`) first, then those its
/// `regions` name, with the regions in order.
pub(super) fn shell_laminates(
    src: &Source,
    name: &str,
    raw: &RawBody,
    lname: &Spanned<String>,
    model: &LaminateModel,
) -> Result<ShellLaminates, DeckError> {
    let mut out = ShellLaminates {
        laminates: Vec::new(),
        regions: Vec::new(),
    };
    laminate_index(
        src,
        &format!("body.{name}.laminate"),
        lname,
        model,
        &mut out,
    )?;
    let Some(list) = &raw.regions else {
        return Ok(out);
    };
    if list.get_ref().is_empty() {
        return Err(src.error(
            span(list),
            Some(format!("body.{name}.regions")),
            "at least one region { laminate, elements | plane | box }",
        ));
    }
    for (i, item) in list.get_ref().iter().enumerate() {
        let key = format!("body.{name}.regions[{i}]");
        let r = item.get_ref();
        let lname = required(
            src,
            Some(item.span()),
            &format!("{key}.laminate"),
            &r.laminate,
            "laminate (a [laminate.*] name)",
        )?;
        let laminate = laminate_index(src, &format!("{key}.laminate"), lname, model, &mut out)?;
        let elements = match (&r.elements, r.plane.is_some() || r.inside.is_some()) {
            (Some(list), false) => ElementSet::Elements(element_list(src, &key, list)?),
            (None, true) => ElementSet::Within(node_set(
                src,
                &key,
                item.span(),
                &None,
                &r.plane,
                &r.inside,
            )?),
            _ => {
                return Err(src.error(
                    Some(item.span()),
                    Some(key),
                    "give the region's elements in one way: elements = [...], plane = { x = … } \
                     (the elements whose nodes all lie on it) or box = [[…], […]] (whose nodes \
                     all lie in it)",
                ));
            }
        };
        out.regions.push(RegionDef {
            laminate,
            elements,
            key,
            span: item.span(),
        });
    }
    Ok(out)
}

/// The index in `out.laminates` of the laminate `lname` that `key` names, added when it is not
/// there yet.
fn laminate_index(
    src: &Source,
    key: &str,
    lname: &Spanned<String>,
    model: &LaminateModel,
    out: &mut ShellLaminates,
) -> Result<usize, DeckError> {
    if let Some(i) = out
        .laminates
        .iter()
        .position(|l| &l.name == lname.get_ref())
    {
        return Ok(i);
    }
    let def = shell_laminate(src, key, lname, model)?;
    out.laminates.push(ShellLaminate::of(lname.get_ref(), def));
    Ok(out.laminates.len() - 1)
}

/// A region's `elements = [...]`: indices from 0, each once.
fn element_list(
    src: &Source,
    key: &str,
    list: &Spanned<Vec<i64>>,
) -> Result<Vec<usize>, DeckError> {
    let values = list.get_ref();
    let bad = |what: String| src.error(span(list), Some(format!("{key}.elements")), what);
    if values.is_empty() || values.iter().any(|&x| x < 0) {
        return Err(bad("a list of element indices (from 0)".to_string()));
    }
    if let Some((_, twice)) = values
        .iter()
        .enumerate()
        .find(|(i, x)| values[..*i].contains(x))
    {
        return Err(bad(format!("element {twice} is listed twice")));
    }
    Ok(values.iter().map(|&x| x as usize).collect())
}

/// The laminate `lname` that the key `key` of a shell body names.
pub(super) fn shell_laminate<'m>(
    src: &Source,
    key: &str,
    lname: &Spanned<String>,
    model: &'m LaminateModel,
) -> Result<&'m crate::deck::laminates::LaminateDef, DeckError> {
    model.laminates.get(lname.get_ref()).ok_or_else(|| {
        let known: Vec<&str> = model.laminates.keys().map(String::as_str).collect();
        src.error(
            span(lname),
            Some(key.to_string()),
            format!(
                "undefined laminate `{}`{}",
                lname.get_ref(),
                suggestion(lname.get_ref(), &known)
            ),
        )
    })
}
