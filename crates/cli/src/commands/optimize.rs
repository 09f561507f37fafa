//! `flexsens optimize`: gradient-based optimisation of the deck's `[design.*]` variables
//! (`[optimize]`, see `docs/optimization.md`).
//!
//! Each evaluation builds the deck at the design `x` (the variables' values written in as
//! `--set` would), and reads each quantity with its exact gradient: an `[objective.*]` from
//! the run's direct sensitivities, a frequency from the modal analysis and Nelson's eigenvalue
//! derivative, a flexible body's mass from its lumped masses in dual numbers (a rigid body's
//! from its mass variable), a laminate's mass per area through the shells' design map. The
//! algorithm is SLSQP (Kraft's sequential least squares programming, NLopt's implementation
//! through the `slsqp` crate), started from the deck's
//! design and from each `starts` entry, several starts at once (`-j`). Every evaluation is
//! logged with its objective, constraints, gradient norm and KKT stationarity; the best
//! feasible design is written as a deck, run, and summarised.

use std::cell::RefCell;
use std::fmt::Write as _;
use std::path::Path;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use nalgebra::{DMatrix, DVector};
use sens::Dual;

use crate::deck::design::{DesignVariable, Target, validate as validate_design};
use crate::deck::laminates::validate as validate_laminates;
use crate::deck::optimize::{Bound, OptimizeDef, Quantity, validate as validate_optimize};
use crate::deck::{self, Source, bodies, mechanism};
use crate::error::CliError;
use crate::files::write_atomic;
use crate::plot::{Figure, Panel, Series};
use crate::study::Study;
use crate::study::flexible::{CHUNK, DesignRequest, build, fem_error};
use crate::table::{CsvTable, number};

/// What `flexsens optimize` was asked for.
pub struct OptimizeRequest<'a> {
    /// Output directory (default `<deck stem>.optimize` beside the deck).
    pub out: Option<&'a Path>,
    /// Starts run at once (default: the available cores).
    pub jobs: Option<usize>,
    /// No progress lines on stderr.
    pub quiet: bool,
    /// Set when the user interrupts (Ctrl-C): the runs stop and the best point is written.
    pub stop: &'a AtomicBool,
    /// `I/N`: run only the I-th of N deterministic slices of the starts (every N-th from the
    /// I-th), into its own directory, for `flexsens merge`.
    pub shard: Option<&'a str>,
}

/// A constraint within 1e-6 of its bound (relative to its scale) counts as met.
const FEASIBLE: f64 = 1e-6;

/// What the optimiser sees of a bound: inequalities tightened and equalities widened by this
/// (relative to their scale), well inside [`FEASIBLE`].
const MARGIN: f64 = 1e-8;

/// The values and gradients of the objective and the constrained quantities at one design.
#[derive(Clone, Debug)]
struct Eval {
    /// The units of the objective and of each constrained quantity.
    units: Vec<String>,
    f: f64,
    df: Vec<f64>,
    /// Per constraint: the quantity's value and gradient.
    q: Vec<f64>,
    dq: Vec<Vec<f64>>,
}

/// A design and what its evaluation gave.
type Evaluated = (Vec<f64>, Result<Eval, String>);

/// One logged evaluation.
#[derive(Clone, Debug)]
struct Row {
    start: usize,
    evaluation: usize,
    x: Vec<f64>,
    eval: Result<Eval, String>,
    /// Largest constraint violation relative to its scale (0 when met).
    violation: f64,
    /// KKT stationarity (relative) and the multipliers of the constraints.
    stationarity: f64,
    multipliers: Vec<f64>,
}

/// The problem: the deck, its design variables and `[optimize]`, and the constraint bounds
/// resolved (`"nominal"` replaced by the value at the deck's design).
struct Problem<'a> {
    path: &'a Path,
    overrides: &'a [String],
    variables: Vec<DesignVariable>,
    def: OptimizeDef,
    /// Per constraint: its bound resolved and its scale (for the optimiser and the violation).
    limits: Vec<(Bound, f64)>,
}

fn runtime(m: impl Into<String>) -> CliError {
    CliError::Runtime(m.into())
}

