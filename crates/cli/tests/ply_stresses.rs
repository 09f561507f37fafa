//! Ply stresses and failure indices in the bodies of a mechanism (`kind = "ply-stress"`,
//! `"ply-failure"`):
//! - a shell cantilever strip sagging under gravity (`flexsens static`) against beam theory,
//!   `σ = 6M/bh²` on its top face, converging with its modes; its failure indices against the
//!   stress by hand; its ply-angle derivatives against central differences of the command;
//! - the plate slider-crank's ply stress, element failure index and body-wide aggregate, and
//!   the KS-in-time objective of the body's peak index, against replayed central differences
//!   of whole runs for a ply angle, a ply thickness and a material constant, and the
//!   objective's adjoint gradient against its direct one, with the rod's second-order field
//!   and without;
//! - the deck's refusals.

mod common;

use common::{bad_deck, deck, json, replayed_differences, run_text, with_deck};

/// A 0.3 m × 20 mm × 2 mm aluminium strip (ν = 0: beam theory holds across its width) clamped
/// along x = 0 to the ground, sagging under gravity; element 20 is a triangle of the cell at
/// x ∈ [0.10, 0.11] m (centroid x = 0.1 + 2/3 · 0.01 m).
const STRIP: &str = r#"
title = "Clamped strip under gravity"

[material.al]
E = 70.0e9
nu = 0.0
density = 2700.0
Xt = 200.0e6
Xc = 150.0e6
Yt = 200.0e6
Yc = 150.0e6
S12 = 100.0e6

[laminate.sheet]
plies = [{ material = "al", thickness = 2.0e-3, angle = 0.0 }]

[body.strip]
kind = "shell"
laminate = "sheet"
length = 0.3
width = 0.02
elements = [30, 2]
reference = "supports"
supports = [{ plane = { x = 0.0 }, fix = "clamped" }]
modes = 8
basis = "modes"
stiffening = false

[body.strip.couplings]
root = { plane = { x = 0.0 } }

[joint.root]
kind = "fixed"
a = { body = "ground", point = [0.0, 0.01, 0.0] }
b = { body = "strip", coupling = "root" }

[force.gravity]
kind = "gravity"
acceleration = [0.0, 0.0, -9.81]

[response.s11]
kind = "ply-stress"
body = "strip"
element = 20
ply = 0
position = "top"
component = "s11"

[response.max_stress]
kind = "ply-failure"
body = "strip"
element = 20
ply = 0
position = "top"
criterion = "max-stress"

[response.tsai_hill]
kind = "ply-failure"
body = "strip"
element = 20
criterion = "tsai-hill"

[response.peak]
kind = "ply-failure"
body = "strip"
criterion = "max-stress"

[analysis]
t_end = 0.01
"#;

/// `flexsens static` of `text` with `sets`: each response's value at the operating point and
/// the gradients' JSON.
fn static_point(text: &str, sets: &[&str]) -> (serde_json::Value, serde_json::Value) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("strip.toml");
    std::fs::write(&path, text).unwrap();
    let out = dir.path().join("out");
    let mut args = vec![
        "static",
        path.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--json",
    ];
    for s in sets {
        args.extend(["--set", s]);
    }
    let j = json(&args);
    let p = &j["points"][0];
    (p["responses"].clone(), p["gradients"].clone())
}

