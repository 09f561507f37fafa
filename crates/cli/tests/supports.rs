//! Supports stated in the deck (`supports = [...]`, `reference = "supports"`): node sets by
//! plane, box or list, and the dof fixed there. Checked against the closed-form frequencies of a
//! simply supported square plate (with mesh convergence), against the built-in pinned-ends
//! reference of a beam, and for their deck errors.

mod common;

use common::{bad_deck, json, with_deck};

/// A simply supported (hard: `w` and the rotation about the edge normal fixed; in-plane
/// displacement along the edge fixed too) square isotropic plate, 1 m × 1 m × 10 mm.
const SS_PLATE: &str = r#"
[material.al]
E = 70.0e9
nu = 0.3
density = 2700.0

[laminate.sheet]
plies = [{ material = "al", thickness = 0.01, angle = 0.0 }]

[body.plate]
kind = "shell"
laminate = "sheet"
length = 1.0
width = 1.0
elements = [16, 16]
modes = 4
mass = "consistent"
reference = "supports"
supports = [
  { plane = { x = 0.0 }, fix = ["uy", "uz", "rx"] },
  { plane = { x = 1.0 }, fix = ["uy", "uz", "rx"] },
  { plane = { y = 0.0 }, fix = ["ux", "uz", "ry"] },
  { plane = { y = 1.0 }, fix = ["ux", "uz", "ry"] },
]
"#;

fn frequencies(text: &str, sets: &[&str], body: &str) -> Vec<f64> {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("deck.toml");
    std::fs::write(&p, text).unwrap();
    let mut args = vec!["modes", p.to_str().unwrap(), "--format", "json"];
    for s in sets {
        args.extend(["--set", s]);
    }
    let doc = json(&args);
    doc["bodies"][body]["values"]["frequencies"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

#[test]
fn simply_supported_square_plate_matches_the_closed_form_and_converges() {
    // thin plate: f_mn = (π/2) (m² + n²) √(D / ρh) / a², D = E h³ / 12(1 − ν²)
    let d = 70e9 * 0.01f64.powi(3) / (12.0 * (1.0 - 0.09));
    let f = |m: f64, n: f64| std::f64::consts::PI / 2.0 * (m * m + n * n) * (d / 27.0).sqrt();
    let exact = [f(1.0, 1.0), f(1.0, 2.0), f(2.0, 1.0), f(2.0, 2.0)];
    let errors: Vec<Vec<f64>> = [16, 32, 48]
        .iter()
        .map(|n| {
            let set = format!("body.plate.elements=[{n}, {n}]");
            let got = frequencies(SS_PLATE, &[&set], "plate");
            got.iter().zip(&exact).map(|(g, e)| g / e - 1.0).collect()
        })
        .collect();
    eprintln!("relative errors at 16, 32, 48 elements a side: {errors:?}");
    // measured: mode 1 1.2e-2, 2.5e-3, 8.5e-4 — second order in the element size
    for m in 0..4 {
        assert!(errors[0][m] > 0.0 && errors[1][m] > 0.0, "{errors:?}");
        assert!(errors[1][m] < errors[0][m] / 3.5, "{errors:?}");
        assert!(errors[2][m] < errors[1][m] / 1.9, "{errors:?}");
        assert!(errors[2][m] < 5e-3, "{errors:?}");
    }
    assert!(errors[1][0] < 5e-3, "{errors:?}");
}

/// A slender aluminium beam held by supports that state the pinned-ends reference condition.
const BEAM: &str = r#"
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
modes = 4
"#;

#[test]
fn supports_can_state_a_built_in_reference_condition() {
    let pinned = frequencies(&format!("{BEAM}reference = \"pinned-ends\"\n"), &[], "beam");
    let stated = frequencies(
        &format!(
            "{BEAM}reference = \"supports\"\nsupports = [\n  {{ nodes = [0], fix = [\"ux\", \
             \"uy\", \"uz\", \"rx\"] }},\n  {{ box = [[0.99, -1, -1], [1.01, 1, 1]], fix = \
             [\"uy\", \"uz\"] }},\n]\n"
        ),
        &[],
        "beam",
    );
    for (a, b) in pinned.iter().zip(&stated) {
        assert!((a / b - 1.0).abs() < 1e-10, "{pinned:?} against {stated:?}");
    }
    // supports add to a reference condition: a beam clamped at its centre vibrates as two equal
    // cantilevers (its modes in pairs); pinning the far end stiffens that half only, and the
    // pairs split
    let centre = frequencies(&format!("{BEAM}\n"), &[], "beam");
    let held = frequencies(
        &format!("{BEAM}supports = [{{ plane = {{ x = 1.0 }}, fix = \"pinned\" }}]\n"),
        &[],
        "beam",
    );
    assert!((centre[1] / centre[0] - 1.0).abs() < 1e-9, "{centre:?}");
    assert!((held[0] / centre[0] - 1.0).abs() < 1e-9, "{held:?}");
    assert!(held[1] > 1.5 * held[0], "{held:?} against {centre:?}");
}

#[test]
fn bad_supports_are_reported_with_their_key() {
    let cases: [(&str, &str, &str); 6] = [
        (
            "reference = \"supports\"\n",
            "body.beam.reference",
            "needs supports",
        ),
        (
            "reference = \"supports\"\nsupports = [{ plane = { x = 2.0 }, fix = \"pinned\" }]\n",
            "body.beam.supports[0]",
            "no node of the body lies there",
        ),
        (
            "supports = [{ plane = { x = 0.0 }, fix = [\"uz\", \"tx\"] }]\n",
            "body.beam.supports[0].fix",
            "list of dof names",
        ),
        (
            "supports = [{ nodes = [0], plane = { x = 0.0 }, fix = \"pinned\" }]\n",
            "body.beam.supports[0]",
            "in one way",
        ),
        (
            "reference = \"free-free\"\nsupports = [{ nodes = [0], fix = \"pinned\" }]\n",
            "body.beam.reference",
            "use reference = \"supports\"",
        ),
        (
            "reference = \"supports\"\nsupports = [{ nodes = [0], fix = \"pinned\" }]\n",
            "body.beam",
            "rigid-body motion(s) free",
        ),
    ];
    for (extra, key, words) in cases {
        let (_d, err) = bad_deck(&format!("{BEAM}{extra}"), |p| with_deck("modes", p, &[]));
        assert!(err.contains(key) && err.contains(words), "{extra}: {err}");
    }
}