impl Problem<'_> {
    /// The `--set` arguments that put the design `x` into the deck.
    fn sets(&self, x: &[f64]) -> Vec<String> {
        let mut sets = self.overrides.to_vec();
        for (v, &b) in self.variables.iter().zip(x) {
            sets.extend(v.overrides(b));
        }
        sets
    }

    /// Every quantity the problem reads, with its gradient, at the design `x`.
    fn evaluate(&self, x: &[f64]) -> Result<Eval, CliError> {
        let sets = self.sets(x);
        let (src, raw) = deck::load(self.path, &sets)?;
        let quantities: Vec<&Quantity> = std::iter::once(&self.def.objective)
            .chain(self.def.constraints.iter().map(|c| &c.quantity))
            .collect();
        // the run, once, when an objective of it is asked for
        let objectives = if quantities
            .iter()
            .any(|q| matches!(q, Quantity::Objective { .. }))
        {
            let mut mech = Study::validate(&src, &raw, true)?;
            mech.design.finite_differences = None;
            let c = super::compute::compute(&src, &mech)?;
            c.objectives
                .into_iter()
                .map(|o| (o.name, (o.value, o.gradient, o.unit)))
                .collect()
        } else {
            std::collections::BTreeMap::new()
        };
        let lam = validate_laminates(&src, &raw)?;
        let design = validate_design(&src, &raw, &lam)?;
        // each flexible body's modal analysis and masses once per evaluation
        let mut bodies = std::collections::BTreeMap::<String, FlexibleQuantities>::new();
        let mut flexible = |body: &String| -> Result<FlexibleQuantities, CliError> {
            if let Some(b) = bodies.get(body) {
                return Ok(b.clone());
            }
            let b = flexible_quantities(&src, &raw, &lam, &design, body)?;
            bodies.insert(body.clone(), b.clone());
            Ok(b)
        };
        let mut read = |q: &Quantity| -> Result<(f64, Vec<f64>, &'static str), CliError> {
            Ok(match q {
                Quantity::Objective { name } => objectives[name].clone(),
                Quantity::Frequency { body, mode } => {
                    let b = flexible(body)?;
                    let n = b.frequencies.len();
                    let f = b.frequencies.get(*mode).ok_or_else(|| {
                        CliError::Input(src.error(
                            None,
                            Some("optimize".into()),
                            format!("frequency.{body}.{}: the body keeps {n} modes", mode + 1),
                        ))
                    })?;
                    (*f, b.d_frequencies[*mode].clone(), "Hz")
                }
                Quantity::Mass { body } if raw.body.contains_key(body) => {
                    let b = flexible(body)?;
                    (b.mass, b.d_mass, "kg")
                }
                Quantity::ArealMass { laminate } => {
                    let def = &lam.laminates[laminate];
                    let d = crate::study::flexible::shell_design(
                        &def.stack,
                        laminate,
                        &def.ply_materials,
                        DesignRequest::Variables(&design.variables),
                    );
                    let grad = super::laminate::derivatives(&d)
                        .iter()
                        .map(|k| k.mass_per_area)
                        .collect();
                    (def.stack.stiffness().mass_per_area, grad, "kg/m^2")
                }
                Quantity::Mass { body } => {
                    let rigid = mechanism::rigid_bodies(&src, &raw)?;
                    let r = rigid
                        .iter()
                        .find(|r| r.name == *body)
                        .expect("validated body name");
                    let grad = self
                        .variables
                        .iter()
                        .map(|v| match &v.target {
                            Target::RigidMass { body: b } if b == body => 1.0,
                            _ => 0.0,
                        })
                        .collect();
                    (r.mass, grad, "kg")
                }
            })
        };
        let n = self.variables.len();
        let gradient_of = |q: &Quantity, g: &[f64]| -> Result<(), CliError> {
            if g.len() == n {
                return Ok(());
            }
            Err(CliError::Input(src.error(
                None,
                Some("optimize".into()),
                format!(
                    "{} has no gradient (its response has no sensitivities, or [sensitivity] \
                     enabled = false): an optimisation needs one",
                    q.label()
                ),
            )))
        };
        let (f, df, unit) = read(&self.def.objective)?;
        gradient_of(&self.def.objective, &df)?;
        let mut units = vec![unit.to_string()];
        let mut q = Vec::new();
        let mut dq = Vec::new();
        for c in &self.def.constraints {
            let (v, g, unit) = read(&c.quantity)?;
            gradient_of(&c.quantity, &g)?;
            units.push(unit.to_string());
            q.push(v);
            dq.push(g);
        }
        let ok = |x: f64| x.is_finite();
        let all_ok = ok(f)
            && df.iter().copied().all(ok)
            && q.iter().copied().all(ok)
            && dq.iter().flatten().copied().all(ok);
        if !all_ok {
            return Err(runtime("a quantity or its gradient is not finite"));
        }
        Ok(Eval {
            units,
            f,
            df,
            q,
            dq,
        })
    }

    /// The constraints as `g ≤ 0` in physical units: `(constraint, sign)` with
    /// `g = sign (q − bound)`; an equality gives both signs.
    fn inequalities(&self) -> Vec<(usize, f64)> {
        let mut g = Vec::new();
        for (i, (bound, _)) in self.limits.iter().enumerate() {
            match bound {
                Bound::AtLeast(_) => g.push((i, -1.0)),
                Bound::AtMost(_) => g.push((i, 1.0)),
                Bound::Equals(_) | Bound::EqualsNominal => {
                    g.push((i, 1.0));
                    g.push((i, -1.0));
                }
            }
        }
        g
    }

    fn bound_value(&self, i: usize) -> f64 {
        match self.limits[i].0 {
            Bound::AtLeast(b) | Bound::AtMost(b) | Bound::Equals(b) => b,
            Bound::EqualsNominal => unreachable!("resolved when the problem is made"),
        }
    }

    /// The largest violation of a constraint, relative to its scale.
    fn violation(&self, e: &Eval) -> f64 {
        self.inequalities()
            .into_iter()
            .map(|(i, s)| (s * (e.q[i] - self.bound_value(i)) / self.limits[i].1).max(0.0))
            .fold(0.0, f64::max)
    }

    /// KKT stationarity of the (minimised) objective at `x` with the constraints within
    /// `FEASIBLE` of their bounds taken as active: the multipliers `λ ≥ 0` (free in sign for
    /// an equality) that best cancel the gradient on the variables not at a bound, and the
    /// largest remaining component of the Lagrangian's gradient, as the change of the
    /// objective across the variable's range relative to the objective (`|r_j| (upper_j −
    /// lower_j) / |f|`; components at a bound count only when they point out of the box): 0 at
    /// a KKT point. Multipliers are in the objective's unit per the constraint quantity's
    /// unit (`dF*/d bound`).
    fn kkt(&self, x: &[f64], e: &Eval) -> (f64, Vec<f64>) {
        let sign = if self.def.maximize { -1.0 } else { 1.0 };
        let g: Vec<f64> = e.df.iter().map(|d| sign * d).collect();
        let n = x.len();
        let at_lower: Vec<bool> = (0..n)
            .map(|j| x[j] <= self.def.bounds[j].0 + 1e-9 * (1.0 + x[j].abs()))
            .collect();
        let at_upper: Vec<bool> = (0..n)
            .map(|j| x[j] >= self.def.bounds[j].1 - 1e-9 * (1.0 + x[j].abs()))
            .collect();
        // active constraints: (constraint, sign of g, free sign?)
        let mut active: Vec<(usize, f64, bool)> = Vec::new();
        for (i, (bound, scale)) in self.limits.iter().enumerate() {
            let r = (e.q[i] - self.bound_value(i)) / scale;
            match bound {
                Bound::AtLeast(_) if r <= FEASIBLE => active.push((i, -1.0, false)),
                Bound::AtMost(_) if r >= -FEASIBLE => active.push((i, 1.0, false)),
                Bound::Equals(_) | Bound::EqualsNominal => active.push((i, 1.0, true)),
                _ => {}
            }
        }
        let free: Vec<usize> = (0..n).filter(|&j| !at_lower[j] && !at_upper[j]).collect();
        let mut lambda = vec![0.0; self.limits.len()];
        loop {
            let m = active.len();
            if m == 0 || free.is_empty() {
                break;
            }
            // least squares over the free variables: min ‖g_F + A_F λ‖
            let a = DMatrix::from_fn(free.len(), m, |r, c| {
                let (i, s, _) = active[c];
                s * e.dq[i][free[r]]
            });
            let rhs = DVector::from_iterator(free.len(), free.iter().map(|&j| -g[j]));
            let ata = a.transpose() * &a
                + DMatrix::identity(m, m) * 1e-14 * (a.norm_squared() + f64::MIN_POSITIVE);
            let sol = ata
                .lu()
                .solve(&(a.transpose() * rhs))
                .unwrap_or_else(|| DVector::zeros(m));
            // drop the most negative multiplier of an inequality and solve again
            let worst = (0..m)
                .filter(|&c| !active[c].2 && sol[c] < 0.0)
                .min_by(|&p, &q| sol[p].total_cmp(&sol[q]));
            match worst {
                Some(c) => {
                    active.remove(c);
                }
                None => {
                    for (c, &(i, s, _)) in active.iter().enumerate() {
                        lambda[i] += s * sol[c];
                    }
                    break;
                }
            }
        }
        // residual ∇f + Σ λ_i ∇q_i (λ signed: g = s (q − b), λ_g = λ_i s)
        let r: Vec<f64> = (0..n)
            .map(|j| {
                g[j] + (0..lambda.len())
                    .map(|i| lambda[i] * e.dq[i][j])
                    .sum::<f64>()
            })
            .collect();
        let worst = (0..n)
            .map(|j| {
                let out_of_box = if at_lower[j] {
                    (-r[j]).max(0.0)
                } else if at_upper[j] {
                    r[j].max(0.0)
                } else {
                    r[j].abs()
                };
                out_of_box * (self.def.bounds[j].1 - self.def.bounds[j].0)
            })
            .fold(0.0, f64::max);
        // relative to the objective, or absolute where it is zero
        let size = if e.f != 0.0 { e.f.abs() } else { 1.0 };
        // multipliers as the sensitivity of the optimum to each bound b_i: with
        // ℒ = sign f + Σ λ_i (q_i − b_i), d(sign f*)/db_i = −λ_i
        // (+ 0.0: an inactive constraint prints 0, not −0)
        let multipliers = lambda.iter().map(|l| -sign * l + 0.0).collect();
        (worst / size.max(f64::MIN_POSITIVE), multipliers)
    }
}

