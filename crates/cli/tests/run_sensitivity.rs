//! `flexsens run` with design variables: direct sensitivities of the responses, objective
//! gradients and the finite-difference comparisons, end to end through the binary on the
//! paper's beam slider-crank deck (shortened).

mod common;

use common::{bad_deck, deck, f64s, run, with_deck};
use flexsens::results::{Attr, Data, Group};

/// A short run of the beam slider-crank: about 0.6 of a crank revolution.
const T_END: &str = "analysis.t_end=0.003";

/// Largest relative difference between the sensitivity methods' mid-node deflection histories
/// (measured 2026-11-21, linear rod: simultaneous 3.0e-7, corrector 2.1e-7 against direct;
/// 2026-11-23 with the rod's geometric stiffening: simultaneous 1.1e-6 in a release build and
/// 8.4e-6 in the test profile, corrector 8e-8). The simultaneous method converges the
/// sensitivities inside the state's modified Newton iteration, whose matrix is not refreshed
/// every step; stiffening makes the Jacobian move faster (the multipliers enter it), so its
/// differences grow with the step sequence. A wrong Jacobian term shows at 1e-2 and above.
const TOL_METHODS: f64 = 2e-5;

fn units(g: &Group, path: &str) -> String {
    match g.get(path).unwrap().attrs.get("units") {
        Some(flexsens::results::Attr::Text(u)) => u.clone(),
        other => panic!("units of {path}: {other:?}"),
    }
}

/// Worst `|a − r| / |r|` where `|r| > 0.1 max |r|`.
fn worst_relative(a: &[f64], r: &[f64]) -> f64 {
    let scale = r.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    a.iter()
        .zip(r)
        .filter(|(_, r)| r.abs() > 0.1 * scale)
        .map(|(x, r)| (x - r).abs() / r.abs())
        .fold(0.0, f64::max)
}

fn read_csv(path: &std::path::Path) -> (Vec<String>, Vec<Vec<String>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let head = lines
        .next()
        .unwrap()
        .split(',')
        .map(str::to_string)
        .collect();
    let rows = lines
        .map(|l| l.split(',').map(str::to_string).collect())
        .collect();
    (head, rows)
}

/// The mid-node deflection's direct sensitivities against the replayed central differences of
/// relative size `size` in a run's results: `(max |CD − direct| / max |direct|, max |direct|)`.
fn direct_vs_central(g: &Group, size: &str) -> (f64, f64) {
    let direct = f64s(g, "sensitivities/mid_deflection");
    let fd = f64s(
        g,
        &format!("finite_differences/central_relative_{size}_replay/mid_deflection"),
    );
    let scale = direct.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    (worst_relative(&fd, &direct), scale)
}

