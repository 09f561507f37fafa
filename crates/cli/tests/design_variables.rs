//! `[design.*]` variables in the commands that differentiate a single object: `laminate`,
//! `section` and `modes --derivatives` print one block per variable, per degree, checked
//! against central differences of command-line runs with the plies turned by `--set`; and a
//! mesh-file section whose regions are laminate plies follows the laminate's variables.

mod common;

use std::path::Path;

use common::{report, run, with_extra};

/// Two variables of the tube's laminate: the outer pair as `[+δ/−δ]`, the innermost ply alone.
const TUBE_DESIGN: &str = "
[design.outer]
laminate = \"tube_wall\"
plies = [2, 3]
factors = [1.0, -1.0]

[design.inner]
laminate = \"tube_wall\"
plies = [0]
";

/// `--set` arguments that put the tube's plies at `angles` (degrees).
fn tube_plies(angles: [f64; 4]) -> Vec<String> {
    angles
        .iter()
        .enumerate()
        .flat_map(|(i, a)| {
            [
                "--set".to_string(),
                format!("laminate.tube_wall.plies.{i}.angle={a}"),
            ]
        })
        .collect()
}

/// Ply angles of the tube at the design `(outer, inner)` moved by `(d_outer, d_inner)`.
fn moved(d_outer: f64, d_inner: f64) -> [f64; 4] {
    [15.0 + d_inner, 15.0, 15.0 + d_outer, 15.0 - d_outer]
}

#[test]
fn section_derivatives_per_design_variable_match_central_differences() {
    let (_dir, path) = with_extra("section_composite_tube.toml", TUBE_DESIGN);
    let doc = report("section", &path, &["--derivatives".into()]);
    let d = doc["sections"]["rod"]["derivatives"].as_array().unwrap();
    let names: Vec<&str> = d.iter().map(|b| b["wrt"].as_str().unwrap()).collect();
    // variables in the deck's (alphabetical) order, per degree
    assert_eq!(names, ["inner", "outer"]);
    assert!(d.iter().all(|b| b["per"] == "deg"));
    let h = 1e-3;
    for (k, (dx, dy)) in [(0.0, 1.0), (1.0, 0.0)].into_iter().enumerate() {
        let plus = report("section", &path, &tube_plies(moved(h * dx, h * dy)));
        let minus = report("section", &path, &tube_plies(moved(-h * dx, -h * dy)));
        let v = |doc: &serde_json::Value, what: &str, i: usize, j: usize| {
            doc["sections"]["rod"]["values"][what][i][j]
                .as_f64()
                .unwrap()
        };
        let scale = (0..6)
            .flat_map(|i| (0..6).map(move |j| (i, j)))
            .map(|(i, j)| d[k]["values"]["stiffness"][i][j].as_f64().unwrap().abs())
            .fold(0.0, f64::max);
        assert!(scale > 0.0);
        for (i, j) in [(0, 0), (0, 3), (3, 3), (1, 1), (4, 4), (5, 5), (2, 5)] {
            let fd = (v(&plus, "stiffness", i, j) - v(&minus, "stiffness", i, j)) / (2.0 * h);
            let exact = d[k]["values"]["stiffness"][i][j].as_f64().unwrap();
            assert!(
                (exact - fd).abs() <= 1e-6 * scale,
                "{}: K{i}{j} {exact} vs {fd}",
                names[k]
            );
        }
    }
    // the table says the unit
    let table = run(&["section", path.to_str().unwrap(), "--derivatives"]);
    let text = String::from_utf8_lossy(&table.stdout);
    assert!(text.contains("d/d outer (per deg)"), "{text}");
    let csv = run(&[
        "section",
        path.to_str().unwrap(),
        "--derivatives",
        "--format",
        "csv",
    ]);
    let text = String::from_utf8_lossy(&csv.stdout);
    assert!(
        text.lines()
            .any(|l| l.starts_with("rod,stiffness,0,0,N/deg,outer,")),
        "{text}"
    );
}

