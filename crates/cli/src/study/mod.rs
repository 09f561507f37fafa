//! The study: a deck validated into what every command works on, and the mechanism built
//! from it.
//!
//! [`Study::validate`] checks every table (errors name the file, line, column and key) into
//! validated definitions: laminates, design, bodies, joints, forces, responses, analysis. It
//! reads the meshes' geometry but analyses nothing: no section, no modes. [`Study::at`] moves
//! the definitions to another design in memory (the laminates by the design variables, every
//! body's sections and shells to them: `BodyDef::at`), and [`Study::build`] builds the
//! [`Mechanism`]: each flexible body's sections, modes and basis (with its design derivatives
//! for a run with sensitivities), the markers placed in the bodies' frames, the initial state,
//! the responses. [`Mechanism::model_at`] gives the model of a perturbed design for finite
//! differences (modes aligned to the nominal ones). The dual model of the direct sensitivities
//! is built from the same parts in `commands::sensitivity`. `docs/architecture.md` follows one
//! design variable through it.

mod assembly;
mod error_weights;
pub mod flexible;
mod model_body;
mod parameters;

use std::collections::BTreeMap;
use std::ops::{Deref, DerefMut, Range};

use mbs::{
    Baumgarte, BdfOptions, Body, BodyId, ForceId, JointId, Model, MultibodySystem, Output,
    RedundancyPolicy, RigidBody, State,
};
use nalgebra::{Matrix3, Vector3};

use crate::deck::analysis::{self, AnalysisDef};
use crate::deck::bodies::{BodyDef, validate_one as validate_body};
use crate::deck::check::span;
use crate::deck::design::{DesignDef, Target, validate as validate_design};
use crate::deck::laminates::{LaminateModel, validate as validate_laminates};
use crate::deck::mechanism::{self, BodyInfo, BodyPlace, ForceDefs, JointDef, RigidDef};
use crate::deck::responses::{self, ResponseDef, ResponseSpec};
use crate::deck::{DeckError, RawDeck, Source};
use crate::error::CliError;
use assembly::Assembly;
use flexible::{Built, DesignRequest, fem_error};
use model_body::ply_responses;
pub(crate) use model_body::{StressInput, flexible_model_body};
pub(crate) use parameters::set_parameter;

/// A flexible body of the mechanism with what its design derivatives need.
pub(crate) struct FlexiblePart {
    pub(crate) id: BodyId,
    pub(crate) name: String,
    pub(crate) built: Built,
    pub(crate) analysis: fem::ModalAnalysis,
    /// The body's table in the deck.
    pub(crate) span: Range<usize>,
    /// Geometric stiffening on.
    pub(crate) stiffening: bool,
    /// The validated body at the nominal design ([`BodyDef::at`] moves it to another).
    pub(crate) def: BodyDef,
}

/// A validated flexible body: its definition and its table in the deck.
#[derive(Debug, Clone)]
pub(crate) struct FlexibleDef {
    pub(crate) name: String,
    pub(crate) span: Range<usize>,
    pub(crate) def: BodyDef,
}

/// Where the deck's design variables and objectives are written, for the checks of a build
/// with sensitivities.
#[derive(Debug, Clone, Default)]
struct DesignSpans {
    /// Each `[design.NAME]` table.
    variables: BTreeMap<String, Range<usize>>,
    /// Each objective's `response` value.
    objective_responses: BTreeMap<String, Option<Range<usize>>>,
}

