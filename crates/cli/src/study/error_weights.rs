//! The integrator's absolute tolerance per state component, from the deck's `atol` and
//! `error_weights` (docs/design.md §3).

use mbs::{BdfOptions, Model, State};

use super::Study;

/// The default displacement tolerance (`error_weights = "displacement"`) per unit of `rtol`
/// and of the mechanism's size: `atol = 1e-4 · rtol · size`, 4.6e-11 m on the paper's
/// slider-crank at `rtol = 1e-6`. A deflection of 1e-3 of the size is then resolved to about
/// 1e-7 of itself a step, which keeps the accumulated error of a run of a few thousand steps
/// near 1e-4: on the beam deck its mid-span deflection is within 1.5e-4 of its range of a run
/// at `rtol = 1e-10` (3.3e-3 at 1e-9 m; 1.0e-4 with a uniform `atol = 1e-9`, in 33 % more
/// steps; docs/design.md §3).
const ATOL_PER_RTOL: f64 = 1e-4;

impl Study {
    /// `analysis.error_weights` as the deck writes it.
    pub(crate) fn error_weights_name(&self) -> &'static str {
        if self.displacement_weights {
            "displacement"
        } else {
            "uniform"
        }
    }

    /// The integrator's options with one absolute tolerance per state component, and the
    /// mechanism's `atol`. With `error_weights = "displacement"` each body's `atol` (its own,
    /// or `analysis.atol`, by default [`ATOL_PER_RTOL`] · `rtol` · the mechanism's size) is a
    /// displacement turned into a tolerance per coordinate ([`mbs::absolute_tolerances`]);
    /// otherwise it applies to each of the body's components (default 1e-8).
    pub(super) fn error_weights(&self, model: &Model<f64>, state: &State) -> (BdfOptions, f64) {
        let mut options = self.options.clone();
        let rtol = options.accuracy.as_ref().map_or(options.rtol, |(r, _)| *r);
        let atol = match (self.atol, self.displacement_weights) {
            (Some(a), _) => a,
            (None, true) => ATOL_PER_RTOL * rtol * mbs::mechanism_size(model, &state.q),
            (None, false) => 1e-8,
        };
        // the model's bodies: the flexible ones, then the rigid ones, in deck order
        let per_body: Vec<f64> = (self.flexible_bodies.iter().map(|b| b.def.atol))
            .chain(self.rigid_bodies.iter().map(|b| b.atol))
            .map(|a| a.unwrap_or(atol))
            .collect();
        let weights = if self.displacement_weights {
            let span = self.times.last().unwrap_or(&1.0) - self.times[0];
            let rate = 2.0 * std::f64::consts::PI / span.max(f64::MIN_POSITIVE);
            mbs::absolute_tolerances(model, &state.q, &per_body, rate)
        } else {
            let mut w = vec![0.0; model.n_q() + model.n_v()];
            let (wq, wv) = w.split_at_mut(model.n_q());
            for (id, a) in model.body_ids().zip(&per_body) {
                wq[model.q_range(id)].fill(*a);
                wv[model.v_range(id)].fill(*a);
            }
            w
        };
        match &mut options.accuracy {
            Some((_, a)) => *a = weights,
            None => options.atol = weights,
        }
        (options, atol)
    }
}