/// `--set` arguments that give every mesh file of the deck (`section.*.file`, `body.*.file`)
/// as an absolute path, so that the optimum deck, written elsewhere, reads the same meshes.
fn absolute_file_keys(path: &Path, overrides: &[String]) -> Result<Vec<String>, CliError> {
    let (_, raw) = deck::load(path, overrides)?;
    let dir = path.parent().unwrap_or(Path::new("."));
    let absolute = |f: &str| {
        let p = dir.join(f);
        std::fs::canonicalize(&p).unwrap_or(p).display().to_string()
    };
    let quote = |s: String| toml::Value::String(s).to_string();
    let mut sets = Vec::new();
    for (name, s) in &raw.section {
        if let Some(f) = &s.get_ref().file {
            sets.push(format!(
                "section.{name}.file={}",
                quote(absolute(f.get_ref()))
            ));
        }
    }
    for (name, b) in &raw.body {
        if let Some(f) = &b.get_ref().file {
            sets.push(format!("body.{name}.file={}", quote(absolute(f.get_ref()))));
        }
    }
    Ok(sets)
}

/// A flexible body's frequencies and mass with their gradients (per design variable).
#[derive(Clone)]
struct FlexibleQuantities {
    frequencies: Vec<f64>,
    /// `[mode][variable]`, Hz per unit of the variable.
    d_frequencies: Vec<Vec<f64>>,
    mass: f64,
    d_mass: Vec<f64>,
}

