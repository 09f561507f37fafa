//! The adjoint method's cost against the number of design variables: the tailored rod of
//! `decks/optimize_tailored_rod.toml` (one objective, the RMS mid-node deflection over 0.06 s)
//! with its first `N` = 8, 32 and 128 variables (ply angles, then ply thicknesses), and a rod
//! of 38 segments made from it the same way with `N` = 300. Before criterion's samples each
//! case is run a few times and the best time is printed against the analysis alone (the row of
//! `docs/performance.md`), with the peak resident memory of the run (Linux: the high-water mark
//! of a process of its own) against the analysis's; then the rod with `N` = 32 over a run ten
//! times as long, its states kept or checkpointed (`sensitivity.adjoint_memory`):
//! `cargo bench -p flexsens --bench adjoint_cost`.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use criterion::{Criterion, criterion_group};
use flexsens::commands::run::{RunRequest, run};

fn deck() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../decks/optimize_tailored_rod.toml")
}

/// The `[design.*]` tables of a deck, in order, and the deck without them.
fn split_design(text: &str) -> (Vec<String>, String) {
    let mut tables = Vec::new();
    let mut rest = String::new();
    let mut current: Option<String> = None;
    for line in text.lines() {
        if line.starts_with('[') {
            if let Some(t) = current.take() {
                tables.push(t);
            }
            if line.starts_with("[design.") {
                current = Some(String::new());
            }
        }
        match &mut current {
            Some(t) => {
                t.push_str(line);
                t.push('\n');
            }
            None => {
                rest.push_str(line);
                rest.push('\n');
            }
        }
    }
    tables.extend(current);
    (tables, rest)
}

/// The shipped deck with its first `n` design variables only.
fn first_variables(text: &str, n: usize) -> String {
    let (tables, rest) = split_design(text);
    assert!(n <= tables.len(), "the deck has {} variables", tables.len());
    let design: String = tables[..n].iter().map(|t| format!("{t}\n")).collect();
    rest.replacen("[objective.", &format!("{design}[objective."), 1)
}

/// The shipped 16-segment rod rebuilt with `segments` segments of the same four-ply tube (the
/// lay-up graded from 10° to 40°), every ply's angle and thickness a variable.
fn segmented(text: &str, segments: usize) -> String {
    let (_, rest) = split_design(text);
    let start = rest.find("[laminate.wall_00]").expect("the laminates");
    let end = rest.find("[body.rod]").expect("the rod");
    let angle = |s: usize| 10.0 + 30.0 * s as f64 / (segments - 1) as f64;
    let mut parts = String::new();
    for s in 0..segments {
        let ply = format!(
            "  {{ material = \"paper_composite\", thickness = 0.25e-3, angle = {} }},\n",
            angle(s)
        );
        parts += &format!("[laminate.wall_{s:02}]\nplies = [\n{}]\n\n", ply.repeat(4));
        parts += &format!(
            "[section.tube_{s:02}]\nshape = \"tube\"\ninner_radius = 4.529e-3\n\
             laminate = \"wall_{s:02}\"\nelements_per_ply = 1\nelements_around = 32\n\n"
        );
    }
    let mut deck = format!("{}{parts}{}", &rest[..start], &rest[end..]);
    let (a, b) = (
        deck.find("segments = [").expect("segments"),
        deck.find("planar").expect("planar"),
    );
    let length = 0.304 / segments as f64;
    let list: String = (0..segments)
        .map(|s| {
            format!("  {{ section = \"tube_{s:02}\", length = {length:.15}, elements = 1 }},\n")
        })
        .collect();
    deck.replace_range(a..b, &format!("segments = [\n{list}]\n"));
    let deck = deck.replace("node = 16,", &format!("node = {segments},"));
    let mut design = String::new();
    for (kind, prefix) in [("ply-angle", "a"), ("ply-thickness", "t")] {
        for s in 0..segments {
            for p in 0..4 {
                design += &format!(
                    "[design.{prefix}{s:02}_{p}]\nkind = \"{kind}\"\nlaminate = \"wall_{s:02}\"\n\
                     plies = [{p}]\n\n"
                );
            }
        }
    }
    deck.replacen("[objective.", &format!("{design}[objective."), 1)
}

fn run_once(deck: &Path, analysis: bool, out: &Path) {
    let req = RunRequest {
        out: Some(out),
        json: true,
        progress: false,
    };
    let overrides: Vec<String> = if analysis {
        vec!["sensitivity.enabled=false".into()]
    } else {
        Vec::new()
    };
    run(deck, &overrides, &req).expect("the deck runs");
}

/// The peak resident memory of this process, in MiB (Linux; `None` elsewhere).
fn peak_mib() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib / 1024.0)
}

