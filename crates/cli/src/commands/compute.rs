//! The computation of `flexsens run` (and of each lay-up of `flexsens report`): the
//! analysis, its direct sensitivities, the objectives and the finite-difference comparisons,
//! from a validated [`Study`].

use mbs::Output;

use super::sensitivity::{self, FdCase, ObjectiveResult, Sensitivities};
use crate::deck;
use crate::error::CliError;
use crate::study::Study;

/// Everything a run computed, ready to be written.
pub(crate) struct Computed {
    pub(crate) outputs: Vec<Output>,
    pub(crate) statistics: mbs::Statistics,
    /// Per response: its history at the output times.
    pub(crate) values: Vec<Vec<f64>>,
    pub(crate) sensitivities: Option<Sensitivities>,
    pub(crate) objectives: Vec<ObjectiveResult>,
    pub(crate) fd: Vec<FdCase>,
}

/// The analysis, its sensitivities, objectives and finite-difference comparisons.
pub(crate) fn compute(src: &deck::Source, mech: &Study) -> Result<Computed, CliError> {
    let runtime = |m: String| CliError::Runtime(format!("{}: {m}", src.file.display()));
    let mut system = mech.system().map_err(|e| runtime(e.to_string()))?;
    let mut state = mech.state.clone();
    system
        .assemble(mech.times[0], &mut state, 1e-10)
        .map_err(|e| {
            runtime(format!(
                "the initial configuration cannot be assembled: {e}"
            ))
        })?;
    if let Some(p) = &mech.progress {
        system.set_progress(Some(p.observer()));
        if mech.design.enabled
            && let Some(fd) = &mech.design.finite_differences
        {
            let m = mech.design.variables.len();
            let k = fd.sizes.len();
            let per_steps = if fd.central { 2 * m * k } else { 1 + m * k };
            p.add_phases(per_steps * fd.steps.len());
        }
    }
    let (outputs, statistics, sens) = if mech.design.enabled {
        let s = sensitivity::analyse(src, mech, &mut system, &state)?;
        (s.outputs.clone(), s.statistics, Some(s))
    } else {
        let sim = mbs::simulate(&mut system, &state, &mech.times, mech.options.clone())
            .map_err(|e| runtime(e.to_string()))?;
        (sim.outputs, sim.statistics, None)
    };
    let values: Vec<Vec<f64>> = (0..mech.responses.len())
        .map(|i| outputs.iter().map(|o| mech.value(i, o)).collect())
        .collect();
    let objectives = sensitivity::objectives(
        src,
        mech,
        &values,
        sens.as_ref().map(|s| s.responses.as_slice()),
    )?;
    let fd = match &sens {
        Some(s) => sensitivity::finite_differences(src, mech, &system, &state, &s.replay)?,
        None => Vec::new(),
    };
    Ok(Computed {
        outputs,
        statistics,
        values,
        sensitivities: sens,
        objectives,
        fd,
    })
}
