//! `flexsens sweep`: run a deck for every combination of varied values, in parallel, and
//! write one row per case to a summary CSV.
//!
//! `--vary KEY=START:STEP:END` (inclusive) or `--vary KEY=V1,V2,…` varies any deck value by its
//! dotted path (as `--set`); `KEY = design.NAME` sets a design variable, i.e. every ply angle it
//! moves. Each case is a complete `flexsens run` into `DIR/case_NNN/`; the summary
//! `DIR/summary.csv` (written last) has the case number, the varied values, the status, the
//! integrator's steps, the largest constraint violation and every objective with its gradient.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

use serde_json::Value;

use super::run::RunRequest;
use crate::deck::{self, DeckError};
use crate::error::CliError;
use crate::files::write_atomic;
use crate::study::Study;

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
        // computed from the index, so that 0:0.1:0.3 gives 0.3, not 0.30000000000000004
        (0..n).map(|i| round(a + i as f64 * h)).collect()
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

/// The `--set` arguments of one case: the varied deck keys, and each varied design variable
/// expanded into the deck entries it sets (its ply angles, a rigid body's mass or inertia).
fn case_overrides(
    path: &Path,
    global: &[String],
    axes: &[Axis],
    values: &[f64],
) -> Result<Vec<String>, CliError> {
    let mut sets = global.to_vec();
    let design: Vec<(&Axis, f64)> = axes
        .iter()
        .zip(values.iter().copied())
        .filter(|(a, _)| a.key.starts_with("design."))
        .collect();
    for (a, v) in axes.iter().zip(values) {
        if !a.key.starts_with("design.") {
            sets.push(format!("{}={v:?}", a.key));
        }
    }
    if !design.is_empty() {
        let (src, raw) = deck::load(path, &sets)?;
        let lam = crate::deck::laminates::validate(&src, &raw)?;
        let d = crate::deck::design::validate(&src, &raw, &lam)?;
        for (a, v) in design {
            let name = &a.key["design.".len()..];
            let var = d.variables.iter().find(|x| x.name == name).ok_or_else(|| {
                let known: Vec<&str> = d.variables.iter().map(|x| x.name.as_str()).collect();
                CliError::Input(DeckError {
                    file: path.to_path_buf(),
                    line: None,
                    key: Some(a.key.clone()),
                    message: format!(
                        "--vary: no design variable `{name}`{}",
                        crate::deck::laminates::suggestion(name, &known)
                    ),
                    snippet: None,
                    note: None,
                })
            })?;
            sets.extend(var.overrides(v));
        }
    }
    Ok(sets)
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
    values: Vec<f64>,
    outcome: Result<Value, CliError>,
}

/// Run the sweep; the returned text goes to stdout and the flag says whether every case ran.
pub fn run(
    path: &Path,
    overrides: &[String],
    req: &SweepRequest,
) -> Result<(String, bool), CliError> {
    if req.vary.is_empty() {
        return Err(usage("sweep needs at least one --vary KEY=START:STEP:END"));
    }
    let axes = req
        .vary
        .iter()
        .map(|a| axis(a))
        .collect::<Result<Vec<_>, _>>()?;
    for (i, a) in axes.iter().enumerate() {
        if axes[..i].iter().any(|b| b.key == a.key) {
            return Err(usage(format!("--vary {} is given twice", a.key)));
        }
    }
    // all combinations, the last axis fastest; counted (not built) and held to the case limit
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
    // the corner cases (each axis at its first and last value, the others at their first) are
    // validated before anything runs, so that bad input is reported at once; an error that
    // only another combination meets fails that case alone, and the summary says so
    for c in corner_cases(&axes) {
        let s = case_overrides(path, overrides, &axes, &case_values(&axes, c))?;
        let (src, raw) = deck::load(path, &s)?;
        Study::validate(&src, &raw, true)?;
    }
    let out = req.out.map(Path::to_path_buf).unwrap_or_else(|| {
        let stem = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "flexsens".into());
        path.with_file_name(format!("{stem}.sweep"))
    });
    let summary_path = out.join("summary.csv");
    match std::fs::remove_file(&summary_path) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
            return Err(CliError::Runtime(format!(
                "cannot remove the old {}: {e}",
                summary_path.display()
            )));
        }
        _ => {}
    }
    let jobs = req
        .jobs
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()))
        .clamp(1, n_cases);
    let width = n_cases.to_string().len().max(3);
    let case_dir = |i: usize| out.join(format!("case_{:0width$}", i + 1));
    let next = AtomicUsize::new(0);
    let done = AtomicUsize::new(0);
    let results: Vec<Mutex<Option<CaseResult>>> = (0..n_cases).map(|_| Mutex::new(None)).collect();
    std::thread::scope(|scope| {
        for _ in 0..jobs {
            scope.spawn(|| {
                loop {
                    let i = next.fetch_add(1, Ordering::SeqCst);
                    if i >= n_cases {
                        break;
                    }
                    let dir = case_dir(i);
                    let request = RunRequest {
                        out: Some(&dir),
                        json: true,
                        progress: false,
                    };
                    let values = case_values(&axes, i);
                    let outcome = case_overrides(path, overrides, &axes, &values)
                        .and_then(|sets| super::run::run(path, &sets, &request))
                        .and_then(|s| {
                            serde_json::from_str::<Value>(&s)
                                .map_err(|e| CliError::Runtime(format!("case {}: {e}", i + 1)))
                        })
                        .map(summary_fields);
                    let n = done.fetch_add(1, Ordering::SeqCst) + 1;
                    if !req.quiet {
                        let status = match &outcome {
                            Ok(_) => "done".to_string(),
                            Err(e) => format!("failed: {e}"),
                        };
                        eprintln!("[{n}/{n_cases}] case {} {status}", i + 1);
                    }
                    *results[i].lock().expect("no poisoned lock") =
                        Some(CaseResult { values, outcome });
                }
            });
        }
    });
    let results: Vec<CaseResult> = results
        .into_iter()
        .map(|m| {
            m.into_inner()
                .expect("no poisoned lock")
                .expect("every case ran")
        })
        .collect();
    let csv = summary_csv(&axes, &results, &case_dir);
    write_atomic(&summary_path, csv.as_bytes())?;
    let failed = results.iter().filter(|r| r.outcome.is_err()).count();
    let text = format!(
        "{} cases ({} failed), {} parallel runs; summary: {}\n",
        results.len(),
        failed,
        jobs,
        summary_path.display()
    );
    Ok((text, failed == 0))
}

