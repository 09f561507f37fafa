//! Responses (output time histories) with their sensitivity histories, and scalar objectives
//! of the Eq. (35) kind with gradients by Eq. (39).
//!
//! A [`Response`] is written once, generic over the scalar: evaluated on the dual model of a
//! chunk with `q`, `v` seeded with the state sensitivities and the multipliers from
//! [`sens::solve_tangents`] (their total derivatives, Eq. 40), its tangents are
//! `dψ/db = ∂ψ/∂b + ∂ψ/∂q q_b + ∂ψ/∂v v_b + ∂ψ/∂λ λ_b` (Eq. 39).
//!
//! Objectives are computed on the recorded points: integrals by the trapezoidal rule, the
//! gradient by the same rule applied to the sensitivities (so that it is the exact derivative
//! of the computed value); maxima and minima take the sensitivity at the point where they occur.

use fem::PointPlace;
use laminate::{Criterion, PlyPosition};
use nalgebra::{DMatrix, Vector3};
use sens::{Dual, Scalar};

use crate::body::{BodyId, foreshortening, mode_vec, pose};
use crate::force::ForceId;
use crate::joint::JointId;
use crate::marker::Marker;
use crate::model::Model;
use crate::ply::{PlySelection, ply_failure, ply_stress};
use crate::sensitivity::{DesignModel, SensitivityError, SensitivityRun, seeded};
use crate::system::{MultibodySystem, Output};

/// An output quantity of the model at one state.
#[derive(Clone, Debug, PartialEq)]
pub enum Response {
    /// Component `axis` (0, 1, 2) of a body frame's origin, global (m).
    BodyPosition { body: BodyId, axis: usize },
    /// Nodal displacement `u' = X w` of a flexible body in its body frame (Eq. 11, 45):
    /// `dof` 0–2 translations (m), 3–5 rotations (rad).
    NodalDisplacement {
        body: BodyId,
        node: usize,
        dof: usize,
    },
    /// The normalised mid-node deflection of docs/design.md §4: the distance of node `mid` from the
    /// straight line through nodes `first` and `last` (deformed, global), signed about
    /// `normal` (the normal of the mechanism plane: positive when `dir × (x_mid − x_first)`
    /// points along it), divided by the undeformed distance between `first` and `last`.
    MidNodeDeflection {
        body: BodyId,
        first: usize,
        mid: usize,
        last: usize,
        normal: Vector3<f64>,
    },
    /// Component `axis` of the reaction force of a joint on the body of its marker `b`,
    /// global (N), from the multipliers.
    ReactionForce { joint: JointId, axis: usize },
    /// Component `i` of the state `y = [q; v]`.
    State(usize),
    /// Component `axis` of the reaction moment of a joint on the body of its marker `b` about
    /// that marker's point, global (N·m). Values only: no sensitivities.
    ReactionMoment { joint: JointId, axis: usize },
    /// Total mechanical energy (J). Values only: no sensitivities.
    Energy,
    /// `max |Φ|` over all constraint rows (m). Values only: no sensitivities.
    ConstraintViolation,
    /// The torque of an actuator ([`crate::Force::JointTorque`]) (N·m).
    ActuatorTorque { force: ForceId },
    /// The power of an actuator, its torque times the rate of the relative angle it turns
    /// (W).
    ActuatorPower { force: ForceId },
    /// Component `axis` (global) of the position (`order` 0, m), velocity (1, m/s) or
    /// acceleration (2, m/s²) of a marker's point — a node's, deformed, on a flexible body —
    /// or of its difference from another marker's point.
    MarkerPoint {
        marker: Marker,
        relative_to: Option<Marker>,
        order: usize,
        axis: usize,
    },
    /// Component `component` (Voigt `[11, 22, 33, 23, 13, 12]`) of the stress in the material
    /// axes of a flexible body with ply stresses ([`crate::FlexibleBody::with_ply_stresses`])
    /// (Pa): at the centroid of shell element `element`, in ply `ply` at its position through
    /// the thickness (`place` [`PointPlace::Ply`]); or at the middle of beam element `element`,
    /// at the integration point of the section's region `ply` nearest to `(x₂, x₃)` (`place`
    /// [`PointPlace::Section`]). With `strain`, the strain component instead (engineering
    /// shear), through the ply's nominal compliance.
    PlyStress {
        body: BodyId,
        element: usize,
        ply: usize,
        place: PointPlace,
        component: usize,
        strain: bool,
    },
    /// The failure index under `criterion` (`1/R`, docs/failure-criteria.md) over the ply
    /// points of the elements `elements` (`None`: every one; a beam element's at its ends and
    /// middle), ply `ply` (a beam section's region; `None`: every one) and `position` (`None`:
    /// bottom, middle and top of a shell's ply; a beam's points have none): their largest
    /// (`rho` `None`), with the derivatives of the point where it is, or their
    /// Kreisselmeier–Steinhauser aggregate
    /// `max + ln Σ exp(ρ (FI_k − max)) / ρ` (between the largest and `ln n / ρ` above it).
    PlyFailure {
        body: BodyId,
        elements: Option<Vec<usize>>,
        ply: Option<usize>,
        position: Option<PlyPosition>,
        criterion: Criterion,
        rho: Option<f64>,
    },
}

