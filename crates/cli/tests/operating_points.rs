//! `flexsens static`: operating points through the command.
//!
//! - A rotating uniform cantilever (an aluminium strip on a driven hub): its flap frequencies
//!   against the published values of Wright et al. (1982, "Vibration modes of centrifugally
//!   stiffened beams", J. Appl. Mech. 49:197–202; the values also of Hodges & Rutkowski 1981)
//!   at speeds up to λ = Ω/√(EI/ρAL⁴) = 12, which an Euler–Bernoulli finite-element model of
//!   the rotating beam written here reproduces first; its lag frequency softened by the spin,
//!   ω² = ω_F(Ω)² − Ω² with ω_F the flap law of the lag stiffness.
//! - A pendulum under a side load: its equilibrium angle and frequency against the closed
//!   forms, and its frozen-time frequencies about the states of a wide swing (`[operating]
//!   at`) against the closed-form linearisation of its angle equation.
//! - A composite cantilever's sag against Timoshenko beam theory on its section stiffness, its
//!   derivative against central differences of the command; rotating frequencies' derivatives
//!   against central differences; an optimisation with a 2P margin active; a bending–torsion
//!   coupled blade against an independent rotating beam model; the VTK mode shapes.

mod common;

use common::{json, run};
use nalgebra::{DMatrix, SymmetricEigen};

/// Wright et al. (1982), Table 1: the first two flap frequencies of a uniform cantilever
/// without hub radius, ω/√(EI/ρAL⁴), at λ = 0 … 12.
const WRIGHT: [(f64, f64, f64); 9] = [
    (0.0, 3.5160, 22.0345),
    (1.0, 3.6816, 22.1810),
    (2.0, 4.1373, 22.6149),
    (3.0, 4.7973, 23.3203),
    (4.0, 5.5850, 24.2733),
    (6.0, 7.3604, 26.8091),
    (8.0, 9.2568, 29.9954),
    (10.0, 11.2023, 33.6404),
    (12.0, 13.1702, 37.6031),
];

/// The cubic Hermite shape functions of an element of length `h` at `s ∈ [0, 1]` (dofs
/// `w0, w0', w1, w1'`), with their first and second derivatives along the beam.
fn hermite(s: f64, h: f64) -> [[f64; 4]; 3] {
    [
        [
            1.0 - 3.0 * s * s + 2.0 * s.powi(3),
            h * (s - 2.0 * s * s + s.powi(3)),
            3.0 * s * s - 2.0 * s.powi(3),
            h * (s.powi(3) - s * s),
        ],
        [
            (6.0 * s * s - 6.0 * s) / h,
            1.0 - 4.0 * s + 3.0 * s * s,
            (6.0 * s - 6.0 * s * s) / h,
            3.0 * s * s - 2.0 * s,
        ],
        [
            (12.0 * s - 6.0) / (h * h),
            (6.0 * s - 4.0) / h,
            (6.0 - 12.0 * s) / (h * h),
            (6.0 * s - 2.0) / h,
        ],
    ]
}

/// The first frequencies (ω/√(EI/ρAL⁴)) of a rotating uniform Euler–Bernoulli cantilever
/// at speed λ: Hermite elements with the centrifugal tension ρAΩ²(L² − x²)/2 as geometric
/// stiffness (unit length, EI and ρA).
fn rotating_cantilever(lambda: f64, elements: usize) -> Vec<f64> {
    let n = 2 * elements;
    let h = 1.0 / elements as f64;
    let mut k = DMatrix::<f64>::zeros(n + 2, n + 2);
    let mut m = DMatrix::<f64>::zeros(n + 2, n + 2);
    let gauss = [
        (-0.906_179_845_938_664, 0.236_926_885_056_189),
        (-0.538_469_310_105_683, 0.478_628_670_499_366),
        (0.0, 0.568_888_888_888_889),
        (0.538_469_310_105_683, 0.478_628_670_499_366),
        (0.906_179_845_938_664, 0.236_926_885_056_189),
    ];
    for e in 0..elements {
        let x0 = e as f64 * h;
        for &(g, w) in &gauss {
            let s = (g + 1.0) / 2.0;
            let x = x0 + s * h;
            let [shape, slope, curvature] = hermite(s, h);
            let tension = lambda * lambda * (1.0 - x * x) / 2.0;
            for a in 0..4 {
                for b in 0..4 {
                    let (i, j) = (2 * e + a, 2 * e + b);
                    let wh = w * h / 2.0;
                    k[(i, j)] += wh * (curvature[a] * curvature[b] + tension * slope[a] * slope[b]);
                    m[(i, j)] += wh * shape[a] * shape[b];
                }
            }
        }
    }
    // clamped at x = 0
    let k = k.view((2, 2), (n, n)).into_owned();
    let m = m.view((2, 2), (n, n)).into_owned();
    frequencies(k, m)
}

