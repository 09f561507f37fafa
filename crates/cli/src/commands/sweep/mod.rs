//! `flexsens sweep`: run a deck for every combination of varied values, in parallel, and
//! write one row per case to a summary CSV.
//!
//! `--vary KEY=START:STEP:END` (inclusive) or `--vary KEY=V1,V2,…` varies any deck value by its
//! dotted path (as `--set`); `KEY = design.NAME` sets a design variable, i.e. every ply angle it
//! moves. Each case is a complete `flexsens run` into `DIR/case_NNN/`; the summary
//! `DIR/summary.csv` (written last) has the case number, the varied values, the status, the
//! integrator's steps, the largest constraint violation and every objective with its gradient.
//!
//! For a batch system, `--shard I/N` runs every N-th case from the I-th into its own
//! directory, recording what it ran (`shard.json`, `cases.jsonl`); `flexsens merge` ([`super::merge`]) gathers the N
//! shards into the directory a single sweep would have written, the summary byte for byte.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use serde_json::Value;

use super::run::run_study;
use super::run_files::per;
use super::shard::{
    SHARD_FILE, manifest_strings, move_dir, parse_shard, remove_old, shard_cases, write_manifest,
};
use crate::deck::{DeckError, Source};
use crate::error::CliError;
use crate::files::write_atomic;
use crate::study::Study;
use crate::table::{CsvTable, number};

mod shards;

pub(crate) use shards::merge_shards;

/// What `flexsens sweep` was asked for.
pub struct SweepRequest<'a> {
    /// `KEY=SPEC` arguments.
    pub vary: &'a [String],
    /// Output directory (default `<deck name>.sweep` beside the deck).
    pub out: Option<&'a Path>,
    /// Parallel runs (default: the available cores).
    pub jobs: Option<usize>,
    /// No per-case lines on stderr.
    pub quiet: bool,
    /// `I/N`: run only the I-th of N deterministic slices of the cases (for a batch system).
    pub shard: Option<&'a str>,
}

/// One varied key and its values.
struct Axis {
    key: String,
    values: Vec<f64>,
}

fn usage(m: impl Into<String>) -> CliError {
    CliError::Usage(m.into())
}

/// Parse `KEY=START:STEP:END` or `KEY=V1,V2,…`.
fn axis(arg: &str) -> Result<Axis, CliError> {
    let (key, spec) = arg.split_once('=').ok_or_else(|| {
        usage(format!(
            "--vary {arg}: expected KEY=START:STEP:END or KEY=V1,V2,…"
        ))
    })?;
    let key = key.trim();
    if key.is_empty() || key.split('.').any(str::is_empty) {
        return Err(usage(format!(
            "--vary {arg}: the key is not a dotted deck path"
        )));
    }
    let num = |s: &str| -> Result<f64, CliError> {
        s.trim()
            .parse::<f64>()
            .ok()
            .filter(|x| x.is_finite())
            .ok_or_else(|| usage(format!("--vary {arg}: `{}` is not a number", s.trim())))
    };
    let values = if spec.contains(':') {
        let parts: Vec<&str> = spec.split(':').collect();
        let [a, h, b] = parts[..] else {
            return Err(usage(format!("--vary {arg}: expected START:STEP:END")));
        };
        let (a, h, b) = (num(a)?, num(h)?, num(b)?);
        if h == 0.0 || (b - a) * h < 0.0 {
            return Err(usage(format!(
                "--vary {arg}: the step must be non-zero and lead from START to END"
            )));
        }
        let n = ((b - a) / h + 1e-9).floor() + 1.0;
        let max = crate::limits::get().cases;
        if n > max as f64 {
            return Err(usage(format!(
                "--vary {arg}: {n} values are more than the limit of {max} cases (--max-cases \
                 raises it)"
            )));
        }
        let n = n as usize;
        // computed from the index, so that 0:0.1:0.3 gives 0.3, not 0.30000000000000004, and
        // -0.3:0.1:0.3 gives 0, not 5.6e-17 (values below 1e-9 of the step are zero)
        (0..n)
            .map(|i| a + i as f64 * h)
            .map(|x| {
                if x.abs() < 1e-9 * h.abs() {
                    0.0
                } else {
                    round(x)
                }
            })
            .collect()
    } else {
        spec.split(',').map(num).collect::<Result<Vec<_>, _>>()?
    };
    if values.is_empty() {
        return Err(usage(format!("--vary {arg}: no values")));
    }
    Ok(Axis {
        key: key.to_string(),
        values,
    })
}

