//! `flexsens run` end to end: closed-form kinematics, result files (HDF5 read by h5py, CSV),
//! golden-file comparison, bad input, failed runs.

use std::process::Command;

mod common;
use common::*;

fn slider_exact(t: f64) -> (f64, f64) {
    // crank r, rod l, θ = ω t
    let (r, l, w) = (0.152_f64, 0.304_f64, 150.0_f64);
    let th = w * t;
    let s = (l * l - r * r * th.sin().powi(2)).sqrt();
    let x = r * th.cos() + s;
    let v = -r * w * th.sin() - r * r * w * th.sin() * th.cos() / s;
    (x, v)
}

fn read_csv(path: &std::path::Path) -> (Vec<String>, Vec<Vec<f64>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let head: Vec<String> = lines
        .next()
        .unwrap()
        .split(',')
        .map(str::to_string)
        .collect();
    let rows = lines
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .collect();
    (head, rows)
}

#[test]
fn rigid_slider_crank_follows_the_closed_form_over_two_revolutions() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let o = run(&[
        "run",
        deck("slider_crank_rigid.toml").to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (head, rows) = read_csv(&out.join("history.csv"));
    assert_eq!(
        head,
        [
            "time [s]",
            "slider_vx [m/s]",
            "slider_x [m]",
            "violation [m]"
        ]
    );
    assert_eq!(rows.len(), 839);
    let (mut ex, mut ev) = (0.0f64, 0.0f64);
    for r in &rows {
        let (x, v) = slider_exact(r[0]);
        ex = ex.max((r[2] - x).abs());
        ev = ev.max((r[1] - v).abs());
    }
    // relative to the stroke scale r + L and the speed scale r ω
    assert!(ex / 0.456 < 1e-7, "slider position error {ex} m");
    assert!(
        ev / (0.152 * 150.0) < 1e-6,
        "slider velocity error {ev} m/s"
    );
}

/// A fixed-step run estimates each step's local error against the deck's tolerances: a step
/// too long for them is warned about (and its largest ratio kept in results.h5), and the
/// warning is right — that run is far from the closed form, while a step short enough for the
/// tolerances runs without a word and follows it.
#[test]
fn a_fixed_step_too_long_for_the_tolerances_is_warned_about() {
    let dir = tempfile::tempdir().unwrap();
    let fixed = |step: &str, out: &std::path::Path| {
        run(&[
            "run",
            deck("slider_crank_rigid.toml").to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--set",
            "analysis.t_end=0.02",
            "--set",
            "analysis.integrator=\"fixed\"",
            "--set",
            &format!("analysis.step={step}"),
            "--set",
            "analysis.rtol=1e-6",
            "--set",
            "analysis.atol=1e-8",
        ])
    };
    let error = |out: &std::path::Path| {
        let (_, rows) = read_csv(&out.join("history.csv"));
        rows.iter()
            .map(|r| (r[2] - slider_exact(r[0]).0).abs())
            .fold(0.0_f64, f64::max)
    };
    let (coarse, fine) = (dir.path().join("coarse"), dir.path().join("fine"));
    let o = fixed("1e-4", &coarse);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("key `analysis.step`") && err.contains("misses the deck's local error"),
        "{err}"
    );
    let o = fixed("5e-6", &fine);
    let quiet = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success() && !quiet.contains("misses"), "{quiet}");
    // against rtol = 1e-6 of the 0.456 m stroke scale
    assert!(error(&coarse) > 1e-5, "coarse error {}", error(&coarse));
    assert!(error(&fine) < 0.456e-6, "fine error {}", error(&fine));
    if common::h5py_available() {
        let ratio = |out: &std::path::Path| -> f64 {
            let o = Command::new("python3")
                .args([
                    "-c",
                    "import h5py,sys; print(h5py.File(sys.argv[1])['statistics'].attrs['max_error_ratio'])",
                    out.join("results.h5").to_str().unwrap(),
                ])
                .output()
                .unwrap();
            String::from_utf8_lossy(&o.stdout).trim().parse().unwrap()
        };
        assert!(ratio(&coarse) > 1.0 && ratio(&fine) < 1.0);
    }
}