/// The square roots of the eigenvalues of `k x = ω² m x` (`m` positive definite), increasing.
fn frequencies(k: DMatrix<f64>, m: DMatrix<f64>) -> Vec<f64> {
    let li = m.cholesky().unwrap().l().try_inverse().unwrap();
    let a: DMatrix<f64> = &li * k * li.transpose();
    let mut w: Vec<f64> = SymmetricEigen::new(a)
        .eigenvalues
        .iter()
        .map(|x| x.sqrt())
        .collect();
    w.sort_by(f64::total_cmp);
    w
}

#[test]
fn the_rotating_beam_model_of_the_test_reproduces_the_published_table() {
    for &(lambda, w1, w2) in &WRIGHT {
        let w = rotating_cantilever(lambda, 40);
        assert!(
            (w[0] / w1 - 1.0).abs() < 1e-4,
            "λ = {lambda}: {} vs {w1}",
            w[0]
        );
        assert!(
            (w[1] / w2 - 1.0).abs() < 1e-4,
            "λ = {lambda}: {} vs {w2}",
            w[1]
        );
    }
}

/// An aluminium strip 1 m long, 12 mm wide in the plane of the spin and 2 mm thick along the
/// spin axis, clamped to a hub driven about z.
const BLADE: &str = r#"
title = "Rotating uniform strip"

[material.aluminium]
E = 70.0e9
nu = 0.3
density = 2700.0

[section.strip]
shape = "rectangle"
width = 0.012     # along x2: global y, in the plane of the spin (lag)
height = 0.002    # along x3: global z, the spin axis (flap)
material = "aluminium"
elements = [24, 4]

[body.blade]
kind = "beam"
section = "strip"
start = [0.0, 0.0, 0.0]
end = [1.0, 0.0, 0.0]
orientation = [0.0, 1.0, 0.0]
elements = 30
modes = 12
reference = "clamped-node"

[joint.hub]
kind = "revolute"
a = { body = "ground", point = [0.0, 0.0, 0.0], axis = [0.0, 0.0, 1.0] }
b = { body = "blade", node = 0, axis = [0.0, 0.0, 1.0] }

[joint.motor]
kind = "angle-driver"
a = { body = "ground", point = [0.0, 0.0, 0.0], axis = [0.0, 0.0, 1.0], reference = [1.0, 0.0, 0.0] }
b = { body = "blade", node = 0, axis = [0.0, 0.0, 1.0], reference = [1.0, 0.0, 0.0] }
motion = { kind = "constant-speed", rate = 0.0 }

[response.tip_flap]
kind = "nodal-displacement"
body = "blade"
node = 30
component = "uz"

[analysis]
t_end = 0.01
"#;

#[test]
fn rotating_cantilever_flap_and_lag_frequencies_match_the_published_values() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("blade.toml");
    std::fs::write(&path, BLADE).unwrap();
    let (e, rho, b, h) = (70.0e9, 2700.0, 0.012, 0.002);
    let rho_a = rho * b * h;
    let scale = |ei: f64| (ei / rho_a).sqrt();
    let (flap, lag) = (
        scale(e * b * h.powi(3) / 12.0),
        scale(e * h * b.powi(3) / 12.0),
    );
    let speeds: Vec<String> = WRIGHT
        .iter()
        .map(|(l, _, _)| format!("\"{} rad/s\"", l * flap))
        .collect();
    let j = json(&[
        "static",
        path.to_str().unwrap(),
        "-o",
        dir.path().join("out").to_str().unwrap(),
        "--json",
        "--set",
        "operating.driver=motor",
        "--set",
        &format!("operating.speeds=[{}]", speeds.join(",")),
    ]);
    let points = j["points"].as_array().unwrap();
    assert_eq!(points.len(), WRIGHT.len());
    let two_pi = 2.0 * std::f64::consts::PI;
    for (p, &(lambda, w1, w2)) in points.iter().zip(&WRIGHT) {
        let omega = lambda * flap;
        let f: Vec<f64> = (p["modes"].as_array().unwrap().iter())
            .map(|m| m["frequency_hz"].as_f64().unwrap() * two_pi)
            .collect();
        let nearest = |w: f64| {
            f.iter()
                .copied()
                .min_by(|a, b| (a - w).abs().total_cmp(&(b - w).abs()))
                .unwrap()
        };
        for (name, expected) in [("flap 1", w1 * flap), ("flap 2", w2 * flap)] {
            let got = nearest(expected);
            assert!(
                (got / expected - 1.0).abs() < 5e-3,
                "λ = {lambda}: {name} {got} rad/s, published {expected}"
            );
        }
        // lag: the flap law of the lag stiffness, softened by Ω²
        let lag_rotating = rotating_cantilever(omega / lag, 40)[0] * lag;
        let expected = (lag_rotating * lag_rotating - omega * omega).sqrt();
        let got = nearest(expected);
        assert!(
            (got / expected - 1.0).abs() < 5e-3,
            "λ = {lambda}: lag {got} rad/s, expected {expected} (unsoftened {lag_rotating})"
        );
    }
    for f in [
        "operating.csv",
        "frequencies.csv",
        "campbell.svg",
        "campbell.png",
    ] {
        assert!(dir.path().join("out").join(f).exists(), "{f}");
    }
}

