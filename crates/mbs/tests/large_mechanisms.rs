//! Mechanisms too large for the dense Eq. (12) and Newton matrix (docs/performance.md): a chain
//! of flexible beams joined by revolute joints, whose Eq. (12) is solved by body blocks and a
//! Schur complement and whose Newton matrix is the sparse system of `mbs::newton`. Checked
//! against the dense path at the same states (solutions, Newton solves, the stability limit's
//! eigenvalues), then over a run: the same history as the dense path, and the energy of an
//! undamped chain conserved.

mod common;

use common::{Beam, assembled, chain};
use mbs::{Bdf, BdfOptions, BodyId, Eq12Factor, MultibodySystem, OdeSystem};
use nalgebra::{Complex, DMatrix, Vector3};
use sens::DenseLu;

/// The chain assembled, then given arbitrary modal coordinates and rates and a swing of the
/// whole chain about the first pin (the identities below hold at any state).
fn chain_state(n: usize) -> (MultibodySystem, Vec<f64>) {
    let (model, mut state) = chain(n, 4, 0.02);
    let l = Beam::slider_crank_rod(6).length;
    for i in 0..n {
        let b = BodyId::from(i);
        let x = (i as f64 + 0.5) * l;
        model.set_velocity(
            &mut state,
            b,
            Vector3::new(0.0, 2.0 * x, 0.0),
            Vector3::new(0.0, 0.0, 2.0),
        );
    }
    let (sys, mut state) = assembled(model, state);
    for i in 0..n {
        let k = i as f64;
        let w = [2e-4 * (k + 1.0).sin(), -1e-4, 5e-5 * k.cos(), 3e-5];
        let wd = [0.3, -0.2 * k.sin(), 0.1, 0.05];
        sys.model().set_modal(&mut state, BodyId::from(i), &w, &wd);
    }
    (sys, state.to_vec())
}

#[test]
fn body_blocks_and_the_schur_complement_give_the_dense_solution_of_eq_12() {
    let (sys, y) = chain_state(12);
    let (q, v) = y.split_at(sys.model().n_q());
    let sol = sys.solve(0.0, q, v).unwrap();
    assert!(
        matches!(sol.lu, Eq12Factor::Bodies(_)),
        "structured above the limit"
    );
    let e = sys.model().equations(0.0, q, v, &sol.rows);
    let lu = DenseLu::new(&e.matrix);
    let mut x = e.rhs.as_slice().to_vec();
    assert!(lu.solve_in_place(&mut x));
    let scale = x.iter().fold(0.0f64, |m, a| m.max(a.abs()));
    for (i, (a, b)) in sol.x.iter().zip(&x).enumerate() {
        assert!((a - b).abs() < 1e-10 * scale, "x[{i}]: {a} vs dense {b}");
    }
    // small mechanisms keep the dense LU
    let (small, y) = chain_state(2);
    let (q, v) = y.split_at(small.model().n_q());
    assert!(matches!(
        small.solve(0.0, q, v).unwrap().lu,
        Eq12Factor::Dense(_)
    ));
}

#[test]
fn the_sparse_newton_system_solves_with_the_dense_newton_matrix() {
    // 90 unknowns in Eq. (12), below the reduced system's limit (factorised dense), and 180,
    // above it (the whole system's sparse LU)
    for links in [6, 12] {
        newton_solves_of(links);
    }
}

