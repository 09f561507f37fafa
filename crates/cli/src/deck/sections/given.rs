//! Sections given by their properties (`shape = "properties"`): a 6×6 stiffness, or the
//! stiffnesses about the tension and shear centres, and the mass properties.

use super::shapes::Shape;
use super::*;

/// The stiffness of a section given by its properties.
#[derive(Debug, Clone, PartialEq)]
pub enum GivenStiffness {
    /// The 6×6 stiffness about the origin.
    Matrix(Box<nalgebra::Matrix6<f64>>),
    /// `[EA, GA2, GA3, GJ, EI2, EI3]` about the tension centre (axial, bending) and the shear
    /// centre (shear, torsion), without couplings there.
    Centres {
        diagonal: [f64; 6],
        tension_centre: [f64; 2],
        shear_centre: [f64; 2],
    },
}

/// A number of a section given by its properties that a design variable can move.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SectionEntry {
    /// `EA`, `GA2`, `GA3`, `GJ`, `EI2`, `EI3` (index in that order) of a section given by
    /// them.
    Stiffness(usize),
    MassPerLength,
    /// `I22` (0) or `I33` (1).
    Inertia(usize),
}

/// The deck's names of the entries a variable can move, in [`SectionEntry`] order.
pub const SECTION_ENTRIES: [&str; 9] = [
    "EA",
    "GA2",
    "GA3",
    "GJ",
    "EI2",
    "EI3",
    "mass_per_length",
    "I22",
    "I33",
];

impl SectionEntry {
    /// The entry of a deck name of [`SECTION_ENTRIES`].
    pub fn named(name: &str) -> Option<SectionEntry> {
        let i = SECTION_ENTRIES.iter().position(|n| *n == name)?;
        Some(match i {
            0..6 => SectionEntry::Stiffness(i),
            6 => SectionEntry::MassPerLength,
            _ => SectionEntry::Inertia(i - 7),
        })
    }

    /// The deck's name of the entry.
    pub fn name(self) -> &'static str {
        match self {
            SectionEntry::Stiffness(i) => SECTION_ENTRIES[i],
            SectionEntry::MassPerLength => SECTION_ENTRIES[6],
            SectionEntry::Inertia(i) => SECTION_ENTRIES[7 + i],
        }
    }

    /// The path of the entry's value in the section's table (a `--set` key below it).
    pub fn key(self) -> String {
        match self {
            SectionEntry::Inertia(i) => format!("inertia.{i}"),
            e => e.name().to_string(),
        }
    }

    /// Its SI unit.
    pub fn unit(self) -> &'static str {
        match self {
            SectionEntry::Stiffness(0..3) => "N",
            SectionEntry::Stiffness(_) => "N*m^2",
            SectionEntry::MassPerLength => "kg/m",
            SectionEntry::Inertia(_) => "kg*m",
        }
    }
}

/// A section given by its properties (`shape = "properties"`): what the deck gives, so that a
/// design variable can move an entry.
#[derive(Debug, Clone, PartialEq)]
pub struct GivenSection {
    pub stiffness: GivenStiffness,
    pub mass_per_length: f64,
    pub mass_centre: [f64; 2],
    /// `[I22, I33, I23]` about the mass centre.
    pub inertia: [f64; 3],
}

impl GivenSection {
    /// The section's properties (checked: [`section::SectionProperties::given`]).
    pub fn properties(&self) -> Result<section::SectionProperties, section::SectionError> {
        let stiffness = match &self.stiffness {
            GivenStiffness::Matrix(k) => **k,
            GivenStiffness::Centres {
                diagonal,
                tension_centre,
                shear_centre,
            } => section::stiffness_from_centres(*diagonal, *tension_centre, *shear_centre),
        };
        section::SectionProperties::given(
            stiffness,
            self.mass_per_length,
            self.mass_centre,
            self.inertia,
        )
    }

    /// The value of `entry`, `None` for a stiffness entry of a section given by its 6×6
    /// stiffness.
    pub fn value(&self, entry: SectionEntry) -> Option<f64> {
        match (entry, &self.stiffness) {
            (SectionEntry::Stiffness(i), GivenStiffness::Centres { diagonal, .. }) => {
                Some(diagonal[i])
            }
            (SectionEntry::Stiffness(_), GivenStiffness::Matrix(_)) => None,
            (SectionEntry::MassPerLength, _) => Some(self.mass_per_length),
            (SectionEntry::Inertia(i), _) => Some(self.inertia[i]),
        }
    }