impl Response {
    /// Whether the response has design sensitivities ([`Self::evaluate`] refuses the others).
    pub fn differentiable(&self) -> bool {
        !matches!(
            self,
            Response::ReactionMoment { .. } | Response::Energy | Response::ConstraintViolation
        )
    }

    /// The value of the response in a recorded output of `model` (the same value
    /// [`Self::evaluate`] gives at that state, for the responses that have one).
    pub fn value(&self, model: &Model<f64>, o: &Output) -> f64 {
        match *self {
            Response::BodyPosition { body, axis } => o.positions[body.0][axis],
            Response::NodalDisplacement { body, node, dof } => {
                o.nodal_displacements[body.0][node][dof]
            }
            Response::MidNodeDeflection {
                body,
                first,
                mid,
                last,
                normal,
            } => {
                let crate::Body::Flexible(f) = model.body(body) else {
                    return f64::NAN;
                };
                let x0 = &f.modal.node_positions;
                let x = |k: usize| {
                    let u = o.nodal_displacements[body.0][k];
                    o.positions[body.0]
                        + o.orientations[body.0] * (x0[k] + Vector3::new(u[0], u[1], u[2]))
                };
                let (a, m, b) = (x(first), x(mid), x(last));
                let dir = (b - a).normalize();
                dir.cross(&(m - a)).dot(&normal.normalize()) / (x0[last] - x0[first]).norm()
            }
            Response::ReactionForce { joint, axis } => o.reactions[joint.0].force_on_b[axis],
            Response::ReactionMoment { joint, axis } => o.reactions[joint.0].moment_on_b[axis],
            Response::State(i) => {
                if i < o.q.len() {
                    o.q[i]
                } else {
                    o.v[i - o.q.len()]
                }
            }
            Response::Energy => o.energy.total(),
            Response::ConstraintViolation => o.position_violation,
            Response::ActuatorTorque { .. }
            | Response::ActuatorPower { .. }
            | Response::MarkerPoint { .. }
            | Response::PlyStress { .. }
            | Response::PlyFailure { .. } => self
                .evaluate_with::<f64, f64>(model, o.t, (&o.q, &o.v), &[], &o.accelerations)
                .unwrap_or(f64::NAN),
        }
    }

    /// Whether [`Response::evaluate_with`] reads the solution of Eq. (12) — the multipliers (a
    /// reaction force) or the accelerations (a marker's): the others need the state alone.
    pub fn needs_solution(&self) -> bool {
        matches!(
            self,
            Response::ReactionForce { .. } | Response::MarkerPoint { order: 2, .. }
        )
    }

    /// The response at `(t, q, v)` with the multipliers `lambda` (one per constraint row, zero
    /// for removed rows); not of a marker's acceleration (see [`Response::evaluate_with`]).
    pub fn evaluate<P: Scalar, S: Scalar + From<P>>(
        &self,
        model: &Model<P>,
        t: f64,
        q: &[S],
        v: &[S],
        lambda: &[S],
    ) -> Result<S, SensitivityError> {
        self.evaluate_with(model, t, (q, v), lambda, &[])
    }