#[test]
fn a_sagging_strip_has_beam_theory_ply_stresses_converging_with_its_modes_and_mesh() {
    let (l, b, h) = (0.3, 0.02, 2.0e-3);
    let q = 2700.0 * 9.81 * b * h;
    // the top face of a cantilever sagging under its weight is in tension: σ = 6M/bh²
    let sigma = |x: f64| 6.0 * q * (l - x) * (l - x) / 2.0 / (b * h * h);
    // (modes, cells along the length, the element of the cell from x = 0.1 m, its centroid)
    let stress = |modes: usize, nx: usize| {
        let dx = l / nx as f64;
        let cell = (0.1 / dx).round() as usize;
        let sets = [
            format!("body.strip.modes={modes}"),
            format!("body.strip.elements=[{nx}, {}]", nx / 15),
            format!("response.s11.element={}", 2 * cell),
            format!("response.max_stress.element={}", 2 * cell),
            format!("response.tsai_hill.element={}", 2 * cell),
        ];
        let sets: Vec<&str> = sets.iter().map(String::as_str).collect();
        let (r, _) = static_point(STRIP, &sets);
        let s11 = r["s11"].as_f64().unwrap();
        // the failure indices of a uniaxial stress: σ/Xt on the top face (max stress), and
        // over the element's points the bottom face's −σ in compression, σ/Xc (Tsai–Hill
        // takes the strength of the stress's sign)
        // (the faces' stresses differ by the modes' slight membrane strain, 1e-4)
        for (name, strength, tol) in [("max_stress", 200e6, 1e-9), ("tsai_hill", 150e6, 1e-3)] {
            let fi = r[name].as_f64().unwrap();
            assert!(
                (fi / (s11 / strength) - 1.0).abs() < tol,
                "{name} {fi} {s11}"
            );
        }
        // the body's peak: at the root, where the moment is largest, on the face in
        // compression (Xc < Xt); the first element's centroid is at x = dx/3
        let peak = r["peak"].as_f64().unwrap();
        let root = sigma(dx / 3.0) / 150e6;
        assert!((peak / root - 1.0).abs() < 0.05, "{peak} {root}");
        s11 / sigma((cell as f64 + 2.0 / 3.0) * dx) - 1.0
    };
    // the modes: the stress settles as they are added (on one mesh)
    let by_modes: Vec<f64> = [2, 4, 8, 16].iter().map(|&m| stress(m, 30)).collect();
    eprintln!("top-face stress at 2, 4, 8, 16 modes against beam theory: {by_modes:?}");
    let change = |i: usize| (by_modes[i] - by_modes[3]).abs();
    assert!(
        change(1) < change(0) / 2.0 && change(2) < change(1) / 2.0,
        "{by_modes:?}"
    );
    // the mesh: the element's constant curvature converges to beam theory
    let by_mesh: Vec<f64> = [30, 60, 120].iter().map(|&n| stress(16, n)).collect();
    eprintln!("top-face stress at 30, 60, 120 cells against beam theory: {by_mesh:?}");
    assert!(by_mesh[2].abs() < 3e-3, "{by_mesh:?}");
    assert!(by_mesh[1].abs() < 0.7 * by_mesh[0].abs(), "{by_mesh:?}");
    assert!(by_mesh[2].abs() < 0.7 * by_mesh[1].abs(), "{by_mesh:?}");
}

/// The strip of [`STRIP`] laminated of three composite plies at 30°, −45°, 30°, with the
/// angle of the outer two a design variable, a ply thickness and a material constant more.
fn composite_strip(angle: f64, thickness: f64, e2: f64) -> String {
    let material = format!(
        "[material.cfrp]\nE1 = 128.0e9\nE2 = {e2:e}\nE3 = 10.1e9\nG12 = 5.36e9\nG13 = 5.36e9\n\
         G23 = 3.6e9\nnu12 = 0.23\nnu13 = 0.23\nnu23 = 0.4\ndensity = 1586.0\nXt = 1500.0e6\n\
         Xc = 1500.0e6\nYt = 40.0e6\nYc = 246.0e6\nS12 = 68.0e6\n\n\
         [laminate.sheet]\nplies = [\n  {{ material = \"cfrp\", thickness = {thickness:e}, \
         angle = {angle} }},\n  {{ material = \"cfrp\", thickness = 1.0e-3, angle = -45.0 }},\n  \
         {{ material = \"cfrp\", thickness = 1.0e-3, angle = {angle} }},\n]\n"
    );
    let design = "\n[design.theta]\nlaminate = \"sheet\"\nplies = [0, 2]\n\n\
                  [design.t0]\nkind = \"ply-thickness\"\nlaminate = \"sheet\"\nplies = [0]\n\n\
                  [design.e2]\nkind = \"material\"\nmaterial = \"cfrp\"\nconstant = \"E2\"\n";
    let start = STRIP.find("[material.al]").unwrap();
    let end = STRIP.find("[body.strip]").unwrap();
    format!("{}{material}\n{}{design}", &STRIP[..start], &STRIP[end..])
        .replace("criterion = \"max-stress\"", "criterion = \"tsai-wu\"")
        .replace("[response.s11]", "[response.s12]")
        .replace(
            "ply = 0\nposition = \"top\"\ncomponent = \"s11\"",
            "ply = 2\nposition = \"top\"\ncomponent = \"s12\"",
        )
}