/// `x` rounded to 12 significant digits (removes the error of `a + i h`).
fn round(x: f64) -> f64 {
    if x == 0.0 {
        return 0.0;
    }
    format!("{x:.11e}").parse().unwrap_or(x)
}

/// What the cases of a sweep start from: the deck as read, the `--set` arguments of the
/// command line, and, when every axis sets a design variable, the deck's study (each case is
/// then that study moved to its design, in memory).
struct Cases<'a> {
    /// The deck as read from its file.
    base: Source,
    global: &'a [String],
    axes: &'a [Axis],
    /// The deck with the command line's `--set` arguments and its study, when no axis edits
    /// the deck.
    nominal: Option<(Source, Study)>,
}

impl<'a> Cases<'a> {
    /// Read the deck once; check that every `design.NAME` axis names a design variable.
    fn new(path: &Path, global: &'a [String], axes: &'a [Axis]) -> Result<Self, CliError> {
        let base = Source::read(path)?;
        let src = base.edited(global)?;
        let raw = src.parse()?;
        let lam = crate::deck::laminates::validate(&src, &raw)?;
        let design = crate::deck::design::validate(&src, &raw, &lam)?;
        let known: Vec<&str> = design.variables.iter().map(|x| x.name.as_str()).collect();
        for a in axes {
            if let Some(name) = a.key.strip_prefix("design.")
                && !known.contains(&name)
            {
                return Err(CliError::Input(DeckError {
                    file: path.to_path_buf(),
                    line: None,
                    key: Some(a.key.clone()),
                    message: format!(
                        "--vary: no design variable `{name}`{}",
                        crate::deck::check::suggestion(name, &known)
                    ),
                    snippet: None,
                    note: None,
                }));
            }
        }
        let nominal = if axes.iter().all(|a| a.key.starts_with("design.")) {
            let study = Study::validate(&src, &raw)?;
            Some((src, study))
        } else {
            None
        };
        Ok(Cases {
            base,
            global,
            axes,
            nominal,
        })
    }

    /// `run` on the deck and study of the case with the axes at `values`, validated (not
    /// built): the deck's keys set (the deck edited in memory and validated), then the design
    /// variables set ([`Study::at`]).
    fn with_study<R>(
        &self,
        values: &[f64],
        run: impl FnOnce(&Source, Study) -> Result<R, CliError>,
    ) -> Result<R, CliError> {
        let (edited, study) = match &self.nominal {
            Some((_, study)) => (None, study.clone()),
            None => {
                let mut sets = self.global.to_vec();
                for (a, v) in self.axes.iter().zip(values) {
                    if !a.key.starts_with("design.") {
                        sets.push(format!("{}={v:?}", a.key));
                    }
                }
                let src = self.base.edited(&sets)?;
                let study = Study::validate(&src, &src.parse()?)?;
                (Some(src), study)
            }
        };
        let src = match (&edited, &self.nominal) {
            (Some(src), _) | (None, Some((src, _))) => src,
            (None, None) => unreachable!("a case's deck is the nominal or an edited one"),
        };
        let design: Vec<(&str, f64)> = self
            .axes
            .iter()
            .zip(values)
            .filter_map(|(a, &v)| a.key.strip_prefix("design.").map(|n| (n, v)))
            .collect();
        if design.is_empty() {
            return run(src, study);
        }
        let mut b = study.design_values();
        for (name, v) in design {
            let j = study
                .design
                .variables
                .iter()
                .position(|x| x.name == name)
                .ok_or_else(|| {
                    CliError::Runtime(format!(
                        "{}: the case's deck has no design variable `{name}`",
                        src.file.display()
                    ))
                })?;
            b[j] = v;
        }
        let moved = study.at(src, &b)?;
        run(src, moved)
    }
}

