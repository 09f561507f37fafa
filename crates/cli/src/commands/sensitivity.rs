//! The design-sensitivity part of `flexsens run`: the direct sensitivity integration (on the
//! mechanism's dual models, `dual_chunks`), response sensitivities, objectives with gradients
//! and the finite-difference comparisons the deck asks for.
//!
//! Chain (one code path from the ply angles up): the deck's `[design.*]` variables →
//! laminate and section derivatives (`modes::Design`) → `fem::analysis_derivatives` (frequencies
//! and mode shapes, fixed- or updated-mode) → `fem::modal_body_dual` per chunk of variables →
//! the mechanism's `Model<Dual<N>>` → `mbs::simulate_sensitivities`. Derivatives are per
//! degree of the design variables.

use nalgebra::DMatrix;

use mbs::{
    BdfOptions, FdScheme, MultibodySystem, Output, Perturbation, SensitivityOptions,
    SensitivityStatistics, State, Statistics,
};

use super::dual_chunks::DualChunks;
use crate::deck::Source;
use crate::deck::design::{FdSteps, SensitivityScheme};
use crate::error::CliError;
use crate::progress::RunProgress;
use crate::study::Mechanism;

/// Results of the direct sensitivity analysis, at the output times.
pub(crate) struct Sensitivities {
    pub(crate) outputs: Vec<Output>,
    pub(crate) statistics: Statistics,
    pub(crate) sensitivity_statistics: SensitivityStatistics,
    /// Per response of the mechanism: `dψ(t_i)/db_j` (rows: times), `None` when the response
    /// has no sensitivities.
    pub(crate) responses: Vec<Option<DMatrix<f64>>>,
    /// Per flexible body: `df_k/db_j` (Hz/deg; rows: modes).
    pub(crate) frequencies: Vec<(String, DMatrix<f64>)>,
    /// Options that replay the run's steps (finite differences of the discrete solution).
    pub(crate) replay: BdfOptions,
    /// With `sensitivity.method = "adjoint"`: per objective of the deck, its gradient (empty
    /// for an objective of a response without sensitivities), and the backward sweeps' work.
    /// With it, the memory of the run's states ([`mbs::CheckpointStatistics`]).
    pub(crate) adjoint: Option<(
        Vec<Vec<f64>>,
        mbs::AdjointStatistics,
        mbs::CheckpointStatistics,
    )>,
}

/// The analysis with its direct sensitivities, from the assembled `state`.
pub(crate) fn analyse(
    src: &Source,
    mech: &Mechanism,
    system: &mut MultibodySystem,
    state: &State,
) -> Result<Sensitivities, CliError> {
    // the chunk width changes the work, never the results
    match mech.design.variables.len() {
        1 => analyse_chunked::<1>(src, mech, system, state),
        2 => analyse_chunked::<2>(src, mech, system, state),
        3 | 4 => analyse_chunked::<4>(src, mech, system, state),
        _ => analyse_chunked::<8>(src, mech, system, state),
    }
}

/// The model build of a run with sensitivities, without the run ([`DualChunks`]).
pub(crate) fn prepare(src: &Source, mech: &Mechanism) -> Result<(), CliError> {
    match mech.design.variables.len() {
        0 => Ok(()),
        1 => DualChunks::<1>::new(src, mech)?.check_all(),
        2 => DualChunks::<2>::new(src, mech)?.check_all(),
        3 | 4 => DualChunks::<4>::new(src, mech)?.check_all(),
        _ => DualChunks::<8>::new(src, mech)?.check_all(),
    }
}

