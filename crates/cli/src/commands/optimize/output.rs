//! The optimisation's files: the iteration table, the convergence figure, and the optimum's
//! deck, run and summary.

use super::evaluate::absolute_file_keys;
use super::*;

/// The units of the objective and the constrained quantities, from the first evaluation that
/// gave values.
pub(super) fn units(rows: &[Row], count: usize) -> Vec<String> {
    rows.iter()
        .find_map(|r| r.eval.as_ref().ok().map(|e| e.units.clone()))
        .unwrap_or_else(|| vec!["?".to_string(); count])
}

pub(super) fn iterations_csv(p: &Problem, rows: &[Row]) -> String {
    let units = units(rows, 1 + p.def.constraints.len());
    let mut head = vec!["start".to_string(), "evaluation".to_string()];
    head.extend(
        p.variables
            .iter()
            .map(|v| format!("{} [{}]", v.name, v.unit)),
    );
    head.push(format!("{} [{}]", p.def.objective.label(), units[0]));
    for (c, u) in p.def.constraints.iter().zip(&units[1..]) {
        head.push(format!("{} [{u}]", c.quantity.label()));
    }
    head.extend(["max_violation", "gradient_norm", "kkt_stationarity"].map(String::from));
    for c in &p.def.constraints {
        head.push(format!("multiplier {}", c.quantity.label()));
    }
    head.push("error".into());
    let mut t = CsvTable::new();
    t.row(head);
    for r in rows {
        let mut row = vec![r.start.to_string(), r.evaluation.to_string()];
        row.extend(r.x.iter().map(|x| number(*x)));
        match &r.eval {
            Ok(e) => {
                row.push(number(e.f));
                row.extend(e.q.iter().map(|q| number(*q)));
                let norm = e.df.iter().map(|d| d * d).sum::<f64>().sqrt();
                row.extend([number(r.violation), number(norm), number(r.stationarity)]);
                row.extend(r.multipliers.iter().map(|m| number(*m)));
                row.push(String::new());
            }
            Err(m) => {
                let empty = 2 + 2 * p.def.constraints.len() + 3;
                row.extend(std::iter::repeat_n(String::new(), empty));
                row.push(m.replace('\n', " "));
            }
        }
        t.row(row);
    }
    t.finish()
}

pub(super) fn convergence_figure(p: &Problem, rows: &[Row], starts: usize) -> Figure {
    let mut objective = Vec::new();
    let mut violation = Vec::new();
    for start in 1..=starts {
        let (mut ex, mut f, mut vx, mut v) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for r in rows.iter().filter(|r| r.start == start) {
            if let Ok(e) = &r.eval {
                ex.push(r.evaluation as f64);
                f.push(e.f);
                vx.push(r.evaluation as f64);
                v.push(r.violation);
            }
        }
        objective.push(Series::solid(format!("start {start}"), &ex, &f, start - 1));
        violation.push(Series::solid(format!("start {start}"), &vx, &v, start - 1));
    }
    Figure {
        title: format!(
            "{} {}: convergence",
            if p.def.maximize {
                "maximise"
            } else {
                "minimise"
            },
            p.def.objective.label()
        ),
        panels: vec![
            Panel {
                title: "objective".into(),
                x_label: "evaluation".into(),
                y_label: format!(
                    "{} [{}]",
                    p.def.objective.label(),
                    units(rows, 1 + p.def.constraints.len())[0]
                ),
                series: objective,
            },
            Panel {
                title: "largest constraint violation".into(),
                x_label: "evaluation".into(),
                y_label: "relative violation [1]".into(),
                series: violation,
            },
        ],
    }
}

