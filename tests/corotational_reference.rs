//! Checks of the co-rotational reference solver (`flexsens_tests::corotational`) on its own:
//! closed forms of the linear and the geometrically nonlinear beam, energy conservation, the
//! rigid limit of the slider-crank, and the convergence of the steel slider-crank's answers
//! under refinement of mesh and step.

use flexsens_tests::corotational::{
    Beam, BeamStart, Discretisation, Drive, FarEnd, History, Rod, STEEL_DISCRETISATION,
    SliderCrank, beam, slider_crank, static_beam,
};
use std::f64::consts::PI;

/// Mean period of the mid-deflection, from its upward zero crossings (interpolated linearly
/// between samples).
fn period(history: &History) -> f64 {
    let w = &history.mid_deflection;
    let t = &history.t;
    let crossings: Vec<f64> = (1..w.len())
        .filter(|&i| w[i - 1] < 0.0 && w[i] >= 0.0)
        .map(|i| t[i - 1] + (t[i] - t[i - 1]) * w[i - 1] / (w[i - 1] - w[i]))
        .collect();
    assert!(crossings.len() >= 3, "too few periods: {crossings:?}");
    (crossings[crossings.len() - 1] - crossings[0]) / (crossings.len() - 1) as f64
}

fn largest_abs(values: &[f64]) -> f64 {
    values.iter().fold(0.0, |m, x| m.max(x.abs()))
}

fn largest_difference(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter().zip(b).fold(0.0, |m, (x, y)| m.max((x - y).abs()))
}

/// Factor of the Rayleigh beam's rotary inertia on the first pinned–pinned ω²:
/// 1 / (1 + (I/A)(π/L)²).
fn rotary_factor(rod: &Rod) -> f64 {
    1.0 / (1.0 + rod.second_moment() / rod.area() * (PI / rod.length).powi(2))
}

/// Small free vibration of the pinned–pinned steel rod in its first mode: the period is the
/// Euler–Bernoulli one, 2π L² / (π² √(EI/ρA)), to 0.3 % from 4 elements, and the error (from
/// the Rayleigh beam's, which the model's rotary inertia makes the exact limit) falls as h⁴.
/// Measured (10 µs step): errors from Euler–Bernoulli −0.38 %, −0.013 %, +0.011 % with 2, 4, 8
/// elements; from the Rayleigh beam −0.39 %, −0.025 %, −0.0011 %.
#[test]
fn small_vibration_has_the_pinned_pinned_period() {
    let rod = Rod::STEEL;
    let euler_bernoulli = 2.0 * PI / rod.pinned_frequency();
    let rayleigh = euler_bernoulli / rotary_factor(&rod).sqrt();
    let errors: Vec<(f64, f64)> = [2, 4, 8]
        .iter()
        .map(|&elements| {
            let problem = Beam {
                rod,
                far_end: FarEnd::Pinned,
                start: BeamStart::FirstMode { mid_velocity: 1e-3 },
            };
            let disc = Discretisation {
                elements,
                step: 1e-5,
            };
            let measured = period(&beam(&problem, &disc, 0.04, 1e-5));
            (measured / euler_bernoulli - 1.0, measured / rayleigh - 1.0)
        })
        .collect();
    for &(eb, _) in &errors[1..] {
        assert!(eb.abs() < 3e-3, "{errors:?}");
    }
    assert!(errors[2].1.abs() < 5e-5, "{errors:?}");
    for pair in errors.windows(2) {
        assert!(pair[0].1.abs() > 8.0 * pair[1].1.abs(), "{errors:?}");
    }
}

/// A free rod spun about its pinned end at 50 rad/s for 2.4 turns: no spurious strain from
/// the large rotation. Stiff (E × 1e4): its end follows L (cos ωt, sin ωt) to 1 µm (0.37 µm
/// measured, the integrator's O(h²) phase error), its length holds to 1e-9 m (1.5e-10), its
/// straightness to 1e-11 m (7e-14) and its energy to 1e-6 (2e-7). Steel: the mean stretch is
/// the centrifugal one, ρω²L³/(3E), to 1 % (+0.3 %), at most twice that in the axial
/// oscillation of the sudden start, and the rod stays straight to 3e-8 m (1.3e-8).
#[test]
fn rigid_rotation_strains_nothing() {
    let rate = 50.0;
    let disc = Discretisation {
        elements: 4,
        step: 1e-5,
    };
    let stiff = Rod {
        youngs_modulus: Rod::STEEL.youngs_modulus * 1e4,
        ..Rod::STEEL
    };
    let spin = |rod: Rod| {
        let problem = Beam {
            rod,
            far_end: FarEnd::Free,
            start: BeamStart::Spin { rate },
        };
        beam(&problem, &disc, 0.3, 4e-5)
    };
    let length = stiff.length;
    let history = spin(stiff);
    for (k, &t) in history.t.iter().enumerate() {
        let end = length * (rate * t).cos();
        assert!((history.slider_x[k] - end).abs() < 1e-6, "t = {t}");
        assert!(history.mid_deflection[k].abs() < 1e-11, "t = {t}");
        assert!((history.rod_chord[k] - length).abs() < 1e-9, "t = {t}");
        let energy = history.energy[k] / history.energy[0] - 1.0;
        assert!(energy.abs() < 1e-6, "t = {t}: {energy:e}");
    }

    let steel = Rod::STEEL;
    let stretch = steel.density * rate * rate * length.powi(3) / (3.0 * steel.youngs_modulus);
    let history = spin(steel);
    let stretches: Vec<f64> = history.rod_chord.iter().map(|c| c - length).collect();
    let mean = stretches.iter().sum::<f64>() / stretches.len() as f64;
    assert!(
        (mean / stretch - 1.0).abs() < 0.01,
        "{mean:e} vs {stretch:e}"
    );
    let largest = largest_abs(&stretches);
    assert!(largest < 2.01 * stretch, "{largest:e} vs {stretch:e}");
    assert!(largest_abs(&history.mid_deflection) < 3e-8);
}

