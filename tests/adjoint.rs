//! The discrete adjoint (`mbs::adjoint_gradient`) on the paper's slider-crank with a composite
//! tube rod (four ply angles, updated modes): its building blocks against the forward-mode
//! Jacobian and design derivatives, its gradients against the direct method's on the same
//! steps, and against central differences of the discrete solution on replayed steps.

use flexsens_tests::{
    Design, Ids, RodOptions, adjoint_integral, assembled, perturbed, slider_crank,
    slider_crank_design,
};
use mbs::{
    BdfOptions, DesignModel, MultibodySystem, Objective, ObjectiveTerm, OdeSystem, Response,
    SensitivityOptions, SensitivityRun, State, TapedModel, adjoint_gradients, adjoint_sweep,
    contract_data, initial_sensitivities, response_history, response_values, simulate_checkpointed,
    simulate_sensitivities, simulate_steps, tangent_rhs,
};
use nalgebra::DMatrix;

const ANGLES: [f64; 4] = [15.0, -30.0, 45.0, 60.0];
const T_END: f64 = 0.01;

fn options() -> BdfOptions {
    BdfOptions::adaptive(1e-6, 1e-9)
}

fn model() -> (DesignModel<4>, MultibodySystem, State, Ids) {
    let (dm, state, ids) =
        slider_crank_design::<4>(&ANGLES, Design::PerPly, &RodOptions::default());
    let (sys, state) = assembled(dm.values(), state);
    (dm, sys, state, ids)
}

/// Largest absolute difference over the largest magnitude of `reference`.
fn relative(a: &[f64], reference: &[f64]) -> f64 {
    let scale = reference.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let diff = a
        .iter()
        .zip(reference)
        .fold(0.0f64, |m, (x, r)| m.max((x - r).abs()));
    diff / scale
}

#[test]
fn the_pullback_is_the_transposed_jacobian_and_the_data_contraction_is_f_b() {
    let (dm, mut sys, state, _) = model();
    // a deformed, moving state
    let run = simulate_steps(&mut sys, &state, 0.0, 0.004, options()).unwrap();
    let (t, y) = (
        *run.times.last().unwrap(),
        run.states.last().unwrap().clone(),
    );
    let n = y.len();
    let nq = sys.model().n_q();
    let lambda: Vec<f64> = (0..n).map(|i| (1.3 * i as f64 + 0.2).sin()).collect();
    let sol = sys.solve(t, &y[..nq], &y[nq..]).unwrap();

    let taped = TapedModel::new(&dm.chunks()[0]);
    let mut adjoints = taped.adjoints();
    let pulled = taped
        .pullback(&sys, (t, &y), &mut adjoints, &lambda)
        .unwrap();
    let mut jac = DMatrix::zeros(n, n);
    sys.jacobian(t, &y, &mut jac).unwrap();
    let expected: Vec<f64> = (jac.transpose() * nalgebra::DVector::from_column_slice(&lambda))
        .iter()
        .copied()
        .collect();
    let err = relative(&pulled, &expected);
    assert!(err < 1e-11, "f_yᵀ λ off by {err:.2e}");

    // λᵀ f_b from the data's adjoints, against the dual chunks' f_b (S = 0)
    let contracted = contract_data(&dm, &taped.data_adjoints(&adjoints));
    let fb = tangent_rhs(&sys, &dm, t, &y, &sol, &DMatrix::zeros(n, 4));
    let expected: Vec<f64> = (0..4)
        .map(|j| fb.column(j).iter().zip(&lambda).map(|(a, b)| a * b).sum())
        .collect();
    let err = relative(&contracted, &expected);
    assert!(
        err < 1e-11,
        "λᵀ f_b off by {err:.2e}: {contracted:?} vs {expected:?}"
    );
    assert!(expected.iter().all(|g| g.abs() > 0.0));
}

/// An objective of a response's history over a window of it (the whole when `None`).
type Case = (Response, Objective, Option<(f64, f64)>);

/// The objectives checked: kinds, windows and responses (one that reads Eq. 12's multipliers).
fn objectives(ids: &Ids) -> Vec<Case> {
    let reaction = Response::ReactionForce {
        joint: ids.wrist_pin,
        axis: 0,
    };
    let quarter = Response::NodalDisplacement {
        body: ids.rod,
        node: ids.rod_mid / 2,
        dof: 1,
    };
    vec![
        (ids.mid_deflection(), Objective::Integral, None),
        (ids.mid_deflection(), Objective::Max, None),
        (
            ids.mid_deflection(),
            Objective::Ks(2e3),
            Some((0.002, 0.009)),
        ),
        (reaction, Objective::Rms, None),
        (quarter.clone(), Objective::At(0.6 * T_END), None),
        (quarter, Objective::Final, None),
    ]
}

