//! Ply-angle and ply-thickness variables: the plies of a laminate a variable moves and
//! their factors.

use super::*;

/// A ply-angle (or, with `thickness`, ply-thickness) variable: the plies of a laminate it
/// moves, each by its factor (mirrored plies of a symmetric laminate too).
pub(super) fn ply_variable(
    src: &Source,
    raw: &RawDeck,
    name: &str,
    d: &Spanned<RawDesign>,
    model: &LaminateModel,
    thickness: bool,
) -> Result<DesignVariable, DeckError> {
    let k = |s: &str| format!("design.{name}.{s}");
    let rd = d.get_ref();
    let lam = rd.laminate.as_ref().ok_or_else(|| {
        src.error(
            span(d),
            Some(k("laminate")),
            "missing value: laminate (the laminate whose ply angles move)",
        )
    })?;
    let lname = lam.get_ref();
    let def = model.laminates.get(lname).ok_or_else(|| {
        let known: Vec<&str> = model.laminates.keys().map(String::as_str).collect();
        src.error(
            span(lam),
            Some(k("laminate")),
            format!("undefined laminate `{lname}`{}", suggestion(lname, &known)),
        )
    })?;
    let raw_lam = raw.laminate[lname].get_ref();
    let n_deck = raw_lam.plies.as_ref().map_or(0, |p| p.get_ref().len());
    let symmetric = raw_lam.symmetric.as_ref().is_some_and(|s| *s.get_ref());
    let plies = ply_list(src, name, d, lname, n_deck)?;
    let factors = ply_factors(src, name, rd, plies.len())?;
    let stack = def.stack.plies();
    let n_stack = stack.len();
    let mut stack_plies = Vec::new();
    let mut deck_plies = Vec::new();
    let rad = std::f64::consts::PI / 180.0;
    // dθ/db in rad/deg; dt/db in m/m
    let scale = if thickness { 1.0 } else { rad };
    for (&i, &f) in plies.iter().zip(&factors) {
        stack_plies.push((i, f * scale));
        if symmetric {
            stack_plies.push((n_stack - 1 - i, f * scale));
        }
        // the value as written (degrees, metres), not a round trip through radians
        let ply = raw_lam.plies.as_ref().map(|p| p.get_ref()[i].get_ref());
        let written = if thickness {
            ply.and_then(|p| p.thickness.as_ref())
                .map_or(stack[i].thickness, |t| *t.get_ref())
        } else {
            ply.and_then(|p| p.angle.as_ref())
                .map_or(stack[i].angle.to_degrees(), |a| *a.get_ref())
        };
        deck_plies.push((i, written, f));
    }
    let value = deck_plies[0].1 / deck_plies[0].2;
    let laminate = lname.clone();
    Ok(DesignVariable {
        name: name.to_string(),
        target: if thickness {
            Target::PlyThickness {
                laminate,
                stack_plies,
                deck_plies,
            }
        } else {
            Target::PlyAngle {
                laminate,
                stack_plies,
                deck_plies,
            }
        },
        value,
        unit: if thickness { "m" } else { "deg" },
    })
}

/// The deck plies (indices into the laminate's `n_deck` plies) a ply variable moves: `plies`,
/// or every ply.
fn ply_list(
    src: &Source,
    name: &str,
    d: &Spanned<RawDesign>,
    lname: &str,
    n_deck: usize,
) -> Result<Vec<usize>, DeckError> {
    let k = |s: &str| format!("design.{name}.{s}");
    let rd = d.get_ref();
    let plies: Vec<usize> = match &rd.plies {
        None => (0..n_deck).collect(),
        Some(p) => {
            let mut out = Vec::new();
            for &i in p.get_ref() {
                if i < 0 || i as usize >= n_deck {
                    return Err(src.error(
                        span(p),
                        Some(k("plies")),
                        format!(
                            "ply {i} does not exist: laminate `{lname}` lists plies 0 to {}",
                            n_deck.saturating_sub(1)
                        ),
                    ));
                }
                if out.contains(&(i as usize)) {
                    return Err(src.error(
                        span(p),
                        Some(k("plies")),
                        format!("ply {i} is listed twice"),
                    ));
                }
                out.push(i as usize);
            }
            out
        }
    };
    if plies.is_empty() {
        return Err(src.error(
            rd.plies.as_ref().and_then(span).or(span(d)),
            Some(k("plies")),
            "a design variable needs at least one ply",
        ));
    }
    Ok(plies)
}

/// The factors of a ply variable's `n` plies (`dθ_i/db`, all 1 when not given).
fn ply_factors(src: &Source, name: &str, rd: &RawDesign, n: usize) -> Result<Vec<f64>, DeckError> {
    let k = |s: &str| format!("design.{name}.{s}");
    Ok(match &rd.factors {
        None => vec![1.0; n],
        Some(f) => {
            let v = f.get_ref();
            if v.len() != n {
                return Err(src.error(
                    span(f),
                    Some(k("factors")),
                    format!("{} factors for {} plies", v.len(), n),
                ));
            }
            if v.iter().any(|x| !x.is_finite() || *x == 0.0) {
                return Err(src.error(
                    span(f),
                    Some(k("factors")),
                    "factors must be finite and non-zero",
                ));
            }
            v.clone()
        }
    })
}
