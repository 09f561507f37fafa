//! Validation of `[material.*]` and `[laminate.*]` into `laminate` types.

use std::collections::BTreeMap;

use laminate::{LaminateError, OrthotropicMaterial, Ply, PlyStack, PlyStrength, ReferenceSurface};
use toml::Spanned;

use super::check::suggestion;
use super::raw::{RawDeck, RawLaminate, RawMaterial};
use super::{DeckError, Source};

/// A validated laminate with what the deck said about its plies.
#[derive(Debug, Clone)]
pub struct LaminateDef {
    pub stack: PlyStack<f64>,
    /// Material name of each ply, bottom first.
    pub ply_materials: Vec<String>,
}

/// Validated materials and laminates of a deck.
#[derive(Debug, Clone, Default)]
pub struct LaminateModel {
    pub materials: BTreeMap<String, OrthotropicMaterial>,
    /// The strengths of the materials that state them.
    pub strengths: BTreeMap<String, PlyStrength>,
    pub laminates: BTreeMap<String, LaminateDef>,
}

fn span<T>(s: &Spanned<T>) -> Option<std::ops::Range<usize>> {
    Some(s.span())
}

/// Validate one material.
fn material(
    src: &Source,
    name: &str,
    m: &Spanned<RawMaterial>,
) -> Result<OrthotropicMaterial, DeckError> {
    let key = |k: &str| format!("material.{name}.{k}");
    let raw = m.get_ref();
    let density = raw.density.as_ref().ok_or_else(|| {
        src.error(
            span(m),
            Some(key("density")),
            "missing value: density (kg/m³)",
        )
    })?;
    let ortho = [
        ("E1", &raw.e1),
        ("E2", &raw.e2),
        ("E3", &raw.e3),
        ("G12", &raw.g12),
        ("G13", &raw.g13),
        ("G23", &raw.g23),
        ("nu12", &raw.nu12),
        ("nu13", &raw.nu13),
        ("nu23", &raw.nu23),
    ];
    let given: Vec<&str> = ortho
        .iter()
        .filter(|(_, v)| v.is_some())
        .map(|(k, _)| *k)
        .collect();
    let result = match (&raw.e, &raw.nu, given.is_empty()) {
        (Some(e), Some(nu), true) => {
            OrthotropicMaterial::isotropic(*e.get_ref(), *nu.get_ref(), *density.get_ref())
        }
        (None, None, false) => {
            if let Some((k, _)) = ortho.iter().find(|(_, v)| v.is_none()) {
                return Err(src.error(
                    span(m),
                    Some(key(k)),
                    format!(
                        "missing value: an orthotropic material needs all of E1, E2, E3, G12, G13, G23 (Pa), \
                         nu12, nu13, nu23 (found {}); an isotropic one needs E and nu",
                        given.join(", ")
                    ),
                ));
            }
            let v = |i: usize| {
                *ortho[i]
                    .1
                    .as_ref()
                    .map(|s| s.get_ref())
                    .unwrap_or(&f64::NAN)
            };
            OrthotropicMaterial::new(
                [v(0), v(1), v(2)],
                [v(3), v(4), v(5)],
                [v(6), v(7), v(8)],
                *density.get_ref(),
            )
        }
        (Some(_), Some(_), false) | (Some(_), None, false) | (None, Some(_), false) => {
            return Err(src.error(
                span(m),
                Some(format!("material.{name}")),
                "give either E and nu (isotropic) or the nine orthotropic constants, not both",
            ));
        }
        (e, _, true) => {
            let missing = if e.is_none() { "E" } else { "nu" };
            return Err(src.error(
                span(m),
                Some(key(missing)),
                "missing value: an isotropic material needs E (Pa) and nu; an orthotropic one E1, E2, E3, \
                 G12, G13, G23, nu12, nu13, nu23",
            ));
        }
    };
    result.map_err(|e| {
        // point at the offending constant when there is one
        let (k, sp) = match &e {
            LaminateError::NotPositive { constant, .. }
            | LaminateError::NotFinite { constant, .. } => {
                let field = match *constant {
                    "density" => Some(density),
                    c => ortho
                        .iter()
                        .find(|(k, _)| *k == c)
                        .and_then(|(_, v)| v.as_ref())
                        .or_else(|| {
                            // isotropic: E1.. come from E and nu
                            if c.starts_with('E') || c.starts_with('G') {
                                raw.e.as_ref()
                            } else {
                                raw.nu.as_ref()
                            }
                        }),
                };
                // an isotropic material is named by its own keys: E for E1..E3, nu for
                // nu12..nu23 (G12.. derive from both and keep their names)
                let isotropic = match *constant {
                    _ if raw.e.is_none() => None,
                    "E1" | "E2" | "E3" => Some("E"),
                    "nu12" | "nu13" | "nu23" => Some("nu"),
                    _ => None,
                };
                if let Some(iso) = isotropic {
                    let message = e.to_string().replacen(constant, iso, 1);
                    return src.error(field.map(|f| f.span()), Some(key(iso)), message);
                }
                (key(constant), field.map(|f| f.span()))
            }
            _ => (format!("material.{name}"), Some(m.span())),
        };
        src.error(sp, Some(k), e.to_string())
    })
}

