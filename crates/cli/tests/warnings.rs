//! Warnings: legal input that is probably not meant (an angle of more than a full turn, a
//! coarse tube mesh, mesh nodes and regions without elements) is reported on stderr with its
//! place, once, and the command still succeeds.

mod common;

use common::{deck, run};

/// Run `args` (a deck command), expect success; its stderr.
fn warnings_of(args: &[&str]) -> String {
    let o = run(args);
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "{args:?}: {err}");
    err
}

#[test]
fn an_angle_beyond_a_full_turn_and_a_coarse_tube_are_warned_about() {
    let p = deck("section_composite_tube.toml");
    let p = p.to_str().unwrap();
    assert!(!warnings_of(&["section", p]).contains("warning"));
    let text = std::fs::read_to_string(p).unwrap();
    let line = common::line_of(&text, "angle = 15.0");
    let err = warnings_of(&[
        "section",
        p,
        "--set",
        "laminate.tube_wall.plies.0.angle=400",
    ]);
    assert!(
        err.contains(&format!(":{line}:"))
            && err.contains("laminate.tube_wall.plies[0].angle")
            && err.contains("more than a full turn"),
        "{err}"
    );
    assert_eq!(err.matches("warning:").count(), 1, "once: {err}");
    let err = warnings_of(&["section", p, "--set", "section.rod.elements_around=4"]);
    assert!(
        err.contains("section.rod.elements_around") && err.contains("coarse"),
        "{err}"
    );
    // the run command validates the model again for its finite differences: still once
    let beam = deck("slider_crank_beam.toml");
    let dir = tempfile::tempdir().unwrap();
    let err = warnings_of(&[
        "run",
        beam.to_str().unwrap(),
        "-o",
        dir.path().join("out").to_str().unwrap(),
        "-q",
        "--set",
        "analysis.t_end=0.001",
        "--set",
        "laminate.tube_wall.plies.0.angle=375",
    ]);
    assert_eq!(err.matches("warning:").count(), 1, "once: {err}");
}

#[test]
fn unused_mesh_nodes_and_empty_regions_are_warned_about() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = "material al isotropic 70e9 0.3 2700\nregion solid al 0 tangent 0\n\
                region empty al 0 tangent 0\nnode 1 0 0\nnode 2 0.01 0\nnode 3 0 0.01\n\
                node 4 0.005 0\nnode 5 0.005 0.005\nnode 6 0 0.005\nnode 7 0.5 0.5\n\
                element tri6 solid 1 2 3 4 5 6\n";
    std::fs::write(dir.path().join("m.txt"), mesh).unwrap();
    let deck = dir.path().join("d.toml");
    std::fs::write(
        &deck,
        "[section.s]\nshape = \"mesh\"\nfile = \"m.txt\"\nformat = \"simple\"\n",
    )
    .unwrap();
    let err = warnings_of(&["section", deck.to_str().unwrap()]);
    assert!(err.contains("d.toml:3:8: key `section.s.file`"), "{err}");
    assert!(
        err.contains("1 node(s) of the mesh belong to no element"),
        "{err}"
    );
    assert!(err.contains("region `empty` has no elements"), "{err}");
}