fn analyse_chunked<const N: usize>(
    src: &Source,
    mech: &Mechanism,
    system: &mut MultibodySystem,
    state: &State,
) -> Result<Sensitivities, CliError> {
    let by_adjoint = matches!(mech.design.method, SensitivityScheme::Adjoint);
    let chunks = DualChunks::<N>::with(src, mech, by_adjoint)?;
    let frequencies = chunks.frequencies();
    let mut options = match mech.design.method {
        SensitivityScheme::Direct => SensitivityOptions::default(),
        SensitivityScheme::Corrector => SensitivityOptions::corrector(),
        SensitivityScheme::Simultaneous => SensitivityOptions::simultaneous(),
        SensitivityScheme::Adjoint => {
            let a = super::adjoint::analyse(src, mech, system, state, &chunks)?;
            return Ok(Sensitivities {
                outputs: a.outputs,
                statistics: a.statistics,
                sensitivity_statistics: Default::default(),
                responses: vec![None; mech.responses.len()],
                frequencies,
                replay: replay_options(mech, (&a.times, &a.orders)),
                adjoint: Some((a.gradients, a.adjoint_statistics, a.checkpoints)),
            });
        }
    };
    options.error_control = mech.design.error_control;
    let design = chunks.design_model()?;
    let (t0, t_end) = (mech.times[0], *mech.times.last().expect("output times"));
    let run = mbs::simulate_sensitivities(
        system,
        &design,
        state,
        t0,
        t_end,
        mech.options.clone(),
        &options,
    )
    .map_err(|e| CliError::computation(src, e))?;
    let replay = replay_options(mech, (&run.times, &run.orders));
    let sampled = run.resample(&mech.times);
    let outputs = sampled
        .times
        .iter()
        .zip(&sampled.states)
        .map(|(&t, y)| system.output(t, y))
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| CliError::computation(src, e))?;
    let mut responses = Vec::new();
    for r in &mech.responses {
        responses.push(if r.response.differentiable() {
            Some(
                mbs::response_history(system, &design, &sampled, &r.response)
                    .map_err(|e| CliError::computation(src, e))?
                    .gradients,
            )
        } else {
            None
        });
    }
    Ok(Sensitivities {
        outputs,
        statistics: run.statistics,
        sensitivity_statistics: run.sensitivity_statistics,
        responses,
        frequencies,
        replay,
        adjoint: None,
    })
}

/// Options that replay `run`'s steps for the finite differences of the discrete solution.
/// Options that replay a run's steps (its `times` and `orders`, the initial point's
/// included).
pub(crate) fn replay_options(mech: &Mechanism, (times, orders): (&[f64], &[usize])) -> BdfOptions {
    // Newton of the replayed steps converges to `newton_tol` of the error weights
    // `atol + rtol |y|`: tight, but not below round-off when the tolerances are tiny (the
    // fixed-step integrator's are 1e-10 and 1e-12). The weights' absolute part is at most the
    // deck's `atol` on every component: displacement weights (`error_weights`) leave rates
    // and modal coordinates looser by ω or √m, and a replay converged only to those differs
    // from the discrete solution by more than the differences resolve
    let newton_tol = (1e-12 / mech.options.rtol).clamp(1e-6, 1e-2);
    let atol: Vec<f64> = (mech.options.atol.iter())
        .map(|a| a.min(mech.displacement_tolerance))
        .collect();
    BdfOptions::replay(
        times[1..].to_vec(),
        orders[1..].to_vec(),
        mech.options.rtol,
        atol,
        newton_tol,
    )
}

/// A computed objective.
pub(crate) struct ObjectiveResult {
    pub(crate) name: String,
    pub(crate) response: String,
    pub(crate) unit: &'static str,
    pub(crate) kind: mbs::Objective,
    pub(crate) window: Option<(f64, f64)>,
    pub(crate) value: f64,
    /// Where a maximum or minimum occurs.
    pub(crate) time: Option<f64>,
    /// Per design variable (empty without sensitivities).
    pub(crate) gradient: Vec<f64>,
}

