//! `flexsens report`: the paper's §5 figures (Neto, Ambrósio & Leal 2008, Figs. 5, 6, 8–13)
//! regenerated with flexsens results for several lay-ups, as SVG and PNG, with a summary.
//!
//! For every lay-up (a value of the deck's first design variable) the deck is run in-process
//! four times, each with the settings one figure needs:
//!
//! - `main`: updated modes, the deck's (variable-step) integrator, forward differences at
//!   0.1 %, 1 % and 5 % on the replayed and on adaptive step sequences (Figs. 5/8, 6c, 11–13);
//! - `fixed-modes`: the sensitivities with the modes kept fixed (Figs. 9, 10);
//! - `fixed-step`: a fixed-step integrator, forward differences at 1 % (Fig. 6b);
//! - `central`: central differences of relative size 1e-4 on the replayed steps (the check
//!   in the summary).
//!
//! The lay-up and `analysis.integrator`/`analysis.step` are applied as `--set` overrides of the
//! deck; the sensitivity and finite-difference settings are set on the validated design, so a
//! deck needs no `[sensitivity]` or `[finite_differences]` table (those it has are replaced).

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use serde_json::json;

use super::compute::compute;
use super::sensitivity::relative_difference;
use crate::deck::design::{FdDef, FdSteps, SensitivityScheme};
use crate::deck::{self, RawDeck, Source};
use crate::error::CliError;
use crate::files::write_atomic;
use crate::plot::{Figure, Panel, Series};
use crate::study::Study;

/// Forward-difference sizes of Figs. 11–13 (relative).
const SIZES: [f64; 3] = [0.001, 0.01, 0.05];
/// The forward-difference size of Fig. 6 (relative).
const FIG6_SIZE: f64 = 0.01;
/// Central-difference size of the summary's check (relative).
const CHECK_SIZE: f64 = 1e-4;

/// What to report.
pub struct ReportRequest<'a> {
    /// Output directory (default: `<deck name>.report` beside the deck).
    pub out: Option<&'a Path>,
    /// The lay-ups: comma-separated values of the first design variable (degrees).
    pub layups: &'a str,
    /// Step of the fixed-step runs (default: a tenth of the output step).
    pub fixed_step: Option<f64>,
    /// Runs at once (default: the available cores).
    pub jobs: Option<usize>,
}

/// The four runs of one lay-up.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    Main,
    FixedModes,
    FixedStep,
    Central,
}

impl Kind {
    const ALL: [Kind; 4] = [Kind::Main, Kind::FixedModes, Kind::FixedStep, Kind::Central];

    fn name(self) -> &'static str {
        match self {
            Kind::Main => "main",
            Kind::FixedModes => "fixed-modes",
            Kind::FixedStep => "fixed-step",
            Kind::Central => "central",
        }
    }
}

/// One finite-difference history of the mid-node deflection.
struct Fd {
    central: bool,
    size: f64,
    steps: FdSteps,
    /// Perturbation (degrees).
    delta: f64,
    values: Vec<f64>,
}

/// What the report keeps of one run.
struct RunResult {
    times: Vec<f64>,
    deflection: Vec<f64>,
    /// `d(deflection)/db` (1/deg).
    sensitivity: Vec<f64>,
    fd: Vec<Fd>,
    /// Per flexible body: name, frequencies (Hz), their derivatives (Hz/deg; updated modes).
    frequencies: Vec<(String, Vec<f64>, Vec<f64>)>,
    steps: usize,
    rejected: usize,
    seconds: f64,
}

/// Parse `--layups`: comma-separated finite numbers (degrees), at least one, no repeats.
pub fn parse_layups(text: &str) -> Result<Vec<f64>, CliError> {
    let bad = |m: String| CliError::Usage(format!("--layups {text:?}: {m}"));
    let mut out: Vec<f64> = Vec::new();
    for item in text.split(',') {
        let item = item.trim();
        if item.is_empty() {
            return Err(bad(
                "expected comma-separated angles in degrees, e.g. 0,15,30".into(),
            ));
        }
        let v: f64 = item
            .trim_end_matches("deg")
            .trim()
            .parse()
            .map_err(|_| bad(format!("`{item}` is not a number (degrees)")))?;
        if !v.is_finite() || v.abs() > 360.0 {
            return Err(bad(format!("`{item}` is not an angle in degrees")));
        }
        if out.contains(&v) {
            return Err(bad(format!("{v} is given twice")));
        }
        out.push(v);
    }
    Ok(out)
}

/// The lay-up as a short name: `15`, `-45`, `22.5`.
fn angle_name(b: f64) -> String {
    if b.fract() == 0.0 {
        format!("{b:.0}")
    } else {
        format!("{b}")
    }
}

