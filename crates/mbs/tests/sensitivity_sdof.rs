//! Direct sensitivities of a single-degree-of-freedom oscillator against the closed form.
//!
//! A flexible body with one node and one mode, its frame fixed to the ground, under a suddenly
//! applied constant force `P` at the node: `ẅ + λ w = φ P`, `w(0) = ẇ(0) = 0`, with the
//! stiffness `λ = k(b) = k₀ eᵇ` a function of the design variable `b` (carried as a dual
//! eigenvalue). The nodal displacement `u = φ w = φ²P/λ (1 − cos √λ t)` and
//! `∂u/∂b = λ ∂u/∂λ`, `∂u/∂λ = φ²P (t sin(√λ t)/(2√λ λ) − (1 − cos √λ t)/λ²)`.
//!
//! Also: the initial sensitivities of Eq. (44) against central differences of the assembly.

use fem::ModalBody;
use mbs::{
    BdfOptions, DesignModel, FlexibleBody, Force, Joint, JointKind, Load, LoadFrame, Marker, Model,
    MultibodySystem, Objective, RedundancyPolicy, Response, SensitivityMethod, SensitivityOptions,
    response_history, simulate_sensitivities,
};
use nalgebra::{DMatrix, Vector3};
use sens::{Dual, Scalar};

const MASS: f64 = 2.0;
const FORCE: f64 = 3.0;
const K0: f64 = 400.0;

fn oscillator<S: Scalar>(lambda: S) -> Model<S> {
    let phi = 1.0 / MASS.sqrt();
    let mut modes = DMatrix::from_element(6, 1, S::zero());
    modes[(1, 0)] = S::from_f64(phi);
    let modal = ModalBody {
        node_positions: vec![Vector3::zeros()],
        node_masses: vec![S::from_f64(MASS)],
        node_inertias: vec![Vector3::from_element(S::from_f64(1e-3))],
        modes,
        eigenvalues: vec![lambda],
        modal_damping: vec![S::zero()],
        stiffness_matrix: None,
        damping_matrix: None,
    };
    let mut model = Model::new();
    let b = model
        .add_flexible_body(FlexibleBody::new("oscillator", modal))
        .unwrap();
    model
        .add_joint(Joint::new(
            "clamp",
            JointKind::Fixed,
            Marker::ground(Vector3::zeros()),
            Marker::on(b, Vector3::zeros()),
        ))
        .unwrap();
    model
        .add_force(Force::PointForce {
            marker: Marker::node(b, 0),
            load: Load::Constant(Vector3::new(0.0, FORCE, 0.0)),
            frame: LoadFrame::Global,
        })
        .unwrap();
    model
}

fn exact(b: f64, t: f64) -> (f64, f64) {
    let lam = K0 * b.exp();
    let w = lam.sqrt();
    let c = FORCE / MASS;
    let u = c / lam * (1.0 - (w * t).cos());
    let du_dlam = c * (t * (w * t).sin() / (2.0 * w * lam) - (1.0 - (w * t).cos()) / (lam * lam));
    (u, du_dlam * lam)
}