/// The deck's objectives of the response histories `values` (one per response, at the output
/// times) with their gradients from the sensitivities when given: of the response histories,
/// or the adjoint method's.
pub(crate) fn objectives(
    src: &Source,
    mech: &Mechanism,
    values: &[Vec<f64>],
    sens: Option<&Sensitivities>,
) -> Result<Vec<ObjectiveResult>, CliError> {
    let gradients = sens.map(|s| s.responses.as_slice());
    let adjoint = sens.and_then(|s| s.adjoint.as_ref()).map(|a| &a.0);
    mech.design
        .objectives
        .iter()
        .enumerate()
        .map(|(k, o)| {
            let i = mech
                .responses
                .iter()
                .position(|r| r.name == o.response)
                .expect("validated objective");
            let g = gradients.and_then(|g| g[i].as_ref());
            let v = (o.kind.evaluate_in(o.window, &mech.times, &values[i], g)).map_err(|e| {
                CliError::Input(src.error(
                    None,
                    Some(format!("objective.{}", o.name)),
                    e.to_string(),
                ))
            })?;
            Ok(ObjectiveResult {
                name: o.name.clone(),
                response: o.response.clone(),
                unit: mech.responses[i].unit,
                kind: o.kind,
                window: o.window,
                value: v.value,
                time: v.time,
                gradient: adjoint.map_or(v.gradient, |a| a[k].clone()),
            })
        })
        .collect()
}

/// One finite-difference comparison: a scheme, a perturbation size and a step policy.
pub(crate) struct FdCase {
    /// e.g. `forward_relative_0.01_replay`.
    pub(crate) label: String,
    pub(crate) central: bool,
    pub(crate) relative: bool,
    pub(crate) size: f64,
    pub(crate) steps: FdSteps,
    /// Perturbation of each variable (degrees).
    pub(crate) deltas: Vec<f64>,
    /// Per response with sensitivities: `n × m` differences (as `Sensitivities::responses`).
    pub(crate) responses: Vec<Option<DMatrix<f64>>>,
    /// Per objective: the differences of its value, one per variable.
    pub(crate) objectives: Vec<Vec<f64>>,
    /// Per response with sensitivities, on replayed steps: the noise of the differences, one
    /// per variable — the largest change `δr` of the response when the first perturbed run's
    /// start is assembled and its Newton iterations go on to a tenth of their tolerances, over
    /// the perturbation `δ` (central: `δr / δ`, forward: `2 δr / δ`). `None` on adaptive steps
    /// (their noise is the step selection's) and when that tighter run fails (round-off can
    /// stop its iterations).
    pub(crate) noise: Vec<Option<Vec<f64>>>,
}

/// The factor by which the noise estimate's second run tightens the replays' Newton
/// tolerance ([`FdCase::noise`]).
const NOISE_TIGHTENING: f64 = 10.0;

/// The position tolerance (m) to which a perturbed run's start is assembled.
const PERTURBED_ASSEMBLY_TOL: f64 = 1e-10;

/// The response histories (differentiable responses, concatenated) and objective values of
/// the deck with the design `b`: the flexible bodies rebuilt at `b` ([`Mechanism::model_at`]),
/// the start assembled to `assembly_tol`.
#[allow(clippy::too_many_arguments)]
fn perturbed_outputs(
    src: &Source,
    mech: &Mechanism,
    nominal: &MultibodySystem,
    state: &State,
    b: &[f64],
    options: &BdfOptions,
    assembly_tol: f64,
    progress: Option<&RunProgress>,
) -> Result<Vec<f64>, CliError> {
    let model = mech.model_at(src, b)?;
    if let Some(p) = progress {
        p.next_phase();
    }
    let mut sys = nominal.with_model(model);
    let mut st = state.clone();
    if nominal.elastic_rates() {
        // elastic rates (and a prestress) that the nominal start gave a mechanism locked when
        // rigid are the assembly's: it makes them again for this design, from the velocities
        // and the elastic state the deck gives (the projection the sensitivities
        // differentiate starts there)
        st.v.clone_from(&mech.state.v);
        for id in sys.model().body_ids() {
            let qr = sys.model().q_range(id);
            st.q[qr.start + 7..qr.end].copy_from_slice(&mech.state.q[qr.start + 7..qr.end]);
        }
    }
    let t0 = mech.times[0];
    sys.assemble(t0, &mut st, assembly_tol)
        .map_err(|e| CliError::computation(src, format!("perturbed design {b:?}: {e}")))?;
    let sim = mbs::simulate(&mut sys, &st, &mech.times, options.clone())
        .map_err(|e| CliError::computation(src, format!("perturbed design {b:?}: {e}")))?;
    let mut out = Vec::new();
    let mut values = Vec::new();
    for r in &mech.responses {
        let v: Vec<f64> = sim
            .outputs
            .iter()
            .map(|o| r.response.value(sys.model(), o))
            .collect();
        if r.response.differentiable() {
            out.extend_from_slice(&v);
        }
        values.push(v);
    }
    for o in objectives(src, mech, &values, None)? {
        out.push(o.value);
    }
    Ok(out)
}

