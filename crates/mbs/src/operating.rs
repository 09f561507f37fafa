//! Operating points: the static equilibrium of a mechanism under its loads and the drivers'
//! positions, the steady spin of a mechanism turning rigidly about a fixed axis (a relative
//! equilibrium: constant in the rotating frame), the linearised equations of the constrained
//! system about them and their eigenvalues, and the equilibrium's design sensitivities
//! (docs/operating-points.md).
//!
//! The equilibrium solves `E(q, λ) = M(q) v̇ₛ(q) − f(q, vₛ(q)) + Φ_vᵀ λ = 0` with `Φ(q) = 0`,
//! where `vₛ`, `v̇ₛ` are the velocities and accelerations of the rigid spin at `q` (zero for a
//! static equilibrium), by Newton's method on the increments of the velocity variables
//! (rotations exact) and the multipliers, the Jacobian by dual numbers; the load (gravity and
//! the spin speed) is stepped when a full step fails. Perturbations `d` of the velocity
//! variables about it, taken in the rotating frame, obey
//! `M d̈ + (M G − f_v) ḋ + (∂E/∂d) d + Φ_vᵀ δλ = 0`, `Φ_v d = 0`, with `G` the frame's
//! Coriolis operator (`2 Ω×` on the translations, `ω'ₛ×` on the body-frame rotations); reduced
//! to independent coordinates by a basis `N` of the null space of `Φ_v`, their eigenvalues are
//! the operating point's modes.

use nalgebra::{Complex, DMatrix, DVector, Vector3, Vector4};
use sens::{Dual, HyperDual, Scalar, chunk_ranges};

use crate::kin::{mtv, rotation};
use crate::sensitivity::seeded;
use crate::system::apply_increment;
use crate::{DesignModel, JointId, JointKind, Model, State};

/// Width of the dual numbers of the Jacobians.
const WIDTH: usize = 8;

/// A rigid spin of the whole mechanism at `speed` (rad/s) about the global line through
/// `centre` along the unit vector `axis`: every body frame turns about it, the elastic
/// coordinates stay constant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spin {
    pub axis: Vector3<f64>,
    pub centre: Vector3<f64>,
    pub speed: f64,
}

/// Why an operating point could not be found or linearised.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum OperatingError {
    #[error("{0}")]
    Spin(String),
    #[error(
        "the equilibrium's Jacobian is singular{at}: the mechanism can move without resistance \
         (a free rigid-body motion or a mechanism with no load holding it), or its constraints \
         are redundant at this state"
    )]
    Singular { at: String },
    #[error(
        "the equilibrium did not converge: Newton's method failed at {load:.4} of the load \
         (gravity and spin speed) after {steps} load steps; the mechanism may buckle or have no \
         equilibrium near the start"
    )]
    NotConverged { load: f64, steps: usize },
    #[error(
        "joint `{joint}` is not steady under the spin: its equation {equation} changes as the \
         mechanism turns (|Φ̇| = {residual:.3e}); a steady spin needs every joint to the ground \
         on the spin axis or turning with it"
    )]
    NotSteady {
        joint: String,
        equation: usize,
        residual: f64,
    },
    #[error("the eigenvalues of the linearised equations did not converge")]
    Eigen,
    #[error("the state at t = {t} s cannot be linearised: {reason}")]
    State { t: f64, reason: String },
}

/// Options of [`equilibrium`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EquilibriumOptions {
    /// Convergence: the largest Newton increment, in metres (rotations times the mechanism's
    /// size, modal coordinates as they are), below `tol · size`.
    pub tol: f64,
    /// Newton iterations per load step.
    pub max_iterations: usize,
    /// Most load steps before giving up.
    pub max_load_steps: usize,
}

impl Default for EquilibriumOptions {
    fn default() -> Self {
        Self {
            tol: 1e-11,
            max_iterations: 25,
            max_load_steps: 64,
        }
    }
}

/// A static equilibrium or steady spin ([`equilibrium`]).
#[derive(Clone, Debug)]
pub struct OperatingPoint {
    /// The drivers' time of the equilibrium.
    pub t: f64,
    pub spin: Option<Spin>,
    /// Positions, and the velocities of the spin (zero when static).
    pub state: State,
    /// The constraint rows solved for (independent), and their multipliers.
    pub rows: Vec<usize>,
    pub lambda: Vec<f64>,
    /// Newton iterations in all, and load steps.
    pub iterations: usize,
    pub load_steps: usize,
    /// `∂[E; Φ]/∂[d; λ]` at the solution, and its LU (the sensitivities' solves).
    jacobian: DMatrix<f64>,
    factor: nalgebra::LU<f64, nalgebra::Dyn, nalgebra::Dyn>,
}

