//! `flexsens optimize`: gradient-based optimisation of the deck's `[design.*]` variables
//! (`[optimize]`, see `docs/optimization.md`).
//!
//! The deck is read and validated once. Each evaluation moves the validated model to the
//! design `x` in memory (the mechanism's `Mechanism::at`, the bodies' `BodyDef::at`, the laminates'
//! `DesignDef::laminates_at`: no deck text is edited or read again) and reads each quantity
//! with its exact gradient: an `[objective.*]` from
//! the run's direct sensitivities, a frequency from the modal analysis and Nelson's eigenvalue
//! derivative, a flexible body's mass from its lumped masses in dual numbers (a rigid body's
//! from its mass variable), a laminate's mass per area through the shells' design map. The
//! algorithm is SLSQP (Kraft's sequential least squares programming, NLopt's implementation
//! through the `slsqp` crate), started from the deck's
//! design and from each `starts` entry, several starts at once (`-j`). Every evaluation is
//! logged with its objective, constraints, gradient norm and KKT stationarity; the best
//! feasible design is written as a deck, run, and summarised.

use std::cell::RefCell;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::ops::Range;
use std::path::Path;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use nalgebra::{DMatrix, DVector};
use sens::Dual;

use crate::deck::bodies::BodyDef;
use crate::deck::design::{
    DesignDef, DesignVariable, SensitivityScheme, validate as validate_design,
};
use crate::deck::laminates::{LaminateModel, validate as validate_laminates};
use crate::deck::operating::OperatingDef;
use crate::deck::optimize::{Bound, OptimizeDef, Quantity, validate as validate_optimize};
use crate::deck::{self, Source, bodies, mechanism};
use crate::error::CliError;
use crate::files::write_atomic;
use crate::plot::{Figure, Panel, Series};
use crate::study::flexible::{CHUNK, DesignRequest, build, fem_error};
use crate::study::{Mechanism, at_design};
use crate::table::{CsvTable, number};

mod driver;
mod evaluate;
mod output;
mod shards;

use driver::run_start;
use output::{finish, iterations_csv};
pub(crate) use shards::merge;
use shards::{EVALUATIONS_FILE, row_json};

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
pub(super) const FEASIBLE: f64 = 1e-6;

/// What the optimiser sees of a bound: inequalities tightened and equalities widened by this
/// (relative to their scale), well inside [`FEASIBLE`].
pub(super) const MARGIN: f64 = 1e-8;

/// The values and gradients of the objective and the constrained quantities at one design.
#[derive(Clone, Debug)]
pub(super) struct Eval {
    /// The units of the objective and of each constrained quantity.
    units: Vec<String>,
    f: f64,
    df: Vec<f64>,
    /// Per constraint: the quantity's value and gradient.
    q: Vec<f64>,
    dq: Vec<Vec<f64>>,
}

/// A design and what its evaluation gave.
pub(super) type Evaluated = (Vec<f64>, Result<Eval, String>);

/// One logged evaluation.
#[derive(Clone, Debug)]
pub(super) struct Row {
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

/// The problem: the deck validated once, its design variables and `[optimize]`, and the
/// constraint bounds resolved (`"nominal"` replaced by the value at the deck's design).
pub(super) struct Problem<'a> {
    path: &'a Path,
    overrides: &'a [String],
    /// The deck with the command line's `--set` arguments.
    src: Source,
    /// Its laminates and design, at the deck's design.
    laminates: LaminateModel,
    design: DesignDef,
    variables: Vec<DesignVariable>,
    /// The flexible bodies whose frequency or mass is constrained: their validated
    /// definitions and deck tables.
    bodies: BTreeMap<String, (BodyDef, Range<usize>)>,
    /// The rigid bodies' masses at the deck's design.
    rigid_masses: BTreeMap<String, f64>,
    /// The deck's study (without finite differences), when an objective is read.
    study: Option<Mechanism>,
    /// The deck's study and `[operating]`, when a quantity at its operating points is read.
    operating: Option<(Mechanism, OperatingDef)>,
    def: OptimizeDef,
    /// Per constraint: its bound resolved and its scale (for the optimiser and the violation).
    limits: Vec<(Bound, f64)>,
}

fn runtime(m: impl Into<String>) -> CliError {
    CliError::Runtime(m.into())
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

/// The deck's problem, with the constraints' bounds resolved and scaled at the deck's
/// design; and whether the deck is a mechanism (its optimum is run).
fn setup<'a>(path: &'a Path, overrides: &'a [String]) -> Result<(Problem<'a>, bool), CliError> {
    let (src, raw) = deck::load(path, overrides)?;
    let laminates = validate_laminates(&src, &raw)?;
    let design = validate_design(&src, &raw, &laminates)?;
    let def = validate_optimize(&src, &raw, &design, &laminates)?;
    let quantities: Vec<&Quantity> = std::iter::once(&def.objective)
        .chain(def.constraints.iter().map(|c| &c.quantity))
        .collect();
    let mut bodies = BTreeMap::new();
    let mut rigid = false;
    for q in &quantities {
        if let Quantity::Frequency { body, .. } | Quantity::Mass { body } = q {
            match raw.body.get(body) {
                Some(table) if !bodies.contains_key(body) => {
                    let def = bodies::validate_one(&src, &raw, body, table, &laminates)?;
                    bodies.insert(body.clone(), (def, table.span()));
                }
                Some(_) => {}
                None => rigid = true,
            }
        }
    }
    let rigid_masses = if rigid {
        mechanism::rigid_bodies(&src, &raw)?
            .into_iter()
            .map(|r| (r.name, r.mass))
            .collect()
    } else {
        BTreeMap::new()
    };
    let study = if quantities
        .iter()
        .any(|q| matches!(q, Quantity::Objective { .. }))
    {
        let mut study = Mechanism::validate(&src, &raw, true)?;
        study.design.finite_differences = None;
        let method_given = (raw.sensitivity.as_ref()).is_some_and(|s| s.get_ref().method.is_some());
        if !method_given {
            let (variables, objectives) =
                (study.design.variables.len(), study.design.objectives.len());
            study.design.method = SensitivityScheme::cheaper(variables, objectives);
        }
        Some(study)
    } else {
        None
    };
    let operating = if quantities.iter().any(|q| q.operating()) {
        let mut study = Mechanism::validate(&src, &raw, true)?;
        study.design.finite_differences = None;
        Some((study, deck::operating::validate(&src, &raw)?))
    } else {
        None
    };
    let mut problem = Problem {
        path,
        overrides,
        src,
        laminates,
        variables: design.variables.clone(),
        design,
        bodies,
        rigid_masses,
        study,
        operating,
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
    let _lock = crate::files::DirLock::acquire(&out, "optimize")?;
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
            super::shard::write_manifest(
                &out,
                "optimize",
                (path, problem.src.file_text()),
                overrides,
                (i, n),
                extra,
            )?;
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
