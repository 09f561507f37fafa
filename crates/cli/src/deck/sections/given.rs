//! Sections given by their properties (`shape = "properties"`): a 6×6 stiffness, or the
//! stiffnesses about the tension and shear centres, and the mass properties.

use super::shapes::Shape;
use super::*;

impl Shape<'_> {
    /// The section's properties: `stiffness` (6×6 about the origin) or `EA`, `GA2`, `GA3`, `GJ`,
    /// `EI2`, `EI3` about the centres, with `mass_per_length`, `mass_centre` and `inertia`.
    pub(super) fn given(&self) -> Result<section::SectionProperties, DeckError> {
        let Shape { src, raw, .. } = *self;
        let k = |key: &str| self.k(key);
        let named = [
            ("EA", &raw.ea),
            ("GA2", &raw.ga2),
            ("GA3", &raw.ga3),
            ("GJ", &raw.gj),
            ("EI2", &raw.ei2),
            ("EI3", &raw.ei3),
        ];
        let stiffness = match &raw.stiffness {
            Some(m) => {
                if let Some((key, v)) = named.iter().find_map(|(n, v)| v.as_ref().map(|v| (n, v))) {
                    return Err(src.error(
                        span(v),
                        Some(k(key)),
                        "give either the 6×6 stiffness or EA, GA2, GA3, GJ, EI2 and EI3, not both",
                    ));
                }
                if raw.tension_centre.is_some() || raw.shear_centre.is_some() {
                    return Err(src.error(
                        span(m),
                        Some(k("stiffness")),
                        "the 6×6 stiffness is about the origin and holds every coupling: \
                         tension_centre and shear_centre go with EA … EI3",
                    ));
                }
                let rows = m.get_ref();
                if rows.len() != 6 || rows.iter().any(|r| r.len() != 6) {
                    return Err(src.error(
                        span(m),
                        Some(k("stiffness")),
                        "expected six rows of six numbers (N, N·m, N·m²), in the order of the \
                         strains [ε, γ2, γ3, κ1, κ2, κ3]",
                    ));
                }
                nalgebra::Matrix6::from_fn(|i, j| rows[i][j])
            }
            None => {
                let mut diagonal = [0.0; 6];
                for (d, (key, v)) in diagonal.iter_mut().zip(named) {
                    let unit = if matches!(key, "EA" | "GA2" | "GA3") {
                        "N"
                    } else {
                        "N·m²"
                    };
                    let v = required(
                        src,
                        self.table.clone(),
                        &k(key),
                        v,
                        &format!("{key} ({unit}), or the 6×6 stiffness"),
                    )?;
                    *d = positive(src, &k(key), v, unit)?;
                }
                let centre = |key: &str, v: &Option<Spanned<[f64; 2]>>| {
                    v.as_ref()
                        .map_or(Ok([0.0; 2]), |c| finite_pair(src, &k(key), c))
                };
                section::stiffness_from_centres(
                    diagonal,
                    centre("tension_centre", &raw.tension_centre)?,
                    centre("shear_centre", &raw.shear_centre)?,
                )
            }
        };
        let mass = required(
            src,
            self.table.clone(),
            &k("mass_per_length"),
            &raw.mass_per_length,
            "mass_per_length (kg/m)",
        )?;
        let mass_per_length = positive(src, &k("mass_per_length"), mass, "kg/m")?;
        let mass_centre = raw
            .mass_centre
            .as_ref()
            .map_or(Ok([0.0; 2]), |c| finite_pair(src, &k("mass_centre"), c))?;
        let inertia = required(
            src,
            self.table.clone(),
            &k("inertia"),
            &raw.inertia,
            "inertia = [I22, I33] or [I22, I33, I23] (kg·m, about the mass centre)",
        )?;
        let mass_inertia = match *inertia.get_ref().as_slice() {
            [i22, i33] => [i22, i33, 0.0],
            [i22, i33, i23] => [i22, i33, i23],
            _ => {
                return Err(src.error(
                    span(inertia),
                    Some(k("inertia")),
                    "expected [I22, I33] or [I22, I33, I23] (kg·m, about the mass centre)",
                ));
            }
        };
        section::SectionProperties::given(stiffness, mass_per_length, mass_centre, mass_inertia)
            .map_err(|e| self.bad(e))
    }
}

/// Two finite coordinates (m).
fn finite_pair(src: &Source, key: &str, v: &Spanned<[f64; 2]>) -> Result<[f64; 2], DeckError> {
    let [a, b] = *v.get_ref();
    if a.is_finite() && b.is_finite() {
        Ok([a, b])
    } else {
        Err(src.error(
            span(v),
            Some(key.into()),
            "expected two finite coordinates (m)",
        ))
    }
}
