//! Direct sensitivities of the flexible slider-crank with a composite tube rod (paper §5.1)
//! with respect to ply angles, through the whole chain section → beam modes → multibody
//! dynamics, against central differences.

use fem::ModeUpdate;
use flexsens_tests::{
    Design, Ids, RodOptions, assembled, perturbed, slider_crank, slider_crank_design,
};
use mbs::{
    Bdf, BdfOptions, FdScheme, Objective, Perturbation, Response, SensitivityOptions,
    SensitivityRun, finite_differences, response_history, response_values, simulate_sensitivities,
    simulate_steps,
};

const T_END: f64 = 0.02;
const ANGLE: f64 = 15.0;

/// Direct sensitivities (common angle) on an adaptive run and the response history.
fn direct<const N: usize>(
    angles: &[f64],
    design: Design,
    opts: &RodOptions,
    bdf: BdfOptions,
) -> (mbs::ResponseHistory, SensitivityRun) {
    let (dm, state, ids) = slider_crank_design::<N>(angles, design, opts);
    let (mut sys, state) = assembled(dm.values(), state);
    let run = simulate_sensitivities(
        &mut sys,
        &dm,
        &state,
        0.0,
        T_END,
        bdf,
        &SensitivityOptions::default(),
    )
    .unwrap();
    let h = response_history(&sys, &dm, &run, &ids.mid_deflection()).unwrap();
    (h, run)
}

/// Further responses checked on the replayed steps: the x-component of the wrist-pin reaction
/// on the slider and the transverse nodal displacement (body frame) of the rod's quarter node.
fn more_responses(ids: &Ids) -> [Response; 2] {
    [
        Response::ReactionForce {
            joint: ids.wrist_pin,
            axis: 0,
        },
        Response::NodalDisplacement {
            body: ids.rod,
            node: ids.rod_mid / 2,
            dof: 1,
        },
    ]
}

fn options6() -> BdfOptions {
    BdfOptions::adaptive(1e-6, 1e-9)
}

const OBJECTIVES: [Objective; 5] = [
    Objective::Integral,
    Objective::Rms,
    Objective::Max,
    Objective::Min,
    Objective::At(0.5 * T_END),
];

/// Central differences (common angle) of the mid-node deflection history at `t_out` followed
/// by the [`OBJECTIVES`] of that history, each perturbed design run with `bdf` (replayed or
/// adaptive), for each perturbation `deltas` (degrees).
fn central(
    angle: f64,
    deltas: &[f64],
    opts: &RodOptions,
    t_out: &[f64],
    bdf: &BdfOptions,
) -> Vec<Vec<f64>> {
    let (model, state, ids) = slider_crank(&[angle; 4], opts);
    let (nominal, state) = assembled(model, state);
    let response = ids.mid_deflection();
    let perturbations: Vec<Perturbation> =
        deltas.iter().map(|&d| Perturbation::Absolute(d)).collect();
    let fd = finite_differences(&[angle], FdScheme::Central, &perturbations, |b| {
        let (m, _, _) = slider_crank(&[b[0]; 4], opts);
        let (mut sys, s) = perturbed(&nominal, &state, m);
        let mut bdf = Bdf::new(bdf.clone());
        bdf.init(&mut sys, t_out[0], &s.to_vec())?;
        let ys = bdf.integrate_to(&mut sys, *t_out.last().unwrap(), t_out, |_| {})?;
        let mut out = response_values(&sys, t_out, &ys, &response)?;
        let objectives: Vec<f64> = OBJECTIVES
            .iter()
            .map(|o| o.evaluate(t_out, &out, None).unwrap().value)
            .collect();
        out.extend(objectives);
        for r in more_responses(&ids) {
            out.extend(response_values(&sys, t_out, &ys, &r)?);
        }
        Ok::<_, mbs::SensitivityError>(out)
    })
    .unwrap();
    fd.iter()
        .map(|f| f.derivative.column(0).iter().copied().collect())
        .collect()
}

