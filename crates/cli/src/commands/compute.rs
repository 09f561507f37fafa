//! The computation of `flexsens run` (and of each lay-up of `flexsens report`): the
//! analysis, its direct sensitivities, the objectives and the finite-difference comparisons,
//! from a built [`Mechanism`].

use mbs::Output;

use super::sensitivity::{self, FdCase, ObjectiveResult, Sensitivities};
use crate::deck;
use crate::error::CliError;
use crate::progress::RunProgress;
use crate::study::Mechanism;

/// Everything a run computed, ready to be written.
pub(crate) struct Computed {
    pub(crate) outputs: Vec<Output>,
    pub(crate) statistics: mbs::Statistics,
    /// Per response: its history at the output times.
    pub(crate) values: Vec<Vec<f64>>,
    pub(crate) sensitivities: Option<Sensitivities>,
    pub(crate) objectives: Vec<ObjectiveResult>,
    pub(crate) fd: Vec<FdCase>,
    /// A loose adaptive run's estimate of each response's history error, relative to the
    /// response's largest magnitude ([`history_error`]; `None` for a constraint violation);
    /// `None` for other runs.
    pub(crate) history_error: Option<Vec<Option<f64>>>,
}

/// The relative tolerance from which an adaptive run estimates the error of its histories.
pub(crate) const LOOSE_RTOL: f64 = 1e-3;

/// The history error above which a loose run warns, relative to the response's largest
/// magnitude.
const HISTORY_WARNING: f64 = 0.01;

