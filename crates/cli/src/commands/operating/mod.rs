//! `flexsens static`: the static equilibrium of the deck's mechanism under its loads at the
//! drivers' positions, or its steady spins about the `[operating]` driver's axis at a list of
//! speeds; at each operating point the modes of the linearised constrained system
//! (frequencies, damping ratios), the deck's responses and, when the deck declares design
//! variables, their exact derivatives; a Campbell diagram of a speed sweep with the rotor
//! orders' crossings. With `[operating] at`, the states of the run at those times instead,
//! linearised in the bodies' moving frames (docs/operating-points.md).

use std::path::Path;

use mbs::{
    DesignModel, EquilibriumOptions, LinearMode, MultibodySystem, OperatingPoint,
    OperatingSensitivities, Spin, TimeFunction,
};
use nalgebra::DMatrix;
use sens::Dual;

use super::shard::remove_old;
use crate::deck::operating::OperatingDef;
use crate::deck::{self, Source};
use crate::error::CliError;
use crate::files::{DirLock, remove_stale_partials};
use crate::study::Mechanism;
use crate::table::short;
use output::{summary, text, write_files};

/// What `flexsens static` was asked for.
pub struct StaticRequest<'a> {
    /// Output directory (default: `<deck stem>.static` beside the deck).
    pub out: Option<&'a Path>,
    /// A JSON summary on stdout instead of the table.
    pub json: bool,
    /// Also write each flexible body's mesh and mode shapes at each operating point as VTK.
    pub vtk: bool,
}

/// The files the command may write (those it does not write are removed).
const OUTPUT_FILES: [&str; 7] = [
    "operating.csv",
    "frequencies.csv",
    "sensitivities.csv",
    "campbell.svg",
    "campbell.png",
    "frequencies.svg",
    "frequencies.png",
];

/// Width of the dual numbers of the design derivatives.
const CHUNK: usize = 8;

/// One operating point and what was computed there.
pub(crate) struct Point {
    /// Spin speed (rad/s; zero for a static equilibrium or a state of the run).
    pub(crate) speed: f64,
    /// The time of a state of the run (`[operating] at`); none for an equilibrium.
    pub(crate) time: Option<f64>,
    /// The state linearised about.
    state: mbs::State,
    /// Newton iterations and load steps of an equilibrium (zero for a state of the run).
    solve: (usize, usize),
    pub(crate) modes: Vec<LinearMode>,
    /// Per response, its value.
    values: Vec<f64>,
    /// `dψ_i/db_j` (rows: responses; `NaN` for a response without derivatives).
    gradients: Option<DMatrix<f64>>,
    /// `df_k/db_j` of the modes' frequencies (Hz per unit of the variable; rows: modes).
    pub(crate) frequency_gradients: Option<DMatrix<f64>>,
}

/// Rotor-order crossings of the Campbell diagram: (mode, order, speed rad/s, frequency Hz).
type Crossing = (usize, u32, f64, f64);

/// Run the command; the returned text goes to stdout.
pub fn run(path: &Path, overrides: &[String], req: &StaticRequest) -> Result<String, CliError> {
    let (src, raw) = deck::load(path, overrides)?;
    let def = deck::operating::validate(&src, &raw)?;
    let mech = Mechanism::validate(&src, &raw, true)?;
    let out = req
        .out
        .map(Path::to_path_buf)
        .unwrap_or_else(|| super::default_dir(path, "static", None));
    let _lock = DirLock::acquire(&out, "static")?;
    std::fs::create_dir_all(&out).map_err(|e| CliError::File {
        action: "create the output directory",
        path: out.clone(),
        reason: e.to_string(),
    })?;
    remove_stale_partials(&out, &OUTPUT_FILES);
    for f in OUTPUT_FILES {
        remove_old(&out.join(f))?;
    }
    // the mode shapes of an earlier command
    if let Ok(entries) = std::fs::read_dir(&out) {
        for e in entries.flatten() {
            let name = e.file_name().to_string_lossy().into_owned();
            if name.starts_with("modes_") && name.ends_with(".vtk") {
                remove_old(&e.path())?;
            }
        }
    }
    let points = match def.at.is_empty() {
        true => operating_points(&src, &mech, &def)?,
        false => run_points(&src, &mech, &def)?,
    };
    let crossings = match def.at.is_empty() {
        true => crossings(&points, &def.orders),
        false => Vec::new(),
    };
    let written = write_files(&src, &mech, &def, &points, (&out, req.vtk))?;
    if req.json {
        return Ok(summary(&mech, &points, &crossings).to_string() + "\n");
    }
    Ok(text(&mech, &def, &points, &crossings, &written))
}

/// rad/s → rpm.
pub(crate) fn rpm(w: f64) -> f64 {
    w * 30.0 / std::f64::consts::PI
}