/// A loose adaptive run estimates the error of its histories (by the run at a tenth of the
/// tolerances) and warns when it is above 1 % of a response's largest value. On the rigid
/// slider-crank at rtol 1e-2 the estimate of the slider's position is within a factor 2 of its
/// error against the closed form (measured 5.8 % and 5.0 %); a constraint violation gets none;
/// at the deck's own rtol (1e-6) there is neither estimate nor warning.
#[test]
fn a_loose_adaptive_run_estimates_its_history_error() {
    let dir = tempfile::tempdir().unwrap();
    let run_at = |rtol: Option<&str>, name: &str| {
        let out = dir.path().join(name);
        let mut args = vec![
            "run".to_string(),
            deck("slider_crank_rigid.toml").display().to_string(),
            "-o".into(),
            out.display().to_string(),
        ];
        if let Some(r) = rtol {
            args.extend(["--set".into(), format!("analysis.rtol={r}")]);
        }
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = run(&args);
        let err = String::from_utf8_lossy(&o.stderr).into_owned();
        assert!(o.status.success(), "{err}");
        let g = flexsens::results::Group::read_hdf5(&out.join("results.h5")).unwrap();
        let estimate = |response: &str| {
            g.groups
                .get("statistics")
                .and_then(|s| s.attrs.get(&format!("history_error_{response}")))
                .map(|a| match a {
                    flexsens::results::Attr::F64(x) => *x,
                    other => panic!("{other:?}"),
                })
        };
        let (_, rows) = read_csv(&out.join("history.csv"));
        let error = rows
            .iter()
            .map(|r| (r[2] - slider_exact(r[0]).0).abs())
            .fold(0.0_f64, f64::max)
            / 0.456;
        (err, estimate("slider_x"), estimate("violation"), error)
    };
    let (err, estimate, violation, error) = run_at(Some("1e-2"), "loose");
    assert!(
        err.contains("key `analysis.rtol`") && err.contains("history of response `slider_x`"),
        "{err}"
    );
    assert!(!err.contains("`violation`"), "{err}");
    assert!(violation.is_none());
    let estimate = estimate.expect("a loose run estimates its history error");
    eprintln!(
        "history error of slider_x: estimated {estimate:.2e}, against the closed form {error:.2e}"
    );
    assert!(error > 0.01, "{error}");
    assert!(
        (0.5..2.0).contains(&(estimate / error)),
        "{estimate} against {error}"
    );
    let (err, estimate, _, error) = run_at(None, "tight");
    assert!(!err.contains("history of response"), "{err}");
    assert!(estimate.is_none());
    assert!(error < 1e-5, "{error}");
}

#[test]
fn json_summary_for_scripts() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o");
    let doc = json(&[
        "run",
        deck("slider_crank_rigid.toml").to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--json",
    ]);
    assert_eq!(doc["outputs"], 839);
    let max = doc["responses"]["slider_x"]["max"].as_f64().unwrap();
    assert!((max - 0.456).abs() < 1e-6);
    assert!(doc["steps"].as_u64().unwrap() > 10);
}

