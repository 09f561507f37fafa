//! Joint actuators in a deck: a pinned arm driven by a PD torque (`kind = "joint-torque"`)
//! tracking a ramp against its closed-form response (angle, torque and power), by a tabulated
//! torque against its double integral, the torque's sensitivity to the arm's mass against the
//! run's replayed central differences; a block on a guide driven by a PD force
//! (`"joint-force"`) and by a tabulated one against the closed forms, with the position's
//! sensitivity to the mass; and the errors of malformed actuators naming their keys.

mod common;

/// A slender arm (0.4 m, 1.5 kg) pinned to the ground at the origin about z, no gravity, with
/// the actuator `law` (the keys after `kind`, `a`, `b`) between the ground and the arm at the
/// pin; its centre's position as responses.
fn arm_deck(law: &str, t_end: f64) -> String {
    format!(
        r#"title = "pinned arm with an actuator"

[rigid.arm]
mass = 1.5
inertia = [1.0e-6, 0.02, 0.02]
position = [0.2, 0.0, 0.0]

[joint.pin]
kind = "revolute"
a = {{ body = "ground", point = [0.0, 0.0, 0.0], axis = [0.0, 0.0, 1.0] }}
b = {{ body = "arm", point = [0.0, 0.0, 0.0], axis = [0.0, 0.0, 1.0] }}

[force.motor]
kind = "joint-torque"
a = {{ body = "ground", point = [0.0, 0.0, 0.0], axis = [0.0, 0.0, 1.0], reference = [1.0, 0.0, 0.0] }}
b = {{ body = "arm", point = [0.0, 0.0, 0.0], axis = [0.0, 0.0, 1.0], reference = [1.0, 0.0, 0.0] }}
{law}

[response.x]
kind = "position"
body = "arm"
component = "x"

[response.y]
kind = "position"
body = "arm"
component = "y"

[response.torque]
kind = "actuator-torque"
force = "motor"

[response.power]
kind = "actuator-power"
force = "motor"

[analysis]
t_end = {t_end}
output_step = 0.01
rtol = 1.0e-9
atol = 1.0e-12
"#
    )
}

/// The arm's angle at the end of a run of `deck`, the actuator's torque and power then.
fn final_state(deck: &str) -> (f64, f64, f64) {
    let doc = common::run_deck_json(deck);
    let r = |n: &str| doc["responses"][n]["final"].as_f64().unwrap();
    (r("y").atan2(r("x")), r("torque"), r("power"))
}

/// The arm's angle at the end of a run of `deck`.
fn final_angle(deck: &str) -> f64 {
    final_state(deck).0
}

/// The arm's moment of inertia about the pin (kg·m²).
const J: f64 = 0.02 + 1.5 * 0.2 * 0.2;

#[test]
fn a_pd_actuator_in_a_deck_tracks_a_ramp_as_the_closed_form() {
    // J ë + kd ė + kp e = 0 for e = f − θ, e(0) = 0, ė(0) = ω: θ = ω t − e
    let (kp, kd, rate_deg): (f64, f64, f64) = (5.0, 0.2, 60.0);
    let law = format!(
        "control = {{ kind = \"pd\", kp = {kp}, kd = {kd}, motion = {{ kind = \"constant-speed\", \
         initial = 0.0, rate = {rate_deg} }} }}"
    );
    let omega = rate_deg.to_radians();
    let (wn, zeta) = ((kp / J).sqrt(), kd / (2.0 * (kp * J).sqrt()));
    let wd = wn * (1.0 - zeta * zeta).sqrt();
    for t in [0.3, 0.7] {
        let decay = (-zeta * wn * t).exp();
        let e = omega / wd * decay * (wd * t).sin();
        let e_dot = omega * decay * ((wd * t).cos() - zeta * wn / wd * (wd * t).sin());
        let (got, torque, power) = final_state(&arm_deck(&law, t));
        assert!(
            (got - (omega * t - e)).abs() < 1e-6,
            "t = {t}: θ {got} against {}",
            omega * t - e
        );
        let tau = kp * e + kd * e_dot;
        assert!(
            (torque - tau).abs() < 1e-6,
            "t = {t}: τ {torque} against {tau}"
        );
        let p = tau * (omega - e_dot);
        assert!(
            (power - p).abs() < 1e-6,
            "t = {t}: power {power} against {p}"
        );
        // the error is a visible part of the angle
        assert!(e.abs() > 0.05 * omega * t, "{e}");
    }
}

