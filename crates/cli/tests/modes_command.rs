//! `flexsens modes` end to end: closed-form frequencies, derivatives against central differences
//! of whole command-line runs, VTK and Matrix Market outputs, bad input.

use std::path::Path;

mod common;
use common::*;

fn floats(v: &serde_json::Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

/// A slender aluminium beam, pinned at both ends.
fn pinned_beam() -> String {
    format!("{ALUMINIUM_BEAM}modes = 3\nreference = \"pinned-ends\"\nmass = \"consistent\"\n")
}

#[test]
fn pinned_beam_frequencies_match_euler_bernoulli() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("beam.toml");
    std::fs::write(&p, pinned_beam()).unwrap();
    let doc = json(&["modes", p.to_str().unwrap(), "--format", "json"]);
    let f = floats(&doc["bodies"]["beam"]["values"]["frequencies"]);
    // L/h = 100: shear and rotary inertia change the frequencies by less than 0.1 %. Bending in
    // the weak plane (height 0.01 m) gives n² f₁, in the strong plane (width 0.02 m) 2 n² f₁:
    // the three lowest are f₁ (weak, n = 1), 2 f₁ (strong, n = 1), 4 f₁ (weak, n = 2).
    let (e, w, h, rho, l): (f64, f64, f64, f64, f64) = (70e9, 0.02, 0.01, 2700.0, 1.0);
    let m = rho * w * h;
    let euler = |n: f64, depth: f64, breadth: f64| {
        let ei = e * breadth * depth.powi(3) / 12.0;
        (n * std::f64::consts::PI).powi(2) / (2.0 * std::f64::consts::PI * l * l) * (ei / m).sqrt()
    };
    let expected = [euler(1.0, h, w), euler(1.0, w, h), euler(2.0, h, w)];
    for i in 0..3 {
        let rel = (f[i] - expected[i]) / expected[i];
        assert!(
            rel.abs() < 5e-3,
            "mode {}: {} Hz vs Euler–Bernoulli {} Hz",
            i + 1,
            f[i],
            expected[i]
        );
    }
}

#[test]
fn shipped_modes_decks_run_in_every_format() {
    for name in ["modes_beam_rod.toml", "modes_plate_rod.toml"] {
        let p = deck(name);
        for format in ["table", "json", "csv"] {
            let o = run(&[
                "modes",
                p.to_str().unwrap(),
                "--format",
                format,
                "--derivatives",
            ]);
            assert!(
                o.status.success(),
                "{name} {format}: {}",
                String::from_utf8_lossy(&o.stderr)
            );
        }
    }
    // damping: 1 % at mode 1, 3 % at mode 6, as the deck asks
    let doc = json(&[
        "modes",
        deck("modes_plate_rod.toml").to_str().unwrap(),
        "--format",
        "json",
    ]);
    let z = floats(&doc["bodies"]["rod"]["values"]["damping_ratios"]);
    assert!(
        (z[0] - 0.01).abs() < 1e-12 && (z[5] - 0.03).abs() < 1e-12,
        "{z:?}"
    );
    let mm = floats(&doc["bodies"]["rod"]["values"]["modal_masses"]);
    assert!(
        mm.iter().all(|m| (m - 1.0).abs() < 1e-10),
        "mass-normalised modes: {mm:?}"
    );
}

/// Repeated frequencies are marked in every format, and the JSON says what their derivatives
/// mean: the round tube rod clamped at its middle has its first four modes at one frequency
/// (two halves × two bending planes); the pinned beam's are all single.
#[test]
fn repeated_frequencies_are_marked_in_json_and_csv() {
    let p = deck("modes_beam_rod.toml");
    let doc = json(&[
        "modes",
        p.to_str().unwrap(),
        "--format",
        "json",
        "--derivatives",
    ]);
    let rod = &doc["bodies"]["rod"];
    let f = floats(&rod["values"]["frequencies"]);
    assert!(f.iter().all(|x| (x / f[0] - 1.0).abs() < 1e-6), "{f:?}");
    assert_eq!(floats(&rod["values"]["repeated_group"]), [1.0; 4]);
    assert_eq!(rod["repeated"], serde_json::json!([[1, 2, 3, 4]]));
    let note = rod["repeated_derivatives"].as_str().unwrap();
    assert!(note.starts_with("directional"), "{note}");
    let csv =
        String::from_utf8(run(&["modes", p.to_str().unwrap(), "--format", "csv"]).stdout).unwrap();
    assert_eq!(
        csv.lines()
            .filter(|l| l.starts_with("rod,repeated_group,"))
            .count(),
        4
    );
    assert!(csv.contains("rod,repeated_group,0,3,1,,1e0"), "{csv}");

    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("beam.toml");
    std::fs::write(&path, pinned_beam()).unwrap();
    let doc = json(&["modes", path.to_str().unwrap(), "--format", "json"]);
    let beam = &doc["bodies"]["beam"];
    assert_eq!(floats(&beam["values"]["repeated_group"]), [0.0; 3]);
    assert_eq!(beam["repeated"], serde_json::json!([]));
    assert!(beam.get("repeated_derivatives").is_none());
}

