//! The files and the summary of `flexsens run`: the result file (HDF5), the CSV tables, and
//! the JSON and text summaries.

use crate::table::{CsvTable, number};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use nalgebra::DMatrix;

use super::compute::Computed;
use super::sensitivity;
use crate::deck::Source;
use crate::deck::design::FdSteps;
use crate::deck::design::{DesignVariable, objective_label};
use crate::deck::responses::ResponseDef;
use crate::results::{Attr, Group};
use crate::study::Mechanism;

/// Unit of a derivative of a quantity in `unit` per one `per` (`"1/deg"`, `"m/kg"`).
pub(crate) fn per(unit: &str, per: &str) -> String {
    let per = if per.contains('*') {
        format!("({per})")
    } else {
        per.to_string()
    };
    format!("{unit}/{per}")
}

/// The design variables' unit when they share one (`"deg"`), else a pointer to
/// `design/units`.
fn common_unit(vars: &[DesignVariable]) -> String {
    match vars.split_first() {
        Some((first, rest)) if rest.iter().all(|v| v.unit == first.unit) => first.unit.into(),
        _ => "per variable: design/units".into(),
    }
}

/// Unit of the derivatives of a quantity in `unit` with respect to every design variable.
fn per_design(unit: &str, vars: &[DesignVariable]) -> String {
    match vars.split_first() {
        Some((first, rest)) if rest.iter().all(|v| v.unit == first.unit) => per(unit, first.unit),
        _ => format!("{unit} per unit of each design variable (design/units)"),
    }
}

/// A row-major copy of a matrix.
pub(crate) fn row_major(m: &DMatrix<f64>) -> Vec<f64> {
    m.transpose().iter().copied().collect()
}

/// The result file's contents.
pub(crate) fn results(src: &Source, mech: &Mechanism, c: &Computed) -> Group {
    let n = mech.times.len();
    let outputs = &c.outputs;
    let mut g = Group::default();
    g.attrs.insert(
        "flexsens_version".into(),
        Attr::Text(env!("CARGO_PKG_VERSION").into()),
    );
    g.put("time", &[n], mech.times.clone()).units("s");
    for (ResponseDef { name, unit, .. }, v) in mech.responses.iter().zip(&c.values) {
        g.put(&format!("responses/{name}"), &[n], v.clone())
            .units(unit);
    }
    put_bodies(&mut g, mech, outputs);
    for (j, name) in mech.joint_names.iter().enumerate() {
        g.put(
            &format!("joints/{name}/reaction_on_b"),
            &[n, 6],
            outputs
                .iter()
                .flat_map(|o| {
                    let r = &o.reactions[j];
                    [
                        r.force_on_b[0],
                        r.force_on_b[1],
                        r.force_on_b[2],
                        r.moment_on_b[0],
                        r.moment_on_b[1],
                        r.moment_on_b[2],
                    ]
                })
                .collect(),
        )
        .units("N, N*m");
    }
    g.put(
        "constraints/position_violation",
        &[n],
        outputs.iter().map(|o| o.position_violation).collect(),
    )
    .units("m");
    g.put(
        "constraints/removed_position_violation",
        &[n],
        outputs
            .iter()
            .map(|o| o.removed_position_violation)
            .collect(),
    )
    .units("m");
    g.put(
        "constraints/velocity_violation",
        &[n],
        outputs.iter().map(|o| o.velocity_violation).collect(),
    )
    .units("m/s");
    g.put(
        "energy/total",
        &[n],
        outputs.iter().map(|o| o.energy.total()).collect(),
    )
    .units("J");
    put_statistics(&mut g, mech, c);
    let vars = &mech.design.variables;
    let m = vars.len();
    if m > 0 {
        g.put_text(
            "design/names",
            vars.iter().map(|v| v.name.clone()).collect(),
        );
        g.put(
            "design/values",
            &[m],
            vars.iter().map(|v| v.value).collect(),
        )
        .units(&common_unit(vars));
        g.put_text(
            "design/units",
            vars.iter().map(|v| v.unit.to_string()).collect(),
        );
        g.put_text(
            "design/targets",
            vars.iter().map(DesignVariable::describe).collect(),
        );
    }
    if let Some(s) = &c.sensitivities {
        let method = format!(
            "{}, {} modes",
            mech.design.method.name(),
            if mech.design.fixed_modes {
                "fixed"
            } else {
                "updated"
            }
        );
        g.group("sensitivities")
            .attrs
            .insert("method".into(), Attr::Text(method));
        for (ResponseDef { name, unit, .. }, d) in mech.responses.iter().zip(&s.responses) {
            if let Some(d) = d {
                g.put(&format!("sensitivities/{name}"), &[n, m], row_major(d))
                    .units(&per_design(unit, vars));
            }
        }
        for (body, df) in &s.frequencies {
            g.put(
                &format!("bodies/{body}/frequency_derivatives"),
                &[df.nrows(), m],
                row_major(df),
            )
            .units(&per_design("Hz", vars));
        }
    }
    put_objectives(&mut g, mech, c);
    g.put_text("meta/deck", vec![src.text.clone()]);
    g.put_text("meta/deck_path", vec![src.file.display().to_string()]);
    g.put_text("meta/overrides", src.overrides.clone());
    g
}