/// The validated deck: definitions only (no raw deck, no file, nothing analysed).
#[derive(Debug, Clone)]
pub(crate) struct Study {
    /// The laminates as the deck gives them (the design variables move them).
    pub(crate) laminates: LaminateModel,
    pub(crate) design: DesignDef,
    /// The flexible bodies, in deck order (the model's first bodies).
    pub(crate) flexible_bodies: Vec<FlexibleDef>,
    /// The rigid bodies, in deck order (after the flexible ones in the model).
    pub(crate) rigid_bodies: Vec<RigidDef>,
    pub(crate) joints: Vec<JointDef>,
    pub(crate) forces: ForceDefs,
    pub(crate) response_specs: Vec<ResponseSpec>,
    pub(crate) times: Vec<f64>,
    /// The integrator's options; `atol` NaN until [`Study::build`] gives each state
    /// component its own.
    pub(crate) options: BdfOptions,
    /// `analysis.atol`, when the deck gives it.
    pub(crate) atol: Option<f64>,
    /// `analysis.error_weights = "displacement"` ([`AnalysisDef::displacement_weights`]).
    pub(crate) displacement_weights: bool,
    pub(crate) baumgarte: Baumgarte,
    pub(crate) policy: RedundancyPolicy,
    /// `analysis.max_violation` (m): the step guard's limit, when the deck sets it.
    pub(crate) max_violation: Option<f64>,
    /// The deck's title.
    pub(crate) title: Option<String>,
    spans: DesignSpans,
}

/// A study built: the nominal mechanism with each flexible body's analysis, the initial state
/// and the responses; the study's definitions through `Deref`.
pub(crate) struct Mechanism {
    pub(crate) study: Study,
    pub(crate) model: Model<f64>,
    pub(crate) flexible: Vec<FlexiblePart>,
    /// The initial state: rigid-body coordinates as placed (not yet assembled), elastic state
    /// as given.
    pub(crate) state: State,
    /// `analysis.atol` or its default: a displacement (m) with displacement weights, the
    /// tolerance of every state component with uniform ones.
    pub(crate) displacement_tolerance: f64,
    pub(crate) bodies: BTreeMap<String, BodyInfo>,
    /// Body names in model order.
    pub(crate) body_order: Vec<String>,
    pub(crate) joint_names: Vec<String>,
    /// The forces of the model by name (`[force.NAME]` but gravity).
    pub(crate) forces: Vec<(String, ForceId)>,
    pub(crate) responses: Vec<ResponseDef>,
    /// The flexible bodies carry their design derivatives (section derivatives): a mechanism
    /// for a run with sensitivities.
    pub(crate) derivatives: bool,
}

impl Deref for Mechanism {
    type Target = Study;
    fn deref(&self) -> &Study {
        &self.study
    }
}

impl DerefMut for Mechanism {
    fn deref_mut(&mut self) -> &mut Study {
        &mut self.study
    }
}

/// A body's initial placement: frame origin, orientation (body → global), velocity of the
/// origin, angular velocity (global components).
struct Placement {
    id: BodyId,
    position: Vector3<f64>,
    rotation: Matrix3<f64>,
    velocity: Vector3<f64>,
    angular_velocity: Vector3<f64>,
}

fn initial_state(model: &Model<f64>, placements: &[Placement]) -> State {
    let mut s = model.rest_state();
    for p in placements {
        model.set_pose(&mut s, p.id, p.position, &p.rotation);
        // ω' in body components from the global angular velocity
        model.set_velocity(
            &mut s,
            p.id,
            p.velocity,
            p.rotation.transpose() * p.angular_velocity,
        );
    }
    s
}

/// A failure to build item `item` of the deck `src` at the design `b`.
pub(crate) fn at_design(src: &Source, item: String, b: &[f64], reason: impl ToString) -> CliError {
    CliError::AtDesign {
        file: src.file.clone(),
        item,
        design: b.to_vec(),
        reason: reason.to_string(),
    }
}

/// A model error of a deck table as bad input at that table.
fn at_table(src: &Source, span: Range<usize>, key: String, e: impl ToString) -> CliError {
    CliError::Input(src.error(Some(span), Some(key), e.to_string()))
}

/// The modal analysis and body of one validated flexible body, and its basis (with its check,
/// and the check's warning, when `with_check`).
fn flexible_body(
    src: &Source,
    name: &str,
    span: Range<usize>,
    def: &BodyDef,
    request: DesignRequest,
    with_check: bool,
) -> Result<
    (
        Built,
        fem::ModalAnalysis,
        fem::ModalBody<f64>,
        mechanism::BasisReport,
    ),
    CliError,