    /// [`Response::evaluate`] with the accelerations `v̇` (empty when unknown: a marker's
    /// acceleration is then refused).
    pub fn evaluate_with<P: Scalar, S: Scalar + From<P>>(
        &self,
        model: &Model<P>,
        t: f64,
        (q, v): (&[S], &[S]),
        lambda: &[S],
        accel: &[S],
    ) -> Result<S, SensitivityError> {
        let bad = |m: &str| SensitivityError::Response(m.to_string());
        let flexible = |body: BodyId| match model.body(body) {
            crate::Body::Flexible(f) => Ok(f),
            crate::Body::Rigid(_) => Err(bad("nodal responses need a flexible body")),
        };
        match *self {
            Response::BodyPosition { body, axis } => {
                if body.0 >= model.n_bodies() || axis > 2 {
                    return Err(bad("body or axis out of range"));
                }
                Ok(q[model.q_range(body).start + axis])
            }
            Response::NodalDisplacement { body, node, dof } => {
                let f = flexible(body)?;
                if node >= f.modal.n_nodes() || dof > 5 {
                    return Err(bad("node or dof out of range"));
                }
                let qr = model.q_range(body);
                let mut u = S::zero();
                for j in 0..f.modal.n_modes() {
                    u += S::from(f.modal.modes[(6 * node + dof, j)]) * q[qr.start + 7 + j];
                }
                if let (Some(g), true) = (&f.geometric, dof < 3) {
                    let w = &q[qr.start + 7..qr.end];
                    u += foreshortening(g, node, w)[dof];
                }
                Ok(u)
            }
            Response::MidNodeDeflection {
                body,
                first,
                mid,
                last,
                normal,
            } => {
                let f = flexible(body)?;
                let nn = f.modal.n_nodes();
                if first >= nn || mid >= nn || last >= nn || first == last {
                    return Err(bad("nodes out of range"));
                }
                let qr = model.q_range(body);
                let ps = pose(&q[qr.start..]);
                let w = &q[qr.start + 7..qr.end];
                let x = |k: usize| -> Vector3<S> {
                    let p = f.modal.node_positions[k];
                    let mut u = Vector3::new(S::from_f64(p.x), S::from_f64(p.y), S::from_f64(p.z));
                    for (j, &wj) in w.iter().enumerate() {
                        u += mode_vec::<P, S>(&f.modal, k, j, false) * wj;
                    }
                    if let Some(g) = &f.geometric {
                        u += foreshortening(g, k, w);
                    }
                    ps.r + ps.a * u
                };
                let (x0, xm, x1) = (x(first), x(mid), x(last));
                let d = x1 - x0;
                let len = d.dot(&d).sqrt();
                let dir = d.map(|x| x / len);
                let c = dir.cross(&(xm - x0));
                let nu = normal / normal.norm();
                let n = Vector3::new(S::from_f64(nu.x), S::from_f64(nu.y), S::from_f64(nu.z));
                let l0 = (f.modal.node_positions[last] - f.modal.node_positions[first]).norm();
                Ok(c.dot(&n) / l0)
            }
            Response::ReactionForce { joint, axis } => {
                if joint.0 >= model.joints().len() || axis > 2 {
                    return Err(bad("joint or axis out of range"));
                }
                let Some(b) = model.joint(joint).b.body else {
                    return Ok(S::zero());
                };
                let c = model.constraints(t, q, v);
                let col = model.v_range(b).start + axis;
                let mut f = S::zero();
                for r in model.joint_rows(joint) {
                    f -= c.jacobian[(r, col)] * lambda[r];
                }
                Ok(f)
            }
            Response::State(i) => {
                let nq = q.len();
                if i < nq {
                    Ok(q[i])
                } else if i < nq + v.len() {
                    Ok(v[i - nq])
                } else {
                    Err(bad("state index out of range"))
                }
            }
            Response::ActuatorTorque { force } | Response::ActuatorPower { force } => {
                let (tau, rate) = model
                    .actuator(force, t, q, v)
                    .ok_or_else(|| bad("the force is not an actuator"))?;
                Ok(match self {
                    Response::ActuatorPower { .. } => tau * rate,
                    _ => tau,
                })
            }
            Response::MarkerPoint {
                ref marker,
                ref relative_to,
                order,
                axis,
            } => {
                if order == 2 && accel.len() != model.n_v() {
                    return Err(bad("a marker's acceleration needs the accelerations"));
                }
                if axis > 2 || order > 2 {
                    return Err(bad("axis or order out of range"));
                }
                let point = |m: &Marker| -> S {
                    let k = model.marker(m, q, v).point;
                    match order {
                        0 => k.val[axis],
                        1 => k.rate[axis],
                        _ => {
                            let mut a = k.quad[axis];
                            for (col, x) in k.jac.iter() {
                                a += x[axis] * accel[col];
                            }
                            a
                        }
                    }
                };
                let base = relative_to.as_ref().map_or(S::zero(), point);
                Ok(point(marker) - base)
            }
            Response::PlyStress { .. } | Response::PlyFailure { .. } => {
                self.ply(model, q).map_err(|m| bad(&m))
            }
            Response::ReactionMoment { .. } | Response::Energy | Response::ConstraintViolation => {
                Err(bad(
                    "reaction moments, energies and constraint violations have no sensitivities",
                ))
            }
        }
    }