/// The direct method's run (the exact derivative of the discrete solution) and its initial
/// sensitivities.
fn direct_run(dm: &DesignModel<4>, sys: &mut MultibodySystem, state: &State) -> SensitivityRun {
    let opts = SensitivityOptions::default();
    simulate_sensitivities(sys, dm, state, 0.0, T_END, options(), &opts).unwrap()
}

/// A gradient and what it is of.
type Labelled = (String, Vec<f64>);

/// Each objective of [`objectives`] on the points of `run` (a direct method's run): its terms
/// for the adjoint sweep (the samples' weights, which give the objective's value) and, labelled,
/// its gradient by the direct method.
fn terms_and_direct(
    sys: &MultibodySystem,
    dm: &DesignModel<4>,
    run: &SensitivityRun,
    ids: &Ids,
) -> (Vec<Vec<ObjectiveTerm>>, Vec<Labelled>) {
    let mut terms = Vec::new();
    let mut direct = Vec::new();
    for (response, objective, window) in objectives(ids) {
        let h = response_history(sys, dm, run, &response).unwrap();
        let d = (objective.evaluate_in(window, &h.times, &h.values, Some(&h.gradients))).unwrap();
        let weights = objective.weights_in(window, &h.times, &h.values).unwrap();
        assert_eq!(weights.value, d.value);
        terms.push(vec![ObjectiveTerm {
            response: response.clone(),
            times: h.times.clone(),
            weights: weights.weights,
        }]);
        direct.push((format!("{response:?} {objective:?}"), d.gradient));
    }
    (terms, direct)
}

#[test]
fn adjoint_gradients_equal_the_direct_methods_for_every_objective_kind() {
    let (dm, mut sys, state, ids) = model();
    let run = direct_run(&dm, &mut sys, &state);
    let s0 = initial_sensitivities(&sys, &dm, 0.0, &state).unwrap();
    // histories on the recorded points, and on output times between them (interpolated, as
    // `flexsens run` samples them)
    let t_out: Vec<f64> = (0..=40).map(|k| T_END * k as f64 / 40.0).collect();
    for sampled in [run.clone(), run.resample(&t_out)] {
        // every objective in one backward sweep
        let (terms, direct) = terms_and_direct(&sys, &dm, &sampled, &ids);
        let (adjoint, stats) = adjoint_gradients(&mut sys, &dm, &run, &s0, &terms).unwrap();
        assert_eq!(stats.steps, run.times.len() - 1);
        for (a, (label, d)) in adjoint.iter().zip(&direct) {
            let err = relative(a, d);
            assert!(
                err < 1e-8,
                "{label} on {} points: adjoint {a:?} vs direct {d:?} ({err:.2e})",
                sampled.times.len()
            );
        }
    }
}

#[test]
fn adjoint_gradients_equal_central_differences_of_the_discrete_solution() {
    let (dm, mut sys, state, ids) = model();
    let run = simulate_steps(&mut sys, &state, 0.0, T_END, options()).unwrap();
    let response = ids.mid_deflection();
    let adjoint = &adjoint_integral(&mut sys, &dm, (&run, &state), &response);
    // each perturbed design on the nominal run's steps (the discrete solution's derivative)
    let replay = run.replay_options(1e-6, &[1e-9], 1e-7);
    let integral = |angles: &[f64]| {
        let (m, _, _) = slider_crank(angles, &RodOptions::default());
        let (mut s, st) = perturbed(&sys, &state, m);
        let r = simulate_steps(&mut s, &st, 0.0, T_END, replay.clone()).unwrap();
        let v = response_values(&s, &r.times, &r.states, &response).unwrap();
        Objective::Integral
            .evaluate(&r.times, &v, None)
            .unwrap()
            .value
    };
    let h = 0.05;
    for j in 0..4 {
        let (mut plus, mut minus) = (ANGLES, ANGLES);
        plus[j] += h;
        minus[j] -= h;
        let fd = (integral(&plus) - integral(&minus)) / (2.0 * h);
        assert!(
            (adjoint[j] - fd).abs() < 1e-5 * adjoint.iter().fold(0.0f64, |m, g| m.max(g.abs())),
            "ply {j}: adjoint {} vs central difference {fd}",
            adjoint[j]
        );
    }
}