/// Every way of integrating the sensitivities, with and without error control.
fn correctors() -> [(&'static str, SensitivityOptions); 5] {
    [
        ("direct", SensitivityOptions::default()),
        (
            "direct, error control",
            SensitivityOptions {
                error_control: true,
                ..SensitivityOptions::default()
            },
        ),
        (
            "corrector",
            SensitivityOptions {
                method: SensitivityMethod::StaggeredCorrector {
                    tol: 1e-3,
                    max_iterations: 8,
                },
                ..SensitivityOptions::default()
            },
        ),
        ("simultaneous", SensitivityOptions::simultaneous()),
        (
            "simultaneous, error control",
            SensitivityOptions {
                error_control: true,
                ..SensitivityOptions::simultaneous()
            },
        ),
    ]
}

#[test]
fn sdof_response_sensitivity_matches_the_closed_form() {
    let b = 0.3;
    let lam = K0 * f64::exp(b);
    let design = DesignModel::new(vec![oscillator(Dual::<1>::new(lam, [lam]))], 1).unwrap();
    let plain = design.values();
    let state = plain.rest_state();
    let body = plain.body_ids().next().unwrap();
    let mut sys = MultibodySystem::new(plain, &state, RedundancyPolicy::Remove).unwrap();
    let response = Response::NodalDisplacement {
        body,
        node: 0,
        dof: 1,
    };
    let t_end = 0.4; // about two periods
    for (label, options) in correctors() {
        let run = simulate_sensitivities(
            &mut sys,
            &design,
            &state,
            0.0,
            t_end,
            BdfOptions::adaptive(1e-11, 1e-14),
            &options,
        )
        .unwrap();
        let h = response_history(&sys, &design, &run, &response).unwrap();
        let scale = h
            .gradients
            .column(0)
            .iter()
            .fold(0.0f64, |m, x| m.max(x.abs()));
        let mut worst_u: f64 = 0.0;
        let mut worst_s: f64 = 0.0;
        for (i, &t) in h.times.iter().enumerate() {
            let (u, du) = exact(b, t);
            worst_u = worst_u.max((h.values[i] - u).abs());
            worst_s = worst_s.max((h.gradients[(i, 0)] - du).abs());
        }
        eprintln!(
            "{label}: {} steps, max |u − exact| {worst_u:.2e}, max |∂u/∂b − exact| {worst_s:.2e} \
             (scale {scale:.3e}); {:?}",
            run.statistics.steps, run.sensitivity_statistics
        );
        assert!(worst_s < 1e-8 * scale.max(1e-300), "{label}: {worst_s:e}");
        // objectives: the maximum's gradient is the sensitivity at its time
        let max = h.objective(&Objective::Max).unwrap();
        let t_max = max.time.unwrap();
        let (_, du) = exact(b, t_max);
        assert!((max.gradient[0] - du).abs() < 1e-7 * scale);
    }
}

/// The sensitivities' error weights follow each variable's scale: the stiffness exponent `b`
/// and the same variable in units `c` times larger (`b' = b/c`, so `∂y/∂b' = c ∂y/∂b`) with
/// the scale `1/c` ([`DesignModel::with_variable_scales`]) are integrated alike, column for
/// column, by every corrector (the simultaneous one with its column-by-column iterations, and
/// each with error control): `∂y/∂b' = c ∂y/∂b` to round-off. With unit scales the large column
/// is held to an absolute tolerance `c` times tighter than the small one and the corrector
/// iterates further for it (the direct method without error control solves each step to
/// round-off whatever the weights).
#[test]
fn sensitivity_error_weights_follow_the_variables_scales() {
    let (b, c) = (0.3, 1.0e4);
    let lam = K0 * f64::exp(b);
    let model = oscillator(Dual::<2>::new(lam, [lam, lam * c]));
    let plain = model.values();
    let state = plain.rest_state();
    let mut sys = MultibodySystem::new(plain, &state, RedundancyPolicy::Remove).unwrap();
    for (label, options) in correctors() {
        let mut run = |scales: Vec<f64>| {
            let design = DesignModel::new(vec![model.clone()], 2)
                .unwrap()
                .with_variable_scales(scales)
                .unwrap();
            simulate_sensitivities(
                &mut sys,
                &design,
                &state,
                0.0,
                0.4,
                BdfOptions::adaptive(1e-5, 1e-8),
                &options,
            )
            .unwrap()
        };
        // the largest |S₁ − c S₀| over the run, relative to the largest |c S₀|
        let mismatch = |r: &mbs::SensitivityRun| {
            let (mut diff, mut size) = (0.0f64, 0.0f64);
            for s in &r.sensitivities {
                for i in 0..s.nrows() {
                    diff = diff.max((s[(i, 1)] - c * s[(i, 0)]).abs());
                    size = size.max((c * s[(i, 0)]).abs());
                }
            }
            diff / size
        };
        let scaled = run(vec![1.0, 1.0 / c]);
        let unit = run(vec![1.0, 1.0]);
        eprintln!(
            "{label}: scaled {:.2e} ({:?}), unit scales {:.2e} ({:?})",
            mismatch(&scaled),
            scaled.sensitivity_statistics,
            mismatch(&unit),
            unit.sensitivity_statistics
        );
        assert!(
            mismatch(&scaled) < 1e-11,
            "{label}: {:e}",
            mismatch(&scaled)
        );
        let (unit_its, scaled_its) = (
            unit.sensitivity_statistics.corrector_iterations,
            scaled.sensitivity_statistics.corrector_iterations,
        );
        if options == SensitivityOptions::default() {
            // solved to round-off, whatever the weights
            assert_eq!(unit_its, scaled_its, "{label}");
        } else {
            assert!(
                unit_its > scaled_its,
                "{label}: unit scales iterate further"
            );
        }
    }
    // a scale must be finite and positive, one per variable
    for bad in [vec![1.0], vec![1.0, 0.0], vec![1.0, f64::NAN]] {
        assert!(
            DesignModel::new(vec![model.clone()], 2)
                .unwrap()
                .with_variable_scales(bad)
                .is_err()
        );
    }
}

/// A free flexible body hanging from a spherical joint at a node whose mode shape depends on
/// the design, deformed and vibrating at the start: the initial sensitivities (Eq. 44) are the
/// derivatives of the assembled state (perturbed designs assembled from the nominal assembled
/// positions and the velocities the nominal assembly was given). The body keeps three rigid
/// rotations free, so the velocity projection's metric and its design dependence matter.
#[test]
fn initial_sensitivities_are_the_derivatives_of_the_assembly() {
    fn body<S: Scalar>(b: S) -> Model<S> {
        let mut modes = DMatrix::from_element(12, 1, S::zero());
        modes[(1, 0)] = b;
        modes[(7, 0)] = b * 2.0;
        modes[(5, 0)] = b * b;
        let modal = ModalBody {
            node_positions: vec![Vector3::new(-0.5, 0.0, 0.0), Vector3::new(0.5, 0.0, 0.0)],
            node_masses: vec![S::one(); 2],
            node_inertias: vec![Vector3::from_element(S::from_f64(1e-3)); 2],
            modes,
            eigenvalues: vec![S::from_f64(100.0)],
            modal_damping: vec![S::zero()],
            stiffness_matrix: None,
            damping_matrix: None,
        };
        let mut model = Model::new();
        let id = model
            .add_flexible_body(FlexibleBody::new("beam", modal))
            .unwrap();
        model
            .add_joint(Joint::new(
                "ball",
                JointKind::Spherical,
                Marker::ground(Vector3::new(-0.5, 0.0, 0.0)),
                Marker::node(id, 0),
            ))
            .unwrap();
        model
    }
    let b = 0.7;
    let design = DesignModel::new(vec![body(Dual::<1>::new(b, [1.0]))], 1).unwrap();
    let plain = design.values();
    let id = plain.body_ids().next().unwrap();
    let mut state = plain.rest_state();
    plain.set_modal(&mut state, id, &[0.05], &[0.3]);
    plain.set_velocity(
        &mut state,
        id,
        Vector3::zeros(),
        Vector3::new(0.0, 0.0, 1.0),
    );
    let guess = state.v.clone();
    let mut sys = MultibodySystem::new(plain, &state, RedundancyPolicy::Remove).unwrap();
    sys.assemble(0.0, &mut state, 1e-14).unwrap();
    let s0 = mbs::initial_sensitivities(&sys, &design, 0.0, &state).unwrap();
    let d = 1e-5;
    let assembled = |bb: f64| {
        let mut p = sys.with_model(body(bb));
        let mut st = state.clone();
        st.v.copy_from_slice(&guess);
        p.assemble(0.0, &mut st, 1e-15).unwrap();
        st.to_vec()
    };
    let (yp, ym) = (assembled(b + d), assembled(b - d));
    let fd: Vec<f64> = yp
        .iter()
        .zip(&ym)
        .map(|(a, c)| (a - c) / (2.0 * d))
        .collect();
    let scale = fd.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let err = fd
        .iter()
        .zip(s0.column(0).iter())
        .fold(0.0f64, |m, (a, c)| m.max((a - c).abs()));
    eprintln!("initial sensitivities: max |S0 − FD| {err:.2e}, max |FD| {scale:.2e}");
    assert!(
        scale > 1e-3,
        "the assembled state must depend on the design"
    );
    assert!(err < 1e-7 * scale, "{err:e}");
}
