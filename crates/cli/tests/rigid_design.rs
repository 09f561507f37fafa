//! A rigid body's mass and principal inertia as design variables, through the whole run:
//! a pendulum's swing against the small-amplitude closed form and its derivatives, and the
//! direct sensitivities against replayed central differences of whole runs; and the slider's
//! mass on the flexible beam slider-crank.

mod common;

use common::{
    bad_deck, beam_direct_vs_central, f64s, json, replayed_difference, run_deck_json, run_text,
    with_deck,
};
use flexsens::results::{Data, Group};

/// Pendulum: a bob of mass M and inertia I about its centre, its centre D from a revolute
/// pivot, released at rest THETA0 from the downward vertical under gravity G.
const M: f64 = 1.0;
const I: f64 = 0.02;
const D: f64 = 0.5;
const G: f64 = 9.81;
const THETA0: f64 = 0.01;

fn pendulum_deck() -> String {
    let (s, c) = THETA0.sin_cos();
    format!(
        "title = \"rigid pendulum\"
[rigid.bob]
mass = {M:?}
inertia = [0.01, 0.01, {I:?}]
position = [{x:?}, {y:?}, 0.0]
orientation = {{ axis = [0.0, 0.0, 1.0], angle = \"{THETA0:?} rad\" }}

[joint.pivot]
kind = \"revolute\"
a = {{ body = \"ground\", point = [0.0, 0.0, 0.0], axis = [0.0, 0.0, 1.0] }}
b = {{ body = \"bob\", point = [0.0, 0.0, 0.0], axis = [0.0, 0.0, 1.0] }}

[force.gravity]
kind = \"gravity\"
acceleration = [0.0, -{G:?}, 0.0]

[response.x]
kind = \"position\"
body = \"bob\"
component = \"x\"

[analysis]
t_end = 1.0
output_step = 0.01
rtol = 1e-10
atol = 1e-13

[design.inertia]
kind = \"rigid-inertia\"
body = \"bob\"
axis = \"z\"

[design.mass]
kind = \"rigid-mass\"
body = \"bob\"

[objective.x_end]
response = \"x\"
kind = \"at\"
time = 1.0

[finite_differences]
scheme = \"central\"
sizes = [1e-4]
",
        x = D * s,
        y = -D * c
    )
}

#[test]
fn pendulum_mass_and_inertia_sensitivities_match_the_closed_form_and_central_differences() {
    let dir = tempfile::tempdir().unwrap();
    let deck = dir.path().join("pendulum.toml");
    std::fs::write(&deck, pendulum_deck()).unwrap();
    let out = dir.path().join("out");
    let summary = json(&[
        "run",
        deck.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--json",
    ]);
    let g = Group::read_hdf5(&out.join("results.h5")).unwrap();
    let t = f64s(&g, "time");
    let x = f64s(&g, "responses/x");
    let dx = f64s(&g, "sensitivities/x"); // rows: times; columns: inertia, mass
    assert_eq!(f64s(&g, "design/values"), [I, M]);
    // small swings: x = D θ0 cos ωt with ω² = M G D / J, J = I + M D² about the pivot; then
    // dx/db = D θ0 t sin(ωt) (−dω/db)
    let j = I + M * D * D;
    let w = (M * G * D / j).sqrt();
    let dw_di = -w / (2.0 * j);
    let dw_dm = 0.5 * w * (1.0 / M - D * D / j);
    let amplitude = D * THETA0;
    let (mut e_x, mut e_i, mut e_m) = (0.0f64, 0.0f64, 0.0f64);
    let (mut s_i, mut s_m) = (0.0f64, 0.0f64);
    for (k, &tk) in t.iter().enumerate() {
        let closed = amplitude * (w * tk).cos();
        let slope = -amplitude * tk * (w * tk).sin();
        e_x = e_x.max((x[k] - closed).abs());
        e_i = e_i.max((dx[2 * k] - slope * dw_di).abs());
        e_m = e_m.max((dx[2 * k + 1] - slope * dw_dm).abs());
        s_i = s_i.max((slope * dw_di).abs());
        s_m = s_m.max((slope * dw_dm).abs());
    }
    eprintln!(
        "pendulum vs the small-swing closed form: x {:.1e}, dx/dI {:.1e}, dx/dm {:.1e} (relative)",
        e_x / amplitude,
        e_i / s_i,
        e_m / s_m
    );
    // the closed form's own error is O(θ0²) = 1e-4
    assert!(e_x < 1e-3 * amplitude, "{e_x:e}");
    assert!(e_i < 2e-3 * s_i, "{e_i:e} of {s_i:e}");
    assert!(e_m < 2e-3 * s_m, "{e_m:e} of {s_m:e}");
    // exact derivatives of the discrete solution against replayed central differences
    let fd = f64s(&g, "finite_differences/central_relative_0.0001_replay/x");
    let scale = dx.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    let err = dx
        .iter()
        .zip(&fd)
        .fold(0.0f64, |a, (d, f)| a.max((d - f).abs()))
        / scale;
    eprintln!("direct vs central differences: {err:.1e}");
    assert!(err < 1e-6, "{err:e}");
    // units per variable
    let units = match &g.get("design/units").unwrap().data {
        Data::Text(u) => u.clone(),
        Data::F64(_) => panic!("design/units is text"),
    };
    assert_eq!(units, ["kg*m^2", "kg"]);
    let gradient = &summary["objectives"][0]["gradient"];
    assert!(gradient[0].as_f64().unwrap().is_finite());
    let (head, _) = {
        let text = std::fs::read_to_string(out.join("sensitivities.csv")).unwrap();
        let head: Vec<String> = text
            .lines()
            .next()
            .unwrap()
            .split(',')
            .map(str::to_string)
            .collect();
        (head, ())
    };
    assert_eq!(
        head,
        [
            "time [s]",
            "d x/d inertia [m/(kg*m^2)]",
            "d x/d mass [m/kg]"
        ]
    );
}

#[test]
fn slider_mass_sensitivities_of_the_flexible_slider_crank_match_central_differences() {
    let errors = beam_direct_vs_central(
        "\n[design.slider_mass]\nkind = \"rigid-mass\"\nbody = \"slider\"\n",
        "1e-4",
        &["slider_mass", "theta"],
    );
    // measured: slider_mass 1.6e-6, theta 1.4e-7 (δ = 0.01 %; at 0.1 % the differences'
    // truncation gives 2.6e-5 with the correction modes' fast dynamics)
    for (err, scale) in errors {
        assert!(scale > 0.0);
        assert!(err < 1e-5, "{err:e}");
    }
}

#[test]
fn bad_rigid_design_variables_are_located() {
    let base = pendulum_deck();
    for (from, to, key, words) in [
        (
            "kind = \"rigid-mass\"\nbody = \"bob\"",
            "kind = \"rigid-mass\"\nbody = \"bobb\"",
            "design.mass.body",
            "undefined rigid body `bobb`",
        ),
        (
            "axis = \"z\"",
            "axis = \"w\"",
            "design.inertia.axis",
            "unknown value `w`",
        ),
        (
            "kind = \"rigid-mass\"\nbody = \"bob\"",
            "kind = \"rigid-mass\"\nbody = \"bob\"\nlaminate = \"x\"",
            "design.mass.laminate",
            "does not apply to kind = \"rigid-mass\"",
        ),
        (
            "inertia = [0.01, 0.01, 0.02]",
            "inertia = [[0.01, 0.0, 0.0], [0.0, 0.01, 0.001], [0.0, 0.001, 0.02]]",
            "design.inertia.axis",
            "products of inertia",
        ),
    ] {
        assert!(base.contains(from), "{from}");
        let text = base.replacen(from, to, 1);
        let (_dir, err) = bad_deck(&text, |p| with_deck("run", p, &[]));
        assert!(err.contains(&format!("key `{key}`")), "{err}");
        assert!(err.contains(words), "{err}");
    }
}

/// The pendulum deck with objectives over windows of the run, its bob's mass `m`.
fn windowed_deck(m: f64) -> String {
    pendulum_deck().replace(&format!("mass = {M:?}"), &format!("mass = {m:?}"))
        + "
[objective.peak]
response = \"x\"
kind = \"max\"
window = [0.25, 0.613]

[objective.settled]
response = \"x\"
kind = \"final\"
window = [0.1, 0.437]

[objective.swing]
response = \"x\"
kind = \"rms\"
window = [0.2, 0.8]

[objective.smooth_peak]
response = \"x\"
kind = \"ks\"
rho = 4000.0
"
}

/// The objectives `peak`, `settled`, `swing`, `smooth_peak` of the windowed deck with bob mass
/// `m`: values and gradients (inertia, mass).
fn windowed(m: f64) -> Vec<(f64, Vec<f64>)> {
    let s = run_deck_json(&windowed_deck(m));
    ["peak", "settled", "swing", "smooth_peak"]
        .iter()
        .map(|name| {
            let o = s["objectives"]
                .as_array()
                .unwrap()
                .iter()
                .find(|o| o["name"] == *name)
                .unwrap();
            let g = o["gradient"].as_array().unwrap();
            (
                o["value"].as_f64().unwrap(),
                g.iter().map(|x| x.as_f64().unwrap()).collect(),
            )
        })
        .collect()
}

#[test]
fn objectives_over_windows_match_the_swing_and_their_gradients_central_differences() {
    let got = windowed(M);
    // small swings: x = A cos ωt
    let w = (M * G * D / (I + M * D * D)).sqrt();
    let a = D * THETA0;
    let x = |t: f64| a * (w * t).cos();
    // the peak of the window is at its start (x falls from 0.25 s, past its zero at π/2ω =
    // 0.369 s, to its trough at π/ω = 0.738 s)
    let peak = x(0.25);
    let settled = x(0.437);
    // RMS over [t0, t1]: √(A²/2 (1 + (sin 2ωt1 − sin 2ωt0)/(2ω (t1 − t0))))
    let (t0, t1) = (0.2, 0.8);
    let swing = (a * a / 2.0
        * (1.0 + ((2.0 * w * t1).sin() - (2.0 * w * t0).sin()) / (2.0 * w * (t1 - t0))))
        .sqrt();
    // KS over the whole run of A cos ωt (1 s, about 0.68 of a period): below the peak A
    // reached at t = 0, within ln(T/τ)/ρ of it (τ ~ 1/(ω √(ρA)) the peak's width)
    let ks = got[3].0;
    let gap = (1.0 / (w * (4000.0 * a).sqrt())).ln().abs() / 4000.0;
    assert!(
        ks < a && a - ks < 2.0 * gap,
        "KS {ks} against the peak {a} (gap {gap})"
    );
    for ((value, _), (name, exact)) in
        got.iter()
            .zip([("peak", peak), ("settled", settled), ("swing", swing)])
    {
        // the closed form's own error O(θ0²) and the trapezoidal rule's on 0.01 s steps
        assert!(
            (value - exact).abs() < 1e-3 * a,
            "{name}: {value} vs the closed form {exact}"
        );
    }
    // d/dm against central differences of whole runs
    let h = 1e-4 * M;
    let (plus, minus) = (windowed(M + h), windowed(M - h));
    for (k, name) in ["peak", "settled", "swing", "smooth_peak"]
        .iter()
        .enumerate()
    {
        let fd = (plus[k].0 - minus[k].0) / (2.0 * h);
        let g = got[k].1[1];
        assert!(
            (g - fd).abs() < 1e-5 * fd.abs().max(1e-3 * a),
            "{name}: d/dm {g} vs central differences {fd}"
        );
    }
}

#[test]
fn windows_must_be_two_increasing_times_within_the_run_and_not_with_at() {
    for (window, kind, says) in [
        ("[0.5]", "max", "expected [t0, t1]"),
        ("[0.6, 0.5]", "max", "must end after it starts"),
        ("[0.5, 1.5]", "max", "outside the simulated span"),
        ("[0.2, 0.5]", "at\"\ntime = \"0.3", "takes its one time"),
    ] {
        let deck = pendulum_deck()
            + &format!("\n[objective.w]\nresponse = \"x\"\nkind = \"{kind}\"\nwindow = {window}\n")
                .replace("time = \"0.3\"", "time = 0.3");
        let (_dir, err) = bad_deck(&deck, |p| with_deck("check", p, &[]));
        assert!(
            err.contains("objective.w.window") && err.contains(says),
            "{window}: {err}"
        );
    }
}

#[test]
fn a_point_of_the_bob_moves_as_the_swing_and_its_acceleration_derivatives_equal_differences() {
    let (s, c) = THETA0.sin_cos();
    let (x0, y0) = (D * s, -D * c);
    let deck = pendulum_deck()
        + &format!(
            "
[response.ax]
kind = \"point-acceleration\"
at = {{ body = \"bob\", point = [{x0:?}, {y0:?}, 0.0] }}
component = \"x\"

[response.vx]
kind = \"point-velocity\"
at = {{ body = \"bob\", point = [{x0:?}, {y0:?}, 0.0] }}
component = \"x\"

[response.from_pivot]
kind = \"point-position\"
at = {{ body = \"bob\", point = [{x0:?}, {y0:?}, 0.0] }}
relative_to = {{ body = \"ground\", point = [0.0, -1.0, 0.0] }}
component = \"y\"
"
        );
    let dir = tempfile::tempdir().unwrap();
    let (_, g) = run_text(dir.path(), "points", &deck, &[]);
    let t = f64s(&g, "time");
    let (ax, vx, rel) = (
        f64s(&g, "responses/ax"),
        f64s(&g, "responses/vx"),
        f64s(&g, "responses/from_pivot"),
    );
    let y = {
        // the bob's centre y from its frame's position response x: y = −√(D² − x²)
        let x = f64s(&g, "responses/x");
        x.iter()
            .map(|x| -(D * D - x * x).sqrt())
            .collect::<Vec<_>>()
    };
    // small swings: x = A cos ωt, ẋ = −A ω sin ωt, ẍ = −A ω² cos ωt
    let w = (M * G * D / (I + M * D * D)).sqrt();
    let a = D * THETA0;
    for (k, &tk) in t.iter().enumerate() {
        assert!(
            (vx[k] + a * w * (w * tk).sin()).abs() < 2e-3 * a * w,
            "t = {tk}"
        );
        assert!(
            (ax[k] + a * w * w * (w * tk).cos()).abs() < 2e-3 * a * w * w,
            "t = {tk}"
        );
        // relative to a ground point 1 m below the pivot
        assert!((rel[k] - (y[k] + 1.0)).abs() < 1e-9, "t = {tk}: {}", rel[k]);
    }
    // exact derivatives of the discrete solution against replayed central differences
    for name in ["ax", "vx"] {
        let err = replayed_difference(&g, name, "0.0001");
        assert!(err < 1e-6, "{name}: {err:e}");
    }
}

#[test]
fn a_ks_aggregate_needs_a_positive_rho_and_only_it_takes_one() {
    for (lines, says) in [
        ("kind = \"ks\"", "missing value: rho"),
        ("kind = \"ks\"\nrho = -3.0", "must be positive"),
        ("kind = \"max\"\nrho = 30.0", "only used with kind = \"ks\""),
    ] {
        let deck = pendulum_deck() + &format!("\n[objective.w]\nresponse = \"x\"\n{lines}\n");
        let (_dir, err) = bad_deck(&deck, |p| with_deck("check", p, &[]));
        assert!(
            err.contains("objective.w.rho") && err.contains(says),
            "{lines}: {err}"
        );
    }
}
