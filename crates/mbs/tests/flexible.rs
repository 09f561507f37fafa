//! Flexible (modal) bodies built from the fixture beam: a free beam keeps its momentum and
//! energy; a cantilever under a suddenly applied tip load oscillates about its static
//! deflection with the first natural frequency.

mod common;

use common::{Beam, assembled};
use mbs::{
    BdfOptions, FlexibleBody, Force, Joint, JointKind, Load, LoadFrame, Marker, Model, Output,
    simulate,
};
use nalgebra::Vector3;

/// Steel bar 0.5 m long, 10 mm (y) × 20 mm (z).
fn bar(elements: usize) -> Beam {
    let (b, h) = (0.02, 0.01); // z-width, y-height
    let iz = b * h * h * h / 12.0;
    let iy = h * b * b * b / 12.0;
    // Saint-Venant torsion constant of the rectangle (series, ratio 2)
    let j = 0.229 * b * h * h * h;
    Beam {
        length: 0.5,
        elements,
        e: 210e9,
        g: 81e9,
        rho: 7850.0,
        area: b * h,
        iy,
        iz,
        j,
    }
}

#[test]
fn cantilever_under_sudden_tip_load_oscillates_about_its_static_deflection() {
    let beam = bar(20);
    let n_modes = 6;
    let modal = beam.modal_body(0.0, 0, n_modes, 0.0);
    let tip = beam.elements;
    let load = Vector3::new(0.0, 10.0, 0.0);
    let mut model = Model::new();
    let b = model
        .add_flexible_body(FlexibleBody::new("cantilever", modal.clone()))
        .unwrap();
    model
        .add_joint(Joint::new(
            "clamp",
            JointKind::Fixed,
            Marker::ground(Vector3::zeros()),
            Marker::on(b, Vector3::zeros()),
        ))
        .unwrap();
    model
        .add_force(Force::PointForce {
            marker: Marker::node(b, tip),
            load: Load::Constant(load),
            frame: LoadFrame::Global,
        })
        .unwrap();
    let state = model.rest_state();
    let (mut sys, state) = assembled(model, state);

    // independent static deflection: Euler–Bernoulli cantilever, P L³ / (3 E I)
    let static_tip = load.y * beam.length.powi(3) / (3.0 * beam.e * beam.iz);
    // first natural frequency: closed form 1.8751² √(EI / (ρ A L⁴)) and the fixture's eigenvalue
    let omega1_exact = 1.875_104_068_7_f64.powi(2)
        * (beam.e * beam.iz / (beam.rho * beam.area * beam.length.powi(4))).sqrt();
    let omega1 = modal.eigenvalues[0].sqrt();
    assert!(
        (omega1 / omega1_exact - 1.0).abs() < 5e-3,
        "ω1 = {omega1}, closed form {omega1_exact}"
    );
    // the modal response: w_i = (X_tipᵀ F / ω_i²)(1 − cos ω_i t), decoupled with the frame clamped
    let x_tip = |i: usize| modal.modes[(6 * tip + 1, i)];
    let exact = |t: f64| -> f64 {
        (0..n_modes)
            .map(|i| {
                x_tip(i) * x_tip(i) * load.y / modal.eigenvalues[i]
                    * (1.0 - (modal.eigenvalues[i].sqrt() * t).cos())
            })
            .sum()
    };
    let modal_static: f64 = (0..n_modes)
        .map(|i| x_tip(i) * x_tip(i) * load.y / modal.eigenvalues[i])
        .sum();
    assert!(
        (modal_static / static_tip - 1.0).abs() < 2e-3,
        "modal static {modal_static} vs {static_tip}"
    );

    let period = 2.0 * std::f64::consts::PI / omega1;
    let t_out: Vec<f64> = (0..=600).map(|i| 3.0 * period * i as f64 / 600.0).collect();
    let sim = simulate(&mut sys, &state, &t_out, BdfOptions::adaptive(1e-9, 1e-12)).unwrap();
    let tip_y = |o: &Output| o.nodal_displacements[0][tip][1];
    let mut worst: f64 = 0.0;
    for o in &sim.outputs {
        worst = worst.max((tip_y(o) - exact(o.t)).abs());
    }
    eprintln!(
        "tip error {:e} of static {static_tip:e}; {:?}",
        worst, sim.statistics
    );
    assert!(
        worst < 1e-5 * static_tip,
        "tip response off the modal solution by {worst:e}"
    );
    // oscillation about the static deflection: mid-range over the last period, and the period
    // from upward crossings of the static value
    let last: Vec<f64> = sim.outputs[400..].iter().map(tip_y).collect();
    let (lo, hi) = last
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
            (a.min(x), b.max(x))
        });
    assert!(
        ((lo + hi) / 2.0 / static_tip - 1.0).abs() < 0.02,
        "mid-range {} vs static {static_tip}",
        (lo + hi) / 2.0
    );
    assert!(
        (hi - lo) / static_tip > 1.8,
        "amplitude of a suddenly applied load is twice the static one"
    );
    let mut crossings = Vec::new();
    for w in sim.outputs.windows(2) {
        let (a, b) = (tip_y(&w[0]) - static_tip, tip_y(&w[1]) - static_tip);
        if a < 0.0 && b >= 0.0 {
            crossings.push(w[0].t + (w[1].t - w[0].t) * (-a) / (b - a));
        }
    }
    assert!(crossings.len() >= 3, "crossings {crossings:?}");
    let measured = (crossings[crossings.len() - 1] - crossings[0]) / (crossings.len() - 1) as f64;
    assert!(
        (measured / period - 1.0).abs() < 0.01,
        "period {measured} vs 2π/ω1 = {period}"
    );
    // the clamp holds: reaction balances the load
    // the clamp's reaction on the beam: static part −F plus the inertia of the vibration,
    // whose time average vanishes over whole periods of the first mode (small remainder from
    // the higher modes)
    let n = sim.outputs.len() - 1;
    let mean = sim.outputs[..n]
        .iter()
        .map(|o| o.reactions[0].force_on_b)
        .sum::<Vector3<f64>>()
        / n as f64;
    assert!(
        (mean + load).norm() < 0.05 * load.norm(),
        "mean clamp reaction {mean:?}"
    );
}