impl Spin {
    /// The spin of angle driver `joint` at `speed`: the axis and centre of its ground marker
    /// (the driver turns its body about the ground; a driver between two bodies is refused).
    pub fn of_driver<P: Scalar>(
        model: &Model<P>,
        joint: JointId,
        speed: f64,
    ) -> Result<Spin, OperatingError> {
        let j = model.joint(joint);
        if !matches!(j.kind, JointKind::AngleDriver(_)) {
            return Err(OperatingError::Spin(format!(
                "joint `{}` is not an angle driver: the spin is about an angle driver's axis",
                j.name
            )));
        }
        let (ground, sign) = match (j.a.body, j.b.body) {
            (None, Some(_)) => (&j.a, 1.0),
            (Some(_), None) => (&j.b, -1.0),
            _ => {
                return Err(OperatingError::Spin(format!(
                    "angle driver `{}` does not turn a body relative to the ground: a steady \
                     spin is about a driver with one marker on the ground",
                    j.name
                )));
            }
        };
        let centre = match &ground.site {
            crate::Site::Point(p) => *p,
            crate::Site::Node(_) => unreachable!("ground markers are points"),
        };
        Ok(Spin {
            axis: ground.axes.column(2).into_owned(),
            centre,
            speed: sign * speed,
        })
    }

    /// The velocities `vₛ` and accelerations `v̇ₛ` of the rigid spin at `q` (per body
    /// `ṙ = Ω × (r − c)`, `ω' = AᵀΩ`, `ẇ = 0`; `r̈ = Ω × (Ω × (r − c))`, `ω̇' = 0`, `ẅ = 0`).
    fn motion<P: Scalar, S: Scalar>(&self, model: &Model<P>, q: &[S]) -> (Vec<S>, Vec<S>) {
        let mut v = vec![S::zero(); model.n_v()];
        let mut a = vec![S::zero(); model.n_v()];
        let omega: Vector3<S> = (self.axis * self.speed).map(S::from_f64);
        for id in model.body_ids() {
            let (qo, vo) = (model.q_range(id).start, model.v_range(id).start);
            let r = Vector3::new(q[qo], q[qo + 1], q[qo + 2]) - self.centre.map(S::from_f64);
            let rd = omega.cross(&r);
            let rdd = omega.cross(&rd);
            let am = rotation(&Vector4::new(q[qo + 3], q[qo + 4], q[qo + 5], q[qo + 6]));
            let w = mtv(&am, &omega);
            for i in 0..3 {
                v[vo + i] = rd[i];
                a[vo + i] = rdd[i];
                v[vo + 3 + i] = w[i];
            }
        }
        (v, a)
    }

    /// `G u`: the rotating frame's Coriolis operator on the velocity variables at `q` applied
    /// to `u` (`2 Ω × u` on the translations, `ω'ₛ × u` on the body-frame rotations, with
    /// `ω'ₛ = AᵀΩ`, zero on the modal coordinates).
    fn coriolis_times<P: Scalar, S: Scalar>(&self, model: &Model<P>, q: &[S], u: &[f64]) -> Vec<S> {
        let mut out = vec![S::zero(); model.n_v()];
        let omega: Vector3<S> = (self.axis * self.speed).map(S::from_f64);
        let (v, _) = self.motion::<P, S>(model, q);
        for id in model.body_ids() {
            let o = model.v_range(id).start;
            let w = Vector3::new(v[o + 3], v[o + 4], v[o + 5]);
            let ut = Vector3::new(u[o], u[o + 1], u[o + 2]).map(S::from_f64);
            let ur = Vector3::new(u[o + 3], u[o + 4], u[o + 5]).map(S::from_f64);
            let (gt, gr) = (omega.cross(&ut), w.cross(&ur));
            for i in 0..3 {
                out[o + i] = gt[i] * 2.0;
                out[o + 3 + i] = gr[i];
            }
        }
        out
    }

    /// `G` as a matrix at `q`.
    fn coriolis<P: Scalar>(&self, model: &Model<P>, q: &[f64]) -> DMatrix<f64> {
        let n = model.n_v();
        let mut g = DMatrix::zeros(n, n);
        let mut e = vec![0.0; n];
        for j in 0..n {
            e[j] = 1.0;
            g.column_mut(j)
                .copy_from_slice(&self.coriolis_times::<P, f64>(model, q, &e));
            e[j] = 0.0;
        }
        g
    }
}

/// The equilibrium equations `[E; Φ_rows]` at `q` with multipliers `lambda` (of `rows`).
fn residual<P: Scalar, S: Scalar + From<P>>(
    model: &Model<P>,
    t: f64,
    spin: Option<&Spin>,
    rows: &[usize],
    q: &[S],
    lambda: &[S],
) -> Vec<S> {
    let (v, a) = steady_motion(model, spin, q);
    equations(model, t, rows, (q, &v, &a), lambda)
}

/// The spin's velocities and accelerations at `q` (zero without a spin).
fn steady_motion<P: Scalar, S: Scalar>(
    model: &Model<P>,
    spin: Option<&Spin>,
    q: &[S],
) -> (Vec<S>, Vec<S>) {
    match spin {
        Some(s) => s.motion(model, q),
        None => (vec![S::zero(); model.n_v()], vec![S::zero(); model.n_v()]),
    }
}

/// `[M(q) a − f(q, v) + Φ_vᵀ λ; Φ_rows(q)]`.
fn equations<P: Scalar, S: Scalar + From<P>>(
    model: &Model<P>,
    t: f64,
    rows: &[usize],
    (q, v, a): (&[S], &[S], &[S]),
    lambda: &[S],
) -> Vec<S> {
    let (m, f) = model.mass_and_forces(t, q, v);
    let k = model.constraint_kin(t, q, v);
    let mut out: Vec<S> = m.mul(a).into_iter().zip(f).map(|(x, y)| x - y).collect();
    for (&row, &l) in rows.iter().zip(lambda) {
        for (col, &x) in k[row].jac.iter() {
            out[col] += x * l;
        }
    }
    out.extend(rows.iter().map(|&r| k[r].val));
    out
}

