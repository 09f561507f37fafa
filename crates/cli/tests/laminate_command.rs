//! `flexsens laminate` end to end: shipped decks, output formats, derivatives, bad input.

use std::process::Output;

use laminate::{OrthotropicMaterial, Ply, PlyStack};

mod common;
use common::*;

fn stdout(o: &Output) -> String {
    String::from_utf8(o.stdout.clone()).unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8(o.stderr.clone()).unwrap()
}

#[test]
fn every_shipped_laminate_deck_runs_in_every_format() {
    for name in [
        "laminate_quasi_isotropic.toml",
        "laminate_paper_composite.toml",
    ] {
        let path = deck(name);
        let p = path.to_str().unwrap();
        for format in ["table", "json", "csv"] {
            let o = run(&["laminate", p, "--format", format, "--derivatives"]);
            assert!(o.status.success(), "{name} {format}: {}", stderr(&o));
            assert!(!stdout(&o).is_empty());
        }
    }
}

#[test]
fn json_output_shows_the_quasi_isotropic_invariants() {
    let path = deck("laminate_quasi_isotropic.toml");
    let o = run(&[
        "laminate",
        path.to_str().unwrap(),
        "--format",
        "json",
        "--laminate",
        "quasi_isotropic",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let doc: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    let lam = &doc["laminates"]["quasi_isotropic"];
    assert_eq!(
        lam["plies"].as_array().unwrap().len(),
        8,
        "symmetric = true mirrors the 4 plies"
    );
    let a = |i: usize, j: usize| lam["values"]["A"][i][j].as_f64().unwrap();
    assert!(((a(0, 0) - a(1, 1)) / a(0, 0)).abs() < 1e-12);
    assert!((a(2, 2) - (a(0, 0) - a(0, 1)) / 2.0).abs() < 1e-12 * a(0, 0));
    assert!(a(0, 2).abs() < 1e-12 * a(0, 0));
    assert_eq!(lam["units"]["D"], "N*m");
    // T300/5208 numbers: h = 1 mm, rho = 1600 kg/m³
    assert!((lam["values"]["mass_per_area"].as_f64().unwrap() - 1.6).abs() < 1e-12);
    assert!(lam.get("derivatives").is_none(), "only with --derivatives");
}

#[test]
fn csv_output_is_one_value_per_row() {
    let path = deck("laminate_paper_composite.toml");
    let o = run(&[
        "laminate",
        path.to_str().unwrap(),
        "--format",
        "csv",
        "--laminate",
        "layup_30",
        "--derivatives",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = stdout(&o);
    let mut lines = text.lines();
    assert_eq!(
        lines.next(),
        Some("laminate,quantity,row,col,unit,wrt,value")
    );
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    assert!(rows.iter().all(|r| r.len() == 7));
    // 4 scalars + 3×9 + 4 entries, for the values and for each of the 6 plies
    assert_eq!(rows.len(), 7 * (4 + 27 + 4));
    let d11 = rows
        .iter()
        .find(|r| r[1] == "D" && r[2] == "0" && r[3] == "0" && r[5].is_empty())
        .unwrap();
    let d11: f64 = d11[6].parse().unwrap();
    assert!(d11 > 0.0);
    assert!(
        rows.iter()
            .any(|r| r[5] == "plies.5.angle" && r[4] == "N*m/rad")
    );
}

#[test]
fn ply_angle_derivatives_match_eq50_and_central_differences_across_chunks() {
    // ten plies: more than one chunk of eight duals
    let g = 5.36e9;
    let mat =
        OrthotropicMaterial::new([128e9, 10.1e9, 10.1e9], [g, g, g], [0.23; 3], 1586.0).unwrap();
    let angles: Vec<f64> = (0..10)
        .map(|i| (17.0 * i as f64 - 60.0).to_radians())
        .collect();
    let stack = |a: &[f64]| {
        PlyStack::new(
            a.iter()
                .map(|&t| Ply {
                    material: mat,
                    thickness: 0.2e-3,
                    angle: t,
                })
                .collect(),
        )
        .unwrap()
    };
    let base = stack(&angles);
    let each: Vec<_> = (0..10).map(|i| vec![(i, 1.0)]).collect();
    let derivs = flexsens::commands::laminate::angle_derivatives(&base, &each);
    assert_eq!(derivs.len(), 10);
    for (i, d) in derivs.iter().enumerate() {
        let closed = base.angle_derivative(&[i]);
        let h = 1e-6;
        let (mut ap, mut am) = (angles.clone(), angles.clone());
        ap[i] += h;
        am[i] -= h;
        let (kp, km) = (stack(&ap).stiffness(), stack(&am).stiffness());
        for (dual, exact, plus, minus) in [
            (d.a, closed.a, kp.a, km.a),
            (d.b, closed.b, kp.b, km.b),
            (d.d, closed.d, kp.d, km.d),
        ] {
            let scale = exact.abs().max();
            assert!((dual - exact).abs().max() <= 1e-12 * scale, "ply {i}");
            let fd = (plus - minus) / (2.0 * h);
            assert!(
                (dual - fd).abs().max() <= 1e-7 * scale,
                "ply {i}: {dual} vs {fd}"
            );
        }
    }
}

/// Write `text` as a deck, run `flexsens laminate` on it, expect exit 2 and an error naming the
/// file, `line` and `key`.
fn expect_bad_deck(text: &str, line: usize, key: &str, words: &str) {
    let (dir, err) = bad_deck(text, |p| with_deck("laminate", p, &[]));
    let loc = format!("{}:{line}:", dir.path().join("bad.toml").display());
    assert!(err.contains(&loc), "expected location {loc} in: {err}");
    assert!(err.contains(key), "expected key {key} in: {err}");
    assert!(err.contains(words), "expected '{words}' in: {err}");
}

const MATERIAL: &str = "[material.cfrp]\nE1 = 128e9\nE2 = 10.1e9\nE3 = 10.1e9\nG12 = 5.36e9\nG13 = 5.36e9\nG23 = 5.36e9\nnu12 = 0.23\nnu13 = 0.23\nnu23 = 0.23\ndensity = 1586\n";

fn with_laminate(plies: &str) -> String {
    format!("{MATERIAL}\n[laminate.rod]\nplies = [\n{plies}\n]\n")
}

#[test]
fn syntax_errors_are_located() {
    expect_bad_deck("[material.cfrp]\nE = 70e9\nnu = = 0.3\n", 3, "bad.toml", "");
}

#[test]
fn unknown_keys_are_named_with_their_line() {
    let text = MATERIAL.replace("nu23 = 0.23\n", "nu23 = 0.23\nE4 = 1e9\n");
    expect_bad_deck(&text, 11, "E4", "unknown field");
    expect_bad_deck("[materials.cfrp]\nE = 1\n", 1, "materials", "unknown field");
}

#[test]
fn wrong_types_are_named() {
    let text = with_laminate("  { material = \"cfrp\", thickness = \"thin\", angle = 0 },");
    expect_bad_deck(&text, 15, "key `thickness`", "invalid type");
}

#[test]
fn physically_invalid_values_are_named() {
    let text = with_laminate(
        "  { material = \"cfrp\", thickness = 1e-3, angle = 0 },\n  { material = \"cfrp\", thickness = -1e-3, angle = 0 },",
    );
    expect_bad_deck(&text, 16, "laminate.rod.plies[1].thickness", "positive");
    let text = MATERIAL.replace("G13 = 5.36e9", "G13 = -5.36e9");
    expect_bad_deck(&text, 6, "material.cfrp.G13", "G13 = -5360000000");
    let text = MATERIAL.replace("nu12 = 0.23", "nu12 = 4.0");
    expect_bad_deck(&text, 1, "material.cfrp", "not positive definite");
    let text = MATERIAL.replace("E2 = 10.1e9", "E2 = nan");
    expect_bad_deck(&text, 3, "material.cfrp.E2", "E2 = NaN");
}

#[test]
fn missing_values_are_named() {
    let text = MATERIAL.replace("density = 1586\n", "");
    expect_bad_deck(&text, 1, "material.cfrp.density", "missing value");
    let text = MATERIAL.replace("G23 = 5.36e9\n", "");
    expect_bad_deck(&text, 1, "material.cfrp.G23", "missing value");
    let text = with_laminate("  { material = \"cfrp\", angle = 0 },");
    expect_bad_deck(
        &text,
        15,
        "laminate.rod.plies[0].thickness",
        "missing value",
    );
}

#[test]
fn undefined_names_are_named_with_a_suggestion() {
    let text = with_laminate("  { material = \"crfp\", thickness = 1e-3, angle = 0 },");
    expect_bad_deck(
        &text,
        15,
        "laminate.rod.plies[0].material",
        "did you mean `cfrp`",
    );
    let text = format!(
        "{MATERIAL}\n[laminate.rod]\nreference = \"midplain\"\nplies = [{{ material = \"cfrp\", thickness = 1e-3, angle = 0 }}]\n"
    );
    expect_bad_deck(
        &text,
        14,
        "laminate.rod.reference",
        "did you mean `mid-plane`",
    );
}

#[test]
fn unreadable_deck_and_unknown_laminate_are_bad_input() {
    let o = run(&["laminate", "/nonexistent/deck.toml"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("/nonexistent/deck.toml") && stderr(&o).contains("cannot read"));
    let path = deck("laminate_paper_composite.toml");
    let o = run(&["laminate", path.to_str().unwrap(), "--laminate", "layup_51"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("no laminate `layup_51`"),
        "{}",
        stderr(&o)
    );
    let o = run(&["laminate", path.to_str().unwrap(), "--format", "xml"]);
    assert_eq!(
        o.status.code(),
        Some(2),
        "clap usage errors are bad input too"
    );
}

mod no_panic {
    use flexsens::deck::{Source, laminates::validate};
    use proptest::prelude::*;

    const VALID: &str = include_str!("../../../decks/laminate_quasi_isotropic.toml");

    fn check(text: String) {
        let src = Source::new("fuzz.toml", text);
        if let Ok(raw) = src.parse() {
            let _ = validate(&src, &raw);
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(300))]
        #[test]
        fn mutated_decks_never_panic(pos in 0usize..VALID.len(), len in 0usize..40, insert in "[ -~\n]{0,12}") {
            let mut text = VALID.to_string();
            let start = (0..=pos).rev().find(|&i| text.is_char_boundary(i)).unwrap_or(0);
            let end = (start + len..=text.len()).find(|&i| text.is_char_boundary(i)).unwrap_or(text.len());
            text.replace_range(start..end, &insert);
            check(text);
        }

        #[test]
        fn arbitrary_text_never_panics(text in "\\PC{0,200}") {
            check(text);
        }

        #[test]
        fn numbers_of_any_size_never_panic(v in prop::num::f64::ANY) {
            let text = VALID.replace("0.125e-3", &format!("{v:e}")).replace("45.0", &format!("{v:?}"));
            check(text);
        }
    }
}
