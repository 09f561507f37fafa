//! One simulated second of the flexible slider-crank (crank at 150 rad/s, beam rod reduced to
//! four modes, 1 % modal damping), adaptive BDF at rtol 1e-6.

#[path = "../tests/common/mod.rs"]
mod common;

use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use mbs::{BdfOptions, simulate};

fn flexible_slider_crank_one_second(c: &mut Criterion) {
    let (model, state, _) = common::slider_crank(150.0, Some(4));
    let (sys, state) = common::assembled(model, state);
    let t_out: Vec<f64> = (0..=1000).map(|i| 1e-3 * i as f64).collect();
    {
        let mut sys = sys.with_model(sys.model().clone());
        let sim = simulate(&mut sys, &state, &t_out, BdfOptions::adaptive(1e-6, 1e-8)).unwrap();
        let last = sim.outputs.last().unwrap();
        eprintln!(
            "flexible slider-crank, 1 s: {:?}; final violation {:e}",
            sim.statistics, last.position_violation
        );
    }
    let mut group = c.benchmark_group("mbs");
    group
        .sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(10));
    group.bench_function("flexible_slider_crank_1s", |b| {
        b.iter(|| {
            let mut sys = sys.with_model(sys.model().clone());
            simulate(&mut sys, &state, &t_out, BdfOptions::adaptive(1e-6, 1e-8)).unwrap()
        })
    });
    group.finish();
}

criterion_group!(benches, flexible_slider_crank_one_second);
criterion_main!(benches);