/// `∂q/∂d`: column `j` the change of `q` along velocity variable `j` (the kinematic rates of
/// a unit velocity).
pub(crate) fn increment_map(model: &Model<f64>, q: &[f64]) -> DMatrix<f64> {
    let (nq, nv) = (model.n_q(), model.n_v());
    let mut t = DMatrix::zeros(nq, nv);
    let mut e = vec![0.0; nv];
    let mut qd = vec![0.0; nq];
    for j in 0..nv {
        e[j] = 1.0;
        model.kinematic_rates(q, &e, &mut qd);
        t.column_mut(j).copy_from_slice(&qd);
        e[j] = 0.0;
    }
    t
}

/// The residual and its Jacobian `∂[E; Φ]/∂[d; λ]` at `(q, λ)`.
fn residual_and_jacobian(
    model: &Model<f64>,
    t: f64,
    spin: Option<&Spin>,
    rows: &[usize],
    q: &[f64],
    lambda: &[f64],
) -> (Vec<f64>, DMatrix<f64>) {
    let nv = model.n_v();
    let n = nv + rows.len();
    let map = increment_map(model, q);
    let mut jac = DMatrix::zeros(n, n);
    let lam: Vec<Dual<WIDTH>> = lambda.iter().map(|&l| Dual::constant(l)).collect();
    let mut value = Vec::new();
    for cols in chunk_ranges(nv, WIDTH) {
        let qd = seeded::<WIDTH>(q, &map, &cols);
        let r = residual(model, t, spin, rows, &qd, &lam);
        for (k, j) in cols.enumerate() {
            for (i, x) in r.iter().enumerate() {
                jac[(i, j)] = x.d[k];
            }
        }
        value = r.iter().map(|x| x.v).collect();
    }
    let v = match spin {
        Some(s) => s.motion::<f64, f64>(model, q).0,
        None => vec![0.0; nv],
    };
    let k = model.constraint_kin(t, q, &v);
    for (a, &row) in rows.iter().enumerate() {
        for (col, &x) in k[row].jac.iter() {
            jac[(col, nv + a)] = x;
        }
    }
    (value, jac)
}

/// The static equilibrium (`spin` none) or steady spin of `model` at the drivers' time `t`,
/// from `start` (assembled), solving the constraint rows `rows` (independent).
///
/// The spin's driver must turn at the spin's speed: its motion a constant speed at `t`
/// (see [`Model::set_motion`]). Every joint must be steady under the spin, else
/// [`OperatingError::NotSteady`] names it. Gravity must lie along the spin axis (or vanish).
pub fn equilibrium(
    model: &Model<f64>,
    rows: &[usize],
    t: f64,
    start: &State,
    spin: Option<Spin>,
    options: &EquilibriumOptions,
) -> Result<OperatingPoint, OperatingError> {
    if let Some(s) = &spin
        && s.speed != 0.0
        && model.gravity.cross(&s.axis).norm() > 1e-12 * model.gravity.norm()
    {
        return Err(OperatingError::Spin(
            "gravity across the spin axis turns with the rotating frame: a steady spin needs \
             gravity along the axis or none"
                .into(),
        ));
    }
    if let Some(s) = &spin {
        // every joint must turn with the spin (checked at the start: the joints' kinematics
        // do not change their steadiness as the bodies deform)
        check_steady(model, t, &start.q, &s.motion::<f64, f64>(model, &start.q).0)?;
    }
    let size = crate::mechanism_size(model, &start.q);
    let mut q = start.q.clone();
    let mut lambda = vec![0.0; rows.len()];
    // the multipliers that balance the start's loads best: the constraint forces' stiffness
    // holds a mechanism whose loads alone do not (a pendulum under gravity)
    if let Some(l) = start_multipliers(model, t, spin.as_ref(), rows, &q) {
        lambda = l;
    }
    let (mut load, mut step) = (0.0f64, 1.0f64);
    let (mut iterations, mut load_steps) = (0, 0);
    let mut scaled = model.clone();
    loop {
        let target = (load + step).min(1.0);
        scaled.gravity = model.gravity * target;
        let spin_at = spin.map(|s| Spin {
            speed: s.speed * target,
            ..s
        });
        load_steps += 1;
        match newton(
            &scaled,
            t,
            spin_at.as_ref(),
            rows,
            &q,
            &lambda,
            size,
            options,
        ) {
            Ok((qn, ln, it)) => {
                iterations += it;
                (q, lambda) = (qn, ln);
                load = target;
                if load >= 1.0 {
                    break;
                }
                step *= 2.0;
            }
            Err(NewtonFailure::Singular) if load_steps == 1 => {
                return Err(OperatingError::Singular { at: String::new() });
            }
            Err(_) => step /= 4.0,
        }
        if load_steps >= options.max_load_steps || step < 1e-6 {
            return Err(OperatingError::NotConverged {
                load,
                steps: load_steps,
            });
        }
    }
    let (_, jacobian) = residual_and_jacobian(model, t, spin.as_ref(), rows, &q, &lambda);
    let factor = jacobian.clone().lu();
    if !factor.is_invertible() || !jacobian.iter().all(|x| x.is_finite()) {
        return Err(OperatingError::Singular {
            at: " at the solution".into(),
        });
    }
    let v = match &spin {
        Some(s) => s.motion::<f64, f64>(model, &q).0,
        None => vec![0.0; model.n_v()],
    };
    if spin.is_some() {
        check_steady(model, t, &q, &v)?;
    }
    Ok(OperatingPoint {
        t,
        spin,
        state: State { q, v },
        rows: rows.to_vec(),
        lambda,
        iterations,
        load_steps,
        jacobian,
        factor,
    })
}