> {
    // (validation refuses a consistent mass: the floating frame needs lumped masses)
    let mut built = flexible::build(src, name, def, request)?;
    let (analysis, check) =
        flexible::analyse(src, name, span.clone(), def, &mut built, with_check)?;
    let modal = fem::modal_body(&built.mesh, &built.props, &analysis)
        .map_err(|e| fem_error(src, name, span.clone(), e))?;
    let report = basis_report(src, name, span, def, &analysis, check);
    Ok((built, analysis, modal, report))
}

/// The basis of a flexible body and its static check at the joints' nodes and couplings; a
/// warning (once) when it misses more than the body's `basis_tolerance`.
fn basis_report(
    src: &Source,
    name: &str,
    span: Range<usize>,
    def: &BodyDef,
    analysis: &fem::ModalAnalysis,
    check: Option<fem::Completeness>,
) -> mechanism::BasisReport {
    let report = mechanism::BasisReport {
        eigenmodes: analysis.kept.len(),
        correction_modes: analysis.correction.as_ref().map_or(0, |c| c.values.len()),
        check,
    };
    if let Some(w) = report.check.as_ref().and_then(|c| c.worst())
        && w.missed > def.basis_tolerance
    {
        src.warn(
            Some(span),
            Some(format!("body.{name}")),
            format!(
                "the basis ({} eigenmodes, {} correction modes) misses {:.1} % of the largest \
                 static compliance under the loads of the mechanism ({}: it captures {:.1} % of \
                 that case, above basis_tolerance = {}); the motion is then not converged: {}",
                report.eigenmodes,
                report.correction_modes,
                100.0 * w.missed,
                w.name,
                100.0 * w.captured,
                def.basis_tolerance,
                match (def.auto_modes, def.reference.holds_body()) {
                    (true, true) => {
                        "modes = \"auto\" stopped at the most eigenmodes it tries; use basis = \
                         \"interface\", or attach the joints through couplings"
                    }
                    (false, true) => {
                        "use basis = \"interface\", attach the joints through couplings, or \
                         retain more modes (modes = \"auto\" chooses them by this check)"
                    }
                    // no static correction without supports that hold every rigid motion
                    (true, false) => {
                        "modes = \"auto\" stopped at the most eigenmodes it tries; hold the \
                         body with supports (reference = \"supports\") to use basis = \
                         \"interface\""
                    }
                    (false, false) => {
                        "retain more modes (modes = \"auto\" chooses them by this check), or \
                         hold the body with supports (reference = \"supports\") to use basis = \
                         \"interface\""
                    }
                }
            ),
        );
    }
    report
}

/// Relative gap below which eigenvalues count as repeated when perturbed modes are tracked.
const CLUSTER_TOL: f64 = 1e-6;

