//! Linearisation about a state of a run: a time point of a moving mechanism, neither at rest
//! nor in a steady spin (docs/operating-points.md).
//!
//! About a moving state the linearised equations depend on the coordinates the perturbation
//! is measured in, so they are fixed here as those of the floating frame of reference: each
//! body's perturbation `d` in its own frame moving with the run, `r = r₀ + A₀ d_t`,
//! `A = A₀ exp(d̂_r)`, `w = w₀ + d_w` (`r₀, A₀, w₀` the run's at every time). A set of them is
//! chosen independent, `z` — the elastic coordinates first, then the rotations, then the
//! translations — the others follow from the constraints. With `z = 0` the run itself, the
//! perturbation obeys `z̈ = F(z, ż, t)` exactly, with `F(0, 0, t) = 0`; the linearisation is
//! `δz̈ = F_z δz + F_ż δż` at the state's time, exact by dual numbers (the dependent
//! coordinates and rates by the implicit-function theorem, the accelerations through the
//! factorisation of Eq. (12) at the state), its eigenvalues the "frozen-time" modes: the
//! modes of the mechanism held at this configuration and motion.
//!
//! In these coordinates the centrifugal, Coriolis and Euler terms of each body's motion
//! appear as they do to an observer on it. For a pendulum the independent coordinate is its
//! angle, and `I δθ̈ + m g l cos θ δθ = 0` whatever its speed; for a mechanism turning steadily
//! (a rotor driven at constant speed) the linearisation is that of the steady spin in the
//! rotating frame ([`crate::OperatingPoint::linearise`]).

use nalgebra::{DMatrix, DVector, Matrix3, Vector3};
use sens::{Dual, Scalar, chunk_ranges};

use crate::operating::{Linearisation, OperatingError, increment_map};
use crate::system::{apply_increment, lu_tangents};
use crate::{Model, MultibodySystem, State};

/// Width of the dual numbers.
const WIDTH: usize = 8;

/// A column is independent of those chosen when its part outside their span exceeds this
/// fraction of its norm.
const PIVOT: f64 = 1e-8;

/// The linearisation about a state of a run ([`linearise_state`]).
#[derive(Clone, Debug)]
pub struct StateLinearisation {
    /// The state made consistent with the constraints (the independent coordinates and rates
    /// kept).
    pub state: State,
    /// The velocity variables whose perturbations are the independent coordinates `z`.
    pub independent: Vec<usize>,
    /// `I δz̈ − F_ż δż − F_z δz = 0`; its basis is `∂d/∂z` (not orthonormal; translations in
    /// the body frames).
    pub linearisation: Linearisation,
}

/// The linearised equations of `system` about the state `state` at time `t` (a state of a
/// run; it is first made consistent with the constraint rows by moving the dependent
/// coordinates and rates).
pub fn linearise_state(
    system: &MultibodySystem,
    t: f64,
    state: &State,
) -> Result<StateLinearisation, OperatingError> {
    let fail = |reason: String| OperatingError::State { t, reason };
    let model = system.model();
    let rows = system.rows_at(t, &state.q);
    let frames = |q: &[f64]| -> Vec<Matrix3<f64>> {
        model
            .body_ids()
            .map(|id| model.rotation_of(id, q))
            .collect()
    };
    // Φ_v of the rows in the body-frame increments
    let jacobian = |q: &[f64], v: &[f64]| {
        let mut j = model.constraints(t, q, v).jacobian.select_rows(&rows);
        for (id, a) in model.body_ids().zip(frames(q)) {
            let o = model.v_range(id).start;
            let cols = j.columns(o, 3) * a;
            j.columns_mut(o, 3).copy_from(&cols);
        }
        j
    };
    let dependent = dependent_columns(model, &jacobian(&state.q, &state.v)).map_err(fail)?;
    let (q, v) = consistent(model, t, &rows, &dependent, state, &jacobian).map_err(fail)?;
    let independent: Vec<usize> = (0..model.n_v())
        .filter(|i| !dependent.contains(i))
        .collect();
    let sol = system.solve(t, &q, &v).map_err(|e| fail(e.to_string()))?;
    let lu = jacobian(&q, &v).select_columns(&dependent).lu();
    let map = increment_map(model, &q);
    let chart = Chart::new(model, &q, &v, &sol.x);
    let ctx = Frozen {
        model,
        t,
        rows: &rows,
        dependent: &dependent,
        independent: &independent,
        lu: &lu,
        q: &q,
        map: &map,
        chart: &chart,
    };
    let f = independent.len();
    let mut basis = DMatrix::zeros(model.n_v(), f);
    let mut rates = DMatrix::zeros(f, 2 * f);
    for cols in chunk_ranges(2 * f, WIDTH) {
        let (d, ddot) = ctx.increments(cols.clone());
        let (qd, vd) = (ctx.positions(&d), chart.velocities(&d, &ddot));
        let res = model.residual(t, &qd, &vd, &sol.rows, &sol.x);
        let accel = lu_tangents(&sol.lu, &sol.x, &res);
        let dddot = chart.second_rates(&d, &ddot, &accel[..model.n_v()]);
        for (k, j) in cols.enumerate() {
            for (i, &c) in independent.iter().enumerate() {
                rates[(i, j)] = dddot[c].d[k];
            }
            if j < f {
                for (i, x) in d.iter().enumerate() {
                    basis[(i, j)] = x.d[k];
                }
            }
        }
    }
    let stiffness = -rates.columns(0, f);
    let damping = -rates.columns(f, f);
    Ok(StateLinearisation {
        state: State { q, v },
        independent,
        linearisation: Linearisation::minimal(basis, stiffness, damping),
    })
}

