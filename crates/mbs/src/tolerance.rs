//! Absolute error tolerances per coordinate, derived from one tolerance on displacements
//! (docs/design.md §3, "Error weights").
//!
//! The state `y = [q; v]` mixes metres, Euler parameters, modal coordinates (√kg·m) and their
//! rates. One absolute tolerance for all of them weighs a modal coordinate of a light body
//! like a position in metres and an angular velocity like a velocity: the error test then
//! resolves vibrations far below anything a point of the mechanism shows. Here each
//! coordinate's tolerance is what moves the body's mass by the displacement tolerance `δ` (m):
//! - translations `r`: `δ`;
//! - Euler parameters `p`: `δ / (2 ρ)`, `ρ` the body's largest radius of gyration about its
//!   frame (a rotation `θ = 2|Δp|` moves its mass by `ρ θ` in the root mean square);
//! - modal coordinates `w_k` (mass-normalised modes): `δ √m`, `m` the body's mass (a modal
//!   amplitude `w` moves the mass by `w / √m` in the root mean square);
//! - rates: each position's tolerance times a frequency. A mode's rate takes its own `ω_k`
//!   (an error `Δẇ` in a vibration at `ω_k` is an amplitude error `Δẇ / ω_k`); the frame's
//!   rates take the body's lowest retained frequency, the slowest vibration the joints pass
//!   into the frame. Rigid bodies take the lowest over the flexible bodies, or `rate` (the
//!   caller's, e.g. `2π` over the span) in a mechanism without them; no frequency is taken
//!   below `rate` (a rigid-body mode a free body keeps).

use crate::{Body, BodyId, Model};
use nalgebra::{Matrix3, SymmetricEigen, Vector3};

/// Absolute tolerances of `y = [q; v]` (length `n_q + n_v`) at the configuration `q`:
/// `displacement[b]` (m) for body `b` (module docs). `rate` (rad/s) is the frequency of the
/// rigid bodies' rates in a mechanism without flexible bodies. Every entry is finite and
/// positive when `displacement` and `rate` are.
pub fn absolute_tolerances(
    model: &Model<f64>,
    q: &[f64],
    displacement: &[f64],
    rate: f64,
) -> Vec<f64> {
    let size = mechanism_size(model, q);
    let scales: Vec<BodyScales> = model
        .body_ids()
        .map(|id| BodyScales::of(model, id, size, rate))
        .collect();
    let lowest = scales
        .iter()
        .filter_map(|s| s.lowest)
        .reduce(f64::min)
        .unwrap_or(rate);
    let n_q = model.n_q();
    let mut atol = vec![0.0; n_q + model.n_v()];
    let (atol_q, atol_v) = atol.split_at_mut(n_q);
    for (id, s) in model.body_ids().zip(&scales) {
        let d = displacement[id.index()];
        let frame_rate = s.lowest.unwrap_or(lowest);
        let (qr, vr) = (model.q_range(id), model.v_range(id));
        let (q, v) = (&mut atol_q[qr], &mut atol_v[vr]);
        q[..3].fill(d);
        q[3..7].fill(d / (2.0 * s.gyration));
        v[..3].fill(d * frame_rate);
        v[3..6].fill(d / s.gyration * frame_rate);
        let modal = d * s.mass.sqrt();
        for (k, omega) in s.frequencies.iter().enumerate() {
            q[7 + k] = modal;
            v[6 + k] = modal * omega;
        }
    }
    atol
}

/// What a body's tolerances are scaled by.
struct BodyScales {
    /// Mass (kg).
    mass: f64,
    /// Largest radius of gyration about the body frame (m), at least 1e-3 of the mechanism.
    gyration: f64,
    /// `ω_k` of each retained mode (rad/s), at least `rate`: a mode slower than that (a
    /// rigid-body mode kept by a free body) is weighed as a rigid body's coordinate.
    frequencies: Vec<f64>,
    /// The lowest of `frequencies` (`None` for a rigid body).
    lowest: Option<f64>,
}

impl BodyScales {
    fn of(model: &Model<f64>, id: BodyId, size: f64, rate: f64) -> Self {
        let (mass, inertia, frequencies) = match model.body(id) {
            Body::Rigid(b) => (b.mass, b.inertia, Vec::new()),
            Body::Flexible(b) => {
                let m = &b.modal;
                let mut inertia = Matrix3::zeros();
                for ((x, &mk), j) in m
                    .node_positions
                    .iter()
                    .zip(&m.node_masses)
                    .zip(&m.node_inertias)
                {
                    inertia += (Matrix3::identity() * x.norm_squared() - x * x.transpose()) * mk
                        + Matrix3::from_diagonal(j);
                }
                let omega = m
                    .eigenvalues
                    .iter()
                    .map(|l| l.max(0.0).sqrt().max(rate))
                    .collect();
                (m.node_masses.iter().sum(), inertia, omega)
            }
        };
        let lowest = frequencies.iter().copied().reduce(f64::min);
        let largest = SymmetricEigen::new(inertia).eigenvalues.max();
        let gyration = (largest / mass).sqrt();
        let floor = 1e-3 * size;
        Self {
            mass: if mass > 0.0 { mass } else { 1.0 },
            gyration: if gyration.is_finite() {
                gyration.max(floor)
            } else {
                size
            },
            frequencies,
            lowest,
        }
    }
}

/// The diagonal of the box around the body origins, the flexible bodies' nodes and the joints'
/// points at `q` (m); 1 m if nothing finite is there, at least 1e-9 m.
pub fn mechanism_size(model: &Model<f64>, q: &[f64]) -> f64 {
    let mut points = Vec::new();
    for id in model.body_ids() {
        let r = model.q_range(id).start;
        let origin = Vector3::new(q[r], q[r + 1], q[r + 2]);
        points.push(origin);
        if let Body::Flexible(b) = model.body(id) {
            let a = model.rotation_of(id, q);
            points.extend(b.modal.node_positions.iter().map(|p| origin + a * p));
        }
    }
    for j in model.joints() {
        points.push(model.marker_position(&j.a, q));
        points.push(model.marker_position(&j.b, q));
    }
    points.retain(|p| p.iter().all(|x| x.is_finite()));
    let (lo, hi) = fem::bounding_box(&points);
    let d = (hi - lo).norm();
    if d.is_finite() { d.max(1e-9) } else { 1.0 }
}