#[test]
fn static_refuses_a_speed_without_a_driver() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("blade.toml");
    std::fs::write(&path, BLADE).unwrap();
    let o = run(&[
        "static",
        path.to_str().unwrap(),
        "--set",
        "operating.speeds=[0, 100]",
    ]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("operating.speeds.1") && err.contains("needs `operating.driver`"),
        "{err}"
    );
    let o = run(&[
        "static",
        path.to_str().unwrap(),
        "--set",
        "operating.driver=hub",
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("not an angle driver"),
        "{err}"
    );
}

/// A cantilever of the paper's composite tube (0.3 m), clamped to the ground, under gravity.
const CANTILEVER: &str = r#"
title = "Composite tube cantilever under gravity"

[material.paper_composite]
E1 = 128.0e9
E2 = 10.1e9
E3 = 10.1e9
G12 = 5.36e9
G13 = 5.36e9
G23 = 5.36e9
nu12 = 0.23
nu13 = 0.23
nu23 = 0.23
density = 1586.0

[laminate.tube_wall]
plies = [
  { material = "paper_composite", thickness = 0.25e-3, angle = 15.0 },
  { material = "paper_composite", thickness = 0.25e-3, angle = 15.0 },
  { material = "paper_composite", thickness = 0.25e-3, angle = 15.0 },
  { material = "paper_composite", thickness = 0.25e-3, angle = 15.0 },
]

[section.tube]
shape = "tube"
inner_radius = 4.529e-3
laminate = "tube_wall"
elements_per_ply = 1
elements_around = 32

[body.rod]
kind = "beam"
section = "tube"
start = [0.0, 0.0, 0.0]
end = [0.3, 0.0, 0.0]
orientation = [0.0, 1.0, 0.0]
elements = 48
modes = 20
reference = "clamped-node"

[joint.root]
kind = "fixed"
a = { body = "ground", point = [0.0, 0.0, 0.0] }
b = { body = "rod", node = 0 }

[force.gravity]
kind = "gravity"
acceleration = [0.0, 0.0, -9.81]

[response.tip]
kind = "nodal-displacement"
body = "rod"
node = 48
component = "uz"

[design.theta]
laminate = "tube_wall"

[analysis]
t_end = 0.01
"#;

/// The tip's static deflection of the cantilever deck with its plies at `angle` (deg), and
/// its derivative with respect to `theta` (per degree).
fn cantilever_tip(dir: &std::path::Path, angle: f64) -> (f64, f64) {
    let path = dir.join("cantilever.toml");
    std::fs::write(
        &path,
        CANTILEVER.replace("angle = 15.0", &format!("angle = {angle}")),
    )
    .unwrap();
    let j = json(&[
        "static",
        path.to_str().unwrap(),
        "-o",
        dir.join("out").to_str().unwrap(),
        "--json",
    ]);
    let p = &j["points"][0];
    (
        p["responses"]["tip"].as_f64().unwrap(),
        p["gradients"]["tip"]["theta"].as_f64().unwrap(),
    )
}

#[test]
fn cantilever_sags_as_timoshenko_beam_theory_and_its_derivative_equals_differences() {
    let dir = tempfile::tempdir().unwrap();
    let (tip, derivative) = cantilever_tip(dir.path(), 15.0);
    // δ = F_MM q L⁴ / 8 + F_VV q L² / 2 with the section's compliance F = S⁻¹ (the tube's
    // plies all at 15° couple bending about x2 with shear along x2, which halves its
    // flexural stiffness when that shear is free: F_MM = 1/EI2 of the classical stiffness)
    let path = dir.path().join("cantilever.toml");
    let s = json(&["section", path.to_str().unwrap(), "--format", "json"]);
    let v = &s["sections"]["tube"]["values"];
    let stiffness = DMatrix::from_fn(6, 6, |i, j| v["stiffness"][i][j].as_f64().unwrap());
    let f = stiffness.try_inverse().unwrap();
    let q = v["mass_per_length"].as_f64().unwrap() * 9.81;
    let l: f64 = 0.3;
    let expected = -(f[(4, 4)] * q * l.powi(4) / 8.0 + f[(2, 2)] * q * l * l / 2.0);
    let classical = v["classical_stiffness"][2][2].as_f64().unwrap();
    assert!((f[(4, 4)] * classical - 1.0).abs() < 1e-9);
    assert!(
        (tip / expected - 1.0).abs() < 2e-4,
        "tip {tip} m, beam theory {expected} m"
    );
    // the derivative against central differences of the command (per degree)
    let h = 0.01;
    let (up, _) = cantilever_tip(dir.path(), 15.0 + h);
    let (down, _) = cantilever_tip(dir.path(), 15.0 - h);
    let fd = (up - down) / (2.0 * h);
    assert!(
        (derivative / fd - 1.0).abs() < 1e-5,
        "d tip/d theta {derivative}, central differences {fd}"
    );
    // plies turned from the axis soften the tube: it sags further (δ < 0 grows in size)
    assert!(derivative < 0.0, "{derivative}");
}