/// The retained modes' frequencies (Nelson's eigenvalue derivatives, updated modes) and the
/// mass (lumped masses in dual numbers) of flexible body `name`, at the deck's design.
fn flexible_quantities(
    src: &Source,
    raw: &deck::RawDeck,
    lam: &crate::deck::laminates::LaminateModel,
    design: &crate::deck::design::DesignDef,
    name: &str,
) -> Result<FlexibleQuantities, CliError> {
    let table = &raw.body[name];
    let def = bodies::validate_one(src, raw, name, table, lam)?;
    let mut built = build(src, name, &def, DesignRequest::Variables(&design.variables))?;
    let span = table.span();
    let (analysis, _) =
        crate::study::flexible::analyse(src, name, span.clone(), &def, &mut built, false)?;
    let d = built.eigenvalue_derivatives::<CHUNK>(src, name, span.clone(), &analysis)?;
    let m = design.variables.len();
    let mut frequencies = Vec::new();
    let mut d_frequencies = Vec::new();
    for &i in &analysis.kept {
        let l = analysis.pairs.values[i];
        frequencies.push(l.max(0.0).sqrt() / (2.0 * std::f64::consts::PI));
        d_frequencies.push(
            (0..m)
                .map(|v| d.eigenvalues[v][i] / (4.0 * std::f64::consts::PI * l.max(0.0).sqrt()))
                .collect(),
        );
    }
    let mut mass = 0.0;
    let mut d_mass = vec![0.0; m];
    for range in sens::chunk_ranges(m, CHUNK) {
        let seeded = sens::seed_chunk::<CHUNK>(built.design.values(), range.start);
        let props = built.design.properties(&seeded).map_err(|e| {
            runtime(format!(
                "{}: body `{name}`: its section: {e}",
                src.file.display()
            ))
        })?;
        let (masses, _) = fem::lumped_nodal_masses(&built.mesh, &props, &analysis.options.element)
            .map_err(|e| fem_error(src, name, span.clone(), e))?;
        let total = masses
            .iter()
            .fold(Dual::<CHUNK>::constant(0.0), |s, &x| s + x);
        mass = total.v;
        for (k, v) in range.enumerate() {
            d_mass[v] = total.d[k];
        }
    }
    Ok(FlexibleQuantities {
        frequencies,
        d_frequencies,
        mass,
        d_mass,
    })
}