#[test]
fn the_actuator_torques_sensitivity_to_the_arms_mass_matches_central_differences() {
    let law = "control = { kind = \"pd\", kp = 5.0, kd = 0.2, motion = { kind = \"constant-speed\", \
               initial = 0.0, rate = 60.0 } }";
    let deck = arm_deck(law, 0.5)
        + "\n[design.m]\nkind = \"rigid-mass\"\nbody = \"arm\"\n\n[finite_differences]\n\
           scheme = \"central\"\nsizes = [0.0001]\nsteps = \"replay\"\n";
    let doc = common::run_deck_json(&deck);
    // a mechanism of rigid bodies has no modes to update
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("arm.toml");
    std::fs::write(&path, &deck).unwrap();
    let o = common::run(&[
        "run",
        path.to_str().unwrap(),
        "-o",
        dir.path().join("out").to_str().unwrap(),
    ]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("sensitivities with respect to m = 1.5 kg\n"),
        "{text}"
    );
    let fd = &doc["finite_differences"][0]["max_relative_difference"];
    for r in ["torque", "power"] {
        let d = fd[r].as_f64().unwrap();
        assert!(d < 1e-5, "{r}: |FD − direct| / max |direct| = {d:e}");
    }
}

#[test]
fn a_tabulated_actuator_torque_turns_the_arm_by_its_double_integral() {
    // τ rises linearly from 0 to 0.4 N·m over 0.5 s: θ = τ' t³ / (6 J)
    let law = "torque = { times = [0.0, 0.5], values = [0.0, 0.4] }";
    let got = final_angle(&arm_deck(law, 0.5));
    let exact = 0.8 * 0.5f64.powi(3) / (6.0 * J);
    assert!((got - exact).abs() < 1e-7, "{got} against {exact}");
    // a constant torque: θ = τ t² / (2 J)
    let got = final_angle(&arm_deck("torque = 0.1", 0.5));
    let exact = 0.1 * 0.25 / (2.0 * J);
    assert!((got - exact).abs() < 1e-7, "{got} against {exact}");
}

#[test]
fn a_malformed_actuator_names_its_key() {
    let cases = [
        (
            "torque = 0.1\n[response.bad]\nkind = \"actuator-torque\"\nforce = \"motr\"",
            "response.bad.force",
            "not an actuator",
        ),
        (
            "torque = 0.1\ncontrol = { kind = \"pd\", kp = 1.0, kd = 0.0, motion = { kind = \"constant-speed\", initial = 0.0, rate = 1.0 } }",
            "force.motor.control",
            "either torque or control",
        ),
        ("", "force.motor.torque", "missing torque"),
        (
            "torque = { times = [0.0, 0.0], values = [1.0, 2.0] }",
            "force.motor.torque",
            "strictly increasing",
        ),
        (
            "torque = { times = [0.0, 1.0], values = [1.0] }",
            "force.motor.torque",
            "1 values for 2 times",
        ),
        (
            "control = { kind = \"pid\", kp = 1.0, kd = 0.0, motion = { kind = \"constant-speed\", initial = 0.0, rate = 1.0 } }",
            "force.motor.control.kind",
            "pd",
        ),
        (
            "control = { kind = \"pd\", kp = -1.0, kd = 0.0, motion = { kind = \"constant-speed\", initial = 0.0, rate = 1.0 } }",
            "force.motor.control.kp",
            "must not be negative",
        ),
        (
            "control = { kind = \"pd\", kp = 1.0, motion = { kind = \"constant-speed\", initial = 0.0, rate = 1.0 } }",
            "force.motor.control.kd",
            "kd",
        ),
    ];
    for (law, key, what) in cases {
        let (_dir, err) =
            common::bad_deck(&arm_deck(law, 0.1), |p| common::with_deck("run", p, &[]));
        assert!(err.contains(key) && err.contains(what), "{law}:\n{err}");
    }
    // both markers on one body
    let deck = arm_deck("torque = 0.1", 0.1).replace(
        "a = { body = \"ground\", point = [0.0, 0.0, 0.0], axis = [0.0, 0.0, 1.0], reference",
        "a = { body = \"arm\", point = [0.0, 0.0, 0.0], axis = [0.0, 0.0, 1.0], reference",
    );
    let (_dir, err) = common::bad_deck(&deck, |p| common::with_deck("run", p, &[]));
    assert!(
        err.contains("force.motor.b") && err.contains("both on `arm`"),
        "{err}"
    );
}