/// The least-squares multipliers of `E(q, λ) = 0` at `q`: `Φ_v Φ_vᵀ λ = Φ_v (f − M v̇ₛ)`.
fn start_multipliers(
    model: &Model<f64>,
    t: f64,
    spin: Option<&Spin>,
    rows: &[usize],
    q: &[f64],
) -> Option<Vec<f64>> {
    let zero = vec![0.0; rows.len()];
    let r = residual(model, t, spin, rows, q, &zero);
    let nv = model.n_v();
    let c = model.constraints(t, q, &vec![0.0; nv]);
    let jac = c.jacobian.select_rows(rows);
    let rhs = &jac * DVector::from_iterator(nv, r[..nv].iter().map(|x| -x));
    (&jac * jac.transpose())
        .lu()
        .solve(&rhs)
        .map(|l| l.iter().copied().collect())
}

/// Every constraint keeps `Φ̇ = 0` under the spin's velocities.
fn check_steady(model: &Model<f64>, t: f64, q: &[f64], v: &[f64]) -> Result<(), OperatingError> {
    let c = model.constraints(t, q, v);
    let scale = v.iter().fold(1e-300f64, |m, x| m.max(x.abs()));
    if let Some((row, &r)) = (c.phi_dot.iter().enumerate())
        .filter(|(_, x)| x.abs() > 1e-8 * scale)
        .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
    {
        let j = model.joint_of_row(row);
        return Err(OperatingError::NotSteady {
            joint: model.joint(j).name.clone(),
            equation: row - model.joint_rows(j).start,
            residual: r.abs(),
        });
    }
    Ok(())
}

enum NewtonFailure {
    Singular,
    Diverged,
}

/// Newton's method from `(q, λ)` at one load; the solution and the iterations taken.
#[allow(clippy::too_many_arguments)]
fn newton(
    model: &Model<f64>,
    t: f64,
    spin: Option<&Spin>,
    rows: &[usize],
    q0: &[f64],
    lambda0: &[f64],
    size: f64,
    options: &EquilibriumOptions,
) -> Result<(Vec<f64>, Vec<f64>, usize), NewtonFailure> {
    let nv = model.n_v();
    let (mut q, mut lambda) = (q0.to_vec(), lambda0.to_vec());
    let mut last = f64::INFINITY;
    let increment_size = |model: &Model<f64>, d: &[f64]| {
        let mut m = 0.0f64;
        for id in model.body_ids() {
            let r = model.v_range(id);
            for (i, x) in d[r.clone()].iter().enumerate() {
                let s = if (3..6).contains(&i) { size } else { 1.0 };
                m = m.max((x * s).abs());
            }
        }
        m
    };
    for it in 1..=options.max_iterations {
        let (r, jac) = residual_and_jacobian(model, t, spin, rows, &q, &lambda);
        if !r.iter().all(|x| x.is_finite()) {
            return Err(NewtonFailure::Diverged);
        }
        let lu = jac.lu();
        let Some(dx) = lu.solve(&DVector::from_iterator(r.len(), r.iter().map(|x| -x))) else {
            return Err(NewtonFailure::Singular);
        };
        if !dx.iter().all(|x| x.is_finite()) {
            return Err(NewtonFailure::Singular);
        }
        let d = &dx.as_slice()[..nv];
        let step = increment_size(model, d);
        // a step that grows is a divergence (only the first may be large)
        if it > 2 && step > last {
            if step < 1e3 * options.tol * size {
                return Ok((q, lambda, it));
            }
            return Err(NewtonFailure::Diverged);
        }
        apply_increment(model, &mut q, d);
        for (l, x) in lambda.iter_mut().zip(&dx.as_slice()[nv..]) {
            *l += x;
        }
        if step <= options.tol * size {
            return Ok((q, lambda, it));
        }
        last = step;
    }
    Err(NewtonFailure::Diverged)
}

/// One eigenvalue of a linearised operating point and its mode.
#[derive(Clone, Debug)]
pub struct LinearMode {
    /// `s`, with `e^{st}` the mode's time dependence (rad/s).
    pub eigenvalue: Complex<f64>,
    /// The mode in the velocity variables (`d`, `n_v` complex components), unit largest
    /// component.
    pub shape: DVector<Complex<f64>>,
    /// The modes of equal eigenvalues (within a relative 1e-6) share a group number; zero for
    /// a single one, else the group's number from 1.
    pub group: usize,
    /// The right and left eigenvectors of the reduced problem (of a group: one of the pair of
    /// bases of its left and right null spaces).
    right: DVector<Complex<f64>>,
    left: DVector<Complex<f64>>,
}