/// Run SLSQP from `x0`, logging every evaluation; returns how it ended.
fn run_start(
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
            match &e {
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
        log.lock().expect("no poisoned lock").push(Row {
            start,
            evaluation,
            x: x.to_vec(),
            eval: e.clone(),
            violation,
            stationarity,
            multipliers,
        });
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
    if stop.load(Ordering::SeqCst) {
        "interrupted".to_string()
    } else {
        match result {
            Ok((slsqp::SuccessStatus::MaxEvalReached, ..)) => "evaluation limit reached".into(),
            Ok((s, ..)) => format!("converged ({s:?})"),
            Err((e, ..)) => format!("stopped ({e:?})"),
        }
    }
}

/// The best feasible evaluation (of one start, or of all).
fn best_feasible(p: &Problem, rows: &[Row], start: Option<usize>) -> Option<usize> {
    let sign = if p.def.maximize { -1.0 } else { 1.0 };
    rows.iter()
        .enumerate()
        .filter(|(_, r)| start.is_none_or(|s| r.start == s))
        .filter(|(_, r)| r.violation <= FEASIBLE)
        .filter_map(|(k, r)| r.eval.as_ref().ok().map(|e| (k, sign * e.f)))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(k, _)| k)
}

/// The units of the objective and the constrained quantities, from the first evaluation that
/// gave values.
fn units(rows: &[Row], count: usize) -> Vec<String> {
    rows.iter()
        .find_map(|r| r.eval.as_ref().ok().map(|e| e.units.clone()))
        .unwrap_or_else(|| vec!["?".to_string(); count])
}

fn iterations_csv(p: &Problem, rows: &[Row]) -> String {
    let units = units(rows, 1 + p.def.constraints.len());
    let mut head = vec!["start".to_string(), "evaluation".to_string()];
    head.extend(
        p.variables
            .iter()
            .map(|v| format!("{} [{}]", v.name, v.unit)),
    );
    head.push(format!("{} [{}]", p.def.objective.label(), units[0]));
    for (c, u) in p.def.constraints.iter().zip(&units[1..]) {
        head.push(format!("{} [{u}]", c.quantity.label()));
    }
    head.extend(["max_violation", "gradient_norm", "kkt_stationarity"].map(String::from));
    for c in &p.def.constraints {
        head.push(format!("multiplier {}", c.quantity.label()));
    }
    head.push("error".into());
    let mut t = CsvTable::new();
    t.row(head);
    for r in rows {
        let mut row = vec![r.start.to_string(), r.evaluation.to_string()];
        row.extend(r.x.iter().map(|x| number(*x)));
        match &r.eval {
            Ok(e) => {
                row.push(number(e.f));
                row.extend(e.q.iter().map(|q| number(*q)));
                let norm = e.df.iter().map(|d| d * d).sum::<f64>().sqrt();
                row.extend([number(r.violation), number(norm), number(r.stationarity)]);
                row.extend(r.multipliers.iter().map(|m| number(*m)));
                row.push(String::new());
            }
            Err(m) => {
                let empty = 2 + 2 * p.def.constraints.len() + 3;
                row.extend(std::iter::repeat_n(String::new(), empty));
                row.push(m.replace('\n', " "));
            }
        }
        t.row(row);
    }
    t.finish()
}

fn convergence_figure(p: &Problem, rows: &[Row], starts: usize) -> Figure {
    let mut objective = Vec::new();
    let mut violation = Vec::new();
    for start in 1..=starts {
        let (mut ex, mut f, mut vx, mut v) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for r in rows.iter().filter(|r| r.start == start) {
            if let Ok(e) = &r.eval {
                ex.push(r.evaluation as f64);
                f.push(e.f);
                vx.push(r.evaluation as f64);
                v.push(r.violation);
            }
        }
        objective.push(Series::solid(format!("start {start}"), &ex, &f, start - 1));
        violation.push(Series::solid(format!("start {start}"), &vx, &v, start - 1));
    }
    Figure {
        title: format!(
            "{} {}: convergence",
            if p.def.maximize {
                "maximise"
            } else {
                "minimise"
            },
            p.def.objective.label()
        ),
        panels: vec![
            Panel {
                title: "objective".into(),
                x_label: "evaluation".into(),
                y_label: format!(
                    "{} [{}]",
                    p.def.objective.label(),
                    units(rows, 1 + p.def.constraints.len())[0]
                ),
                series: objective,
            },
            Panel {
                title: "largest constraint violation".into(),
                x_label: "evaluation".into(),
                y_label: "relative violation [1]".into(),
                series: violation,
            },
        ],
    }
}

