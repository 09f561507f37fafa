//! The per-step information the integrator exposes ([`mbs::AcceptedStep`]) is enough to
//! integrate forward sensitivities on the same step sequence with the same BDF formula
//! ("staggered direct", docs/design.md §3): on `x'' = −k x` the result is the exact derivative of
//! the discrete solution (checked against finite differences of runs on identical steps) and
//! approximates the analytic `∂x/∂k`.

use std::collections::VecDeque;

use mbs::{Bdf, BdfOptions, OdeSystem, RhsError};
use nalgebra::{DMatrix, Matrix2, Vector2};

struct Oscillator {
    k: f64,
}

impl OdeSystem for Oscillator {
    fn dim(&self) -> usize {
        2
    }
    fn rhs(&mut self, _t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), RhsError> {
        dy[0] = y[1];
        dy[1] = -self.k * y[0];
        Ok(())
    }
    fn jacobian(&mut self, _t: f64, _y: &[f64], j: &mut DMatrix<f64>) -> Result<(), RhsError> {
        j.fill(0.0);
        j[(0, 1)] = 1.0;
        j[(1, 0)] = -self.k;
        Ok(())
    }
}

/// State and `∂y/∂k` at `t_end`.
fn run(k: f64, opts: BdfOptions, t_end: f64) -> (Vec<f64>, Vector2<f64>) {
    let mut sys = Oscillator { k };
    let mut bdf = Bdf::new(opts);
    bdf.init(&mut sys, 0.0, &[1.0, 0.0]).unwrap();
    let mut s_hist: VecDeque<Vector2<f64>> = VecDeque::from([Vector2::zeros()]);
    let out = bdf
        .integrate_to(&mut sys, t_end, &[t_end], |b| {
            let step = b.last_step();
            let y = step.states[0];
            // (c0 I − f_y) s_{n+1} = −Σ_{j≥1} c_j s_{n+1−j} + f_k(y_{n+1}), f_y exact here
            let fy = Matrix2::new(0.0, 1.0, -k, 0.0);
            let mut rhs = Vector2::new(0.0, -y[0]);
            for j in 1..=step.order {
                rhs -= s_hist[j - 1] * step.coefficients[j];
            }
            let m = Matrix2::identity() * step.coefficients[0] - fy;
            let s = m.lu().solve(&rhs).unwrap();
            s_hist.push_front(s);
            s_hist.truncate(8);
        })
        .unwrap();
    (out[0].clone(), s_hist[0])
}

#[test]
fn staggered_direct_sensitivities_on_the_integrators_steps() {
    let (k, t_end) = (4.0, 2.0);
    // fixed steps: the discrete solution's derivative, against central differences of runs
    // on the identical step sequence
    let fixed = || BdfOptions::fixed(1e-3, 4);
    let (_, s) = run(k, fixed(), t_end);
    let dk = 1e-5;
    let (yp, _) = run(k + dk, fixed(), t_end);
    let (ym, _) = run(k - dk, fixed(), t_end);
    let fd = Vector2::new(yp[0] - ym[0], yp[1] - ym[1]) / (2.0 * dk);
    assert!(
        (s - fd).norm() < 1e-8 * s.norm(),
        "staggered {s:?} vs discrete FD {fd:?}"
    );
    // adaptive steps: close to the analytic derivative of x = cos(√k t)
    let (_, s) = run(k, BdfOptions::adaptive(1e-9, 1e-12), t_end);
    let w = k.sqrt();
    let exact = -(w * t_end).sin() * t_end / (2.0 * w);
    assert!((s[0] - exact).abs() < 1e-6, "∂x/∂k = {} vs {exact}", s[0]);
}