#[test]
fn laminate_derivatives_per_design_variable_match_central_differences() {
    let (_dir, path) = with_extra("section_composite_tube.toml", TUBE_DESIGN);
    let doc = report("laminate", &path, &["--derivatives".into()]);
    let d = doc["laminates"]["tube_wall"]["derivatives"]
        .as_array()
        .unwrap();
    assert_eq!(d.len(), 2);
    assert_eq!(d[1]["wrt"], "outer");
    assert_eq!(d[1]["per"], "deg");
    let h = 1e-3;
    let plus = report("laminate", &path, &tube_plies(moved(h, 0.0)));
    let minus = report("laminate", &path, &tube_plies(moved(-h, 0.0)));
    for m in ["A", "B", "D"] {
        // a derivative may vanish (the pair's A): then round-off of the values sets the scale
        let max = |doc: &serde_json::Value| {
            (0..3)
                .flat_map(|i| (0..3).map(move |j| (i, j)))
                .map(|(i, j)| doc[m][i][j].as_f64().unwrap().abs())
                .fold(0.0, f64::max)
        };
        let scale = max(&d[1]["values"]).max(1e-7 * max(&doc["laminates"]["tube_wall"]["values"]));
        for i in 0..3 {
            for j in 0..3 {
                let v = |doc: &serde_json::Value| {
                    doc["laminates"]["tube_wall"]["values"][m][i][j]
                        .as_f64()
                        .unwrap()
                };
                let fd = (v(&plus) - v(&minus)) / (2.0 * h);
                let exact = d[1]["values"][m][i][j].as_f64().unwrap();
                assert!(
                    (exact - fd).abs() <= 1e-6 * scale,
                    "{m}{i}{j}: {exact} vs {fd}"
                );
            }
        }
    }
}