/// The varied values of case `i` (0-based; the last axis fastest).
fn case_values(axes: &[Axis], i: usize) -> Vec<f64> {
    let mut rest = i;
    let mut values = vec![0.0; axes.len()];
    for (v, a) in values.iter_mut().zip(axes).rev() {
        *v = a.values[rest % a.values.len()];
        rest /= a.values.len();
    }
    values
}

/// The cases (0-based, ascending, without repeats) where every axis is at its first value but
/// at most one, which is at its last.
fn corner_cases(axes: &[Axis]) -> Vec<usize> {
    let mut cases = vec![0];
    let mut stride = 1;
    for a in axes.iter().rev() {
        cases.push((a.values.len() - 1) * stride);
        stride *= a.values.len();
    }
    cases.sort_unstable();
    cases.dedup();
    cases
}

/// The parts of a run's JSON summary that the sweep's summary uses (a sweep holds one per
/// case).
fn summary_fields(s: Value) -> Value {
    let mut kept = serde_json::Map::new();
    if let Value::Object(mut m) = s {
        for key in ["steps", "max_position_violation", "objectives", "design"] {
            if let Some(v) = m.remove(key) {
                kept.insert(key.to_string(), v);
            }
        }
    }
    Value::Object(kept)
}

/// The result of one case.
struct CaseResult {
    /// The case's index (0-based) among all the sweep's cases.
    index: usize,
    values: Vec<f64>,
    /// The run's summary fields, or its error message.
    outcome: Result<Value, String>,
}

/// The axes and the number of cases of a sweep.
struct Plan {
    axes: Vec<Axis>,
    n_cases: usize,
}

/// Parse the `--vary` arguments and count the cases (all combinations, the last axis
/// fastest), held to the case limit.
fn plan(vary: &[String]) -> Result<Plan, CliError> {
    if vary.is_empty() {
        return Err(usage("sweep needs at least one --vary KEY=START:STEP:END"));
    }
    let axes = vary
        .iter()
        .map(|a| axis(a))
        .collect::<Result<Vec<_>, _>>()?;
    for (i, a) in axes.iter().enumerate() {
        if axes[..i].iter().any(|b| b.key == a.key) {
            return Err(usage(format!("--vary {} is given twice", a.key)));
        }
    }
    let max_cases = crate::limits::get().cases;
    let n_cases = axes
        .iter()
        .try_fold(1usize, |n, a| n.checked_mul(a.values.len()))
        .filter(|&n| n <= max_cases)
        .ok_or_else(|| {
            let sizes: Vec<String> = axes.iter().map(|a| a.values.len().to_string()).collect();
            usage(format!(
                "--vary: {} cases are more than the limit of {max_cases} (--max-cases raises it)",
                sizes.join(" × ")
            ))
        })?;
    Ok(Plan { axes, n_cases })
}

/// The name of case `i`'s directory (`case_001`; as many digits as the sweep needs).
fn case_name(i: usize, n_cases: usize) -> String {
    let width = n_cases.to_string().len().max(3);
    format!("case_{:0width$}", i + 1)
}

const CASES_FILE: &str = "cases.jsonl";

