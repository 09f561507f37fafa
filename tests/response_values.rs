//! `mbs::Response::value` (read from a recorded output) equals `Response::evaluate` (computed
//! from the state, the path of the sensitivities) for every response that has both, on the
//! flexible slider-crank in motion; the value-only responses read the output's own fields.

use flexsens_tests::{RodOptions, assembled, slider_crank};
use mbs::{BdfOptions, Response, simulate};

#[test]
fn output_values_equal_state_evaluations() {
    let (model, state, ids) = slider_crank(&[15.0; 4], &RodOptions::default());
    let (mut sys, state) = assembled(model, state);
    let times = [0.0, 0.004, 0.008];
    let sim = simulate(&mut sys, &state, &times, BdfOptions::adaptive(1e-6, 1e-9)).unwrap();
    let model = sys.model();
    let nq = model.n_q();
    let responses = [
        ids.mid_deflection(),
        Response::BodyPosition {
            body: ids.slider,
            axis: 0,
        },
        Response::NodalDisplacement {
            body: ids.rod,
            node: ids.rod_mid,
            dof: 1,
        },
        Response::ReactionForce {
            joint: ids.wrist_pin,
            axis: 1,
        },
        Response::State(model.q_range(ids.rod).start + 7),
        Response::State(nq + model.v_range(ids.crank).start + 5),
    ];
    let mut moved = 0.0f64;
    for o in &sim.outputs {
        for r in &responses {
            assert!(r.differentiable());
            let a = r.value(model, o);
            let b = r.evaluate(model, o.t, &o.q, &o.v, &o.lambda).unwrap();
            assert!(
                (a - b).abs() <= 1e-12 * b.abs().max(1e-9),
                "{r:?} at t = {}: {a:e} vs {b:e}",
                o.t
            );
        }
        moved = moved.max(ids.mid_deflection().value(model, o).abs());
        // value-only responses: read from the output, refused by `evaluate`
        let joint = ids.wrist_pin;
        for (r, expected) in [
            (
                Response::ReactionMoment { joint, axis: 2 },
                o.reactions[joint.index()].moment_on_b[2],
            ),
            (Response::Energy, o.energy.total()),
            (Response::ConstraintViolation, o.position_violation),
        ] {
            assert!(!r.differentiable());
            assert_eq!(r.value(model, o), expected);
            assert!(r.evaluate(model, o.t, &o.q, &o.v, &o.lambda).is_err());
        }
    }
    // the rod deflects, so the comparison is not of zeros
    assert!(moved > 1e-5, "{moved:e}");
}
