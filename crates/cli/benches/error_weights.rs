//! The integrator's error weights on a spatial mechanism (`four_bar_spatial.toml` beside
//! this file, 0.3 s simulated): a uniform `atol` against displacement weights
//! (`analysis.error_weights = "displacement"`, docs/design.md §3). Each setting is run once
//! first and its step count and time printed (the rows of `docs/performance.md`); criterion
//! then samples the displacement weights at 3.9e-9 m.

use std::path::{Path, PathBuf};
use std::time::Instant;

use criterion::{Criterion, criterion_group, criterion_main};
use flexsens::commands::run::{RunRequest, run};

fn deck() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("benches/four_bar_spatial.toml")
}

/// The run's step count (its JSON summary).
fn run_once(sets: &[&str], out: &Path) -> u64 {
    let req = RunRequest {
        out: Some(out),
        json: true,
        progress: false,
    };
    let mut o: Vec<String> = vec!["analysis.t_end=0.3".into()];
    o.extend(sets.iter().map(|s| s.to_string()));
    let json = run(&deck(), &o, &req).expect("the bench deck runs");
    let doc: serde_json::Value = serde_json::from_str(&json).expect("a JSON summary");
    doc["steps"].as_u64().expect("steps")
}

const DISPLACEMENT: &str = "analysis.error_weights=\"displacement\"";
const UNIFORM: &str = "analysis.error_weights=\"uniform\"";

fn error_weights(c: &mut Criterion) {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let out = dir.path();
    for (name, sets) in [
        ("uniform atol = 1e-6", vec![UNIFORM, "analysis.atol=1e-6"]),
        ("uniform atol = 1e-4", vec![UNIFORM, "analysis.atol=1e-4"]),
        (
            "displacement, atol = 3.9e-9 m",
            vec![DISPLACEMENT, "analysis.atol=3.9e-9"],
        ),
        ("displacement, the default", vec![DISPLACEMENT]),
    ] {
        let start = Instant::now();
        let steps = run_once(&sets, out);
        println!(
            "{name}: {steps} steps, {:.2} s",
            start.elapsed().as_secs_f64()
        );
    }
    let mut group = c.benchmark_group("error_weights");
    group.sample_size(10);
    group.bench_function("four_bar_displacement_3.9e-9", |b| {
        b.iter(|| run_once(&[DISPLACEMENT, "analysis.atol=3.9e-9"], out))
    });
    group.finish();
}

criterion_group!(benches, error_weights);
criterion_main!(benches);