#[test]
fn beam_deck_sensitivities_match_replayed_central_differences_and_converge() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let summary = common::run_json(
        "slider_crank_beam.toml",
        &out,
        &[
            T_END,
            // the exact derivative of the discrete solution, which replayed differences check
            // to their truncation (the default method agrees with it to its local error
            // tolerance: `sensitivity_methods_agree`)
            "sensitivity.method=\"direct\"",
            "finite_differences.scheme=central",
            "finite_differences.sizes=[1e-2, 1e-3, 1e-4]",
        ],
    );
    let g = Group::read_hdf5(&out.join("results.h5")).unwrap();
    let n = f64s(&g, "time").len();
    let direct = f64s(&g, "sensitivities/mid_deflection");
    assert_eq!(direct.len(), n);
    assert_eq!(units(&g, "sensitivities/mid_deflection"), "1/deg");
    assert_eq!(units(&g, "sensitivities/slider_x"), "m/deg");
    assert_eq!(f64s(&g, "design/values"), [15.0]);
    let error = |size: &str| direct_vs_central(&g, size).0;
    let (e_coarse, e_mid, e_fine) = (error("0.01"), error("0.001"), error("0.0001"));
    eprintln!(
        "mid-node deflection vs central differences: δ = 0.15° {e_coarse:.2e}, 0.015° \
         {e_mid:.2e}, 0.0015° {e_fine:.2e}"
    );
    // measured 2026-11-23 (physical start, planar shear released): 5.7e-5, 6.1e-7, 1.2e-7 —
    // the δ² truncation falls a hundredfold, then the round-off of the perturbed runs shows
    assert!(e_mid < 2e-6 && e_fine < 2e-6, "{e_mid:e}, {e_fine:e}");
    assert!(e_mid < e_coarse / 30.0, "{e_mid:e} vs {e_coarse:e}");
    // the sensitivity is not trivially small: a 1° change moves the deflection visibly
    let scale = direct.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    assert!(scale > 1e-5, "{scale:e}");
    // objectives: gradients against the differences of their values
    for name in ["peak_deflection", "rms_deflection"] {
        let grad = f64s(&g, &format!("objectives/{name}/gradient"));
        let fd = f64s(
            &g,
            &format!("finite_differences/central_relative_0.0001_replay/objectives/{name}"),
        );
        let err = (grad[0] - fd[0]).abs() / grad[0].abs();
        eprintln!(
            "{name}: gradient {:.6e}, central differences {:.6e}",
            grad[0], fd[0]
        );
        assert!(err < 1e-5, "{name}: {err:e}");
    }
    // the summary reports the comparisons
    let cases = summary["finite_differences"].as_array().unwrap();
    assert_eq!(cases.len(), 3);
    let worst = cases[2]["max_relative_difference"]["mid_deflection"]
        .as_f64()
        .unwrap();
    assert!(worst < 1e-4, "{worst:e}");
    // CSV files: one column per (response, variable), one row per objective
    let (head, rows) = read_csv(&out.join("sensitivities.csv"));
    assert_eq!(
        head,
        [
            "time [s]",
            "d mid_deflection/d theta [1/deg]",
            "d slider_x/d theta [m/deg]"
        ]
    );
    assert_eq!(rows.len(), n);
    let csv_direct: Vec<f64> = rows.iter().map(|r| r[1].parse().unwrap()).collect();
    assert_eq!(csv_direct, direct);
    let (head, rows) = read_csv(&out.join("gradients.csv"));
    assert_eq!(
        head[..6],
        ["objective", "response", "kind", "value", "unit", "time [s]"]
    );
    assert_eq!(head[6], "d/d theta [unit/deg]");
    assert_eq!(rows.len(), 2);
    assert_eq!(rows[0][0], "peak_deflection");
    assert_eq!(
        rows[0][6].parse::<f64>().unwrap(),
        f64s(&g, "objectives/peak_deflection/gradient")[0]
    );
}