/// Every body's position, orientation and, for a flexible body, its modal coordinates,
/// frequencies and basis check.
fn put_bodies(g: &mut Group, mech: &Mechanism, outputs: &[mbs::Output]) {
    let n = mech.times.len();
    for name in &mech.body_order {
        let b = &mech.bodies[name];
        let i = b.id.index();
        g.put(
            &format!("bodies/{name}/position"),
            &[n, 3],
            outputs
                .iter()
                .flat_map(|o| o.positions[i].iter().copied().collect::<Vec<_>>())
                .collect(),
        )
        .units("m");
        g.put(
            &format!("bodies/{name}/orientation"),
            &[n, 3, 3],
            outputs
                .iter()
                .flat_map(|o| {
                    o.orientations[i]
                        .transpose()
                        .iter()
                        .copied()
                        .collect::<Vec<_>>()
                })
                .collect(),
        )
        .units("1");
        if b.nodes.is_some() {
            let m = outputs[0].modal[i].len();
            g.put(
                &format!("bodies/{name}/modal_coordinates"),
                &[n, m],
                outputs.iter().flat_map(|o| o.modal[i].clone()).collect(),
            )
            .units("1");
            g.put(
                &format!("bodies/{name}/frequencies"),
                &[b.frequencies.len()],
                b.frequencies.clone(),
            )
            .units("Hz");
            if let Some(basis) = &b.basis {
                let cases = basis.check.as_ref().map_or(&[][..], |c| &c.cases[..]);
                g.put(
                    &format!("bodies/{name}/basis_missed_compliance"),
                    &[cases.len()],
                    cases.iter().map(|c| c.missed).collect(),
                )
                .units("1")
                .attr(
                    "load_cases",
                    Attr::Text(
                        cases
                            .iter()
                            .map(|c| c.name.as_str())
                            .collect::<Vec<_>>()
                            .join("; "),
                    ),
                )
                .attr("eigenmodes", Attr::I64(basis.eigenmodes as i64))
                .attr("correction_modes", Attr::I64(basis.correction_modes as i64));
            }
        }
    }
}

