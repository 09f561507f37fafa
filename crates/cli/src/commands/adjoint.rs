//! `sensitivity.method = "adjoint"`: the analysis recording its steps, then each objective's
//! gradient by the discrete adjoint (`mbs::adjoint_gradient`, docs/design.md §3): one backward
//! sweep per objective whatever the number of design variables, the same numbers as the
//! direct method's. The responses' sensitivity histories are not computed.

use mbs::{DesignModel, MultibodySystem, ObjectiveTerm, State};

use super::dual_chunks::DualChunks;

use crate::deck::Source;
use crate::error::CliError;
use crate::study::Mechanism;

/// What the adjoint method computed.
pub(crate) struct AdjointRun {
    /// The run's steps: times (the initial one included) and orders.
    pub(crate) times: Vec<f64>,
    pub(crate) orders: Vec<usize>,
    /// The run's integrator counters.
    pub(crate) statistics: mbs::Statistics,
    /// The memory its states took ([`mbs::simulate_checkpointed`]).
    pub(crate) checkpoints: mbs::CheckpointStatistics,
    /// The outputs at the deck's output times.
    pub(crate) outputs: Vec<mbs::Output>,
    /// Per objective of the deck, its gradient (empty for an objective of a response without
    /// sensitivities).
    pub(crate) gradients: Vec<Vec<f64>>,
    pub(crate) adjoint_statistics: mbs::AdjointStatistics,
}

/// The analysis from the assembled `state` and the gradient of every objective of the deck by
/// the adjoint method: the backward sweep at the model's data, then its contraction with the
/// design derivatives of the data, one chunk of `N` variables of `chunks` at a time (built,
/// contracted and dropped: the memory of one chunk's dual model).
pub(crate) fn analyse<const N: usize>(
    src: &Source,
    mech: &Mechanism,
    system: &mut MultibodySystem,
    state: &State,
    chunks: &DualChunks<N>,
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
    let budget = mech.design.adjoint_memory;
    let (mut run, states) = mbs::simulate_checkpointed(
        system,
        state,
        (t0, t_end),
        mech.options.clone(),
        &mech.times,
        budget,
    )
    .map_err(|e| CliError::computation(src, e))?;
    let outputs = (mech.times.iter().zip(&states))
        .map(|(&t, y)| system.output(t, y))
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| CliError::computation(src, e))?;
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
    let m = mech.design.variables.len();
    let mut gradients = vec![Vec::new(); objectives.len()];
    let mut statistics = mbs::AdjointStatistics::default();
    if m > 0 && objectives.iter().any(|terms| !terms.is_empty()) {
        // the data the adjoints are of: the first chunk's (its values are the model's)
        let ranges = chunks.ranges();
        let mut first = Some(chunks.chunk(&ranges[0])?);
        let taped_model = first.as_ref().expect("first chunk");
        let sweep = mbs::adjoint_sweep(system, taped_model, &mut run, &objectives)
            .map_err(|e| CliError::computation(src, e))?;
        statistics = sweep.statistics;
        // an objective of a response without sensitivities keeps an empty gradient
        for (g, terms) in gradients.iter_mut().zip(&objectives) {
            if !terms.is_empty() {
                g.resize(m, 0.0);
            }
        }
        // the eigenvector derivatives left to the adjoint (`DualChunks::with`): their part of
        // the gradients, or, where the initial state's sensitivities are read (they take in
        // the modes' derivatives), the chunks made with them
        let explicit;
        let chunks = match chunks.eigenvectors_by_adjoint() {
            true if sweep.needs_initial_sensitivities() => {
                first = None;
                explicit = DualChunks::<N>::new(src, mech)?;
                &explicit
            }
            true => {
                let swept = first
                    .as_ref()
                    .expect("the first chunk, not yet contracted")
                    .values();
                let parts = chunks.eigenvector_gradients(&swept, sweep.data_adjoints())?;
                for (g, part) in gradients.iter_mut().zip(parts) {
                    g.iter_mut().zip(part).for_each(|(g, p)| *g += p);
                }
                chunks
            }
            false => chunks,
        };
        for range in ranges {
            let chunk = match first.take() {
                Some(chunk) => chunk,
                None => chunks.chunk(&range)?,
            };
            let design = DesignModel::new(vec![chunk], range.len())
                .map_err(|e| CliError::computation(src, e))?;
            // (read only where the start deformed the bodies or gave them elastic rates: the
            // sweep took the initial state's adjoint back through the start otherwise)
            let s0 = if sweep.needs_initial_sensitivities() {
                mbs::initial_sensitivities(system, &design, t0, state)
                    .map_err(|e| CliError::computation(src, e))?
            } else {
                nalgebra::DMatrix::zeros(state.q.len() + state.v.len(), range.len())
            };
            let chunk_gradients = sweep.gradients(&design.chunks()[0], &s0);
            for (g, chunk_g) in gradients.iter_mut().zip(chunk_gradients) {
                if !g.is_empty() {
                    (g[range.clone()].iter_mut())
                        .zip(chunk_g)
                        .for_each(|(g, c)| *g += c);
                }
            }
        }
    }
    Ok(AdjointRun {
        checkpoints: run.checkpoint_statistics(),
        times: run.times,
        orders: run.orders,
        statistics: run.statistics,
        outputs,
        gradients,
        adjoint_statistics: statistics,
    })
}
