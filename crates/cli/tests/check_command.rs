//! `flexsens check`: every shipped deck passes; bad decks fail with their place; mechanisms are
//! assembled and redundant equations named.

mod common;
use common::*;

/// The decks in `dir` (`.toml` files) that pass `check`, asserting that each does.
fn check_every_deck_in(dir: &std::path::Path) -> usize {
    let mut n = 0;
    for entry in std::fs::read_dir(dir).unwrap() {
        let p = entry.unwrap().path();
        if p.extension().is_some_and(|e| e == "toml") {
            let o = run(&["check", p.to_str().unwrap()]);
            assert!(
                o.status.success(),
                "{}: {}",
                p.display(),
                String::from_utf8_lossy(&o.stderr)
            );
            assert!(String::from_utf8_lossy(&o.stdout).ends_with("deck OK\n"));
            n += 1;
        }
    }
    n
}

/// The shipped decks, and those of the examples and benchmarks.
#[test]
fn every_shipped_deck_passes_check() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let n = check_every_deck_in(&root.join("decks"));
    assert!(n >= 7, "the shipped decks were found ({n})");
    for dir in ["examples/time_to_accuracy", "crates/cli/benches"] {
        assert!(check_every_deck_in(&root.join(dir)) >= 1, "{dir}");
    }
}