fn newton_solves_of(links: usize) {
    let (mut sys, y) = chain_state(links);
    let n = y.len();
    let t = 0.01;
    let mut jac = DMatrix::zeros(n, n);
    sys.jacobian(t, &y, &mut jac).unwrap();
    let structured = sys
        .structured_jacobian(t, &y)
        .expect("a structured Jacobian above the limit")
        .unwrap();
    // c0 of a long and of a short step of order 1
    for c0 in [1e2, 1e6] {
        let mut newton = -jac.clone();
        for i in 0..n {
            newton[(i, i)] += c0;
        }
        let f = structured.factor(c0).expect("nonsingular");
        let r = DMatrix::from_fn(n, 3, |i, k| ((i * 7 + k * 3) as f64).sin());
        let mut x = r.clone();
        f.solve_columns(x.as_mut_slice(), 3);
        let res = &newton * &x - &r;
        let scale = newton.amax() * x.amax();
        assert!(
            res.amax() < 1e-12 * scale,
            "{links} links, c0 = {c0:e}: residual {:e} of scale {scale:e}",
            res.amax()
        );
    }
    // and the dense path is what a system forced dense gives
    sys.set_dense(true);
    assert!(sys.structured_jacobian(t, &y).is_none());
}

/// The oscillatory eigenvalues (`Im λ > |Re λ|`, `Re λ ≤ 0`) of a dense matrix.
fn oscillatory(a: &DMatrix<f64>) -> Vec<Complex<f64>> {
    a.clone()
        .schur()
        .complex_eigenvalues()
        .iter()
        .filter(|l| l.re <= 0.0 && l.im > l.re.abs())
        .copied()
        .collect()
}

#[test]
fn the_stability_limit_watches_the_fastest_modes_of_the_whole_jacobian() {
    let (mut sys, y) = chain_state(12);
    let n = y.len();
    let mut jac = DMatrix::zeros(n, n);
    sys.jacobian(0.0, &y, &mut jac).unwrap();
    let structured = sys.structured_jacobian(0.0, &y).unwrap().unwrap();
    let sorted = |l: &[Complex<f64>]| {
        let mut m: Vec<f64> = l.iter().map(|l| l.norm()).collect();
        m.sort_by(f64::total_cmp);
        m
    };
    let estimate = sorted(&structured.oscillatory_eigenvalues());
    // they approximate the eigenvalues of each body's diagonal block of the dense Jacobian on
    // its modal coordinates and rates (Eq. 12 of the body and its neighbours for the whole
    // mechanism's): within 16 % (measured), 4185 … 34 760 rad/s
    let nq = sys.model().n_q();
    let mut blocks = Vec::new();
    for i in 0..12 {
        let b = BodyId::from(i);
        let qw = sys.model().q_range(b).skip(7);
        let vw = sys.model().v_range(b).skip(6).map(|k| nq + k);
        let idx: Vec<usize> = qw.chain(vw).collect();
        let sub = DMatrix::from_fn(idx.len(), idx.len(), |r, c| jac[(idx[r], idx[c])]);
        blocks.extend(oscillatory(&sub));
    }
    let blocks = sorted(&blocks);
    assert_eq!(estimate.len(), blocks.len());
    for (a, b) in estimate.iter().zip(&blocks) {
        assert!((a - b).abs() < 0.2 * b, "{a} against the dense block's {b}");
    }
    // the fastest of them is the fastest of the whole Jacobian, within 2 % (the spectrum
    // reaches 35 000 rad/s; each body's modes with its frame held, without the joints,
    // only 7 000)
    let exact = sorted(&oscillatory(&jac));
    let (top, top_exact) = (estimate.last().unwrap(), exact.last().unwrap());
    assert!(
        (top - top_exact).abs() < 0.02 * top_exact,
        "largest |λ| {top} against the whole Jacobian's {top_exact}"
    );
    assert!(*top_exact > 30_000.0);
}

/// `(t, y)` at the output times of a run of `sys` from `y0`.
fn run(sys: &mut MultibodySystem, y0: &[f64], t_end: f64, outputs: &[f64]) -> Vec<Vec<f64>> {
    let mut bdf = Bdf::new(BdfOptions::adaptive(1e-7, 1e-10));
    bdf.init(sys, 0.0, y0).unwrap();
    bdf.integrate_to(sys, t_end, outputs, |_| {}).unwrap()
}

