//! A flexible body's mass as a design variable, through the floating-frame equations: the
//! rod of the flexible slider-crank with its density scaled by `s` (masses and rotary
//! inertias `s m`, `s μ`; mass-normalised modes `X/√s`; eigenvalues `λ/s`; modal damping
//! `c/√s` at fixed damping ratios) carries its mass derivatives into every invariant of the
//! mass matrix and the inertia forces. The direct sensitivities of the mid-node deflection
//! against central differences of whole runs on the replayed steps.

use fem::ModalBody;
use flexsens_tests::{RodOptions, assembled, mechanism, perturbed, slider_crank};
use mbs::{
    Bdf, BdfOptions, Body, DesignModel, SensitivityOptions, response_history, response_values,
    simulate_sensitivities,
};
use sens::{Dual, Scalar};

const T_END: f64 = 0.01;

/// The rod of the deck-like slider-crank with its density scaled by `s`.
fn scaled<S: Scalar>(rod: &ModalBody<f64>, s: S) -> ModalBody<S> {
    let root = s.sqrt();
    ModalBody {
        node_positions: rod.node_positions.clone(),
        node_masses: rod.node_masses.iter().map(|&m| s * m).collect(),
        node_inertias: rod
            .node_inertias
            .iter()
            .map(|mu| mu.map(|x| s * x))
            .collect(),
        modes: rod.modes.map(|x| S::from_f64(x) / root),
        eigenvalues: rod
            .eigenvalues
            .iter()
            .map(|&l| S::from_f64(l) / s)
            .collect(),
        modal_damping: rod
            .modal_damping
            .iter()
            .map(|&c| S::from_f64(c) / root)
            .collect(),
        stiffness_matrix: None,
        damping_matrix: None,
    }
}

#[test]
fn rod_density_sensitivities_match_replayed_central_differences() {
    let opts = RodOptions::default();
    let (model, _, ids) = slider_crank(&[15.0; 4], &opts);
    let Body::Flexible(rod) = model.body(ids.rod) else {
        panic!("the rod is flexible")
    };
    let rod = rod.modal.clone();
    // the dual model at s = 1 and its nominal run
    let (dual, state, _) = mechanism(scaled(&rod, Dual::<1>::new(1.0, [1.0])), opts.elements);
    let dm = DesignModel::new(vec![dual], 1).unwrap();
    let (mut sys, state) = assembled(dm.values(), state);
    let run = simulate_sensitivities(
        &mut sys,
        &dm,
        &state,
        0.0,
        T_END,
        BdfOptions::adaptive(1e-6, 1e-9),
        &SensitivityOptions::default(),
    )
    .unwrap();
    let replay = run.replay_options(1e-6, &[1e-9], 1e-7);
    let run = simulate_sensitivities(
        &mut sys,
        &dm,
        &state,
        0.0,
        T_END,
        replay.clone(),
        &SensitivityOptions::default(),
    )
    .unwrap();
    let response = ids.mid_deflection();
    let h = response_history(&sys, &dm, &run, &response).unwrap();
    let direct: Vec<f64> = h.gradients.column(0).iter().copied().collect();
    // central differences of the rod's density on the same steps
    let at = |s: f64| {
        let (m, _, _) = mechanism(scaled(&rod, s), opts.elements);
        let (mut psys, ps) = perturbed(&sys, &state, m);
        let mut bdf = Bdf::new(replay.clone());
        bdf.init(&mut psys, 0.0, &ps.to_vec()).unwrap();
        let ys = bdf
            .integrate_to(&mut psys, T_END, &run.times, |_| {})
            .unwrap();
        response_values(&psys, &run.times, &ys, &response).unwrap()
    };
    let d = 1e-4;
    let (plus, minus) = (at(1.0 + d), at(1.0 - d));
    let scale = direct.iter().fold(0.0f64, |a, x| a.max(x.abs()));
    let err = direct
        .iter()
        .zip(plus.iter().zip(&minus))
        .fold(0.0f64, |a, (x, (p, m))| {
            a.max((x - (p - m) / (2.0 * d)).abs())
        })
        / scale;
    eprintln!("rod density: direct vs central differences {err:.1e} (max {scale:.2e})");
    // the rod's inertia loads its bending: the deflection moves with its density
    let max_defl = h.values.iter().fold(0.0f64, |a, x| a.max(x.abs()));
    assert!(scale > 0.1 * max_defl, "{scale:e} vs {max_defl:e}");
    assert!(err < 1e-5, "{err:e}");
}