/// Worst relative difference where `|reference| > 0.1 max |reference|`.
fn worst_relative(a: &[f64], reference: &[f64]) -> f64 {
    let scale = reference.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    a.iter()
        .zip(reference)
        .filter(|(_, r)| r.abs() > 0.1 * scale)
        .map(|(x, r)| (x - r).abs() / r.abs())
        .fold(0.0, f64::max)
}

/// Richardson extrapolation of central differences at `δ` and `δ/2`: removes the `δ²` term.
fn richardson(coarse: &[f64], fine: &[f64]) -> Vec<f64> {
    coarse
        .iter()
        .zip(fine)
        .map(|(c, f)| (4.0 * f - c) / 3.0)
        .collect()
}

fn column(h: &mbs::ResponseHistory, j: usize) -> Vec<f64> {
    h.gradients.column(j).iter().copied().collect()
}

/// The headline check: on the nominal step sequence (replayed), the direct sensitivities of
/// the mid-node deflection history are the derivative of the discrete solution; updated-mode
/// agrees with central differences, fixed-mode does not (the tube's mode shapes depend on the
/// ply angle); the objectives' gradients agree too.
#[test]
fn mid_node_deflection_sensitivity_matches_central_differences_on_the_replayed_steps() {
    let angles = [ANGLE; 4];
    let updated = RodOptions::default();
    let fixed = RodOptions {
        update: ModeUpdate::Fixed,
        ..updated
    };
    // nominal adaptive run: its step sequence is replayed by everything below
    let (h0, run) = direct::<1>(
        &angles,
        Design::Common,
        &updated,
        BdfOptions::adaptive(1e-6, 1e-9),
    );
    // Newton iterations of the replayed runs converged to 1e-7 of the error norm: their
    // remaining iteration error, divided by δ, is the central differences' noise (at 1e-6 it
    // was 6.6e-7 of the mid-node sensitivity after Richardson on one round-off variant of the
    // model and 3.4e-8 on another; at 1e-7 it is 7.8e-9)
    let replay = run.replay_options(1e-6, &[1e-9], 1e-7);
    let (h, _) = direct::<1>(&angles, Design::Common, &updated, replay.clone());
    let (hf, _) = direct::<1>(&angles, Design::Common, &fixed, replay.clone());
    let s = column(&h, 0);
    let sf = column(&hf, 0);
    let max_defl = h.values.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let max_s = s.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    eprintln!(
        "{} steps; max |deflection| {max_defl:.3e}, max |∂/∂θ| {max_s:.3e} per degree; {:?}",
        run.statistics.steps, run.sensitivity_statistics
    );
    // the adaptive nominal run (loose Newton) and its replay (tight Newton) agree closely
    assert!(worst_relative(&column(&h0, 0), &s) < 1e-4);
    // measured 2026-11-21 (planar modes): 1351 steps, max |deflection| 1.261e-3 (1.492e-3 in
    // 743 steps with the former 3-D modes, whose slider rolled freely under `Remove`)
    let n = run.times.len();
    let fd = central(ANGLE, &[2e-3, 1e-3], &updated, &run.times, &replay);
    // wider perturbations for the reaction force (below)
    let fd_wide = central(ANGLE, &[2e-2, 1e-2], &updated, &run.times, &replay);
    let extrapolated_wide = richardson(&fd_wide[0], &fd_wide[1]);
    let extrapolated = richardson(&fd[0], &fd[1]);
    let (plain, rich) = (
        worst_relative(&fd[1][..n], &s),
        worst_relative(&extrapolated[..n], &s),
    );
    let fixed_err = worst_relative(&extrapolated[..n], &sf);
    eprintln!(
        "replayed central differences: δ = 0.001° {plain:.2e}, Richardson (0.002°, 0.001°) \
         {rich:.2e}; fixed-mode vs central differences {fixed_err:.2e}"
    );
    // measured 2026-11-21: plain 1.27e-6 (the δ² truncation of a response whose phase moves
    // with the frequencies), Richardson 7.8e-9 (the issue asks for 1e-6)
    assert!(plain < 3e-6, "{plain:e}");
    assert!(rich < 1e-7, "{rich:e}");
    // measured 2026-11-21: fixed-mode is 8.0 % off
    assert!(fixed_err > 1e-2, "{fixed_err:e}");
    // reaction force and slider position histories
    let (dm, state0, ids) = slider_crank_design::<1>(&angles, Design::Common, &updated);
    let (mut sys, state0) = assembled(dm.values(), state0);
    let run_r = simulate_sensitivities(
        &mut sys,
        &dm,
        &state0,
        0.0,
        T_END,
        replay.clone(),
        &SensitivityOptions::default(),
    )
    .unwrap();
    // The reaction is checked against the wider perturbations (0.02°, 0.01°): multipliers
    // carry the modal stiffness forces λ_k w_k, which amplify the Newton residuals of the
    // perturbed runs, and with the planar modes (modes 3 and 4, second bending of each half at
    // 3056 Hz, λ 28 times that of the first at 582 Hz) this noise dominates at 0.001° (measured 2026-11-21: (0.002°, 0.001°) 1.23e-4 and
    // 4.7e-5, Richardson 8.9e-5; with the Newton tolerance 1e-7 4.8e-5 and 1.2e-4, the finer
    // the worse; 1e-8 fails to converge). At (0.02°, 0.01°) the differences are 2.24e-3 and
    // 5.67e-4 (δ², ratio 3.95) and Richardson leaves 1.5e-5. The nodal displacement keeps
    // (0.002°, 0.001°).
    for (k, (r, bound)) in more_responses(&ids).iter().zip([5e-5, 5e-6]).enumerate() {
        let hr = response_history(&sys, &dm, &run_r, r).unwrap();
        let start = n + OBJECTIVES.len() + k * n;
        let (fd, extrapolated, deltas) = if k == 0 {
            (&fd_wide, &extrapolated_wide, ["0.02", "0.01"])
        } else {
            (&fd, &extrapolated, ["0.002", "0.001"])
        };
        let err = worst_relative(&extrapolated[start..start + n], &column(&hr, 0));
        let e0 = worst_relative(&fd[0][start..start + n], &column(&hr, 0));
        let e1 = worst_relative(&fd[1][start..start + n], &column(&hr, 0));
        eprintln!(
            "{r:?}: worst relative difference {err:.2e} (δ = {}°: {e0:.2e}, {}°: {e1:.2e})",
            deltas[0], deltas[1]
        );
        // measured 2026-11-21: reaction 1.5e-5 (the δ² term is gone, the rest is the
        // differences' noise), nodal displacement 7.4e-9
        assert!(err < bound, "{r:?}: {err:e}");
    }
    // objectives' gradients (Eq. 39) against central differences of the objectives
    for (k, o) in OBJECTIVES.iter().enumerate() {
        let v = h.objective(o).unwrap();
        let reference = extrapolated[n + k];
        let rel = (v.gradient[0] - reference).abs() / reference.abs();
        eprintln!(
            "{o:?}: Ψ = {:.6e} (t = {:?}), dΨ/dθ = {:.6e}, central differences {reference:.6e}, \
             relative difference {rel:.1e}",
            v.value, v.time, v.gradient[0]
        );
        assert!(rel < 1e-6, "{o:?}: {rel:e}");
    }
}

