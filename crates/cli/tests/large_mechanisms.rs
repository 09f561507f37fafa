//! A mechanism above the size where Eq. (12) and the Newton matrix are solved by their
//! structure (body blocks, Schur complement, sparse Newton system; docs/performance.md), run
//! as a user writes it: a chain of eight composite tubes pinned end to end and falling under
//! gravity, whose direct sensitivities to the ply angle match the run's replayed central
//! differences as on the dense path.

mod common;

/// `n` tubes of 0.3 m (a [30°]₂ carbon–epoxy wall, four elements, four eigenmodes), the first
/// pinned to the ground, each to the end of the one before, all pins about z; gravity along
/// −y; the first tube's mid-node deflection and the last tube's height as responses. Uniform
/// error weights: the last tube's height has a small derivative (its free fall does not depend
/// on the lay-up), which the state's Newton errors in the rates, looser under displacement
/// weights, move by 5e-2 against replayed differences (docs/design.md §3).
fn chain_deck(n: usize) -> String {
    let mut deck = String::from(
        r#"title = "chain of composite tubes"

[material.cfrp]
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

[laminate.wall]
plies = [
  { material = "cfrp", thickness = 0.5e-3, angle = 30.0 },
  { material = "cfrp", thickness = 0.5e-3, angle = 30.0 },
]

[section.tube]
shape = "tube"
inner_radius = 4.0e-3
laminate = "wall"
elements_around = 16

[force.g]
kind = "gravity"
acceleration = [0.0, -9.81, 0.0]
"#,
    );
    for i in 0..n {
        let a = if i == 0 {
            r#"body = "ground", point = [0.0, 0.0, 0.0]"#.to_string()
        } else {
            format!(r#"body = "b{}", node = 4"#, i - 1)
        };
        deck += &format!(
            r#"
[body.b{i}]
kind = "beam"
section = "tube"
start = [{x0}, 0.0, 0.0]
end = [{x1}, 0.0, 0.0]
orientation = [0.0, 1.0, 0.0]
elements = 4
planar = [0.0, 0.0, 1.0]
modes = 4
basis = "modes"
damping = {{ modes = [1, 4], ratios = [0.02, 0.02] }}

[joint.pin{i}]
kind = "revolute"
a = {{ {a}, axis = [0.0, 0.0, 1.0] }}
b = {{ body = "b{i}", node = 0, axis = [0.0, 0.0, 1.0] }}
"#,
            x0 = 0.3 * i as f64,
            x1 = 0.3 * (i + 1) as f64,
        );
    }
    deck += &format!(
        r#"
[response.deflection]
kind = "mid-node-deflection"
body = "b0"

[response.tip_y]
kind = "position"
body = "b{}"
component = "y"

[design.theta]
laminate = "wall"

[finite_differences]
scheme = "central"
sizes = [0.0001]
steps = "replay"

[analysis]
t_end = 0.2
output_step = 0.01
rtol = 1.0e-9
atol = 1.0e-12
error_weights = "uniform"
"#,
        n - 1
    );
    deck
}

#[test]
fn a_chain_of_eight_tubes_has_sensitivities_that_match_central_differences() {
    let doc = common::run_deck_json(&chain_deck(8));
    // the tip of a chain released from the horizontal falls freely at first: ½ g t²
    let tip = doc["responses"]["tip_y"]["final"].as_f64().unwrap();
    assert!((tip + 0.5 * 9.81 * 0.04).abs() < 1e-4, "tip {tip}");
    // measured 1.3e-5 and 1.1e-5 (the dense path: 1.4e-5 and 1.1e-5), at the differences'
    // noise
    let fd = &doc["finite_differences"][0]["max_relative_difference"];
    for r in ["deflection", "tip_y"] {
        let d = fd[r].as_f64().unwrap();
        assert!(d < 1e-4, "{r}: |FD − direct| / max |direct| = {d:e}");
    }
}
