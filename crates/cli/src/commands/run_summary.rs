//! The summaries of `flexsens run`: the JSON document (`--json`) and the text table made
//! from it.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::compute::Computed;
use super::sensitivity;
use crate::deck::Source;
use crate::deck::design::objective_label;
use crate::deck::responses::ResponseDef;
use crate::study::Mechanism;

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