/// The dependent velocity variables: a basis of the columns of `jacobian` (the constraint
/// rows' `Φ_v`), chosen greedily with pivoting among the translations, then the rotations,
/// then the elastic coordinates.
fn dependent_columns(model: &Model<f64>, jacobian: &DMatrix<f64>) -> Result<Vec<usize>, String> {
    let m = jacobian.nrows();
    let mut classes: [Vec<usize>; 3] = Default::default();
    for id in model.body_ids() {
        let r = model.v_range(id);
        classes[0].extend(r.start..r.start + 3);
        classes[1].extend(r.start + 3..r.start + 6);
        classes[2].extend(r.start + 6..r.end);
    }
    let mut chosen = Vec::new();
    let mut span: Vec<nalgebra::DVector<f64>> = Vec::new();
    let outside = |c: usize, span: &[nalgebra::DVector<f64>]| {
        let mut r = jacobian.column(c).into_owned();
        for e in span {
            r -= e * e.dot(&r);
        }
        r
    };
    for class in &mut classes {
        while chosen.len() < m {
            let best = (class.iter().enumerate())
                .map(|(k, &c)| {
                    let norm = jacobian.column(c).norm();
                    let r = outside(c, &span).norm();
                    (k, if norm > 0.0 { r / norm } else { 0.0 })
                })
                .max_by(|a, b| a.1.total_cmp(&b.1));
            match best {
                Some((k, rel)) if rel > PIVOT => {
                    let c = class.remove(k);
                    let r = outside(c, &span);
                    span.push(&r / r.norm());
                    chosen.push(c);
                }
                _ => break,
            }
        }
    }
    if chosen.len() < m {
        return Err(format!(
            "{} of its {m} constraint equations are dependent (the mechanism is locked or \
             redundantly constrained here)",
            m - chosen.len()
        ));
    }
    chosen.sort_unstable();
    Ok(chosen)
}