/// The cantilever deck turned into a rotor: the tube on a hub driven about z, no gravity.
fn rotor(angle: f64) -> String {
    CANTILEVER
        .replace("angle = 15.0", &format!("angle = {angle}"))
        .replace(
            r#"[joint.root]
kind = "fixed"
a = { body = "ground", point = [0.0, 0.0, 0.0] }
b = { body = "rod", node = 0 }

[force.gravity]
kind = "gravity"
acceleration = [0.0, 0.0, -9.81]
"#,
            r#"[joint.hub]
kind = "revolute"
a = { body = "ground", point = [0.0, 0.0, 0.0], axis = [0.0, 0.0, 1.0] }
b = { body = "rod", node = 0, axis = [0.0, 0.0, 1.0] }

[joint.motor]
kind = "angle-driver"
a = { body = "ground", point = [0.0, 0.0, 0.0], axis = [0.0, 0.0, 1.0], reference = [1.0, 0.0, 0.0] }
b = { body = "rod", node = 0, axis = [0.0, 0.0, 1.0], reference = [1.0, 0.0, 0.0] }
motion = { kind = "constant-speed", rate = 0.0 }

[operating]
driver = "motor"
speeds = ["0 rpm", "3000 rpm", "6000 rpm"]
modes = 6
"#,
        )
        .replace("elements = 48\nmodes = 20", "elements = 24\nmodes = 10")
        .replace("node = 48", "node = 24")
}

/// Per speed, the rotor's first frequencies (Hz) and their derivatives with respect to
/// `theta` (Hz/deg), with the plies at `angle`.
fn rotor_frequencies(dir: &std::path::Path, angle: f64) -> Vec<Vec<(f64, f64)>> {
    let path = dir.join("rotor.toml");
    std::fs::write(&path, rotor(angle)).unwrap();
    let j = json(&[
        "static",
        path.to_str().unwrap(),
        "-o",
        dir.join("rotor").to_str().unwrap(),
        "--json",
    ]);
    (j["points"].as_array().unwrap().iter())
        .map(|p| {
            (p["modes"].as_array().unwrap().iter())
                .map(|m| {
                    (
                        m["frequency_hz"].as_f64().unwrap(),
                        m["frequency_derivatives"]["theta"].as_f64().unwrap(),
                    )
                })
                .collect()
        })
        .collect()
}

#[test]
fn rotating_frequencies_derivatives_equal_central_differences_of_the_command() {
    let dir = tempfile::tempdir().unwrap();
    let nominal = rotor_frequencies(dir.path(), 15.0);
    // the model's frequencies carry noise of about 1e-8 of their value (the section and modal
    // solutions' tolerances), so the step is not smaller
    let h = 0.05;
    let up = rotor_frequencies(dir.path(), 15.0 + h);
    let down = rotor_frequencies(dir.path(), 15.0 - h);
    for (speed, ((n, u), d)) in nominal.iter().zip(&up).zip(&down).enumerate() {
        for (k, &(f, df)) in n.iter().enumerate() {
            let fd = (u[k].0 - d[k].0) / (2.0 * h);
            assert!(
                (df - fd).abs() <= 1e-4 * fd.abs().max(1e-3 * f),
                "speed {speed}, mode {}: df/dθ {df} Hz/deg, central differences {fd} ({f} Hz)",
                k + 1
            );
        }
    }
    // the spin stiffens the flap modes and splits the tube's pairs (lag softens by Ω²)
    assert!(nominal[2][0].0 != nominal[2][1].0);
}

