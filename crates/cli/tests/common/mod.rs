//! Helpers shared by the command-line tests.
#![allow(dead_code)] // each test file uses its own subset

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use flexsens::results::{Data, Group};

/// A shipped deck.
pub fn deck(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../decks")
        .join(name)
}

/// Run the binary.
pub fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_flexsens"))
        .args(args)
        .output()
        .expect("flexsens runs")
}

/// Run the binary, expect success, parse its stdout as JSON.
pub fn json(args: &[&str]) -> serde_json::Value {
    let o = run(args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).unwrap()
}

/// The 1-based line of the first occurrence of `needle`.
pub fn line_of(text: &str, needle: &str) -> usize {
    text.lines()
        .position(|l| l.contains(needle))
        .expect("needle in text")
        + 1
}

/// Write `text` as `bad.toml` in a fresh directory, run the binary with `args(deck path)`, and
/// expect bad input: exit code 2, no panic, nothing on stdout. Returns the directory (kept
/// alive for the caller's checks) and stderr.
pub fn bad_deck(text: &str, args: impl Fn(&Path) -> Vec<String>) -> (tempfile::TempDir, String) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.toml");
    std::fs::write(&path, text).unwrap();
    let args = args(&path);
    let o = Command::new(env!("CARGO_BIN_EXE_flexsens"))
        .args(&args)
        .output()
        .expect("flexsens runs");
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(
        o.status.code(),
        Some(2),
        "exit code of {args:?} for:\n{text}\nstderr: {err}"
    );
    assert!(!err.contains("panicked"), "{err}");
    assert!(
        o.stdout.is_empty(),
        "nothing on stdout after an error: {}",
        String::from_utf8_lossy(&o.stdout)
    );
    (dir, err)
}

/// The arguments `[command, deck path, extra…]`.
pub fn with_deck(command: &str, deck: &Path, extra: &[&str]) -> Vec<String> {
    let mut a = vec![command.to_string(), deck.display().to_string()];
    a.extend(extra.iter().map(|s| s.to_string()));
    a
}

/// Whether h5py can be imported; CI must have it (a missing h5py there fails the test instead
/// of skipping it).
pub fn h5py_available() -> bool {
    let ok = Command::new("python3")
        .args(["-c", "import h5py"])
        .status()
        .is_ok_and(|s| s.success());
    if !ok {
        assert!(std::env::var_os("CI").is_none(), "CI must have h5py");
        eprintln!("SKIPPED: h5py not installed");
    }
    ok
}

/// `flexsens run DECK -o OUT --json --set …` (the shipped deck `deck_name`), expecting success;
/// the JSON summary.
pub fn run_json(deck_name: &str, out: &Path, sets: &[&str]) -> serde_json::Value {
    let mut args = vec![
        "run".to_string(),
        deck(deck_name).display().to_string(),
        "-o".into(),
        out.display().to_string(),
        "--json".into(),
    ];
    for s in sets {
        args.extend(["--set".to_string(), s.to_string()]);
    }
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    json(&args)
}

/// A numeric dataset of a result file.
pub fn f64s(g: &Group, path: &str) -> Vec<f64> {
    match &g
        .get(path)
        .unwrap_or_else(|| panic!("no dataset {path}"))
        .data
    {
        Data::F64(v) => v.clone(),
        Data::Text(_) => panic!("{path} is text"),
    }
}