/// The deck's problem, with the constraints' bounds resolved and scaled at the deck's
/// design; and whether the deck is a mechanism (its optimum is run).
fn setup<'a>(path: &'a Path, overrides: &'a [String]) -> Result<(Problem<'a>, bool), CliError> {
    let (src, raw) = deck::load(path, overrides)?;
    let lam = validate_laminates(&src, &raw)?;
    let design = validate_design(&src, &raw, &lam)?;
    let def = validate_optimize(&src, &raw, &design)?;
    let mut problem = Problem {
        path,
        overrides,
        variables: design.variables.clone(),
        def,
        limits: Vec::new(),
    };
    // the nominal values of "equals = nominal" constraints and every constraint's scale come
    // from the deck's design
    let nominal = problem.evaluate(&problem.def.starts[0].clone())?;
    problem.limits = problem
        .def
        .constraints
        .iter()
        .zip(&nominal.q)
        .map(|(c, &q0)| {
            let bound = match c.bound {
                Bound::EqualsNominal => Bound::Equals(q0),
                b => b,
            };
            let b = match bound {
                Bound::AtLeast(b) | Bound::AtMost(b) | Bound::Equals(b) => b,
                Bound::EqualsNominal => q0,
            };
            // the larger of the bound and the nominal value, or 1 where both are zero
            let scale = b.abs().max(q0.abs());
            (bound, if scale > 0.0 { scale } else { 1.0 })
        })
        .collect();
    Ok((problem, raw.analysis.is_some()))
}

/// Run SLSQP from the starts `chosen` (0-based), `jobs` at once: every evaluation (sorted by
/// start and evaluation) and how each start ended.
fn solve(
    problem: &Problem,
    chosen: &[usize],
    req: &OptimizeRequest,
) -> (Vec<Row>, Vec<(usize, String)>) {
    let log = Mutex::new(Vec::<Row>::new());
    let jobs = super::job_count(req.jobs, chosen.len());
    let outcomes = super::parallel_map(chosen.len(), jobs, |j| {
        let s = chosen[j];
        run_start(
            problem,
            s + 1,
            &problem.def.starts[s],
            &log,
            req.stop,
            req.quiet,
        )
    });
    let mut rows = log.into_inner().expect("no poisoned lock");
    rows.sort_by_key(|r| (r.start, r.evaluation));
    let statuses = chosen.iter().map(|s| s + 1).zip(outcomes).collect();
    (rows, statuses)
}

/// What a shard of an optimisation writes beside its iterations for `flexsens merge`.
const EVALUATIONS_FILE: &str = "evaluations.jsonl";

fn row_json(r: &Row) -> serde_json::Value {
    let mut v = serde_json::json!({
        "start": r.start,
        "evaluation": r.evaluation,
        "x": r.x,
        "violation": r.violation,
        "stationarity": r.stationarity,
        "multipliers": r.multipliers,
    });
    match &r.eval {
        Ok(e) => {
            v["units"] = serde_json::json!(e.units);
            v["f"] = serde_json::json!(e.f);
            v["df"] = serde_json::json!(e.df);
            v["q"] = serde_json::json!(e.q);
            v["dq"] = serde_json::json!(e.dq);
        }
        Err(m) => v["error"] = serde_json::json!(m),
    }
    v
}

fn row_from_json(v: &serde_json::Value) -> Option<Row> {
    let floats = |v: &serde_json::Value| -> Option<Vec<f64>> {
        v.as_array()?
            .iter()
            .map(|x| x.as_f64().or(x.is_null().then_some(f64::NAN)))
            .collect()
    };
    let num = |v: &serde_json::Value| v.as_f64().unwrap_or(f64::NAN);
    let eval = match v["error"].as_str() {
        Some(m) => Err(m.to_string()),
        None => Ok(Eval {
            units: v["units"]
                .as_array()?
                .iter()
                .map(|u| u.as_str().map(String::from))
                .collect::<Option<_>>()?,
            f: v["f"].as_f64()?,
            df: floats(&v["df"])?,
            q: floats(&v["q"])?,
            dq: v["dq"]
                .as_array()?
                .iter()
                .map(floats)
                .collect::<Option<_>>()?,
        }),
    };
    Some(Row {
        start: v["start"].as_u64()? as usize,
        evaluation: v["evaluation"].as_u64()? as usize,
        x: floats(&v["x"])?,
        eval,
        violation: num(&v["violation"]),
        stationarity: num(&v["stationarity"]),
        multipliers: floats(&v["multipliers"])?,
    })
}

