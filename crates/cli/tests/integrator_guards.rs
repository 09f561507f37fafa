//! The integrator's guards through the deck (issue 19): a loose tolerance either stays near
//! the tight answer or stops with exit 1, never exit 0 with a diverged answer; a short torque
//! ramp from rest is followed (breakpoints, `max_step`); the new `[analysis]` keys are checked.

mod common;

use common::{bad_deck, deck, run, run_json, with_deck};

/// The peak mid-node deflection of the §5.1 deck, analysis only, with `sets`.
fn beam_peak(sets: &[&str]) -> Result<f64, String> {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let mut args: Vec<String> = vec![
        "run".into(),
        deck("slider_crank_beam.toml").display().to_string(),
        "-o".into(),
        out.display().to_string(),
        "--json".into(),
        "--set".into(),
        "sensitivity.enabled=false".into(),
    ];
    for s in sets {
        args.extend(["--set".to_string(), s.to_string()]);
    }
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let o = run(&args);
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(!err.contains("panicked"), "{err}");
    match o.status.code() {
        Some(0) => {
            let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
            Ok(v["responses"]["mid_deflection"]["max"].as_f64().unwrap())
        }
        Some(1) => {
            assert!(
                !out.join("results.h5").exists(),
                "a failed run left results"
            );
            Err(err)
        }
        c => panic!("exit {c:?}: {err}"),
    }
}

/// The issue's reproducer: at `rtol` 1e-2 … 1e-1 with `atol = 1e-6` the unlimited orders 3–5
/// let the rod's unresolved modes grow (peak 37 % high at 3e-2, measured before the limit).
/// Every run now either lands within three times its tolerance of the tight answer (a loose local
/// tolerance allows a global error of a few times itself) or stops with exit 1 and a message
/// that names the cause.
#[test]
fn a_loose_tolerance_stays_accurate_or_fails_cleanly() {
    let tight = beam_peak(&[]).unwrap();
    for rtol in [1e-2, 3e-2, 1e-1] {
        let r = format!("analysis.rtol={rtol}");
        match beam_peak(&[&r, "analysis.atol=1e-6"]) {
            Ok(peak) => {
                let rel = (peak - tight).abs() / tight;
                eprintln!("rtol {rtol:e}: peak {peak:.4e} (tight {tight:.4e}), off by {rel:.2e}");
                assert!(
                    rel < 3.0 * rtol,
                    "rtol {rtol:e}: peak {peak} against {tight}"
                );
            }
            Err(msg) => {
                eprintln!("rtol {rtol:e}: {msg}");
                assert!(
                    msg.contains("violation") || msg.contains("deflects"),
                    "{msg}"
                );
            }
        }
    }
}

/// A rotor (a disc on a revolute joint, moment of inertia 0.05 kg·m² about it, its centre of
/// mass 0.1 m off the axis to make the angle visible) driven from rest by a torque ramp from 0
/// to 1 N·m over the first 10 ms, then held. Closed form: θ = t³/(6 t₁ J) during the ramp,
/// then θ₁ + ω₁(t − t₁) + (t − t₁)²/(2J).
const ROTOR: &str = r#"
title = "Rotor under a short torque ramp"

[rigid.rotor]
mass = 1.0
inertia = [0.04, 0.04, 0.04]
position = [0.1, 0.0, 0.0]

[joint.axle]
kind = "revolute"
a = { body = "ground", point = [0.0, 0.0, 0.0], axis = [0.0, 0.0, 1.0] }
b = { body = "rotor", point = [0.0, 0.0, 0.0], axis = [0.0, 0.0, 1.0] }

[force.drive]
kind = "point-torque"
at = { body = "rotor", point = [0.1, 0.0, 0.0] }
table = { times = [0.0, 0.01], values = [[0.0, 0.0, 0.0], [0.0, 0.0, 1.0]] }

[response.y]
kind = "position"
body = "rotor"
component = "y"

[analysis]
t_end = 0.5
output_step = 0.05
"#;

fn rotor_angle(t: f64) -> f64 {
    let (j, t1) = (0.05, 0.01);
    if t <= t1 {
        t.powi(3) / (6.0 * t1 * j)
    } else {
        let (th1, w1) = (t1 * t1 / (6.0 * j), t1 / (2.0 * j));
        th1 + w1 * (t - t1) + (t - t1).powi(2) / (2.0 * j)
    }
}

#[test]
fn a_short_torque_ramp_from_rest_is_followed() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("rotor.toml");
    std::fs::write(&path, ROTOR).unwrap();
    let exact = 0.1 * rotor_angle(0.5).sin();
    for extra in [vec![], vec!["--set", "analysis.max_step=1e-3"]] {
        let out = dir.path().join("out");
        let mut args = with_deck("run", &path, &["--json", "-o"]);
        args.push(out.display().to_string());
        args.extend(extra.iter().map(|s| s.to_string()));
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let v = common::json(&args);
        let y = v["responses"]["y"]["final"].as_f64().unwrap();
        let steps = v["statistics"]["steps"].as_f64().unwrap_or(f64::NAN);
        eprintln!("{extra:?}: y(0.5) = {y:.8} (exact {exact:.8}), {steps} steps");
        assert!(
            (y - exact).abs() < 1e-5 * exact.abs().max(1e-3),
            "{y} vs {exact}"
        );
    }
}

#[test]
fn the_new_analysis_keys_are_checked() {
    let base = std::fs::read_to_string(deck("slider_crank_rigid.toml")).unwrap();
    let cases = [
        ("max_step = -1.0", "analysis.max_step"),
        ("initial_step = 0.0", "analysis.initial_step"),
        (
            "max_step = 1e-4\ninitial_step = 1e-3",
            "analysis.initial_step",
        ),
        ("stability_limit = 3", "stability_limit"),
        ("max_violation = -1e-3", "analysis.max_violation"),
        (
            "integrator = \"fixed\"\nstep = 1e-4\nmax_step = 1e-3",
            "analysis.max_step",
        ),
    ];
    for (extra, key) in cases {
        let text = base.replace("[analysis]\n", &format!("[analysis]\n{extra}\n"));
        assert_ne!(text, base);
        let (_d, err) = bad_deck(&text, |p| with_deck("check", p, &[]));
        assert!(err.contains(key), "{extra}: {err}");
    }
    // and a deck with them all runs
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let v = run_json(
        "slider_crank_rigid.toml",
        &out,
        &[
            "analysis.max_step=1e-3",
            "analysis.initial_step=1e-5",
            "analysis.stability_limit=false",
            "analysis.max_violation=1e-3",
        ],
    );
    assert!(v["responses"].is_object());
}