/// The rotor with the plies' angle free in [0°, 60°]: the softest lay-up at rest (least first
/// frequency) whose flap frequency at 3000 rpm stays `margin` above twice the rotor speed.
fn rotor_optimization(dir: &std::path::Path, margin: f64) -> (f64, f64, f64, f64) {
    let text = rotor(15.0)
        .replace(
            "[design.theta]\nlaminate = \"tube_wall\"\n",
            "[design.theta]\nlaminate = \"tube_wall\"\nlower = 0.0\nupper = 60.0\n",
        )
        .replace(
            r#"speeds = ["0 rpm", "3000 rpm", "6000 rpm"]"#,
            r#"speeds = ["0 rpm", "3000 rpm"]"#,
        )
        + &format!(
            "\n[optimize]\nminimize = \"frequency.rod.1\"\n\n[[optimize.constraint]]\n\
             quantity = \"order_margin.2.2.2\"\nmin = {margin}\n"
        );
    let path = dir.join(format!("rotor_{margin}.toml"));
    std::fs::write(&path, text).unwrap();
    let out = dir.join(format!("rotor_{margin}"));
    let o = run(&[
        "optimize",
        path.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    let text = String::from_utf8_lossy(&o.stdout).into_owned();
    assert_eq!(
        o.status.code(),
        Some(0),
        "{text}\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let value = |name: &str| -> f64 {
        let line = text
            .lines()
            .find(|l| l.contains(&format!("{name} = ")))
            .unwrap_or_else(|| panic!("no {name} in\n{text}"));
        let after = line.rsplit(&format!("{name} = ")).next().unwrap();
        after.split_whitespace().next().unwrap().parse().unwrap()
    };
    let kkt: f64 = (text.lines())
        .find_map(|l| l.trim().strip_prefix("KKT stationarity "))
        .and_then(|rest| rest.split_whitespace().next())
        .unwrap_or_else(|| panic!("no KKT stationarity in\n{text}"))
        .parse()
        .unwrap();
    (
        value("theta"),
        value("order_margin.2.2.2"),
        value("multiplier dF*/d(bound)"),
        kkt,
    )
}

#[test]
fn the_softest_rotor_keeps_its_flap_frequency_clear_of_2p_with_the_bound_active() {
    let dir = tempfile::tempdir().unwrap();
    let (theta, margin, multiplier, kkt) = rotor_optimization(dir.path(), 0.1);
    assert!(
        (margin - 0.1).abs() < 1e-6,
        "the margin constraint is active: {margin}"
    );
    assert!(kkt < 1e-6, "KKT stationarity {kkt}");
    assert!((15.0..45.0).contains(&theta), "θ* = {theta}");
    // a sweep about the optimum: turning the plies further violates the margin, turning them
    // back stiffens the blade at rest (a worse objective)
    let sweep = |angle: f64| {
        let path = dir.path().join("sweep.toml");
        std::fs::write(&path, rotor(angle)).unwrap();
        let j = json(&[
            "static",
            path.to_str().unwrap(),
            "-o",
            dir.path().join("sweep").to_str().unwrap(),
            "--json",
        ]);
        let f = |p: usize, k: usize| j["points"][p]["modes"][k]["frequency_hz"].as_f64().unwrap();
        (f(0, 0), f(1, 1) / (2.0 * 50.0) - 1.0)
    };
    let (f0, m0) = sweep(theta);
    assert!((m0 - 0.1).abs() < 1e-6, "the sweep's margin at θ* {m0}");
    let (f_up, m_up) = sweep(theta + 0.5);
    let (f_down, m_down) = sweep(theta - 0.5);
    assert!(m_up < 0.1 && m_down > 0.1, "margins {m_down}, {m_up}");
    assert!(f_down > f0 && f_up < f0, "objective {f_down}, {f0}, {f_up}");
    // the multiplier is the optimum's sensitivity to the bound: central differences of two
    // more optimisations
    let h = 0.005;
    let optimum_at = |bound: f64| {
        let (t, ..) = rotor_optimization(dir.path(), bound);
        sweep(t).0
    };
    let central = (optimum_at(0.1 + h) - optimum_at(0.1 - h)) / (2.0 * h);
    assert!(
        (multiplier - central).abs() < 1e-3 * central.abs(),
        "multiplier {multiplier}, central differences {central}"
    );
}

/// The frequencies (rad/s) of a rotating bending–torsion coupled cantilever (Euler–Bernoulli
/// flap `w` and Saint-Venant twist `φ`) at speed `omega`: strain energy
/// `½∫(EI w''² + 2 K w''φ' + GJ φ'²)` plus the centrifugal tension's `½∫T w'²` and the
/// propeller moment's `½∫Ω²(I_chord − I_thickness) φ²`; kinetic energy
/// `½∫(ρA ẇ² + (I_chord + I_thickness) φ̇²)` (the chord in the plane of rotation, the flap
/// along the spin axis). Hermite elements for `w`, linear for `φ`.
fn coupled_rotating_cantilever(
    (ei, gj, k): (f64, f64, f64),
    (rho_a, i_chord, i_thickness): (f64, f64, f64),
    length: f64,
    omega: f64,
    elements: usize,
) -> Vec<f64> {
    let n = 3 * (elements + 1);
    let h = length / elements as f64;
    let mut kk = DMatrix::<f64>::zeros(n, n);
    let mut mm = DMatrix::<f64>::zeros(n, n);
    let (g, w) = (
        [
            -0.861_136_311_594_053,
            -0.339_981_043_584_856,
            0.339_981_043_584_856,
            0.861_136_311_594_053,
        ],
        [
            0.347_854_845_137_454,
            0.652_145_154_862_546,
            0.652_145_154_862_546,
            0.347_854_845_137_454,
        ],
    );
    for e in 0..elements {
        let x0 = e as f64 * h;
        // element dofs: w0, w0', φ0, w1, w1', φ1
        let dofs = [3 * e, 3 * e + 1, 3 * e + 2, 3 * e + 3, 3 * e + 4, 3 * e + 5];
        for (&gi, &wi) in g.iter().zip(&w) {
            let s = (gi + 1.0) / 2.0;
            let x = x0 + s * h;
            let wh = wi * h / 2.0;
            // element dofs (w0, w0', φ0, w1, w1', φ1): Hermite for w, nothing for φ
            let with_twist = |x: [f64; 4]| [x[0], x[1], 0.0, x[2], x[3], 0.0];
            let [shape, slope, curvature] = hermite(s, h).map(with_twist);
            let twist = [0.0, 0.0, 1.0 - s, 0.0, 0.0, s];
            let twist_rate = [0.0, 0.0, -1.0 / h, 0.0, 0.0, 1.0 / h];
            let tension = rho_a * omega * omega * (length * length - x * x) / 2.0;
            for a in 0..6 {
                for b in 0..6 {
                    let (i, j) = (dofs[a], dofs[b]);
                    kk[(i, j)] += wh
                        * (ei * curvature[a] * curvature[b]
                            + k * (curvature[a] * twist_rate[b] + twist_rate[a] * curvature[b])
                            + gj * twist_rate[a] * twist_rate[b]
                            + tension * slope[a] * slope[b]
                            + omega * omega * (i_chord - i_thickness) * twist[a] * twist[b]);
                    mm[(i, j)] += wh
                        * (rho_a * shape[a] * shape[b]
                            + (i_chord + i_thickness) * twist[a] * twist[b]);
                }
            }
        }
    }
    let (kk, mm) = (
        kk.view((3, 3), (n - 3, n - 3)).into_owned(),
        mm.view((3, 3), (n - 3, n - 3)).into_owned(),
    );
    frequencies(kk, mm)
}

#[test]
fn a_coupled_composite_blade_spins_as_an_independent_bending_torsion_model() {
    let dir = tempfile::tempdir().unwrap();
    let shipped = common::deck("rotor_blade_composite.toml");
    let section = json(&["section", shipped.to_str().unwrap(), "--format", "json"]);
    let v = &section["sections"]["strip"]["values"];
    // the strip's classical stiffness (its transverse shear condensed): the flap–twist block
    // with the axial force and the lag moment free, the (T, M2) block of its compliance
    let classical = DMatrix::from_fn(4, 4, |i, j| {
        v["classical_stiffness"][i][j].as_f64().unwrap()
    });
    let compliance = classical.clone().try_inverse().unwrap();
    let block = DMatrix::from_fn(2, 2, |i, j| compliance[(1 + i, 1 + j)])
        .try_inverse()
        .unwrap();
    let (gj, k, ei) = (block[(0, 0)], block[(0, 1)], block[(1, 1)]);
    assert!(
        k * k / (gj * ei) > 0.3,
        "a strongly coupled section: {gj} {k} {ei}"
    );
    let rho_a = v["mass_per_length"].as_f64().unwrap();
    let (i_thickness, i_chord) = (
        v["mass_inertia"][0].as_f64().unwrap(),
        v["mass_inertia"][1].as_f64().unwrap(),
    );
    // the blade given that classical stiffness with a transverse shear 1e4 times stiffer than
    // the strip's (the Euler–Bernoulli limit of both models; with the strip's own shear the
    // beam's second and third frequencies are 2.4e-3 and 5.5e-3 lower), flat in the plane of
    // rotation
    let stiff_shear = 1e4 * v["stiffness"][2][2].as_f64().unwrap();
    let map = [0, 3, 4, 5];
    let stiffness: Vec<String> = (0..6)
        .map(|i| {
            let row: Vec<String> = (0..6)
                .map(|j| {
                    match (
                        map.iter().position(|&m| m == i),
                        map.iter().position(|&m| m == j),
                    ) {
                        (Some(a), Some(b)) => format!("{:e}", classical[(a, b)]),
                        _ if i == j => format!("{stiff_shear:e}"),
                        _ => "0.0".to_string(),
                    }
                })
                .collect();
            format!("[{}]", row.join(", "))
        })
        .collect();
    let text = std::fs::read_to_string(&shipped).unwrap();
    let start = text.find("[section.strip]").unwrap();
    let end = start + text[start..].find("[body.blade]").unwrap();
    let text = format!(
        "{}[section.strip]\nshape = \"properties\"\nstiffness = [{}]\nmass_per_length = {rho_a:e}\n\
         inertia = [{i_thickness:e}, {i_chord:e}]\n\n{}",
        &text[..start],
        stiffness.join(", "),
        &text[end..]
    )
    .replace(
        "[design.fibre_angle]\nkind = \"section-angle\"\nsection = \"strip\"\n",
        "",
    )
    .replace("end = [0.498097, 0.0, 0.043578]", "end = [0.5, 0.0, 0.0]")
    .replace("elements = 24", "elements = 96")
    .replace("node = 24", "node = 96");
    let path = dir.path().join("blade.toml");
    std::fs::write(&path, text).unwrap();
    let j = json(&[
        "static",
        path.to_str().unwrap(),
        "-o",
        dir.path().join("out").to_str().unwrap(),
        "--json",
    ]);
    let two_pi = 2.0 * std::f64::consts::PI;
    for p in j["points"].as_array().unwrap() {
        let omega = p["speed_rad_s"].as_f64().unwrap();
        let got: Vec<f64> = (p["modes"].as_array().unwrap().iter())
            .map(|m| m["frequency_hz"].as_f64().unwrap() * two_pi)
            .collect();
        let expected =
            coupled_rotating_cantilever((ei, gj, k), (rho_a, i_chord, i_thickness), 0.5, omega, 80);
        // the first four flap–twist modes (the lag modes are not in the independent model),
        // within the beam's discretisation (96 elements, lumped masses: 4e-5 to 6.3e-4, the
        // same at every speed); the twist-dominated fourth (1987 rad/s) rises by Ω²/2ω with
        // the speed through the propeller moment, 7.8e-4 at 750 rpm
        for &e in &expected[..4] {
            let nearest = got
                .iter()
                .copied()
                .min_by(|a, b| (a - e).abs().total_cmp(&(b - e).abs()))
                .unwrap();
            assert!(
                (nearest / e - 1.0).abs() < 7e-4,
                "Ω = {omega} rad/s: {nearest} rad/s, independent model {e} (all: {got:?})"
            );
        }
    }
}

#[test]
fn vtk_files_hold_the_equilibrium_mesh_and_the_modes_directions() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("blade.toml");
    std::fs::write(&path, BLADE).unwrap();
    let out = dir.path().join("out");
    let o = run(&[
        "static",
        path.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--vtk",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(out.join("modes_1_blade.vtk")).unwrap();
    assert!(text.contains("POINTS 31 double") && text.contains("CELLS 30 90"));
    // the tip's translation in a mode (node 30, the last of each vector block)
    let tip = |mode: usize| -> [f64; 3] {
        let start = text
            .find(&format!("VECTORS mode_{mode}_real double"))
            .unwrap();
        let line = text[start..].lines().nth(31).unwrap();
        let v: Vec<f64> = line
            .split_whitespace()
            .map(|x| x.parse().unwrap())
            .collect();
        [v[0], v[1], v[2]]
    };
    // at rest the strip's first mode flaps (along z, the thin direction), its second lags
    // (along y)
    let (flap, lag) = (tip(1), tip(2));
    assert!(
        flap[2].abs() > 1e3 * flap[1].abs().max(flap[0].abs()),
        "{flap:?}"
    );
    assert!(
        lag[1].abs() > 1e3 * lag[2].abs().max(lag[0].abs()),
        "{lag:?}"
    );
    // a second command without --vtk leaves no mode shapes of the first
    let o = run(&[
        "static",
        path.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success());
    assert!(!out.join("modes_1_blade.vtk").exists());
}

/// A bob (mass 2 kg, 0.01 kg·m² about its centre) on a massless arm of 0.5 m from a pin about
/// z, under gravity along −y and a side load of 5 N along x, drawn at angle `theta0` (rad)
/// from hanging, swinging at `omega0` (deg/s).
fn pendulum(theta0: f64, omega0: f64) -> String {
    let (s, c) = theta0.sin_cos();
    format!(
        r#"
title = "pendulum under a side load"
[rigid.bob]
mass = 2.0
inertia = [0.01, 0.01, 0.01]
position = [{x:?}, {y:?}, 0.0]
angular_velocity = [0.0, 0.0, {omega0:?}]
velocity = [{vx:?}, {vy:?}, 0.0]

[joint.pin]
kind = "revolute"
a = {{ body = "ground", point = [0.0, 0.0, 0.0], axis = [0.0, 0.0, 1.0] }}
b = {{ body = "bob", point = [0.0, 0.0, 0.0], axis = [0.0, 0.0, 1.0] }}

[force.gravity]
kind = "gravity"
acceleration = [0.0, -9.81, 0.0]

[force.side]
kind = "point-force"
at = {{ body = "bob", point = [{x:?}, {y:?}, 0.0] }}
value = [5.0, 0.0, 0.0]

[response.x]
kind = "position"
body = "bob"
component = "x"

[response.y]
kind = "position"
body = "bob"
component = "y"

[analysis]
t_end = 1.0
rtol = 1e-10
atol = 1e-12
"#,
        x = 0.5 * s,
        y = -0.5 * c,
        vx = 0.5 * c * omega0.to_radians(),
        vy = 0.5 * s * omega0.to_radians(),
    )
}

#[test]
fn a_pendulum_linearises_about_its_equilibrium_and_along_its_swing_as_its_angle_equation() {
    let (m, d, ic, g, f): (f64, f64, f64, f64, f64) = (2.0, 0.5, 0.01, 9.81, 5.0);
    let i_pin = ic + m * d * d;
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("pendulum.toml");
    std::fs::write(&path, pendulum(0.2, 0.0)).unwrap();
    let deck = path.to_str().unwrap();
    let out = dir.path().join("out");
    let o = out.to_str().unwrap();
    // the equilibrium: tan θ = F / (m g), I ω² = d √((m g)² + F²)
    let s = json(&["static", deck, "-o", o, "--json"]);
    let p = &s["points"][0];
    let theta = (f / (m * g)).atan();
    let x = p["responses"]["x"].as_f64().unwrap();
    assert!((x - d * theta.sin()).abs() < 1e-10, "x = {x}");
    let omega = (d * ((m * g).powi(2) + f * f).sqrt() / i_pin).sqrt();
    let hz = p["modes"][0]["frequency_hz"].as_f64().unwrap();
    assert!((hz * 2.0 * std::f64::consts::PI / omega - 1.0).abs() < 1e-9);
    // a wide swing, past the horizontal: about its state at each time the frozen equation
    // I δθ̈ = −d (m g cos θ + F sin θ) δθ, whatever the speed
    std::fs::write(&path, pendulum(0.2, 400.0)).unwrap();
    let at: Vec<f64> = (1..=9).map(|i| 0.1 * i as f64).collect();
    let list = at.iter().map(|t| format!("{t:?}")).collect::<Vec<_>>();
    let set = format!("operating.at=[{}]", list.join(", "));
    let s = json(&["static", deck, "-o", o, "--json", "--set", &set]);
    let points = s["points"].as_array().unwrap();
    assert_eq!(points.len(), at.len());
    let mut beyond_horizontal = false;
    for (p, t) in points.iter().zip(&at) {
        assert_eq!(p["time_s"].as_f64(), Some(*t));
        let (x, y) = (
            p["responses"]["x"].as_f64().unwrap(),
            p["responses"]["y"].as_f64().unwrap(),
        );
        let theta = x.atan2(-y);
        beyond_horizontal |= theta.cos() < 0.0;
        let k = d * (m * g * theta.cos() + f * theta.sin());
        let mode = &p["modes"][0];
        let s = mode["frequency_hz"].as_f64().unwrap() * 2.0 * std::f64::consts::PI;
        // (relative to the stiffness's scale: it passes through zero)
        let scale = d * (m * g).hypot(f) / i_pin;
        assert!(
            (s * s - k.abs() / i_pin).abs() < 1e-9 * scale,
            "t = {t}: |s| = {s}, closed form {}",
            (k.abs() / i_pin).sqrt()
        );
        // a restoring stiffness oscillates, a negative one diverges (a real eigenvalue)
        let damped = mode["damped_frequency_hz"].as_f64().unwrap();
        assert_eq!(damped > 0.0, k > 0.0, "t = {t}, k = {k}");
    }
    assert!(beyond_horizontal, "the swing stays below the horizontal");
    let csv = std::fs::read_to_string(out.join("frequencies.csv")).unwrap();
    assert!(csv.starts_with("time [s],mode,"), "{csv}");
    assert!(out.join("frequencies.svg").exists() && !out.join("campbell.svg").exists());
    // the times within the run, and alone of the keys that choose the operating points
    for (set, key, says) in [
        (
            "operating.at=[0.5, 2.0]",
            "operating.at.1",
            "outside the analysis's span",
        ),
        ("operating.at=[0.5, 0.4]", "operating.at.1", "must increase"),
        (
            "operating.time=0.1",
            "operating.at",
            "cannot be given with it",
        ),
    ] {
        let mut args = vec!["static", deck, "-o", o, "--set", "operating.at=[0.5]"];
        args.extend(["--set", set]);
        let r = run(&args);
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(
            !r.status.success() && err.contains(key) && err.contains(says),
            "{set}: {err}"
        );
    }
}

#[test]
fn a_spinning_tips_acceleration_is_centripetal_and_its_derivative_equals_differences() {
    let dir = tempfile::tempdir().unwrap();
    let tip = |angle: f64| -> Vec<(f64, f64)> {
        let deck = rotor(angle)
            + "
[response.tip_ax]
kind = \"point-acceleration\"
at = { body = \"rod\", node = 24 }
component = \"x\"
";
        let path = dir.path().join("tip.toml");
        std::fs::write(&path, deck).unwrap();
        let out = dir.path().join("tip");
        let j = json(&[
            "static",
            path.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--json",
        ]);
        (j["points"].as_array().unwrap().iter())
            .map(|p| {
                (
                    p["responses"]["tip_ax"].as_f64().unwrap(),
                    p["gradients"]["tip_ax"]["theta"].as_f64().unwrap(),
                )
            })
            .collect()
    };
    let nominal = tip(15.0);
    // the derivative comes from the centrifugal stretch alone (~1e-3 of the acceleration):
    // a step large enough that the model's noise (~1e-8 of the value) stays below it
    let h = 0.5;
    let (up, down) = (tip(15.0 + h), tip(15.0 - h));
    for (k, rpm) in [0.0f64, 3000.0, 6000.0].iter().enumerate() {
        let w = rpm * std::f64::consts::PI / 30.0;
        let (a, da) = nominal[k];
        // the tip, 0.3 m out (stretched by up to ~0.1 mm at 6000 rpm), turns about the hub
        assert!(
            (a + w * w * 0.3).abs() <= 2e-3 * (w * w * 0.3) + 1e-9,
            "{rpm} rpm: {a}"
        );
        let fd = (up[k].0 - down[k].0) / (2.0 * h);
        assert!(
            (da - fd).abs() <= 1e-3 * fd.abs() + 1e-9 * w * w + 1e-9,
            "{rpm} rpm: d/dθ {da}, central differences {fd}"
        );
    }
}
