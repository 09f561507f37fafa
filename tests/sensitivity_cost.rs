//! Cost of direct sensitivities on the composite-tube slider-crank (0.02 s, rtol 1e-6):
//! (analysis + N direct sensitivities) / analysis for N = 1, 2, 4, 8, 16 design variables
//! (the angles of the first N of 16 plies), for the simultaneous corrector, the staggered
//! corrector and the staggered direct method, forward finite differences (N + 1 analyses) for
//! comparison, and the adjoint method's gradient of one objective (the integral of the rod's
//! mid-node deflection: the analysis recording its steps, the initial sensitivities, the
//! backward sweep). The target of the issue is at most 1 + 0.25 N.
//!
//! Criterion times every case; the table printed after its report comes from paired runs
//! instead (the analysis, then the case, [`PAIRS`] times, the median of the ratios), which
//! holds on a machine whose speed drifts while the benchmark runs. The table is skipped under
//! `cargo test --benches` and when a filter is given.

use std::time::{Duration, Instant};

use criterion::Criterion;
use flexsens_tests::{
    Design, RodOptions, adjoint_integral, assembled, perturbed, slider_crank, slider_crank_design,
};
use mbs::{
    BdfOptions, MultibodySystem, SensitivityOptions, State, simulate_sensitivities, simulate_steps,
};

const T_END: f64 = 0.02;
const PLIES: usize = 16;
const NS: [usize; 5] = [1, 2, 4, 8, 16];
/// Paired runs per cell of the table.
const PAIRS: usize = 15;

fn options() -> BdfOptions {
    BdfOptions::adaptive(1e-6, 1e-9)
}

fn angles() -> Vec<f64> {
    vec![15.0; PLIES]
}

/// The nominal system and its assembled state.
fn nominal() -> (MultibodySystem, State) {
    let (model, state, _) = slider_crank(&angles(), &RodOptions::default());
    assembled(model, state)
}

/// The analysis alone.
fn analysis_case() -> Box<dyn FnMut()> {
    let (mut sys, state) = nominal();
    Box::new(move || {
        let run = simulate_steps(&mut sys, &state, 0.0, T_END, options()).unwrap();
        std::hint::black_box(run.times.len());
    })
}

/// Analysis plus `n` sensitivities with chunks of `W`.
fn sensitivity_case<const W: usize>(n: usize, method: SensitivityOptions) -> Box<dyn FnMut()> {
    let opts = RodOptions::default();
    let (dm, state, _) = slider_crank_design::<W>(&angles(), Design::FirstPlies(n), &opts);
    let (mut sys, state) = assembled(dm.values(), state);
    Box::new(move || {
        let run =
            simulate_sensitivities(&mut sys, &dm, &state, 0.0, T_END, options(), &method).unwrap();
        std::hint::black_box(run.times.len());
    })
}

/// Analysis plus the adjoint gradient of one objective with respect to `n` variables (chunks
/// of `W`, which only the set-up and the initial sensitivities use).
fn adjoint_case<const W: usize>(n: usize) -> Box<dyn FnMut()> {
    let opts = RodOptions::default();
    let (dm, state, ids) = slider_crank_design::<W>(&angles(), Design::FirstPlies(n), &opts);
    let (mut sys, state) = assembled(dm.values(), state);
    let response = ids.mid_deflection();
    Box::new(move || {
        let run = simulate_steps(&mut sys, &state, 0.0, T_END, options()).unwrap();
        let g = adjoint_integral(&mut sys, &dm, (&run, &state), &response);
        std::hint::black_box(g);
    })
}