/// A 2 kg block on a frictionless guide along x from the origin, no gravity, with the linear
/// actuator `law` (the keys after `kind`, `a`, `b`) between the ground and the block along the
/// guide; its position, the actuator's force and power as responses.
fn slider_deck(law: &str, t_end: f64) -> String {
    format!(
        r#"title = "a block driven along a guide"

[rigid.block]
mass = 2.0
inertia = [0.01, 0.01, 0.01]
position = [0.0, 0.0, 0.0]

[joint.guide]
kind = "translational"
a = {{ body = "ground", point = [0.0, 0.0, 0.0], axis = [1.0, 0.0, 0.0] }}
b = {{ body = "block", point = [0.0, 0.0, 0.0], axis = [1.0, 0.0, 0.0] }}

[force.ram]
kind = "joint-force"
a = {{ body = "ground", point = [0.0, 0.0, 0.0], axis = [1.0, 0.0, 0.0] }}
b = {{ body = "block", point = [0.0, 0.0, 0.0], axis = [1.0, 0.0, 0.0] }}
{law}

[response.x]
kind = "position"
body = "block"
component = "x"

[response.force]
kind = "actuator-force"
force = "ram"

[response.power]
kind = "actuator-power"
force = "ram"

[analysis]
t_end = {t_end}
output_step = 0.01
rtol = 1.0e-9
atol = 1.0e-12
"#
    )
}

/// The block's mass (kg).
const M: f64 = 2.0;

/// A PD ram tracking a constant speed: `m ë + kd ė + kp e = 0` for the error `e = f − x`,
/// `e(0) = 0`, `ė(0) = v`; the block's position, the force and the power as the closed form.
#[test]
fn a_pd_linear_actuator_tracks_a_constant_speed_as_the_closed_form() {
    let (kp, kd, v): (f64, f64, f64) = (800.0, 8.0, 0.3);
    let law = format!(
        "control = {{ kind = \"pd\", kp = {kp}, kd = {kd}, motion = {{ kind = \"constant-speed\", \
         initial = 0.0, rate = {v} }} }}"
    );
    let (wn, zeta) = ((kp / M).sqrt(), kd / (2.0 * (kp * M).sqrt()));
    let wd = wn * (1.0 - zeta * zeta).sqrt();
    for t in [0.05, 0.2] {
        let decay = (-zeta * wn * t).exp();
        let e = v / wd * decay * (wd * t).sin();
        let e_dot = v * decay * ((wd * t).cos() - zeta * wn / wd * (wd * t).sin());
        let doc = common::run_deck_json(&slider_deck(&law, t));
        let r = |n: &str| doc["responses"][n]["final"].as_f64().unwrap();
        assert!(
            (r("x") - (v * t - e)).abs() < 1e-8,
            "t = {t}: x {} against {}",
            r("x"),
            v * t - e
        );
        let force = kp * e + kd * e_dot;
        assert!(
            (r("force") - force).abs() < 1e-6,
            "t = {t}: F {} against {force}",
            r("force")
        );
        let power = force * (v - e_dot);
        assert!(
            (r("power") - power).abs() < 1e-6,
            "t = {t}: P {} against {power}",
            r("power")
        );
        assert!(
            e.abs() > 0.05 * v * t,
            "the error is a visible part of the motion: {e}"
        );
    }
}

/// A tabulated force rising from 0 to 4 N over 0.5 s moves the block by `F' t³ / 6m`; its
/// sensitivity to the block's mass (`−x / m`) equals replayed central differences.
#[test]
fn a_tabulated_linear_actuator_moves_the_block_by_its_double_integral() {
    let law = "force = { times = [0.0, 0.5], values = [0.0, 4.0] }";
    let deck = slider_deck(law, 0.5)
        + "\n[design.m]\nkind = \"rigid-mass\"\nbody = \"block\"\n\n[objective.x_end]\n\
           response = \"x\"\nkind = \"at\"\ntime = 0.5\n\n[finite_differences]\n\
           scheme = \"central\"\nsizes = [0.0001]\nsteps = \"replay\"\n";
    let doc = common::run_deck_json(&deck);
    let x = doc["responses"]["x"]["final"].as_f64().unwrap();
    let exact = 8.0 * 0.5f64.powi(3) / (6.0 * M);
    assert!((x - exact).abs() < 1e-8, "{x} against {exact}");
    let gradient = doc["objectives"][0]["gradient"][0].as_f64().unwrap();
    assert!(
        (gradient / (-exact / M) - 1.0).abs() < 1e-6,
        "{gradient} against {}",
        -exact / M
    );
    let d = doc["finite_differences"][0]["max_relative_difference"]["x"]
        .as_f64()
        .unwrap();
    assert!(d < 1e-5, "|FD − direct| / max |direct| = {d:e}");
}