/// The integrator's counters and tolerances (`rtol`, `atol` with its default resolved,
/// `error_weights`) as attributes of `/statistics` (and, for a fixed-step run,
/// `max_error_ratio`: its largest estimated local error relative to the deck's tolerances; for
/// a loose adaptive run, `history_error_NAME`: each response's estimated history error
/// relative to its largest value).
fn put_statistics(g: &mut Group, mech: &Mechanism, c: &Computed) {
    let st = &c.statistics;
    let mut counters = vec![
        ("steps", st.steps),
        ("rejected_steps", st.rejected_steps),
        ("newton_failures", st.newton_failures),
        ("newton_iterations", st.newton_iterations),
        ("rhs_evaluations", st.rhs_evaluations),
        ("jacobians", st.jacobians),
        ("factorizations", st.factorizations),
    ];
    if let Some(s) = &c.sensitivities {
        let ss = &s.sensitivity_statistics;
        counters.extend([
            ("sensitivity_dual_evaluations", ss.dual_evaluations),
            ("sensitivity_corrector_iterations", ss.corrector_iterations),
            ("sensitivity_direct_solves", ss.direct_solves),
        ]);
        if let Some((_, a, m)) = &s.adjoint {
            counters.extend([
                ("adjoint_steps", a.steps),
                ("adjoint_recordings", a.reverse_evaluations),
                ("adjoint_sweeps", a.sweeps),
                ("adjoint_jacobians", a.jacobians),
                ("adjoint_recomputed_steps", m.recomputed_steps),
                ("adjoint_state_memory", m.peak_bytes),
            ]);
        }
    }
    for (k, v) in counters {
        g.group("statistics")
            .attrs
            .insert(k.into(), Attr::I64(v as i64));
    }
    // a loose adaptive run: the estimated error of each response's history
    if let Some(errors) = &c.history_error {
        for (r, e) in mech.responses.iter().zip(errors) {
            if let Some(e) = e {
                g.group("statistics")
                    .attrs
                    .insert(format!("history_error_{}", r.name), Attr::F64(*e));
            }
        }
    }
    // the tolerances the run was made with, the default atol resolved
    let stats = g.group("statistics");
    let rtol = mech
        .options
        .accuracy
        .as_ref()
        .map_or(mech.options.rtol, |(r, _)| *r);
    stats.attrs.insert("rtol".into(), Attr::F64(rtol));
    let atol = mech.displacement_tolerance;
    stats.attrs.insert("atol".into(), Attr::F64(atol));
    stats.attrs.insert(
        "error_weights".into(),
        Attr::Text(mech.error_weights_name().into()),
    );
    // a fixed-step run: its largest estimated local error against the deck's tolerances
    if mech.options.accuracy.is_some() {
        g.group("statistics")
            .attrs
            .insert("max_error_ratio".into(), Attr::F64(st.max_error_ratio));
    }
}

/// The objectives with their gradients and the finite differences' cases.
fn put_objectives(g: &mut Group, mech: &Mechanism, c: &Computed) {
    let n = mech.times.len();
    let vars = &mech.design.variables;
    let m = vars.len();
    for o in &c.objectives {
        let base = format!("objectives/{}", o.name);
        g.put(&format!("{base}/value"), &[1], vec![o.value])
            .units(o.unit);
        if let Some(t) = o.time {
            g.put(&format!("{base}/time"), &[1], vec![t]).units("s");
        }
        if !o.gradient.is_empty() {
            g.put(&format!("{base}/gradient"), &[m], o.gradient.clone())
                .units(&per_design(o.unit, vars));
        }
        let og = g.group(&base);
        og.attrs
            .insert("response".into(), Attr::Text(o.response.clone()));
        og.attrs.insert(
            "kind".into(),
            Attr::Text(objective_label(&o.kind, o.window)),
        );
    }
    for case in &c.fd {
        let base = format!("finite_differences/{}", case.label);
        for (ResponseDef { name, unit, .. }, d) in mech.responses.iter().zip(&case.responses) {
            if let Some(d) = d {
                g.put(&format!("{base}/{name}"), &[n, m], row_major(d))
                    .units(&per_design(unit, vars));
            }
        }
        for (o, d) in c.objectives.iter().zip(&case.objectives) {
            g.put(&format!("{base}/objectives/{}", o.name), &[m], d.clone())
                .units(&per_design(o.unit, vars));
        }
        for (ResponseDef { name, unit, .. }, noise) in mech.responses.iter().zip(&case.noise) {
            if let Some(noise) = noise {
                g.put(&format!("{base}/noise/{name}"), &[m], noise.clone())
                    .units(&per_design(unit, vars));
            }
        }
        g.put(&format!("{base}/perturbations"), &[m], case.deltas.clone())
            .units(&common_unit(vars));
        let cg = g.group(&base);
        for (k, v) in [
            ("scheme", if case.central { "central" } else { "forward" }),
            (
                "perturbation",
                if case.relative {
                    "relative"
                } else {
                    "absolute"
                },
            ),
            (
                "steps",
                match case.steps {
                    FdSteps::Replay => "replay",
                    FdSteps::Adaptive => "adaptive",
                },
            ),
        ] {
            cg.attrs.insert(k.into(), Attr::Text(v.into()));
        }
        cg.attrs.insert("size".into(), Attr::F64(case.size));
    }
}

