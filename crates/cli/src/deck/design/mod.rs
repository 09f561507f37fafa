//! `[design.*]`, `[objective.*]`, `[sensitivity]` and `[finite_differences]`: what `flexsens run`
//! differentiates, with respect to what, and how it compares with finite differences.
//!
//! A design variable `b` moves one thing of the model ([`Target`]): the angles (degrees) or
//! thicknesses (m) of plies of one laminate, `x_i(b) = x_i0 + f_i (b − b0)` with `b0` the
//! first listed ply's value divided by its factor; a material's elastic constant or density;
//! a rigid body's mass or principal inertia. Every section and shell made of what it moves
//! follows; the derivatives are per unit of the variable.

use laminate::LaminateError;
use mbs::Objective;
use toml::Spanned;

use super::check::suggestion;
use super::check::{finite, positive, required, span};
use super::laminates::LaminateModel;
use super::raw::{RawDesign, RawFiniteDifferences, RawObjective};
use super::{DeckError, RawDeck, Source};

mod actuator;
mod material;
mod objectives;
mod ply;
mod rigid;
mod section;
mod target;

use actuator::actuator_variable;
use material::material_variable;
pub use material::{MaterialLaw, elastic, material_constants, with_material_constants};
pub use objectives::{FdDef, FdSteps, ObjectiveDef, SensitivityScheme, objective_label};
use objectives::{finite_differences, objective};
use ply::ply_variable;
use rigid::rigid_variable;
use section::section_variable;
pub use target::Target;

/// A validated design variable.
#[derive(Debug, Clone, PartialEq)]
pub struct DesignVariable {
    pub name: String,
    pub target: Target,
    /// The nominal value `b0`, in [`Self::unit`].
    pub value: f64,
    /// The variable's unit; derivatives are per one of it (`"deg"`, `"kg"`, `"kg*m^2"`,
    /// `"Pa"`, `"1"`).
    pub unit: &'static str,
}

impl DesignVariable {
    /// The plies of `laminate` this variable turns, `(stack ply, dθ/db)` (empty when it moves
    /// something else).
    pub fn ply_links(&self, laminate: &str) -> &[(usize, f64)] {
        match &self.target {
            Target::PlyAngle {
                laminate: l,
                stack_plies,
                ..
            } if l == laminate => stack_plies,
            _ => &[],
        }
    }

    /// The plies of `laminate` whose thickness this variable moves, `(stack ply, dt/db)`.
    pub fn thickness_links(&self, laminate: &str) -> &[(usize, f64)] {
        match &self.target {
            Target::PlyThickness {
                laminate: l,
                stack_plies,
                ..
            } if l == laminate => stack_plies,
            _ => &[],
        }
    }

    /// How the variable moves the constants of `material` (none when it moves something
    /// else).
    pub fn material_links(&self, material: &str) -> Option<&MaterialLaw> {
        match &self.target {
            Target::Material {
                material: m, law, ..
            } if m == material => Some(law),
            _ => None,
        }
    }

    /// What the variable moves, for tables and messages.
    pub fn describe(&self) -> String {
        match &self.target {
            Target::PlyAngle { laminate, .. } => format!("ply angles of laminate `{laminate}`"),
            Target::PlyThickness { laminate, .. } => {
                format!("ply thicknesses of laminate `{laminate}`")
            }
            Target::Material {
                material, constant, ..
            } => format!("{constant} of material `{material}`"),
            Target::RigidMass { body } => format!("mass of rigid body `{body}`"),
            Target::RigidInertia { body, axis, .. } => {
                format!(
                    "inertia I{0}{0} of rigid body `{body}`",
                    ["x", "y", "z"][*axis]
                )
            }
            Target::SectionProperty { section, entry } => {
                format!("{} of section `{section}`", entry.name())
            }
            Target::SectionAngle { section } => format!("material angle of section `{section}`"),
            Target::ActuatorGain { force, gain } => {
                format!("{} of actuator `{force}`", ["kp", "kd"][*gain])
            }
        }
    }