/// The noise of replayed runs per response (`None` for one without sensitivities): the
/// largest change of its history `values` (the design `b`'s replay with `options`) when the
/// replay's start is assembled and its Newton iterations go on to a tenth of their tolerances;
/// `None` for every response when that run fails.
#[allow(clippy::too_many_arguments)]
fn response_noise(
    src: &Source,
    mech: &Mechanism,
    nominal: &MultibodySystem,
    state: &State,
    b: &[f64],
    values: &[f64],
    options: &BdfOptions,
    progress: Option<&RunProgress>,
) -> Vec<Option<f64>> {
    let mut tight = options.clone();
    if let mbs::StepControl::Replay { newton_tol, .. } = &mut tight.control {
        *newton_tol /= NOISE_TIGHTENING;
    }
    let tighter = perturbed_outputs(
        src,
        mech,
        nominal,
        state,
        b,
        &tight,
        PERTURBED_ASSEMBLY_TOL / NOISE_TIGHTENING,
        progress,
    );
    let Ok(tighter) = tighter else {
        return vec![None; mech.responses.len()];
    };
    let n = mech.times.len();
    let mut row = 0;
    mech.responses
        .iter()
        .map(|r| {
            r.response.differentiable().then(|| {
                let d = (row..row + n)
                    .map(|i| (values[i] - tighter[i]).abs())
                    .fold(0.0, f64::max);
                row += n;
                d
            })
        })
        .collect()
}

/// Run the deck's finite-difference comparisons.
pub(crate) fn finite_differences(
    src: &Source,
    mech: &Mechanism,
    nominal: &MultibodySystem,
    state: &State,
    replay: &BdfOptions,
    progress: Option<&RunProgress>,
) -> Result<Vec<FdCase>, CliError> {
    let Some(fd) = &mech.design.finite_differences else {
        return Ok(Vec::new());
    };
    let b = mech.design_values();
    let m = b.len();
    let n = mech.times.len();
    let scheme = if fd.central {
        FdScheme::Central
    } else {
        FdScheme::Forward
    };
    let perturbations: Vec<Perturbation> = fd
        .sizes
        .iter()
        .map(|&s| {
            if fd.relative {
                Perturbation::Relative(s)
            } else {
                Perturbation::Absolute(s)
            }
        })
        .collect();
    let mut cases = Vec::new();
    for &steps in &fd.steps {
        let options = match steps {
            FdSteps::Replay => replay.clone(),
            FdSteps::Adaptive => mech.options.clone(),
        };
        // the perturbed runs are independent: one per core, the results in the serial order
        let designs = mbs::finite_difference_designs(&b, scheme, &perturbations);
        let values =
            super::parallel_map(designs.len(), super::job_count(None, designs.len()), |i| {
                perturbed_outputs(
                    src,
                    mech,
                    nominal,
                    state,
                    &designs[i],
                    &options,
                    PERTURBED_ASSEMBLY_TOL,
                    progress,
                )
            })
            .into_iter()
            .collect::<Result<Vec<_>, _>>()?;
        let noise = match steps {
            FdSteps::Replay => Some(response_noise(
                src,
                mech,
                nominal,
                state,
                &designs[0],
                &values[0],
                &options,
                progress,
            )),
            FdSteps::Adaptive => None,
        };
        let results = mbs::finite_differences_from(&b, scheme, &perturbations, &values);
        for r in results {
            let mut responses = Vec::new();
            let mut row = 0;
            for resp in &mech.responses {
                if resp.response.differentiable() {
                    responses.push(Some(r.derivative.rows(row, n).into_owned()));
                    row += n;
                } else {
                    responses.push(None);
                }
            }
            let objectives = (0..mech.design.objectives.len())
                .map(|k| (0..m).map(|j| r.derivative[(row + k, j)]).collect())
                .collect();
            let size = match r.perturbation {
                Perturbation::Relative(s) | Perturbation::Absolute(s) => s,
            };
            let per_variable = |dr: f64| -> Vec<f64> {
                let factor = if fd.central { 1.0 } else { 2.0 };
                r.steps.iter().map(|d| factor * dr / d.abs()).collect()
            };
            // (`response_noise` leaves the responses without sensitivities out)
            let noise = (0..mech.responses.len())
                .map(|i| noise.as_ref()?[i].map(per_variable))
                .collect();
            cases.push(FdCase {
                label: format!(
                    "{}_{}_{size}_{}",
                    if fd.central { "central" } else { "forward" },
                    if fd.relative { "relative" } else { "absolute" },
                    match steps {
                        FdSteps::Replay => "replay",
                        FdSteps::Adaptive => "adaptive",
                    }
                ),
                central: fd.central,
                relative: fd.relative,
                size,
                steps,
                deltas: r.steps,
                responses,
                objectives,
                noise,
            });
        }
    }
    Ok(cases)
}