/// `history.csv`: time and every response.
pub(crate) fn history_csv(mech: &Mechanism, c: &Computed) -> String {
    let mut t = CsvTable::new();
    t.row(
        std::iter::once("time [s]".to_string()).chain(
            mech.responses
                .iter()
                .map(|ResponseDef { name, unit, .. }| format!("{name} [{unit}]")),
        ),
    );
    for (i, time) in mech.times.iter().enumerate() {
        t.row(std::iter::once(number(*time)).chain(c.values.iter().map(|v| number(v[i]))));
    }
    t.finish()
}

/// `sensitivities.csv`: time and `d(response)/d(variable)` for every response that has
/// sensitivities and every design variable (none with the adjoint method, which computes the
/// objectives' gradients only).
pub(crate) fn sensitivities_csv(mech: &Mechanism, c: &Computed) -> Option<String> {
    let s = c.sensitivities.as_ref().filter(|s| s.adjoint.is_none())?;
    let vars = &mech.design.variables;
    let mut head = vec!["time [s]".to_string()];
    let mut columns = Vec::new();
    for (ResponseDef { name, unit, .. }, d) in mech.responses.iter().zip(&s.responses) {
        if let Some(d) = d {
            for (j, v) in vars.iter().enumerate() {
                head.push(format!("d {name}/d {} [{}]", v.name, per(unit, v.unit)));
                columns.push((d, j));
            }
        }
    }
    let mut t = CsvTable::new();
    t.row(head);
    for (i, time) in mech.times.iter().enumerate() {
        t.row(
            std::iter::once(number(*time)).chain(columns.iter().map(|(d, j)| number(d[(i, *j)]))),
        );
    }
    Some(t.finish())
}

/// `gradients.csv`: one row per objective, its value and one column per design variable.
pub(crate) fn gradients_csv(mech: &Mechanism, c: &Computed) -> String {
    let mut head: Vec<String> = ["objective", "response", "kind", "value", "unit", "time [s]"]
        .map(String::from)
        .into();
    if c.sensitivities.is_some() {
        for v in &mech.design.variables {
            head.push(format!("d/d {} [unit/{}]", v.name, v.unit));
        }
    }
    let mut t = CsvTable::new();
    t.row(head);
    for o in &c.objectives {
        let fields = [
            o.name.clone(),
            o.response.clone(),
            objective_label(&o.kind, o.window).to_string(),
            number(o.value),
            o.unit.to_string(),
            o.time.map(number).unwrap_or_default(),
        ];
        t.row(
            fields
                .into_iter()
                .chain(o.gradient.iter().map(|g| number(*g))),
        );
    }
    t.finish()
}

