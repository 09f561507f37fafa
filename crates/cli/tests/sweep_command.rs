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
            "design.theta [deg]",
            "analysis.rtol",
            "status",
            "steps",
            "max_position_violation [m]",
            "peak_deflection [1]",
            "d peak_deflection/d theta [1/deg]",
            "rms_deflection [1]",
            "d rms_deflection/d theta [1/deg]",
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

/// `sweep --shard I/N` run as separate processes (as a batch system's tasks would) and
/// `merge` give the directory a single sweep writes: the same summary, byte for byte, and the
/// same case results. Shards that do not make one whole sweep are refused.
#[test]
fn sharded_sweeps_merge_into_the_single_sweep() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("sweep");
    let single = dir.path().join("single");
    let o = sweep(&out, "2");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    std::fs::rename(&out, &single).unwrap();
    let d = deck("slider_crank_beam.toml").display().to_string();
    let shard_dir = |i: usize| dir.path().join(format!("shard_{i}"));
    let shard = |i: usize, n: usize, rtols: &str| {
        let mut args = vec![
            "sweep".to_string(),
            d.clone(),
            "--vary".into(),
            "design.theta=0:15:15".into(),
            "--vary".into(),
            format!("analysis.rtol={rtols}"),
            "--shard".into(),
            format!("{i}/{n}"),
            "-o".into(),
            shard_dir(i).display().to_string(),
            "--quiet".into(),
        ];
        args.extend(FAST.iter().map(|s| s.to_string()));
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        run(&args)
    };
    for i in 1..=3 {
        let o = shard(i, 3, "1e-5,1e-6");
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    // shard 1 holds cases 1 and 4, shard 2 case 2, shard 3 case 3
    assert!(shard_dir(1).join("case_004").exists() && !shard_dir(1).join("case_002").exists());
    let merge = |dirs: &[usize], to: &std::path::Path| {
        let mut args = vec!["merge".to_string()];
        args.extend(dirs.iter().map(|&i| shard_dir(i).display().to_string()));
        args.extend(["-o".to_string(), to.display().to_string()]);
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        run(&args)
    };
    // incomplete or repeated sets of shards are refused before anything moves
    for (dirs, says) in [
        (&[1, 3][..], "shard 2/3 is missing"),
        (&[1, 2, 2, 3][..], "are both shard 2/3"),
    ] {
        let o = merge(dirs, &out);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(err.contains(says), "{err}");
    }
    let o = merge(&[3, 1, 2], &out);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // the summary names the case directories under the merged directory, as a single sweep
    // names them under its own: compared at the same path, byte for byte
    let merged = std::fs::read(out.join("summary.csv")).unwrap();
    // merging again into the same directory gives the same; into another, whose cases the
    // first merge moved away, is refused naming a case
    let o = merge(&[1, 2, 3], &out);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(std::fs::read(out.join("summary.csv")).unwrap(), merged);
    let o = merge(&[1, 2, 3], &dir.path().join("elsewhere"));
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("case 1 of shard 1/3 ran, but neither"),
        "{err}"
    );
    assert!(!dir.path().join("elsewhere").join("summary.csv").exists());
    std::fs::rename(&out, dir.path().join("merged")).unwrap();
    std::fs::rename(&single, &out).unwrap();
    assert_eq!(
        String::from_utf8(merged).unwrap(),
        std::fs::read_to_string(out.join("summary.csv")).unwrap()
    );
    for case in ["case_001", "case_002", "case_003", "case_004"] {
        assert_eq!(
            std::fs::read(out.join(case).join("history.csv")).unwrap(),
            std::fs::read(dir.path().join("merged").join(case).join("history.csv")).unwrap(),
            "{case}"
        );
    }
    // a shard of another sweep is refused
    let o = shard(2, 3, "1e-5,1e-7");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = shard(1, 3, "1e-5,1e-6");
    assert!(o.status.success());
    let o = shard(3, 3, "1e-5,1e-6");
    assert!(o.status.success());
    let o = merge(&[1, 2, 3], &dir.path().join("mixed"));
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("shards of different runs"), "{err}");
}

#[test]
fn bad_shards_are_refused() {
    let d = deck("slider_crank_rigid.toml").display().to_string();
    for (shard, says) in [
        ("0/3", "expected I/N with 1 ≤ I ≤ N"),
        ("4/3", "expected I/N with 1 ≤ I ≤ N"),
        ("x", "expected I/N"),
        ("5/5", "this shard has none"),
    ] {
        let o = run(&[
            "sweep",
            &d,
            "--vary",
            "rigid.slider.mass=0.05,0.06",
            "--shard",
            shard,
            "-o",
            "/nonexistent/never-written",
        ]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{shard}: {err}");
        assert!(err.contains(says), "{shard}: {err}");
    }
    let dir = tempfile::tempdir().unwrap();
    let o = run(&[
        "merge",
        &dir.path().display().to_string(),
        "-o",
        "/nonexistent",
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("not a shard of a sweep"), "{err}");
}

/// `merge` verifies what it is given: shards run on a deck that changed between them are
/// refused (their manifests fingerprint the deck's text), and a case a shard lists as run
/// whose directory was removed is named (exit 1) before anything moves.
#[test]
fn merge_refuses_changed_decks_and_missing_cases() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("rigid.toml");
    let text = std::fs::read_to_string(deck("slider_crank_rigid.toml")).unwrap();
    std::fs::write(&path, &text).unwrap();
    let shard_dir = |i: usize| dir.path().join(format!("shard_{i}"));
    let shard = |i: usize| {
        let args = [
            "sweep".to_string(),
            path.display().to_string(),
            "--vary".into(),
            "rigid.slider.mass=0.04,0.05".into(),
            "--shard".into(),
            format!("{i}/2"),
            "-o".into(),
            shard_dir(i).display().to_string(),
            "--quiet".into(),
            "--set".into(),
            "analysis.t_end=0.002".into(),
        ];
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = run(&args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    };
    let merge = |to: &std::path::Path| {
        let args = [
            "merge".to_string(),
            shard_dir(1).display().to_string(),
            shard_dir(2).display().to_string(),
            "-o".into(),
            to.display().to_string(),
        ];
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        run(&args)
    };
    shard(1);
    std::fs::write(&path, text.clone() + "# edited between the shards\n").unwrap();
    shard(2);
    let o = merge(&dir.path().join("out"));
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("changed between them"), "{err}");
    std::fs::write(&path, &text).unwrap();
    shard(2);
    std::fs::remove_dir_all(shard_dir(2).join("case_002")).unwrap();
    let o = merge(&dir.path().join("out"));
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("case 2 of shard 2/2 ran, but neither"),
        "{err}"
    );
    // nothing moved
    assert!(shard_dir(1).join("case_001").join("results.h5").exists());
    shard(2);
    let o = merge(&dir.path().join("out"));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}