    /// A [`Response::PlyStress`] or [`Response::PlyFailure`] of `model` at the coordinates `q`.
    fn ply<P: Scalar, S: Scalar + From<P>>(&self, model: &Model<P>, q: &[S]) -> Result<S, String> {
        let (Response::PlyStress { body, .. } | Response::PlyFailure { body, .. }) = *self else {
            return Err("not a ply response".into());
        };
        let crate::Body::Flexible(f) = model.body(body) else {
            return Err("ply responses need a flexible body".into());
        };
        let w = &q[model.q_range(body).start + 7..model.q_range(body).end];
        match *self {
            Response::PlyStress {
                element,
                ply,
                place,
                component,
                strain,
                ..
            } => ply_stress(f, w, (element, ply, place), (component, strain)),
            Response::PlyFailure {
                ref elements,
                ply,
                position,
                criterion,
                rho,
                ..
            } => {
                let selection = PlySelection {
                    elements: elements.as_deref(),
                    ply,
                    position,
                };
                ply_failure(f, w, selection, criterion, rho)
            }
            _ => Err("not a ply response".into()),
        }
    }
}

/// A response history with its sensitivities.
#[derive(Clone, Debug, PartialEq)]
pub struct ResponseHistory {
    pub times: Vec<f64>,
    pub values: Vec<f64>,
    /// `dψ(t_i)/db_j`, one row per time, one column per design variable.
    pub gradients: DMatrix<f64>,
}

/// The response and its sensitivities at every recorded point of a sensitivity run.
pub fn response_history<const N: usize>(
    sys: &MultibodySystem,
    design: &DesignModel<N>,
    run: &SensitivityRun,
    response: &Response,
) -> Result<ResponseHistory, SensitivityError> {
    let nq = run.n_q;
    let nv = sys.model().n_v();
    let nc = sys.model().n_constraints();
    let m = design.n_variables();
    let mut values = Vec::with_capacity(run.times.len());
    let mut gradients = DMatrix::zeros(run.times.len(), m);
    let mut lambda = vec![Dual::<N>::constant(0.0); nc];
    for (i, (&t, y)) in run.times.iter().zip(&run.states).enumerate() {
        // the multipliers, accelerations and their tangents (Eq. 40) only for a response that
        // reads them
        let sol = match response.needs_solution() {
            true => Some(sys.solve(t, &y[..nq], &y[nq..])?),
            false => None,
        };
        let mut accel = Vec::new();
        let s = &run.sensitivities[i];
        for (c, (model, range)) in design.chunk_ranges().enumerate() {
            let yd = seeded::<N>(y, s, &range);
            let (qd, vd) = yd.split_at(nq);
            if let Some(sol) = &sol {
                let res = model.residual(t, qd, vd, &sol.rows, &sol.x);
                let x = crate::system::lu_tangents(&sol.lu, &sol.x, &res);
                // zero for the rows the solution removed (they may change from time to time)
                lambda.fill(Dual::constant(0.0));
                for (a, &r) in sol.rows.iter().enumerate() {
                    lambda[r] = x[nv + a];
                }
                accel = x[..nv].to_vec();
            }
            let val = response.evaluate_with(model, t, (qd, vd), &lambda, &accel)?;
            if c == 0 {
                values.push(val.v);
            }
            for (k, j) in range.enumerate() {
                gradients[(i, j)] = val.d[k];
            }
        }
    }
    Ok(ResponseHistory {
        times: run.times.clone(),
        values,
        gradients,
    })
}

