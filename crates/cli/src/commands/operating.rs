//! `flexsens static`: the static equilibrium of the deck's mechanism under its loads at the
//! drivers' positions, or its steady spins about the `[operating]` driver's axis at a list of
//! speeds; at each operating point the modes of the linearised constrained system
//! (frequencies, damping ratios), the deck's responses and, when the deck declares design
//! variables, their exact derivatives; a Campbell diagram of a speed sweep with the rotor
//! orders' crossings (docs/operating-points.md).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use mbs::{
    DesignModel, EquilibriumOptions, LinearMode, MultibodySystem, OperatingPoint,
    OperatingSensitivities, Spin, TimeFunction,
};
use nalgebra::DMatrix;
use sens::Dual;
use serde_json::json;

use super::run_files::per;
use super::shard::remove_old;
use crate::deck::operating::OperatingDef;
use crate::deck::{self, Source};
use crate::error::CliError;
use crate::files::{DirLock, Staged, remove_stale_partials};
use crate::plot::{Figure, Panel, Series};
use crate::study::Mechanism;
use crate::table::{CsvTable, number};

/// What `flexsens static` was asked for.
pub struct StaticRequest<'a> {
    /// Output directory (default: `<deck stem>.static` beside the deck).
    pub out: Option<&'a Path>,
    /// A JSON summary on stdout instead of the table.
    pub json: bool,
}

/// The files the command may write (those it does not write are removed).
const OUTPUT_FILES: [&str; 4] = [
    "operating.csv",
    "frequencies.csv",
    "sensitivities.csv",
    "campbell.svg",
];

/// Width of the dual numbers of the design derivatives.
const CHUNK: usize = 8;

/// One operating point and what was computed there.
pub(crate) struct Point {
    /// Spin speed (rad/s).
    pub(crate) speed: f64,
    op: OperatingPoint,
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
    let points = operating_points(&src, &mech, &def)?;
    let crossings = crossings(&points, &def.orders);
    let written = write_files(&src, &mech, &def, &points, &out)?;
    if req.json {
        return Ok(summary(&mech, &points, &crossings).to_string() + "\n");
    }
    Ok(text(&mech, &def, &points, &crossings, &written))
}

fn computation(src: &Source, reason: impl std::fmt::Display) -> CliError {
    CliError::Computation {
        file: src.file.clone(),
        reason: reason.to_string(),
    }
}