/// Relative distance below which eigenvalues count as repeated.
pub const REPEATED: f64 = 1e-6;

impl LinearMode {
    /// `|s| / 2π` (Hz): the undamped natural frequency.
    pub fn frequency_hz(&self) -> f64 {
        self.eigenvalue.norm() / (2.0 * std::f64::consts::PI)
    }

    /// `Im s / 2π` (Hz): the damped frequency (zero for a real eigenvalue).
    pub fn damped_frequency_hz(&self) -> f64 {
        self.eigenvalue.im.abs() / (2.0 * std::f64::consts::PI)
    }

    /// `−Re s / |s|` (zero for a zero eigenvalue); negative when the mode grows.
    pub fn damping_ratio(&self) -> f64 {
        let n = self.eigenvalue.norm();
        if n > 0.0 {
            -self.eigenvalue.re / n
        } else {
            0.0
        }
    }

    /// The derivative of [`LinearMode::frequency_hz`] from the eigenvalue's derivative `ds`.
    pub fn frequency_derivative(&self, ds: Complex<f64>) -> f64 {
        let n = self.eigenvalue.norm();
        if n > 0.0 {
            (self.eigenvalue.conj() * ds).re / n / (2.0 * std::f64::consts::PI)
        } else {
            0.0
        }
    }
}

/// The linearised equations about an operating point, reduced to independent coordinates
/// `d = N z`: `M̄ z̈ + C̄ ż + K̄ z = 0`.
#[derive(Clone, Debug)]
pub struct Linearisation {
    /// `N`, `n_v × f`, orthonormal columns spanning the null space of `Φ_v`.
    pub basis: DMatrix<f64>,
    pub mass: DMatrix<f64>,
    /// Damping and gyroscopic terms.
    pub damping: DMatrix<f64>,
    /// Elastic, geometric, centrifugal and constraint-force stiffness.
    pub stiffness: DMatrix<f64>,
    /// Of an operating point: the unreduced `M`, `C`, `K` (`n_v × n_v`) and the rows' `Φ_v`
    /// (for the eigenvalue derivatives).
    unreduced: Option<([DMatrix<f64>; 3], DMatrix<f64>)>,
}

impl OperatingPoint {
    /// The velocities and accelerations of this point's steady motion at the positions `q`
    /// (zero for a static equilibrium), in any scalar (e.g. positions seeded with the design
    /// derivatives).
    pub fn motion_at<P: Scalar, S: Scalar>(&self, model: &Model<P>, q: &[S]) -> (Vec<S>, Vec<S>) {
        steady_motion(model, self.spin.as_ref(), q)
    }

    /// The linearised equations about this operating point of `model` (the model it was
    /// found for).
    pub fn linearise(&self, model: &Model<f64>) -> Linearisation {
        let nv = model.n_v();
        let q = &self.state.q;
        let k = self.jacobian.view((0, 0), (nv, nv)).into_owned();
        let (m, _) = model.mass_and_forces(self.t, q, &self.state.v);
        let m = m.to_dense();
        // −f_v by dual numbers on the velocities
        let mut c = DMatrix::zeros(nv, nv);
        let qd: Vec<Dual<WIDTH>> = q.iter().map(|&x| Dual::constant(x)).collect();
        for cols in chunk_ranges(nv, WIDTH) {
            let vd: Vec<Dual<WIDTH>> = (self.state.v.iter().enumerate())
                .map(|(i, &x)| match cols.clone().position(|j| j == i) {
                    Some(k) => Dual::variable(x, k),
                    None => Dual::constant(x),
                })
                .collect();
            let (_, f) = model.mass_and_forces(self.t, &qd, &vd);
            for (k, j) in cols.enumerate() {
                for i in 0..nv {
                    c[(i, j)] = -f[i].d[k];
                }
            }
        }
        if let Some(s) = &self.spin {
            c += &m * s.coriolis(model, q);
        }
        let kin = model.constraints(self.t, q, &self.state.v);
        let jacobian = kin.jacobian.select_rows(&self.rows);
        let basis = null_space(&jacobian);
        let project = |a: &DMatrix<f64>| basis.transpose() * a * &basis;
        Linearisation {
            mass: project(&m),
            damping: project(&c),
            stiffness: project(&k),
            basis,
            unreduced: Some(([m, c, k], jacobian)),
        }
    }
}

/// Orthonormal columns spanning the null space of `a` (`m × n`).
fn null_space(a: &DMatrix<f64>) -> DMatrix<f64> {
    let n = a.ncols();
    if a.nrows() == 0 {
        return DMatrix::identity(n, n);
    }
    let eig = (a.transpose() * a).symmetric_eigen();
    let scale = eig.eigenvalues.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let cols: Vec<usize> = (0..n)
        .filter(|&i| eig.eigenvalues[i].abs() <= 1e-10 * scale.max(1e-300))
        .collect();
    eig.eigenvectors.select_columns(&cols)
}