#[test]
fn frequency_derivatives_match_central_differences_of_command_line_runs() {
    let p = deck("modes_plate_rod.toml");
    let p = p.to_str().unwrap();
    let doc = json(&["modes", p, "--format", "json", "--derivatives"]);
    let d = &doc["bodies"]["rod"]["derivatives"];
    assert_eq!(d[1]["wrt"], "plate.plies.1.angle");
    // a step large enough that the eigen solver's convergence tolerance does not show in the
    // difference quotient, small enough that the truncation error (∝ h²) stays below 1e-7
    let h = 0.02; // degrees
    let at = |a: f64| {
        json(&[
            "modes",
            p,
            "--format",
            "json",
            "--set",
            &format!("laminate.plate.plies.1.angle={a}"),
        ])
    };
    let (fp, fm) = (at(15.0 + h), at(15.0 - h));
    let fp = floats(&fp["bodies"]["rod"]["values"]["frequencies"]);
    let fm = floats(&fm["bodies"]["rod"]["values"]["frequencies"]);
    let exact = floats(&d[1]["values"]["frequencies"]);
    for i in 0..6 {
        let fd = (fp[i] - fm[i]) / (2.0 * h.to_radians());
        assert!(
            (exact[i] - fd).abs() <= 1e-6 * exact[i].abs().max(1e-2),
            "mode {}: {} vs {fd}",
            i + 1,
            exact[i]
        );
    }
}

/// Read a Matrix Market coordinate file into (rows, cols, entries).
fn read_mtx(path: &Path) -> (usize, usize, Vec<(usize, usize, f64)>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines().filter(|l| !l.starts_with('%'));
    let head: Vec<usize> = lines
        .next()
        .unwrap()
        .split_whitespace()
        .map(|x| x.parse().unwrap())
        .collect();
    let entries: Vec<(usize, usize, f64)> = lines
        .map(|l| {
            let w: Vec<&str> = l.split_whitespace().collect();
            (
                w[0].parse().unwrap(),
                w[1].parse().unwrap(),
                w[2].parse().unwrap(),
            )
        })
        .collect();
    assert_eq!(entries.len(), head[2]);
    (head[0], head[1], entries)
}

