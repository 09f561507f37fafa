//! A marker point's kinematics on a flexible body: the tip node of a driven, vibrating beam —
//! its position against the frame and the nodal displacement composed by hand, its velocity
//! and acceleration against central differences in time of the run's dense output.

use mbs::{
    BdfOptions, Marker, Model, MultibodySystem, RedundancyPolicy, Response, TimeFunction, simulate,
};
use nalgebra::Vector3;

mod common;

/// A beam along x (1 m, `EI` 100 and 400 in its two planes, unit mass per length) clamped at
/// its root node to a hub on z that an angle driver spins up at 2 rad/s², under gravity along
/// −y.
fn spun_beam() -> (Model<f64>, mbs::State, mbs::BodyId) {
    let mut model = Model::new();
    model.gravity = Vector3::new(0.0, -9.81, 0.0);
    let beam = model
        .add_flexible_body(common::fem_cantilever(12, 4, [100.0, 400.0], false))
        .unwrap();
    common::drive_about_z(
        &mut model,
        beam,
        TimeFunction::Polynomial(vec![0.0, 0.0, 1.0]),
    );
    let state = model.rest_state();
    (model, state, beam)
}

#[test]
fn a_tip_node_moves_as_its_frame_and_deformation_and_its_rates_are_the_time_derivatives() {
    let (model, mut state, beam) = spun_beam();
    let mut sys = MultibodySystem::new(model.clone(), &state, RedundancyPolicy::Remove).unwrap();
    sys.assemble(0.0, &mut state, 1e-12).unwrap();
    let tip = 12;
    let point = |order: usize, axis: usize| Response::MarkerPoint {
        marker: Marker::node(beam, tip),
        relative_to: None,
        order,
        axis,
    };
    let h = 1e-5;
    let times = [0.0, 0.6 - h, 0.6, 0.6 + h, 1.1 - h, 1.1, 1.1 + h];
    let sim = simulate(&mut sys, &state, &times, BdfOptions::adaptive(1e-11, 1e-13)).unwrap();
    let value =
        |k: usize, order: usize, axis: usize| point(order, axis).value(&model, &sim.outputs[k]);
    for centre in [2, 5] {
        let o = &sim.outputs[centre];
        // r + A (x₀ + u)
        let x0 = Vector3::x();
        let u = o.nodal_displacements[0][tip];
        let p = o.positions[0] + o.orientations[0] * (x0 + Vector3::new(u[0], u[1], u[2]));
        assert!(u[1].abs() > 1e-4, "the beam bends: {u:?}");
        for axis in 0..3 {
            assert!(
                (value(centre, 0, axis) - p[axis]).abs() < 1e-12,
                "axis {axis}"
            );
            // central differences in time of the dense output
            let d1 = (value(centre + 1, 0, axis) - value(centre - 1, 0, axis)) / (2.0 * h);
            let v = value(centre, 1, axis);
            assert!(
                (v - d1).abs() < 1e-5 * (1.0 + v.abs()),
                "velocity {axis}: {v} vs {d1}"
            );
            let d2 = (value(centre + 1, 1, axis) - value(centre - 1, 1, axis)) / (2.0 * h);
            let a = value(centre, 2, axis);
            assert!(
                (a - d2).abs() < 1e-4 * (1.0 + a.abs()),
                "acceleration {axis}: {a} vs {d2}"
            );
        }
        // relative to the hub's centre (a ground point on the axis): the same
        let rel = Response::MarkerPoint {
            marker: Marker::node(beam, tip),
            relative_to: Some(Marker::ground(Vector3::new(0.0, 0.0, 0.5))),
            order: 0,
            axis: 2,
        };
        assert!((rel.value(&model, o) - (p.z - 0.5)).abs() < 1e-12);
    }
}