/// CSV-safe text (quoted when it holds a comma, quote or newline).
fn field(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

fn summary_csv(
    axes: &[Axis],
    results: &[CaseResult],
    case_dir: &dyn Fn(usize) -> PathBuf,
) -> String {
    // objective columns from the first successful case (every case has the same deck tables)
    let first = results.iter().find_map(|r| r.outcome.as_ref().ok());
    let objectives: Vec<(String, Vec<String>)> = first
        .and_then(|s| s["objectives"].as_array())
        .map(|objs| {
            let vars: Vec<String> = first
                .and_then(|s| s["design"].as_array())
                .map(|d| {
                    d.iter()
                        .map(|v| v["name"].as_str().unwrap_or("").to_string())
                        .collect()
                })
                .unwrap_or_default();
            objs.iter()
                .map(|o| {
                    let has_gradient = o["gradient"].as_array().is_some_and(|g| !g.is_empty());
                    (
                        o["name"].as_str().unwrap_or("").to_string(),
                        if has_gradient {
                            vars.clone()
                        } else {
                            Vec::new()
                        },
                    )
                })
                .collect()
        })
        .unwrap_or_default();
    let mut csv = String::from("case,directory");
    for a in axes {
        let _ = write!(csv, ",{}", field(&a.key));
    }
    csv.push_str(",status,steps,max_position_violation [m]");
    for (name, vars) in &objectives {
        let _ = write!(csv, ",{}", field(name));
        for v in vars {
            let _ = write!(csv, ",{}", field(&format!("d {name}/d {v}")));
        }
    }
    csv.push_str(",error\n");
    for (i, r) in results.iter().enumerate() {
        let _ = write!(
            csv,
            "{},{}",
            i + 1,
            field(&case_dir(i).display().to_string())
        );
        for v in &r.values {
            let _ = write!(csv, ",{v}");
        }
        match &r.outcome {
            Ok(s) => {
                let _ = write!(
                    csv,
                    ",ok,{},{:e}",
                    s["steps"].as_u64().unwrap_or(0),
                    s["max_position_violation"].as_f64().unwrap_or(f64::NAN)
                );
                let objs = s["objectives"].as_array().cloned().unwrap_or_default();
                for ((_, vars), o) in objectives.iter().zip(objs.iter()) {
                    let _ = write!(csv, ",{:e}", o["value"].as_f64().unwrap_or(f64::NAN));
                    let g = o["gradient"].as_array().cloned().unwrap_or_default();
                    for k in 0..vars.len() {
                        let _ = write!(
                            csv,
                            ",{:e}",
                            g.get(k).and_then(Value::as_f64).unwrap_or(f64::NAN)
                        );
                    }
                }
                csv.push_str(",\n");
            }
            Err(e) => {
                let _ = write!(csv, ",failed,,");
                for (_, vars) in &objectives {
                    csv.push(',');
                    for _ in vars {
                        csv.push(',');
                    }
                }
                let _ = writeln!(csv, ",{}", field(&e.to_string().replace('\n', " ")));
            }
        }
    }
    csv
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