/// The machine-readable summary (`--json`), also the source of the table.
pub(crate) fn summary(
    src: &Source,
    mech: &Mechanism,
    c: &Computed,
    out: &Path,
) -> serde_json::Value {
    use serde_json::json;
    let st = &c.statistics;
    let responses: serde_json::Map<_, _> = mech
        .responses
        .iter()
        .zip(&c.values)
        .map(|(ResponseDef { name, unit, .. }, v)| {
            (
                name.clone(),
                json!({
                    "unit": unit,
                    "final": v.last(),
                    "min": v.iter().copied().fold(f64::INFINITY, f64::min),
                    "max": v.iter().copied().fold(f64::NEG_INFINITY, f64::max),
                }),
            )
        })
        .collect();
    let design: Vec<_> = mech
        .design
        .variables
        .iter()
        .map(|v| json!({"name": v.name, "target": v.describe(), "value": v.value, "unit": v.unit}))
        .collect();
    let objectives: Vec<_> = c
        .objectives
        .iter()
        .map(|o| {
            json!({
                "name": o.name, "response": o.response, "kind": objective_label(&o.kind, o.window),
                "value": o.value, "unit": o.unit, "time": o.time, "gradient": o.gradient,
            })
        })
        .collect();
    let fd: Vec<_> =
        c.fd.iter()
            .map(|case| {
                let s = c
                    .sensitivities
                    .as_ref()
                    .expect("comparisons need sensitivities");
                let mut worst = serde_json::Map::new();
                let mut absolute = serde_json::Map::new();
                // the noise relative to the largest derivative, per variable, the worst
                let mut noise = serde_json::Map::new();
                for ((ResponseDef { name, .. }, (f, d)), n) in mech
                    .responses
                    .iter()
                    .zip(case.responses.iter().zip(&s.responses))
                    .zip(&case.noise)
                {
                    let (Some(f), Some(d)) = (f, d) else {
                        continue;
                    };
                    worst.insert(name.clone(), json!(sensitivity::relative_difference(f, d)));
                    absolute.insert(
                        name.clone(),
                        json!({"difference": (f - d).amax(), "sensitivity": d.amax()}),
                    );
                    if let Some(n) = n {
                        let ratio = n
                            .iter()
                            .zip(d.column_iter())
                            .map(|(x, column)| {
                                let scale = column.amax();
                                if scale > 0.0 { x / scale } else { *x }
                            })
                            .fold(0.0, f64::max);
                        noise.insert(name.clone(), json!(ratio));
                    }
                }
                // each objective's gradient against the differences of its value
                let objectives: serde_json::Map<_, _> = (c.objectives.iter())
                    .zip(&case.objectives)
                    .filter(|(o, d)| !o.gradient.is_empty() && o.gradient.len() == d.len())
                    .map(|(o, d)| {
                        // as the responses': per variable, relative to the gradient
                        let row = |x: &[f64]| nalgebra::DMatrix::from_row_slice(1, x.len(), x);
                        let rel = sensitivity::relative_difference(&row(d), &row(&o.gradient));
                        (o.name.clone(), json!(rel))
                    })
                    .collect();
                json!({
                    "case": case.label,
                    "max_relative_difference": worst,
                    "max_absolute": absolute,
                    "relative_noise": noise,
                    "objectives": objectives,
                })
            })
            .collect();
    json!({
        "deck": src.file.display().to_string(),
        "output": out.display().to_string(),
        "t_end": mech.times.last(),
        "outputs": mech.times.len(),
        "steps": st.steps,
        "rejected_steps": st.rejected_steps,
        "rhs_evaluations": st.rhs_evaluations,
        "max_position_violation": c.outputs.iter().map(|o| o.position_violation).fold(0.0, f64::max),
        "max_removed_position_violation": c.outputs.iter().map(|o| o.removed_position_violation).fold(0.0, f64::max),
        "responses": responses,
        "design": design,
        "objectives": objectives,
        "finite_differences": fd,
    })
}