/// Direct sensitivities converge as the tolerances tighten; central differences of independent
/// adaptive runs of perturbed designs do not: truncation at large steps, the runs' own
/// discretisation and step-selection noise at small ones (paper §5, Fig. 6c), documented here
/// by their size.
#[test]
fn direct_sensitivities_converge_and_adaptive_finite_differences_are_noisy() {
    let angles = [ANGLE; 4];
    let opts = RodOptions::default();
    let at_end = |rtol: f64| {
        let (h, run) = direct::<1>(
            &angles,
            Design::Common,
            &opts,
            BdfOptions::adaptive(rtol, rtol * 1e-3),
        );
        (h.gradients[(h.times.len() - 1, 0)], run.statistics.steps)
    };
    let (reference, steps) = at_end(1e-9);
    eprintln!("reference (rtol 1e-9, {steps} steps): ∂ζ(t_end)/∂θ = {reference:.9e}");
    // measured 2026-11-21 (planar modes): rtol 1e-4 1.90e-3 (728 steps), 1e-5 1.84e-3 (903),
    // 1e-6 3.23e-4 (1351), 1e-7 1.69e-5 (1681); before the inertia invariants changed the
    // round-off (and with it the step sequence), 3e-5 2.46e-3, 1e-5 1.99e-3, 3e-6 6.6e-4,
    // 1e-6 2.49e-4 (1383), 3e-7 9.1e-5, 1e-7 1.83e-5, 1e-8 7.1e-8: a plateau at ~2e-3 down
    // to rtol 1e-5, then convergence (the 3-D modes, first bending only, gave 2.65e-3,
    // 6.45e-5, 2.35e-5, 3.77e-6 at rtol 1e-4 … 1e-7). Monotone from rtol 1e-5 on; the plateau
    // is bounded. Measured 2026-11-24 with the stability limit of the order (issue 19):
    // 2.40e-2 (595 steps), 2.71e-3 (802), 6.92e-4 (1143), 3.28e-6 (1411); without it 4.27e-3,
    // 1.61e-3, 2.18e-4, 2.43e-6. The limit damps the unresolved rod modes at loose
    // tolerances (orders ≤ 2 where 3–5 would let them grow): the state keeps its tolerance,
    // the sensitivities, outside the error control by default, lose at rtol 1e-4.
    let mut previous = f64::INFINITY;
    for rtol in [1e-4, 1e-5, 1e-6, 1e-7] {
        let (s, steps) = at_end(rtol);
        let err = (s - reference).abs() / reference.abs();
        eprintln!("rtol {rtol:.0e}: {steps} steps, relative error {err:.2e}");
        if rtol < 1e-5 {
            assert!(err < previous, "no convergence at rtol {rtol:e}");
        }
        if rtol > 1e-6 {
            let bound = if rtol > 1e-5 { 3e-2 } else { 5e-3 };
            assert!(err < bound, "rtol {rtol:e}: {err:e}");
        }
        previous = err;
    }
    assert!(previous < 1e-3, "{previous:e}");
    let (s6, _) = at_end(1e-6);
    let discretisation = (s6 - reference).abs() / reference.abs();
    // the staggered and simultaneous correctors (the integrator's Newton matrix, its
    // tolerance) and the sensitivities in the error control are as accurate at rtol 1e-6 as
    // the staggered direct method (measured 2026-11-21: 3.23e-4)
    let (dm, state, ids) = slider_crank_design::<1>(&angles, Design::Common, &opts);
    let (mut sys, state) = assembled(dm.values(), state);
    for (label, o) in [
        ("corrector", SensitivityOptions::corrector()),
        (
            "corrector, error control",
            SensitivityOptions {
                error_control: true,
                ..SensitivityOptions::corrector()
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
    ] {
        let run =
            simulate_sensitivities(&mut sys, &dm, &state, 0.0, T_END, options6(), &o).unwrap();
        let h = response_history(&sys, &dm, &run, &ids.mid_deflection()).unwrap();
        let err = (h.gradients[(h.times.len() - 1, 0)] - reference).abs() / reference.abs();
        eprintln!(
            "{label}: {} steps ({} rejected), {:?}, relative error {err:.2e}",
            run.statistics.steps, run.statistics.rejected_steps, run.sensitivity_statistics
        );
        // measured 2026-11-21: corrector 3.24e-4 (1351 steps) and 4.0e-5 (1937 steps, 413
        // rejected); simultaneous 3.44e-4 (1351 steps, one dual evaluation per step) and
        // 3.2e-5 (1849 steps, 443 rejected)
        assert!(err < 2.0 * discretisation, "{label}: {err:e}");
    }
    // the simultaneous corrector converges with the tolerance like the direct method
    // (measured 2026-11-21 at rtol 1e-7: 1.56e-5, the direct method's 1.69e-5)
    let run = simulate_sensitivities(
        &mut sys,
        &dm,
        &state,
        0.0,
        T_END,
        BdfOptions::adaptive(1e-7, 1e-10),
        &SensitivityOptions::simultaneous(),
    )
    .unwrap();
    let h = response_history(&sys, &dm, &run, &ids.mid_deflection()).unwrap();
    let err7 = (h.gradients[(h.times.len() - 1, 0)] - reference).abs() / reference.abs();
    eprintln!("simultaneous, rtol 1e-7: relative error {err7:.2e}");
    assert!(err7 < 0.2 * discretisation, "{err7:e}");
    // independent adaptive runs (rtol 1e-6) of the perturbed designs
    let t_out = [0.0, T_END];
    let fd = central(
        ANGLE,
        &[1e-1, 1e-2, 1e-3, 1e-4],
        &opts,
        &t_out,
        &BdfOptions::adaptive(1e-6, 1e-9),
    );
    for (f, delta) in fd.iter().zip(["0.1", "0.01", "0.001", "0.0001"]) {
        let err = (f[1] - reference).abs() / reference.abs();
        eprintln!(
            "adaptive central differences δ = {delta}°: relative error {err:.2e} \
             (direct at the same rtol: {discretisation:.2e})"
        );
    }
    let noise = |f: &Vec<f64>| (f[1] - reference).abs() / reference.abs();
    // measured 2026-11-21 (rtol 1e-6; direct 3.23e-4): δ = 0.1° 4.9e-3, 0.01° 1.7e-4 (by
    // chance; 4.0e-3 on another round-off variant of the model), 0.001° 5.1e-2, 0.0001° 2.2e-1
    // (step-selection noise ∝ 1/δ). Measured 2026-11-25 (direct 6.97e-4), since the rod's
    // repeated pairs get a basis fixed by their span (`fem::eigen::canonical_cluster_bases`):
    // 3.24e-3, 6.67e-4, 2.30e-4, 6.57e-4; with the eigen solver's arbitrary basis in each
    // perturbed design, as before, 3.21e-3, 2.44e-4, 2.36e-3, 5.42e-2. The perturbed runs now
    // see the same modes and mostly choose the same steps, so the noise no longer grows as
    // 1/δ; but no difference step comes near the direct method at a tighter tolerance.
    assert!(
        noise(&fd[0]) > 2.0 * discretisation,
        "truncation at δ = 0.1°"
    );
    let best = fd.iter().map(noise).fold(f64::INFINITY, f64::min);
    assert!(
        best > 10.0 * previous,
        "central differences {best:e}, direct at rtol 1e-7 {previous:e}"
    );
}

/// Many design variables (one per ply) in chunks of 1, 2, 4 and 8: identical sensitivities
/// (measured 2026-11-21: bitwise identical), with the staggered direct method and with the
/// simultaneous corrector (whose Newton right-hand sides are the values of the first chunk's
/// dual evaluation: the state must not change either).
#[test]
fn sensitivities_do_not_depend_on_the_chunk_width() {
    let angles = [10.0, 20.0, 30.0, 40.0];
    let opts = RodOptions::default();
    let t_end = 0.005;
    fn run<const N: usize>(
        angles: &[f64],
        opts: &RodOptions,
        t_end: f64,
        method: &SensitivityOptions,
    ) -> SensitivityRun {
        let (dm, state, _) = slider_crank_design::<N>(angles, Design::PerPly, opts);
        let (mut sys, state) = assembled(dm.values(), state);
        simulate_sensitivities(
            &mut sys,
            &dm,
            &state,
            0.0,
            t_end,
            BdfOptions::adaptive(1e-6, 1e-9),
            method,
        )
        .unwrap()
    }
    for method in [
        SensitivityOptions::default(),
        SensitivityOptions::simultaneous(),
    ] {
        let r1 = run::<1>(&angles, &opts, t_end, &method);
        // and the state is the analysis's, bit for bit (without error control)
        let (dm, state, _) = slider_crank_design::<1>(&angles, Design::PerPly, &opts);
        let (mut sys, state) = assembled(dm.values(), state);
        let plain = simulate_steps(
            &mut sys,
            &state,
            0.0,
            t_end,
            BdfOptions::adaptive(1e-6, 1e-9),
        )
        .unwrap();
        assert_eq!(plain.times, r1.times);
        assert_eq!(plain.states, r1.states);
        let scale = r1
            .sensitivities
            .iter()
            .flat_map(|s| s.iter())
            .fold(0.0f64, |m, x| m.max(x.abs()));
        for (n, r) in [
            (2, run::<2>(&angles, &opts, t_end, &method)),
            (4, run::<4>(&angles, &opts, t_end, &method)),
            (8, run::<8>(&angles, &opts, t_end, &method)),
        ] {
            assert_eq!(
                r.times, r1.times,
                "N = {n}: the state integration must not change"
            );
            assert_eq!(r.states, r1.states, "N = {n}: the states must not change");
            let diff = r
                .sensitivities
                .iter()
                .zip(&r1.sensitivities)
                .map(|(a, b)| (a - b).amax())
                .fold(0.0, f64::max);
            eprintln!(
                "{:?}, N = {n}: max |S_N − S_1| = {diff:.2e} (max |S| = {scale:.2e})",
                method.method
            );
            assert!(diff <= 1e-12 * scale, "N = {n}: {diff:e}");
        }
    }
}

/// `c_0 … c_k` of the variable-step BDF formula `Σ c_j y_{n+1−j} = f(t_{n+1}, y_{n+1})` over
/// `nodes = [t_{n+1}, t_n, …]`: the derivatives at `t_{n+1}` of the Lagrange basis polynomials.
/// Written again here from the definition rather than taken from mbs (whose own is private),
/// so that the check below shares nothing with the integrator's formula.
fn bdf_coefficients(nodes: &[f64]) -> Vec<f64> {
    let t = nodes[0];
    (0..nodes.len())
        .map(|j| {
            let denom: f64 = (0..nodes.len())
                .filter(|&m| m != j)
                .map(|m| nodes[j] - nodes[m])
                .product();
            // d/dt Π_{m≠j} (t − t_m) at t = nodes[0]
            let mut d = 0.0;
            for skip in (0..nodes.len()).filter(|&m| m != j) {
                d += (0..nodes.len())
                    .filter(|&m| m != j && m != skip)
                    .map(|m| t - nodes[m])
                    .product::<f64>();
            }
            d / denom
        })
        .collect()
}

/// Each accepted step's remaining iteration error of a sensitivity run of `method` on the
/// §5.1 slider-crank (5 ms), in the error weights of the corrector (weighted RMS against the
/// last accepted sensitivities), computed independently of the integrator: the residual
/// `f_y S + f_b − c_0 S − ψ` of the step's BDF system by a dual evaluation at the accepted
/// state, through the exact Jacobian there. Also the dual evaluations the run took.
fn step_iteration_errors(method: &SensitivityOptions) -> (Vec<f64>, usize) {
    use mbs::OdeSystem;
    let angles = [ANGLE; 4];
    let (dm, state, _) = slider_crank_design::<1>(&angles, Design::Common, &RodOptions::default());
    let (mut sys, state) = assembled(dm.values(), state);
    let (rtol, atol) = (1e-6, 1e-9);
    let run = simulate_sensitivities(
        &mut sys,
        &dm,
        &state,
        0.0,
        0.005,
        BdfOptions::adaptive(rtol, atol),
        method,
    )
    .unwrap();
    let nq = run.n_q;
    let n = run.states[0].len();
    let errors = (1..run.times.len())
        .map(|i| {
            let k = run.orders[i];
            let nodes: Vec<f64> = (0..=k).map(|j| run.times[i - j]).collect();
            let c = bdf_coefficients(&nodes);
            let mut psi = &run.sensitivities[i - 1] * c[1];
            for (j, cj) in c.iter().enumerate().skip(2) {
                psi += &run.sensitivities[i - j] * *cj;
            }
            let (t, y, s) = (run.times[i], &run.states[i], &run.sensitivities[i]);
            let sol = sys.solve(t, &y[..nq], &y[nq..]).unwrap();
            let residual = mbs::tangent_rhs(&sys, &dm, t, y, &sol, s) - s * c[0] - &psi;
            let mut jac = nalgebra::DMatrix::zeros(n, n);
            sys.jacobian(t, y, &mut jac).unwrap();
            let matrix = nalgebra::DMatrix::identity(n, n) * c[0] - jac;
            let error = matrix.lu().solve(&residual).unwrap();
            let reference = &run.sensitivities[i - 1];
            (error
                .iter()
                .zip(reference.iter())
                .map(|(e, r)| (e / (rtol * r.abs() + atol)).powi(2))
                .sum::<f64>()
                / n as f64)
                .sqrt()
        })
        .collect();
    (errors, run.sensitivity_statistics.dual_evaluations)
}

/// The simultaneous corrector's check of its iteration error, step by step: the sensitivities
/// it accepts solve each step's linear system `(c_0 I − f_y) S = f_b − ψ` to about its
/// tolerance (`mbs::SIMULTANEOUS_TOLERANCE` error weights), measured independently
/// ([`step_iteration_errors`]). The measurement is checked on the direct method, which solves
/// every step's system to 1e-6 of the weights.
///
/// The corrector estimates its error with a carried rate (CVODE's heuristic), so a few steps
/// exceed the tolerance. Measured 2026-11-26 on 361 steps: median 0.075 weights, largest 4.1,
/// 9 steps above 1. With the single update inside the state's Newton iteration alone: median
/// 0.20, largest 14, 61 steps above; with the state's Newton rate as the estimate: largest 13.
/// The direct method: largest 5.6e-7.
#[test]
fn simultaneous_sensitivities_solve_every_step_to_their_tolerance() {
    let (direct, _) = step_iteration_errors(&SensitivityOptions::default());
    let direct_worst = direct.iter().copied().fold(0.0f64, f64::max);
    let (mut errors, dual_evaluations) = step_iteration_errors(&SensitivityOptions::simultaneous());
    let steps = errors.len();
    let worst = errors.iter().copied().fold(0.0f64, f64::max);
    errors.sort_by(f64::total_cmp);
    let above = errors
        .iter()
        .filter(|&&e| e > mbs::SIMULTANEOUS_TOLERANCE)
        .count();
    eprintln!(
        "{steps} steps, {dual_evaluations} dual evaluations: remaining iteration error median \
         {:.2e}, largest {worst:.2e} error weights, {above} steps above the tolerance (direct \
         method: largest {direct_worst:.2e})",
        errors[steps / 2]
    );
    assert!(direct_worst < 1e-5, "{direct_worst:e}");
    assert!(worst < 8.0 * mbs::SIMULTANEOUS_TOLERANCE, "{worst:e}");
    assert!(
        above * 20 <= steps,
        "{above} of {steps} steps above the tolerance"
    );
    assert!(errors[steps / 2] < 0.15 * mbs::SIMULTANEOUS_TOLERANCE);
}