#[test]
fn a_composite_strip_s_ply_stress_and_failure_derivatives_equal_central_differences() {
    let (theta, t0, e2) = (30.0, 1.0e-3, 10.1e9);
    let (_, g) = static_point(&composite_strip(theta, t0, e2), &[]);
    let value = |a: f64, t: f64, e: f64, name: &str| {
        let (r, _) = static_point(&composite_strip(a, t, e), &[]);
        r[name].as_f64().unwrap()
    };
    for name in ["s12", "max_stress", "tsai_hill", "peak"] {
        for (variable, step) in [("theta", 0.01), ("t0", 1e-7), ("e2", 1e6)] {
            let (mut p, mut m) = ([theta, t0, e2], [theta, t0, e2]);
            let i = ["theta", "t0", "e2"]
                .iter()
                .position(|v| *v == variable)
                .unwrap();
            p[i] += step;
            m[i] -= step;
            let fd = (value(p[0], p[1], p[2], name) - value(m[0], m[1], m[2], name)) / (2.0 * step);
            let exact = g[name][variable].as_f64().unwrap();
            eprintln!("d{name}/d{variable}: {exact:.6e}, central differences {fd:.6e}");
            assert!(
                (exact - fd).abs() < 1e-5 * fd.abs().max(1e-3 * exact.abs()) + 1e-12,
                "d{name}/d{variable}: {exact} vs {fd}"
            );
            assert!(exact != 0.0, "d{name}/d{variable} is zero");
        }
    }
}

/// The plate slider-crank on a coarse mesh with the composite's strengths, ply stress and
/// failure responses, and a ply thickness and a material constant besides the angle.
const PLATE_EXTRA: &str = r#"
[response.shear]
kind = "ply-stress"
body = "rod"
element = 17
ply = 2
position = "top"
component = "s12"

[response.element_tsai_wu]
kind = "ply-failure"
body = "rod"
element = 17
criterion = "tsai-wu"

[response.rod_hashin]
kind = "ply-failure"
body = "rod"
criterion = "hashin"
rho = 300.0

[response.rod_tsai_wu]
kind = "ply-failure"
body = "rod"
criterion = "tsai-wu"

[objective.tsai_wu_ks]
response = "rod_tsai_wu"
kind = "ks"
rho = 100.0

[design.t0]
kind = "ply-thickness"
laminate = "plate"
plies = [0]

[design.e2]
kind = "material"
material = "paper_composite"
constant = "E2"
"#;