/// Every operating point of the deck, each speed's equilibrium starting from the previous
/// one's.
pub(crate) fn operating_points(
    src: &Source,
    mech: &Mechanism,
    def: &OperatingDef,
) -> Result<Vec<Point>, CliError> {
    let t = def.time.unwrap_or(mech.times[0]);
    let mut model = mech.model.clone();
    let driver = def.driver.as_ref().map(|(name, span)| {
        let id = model.joint_id(name).expect("validated driver");
        let law = match &model.joint(id).kind {
            mbs::JointKind::AngleDriver(f) => f.clone(),
            _ => unreachable!("validated angle driver"),
        };
        (id, law.eval(t)[0], name.as_str(), span.clone())
    });
    let mut system = MultibodySystem::new_at(model.clone(), t, &mech.state, mech.policy)
        .map_err(|e| CliError::computation(src, e))?;
    let mut start = mech.state.clone();
    system.assemble(t, &mut start, 1e-10).map_err(|e| {
        CliError::computation(
            src,
            format!("the configuration at t = {t} s cannot be assembled: {e}"),
        )
    })?;
    let design = match mech.design.enabled && !mech.design.variables.is_empty() {
        true => Some(super::dual_chunks::dual_models::<CHUNK>(src, mech)?.0),
        false => None,
    };
    let mut points = Vec::new();
    for &speed in &def.speeds {
        let spin = match &driver {
            Some((id, angle, name, span)) => {
                model.set_motion(
                    *id,
                    TimeFunction::ConstantSpeed {
                        initial: angle - speed * t,
                        rate: speed,
                    },
                );
                let spin = Spin::of_driver(&model, *id, speed).map_err(|e| {
                    src.error(
                        span.clone(),
                        Some("operating.driver".into()),
                        format!("`{name}`: {e}"),
                    )
                })?;
                Some(spin)
            }
            None => None,
        };
        let at = |e: mbs::OperatingError| match &driver {
            Some(_) => CliError::computation(src, format!("at {} rpm: {e}", short(rpm(speed)))),
            None => CliError::computation(src, e),
        };
        let op = mbs::equilibrium(
            &model,
            system.active_rows(),
            t,
            &start,
            spin,
            &EquilibriumOptions::default(),
        )
        .map_err(at)?;
        let lin = op.linearise(&model);
        let modes = reported(lin.modes().map_err(at)?, def.modes);
        let system = system.with_model(model.clone());
        let values = response_values(src, mech, &system, &op)?;
        let (gradients, frequency_gradients) = match &design {
            Some(d) => {
                let s = op.sensitivities(d).map_err(at)?;
                let ds = op.eigenvalue_derivatives(&lin, &modes, d, &s);
                let df = DMatrix::from_fn(ds.nrows(), ds.ncols(), |k, j| {
                    modes[k].frequency_derivative(ds[(k, j)])
                });
                (Some(response_gradients(src, mech, d, &op, &s)?), Some(df))
            }
            None => (None, None),
        };
        start = op.state.clone();
        points.push(Point {
            speed,
            time: None,
            state: op.state,
            solve: (op.iterations, op.load_steps),
            modes,
            values,
            gradients,
            frequency_gradients,
        });
    }
    Ok(points)
}

/// The modes asked for, and the rest of a repeated group the last of them is in (its
/// derivatives are the group's).
fn reported(mut modes: Vec<LinearMode>, asked: usize) -> Vec<LinearMode> {
    let mut keep = asked.min(modes.len());
    while keep > 0 && keep < modes.len() && modes[keep].group > 0 {
        if modes[keep].group != modes[keep - 1].group {
            break;
        }
        keep += 1;
    }
    modes.truncate(keep);
    modes
}

/// The states of the run at `[operating] at`, each linearised in the bodies' moving frames
/// ([`mbs::linearise_state`]).
fn run_points(src: &Source, mech: &Mechanism, def: &OperatingDef) -> Result<Vec<Point>, CliError> {
    deck::operating::check_times(src, def, &mech.times)?;
    let t0 = mech.times[0];
    let (mut system, state) = super::compute::assembled(src, mech)?;
    let mut times = vec![t0];
    times.extend(def.at.iter().map(|(t, _)| *t).filter(|&t| t > t0));
    let sim = mbs::simulate(&mut system, &state, &times, mech.options.clone())
        .map_err(|e| CliError::computation(src, e))?;
    let mut points = Vec::new();
    for o in &sim.outputs {
        if !def.at.iter().any(|(t, _)| *t == o.t) {
            continue;
        }
        let here =
            |e: mbs::OperatingError| CliError::computation(src, format!("at t = {} s: {e}", o.t));
        let state = mbs::State {
            q: o.q.clone(),
            v: o.v.clone(),
        };
        let lin = mbs::linearise_state(&system, o.t, &state).map_err(here)?;
        points.push(Point {
            speed: 0.0,
            time: Some(o.t),
            state: lin.state,
            solve: (0, 0),
            modes: reported(lin.linearisation.modes().map_err(here)?, def.modes),
            values: (0..mech.responses.len())
                .map(|i| mech.value(i, o))
                .collect(),
            gradients: None,
            frequency_gradients: None,
        });
    }
    Ok(points)
}

