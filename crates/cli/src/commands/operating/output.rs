//! The files and the report of `flexsens static`: `operating.csv`, `frequencies.csv`,
//! `sensitivities.csv`, the Campbell diagram (or, for states of the run, the frequencies
//! against time), the JSON summary and the table.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use serde_json::json;

use mbs::LinearMode;

use super::{Crossing, Point, rpm};
use crate::commands::run_files::per;
use crate::deck::Source;
use crate::deck::operating::OperatingDef;
use crate::error::CliError;
use crate::files::Staged;
use crate::plot::{Figure, Panel, Series};
use crate::study::Mechanism;
use crate::table::{CsvTable, number, short};

/// The files of the command, written under temporary names and committed together.
pub(super) fn write_files(
    src: &Source,
    mech: &Mechanism,
    def: &OperatingDef,
    points: &[Point],
    (out, vtk): (&Path, bool),
) -> Result<Vec<PathBuf>, CliError> {
    let mut files = vec![
        (out.join("operating.csv"), operating_csv(mech, points)),
        (out.join("frequencies.csv"), frequencies_csv(mech, points)),
    ];
    if let Some(csv) = sensitivities_csv(mech, points) {
        files.push((out.join("sensitivities.csv"), csv));
    }
    let mut png = None;
    if points.len() > 1 {
        let (figure, name) = match def.at.is_empty() {
            true => (campbell(src, def, points), "campbell"),
            false => (along_the_run(src, points), "frequencies"),
        };
        let draw = |e: String| CliError::computation(src, format!("cannot draw {name}.svg: {e}"));
        files.push((out.join(format!("{name}.svg")), figure.svg().map_err(draw)?));
        png = Some((format!("{name}.png"), figure.png().map_err(draw)?));
    }
    if vtk {
        for (i, p) in points.iter().enumerate() {
            for part in &mech.flexible {
                let name = format!("modes_{}_{}.vtk", i + 1, part.name);
                files.push((out.join(name), mode_shapes(mech, part, p)));
            }
        }
    }
    let mut staged = files
        .iter()
        .map(|(p, text)| Staged::new(p, text.as_bytes()))
        .collect::<Result<Vec<_>, _>>()?;
    let mut written: Vec<PathBuf> = files.into_iter().map(|(p, _)| p).collect();
    if let Some((name, bytes)) = &png {
        let path = out.join(name);
        staged.push(Staged::new(&path, bytes)?);
        written.push(path);
    }
    for s in staged {
        s.commit()?;
    }
    Ok(written)
}

/// The columns that say which operating point a row is of: the time of a state of the run,
/// else the speed.
fn point_head(points: &[Point]) -> Vec<String> {
    match points.first().is_some_and(|p| p.time.is_some()) {
        true => vec!["time [s]".into()],
        false => vec!["speed [rad/s]".into(), "speed [rpm]".into()],
    }
}

fn point_columns(p: &Point) -> Vec<String> {
    match p.time {
        Some(t) => vec![number(t)],
        None => vec![number(p.speed), number(rpm(p.speed))],
    }
}

fn operating_csv(mech: &Mechanism, points: &[Point]) -> String {
    let mut t = CsvTable::new();
    let mut head = point_head(points);
    head.extend(["iterations".into(), "load steps".into()]);
    head.extend(
        mech.responses
            .iter()
            .map(|r| format!("{} [{}]", r.name, r.unit)),
    );
    t.row(head);
    for p in points {
        let mut row = point_columns(p);
        row.extend([p.solve.0.to_string(), p.solve.1.to_string()]);
        row.extend(p.values.iter().map(|&x| number(x)));
        t.row(row);
    }
    t.finish()
}