type CMatrix = DMatrix<Complex<f64>>;
type CVector = DVector<Complex<f64>>;

fn complex(a: &DMatrix<f64>) -> CMatrix {
    a.map(|x| Complex::new(x, 0.0))
}

impl Linearisation {
    /// The minimal-coordinate form `I z̈ + C z' + K z = 0` with `d = basis · z`.
    pub(crate) fn minimal(
        basis: DMatrix<f64>,
        stiffness: DMatrix<f64>,
        damping: DMatrix<f64>,
    ) -> Self {
        Self {
            mass: DMatrix::identity(basis.ncols(), basis.ncols()),
            damping,
            stiffness,
            basis,
            unreduced: None,
        }
    }

    /// The number of independent coordinates.
    pub fn dim(&self) -> usize {
        self.basis.ncols()
    }

    /// `M̄ s² + C̄ s + K̄`.
    fn reduced_operator(&self, s: Complex<f64>) -> CMatrix {
        complex(&self.mass) * (s * s) + complex(&self.damping) * s + complex(&self.stiffness)
    }

    /// The eigenvalues of `M̄ s² + C̄ s + K̄` with their modes: one of each complex-conjugate
    /// pair (`Im s > 0`) and every real one, by increasing `|s|`.
    pub fn modes(&self) -> Result<Vec<LinearMode>, OperatingError> {
        let f = self.dim();
        if f == 0 {
            return Ok(Vec::new());
        }
        let Some(minv) = self.mass.clone().try_inverse() else {
            return Err(OperatingError::Singular {
                at: " (the reduced mass matrix)".into(),
            });
        };
        let mut a = DMatrix::zeros(2 * f, 2 * f);
        a.view_mut((0, f), (f, f)).fill_with_identity();
        a.view_mut((f, 0), (f, f))
            .copy_from(&(-&minv * &self.stiffness));
        a.view_mut((f, f), (f, f))
            .copy_from(&(-&minv * &self.damping));
        // faer's QR iteration (nalgebra's can stall for many minutes on defective pairs)
        let values = faer::Mat::from_fn(2 * f, 2 * f, |i, j| a[(i, j)])
            .eigenvalues()
            .map_err(|_| OperatingError::Eigen)?;
        let mut values: Vec<Complex<f64>> = (values.iter())
            .map(|s| Complex::new(s.re, s.im))
            .filter(|s| s.im >= 0.0)
            .collect();
        values.sort_by(|a, b| a.norm().total_cmp(&b.norm()));
        let mut modes = Vec::with_capacity(values.len());
        let mut group = 0;
        let mut i = 0;
        while i < values.len() {
            let s0 = values[i];
            let mut j = i + 1;
            while j < values.len() && (values[j] - s0).norm() <= REPEATED * s0.norm().max(1e-300) {
                j += 1;
            }
            let r = j - i;
            let mean = values[i..j].iter().sum::<Complex<f64>>() / r as f64;
            let (right, left) = null_spaces(&self.reduced_operator(mean), r);
            if r > 1 {
                group += 1;
            }
            for (k, &s) in values[i..j].iter().enumerate() {
                let shape = complex(&self.basis) * right.column(k);
                let big = shape.iter().fold(Complex::new(0.0, 0.0), |m, x| {
                    if x.norm() > m.norm() { *x } else { m }
                });
                modes.push(LinearMode {
                    eigenvalue: s,
                    shape: if big.norm() > 0.0 { shape / big } else { shape },
                    group: if r > 1 { group } else { 0 },
                    right: right.column(k).into_owned(),
                    left: left.column(k).into_owned(),
                });
            }
            i = j;
        }
        Ok(modes)
    }
}

/// Orthonormal bases of the right and left null spaces of dimension `r` of the square `q`:
/// its singular vectors of the `r` smallest singular values.
fn null_spaces(q: &CMatrix, r: usize) -> (CMatrix, CMatrix) {
    let svd = q.clone().svd(true, true);
    let (u, v_t) = (svd.u.expect("asked for U"), svd.v_t.expect("asked for Vᵀ"));
    let mut order: Vec<usize> = (0..svd.singular_values.len()).collect();
    order.sort_by(|&a, &b| svd.singular_values[a].total_cmp(&svd.singular_values[b]));
    let right = CMatrix::from_fn(q.ncols(), r, |i, k| v_t[(order[k], i)].conj());
    let left = CMatrix::from_fn(q.nrows(), r, |i, k| u[(i, order[k])]);
    (right, left)
}

/// Design sensitivities of an operating point: `∂q/∂b`, `∂v/∂b` (the spin's velocities at the
/// moved positions) and `∂λ/∂b`, one column per design variable.
#[derive(Clone, Debug)]
pub struct OperatingSensitivities {
    pub q: DMatrix<f64>,
    pub v: DMatrix<f64>,
    pub lambda: DMatrix<f64>,
}