/// `state` made consistent with the rows: the dependent coordinates by Newton's method on
/// `Φ = 0`, then the dependent rates by `Φ̇ = 0` (`jacobian`: the rows' `Φ_v` in the
/// body-frame increments).
fn consistent(
    model: &Model<f64>,
    t: f64,
    rows: &[usize],
    dependent: &[usize],
    state: &State,
    jacobian: &impl Fn(&[f64], &[f64]) -> DMatrix<f64>,
) -> Result<(Vec<f64>, Vec<f64>), String> {
    let (mut q, mut v) = (state.q.clone(), state.v.clone());
    let scale = crate::tolerance::mechanism_size(model, &q).max(1e-3);
    // the change of the dependent increments that zeroes `g` to first order, as velocity
    // variables (the translations turned to the global frame)
    let change = |q: &[f64], v: &[f64], g: &[f64]| -> Result<Vec<f64>, String> {
        let mut d = vec![0.0; model.n_v()];
        if dependent.is_empty() {
            return Ok(d);
        }
        let a = jacobian(q, v).select_columns(dependent);
        let g = DVector::from_iterator(rows.len(), rows.iter().map(|&r| g[r]));
        let x = (a.lu().solve(&g)).ok_or("the dependent coordinates' Jacobian is singular")?;
        for (&i, x) in dependent.iter().zip(x.iter()) {
            d[i] = -x;
        }
        for id in model.body_ids() {
            let o = model.v_range(id).start;
            let turned = model.rotation_of(id, q) * Vector3::new(d[o], d[o + 1], d[o + 2]);
            d[o..o + 3].copy_from_slice(turned.as_slice());
        }
        Ok(d)
    };
    for _ in 0..20 {
        let c = model.constraints(t, &q, &v);
        if rows.iter().all(|&r| c.phi[r].abs() <= 1e-13 * scale) {
            let dv = change(&q, &v, &c.phi_dot)?;
            for (x, dx) in v.iter_mut().zip(dv) {
                *x += dx;
            }
            return Ok((q, v));
        }
        let d = change(&q, &v, &c.phi)?;
        apply_increment(model, &mut q, &d);
    }
    Err("its constraints could not be met by moving the dependent coordinates".into())
}

type D = Dual<WIDTH>;

/// The bodies' frames moving with the run at the state: per body, `A₀`, `ω'₀`, `ω̇'₀`, and
/// the state's velocities and accelerations.
struct Chart {
    v_offsets: Vec<usize>,
    frames: Vec<Matrix3<f64>>,
    v: Vec<f64>,
    accel: Vec<f64>,
}

fn vec3<S: Scalar>(x: &[S], o: usize) -> Vector3<S> {
    Vector3::new(x[o], x[o + 1], x[o + 2])
}

fn constant(a: &Matrix3<f64>) -> Matrix3<D> {
    a.map(D::constant)
}

impl Chart {
    fn new(model: &Model<f64>, q: &[f64], v: &[f64], x: &[f64]) -> Self {
        Self {
            v_offsets: model.body_ids().map(|id| model.v_range(id).start).collect(),
            frames: model
                .body_ids()
                .map(|id| model.rotation_of(id, q))
                .collect(),
            v: v.to_vec(),
            accel: x[..model.n_v()].to_vec(),
        }
    }

    /// Per body: its velocity offset, `A₀`, `ω'₀` and `ω̇'₀` (dual constants).
    fn bodies(&self) -> impl Iterator<Item = (usize, Matrix3<D>, Vector3<D>, Vector3<D>)> + '_ {
        (self.v_offsets.iter().zip(&self.frames)).map(|(&o, a)| {
            let w = vec3(&self.v, o + 3).map(D::constant);
            let wd = vec3(&self.accel, o + 3).map(D::constant);
            (o, constant(a), w, wd)
        })
    }

    /// The global increments of the velocity variables of body-frame increments `d`
    /// (`A₀ d_t` on the translations).
    fn global(&self, d: &[D]) -> Vec<D> {
        let mut e = d.to_vec();
        for (o, a, _, _) in self.bodies() {
            let t = a * vec3(d, o);
            e[o..o + 3].copy_from_slice(t.as_slice());
        }
        e
    }

    /// The velocity variables at the perturbation `(d, ḋ)` (first order):
    /// `ṙ = ṙ₀ + A₀ (ω'₀ × d_t + ḋ_t)`, `ω' = ω'₀ − d_r × ω'₀ + ḋ_r`, `ẇ = ẇ₀ + ḋ_w`.
    fn velocities(&self, d: &[D], ddot: &[D]) -> Vec<D> {
        let mut v: Vec<D> = (self.v.iter().zip(ddot)).map(|(&x, r)| *r + x).collect();
        for (o, a, w, _) in self.bodies() {
            let t = a * (w.cross(&vec3(d, o)) + vec3(ddot, o)) + vec3(&self.v, o).map(D::constant);
            let r = w - vec3(d, o + 3).cross(&w) + vec3(ddot, o + 3);
            v[o..o + 3].copy_from_slice(t.as_slice());
            v[o + 3..o + 6].copy_from_slice(r.as_slice());
        }
        v
    }

    /// `d̈` from the accelerations `v̇` (first order):
    /// `d̈_t = A₀ᵀ (r̈ − r̈₀) − ω̇'₀ × d_t − 2 ω'₀ × ḋ_t − ω'₀ × (ω'₀ × d_t)`,
    /// `d̈_r = ω̇' − ω̇'₀ + ḋ_r × ω'₀ + d_r × ω̇'₀`, `d̈_w = ẅ − ẅ₀`.
    fn second_rates(&self, d: &[D], ddot: &[D], accel: &[D]) -> Vec<D> {
        let mut out: Vec<D> = (accel.iter().zip(&self.accel))
            .map(|(a, &x)| *a - x)
            .collect();
        for (o, a, w, wd) in self.bodies() {
            let (dt, dr) = (vec3(d, o), vec3(d, o + 3));
            let (vt, vr) = (vec3(ddot, o), vec3(ddot, o + 3));
            let two = D::from_f64(2.0);
            let t = a.transpose() * vec3(&out, o)
                - wd.cross(&dt)
                - w.cross(&vt) * two
                - w.cross(&w.cross(&dt));
            let r = vec3(&out, o + 3) + vr.cross(&w) + dr.cross(&wd);
            out[o..o + 3].copy_from_slice(t.as_slice());
            out[o + 3..o + 6].copy_from_slice(r.as_slice());
        }
        out
    }
}