/// The one-screen summary for people.
pub(crate) fn summary_text(
    mech: &Mechanism,
    c: &Computed,
    summary: &serde_json::Value,
    written: &[PathBuf],
) -> String {
    let n = mech.times.len();
    let st = &c.statistics;
    let mut s = String::new();
    if let Some(t) = &mech.title {
        let _ = writeln!(s, "{t}");
    }
    let _ = writeln!(
        s,
        "{} bodies, {} joints; t = {} … {} s, {} output times",
        mech.body_order.len(),
        mech.joint_names.len(),
        mech.times[0],
        mech.times[n - 1],
        n
    );
    for name in &mech.body_order {
        if let Some(b) = &mech.bodies[name].basis {
            let _ = writeln!(s, "basis of body {name}: {}", b.describe());
        }
    }
    let _ = writeln!(
        s,
        "integrator: {} steps ({} rejected), {} right-hand sides, {} Jacobians{}",
        st.steps,
        st.rejected_steps,
        st.rhs_evaluations,
        st.jacobians,
        if st.stability_limited > 0 {
            format!(
                "; order lowered for stability {} times",
                st.stability_limited
            )
        } else {
            String::new()
        }
    );
    if let Some((_, a, m)) = c.sensitivities.as_ref().and_then(|s| s.adjoint.as_ref()) {
        let mib = m.peak_bytes as f64 / (1024.0 * 1024.0);
        let _ = writeln!(
            s,
            "adjoint: {} sweeps, {} Jacobians; the run's states {mib:.1} MiB at the most, {} \
             steps recomputed",
            a.sweeps, a.jacobians, m.recomputed_steps
        );
    }
    let _ = writeln!(
        s,
        "largest position-constraint violation: {:.3e} (equations dropped as redundant: {:.3e})",
        summary["max_position_violation"].as_f64().unwrap_or(0.0),
        summary["max_removed_position_violation"]
            .as_f64()
            .unwrap_or(0.0)
    );
    if !c.values.is_empty() {
        let _ = writeln!(
            s,
            "{:<24} {:>14} {:>14} {:>14}  unit",
            "response", "min", "max", "final"
        );
        for (ResponseDef { name, unit, .. }, v) in mech.responses.iter().zip(&c.values) {
            let r = &summary["responses"][name];
            let _ = writeln!(
                s,
                "{name:<24} {:>14.6e} {:>14.6e} {:>14.6e}  {unit}",
                r["min"].as_f64().unwrap_or(0.0),
                r["max"].as_f64().unwrap_or(0.0),
                v.last().copied().unwrap_or(0.0)
            );
        }
    }
    let vars = &mech.design.variables;
    if c.sensitivities.is_some() {
        let names: Vec<String> = vars
            .iter()
            .map(|v| {
                if v.unit == "deg" {
                    format!("{} = {}°", v.name, v.value)
                } else {
                    format!("{} = {} {}", v.name, v.value, v.unit)
                }
            })
            .collect();
        // how the modes follow the design, for a mechanism that has modes
        let modes = match (mech.flexible.is_empty(), mech.design.fixed_modes) {
            (true, _) => "",
            (false, true) => " (fixed modes)",
            (false, false) => " (updated modes)",
        };
        let _ = writeln!(
            s,
            "sensitivities with respect to {}{modes}",
            names.join(", ")
        );
    }
    if !c.objectives.is_empty() {
        let _ = write!(s, "{:<24} {:>14}", "objective", "value");
        if c.sensitivities.is_some() {
            for v in vars {
                let _ = write!(s, " {:>14}", format!("d/d {}", v.name));
            }
        }
        let _ = writeln!(s, "  unit");
        for o in &c.objectives {
            let _ = write!(s, "{:<24} {:>14.6e}", o.name, o.value);
            for g in &o.gradient {
                let _ = write!(s, " {g:>14.6e}");
            }
            let at = o
                .time
                .map(|t| format!(" (at {t:.6} s)"))
                .unwrap_or_default();
            let _ = writeln!(s, "  {}{at}", o.unit);
        }
    }
    s.push_str(&super::sensitivity::fd_summary_text(summary));
    let files: Vec<String> = written.iter().map(|p| p.display().to_string()).collect();
    let _ = writeln!(s, "written: {}", files.join(", "));
    s
}
