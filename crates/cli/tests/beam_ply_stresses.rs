//! Ply stresses and failure indices of beam bodies in a mechanism (`kind = "ply-stress"`,
//! `"ply-failure"` with `region` and `section_point`): the section analysis's stresses under
//! each element's section forces at its ends and middle (a stress is read at the middle).
//! - an aluminium cantilever sagging under gravity (`flexsens static`) against beam theory,
//!   `σ₁₁ = M x₃/I` at the section's outer integration point and `τ₁₃ = 3V/2A` on its axis,
//!   converging with the mesh; an element's failure index, at its end nearer the root,
//!   against beam theory;
//! - the paper's slider-crank tube rod: a ply stress, an element's Tsai–Wu index and the rod's
//!   KS aggregate against replayed central differences of whole runs for the plies' angle, a
//!   ply thickness (which moves the section's points) and a material constant;
//! - the deck's refusals.

mod common;

use common::{bad_deck, deck, json, replayed_differences, run, run_text, with_deck};

/// A 0.5 m aluminium bar of 20 mm × 10 mm (ν = 0: the section's shear is beam theory's
/// parabola) clamped at its first node to the ground, sagging under gravity along −x₃.
const BAR: &str = r#"
title = "Cantilever bar under gravity"

[material.al]
E = 70.0e9
nu = 0.0
density = 2700.0
Xt = 200.0e6
Xc = 150.0e6
Yt = 200.0e6
Yc = 150.0e6
S12 = 100.0e6

[section.bar]
shape = "rectangle"
width = 0.02
height = 0.01
material = "al"
elements = [5, 5]

[body.bar]
kind = "beam"
section = "bar"
start = [0.0, 0.0, 0.0]
end = [0.5, 0.0, 0.0]
orientation = [0.0, 1.0, 0.0]
elements = 10
modes = 32
reference = "clamped-node"

[joint.root]
kind = "fixed"
a = { body = "ground", point = [0.0, 0.0, 0.0] }
b = { body = "bar", node = 0 }

[force.gravity]
kind = "gravity"
acceleration = [0.0, 0.0, -9.81]

[response.s11]
kind = "ply-stress"
body = "bar"
element = 2
region = 0
section_point = [0.0, 0.005]
component = "s11"

[response.e11]
kind = "ply-stress"
body = "bar"
element = 2
region = 0
section_point = [0.0, 0.005]
component = "e11"

[response.s13]
kind = "ply-stress"
body = "bar"
element = 2
region = 0
section_point = [0.0, 0.0]
component = "s13"

[response.max_stress]
kind = "ply-failure"
body = "bar"
element = 2
criterion = "max-stress"

[analysis]
t_end = 0.01
"#;

/// `flexsens static` of [`BAR`] with `elements` beam elements and `rows` rows of section
/// elements (an odd number): the errors of `σ₁₁` at the section's top integration point and
/// of `τ₁₃` on its axis against beam theory, at the middle of the element nearest a quarter
/// of the length; the element's failure index (at its end nearer the root) against beam theory.
fn bar_errors(elements: usize, rows: usize) -> (f64, f64) {
    let (l, w, h) = (0.5f64, 0.02f64, 0.01f64);
    let q = 2700.0 * 9.81 * w * h;
    let (area, i2) = (w * h, w * h.powi(3) / 12.0);
    // the outer point of the section's 3 × 3 Gauss rule in its top row of elements
    let x3 = h / 2.0 - h / (2.0 * rows as f64) * (1.0 - 0.6f64.sqrt());
    let e = elements / 4;
    let x = (e as f64 + 0.5) * l / elements as f64;
    let sets = [
        format!("body.bar.elements={elements}"),
        format!("section.bar.elements=[5, {rows}]"),
        format!("response.s11.element={e}"),
        format!("response.e11.element={e}"),
        format!("response.s13.element={e}"),
        format!("response.max_stress.element={e}"),
    ];
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bar.toml");
    std::fs::write(&path, BAR).unwrap();
    let out = dir.path().join("out");
    let mut args = vec!["static", path.to_str().unwrap(), "-o"];
    args.extend([out.to_str().unwrap(), "--json"]);
    for s in &sets {
        args.extend(["--set", s]);
    }
    let r = json(&args)["points"][0]["responses"].clone();
    let (s11, s13) = (r["s11"].as_f64().unwrap(), r["s13"].as_f64().unwrap());
    // a cantilever sagging under its weight: the top in tension, M = q(L − x)²/2, V = q(L − x)
    let sigma = q * (l - x).powi(2) / 2.0 * x3 / i2;
    let tau = 1.5 * q * (l - x) / area;
    // the element's largest max-stress index: at its end nearer the root, the bottom's
    // compression, σ/Xc
    let fi = r["max_stress"].as_f64().unwrap();
    let start = x - l / elements as f64 / 2.0;
    let root_side = q * (l - start).powi(2) / 2.0 * x3 / i2 / 150e6;
    // (the end's moment is the element's exact end load: no qℓ²/8 here, the modes' truncation
    // is what is left)
    assert!((fi / root_side - 1.0).abs() < 5e-4, "{fi} {root_side}");
    // the strain there: σ/E (ν = 0)
    let e11 = r["e11"].as_f64().unwrap();
    assert!((e11 / (s11 / 70e9) - 1.0).abs() < 1e-9, "{e11} {s11}");
    (s11 / sigma - 1.0, s13.abs() / tau - 1.0)
}