    /// `--set` overrides of the deck that put this variable at `b` (the lay-ups of
    /// `flexsens report` and the cases of `flexsens sweep`, which run whole decks).
    pub fn overrides(&self, b: f64) -> Vec<String> {
        let (laminate, deck_plies, key) = match &self.target {
            Target::PlyAngle {
                laminate,
                deck_plies,
                ..
            } => (laminate, deck_plies, "angle"),
            Target::PlyThickness {
                laminate,
                deck_plies,
                ..
            } => (laminate, deck_plies, "thickness"),
            Target::RigidMass { body } => return vec![format!("rigid.{body}.mass={b:?}")],
            Target::Material {
                material, constant, ..
            } => return vec![format!("material.{material}.{constant}={b:?}")],
            Target::RigidInertia { key, .. } => return vec![format!("{key}={b:?}")],
            Target::SectionProperty { section, entry } => {
                return vec![format!("section.{section}.{}={b:?}", entry.key())];
            }
            Target::SectionAngle { section } => {
                return vec![format!("section.{section}.angle={b:?}")];
            }
            Target::ActuatorGain { force, gain } => {
                return vec![format!(
                    "force.{force}.control.{}={b:?}",
                    ["kp", "kd"][*gain]
                )];
            }
        };
        deck_plies
            .iter()
            .map(|&(i, theta0, f)| {
                format!(
                    "laminate.{laminate}.plies.{i}.{key}={:?}",
                    theta0 + f * (b - self.value)
                )
            })
            .collect()
    }

    /// The variable at the value `b`: its nominal value `b`, and the plies as they would be
    /// written at `b` (what [`Self::overrides`] writes and [`Self::apply`] moves from).
    pub fn at(&self, b: f64) -> DesignVariable {
        let mut v = self.clone();
        let h = b - self.value;
        if let Target::PlyAngle { deck_plies, .. } | Target::PlyThickness { deck_plies, .. } =
            &mut v.target
        {
            for (_, x0, f) in deck_plies.iter_mut() {
                *x0 += *f * h;
            }
        }
        v.value = b;
        v
    }

    /// Move the laminates to the value `b` of this variable (from the nominal laminates): each
    /// linked ply to `θ_i0 + f_i (b − b0)` as written in degrees (or metres), converted as
    /// validation converts a written value, so that the laminates are those of the deck with
    /// the variable written at `b`, bit for bit (their tangent `dθ/db` is the target's
    /// `stack_plies`); a material's constants move by `dc/db · (b − b0)`, in every ply made of
    /// it; other variables leave them.
    pub fn apply(&self, model: &mut LaminateModel, b: f64) -> Result<(), LaminateError> {
        if b == self.value {
            return Ok(());
        }
        if let Target::Material { material, law, .. } = &self.target {
            let m0 = model.materials[material];
            let c = MaterialLaw::moved(material_constants(&m0), [(law, b - self.value)]);
            let m = with_material_constants(&m0, &c)?;
            model.materials.insert(material.clone(), m);
            for def in model.laminates.values_mut() {
                if !def.ply_materials.contains(material) {
                    continue;
                }
                let plies = def
                    .stack
                    .plies()
                    .iter()
                    .zip(&def.ply_materials)
                    .map(|(p, name)| laminate::Ply {
                        material: if name == material { m } else { p.material },
                        ..*p
                    })
                    .collect();
                def.stack = laminate::PlyStack::with_options(
                    plies,
                    def.stack.reference(),
                    def.stack.shear_correction(),
                )?;
            }
            return Ok(());
        }
        let (laminate, stack_plies, deck_plies, thickness) = match &self.target {
            Target::PlyAngle {
                laminate,
                stack_plies,
                deck_plies,
            } => (laminate, stack_plies, deck_plies, false),
            Target::PlyThickness {
                laminate,
                stack_plies,
                deck_plies,
            } => (laminate, stack_plies, deck_plies, true),
            _ => return Ok(()),
        };
        let def = model
            .laminates
            .get_mut(laminate)
            .expect("a validated variable names a laminate of the model");
        let plies = def.stack.plies();
        let mut angles: Vec<f64> = plies.iter().map(|p| p.angle).collect();
        let mut thicknesses: Vec<f64> = plies.iter().map(|p| p.thickness).collect();
        let moved = if thickness {
            &mut thicknesses
        } else {
            &mut angles
        };
        // each ply as the deck would write it at `b` (`x_i0 + f_i (b − b0)`, degrees or
        // metres), taken as validation takes a written value: the same bits as the deck with
        // the variable written at `b`; the mirrored ply of a symmetric laminate too
        // (`stack_plies` holds one stack ply per deck ply, or two in a symmetric laminate: the
        // ply and its mirror, in the order of `deck_plies`)
        let per_ply = stack_plies.len() / deck_plies.len().max(1);
        for (k, &(_, x0, f)) in deck_plies.iter().enumerate() {
            let written = x0 + f * (b - self.value);
            let value = if thickness {
                written
            } else {
                written.to_radians()
            };
            for &(p, _) in &stack_plies[per_ply * k..per_ply * (k + 1)] {
                moved[p] = value;
            }
        }
        def.stack = def.stack.with_plies(&angles, &thicknesses)?;
        Ok(())
    }
}