/// The response (values only) at given times and states of the plain model of `sys`.
pub fn response_values(
    sys: &MultibodySystem,
    times: &[f64],
    states: &[Vec<f64>],
    response: &Response,
) -> Result<Vec<f64>, SensitivityError> {
    let model = sys.model();
    let nq = model.n_q();
    let nc = model.n_constraints();
    let nv = model.n_v();
    times
        .iter()
        .zip(states)
        .map(|(&t, y)| {
            let (q, v) = y.split_at(nq);
            let mut lambda = vec![0.0; nc];
            let mut accel = Vec::new();
            if response.needs_solution() {
                let sol = sys.solve(t, q, v)?;
                for (a, &r) in sol.rows.iter().enumerate() {
                    lambda[r] = sol.x[nv + a];
                }
                accel = sol.x[..nv].to_vec();
            }
            response.evaluate_with::<f64, f64>(model, t, (q, v), &lambda, &accel)
        })
        .collect()
}

/// A scalar objective of a response history `ψ(t)` (Eq. 35 and the usual variants).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Objective {
    /// `∫ ψ dt` over the whole history (trapezoidal rule on the recorded points).
    Integral,
    /// `(1/T) ∫ ψ dt`.
    Mean,
    /// `√((1/T) ∫ ψ² dt)`.
    Rms,
    /// `max ψ(t_i)`, with the time where it occurs.
    Max,
    /// `min ψ(t_i)`, with the time where it occurs.
    Min,
    /// `ψ(t)`, linear between recorded points.
    At(f64),
    /// `ψ` at the end of the history (of the window).
    Final,
    /// The Kreisselmeier–Steinhauser aggregate over time, a smooth maximum with parameter `ρ`
    /// (in the inverse of the response's unit):
    /// `KS = m + (1/ρ) ln((1/T) ∫ exp(ρ (ψ − m)) dt)`, `m = max ψ(t_i)`, the integral by the
    /// trapezoidal rule. `KS ≤ max ψ`, approaching it as `ρ` grows (by about `ln(T/τ)/ρ` for
    /// a peak of width `τ`), and independent of the output step once the peaks are resolved;
    /// unlike the maximum it is differentiable where the peak moves from one time to another.
    Ks(f64),
}

/// Value, gradient and (for extrema) time of an objective.
#[derive(Clone, Debug, PartialEq)]
pub struct ObjectiveValue {
    pub value: f64,
    /// `dΨ/db_j` (empty when computed without sensitivities).
    pub gradient: Vec<f64>,
    pub time: Option<f64>,
}

/// An objective's value and its derivative with respect to each sample `ψ(t_i)` of the
/// history it was computed from: its gradient is `Σ_i w_i dψ(t_i)/db`
/// ([`Objective::evaluate_in`]), and the seed of the adjoint method (`crate::adjoint_gradient`).
#[derive(Clone, Debug, PartialEq)]
pub struct SampleWeights {
    pub value: f64,
    /// `∂Ψ/∂ψ(t_i)`, one per sample of the whole history (zero outside a window).
    pub weights: Vec<f64>,
    /// Where an extremum occurs, or the time of a value at a time.
    pub time: Option<f64>,
}

/// A value of a history as the samples it mixes, `(index, weight)`.
type Mix = [(usize, f64); 2];

/// The history's value at `t` (within it) as the samples it mixes: linear between recorded
/// points.
fn interpolation(times: &[f64], t: f64) -> Mix {
    let i = times.partition_point(|&x| x < t).min(times.len() - 1);
    let (w0, i0) = if i == 0 || times[i] == t {
        (0.0, i)
    } else {
        ((times[i] - t) / (times[i] - times[i - 1]), i - 1)
    };
    [(i0, w0), (i, 1.0 - w0)]
}

