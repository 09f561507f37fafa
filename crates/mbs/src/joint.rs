//! Kinematic joints and drivers between two markers (Nikravesh-style constraint primitives).
//!
//! Every joint is built from the marker point difference `d = x_B − x_A` and dot products of
//! marker axes, so its Jacobian and `γ` follow from the product rule in [`crate::kin`].

use sens::Scalar;

use crate::kin::{Kin, Kin3};
use crate::marker::MarkerKin;

/// Handle of a joint in a [`crate::Model`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct JointId(pub(crate) usize);

impl JointId {
    pub fn index(self) -> usize {
        self.0
    }
}

/// A prescribed function of time `f(t)` (rad or m) with its first two derivatives.
#[derive(Clone, Debug, PartialEq)]
pub enum TimeFunction {
    /// `f = f0 + rate · t`.
    ConstantSpeed { initial: f64, rate: f64 },
    /// `f = Σ c_i t^i`.
    Polynomial(Vec<f64>),
    /// From `from` (held until `t0`) to `to` (reached at `t1`, held after) along the cycloidal
    /// step `s(τ) = τ − sin(2πτ)/(2π)`: zero velocity and acceleration at both ends.
    SmoothRamp {
        from: f64,
        to: f64,
        t0: f64,
        t1: f64,
    },
    /// A spin-up from rest: the rate rises from 0 to `speed` over `[0, duration]` along the
    /// cycloidal step, `ḟ = speed · (τ − sin(2πτ)/(2π))` with `τ = t/duration`, and stays at
    /// `speed` after (Kane, Ryan & Banerjee 1987); `f(0) = 0`.
    SpinUp { speed: f64, duration: f64 },
}

impl TimeFunction {
    /// Times where the motion changes its law (the ends of a ramp or a spin-up): the
    /// integrator lands on them rather than stepping across.
    pub fn breakpoints(&self) -> Vec<f64> {
        match self {
            TimeFunction::SmoothRamp { t0, t1, .. } => vec![*t0, *t1],
            TimeFunction::SpinUp { duration, .. } => vec![0.0, *duration],
            TimeFunction::ConstantSpeed { .. } | TimeFunction::Polynomial(_) => Vec::new(),
        }
    }

    /// `[f, ḟ, f̈]` at `t`.
    pub fn eval(&self, t: f64) -> [f64; 3] {
        match self {
            TimeFunction::ConstantSpeed { initial, rate } => [initial + rate * t, *rate, 0.0],
            TimeFunction::Polynomial(c) => {
                let f = c.iter().rev().fold(0.0, |acc, &ci| acc * t + ci);
                poly_eval(c, t, f)
            }
            TimeFunction::SmoothRamp { from, to, t0, t1 } => {
                let span = t1 - t0;
                if t <= *t0 {
                    [*from, 0.0, 0.0]
                } else if t >= *t1 {
                    [*to, 0.0, 0.0]
                } else {
                    let tau = (t - t0) / span;
                    let w = 2.0 * std::f64::consts::PI;
                    let s = tau - (w * tau).sin() / w;
                    let sd = (1.0 - (w * tau).cos()) / span;
                    let sdd = w * (w * tau).sin() / (span * span);
                    let dv = to - from;
                    [from + dv * s, dv * sd, dv * sdd]
                }
            }
            TimeFunction::SpinUp { speed, duration } => {
                let (w, d) = (2.0 * std::f64::consts::PI, *duration);
                if t >= d {
                    // f(d) = speed · (d/2 + (cos 2π − 1) d/(2π)²) = speed · d / 2
                    [speed * (0.5 * d + (t - d)), *speed, 0.0]
                } else {
                    let tau = t / d;
                    let f = speed * d * (0.5 * tau * tau + ((w * tau).cos() - 1.0) / (w * w));
                    let fd = speed * (tau - (w * tau).sin() / w);
                    let fdd = speed * (1.0 - (w * tau).cos()) / d;
                    [f, fd, fdd]
                }
            }
        }
    }
}

fn poly_eval(c: &[f64], t: f64, f: f64) -> [f64; 3] {
    let mut fd = 0.0;
    let mut fdd = 0.0;
    for (i, &ci) in c.iter().enumerate().skip(1) {
        fd += i as f64 * ci * t.powi(i as i32 - 1);
        if i >= 2 {
            fdd += (i * (i - 1)) as f64 * ci * t.powi(i as i32 - 2);
        }
    }
    [f, fd, fdd]
}

