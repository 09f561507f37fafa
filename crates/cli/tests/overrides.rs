//! `--set KEY=VALUE` deck overrides.

use std::process::{Command, Output};

use flexsens::deck::overrides::{Override, OverrideError, apply};

mod common;
use common::*;

fn laminate_json(args: &[&str]) -> (Output, Option<serde_json::Value>) {
    let path = deck("laminate_paper_composite.toml");
    let o = Command::new(env!("CARGO_BIN_EXE_flexsens"))
        .args(["laminate", path.to_str().unwrap(), "--format", "json"])
        .args(args)
        .output()
        .unwrap();
    let doc = serde_json::from_slice(&o.stdout).ok();
    (o, doc)
}

fn set(text: &str, args: &[&str]) -> Result<String, OverrideError> {
    let o: Vec<Override> = args
        .iter()
        .map(|a| Override::parse(a))
        .collect::<Result<_, _>>()?;
    apply(text, &o)
}

#[test]
fn overriding_a_ply_angle_changes_the_stiffness_as_editing_the_file_would() {
    let (o, doc) = laminate_json(&[
        "--laminate",
        "layup_0",
        "--set",
        "laminate.layup_0.plies.0.angle=90",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let doc = doc.unwrap();
    let lam = &doc["laminates"]["layup_0"];
    assert_eq!(lam["plies"][0]["angle_deg"], 90.0);
    assert_eq!(lam["plies"][1]["angle_deg"], 0.0);
    // the same edit made in the file gives the same numbers
    let text = std::fs::read_to_string(deck("laminate_paper_composite.toml")).unwrap();
    let edited = text.replacen(
        "thickness = 1.25e-3, angle = 0.0 }",
        "thickness = 1.25e-3, angle = 90.0 }",
        1,
    );
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("edited.toml");
    std::fs::write(&p, edited).unwrap();
    let o2 = Command::new(env!("CARGO_BIN_EXE_flexsens"))
        .args([
            "laminate",
            p.to_str().unwrap(),
            "--format",
            "json",
            "--laminate",
            "layup_0",
        ])
        .output()
        .unwrap();
    let doc2: serde_json::Value = serde_json::from_slice(&o2.stdout).unwrap();
    assert_eq!(lam["values"], doc2["laminates"]["layup_0"]["values"]);
    let (_, base) = laminate_json(&["--laminate", "layup_0"]);
    assert_ne!(
        lam["values"]["D"],
        base.unwrap()["laminates"]["layup_0"]["values"]["D"]
    );
}

#[test]
fn several_overrides_and_bare_words() {
    let (o, doc) = laminate_json(&[
        "--laminate",
        "layup_15",
        "--set",
        "material.paper_composite.E1=130e9",
        "--set",
        "laminate.layup_15.reference=bottom",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let lam = &doc.unwrap()["laminates"]["layup_15"];
    // reference at the bottom face: B = −(h/2) A ≠ 0
    assert!(lam["values"]["B"][0][0].as_f64().unwrap().abs() > 1e3);
}

#[test]
fn overrides_keep_comments_lines_and_formatting() {
    let text = "# header\n[laminate.a]  # trailing\nplies = [ { material = \"m\", thickness = 1e-3, angle = 0 } ]\nsymmetric = false # keep\n";
    let out = set(
        text,
        &["laminate.a.plies.0.angle=45", "laminate.a.symmetric=true"],
    )
    .unwrap();
    assert_eq!(
        out,
        "# header\n[laminate.a]  # trailing\nplies = [ { material = \"m\", thickness = 1e-3, angle = 45 } ]\nsymmetric = true # keep\n"
    );
}

#[test]
fn arrays_of_tables_and_new_keys() {
    let text = "[[laminate.a.plies]]\nmaterial = \"m\"\nangle = 0\n\n[[laminate.a.plies]]\nmaterial = \"m\"\nangle = 10\n";
    let out = set(
        text,
        &[
            "laminate.a.plies.1.angle=-10",
            "laminate.a.plies.0.thickness=2e-3",
        ],
    )
    .unwrap();
    let v: toml::Table = out.parse().unwrap();
    let plies = v["laminate"]["a"]["plies"].as_array().unwrap();
    assert_eq!(plies[1]["angle"].as_integer(), Some(-10));
    assert_eq!(plies[0]["thickness"].as_float(), Some(2e-3));
}

#[test]
fn bad_overrides_name_the_path() {
    let text = "[laminate.a]\nplies = [ { angle = 0 } ]\n";
    let e = set(text, &["laminate.b.plies.0.angle=1"]).unwrap_err();
    assert!(
        e.to_string().contains("`laminate.b` is not in the deck"),
        "{e}"
    );
    let e = set(text, &["laminate.a.plies.3.angle=1"]).unwrap_err();
    assert!(
        e.to_string()
            .contains("`laminate.a.plies.3` is out of range (1 entries)"),
        "{e}"
    );
    let e = set(text, &["laminate.a.plies.x=1"]).unwrap_err();
    assert!(e.to_string().contains("must be an index"), "{e}");
    let e = set(text, &["laminate.a.plies.0.angle.deg=1"]).unwrap_err();
    assert!(e.to_string().contains("is a value"), "{e}");
    assert!(matches!(
        Override::parse("laminate.a"),
        Err(OverrideError::Syntax(_))
    ));
    assert!(matches!(
        Override::parse("=3"),
        Err(OverrideError::Syntax(_))
    ));
    assert!(matches!(
        Override::parse("a..b=3"),
        Err(OverrideError::Syntax(_))
    ));
}

/// A path into a single table the deck leaves out (`[sensitivity]`, `[analysis]`, …) creates
/// it after the deck's text (its lines keep their numbers); a missing named table is still an
/// error.
#[test]
fn overrides_create_the_single_tables_a_deck_leaves_out() {
    let text = "# a deck\n[laminate.a]\nplies = [ { angle = 0 } ]\n";
    let out = set(
        text,
        &[
            "sensitivity.method=\"direct\"",
            "analysis.baumgarte.alpha=2.0",
            "analysis.t_end=0.5",
        ],
    )
    .unwrap();
    assert!(out.starts_with(text), "{out}");
    let v: toml::Table = out.parse().unwrap();
    assert_eq!(v["sensitivity"]["method"].as_str(), Some("direct"));
    assert_eq!(v["analysis"]["baumgarte"]["alpha"].as_float(), Some(2.0));
    assert_eq!(v["analysis"]["t_end"].as_float(), Some(0.5));
    // a table inside one the deck has goes after the deck's text too
    let text = "[analysis]\nt_end = 1.0\n\n[laminate.a]\nplies = [ { angle = 0 } ]\n";
    let out = set(text, &["analysis.baumgarte.alpha=2.0"]).unwrap();
    assert!(out.starts_with(text), "{out}");
    for bad in ["body.rod.modes=4", "laminate.b.plies.0.angle=1"] {
        let e = set(text, &[bad]).unwrap_err();
        assert!(e.to_string().contains("is not in the deck"), "{bad}: {e}");
    }
}

#[test]
fn an_invalid_value_set_from_the_command_line_is_reported_with_a_note() {
    let (o, _) = laminate_json(&["--set", "laminate.layup_0.plies.2.thickness=-1e-3"]);
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("laminate_paper_composite.toml:25:"), "{err}");
    assert!(err.contains("laminate.layup_0.plies[2].thickness"), "{err}");
    assert!(
        err.contains("note: the deck was edited by --set laminate.layup_0.plies.2.thickness=-1e-3"),
        "{err}"
    );
    let (o, _) = laminate_json(&["--set", "laminate.nope.plies.0.angle=1"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("`laminate.nope` is not in the deck"));
}