/// The history restricted to `[a, b]` (within it): its times, its values (those at the ends
/// interpolated linearly) and each value as the samples of the whole history it mixes.
fn clip((a, b): (f64, f64), times: &[f64], values: &[f64]) -> (Vec<f64>, Vec<f64>, Vec<Mix>) {
    let mix = |m: &Mix| m[0].1 * values[m[0].0] + m[1].1 * values[m[1].0];
    let (ma, mb) = (interpolation(times, a), interpolation(times, b));
    let (mut t, mut v, mut maps) = (vec![a], vec![mix(&ma)], vec![ma]);
    for i in (0..times.len()).filter(|&i| times[i] > a && times[i] < b) {
        t.push(times[i]);
        v.push(values[i]);
        maps.push([(i, 1.0), (i, 0.0)]);
    }
    t.push(b);
    v.push(mix(&mb));
    maps.push(mb);
    (t, v, maps)
}

/// One sample's weight: 1 at `i`, 0 elsewhere.
fn one_hot(n: usize, i: usize) -> Vec<f64> {
    let mut w = vec![0.0; n];
    w[i] = 1.0;
    w
}

impl Objective {
    /// [`Objective::evaluate`] over the window `[t0, t1]` of the history when given (within
    /// the history): the history between, with its values (and gradients) at the window's ends
    /// interpolated linearly.
    pub fn evaluate_in(
        &self,
        window: Option<(f64, f64)>,
        times: &[f64],
        values: &[f64],
        gradients: Option<&DMatrix<f64>>,
    ) -> Result<ObjectiveValue, SensitivityError> {
        if gradients.is_some_and(|g| g.nrows() != times.len()) {
            return Err(SensitivityError::Response(
                "objective of an empty or inconsistent history".into(),
            ));
        }
        let s = self.weights_in(window, times, values)?;
        let gradient = gradients.map_or(Vec::new(), |g| {
            (0..g.ncols())
                .map(|j| {
                    (s.weights.iter().enumerate())
                        .filter(|(_, w)| **w != 0.0)
                        .map(|(i, w)| w * g[(i, j)])
                        .sum()
                })
                .collect()
        });
        Ok(ObjectiveValue {
            value: s.value,
            gradient,
            time: s.time,
        })
    }

    /// The objective of `values` at `times`, with its gradient from `gradients` (rows per time)
    /// when given.
    pub fn evaluate(
        &self,
        times: &[f64],
        values: &[f64],
        gradients: Option<&DMatrix<f64>>,
    ) -> Result<ObjectiveValue, SensitivityError> {
        self.evaluate_in(None, times, values, gradients)
    }

    /// The objective over the window `[t0, t1]` of the history when given (as
    /// [`Objective::evaluate_in`]) and its derivative with respect to each sample.
    pub fn weights_in(
        &self,
        window: Option<(f64, f64)>,
        times: &[f64],
        values: &[f64],
    ) -> Result<SampleWeights, SensitivityError> {
        let Some((a, b)) = window else {
            return self.weights(times, values);
        };
        let n = times.len();
        if n == 0 || values.len() != n || !(a < b && a >= times[0] && b <= times[n - 1]) {
            return Err(SensitivityError::Response(format!(
                "window [{a}, {b}] outside the history [{}, {}] or empty",
                times.first().copied().unwrap_or(f64::NAN),
                times.last().copied().unwrap_or(f64::NAN)
            )));
        }
        let (t, v, maps) = clip((a, b), times, values);
        let clipped = self.weights(&t, &v)?;
        let mut weights = vec![0.0; n];
        for (w, map) in clipped.weights.iter().zip(&maps) {
            for &(i, m) in map {
                weights[i] += w * m;
            }
        }
        Ok(SampleWeights { weights, ..clipped })
    }