/// A limit beyond every count a deck can write is no limit (it used to wrap to a negative
/// number and refuse every deck), for each `--max-*` flag.
#[test]
fn the_largest_limits_refuse_nothing() {
    let deck =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../decks/slider_crank_beam.toml");
    for flag in [
        "--max-elements",
        "--max-steps",
        "--max-cases",
        "--max-input-bytes",
        "--max-memory",
    ] {
        let o = run(&[
            "check",
            deck.to_str().unwrap(),
            flag,
            "18446744073709551615",
        ]);
        assert!(
            o.status.success(),
            "{flag}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
}

#[test]
fn check_lists_the_design_variables_with_what_they_move() {
    let (_dir, path) = with_extra(
        "slider_crank_beam.toml",
        "\n[design.slider_mass]\nkind = \"rigid-mass\"\nbody = \"slider\"\n\
         [design.e1]\nkind = \"material\"\nmaterial = \"paper_composite\"\nconstant = \"E1\"\n",
    );
    let o = run(&["check", path.to_str().unwrap()]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for line in [
        "design variable theta = 15 deg: ply angles of laminate `tube_wall`",
        "design variable slider_mass = 0.038 kg: mass of rigid body `slider`",
        "design variable e1 = 128000000000 Pa: E1 of material `paper_composite`",
        "geometric stiffening: rod on",
    ] {
        assert!(out.contains(line), "{line}\n{out}");
    }
}

#[test]
fn check_names_redundant_equations_and_can_refuse_them() {
    let p = deck("slider_crank_rigid.toml");
    let o = run(&["check", p.to_str().unwrap()]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("3 redundant joint equations removed") && text.contains("slider_guide"),
        "{text}"
    );
    let o = run(&[
        "check",
        p.to_str().unwrap(),
        "--set",
        "analysis.redundant=error",
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("redundant constraint equations") && err.contains("slider_guide"),
        "{err}"
    );
}

#[test]
fn check_reports_bad_input_with_its_place_and_runs_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(deck("slider_crank_rigid.toml"))
        .unwrap()
        .replace("mass = 0.0380", "mass = -0.0380");
    let p = dir.path().join("bad.toml");
    std::fs::write(&p, &text).unwrap();
    let o = run(&["check", p.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains(&format!("bad.toml:{}:", line_of(&text, "mass = -0.0380")))
            && err.contains("rigid.crank.mass"),
        "{err}"
    );
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        1,
        "nothing written"
    );
}

/// An empty deck (or one with only a title) is not "OK": it is probably the wrong file.
#[test]
fn an_empty_deck_is_refused() {
    for text in ["", "title = \"nothing\"\n"] {
        let (_d, err) = common::bad_deck(text, |p| common::with_deck("check", p, &[]));
        assert!(err.contains("defines nothing to check"), "{err}");
    }
}

/// Meshes beyond the stated limits (1e6 elements a direction, 1e6 elements in all) are refused
/// with the key before anything is allocated, instead of aborting on allocation.
#[test]
fn oversized_meshes_are_refused_before_allocation() {
    let beam = std::fs::read_to_string(deck("slider_crank_beam.toml")).unwrap();
    let plate = std::fs::read_to_string(deck("slider_crank_plate.toml")).unwrap();
    let cases = [
        (
            beam.replace("elements = 8 ", "elements = 1000000000 "),
            "body.rod.elements",
        ),
        (
            beam.replace("elements_around = 32", "elements_around = 1000000000"),
            "section.tube.elements_around",
        ),
        (
            beam.replace("elements_around = 32", "elements_around = 900000"),
            "section.tube.elements_around",
        ),
        (
            plate.replace("elements = [64, 8]", "elements = [100000, 100000]"),
            "body.rod.elements",
        ),
    ];
    for (text, key) in cases {
        let (_d, err) = common::bad_deck(&text, |p| common::with_deck("check", p, &[]));
        assert!(err.contains(key) && err.contains("limit"), "{key}: {err}");
    }
}

/// An objective taken at a time outside the simulated span is refused by `check`, with its key
/// and line (before, `run` failed only after the whole simulation).
#[test]
fn an_objective_outside_the_span_is_refused() {
    let text = std::fs::read_to_string(deck("slider_crank_beam.toml")).unwrap()
        + "\n[objective.late]\nresponse = \"mid_deflection\"\nkind = \"at\"\ntime = 1.0\n";
    let (_d, err) = common::bad_deck(&text, |p| common::with_deck("check", p, &[]));
    let line = common::line_of(&text, "time = 1.0");
    assert!(
        err.contains("objective.late.time")
            && err.contains("outside the simulated span")
            && err.contains(&format!(":{line}:")),
        "{err}"
    );
}

/// The library's own checks reach the deck with the table's line: a joint from the ground to
/// the ground, and an inertia no mass distribution has (3 > 1 + 1).
#[test]
fn ground_to_ground_joints_and_impossible_inertias_are_refused_at_their_table() {
    let base = std::fs::read_to_string(common::deck("slider_crank_rigid.toml")).unwrap();
    let cases = [
        (
            base.replace(
                "b = { body = \"crank\", point = [0.0, 0.0, 0.0], axis = [0.0, 0.0, 1.0] }",
                "b = { body = \"ground\", point = [0.0, 0.0, 0.0], axis = [0.0, 0.0, 1.0] }",
            ),
            "joint.crank_pivot",
            "two different bodies",
        ),
        (
            base.replace(
                "inertia = [1.0e-7, 7.32e-5, 7.32e-5]",
                "inertia = [1.0, 1.0, 3.0]",
            ),
            "rigid.crank",
            "principal moments",
        ),
    ];
    for (text, key, what) in cases {
        assert_ne!(text, base);
        let (_d, err) = common::bad_deck(&text, |p| common::with_deck("check", p, &[]));
        assert!(err.contains(key) && err.contains(what), "{err}");
        let line = common::line_of(&text, &format!("[{key}]"));
        assert!(err.contains(&format!(":{line}:")), "{err}");
    }
}

/// `check` refuses what `run` refuses before it integrates: here a design variable that splits
/// a pair of repeated frequencies of a body of which only one is retained (a square cross-ply
/// plate, free-free, whose modes 4 and 5 are equal at the nominal design, four modes kept),
/// found while building the bodies' derivatives.
#[test]
fn check_refuses_the_design_derivatives_run_would_refuse() {
    let text = r#"
[material.ud]
E1 = 128.0e9
E2 = 10.1e9
E3 = 10.1e9
G12 = 5.36e9
G13 = 5.36e9
G23 = 3.0e9
nu12 = 0.23
nu13 = 0.23
nu23 = 0.3
density = 1586.0
[laminate.plate]
plies = [
  { material = "ud", thickness = 1e-3, angle = 0.0 },
  { material = "ud", thickness = 1e-3, angle = 90.0 },
]
[body.p]
kind = "shell"
laminate = "plate"
length = 0.2
width = 0.2
elements = [8, 8]
modes = 4
reference = "free-free"
[design.a]
laminate = "plate"
plies = [0]
[response.d]
kind = "nodal-displacement"
body = "p"
node = 0
component = "uz"
[analysis]
t_end = 0.001
"#;
    let mut messages = Vec::new();
    for command in ["run", "check"] {
        let (_d, err) = bad_deck(text, |p| {
            let mut args = with_deck(command, p, &[]);
            if command == "run" {
                let out = p.with_extension("out");
                args.extend(["-o".into(), out.display().to_string()]);
            }
            args
        });
        assert!(err.contains("key `body.p`"), "{command}: {err}");
        assert!(
            err.contains("splits the repeated frequencies of modes 4, 5, of which only some"),
            "{command}: {err}"
        );
        // the same message, but for the temporary directory
        messages.push(
            err.split_once("bad.toml")
                .map(|(_, m)| m.to_string())
                .unwrap(),
        );
    }
    assert_eq!(messages[0], messages[1]);
}
