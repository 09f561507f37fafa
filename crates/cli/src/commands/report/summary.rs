//! The report's summary (`summary.md` and `summary.json`): the natural frequencies, the
//! direct sensitivities against finite differences, the peaks, the settings and the runs.

use super::*;

pub(super) struct Settings<'a> {
    pub(super) raw: &'a RawDeck,
    pub(super) nominal: &'a Mechanism,
    pub(super) output_step: f64,
    pub(super) fixed_step: f64,
    pub(super) jobs: usize,
    pub(super) overrides: &'a [String],
    pub(super) seconds: f64,
}

/// summary.md and summary.json.
pub(super) fn summary(
    src: &Source,
    s: &Subject,
    layups: &[Layup],
    st: &Settings,
    files: &[String],
) -> (String, serde_json::Value) {
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

    let freq_json = frequencies(&mut md, s, layups);
    let diff_json = differences(&mut md, layups);
    let peak = peaks(&mut md, layups);
    let settings_json = settings(&mut md, st);
    let runs_json = runs(&mut md, layups);
    let _ = writeln!(
        md,
        "\nTotal wall time before the figures: {:.1} s on {} threads.\n",
        st.seconds, st.jobs
    );
    figure_list(&mut md, files);
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
        "settings": settings_json,
        "runs": runs_json,
        "files": files,
        "seconds": st.seconds,
    });
    (md, js)
}

/// The table of every flexible body's frequencies and their derivatives, per lay-up.
fn frequencies(md: &mut String, s: &Subject, layups: &[Layup]) -> Vec<serde_json::Value> {
    // natural frequencies
    let _ = writeln!(*md, "## Natural frequencies\n");
    let _ = writeln!(
        *md,
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
        let _ = writeln!(*md, "Body `{body}`:\n");
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
        let _ = writeln!(*md, "{head}\n{rule}");
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
            let _ = writeln!(*md, "{row}");
            freq_json.push(json!({
                "layup": l.angle, "body": body, "frequencies_hz": f, "derivatives_hz_per_deg": d,
            }));
        }
        let _ = writeln!(*md);
    }

    freq_json
}

/// The table of the direct sensitivities' differences from the finite differences.
fn differences(md: &mut String, layups: &[Layup]) -> Vec<serde_json::Value> {
    // agreement of the sensitivities
    let _ = writeln!(*md, "## Direct sensitivities against finite differences\n");
    let _ = writeln!(
        *md,
        "Largest difference over the history, relative to the largest direct sensitivity: \
         max_t |FD − direct| / max_t |direct|. Central differences of relative size \
         {CHECK_SIZE:e} on the replayed step sequence check the direct method; the forward \
         differences are those of the figures (\"replay\": the perturbed run takes the nominal \
         run's steps; \"adaptive\": it chooses its own).\n"
    );
    let _ = writeln!(
        *md,
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
    let _ = writeln!(*md, "{head}\n{rule}");
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
        let _ = writeln!(*md, "{row}");
        diff_json.push(json!({
            "layup": l.angle,
            "max_abs_direct": amax(&l.main.sensitivity),
            "direct_vanishes": absolute,
            "relative": rel,
            "absolute": abs,
        }));
    }
    let _ = writeln!(*md);
    diff_json
}

/// The peak deflection of every lay-up and its time.
fn peaks(md: &mut String, layups: &[Layup]) -> Vec<serde_json::Value> {
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
    let _ = writeln!(*md, "Peak normalised deflection:\n");
    let _ = writeln!(*md, "| lay-up | peak [1] | at t [s] |\n|---|---:|---:|");
    for p in &peak {
        let _ = writeln!(
            *md,
            "| [{}°] | {:.4e} | {:.5} |",
            angle_name(p["layup"].as_f64().unwrap_or(f64::NAN)),
            p["peak_deflection"].as_f64().unwrap_or(f64::NAN),
            p["time"].as_f64().unwrap_or(f64::NAN)
        );
    }
    let _ = writeln!(*md);

    peak
}

/// The settings section, and the settings as JSON.
fn settings(md: &mut String, st: &Settings) -> serde_json::Value {
    let mech = st.nominal;
    let opt = &mech.options;
    let atol = mech.displacement_tolerance;
    let t0 = mech.times.first().copied().unwrap_or(0.0);
    let t1 = mech.times.last().copied().unwrap_or(0.0);
    let variable_step = matches!(opt.control, mbs::StepControl::Adaptive { .. });
    let _ = writeln!(*md, "## Settings\n");
    let _ = writeln!(
        *md,
        "- time span {} s to {} s, {} output times every {} s",
        short(t0),
        short(t1),
        mech.times.len(),
        short(st.output_step)
    );
    let _ = writeln!(
        *md,
        "- integrator of the deck: {} (rtol {:e}, atol {:e}{}); it is used by the main, \
         fixed-modes and central runs",
        if variable_step {
            "variable step and order BDF"
        } else {
            "fixed-step BDF (the \"variable-step\" panels then show fixed steps too)"
        },
        opt.rtol,
        atol,
        if mech.displacement_weights {
            " m, displacement error weights"
        } else {
            ""
        }
    );
    let _ = writeln!(
        *md,
        "- fixed-step runs (Fig. 6, left panels): `analysis.integrator = \"fixed\"`, \
         `analysis.step = {}` s",
        short(st.fixed_step)
    );
    let _ = writeln!(
        *md,
        "- direct sensitivities: direct differentiation; main, fixed-step and central runs \
         with updated modes (Nelson's method), the fixed-modes run keeps the modes of each \
         lay-up"
    );
    let _ = writeln!(
        *md,
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
        let _ = writeln!(*md, "- body `{name}`: {kind}, elements {elements}, {basis}");
        mesh_json.push(json!({"body": name, "kind": kind, "elements": elements, "modes": modes}));
    }
    if !st.overrides.is_empty() {
        let _ = writeln!(
            *md,
            "- deck edited by `--set {}`",
            st.overrides.join(" --set ")
        );
    }
    json!({
        "t_start": t0, "t_end": t1, "output_step": st.output_step,
        "variable_step": variable_step, "rtol": opt.rtol, "atol": atol,
        "error_weights": mech.error_weights_name(),
        "fixed_step": st.fixed_step,
        "forward_sizes": SIZES, "fig6_size": FIG6_SIZE, "central_size": CHECK_SIZE,
        "bodies": mesh_json, "overrides": st.overrides, "threads": st.jobs,
    })
}

/// The table of the runs of every lay-up.
fn runs(md: &mut String, layups: &[Layup]) -> Vec<serde_json::Value> {
    let _ = writeln!(*md, "\n## Runs\n");
    let _ = writeln!(
        *md,
        "| lay-up | run | steps | rejected | wall time [s] |\n|---|---|---:|---:|---:|"
    );
    let mut runs_json = Vec::new();
    for l in layups {
        for (kind, r) in Kind::ALL
            .iter()
            .zip([l.main, l.fixed_modes, l.fixed_step, l.central])
        {
            let _ = writeln!(
                *md,
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
    runs_json
}

/// The list of the figures with what each shows.
fn figure_list(md: &mut String, files: &[String]) {
    let _ = writeln!(*md, "## Figures\n");
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
        let _ = writeln!(*md, "- `{stem}.svg`, `{stem}.png`: {what}");
    }
}