    /// The objective of `values` at `times` and its derivative with respect to each sample.
    pub fn weights(
        &self,
        times: &[f64],
        values: &[f64],
    ) -> Result<SampleWeights, SensitivityError> {
        let n = times.len();
        if n == 0 || values.len() != n {
            return Err(SensitivityError::Response(
                "objective of an empty or inconsistent history".into(),
            ));
        }
        // trapezoidal weights
        let trapezoid = || -> Vec<f64> {
            let mut w = vec![0.0; n];
            for i in 0..n.saturating_sub(1) {
                let h = times[i + 1] - times[i];
                w[i] += 0.5 * h;
                w[i + 1] += 0.5 * h;
            }
            w
        };
        let span = times[n - 1] - times[0];
        let plain = |value: f64, weights: Vec<f64>| SampleWeights {
            value,
            weights,
            time: None,
        };
        Ok(match *self {
            Objective::Integral | Objective::Mean => {
                let mut w = trapezoid();
                if *self == Objective::Mean {
                    if !(span > 0.0) {
                        return Err(SensitivityError::Response("mean over no time".into()));
                    }
                    w.iter_mut().for_each(|x| *x /= span);
                }
                plain((0..n).map(|i| w[i] * values[i]).sum(), w)
            }
            Objective::Rms => {
                if !(span > 0.0) {
                    return Err(SensitivityError::Response("RMS over no time".into()));
                }
                let w: Vec<f64> = trapezoid().iter().map(|x| x / span).collect();
                let value = (0..n)
                    .map(|i| w[i] * values[i] * values[i])
                    .sum::<f64>()
                    .sqrt();
                // d√(Σ w ψ²) = Σ w ψ dψ / √(…)
                let weights = (0..n)
                    .map(|i| match value > 0.0 {
                        true => w[i] * values[i] / value,
                        false => 0.0,
                    })
                    .collect();
                plain(value, weights)
            }
            Objective::Max | Objective::Min => {
                let sign = if *self == Objective::Max { 1.0 } else { -1.0 };
                let i = (0..n)
                    .max_by(|&a, &b| (sign * values[a]).total_cmp(&(sign * values[b])))
                    .expect("non-empty");
                SampleWeights {
                    value: values[i],
                    weights: one_hot(n, i),
                    time: Some(times[i]),
                }
            }
            Objective::Ks(rho) => {
                if !(span > 0.0 && rho > 0.0 && rho.is_finite()) {
                    return Err(SensitivityError::Response(
                        "KS aggregate over no time or with ρ not positive".into(),
                    ));
                }
                let peak = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                let w = trapezoid();
                let e: Vec<f64> = (0..n)
                    .map(|i| w[i] * (rho * (values[i] - peak)).exp())
                    .collect();
                let sum: f64 = e.iter().sum();
                plain(
                    peak + (sum / span).ln() / rho,
                    e.iter().map(|x| x / sum).collect(),
                )
            }
            Objective::Final => SampleWeights {
                value: values[n - 1],
                weights: one_hot(n, n - 1),
                time: Some(times[n - 1]),
            },
            Objective::At(t) => {
                if !(t >= times[0] && t <= times[n - 1]) {
                    return Err(SensitivityError::Response(format!(
                        "time {t} outside the history [{}, {}]",
                        times[0],
                        times[n - 1]
                    )));
                }
                let mut weights = vec![0.0; n];
                let mut value = 0.0;
                for (i, w) in interpolation(times, t) {
                    weights[i] += w;
                    value += w * values[i];
                }
                SampleWeights {
                    value,
                    weights,
                    time: Some(t),
                }
            }
        })
    }
}

