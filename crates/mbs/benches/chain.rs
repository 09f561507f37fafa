//! Cost against mechanism size: a chain of `N` flexible beams (0.304 m composite tubes, six
//! elements, four modes clamped at the middle node, 2 % modal damping) pinned end to end and
//! to the ground, falling from the horizontal under gravity, one simulated second at rtol 1e-6
//! (`cargo bench -p mbs --bench chain`). Before criterion's samples it prints, for N = 4 … 64,
//! the step count and the CPU seconds of one run, the structured path (body blocks, Schur
//! complement, sparse Newton matrix) and, up to N = 16, the dense one: the growth law of
//! docs/performance.md.

#[path = "../tests/common/mod.rs"]
mod common;

use std::time::{Duration, Instant};

use criterion::{Criterion, criterion_group, criterion_main};
use mbs::{BdfOptions, MultibodySystem, State, simulate};

fn system(n: usize) -> (MultibodySystem, State) {
    let (model, state) = common::chain(n, 4, 0.02);
    common::assembled(model, state)
}

fn one_second(sys: &mut MultibodySystem, state: &State) -> mbs::Simulation {
    let t_out: Vec<f64> = (0..=100).map(|i| 0.01 * i as f64).collect();
    simulate(sys, state, &t_out, BdfOptions::adaptive(1e-6, 1e-8)).unwrap()
}

fn chain(c: &mut Criterion) {
    for n in [4, 8, 16, 32, 64] {
        for dense in [false, true] {
            if dense && n > 16 {
                continue;
            }
            let (mut sys, state) = system(n);
            sys.set_dense(dense);
            let start = Instant::now();
            let sim = one_second(&mut sys, &state);
            let s = start.elapsed().as_secs_f64();
            let st = sim.statistics;
            eprintln!(
                "chain of {n:2} ({} unknowns in Eq. 12), {}: {:.2} s, {} steps, {:.0} µs a step, \
                 {} Jacobians",
                sys.model().n_v() + sys.active_rows().len(),
                if dense { "dense" } else { "structured" },
                s,
                st.steps,
                1e6 * s / st.steps as f64,
                st.jacobians
            );
        }
    }
    let mut group = c.benchmark_group("mbs");
    group
        .sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(20));
    let (sys, state) = system(64);
    group.bench_function("chain_64_flexible_1s", |b| {
        b.iter(|| one_second(&mut sys.with_model(sys.model().clone()), &state))
    });
    group.finish();
}

criterion_group!(benches, chain);
criterion_main!(benches);
