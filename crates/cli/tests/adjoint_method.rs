//! `sensitivity.method = "adjoint"` end to end: on both paper decks (a beam and a shell body,
//! both with geometric stiffening and static correction modes) with ply-angle, ply-thickness
//! and rigid-mass variables, every objective kind's gradient equals the direct method's (the
//! exact derivative of the same discrete solution) to 1e-8, and the run's finite-difference
//! check compares the objectives' gradients, which are all the adjoint gives.

mod common;

use common::{f64s, run_results, with_extra};
use flexsens::results::{Attr, Group};

/// Variables of three kinds and objectives of every kind, windowed ones among them.
const EXTRA: &str = r#"
[design.outer]
kind = "ply-thickness"
laminate = "LAMINATE"
plies = [0]

[design.slider_mass]
kind = "rigid-mass"
body = "slider"

[objective.mean_late]
response = "mid_deflection"
kind = "mean"
window = [0.0011, 0.0029]

[objective.ks]
response = "mid_deflection"
kind = "ks"
rho = 2000.0

[objective.slider_final]
response = "slider_x"
kind = "final"

[objective.at_mid]
response = "mid_deflection"
kind = "at"
time = 0.0017

[objective.deflection_integral]
response = "mid_deflection"
kind = "integral"
window = [0.0004, 0.003]
"#;

/// A short run (about 0.6 of a crank revolution).
const T_END: &str = "analysis.t_end=0.003";

/// The objectives' gradients of a run's summary, by name.
fn gradients(j: &serde_json::Value) -> Vec<(String, Vec<f64>)> {
    (j["objectives"].as_array().unwrap().iter())
        .map(|o| {
            let g = o["gradient"].as_array().unwrap();
            let g = g.iter().map(|x| x.as_f64().unwrap()).collect();
            (o["name"].as_str().unwrap().to_string(), g)
        })
        .collect()
}

fn attr(g: &Group, name: &str) -> i64 {
    match g.groups["statistics"].attrs.get(name) {
        Some(Attr::I64(v)) => *v,
        other => panic!("statistics attribute {name}: {other:?}"),
    }
}

/// The deck with [`EXTRA`] run by the direct and the adjoint method: their gradients agree.
fn adjoint_equals_direct(deck: &str, laminate: &str) {
    let (dir, path) = with_extra(deck, &EXTRA.replace("LAMINATE", laminate));
    let sets = |method: &str| {
        [
            T_END.to_string(),
            format!("sensitivity.method=\"{method}\""),
            "finite_differences.enabled=false".to_string(),
        ]
    };
    let run = |method: &str, extra: Option<&str>| {
        let mut s = sets(method).to_vec();
        s.extend(extra.map(str::to_string));
        let s: Vec<&str> = s.iter().map(String::as_str).collect();
        run_results(
            &path,
            &dir.path().join(extra.map_or(method, |_| "extra")),
            &s,
        )
    };
    let (direct, _) = run("direct", None);
    let (adjoint, h5) = run("adjoint", None);
    // the run's states within 20 kB (about a twentieth of them): the dropped ones recomputed
    // from checkpoints for the backward sweep, bitwise, so the same gradients to the bit
    let (checkpointed, h5_checkpointed) = run("adjoint", Some("sensitivity.adjoint_memory=0.02"));
    assert_eq!(checkpointed["objectives"], adjoint["objectives"]);
    assert_eq!(
        attr(&h5, "adjoint_recomputed_steps"),
        0,
        "16 MiB by default"
    );
    let recomputed = attr(&h5_checkpointed, "adjoint_recomputed_steps");
    let steps = attr(&h5_checkpointed, "steps");
    assert!(
        recomputed > steps / 2 && recomputed < 3 * steps,
        "{recomputed} of {steps}"
    );
    let memory = |h5| attr(h5, "adjoint_state_memory");
    assert!(
        memory(&h5_checkpointed) < memory(&h5) / 2,
        "{} B against {} B",
        memory(&h5_checkpointed),
        memory(&h5)
    );
    let (d, a) = (gradients(&direct), gradients(&adjoint));
    assert_eq!(d.len(), 7, "the deck's two objectives and the five above");
    let mut nonzero = 0;
    for ((name, gd), (_, ga)) in d.iter().zip(&a) {
        assert_eq!(gd.len(), 3);
        let scale = gd.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let diff = (gd.iter().zip(ga)).fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
        // (a peak at the start, where the rod is straight whatever the design, has none)
        nonzero += usize::from(scale > 0.0);
        assert!(
            diff <= 1e-8 * scale,
            "{deck} {name}: adjoint {ga:?} vs direct {gd:?} ({:.2e})",
            diff / scale
        );
    }
    assert!(nonzero >= 6, "{d:?}");
    // the same values and histories; no response sensitivities; the sweep's counters
    assert_eq!(direct["objectives"], {
        let mut o = adjoint["objectives"].clone();
        for (x, y) in
            (o.as_array_mut().unwrap().iter_mut()).zip(direct["objectives"].as_array().unwrap())
        {
            x["gradient"] = y["gradient"].clone();
        }
        o
    });
    assert!(!dir.path().join("adjoint/sensitivities.csv").exists());
    assert!(dir.path().join("direct/sensitivities.csv").exists());
    assert!(h5.get("sensitivities/mid_deflection").is_none());
    assert_eq!(attr(&h5, "adjoint_steps"), attr(&h5, "steps"));
    assert!(attr(&h5, "adjoint_sweeps") >= attr(&h5, "steps"));
    assert!(!f64s(&h5, "objectives/ks/gradient").is_empty());
}