impl Study {
    /// Validate the deck into definitions: every table checked, the meshes generated (or read)
    /// to place the markers and responses; no section or modal analysis.
    pub(crate) fn validate(src: &Source, raw: &RawDeck) -> Result<Study, CliError> {
        if raw.body.is_empty() && raw.rigid.is_empty() {
            return Err(src
                .error(
                    raw.analysis.as_ref().map(|a| a.span()),
                    Some("analysis".into()),
                    "the mechanism has no bodies: a run needs at least one [rigid.*] or [body.*] \
                     table",
                )
                .into());
        }
        let laminates = validate_laminates(src, raw)?;
        let design = validate_design(src, raw, &laminates)?;
        let mut places = BTreeMap::new();
        let mut flexible_bodies = Vec::new();
        for (name, b) in &raw.body {
            let def = validate_body(src, raw, name, b, &laminates)?;
            if !def.lumped {
                return Err(CliError::Input(src.error(
                    Some(b.span()),
                    Some(format!("body.{name}.mass")),
                    "the floating frame of reference needs mass = \"lumped\"",
                )));
            }
            let geometry = flexible::geometry(src, name, &def, &laminates.strengths)?;
            places.insert(
                name.clone(),
                BodyPlace {
                    flexible: Some(geometry),
                },
            );
            flexible_bodies.push(FlexibleDef {
                name: name.clone(),
                span: b.span(),
                def,
            });
        }
        let rigid_bodies = mechanism::rigid_bodies(src, raw)?;
        for r in &rigid_bodies {
            places.insert(r.name.clone(), BodyPlace { flexible: None });
        }
        let AnalysisDef {
            times,
            options,
            baumgarte,
            policy,
            max_violation,
            atol,
            displacement_weights,
        } = analysis::validate(src, raw)?;
        let joints = mechanism::joints(src, raw, &places)?;
        let forces = mechanism::forces(src, raw, &places)?;
        let joint_names: Vec<String> = joints.iter().map(|j| j.name.clone()).collect();
        let actuators: Vec<(String, bool)> = (forces.forces.iter())
            .filter_map(|(n, f, _)| match f {
                mechanism::ForceDef::JointTorque { .. } => Some((n.clone(), false)),
                mechanism::ForceDef::JointForce { .. } => Some((n.clone(), true)),
                _ => None,
            })
            .collect();
        let response_specs = responses::validate(src, raw, &places, &joint_names, &actuators)?;
        ply_responses(
            src,
            raw,
            &response_specs,
            &places,
            &design,
            &mut flexible_bodies,
        )?;
        let spans = DesignSpans {
            variables: raw
                .design
                .iter()
                .map(|(n, d)| (n.clone(), d.span()))
                .collect(),
            objective_responses: raw
                .objective
                .iter()
                .map(|(n, o)| (n.clone(), o.get_ref().response.as_ref().and_then(span)))
                .collect(),
        };
        let study = Study {
            laminates,
            design,
            flexible_bodies,
            rigid_bodies,
            joints,
            forces,
            response_specs,
            times,
            atol,
            displacement_weights,
            options,
            baumgarte,
            policy,
            max_violation,
            title: raw.title.clone(),
            spans,
        };
        study.check_objective_times(src, raw)?;
        Ok(study)
    }

    /// Build the nominal mechanism; with `derivatives` (and design variables enabled), each
    /// flexible body also gets its derivatives with respect to the design variables ready
    /// (section derivatives), and the design is checked for a run with sensitivities.
    pub(crate) fn build(self, src: &Source, derivatives: bool) -> Result<Mechanism, CliError> {
        let derivatives = derivatives && self.design.enabled;
        let request = if derivatives {
            DesignRequest::Variables(&self.design.variables)
        } else {
            DesignRequest::None
        };
        let mut a = Assembly::default();
        a.add_flexible_bodies(src, &self.flexible_bodies, request)?;
        a.add_rigid_bodies(src, &self.rigid_bodies)?;
        a.model.baumgarte = self.baumgarte;
        let (named_joints, named_forces) =
            a.add_joints_and_forces(src, &self.joints, &self.forces)?;
        let state = a.initial_state();
        let mut study = self;
        let displacement_tolerance;
        (study.options, displacement_tolerance) = study.error_weights(&a.model, &state);
        let responses = study
            .response_specs
            .iter()
            .map(|r| r.resolve(src, &a.model, &a.bodies, &named_joints, &named_forces))
            .collect::<Result<Vec<_>, _>>()?;
        let mechanism = Mechanism {
            study,
            displacement_tolerance,
            model: a.model,
            flexible: a.flexible,
            state,
            bodies: a.bodies,
            body_order: a.body_order,
            joint_names: named_joints.into_iter().map(|(n, _)| n).collect(),
            forces: named_forces,
            responses,
            derivatives,
        };
        if derivatives {
            mechanism.check_design(src)?;
        }
        Ok(mechanism)
    }

    /// The nominal values of the design variables.
    pub(crate) fn design_values(&self) -> Vec<f64> {
        self.design.variables.iter().map(|v| v.value).collect()
    }

    /// The laminates moved to the design `b`.
    pub(crate) fn laminates_at(&self, src: &Source, b: &[f64]) -> Result<LaminateModel, CliError> {
        self.design
            .laminates_at(&self.laminates, b)
            .map_err(|(name, e)| at_design(src, format!("design variable `{name}`"), b, e))
    }