#[test]
fn mode_derivatives_per_design_variable_match_central_differences() {
    let (_dir, path) = with_extra(
        "modes_beam_rod.toml",
        "\n[design.theta]\nlaminate = \"tube_wall\"\n",
    );
    let doc = report("modes", &path, &["--derivatives".into()]);
    let d = &doc["bodies"]["rod"]["derivatives"];
    assert_eq!(d.as_array().unwrap().len(), 1);
    assert_eq!(d[0]["wrt"], "theta");
    assert_eq!(d[0]["per"], "deg");
    let h = 0.02;
    let at = |a: f64| report("modes", &path, &tube_plies([a; 4]));
    let (plus, minus) = (at(15.0 + h), at(15.0 - h));
    let f = |doc: &serde_json::Value| -> Vec<f64> {
        doc["bodies"]["rod"]["values"]["frequencies"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect()
    };
    let (fp, fm) = (f(&plus), f(&minus));
    for (i, x) in d[0]["values"]["frequencies"]
        .as_array()
        .unwrap()
        .iter()
        .enumerate()
    {
        let exact = x.as_f64().unwrap();
        let fd = (fp[i] - fm[i]) / (2.0 * h);
        assert!(
            (exact - fd).abs() <= 1e-5 * exact.abs(),
            "mode {}: {exact} vs {fd} Hz/deg",
            i + 1
        );
    }
}

/// A Gmsh tube (inner radius 10 mm, two 0.5 mm plies, regions "inner" and "outer") whose
/// regions are given either as material and angle or as the plies of a laminate.
fn mesh_deck(regions: &str) -> String {
    format!(
        "[material.ud]
E1 = 128.0e9
E2 = 10.1e9
E3 = 10.1e9
G12 = 5.36e9
G13 = 5.36e9
G23 = 3.9e9
nu12 = 0.23
nu13 = 0.23
nu23 = 0.3
density = 1586.0

[laminate.wall]
plies = [
  {{ material = \"ud\", thickness = 0.5e-3, angle = 30.0 }},
  {{ material = \"ud\", thickness = 0.5e-3, angle = -30.0 }},
]

[section.tube]
shape = \"mesh\"
file = \"{}\"
{regions}
",
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../section/tests/data/tube_q8.msh")
            .display()
    )
}

#[test]
fn mesh_regions_given_as_laminate_plies_follow_the_laminate_and_its_variables() {
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, text: String| {
        let p = dir.path().join(name);
        std::fs::write(&p, text).unwrap();
        p
    };
    let by_material = write(
        "material.toml",
        mesh_deck(
            "regions.inner = { material = \"ud\", angle = 30.0, frame = \"radial\" }
regions.outer = { material = \"ud\", angle = -30.0, frame = \"radial\" }",
        ),
    );
    let by_ply = mesh_deck(
        "regions.inner = { laminate = \"wall\", ply = 0, frame = \"radial\" }
regions.outer = { laminate = \"wall\", ply = 1, frame = \"radial\" }

[design.pair]
laminate = \"wall\"
factors = [1.0, -1.0]",
    );
    let by_ply = write("ply.toml", by_ply);
    let a = report("section", &by_material, &[]);
    let b = report("section", &by_ply, &["--derivatives".into()]);
    let k = |doc: &serde_json::Value, i: usize, j: usize| {
        doc["sections"]["tube"]["values"]["stiffness"][i][j]
            .as_f64()
            .unwrap()
    };
    for i in 0..6 {
        for j in 0..6 {
            assert_eq!(k(&a, i, j), k(&b, i, j), "K{i}{j}");
        }
    }
    // the [+30/−30] pair turned as [+30+δ/−30−δ]: extension–twist coupling moves
    let d = &b["sections"]["tube"]["derivatives"][0];
    assert_eq!(d["wrt"], "pair");
    let h = 1e-3;
    let at = |delta: f64| {
        report(
            "section",
            &by_ply,
            &[
                "--set".into(),
                format!("laminate.wall.plies.0.angle={}", 30.0 + delta),
                "--set".into(),
                format!("laminate.wall.plies.1.angle={}", -30.0 - delta),
            ],
        )
    };
    let (plus, minus) = (at(h), at(-h));
    for (i, j) in [(0, 0), (0, 3), (3, 3), (4, 4)] {
        let fd = (k(&plus, i, j) - k(&minus, i, j)) / (2.0 * h);
        let exact = d["values"]["stiffness"][i][j].as_f64().unwrap();
        assert!(
            (exact - fd).abs() <= 1e-6 * exact.abs().max(1e-6 * k(&b, i, i).abs()),
            "K{i}{j}: {exact} vs {fd}"
        );
    }
    assert!(d["values"]["stiffness"][0][3].as_f64().unwrap().abs() > 0.0);
    // giving both a material and a laminate ply is refused, naming the key
    let both = write(
        "both.toml",
        mesh_deck(
            "regions.inner = { laminate = \"wall\", ply = 0, angle = 5.0 }
regions.outer = { laminate = \"wall\", ply = 7 }",
        ),
    );
    let o = run(&["section", both.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("section.tube.regions.inner.angle"), "{err}");
}

/// Gmsh regions take every wall frame of the simple format, the element-aligned ones
/// (`"xi"`, `"eta"`) included (their numbers are checked on a structured half tube in
/// `crates/section/tests/mesh_input.rs`; this tube mesh is not structured, so its elements'
/// directions vary and the result is not the radial frame's).
#[test]
fn mesh_regions_accept_element_aligned_frames() {
    let dir = tempfile::tempdir().unwrap();
    for frame in ["xi", "eta"] {
        let p = dir.path().join(format!("{frame}.toml"));
        std::fs::write(
            &p,
            mesh_deck(&format!(
                "regions.inner = {{ laminate = \"wall\", ply = 0, frame = \"{frame}\" }}
regions.outer = {{ laminate = \"wall\", ply = 1, frame = \"{frame}\" }}"
            )),
        )
        .unwrap();
        let doc = report("section", &p, &[]);
        let ea = doc["sections"]["tube"]["values"]["stiffness"][0][0]
            .as_f64()
            .unwrap();
        assert!(ea > 0.0, "{frame}: {ea}");
    }
    // keys of another frame are refused
    let text = mesh_deck(
        "regions.inner = { laminate = \"wall\", ply = 0, frame = \"xi\", centre = [0.0, 0.0] }
regions.outer = { laminate = \"wall\", ply = 1, frame = \"xi\" }",
    );
    let (_d, err) = common::bad_deck(&text, |q| common::with_deck("section", q, &[]));
    assert!(err.contains("section.tube.regions.inner.centre"), "{err}");
    assert!(err.contains("frame = \"xi\""), "{err}");
}