#[test]
fn results_h5_holds_every_history_with_units_readable_by_h5py() {
    if !common::h5py_available() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let o = run(&[
        "run",
        deck("slider_crank_rigid.toml").to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let script = r#"
import h5py, json, sys
def s(v): return v.decode() if isinstance(v, bytes) else str(v)
with h5py.File(sys.argv[1], "r") as f:
    out = {"time": f["time"][()].tolist(), "units": s(f["time"].attrs["units"]),
           "slider_x": f["responses/slider_x"][()].tolist(), "x_units": s(f["responses/slider_x"].attrs["units"]),
           "pos_shape": list(f["bodies/slider/position"].shape), "steps": int(f["statistics"].attrs["steps"]),
           "deck": f["meta/deck"].asstr()[()].tolist()[0]}
print(json.dumps(out))
"#;
    let o = Command::new("python3")
        .arg("-c")
        .arg(script)
        .arg(out.join("results.h5"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let doc: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(doc["units"], "s");
    assert_eq!(doc["x_units"], "m");
    assert_eq!(doc["pos_shape"], serde_json::json!([839, 3]));
    assert!(doc["steps"].as_u64().unwrap() > 10);
    assert!(
        doc["deck"]
            .as_str()
            .unwrap()
            .contains("[joint.crank_drive]")
    );
    // the HDF5 histories are the CSV ones, to the last bit
    let (_, rows) = read_csv(&out.join("history.csv"));
    let x: Vec<f64> = doc["slider_x"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    for (r, xh) in rows.iter().zip(&x) {
        assert_eq!(r[2], *xh);
    }
}

#[test]
fn same_deck_same_results_and_compare_catches_a_change() {
    let dir = tempfile::tempdir().unwrap();
    let p = deck("slider_crank_rigid.toml");
    let p = p.to_str().unwrap();
    let (a, b, c) = (
        dir.path().join("a"),
        dir.path().join("b"),
        dir.path().join("c"),
    );
    for d in [&a, &b] {
        assert!(
            run(&["run", p, "-o", d.to_str().unwrap(), "--json"])
                .status
                .success()
        );
    }
    assert_eq!(
        std::fs::read(a.join("results.h5")).unwrap(),
        std::fs::read(b.join("results.h5")).unwrap(),
        "deterministic"
    );
    let o = run(&[
        "compare",
        a.join("results.h5").to_str().unwrap(),
        b.join("results.h5").to_str().unwrap(),
        "--rtol",
        "0",
        "--atol",
        "0",
    ]);
    assert_eq!(o.status.code(), Some(0));
    let o = run(&[
        "run",
        p,
        "-o",
        c.to_str().unwrap(),
        "--json",
        "--set",
        "joint.crank_drive.motion.rate=\"151 rad/s\"",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = run(&[
        "compare",
        c.join("results.h5").to_str().unwrap(),
        a.join("results.h5").to_str().unwrap(),
    ]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert_eq!(o.status.code(), Some(1), "{text}");
    assert!(text.contains("/responses/slider_x: t = "), "{text}");
}

/// While one flexsens writes into a directory (here the test holds its lock, as a running
/// flexsens does), a second one writing there fails at once with exit 1, naming the holder,
/// and writes nothing; once the holder is done the directory works again.
#[test]
fn a_second_writer_into_a_directory_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    std::fs::create_dir_all(&out).unwrap();
    let lock = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .create(true)
        .truncate(true)
        .open(out.join(".flexsens.lock"))
        .unwrap();
    lock.try_lock().unwrap();
    std::fs::write(out.join(".flexsens.lock"), "4242 (flexsens run)\n").unwrap();
    let deck_path = deck("slider_crank_rigid.toml");
    let args = |command: &str| -> Vec<String> {
        let mut a = vec![command.to_string(), deck_path.display().to_string()];
        a.extend(["-o".to_string(), out.display().to_string()]);
        if command == "sweep" {
            a.extend([
                "--vary".to_string(),
                "rigid.slider.mass=0.04,0.05".to_string(),
            ]);
        }
        a.extend(["--set".to_string(), "analysis.t_end=0.002".to_string()]);
        a
    };
    for command in ["run", "sweep"] {
        let a = args(command);
        let a: Vec<&str> = a.iter().map(String::as_str).collect();
        let o = run(&a);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{command}: {err}");
        assert!(
            err.contains("another flexsens is writing into this directory")
                && err.contains("process 4242 (flexsens run)"),
            "{command}: {err}"
        );
        assert!(!out.join("results.h5").exists() && !out.join("summary.csv").exists());
    }
    drop(lock);
    let a = args("run");
    let a: Vec<&str> = a.iter().map(String::as_str).collect();
    let o = run(&a);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(out.join("results.h5").exists());
}

#[test]
fn a_failed_run_leaves_no_result_file_and_exits_1() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(deck("slider_crank_rigid.toml")).unwrap();
    // the guide 0.1 m off the line through the crank axis: the rod cannot reach it
    let text = text.replace(
        "a = { body = \"ground\", point = [0.456, 0.0, 0.0], axis = [1.0, 0.0, 0.0] }",
        "a = { body = \"ground\", point = [0.456, 0.5, 0.0], axis = [1.0, 0.0, 0.0] }",
    );
    let p = dir.path().join("bad.toml");
    std::fs::write(&p, text).unwrap();
    let out = dir.path().join("out");
    let o = run(&["run", p.to_str().unwrap(), "-o", out.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("cannot be assembled"), "{err}");
    assert!(!out.join("results.h5").exists());
}

fn expect_bad(text: &str, at: &str, words: &str) {
    let out = |p: &std::path::Path| p.with_file_name("o").display().to_string();
    let (dir, err) = bad_deck(text, |p| with_deck("run", p, &["-o", &out(p)]));
    assert!(
        err.contains(&format!("bad.toml:{}:", line_of(text, at))),
        "line of `{at}` in: {err}"
    );
    assert!(err.contains(words), "'{words}' in: {err}");
    assert!(!dir.path().join("o").exists(), "no output after bad input");
}

#[test]
fn bad_mechanisms_are_located() {
    let base = std::fs::read_to_string(deck("slider_crank_rigid.toml")).unwrap();
    expect_bad(
        &base.replace(
            "body = \"slider\", point = [0.456, 0.0, 0.0], axis = [1.0",
            "body = \"slidr\", point = [0.456, 0.0, 0.0], axis = [1.0",
        ),
        "slidr",
        "did you mean `slider`",
    );
    expect_bad(
        &base.replace("kind = \"translational\"", "kind = \"prismatic\""),
        "prismatic",
        "unknown joint kind",
    );
    expect_bad(
        &base.replace("rate = \"150 rad/s\"", "rate = \"150 rad/min\""),
        "rad/min",
        "deg/s, rad/s, rpm",
    );
    expect_bad(
        &base.replace(
            "component = \"x\"\n\n[response.slider_vx]",
            "component = \"w\"\n\n[response.slider_vx]",
        ),
        "component = \"w\"",
        "unknown component `w`",
    );
    expect_bad(
        &base.replace(
            "mass = 0.0760\ninertia = [1.0e-5, 1.0e-5, 1.0e-5]",
            "mass = 0.0760\ninertia = [1.0e-5, -1.0e-5, 1.0e-5]",
        ),
        "-1.0e-5",
        "positive definite",
    );
    expect_bad(
        &base.replace("t_end = 0.0838", "t_end = -1.0"),
        "t_end = -1.0",
        "later than t_start",
    );
    expect_bad(
        &base.replace(
            "b = { body = \"crank\", point = [0.0, 0.0, 0.0], axis = [0.0, 0.0, 1.0] }",
            "b = { body = \"crank\", node = 3, axis = [0.0, 0.0, 1.0] }",
        ),
        "node = 3",
        "rigid body",
    );
}

/// A free aluminium beam (no joints) with transverse loads F at both ends and −2F at the middle
/// node, plus an axial force P at the middle: the body frame accelerates as P/m exactly, and the
/// heavily damped bending settles where each half is a cantilever under its end load.
const FREE_BEAM: &str = r#"
[material.alu]
E = 70e9
nu = 0.33
density = 2700

[section.bar]
shape = "rectangle"
width = 0.01
height = 0.01
material = "alu"
elements = [4, 4]

[body.beam]
kind = "beam"
section = "bar"
start = [0.0, 0.0, 0.0]
end = [0.4, 0.0, 0.0]
elements = 8
modes = 8                 # the square section and the centre clamp give groups of four equal modes
damping = { modes = [1, 5], ratios = [0.7, 0.7] }

[force.end_a]
kind = "point-force"
at = { body = "beam", node = 0 }
value = [0.0, 1.0, 0.0]

[force.end_b]
kind = "point-force"
at = { body = "beam", node = 8 }
value = [0.0, 1.0, 0.0]

[force.middle]
kind = "point-force"
at = { body = "beam", node = 4 }
value = [0.5, -2.0, 0.0]

[response.frame_x]
kind = "position"
body = "beam"
component = "x"

[response.bend]
kind = "mid-node-deflection"
body = "beam"

[response.end_uy]
kind = "nodal-displacement"
body = "beam"
node = 8
component = "uy"

[analysis]
t_end = 0.2
output_step = 0.001
rtol = 1e-8
atol = 1e-12
"#;

#[test]
fn free_flexible_beam_accelerates_as_a_whole_and_bends_to_its_static_shape() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("beam.toml");
    std::fs::write(&p, FREE_BEAM).unwrap();
    let out = dir.path().join("out");
    let o = run(&["run", p.to_str().unwrap(), "-o", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (head, rows) = read_csv(&out.join("history.csv"));
    assert_eq!(head, ["time [s]", "bend [1]", "end_uy [m]", "frame_x [m]"]);
    // x of the frame: ½ (P/m) t², m = ρ A L (the lumped masses add up to it)
    let m = 2700.0 * 1e-4 * 0.4;
    let last = rows.last().unwrap();
    let t = last[0];
    let expected = 0.2 + 0.5 * (0.5 / m) * t * t;
    // (the frame sits at the centre node, not exactly at the centre of mass: the inertial axial
    // load stretches the halves by ~1e-8 of the travel)
    assert!(
        (last[3] - expected).abs() < 1e-7 * (expected - 0.2),
        "frame x {} vs {expected}",
        last[3]
    );
    // each half is a cantilever of length L/2 from the clamped centre, with end load F = 1 N:
    // δ = F (L/2)³ / (3 E I); the ends rise by δ above the middle, so the mid node lies δ below
    // the line through the ends (deflection along z × x = y, negative), divided by L
    let ei = 70e9 * 0.01f64.powi(4) / 12.0;
    let delta = 0.2f64.powi(3) / (3.0 * ei);
    let bend = last[1];
    assert!(
        (bend + delta / 0.4).abs() < 0.02 * delta / 0.4,
        "settled deflection {bend} vs {}",
        -delta / 0.4
    );
    // the end node's own displacement in the body frame is δ (the frame is at the centre)
    assert!(
        (last[2] - delta).abs() < 0.02 * delta,
        "end uy {} vs {delta}",
        last[2]
    );
}
