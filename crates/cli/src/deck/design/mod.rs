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
mod section;
mod target;

use actuator::actuator_variable;
use material::material_variable;
pub use material::{MaterialLaw, elastic, material_constants, with_material_constants};
pub use objectives::{FdDef, FdSteps, ObjectiveDef, SensitivityScheme, objective_label};
use objectives::{finite_differences, objective};
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

/// A ply-angle (or, with `thickness`, ply-thickness) variable: the plies of a laminate it
/// moves, each by its factor (mirrored plies of a symmetric laminate too).
fn ply_variable(
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

/// A rigid body's mass or principal inertia as a design variable.
fn rigid_variable(
    src: &Source,
    raw: &RawDeck,
    name: &str,
    d: &Spanned<RawDesign>,
    kind: &str,
) -> Result<DesignVariable, DeckError> {
    let k = |s: &str| format!("design.{name}.{s}");
    let rd = d.get_ref();
    let body = required(
        src,
        span(d),
        &k("body"),
        &rd.body,
        "body (a rigid body's name)",
    )?;
    let rigid = super::mechanism::rigid_bodies(src, raw)?;
    let Some(r) = rigid.iter().find(|r| r.name == *body.get_ref()) else {
        let known: Vec<&str> = rigid.iter().map(|r| r.name.as_str()).collect();
        let what = if raw.body.contains_key(body.get_ref()) {
            " (a flexible body: its mass comes from its laminates)".to_string()
        } else {
            suggestion(body.get_ref(), &known)
        };
        return Err(src.error(
            span(body),
            Some(k("body")),
            format!("undefined rigid body `{}`{what}", body.get_ref()),
        ));
    };
    let body = body.get_ref().clone();
    Ok(if kind == "rigid-mass" {
        DesignVariable {
            name: name.to_string(),
            value: r.mass,
            target: Target::RigidMass { body },
            unit: "kg",
        }
    } else {
        let axis = required(
            src,
            span(d),
            &k("axis"),
            &rd.axis,
            "axis (\"x\", \"y\" or \"z\")",
        )?;
        let axis = choice(src, &k("axis"), Some(axis), super::keys::INERTIA_AXIS.words)?
            .map_or(0, |a| (a.as_bytes()[0] - b'x') as usize);
        let off = (0..3).any(|j| j != axis && r.inertia[(axis, j)] != 0.0);
        if off {
            return Err(src.error(
                rd.axis.as_ref().and_then(span),
                Some(k("axis")),
                "the inertia has products of inertia on this axis: a principal moment is a \
                 design variable only where the tensor is diagonal",
            ));
        }
        // the entry as written: [Ixx, Iyy, Izz] or a 3×3 matrix
        let matrix = raw.rigid[&body]
            .get_ref()
            .inertia
            .as_ref()
            .and_then(|v| v.get_ref().as_array())
            .is_some_and(|a| a.first().is_some_and(toml::Value::is_array));
        let key = if matrix {
            format!("rigid.{body}.inertia.{axis}.{axis}")
        } else {
            format!("rigid.{body}.inertia.{axis}")
        };
        DesignVariable {
            name: name.to_string(),
            value: r.inertia[(axis, axis)],
            target: Target::RigidInertia { body, axis, key },
            unit: "kg*m^2",
        }
    })
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