/// The environment variable that makes this program one run of a deck (`deck;analysis` or
/// `deck;adjoint`) that prints its peak memory: a fresh process, so that the peak is the run's.
const CASE: &str = "FLEXSENS_ADJOINT_COST_CASE";

/// The peak memory of a run of `deck` in a process of its own, in MiB.
fn peak_of(deck: &Path, analysis: bool) -> Option<f64> {
    let exe = std::env::current_exe().ok()?;
    let case = format!(
        "{};{}",
        deck.display(),
        if analysis { "analysis" } else { "adjoint" }
    );
    let out = std::process::Command::new(exe)
        .env(CASE, case)
        .output()
        .ok()?;
    String::from_utf8_lossy(&out.stdout).trim().parse().ok()
}

/// The best of `n` wall times of a run.
fn best_of(n: usize, deck: &Path, analysis: bool, out: &Path) -> Duration {
    (0..n)
        .map(|_| {
            let start = Instant::now();
            run_once(deck, analysis, out);
            start.elapsed()
        })
        .min()
        .expect("at least one run")
}

fn adjoint_cost(c: &mut Criterion) {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let out = dir.path();
    let text = std::fs::read_to_string(deck()).expect("the tailored rod deck");
    let mut group = c.benchmark_group("adjoint_cost");
    group
        .sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(10));
    let long = segmented(&text, 38);
    for (label, base, counts) in [
        ("16 segments", &text, &[8, 32, 128][..]),
        ("38 segments", &long, &[300][..]),
    ] {
        let path = out.join("analysis.toml");
        std::fs::write(&path, first_variables(base, 1)).expect("the deck is written");
        let analysis = best_of(5, &path, true, out);
        let memory = peak_of(&path, true);
        let mib = |m: Option<f64>| m.map_or("?".to_string(), |m| format!("{m:.0} MiB"));
        eprintln!(
            "{label}: analysis {:.1} ms, peak {}",
            analysis.as_secs_f64() * 1e3,
            mib(memory)
        );
        for &n in counts {
            let path = out.join(format!("adjoint_{n}.toml"));
            std::fs::write(&path, first_variables(base, n)).expect("the deck is written");
            let with = best_of(3, &path, false, out);
            let peak = peak_of(&path, false);
            eprintln!(
                "  N = {n}: {:.1} ms, {:.2} analyses; peak {}",
                with.as_secs_f64() * 1e3,
                with.as_secs_f64() / analysis.as_secs_f64(),
                mib(peak)
            );
            group.bench_function(format!("adjoint_{n}"), |b| {
                b.iter(|| run_once(&path, false, out))
            });
        }
    }
    long_run(&text, out);
    group.finish();
}

/// The 16-segment rod with `N` = 32 over a run ten times as long (0.6 s): every state kept
/// (the default budget, 16 MiB, holds them) against a budget of 1 MiB (`adjoint_memory`: the
/// states checkpointed and recomputed for the sweep), each against the same run's analysis;
/// printed only (one run each).
fn long_run(text: &str, out: &Path) {
    let deck = first_variables(text, 32).replacen("t_end = 0.06 ", "t_end = 0.6 ", 1);
    assert!(deck.contains("t_end = 0.6 "), "the deck's t_end");
    let mib = |m: Option<f64>| m.map_or("?".to_string(), |m| format!("{m:.0} MiB"));
    let path = out.join("long.toml");
    std::fs::write(&path, &deck).expect("the deck is written");
    let analysis = best_of(1, &path, true, out);
    eprintln!(
        "0.6 s run: analysis {:.1} ms, peak {}",
        analysis.as_secs_f64() * 1e3,
        mib(peak_of(&path, true))
    );
    for (label, budget) in [("16 MiB", None), ("1 MiB", Some(1.0))] {
        let deck = match budget {
            None => deck.clone(),
            Some(m) => deck.replacen(
                "method = \"adjoint\"",
                &format!("method = \"adjoint\"\nadjoint_memory = {m:?}"),
                1,
            ),
        };
        let path = out.join("long_adjoint.toml");
        std::fs::write(&path, deck).expect("the deck is written");
        let with = best_of(1, &path, false, out);
        eprintln!(
            "  N = 32, adjoint_memory {label}: {:.1} ms, {:.2} analyses; peak {}",
            with.as_secs_f64() * 1e3,
            with.as_secs_f64() / analysis.as_secs_f64(),
            mib(peak_of(&path, false))
        );
    }
}

criterion_group!(benches, adjoint_cost);

fn main() {
    if let Ok(case) = std::env::var(CASE) {
        let (deck, kind) = case.rsplit_once(';').expect("deck;kind");
        let dir = tempfile::tempdir().expect("a temporary directory");
        run_once(Path::new(deck), kind == "analysis", dir.path());
        println!("{}", peak_mib().unwrap_or(f64::NAN));
        return;
    }
    benches();
    Criterion::default().configure_from_args().final_summary();
}