    /// The study at the design `b` (one value per design variable), in memory: the laminates
    /// moved ([`DesignDef::laminates_at`]), each variable at its value there
    /// ([`DesignDef::at`]), every flexible body's sections and shells moved to those laminates
    /// ([`BodyDef::at`]), the sections given by their properties and the rigid bodies' mass
    /// and inertia variables set. What validating the deck with the variables written at `b`
    /// gives.
    pub(crate) fn at(&self, src: &Source, b: &[f64]) -> Result<Study, CliError> {
        let laminates = self.laminates_at(src, b)?;
        let mut study = self.clone();
        for f in &mut study.flexible_bodies {
            f.def = f.def.at(&laminates).map_err(|e| {
                at_design(
                    src,
                    format!("body `{}`", f.name),
                    b,
                    format!("its section: {e}"),
                )
            })?;
        }
        for f in &mut study.flexible_bodies {
            flexible::move_own_section(&mut f.def, &self.design.variables, b);
        }
        for (v, &bj) in self.design.variables.iter().zip(b) {
            parameters::move_definition(&mut study, &v.target, bj);
        }
        study.laminates = laminates;
        study.design = self.design.at(b);
        Ok(study)
    }

    /// An objective taken at a time, or over a window, must lie in the simulated span (found
    /// before the run, not after it).
    fn check_objective_times(&self, src: &Source, raw: &RawDeck) -> Result<(), DeckError> {
        let (t0, t1) = (self.times[0], self.times[self.times.len() - 1]);
        for o in &self.design.objectives {
            if let mbs::Objective::At(t) = o.kind
                && !(t0..=t1).contains(&t)
            {
                let ro = raw.objective[&o.name].get_ref();
                return Err(src.error(
                    ro.time.as_ref().and_then(span),
                    Some(format!("objective.{}.time", o.name)),
                    format!("time = {t} s lies outside the simulated span [{t0}, {t1}] s"),
                ));
            }
            if let Some((a, b)) = o.window
                && !(a >= t0 && b <= t1)
            {
                let ro = raw.objective[&o.name].get_ref();
                return Err(src.error(
                    ro.window.as_ref().and_then(span),
                    Some(format!("objective.{}.window", o.name)),
                    format!(
                        "the window [{a}, {b}] s reaches outside the simulated span [{t0}, {t1}] s"
                    ),
                ));
            }
        }
        Ok(())
    }
}

impl Mechanism {
    /// Validate the deck and build its nominal mechanism ([`Study::validate`],
    /// [`Study::build`]).
    pub(crate) fn validate(
        src: &Source,
        raw: &RawDeck,
        derivatives: bool,
    ) -> Result<Mechanism, CliError> {
        Study::validate(src, raw)?.build(src, derivatives)
    }

    /// The `f64` system of the nominal model at the start time, with the deck's step guard.
    pub(crate) fn system(&self) -> Result<MultibodySystem, mbs::ConstraintError> {
        let mut system =
            MultibodySystem::new_at(self.model.clone(), self.times[0], &self.state, self.policy)?;
        if let Some(v) = self.max_violation {
            let mut guard = system.guard();
            guard.max_violation = v;
            system.set_guard(guard);
        }
        Ok(system)
    }

    /// The mechanism at the design `b` (one value per design variable): the study moved there
    /// ([`Study::at`]) and built as this one was (with derivatives when this one has them),
    /// every body with `modes = "auto"` keeping the number of eigenmodes chosen here (so the
    /// state's layout and the responses that name modes stay those of this mechanism).
    pub(crate) fn at(&self, src: &Source, b: &[f64]) -> Result<Mechanism, CliError> {
        let mut study = self.study.at(src, b)?;
        for (f, part) in study.flexible_bodies.iter_mut().zip(&self.flexible) {
            fix_auto_modes(&mut f.def, part);
        }
        study.build(src, self.derivatives)
    }