/// Run the sweep; the returned text goes to stdout and the flag says whether every case ran.
pub fn run(
    path: &Path,
    overrides: &[String],
    req: &SweepRequest,
) -> Result<(String, bool), CliError> {
    let Plan { axes, n_cases } = plan(req.vary)?;
    let shard = req.shard.map(parse_shard).transpose()?;
    // the corner cases (each axis at its first and last value, the others at their first) are
    // validated (not analysed) before anything runs, so that bad input is reported at once; an error that only
    // another combination meets fails that case alone, and the summary says so
    let start = Cases::new(path, overrides, &axes)?;
    for c in corner_cases(&axes) {
        start.with_study(&case_values(&axes, c), |_, _| Ok(()))?;
    }
    let out = req
        .out
        .map(Path::to_path_buf)
        .unwrap_or_else(|| super::default_dir(path, "sweep", shard));
    let cases = shard_cases(n_cases, shard);
    if cases.is_empty() {
        return Err(usage(format!(
            "--shard {}: the sweep has only {n_cases} cases, so this shard has none",
            req.shard.unwrap_or_default()
        )));
    }
    let _lock = crate::files::DirLock::acquire(&out, "sweep")?;
    let summary_path = out.join("summary.csv");
    for f in ["summary.csv", SHARD_FILE, CASES_FILE] {
        remove_old(&out.join(f))?;
    }
    let jobs = super::job_count(req.jobs, cases.len());
    let case_dir = |i: usize| out.join(case_name(i, n_cases));
    let done = AtomicUsize::new(0);
    let results = super::parallel_map(cases.len(), jobs, |j| {
        let i = cases[j];
        let dir = case_dir(i);
        let values = case_values(&axes, i);
        let outcome = start
            .with_study(&values, |src, study| {
                run_study(src, &study.build(src, true)?, &dir, None)
            })
            .map(|done| summary_fields(done.summary))
            .map_err(|e| e.to_string());
        let n = done.fetch_add(1, Ordering::SeqCst) + 1;
        if !req.quiet {
            let status = match &outcome {
                Ok(_) => "done".to_string(),
                Err(e) => format!("failed: {e}"),
            };
            eprintln!("[{n}/{}] case {} {status}", cases.len(), i + 1);
        }
        CaseResult {
            index: i,
            values,
            outcome,
        }
    });
    if let Some(shard) = shard {
        let lines: String = results
            .iter()
            .map(|r| {
                let v = match &r.outcome {
                    Ok(s) => serde_json::json!({ "case": r.index + 1, "summary": s }),
                    Err(e) => serde_json::json!({ "case": r.index + 1, "error": e }),
                };
                v.to_string() + "\n"
            })
            .collect();
        write_atomic(&out.join(CASES_FILE), lines.as_bytes())?;
        let extra = serde_json::json!({ "vary": req.vary, "cases": n_cases });
        write_manifest(
            &out,
            "sweep",
            (path, start.base.file_text()),
            overrides,
            shard,
            extra,
        )?;
    }
    let csv = summary_csv(&axes, &results, &case_dir);
    write_atomic(&summary_path, csv.as_bytes())?;
    let failed = results.iter().filter(|r| r.outcome.is_err()).count();
    let of = shard.map_or(String::new(), |(i, n)| {
        format!("shard {i}/{n}: {} of ", results.len())
    });
    let text = format!(
        "{of}{n_cases} cases ({failed} failed), {jobs} parallel runs; summary: {}\n",
        summary_path.display()
    );
    Ok((text, failed == 0))
}