#[test]
fn the_adjoint_gives_the_direct_gradients_on_the_beam_deck() {
    adjoint_equals_direct("slider_crank_beam.toml", "tube_wall");
}

#[test]
fn the_adjoint_gives_the_direct_gradients_on_the_plate_deck() {
    adjoint_equals_direct("slider_crank_plate.toml", "plate");
}

#[test]
fn the_finite_difference_check_compares_the_adjoint_objective_gradients() {
    let (dir, path) = with_extra("slider_crank_beam.toml", "");
    let sets = [T_END, "sensitivity.method=\"adjoint\""];
    let (j, _) = run_results(&path, &dir.path().join("out"), &sets);
    let cases = j["finite_differences"].as_array().unwrap();
    assert!(!cases.is_empty());
    for case in cases {
        let objectives = case["objectives"].as_object().unwrap();
        assert_eq!(objectives.len(), 2, "{case}");
        for (name, d) in objectives {
            // central differences at 0.01 % on replayed steps: the δ² truncation and the
            // replays' Newton tolerance, far below a wrong gradient's error
            let d = d.as_f64().unwrap();
            assert!(d < 1e-4, "{name}: |FD − adjoint| / |adjoint| = {d:e}");
        }
        assert!(
            case["max_relative_difference"]
                .as_object()
                .unwrap()
                .is_empty()
        );
    }
}

#[test]
fn an_optimisation_reads_the_same_gradients_from_the_adjoint() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(common::deck("optimize_beam_layup.toml"))
        .unwrap()
        .replace("max_evaluations = 60", "max_evaluations = 3")
        .replace(
            "starts = [[45.0, -45.0, -45.0, 45.0], [60.0, 30.0, -30.0, -60.0]]",
            "starts = [[45.0, -45.0, -45.0, 45.0]]",
        );
    let path = dir.path().join("layup.toml");
    std::fs::write(&path, text).unwrap();
    // the first evaluation's objective gradient norm (iterations.csv), by each method
    let norm = |method: &str| {
        let m = format!("sensitivity.method=\"{method}\"");
        let out = dir.path().join(method);
        let (o, csv) = common::optimize_iterations(&path, &out, &[T_END, &m]);
        assert!(o.status.success() || o.status.code() == Some(1), "{o:?}");
        let head: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
        let col = (head.iter()).position(|h| *h == "gradient_norm").unwrap();
        let row: Vec<&str> = csv.lines().nth(1).unwrap().split(',').collect();
        row[col].parse::<f64>().unwrap()
    };
    let (direct, adjoint) = (norm("direct"), norm("adjoint"));
    assert!(
        (direct - adjoint).abs() < 1e-8 * direct,
        "gradient norms: direct {direct}, adjoint {adjoint}"
    );
}

#[test]
fn the_adjoint_without_objectives_warns_that_it_computes_nothing() {
    let text = std::fs::read_to_string(common::deck("slider_crank_beam.toml")).unwrap();
    let start = text.find("[objective.peak_deflection]").unwrap();
    let end = text.find("[sensitivity]").unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("none.toml");
    std::fs::write(&path, format!("{}{}", &text[..start], &text[end..])).unwrap();
    let out = dir.path().join("out");
    let o = common::run(&[
        "run",
        path.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--set",
        T_END,
        "--set",
        "sensitivity.method=\"adjoint\"",
        "--set",
        "finite_differences.enabled=false",
    ]);
    assert!(o.status.success(), "{o:?}");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("sensitivity.method") && err.contains("declares none"),
        "{err}"
    );
}

/// `sensitivity.method = "auto"`: the adjoint for the tailored rod's 128 variables and one
/// objective, the simultaneous method for the beam deck's one variable and two objectives
/// (named in the results' `/sensitivities` group either way).
#[test]
fn auto_takes_the_adjoint_for_many_variables_per_objective() {
    let dir = tempfile::tempdir().unwrap();
    let method_of = |deck: &str, t_end: &str| {
        let out = dir.path().join(deck);
        let sets = [
            t_end,
            "sensitivity.method=\"auto\"",
            "finite_differences.enabled=false",
        ];
        let (_, h5) = run_results(&common::deck(deck), &out, &sets);
        let method = match h5.groups["sensitivities"].attrs.get("method") {
            Some(Attr::Text(m)) => m.clone(),
            other => panic!("{deck}: {other:?}"),
        };
        (method, out.join("sensitivities.csv").exists())
    };
    let (method, csv) = method_of("optimize_tailored_rod.toml", "analysis.t_end=0.002");
    assert_eq!((method.as_str(), csv), ("adjoint, updated modes", false));
    let (method, csv) = method_of("slider_crank_beam.toml", T_END);
    assert_eq!(
        (method.as_str(), csv),
        ("simultaneous, updated modes", true)
    );
}

#[test]
fn a_memory_budget_that_is_not_a_positive_number_is_refused() {
    let text = std::fs::read_to_string(common::deck("slider_crank_beam.toml")).unwrap();
    for bad in ["0.0", "-1.0", "nan"] {
        let deck = text.replacen(
            "[sensitivity]\n",
            &format!("[sensitivity]\nadjoint_memory = {bad}\n"),
            1,
        );
        let (_dir, err) = common::bad_deck(&deck, |p| common::with_deck("check", p, &[]));
        let line = common::line_of(&deck, "adjoint_memory");
        assert!(
            err.contains("sensitivity.adjoint_memory")
                && err.contains("must be a positive, finite number (MiB)")
                && err.contains(&format!(":{line}")),
            "{bad}: {err}"
        );
    }
}