    /// Design variables must move some flexible body; objectives of a run with sensitivities
    /// need responses that have them.
    fn check_design(&self, src: &Source) -> Result<(), DeckError> {
        for (j, v) in self.design.variables.iter().enumerate() {
            let direct = v.target.rigid().is_some() || v.target.gain().is_some();
            if !direct && !self.flexible.iter().any(|p| p.built.design.depends_on(j)) {
                return Err(src.error(
                    self.spans.variables.get(&v.name).cloned(),
                    Some(format!("design.{}", v.name)),
                    format!(
                        "the design variable ({}) changes no flexible body: no shell body and no \
                         beam body's section is made of it",
                        v.describe()
                    ),
                ));
            }
        }
        for o in &self.design.objectives {
            let r = self.response(&o.response);
            if !r.response.differentiable() {
                return Err(src.error(
                    self.spans
                        .objective_responses
                        .get(&o.name)
                        .cloned()
                        .flatten(),
                    Some(format!("objective.{}.response", o.name)),
                    format!(
                        "response `{}` has no design sensitivities (energies, constraint \
                         violations and reaction moments have none), so its objective has no \
                         gradient",
                        o.response
                    ),
                ));
            }
        }
        Ok(())
    }

    /// The response of this name (objectives refer to validated names).
    pub(crate) fn response(&self, name: &str) -> &ResponseDef {
        self.responses
            .iter()
            .find(|r| r.name == name)
            .expect("objective responses are validated")
    }

    /// The value of response `i` at one output.
    pub(crate) fn value(&self, i: usize, o: &Output) -> f64 {
        self.responses[i].response.value(&self.model, o)
    }

    /// The definition of flexible body `part` moved to the laminates `lam` of the design `b`,
    /// with the number of eigenmodes of this mechanism (`modes = "auto"` chose it here).
    fn part_at(
        &self,
        src: &Source,
        part: &FlexiblePart,
        lam: &LaminateModel,
        b: &[f64],
    ) -> Result<BodyDef, CliError> {
        let mut def = part.def.at(lam).map_err(|e| {
            at_design(
                src,
                format!("body `{}`", part.name),
                b,
                format!("its section: {e}"),
            )
        })?;
        flexible::move_own_section(&mut def, &self.design.variables, b);
        fix_auto_modes(&mut def, part);
        Ok(def)
    }

    /// The mechanism's model at the design `b`: every flexible body rebuilt from the laminates
    /// at `b`, its modes expressed in the nominal modes' basis (any basis of a repeated
    /// frequency, any sign), so that the nominal state means the same motion.
    pub(crate) fn model_at(&self, src: &Source, b: &[f64]) -> Result<Model<f64>, CliError> {
        let lam = self.laminates_at(src, b)?;
        let mut model = self.model.clone();
        for part in &self.flexible {
            let def = self.part_at(src, part, &lam, b)?;
            // the perturbed designs of finite differences: no check (nor its warning) again
            let (built, analysis, mut body, _) = flexible_body(
                src,
                &part.name,
                part.span.clone(),
                &def,
                DesignRequest::None,
                false,
            )?;
            if let Body::Flexible(reference) = self.model.body(part.id) {
                body.align_to(&reference.modal, CLUSTER_TOL)
                    .map_err(|e| at_design(src, format!("body `{}`", part.name), b, e))?;
            }
            let stresses = StressInput::of((src, &part.name), &def, &built, || {
                built.design.nominal_stress_parts()
            })?;
            let body = flexible_model_body(
                &part.name,
                &built.mesh,
                &built.props,
                &analysis,
                body,
                (def.stiffening, stresses),
            )
            .map_err(|e| fem_error(src, &part.name, part.span.clone(), e))?;
            *model.body_mut(part.id) = Body::Flexible(body);
        }
        for (v, &bj) in self.design.variables.iter().zip(b) {
            set_parameter(&mut model, self, &v.target, bj);
        }
        Ok(model)
    }
}

/// A body definition with `modes = "auto"` set to the number of eigenmodes the built `part`
/// has (its choice at that design).
fn fix_auto_modes(def: &mut BodyDef, part: &FlexiblePart) {
    if def.auto_modes {
        def.auto_modes = false;
        def.modes = part.analysis.n_modes;
        def.computed = part.analysis.n_modes;
    }
}

#[cfg(test)]
mod tests;