/// Run the command; the returned text goes to stdout, with the exit code (0: a feasible
/// optimum; 1: no feasible design found; 130: interrupted, the best design written).
pub fn run(
    path: &Path,
    overrides: &[String],
    req: &OptimizeRequest,
) -> Result<(String, u8), CliError> {
    let (problem, mechanism) = setup(path, overrides)?;
    let shard = req.shard.map(super::shard::parse_shard).transpose()?;
    let n_starts = problem.def.starts.len();
    let chosen = super::shard::shard_cases(n_starts, shard);
    if chosen.is_empty() {
        return Err(CliError::Usage(format!(
            "--shard {}: the problem has only {n_starts} starts, so this shard has none",
            req.shard.unwrap_or_default()
        )));
    }
    let out = req
        .out
        .map(Path::to_path_buf)
        .unwrap_or_else(|| super::default_dir(path, "optimize", shard));
    std::fs::create_dir_all(&out).map_err(|e| {
        runtime(format!(
            "cannot create the output directory {}: {e}",
            out.display()
        ))
    })?;
    // the optimum's run files too: a new optimisation without a feasible design (or without
    // a mechanism) must not leave an earlier optimum's results.h5 looking like its own
    for f in [
        "iterations.csv",
        "optimum.toml",
        "convergence.svg",
        "convergence.png",
        super::shard::SHARD_FILE,
        EVALUATIONS_FILE,
    ]
    .into_iter()
    .chain(super::run::OUTPUT_FILES)
    {
        super::shard::remove_old(&out.join(f))?;
    }
    let (rows, statuses) = solve(&problem, &chosen, req);
    let interrupted = req.stop.load(Ordering::SeqCst);
    if let Some((i, n)) = shard {
        let mut lines = String::new();
        for (s, status) in &statuses {
            lines += &(serde_json::json!({ "start": s, "status": status }).to_string() + "\n");
        }
        for r in &rows {
            lines += &(row_json(r).to_string() + "\n");
        }
        write_atomic(&out.join(EVALUATIONS_FILE), lines.as_bytes())?;
        write_atomic(
            &out.join("iterations.csv"),
            iterations_csv(&problem, &rows).as_bytes(),
        )?;
        // the manifest last, and only for a shard that ran to its end: a shard that has it is
        // complete (an interrupted one — Ctrl-C, a batch system's time limit — is not merged)
        if !interrupted {
            let extra = serde_json::json!({ "starts": n_starts });
            super::shard::write_manifest(&out, "optimize", path, overrides, (i, n), extra)?;
        }
        let text = format!(
            "shard {i}/{n}: {} of {n_starts} starts, {} evaluations{}; gather the shards with \
             `flexsens merge`\n",
            statuses.len(),
            rows.len(),
            if interrupted {
                " (interrupted: run the shard again before merging)"
            } else {
                ""
            }
        );
        return Ok((text, if interrupted { 130 } else { 0 }));
    }
    finish(&problem, mechanism, &rows, &statuses, &out, interrupted)
}

/// Gather the shards of one optimisation (`optimize --shard I/N`; their manifests already
/// checked to be the N shards of one problem) into `out`, as the optimisation on one machine
/// would have written it.
pub(crate) fn merge(
    dirs: &[std::path::PathBuf],
    manifests: &[serde_json::Value],
    out: &Path,
) -> Result<(String, u8), CliError> {
    let first = &manifests[0];
    let deck = std::path::PathBuf::from(first["deck"].as_str().unwrap_or_default());
    let set = super::shard::manifest_strings(first, "set");
    let (problem, mechanism) = setup(&deck, &set)?;
    let n_starts = problem.def.starts.len();
    let mut rows = Vec::new();
    let mut statuses = Vec::new();
    for (dir, m) in dirs.iter().zip(manifests) {
        let bad =
            |e: String| CliError::Usage(format!("{}: {EVALUATIONS_FILE}: {e}", dir.display()));
        let i = m["shard"][0].as_u64().unwrap_or(0) as usize;
        let n = m["shard"][1].as_u64().unwrap_or(0) as usize;
        if m["starts"].as_u64() != Some(n_starts as u64) {
            return Err(CliError::Usage(format!(
                "{}: the shard has {} starts, the deck {n_starts}",
                dir.display(),
                m["starts"]
            )));
        }
        let text = crate::limits::read_text(&dir.join(EVALUATIONS_FILE)).map_err(bad)?;
        let mut own = Vec::new();
        for (k, line) in text.lines().enumerate() {
            let v: serde_json::Value =
                serde_json::from_str(line).map_err(|e| bad(format!("line {}: {e}", k + 1)))?;
            if let Some(status) = v["status"].as_str() {
                own.push(v["start"].as_u64().unwrap_or(0) as usize);
                statuses.push((
                    v["start"].as_u64().unwrap_or(0) as usize,
                    status.to_string(),
                ));
            } else {
                rows.push(
                    row_from_json(&v)
                        .ok_or_else(|| bad(format!("line {}: not an evaluation", k + 1)))?,
                );
            }
        }
        let expected: Vec<usize> = super::shard::shard_cases(n_starts, Some((i, n)))
            .into_iter()
            .map(|s| s + 1)
            .collect();
        if own != expected {
            return Err(CliError::Usage(format!(
                "{}: shard {i}/{n} ran starts {own:?}, not its starts {expected:?}",
                dir.display()
            )));
        }
    }
    rows.sort_by_key(|r| (r.start, r.evaluation));
    statuses.sort();
    finish(&problem, mechanism, &rows, &statuses, out, false)
}