/// The strengths of one material, if it states any: then at least `Xt`, `Xc`, `Yt`, `Yc` and
/// `S12`, the through-thickness ones defaulting as [`PlyStrength::new`] says.
fn strength(
    src: &Source,
    name: &str,
    m: &Spanned<RawMaterial>,
) -> Result<Option<PlyStrength>, DeckError> {
    let raw = m.get_ref();
    let keys = [
        ("Xt", &raw.xt),
        ("Xc", &raw.xc),
        ("Yt", &raw.yt),
        ("Yc", &raw.yc),
        ("S12", &raw.s12),
        ("Zt", &raw.zt),
        ("Zc", &raw.zc),
        ("S13", &raw.s13),
        ("S23", &raw.s23),
    ];
    if keys.iter().all(|(_, v)| v.is_none()) {
        return Ok(None);
    }
    let key = |k: &str| format!("material.{name}.{k}");
    for (k, v) in &keys {
        if let Some(v) = v
            && !(v.get_ref().is_finite() && *v.get_ref() > 0.0)
        {
            return Err(src.error(
                span(v),
                Some(key(k)),
                format!("{} must be a positive strength (Pa)", v.get_ref()),
            ));
        }
    }
    let missing: Vec<&str> = keys[..5]
        .iter()
        .filter(|(_, v)| v.is_none())
        .map(|(k, _)| *k)
        .collect();
    if let Some(first) = missing.first() {
        return Err(src.error(
            span(m),
            Some(key(first)),
            format!(
                "missing value: strengths need Xt, Xc, Yt, Yc and S12 (Pa; missing {})",
                missing.join(", ")
            ),
        ));
    }
    let v = |i: usize| keys[i].1.as_ref().map(|s| *s.get_ref());
    let given = |i: usize| v(i).expect("checked");
    let base = PlyStrength::new(given(0), given(1), given(2), given(3), given(4))
        .expect("checked positive");
    let out = base
        .with_transverse(
            v(5).unwrap_or(base.zt),
            v(6).unwrap_or(base.zc),
            v(7).unwrap_or(base.s13),
            v(8).unwrap_or(base.s23),
        )
        .expect("checked positive");
    Ok(Some(out))
}

