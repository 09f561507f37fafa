//! The flexible slider-crank (the benchmark's model) runs and stays close to the rigid
//! kinematics: the rod is stiff, so the slider follows the closed form to within the small
//! elastic deflection.

mod common;

use common::{CRANK, ROD, assembled, slider_crank, slider_exact};
use mbs::{BdfOptions, simulate};

#[test]
fn flexible_slider_crank_follows_the_rigid_kinematics_closely() {
    let omega = 150.0;
    let (model, state, slider) = slider_crank(omega, Some(4));
    let (mut sys, state) = assembled(model, state);
    let t_out: Vec<f64> = (0..=100).map(|i| 1e-3 * i as f64).collect();
    let sim = simulate(&mut sys, &state, &t_out, BdfOptions::adaptive(1e-8, 1e-10)).unwrap();
    let mut worst: f64 = 0.0;
    let mut max_w: f64 = 0.0;
    for o in &sim.outputs {
        let [x, _, _] = slider_exact(omega * o.t, omega);
        worst = worst.max((o.positions[slider.index()].x - x).abs());
        max_w = o.modal[1].iter().fold(max_w, |m, w| m.max(w.abs()));
    }
    let violation = sim
        .outputs
        .iter()
        .map(|o| o.position_violation)
        .fold(0.0, f64::max);
    eprintln!(
        "slider deviation {worst:e} m, max |w| {max_w:e}, violation {violation:e}; {:?}",
        sim.statistics
    );
    assert!(max_w > 0.0, "the rod must deform");
    assert!(
        worst < 1e-4 * (CRANK + ROD),
        "slider deviates by {worst:e} m"
    );
    assert!(violation < 1e-6);
}