/// Total linear momentum and angular momentum about the centre of mass of a flexible body,
/// from its nodes.
fn momenta(
    model: &Model<f64>,
    beam: &Beam,
    modal: &fem::ModalBody<f64>,
    o: &Output,
) -> (Vector3<f64>, Vector3<f64>) {
    let b = mbs::BodyId::from(0);
    let (masses, inertias) = beam.lumped();
    let total: f64 = masses.iter().sum();
    let a = o.orientations[0];
    let omega = Vector3::new(o.v[3], o.v[4], o.v[5]);
    let wd = &o.v[6..];
    let nodes: Vec<_> = (0..beam.n_nodes())
        .map(|k| model.marker_velocity(&Marker::node(b, k), &o.q, &o.v))
        .collect();
    let xc = nodes
        .iter()
        .zip(&masses)
        .map(|((x, _), m)| x * *m)
        .sum::<Vector3<f64>>()
        / total;
    let vc = nodes
        .iter()
        .zip(&masses)
        .map(|((_, v), m)| v * *m)
        .sum::<Vector3<f64>>()
        / total;
    let mut h = Vector3::zeros();
    for (k, (x, xd)) in nodes.iter().enumerate() {
        h += (x - xc).cross(&(xd - vc)) * masses[k];
        let mut om_k = omega;
        for (j, &w) in wd.iter().enumerate() {
            om_k += Vector3::new(
                modal.modes[(6 * k + 3, j)],
                modal.modes[(6 * k + 4, j)],
                modal.modes[(6 * k + 5, j)],
            ) * w;
        }
        h += a * inertias[k].component_mul(&om_k);
    }
    (vc * total, h)
}

#[test]
fn free_flexible_beam_keeps_momentum_and_energy_under_gravity() {
    let beam = bar(10);
    let n_modes = 6;
    let modal = beam.modal_body(-beam.length / 2.0, beam.elements / 2, n_modes, 0.0);
    let mut model = Model::new();
    let gravity = Vector3::new(0.0, 0.0, -9.81);
    model.gravity = gravity;
    let b = model
        .add_flexible_body(FlexibleBody::new("free beam", modal.clone()))
        .unwrap();
    let mut state = model.rest_state();
    let a0 = nalgebra::Rotation3::from_euler_angles(0.2, 0.1, -0.3).into_inner();
    model.set_pose(&mut state, b, Vector3::new(0.1, 0.2, 0.3), &a0);
    model.set_velocity(
        &mut state,
        b,
        Vector3::new(1.0, 0.5, -0.2),
        Vector3::new(0.3, 1.0, 5.0),
    );
    // vibrating in its first two modes
    let mut w0 = vec![0.0; n_modes];
    let mut wd0 = vec![0.0; n_modes];
    w0[0] = 2e-3;
    wd0[1] = 1.0;
    model.set_modal(&mut state, b, &w0, &wd0);
    let (mut sys, state) = assembled(model, state);
    let period = 2.0 * std::f64::consts::PI / modal.eigenvalues[0].sqrt();
    let t_out: Vec<f64> = (0..=100).map(|i| 4.0 * period * i as f64 / 100.0).collect();
    let sim = simulate(&mut sys, &state, &t_out, BdfOptions::adaptive(1e-11, 1e-14)).unwrap();
    let model = sys.model();
    let (p0, h0) = momenta(model, &beam, &modal, &sim.outputs[0]);
    let e0 = sim.outputs[0].energy.total();
    let elastic_max = sim
        .outputs
        .iter()
        .map(|o| o.energy.elastic)
        .fold(0.0, f64::max);
    assert!(elastic_max > 1e-3 * e0, "the beam must vibrate");
    let (mut dp, mut dh, mut de) = (0.0f64, 0.0f64, 0.0f64);
    for o in &sim.outputs {
        let (p, h) = momenta(model, &beam, &modal, o);
        // uniform gravity: momentum grows by M g t, angular momentum about the centre of mass
        // is conserved
        let p_expected = p0 + gravity * (modal.total_mass() * o.t);
        dp = dp.max((p - p_expected).norm() / p0.norm());
        dh = dh.max((h - h0).norm() / h0.norm());
        de = de.max((o.energy.total() - e0).abs() / e0);
    }
    eprintln!(
        "momentum {dp:e}, angular momentum {dh:e}, energy {de:e}; {:?}",
        sim.statistics
    );
    assert!(dp < 1e-9, "linear momentum drift {dp:e}");
    assert!(dh < 1e-6, "angular momentum drift {dh:e}");
    assert!(de < 1e-6, "energy drift {de:e}");
}