/// The deck's responses at an operating point.
fn response_values(
    src: &Source,
    mech: &Mechanism,
    system: &MultibodySystem,
    op: &OperatingPoint,
) -> Result<Vec<f64>, CliError> {
    let y = op.state.to_vec();
    let output = system
        .output(op.t, &y)
        .map_err(|e| CliError::computation(src, e))?;
    Ok((0..mech.responses.len())
        .map(|i| mech.value(i, &output))
        .collect())
}

/// `dψ_i/db_j` of the deck's responses at an operating point (`NaN` for a response without
/// derivatives).
fn response_gradients(
    src: &Source,
    mech: &Mechanism,
    design: &DesignModel<CHUNK>,
    op: &OperatingPoint,
    s: &OperatingSensitivities,
) -> Result<DMatrix<f64>, CliError> {
    let nc = mech.model.n_constraints();
    let mut g = DMatrix::from_element(mech.responses.len(), design.n_variables(), f64::NAN);
    for (model, range) in design.chunk_ranges() {
        let q: Vec<Dual<CHUNK>> = mbs::seeded(&op.state.q, &s.q, &range);
        let v: Vec<Dual<CHUNK>> = mbs::seeded(&op.state.v, &s.v, &range);
        let mut lambda = vec![Dual::constant(0.0); nc];
        for (&r, l) in op
            .rows
            .iter()
            .zip(mbs::seeded(&op.lambda, &s.lambda, &range))
        {
            lambda[r] = l;
        }
        // the steady motion's accelerations at the moved positions (a point's acceleration)
        let (_, accel) = op.motion_at(model, &q);
        for (i, r) in mech.responses.iter().enumerate() {
            if !r.response.differentiable() {
                continue;
            }
            let val = r
                .response
                .evaluate_with(model, op.t, (&q, &v), &lambda, &accel)
                .map_err(|e| CliError::computation(src, e))?;
            for (k, j) in range.clone().enumerate() {
                g[(i, j)] = val.d[k];
            }
        }
    }
    Ok(g)
}

/// Where the modes' frequencies cross the rotor orders `n Ω / 2π` between two speeds of the
/// sweep, by linear interpolation: each oscillating mode at one speed paired with the nearest
/// oscillating mode at the next (the mode numbers are those at the lower speed).
fn crossings(points: &[Point], orders: &[u32]) -> Vec<Crossing> {
    let oscillating = |p: &Point| -> Vec<usize> {
        (0..p.modes.len())
            .filter(|&k| p.modes[k].eigenvalue.im > 0.0)
            .collect()
    };
    let mut out = Vec::new();
    for pair in points.windows(2) {
        let (a, b) = (&pair[0], &pair[1]);
        let (ka, kb) = (oscillating(a), oscillating(b));
        // nearest pairs first, each mode used once
        let mut candidates: Vec<(f64, usize, usize)> = ka
            .iter()
            .flat_map(|&i| kb.iter().map(move |&j| (i, j)))
            .map(|(i, j)| {
                let (fa, fb) = (a.modes[i].frequency_hz(), b.modes[j].frequency_hz());
                ((fa - fb).abs() / fa.max(fb), i, j)
            })
            .collect();
        candidates.sort_by(|x, y| x.0.total_cmp(&y.0));
        let (mut used_a, mut used_b) = (vec![false; a.modes.len()], vec![false; b.modes.len()]);
        let mut pairs = Vec::new();
        for (_, i, j) in candidates {
            if !used_a[i] && !used_b[j] {
                (used_a[i], used_b[j]) = (true, true);
                pairs.push((i, j));
            }
        }
        pairs.sort();
        for (i, j) in pairs {
            for &order in orders {
                let line = |p: &Point| order as f64 * p.speed / (2.0 * std::f64::consts::PI);
                let (fa, fb) = (a.modes[i].frequency_hz(), b.modes[j].frequency_hz());
                let (ga, gb) = (fa - line(a), fb - line(b));
                if ga * gb < 0.0 || (gb == 0.0 && ga != 0.0) {
                    let s = ga / (ga - gb);
                    let speed = a.speed + s * (b.speed - a.speed);
                    out.push((i, order, speed, fa + s * (fb - fa)));
                }
            }
        }
    }
    out.sort_by(|a, b| a.2.total_cmp(&b.2));
    out
}

mod output;