#[test]
fn a_sagging_bar_has_beam_theory_section_stresses_converging_with_its_meshes() {
    // the beam's mesh: an element's middle carries the mean of its ends' moments, off by
    // qℓ²/8, shrinking with the square of the element's length
    let by_mesh: Vec<f64> = [8, 16, 32].iter().map(|&n| bar_errors(n, 5).0).collect();
    eprintln!("σ11 against beam theory at 8, 16, 32 elements: {by_mesh:?}");
    assert!(by_mesh[2].abs() < 5e-4, "{by_mesh:?}");
    assert!(by_mesh[1].abs() < 0.3 * by_mesh[0].abs(), "{by_mesh:?}");
    assert!(by_mesh[2].abs() < 0.3 * by_mesh[1].abs(), "{by_mesh:?}");
    // the section's mesh: its quadratic elements approach the parabola of the shear
    let by_rows: Vec<f64> = [5, 9, 15].iter().map(|&n| bar_errors(16, n).1).collect();
    eprintln!("τ13 against beam theory at 5, 9, 15 rows: {by_rows:?}");
    assert!(by_rows[2].abs() < 5e-3, "{by_rows:?}");
    assert!(by_rows[1].abs() < 0.6 * by_rows[0].abs(), "{by_rows:?}");
    assert!(by_rows[2].abs() < 0.8 * by_rows[1].abs(), "{by_rows:?}");
}

/// The paper's beam deck with strengths, beam ply responses, and a ply thickness and a
/// material constant as design variables next to its angle.
fn tube_rod() -> String {
    std::fs::read_to_string(deck("slider_crank_beam.toml"))
        .unwrap()
        .replace(
            "density = 1586.0\n",
            "density = 1586.0\nXt = 1500.0e6\nXc = 1500.0e6\nYt = 40.0e6\nYc = 246.0e6\nS12 = 68.0e6\n",
        )
        + r#"
[response.axial]
kind = "ply-stress"
body = "rod"
element = 4
region = 3
section_point = [1.0e-3, 5.6e-3]
component = "s11"

[response.element_tsai_wu]
kind = "ply-failure"
body = "rod"
element = 2
criterion = "tsai-wu"

[response.rod_tsai_wu]
kind = "ply-failure"
body = "rod"
criterion = "tsai-wu"
rho = 300.0

[design.t0]
kind = "ply-thickness"
laminate = "tube_wall"
plies = [0]

"# + E2
}

/// The material design variable of [`tube_rod`].
const E2: &str = r#"
[design.e2]
kind = "material"
material = "paper_composite"
constant = "E2"
"#;

#[test]
fn tube_rod_ply_stress_and_failure_sensitivities_equal_replayed_central_differences() {
    let dir = tempfile::tempdir().unwrap();
    let (_, g) = run_text(
        dir.path(),
        "tube",
        &tube_rod(),
        &["analysis.t_end=0.01", "sensitivity.method=\"direct\""],
    );
    for response in ["axial", "element_tsai_wu", "rod_tsai_wu"] {
        let errors = replayed_differences(&g, response, "0.0001", 3);
        eprintln!("{response}: direct vs replayed central differences (e2, t0, theta) {errors:?}");
        assert!(errors.iter().all(|e| *e < 1e-4), "{response}: {errors:?}");
    }
    // a ply's shear strain, through the nominal compliance (no material variable)
    let strain = tube_rod().replace(E2, "")
        + "\n[response.shear_strain]\nkind = \"ply-stress\"\nbody = \"rod\"\nelement = 4\n\
           region = 1\nsection_point = [1.0e-3, 5.2e-3]\ncomponent = \"e12\"\n";
    let (_, g) = run_text(
        dir.path(),
        "strain",
        &strain,
        &["analysis.t_end=0.01", "sensitivity.method=\"direct\""],
    );
    let errors = replayed_differences(&g, "shear_strain", "0.0001", 2);
    eprintln!("shear_strain: direct vs replayed central differences (t0, theta) {errors:?}");
    assert!(errors.iter().all(|e| *e < 1e-4), "{errors:?}");
}