/// Pinned–pinned, its far end pulled by P = P_E: ω² = ω₀² (1 + P/P_E) (twice the linear
/// model's ω₀²), to 0.3 % with 16 elements (−0.20 % measured with the rotary-inertia factor;
/// −0.65 % with 8: the co-rotational element's geometric stiffness comes from the chords'
/// rotations alone, so it converges as h²).
#[test]
fn tension_stiffens_the_rod() {
    let rod = Rod::STEEL;
    let expected = 2.0;
    let errors: Vec<f64> = [8, 16]
        .iter()
        .map(|&elements| {
            let problem = Beam {
                rod,
                far_end: FarEnd::OnAxis {
                    mass: 0.0,
                    force: rod.euler_load(),
                },
                start: BeamStart::FirstMode { mid_velocity: 1e-3 },
            };
            let disc = Discretisation {
                elements,
                step: 1e-5,
            };
            let omega = 2.0 * PI / period(&beam(&problem, &disc, 0.03, 1e-5));
            let ratio = (omega / rod.pinned_frequency()).powi(2) / rotary_factor(&rod);
            ratio / expected - 1.0
        })
        .collect();
    assert!(errors[1].abs() < 3e-3, "{errors:?}");
    assert!(errors[0].abs() > 2.5 * errors[1].abs(), "{errors:?}");
}

/// On a roller, under a uniform load q: mid deflection 5qL⁴/(384EI) (to second order) and
/// end-to-end shortening ½∫w′² = ½ (q/(24EI))² L⁷ · 17/35 (zero in a linear model), for a
/// deflection of L/200. Measured shortening errors −0.39 % (16 elements), −0.15 % (32):
/// the local linear element misses the shortening within an element (O(h²)).
#[test]
fn deflection_shortens_the_chord() {
    let rod = Rod::STEEL;
    let bending = rod.youngs_modulus * rod.second_moment();
    let length = rod.length;
    let deflection = length / 200.0;
    let load = deflection * 384.0 * bending / (5.0 * length.powi(4));
    let shortening = 0.5 * (load / (24.0 * bending)).powi(2) * length.powi(7) * 17.0 / 35.0;
    let roller = FarEnd::OnAxis {
        mass: 0.0,
        force: 0.0,
    };
    let errors: Vec<f64> = [(16, 5e-3), (32, 2e-3)]
        .iter()
        .map(|&(elements, tolerance)| {
            let solution = static_beam(&rod, roller, load, elements);
            let w = solution.mid_deflection / deflection - 1.0;
            assert!(w.abs() < 5e-4, "{elements} elements: deflection {w:e}");
            let error = (length - solution.chord) / shortening - 1.0;
            assert!(error.abs() < tolerance, "{elements} elements: {error:e}");
            error
        })
        .collect();
    assert!(errors[0].abs() > 2.5 * errors[1].abs(), "{errors:?}");
}

/// Large free vibration of the rod between a fixed pin and the slider (no drive): the energy
/// is conserved to 1e-6 (3.7e-7 measured, the integrator's dissipation) and the slider moves
/// in by the foreshortening π² a² / (4L) of the first mode (−0.5 % measured, 8 elements).
#[test]
fn free_vibration_conserves_energy() {
    let rod = Rod::STEEL;
    let problem = Beam {
        rod,
        far_end: FarEnd::OnAxis {
            mass: 0.038,
            force: 0.0,
        },
        start: BeamStart::FirstMode { mid_velocity: 2.0 },
    };
    let disc = Discretisation {
        elements: 8,
        step: 1e-5,
    };
    let history = beam(&problem, &disc, 0.1, 1e-5);
    let initial = history.energy[0];
    let drift = largest_abs(
        &history
            .energy
            .iter()
            .map(|e| e / initial - 1.0)
            .collect::<Vec<_>>(),
    );
    assert!(drift < 1e-6, "{drift:e}");
    let amplitude = largest_abs(&history.mid_deflection);
    assert!(amplitude > 2e-3, "{amplitude:e}");
    let foreshortening = PI * PI * amplitude * amplitude / (4.0 * rod.length);
    let pulled_in = rod.length
        - history
            .slider_x
            .iter()
            .fold(f64::INFINITY, |m, &x| m.min(x));
    assert!(
        (pulled_in / foreshortening - 1.0).abs() < 0.02,
        "{pulled_in:e} vs {foreshortening:e}"
    );
}