/// Write the results of an optimisation and its summary (see [`run`]).
pub(super) fn finish(
    problem: &Problem,
    mechanism: bool,
    rows: &[Row],
    statuses: &[(usize, String)],
    out: &Path,
    interrupted: bool,
) -> Result<(String, u8), CliError> {
    let path = problem.path;
    let n_starts = problem.def.starts.len();
    std::fs::create_dir_all(out).map_err(|e| {
        runtime(format!(
            "cannot create the output directory {}: {e}",
            out.display()
        ))
    })?;
    write_atomic(
        &out.join("iterations.csv"),
        iterations_csv(problem, rows).as_bytes(),
    )?;
    let figure = convergence_figure(problem, rows, n_starts);
    if let Ok(svg) = figure.svg() {
        write_atomic(&out.join("convergence.svg"), svg.as_bytes())?;
    }
    if let Ok(png) = figure.png() {
        write_atomic(&out.join("convergence.png"), &png)?;
    }
    let mut text = String::new();
    let _ = writeln!(
        text,
        "{} {} over {} design variables, {} constraints; {} starts, {} evaluations",
        if problem.def.maximize {
            "maximise"
        } else {
            "minimise"
        },
        problem.def.objective.label(),
        problem.variables.len(),
        problem.def.constraints.len(),
        n_starts,
        rows.len()
    );
    for (s, status) in statuses {
        let evaluations = rows.iter().filter(|r| r.start == *s).count();
        let best = best_feasible(problem, rows, Some(*s))
            .and_then(|k| rows[k].eval.as_ref().ok())
            .map_or("no feasible design".to_string(), |e| {
                format!(
                    "best feasible {} = {:.9e}",
                    problem.def.objective.label(),
                    e.f
                )
            });
        let _ = writeln!(
            text,
            "start {s}: {status} after {evaluations} evaluations; {best}"
        );
    }
    let Some(k) = best_feasible(problem, rows, None) else {
        let _ = writeln!(
            text,
            "no feasible design found; every evaluation is in {}",
            out.join("iterations.csv").display()
        );
        return Ok((text, if interrupted { 130 } else { 1 }));
    };
    let best = &rows[k];
    let e = best.eval.as_ref().expect("a feasible row has values");
    let mut sets = problem.sets(&best.x);
    sets.extend(absolute_file_keys(path, &problem.src.parse()?));
    let optimum = problem.src.edited(&sets)?;
    let optimum_path = out.join("optimum.toml");
    let deck_text = if interrupted {
        format!(
            "# flexsens optimize was interrupted: this is the best feasible design of the {} \
             evaluations made (start {}, evaluation {}), not a converged optimum\n{}",
            rows.len(),
            best.start,
            best.evaluation,
            optimum.text
        )
    } else {
        optimum.text
    };
    write_atomic(&optimum_path, deck_text.as_bytes())?;
    let _ = writeln!(
        text,
        "optimum (start {}, evaluation {}): {} = {:.9e}",
        best.start,
        best.evaluation,
        problem.def.objective.label(),
        e.f
    );
    text.push_str(&optimum_lines(problem, best, e));
    // the optimum's full run, when the deck is a mechanism
    if mechanism && !interrupted {
        let request = crate::commands::run::RunRequest {
            out: Some(out),
            json: true,
            progress: false,
        };
        // a failure of this run does not hide the optimum found
        match crate::commands::run::run(&optimum_path, &[], &request) {
            Ok(_) => {
                let _ = writeln!(
                    text,
                    "the optimum's run: {}",
                    out.join("results.h5").display()
                );
            }
            Err(e) => {
                let _ = writeln!(text, "the optimum's run failed: {e}");
                return Ok((text, 1));
            }
        }
    }
    let _ = writeln!(
        text,
        "files: {}, {}, {}",
        optimum_path.display(),
        out.join("iterations.csv").display(),
        out.join("convergence.svg").display()
    );
    if interrupted {
        let _ = writeln!(
            text,
            "interrupted: the best feasible design so far is written"
        );
    }
    Ok((text, if interrupted { 130 } else { 0 }))
}

/// The optimum's variables (with the bounds they sit at), constraints with their multipliers,
/// and KKT stationarity, a line each.
fn optimum_lines(problem: &Problem, best: &Row, e: &Eval) -> String {
    let mut text = String::new();
    for ((v, x), &(lo, hi)) in problem
        .variables
        .iter()
        .zip(&best.x)
        .zip(&problem.def.bounds)
    {
        // the optimiser stops near an active bound, not on it: within 1e-6 of the range
        let near = 1e-6 * (hi - lo);
        let at = if *x <= lo + near {
            " (at its lower bound)"
        } else if *x >= hi - near {
            " (at its upper bound)"
        } else {
            ""
        };
        let _ = writeln!(text, "  {} = {x} {}{at}", v.name, v.unit);
    }
    for (i, c) in problem.def.constraints.iter().enumerate() {
        let bound = match problem.limits[i].0 {
            Bound::AtLeast(b) => format!(">= {b:e}"),
            Bound::AtMost(b) => format!("<= {b:e}"),
            Bound::Equals(b) => format!("= {b:e}"),
            Bound::EqualsNominal => unreachable!("resolved"),
        };
        let _ = writeln!(
            text,
            "  {} = {:.9e} ({bound}); multiplier dF*/d(bound) = {:.6e}",
            c.quantity.label(),
            e.q[i],
            best.multipliers.get(i).copied().unwrap_or(0.0)
        );
    }
    let _ = writeln!(
        text,
        "  KKT stationarity {:.2e} (relative), largest violation {:.2e}",
        best.stationarity, best.violation
    );
    text
}
