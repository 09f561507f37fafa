//! `fem`'s own Timoshenko beam reduced to a `ModalBody` (clamped at its centre of mass, the
//! paper's reference condition) in the multibody layer: with the body frame clamped to the
//! ground, each half is a cantilever; a suddenly applied tip load makes it oscillate about
//! the closed-form Timoshenko static deflection with the first natural frequency.

use fem::{BeamSection, Mesh, ModalOptions, Properties, modal_analysis, modal_body};
use mbs::{
    BdfOptions, FlexibleBody, Force, Joint, JointKind, Load, LoadFrame, Marker, Model,
    MultibodySystem, RedundancyPolicy, simulate,
};
use nalgebra::{Matrix3, Vector3};

#[test]
fn fem_beam_half_cantilever_oscillates_about_the_timoshenko_static_deflection() {
    // aluminium bar 1 m, 20 mm (along y) × 10 mm (along z): weak-axis bending in x–z
    let (e, nu, rho, hy, hz) = (70e9, 0.3, 2700.0, 0.02, 0.01);
    let (a, g, kappa) = (hy * hz, e / (2.0 * (1.0 + nu)), 5.0 / 6.0);
    let i2 = hy * hz * hz * hz / 12.0; // about y
    let i3 = hz * hy * hy * hy / 12.0;
    let section = BeamSection::diagonal(
        [
            e * a,
            kappa * g * a,
            kappa * g * a,
            g * (i2 + i3),
            e * i2,
            e * i3,
        ],
        rho * a,
        rho * i2,
        rho * i3,
    );
    let props = Properties {
        sections: vec![section],
        laminates: vec![],
    };
    let n = 20;
    let mesh = Mesh::straight_beam(
        Vector3::zeros(),
        Vector3::new(1.0, 0.0, 0.0),
        n,
        0,
        Vector3::y(),
    )
    .unwrap();
    let analysis = modal_analysis(&mesh, &props, &ModalOptions::new(10)).unwrap();
    let modal = modal_body(&mesh, &props, &analysis).unwrap();
    let centre = n / 2;
    assert!(
        modal.node_positions[centre].norm() < 1e-12,
        "frame at the centre node"
    );

    let mut model = Model::new();
    let b = model
        .add_flexible_body(FlexibleBody::new("bar", modal.clone()))
        .unwrap();
    model
        .add_joint(Joint::new(
            "clamp",
            JointKind::Fixed,
            Marker::ground(Vector3::new(0.5, 0.0, 0.0)),
            Marker::on(b, Vector3::zeros()),
        ))
        .unwrap();
    let p = 20.0;
    model
        .add_force(Force::PointForce {
            marker: Marker::node(b, n),
            load: Load::Constant(Vector3::new(0.0, 0.0, p)),
            frame: LoadFrame::Global,
        })
        .unwrap();
    let mut state = model.rest_state();
    model.set_pose(
        &mut state,
        b,
        Vector3::new(0.5, 0.0, 0.0),
        &Matrix3::identity(),
    );
    let mut sys = MultibodySystem::new(model, &state, RedundancyPolicy::Remove).unwrap();
    sys.assemble(0.0, &mut state, 1e-13).unwrap();

    // closed forms for a cantilever of length l = 0.5
    let l: f64 = 0.5;
    let static_tip = p * l.powi(3) / (3.0 * e * i2) + p * l / (kappa * g * a);
    let omega1 = modal.eigenvalues[0].sqrt();
    let omega1_eb = 1.875_104_068_7_f64.powi(2) * (e * i2 / (rho * a * l.powi(4))).sqrt();
    assert!(
        (omega1 / omega1_eb - 1.0).abs() < 0.01,
        "ω1 {omega1} vs Euler–Bernoulli {omega1_eb}"
    );
    // the centre of the undamped modal oscillation: Σ X_tip X_tipᵀ F / ω_i²
    let modal_static: f64 = (0..modal.n_modes())
        .map(|i| modal.modes[(6 * n + 2, i)].powi(2) * p / modal.eigenvalues[i])
        .sum();
    assert!(
        (modal_static / static_tip - 1.0).abs() < 5e-3,
        "modal static {modal_static} vs {static_tip}"
    );
    let period = 2.0 * std::f64::consts::PI / omega1;
    let t_out: Vec<f64> = (0..=600).map(|i| 3.0 * period * i as f64 / 600.0).collect();
    let sim = simulate(&mut sys, &state, &t_out, BdfOptions::adaptive(1e-8, 1e-12)).unwrap();
    let tip = |o: &mbs::Output| o.nodal_displacements[0][n][2];
    let last: Vec<f64> = sim.outputs[400..].iter().map(tip).collect();
    let (lo, hi) = last
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
            (a.min(x), b.max(x))
        });
    let mid = 0.5 * (lo + hi);
    eprintln!(
        "mid-range {mid:e}, static {static_tip:e}, amplitude {:e}; {:?}",
        hi - lo,
        sim.statistics
    );
    assert!(
        (mid / static_tip - 1.0).abs() < 0.02,
        "mid-range {mid} vs static {static_tip}"
    );
    assert!(
        ((hi - lo) / static_tip - 2.0).abs() < 0.1,
        "a sudden load doubles the static deflection"
    );
    let mut crossings = Vec::new();
    for w in sim.outputs.windows(2) {
        let (a, b) = (tip(&w[0]) - static_tip, tip(&w[1]) - static_tip);
        if a < 0.0 && b >= 0.0 {
            crossings.push(w[0].t + (w[1].t - w[0].t) * (-a) / (b - a));
        }
    }
    assert!(crossings.len() >= 3, "{crossings:?}");
    let measured = (crossings[crossings.len() - 1] - crossings[0]) / (crossings.len() - 1) as f64;
    assert!(
        (measured / period - 1.0).abs() < 0.01,
        "period {measured} vs {period}"
    );
    // the unloaded half stays (nearly) still
    let left = sim
        .outputs
        .iter()
        .map(|o| o.nodal_displacements[0][0][2].abs())
        .fold(0.0, f64::max);
    assert!(left < 1e-6 * static_tip, "left tip moved {left:e}");
}