/// The steel slider-crank at [`STEEL_DISCRETISATION`] against twice the elements at half the
/// step: peak |mid-deflection| within 0.1 % of the peak, histories within 0.2 % of the peak,
/// slider within 1 µm; returns the history at the default discretisation.
fn assert_converged(drive: Drive) -> History {
    let model = SliderCrank::steel(drive);
    let coarse = slider_crank(&model, &STEEL_DISCRETISATION, 0.1, 1e-5);
    let fine_disc = Discretisation {
        elements: 2 * STEEL_DISCRETISATION.elements,
        step: STEEL_DISCRETISATION.step / 2.0,
    };
    let fine = slider_crank(&model, &fine_disc, 0.1, 1e-5);
    let peak = largest_abs(&fine.mid_deflection);
    let peak_change = (largest_abs(&coarse.mid_deflection) - peak).abs() / peak;
    assert!(
        peak_change < 1e-3,
        "{drive:?}: peak {peak:e} changes by {peak_change:e}"
    );
    let history_change = largest_difference(&coarse.mid_deflection, &fine.mid_deflection) / peak;
    assert!(history_change < 2e-3, "{drive:?}: {history_change:e}");
    let slider_change = largest_difference(&coarse.slider_x, &fine.slider_x);
    assert!(slider_change < 1e-6, "{drive:?}: {slider_change:e}");
    coarse
}

/// Peak of a history's |mid-deflection|: (time, signed value).
fn peak(history: &History) -> (f64, f64) {
    let k = (0..history.t.len())
        .max_by(|&a, &b| {
            history.mid_deflection[a]
                .abs()
                .total_cmp(&history.mid_deflection[b].abs())
        })
        .unwrap_or(0);
    (history.t[k], history.mid_deflection[k])
}

/// Constant 150 rad/s from the rigid mechanism's velocities (the crank pin's sudden
/// acceleration rings the rod axially, ±19 µm at the slider, so the step resolves the axial
/// mode). Measured: changes 1.3e-4 (peak), 1.8e-4 (histories) of the peak, 0.80 µm (slider);
/// peak +4.8877 mm at 5.45 ms.
#[test]
fn constant_rate_slider_crank_converges() {
    let history = assert_converged(Drive::Constant { omega: 150.0 });
    let (t, value) = peak(&history);
    assert!((t - 5.45e-3).abs() < 5e-5, "{t}");
    assert!((value / 4.8877e-3 - 1.0).abs() < 1e-3, "{value:e}");
}

/// Cycloidal spin-up to 150 rad/s in 0.05 s, from rest. Peak −4.0492 mm at 60.9 ms.
#[test]
fn spin_up_slider_crank_converges() {
    let history = assert_converged(Drive::SpinUp {
        omega: 150.0,
        duration: 0.05,
    });
    let (t, value) = peak(&history);
    assert!((t - 60.9e-3).abs() < 5e-5, "{t}");
    assert!((value / -4.0492e-3 - 1.0).abs() < 1e-3, "{value:e}");
}

/// A rod a million times stiffer: the slider follows the rigid mechanism,
/// R cos φ + √(L² − R² sin² φ), to 1e-9 m (2.4e-11 measured), for both drives.
#[test]
fn stiff_rod_moves_the_slider_rigidly() {
    for drive in [
        Drive::Constant { omega: 150.0 },
        Drive::SpinUp {
            omega: 150.0,
            duration: 0.05,
        },
    ] {
        let mut model = SliderCrank::steel(drive);
        model.rod.youngs_modulus *= 1e6;
        let disc = Discretisation {
            elements: 4,
            step: 1e-5,
        };
        let history = slider_crank(&model, &disc, 0.1, 1e-4);
        for (k, &t) in history.t.iter().enumerate() {
            let error = history.slider_x[k] - model.rigid_slider_x(t);
            assert!(error.abs() < 1e-9, "{drive:?}, t = {t}: {error:e}");
        }
        assert!(largest_abs(&history.mid_deflection) < 1e-8);
    }
}

/// The mid-length point must be a node.
#[test]
#[should_panic(expected = "even")]
fn odd_element_counts_are_refused() {
    let disc = Discretisation {
        elements: 5,
        step: 1e-5,
    };
    slider_crank(
        &SliderCrank::steel(Drive::Constant { omega: 150.0 }),
        &disc,
        1e-3,
        1e-4,
    );
}