#[test]
fn beam_ply_responses_refuse_what_they_cannot_give() {
    let cases: [(String, &str); 6] = [
        (
            BAR.replace(
                "region = 0\nsection_point = [0.0, 0.005]",
                "ply = 0\nsection_point = [0.0, 0.005]",
            ),
            "`bar` is a beam body: its stress points are its sections' integration points",
        ),
        (
            BAR.replace(
                "element = 2\ncriterion",
                "element = 2\nposition = \"top\"\ncriterion",
            ),
            "key `response.max_stress.position`",
        ),
        (
            BAR.replace("section_point = [0.0, 0.005]\n", ""),
            "missing value: section_point ([x2, x3], m",
        ),
        (
            BAR.replace(
                "region = 0\nsection_point = [0.0, 0.005]",
                "region = 1\nsection_point = [0.0, 0.005]",
            ),
            "region 1 does not exist: section bar has regions 0 to 0",
        ),
        (
            BAR.replace(
                "element = 2\nregion = 0\nsection_point = [0.0, 0.005]",
                "element = 10\nregion = 0\nsection_point = [0.0, 0.005]",
            ),
            "element 10 does not exist (elements 0 to 9)",
        ),
        (
            BAR.replace(
                "Xt = 200.0e6\nXc = 150.0e6\nYt = 200.0e6\nYc = 150.0e6\nS12 = 100.0e6\n",
                "",
            ),
            "region 0 of section `bar` is of material `al`, which states no strengths",
        ),
    ];
    for (text, message) in &cases {
        let (_dir, err) = bad_deck(text, |p| with_deck("check", p, &[]));
        assert!(err.contains(message), "expected `{message}` in:\n{err}");
    }
    // a section given by its properties has no stress points
    let given = BAR.replace(
        "shape = \"rectangle\"\nwidth = 0.02\nheight = 0.01\nmaterial = \"al\"\nelements = [5, 5]",
        "shape = \"properties\"\nEA = 14.0e6\nGA2 = 4.0e6\nGA3 = 4.0e6\nGJ = 100.0\nEI2 = 80.0\n\
         EI3 = 300.0\nmass_per_length = 0.54\ninertia = [4.5e-6, 1.8e-5]",
    );
    let (_dir, err) = bad_deck(&given, |p| with_deck("check", p, &[]));
    assert!(
        err.contains("section `bar` of the body is given by its properties: it has no stress"),
        "{err}"
    );
    // a ply strain through the nominal compliance with the material a design variable
    let moved = tube_rod()
        + "\n[response.strain]\nkind = \"ply-stress\"\nbody = \"rod\"\nelement = 4\n\
                              region = 1\nsection_point = [1.0e-3, 5.2e-3]\ncomponent = \"e12\"\n";
    let (_dir, err) = bad_deck(&moved, |p| with_deck("check", p, &[]));
    assert!(
        err.contains(
            "key `response.strain.component`: design variable `e2` moves the material \
                      `paper_composite` of body `rod`: a ply strain takes the strains"
        ),
        "{err}"
    );
    // an aggregate of Hashin's fibre index is checked, with a warning of its jumps
    let hashin = BAR.to_string()
        + "\n[response.h]\nkind = \"ply-failure\"\nbody = \"bar\"\ncriterion = \"hashin\"\nrho = 100.0\n";
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("hashin.toml");
    std::fs::write(&path, hashin).unwrap();
    let o = run(&["check", path.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("warning: ") && err.contains("Hashin's fibre index jumps where σ11 changes"),
        "{err}"
    );
    // a shell body's points are chosen by ply and position
    let shell = std::fs::read_to_string(deck("slider_crank_plate.toml")).unwrap()
        + "\n[response.s]\nkind = \"ply-failure\"\nbody = \"rod\"\nregion = 0\ncriterion = \"tsai-wu\"\n";
    let (_dir, err) = bad_deck(&shell, |p| with_deck("check", p, &[]));
    assert!(
        err.contains("`rod` is a shell body: its stress points are chosen by `ply`"),
        "{err}"
    );
}