/// A linear actuator's keys are checked as a torque's: the other kind's key, a torque
/// response of a force.
#[test]
fn a_malformed_linear_actuator_names_its_key() {
    let cases = [
        (
            "torque = 1.0",
            "force.ram.torque",
            "takes `force`, not `torque`",
        ),
        ("", "force.ram.force", "missing force"),
        (
            "force = 1.0\n[response.bad]\nkind = \"actuator-torque\"\nforce = \"ram\"",
            "response.bad.force",
            "not an actuator of its kind",
        ),
    ];
    for (law, key, what) in cases {
        let (_dir, err) =
            common::bad_deck(&slider_deck(law, 0.1), |p| common::with_deck("run", p, &[]));
        assert!(err.contains(key) && err.contains(what), "{law}:\n{err}");
    }
}

/// The arm's angle at `t` under the PD law (closed form, as in
/// `a_pd_actuator_in_a_deck_tracks_a_ramp_as_the_closed_form`).
fn pd_angle(kp: f64, kd: f64, omega: f64, t: f64) -> f64 {
    let (wn, zeta) = ((kp / J).sqrt(), kd / (2.0 * (kp * J).sqrt()));
    let wd = wn * (1.0 - zeta * zeta).sqrt();
    omega * t - omega / wd * (-zeta * wn * t).exp() * (wd * t).sin()
}

/// The PD gains as design variables: the arm's height at 0.5 s has the derivatives of the
/// closed form (differentiated here by central differences of that formula), and the run's
/// sensitivities equal replayed central differences of whole runs.
#[test]
fn the_pd_gains_sensitivities_are_the_closed_forms() {
    let (kp, kd, rate_deg, t) = (5.0, 0.2, 60.0f64, 0.5);
    let law = format!(
        "control = {{ kind = \"pd\", kp = {kp}, kd = {kd}, motion = {{ kind = \"constant-speed\", \
         initial = 0.0, rate = {rate_deg} }} }}"
    );
    let deck = arm_deck(&law, t)
        + "\n[design.kp]\nkind = \"actuator-gain\"\nforce = \"motor\"\ngain = \"kp\"\n\n\
           [design.kd]\nkind = \"actuator-gain\"\nforce = \"motor\"\ngain = \"kd\"\n\n\
           [objective.height]\nresponse = \"y\"\nkind = \"at\"\ntime = 0.5\n\n\
           [finite_differences]\nscheme = \"central\"\nsizes = [0.0001]\nsteps = \"replay\"\n";
    let doc = common::run_deck_json(&deck);
    let omega = rate_deg.to_radians();
    let height = |kp: f64, kd: f64| 0.2 * pd_angle(kp, kd, omega, t).sin();
    let h = 1e-6;
    let exact = [
        ("kp", (height(kp + h, kd) - height(kp - h, kd)) / (2.0 * h)),
        ("kd", (height(kp, kd + h) - height(kp, kd - h)) / (2.0 * h)),
    ];
    let design = doc["design"].as_array().unwrap();
    let index = |name: &str| design.iter().position(|d| d["name"] == name).unwrap();
    let gradient = &doc["objectives"][0]["gradient"];
    for (name, e) in exact {
        let got = gradient[index(name)].as_f64().unwrap();
        assert!(
            (got / e - 1.0).abs() < 1e-5,
            "{name}: {got:e} against {e:e}"
        );
    }
    let fd = &doc["finite_differences"][0]["max_relative_difference"];
    for r in ["y", "torque", "power"] {
        let d = fd[r].as_f64().unwrap();
        assert!(d < 1e-5, "{r}: |FD − direct| / max |direct| = {d:e}");
    }
    // the variables are the deck's gains, with their units
    assert_eq!(design[index("kp")]["value"].as_f64(), Some(kp));
    assert_eq!(design[index("kd")]["unit"].as_str(), Some("N*m*s/rad"));
}

/// A gain variable names an actuator with a PD law, and its gain.
#[test]
fn a_gain_variable_is_checked() {
    let law = "control = { kind = \"pd\", kp = 5.0, kd = 0.2, motion = { kind = \"constant-speed\", \
               initial = 0.0, rate = 60.0 } }";
    let cases = [
        (
            law,
            "force = \"motr\"\ngain = \"kp\"",
            "design.g.force",
            "undefined force",
        ),
        (
            law,
            "force = \"motor\"\ngain = \"ki\"",
            "design.g.gain",
            "unknown gain",
        ),
        (
            "torque = 0.1",
            "force = \"motor\"\ngain = \"kp\"",
            "design.g.force",
            "has no kp",
        ),
    ];
    for (law, keys, key, what) in cases {
        let deck =
            arm_deck(law, 0.1) + &format!("\n[design.g]\nkind = \"actuator-gain\"\n{keys}\n");
        let (_dir, err) = common::bad_deck(&deck, |p| common::with_deck("check", p, &[]));
        assert!(err.contains(key) && err.contains(what), "{keys}:\n{err}");
    }
}
