//! The files of `flexsens run`: the result file (HDF5) and the CSV tables (the summaries are
//! `run_summary`'s).

use crate::table::{CsvTable, number};

use nalgebra::DMatrix;

use super::compute::Computed;
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