/// Validate one laminate.
fn laminate(
    src: &Source,
    name: &str,
    l: &Spanned<RawLaminate>,
    materials: &BTreeMap<String, OrthotropicMaterial>,
) -> Result<LaminateDef, DeckError> {
    let key = |k: &str| format!("laminate.{name}.{k}");
    let raw = l.get_ref();
    let plies = raw.plies.as_ref().ok_or_else(|| {
        src.error(
            span(l),
            Some(key("plies")),
            "missing value: plies (a list of { material, thickness, angle })",
        )
    })?;
    if plies.get_ref().is_empty() {
        return Err(src.error(
            span(plies),
            Some(key("plies")),
            "a laminate needs at least one ply",
        ));
    }
    let mut stack = Vec::new();
    let mut names = Vec::new();
    for (i, p) in plies.get_ref().iter().enumerate() {
        let pk = |k: &str| format!("laminate.{name}.plies[{i}].{k}");
        let r = p.get_ref();
        let missing =
            |k: &str, what: &str| src.error(span(p), Some(pk(k)), format!("missing value: {what}"));
        let mat_name = r
            .material
            .as_ref()
            .ok_or_else(|| missing("material", "material (a name from [material.*])"))?;
        let thickness = r
            .thickness
            .as_ref()
            .ok_or_else(|| missing("thickness", "thickness (m)"))?;
        let angle = r
            .angle
            .as_ref()
            .ok_or_else(|| missing("angle", "angle (degrees)"))?;
        let material = *materials.get(mat_name.get_ref()).ok_or_else(|| {
            let known: Vec<&str> = materials.keys().map(String::as_str).collect();
            src.error(
                span(mat_name),
                Some(pk("material")),
                format!(
                    "undefined material `{}`{}",
                    mat_name.get_ref(),
                    suggestion(mat_name.get_ref(), &known)
                ),
            )
        })?;
        let t = *thickness.get_ref();
        if !(t.is_finite() && t > 0.0) {
            return Err(src.error(
                span(thickness),
                Some(pk("thickness")),
                format!("thickness = {t} must be a positive, finite number (m)"),
            ));
        }
        let a = *angle.get_ref();
        if !a.is_finite() {
            return Err(src.error(
                span(angle),
                Some(pk("angle")),
                format!("angle = {a} must be a finite number (degrees)"),
            ));
        }
        if a.abs() > 360.0 {
            src.warn(
                span(angle),
                Some(pk("angle")),
                format!("angle = {a}° is more than a full turn (angles are in degrees)"),
            );
        }
        stack.push(Ply {
            material,
            thickness: t,
            angle: a.to_radians(),
        });
        names.push(mat_name.get_ref().clone());
    }
    if raw.symmetric.as_ref().is_some_and(|s| *s.get_ref()) {
        let mirrored: Vec<_> = stack.iter().rev().copied().collect();
        stack.extend(mirrored);
        let mirrored: Vec<_> = names.iter().rev().cloned().collect();
        names.extend(mirrored);
    }
    let reference = match raw.reference.as_ref() {
        None => {
            if let Some(o) = &raw.offset {
                return Err(src.error(
                    span(o),
                    Some(key("offset")),
                    "offset is only used with reference = \"offset\"",
                ));
            }
            ReferenceSurface::MidPlane
        }
        Some(r) => match r.get_ref().as_str() {
            "mid-plane" | "midplane" => ReferenceSurface::MidPlane,
            "bottom" => ReferenceSurface::Bottom,
            "top" => ReferenceSurface::Top,
            "offset" => {
                let o = raw.offset.as_ref().ok_or_else(|| {
                    src.error(
                        span(r),
                        Some(key("offset")),
                        "missing value: offset (m) for reference = \"offset\"",
                    )
                })?;
                ReferenceSurface::Offset(*o.get_ref())
            }
            other => {
                return Err(src.error(
                    span(r),
                    Some(key("reference")),
                    super::keys::LAMINATE_REFERENCE.unknown("reference surface", other),
                ));
            }
        },
    };
    let k = raw
        .shear_correction
        .as_ref()
        .map_or(laminate::DEFAULT_SHEAR_CORRECTION, |s| *s.get_ref());
    let stack = PlyStack::with_options(stack, reference, k).map_err(|e| {
        let (k, sp) = match &e {
            LaminateError::ShearCorrection { .. } => (
                key("shear_correction"),
                raw.shear_correction.as_ref().map(|s| s.span()),
            ),
            LaminateError::ReferenceOffset { .. } => {
                (key("offset"), raw.offset.as_ref().map(|s| s.span()))
            }
            _ => (format!("laminate.{name}"), Some(l.span())),
        };
        src.error(sp, Some(k), e.to_string())
    })?;
    Ok(LaminateDef {
        stack,
        ply_materials: names,
    })
}

/// Validate the materials and laminates of a deck.
pub fn validate(src: &Source, deck: &RawDeck) -> Result<LaminateModel, DeckError> {
    let mut model = LaminateModel::default();
    for (name, m) in &deck.material {
        model
            .materials
            .insert(name.clone(), material(src, name, m)?);
        if let Some(s) = strength(src, name, m)? {
            model.strengths.insert(name.clone(), s);
        }
    }
    for (name, l) in &deck.laminate {
        let def = laminate(src, name, l, &model.materials)?;
        model.laminates.insert(name.clone(), def);
    }
    Ok(model)
}