/// The kind of a joint between markers A and B (B relative to A).
#[derive(Clone, Debug, PartialEq)]
pub enum JointKind {
    /// Points coincide (3 equations).
    Spherical,
    /// Points coincide, axes `e3` parallel (5).
    Revolute,
    /// Points coincide, axes `e3_A ⟂ e3_B` (the two cross-pin axes) (4).
    Universal,
    /// Axes `e3` parallel and B's point on A's axis (4).
    Cylindrical,
    /// Cylindrical plus no rotation about the axis (5).
    Translational,
    /// Points coincide, triads stay aligned (6).
    Fixed,
    /// Relative rotation of B about A's `e3`, measured from `e1_A` to `e1_B`, prescribed (1).
    /// Usually paired with a revolute joint.
    AngleDriver(TimeFunction),
    /// Displacement of B's point along A's `e3`, `e3_A · (x_B − x_A)`, prescribed (1).
    /// Usually paired with a translational joint.
    DistanceDriver(TimeFunction),
}

impl JointKind {
    /// Number of constraint equations.
    pub fn n_equations(&self) -> usize {
        match self {
            JointKind::Spherical => 3,
            JointKind::Revolute => 5,
            JointKind::Universal => 4,
            JointKind::Cylindrical => 4,
            JointKind::Translational => 5,
            JointKind::Fixed => 6,
            JointKind::AngleDriver(_) | JointKind::DistanceDriver(_) => 1,
        }
    }
}

/// Append the constraint equations of a joint of kind `kind` between markers `a` and `b`.
pub(crate) fn joint_equations<S: Scalar>(
    kind: &JointKind,
    a: &MarkerKin<S>,
    b: &MarkerKin<S>,
    t: f64,
    out: &mut Vec<Kin<S>>,
) {
    let d: Kin3<S> = b.point.sub(&a.point);
    let sph = |out: &mut Vec<Kin<S>>| {
        for i in 0..3 {
            out.push(d.component(i));
        }
    };
    // the marker axes e1, e2, e3 are indices 0, 1, 2; each computed only if used
    match kind {
        JointKind::Spherical => sph(out),
        JointKind::Revolute => {
            sph(out);
            let b3 = b.axis(2);
            out.push(a.axis(0).dot(&b3));
            out.push(a.axis(1).dot(&b3));
        }
        JointKind::Universal => {
            sph(out);
            out.push(a.axis(2).dot(&b.axis(2)));
        }
        JointKind::Cylindrical => {
            let (a1, a2, b3) = (a.axis(0), a.axis(1), b.axis(2));
            out.push(a1.dot(&b3));
            out.push(a2.dot(&b3));
            out.push(a1.dot(&d));
            out.push(a2.dot(&d));
        }
        JointKind::Translational => {
            let (a1, a2, b3) = (a.axis(0), a.axis(1), b.axis(2));
            out.push(a1.dot(&b3));
            out.push(a2.dot(&b3));
            out.push(a1.dot(&d));
            out.push(a2.dot(&d));
            out.push(a1.dot(&b.axis(1)));
        }
        JointKind::Fixed => {
            sph(out);
            let a3 = a.axis(2);
            out.push(a.axis(1).dot(&b.axis(2)));
            out.push(a3.dot(&b.axis(0)));
            out.push(a.axis(0).dot(&b.axis(1)));
        }
        JointKind::AngleDriver(f) => {
            // ρ sin(f − θ) with ρ cos θ = e1A·e1B, ρ sin θ = e2A·e1B
            let b1 = b.axis(0);
            let c = a.axis(0).dot(&b1);
            let s = a.axis(1).dot(&b1);
            let [fv, fd, fdd] = f.eval(t);
            let (sf, cf) = fv.sin_cos();
            let sin_f = Kin::of_time([
                S::from_f64(sf),
                S::from_f64(cf * fd),
                S::from_f64(-sf * fd * fd + cf * fdd),
            ]);
            let cos_f = Kin::of_time([
                S::from_f64(cf),
                S::from_f64(-sf * fd),
                S::from_f64(-cf * fd * fd - sf * fdd),
            ]);
            out.push(c.mul(&sin_f).sub(&s.mul(&cos_f)));
        }
        JointKind::DistanceDriver(f) => {
            let x = a.axis(2).dot(&d);
            let [fv, fd, fdd] = f.eval(t);
            let ft = Kin::of_time([S::from_f64(fv), S::from_f64(fd), S::from_f64(fdd)]);
            out.push(x.sub(&ft));
        }
    }
}