fn summary_csv(
    axes: &[Axis],
    results: &[CaseResult],
    case_dir: &dyn Fn(usize) -> PathBuf,
) -> String {
    // objective columns from the first successful case (every case has the same deck tables)
    let first = results.iter().find_map(|r| r.outcome.as_ref().ok());
    // the design variables: (name, unit)
    let vars: Vec<(String, String)> = first
        .and_then(|s| s["design"].as_array())
        .map(|d| {
            d.iter()
                .map(|v| {
                    let text = |k: &str| v[k].as_str().unwrap_or("").to_string();
                    (text("name"), text("unit"))
                })
                .collect()
        })
        .unwrap_or_default();
    // (name, unit, whether it carries a gradient)
    let objectives: Vec<(String, String, bool)> = first
        .and_then(|s| s["objectives"].as_array())
        .map(|objs| {
            objs.iter()
                .map(|o| {
                    (
                        o["name"].as_str().unwrap_or("").to_string(),
                        o["unit"].as_str().unwrap_or("1").to_string(),
                        o["gradient"].as_array().is_some_and(|g| !g.is_empty()),
                    )
                })
                .collect()
        })
        .unwrap_or_default();
    let n_gradient = |has: bool| if has { vars.len() } else { 0 };
    let mut head = vec!["case".to_string(), "directory".to_string()];
    head.extend(axes.iter().map(|a| {
        // a design axis carries its variable's unit; a deck key's unit is the deck's
        let unit = a
            .key
            .strip_prefix("design.")
            .and_then(|n| vars.iter().find(|(v, _)| v == n))
            .map(|(_, u)| u.as_str());
        match unit {
            Some(u) if !u.is_empty() => format!("{} [{u}]", a.key),
            _ => a.key.clone(),
        }
    }));
    head.extend(["status", "steps", "max_position_violation [m]"].map(String::from));
    for (name, unit, has) in &objectives {
        head.push(format!("{name} [{unit}]"));
        if *has {
            head.extend(
                vars.iter()
                    .map(|(v, u)| format!("d {name}/d {v} [{}]", per(unit, u))),
            );
        }
    }
    head.push("error".into());
    let mut t = CsvTable::new();
    t.row(head);
    for r in results {
        let mut row = vec![
            (r.index + 1).to_string(),
            case_dir(r.index).display().to_string(),
        ];
        row.extend(r.values.iter().map(|v| v.to_string()));
        match &r.outcome {
            Ok(s) => {
                row.extend([
                    "ok".to_string(),
                    s["steps"].as_u64().unwrap_or(0).to_string(),
                    number(s["max_position_violation"].as_f64().unwrap_or(f64::NAN)),
                ]);
                let objs = s["objectives"].as_array().cloned().unwrap_or_default();
                for ((_, _, has), o) in objectives.iter().zip(objs.iter()) {
                    row.push(number(o["value"].as_f64().unwrap_or(f64::NAN)));
                    let g = o["gradient"].as_array().cloned().unwrap_or_default();
                    row.extend(
                        (0..n_gradient(*has))
                            .map(|k| number(g.get(k).and_then(Value::as_f64).unwrap_or(f64::NAN))),
                    );
                }
                row.push(String::new());
            }
            Err(e) => {
                row.extend(["failed".to_string(), String::new(), String::new()]);
                for (_, _, has) in &objectives {
                    row.extend(std::iter::repeat_n(String::new(), 1 + n_gradient(*has)));
                }
                row.push(e.replace('\n', " "));
            }
        }
        t.row(row);
    }
    t.finish()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn axes(sizes: &[usize]) -> Vec<Axis> {
        sizes
            .iter()
            .enumerate()
            .map(|(k, &n)| Axis {
                key: format!("a{k}"),
                values: (0..n).map(|j| (10 * k + j) as f64).collect(),
            })
            .collect()
    }

    /// Case indices enumerate every combination once, the last axis fastest, as the nested
    /// loops the summary promises.
    #[test]
    fn case_values_are_the_combinations_in_order() {
        let a = axes(&[2, 3, 2]);
        let mut expected = Vec::new();
        for x in 0..2 {
            for y in 10..13 {
                for z in 20..22 {
                    expected.push(vec![x as f64, y as f64, z as f64]);
                }
            }
        }
        let got: Vec<Vec<f64>> = (0..12).map(|i| case_values(&a, i)).collect();
        assert_eq!(got, expected);
    }

    #[test]
    fn corner_cases_hold_each_axis_at_its_ends() {
        let a = axes(&[2, 3, 2]);
        let corners: Vec<Vec<f64>> = corner_cases(&a)
            .into_iter()
            .map(|i| case_values(&a, i))
            .collect();
        assert_eq!(
            corners,
            vec![
                vec![0.0, 10.0, 20.0],
                vec![0.0, 10.0, 21.0],
                vec![0.0, 12.0, 20.0],
                vec![1.0, 10.0, 20.0],
            ]
        );
        assert_eq!(corner_cases(&axes(&[1, 1])), vec![0]);
    }
}
