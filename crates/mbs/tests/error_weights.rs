//! The integrator's absolute tolerances per coordinate (`mbs::absolute_tolerances`): each is
//! the amount of its coordinate that moves its body's mass by the displacement tolerance, the
//! displacements computed here node by node; and a run's error falls with the tolerance.

mod common;

use common::{CRANK, ROD, assembled, slider_crank};
use mbs::{BdfOptions, Body, Model, absolute_tolerances, mechanism_size, simulate};
use nalgebra::{SymmetricEigen, Vector3};

/// Root-mean-square displacement over a flexible body's mass (rotary inertia included) of
/// the nodal field `u` (6 per node), from the lumped nodal masses and inertias.
fn rms_displacement(model: &Model<f64>, id: mbs::BodyId, u: &[[f64; 6]]) -> f64 {
    let Body::Flexible(b) = model.body(id) else {
        panic!("a flexible body")
    };
    let m = &b.modal;
    let mut sum = 0.0;
    for ((d, &mk), j) in u.iter().zip(&m.node_masses).zip(&m.node_inertias) {
        sum += mk * (d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
            + j[0] * d[3] * d[3]
            + j[1] * d[4] * d[4]
            + j[2] * d[5] * d[5];
    }
    (sum / m.node_masses.iter().sum::<f64>()).sqrt()
}

#[test]
fn each_coordinate_tolerance_moves_its_body_by_the_displacement_tolerance() {
    let (model, state, _) = slider_crank(150.0, Some(4));
    let n_q = model.n_q();
    let ids: Vec<_> = model.body_ids().collect();
    let delta: Vec<f64> = (0..ids.len()).map(|i| 1e-9 * (1.0 + i as f64)).collect();
    let atol = absolute_tolerances(&model, &state.q, &delta, 7.0);
    assert_eq!(atol.len(), n_q + model.n_v());
    let rod = ids
        .iter()
        .copied()
        .find(|&id| matches!(model.body(id), Body::Flexible(_)))
        .unwrap();
    let Body::Flexible(fb) = model.body(rod) else {
        unreachable!()
    };
    let modal = &fb.modal;
    let lowest = modal.eigenvalues[0].sqrt();
    for &id in &ids {
        let d = delta[id.index()];
        let (q, v) = (model.q_range(id), model.v_range(id));
        let (aq, av) = (&atol[q.clone()], &atol[n_q + v.start..n_q + v.end]);
        assert!(aq[..3].iter().all(|&a| a == d), "translations: {aq:?}");
        // a rotation θ = 2 Δp about the axis of the largest inertia, node by node (flexible)
        // or from the given inertia (rigid)
        let theta = 2.0 * aq[3];
        let moved = match model.body(id) {
            Body::Flexible(b) => {
                let inertia: nalgebra::Matrix3<f64> = b
                    .modal
                    .node_positions
                    .iter()
                    .zip(&b.modal.node_masses)
                    .zip(&b.modal.node_inertias)
                    .map(|((x, &m), j)| {
                        (nalgebra::Matrix3::identity() * x.norm_squared() - x * x.transpose()) * m
                            + nalgebra::Matrix3::from_diagonal(j)
                    })
                    .sum();
                let e = SymmetricEigen::new(inertia);
                let axis: Vector3<f64> = e.eigenvectors.column(e.eigenvalues.imax()).into();
                let u: Vec<[f64; 6]> = b
                    .modal
                    .node_positions
                    .iter()
                    .map(|x| {
                        let t = axis.cross(x) * theta;
                        let r = axis * theta;
                        [t.x, t.y, t.z, r.x, r.y, r.z]
                    })
                    .collect();
                rms_displacement(&model, id, &u)
            }
            Body::Rigid(b) => {
                let largest = SymmetricEigen::new(b.inertia).eigenvalues.max();
                theta * (largest / b.mass).sqrt()
            }
        };
        let rho = d / (theta / 2.0) / 2.0;
        if rho > 1e-3 * mechanism_size(&model, &state.q) {
            assert!(
                (moved / d - 1.0).abs() < 1e-12,
                "rotation moves {moved} for {d}"
            );
        }
        match model.body(id) {
            Body::Flexible(b) => {
                for k in 0..b.modal.n_modes() {
                    let w = aq[7 + k];
                    let u: Vec<[f64; 6]> = (0..b.modal.n_nodes())
                        .map(|n| std::array::from_fn(|i| w * b.modal.modes[(6 * n + i, k)]))
                        .collect();
                    let moved = rms_displacement(&model, id, &u);
                    assert!((moved / d - 1.0).abs() < 1e-12, "mode {k}: {moved} for {d}");
                    let omega = b.modal.eigenvalues[k].sqrt();
                    assert!((av[6 + k] / (w * omega) - 1.0).abs() < 1e-14);
                }
                for i in 0..6 {
                    let pos = if i < 3 { aq[i] } else { 2.0 * aq[3] };
                    assert!((av[i] / (pos * lowest) - 1.0).abs() < 1e-14, "rate {i}");
                }
            }
            // the rigid bodies' rates take the flexible rod's lowest frequency, not `rate`
            Body::Rigid(_) => {
                for i in 0..6 {
                    let pos = if i < 3 { aq[i] } else { 2.0 * aq[3] };
                    assert!((av[i] / (pos * lowest) - 1.0).abs() < 1e-14, "rate {i}");
                }
            }
        }
    }
    assert_eq!(modal.n_modes(), 4);
}

#[test]
fn a_rigid_mechanism_takes_the_given_rate_for_its_velocities() {
    let (model, state, _) = slider_crank(150.0, None);
    let delta = vec![2e-9; model.n_bodies()];
    let atol = absolute_tolerances(&model, &state.q, &delta, 7.0);
    let n_q = model.n_q();
    for id in model.body_ids() {
        let v = model.v_range(id);
        assert_eq!(atol[n_q + v.start], 2e-9 * 7.0);
        let q = model.q_range(id);
        assert!((atol[n_q + v.start + 3] / (2.0 * atol[q.start + 3] * 7.0) - 1.0).abs() < 1e-14);
    }
    // the size: crank and rod along x from the origin to the slider
    let size = mechanism_size(&model, &state.q);
    assert!((size - (CRANK + ROD)).abs() < 1e-9, "size {size}");
}

/// The flexible slider-crank over 0.01 s with the weights from displacement tolerances of
/// 1e-7, 1e-9 and 1e-11 m against 1e-13 m (`rtol = 1e-10`): the rod's modal coordinates'
/// largest error falls with the tolerance.
#[test]
fn the_error_of_a_run_falls_with_the_displacement_tolerance() {
    let (model, state, _) = slider_crank(150.0, Some(4));
    let times: Vec<f64> = (0..=20).map(|i| i as f64 * 5e-4).collect();
    let run = |delta: f64| {
        let (mut sys, s0) = assembled(model.clone(), state.clone());
        let mut options = BdfOptions::adaptive(1e-10, 1.0);
        let d = vec![delta; model.n_bodies()];
        options.atol = absolute_tolerances(sys.model(), &s0.q, &d, 1.0);
        let sim = simulate(&mut sys, &s0, &times, options).unwrap();
        let modal: Vec<Vec<f64>> = sim.outputs.iter().map(|o| o.modal[1].clone()).collect();
        (modal, sim.statistics.steps)
    };
    let (reference, _) = run(1e-13);
    let range = reference
        .iter()
        .flatten()
        .fold(0.0f64, |m, w| m.max(w.abs()));
    assert!(range > 1e-6, "the rod deforms: {range}");
    let mut errors = Vec::new();
    for delta in [1e-7, 1e-9, 1e-11] {
        let (w, steps) = run(delta);
        let err = w
            .iter()
            .flatten()
            .zip(reference.iter().flatten())
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        errors.push((delta, err / range, steps));
    }
    eprintln!("{errors:?}");
    for pair in errors.windows(2) {
        let ((_, e0, s0), (_, e1, s1)) = (pair[0], pair[1]);
        assert!(e1 < 0.2 * e0, "{errors:?}");
        assert!(s1 > s0, "{errors:?}");
    }
    assert!(errors[0].1 > 1e-5 && errors[2].1 < 1e-5, "{errors:?}");
}

/// A mode without stiffness (a rigid-body mode kept by a free body) is weighed at `rate`, not
/// at its zero frequency, and so are its body's frame rates.
#[test]
fn a_mode_without_stiffness_takes_the_given_rate() {
    let (mut model, state, _) = slider_crank(150.0, Some(4));
    let rod = model
        .body_ids()
        .find(|&id| matches!(model.body(id), Body::Flexible(_)))
        .unwrap();
    if let Body::Flexible(b) = model.body_mut(rod) {
        b.modal.eigenvalues[0] = 0.0;
    }
    let atol = absolute_tolerances(&model, &state.q, &vec![1e-9; model.n_bodies()], 7.0);
    let (q, v) = (model.q_range(rod), model.v_range(rod));
    let at = |i: usize| atol[model.n_q() + v.start + i];
    assert!((at(6) / (atol[q.start + 7] * 7.0) - 1.0).abs() < 1e-14);
    assert!((at(0) / (1e-9 * 7.0) - 1.0).abs() < 1e-14);
    assert!(atol.iter().all(|a| a.is_finite() && *a > 0.0));
}
