//! Helpers shared by the command-line tests.
#![allow(dead_code)] // each test file uses its own subset

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use flexsens::results::{Data, Group};

/// A shipped deck.
pub fn deck(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../decks")
        .join(name)
}

/// Run the binary.
pub fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_flexsens"))
        .args(args)
        .output()
        .expect("flexsens runs")
}

/// Run the binary, expect success, parse its stdout as JSON.
pub fn json(args: &[&str]) -> serde_json::Value {
    let o = run(args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).unwrap()
}

/// Write `deck` to a fresh directory, `run` it there and parse its JSON summary.
pub fn run_deck_json(deck: &str) -> serde_json::Value {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("deck.toml");
    std::fs::write(&path, deck).unwrap();
    let out = dir.path().join("out");
    json(&[
        "run",
        path.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--json",
    ])
}

/// The 1-based line of the first occurrence of `needle`.
pub fn line_of(text: &str, needle: &str) -> usize {
    text.lines()
        .position(|l| l.contains(needle))
        .expect("needle in text")
        + 1
}

/// Write `text` as `bad.toml` in a fresh directory, run the binary with `args(deck path)`, and
/// expect bad input: exit code 2, no panic, nothing on stdout. Returns the directory (kept
/// alive for the caller's checks) and stderr.
pub fn bad_deck(text: &str, args: impl Fn(&Path) -> Vec<String>) -> (tempfile::TempDir, String) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.toml");
    std::fs::write(&path, text).unwrap();
    let args = args(&path);
    let o = Command::new(env!("CARGO_BIN_EXE_flexsens"))
        .args(&args)
        .output()
        .expect("flexsens runs");
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(
        o.status.code(),
        Some(2),
        "exit code of {args:?} for:\n{text}\nstderr: {err}"
    );
    assert!(!err.contains("panicked"), "{err}");
    assert!(
        o.stdout.is_empty(),
        "nothing on stdout after an error: {}",
        String::from_utf8_lossy(&o.stdout)
    );
    (dir, err)
}

/// The arguments `[command, deck path, extra…]`.
pub fn with_deck(command: &str, deck: &Path, extra: &[&str]) -> Vec<String> {
    let mut a = vec![command.to_string(), deck.display().to_string()];
    a.extend(extra.iter().map(|s| s.to_string()));
    a
}

/// `flexsens optimize path -o out --quiet` with `--set` of each of `sets`: the process's
/// output and its `iterations.csv` (empty if it wrote none).
pub fn optimize_iterations(path: &Path, out: &Path, sets: &[&str]) -> (Output, String) {
    let mut args = vec![
        "optimize",
        path.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ];
    args.push("--quiet");
    for s in sets {
        args.extend(["--set", s]);
    }
    let o = run(&args);
    let csv = std::fs::read_to_string(out.join("iterations.csv")).unwrap_or_default();
    (o, csv)
}

/// Whether h5py can be imported; CI must have it (a missing h5py there fails the test instead
/// of skipping it).
pub fn h5py_available() -> bool {
    let ok = Command::new("python3")
        .args(["-c", "import h5py"])
        .status()
        .is_ok_and(|s| s.success());
    if !ok {
        assert!(std::env::var_os("CI").is_none(), "CI must have h5py");
        eprintln!("SKIPPED: h5py not installed");
    }
    ok
}

/// `flexsens run DECK -o OUT --json --set …` (the shipped deck `deck_name`), expecting success;
/// the JSON summary.
pub fn run_json(deck_name: &str, out: &Path, sets: &[&str]) -> serde_json::Value {
    run_path_json(&deck(deck_name), out, sets)
}

/// `flexsens run PATH -o OUT --json --set …`, expecting success; the JSON summary and the
/// results file.
pub fn run_results(path: &Path, out: &Path, sets: &[&str]) -> (serde_json::Value, Group) {
    let j = run_path_json(path, out, sets);
    (j, Group::read_hdf5(&out.join("results.h5")).unwrap())
}

/// The deck `text` written as `NAME.toml` in `dir` and run into `dir/NAME` ([`run_results`]).
pub fn run_text(dir: &Path, name: &str, text: &str, sets: &[&str]) -> (serde_json::Value, Group) {
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, text).unwrap();
    run_results(&path, &dir.join(name), sets)
}

/// `flexsens run PATH -o OUT --json --set …`, expecting success; the JSON summary.
fn run_path_json(path: &Path, out: &Path, sets: &[&str]) -> serde_json::Value {
    let mut args = vec![
        "run".to_string(),
        path.display().to_string(),
        "-o".into(),
        out.display().to_string(),
        "--json".into(),
    ];
    for s in sets {
        args.extend(["--set".to_string(), s.to_string()]);
    }
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    json(&args)
}