/// The validated design part of a deck.
#[derive(Debug, Clone, PartialEq)]
pub struct DesignDef {
    pub variables: Vec<DesignVariable>,
    /// Sensitivities are computed (design variables declared and not disabled).
    pub enabled: bool,
    pub method: SensitivityScheme,
    pub fixed_modes: bool,
    pub error_control: bool,
    /// The adjoint method's budget for the run's states (bytes; `sensitivity.adjoint_memory`).
    pub adjoint_memory: usize,
    pub objectives: Vec<ObjectiveDef>,
    pub finite_differences: Option<FdDef>,
}

impl DesignDef {
    /// The design at the values `b` (one per variable): each variable at its value there
    /// ([`DesignVariable::at`]).
    pub fn at(&self, b: &[f64]) -> DesignDef {
        DesignDef {
            variables: self
                .variables
                .iter()
                .zip(b)
                .map(|(v, &bj)| v.at(bj))
                .collect(),
            ..self.clone()
        }
    }

    /// The laminates `nominal` (this design's) moved to the values `b`
    /// ([`DesignVariable::apply`]); a failure names the variable.
    pub fn laminates_at(
        &self,
        nominal: &LaminateModel,
        b: &[f64],
    ) -> Result<LaminateModel, (String, LaminateError)> {
        let mut lam = nominal.clone();
        for (v, &bj) in self.variables.iter().zip(b) {
            v.apply(&mut lam, bj).map_err(|e| (v.name.clone(), e))?;
        }
        Ok(lam)
    }
}

fn choice<'a>(
    src: &Source,
    key: &str,
    v: Option<&'a Spanned<String>>,
    allowed: &[&'a str],
) -> Result<Option<&'a str>, DeckError> {
    let Some(v) = v else { return Ok(None) };
    let s = v.get_ref().as_str();
    if allowed.contains(&s) {
        return Ok(Some(s));
    }
    let list: Vec<String> = allowed.iter().map(|a| format!("\"{a}\"")).collect();
    Err(src.error(
        span(v),
        Some(key.into()),
        format!(
            "unknown value `{s}`: expected {}{}",
            list.join(", "),
            suggestion(s, allowed)
        ),
    ))
}