/// The backward sweep over a run kept within an eighth of its states' memory (checkpoints,
/// the states between them recomputed; the peak is that plus the segment being swept, long
/// on a run this short): bitwise the gradients of the sweep over the stored
/// run, for every objective kind, with the samples at the output times bitwise the stored
/// run's.
#[test]
fn a_checkpointed_run_gives_the_stored_runs_gradients_bitwise() {
    let (dm, mut sys, state, ids) = model();
    let stored = simulate_steps(&mut sys, &state, 0.0, T_END, options()).unwrap();
    let t_out: Vec<f64> = (0..=40).map(|k| T_END * k as f64 / 40.0).collect();
    let sampled = stored.resample(&t_out);
    let terms: Vec<Vec<ObjectiveTerm>> = (objectives(&ids).into_iter())
        .map(|(response, objective, window)| {
            let values = response_values(&sys, &t_out, &sampled.states, &response).unwrap();
            let weights = objective.weights_in(window, &t_out, &values).unwrap();
            vec![ObjectiveTerm {
                response,
                times: t_out.clone(),
                weights: weights.weights,
            }]
        })
        .collect();
    let chunk = &dm.chunks()[0];
    let s0 = initial_sensitivities(&sys, &dm, 0.0, &state).unwrap();
    let expected = adjoint_sweep(&mut sys, chunk, &mut &stored, &terms)
        .unwrap()
        .gradients(chunk, &s0);

    let all = 8 * state.to_vec().len() * stored.times.len();
    let (mut run, outputs) =
        simulate_checkpointed(&mut sys, &state, (0.0, T_END), options(), &t_out, all / 8).unwrap();
    assert_eq!(outputs, sampled.states);
    let sweep = adjoint_sweep(&mut sys, chunk, &mut run, &terms).unwrap();
    assert_eq!(sweep.gradients(chunk, &s0), expected);
    let memory = run.checkpoint_statistics();
    assert!(
        memory.recomputed_steps >= stored.times.len() / 2 && memory.peak_bytes < all * 3 / 4,
        "{memory:?} for {} points ({all} B)",
        stored.times.len()
    );
}

/// A start with the rod deformed (modal coordinates and rates given, the rigid coordinates
/// assembled to them): the joints' positions and rates at the start then depend on the
/// mode shapes, so the initial sensitivities' position and velocity parts are not zero, and
/// the sweep takes the initial state's adjoint back through both projections by reverse
/// mode: the gradients equal the direct method's (forward `S_0`) to 1e-9 — the peak's kinds
/// too, whose single sample on this stiff start (steps of a few µs) shows any residual the
/// adjoint's step iterations leave (5–7e-7 when they stopped at 1e-12 of the adjoint).
#[test]
fn the_adjoint_of_a_deformed_start_equals_the_direct_methods() {
    let (dm, state, ids) =
        slider_crank_design::<4>(&ANGLES, Design::PerPly, &RodOptions::default());
    let mut state = state;
    let plain = dm.values();
    plain.set_modal(
        &mut state,
        ids.rod,
        &[2e-4, -1e-4, 5e-5, 2e-5],
        &[0.3, -0.2, 0.1, 0.05],
    );
    let (mut sys, state) = assembled(plain, state);
    let s0 = initial_sensitivities(&sys, &dm, 0.0, &state).unwrap();
    let nq = sys.model().n_q();
    let size = |r: std::ops::Range<usize>| s0.rows(r.start, r.len()).abs().max();
    assert!(
        size(0..nq) > 1e-6 && size(nq..s0.nrows()) > 1e-6,
        "S_0 positions {:e}, velocities {:e}",
        size(0..nq),
        size(nq..s0.nrows())
    );
    let run = direct_run(&dm, &mut sys, &state);
    let (terms, direct) = terms_and_direct(&sys, &dm, &run, &ids);
    let chunk = &dm.chunks()[0];
    let sweep = adjoint_sweep(&mut sys, chunk, &mut &run, &terms).unwrap();
    assert!(!sweep.needs_initial_sensitivities());
    let adjoint = sweep.gradients(chunk, &DMatrix::zeros(s0.nrows(), 4));
    for (a, (label, d)) in adjoint.iter().zip(&direct) {
        let err = relative(a, d);
        assert!(
            err < 1e-9,
            "{label}: adjoint {a:?} vs direct {d:?} ({err:.2e})"
        );
    }
}
