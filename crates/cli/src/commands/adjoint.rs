//! `sensitivity.method = "adjoint"`: the analysis recording its steps, then each objective's
//! gradient by the discrete adjoint (`mbs::adjoint_gradient`, docs/design.md §3): one backward
//! sweep per objective whatever the number of design variables, the same numbers as the
//! direct method's. The responses' sensitivity histories are not computed.

use mbs::{DesignModel, MultibodySystem, ObjectiveTerm, State};

use crate::deck::Source;
use crate::error::CliError;
use crate::study::Mechanism;

fn runtime(src: &Source, m: impl std::fmt::Display) -> CliError {
    CliError::Computation {
        file: src.file.clone(),
        reason: m.to_string(),
    }
}

/// What the adjoint method computed.
pub(crate) struct AdjointRun {
    /// The run, every accepted step recorded.
    pub(crate) run: mbs::SensitivityRun,
    /// The outputs at the deck's output times.
    pub(crate) outputs: Vec<mbs::Output>,
    /// Per objective of the deck, its gradient (empty for an objective of a response without
    /// sensitivities).
    pub(crate) gradients: Vec<Vec<f64>>,
    pub(crate) statistics: mbs::AdjointStatistics,
}

/// The analysis from the assembled `state` and the gradient of every objective of the deck by
/// the adjoint method, with the design model's chunks `design` (their tangents are the design
/// derivatives of the model's data).
pub(crate) fn analyse<const N: usize>(
    src: &Source,
    mech: &Mechanism,
    system: &mut MultibodySystem,
    state: &State,
    design: &DesignModel<N>,
) -> Result<AdjointRun, CliError> {
    if mech.design.objectives.is_empty() {
        src.warn(
            None,
            Some("sensitivity.method".into()),
            "the adjoint method gives the gradients of the deck's objectives, and it declares \
             none: the run computes no sensitivities (declare an [objective.*] table, or use \
             another method for the responses' sensitivities)",
        );
    }
    let (t0, t_end) = (mech.times[0], *mech.times.last().expect("output times"));
    let run = mbs::simulate_steps(system, state, t0, t_end, mech.options.clone())
        .map_err(|e| runtime(src, e))?;
    let sampled = run.resample(&mech.times);
    let outputs = (sampled.times.iter().zip(&sampled.states))
        .map(|(&t, y)| system.output(t, y))
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| runtime(src, e))?;
    let s0 = mbs::initial_sensitivities(system, design, t0, state).map_err(|e| runtime(src, e))?;
    // each differentiable objective's terms (one: its response on the output times)
    let mut objectives = Vec::new();
    for o in &mech.design.objectives {
        let i = (mech.responses.iter())
            .position(|r| r.name == o.response)
            .expect("validated objective");
        let response = &mech.responses[i].response;
        if !response.differentiable() {
            objectives.push(Vec::new());
            continue;
        }
        let values: Vec<f64> = outputs.iter().map(|out| mech.value(i, out)).collect();
        let weights = (o.kind.weights_in(o.window, &mech.times, &values)).map_err(|e| {
            CliError::Input(src.error(None, Some(format!("objective.{}", o.name)), e.to_string()))
        })?;
        objectives.push(vec![ObjectiveTerm {
            response: response.clone(),
            times: mech.times.clone(),
            weights: weights.weights,
        }]);
    }
    let (mut gradients, statistics) =
        mbs::adjoint_gradients(system, design, &run, &s0, &objectives)
            .map_err(|e| runtime(src, e))?;
    for (g, terms) in gradients.iter_mut().zip(&objectives) {
        if terms.is_empty() {
            g.clear();
        }
    }
    Ok(AdjointRun {
        run,
        outputs,
        gradients,
        statistics,
    })
}