    /// The section with `entry` at `value`.
    pub fn with(&self, entry: SectionEntry, value: f64) -> GivenSection {
        let mut out = self.clone();
        match (entry, &mut out.stiffness) {
            (SectionEntry::Stiffness(i), GivenStiffness::Centres { diagonal, .. }) => {
                diagonal[i] = value
            }
            (SectionEntry::Stiffness(_), GivenStiffness::Matrix(_)) => {}
            (SectionEntry::MassPerLength, _) => out.mass_per_length = value,
            (SectionEntry::Inertia(i), _) => out.inertia[i] = value,
        }
        out
    }

    /// The derivative of the section's stiffness and mass properties with respect to `entry`
    /// (per its unit; the fields a beam reads: stiffness, mass per length, mass centre,
    /// inertias). The stiffness is linear in `EA` … `EI3`, the mass properties in their
    /// entries.
    pub fn derivative(&self, entry: SectionEntry) -> section::SectionProperties {
        let mut d = section::SectionProperties::default();
        match (entry, &self.stiffness) {
            (
                SectionEntry::Stiffness(i),
                GivenStiffness::Centres {
                    tension_centre,
                    shear_centre,
                    ..
                },
            ) => {
                let mut unit = [0.0; 6];
                unit[i] = 1.0;
                d.stiffness = section::stiffness_from_centres(unit, *tension_centre, *shear_centre);
            }
            (SectionEntry::Stiffness(_), GivenStiffness::Matrix(_)) => {}
            (SectionEntry::MassPerLength, _) => d.mass_per_length = 1.0,
            (SectionEntry::Inertia(i), _) => d.mass_inertia[i] = 1.0,
        }
        d
    }
}

impl Shape<'_> {
    /// The section's properties: `stiffness` (6×6 about the origin) or `EA`, `GA2`, `GA3`, `GJ`,
    /// `EI2`, `EI3` about the centres, with `mass_per_length`, `mass_centre` and `inertia`.
    pub(super) fn given(&self) -> Result<GivenSection, DeckError> {
        let Shape { src, raw, .. } = *self;
        let k = |key: &str| self.k(key);
        // EA … EI3, the first six entries a variable can move
        let fields = [&raw.ea, &raw.ga2, &raw.ga3, &raw.gj, &raw.ei2, &raw.ei3];
        let named: Vec<(&str, _)> = SECTION_ENTRIES.iter().copied().zip(fields).collect();
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
                GivenStiffness::Matrix(Box::new(nalgebra::Matrix6::from_fn(|i, j| rows[i][j])))
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
                GivenStiffness::Centres {
                    diagonal,
                    tension_centre: centre("tension_centre", &raw.tension_centre)?,
                    shear_centre: centre("shear_centre", &raw.shear_centre)?,
                }
            }
        };
        let (mass_per_length, mass_centre, mass_inertia) = self.given_mass()?;
        let given = GivenSection {
            stiffness,
            mass_per_length,
            mass_centre,
            inertia: mass_inertia,
        };
        given.properties().map_err(|e| self.bad(e))?;
        Ok(given)
    }

    /// The mass per length, mass centre and inertias of a section given by its properties:
    /// `mass_matrix` (6×6 about the origin) or `mass_per_length`, `mass_centre`, `inertia`.
    fn given_mass(&self) -> Result<(f64, [f64; 2], [f64; 3]), DeckError> {
        let Shape { src, raw, .. } = *self;
        let k = |key: &str| self.k(key);
        if let Some(mm) = &raw.mass_matrix {
            let parts = [
                (
                    "mass_per_length",
                    raw.mass_per_length.as_ref().map(|x| x.span()),
                ),
                ("mass_centre", raw.mass_centre.as_ref().map(|x| x.span())),
                ("inertia", raw.inertia.as_ref().map(|x| x.span())),
            ];
            if let Some((key, at)) = parts.into_iter().find(|(_, at)| at.is_some()) {
                return Err(src.error(
                    at,
                    Some(k(key)),
                    "give either the 6×6 mass_matrix or mass_per_length, mass_centre and \
                     inertia, not both",
                ));
            }
            let rows = mm.get_ref();
            if rows.len() != 6 || rows.iter().any(|r| r.len() != 6) {
                return Err(src.error(
                    span(mm),
                    Some(k("mass_matrix")),
                    "expected six rows of six numbers (kg/m, kg, kg·m), conjugate to the \
                     velocities [u1, u2, u3, φ1, φ2, φ3]",
                ));
            }
            let matrix = nalgebra::Matrix6::from_fn(|i, j| rows[i][j]);
            return section::SectionProperties::mass_of_matrix(&matrix)
                .map_err(|e| src.error(span(mm), Some(k("mass_matrix")), e.to_string()));
        }
        let mass = required(
            src,
            self.table.clone(),
            &k("mass_per_length"),
            &raw.mass_per_length,
            "mass_per_length (kg/m), or the 6×6 mass_matrix",
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
        Ok((mass_per_length, mass_centre, mass_inertia))
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