#[test]
fn plate_rod_ply_stress_and_failure_sensitivities_equal_replayed_central_differences() {
    let text = std::fs::read_to_string(deck("slider_crank_plate.toml"))
        .unwrap()
        .replace(
            "density = 1586.0\n",
            "density = 1586.0\nXt = 1500.0e6\nXc = 1500.0e6\nYt = 40.0e6\nYc = 246.0e6\nS12 = 68.0e6\n",
        )
        + PLATE_EXTRA;
    let dir = tempfile::tempdir().unwrap();
    let (summary, g) = run_text(
        dir.path(),
        "plate",
        &text,
        &[
            "body.rod.elements=[16, 2]",
            "response.mid_deflection.nodes=[17, 25, 33]",
            "analysis.t_end=0.01",
            "sensitivity.method=\"direct\"",
        ],
    );
    for response in ["shear", "element_tsai_wu", "rod_hashin"] {
        let errors = replayed_differences(&g, response, "0.0001", 3);
        eprintln!("{response}: direct vs replayed central differences (theta, t0, e2) {errors:?}");
        assert!(errors.iter().all(|e| *e < 1e-4), "{response}: {errors:?}");
    }
    // the KS objective of the body's peak index over time, with a gradient for every variable
    let o = (summary["objectives"].as_array().unwrap().iter())
        .find(|o| o["name"] == "tsai_wu_ks")
        .unwrap();
    let peak = g_max(&g, "rod_tsai_wu");
    let ks = o["value"].as_f64().unwrap();
    // the integral form: never above the peak, below it by about ln(T/τ)/ρ for a peak of
    // width τ (at most ln(outputs)/ρ)
    let outputs = summary["outputs"].as_f64().unwrap();
    assert!(
        ks <= peak && ks > peak - outputs.ln() / 100.0,
        "{ks} {peak}"
    );
    let gradient = o["gradient"].as_array().unwrap();
    assert_eq!(gradient.len(), 3);
    assert!(gradient.iter().all(|x| x.as_f64().unwrap() != 0.0), "{o}");
    // the adjoint method's gradient of it is the direct method's, with the rod's second-order
    // field and without: the adjoint of the eigenproblem takes the eigenvector derivatives
    // back through the plies' stresses and the field's static solves (docs/design.md §3, "The
    // adjoint method")
    let ks_gradient = |method: &str, stiffening: bool| {
        let set = format!("sensitivity.method=\"{method}\"");
        let stiff = format!("body.rod.stiffening={stiffening}");
        let sets = [
            "body.rod.elements=[16, 2]",
            "response.mid_deflection.nodes=[17, 25, 33]",
            "analysis.t_end=0.01",
            "finite_differences.enabled=false",
            &stiff,
            &set,
        ];
        let name = format!("{method}_{stiffening}");
        let (summary, _) = run_text(dir.path(), &name, &text, &sets);
        let o = (summary["objectives"].as_array().unwrap().iter())
            .find(|o| o["name"] == "tsai_wu_ks")
            .unwrap()
            .clone();
        (o["gradient"].as_array().unwrap().iter())
            .map(|x| x.as_f64().unwrap())
            .collect::<Vec<_>>()
    };
    for stiffening in [true, false] {
        let direct = ks_gradient("direct", stiffening);
        let adjoint = ks_gradient("adjoint", stiffening);
        assert_eq!(direct.len(), 3);
        for (d, a) in direct.iter().zip(&adjoint) {
            assert!(
                *d != 0.0 && (d - a).abs() <= 1e-8 * d.abs(),
                "stiffening {stiffening}: adjoint {a:e} vs direct {d:e}"
            );
        }
    }
}

/// The largest value of a response's history in a results file.
fn g_max(g: &flexsens::results::Group, response: &str) -> f64 {
    common::f64s(g, &format!("responses/{response}"))
        .into_iter()
        .fold(f64::NEG_INFINITY, f64::max)
}

#[test]
fn a_box_selects_the_elements_whose_nodes_lie_in_it() {
    // the whole strip: the body's peak; its outer half (x ≥ 0.15 m): the peak there, at its
    // first elements, below the root's by beam theory's (L − x)² law
    let text = format!(
        "{STRIP}\n[response.all]\nkind = \"ply-failure\"\nbody = \"strip\"\n\
         criterion = \"max-stress\"\nbox = [[-1.0, -1.0, -1.0], [1.0, 1.0, 1.0]]\n\n\
         [response.outer]\nkind = \"ply-failure\"\nbody = \"strip\"\n\
         criterion = \"max-stress\"\nbox = [[0.15, -1.0, -1.0], [0.3, 1.0, 1.0]]\n"
    );
    let (r, _) = static_point(&text, &[]);
    let (all, outer, peak) = (
        r["all"].as_f64().unwrap(),
        r["outer"].as_f64().unwrap(),
        r["peak"].as_f64().unwrap(),
    );
    assert_eq!(all, peak);
    // the outer half's first elements have centroids at x = 0.15 + 0.01/3 m
    let expected = peak * ((0.3 - 0.1533) / (0.3 - 0.0033_f64)).powi(2);
    assert!(
        (outer / expected - 1.0).abs() < 0.03,
        "{outer} vs {expected}"
    );
}

