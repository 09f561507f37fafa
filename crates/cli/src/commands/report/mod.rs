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
//! The deck is validated twice, as written and with the fixed-step integrator
//! (`analysis.integrator`/`analysis.step` set in memory); each lay-up is that study moved to
//! the lay-up's design (`Study::at`) and built; the sensitivity and finite-difference settings are set
//! on the study's design, so a deck needs no `[sensitivity]` or `[finite_differences]` table
//! (those it has are replaced).

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
use crate::study::{Mechanism, Study};

mod figures;
mod summary;

use figures::{figures, fmt_g};
use summary::{Settings, summary};

/// Forward-difference sizes of Figs. 11–13 (relative).
pub(super) const SIZES: [f64; 3] = [0.001, 0.01, 0.05];
/// The forward-difference size of Fig. 6 (relative).
pub(super) const FIG6_SIZE: f64 = 0.01;
/// Central-difference size of the summary's check (relative).
pub(super) const CHECK_SIZE: f64 = 1e-4;

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
pub(super) enum Kind {
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
pub(super) struct Fd {
    central: bool,
    size: f64,
    steps: FdSteps,
    /// Perturbation (degrees).
    delta: f64,
    values: Vec<f64>,
}

/// What the report keeps of one run.
pub(super) struct RunResult {
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
pub(super) fn angle_name(b: f64) -> String {
    if b.fract() == 0.0 {
        format!("{b:.0}")
    } else {
        format!("{b}")
    }
}

/// The deck's first design variable and first mid-node-deflection response, checked.
pub(super) struct Subject {
    variable: String,
    laminate: String,
    /// Index in `Mechanism::responses`.
    response: usize,
    response_name: String,
    other_variables: Vec<String>,
}

pub(super) fn subject(src: &Source, mech: &Mechanism) -> Result<Subject, CliError> {
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

/// The design of lay-up `b`: the first design variable at `b`, the others at their values in
/// the deck.
pub(super) fn layup(mech: &Study, b: f64) -> Vec<f64> {
    let mut x = mech.design_values();
    x[0] = b;
    x
}

/// The deck's studies: as written, and with a fixed-step integrator (the `fixed-step` runs).
pub(super) struct Studies<'a> {
    pub(super) nominal: (&'a Source, &'a Study),
    pub(super) fixed_step: (&'a Source, &'a Study),
}

/// Run the deck for lay-up `b` with the settings of `kind`.
pub(super) fn run_one(
    studies: &Studies,
    b: f64,
    kind: Kind,
    response: usize,
) -> Result<RunResult, CliError> {
    let start = Instant::now();
    let (src, base) = if kind == Kind::FixedStep {
        studies.fixed_step
    } else {
        studies.nominal
    };
    let mut mech = base.at(src, &layup(base, b))?.build(src, true)?;
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
    let c = compute(src, &mech, None)?;
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
pub(super) fn run_all(
    studies: &Studies,
    angles: &[f64],
    response: usize,
    jobs: usize,
) -> Result<Vec<RunResult>, CliError> {
    let work: Vec<(usize, Kind)> = (0..angles.len())
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
                    let r = run_one(studies, angles[i], kind, response);
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
pub(super) struct Layup<'a> {
    angle: f64,
    main: &'a RunResult,
    fixed_modes: &'a RunResult,
    fixed_step: &'a RunResult,
    central: &'a RunResult,
}

pub(super) fn find(r: &RunResult, central: bool, size: f64, steps: FdSteps) -> Option<&Fd> {
    r.fd.iter()
        .find(|f| f.central == central && f.size == size && f.steps == steps)
}

pub(super) fn percent(size: f64) -> String {
    format!("{} %", size * 100.0)
}

/// max |a − b| / max |b| over the history (the worst variable); NaN when a is missing.
pub(super) fn rel_diff(a: &[f64], reference: &[f64]) -> f64 {
    if a.len() != reference.len() || a.is_empty() {
        return f64::NAN;
    }
    let a = nalgebra::DMatrix::from_column_slice(a.len(), 1, a);
    let b = nalgebra::DMatrix::from_column_slice(reference.len(), 1, reference);
    relative_difference(&a, &b)
}

/// max |a − b| over the history; NaN when a is missing.
pub(super) fn abs_diff(a: &[f64], reference: &[f64]) -> f64 {
    if a.len() != reference.len() || a.is_empty() {
        return f64::NAN;
    }
    a.iter()
        .zip(reference)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

pub(super) fn amax(v: &[f64]) -> f64 {
    v.iter().map(|x| x.abs()).fold(0.0, f64::max)
}

/// Whether the direct sensitivity of a lay-up vanishes (e.g. at 0°, where the stiffness of a
/// single-angle lay-up is even in the angle): below 1e-9 of the deflection per degree.
pub(super) fn vanishes(l: &Layup) -> bool {
    amax(&l.main.sensitivity) <= 1e-9 * amax(&l.main.deflection)
}

pub(super) use crate::table::short;

/// Run the command; the returned text goes to stdout.
pub fn run(path: &Path, overrides: &[String], req: &ReportRequest) -> Result<String, CliError> {
    let started = Instant::now();
    let angles = parse_layups(req.layups)?;
    let (src, raw) = deck::load(path, overrides)?;
    let nominal = Mechanism::validate(&src, &raw, false)?;
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
    let mut fixed_args = overrides.to_vec();
    fixed_args.push("analysis.integrator=fixed".into());
    fixed_args.push(format!("analysis.step={fixed_step:?}"));
    let fixed_src = src.edited(&fixed_args)?;
    let fixed = Study::validate(&fixed_src, &fixed_src.parse()?)?;
    // every lay-up's design is valid before anything long starts
    for &b in &angles {
        nominal.study.at(&src, &layup(&nominal, b))?;
    }
    let studies = Studies {
        nominal: (&src, &nominal.study),
        fixed_step: (&fixed_src, &fixed),
    };
    let results = run_all(&studies, &angles, s.response, jobs)?;
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
