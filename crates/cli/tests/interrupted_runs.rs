//! Faults: a run that is interrupted (Ctrl-C, kill) never leaves a `results.h5` that looks
//! complete — neither its own nor the previous run's — and a later run in the same directory
//! works.

mod common;

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::Duration;

/// Start the paper's beam deck over a span long enough for tens of seconds of work into
/// `out`, let it run for a while, then stop it with `signal` (`KILL` or `INT`); returns whether
/// it was still running when stopped. (The deck's own span takes about a second now: the
/// stop must not race its end.)
fn start_and_stop(out: &Path, signal: &str) -> bool {
    let deck = common::deck("slider_crank_beam.toml");
    let mut child = Command::new(env!("CARGO_BIN_EXE_flexsens"))
        .args([
            "run",
            &deck.display().to_string(),
            "--set",
            "analysis.t_end=2.0",
            "-o",
        ])
        .arg(out)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(1500));
    let running = child.try_wait().unwrap().is_none();
    let sent = Command::new("kill")
        .args([&format!("-{signal}"), &child.id().to_string()])
        .status()
        .is_ok_and(|s| s.success());
    if !sent {
        child.kill().unwrap();
    }
    let status = child.wait().unwrap();
    running && !status.success()
}

/// Whether this process ignores SIGINT (and its children inherit that): bit 1 of the
/// `SigIgn` mask of `/proc/self/status` (Linux; false elsewhere).
fn sigint_ignored() -> bool {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find_map(|l| l.strip_prefix("SigIgn:"))
                .and_then(|m| u64::from_str_radix(m.trim(), 16).ok())
        })
        .is_some_and(|mask| mask & (1 << 1) != 0)
}

#[test]
fn an_interrupted_run_leaves_no_complete_looking_results_and_a_rerun_works() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let rigid = common::deck("slider_crank_rigid.toml");
    let rerun = || {
        common::run(&[
            "run",
            &rigid.display().to_string(),
            "-o",
            &out.display().to_string(),
        ])
    };
    // a complete run first: its results.h5 must not survive an interrupted successor
    let o = rerun();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(out.join("results.h5").exists());
    // A background job of a non-interactive shell starts with SIGINT ignored, and so do the
    // processes it spawns: no Ctrl-C can reach the run there, and SIGTERM (the same polite
    // termination) stands in for it.
    let polite = if sigint_ignored() { "TERM" } else { "INT" };
    for signal in [polite, "KILL"] {
        let stopped = start_and_stop(&out, signal);
        assert!(
            stopped,
            "the run should still have been running when stopped (SIG{signal})"
        );
        assert!(
            !out.join("results.h5").exists(),
            "SIG{signal}: a results.h5 is left that looks complete"
        );
        for f in ["history.csv", "sensitivities.csv", "gradients.csv"] {
            assert!(!out.join(f).exists(), "SIG{signal}: {f} is left behind");
        }
        // the same directory works again, and holds a complete run and no temporary files
        let o = rerun();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        assert!(out.join("results.h5").exists());
        let partial: Vec<_> = std::fs::read_dir(&out)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.contains(".partial-"))
            .collect();
        assert!(partial.is_empty(), "{partial:?}");
    }
}

/// An output directory that cannot be made is a runtime failure (exit 1) naming the path, and
/// nothing is written.
#[test]
fn an_output_directory_that_cannot_be_made_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("a_file");
    std::fs::write(&file, "x").unwrap();
    let out = file.join("out");
    let o = common::run(&[
        "run",
        &common::deck("slider_crank_rigid.toml")
            .display()
            .to_string(),
        "-o",
        &out.display().to_string(),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("cannot create the output directory")
            && err.contains(&out.display().to_string()),
        "{err}"
    );
}
