//! The paper decks as users run them (`flexsens run`, the whole command: deck, model build,
//! integration, outputs), analysis alone and with sensitivities (the decks' default method):
//! the rows of `docs/performance.md` for `decks/slider_crank_beam.toml` and
//! `decks/slider_crank_plate.toml`.
//!
//! Before criterion's samples, each deck is run a few times in both settings and the ratio of
//! the best times (sensitivities over analysis) is printed with the step count, so that the
//! ratio rows come from one run on one machine: `cargo bench -p flexsens --bench paper_decks`.
//! Then the beam deck with 8 and 32 design variables (ply angles, ply thicknesses): the cost
//! against the number of variables.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use criterion::{Criterion, criterion_group, criterion_main};
use flexsens::commands::run::{RunRequest, run};

fn deck(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../decks")
        .join(name)
}

/// The overrides of the two settings: no finite-difference check in either, and no
/// sensitivities in the analysis.
fn overrides(sensitivities: bool) -> Vec<String> {
    let mut o = vec!["finite_differences.enabled=false".to_string()];
    if !sensitivities {
        o.push("sensitivity.enabled=false".to_string());
    }
    o
}

fn run_once(deck: &Path, sensitivities: bool, out: &Path) -> String {
    let req = RunRequest {
        out: Some(out),
        json: true,
        progress: false,
    };
    run(deck, &overrides(sensitivities), &req).expect("the shipped deck runs")
}

/// The best of `n` wall times of a run.
fn best_of(n: usize, deck: &Path, sensitivities: bool, out: &Path) -> Duration {
    (0..n)
        .map(|_| {
            let start = Instant::now();
            run_once(deck, sensitivities, out);
            start.elapsed()
        })
        .min()
        .expect("at least one run")
}

fn paper_decks(c: &mut Criterion) {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let out = dir.path();
    let mut group = c.benchmark_group("paper_decks");
    group
        .sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(8));
    for (label, name) in [
        ("beam", "slider_crank_beam.toml"),
        ("plate", "slider_crank_plate.toml"),
    ] {
        let path = deck(name);
        // the step count, from the run's one-line JSON summary
        let summary = run_once(&path, false, out);
        let steps = summary
            .split("\"steps\":")
            .nth(1)
            .and_then(|r| r.split([',', '}']).next())
            .unwrap_or("?")
            .to_string();
        let analysis = best_of(5, &path, false, out);
        let with = best_of(5, &path, true, out);
        eprintln!(
            "{label}: {steps} steps; analysis {:.1} ms, with sensitivities {:.1} ms, ratio {:.2}",
            analysis.as_secs_f64() * 1e3,
            with.as_secs_f64() * 1e3,
            with.as_secs_f64() / analysis.as_secs_f64()
        );
        group.bench_function(format!("{label}_analysis"), |b| {
            b.iter(|| run_once(&path, false, out))
        });
        group.bench_function(format!("{label}_sensitivities"), |b| {
            b.iter(|| run_once(&path, true, out))
        });
    }
    // the cost against the number of variables: the beam deck with `n − 1` more variables,
    // each on one ply of the tube, angles or thicknesses (a thickness moves the section's
    // nodes, whose derivatives take dual passes of its kernel instead of the adjoint)
    let beam = best_of(5, &deck("slider_crank_beam.toml"), false, out);
    for kind in ["ply-angle", "ply-thickness"] {
        for n in [8, 32] {
            let path = out.join(format!("{kind}_{n}.toml"));
            std::fs::write(&path, with_variables(kind, n)).expect("the deck is written");
            let with = best_of(3, &path, true, out);
            eprintln!(
                "beam with {n} variables ({kind}): {:.1} ms, ratio {:.2} (1 + {:.2} N)",
                with.as_secs_f64() * 1e3,
                with.as_secs_f64() / beam.as_secs_f64(),
                (with.as_secs_f64() / beam.as_secs_f64() - 1.0) / n as f64
            );
            if n == 32 {
                group.bench_function(format!("beam_{kind}_32"), |b| {
                    b.iter(|| run_once(&path, true, out))
                });
            }
        }
    }
    group.finish();
}

/// The beam deck with `n − 1` variables of `kind` after its common angle, variable `i` on
/// ply `i mod 4` with the factor `1 + i/100`.
fn with_variables(kind: &str, n: usize) -> String {
    let text = std::fs::read_to_string(deck("slider_crank_beam.toml")).expect("the beam deck");
    let extra: String = (1..n)
        .map(|i| {
            format!(
                "[design.v{i}]\nkind = \"{kind}\"\nlaminate = \"tube_wall\"\nplies = [{}]\n\
                 factors = [{}]\n\n",
                i % 4,
                1.0 + i as f64 / 100.0
            )
        })
        .collect();
    text.replacen(
        "[objective.peak_deflection]",
        &format!("{extra}[objective.peak_deflection]"),
        1,
    )
}

criterion_group!(benches, paper_decks);
criterion_main!(benches);