fn variable(
    src: &Source,
    raw: &RawDeck,
    name: &str,
    d: &Spanned<RawDesign>,
    model: &LaminateModel,
) -> Result<DesignVariable, DeckError> {
    let k = |s: &str| format!("design.{name}.{s}");
    let rd = d.get_ref();
    let kind = choice(
        src,
        &k("kind"),
        rd.kind.as_ref(),
        super::keys::DESIGN_KIND.words,
    )?
    .unwrap_or("ply-angle");
    // keys of the other kinds
    let keys = [
        (
            "laminate",
            rd.laminate.as_ref().and_then(span),
            "ply-angle ply-thickness",
        ),
        (
            "plies",
            rd.plies.as_ref().and_then(span),
            "ply-angle ply-thickness",
        ),
        (
            "factors",
            rd.factors.as_ref().and_then(span),
            "ply-angle ply-thickness",
        ),
        (
            "body",
            rd.body.as_ref().and_then(span),
            "rigid-mass rigid-inertia",
        ),
        ("axis", rd.axis.as_ref().and_then(span), "rigid-inertia"),
        ("material", rd.material.as_ref().and_then(span), "material"),
        ("constant", rd.constant.as_ref().and_then(span), "material"),
        (
            "section",
            rd.section.as_ref().and_then(span),
            "section-property section-angle",
        ),
        (
            "entry",
            rd.entry.as_ref().and_then(span),
            "section-property",
        ),
        ("force", rd.force.as_ref().and_then(span), "actuator-gain"),
        ("gain", rd.gain.as_ref().and_then(span), "actuator-gain"),
    ];
    for (key, at, kinds) in keys {
        if at.is_some() && !kinds.split(' ').any(|x| x == kind) {
            return Err(src.error(
                at,
                Some(k(key)),
                format!("this key does not apply to kind = \"{kind}\""),
            ));
        }
    }
    if kind == "material" {
        return material_variable(src, raw, name, d, model);
    }
    if kind == "section-property" || kind == "section-angle" {
        return section_variable(src, raw, name, d, model, kind == "section-angle");
    }
    if kind == "actuator-gain" {
        return actuator_variable(src, raw, name, d);
    }
    if kind != "ply-angle" && kind != "ply-thickness" {
        return rigid_variable(src, raw, name, d, kind);
    }
    ply_variable(src, raw, name, d, model, kind == "ply-thickness")
}

/// Validate the design tables of a deck.
pub fn validate(
    src: &Source,
    raw: &RawDeck,
    model: &LaminateModel,
) -> Result<DesignDef, DeckError> {
    let variables = raw
        .design
        .iter()
        .map(|(name, d)| variable(src, raw, name, d, model))
        .collect::<Result<Vec<_>, _>>()?;
    let objectives = raw
        .objective
        .iter()
        .map(|(name, o)| objective(src, raw, name, o))
        .collect::<Result<Vec<_>, _>>()?;
    let s = raw.sensitivity.as_ref().map(|s| s.get_ref());
    let enabled = s
        .and_then(|s| s.enabled.as_ref())
        .is_none_or(|e| *e.get_ref())
        && !variables.is_empty();
    let method = choice(
        src,
        "sensitivity.method",
        s.and_then(|s| s.method.as_ref()),
        super::keys::SENSITIVITY_METHOD.words,
    )?;
    let modes = choice(
        src,
        "sensitivity.modes",
        s.and_then(|s| s.modes.as_ref()),
        super::keys::SENSITIVITY_MODES.words,
    )?;
    let finite_differences = raw
        .finite_differences
        .as_ref()
        .map(|r| finite_differences(src, r))
        .transpose()?
        .filter(|_| {
            raw.finite_differences
                .as_ref()
                .and_then(|r| r.get_ref().enabled.as_ref())
                .is_none_or(|e| *e.get_ref())
        });
    // (a table that turns them off asks for nothing)
    if let Some(fd) = &raw.finite_differences
        && variables.is_empty()
        && finite_differences.is_some()
    {
        return Err(src.error(
            span(fd),
            Some("finite_differences".into()),
            "finite differences need design variables: declare a [design.*] table",
        ));
    }
    Ok(DesignDef {
        method: SensitivityScheme::of_deck(method, variables.len(), objectives.len()),
        variables,
        enabled,
        fixed_modes: modes == Some("fixed"),
        error_control: s
            .and_then(|s| s.error_control.as_ref())
            .is_some_and(|e| *e.get_ref()),
        adjoint_memory: objectives::adjoint_memory(src, s)?,
        objectives,
        finite_differences,
    })
}