impl OperatingPoint {
    /// The equilibrium's derivatives with respect to the design variables of `design` (whose
    /// values are the model of this operating point): `J [∂d; ∂λ] = −∂[E; Φ]/∂b`, with the
    /// factorisation of the equilibrium's Jacobian.
    pub fn sensitivities<const N: usize>(
        &self,
        design: &DesignModel<N>,
    ) -> Result<OperatingSensitivities, OperatingError> {
        let values = design.values();
        let (nq, nv) = (values.n_q(), values.n_v());
        let m = design.n_variables();
        let map = increment_map(&values, &self.state.q);
        let qd: Vec<Dual<N>> = self.state.q.iter().map(|&x| Dual::constant(x)).collect();
        let ld: Vec<Dual<N>> = self.lambda.iter().map(|&x| Dual::constant(x)).collect();
        let mut out = OperatingSensitivities {
            q: DMatrix::zeros(nq, m),
            v: DMatrix::zeros(nv, m),
            lambda: DMatrix::zeros(self.rows.len(), m),
        };
        for (model, range) in design.chunk_ranges() {
            let r = residual(model, self.t, self.spin.as_ref(), &self.rows, &qd, &ld);
            for (k, j) in range.enumerate() {
                let rhs = DVector::from_iterator(r.len(), r.iter().map(|x| -x.d[k]));
                let Some(dx) = self.factor.solve(&rhs) else {
                    return Err(OperatingError::Singular {
                        at: " at the solution".into(),
                    });
                };
                let dq = &map * dx.rows(0, nv);
                out.q.column_mut(j).copy_from(&dq);
                out.lambda
                    .column_mut(j)
                    .copy_from(&dx.rows(nv, self.rows.len()));
                if let Some(s) = &self.spin {
                    let q1: Vec<Dual<1>> = (self.state.q.iter().zip(dq.iter()))
                        .map(|(&x, &dx)| Dual::new(x, [dx]))
                        .collect();
                    let (v, _) = s.motion::<f64, Dual<1>>(&values, &q1);
                    for (i, x) in v.iter().enumerate() {
                        out.v[(i, j)] = x.d[0];
                    }
                }
            }
        }
        Ok(out)
    }
}

/// What the eigenvalue derivative of one mode needs: the unreduced right mode `x` with the
/// multipliers' amplitude `μ` (`L(s) x + Φ_vᵀ μ = 0`), the left vector `[y; ν]` of the
/// constrained problem and `yᴴ (2 s M + C) x`.
struct ModeVectors {
    s: Complex<f64>,
    x: CVector,
    mu: CVector,
    left: CVector,
    /// `(2 s M + C) x`.
    slope: CVector,
}

/// The eigenvalue derivatives of the modes `group` (one, or a group of repeated ones) from
/// their vectors and `g` = `(∂T/∂b) [x; μ]` of each mode: for a group of `r`, the
/// eigenvalues of `−(Yᴴ T_s X)⁻¹ (Ŷᴴ G)` — the derivatives along the design variable, in
/// the basis of the group that it diagonalises — by increasing real part.
fn group_derivatives(
    vectors: &[ModeVectors],
    g: &[CVector],
    group: &[usize],
) -> Vec<(usize, Complex<f64>)> {
    let nv = vectors[group[0]].x.len();
    let y = |a: usize| vectors[group[a]].left.rows(0, nv).into_owned();
    let r = group.len();
    let slopes = CMatrix::from_fn(r, r, |a, b| y(a).dotc(&vectors[group[b]].slope));
    let numerator = CMatrix::from_fn(r, r, |a, b| vectors[group[a]].left.dotc(&g[group[b]]));
    let zero = Complex::new(0.0, 0.0);
    let Some(d) = slopes.lu().solve(&numerator) else {
        return group
            .iter()
            .map(|&i| (i, Complex::new(f64::NAN, f64::NAN)))
            .collect();
    };
    let mut values: Vec<Complex<f64>> = match r {
        1 => vec![-d[(0, 0)]],
        _ => (-d)
            .schur()
            .eigenvalues()
            .map(|e| e.iter().copied().collect())
            .unwrap_or_else(|| vec![zero; r]),
    };
    values.sort_by(|a, b| a.re.total_cmp(&b.re));
    group.iter().copied().zip(values).collect()
}

impl Linearisation {
    fn mode_vectors(&self, mode: &LinearMode) -> ModeVectors {
        let s = mode.eigenvalue;
        let ([m, c, k], jac) = (self.unreduced.as_ref())
            .expect("eigenvalue derivatives need an operating point's linearisation");
        let basis = complex(&self.basis);
        let (x, y) = (&basis * &mode.right, &basis * &mode.left);
        let l = complex(k) + complex(c) * s + complex(m) * (s * s);
        // (J Jᵀ)⁻¹ J v, the multipliers that balance v in the least-squares sense
        let jjt = (jac * jac.transpose()).lu();
        let balance = |v: &CVector| -> CVector {
            let part = |f: fn(&Complex<f64>) -> f64| {
                let r = jac * v.map(|z| f(&z));
                jjt.solve(&r).unwrap_or_else(|| DVector::zeros(r.len()))
            };
            let (re, im) = (part(|z| z.re), part(|z| z.im));
            CVector::from_fn(re.len(), |i, _| Complex::new(re[i], im[i]))
        };
        let mu = -balance(&(&l * &x));
        let nu = -balance(&(l.adjoint() * &y));
        let slope = (complex(m) * (s * 2.0) + complex(c)) * &x;
        let mut left = CVector::zeros(y.len() + nu.len());
        left.rows_mut(0, y.len()).copy_from(&y);
        left.rows_mut(y.len(), nu.len()).copy_from(&nu);
        ModeVectors {
            s,
            x,
            mu,
            left,
            slope,
        }
    }
}

