//! `modes = "auto"`: the fewest eigenmodes whose basis check meets `basis_tolerance` (a
//! warning below it), used for the nominal run and the finite differences' perturbed runs
//! alike (their sensitivities agree).

mod common;

use common::{deck, run};
use flexsens::results::Group;

#[test]
fn auto_modes_take_the_fewest_that_meet_the_tolerance() {
    let dir = tempfile::tempdir().unwrap();
    // the beam deck's four eigenmodes miss 0.2 % of the largest compliance, eight 0.08 %
    let out = dir.path().join("beam");
    common::run_json(
        "slider_crank_beam.toml",
        &out,
        &[
            "body.rod.modes=\"auto\"",
            "body.rod.basis_tolerance=1e-3",
            "analysis.t_end=0.003",
            "finite_differences.enabled=false",
        ],
    );
    let g = Group::read_hdf5(&out.join("results.h5")).unwrap();
    assert_eq!(common::f64s(&g, "bodies/rod/frequencies").len(), 8);
    let missed = common::f64s(&g, "bodies/rod/basis_missed_compliance");
    let worst = missed.iter().fold(0.0f64, |a, &x| a.max(x));
    assert!(worst <= 1e-3, "{worst:e}");
    // four modes, stated, miss more than that tolerance: a warning at the body's table
    let o = run(&[
        "check",
        deck("slider_crank_beam.toml").to_str().unwrap(),
        "--set",
        "body.rod.basis_tolerance=1e-3",
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(0), "{err}");
    assert!(
        err.contains("warning:") && err.contains("key `body.rod`") && err.contains("4 eigenmodes"),
        "{err}"
    );
    // and the deck's own tolerance (2 %) is met by its four: no warning
    let o = run(&["check", deck("slider_crank_beam.toml").to_str().unwrap()]);
    assert!(!String::from_utf8_lossy(&o.stderr).contains("warning"));
    // on the plate deck (interface basis) the check is met at once: the six modes its damping
    // fit refers to; the replayed central differences rebuild the body with the same six
    let out = dir.path().join("plate");
    common::run_json(
        "slider_crank_plate.toml",
        &out,
        &[
            "body.rod.modes=\"auto\"",
            "analysis.t_end=0.003",
            "sensitivity.method=\"direct\"",
        ],
    );
    let g = Group::read_hdf5(&out.join("results.h5")).unwrap();
    assert_eq!(
        common::f64s(&g, "bodies/rod/frequency_derivatives").len(),
        6
    );
    let err = common::replayed_difference(&g, "mid_deflection", "0.0001");
    eprintln!("plate, auto: sensitivities against central differences {err:.1e}");
    assert!(err < 1e-5, "{err:e}");
}

#[test]
fn auto_modes_and_the_tolerance_are_checked() {
    let text = std::fs::read_to_string(deck("slider_crank_beam.toml")).unwrap();
    for (set, key, what) in [
        (
            "body.rod.basis_tolerance=1.5",
            "body.rod.basis_tolerance",
            "between 0 and 1",
        ),
        ("body.rod.modes=\"many\"", "body.rod.modes", "\"auto\""),
        (
            "body.rod.reference=\"free-free\"",
            "body.rod.modes",
            "not free-free",
        ),
    ] {
        let extra: &[&str] = if set.contains("free-free") {
            &["--set", "body.rod.modes=\"auto\"", "--set", set]
        } else {
            &["--set", set]
        };
        let (_d, err) = common::bad_deck(&text, |p| common::with_deck("check", p, extra));
        assert!(err.contains(key) && err.contains(what), "{set}: {err}");
    }
}