#[test]
fn a_chain_runs_as_on_the_dense_path_and_conserves_its_energy_undamped() {
    let (model, state) = chain(8, 4, 0.0);
    let (mut sys, state) = assembled(model, state);
    let y0 = state.to_vec();
    let outputs = [0.05, 0.1];
    let sparse = run(&mut sys, &y0, 0.1, &outputs);
    sys.set_dense(true);
    let dense = run(&mut sys, &y0, 0.1, &outputs);
    let nq = sys.model().n_q();
    // the Newton matrix changes the iterates, not the converged steps: the same step
    // sequence to round-off (2e-11 m measured)
    for (k, (a, b)) in sparse.iter().zip(&dense).enumerate() {
        for i in 0..nq {
            assert!(
                (a[i] - b[i]).abs() < 1e-8,
                "t = {}: q[{i}] {} sparse vs {} dense",
                outputs[k],
                a[i],
                b[i]
            );
        }
    }
    let energy = |y: &[f64]| {
        let (q, v) = y.split_at(nq);
        sys.model().energy(0.0, q, v)
    };
    let e0 = energy(&y0).total();
    for y in &sparse {
        let e = energy(y);
        // against the kinetic energy the chain has gained by then (1e-12 J of 0.056 J
        // measured: the steps resolve the undamped modes)
        assert!(
            (e.total() - e0).abs() < 1e-8 * e.kinetic,
            "energy {} against {e0} (kinetic {})",
            e.total(),
            e.kinetic
        );
    }
}

/// A run recorded within an eighth of its states' memory: each segment's states recomputed
/// from its checkpoint (checkpointed again within half that) are bitwise the stored run's, with the sparse Newton matrix
/// (12 links), the reduced one (6) and the dense one (2), and the samples at output times
/// are bitwise those interpolated in the stored run.
#[test]
fn a_checkpointed_run_recomputes_its_dropped_states_bitwise() {
    use mbs::{StepHistory, simulate_checkpointed, simulate_steps};
    for links in [2, 6, 12] {
        let (model, state) = chain(links, 4, 0.02);
        let (mut sys, state) = assembled(model, state);
        let y0 = state.to_vec();
        let opts = BdfOptions::adaptive(1e-7, 1e-10);
        let t_end = 0.02;
        let stored = simulate_steps(&mut sys, &state, 0.0, t_end, opts.clone()).unwrap();
        let t_out: Vec<f64> = (0..=7).map(|k| t_end * k as f64 / 7.0).collect();
        // an eighth of the states' memory
        let all = 8 * y0.len() * stored.times.len();
        let (mut run, outputs) =
            simulate_checkpointed(&mut sys, &state, (0.0, t_end), opts, &t_out, all / 8).unwrap();
        assert_eq!(run.times, stored.times, "{links} links: the same steps");
        assert_eq!(run.orders, stored.orders);
        assert_eq!(outputs, stored.resample(&t_out).states);
        let points = run.times.len();
        for i in (0..points).rev() {
            run.load(&mut sys, i).unwrap();
            for j in 0..=5.min(i) {
                assert_eq!(
                    run.state(i - j),
                    stored.states[i - j].as_slice(),
                    "{links} links: point {} of {points} from point {i}",
                    i - j
                );
            }
        }
        let memory = run.checkpoint_statistics();
        eprintln!("{links} links: {points} points, {memory:?}, all states {all} B");
        // all but the states the budget kept recomputed, those of the long segments twice
        // (their own runs checkpointed within half the budget)
        assert!(memory.recomputed_steps >= points * 3 / 4, "{memory:?}");
        assert!(memory.recomputed_steps < 3 * points, "{memory:?}");
        // the budget, and the recomputed segments' runs within half of it each level (and
        // a last level's 64 steps)
        assert!(
            memory.peak_bytes < all / 8 * 5 / 2,
            "{memory:?} against {all} B"
        );
    }
}