impl OperatingPoint {
    /// The design derivatives `ds/db_j` of the eigenvalues of `modes` (from `lin`, this
    /// point's linearisation of the values of `design`), through the equilibrium's own
    /// derivatives `sens` ([`OperatingPoint::sensitivities`]); rows: modes.
    ///
    /// For the constrained eigenproblem `T(s) [x; μ] = [L(s) x + Φ_vᵀ μ; Φ_v x] = 0`,
    /// `ds/db = −[y; ν]ᴴ (∂T/∂b) [x; μ] / yᴴ (2 s M + C) x`; `(∂T/∂b) [x; μ]` is the design
    /// derivative of the equations' derivative along the mode (`d = x`, `ḋ = s x`,
    /// `d̈ = s² x`, `δλ = μ`), both exact at once as the mixed part of hyper-dual numbers
    /// (`ε₁` along the mode, `ε₂` along the design variable and the equilibrium's
    /// derivative), for the real and imaginary parts of the mode.
    pub fn eigenvalue_derivatives<const N: usize>(
        &self,
        lin: &Linearisation,
        modes: &[LinearMode],
        design: &DesignModel<N>,
        sens: &OperatingSensitivities,
    ) -> DMatrix<Complex<f64>> {
        let vectors: Vec<ModeVectors> = modes.iter().map(|m| lin.mode_vectors(m)).collect();
        // the modes of a group of repeated eigenvalues together, the others one by one
        let mut groups: Vec<Vec<usize>> = Vec::new();
        for (i, m) in modes.iter().enumerate() {
            match groups.last_mut() {
                Some(g) if m.group > 0 && modes[g[0]].group == m.group => g.push(i),
                _ => groups.push(vec![i]),
            }
        }
        let zero = Complex::new(0.0, 0.0);
        let mut out = DMatrix::from_element(modes.len(), design.n_variables(), zero);
        for (chunk, range) in design.chunk_ranges() {
            for (k, j) in range.enumerate() {
                let model = chunk.map(|p: Dual<N>| HyperDual::new(p.v, 0.0, p.d[k]));
                let q: Vec<HyperDual> = (self.state.q.iter().enumerate())
                    .map(|(i, &x)| HyperDual::new(x, 0.0, sens.q[(i, j)]))
                    .collect();
                let lambda: Vec<HyperDual> = (self.lambda.iter().enumerate())
                    .map(|(a, &x)| HyperDual::new(x, 0.0, sens.lambda[(a, j)]))
                    .collect();
                let g: Vec<CVector> = (vectors.iter())
                    .map(|v| {
                        let re = self.mixed_along(&model, &q, &lambda, v, |z| z.re);
                        let im = self.mixed_along(&model, &q, &lambda, v, |z| z.im);
                        CVector::from_fn(re.len(), |r, _| Complex::new(re[r], im[r]))
                    })
                    .collect();
                for group in &groups {
                    for (i, ds) in group_derivatives(&vectors, &g, group) {
                        out[(i, j)] = ds;
                    }
                }
            }
        }
        out
    }

    /// The mixed parts of the equations at the hyper-dual state `(q, λ)` moved by `ε₁` along
    /// the part `part` (real or imaginary) of the mode `v`.
    fn mixed_along(
        &self,
        model: &Model<HyperDual>,
        q: &[HyperDual],
        lambda: &[HyperDual],
        v: &ModeVectors,
        part: fn(&Complex<f64>) -> f64,
    ) -> Vec<f64> {
        let nv = model.n_v();
        let dir = |z: &CVector| -> Vec<f64> { z.iter().map(part).collect() };
        let (x, sx, ssx) = (dir(&v.x), dir(&(&v.x * v.s)), dir(&(&v.x * (v.s * v.s))));
        let eps = |u: f64| HyperDual::new(0.0, u, 0.0);
        // q ⊕ ε₁ x, exact to the mixed order (the increment map moves with the equilibrium)
        let inc: Vec<HyperDual> = x.iter().map(|&u| eps(u)).collect();
        let mut qdot = vec![HyperDual::from(0.0); q.len()];
        model.kinematic_rates(q, &inc, &mut qdot);
        let qh: Vec<HyperDual> = q.iter().zip(&qdot).map(|(a, b)| *a + *b).collect();
        let (mut vh, mut ah) = steady_motion(model, self.spin.as_ref(), &qh);
        let gsx = match &self.spin {
            Some(s) => s.coriolis_times(model, q, &sx),
            None => vec![HyperDual::from(0.0); nv],
        };
        for i in 0..nv {
            vh[i] += eps(sx[i]);
            ah[i] += eps(1.0) * gsx[i] + eps(ssx[i]);
        }
        let lh: Vec<HyperDual> = (lambda.iter().zip(dir(&v.mu)))
            .map(|(l, m)| *l + eps(m))
            .collect();
        equations(model, self.t, &self.rows, (&qh, &vh, &ah), &lh)
            .iter()
            .map(|r| r.mixed())
            .collect()
    }
}