#[test]
fn ply_responses_refuse_what_they_cannot_give() {
    let cases: [(String, &str); 8] = [
        (
            STRIP.replace(
                "element = 20\nply = 0\nposition = \"top\"\ncomponent",
                "element = 120\nply = 0\nposition = \"top\"\ncomponent",
            ),
            "element 120 does not exist (elements 0 to 119)",
        ),
        (
            STRIP.replace(
                "ply = 0\nposition = \"top\"\ncomponent",
                "ply = 3\nposition = \"top\"\ncomponent",
            ),
            "ply 3 does not exist: laminate sheet has plies 0 to 0",
        ),
        (
            STRIP.replace(
                "position = \"top\"\ncomponent",
                "position = \"upper\"\ncomponent",
            ),
            "unknown component `upper`: expected one of bottom, middle, top",
        ),
        (
            STRIP.replace("component = \"s11\"", "component = \"sxx\""),
            "expected one of s11, s22, s33, s23, s13, s12",
        ),
        (
            STRIP.replace("criterion = \"tsai-hill\"", "criterion = \"tsai-hil\""),
            "unknown criterion `tsai-hil`: expected one of max-stress, max-strain, tsai-wu, \
             tsai-hill, hashin, hashin-fibre, hashin-matrix, did you mean `tsai-hill`?",
        ),
        (
            STRIP.replace("Xt = 200.0e6\n", "").replace(
                "Xc = 150.0e6\nYt = 200.0e6\nYc = 150.0e6\nS12 = 100.0e6\n",
                "",
            ),
            "ply 0 of laminate `sheet` is of material `al`, which states no strengths",
        ),
        (
            STRIP.replace(
                "criterion = \"tsai-hill\"",
                "criterion = \"tsai-hill\"\nrho = -2.0",
            ),
            "key `response.tsai_hill.rho`",
        ),
        (
            STRIP.replace("criterion = \"tsai-hill\"", "criterion = \"max-strain\"")
                + "\n[design.e]\nkind = \"material\"\nmaterial = \"al\"\nconstant = \"E\"\n",
            "design variable `e` moves the material `al` of body `strip`: the max-strain index",
        ),
    ];
    let both = STRIP.replace(
        "criterion = \"tsai-hill\"",
        "criterion = \"tsai-hill\"\nbox = [[0.0, 0.0, -1.0], [0.1, 0.02, 1.0]]",
    );
    let empty = STRIP.replace(
        "[response.peak]\nkind = \"ply-failure\"",
        "[response.peak]\nbox = [[0.1, 0.001, -1.0], [0.2, 0.002, 1.0]]\nkind = \"ply-failure\"",
    );
    let cases: Vec<(String, &str)> = cases
        .into_iter()
        .chain([
            (both, "give the elements in one way: element = N or box"),
            (empty, "no element of the body has all its nodes in the box"),
        ])
        .collect();
    for (text, message) in &cases {
        let (_dir, err) = bad_deck(text, |p| with_deck("check", p, &[]));
        assert!(err.contains(message), "expected `{message}` in:\n{err}");
    }
}

/// The value printed for `name = VALUE …` in an optimisation's summary.
fn summary_value(text: &str, name: &str) -> f64 {
    let line = (text.lines())
        .find(|l| l.trim_start().starts_with(&format!("{name} = ")))
        .unwrap_or_else(|| panic!("no `{name}` in\n{text}"));
    let value = line
        .split('=')
        .nth(1)
        .unwrap()
        .split_whitespace()
        .next()
        .unwrap();
    value.parse().unwrap()
}

/// The multiplier printed on the line of constraint `name`.
fn multiplier(text: &str, name: &str) -> f64 {
    let line = (text.lines())
        .find(|l| l.trim_start().starts_with(&format!("{name} = ")) && l.contains("multiplier"))
        .unwrap_or_else(|| panic!("no constraint `{name}` in\n{text}"));
    line.rsplit("= ").next().unwrap().trim().parse().unwrap()
}