/// The largest difference between two derivative histories relative to the largest magnitude
/// of `reference` (per variable, the worst variable).
pub(crate) fn relative_difference(a: &DMatrix<f64>, reference: &DMatrix<f64>) -> f64 {
    (0..reference.ncols())
        .map(|j| {
            let scale = reference.column(j).amax();
            let diff = (a.column(j) - reference.column(j)).amax();
            if scale > 0.0 { diff / scale } else { diff }
        })
        .fold(0.0, f64::max)
}

/// A finite difference within this many times its estimated noise of the direct derivative
/// is reported as not resolved.
const NOISE_MARGIN: f64 = 3.0;

/// The lines of a run's summary text on its finite-difference comparisons (`summary`: the run's
/// JSON summary): each case's largest relative difference per response, marked where it is
/// within its noise.
pub(crate) fn fd_summary_text(summary: &serde_json::Value) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    if let Some(cases) = summary["finite_differences"].as_array()
        && !cases.is_empty()
    {
        // the adjoint method gives the objectives' gradients alone
        let adjoint = cases.iter().all(|c| {
            (c["max_relative_difference"].as_object()).is_none_or(|m| m.is_empty())
                && (c["objectives"].as_object()).is_some_and(|m| !m.is_empty())
        });
        let _ = writeln!(
            s,
            "finite differences: {}",
            match adjoint {
                true => "largest |FD − adjoint| / max |adjoint| per objective",
                false => "largest |FD − direct| / max |direct| per response",
            }
        );
        let mut unresolved = false;
        for case in cases {
            let worst = case["max_relative_difference"]
                .as_object()
                .map(|m| {
                    m.iter()
                        .map(|(k, v)| {
                            let v = v.as_f64().unwrap_or(f64::NAN);
                            match case["relative_noise"][k].as_f64() {
                                // a difference within a few times the noise resolves nothing
                                Some(noise) if v <= NOISE_MARGIN * noise => {
                                    unresolved = true;
                                    format!("{k} {v:.2e} (noise {noise:.1e}: not resolved)")
                                }
                                _ => format!("{k} {v:.2e}"),
                            }
                        })
                        .collect::<Vec<_>>()
                        .join(", ")
                })
                .unwrap_or_default();
            // without response sensitivities (the adjoint method): the objectives' gradients
            let worst = match worst.is_empty() {
                true => (case["objectives"].as_object().into_iter().flatten())
                    .map(|(k, v)| format!("objective {k} {:.2e}", v.as_f64().unwrap_or(f64::NAN)))
                    .collect::<Vec<_>>()
                    .join(", "),
                false => worst,
            };
            let _ = writeln!(s, "  {:<36} {worst}", case["case"].as_str().unwrap_or(""));
        }
        if unresolved {
            let _ = writeln!(
                s,
                "  (not resolved: the replays' Newton tolerance over the perturbation is as large \
                 as the difference; a larger perturbation or sensitivity.method = \"direct\" \
                 resolves more)"
            );
        }
    }
    s
}