fn frequencies_csv(mech: &Mechanism, points: &[Point]) -> String {
    let mut t = CsvTable::new();
    let mut head = point_head(points);
    head.extend(
        [
            "mode",
            "repeated group",
            "frequency [Hz]",
            "damped frequency [Hz]",
            "damping ratio",
            "Re s [1/s]",
            "Im s [rad/s]",
        ]
        .map(String::from),
    );
    let derivatives = points.iter().all(|p| p.frequency_gradients.is_some());
    if derivatives {
        for v in &mech.design.variables {
            head.push(format!("d frequency/d {} [{}]", v.name, per("Hz", v.unit)));
        }
    }
    t.row(head);
    for p in points {
        for (k, m) in p.modes.iter().enumerate() {
            let mut row = point_columns(p);
            row.extend([
                (k + 1).to_string(),
                m.group.to_string(),
                number(m.frequency_hz()),
                number(m.damped_frequency_hz()),
                number(m.damping_ratio()),
                number(m.eigenvalue.re),
                number(m.eigenvalue.im),
            ]);
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
    let mut head = point_head(points);
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
        let mut row = point_columns(p);
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
    // the orders dashed, each in a colour of its own (the palette from its far end)
    for (i, &order) in def.orders.iter().enumerate() {
        let y: Vec<f64> = points
            .iter()
            .map(|p| order as f64 * p.speed / (2.0 * std::f64::consts::PI))
            .collect();
        series.push(Series::dashed(format!("{order}P"), &x, &y, 7 - i % 8));
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

/// The modes' frequencies against the time of the run's states.
fn along_the_run(src: &Source, points: &[Point]) -> Figure {
    let x: Vec<f64> = points.iter().map(|p| p.time.unwrap_or(0.0)).collect();
    let n = points.iter().map(|p| p.modes.len()).min().unwrap_or(0);
    let series: Vec<Series> = (0..n)
        .map(|k| {
            let y: Vec<f64> = points.iter().map(|p| p.modes[k].frequency_hz()).collect();
            Series::solid(format!("mode {}", k + 1), &x, &y, k + 1)
        })
        .collect();
    Figure {
        title: format!(
            "Frequencies along the run of {}",
            src.file.file_name().map_or_else(
                || "the deck".to_string(),
                |f| f.to_string_lossy().into_owned()
            )
        ),
        panels: vec![Panel {
            title: "modes linearised about the run's states (numbered by frequency)".into(),
            x_label: "time [s]".into(),
            y_label: "frequency [Hz]".into(),
            series,
        }],
    }
}

pub(super) fn summary(
    mech: &Mechanism,
    points: &[Point],
    crossings: &[Crossing],
) -> serde_json::Value {
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
                "time_s": p.time,
                "speed_rad_s": p.speed,
                "speed_rpm": rpm(p.speed),
                "iterations": p.solve.0,
                "load_steps": p.solve.1,
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

pub(super) fn text(
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
        match (&def.driver, p.time) {
            (_, Some(t)) => writeln!(
                s,
                "the run's state at t = {} s (modes in the bodies' moving frames)",
                short(t)
            ),
            (Some((name, _)), None) => writeln!(
                s,
                "steady spin of `{name}` at {} rpm ({} rad/s)",
                short(rpm(p.speed)),
                short(p.speed)
            ),
            (None, None) => writeln!(s, "static equilibrium"),
        }
        .expect("writing to a String");
        if p.time.is_none() {
            let _ = writeln!(
                s,
                "  {} Newton iterations, {} load steps",
                p.solve.0, p.solve.1
            );
        }
        for (r, v) in mech.responses.iter().zip(&p.values) {
            let _ = writeln!(s, "  {:<24} {:>14} {}", r.name, short(*v), r.unit);
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
                short(m.frequency_hz()),
                short(zeta(m))
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
                short(rpm(speed)),
                short(f)
            );
        }
    }
    for w in written {
        let _ = writeln!(s, "wrote {}", w.display());
    }
    s
}

/// Legacy ASCII VTK of a flexible body at an operating point: its mesh at the equilibrium
/// (global coordinates) and, per linearised mode, the nodal translations of the mode's real
/// and imaginary parts (the frame's `δr + A (δθ × x)` and the modes' `X δw`, to first order;
/// about a state of the run the frame's translation `δr` is in the body frame).
fn mode_shapes(mech: &Mechanism, part: &crate::study::FlexiblePart, p: &Point) -> String {
    let model = &mech.model;
    let id = part.id;
    let q = &p.state.q;
    let (qr, vr) = (model.q_range(id), model.v_range(id));
    let r = nalgebra::Vector3::new(q[qr.start], q[qr.start + 1], q[qr.start + 2]);
    let a = model.rotation_of(id, q);
    let mbs::Body::Flexible(body) = model.body(id) else {
        unreachable!("a flexible part is a flexible body")
    };
    let modal = &body.modal;
    let u = model.nodal_displacements(id, q);
    let local: Vec<nalgebra::Vector3<f64>> = (modal.node_positions.iter().zip(&u))
        .map(|(x, u)| x + nalgebra::Vector3::new(u[0], u[1], u[2]))
        .collect();
    let mut s = String::new();
    let _ = writeln!(s, "# vtk DataFile Version 3.0");
    let f: Vec<String> = p
        .modes
        .iter()
        .map(|m| format!("{:.6e}", m.frequency_hz()))
        .collect();
    let at = match p.time {
        Some(t) => format!("the run's state at {} s", short(t)),
        None => format!("{} rpm", short(rpm(p.speed))),
    };
    let _ = writeln!(
        s,
        "flexsens static: body {} at {at}; frequencies/Hz {}",
        part.name,
        f.join(" ")
    );
    let _ = writeln!(s, "ASCII\nDATASET UNSTRUCTURED_GRID");
    let _ = writeln!(s, "POINTS {} double", local.len());
    for x in &local {
        let g = r + a * x;
        let _ = writeln!(s, "{:e} {:e} {:e}", g.x, g.y, g.z);
    }
    let mesh = &part.built.mesh;
    let size: usize = mesh.elements.iter().map(|e| e.nodes().len() + 1).sum();
    let _ = writeln!(s, "CELLS {} {size}", mesh.elements.len());
    for e in &mesh.elements {
        let ids: Vec<String> = e.nodes().iter().map(|i| i.to_string()).collect();
        let _ = writeln!(s, "{} {}", ids.len(), ids.join(" "));
    }
    let _ = writeln!(s, "CELL_TYPES {}", mesh.elements.len());
    for e in &mesh.elements {
        let _ = writeln!(s, "{}", if e.nodes().len() == 2 { 3 } else { 5 });
    }
    let _ = writeln!(s, "POINT_DATA {}", local.len());
    for (m, mode) in p.modes.iter().enumerate() {
        let d = &mode.shape;
        for (part_name, pick) in [("real", 0), ("imag", 1)] {
            let c = |i: usize| {
                if pick == 0 {
                    d[vr.start + i].re
                } else {
                    d[vr.start + i].im
                }
            };
            let dr = nalgebra::Vector3::new(c(0), c(1), c(2));
            let dtheta = nalgebra::Vector3::new(c(3), c(4), c(5));
            let _ = writeln!(s, "VECTORS mode_{}_{part_name} double", m + 1);
            for (k, x) in local.iter().enumerate() {
                let mut elastic = nalgebra::Vector3::zeros();
                for j in 0..modal.n_modes() {
                    for i in 0..3 {
                        elastic[i] += modal.modes[(6 * k + i, j)] * c(6 + j);
                    }
                }
                let g = match p.time {
                    Some(_) => a * (dr + dtheta.cross(x) + elastic),
                    None => dr + a * (dtheta.cross(x) + elastic),
                };
                let _ = writeln!(s, "{:e} {:e} {:e}", g.x, g.y, g.z);
            }
        }
    }
    s
}