/// Forward differences: the nominal run and `n` perturbed designs (models prebuilt).
fn forward_fd_case(n: usize) -> Box<dyn FnMut()> {
    let opts = RodOptions::default();
    let (mut nominal, state) = nominal();
    let mut perturbed_systems: Vec<(MultibodySystem, State)> = (0..n)
        .map(|j| {
            let mut a = angles();
            a[j] += 0.15;
            perturbed(&nominal, &state, slider_crank(&a, &opts).0)
        })
        .collect();
    Box::new(move || {
        simulate_steps(&mut nominal, &state, 0.0, T_END, options()).unwrap();
        for (sys, s) in perturbed_systems.iter_mut() {
            simulate_steps(sys, s, 0.0, T_END, options()).unwrap();
        }
    })
}

/// A case of the benchmark: its label and its run.
type Case = (&'static str, Box<dyn FnMut()>);

/// The cases of a row.
fn row(n: usize) -> Vec<Case> {
    let mut out: Vec<Case> = Vec::new();
    for (label, method) in [
        ("simultaneous", SensitivityOptions::simultaneous()),
        ("corrector", SensitivityOptions::corrector()),
        ("direct", SensitivityOptions::default()),
    ] {
        let f = match n {
            1 => sensitivity_case::<1>(n, method),
            2 => sensitivity_case::<2>(n, method),
            4 => sensitivity_case::<4>(n, method),
            _ => sensitivity_case::<8>(n, method),
        };
        out.push((label, f));
    }
    out.push(("forward_fd", forward_fd_case(n)));
    out.push((
        "adjoint",
        match n {
            1 => adjoint_case::<1>(n),
            2 => adjoint_case::<2>(n),
            4 => adjoint_case::<4>(n),
            _ => adjoint_case::<8>(n),
        },
    ));
    out
}

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("slider_crank_sensitivities");
    group.sample_size(10);
    group.warm_up_time(Duration::from_millis(500));
    group.measurement_time(Duration::from_secs(3));
    let mut analysis = analysis_case();
    group.bench_function("analysis", |b| b.iter(&mut analysis));
    for &n in &NS {
        for (label, mut f) in row(n) {
            group.bench_function(format!("{label}_{n}"), |b| b.iter(&mut f));
        }
    }
    group.finish();
}

fn seconds(f: &mut dyn FnMut()) -> f64 {
    let start = Instant::now();
    f();
    start.elapsed().as_secs_f64()
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// The table of the issue from paired runs (see the module docs).
fn paired_table() {
    let mut analysis = analysis_case();
    analysis(); // warm-up
    let mut base = Vec::new();
    println!(
        "\n(analysis + N sensitivities) / analysis, median of {PAIRS} paired runs \
         (t_end = {T_END} s, rtol 1e-6)"
    );
    println!(
        "{:>3} | {:>12} | {:>12} | {:>12} | {:>10} | {:>10} | {:>10}",
        "N", "simultaneous", "corrector", "direct", "forward FD", "adjoint", "1 + 0.25 N"
    );
    for n in NS {
        let cells: Vec<String> = row(n)
            .into_iter()
            .map(|(_, mut f)| {
                f(); // warm-up
                let ratios = (0..PAIRS)
                    .map(|_| {
                        let a = seconds(&mut analysis);
                        base.push(a);
                        seconds(&mut f) / a
                    })
                    .collect();
                format!("{:.2}", median(ratios))
            })
            .collect();
        println!(
            "{n:>3} | {:>12} | {:>12} | {:>12} | {:>10} | {:>10} | {:>10.2}",
            cells[0],
            cells[1],
            cells[2],
            cells[3],
            cells[4],
            1.0 + 0.25 * n as f64
        );
    }
    println!("analysis alone: {:.4} s (median)", median(base));
}

fn main() {
    let dir = std::env::temp_dir().join("flexsens-sensitivity-cost");
    let mut c = Criterion::default()
        .output_directory(&dir)
        .configure_from_args();
    bench(&mut c);
    c.final_summary();
    // `cargo bench` passes `--bench`; a positional argument is a filter
    let args: Vec<String> = std::env::args().skip(1).collect();
    let benching = args.iter().any(|a| a == "--bench");
    let filtered = args.iter().any(|a| !a.starts_with('-'));
    if benching && !filtered {
        paired_table();
    }
}
