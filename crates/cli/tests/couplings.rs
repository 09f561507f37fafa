//! Couplings in decks, end to end: a distributing coupling over a single node is that node
//! (its fit reproduces the node's translation and rotation), and so is a rigid one, so joints
//! attached to couplings of the beam deck's end nodes give the run of joints at the nodes,
//! sensitivities included, with the eigenmodes alone and with correction modes at the
//! interfaces, with the beams' geometric stiffening (a force at a coupling is spread over its
//! nodes) and without. Rigid end edges of the plate deck move its peak little from the
//! distributing ones, with sensitivities against replayed central differences.

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
    // a rigid coupling of one node at the node is that node too (its rigid motion is the
    // node's six dof)
    let rigid = coupled
        .replace("nodes = [0] }", "nodes = [0], kind = \"rigid\" }")
        .replace("nodes = [8] }", "nodes = [8], kind = \"rigid\" }");
    assert_eq!(rigid.matches("kind = \"rigid\"").count(), 2);
    for (basis, stiffening, kind) in [
        ("modes", true, "distributing"),
        ("interface", true, "distributing"),
        ("modes", false, "distributing"),
        ("interface", true, "rigid"),
    ] {
        let set = format!("body.rod.basis=\"{basis}\"");
        let stiff = format!("body.rod.stiffening={stiffening}");
        let sets = [set.as_str(), stiff.as_str()];
        let case = format!("{basis}_{stiffening}_{kind}");
        let text = if kind == "rigid" { &rigid } else { &coupled };
        let a = run_text(dir.path(), &format!("nodes_{case}"), &nodes, &sets);
        let b = run_text(dir.path(), &format!("coupled_{case}"), text, &sets);
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

/// The plate deck with rigid (RBE2) end edges: the edges keep their shape, the supports on
/// their nodes leave the rigid motions they allow, and the peak stays within 1 % of the
/// distributing edges' (measured 0.3 %: a rigid edge stiffens only where the joint acts);
/// the objectives' gradients against replayed central differences.
#[test]
fn rigid_end_edges_of_the_plate_deck_have_exact_gradients() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(deck("slider_crank_plate.toml")).unwrap();
    let common_sets = [
        "laminate.plate.plies.0.angle=45",
        "laminate.plate.plies.1.angle=45",
        "laminate.plate.plies.2.angle=45",
        "analysis.t_end=0.03",
    ];
    let rigid_sets: Vec<&str> = common_sets
        .iter()
        .copied()
        .chain([
            "body.rod.couplings.crank_end.kind=\"rigid\"",
            "body.rod.couplings.slider_end.kind=\"rigid\"",
            "finite_differences.enabled=true",
            "finite_differences.scheme=central",
            "finite_differences.sizes=[1e-4]",
        ])
        .collect();
    let g = run_text(dir.path(), "rigid", &text, &rigid_sets);
    let case = "finite_differences/central_relative_0.0001_replay";
    let exact = common::f64s(&g, "objectives/rms_deflection/gradient")[0];
    let fd = common::f64s(&g, &format!("{case}/objectives/rms_deflection"))[0];
    let err = (exact - fd).abs() / exact.abs();
    eprintln!("rigid edges: rms gradient {exact:.4e}, central differences {fd:.4e}: {err:.1e}");
    assert!(err < 1e-4, "{err:e}");
    assert!(exact.abs() > 1e-6, "{exact:e}");
    let worst = common::replayed_difference(&g, "mid_deflection", "0.0001");
    eprintln!("rigid edges: mid_deflection sensitivity against central differences {worst:.1e}");
    assert!(worst < 1e-3, "{worst:e}");
    let distributing = run_text(dir.path(), "distributing", &text, &common_sets);
    let peak = |g: &Group| {
        common::f64s(g, "responses/mid_deflection")
            .iter()
            .fold(0.0f64, |a, x| a.max(x.abs()))
    };
    let (r, d) = (peak(&g), peak(&distributing));
    eprintln!("45°: peak with rigid edges {r:.4e}, distributing {d:.4e}");
    assert!((r - d).abs() < 0.01 * d, "{r:e} {d:e}");
}
