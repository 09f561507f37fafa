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

/// The numbers of a JSON array.
fn floats(v: &serde_json::Value) -> Vec<f64> {
    v.as_array()
        .unwrap_or_else(|| panic!("not an array: {v}"))
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

/// The cross-ply [0/90]s of T300/5208-like plies (0.125 mm) with their strengths (MPa: Xt 1500,
/// Xc 1200, Yt 40, Yc 246, S12 68).
const CROSS_PLY: &str = r#"
[material.t300]
E1 = 181e9
E2 = 10.3e9
E3 = 10.3e9
G12 = 7.17e9
G13 = 7.17e9
G23 = 3.78e9
nu12 = 0.28
nu13 = 0.28
nu23 = 0.36
density = 1600.0
Xt = 1500e6
Xc = 1200e6
Yt = 40e6
Yc = 246e6
S12 = 68e6

[laminate.xply]
plies = [
  { material = "t300", thickness = 0.125e-3, angle = 0.0 },
  { material = "t300", thickness = 0.125e-3, angle = 90.0 },
]
symmetric = true
"#;

#[test]
fn a_bent_cross_ply_stresses_its_plies_and_fails_them_as_laminate_theory_by_hand() {
    let (e1, e2, nu12): (f64, f64, f64) = (181e9, 10.3e9, 0.28);
    let nu21 = nu12 * e2 / e1;
    let d = 1.0 - nu12 * nu21;
    let (q11, q22, q12) = (e1 / d, e2 / d, nu12 * e2 / d);
    let t: f64 = 0.125e-3;
    // D of [0/90]s: the 0° plies outside (|z| from t to 2t), the 90° ones inside
    let outer = 2.0 * ((2.0 * t).powi(3) - t.powi(3)) / 3.0;
    let inner = 2.0 * t.powi(3) / 3.0;
    let (d11, d22, d12) = (
        q11 * outer + q22 * inner,
        q22 * outer + q11 * inner,
        q12 * (outer + inner),
    );
    let mx = 5.0;
    // κ = D⁻¹ [Mx, 0]
    let det = d11 * d22 - d12 * d12;
    let (kx, ky) = (d22 * mx / det, -d12 * mx / det);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("xply.toml");
    std::fs::write(&path, CROSS_PLY).unwrap();
    let o = run(&[
        "laminate",
        path.to_str().unwrap(),
        "--load",
        "Mx=5",
        "--format",
        "json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let values = &v["laminates"]["xply"]["values"];
    let curvature = floats(&values["curvature"]);
    assert!((curvature[0] / kx - 1.0).abs() < 1e-12 && (curvature[1] / ky - 1.0).abs() < 1e-10);
    // the bottom of the 0° ply (z = −2t): σ1 = z (Q11 κx + Q12 κy), σ2 = z (Q12 κx + Q22 κy)
    let z = -2.0 * t;
    let (s1, s2) = (z * (q11 * kx + q12 * ky), z * (q12 * kx + q22 * ky));
    let stress = &values["ply_stress"];
    let bottom = floats(&stress[0]);
    assert!(
        (bottom[0] / s1 - 1.0).abs() < 1e-10,
        "{} vs {s1}",
        bottom[0]
    );
    assert!(
        (bottom[1] / s2 - 1.0).abs() < 1e-10,
        "{} vs {s2}",
        bottom[1]
    );
    // the least reserve factors: max stress at that point (fibre compression, σ1/Xc)
    let rf = floats(&values["reserve_factor"]);
    assert!((rf[0] - 1200e6 / -s1).abs() < 1e-9 * rf[0], "{rf:?}");
    // Tsai–Wu by hand at every point, the least R among them
    let (xt, xc, yt, yc, s) = (1500e6, 1200e6, 40e6, 246e6, 68e6);
    let (f11, f22) = (1.0 / (xt * xc), 1.0 / (yt * yc));
    let tsai_wu = |p: &[f64]| {
        let a = f11 * p[0] * p[0] + f22 * p[1] * p[1] + p[5] * p[5] / (s * s)
            - (f11 * f22).sqrt() * p[0] * p[1];
        let b = (1.0 / xt - 1.0 / xc) * p[0] + (1.0 / yt - 1.0 / yc) * p[1];
        2.0 / (b + (b * b + 4.0 * a).sqrt())
    };
    let points = stress.as_array().unwrap();
    assert_eq!(points.len(), 12);
    let least = points
        .iter()
        .map(|p| tsai_wu(&floats(p)))
        .fold(f64::INFINITY, f64::min);
    assert!((rf[2] / least - 1.0).abs() < 1e-10, "{} vs {least}", rf[2]);
    // and the table names the criteria and the critical plies
    let o = run(&["laminate", path.to_str().unwrap(), "--load", "Mx=5,Qx=100"]);
    let text = stdout(&o);
    assert!(
        text.contains("tsai-wu") && text.contains("at ply 0/bottom"),
        "{text}"
    );
    assert!(!text.contains("NaN"), "{text}");
    // a resultant that is not one, a value that is no number
    for (arg, says) in [
        ("Mz=5", "not a resultant"),
        ("Mx=five", "not a finite number"),
    ] {
        let o = run(&["laminate", path.to_str().unwrap(), "--load", arg]);
        assert_eq!(o.status.code(), Some(2), "{arg}");
        assert!(stderr(&o).contains(says), "{arg}: {}", stderr(&o));
    }
}

#[test]
fn strengths_need_the_five_in_plane_ones_and_must_be_positive() {
    let deck = |extra: &str| {
        format!(
            "[material.cfrp]\nE1 = 128e9\nE2 = 10.1e9\nE3 = 10.1e9\nG12 = 5.36e9\nG13 = 5.36e9\n\
             G23 = 5.36e9\nnu12 = 0.23\nnu13 = 0.23\nnu23 = 0.23\ndensity = 1586\n{extra}\n\
             [laminate.rod]\nplies = [{{ material = \"cfrp\", thickness = 1e-4, angle = 0.0 }}]\n"
        )
    };
    expect_bad_deck(
        &deck("Xt = 1.5e9\nXc = 1.2e9\nYt = 4e7\nYc = 2.46e8"),
        1,
        "material.cfrp.S12",
        "strengths need Xt, Xc, Yt, Yc and S12",
    );
    expect_bad_deck(
        &deck("Xt = 1.5e9\nXc = 1.2e9\nYt = 4e7\nYc = 2.46e8\nS12 = 6.8e7\nS23 = -1.0"),
        17,
        "material.cfrp.S23",
        "must be a positive strength",
    );
}

#[test]
fn loaded_ply_stress_and_failure_derivatives_equal_central_differences_of_the_command() {
    // an unbalanced [30/−45/60] under bending, stretching and shear: every ply angle's
    // derivatives of the deformation, the ply stresses, strains and failure indices
    let deck = |a: [f64; 3]| {
        CROSS_PLY.replace(
            "plies = [\n  { material = \"t300\", thickness = 0.125e-3, angle = 0.0 },\n  { material = \"t300\", thickness = 0.125e-3, angle = 90.0 },\n]\nsymmetric = true",
            &format!(
                "plies = [\n  {{ material = \"t300\", thickness = 0.125e-3, angle = {} }},\n  \
                 {{ material = \"t300\", thickness = 0.125e-3, angle = {} }},\n  \
                 {{ material = \"t300\", thickness = 0.125e-3, angle = {} }},\n]",
                a[0], a[1], a[2]
            ),
        )
    };
    let dir = tempfile::tempdir().unwrap();
    let laminate = |a: [f64; 3], derivatives: bool| {
        let path = dir.path().join("lam.toml");
        std::fs::write(&path, deck(a)).unwrap();
        let mut args = vec![
            "laminate",
            path.to_str().unwrap(),
            "--load",
            "Mx=2,My=-1,Nx=3000,Nxy=500,Qx=80",
            "--format",
            "json",
        ];
        if derivatives {
            args.push("--derivatives");
        }
        let o = run(&args);
        assert!(o.status.success(), "{}", stderr(&o));
        let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        v["laminates"]["xply"].clone()
    };
    let angles = [30.0, -45.0, 60.0];
    let nominal = laminate(angles, true);
    assert!(nominal.to_string().contains("\"failure_index\""));
    fn flat(v: &serde_json::Value) -> Vec<f64> {
        match v {
            serde_json::Value::Array(a) => a.iter().flat_map(flat).collect(),
            x => vec![x.as_f64().unwrap_or(f64::NAN)],
        }
    }
    let h = 1e-4; // degrees
    for ply in 0..3 {
        let block = &nominal["derivatives"][ply];
        assert_eq!(block["wrt"], format!("plies.{ply}.angle"));
        let (mut p, mut m) = (angles, angles);
        p[ply] += h;
        m[ply] -= h;
        let (plus, minus) = (laminate(p, false), laminate(m, false));
        for q in [
            "midplane_strain",
            "curvature",
            "ply_stress",
            "ply_strain",
            "failure_index",
        ] {
            let exact = flat(&block["values"][q]);
            let (vp, vm) = (flat(&plus["values"][q]), flat(&minus["values"][q]));
            // per radian, the angles stepped in degrees
            let cd: Vec<f64> = (vp.iter().zip(&vm))
                .map(|(a, b)| (a - b) / (2.0 * h.to_radians()))
                .collect();
            let scale = cd.iter().fold(0.0f64, |s, x| s.max(x.abs()));
            let worst = (exact.iter().zip(&cd)).fold(0.0f64, |w, (e, c)| w.max((e - c).abs()));
            assert!(
                scale > 0.0 && worst < 1e-5 * scale,
                "ply {ply} {q}: {worst:e} of {scale:e}"
            );
        }
    }
}
