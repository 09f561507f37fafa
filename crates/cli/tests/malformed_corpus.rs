//! The malformed-input corpus (`tests/corpus`): decks, mesh files, result files and command
//! lines that are wrong in every way a user or a hostile file can be. Each case must exit with
//! its pinned code (2 bad input, 1 runtime failure) and first line of stderr, which names the
//! file, the item and what is wrong; none may panic, abort, hang or use unbounded memory (each
//! runs under a 4 GiB address-space limit and a time limit).
//!
//! `FLEXSENS_BLESS=1 cargo test -p flexsens --test malformed_corpus` rewrites
//! `tests/corpus/expected.txt` from the current messages; review its diff.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

#[derive(serde::Deserialize)]
struct Cases {
    case: Vec<Case>,
}

#[derive(serde::Deserialize)]
struct Case {
    name: String,
    class: String,
    args: Vec<String>,
}

/// What a case did.
#[derive(Debug, PartialEq)]
struct Outcome {
    exit: String,
    first_line: String,
}

const TIME_LIMIT: Duration = Duration::from_secs(120);

fn corpus() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../tests/corpus")
        .canonicalize()
        .expect("tests/corpus exists")
}

fn canonical(rel: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join(rel)
        .canonicalize()
        .expect("the directory exists")
        .display()
        .to_string()
}

/// Run one case under the memory and time limits.
fn run_case(case: &Case, places: &[(String, &str)]) -> (Outcome, String, String) {
    let tmp = tempfile::tempdir().unwrap();
    let tmp_path = tmp.path().canonicalize().unwrap().display().to_string();
    let mut places: Vec<(String, &str)> = places.to_vec();
    places.push((tmp_path, "{tmp}"));
    let args: Vec<String> = case
        .args
        .iter()
        .map(|a| {
            places
                .iter()
                .fold(a.clone(), |a, (path, name)| a.replace(name, path))
        })
        .collect();
    // a 4 GiB address-space limit: an allocation sized from the input aborts the process
    // instead of exhausting the machine
    let mut child = Command::new("sh")
        .arg("-c")
        .arg("ulimit -v 4194304; exec \"$0\" \"$@\"")
        .arg(env!("CARGO_BIN_EXE_flexsens"))
        .args(&args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("sh runs");
    let start = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break Some(s);
        }
        if start.elapsed() > TIME_LIMIT {
            let _ = child.kill();
            break None;
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    let exit = match status {
        None => "hang".to_string(),
        Some(s) => s
            .code()
            .map_or_else(|| "killed by a signal".to_string(), |c| c.to_string()),
    };
    // the first line of stderr that is not a warning; stdout's for a result without an error
    // (compare's report of differences)
    let first = stderr
        .lines()
        .find(|l| !l.starts_with("warning:"))
        .or_else(|| stdout.lines().next())
        .unwrap_or("");
    let first_line = places
        .iter()
        .fold(first.to_string(), |l, (path, name)| l.replace(path, name));
    (Outcome { exit, first_line }, stdout, stderr)
}

#[test]
fn every_malformed_input_gets_its_pinned_exit_code_and_message() {
    let dir = corpus();
    let cases: Cases =
        toml::from_str(&std::fs::read_to_string(dir.join("cases.toml")).unwrap()).unwrap();
    assert!(
        cases.case.len() >= 60,
        "the corpus has {} cases",
        cases.case.len()
    );
    let places = vec![
        (dir.join("inputs").display().to_string(), "{inputs}"),
        (canonical("../../decks"), "{decks}"),
        (canonical("tests/golden"), "{golden}"),
    ];
    let expected_path = dir.join("expected.txt");
    let expected_text = std::fs::read_to_string(&expected_path).unwrap_or_default();
    let expected: std::collections::BTreeMap<&str, Outcome> = expected_text
        .lines()
        .filter_map(|l| {
            let mut parts = l.splitn(3, '\t');
            Some((
                parts.next()?,
                Outcome {
                    exit: parts.next()?.to_string(),
                    first_line: parts.next()?.to_string(),
                },
            ))
        })
        .collect();
    let bless = std::env::var_os("FLEXSENS_BLESS").is_some();
    let mut blessed = String::new();
    let mut failures = Vec::new();
    let mut classes = std::collections::BTreeSet::new();
    for case in &cases.case {
        classes.insert(case.class.as_str());
        let (got, stdout, stderr) = run_case(case, &places);
        blessed.push_str(&format!(
            "{}\t{}\t{}\n",
            case.name, got.exit, got.first_line
        ));
        // invariants that hold whatever the pinned message says
        if stderr.contains("panicked") || got.exit == "hang" || got.exit.starts_with("killed") {
            failures.push(format!("{}: {} — {stderr}", case.name, got.exit));
            continue;
        }
        if got.exit != "1" && got.exit != "2" {
            failures.push(format!(
                "{}: exit {} (expected 1 or 2)",
                case.name, got.exit
            ));
        }
        if got.exit == "2" && !stdout.is_empty() {
            failures.push(format!(
                "{}: bad input printed to stdout: {stdout}",
                case.name
            ));
        }
        if !bless {
            match expected.get(case.name.as_str()) {
                Some(e) if *e == got => {}
                Some(e) => failures.push(format!(
                    "{}:\n  expected exit {} `{}`\n       got exit {} `{}`",
                    case.name, e.exit, e.first_line, got.exit, got.first_line
                )),
                None => failures.push(format!("{}: nothing pinned in expected.txt", case.name)),
            }
        }
    }
    if bless {
        std::fs::write(&expected_path, blessed).unwrap();
    }
    assert!(
        failures.is_empty(),
        "{} of {} cases failed:\n{}",
        failures.len(),
        cases.case.len(),
        failures.join("\n")
    );
    assert!(classes.len() >= 8, "classes covered: {classes:?}");
}