/// A numeric dataset of a result file.
pub fn f64s(g: &Group, path: &str) -> Vec<f64> {
    match &g
        .get(path)
        .unwrap_or_else(|| panic!("no dataset {path}"))
        .data
    {
        Data::F64(v) => v.clone(),
        Data::Text(_) => panic!("{path} is text"),
    }
}

/// `max |a − b| / max |a|`: the largest difference of two histories against the first's size.
pub fn worst_difference(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len(), "histories of different lengths");
    let scale = a.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    a.iter()
        .zip(b)
        .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()))
        / scale
}

/// The direct sensitivities of `response` against the replayed central differences of
/// relative size `size` (as the case is named, e.g. `"0.0001"`) in a run's results of one
/// design variable: `max |CD − direct| / max |direct|`.
pub fn replayed_difference(g: &Group, response: &str, size: &str) -> f64 {
    let direct = f64s(g, &format!("sensitivities/{response}"));
    let fd = f64s(
        g,
        &format!("finite_differences/central_relative_{size}_replay/{response}"),
    );
    worst_difference(&direct, &fd)
}

/// [`replayed_difference`] of each of a run's `m` design variables (its own scale).
pub fn replayed_differences(g: &Group, response: &str, size: &str, m: usize) -> Vec<f64> {
    let direct = f64s(g, &format!("sensitivities/{response}"));
    let fd = f64s(
        g,
        &format!("finite_differences/central_relative_{size}_replay/{response}"),
    );
    let column =
        |x: &[f64], v: usize| -> Vec<f64> { x.iter().skip(v).step_by(m).copied().collect() };
    (0..m)
        .map(|v| worst_difference(&column(&direct, v), &column(&fd, v)))
        .collect()
}

/// The shipped deck `name` with `extra` appended, written in a fresh directory (kept alive by
/// the returned guard).
pub fn with_extra(name: &str, extra: &str) -> (tempfile::TempDir, std::path::PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(deck(name)).unwrap() + extra;
    let path = dir.path().join(name);
    std::fs::write(&path, text).unwrap();
    (dir, path)
}

/// `text` with the table headed `header` (up to the next blank line) replaced by `table`
/// (written without its header).
pub fn with_table(text: &str, header: &str, table: &str) -> String {
    let start = text
        .find(header)
        .unwrap_or_else(|| panic!("{header} in the deck"));
    let end = start + text[start..].find("\n\n").unwrap_or(text.len() - start);
    format!("{}{header}\n{table}{}", &text[..start], &text[end..])
}

/// `flexsens COMMAND PATH --format json EXTRA…`, expecting success.
pub fn report(command: &str, path: &Path, extra: &[String]) -> serde_json::Value {
    let mut args = vec![command.to_string(), path.display().to_string()];
    args.extend(["--format".to_string(), "json".to_string()]);
    args.extend_from_slice(extra);
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    json(&args)
}

/// The beam slider-crank with `extra` tables, run for 3 ms with central differences of relative
/// size `size` on the replayed steps; per design variable (`names`, in the deck's order), the
/// largest difference between the direct sensitivities of the mid-node deflection and the
/// differences, relative to the largest sensitivity, with that largest sensitivity. The
/// sensitivities are those of `sensitivity.method = "direct"`, the exact derivative of the
/// discrete solution, so that the comparison sees the derivative terms alone (the default
/// method's own iteration error, up to about 5e-5 of the largest value, is checked by
/// `run_sensitivity.rs`).
pub fn beam_direct_vs_central(extra: &str, size: &str, names: &[&str]) -> Vec<(f64, f64)> {
    direct_vs_central("slider_crank_beam.toml", extra, size, names)
}

/// [`beam_direct_vs_central`] for the shipped deck `deck_name`.
pub fn direct_vs_central(
    deck_name: &str,
    extra: &str,
    size: &str,
    names: &[&str],
) -> Vec<(f64, f64)> {
    direct_vs_central_of(deck_name, extra, size, names, "mid_deflection", "0.003")
}

