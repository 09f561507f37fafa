//! One start of the optimiser: SLSQP driven through its callbacks, every evaluation logged.

use std::cell::Cell;

use super::*;

/// Run SLSQP from `x0`, logging every evaluation; returns how it ended.
pub(super) fn run_start(
    p: &Problem,
    start: usize,
    x0: &[f64],
    log: &Mutex<Vec<Row>>,
    stop: &AtomicBool,
    quiet: bool,
) -> String {
    let sign = if p.def.maximize { -1.0 } else { 1.0 };
    // the last design evaluated: SLSQP asks for the objective and each constraint in turn
    let last: RefCell<Option<Evaluated>> = RefCell::new(None);
    let count = AtomicUsize::new(0);
    // the KKT stationarity of the feasible evaluation that met `optimize.kkt_tolerance`: the
    // evaluations after it are refused, which ends SLSQP
    let kkt_met: Cell<Option<f64>> = Cell::new(None);
    let scale_f = RefCell::new(None::<f64>);
    // SLSQP works in the unit box: y = (x − lower) / (upper − lower), so that variables of any
    // unit (degrees, metres, pascals) are equally scaled
    let width: Vec<f64> = p.def.bounds.iter().map(|(lo, hi)| hi - lo).collect();
    let to_x = |y: &[f64]| -> Vec<f64> {
        y.iter()
            .zip(&p.def.bounds)
            .map(|(y, (lo, hi))| (lo + y * (hi - lo)).clamp(*lo, *hi))
            .collect()
    };
    let at = |y: &[f64]| -> Result<Eval, String> {
        let x = to_x(y);
        let x = x.as_slice();
        if let Some((lx, e)) = &*last.borrow()
            && lx.as_slice() == x
        {
            return e.clone();
        }
        if stop.load(Ordering::SeqCst) {
            return Err("interrupted".into());
        }
        if kkt_met.get().is_some() {
            return Err("converged".into());
        }
        let e = p.evaluate(x).map_err(|e| e.to_string());
        let evaluation = count.fetch_add(1, Ordering::SeqCst) + 1;
        let (violation, stationarity, multipliers) = match &e {
            Ok(ev) => {
                let (s, m) = p.kkt(x, ev);
                (p.violation(ev), s, m)
            }
            Err(_) => (f64::NAN, f64::NAN, Vec::new()),
        };
        if !quiet {
            report(p, (start, evaluation), &e, (violation, stationarity));
        }
        log.lock().expect("no poisoned lock").push(Row {
            start,
            evaluation,
            x: x.to_vec(),
            eval: e.clone(),
            violation,
            stationarity,
            multipliers,
        });
        if let Some(tol) = p.def.kkt_tolerance
            && e.is_ok()
            && violation <= FEASIBLE
            && stationarity <= tol
        {
            kkt_met.set(Some(stationarity));
        }
        *last.borrow_mut() = Some((x.to_vec(), e.clone()));
        e
    };
    let objective = |x: &[f64], grad: Option<&mut [f64]>, _: &mut ()| -> f64 {
        match at(x) {
            Ok(e) => {
                let s =
                    *scale_f
                        .borrow_mut()
                        .get_or_insert(if e.f != 0.0 { e.f.abs() } else { 1.0 });
                if let Some(g) = grad {
                    for ((g, d), w) in g.iter_mut().zip(&e.df).zip(&width) {
                        *g = sign * d * w / s;
                    }
                }
                sign * e.f / s
            }
            Err(_) => f64::NAN,
        }
    };
    let inequalities = p.inequalities();
    let constraint_fns: Vec<Box<dyn slsqp::Func<()> + '_>> = inequalities
        .iter()
        .map(|&(i, s)| {
            let at = &at;
            let width = &width;
            let bound = p.bound_value(i);
            let scale = p.limits[i].1;
            // SLSQP meets a constraint to round-off only, and a frequency carries the eigen
            // solver's (about 1e-10): an inequality is tightened, an equality widened to a
            // band, by MARGIN of its scale, so that its converged designs count as feasible
            let margin = match p.limits[i].0 {
                Bound::AtLeast(_) | Bound::AtMost(_) => MARGIN,
                Bound::Equals(_) | Bound::EqualsNominal => -MARGIN,
            };
            Box::new(
                move |x: &[f64], grad: Option<&mut [f64]>, _: &mut ()| -> f64 {
                    match at(x) {
                        Ok(e) => {
                            if let Some(g) = grad {
                                for ((g, d), w) in g.iter_mut().zip(&e.dq[i]).zip(width) {
                                    *g = s * d * w / scale;
                                }
                            }
                            s * (e.q[i] - bound) / scale + margin
                        }
                        Err(_) => f64::NAN,
                    }
                },
            ) as Box<dyn slsqp::Func<()> + '_>
        })
        .collect();
    let cons: Vec<&dyn slsqp::Func<()>> = constraint_fns.iter().map(|f| f.as_ref()).collect();
    let y0: Vec<f64> = x0
        .iter()
        .zip(&p.def.bounds)
        .map(|(x, (lo, hi))| (x - lo) / (hi - lo))
        .collect();
    // converged when the objective changes by less than the tolerance, or the design by less
    // than 1e-9 of each variable's range
    let tols = slsqp::StopTols {
        ftol_rel: p.def.tolerance,
        xtol_abs: vec![1e-9; x0.len()],
        ..Default::default()
    };
    let result = slsqp::minimize(
        objective,
        &y0,
        &vec![(0.0, 1.0); x0.len()],
        &cons,
        (),
        p.def.max_evaluations,
        Some(tols),
    );
    let kkt = kkt_met
        .get()
        .map(|s| (s, p.def.kkt_tolerance.unwrap_or_default()));
    outcome(stop.load(Ordering::SeqCst), kkt, &result)
}

/// One evaluation's line on stderr.
fn report(
    p: &Problem,
    (start, evaluation): (usize, usize),
    e: &Result<Eval, String>,
    (violation, stationarity): (f64, f64),
) {
    match e {
        Ok(ev) => eprintln!(
            "[start {start}] evaluation {evaluation}: {} = {:.6e}, violation {:.1e}, \
             stationarity {:.1e}",
            p.def.objective.label(),
            ev.f,
            violation,
            stationarity
        ),
        Err(m) => eprintln!("[start {start}] evaluation {evaluation} failed: {m}"),
    }
}

/// What `slsqp::minimize` returns.
type SlsqpOutcome =
    Result<(slsqp::SuccessStatus, Vec<f64>, f64), (slsqp::FailStatus, Vec<f64>, f64)>;

/// How a start ended, as the summary says it: interrupted, converged on the KKT conditions
/// (`kkt`: the stationarity met and `optimize.kkt_tolerance`), or SLSQP's own ending.
fn outcome(interrupted: bool, kkt: Option<(f64, f64)>, result: &SlsqpOutcome) -> String {
    if interrupted {
        return "interrupted".to_string();
    }
    if let Some((s, tol)) = kkt {
        return format!("converged (KKT stationarity {s:.1e} ≤ kkt_tolerance {tol:e})");
    }
    match result {
        Ok((slsqp::SuccessStatus::MaxEvalReached, ..)) => "evaluation limit reached".into(),
        Ok((s, ..)) => format!("converged ({s:?})"),
        Err((e, ..)) => format!("stopped ({e:?})"),
    }
}