#[test]
fn exported_stiffness_derivative_matches_central_differences_of_exported_matrices() {
    let dir = tempfile::tempdir().unwrap();
    let p = deck("modes_plate_rod.toml");
    let p = p.to_str().unwrap();
    let out = |sub: &str, angle: f64| {
        let d = dir.path().join(sub);
        let o = run(&[
            "modes",
            p,
            "--derivatives",
            "--export-matrices",
            d.to_str().unwrap(),
            "--set",
            &format!("laminate.plate.plies.0.angle={angle}"),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        d
    };
    let h = 1e-3;
    let (base, plus, minus) = (
        out("base", 15.0),
        out("plus", 15.0 + h),
        out("minus", 15.0 - h),
    );
    let (n, m, dk) = read_mtx(&base.join("rod.dK_0.mtx"));
    let (_, _, kp) = read_mtx(&plus.join("rod.K.mtx"));
    let (_, _, km) = read_mtx(&minus.join("rod.K.mtx"));
    assert_eq!(n, m);
    let dofs = std::fs::read_to_string(base.join("rod.dofs.csv")).unwrap();
    assert_eq!(
        dofs.lines().count(),
        n + 1,
        "one line per free dof and a header"
    );
    // K's pattern in both perturbed files; dK holds the entries the angle moves, on it (the
    // others zero): compare entry by entry
    assert_eq!(kp.len(), km.len());
    assert!(!dk.is_empty() && dk.len() <= kp.len());
    let moved: std::collections::HashMap<(usize, usize), f64> =
        dk.iter().map(|e| ((e.0, e.1), e.2)).collect();
    let scale = dk.iter().fold(0.0f64, |a, e| a.max(e.2.abs()));
    for (b, c) in kp.iter().zip(&km) {
        assert_eq!((b.0, b.1), (c.0, c.1));
        let a = moved.get(&(b.0, b.1)).copied().unwrap_or(0.0);
        let fd = (b.2 - c.2) / (2.0 * h.to_radians());
        assert!(
            (a - fd).abs() <= 1e-6 * scale,
            "entry ({}, {}): {a} vs {fd}",
            b.0,
            b.1
        );
    }
    let pattern: std::collections::HashSet<(usize, usize)> =
        kp.iter().map(|e| (e.0, e.1)).collect();
    assert!(dk.iter().all(|e| pattern.contains(&(e.0, e.1))));
    // K is symmetric
    let (_, _, k) = read_mtx(&base.join("rod.K.mtx"));
    let map: std::collections::HashMap<(usize, usize), f64> =
        k.iter().map(|e| ((e.0, e.1), e.2)).collect();
    let kmax = k.iter().fold(0.0f64, |a, e| a.max(e.2.abs()));
    for e in &k {
        assert!((map.get(&(e.1, e.0)).copied().unwrap_or(0.0) - e.2).abs() <= 1e-12 * kmax);
    }
}

#[test]
fn vtk_file_holds_the_mesh_and_every_mode() {
    let dir = tempfile::tempdir().unwrap();
    let vtk = dir.path().join("out/rod.vtk");
    let o = run(&[
        "modes",
        deck("modes_beam_rod.toml").to_str().unwrap(),
        "--vtk",
        vtk.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(&vtk).unwrap();
    assert!(text.starts_with("# vtk DataFile Version 3.0\n"));
    assert!(text.contains("POINTS 9 double"));
    assert!(text.contains("CELLS 8 24"));
    for m in 1..=4 {
        assert!(text.contains(&format!("VECTORS mode_{m}_translation double")));
        assert!(text.contains(&format!("VECTORS mode_{m}_rotation double")));
    }
    // no temporary file left behind
    let left: Vec<_> = std::fs::read_dir(dir.path().join("out")).unwrap().collect();
    assert_eq!(left.len(), 1);
}

fn expect_bad(text: &str, extra: &[&str], line: Option<usize>, words: &str) {
    let (_dir, err) = bad_deck(text, |p| with_deck("modes", p, extra));
    if let Some(l) = line {
        assert!(
            err.contains(&format!("bad.toml:{l}:")),
            "line {l} in: {err}"
        );
    }
    assert!(err.contains(words), "'{words}' in: {err}");
}

#[test]
fn bad_bodies_are_reported() {
    let cases = [
        (
            "kind = \"beam\"",
            "kind = \"bean\"",
            "kind = ",
            "did you mean `beam`",
        ),
        (
            "section = \"bar\"\nstart",
            "section = \"rod\"\nstart",
            "section = \"rod\"",
            "undefined section `rod`",
        ),
        (
            "modes = 3",
            "modes = 3\ndamping = { modes = [1, 5], ratios = [0.01, 0.03] }",
            "damping =",
            "between 1 and 3",
        ),
        (
            "orientation = [0, 1, 0]",
            "orientation = [1, 0, 0]",
            "orientation =",
            "parallel to the beam axis",
        ),
        (
            "modes = 3",
            "modes = 3000",
            "[body.beam]",
            "3000 modes requested",
        ),
        (
            "elements = 40",
            "elements = 40\nlaminate = \"x\"",
            "laminate = ",
            "does not apply to kind = \"beam\"",
        ),
    ];
    for (from, to, at, words) in cases {
        let text = pinned_beam().replace(from, to);
        expect_bad(&text, &[], Some(line_of(&text, at)), words);
    }
    expect_bad(
        &pinned_beam(),
        &["--body", "bem"],
        None,
        "did you mean `beam`",
    );
}