/// [`direct_vs_central`] of the response `response` over a run to `t_end` (s).
pub fn direct_vs_central_of(
    deck_name: &str,
    extra: &str,
    size: &str,
    names: &[&str],
    response: &str,
    t_end: &str,
) -> Vec<(f64, f64)> {
    // the method: in the deck's [sensitivity] table, or in one added
    let text = std::fs::read_to_string(deck(deck_name)).unwrap();
    let method = "sensitivity.method=\"direct\"";
    let has_table = text.contains("\n[sensitivity]");
    let extra = if has_table {
        extra.to_string()
    } else {
        format!("{extra}\n[sensitivity]\nmethod = \"direct\"\n")
    };
    let (dir, path) = with_extra(deck_name, &extra);
    let out = dir.path().join("out");
    let mut args = vec![
        "run".to_string(),
        path.display().to_string(),
        "-o".into(),
        out.display().to_string(),
        "--json".into(),
        "--set".into(),
        format!("analysis.t_end={t_end}"),
        "--set".into(),
        "finite_differences.scheme=central".into(),
        "--set".into(),
        format!("finite_differences.sizes=[{size}]"),
    ];
    if has_table {
        args.extend(["--set".into(), method.into()]);
    }
    json(&args.iter().map(String::as_str).collect::<Vec<_>>());
    let g = Group::read_hdf5(&out.join("results.h5")).unwrap();
    let direct = f64s(&g, &format!("sensitivities/{response}"));
    let label = format!("{}", size.parse::<f64>().unwrap());
    let fd = f64s(
        &g,
        &format!("finite_differences/central_relative_{label}_replay/{response}"),
    );
    let m = names.len();
    (0..m)
        .map(|v| {
            let col = |x: &[f64]| -> Vec<f64> { x.iter().skip(v).step_by(m).copied().collect() };
            let (d, f) = (col(&direct), col(&fd));
            let scale = d.iter().fold(0.0f64, |a, x| a.max(x.abs()));
            let err = worst_difference(&d, &f);
            eprintln!(
                "{}: direct vs central differences {err:.1e} (max {scale:.2e})",
                names[v]
            );
            (err, scale)
        })
        .collect()
}

/// A JSON array of arrays of numbers (a matrix in a report).
pub fn matrix(v: &serde_json::Value) -> Vec<Vec<f64>> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|r| {
            r.as_array()
                .unwrap()
                .iter()
                .map(|x| x.as_f64().unwrap())
                .collect()
        })
        .collect()
}

/// A slender aluminium beam, 1 m, 20 mm × 10 mm, 40 elements, without its `modes`, reference
/// condition or supports (the tests add them).
pub const ALUMINIUM_BEAM: &str = r#"
[material.alu]
E = 70e9
nu = 0.33
density = 2700

[section.bar]
shape = "rectangle"
width = 0.02
height = 0.01
material = "alu"
elements = [8, 4]

[body.beam]
kind = "beam"
section = "bar"
start = [0, 0, 0]
end = [1.0, 0, 0]
orientation = [0, 1, 0]
elements = 40
"#;

/// The coupler's mid-point at each time of the four-bar of `decks/four_bar_spatial.toml` with
/// rigid bars, its rocker axis tilted `tilt_deg` about x (0: the planar four-bar): the crank's
/// tip on its circle at one revolution a second, the rocker's tip on the cone its axis sweeps,
/// the coupler's length kept.
pub fn four_bar_midpoints(times: &[f64], tilt_deg: f64) -> Vec<nalgebra::Vector3<f64>> {
    use nalgebra::Vector3;
    let a0 = Vector3::new(0.1, 0.0, 0.0);
    let b0 = Vector3::new(0.26875, 0.2480391854, 0.0);
    let pivot = Vector3::new(0.3, 0.0, 0.0);
    let tilt = tilt_deg.to_radians();
    let n = Vector3::new(0.0, -tilt.sin(), tilt.cos());
    let coupler = (b0 - a0).norm();
    let d = b0 - pivot;
    let centre = n * d.dot(&n);
    let radial = d - centre;
    let r = radial.norm();
    let (e1, e2) = (radial / r, n.cross(&(radial / r)));
    let mut psi = 0.0f64;
    times
        .iter()
        .map(|&t| {
            let phi = 2.0 * std::f64::consts::PI * t;
            let a = Vector3::new(0.1 * phi.cos(), 0.1 * phi.sin(), 0.0);
            let tip = |psi: f64| pivot + centre + (e1 * psi.cos() + e2 * psi.sin()) * r;
            for _ in 0..50 {
                let b = tip(psi);
                let f = (b - a).norm_squared() - coupler * coupler;
                let db = (e2 * psi.cos() - e1 * psi.sin()) * r;
                psi -= f / (2.0 * (b - a).dot(&db));
                if f.abs() < 1e-18 {
                    break;
                }
            }
            (a + tip(psi)) / 2.0
        })
        .collect()
}