/// Two variables that split the plies sum to the common angle's derivative; the result does
/// not depend on how many variables share a run (dual-number chunk widths 1 and 4) beyond the
/// direct method's iteration tolerance: its iterations stop at an estimated remaining error of
/// about 1e-12 of `S` measured over all the run's variables (`mbs::sensitivity`'s
/// `DIRECT_TOL`), so a variable's sensitivity with others beside it differs from its own run's
/// by up to a few of those (1.3e-12 of its largest here; 5e-14 where both runs happen to stop
/// after the same iterations).
#[test]
fn split_ply_variables_sum_to_the_common_angle_and_chunking_does_not_matter() {
    let text = std::fs::read_to_string(deck("slider_crank_beam.toml")).unwrap();
    let text = text.replace(
        "[design.theta]",
        "[design.inner]\nlaminate = \"tube_wall\"\nplies = [0, 1]\n\n\
         [design.outer]\nlaminate = \"tube_wall\"\nplies = [2, 3]\n\n[design.theta]",
    );
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("split.toml");
    std::fs::write(&p, text).unwrap();
    let out3 = dir.path().join("three");
    let out1 = dir.path().join("one");
    for (deck_path, out) in [(p.clone(), &out3), (deck("slider_crank_beam.toml"), &out1)] {
        let o = run(&[
            "run",
            deck_path.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--set",
            T_END,
            "--set",
            "finite_differences.enabled=false",
            // linear in the variables to round-off: the exact discrete derivative (the default
            // method's columns each stop their iterations on their own, so their sum agrees
            // to the local error tolerance only)
            "--set",
            "sensitivity.method=\"direct\"",
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let g3 = Group::read_hdf5(&out3.join("results.h5")).unwrap();
    let g1 = Group::read_hdf5(&out1.join("results.h5")).unwrap();
    let names = match &g3.get("design/names").unwrap().data {
        Data::Text(t) => t.clone(),
        Data::F64(_) => panic!(),
    };
    assert_eq!(names, ["inner", "outer", "theta"]);
    let s3 = f64s(&g3, "sensitivities/mid_deflection");
    let s1 = f64s(&g1, "sensitivities/mid_deflection");
    let n = s1.len();
    assert_eq!(s3.len(), 3 * n);
    let scale = s1.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let mut sum_err = 0.0f64;
    let mut chunk_err = 0.0f64;
    for i in 0..n {
        let (a, b, c) = (s3[3 * i], s3[3 * i + 1], s3[3 * i + 2]);
        sum_err = sum_err.max((a + b - c).abs() / scale);
        chunk_err = chunk_err.max((c - s1[i]).abs() / scale);
    }
    eprintln!("inner + outer − common: {sum_err:.2e}; chunk widths 4 vs 1: {chunk_err:.2e}");
    assert!(sum_err < 1e-9, "{sum_err:e}");
    assert!(chunk_err < 1e-11, "{chunk_err:e}");
    // the frequency derivatives split the same way
    let df = f64s(&g3, "bodies/rod/frequency_derivatives");
    for k in 0..df.len() / 3 {
        let (a, b, c) = (df[3 * k], df[3 * k + 1], df[3 * k + 2]);
        assert!(
            (a + b - c).abs() <= 1e-9 * c.abs().max(1e-12),
            "{a} + {b} vs {c}"
        );
    }
}

/// The rod's mode shapes depend on the ply angle: keeping them fixed changes the sensitivities.
#[test]
fn fixed_mode_sensitivities_differ_from_updated_mode_ones() {
    let dir = tempfile::tempdir().unwrap();
    let mut s = Vec::new();
    for modes in ["updated", "fixed"] {
        let out = dir.path().join(modes);
        let o = run(&[
            "run",
            deck("slider_crank_beam.toml").to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--set",
            T_END,
            "--set",
            &format!("sensitivity.modes={modes}"),
            "--set",
            "finite_differences.enabled=false",
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        // stderr is not a terminal here: no progress bar
        assert!(
            o.stderr.is_empty(),
            "{}",
            String::from_utf8_lossy(&o.stderr)
        );
        let g = Group::read_hdf5(&out.join("results.h5")).unwrap();
        s.push(f64s(&g, "sensitivities/mid_deflection"));
    }
    let diff = worst_relative(&s[1], &s[0]);
    eprintln!("fixed-mode vs updated-mode: {diff:.2e}");
    assert!(diff > 1e-2, "{diff:e}");
}

/// The three integration methods of `[sensitivity] method` give the same sensitivities to
/// within the integrator's Newton tolerance, the results name the method used, and a deck
/// that names none gets the simultaneous one.
#[test]
fn sensitivity_methods_agree() {
    let dir = tempfile::tempdir().unwrap();
    let mut s = Vec::new();
    for method in ["direct", "simultaneous", "corrector", ""] {
        let out = dir.path().join(format!("method_{method}"));
        let set = format!("sensitivity.method={method}");
        let path = deck("slider_crank_beam.toml");
        let mut args = vec![
            "run",
            path.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--set",
            T_END,
            "--set",
            "finite_differences.enabled=false",
        ];
        if !method.is_empty() {
            args.extend(["--set", &set]);
        }
        let o = run(&args);
        let method = if method.is_empty() {
            "simultaneous"
        } else {
            method
        };
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let g = Group::read_hdf5(&out.join("results.h5")).unwrap();
        let attr = g.groups["sensitivities"].attrs.get("method").cloned();
        assert_eq!(
            attr,
            Some(Attr::Text(format!("{method}, updated modes"))),
            "{method}"
        );
        s.push(f64s(&g, "sensitivities/mid_deflection"));
    }
    for (method, x) in ["simultaneous", "corrector"].iter().zip(&s[1..]) {
        let diff = worst_relative(x, &s[0]);
        eprintln!("{method} vs direct: {diff:.2e}");
        assert!(diff < TOL_METHODS, "{method}: {diff:e}");
    }
    assert_eq!(s[3], s[1], "the default is the simultaneous method");
}

/// `(text to replace, replacement, text of the line the error points at, key, message)`.
const BAD: [(&str, &str, &str, &str, &str); 7] = [
    (
        "laminate = \"tube_wall\"\n\n[objective.peak_deflection]",
        "laminate = \"tube_wal\"\n\n[objective.peak_deflection]",
        "laminate = \"tube_wal\"",
        "design.theta.laminate",
        "did you mean `tube_wall`",
    ),
    (
        "laminate = \"tube_wall\"\n\n[objective.peak_deflection]",
        "laminate = \"tube_wall\"\nplies = [0, 4]\n\n[objective.peak_deflection]",
        "plies = [0, 4]",
        "design.theta.plies",
        "ply 4 does not exist",
    ),
    (
        "laminate = \"tube_wall\"\n\n[objective.peak_deflection]",
        "laminate = \"tube_wall\"\nfactors = [1.0]\n\n[objective.peak_deflection]",
        "factors = [1.0]",
        "design.theta.factors",
        "1 factors for 4 plies",
    ),
    (
        "response = \"mid_deflection\"\nkind = \"max\"",
        "response = \"mid_deflexion\"\nkind = \"max\"",
        "response = \"mid_deflexion\"",
        "objective.peak_deflection.response",
        "did you mean `mid_deflection`",
    ),
    (
        "response = \"mid_deflection\"\nkind = \"max\"",
        "response = \"mid_deflection\"\nkind = \"maximum\"",
        "kind = \"maximum\"",
        "objective.peak_deflection.kind",
        "unknown value `maximum`",
    ),
    (
        "modes = \"updated\"",
        "modes = \"updatd\"",
        "modes = \"updatd\"",
        "sensitivity.modes",
        "did you mean `updated`",
    ),
    (
        "scheme = \"central\"",
        "scheme = \"backward\"",
        "scheme = \"backward\"",
        "finite_differences.scheme",
        "expected \"forward\", \"central\"",
    ),
];

#[test]
fn bad_design_tables_are_reported_with_file_line_and_key() {
    let base = std::fs::read_to_string(deck("slider_crank_beam.toml")).unwrap();
    for (from, to, at, key, message) in BAD {
        assert!(base.contains(from), "{from}");
        let text = base.replacen(from, to, 1);
        let (_, err) = bad_deck(&text, |p| with_deck("check", p, &[]));
        let line = common::line_of(&text, at);
        assert!(err.contains(&format!("bad.toml:{line}:")), "{key}: {err}");
        assert!(err.contains(&format!("key `{key}`")), "{key}: {err}");
        assert!(err.contains(message), "{key}: {err}");
    }
}

#[test]
fn design_that_moves_nothing_or_objectives_without_gradients_are_rejected() {
    let base = std::fs::read_to_string(deck("slider_crank_beam.toml")).unwrap();
    // a laminate no body uses
    let text = base.replace(
        "[section.tube]",
        "[laminate.spare]\nplies = [{ material = \"paper_composite\", thickness = 1e-3, angle = 0.0 }]\n\n[section.tube]",
    ) + "\n[design.unused]\nlaminate = \"spare\"\n";
    let (_, err) = bad_deck(&text, |p| with_deck("check", p, &[]));
    assert!(err.contains("key `design.unused`"), "{err}");
    assert!(err.contains("changes no flexible body"), "{err}");
    // an objective of a response without sensitivities
    let text = base.clone()
        + "\n[response.energy]\nkind = \"energy\"\n\n[objective.work]\nresponse = \"energy\"\nkind = \"max\"\n";
    let (_, err) = bad_deck(&text, |p| with_deck("check", p, &[]));
    assert!(err.contains("key `objective.work.response`"), "{err}");
    assert!(err.contains("no design sensitivities"), "{err}");
    // finite differences need design variables
    let (i, j) = (
        base.find("[design.theta]").unwrap(),
        base.find("[sensitivity]").unwrap(),
    );
    let text = format!("{}{}", &base[..i], &base[j..]);
    let (_, err) = bad_deck(&text, |p| with_deck("check", p, &[]));
    assert!(err.contains("key `finite_differences`"), "{err}");
    assert!(err.contains("need design variables"), "{err}");
    // ... unless the table turns them off (as a script's `--set` does on every deck)
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("no_design.toml");
    std::fs::write(&p, &text).unwrap();
    let o = common::run(&[
        "check",
        p.to_str().unwrap(),
        "--set",
        "finite_differences.enabled=false",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// The paper's plate deck (shell rod on its end edges through couplings, interface basis with
/// correction modes, 3-D plate modes, constraint rows reselected along the way): its exact
/// (`"direct"`) sensitivities agree with replayed central differences.
#[test]
fn plate_deck_sensitivities_match_replayed_central_differences() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let summary = common::run_json(
        "slider_crank_plate.toml",
        &out,
        &[
            "analysis.t_end=0.002",
            "finite_differences.scheme=central",
            "finite_differences.sizes=[1e-4]",
            "sensitivity.method=\"direct\"",
        ],
    );
    let g = Group::read_hdf5(&out.join("results.h5")).unwrap();
    let (err, scale) = direct_vs_central(&g, "0.0001");
    eprintln!("plate: mid-node deflection vs central differences {err:.2e}");
    // measured 7.5e-7 (1.3e-8 on the deck's earlier basis, six eigenmodes alone)
    assert!(err < 3e-6, "{err:e}");
    assert!(scale > 1e-6, "{scale:e}");
    // six modes with their derivatives, the frame constraints kept tight
    assert_eq!(f64s(&g, "bodies/rod/frequency_derivatives").len(), 6);
    let v = summary["max_position_violation"].as_f64().unwrap();
    assert!(v < 1e-5, "{v:e}");
}

/// Every group, dataset and attribute of a run with design sensitivities, read back through the
/// reference HDF5 library (h5py), equals what flexsens wrote: names, shapes, values, units.
#[test]
fn every_dataset_and_attribute_reads_back_through_h5py() {
    use flexsens::results::Attr;
    if !common::h5py_available() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    common::run_json("slider_crank_beam.toml", &out, &["analysis.t_end=0.001"]);
    let script = r#"
import h5py, json, sys
def val(v):
    if isinstance(v, bytes): return v.decode()
    if hasattr(v, "tolist"): v = v.tolist()
    if isinstance(v, list): return [val(x) for x in v]
    return v
out = {"datasets": {}, "attrs": {}}
def visit(name, obj):
    out["attrs"]["/" + name] = {k: val(v) for k, v in obj.attrs.items()}
    if isinstance(obj, h5py.Dataset):
        data = obj.asstr()[()] if h5py.check_string_dtype(obj.dtype) else obj[()]
        out["datasets"]["/" + name] = {"shape": list(obj.shape), "values": val(data)}
with h5py.File(sys.argv[1], "r") as f:
    out["attrs"]["/"] = {k: val(v) for k, v in f.attrs.items()}
    f.visititems(visit)
print(json.dumps(out))
"#;
    let o = std::process::Command::new("python3")
        .arg("-c")
        .arg(script)
        .arg(out.join("results.h5"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let doc: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let g = Group::read_hdf5(&out.join("results.h5")).unwrap();
    // walk what flexsens wrote
    let mut datasets = 0;
    let mut stack: Vec<(String, &Group)> = vec![(String::new(), &g)];
    let attr_json = |a: &Attr| match a {
        Attr::Text(t) => serde_json::json!(t),
        Attr::F64(x) => serde_json::json!(x),
        Attr::I64(i) => serde_json::json!(i),
    };
    while let Some((path, group)) = stack.pop() {
        let key = if path.is_empty() {
            "/".to_string()
        } else {
            path.clone()
        };
        for (k, a) in &group.attrs {
            assert_eq!(doc["attrs"][&key][k], attr_json(a), "{key} @{k}");
        }
        for (name, d) in &group.datasets {
            let p = format!("{path}/{name}");
            let h = &doc["datasets"][&p];
            assert!(!h.is_null(), "h5py does not see {p}");
            assert_eq!(h["shape"], serde_json::json!(d.shape), "{p}");
            let flat: Vec<serde_json::Value> = {
                fn flatten(v: &serde_json::Value, out: &mut Vec<serde_json::Value>) {
                    match v.as_array() {
                        Some(a) => a.iter().for_each(|x| flatten(x, out)),
                        None => out.push(v.clone()),
                    }
                }
                let mut f = Vec::new();
                flatten(&h["values"], &mut f);
                f
            };
            match &d.data {
                Data::F64(v) => {
                    let got: Vec<f64> = flat.iter().map(|x| x.as_f64().unwrap()).collect();
                    assert_eq!(&got, v, "{p}");
                }
                Data::Text(t) => {
                    let got: Vec<&str> = flat.iter().map(|x| x.as_str().unwrap()).collect();
                    assert_eq!(got, *t, "{p}");
                }
            }
            for (k, a) in &d.attrs {
                assert_eq!(doc["attrs"][&p][k], attr_json(a), "{p} @{k}");
            }
            datasets += 1;
        }
        for (name, sub) in &group.groups {
            stack.push((format!("{path}/{name}"), sub));
        }
    }
    assert_eq!(
        doc["datasets"].as_object().unwrap().len(),
        datasets,
        "h5py sees exactly the datasets written"
    );
    // the sensitivity part is there, with units
    for p in [
        "/sensitivities/mid_deflection",
        "/design/values",
        "/objectives/peak_deflection/gradient",
        "/bodies/rod/frequency_derivatives",
        "/finite_differences/central_relative_0.0001_replay/mid_deflection",
    ] {
        assert!(!doc["datasets"][p].is_null(), "{p}");
        if p != "/design/values" {
            assert!(
                doc["attrs"][p]["units"].as_str().unwrap().ends_with("/deg"),
                "{p}"
            );
        }
    }
}

/// Modes chosen by number (`modes = [1, 2, 4]`: the first two bending modes and the axial mode
/// of the pinned–pinned rod, without the third bending mode): `flexsens modes` lists exactly
/// those of the full analysis, and the direct sensitivities through the selection (updated
/// modes, damping fitted at modes 1 and 4) match replayed central differences.
#[test]
fn modes_chosen_by_number_keep_exact_sensitivities() {
    let sets = [
        "--set",
        "body.rod.reference=\"pinned-ends\"",
        "--set",
        "body.rod.damping.modes=[1, 4]",
    ];
    let frequencies = |modes: &str| {
        let mut args = vec![
            "modes",
            deck("slider_crank_beam.toml")
                .to_str()
                .unwrap()
                .to_string()
                .leak(),
            "--format",
            "json",
            "--set",
        ];
        let m = format!("body.rod.modes={modes}");
        args.push(m.leak());
        args.extend(sets);
        let doc = common::json(&args);
        doc["bodies"]["rod"]["values"]["frequencies"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect::<Vec<f64>>()
    };
    // the eigenmodes come first (then the correction modes, which differ with the modes kept)
    let (all, chosen) = (frequencies("4"), frequencies("[1, 2, 4]"));
    assert_eq!(chosen[..3], [all[0], all[1], all[3]]);
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let summary = common::run_json(
        "slider_crank_beam.toml",
        &out,
        &[
            T_END,
            "body.rod.reference=\"pinned-ends\"",
            "body.rod.modes=[1, 2, 4]",
            "body.rod.damping.modes=[1, 4]",
            // the exact derivative of the discrete solution, which replayed differences check,
            // on fixed steps: adaptive steps stop Newton at a share of the error weights, whose
            // floor (2.3e-6 here, with the correction modes' fast dynamics) would hide an error
            "sensitivity.method=\"direct\"",
            "analysis.integrator=\"fixed\"",
            "analysis.step=2e-5",
            "analysis.order=2",
            "finite_differences.sizes=[1e-4]",
        ],
    );
    let g = Group::read_hdf5(&out.join("results.h5")).unwrap();
    let (err, scale) = direct_vs_central(&g, "0.0001");
    eprintln!("modes [1, 2, 4]: direct vs central differences {err:.2e}");
    // measured 7.6e-9
    assert!(err < 1e-7, "{err:e}");
    assert!(summary["finite_differences"].as_array().unwrap().len() == 1);
    assert!(scale > 1e-6, "{scale:e}");
    // a list that is not ascending is bad input, named
    let (_, err) = bad_deck(
        &std::fs::read_to_string(deck("slider_crank_beam.toml"))
            .unwrap()
            .replace("modes = 4\n", "modes = [2, 1]\n"),
        |p| with_deck("check", p, &[]),
    );
    assert!(
        err.contains("body.rod.modes") && err.contains("strictly ascending"),
        "{err}"
    );
}

/// The replayed finite differences estimate their own noise (a replay whose start and Newton
/// iterations go on to a tenth of their tolerances): it falls as the perturbation grows (about
/// as its inverse), and a difference within three times it is reported as not resolved. On the
/// beam deck at rtol 1e-7 with the direct method the slider's difference (1e-5 of its
/// derivative) is within its noise, the mid-node deflection's is not.
#[test]
fn finite_differences_report_their_noise() {
    let dir = tempfile::tempdir().unwrap();
    let sets = [
        "sensitivity.method=\"direct\"",
        "analysis.rtol=1e-7",
        "analysis.atol=1e-10",
    ];
    let mut with_sizes = sets.to_vec();
    with_sizes.push("finite_differences.sizes=[1e-5, 1e-3]");
    let doc = common::run_json("slider_crank_beam.toml", &dir.path().join("a"), &with_sizes);
    let cases = doc["finite_differences"].as_array().unwrap();
    let noise = |c: usize, r: &str| cases[c]["relative_noise"][r].as_f64().unwrap();
    for r in ["mid_deflection", "slider_x"] {
        let (small, large) = (noise(0, r), noise(1, r));
        assert!(
            small > 5.0 * large && large > 0.0,
            "{r}: {small:e} at 1e-5, {large:e} at 1e-3"
        );
    }
    let dir_b = dir.path().join("b");
    let o = run(&[
        "run",
        deck("slider_crank_beam.toml").to_str().unwrap(),
        "-o",
        dir_b.to_str().unwrap(),
        "--set",
        sets[0],
        "--set",
        sets[1],
        "--set",
        sets[2],
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = String::from_utf8_lossy(&o.stdout);
    let line = text
        .lines()
        .find(|l| l.contains("central_relative_0.0001_replay"))
        .unwrap_or_else(|| panic!("{text}"));
    assert!(
        line.contains("slider_x") && line.contains(": not resolved)"),
        "{line}"
    );
    let mid = line
        .split(", ")
        .find(|p| p.contains("mid_deflection"))
        .unwrap();
    assert!(!mid.contains("not resolved"), "{line}");
    assert!(
        text.contains("(not resolved: the replays' Newton tolerance"),
        "{text}"
    );
}