/// The deck's first design variable and first mid-node-deflection response, checked.
struct Subject {
    variable: String,
    laminate: String,
    /// Index in `Study::responses`.
    response: usize,
    response_name: String,
    other_variables: Vec<String>,
}

fn subject(src: &Source, mech: &Study) -> Result<Subject, CliError> {
    let Some(var) = mech.design.variables.first() else {
        return Err(CliError::Input(src.error(
            None,
            Some("design".into()),
            "the deck declares no design variable: `flexsens report` varies the first \
             [design.*] variable (e.g. [design.theta] with laminate = \"…\")",
        )));
    };
    let Some(response) = mech
        .responses
        .iter()
        .position(|r| matches!(r.response, mbs::Response::MidNodeDeflection { .. }))
    else {
        return Err(CliError::Input(src.error(
            None,
            Some("response".into()),
            "the deck has no response of kind = \"mid-node-deflection\": the figures of \
             `flexsens report` plot it (e.g. [response.mid_deflection] kind = \
             \"mid-node-deflection\", body = \"rod\")",
        )));
    };
    let crate::deck::design::Target::PlyAngle { laminate, .. } = &var.target else {
        return Err(CliError::Input(src.error(
            None,
            Some(format!("design.{}", var.name)),
            "`flexsens report` varies the lay-up: its first [design.*] variable must be of kind \
             \"ply-angle\"",
        )));
    };
    Ok(Subject {
        variable: var.name.clone(),
        laminate: laminate.clone(),
        response,
        response_name: mech.responses[response].name.clone(),
        other_variables: mech.design.variables[1..]
            .iter()
            .map(|v| v.name.clone())
            .collect(),
    })
}

/// The overrides that put the first design variable at `b`.
fn layup_overrides(mech: &Study, b: f64) -> Vec<String> {
    mech.design.variables[0].overrides(b)
}