/// What the dual evaluations at the consistent state share.
struct Frozen<'a> {
    model: &'a Model<f64>,
    t: f64,
    rows: &'a [usize],
    dependent: &'a [usize],
    independent: &'a [usize],
    /// LU of the dependent columns of the rows' `Φ_v` in the body-frame increments.
    lu: &'a nalgebra::LU<f64, nalgebra::Dyn, nalgebra::Dyn>,
    q: &'a [f64],
    /// `∂q/∂d` of the global increments.
    map: &'a DMatrix<f64>,
    chart: &'a Chart,
}

impl Frozen<'_> {
    /// The perturbation `d` and its rate `ḋ` seeded along the state columns `cols` (`z`
    /// first, then `ż`), the dependent ones' tangents from the constraints.
    fn increments(&self, cols: std::ops::Range<usize>) -> (Vec<D>, Vec<D>) {
        let nv = self.model.n_v();
        let f = self.independent.len();
        let mut d = vec![D::constant(0.0); nv];
        let mut ddot = vec![D::constant(0.0); nv];
        for (k, j) in cols.enumerate() {
            match j < f {
                true => d[self.independent[j]].d[k] = 1.0,
                false => ddot[self.independent[j - f]].d[k] = 1.0,
            }
        }
        let q = self.positions(&d);
        let c = (self.model).constraints(self.t, &q, &self.chart.velocities(&d, &ddot));
        self.solve_dependent(&mut d, |r| c.phi[r]);
        let q = self.positions(&d);
        let c = (self.model).constraints(self.t, &q, &self.chart.velocities(&d, &ddot));
        self.solve_dependent(&mut ddot, |r| c.phi_dot[r]);
        (d, ddot)
    }

    /// Subtract from the tangents of `x`'s dependent entries `A⁻¹` times the rows' tangents
    /// of `g` (the dependent ones' first-order change that keeps `g` zero).
    fn solve_dependent(&self, x: &mut [D], g: impl Fn(usize) -> D) {
        let m = self.rows.len();
        if m == 0 {
            return;
        }
        let rhs = DMatrix::from_fn(m, WIDTH, |a, k| g(self.rows[a]).d[k]);
        let sol = self
            .lu
            .solve(&rhs)
            .unwrap_or_else(|| DMatrix::zeros(m, WIDTH));
        for (a, &i) in self.dependent.iter().enumerate() {
            for k in 0..WIDTH {
                x[i].d[k] -= sol[(a, k)];
            }
        }
    }

    /// `q₀ ⊕ d` to first order.
    fn positions(&self, d: &[D]) -> Vec<D> {
        let e = self.chart.global(d);
        (0..self.q.len())
            .map(|i| {
                let mut x = D::constant(self.q[i]);
                for (j, ej) in e.iter().enumerate() {
                    let m = self.map[(i, j)];
                    if m != 0.0 {
                        for k in 0..WIDTH {
                            x.d[k] += m * ej.d[k];
                        }
                    }
                }
                x
            })
            .collect()
    }
}
