//! One simulated second of the flexible slider-crank (crank at 150 rad/s, beam rod reduced to
//! four modes, 1 % modal damping), adaptive BDF at rtol 1e-6; linear floating frame and with
//! geometric stiffening (`cargo bench -p mbs -- stiffening`: the cost of stiffening).

#[path = "../tests/common/mod.rs"]
mod common;

use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use fem::{Mesh, geometric_stiffness};
use mbs::{BdfOptions, Body, FlexibleBody, simulate};
use nalgebra::Vector3;

fn flexible_slider_crank_one_second(c: &mut Criterion) {
    let (model, state, rod) = common::slider_crank(150.0, Some(4));
    // the same rod stiffened: its 10 elements in a line, load cases held at the frame node 5
    let mut stiffened = model.clone();
    if let Body::Flexible(b) = model.body(rod) {
        let mesh =
            Mesh::straight_beam(Vector3::zeros(), Vector3::x(), 10, 0, Vector3::y()).unwrap();
        let g = geometric_stiffness(&mesh, &b.modal, 5).unwrap();
        *stiffened.body_mut(rod) =
            Body::Flexible(FlexibleBody::new("rod", b.modal.clone()).with_geometric_stiffness(g));
    }
    let (sys_stiffened, state_stiffened) = common::assembled(stiffened, state.clone());
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
    group.bench_function("flexible_slider_crank_1s_stiffening", |b| {
        b.iter(|| {
            let mut sys = sys_stiffened.with_model(sys_stiffened.model().clone());
            simulate(
                &mut sys,
                &state_stiffened,
                &t_out,
                BdfOptions::adaptive(1e-6, 1e-8),
            )
            .unwrap()
        })
    });
    group.finish();
}

criterion_group!(benches, flexible_slider_crank_one_second);
criterion_main!(benches);
