//! `flexsens sweep`: every combination of the varied values runs, one summary row per case,
//! results independent of the number of parallel jobs; bad arguments are rejected before
//! anything runs.

mod common;

use common::{deck, run};

const FAST: [&str; 4] = [
    "--set",
    "analysis.t_end=0.001",
    "--set",
    "finite_differences.enabled=false",
];

fn sweep(out: &std::path::Path, jobs: &str) -> std::process::Output {
    let mut args = vec![
        "sweep",
        deck("slider_crank_beam.toml")
            .to_str()
            .unwrap()
            .to_string()
            .leak(),
        "--vary",
        "design.theta=0:15:15",
        "--vary",
        "analysis.rtol=1e-5,1e-6",
        "-j",
        jobs,
        "-o",
        out.to_str().unwrap().to_string().leak(),
        "--quiet",
    ];
    args.extend(FAST);
    run(&args)
}

fn rows(path: &std::path::Path) -> Vec<Vec<String>> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .map(|l| l.split(',').map(str::to_string).collect())
        .collect()
}

#[test]
fn sweep_runs_every_combination_and_does_not_depend_on_the_job_count() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    for (out, jobs) in [(&a, "1"), (&b, "2")] {
        let o = sweep(out, jobs);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        assert!(
            o.stderr.is_empty(),
            "--quiet: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
    let (ra, rb) = (rows(&a.join("summary.csv")), rows(&b.join("summary.csv")));
    assert_eq!(
        ra[0],
        [
            "case",
            "directory",
            "design.theta",
            "analysis.rtol",
            "status",
            "steps",
            "max_position_violation [m]",
            "peak_deflection",
            "d peak_deflection/d theta",
            "rms_deflection",
            "d rms_deflection/d theta",
            "error"
        ]
    );
    assert_eq!(ra.len(), 5, "a header and four cases");
    // the last --vary changes fastest
    let varied: Vec<(&str, &str)> = ra[1..]
        .iter()
        .map(|r| (r[2].as_str(), r[3].as_str()))
        .collect();
    assert_eq!(
        varied,
        [
            ("0", "0.00001"),
            ("0", "0.000001"),
            ("15", "0.00001"),
            ("15", "0.000001")
        ]
    );
    for (x, y) in ra.iter().zip(&rb).skip(1) {
        assert_eq!(x[4], "ok");
        // everything but the directory is identical, and so are the result files
        assert_eq!(x[2..], y[2..]);
        let case = std::path::Path::new(&x[1]).file_name().unwrap();
        assert_eq!(
            std::fs::read(a.join(case).join("results.h5")).unwrap(),
            std::fs::read(b.join(case).join("results.h5")).unwrap()
        );
    }
    // a 0° lay-up is a symmetry point (θ and −θ give the same deflection): its RMS has a zero
    // gradient, 15° not
    let g0: f64 = ra[1][10].parse().unwrap();
    let g15: f64 = ra[3][10].parse().unwrap();
    assert!(g0.abs() < 1e-12 * g15.abs(), "{g0:e} vs {g15:e}");
    // measured 1.7e-6 over the first millisecond (the rod's deflection is small there)
    assert!(g15.abs() > 1e-7, "{g15:e}");
}

#[test]
fn bad_sweep_arguments_fail_before_anything_runs() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let d = deck("slider_crank_beam.toml");
    for (vary, message) in [
        ("design.thta=0,15", "did you mean `theta`"),
        ("analysis.rtol", "expected KEY=START:STEP:END"),
        ("analysis.rtol=1:0:2", "the step must be non-zero"),
        ("analysis.rtol=1e-6,x", "`x` is not a number"),
        ("analysis.tend=1,2", "did you mean `t_end`"),
        ("laminate.tube_wall.plies.9.angle=1,2", "plies.9"),
    ] {
        let o = run(&[
            "sweep",
            d.to_str().unwrap(),
            "--vary",
            vary,
            "-o",
            out.to_str().unwrap(),
        ]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{vary}: {err}");
        assert!(err.contains(message), "{vary}: {err}");
        assert!(!err.contains("panicked"), "{err}");
        assert!(!out.exists(), "{vary}: nothing is written");
    }
}

#[test]
fn unknown_deck_keys_get_a_did_you_mean() {
    let text = std::fs::read_to_string(deck("slider_crank_beam.toml"))
        .unwrap()
        .replace("rtol = 1.0e-6", "rtoll = 1.0e-6");
    let (_, err) = common::bad_deck(&text, |p| common::with_deck("check", p, &[]));
    assert!(err.contains("unknown field `rtoll`"), "{err}");
    assert!(err.contains("did you mean `rtol`"), "{err}");
}
