//! The report's figures: the paper's Figs. 5–13 from the runs of every lay-up.

use super::*;

pub(super) const SENS_LABEL: &str = "d(deflection)/dθ [1/deg]";
pub(super) const TIME_LABEL: &str = "time [s]";

/// The figures: (file stem, figure).
pub(super) fn figures(s: &Subject, layups: &[Layup], fixed_step: f64) -> Vec<(String, Figure)> {
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

pub(super) fn fmt_g(x: f64) -> String {
    if x.is_nan() {
        "–".into()
    } else {
        format!("{x:.3e}")
    }
}
