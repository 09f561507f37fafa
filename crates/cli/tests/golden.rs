//! Golden-file checks, as users run them in CI: two small shipped decks are run and their
//! `results.h5` compared with the committed reference files by `flexsens compare`.
//!
//! After a deliberate change of results, regenerate the references with
//! `FLEXSENS_BLESS=1 cargo test -p flexsens --test golden` and commit them with the change.

mod common;

use std::path::{Path, PathBuf};

use common::run;

/// Relative tolerance of the comparison: far below any modelling change, above the last-bit
/// differences that vectorised kernels may give on another processor. The runs take fixed
/// steps: an adaptive step sequence can change with the last bits of a Jacobian, and with it
/// the results by the integrator's tolerance.
const RTOL: &str = "1e-7";
/// Absolute tolerance: for values that are zero up to round-off in datasets of a larger
/// scale. A reaction force that vanishes by symmetry comes out as a few ε times the joint's
/// 10–100 N (±1e-14 N, its sign at random), and a change of the LU's operation order moves it
/// by that much; the smallest meaningful values (modal coordinates, 1e-7 and above) are still
/// held to 1e-5 of themselves.
const ATOL: &str = "1e-12";

fn golden(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/golden")
        .join(name)
}

/// The rigid slider-crank's run: a short span on fixed steps.
const RIGID: [&str; 3] = [
    "analysis.t_end=0.02",
    "analysis.integrator=\"fixed\"",
    "analysis.step=1e-4",
];

/// `flexsens compare RESULT REFERENCE` with the golden tolerances.
fn compare(result: &Path, reference: &Path) -> std::process::Output {
    run(&[
        "compare",
        result.to_str().unwrap(),
        reference.to_str().unwrap(),
        "--rtol",
        RTOL,
        "--atol",
        ATOL,
    ])
}

fn check(deck_name: &str, sets: &[&str], golden_name: &str) {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    common::run_json(deck_name, &out, sets);
    let reference = golden(golden_name);
    if std::env::var_os("FLEXSENS_BLESS").is_some() {
        std::fs::copy(out.join("results.h5"), &reference).unwrap();
        return;
    }
    let o = compare(&out.join("results.h5"), &reference);
    assert!(
        o.status.success(),
        "{golden_name} differs from the reference:\n{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
}

#[test]
fn rigid_slider_crank_matches_its_golden_file() {
    check("slider_crank_rigid.toml", &RIGID, "slider_crank_rigid.h5");
}

#[test]
fn beam_slider_crank_with_sensitivities_matches_its_golden_file() {
    check(
        "slider_crank_beam.toml",
        &[
            "analysis.t_end=0.002",
            "analysis.integrator=\"fixed\"",
            "analysis.step=1e-5",
            // the exact derivative of the discrete solution, to round-off: the default
            // (simultaneous) method carries an iteration error of up to its local error
            // tolerance, which moves with the chord iterations' rate estimates
            "sensitivity.method=\"direct\"",
            "finite_differences.scheme=central",
            "finite_differences.sizes=[1e-3]",
        ],
        "slider_crank_beam.h5",
    );
}

/// The check can fail: a changed deck value is caught.
#[test]
fn a_changed_result_fails_the_golden_check() {
    if std::env::var_os("FLEXSENS_BLESS").is_some() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let mut sets = RIGID.to_vec();
    sets.push("rigid.slider.mass=0.0381");
    common::run_json("slider_crank_rigid.toml", &out, &sets);
    let o = compare(&out.join("results.h5"), &golden("slider_crank_rigid.h5"));
    assert_eq!(
        o.status.code(),
        Some(1),
        "{}",
        String::from_utf8_lossy(&o.stdout)
    );
}