impl ResponseHistory {
    /// An objective of this history with its gradient.
    pub fn objective(&self, objective: &Objective) -> Result<ObjectiveValue, SensitivityError> {
        objective.evaluate(&self.times, &self.values, Some(&self.gradients))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `ψ = b f(t)` sampled at `times`, with its gradient `f(t)` along `b`.
    fn history(times: &[f64], f: impl Fn(f64) -> f64, b: f64) -> (Vec<f64>, DMatrix<f64>) {
        let v = times.iter().map(|&t| b * f(t)).collect();
        let g = DMatrix::from_fn(times.len(), 1, |i, _| f(times[i]));
        (v, g)
    }

    #[test]
    fn windowed_objectives_of_a_piecewise_linear_history_are_exact() {
        let times = [0.0, 0.3, 0.7, 1.0, 1.6, 2.0];
        // linear: the trapezoidal rule and the interpolation at the ends are exact
        let f = |t: f64| 2.0 * t + 1.0;
        let (v, g) = history(&times, f, 1.0);
        let w = Some((0.5, 1.3));
        let integral = Objective::Integral
            .evaluate_in(w, &times, &v, Some(&g))
            .unwrap();
        // ∫ (2t + 1) dt from 0.5 to 1.3 = [t² + t]
        let exact = (1.3f64.powi(2) + 1.3) - (0.25 + 0.5);
        assert!((integral.value - exact).abs() < 1e-14, "{}", integral.value);
        let mean = Objective::Mean.evaluate_in(w, &times, &v, None).unwrap();
        assert!((mean.value - exact / 0.8).abs() < 1e-14);
        let fin = Objective::Final
            .evaluate_in(w, &times, &v, Some(&g))
            .unwrap();
        assert!((fin.value - f(1.3)).abs() < 1e-14 && fin.time == Some(1.3));
        let max = Objective::Max.evaluate_in(w, &times, &v, None).unwrap();
        assert!((max.value - f(1.3)).abs() < 1e-14 && max.time == Some(1.3));
        let min = Objective::Min.evaluate_in(w, &times, &v, None).unwrap();
        assert!((min.value - f(0.5)).abs() < 1e-14 && min.time == Some(0.5));
        // without a window: the whole history
        let all = Objective::Final
            .evaluate_in(None, &times, &v, None)
            .unwrap();
        assert_eq!(all.value, f(2.0));
    }

    #[test]
    fn windowed_objectives_pick_interior_peaks_and_their_gradients_follow_the_values() {
        let times: Vec<f64> = (0..=40).map(|i| 0.05 * i as f64).collect();
        let f = |t: f64| (3.0 * t).sin() + 0.2 * t;
        let w = Some((0.42, 1.81));
        // the peak inside the window, at the sample nearest f's (t = 0.5458)
        let (v, g) = history(&times, f, 1.0);
        let max = Objective::Max.evaluate_in(w, &times, &v, Some(&g)).unwrap();
        assert_eq!((max.value, max.time), (f(0.55), Some(0.55)));
        assert_eq!(max.gradient, vec![f(0.55)]);
        // every objective is b times that of f for ψ = b f, the gradient that of f
        for kind in [
            Objective::Integral,
            Objective::Mean,
            Objective::Rms,
            Objective::Max,
            Objective::Min,
            Objective::Final,
            Objective::Ks(30.0),
        ] {
            let at = |b: f64| {
                let (v, g) = history(&times, f, b);
                kind.evaluate_in(w, &times, &v, Some(&g)).unwrap()
            };
            let (o, h) = (at(1.5), 1e-6);
            let fd = (at(1.5 + h).value - at(1.5 - h).value) / (2.0 * h);
            assert!(
                (o.gradient[0] - fd).abs() < 1e-8 * fd.abs().max(1.0),
                "{kind:?}: {} vs {fd}",
                o.gradient[0]
            );
        }
        // a window outside the history or empty is refused
        assert!(
            Objective::Max
                .evaluate_in(Some((1.0, 2.5)), &times, &v, None)
                .is_err()
        );
        assert!(
            Objective::Max
                .evaluate_in(Some((1.0, 1.0)), &times, &v, None)
                .is_err()
        );
    }

    #[test]
    fn the_ks_aggregate_of_a_sine_is_the_bessel_closed_form_below_the_peak() {
        // (1/T) ∫₀¹ exp(ρ (sin 2πt − 1)) dt = e^{−ρ} I₀(ρ): KS = ln I₀(ρ) / ρ
        let times: Vec<f64> = (0..=2000).map(|i| i as f64 / 2000.0).collect();
        let v: Vec<f64> = times
            .iter()
            .map(|t| (2.0 * std::f64::consts::PI * t).sin())
            .collect();
        let bessel_i0 = |x: f64| {
            let (mut term, mut sum) = (1.0, 1.0);
            for k in 1..200 {
                term *= (x / 2.0).powi(2) / (k * k) as f64;
                sum += term;
            }
            sum
        };
        let mut last = f64::NEG_INFINITY;
        for rho in [5.0, 20.0, 80.0] {
            let ks = Objective::Ks(rho).evaluate(&times, &v, None).unwrap().value;
            let exact = bessel_i0(rho).ln() / rho;
            assert!((ks - exact).abs() < 1e-10, "ρ = {rho}: {ks} vs {exact}");
            assert!(ks < 1.0 && ks > last, "below the peak, rising with ρ");
            last = ks;
        }
        // a constant history is its own aggregate
        let c = vec![0.7; times.len()];
        let ks = Objective::Ks(50.0)
            .evaluate(&times, &c, None)
            .unwrap()
            .value;
        assert!((ks - 0.7).abs() < 1e-13);
        assert!(Objective::Ks(0.0).evaluate(&times, &c, None).is_err());
    }
}