/// The analysis, its sensitivities, objectives and finite-difference comparisons (`progress`:
/// the progress bar, when one is shown).
pub(crate) fn compute(
    src: &deck::Source,
    mech: &Mechanism,
    progress: Option<&RunProgress>,
) -> Result<Computed, CliError> {
    let runtime = |reason: String| CliError::Computation {
        file: src.file.clone(),
        reason,
    };
    let (mut system, state) = assembled(src, mech)?;
    warn_redundant_with_stiffening(src, mech, &system, &state);
    if let Some(p) = progress {
        system.set_progress(Some(p.observer()));
        if mech.design.enabled
            && let Some(fd) = &mech.design.finite_differences
        {
            let m = mech.design.variables.len();
            let k = fd.sizes.len();
            let per_steps = if fd.central { 2 * m * k } else { 1 + m * k };
            // and one run more for the noise of the replayed differences
            let replays = fd
                .steps
                .iter()
                .filter(|s| matches!(s, crate::deck::design::FdSteps::Replay))
                .count();
            p.add_phases(per_steps * fd.steps.len() + replays);
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
    warn_fixed_step_accuracy(src, mech, &statistics);
    let values: Vec<Vec<f64>> = (0..mech.responses.len())
        .map(|i| outputs.iter().map(|o| mech.value(i, o)).collect())
        .collect();
    let history_error = history_error(src, mech, &values);
    let objectives = sensitivity::objectives(src, mech, &values, sens.as_ref())?;
    let fd = match &sens {
        Some(s) => {
            sensitivity::finite_differences(src, mech, &system, &state, &s.replay, progress)?
        }
        None => Vec::new(),
    };
    Ok(Computed {
        outputs,
        statistics,
        values,
        sensitivities: sens,
        objectives,
        fd,
        history_error,
    })
}

/// The mechanism's system and its initial state assembled (the positions made consistent
/// with the joints, the redundant equations chosen).
pub(crate) fn assembled(
    src: &deck::Source,
    mech: &Mechanism,
) -> Result<(mbs::MultibodySystem, mbs::State), CliError> {
    let fail = |reason: String| CliError::Computation {
        file: src.file.clone(),
        reason,
    };
    let mut system = mech.system().map_err(|e| fail(e.to_string()))?;
    let mut state = mech.state.clone();
    system
        .assemble(mech.times[0], &mut state, 1e-10)
        .map_err(|e| {
            fail(format!(
                "the initial configuration cannot be assembled: {e}"
            ))
        })?;
    if system.elastic_rates() && system.elastic_start().is_none() {
        src.warn(
            None,
            None,
            "the drivers' speeds cannot be met by the bodies moving rigidly (the mechanism is \
             locked when its bodies are rigid: a misaligned joint?): the start gives the \
             flexible bodies elastic rates, the least kinetic energy that meets them, and the \
             mechanism moves by deforming"
                .to_string(),
        );
    }
    if let Some(prestress) = system.elastic_start() {
        src.warn(
            None,
            None,
            format!(
                "the joints cannot be met by moving the bodies rigidly (a misaligned joint?): \
                 the start deforms the flexible bodies to meet them at the least strain energy, \
                 the static equilibrium of the locked frame ({}), and the run starts from that \
                 prestressed state",
                describe_prestress(prestress)
            ),
        );
    }
    Ok((system, state))
}

/// An elastic start's prestress in words: the strain energy by body and the largest joint
/// force.
pub(crate) fn describe_prestress(p: &mbs::ElasticStart) -> String {
    let bodies: Vec<String> = p
        .bodies
        .iter()
        .map(|(name, e)| format!("`{name}` {e:.3e} J"))
        .collect();
    format!(
        "strain energy {:.3e} J: {}; the largest joint force {:.3e} N, at `{}`",
        p.energy(),
        bodies.join(", "),
        p.force,
        p.joint
    )
}

/// The error of a loose adaptive run's histories (`rtol` at least [`LOOSE_RTOL`]): a step's
/// local error control leaves a history free to drift (in phase, typically) by much more than
/// `rtol`. Estimated by the same analysis at a tenth of the tolerances, whose error is about a
/// tenth: per response, the largest difference of the two histories relative to the largest
/// magnitude of the tighter one, with a warning at `analysis.rtol` above 1 % (a constraint
/// violation, which measures the integrator's own error, has none). `None` for a fixed-step
/// or tight run, or when the tighter run fails (then with a warning).
fn history_error(
    src: &deck::Source,
    mech: &Mechanism,
    values: &[Vec<f64>],
) -> Option<Vec<Option<f64>>> {
    if !matches!(mech.options.control, mbs::StepControl::Adaptive { .. })
        || mech.options.rtol < LOOSE_RTOL
        || values.is_empty()
    {
        return None;
    }
    let mut options = mech.options.clone();
    options.rtol /= 10.0;
    options.atol.iter_mut().for_each(|a| *a /= 10.0);
    let tighter = assembled(src, mech).ok().and_then(|(mut system, state)| {
        mbs::simulate(&mut system, &state, &mech.times, options).ok()
    });
    let Some(tighter) = tighter else {
        src.warn(
            None,
            Some("analysis.rtol".into()),
            "the run at a tenth of the tolerances, which estimates this loose run's history \
             error, failed: the histories' error is not known",
        );
        return None;
    };
    let errors: Vec<Option<f64>> = values
        .iter()
        .zip(&mech.responses)
        .enumerate()
        .map(|(i, (loose, r))| {
            if matches!(r.response, mbs::Response::ConstraintViolation) {
                return None;
            }
            let tight: Vec<f64> = tighter.outputs.iter().map(|o| mech.value(i, o)).collect();
            let scale = tight.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            let diff = loose
                .iter()
                .zip(&tight)
                .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
            Some(if scale > 0.0 { diff / scale } else { diff })
        })
        .collect();
    for (r, e) in mech.responses.iter().zip(&errors) {
        if let Some(e) = e
            && *e > HISTORY_WARNING
        {
            src.warn(
                None,
                Some("analysis.rtol".into()),
                format!(
                    "the history of response `{}` is estimated to be off by {:.1} % of its \
                     largest value (a run at a tenth of the tolerances differs by that much): \
                     at rtol = {} the steps' local errors add up along the run; tighten rtol",
                    r.name,
                    100.0 * e,
                    mech.options.rtol
                ),
            );
        }
    }
    Some(errors)
}

/// A warning when a stiffened flexible body with three-dimensional modes moves in a mechanism
/// whose joints hold the rigid motions more than once: the equations that only the bodies'
/// modes make independent have reactions the rigid mechanism does not determine (as large as
/// the stiff modes they strain), and the body's second-order field turns them into stiffness
/// (docs/geometric-stiffening.md, "Redundant constraints"). Planar modes leave the redundant
/// directions (out of the plane) without a field.
pub(crate) fn warn_redundant_with_stiffening(
    src: &deck::Source,
    mech: &Mechanism,
    system: &mbs::MultibodySystem,
    state: &mbs::State,
) {
    let stiffened: Vec<&str> = mech
        .flexible
        .iter()
        .filter(|p| p.stiffening && p.def.planar.is_none())
        .map(|p| p.name.as_str())
        .collect();
    if stiffened.is_empty() {
        return;
    }
    let model = system.model();
    let jacobian = model
        .constraints(mech.times[0], &state.q, &state.v)
        .jacobian;
    // the rows that depend on the rows before them in the frames' columns alone
    let frames: Vec<usize> = model
        .body_ids()
        .flat_map(|id| model.v_range(id).start..model.v_range(id).start + 6)
        .collect();
    let mut kept: Vec<nalgebra::DVector<f64>> = Vec::new();
    let mut joints: Vec<&str> = Vec::new();
    for r in 0..jacobian.nrows() {
        let row = nalgebra::DVector::from_iterator(
            frames.len(),
            frames.iter().map(|&c| jacobian[(r, c)]),
        );
        let mut rest = row.clone();
        for k in &kept {
            rest -= k * k.dot(&rest);
        }
        if rest.norm() > 1e-8 * row.norm().max(f64::MIN_POSITIVE) {
            kept.push(rest.normalize());
        } else {
            let name = model.joint(model.joint_of_row(r)).name.as_str();
            if !joints.contains(&name) {
                joints.push(name);
            }
        }
    }
    let redundant = jacobian.nrows() - kept.len();
    if redundant == 0 {
        return;
    }
    src.warn(
        None,
        None,
        format!(
            "{redundant} joint equations hold rigid motions that other joints already hold (at \
             {}): only the flexible bodies' modes make them independent, so their reactions are \
             not determined by the mechanism, and the second-order field of the stiffened body \
             {} turns them into stiffness; state joints that hold the mechanism once (e.g. a \
             spherical and a universal joint at a rod's ends instead of two revolute joints), \
             or set stiffening = false on the body",
            joints.join(", "),
            stiffened.join(", ")
        ),
    );
}

/// A warning when a fixed-step run's estimated local error exceeds the deck's tolerances
/// (`mbs::Statistics::max_error_ratio`): its results are not converged to them.
fn warn_fixed_step_accuracy(src: &deck::Source, mech: &Mechanism, st: &mbs::Statistics) {
    let (mbs::StepControl::Fixed { step, .. }, Some((rtol, _))) =
        (&mech.options.control, &mech.options.accuracy)
    else {
        return;
    };
    if st.max_error_ratio > 1.0 {
        src.warn(
            None,
            Some("analysis.step".into()),
            format!(
                "the fixed step of {step} s misses the deck's local error tolerances (rtol = \
                 {rtol}, atol = {}{}) by up to {:.1} times, estimated as the adaptive \
                 integrator estimates it: the results are not converged to those tolerances; \
                 take a smaller step, or integrator = \"adaptive\"",
                mech.displacement_tolerance,
                if mech.displacement_weights { " m" } else { "" },
                st.max_error_ratio
            ),
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::deck::Source;

    /// `Mechanism::at` (the optimiser's path) and `Study::at` then `build` (the sweep's and the
    /// report's) give the mechanism of the deck validated with the variables written at that
    /// design (the text path `--set` takes): the same frequencies and, run, the same response
    /// histories and sensitivities, bit for bit. Every kind of variable: ply angle, ply
    /// thickness, material constant, rigid mass. A second move from the moved mechanism
    /// (the finite differences of a moved design) agrees to round-off: it sums the two moves
    /// in another order.
    #[test]
    fn a_study_moved_to_a_design_is_the_deck_validated_there() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../decks");
        let text = std::fs::read_to_string(dir.join("slider_crank_beam.toml")).unwrap()
            + "\n[design.outer]\nkind = \"ply-thickness\"\nlaminate = \"tube_wall\"\n\
               plies = [2, 3]\n\n[design.e1]\nkind = \"material\"\n\
               material = \"paper_composite\"\nconstant = \"E1\"\n\
               \n[design.slider_mass]\nkind = \"rigid-mass\"\nbody = \"slider\"\n";
        let short = ["analysis.t_end=0.01".to_string()];
        let src = Source::new("beam.toml", text)
            .with_overrides(&short)
            .unwrap();
        let mut nominal = Mechanism::validate(&src, &src.parse().unwrap(), true).unwrap();
        nominal.design.finite_differences = None;
        let b0 = nominal.design_values();
        let b: Vec<f64> = b0.iter().map(|x| x * 1.07).collect();
        let b2: Vec<f64> = b0.iter().map(|x| x * 0.96).collect();
        let moved = nominal.at(&src, &b).unwrap();
        let built = nominal
            .study
            .at(&src, &b)
            .unwrap()
            .build(&src, true)
            .unwrap();
        let moved_twice = moved.at(&src, &b2).unwrap();
        for (b, moved, tol) in [
            (&b, &moved, 0.0),
            (&b, &built, 0.0),
            (&b2, &moved_twice, 1e-9),
        ] {
            let mut sets = short.to_vec();
            for (v, &x) in nominal.design.variables.iter().zip(b.iter()) {
                sets.extend(v.overrides(x));
            }
            let there_src = src.edited(&sets).unwrap();
            let mut there =
                Mechanism::validate(&there_src, &there_src.parse().unwrap(), true).unwrap();
            there.design.finite_differences = None;
            for (v, w) in moved.design.variables.iter().zip(&there.design.variables) {
                assert!(
                    (v.value - w.value).abs() <= tol * v.value.abs(),
                    "{}",
                    v.name
                );
            }
            let (fa, fb) = (
                &moved.bodies["rod"].frequencies,
                &there.bodies["rod"].frequencies,
            );
            assert_eq!(fa.len(), fb.len());
            for (x, y) in fa.iter().zip(fb) {
                assert!((x - y).abs() <= tol * y, "frequency {x} vs {y}");
            }
            let f0 = &nominal.bodies["rod"].frequencies;
            assert!(
                (fa[0] - f0[0]).abs() > 1e-3 * f0[0],
                "the design moves the rod"
            );
            let ca = compute(&src, moved, None).unwrap();
            let cb = compute(&there_src, &there, None).unwrap();
            let close = |a: &[f64], b: &[f64], what: &str| {
                let scale = b.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
                let worst = a
                    .iter()
                    .zip(b)
                    .fold(0.0_f64, |m, (x, y)| m.max((x - y).abs()));
                assert!(worst <= tol * scale, "{what}: {worst:e} of {scale:e}");
            };
            for (i, r) in moved.responses.iter().enumerate() {
                close(&ca.values[i], &cb.values[i], &r.name);
                let (sa, sb) = (ca.sensitivities.as_ref(), cb.sensitivities.as_ref());
                if let (Some(Some(x)), Some(Some(y))) =
                    (sa.map(|s| &s.responses[i]), sb.map(|s| &s.responses[i]))
                {
                    close(x.as_slice(), y.as_slice(), &format!("d {}/db", r.name));
                }
            }
        }
    }
}