#[test]
fn the_lightest_plate_rod_that_holds_sits_on_its_strength_bound_and_a_sweep_confirms_it() {
    // the shipped example, cheaper: 16 × 4 elements over the first 6 ms, started near that
    // problem's own optimum (as the deck starts from its coarser mesh's)
    let sets = [
        "body.rod.elements=[16, 4]",
        "response.mid_deflection.nodes=[34, 42, 50]",
        "analysis.t_end=0.006",
        "laminate.plate.plies.0.thickness=3.3e-3",
        "laminate.plate.plies.1.thickness=0.75e-3",
        "laminate.plate.plies.2.thickness=3.3e-3",
    ];
    let dir = tempfile::tempdir().unwrap();
    let path = deck("optimize_plate_strength.toml");
    let mut args = vec![
        "optimize".to_string(),
        path.display().to_string(),
        "-o".into(),
        dir.path().join("opt").display().to_string(),
        "--quiet".into(),
    ];
    for s in sets {
        args.extend(["--set".into(), s.into()]);
    }
    let o = common::run(&args.iter().map(String::as_str).collect::<Vec<_>>());
    let text = String::from_utf8_lossy(&o.stdout).into_owned();
    assert_eq!(
        o.status.code(),
        Some(0),
        "{text}\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let (t_outer, t_core) = (
        summary_value(&text, "t_outer"),
        summary_value(&text, "t_core"),
    );
    // the strength bound is the active constraint, the frequency clear of its bound
    let strength = summary_value(&text, "objective.strength");
    assert!((strength - 0.6667).abs() < 1e-6, "{text}");
    assert!(multiplier(&text, "objective.strength") < 0.0, "{text}");
    assert!(summary_value(&text, "frequency.rod.1") > 185.0, "{text}");
    assert_eq!(multiplier(&text, "frequency.rod.1"), 0.0, "{text}");
    let kkt = text
        .lines()
        .find(|l| l.contains("KKT stationarity"))
        .unwrap();
    let stationarity: f64 = kkt.split_whitespace().nth(2).unwrap().parse().unwrap();
    assert!(stationarity < 1e-3, "{kkt}");
    // the rod's mass is ρ L w (2 t_outer + t_core)
    let mass = |a: f64, b: f64| 1586.0 * 0.304 * 0.04 * (2.0 * a + b);
    let optimum = text.lines().find(|l| l.starts_with("optimum")).unwrap();
    let m_star: f64 = optimum.rsplit("= ").next().unwrap().trim().parse().unwrap();
    assert!(
        (m_star / mass(t_outer, t_core) - 1.0).abs() < 1e-9,
        "{optimum}"
    );
    // the sweep about the optimum (±1 % in each thickness): every lighter design breaks the
    // strength bound, every design that holds is heavier
    let vary = |t: f64| format!("{:e},{:e},{:e}", 0.99 * t, t, 1.01 * t);
    let mut args = vec![
        "sweep".to_string(),
        path.display().to_string(),
        "-o".into(),
        dir.path().join("sweep").display().to_string(),
        "--vary".into(),
        format!("design.t_outer={}", vary(t_outer)),
        "--vary".into(),
        format!("design.t_core={}", vary(t_core)),
    ];
    for s in sets {
        args.extend(["--set".into(), s.into()]);
    }
    let o = common::run(&args.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let csv = std::fs::read_to_string(dir.path().join("sweep/summary.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let column = |name: &str| header.iter().position(|h| h.starts_with(name)).unwrap();
    let (a, b, s) = (
        column("design.t_outer"),
        column("design.t_core"),
        column("strength ["),
    );
    let mut lighter = 0;
    for line in lines {
        let row: Vec<f64> = line
            .split(',')
            .map(|x| x.parse().unwrap_or(f64::NAN))
            .collect();
        let (m, strength) = (mass(row[a], row[b]), row[s]);
        eprintln!(
            "t_outer {:e}, t_core {:e}: mass {m:.6e}, strength {strength:.6}",
            row[a], row[b]
        );
        if m < m_star * (1.0 - 1e-9) {
            lighter += 1;
            assert!(strength > 0.6667, "a lighter design holds: {line}");
        }
        if strength <= 0.6667 {
            assert!(m >= m_star * (1.0 - 1e-9), "{line}");
        }
    }
    assert!(lighter >= 3, "{csv}");
}