fn rpm(w: f64) -> f64 {
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
        .map_err(|e| computation(src, e))?;
    let mut start = mech.state.clone();
    system.assemble(t, &mut start, 1e-10).map_err(|e| {
        computation(
            src,
            format!("the configuration at t = {t} s cannot be assembled: {e}"),
        )
    })?;
    let design = match mech.design.enabled && !mech.design.variables.is_empty() {
        true => Some(super::sensitivity::dual_models::<CHUNK>(src, mech)?.0),
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
            Some(_) => computation(src, format!("at {} rpm: {e}", short(rpm(speed)))),
            None => computation(src, e),
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
        let mut modes = lin.modes().map_err(at)?;
        modes.truncate(def.modes);
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
            op,
            modes,
            values,
            gradients,
            frequency_gradients,
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
    let output = system.output(op.t, &y).map_err(|e| computation(src, e))?;
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
        let seed = |x: &[f64], d: &DMatrix<f64>, i: usize| {
            let mut t = [0.0; CHUNK];
            for (k, j) in range.clone().enumerate() {
                t[k] = d[(i, j)];
            }
            Dual::new(x[i], t)
        };
        let q: Vec<Dual<CHUNK>> = (0..op.state.q.len())
            .map(|i| seed(&op.state.q, &s.q, i))
            .collect();
        let v: Vec<Dual<CHUNK>> = (0..op.state.v.len())
            .map(|i| seed(&op.state.v, &s.v, i))
            .collect();
        let mut lambda = vec![Dual::constant(0.0); nc];
        for (a, &r) in op.rows.iter().enumerate() {
            lambda[r] = seed(&op.lambda, &s.lambda, a);
        }
        for (i, r) in mech.responses.iter().enumerate() {
            if !r.response.differentiable() {
                continue;
            }
            let val = r
                .response
                .evaluate(model, op.t, &q, &v, &lambda)
                .map_err(|e| computation(src, e))?;
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

/// The files of the command, written under temporary names and committed together.
fn write_files(
    src: &Source,
    mech: &Mechanism,
    def: &OperatingDef,
    points: &[Point],
    out: &Path,
) -> Result<Vec<PathBuf>, CliError> {
    let mut files = vec![
        (out.join("operating.csv"), operating_csv(mech, points)),
        (out.join("frequencies.csv"), frequencies_csv(mech, points)),
    ];
    if let Some(csv) = sensitivities_csv(mech, points) {
        files.push((out.join("sensitivities.csv"), csv));
    }
    if points.len() > 1 {
        let svg = campbell(src, def, points)
            .svg()
            .map_err(|e| computation(src, format!("cannot draw the Campbell diagram: {e}")))?;
        files.push((out.join("campbell.svg"), svg));
    }
    let staged = files
        .iter()
        .map(|(p, text)| Staged::new(p, text.as_bytes()))
        .collect::<Result<Vec<_>, _>>()?;
    for s in staged {
        s.commit()?;
    }
    Ok(files.into_iter().map(|(p, _)| p).collect())
}

fn operating_csv(mech: &Mechanism, points: &[Point]) -> String {
    let mut t = CsvTable::new();
    let mut head: Vec<String> = ["speed [rad/s]", "speed [rpm]", "iterations", "load steps"]
        .map(String::from)
        .into();
    head.extend(
        mech.responses
            .iter()
            .map(|r| format!("{} [{}]", r.name, r.unit)),
    );
    t.row(head);
    for p in points {
        let mut row = vec![
            number(p.speed),
            number(rpm(p.speed)),
            p.op.iterations.to_string(),
            p.op.load_steps.to_string(),
        ];
        row.extend(p.values.iter().map(|&x| number(x)));
        t.row(row);
    }
    t.finish()
}

fn frequencies_csv(mech: &Mechanism, points: &[Point]) -> String {
    let mut t = CsvTable::new();
    let mut head: Vec<String> = [
        "speed [rad/s]",
        "speed [rpm]",
        "mode",
        "repeated group",
        "frequency [Hz]",
        "damped frequency [Hz]",
        "damping ratio",
        "Re s [1/s]",
        "Im s [rad/s]",
    ]
    .map(String::from)
    .into();
    let derivatives = points.iter().all(|p| p.frequency_gradients.is_some());
    if derivatives {
        for v in &mech.design.variables {
            head.push(format!("d frequency/d {} [{}]", v.name, per("Hz", v.unit)));
        }
    }
    t.row(head);
    for p in points {
        for (k, m) in p.modes.iter().enumerate() {
            let mut row = vec![
                number(p.speed),
                number(rpm(p.speed)),
                (k + 1).to_string(),
                m.group.to_string(),
                number(m.frequency_hz()),
                number(m.damped_frequency_hz()),
                number(m.damping_ratio()),
                number(m.eigenvalue.re),
                number(m.eigenvalue.im),
            ];
            if let (true, Some(g)) = (derivatives, &p.frequency_gradients) {
                row.extend(g.row(k).iter().map(|&x| number(x)));
            }
            t.row(row);
        }
    }
    t.finish()
}

fn sensitivities_csv(mech: &Mechanism, points: &[Point]) -> Option<String> {
    points.first()?.gradients.as_ref()?;
    let vars = &mech.design.variables;
    let mut head = vec!["speed [rad/s]".to_string(), "speed [rpm]".to_string()];
    let mut columns = Vec::new();
    for (i, r) in mech.responses.iter().enumerate() {
        if r.response.differentiable() {
            for (j, v) in vars.iter().enumerate() {
                head.push(format!(
                    "d {}/d {} [{}]",
                    r.name,
                    v.name,
                    per(r.unit, v.unit)
                ));
                columns.push((i, j));
            }
        }
    }
    let mut t = CsvTable::new();
    t.row(head);
    for p in points {
        let g = p.gradients.as_ref()?;
        let mut row = vec![number(p.speed), number(rpm(p.speed))];
        row.extend(columns.iter().map(|&(i, j)| number(g[(i, j)])));
        t.row(row);
    }
    Some(t.finish())
}

/// The Campbell diagram: each mode's frequency against the speed (rpm), the rotor orders
/// dashed.
fn campbell(src: &Source, def: &OperatingDef, points: &[Point]) -> Figure {
    let x: Vec<f64> = points.iter().map(|p| rpm(p.speed)).collect();
    let n = points.iter().map(|p| p.modes.len()).min().unwrap_or(0);
    let mut series: Vec<Series> = (0..n)
        .map(|k| {
            let y: Vec<f64> = points.iter().map(|p| p.modes[k].frequency_hz()).collect();
            Series::solid(format!("mode {}", k + 1), &x, &y, k + 1)
        })
        .collect();
    for &order in &def.orders {
        let y: Vec<f64> = points
            .iter()
            .map(|p| order as f64 * p.speed / (2.0 * std::f64::consts::PI))
            .collect();
        series.push(Series::dashed(format!("{order}P"), &x, &y, 0));
    }
    let name = def.driver.as_ref().map_or("", |(n, _)| n.as_str());
    Figure {
        title: format!(
            "Campbell diagram of {}",
            src.file.file_name().map_or_else(
                || "the deck".to_string(),
                |f| f.to_string_lossy().into_owned()
            )
        ),
        panels: vec![Panel {
            title: format!("modes about the steady spin of `{name}`"),
            x_label: "speed [rpm]".into(),
            y_label: "frequency [Hz]".into(),
            series,
        }],
    }
}

fn summary(mech: &Mechanism, points: &[Point], crossings: &[Crossing]) -> serde_json::Value {
    let points: Vec<serde_json::Value> = points
        .iter()
        .map(|p| {
            let responses: serde_json::Map<String, serde_json::Value> = (mech.responses.iter())
                .zip(&p.values)
                .map(|(r, &v)| (r.name.clone(), json!(v)))
                .collect();
            let modes: Vec<serde_json::Value> = (p.modes.iter().enumerate())
                .map(|(k, m)| {
                    let derivatives = p.frequency_gradients.as_ref().map(|g| {
                        (mech.design.variables.iter().enumerate())
                            .map(|(j, v)| (v.name.clone(), json!(g[(k, j)])))
                            .collect::<serde_json::Map<_, _>>()
                    });
                    json!({
                        "frequency_hz": m.frequency_hz(),
                        "damped_frequency_hz": m.damped_frequency_hz(),
                        "damping_ratio": m.damping_ratio(),
                        "repeated_group": m.group,
                        "frequency_derivatives": derivatives,
                    })
                })
                .collect();
            let gradients = p.gradients.as_ref().map(|g| {
                (mech.responses.iter().enumerate())
                    .filter(|(_, r)| r.response.differentiable())
                    .map(|(i, r)| {
                        let row: serde_json::Map<String, serde_json::Value> =
                            (mech.design.variables.iter().enumerate())
                                .map(|(j, v)| (v.name.clone(), json!(g[(i, j)])))
                                .collect();
                        (r.name.clone(), serde_json::Value::Object(row))
                    })
                    .collect::<serde_json::Map<_, _>>()
            });
            json!({
                "speed_rad_s": p.speed,
                "speed_rpm": rpm(p.speed),
                "iterations": p.op.iterations,
                "load_steps": p.op.load_steps,
                "responses": responses,
                "gradients": gradients,
                "modes": modes,
            })
        })
        .collect();
    let crossings: Vec<serde_json::Value> = crossings
        .iter()
        .map(|&(k, order, speed, f)| {
            json!({"mode": k + 1, "order": order, "speed_rpm": rpm(speed), "frequency_hz": f})
        })
        .collect();
    json!({"points": points, "crossings": crossings})
}

fn text(
    mech: &Mechanism,
    def: &OperatingDef,
    points: &[Point],
    crossings: &[Crossing],
    written: &[PathBuf],
) -> String {
    let mut s = String::new();
    for p in points {
        let zeta = |m: &LinearMode| match m.damping_ratio() {
            z if z.abs() < 1e-10 => 0.0,
            z => z,
        };
        match &def.driver {
            Some((name, _)) => writeln!(
                s,
                "steady spin of `{name}` at {} rpm ({} rad/s)",
                short(rpm(p.speed)),
                short(p.speed)
            ),
            None => writeln!(s, "static equilibrium"),
        }
        .expect("writing to a String");
        let _ = writeln!(
            s,
            "  {} Newton iterations, {} load steps",
            p.op.iterations, p.op.load_steps
        );
        for (r, v) in mech.responses.iter().zip(&p.values) {
            let _ = writeln!(s, "  {:<24} {:>14} {}", r.name, fmt(*v), r.unit);
        }
        let _ = writeln!(s, "  mode  frequency [Hz]  damping ratio");
        for (k, m) in p.modes.iter().enumerate() {
            let note = match m.damping_ratio() {
                z if z < -1e-9 => "  unstable",
                _ if m.group > 0 => "  repeated",
                _ if m.eigenvalue.im == 0.0 && m.eigenvalue.re != 0.0 => "  not oscillating",
                _ => "",
            };
            let _ = writeln!(
                s,
                "  {:>4}  {:>14}  {:>13}{note}",
                k + 1,
                fmt(m.frequency_hz()),
                fmt(zeta(m))
            );
        }
    }
    if !crossings.is_empty() {
        let _ = writeln!(
            s,
            "rotor-order crossings (modes numbered by frequency at the lower speed):"
        );
        for &(k, order, speed, f) in crossings {
            let _ = writeln!(
                s,
                "  mode {} crosses {order}P at {} rpm, {} Hz",
                k + 1,
                fmt(rpm(speed)),
                fmt(f)
            );
        }
    }
    for w in written {
        let _ = writeln!(s, "wrote {}", w.display());
    }
    s
}

/// A speed for a sentence: at most six decimals, trailing zeros dropped.
fn short(x: f64) -> String {
    let s = format!("{x:.6}");
    s.trim_end_matches('0').trim_end_matches('.').to_string()
}

/// A value for the table: six significant digits.
fn fmt(x: f64) -> String {
    if x == 0.0 {
        "0".into()
    } else if (1e-3..1e6).contains(&x.abs()) {
        let decimals = (5 - x.abs().log10().floor() as i32).max(0) as usize;
        format!("{x:.decimals$}")
    } else {
        format!("{x:.5e}")
    }
}