/// Write the results of an optimisation and its summary (see [`run`]).
fn finish(
    problem: &Problem,
    mechanism: bool,
    rows: &[Row],
    statuses: &[(usize, String)],
    out: &Path,
    interrupted: bool,
) -> Result<(String, u8), CliError> {
    let path = problem.path;
    let n_starts = problem.def.starts.len();
    std::fs::create_dir_all(out).map_err(|e| {
        runtime(format!(
            "cannot create the output directory {}: {e}",
            out.display()
        ))
    })?;
    write_atomic(
        &out.join("iterations.csv"),
        iterations_csv(problem, rows).as_bytes(),
    )?;
    let figure = convergence_figure(problem, rows, n_starts);
    if let Ok(svg) = figure.svg() {
        write_atomic(&out.join("convergence.svg"), svg.as_bytes())?;
    }
    if let Ok(png) = figure.png() {
        write_atomic(&out.join("convergence.png"), &png)?;
    }
    let mut text = String::new();
    let _ = writeln!(
        text,
        "{} {} over {} design variables, {} constraints; {} starts, {} evaluations",
        if problem.def.maximize {
            "maximise"
        } else {
            "minimise"
        },
        problem.def.objective.label(),
        problem.variables.len(),
        problem.def.constraints.len(),
        n_starts,
        rows.len()
    );
    for (s, status) in statuses {
        let evaluations = rows.iter().filter(|r| r.start == *s).count();
        let best = best_feasible(problem, rows, Some(*s))
            .and_then(|k| rows[k].eval.as_ref().ok())
            .map_or("no feasible design".to_string(), |e| {
                format!(
                    "best feasible {} = {:.9e}",
                    problem.def.objective.label(),
                    e.f
                )
            });
        let _ = writeln!(
            text,
            "start {s}: {status} after {evaluations} evaluations; {best}"
        );
    }
    let Some(k) = best_feasible(problem, rows, None) else {
        let _ = writeln!(
            text,
            "no feasible design found; every evaluation is in {}",
            out.join("iterations.csv").display()
        );
        return Ok((text, if interrupted { 130 } else { 1 }));
    };
    let best = &rows[k];
    let e = best.eval.as_ref().expect("a feasible row has values");
    let mut sets = problem.sets(&best.x);
    sets.extend(absolute_file_keys(path, problem.overrides)?);
    let optimum = Source::read(path)?.with_overrides(&sets)?;
    let optimum_path = out.join("optimum.toml");
    write_atomic(&optimum_path, optimum.text.as_bytes())?;
    let _ = writeln!(
        text,
        "optimum (start {}, evaluation {}): {} = {:.9e}",
        best.start,
        best.evaluation,
        problem.def.objective.label(),
        e.f
    );
    for ((v, x), &(lo, hi)) in problem
        .variables
        .iter()
        .zip(&best.x)
        .zip(&problem.def.bounds)
    {
        let at = if *x <= lo + 1e-9 * (1.0 + x.abs()) {
            " (at its lower bound)"
        } else if *x >= hi - 1e-9 * (1.0 + x.abs()) {
            " (at its upper bound)"
        } else {
            ""
        };
        let _ = writeln!(text, "  {} = {x} {}{at}", v.name, v.unit);
    }
    for (i, c) in problem.def.constraints.iter().enumerate() {
        let bound = match problem.limits[i].0 {
            Bound::AtLeast(b) => format!(">= {b:e}"),
            Bound::AtMost(b) => format!("<= {b:e}"),
            Bound::Equals(b) => format!("= {b:e}"),
            Bound::EqualsNominal => unreachable!("resolved"),
        };
        let _ = writeln!(
            text,
            "  {} = {:.9e} ({bound}); multiplier dF*/d(bound) = {:.6e}",
            c.quantity.label(),
            e.q[i],
            best.multipliers.get(i).copied().unwrap_or(0.0)
        );
    }
    let _ = writeln!(
        text,
        "  KKT stationarity {:.2e} (relative), largest violation {:.2e}",
        best.stationarity, best.violation
    );
    // the optimum's full run, when the deck is a mechanism
    if mechanism && !interrupted {
        let request = super::run::RunRequest {
            out: Some(out),
            json: true,
            progress: false,
        };
        // a failure of this run does not hide the optimum found
        match super::run::run(&optimum_path, &[], &request) {
            Ok(_) => {
                let _ = writeln!(
                    text,
                    "the optimum's run: {}",
                    out.join("results.h5").display()
                );
            }
            Err(e) => {
                let _ = writeln!(text, "the optimum's run failed: {e}");
                return Ok((text, 1));
            }
        }
    }
    let _ = writeln!(
        text,
        "files: {}, {}, {}",
        optimum_path.display(),
        out.join("iterations.csv").display(),
        out.join("convergence.svg").display()
    );
    if interrupted {
        let _ = writeln!(
            text,
            "interrupted: the best feasible design so far is written"
        );
    }
    Ok((text, if interrupted { 130 } else { 0 }))
}