/// Run the deck for lay-up `b` with the settings of `kind`.
fn run_one(
    path: &Path,
    overrides: &[String],
    layup: &[String],
    kind: Kind,
    fixed_step: f64,
    response: usize,
) -> Result<RunResult, CliError> {
    let start = Instant::now();
    let mut args: Vec<String> = overrides.to_vec();
    args.extend_from_slice(layup);
    if kind == Kind::FixedStep {
        args.push("analysis.integrator=fixed".into());
        args.push(format!("analysis.step={fixed_step:?}"));
    }
    let (src, raw) = deck::load(path, &args)?;
    let mut mech = Study::validate(&src, &raw, true)?;
    let d = &mut mech.design;
    d.enabled = true;
    // the figures compare the exact derivative of the discrete solution with differences
    d.method = SensitivityScheme::Direct;
    d.fixed_modes = kind == Kind::FixedModes;
    d.finite_differences = match kind {
        Kind::Main => Some(FdDef {
            central: false,
            relative: true,
            sizes: SIZES.to_vec(),
            steps: vec![FdSteps::Replay, FdSteps::Adaptive],
        }),
        Kind::FixedModes => None,
        // the perturbed runs integrate with the same fixed step ("adaptive" means: with the
        // deck's own integrator, here the fixed-step one)
        Kind::FixedStep => Some(FdDef {
            central: false,
            relative: true,
            sizes: vec![FIG6_SIZE],
            steps: vec![FdSteps::Adaptive],
        }),
        Kind::Central => Some(FdDef {
            central: true,
            relative: true,
            sizes: vec![CHECK_SIZE],
            steps: vec![FdSteps::Replay],
        }),
    };
    let c = compute(&src, &mech)?;
    let sens = c
        .sensitivities
        .as_ref()
        .ok_or_else(|| CliError::Runtime("no sensitivities were computed".into()))?;
    let column = |m: &Option<nalgebra::DMatrix<f64>>| -> Vec<f64> {
        m.as_ref()
            .map(|m| m.column(0).iter().copied().collect())
            .unwrap_or_default()
    };
    let sensitivity = column(&sens.responses[response]);
    if sensitivity.is_empty() {
        return Err(CliError::Runtime(format!(
            "{}: the mid-node deflection has no sensitivities",
            src.file.display()
        )));
    }
    let fd =
        c.fd.iter()
            .map(|f| Fd {
                central: f.central,
                size: f.size,
                steps: f.steps,
                delta: f.deltas.first().copied().unwrap_or(f64::NAN),
                values: column(&f.responses[response]),
            })
            .collect();
    let frequencies = sens
        .frequencies
        .iter()
        .map(|(body, d)| {
            // the eigenmodes (static correction modes after them have Ritz values, not
            // frequencies, and no derivatives of their own)
            let f: Vec<f64> = mech
                .bodies
                .get(body)
                .map(|b| b.frequencies.iter().take(d.nrows()).copied().collect())
                .unwrap_or_default();
            // the derivative matrix may hold more modes than the body keeps
            let d: Vec<f64> = d.column(0).iter().take(f.len()).copied().collect();
            (body.clone(), f, d)
        })
        .collect();
    Ok(RunResult {
        times: mech.times.clone(),
        deflection: c.values[response].clone(),
        sensitivity,
        fd,
        frequencies,
        steps: c.statistics.steps,
        rejected: c.statistics.rejected_steps,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// Run every (lay-up, kind) job on `jobs` threads; results in job order.
fn run_all(
    path: &Path,
    overrides: &[String],
    angles: &[f64],
    layups: &[Vec<String>],
    fixed_step: f64,
    response: usize,
    jobs: usize,
) -> Result<Vec<RunResult>, CliError> {
    let work: Vec<(usize, Kind)> = (0..layups.len())
        .flat_map(|i| Kind::ALL.into_iter().map(move |k| (i, k)))
        .collect();
    let next = std::sync::atomic::AtomicUsize::new(0);
    let results: std::sync::Mutex<Vec<Option<Result<RunResult, CliError>>>> =
        std::sync::Mutex::new((0..work.len()).map(|_| None).collect());
    std::thread::scope(|scope| {
        for _ in 0..jobs.clamp(1, work.len().max(1)) {
            scope.spawn(|| {
                loop {
                    let j = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                    let Some(&(i, kind)) = work.get(j) else { break };
                    let r = run_one(path, overrides, &layups[i], kind, fixed_step, response);
                    let failed = r.is_err();
                    results.lock().expect("no panics while holding the lock")[j] = Some(r);
                    if failed {
                        // the first failure is reported; stop handing out work
                        next.store(work.len(), std::sync::atomic::Ordering::Relaxed);
                    }
                }
            });
        }
    });
    let results = results
        .into_inner()
        .expect("no panics while holding the lock");
    let mut out = Vec::with_capacity(work.len());
    for (r, &(i, kind)) in results.into_iter().zip(&work) {
        match r {
            Some(Ok(r)) => out.push(r),
            Some(Err(e)) => {
                return Err(match e {
                    CliError::Runtime(m) => CliError::Runtime(format!(
                        "lay-up [{}°] ({} run): {m}",
                        angle_name(angles[i]),
                        kind.name()
                    )),
                    e => e,
                });
            }
            None => {} // not run after a failure
        }
    }
    if out.len() != work.len() {
        return Err(CliError::Runtime("a run was not completed".into()));
    }
    Ok(out)
}

/// The runs of one lay-up.
struct Layup<'a> {
    angle: f64,
    main: &'a RunResult,
    fixed_modes: &'a RunResult,
    fixed_step: &'a RunResult,
    central: &'a RunResult,
}

fn find(r: &RunResult, central: bool, size: f64, steps: FdSteps) -> Option<&Fd> {
    r.fd.iter()
        .find(|f| f.central == central && f.size == size && f.steps == steps)
}

fn percent(size: f64) -> String {
    format!("{} %", size * 100.0)
}

/// max |a − b| / max |b| over the history (the worst variable); NaN when a is missing.
fn rel_diff(a: &[f64], reference: &[f64]) -> f64 {
    if a.len() != reference.len() || a.is_empty() {
        return f64::NAN;
    }
    let a = nalgebra::DMatrix::from_column_slice(a.len(), 1, a);
    let b = nalgebra::DMatrix::from_column_slice(reference.len(), 1, reference);
    relative_difference(&a, &b)
}

/// max |a − b| over the history; NaN when a is missing.
fn abs_diff(a: &[f64], reference: &[f64]) -> f64 {
    if a.len() != reference.len() || a.is_empty() {
        return f64::NAN;
    }
    a.iter()
        .zip(reference)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

fn amax(v: &[f64]) -> f64 {
    v.iter().map(|x| x.abs()).fold(0.0, f64::max)
}

/// Whether the direct sensitivity of a lay-up vanishes (e.g. at 0°, where the stiffness of a
/// single-angle lay-up is even in the angle): below 1e-9 of the deflection per degree.
fn vanishes(l: &Layup) -> bool {
    amax(&l.main.sensitivity) <= 1e-9 * amax(&l.main.deflection)
}

/// A number printed as short as it reads (`1e-4`, `0.0001`), 6 significant digits.
fn short(x: f64) -> String {
    let r: f64 = format!("{x:.5e}").parse().unwrap_or(x);
    format!("{r}")
}

const SENS_LABEL: &str = "d(deflection)/dθ [1/deg]";
const TIME_LABEL: &str = "time [s]";

/// The figures: (file stem, figure).
fn figures(s: &Subject, layups: &[Layup], fixed_step: f64) -> Vec<(String, Figure)> {
    let mut figs = Vec::new();
    let var = &s.variable;
    // (a) Figs. 5/8
    figs.push((
        "displacement".to_string(),
        Figure {
            title: "Normalised mid-node deflection (paper Figs. 5/8)".into(),
            panels: vec![Panel {
                title: format!("`{}`: mid-node deflection / length", s.response_name),
                x_label: TIME_LABEL.into(),
                y_label: "normalised deflection [1]".into(),
                series: layups
                    .iter()
                    .enumerate()
                    .map(|(i, l)| {
                        Series::solid(
                            format!("lay-up [{}°]", angle_name(l.angle)),
                            &l.main.times,
                            &l.main.deflection,
                            i,
                        )
                    })
                    .collect(),
            }],
        },
    ));
    for l in layups {
        let a = angle_name(l.angle);
        let note = if vanishes(l) {
            " — the derivative vanishes here"
        } else {
            ""
        };
        let t = &l.main.times;
        let direct = |r: &RunResult, label: &str| Series::solid(label, &r.times, &r.sensitivity, 0);
        // (b) Fig. 6
        let mut fixed = vec![direct(l.fixed_step, "direct")];
        if let Some(f) = find(l.fixed_step, false, FIG6_SIZE, FdSteps::Adaptive) {
            fixed.push(Series::dashed(
                format!("forward difference {}", percent(FIG6_SIZE)),
                &l.fixed_step.times,
                &f.values,
                3,
            ));
        }
        let mut variable = vec![direct(l.main, "direct")];
        for (steps, label, color) in [
            (FdSteps::Replay, "replayed steps", 2),
            (FdSteps::Adaptive, "adaptive steps", 1),
        ] {
            if let Some(f) = find(l.main, false, FIG6_SIZE, steps) {
                variable.push(Series::dashed(
                    format!("forward {}, {label}", percent(FIG6_SIZE)),
                    t,
                    &f.values,
                    color,
                ));
            }
        }
        figs.push((
            format!("integrators_{a}deg"),
            Figure {
                title: format!(
                    "Lay-up [{a}°]: direct sensitivities and forward differences (1 %), \
                     fixed and variable steps (paper Fig. 6){note}"
                ),
                panels: vec![
                    Panel {
                        title: format!("fixed step h = {} s", short(fixed_step)),
                        x_label: TIME_LABEL.into(),
                        y_label: SENS_LABEL.into(),
                        series: fixed,
                    },
                    Panel {
                        title: "variable step and order (BDF)".into(),
                        x_label: TIME_LABEL.into(),
                        y_label: SENS_LABEL.into(),
                        series: variable,
                    },
                ],
            },
        ));
        // (c) Figs. 9, 10
        figs.push((
            format!("modes_{a}deg"),
            Figure {
                title: format!("Lay-up [{a}°]: updated vs fixed modes (paper Figs. 9, 10){note}"),
                panels: vec![Panel {
                    title: format!("d({})/d{var}", s.response_name),
                    x_label: TIME_LABEL.into(),
                    y_label: SENS_LABEL.into(),
                    series: vec![
                        Series::solid("updated modes", t, &l.main.sensitivity, 0),
                        Series::dashed(
                            "fixed modes",
                            &l.fixed_modes.times,
                            &l.fixed_modes.sensitivity,
                            3,
                        ),
                    ],
                }],
            },
        ));
        // (d) Figs. 11–13
        let panel = |steps: FdSteps, title: &str| {
            let mut series = vec![Series::solid("direct", t, &l.main.sensitivity, 0)];
            for (k, size) in SIZES.iter().enumerate() {
                if let Some(f) = find(l.main, false, *size, steps) {
                    series.push(Series::dashed(
                        format!("forward {}", percent(*size)),
                        t,
                        &f.values,
                        k + 1,
                    ));
                }
            }
            Panel {
                title: title.into(),
                x_label: TIME_LABEL.into(),
                y_label: SENS_LABEL.into(),
                series,
            }
        };
        figs.push((
            format!("perturbations_{a}deg"),
            Figure {
                title: format!(
                    "Lay-up [{a}°]: direct sensitivities and forward differences of 0.1 %, 1 %, \
                     5 % (paper Figs. 11–13){note}"
                ),
                panels: vec![
                    panel(FdSteps::Replay, "perturbed runs replay the nominal steps"),
                    panel(FdSteps::Adaptive, "perturbed runs choose their own steps"),
                ],
            },
        ));
    }
    figs
}

fn fmt_g(x: f64) -> String {
    if x.is_nan() {
        "–".into()
    } else {
        format!("{x:.3e}")
    }
}

/// Run the command; the returned text goes to stdout.
pub fn run(path: &Path, overrides: &[String], req: &ReportRequest) -> Result<String, CliError> {
    let started = Instant::now();
    let angles = parse_layups(req.layups)?;
    let (src, raw) = deck::load(path, overrides)?;
    let nominal = Study::validate(&src, &raw, false)?;
    let s = subject(&src, &nominal)?;
    let output_step = match nominal.times.as_slice() {
        [a, b, ..] => b - a,
        _ => nominal.times.last().copied().unwrap_or(1.0),
    };
    let fixed_step = match req.fixed_step {
        Some(h) if h.is_finite() && h > 0.0 => h,
        Some(h) => {
            return Err(CliError::Usage(format!(
                "--fixed-step {h}: expected a positive step in seconds"
            )));
        }
        None => output_step / 10.0,
    };
    let jobs = req.jobs.unwrap_or_else(|| {
        std::thread::available_parallelism()
            .map(|n| n.get())
            .unwrap_or(1)
    });
    if jobs == 0 {
        return Err(CliError::Usage("--jobs 0: expected at least one".into()));
    }
    let layup_args: Vec<Vec<String>> = angles
        .iter()
        .map(|&b| layup_overrides(&nominal, b))
        .collect();
    // every lay-up's deck is valid before anything long starts
    for args in &layup_args {
        let mut all = overrides.to_vec();
        all.extend_from_slice(args);
        let (src, raw) = deck::load(path, &all)?;
        Study::validate(&src, &raw, false)?;
    }
    let results = run_all(
        path,
        overrides,
        &angles,
        &layup_args,
        fixed_step,
        s.response,
        jobs,
    )?;
    let layups: Vec<Layup> = angles
        .iter()
        .zip(results.chunks(Kind::ALL.len()))
        .map(|(&angle, r)| Layup {
            angle,
            main: &r[0],
            fixed_modes: &r[1],
            fixed_step: &r[2],
            central: &r[3],
        })
        .collect();
    let out = req
        .out
        .map(Path::to_path_buf)
        .unwrap_or_else(|| super::default_dir(path, "report", None));
    let mut files = Vec::new();
    for (stem, fig) in figures(&s, &layups, fixed_step) {
        let svg = fig
            .svg()
            .map_err(|e| CliError::Runtime(format!("figure {stem}: {e}")))?;
        let png = fig
            .png()
            .map_err(|e| CliError::Runtime(format!("figure {stem}: {e}")))?;
        for (ext, bytes) in [("svg", svg.into_bytes()), ("png", png)] {
            let name = format!("{stem}.{ext}");
            write_atomic(&out.join(&name), &bytes)?;
            files.push(name);
        }
    }
    let settings = Settings {
        raw: &raw,
        nominal: &nominal,
        output_step,
        fixed_step,
        jobs,
        overrides,
        seconds: started.elapsed().as_secs_f64(),
    };
    let (md, js) = summary(&src, &s, &layups, &settings, &files);
    write_atomic(
        &out.join("summary.json"),
        serde_json::to_string_pretty(&js)
            .expect("JSON of plain values")
            .as_bytes(),
    )?;
    write_atomic(&out.join("summary.md"), md.as_bytes())?;
    let mut text = String::new();
    let _ = writeln!(
        text,
        "report of {} for lay-ups {} written to {} ({} figures, SVG and PNG, summary.md, \
         summary.json) in {:.1} s",
        path.display(),
        angles
            .iter()
            .map(|&a| angle_name(a))
            .collect::<Vec<_>>()
            .join(", "),
        out.display(),
        files.len() / 2,
        started.elapsed().as_secs_f64()
    );
    for l in &layups {
        let fd = find(l.central, true, CHECK_SIZE, FdSteps::Replay);
        let (what, v) = if vanishes(l) {
            (
                "absolute",
                fd.map_or(f64::NAN, |f| abs_diff(&f.values, &l.central.sensitivity)),
            )
        } else {
            (
                "relative",
                fd.map_or(f64::NAN, |f| rel_diff(&f.values, &l.central.sensitivity)),
            )
        };
        let _ = writeln!(
            text,
            "  lay-up [{}°]: direct vs central differences ({CHECK_SIZE:e}, replayed steps): \
             max {what} difference {}",
            angle_name(l.angle),
            fmt_g(v)
        );
    }
    Ok(text)
}

struct Settings<'a> {
    raw: &'a RawDeck,
    nominal: &'a Study,
    output_step: f64,
    fixed_step: f64,
    jobs: usize,
    overrides: &'a [String],
    seconds: f64,
}

/// summary.md and summary.json.
fn summary(
    src: &Source,
    s: &Subject,
    layups: &[Layup],
    st: &Settings,
    files: &[String],
) -> (String, serde_json::Value) {
    let mech = st.nominal;
    let mut md = String::new();
    let title = st.raw.title.clone().unwrap_or_default();
    let _ = writeln!(md, "# flexsens report: {}\n", src.file.display());
    if !title.is_empty() {
        let _ = writeln!(md, "{title}\n");
    }
    let names: Vec<String> = layups.iter().map(|l| angle_name(l.angle)).collect();
    let _ = writeln!(
        md,
        "Lay-ups: {} (degrees): every ply of laminate `{}` set through design variable `{}`; \
         response `{}` (mid-node deflection / length).\n",
        names.join(", "),
        s.laminate,
        s.variable,
        s.response_name
    );
    if !s.other_variables.is_empty() {
        let _ = writeln!(
            md,
            "Other design variables ({}) stay at their deck values; their sensitivities are \
             computed but not shown.\n",
            s.other_variables.join(", ")
        );
    }

    // natural frequencies
    let _ = writeln!(md, "## Natural frequencies\n");
    let _ = writeln!(
        md,
        "Frequencies f (Hz) of the flexible bodies' retained modes and their derivatives \
         df/d{} (Hz/deg, updated modes, Nelson's method).\n",
        s.variable
    );
    let mut freq_json = Vec::new();
    let bodies: Vec<String> = layups
        .first()
        .map(|l| l.main.frequencies.iter().map(|(b, ..)| b.clone()).collect())
        .unwrap_or_default();
    for (k, body) in bodies.iter().enumerate() {
        let n = layups
            .iter()
            .map(|l| l.main.frequencies.get(k).map_or(0, |f| f.1.len()))
            .max()
            .unwrap_or(0);
        let _ = writeln!(md, "Body `{body}`:\n");
        let mut head = "| lay-up |".to_string();
        let mut rule = "|---|".to_string();
        for i in 1..=n {
            let _ = write!(head, " f{i} [Hz] |");
            rule.push_str("---:|");
        }
        for i in 1..=n {
            let _ = write!(head, " df{i}/d{} [Hz/deg] |", s.variable);
            rule.push_str("---:|");
        }
        let _ = writeln!(md, "{head}\n{rule}");
        for l in layups {
            let Some((_, f, d)) = l.main.frequencies.get(k) else {
                continue;
            };
            let mut row = format!("| [{}°] |", angle_name(l.angle));
            for x in f {
                let _ = write!(row, " {x:.2} |");
            }
            for x in d {
                // a derivative that rounds to zero prints without the sign of its round-off
                let x = if x.abs() < 5e-5 { 0.0 } else { *x };
                let _ = write!(row, " {x:.4} |");
            }
            let _ = writeln!(md, "{row}");
            freq_json.push(json!({
                "layup": l.angle, "body": body, "frequencies_hz": f, "derivatives_hz_per_deg": d,
            }));
        }
        let _ = writeln!(md);
    }

    // agreement of the sensitivities
    let _ = writeln!(md, "## Direct sensitivities against finite differences\n");
    let _ = writeln!(
        md,
        "Largest difference over the history, relative to the largest direct sensitivity: \
         max_t |FD − direct| / max_t |direct|. Central differences of relative size \
         {CHECK_SIZE:e} on the replayed step sequence check the direct method; the forward \
         differences are those of the figures (\"replay\": the perturbed run takes the nominal \
         run's steps; \"adaptive\": it chooses its own).\n"
    );
    let _ = writeln!(
        md,
        "Where the direct sensitivity vanishes (max |direct| below 1e-9 of the deflection per \
         degree: at 0° the stiffness of a single-angle lay-up is even in the angle) the \
         absolute difference max_t |FD − direct| (1/deg) is given instead, marked \"abs\".\n"
    );
    type Pair<'a> = Box<dyn Fn(&Layup<'a>) -> Option<(Vec<f64>, Vec<f64>)> + 'a>;
    let mut cols: Vec<(String, Pair)> = vec![(
        format!("central {CHECK_SIZE:e}, replay"),
        Box::new(|l: &Layup| {
            find(l.central, true, CHECK_SIZE, FdSteps::Replay)
                .map(|f| (f.values.clone(), l.central.sensitivity.clone()))
        }),
    )];
    for steps in [FdSteps::Replay, FdSteps::Adaptive] {
        for size in SIZES {
            let label = match steps {
                FdSteps::Replay => "replay",
                FdSteps::Adaptive => "adaptive",
            };
            cols.push((
                format!("forward {}, {label}", percent(size)),
                Box::new(move |l: &Layup| {
                    find(l.main, false, size, steps)
                        .map(|f| (f.values.clone(), l.main.sensitivity.clone()))
                }),
            ));
        }
    }
    cols.push((
        format!("forward {}, fixed step", percent(FIG6_SIZE)),
        Box::new(|l: &Layup| {
            find(l.fixed_step, false, FIG6_SIZE, FdSteps::Adaptive)
                .map(|f| (f.values.clone(), l.fixed_step.sensitivity.clone()))
        }),
    ));
    cols.push((
        "fixed modes vs updated".into(),
        Box::new(|l: &Layup| {
            Some((
                l.fixed_modes.sensitivity.clone(),
                l.main.sensitivity.clone(),
            ))
        }),
    ));
    let mut head = "| lay-up | max \\|direct\\| [1/deg] |".to_string();
    let mut rule = "|---|---:|".to_string();
    for (c, _) in &cols {
        let _ = write!(head, " {c} |");
        rule.push_str("---:|");
    }
    let _ = writeln!(md, "{head}\n{rule}");
    let mut diff_json = Vec::new();
    for l in layups {
        let absolute = vanishes(l);
        let mut row = format!(
            "| [{}°] | {} |",
            angle_name(l.angle),
            fmt_g(amax(&l.main.sensitivity))
        );
        let mut rel = serde_json::Map::new();
        let mut abs = serde_json::Map::new();
        for (c, f) in &cols {
            let (r, a) = f(l)
                .map(|(fd, direct)| (rel_diff(&fd, &direct), abs_diff(&fd, &direct)))
                .unwrap_or((f64::NAN, f64::NAN));
            if absolute {
                let _ = write!(row, " abs {} |", fmt_g(a));
            } else {
                let _ = write!(row, " {} |", fmt_g(r));
            }
            let num = |v: f64| if v.is_finite() { json!(v) } else { json!(null) };
            rel.insert(c.clone(), num(r));
            abs.insert(c.clone(), num(a));
        }
        let _ = writeln!(md, "{row}");
        diff_json.push(json!({
            "layup": l.angle,
            "max_abs_direct": amax(&l.main.sensitivity),
            "direct_vanishes": absolute,
            "relative": rel,
            "absolute": abs,
        }));
    }
    let _ = writeln!(md);
    let peak: Vec<serde_json::Value> = layups
        .iter()
        .map(|l| {
            let (i, v) =
                l.main
                    .deflection
                    .iter()
                    .enumerate()
                    .fold((0, 0.0_f64), |(bi, bv), (i, &v)| {
                        if v.abs() > bv.abs() { (i, v) } else { (bi, bv) }
                    });
            json!({"layup": l.angle, "peak_deflection": v, "time": l.main.times.get(i)})
        })
        .collect();
    let _ = writeln!(md, "Peak normalised deflection:\n");
    let _ = writeln!(md, "| lay-up | peak [1] | at t [s] |\n|---|---:|---:|");
    for p in &peak {
        let _ = writeln!(
            md,
            "| [{}°] | {:.4e} | {:.5} |",
            angle_name(p["layup"].as_f64().unwrap_or(f64::NAN)),
            p["peak_deflection"].as_f64().unwrap_or(f64::NAN),
            p["time"].as_f64().unwrap_or(f64::NAN)
        );
    }
    let _ = writeln!(md);

    // settings
    let opt = &mech.options;
    let atol = opt.atol.first().copied().unwrap_or(f64::NAN);
    let t0 = mech.times.first().copied().unwrap_or(0.0);
    let t1 = mech.times.last().copied().unwrap_or(0.0);
    let variable_step = matches!(opt.control, mbs::StepControl::Adaptive { .. });
    let _ = writeln!(md, "## Settings\n");
    let _ = writeln!(
        md,
        "- time span {} s to {} s, {} output times every {} s",
        short(t0),
        short(t1),
        mech.times.len(),
        short(st.output_step)
    );
    let _ = writeln!(
        md,
        "- integrator of the deck: {} (rtol {:e}, atol {:e}); it is used by the main, \
         fixed-modes and central runs",
        if variable_step {
            "variable step and order BDF"
        } else {
            "fixed-step BDF (the \"variable-step\" panels then show fixed steps too)"
        },
        opt.rtol,
        atol
    );
    let _ = writeln!(
        md,
        "- fixed-step runs (Fig. 6, left panels): `analysis.integrator = \"fixed\"`, \
         `analysis.step = {}` s",
        short(st.fixed_step)
    );
    let _ = writeln!(
        md,
        "- direct sensitivities: direct differentiation; main, fixed-step and central runs \
         with updated modes (Nelson's method), the fixed-modes run keeps the modes of each \
         lay-up"
    );
    let _ = writeln!(
        md,
        "- finite differences: forward, relative sizes {} on the replayed and adaptive step \
         sequences (main runs), {} on the fixed steps, central {CHECK_SIZE:e} replayed",
        SIZES.map(percent).join(", "),
        percent(FIG6_SIZE)
    );
    let mut mesh_json = Vec::new();
    for (name, b) in &st.raw.body {
        let b = b.get_ref();
        let kind = b
            .kind
            .as_ref()
            .map(|k| k.get_ref().clone())
            .unwrap_or_default();
        let elements = b
            .elements
            .as_ref()
            .map(|e| e.get_ref().to_string())
            .unwrap_or_else(|| "default".into());
        let modes = mech.bodies.get(name).map_or(0, |i| i.frequencies.len());
        let basis = mech
            .bodies
            .get(name)
            .and_then(|i| i.basis.as_ref())
            .map_or_else(|| format!("{modes} modes retained"), |b| b.describe());
        let _ = writeln!(md, "- body `{name}`: {kind}, elements {elements}, {basis}");
        mesh_json.push(json!({"body": name, "kind": kind, "elements": elements, "modes": modes}));
    }
    if !st.overrides.is_empty() {
        let _ = writeln!(
            md,
            "- deck edited by `--set {}`",
            st.overrides.join(" --set ")
        );
    }
    let _ = writeln!(md, "\n## Runs\n");
    let _ = writeln!(
        md,
        "| lay-up | run | steps | rejected | wall time [s] |\n|---|---|---:|---:|---:|"
    );
    let mut runs_json = Vec::new();
    for l in layups {
        for (kind, r) in Kind::ALL
            .iter()
            .zip([l.main, l.fixed_modes, l.fixed_step, l.central])
        {
            let _ = writeln!(
                md,
                "| [{}°] | {} | {} | {} | {:.1} |",
                angle_name(l.angle),
                kind.name(),
                r.steps,
                r.rejected,
                r.seconds
            );
            let deltas: BTreeMap<String, f64> =
                r.fd.iter()
                    .map(|f| {
                        (
                            format!(
                                "{}_{}_{}",
                                if f.central { "central" } else { "forward" },
                                f.size,
                                match f.steps {
                                    FdSteps::Replay => "replay",
                                    FdSteps::Adaptive => "adaptive",
                                }
                            ),
                            f.delta,
                        )
                    })
                    .collect();
            runs_json.push(json!({
                "layup": l.angle, "run": kind.name(), "steps": r.steps,
                "rejected_steps": r.rejected, "seconds": r.seconds,
                "perturbations_deg": deltas,
            }));
        }
    }
    let _ = writeln!(
        md,
        "\nTotal wall time before the figures: {:.1} s on {} threads.\n",
        st.seconds, st.jobs
    );
    let _ = writeln!(md, "## Figures\n");
    for f in files.iter().filter(|f| f.ends_with(".svg")) {
        let stem = f.trim_end_matches(".svg");
        let what = if stem == "displacement" {
            "normalised mid-node deflection of every lay-up (Figs. 5/8)"
        } else if stem.starts_with("integrators_") {
            "direct vs forward differences (1 %), fixed step and variable step (Fig. 6)"
        } else if stem.starts_with("modes_") {
            "updated vs fixed modes (Figs. 9, 10)"
        } else {
            "direct vs forward differences of 0.1 %, 1 %, 5 % (Figs. 11–13)"
        };
        let _ = writeln!(md, "- `{stem}.svg`, `{stem}.png`: {what}");
    }
    let js = json!({
        "deck": src.file.display().to_string(),
        "title": title,
        "design_variable": s.variable,
        "laminate": s.laminate,
        "response": s.response_name,
        "layups_deg": layups.iter().map(|l| l.angle).collect::<Vec<_>>(),
        "frequencies": freq_json,
        "relative_differences": diff_json,
        "peak_deflection": peak,
        "settings": {
            "t_start": t0, "t_end": t1, "output_step": st.output_step,
            "variable_step": variable_step, "rtol": opt.rtol, "atol": atol,
            "fixed_step": st.fixed_step,
            "forward_sizes": SIZES, "fig6_size": FIG6_SIZE, "central_size": CHECK_SIZE,
            "bodies": mesh_json, "overrides": st.overrides, "threads": st.jobs,
        },
        "runs": runs_json,
        "files": files,
        "seconds": st.seconds,
    });
    (md, js)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layups_parse() {
        assert_eq!(parse_layups("0,15, 30").unwrap(), vec![0.0, 15.0, 30.0]);
        assert_eq!(parse_layups("-45,22.5deg").unwrap(), vec![-45.0, 22.5]);
        for bad in ["", "0,,15", "a", "0,0", "nan", "1e9"] {
            assert!(
                matches!(parse_layups(bad), Err(CliError::Usage(_))),
                "{bad}"
            );
        }
        assert_eq!(angle_name(15.0), "15");
        assert_eq!(angle_name(-22.5), "-22.5");
    }
}
