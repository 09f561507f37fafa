//! Couplings in decks, end to end: a distributing coupling over a single node is that node
//! (its fit reproduces the node's translation and rotation), so joints attached to couplings of
//! the beam deck's end nodes give the run of joints at the nodes, sensitivities included, with
//! the eigenmodes alone and with correction modes at the interfaces, with the beams' geometric
//! stiffening (a force at a coupling is spread over its nodes) and without.

mod common;

use common::{deck, json};
use flexsens::results::Group;

fn run_text(dir: &std::path::Path, name: &str, text: &str, sets: &[&str]) -> Group {
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, text).unwrap();
    let out = dir.join(name);
    let mut args = vec![
        "run".to_string(),
        path.display().to_string(),
        "-o".into(),
        out.display().to_string(),
        "--json".into(),
        "--set".into(),
        "analysis.t_end=0.01".into(),
        "--set".into(),
        "finite_differences.enabled=false".into(),
    ];
    for s in sets {
        args.extend(["--set".to_string(), s.to_string()]);
    }
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    json(&args);
    Group::read_hdf5(&out.join("results.h5")).unwrap()
}

#[test]
fn joints_on_single_node_couplings_are_joints_at_the_nodes() {
    let dir = tempfile::tempdir().unwrap();
    let nodes = std::fs::read_to_string(deck("slider_crank_beam.toml")).unwrap();
    let coupled = nodes
        .replace(
            "[body.rod]\n",
            "[body.rod.couplings]\ncrank_end = { nodes = [0] }\nslider_end = { nodes = [8] }\n\n[body.rod]\n",
        )
        .replace("node = 0, axis", "coupling = \"crank_end\", axis")
        .replace("node = 8, axis", "coupling = \"slider_end\", axis");
    assert!(
        coupled.contains("coupling = \"crank_end\"")
            && coupled.contains("coupling = \"slider_end\"")
    );
    for (basis, stiffening) in [("modes", true), ("interface", true), ("modes", false)] {
        let set = format!("body.rod.basis=\"{basis}\"");
        let stiff = format!("body.rod.stiffening={stiffening}");
        let sets = [set.as_str(), stiff.as_str()];
        let case = format!("{basis}_{stiffening}");
        let a = run_text(dir.path(), &format!("nodes_{case}"), &nodes, &sets);
        let b = run_text(dir.path(), &format!("coupled_{case}"), &coupled, &sets);
        for path in [
            "responses/mid_deflection",
            "sensitivities/mid_deflection",
            "responses/slider_x",
        ] {
            let (x, y) = (common::f64s(&a, path), common::f64s(&b, path));
            let err = common::worst_difference(&x, &y);
            eprintln!("{case}: {path}: {err:.1e}");
            assert!(err < 1e-8, "{case} {path}: {err:e}");
        }
        // the coupled body has two more (massless) nodes, the same modes
        let (fa, fb) = (
            common::f64s(&a, "bodies/rod/frequencies"),
            common::f64s(&b, "bodies/rod/frequencies"),
        );
        assert_eq!(fa.len(), fb.len());
        assert!(common::worst_difference(&fa, &fb) < 1e-12);
    }
}
