//! `flexsens laminate`: plate stiffness of the deck's laminates and its ply-angle derivatives.

use std::fmt::Write as _;
use std::path::Path;

use laminate::{LaminateStiffness, PlyStack};
use sens::{chunk_ranges, seed_chunk};
use serde_json::json;

use super::Format;
use crate::deck::laminates::{LaminateDef, suggestion, validate};
use crate::deck::{self, DeckError};

/// Width of the dual-number chunks (results do not depend on it).
const CHUNK: usize = 8;

/// One reported quantity: name, unit, entries by (row, col).
struct Quantity {
    name: &'static str,
    unit: &'static str,
    rows: usize,
    cols: usize,
    values: Vec<f64>,
}

fn quantities(k: &LaminateStiffness<f64>) -> Vec<Quantity> {
    let m3 = |name, unit, m: &nalgebra::Matrix3<f64>| Quantity {
        name,
        unit,
        rows: 3,
        cols: 3,
        values: m.transpose().iter().copied().collect(), // row-major
    };
    let s = |name, unit, v: f64| Quantity {
        name,
        unit,
        rows: 1,
        cols: 1,
        values: vec![v],
    };
    vec![
        s("thickness", "m", k.thickness),
        s("mass_per_area", "kg/m^2", k.mass_per_area),
        s("first_moment", "kg/m", k.first_moment),
        s("rotary_inertia", "kg", k.rotary_inertia),
        m3("A", "N/m", &k.a),
        m3("B", "N", &k.b),
        m3("D", "N*m", &k.d),
        Quantity {
            name: "As",
            unit: "N/m",
            rows: 2,
            cols: 2,
            values: k.shear.transpose().iter().copied().collect(),
        },
    ]
}

/// Derivatives of the laminate's stiffness with respect to each ply's angle (per radian).
pub fn ply_angle_derivatives(stack: &PlyStack<f64>) -> Vec<LaminateStiffness<f64>> {
    let angles: Vec<f64> = stack.plies().iter().map(|p| p.angle).collect();
    let mut out = Vec::with_capacity(angles.len());
    for range in chunk_ranges(angles.len(), CHUNK) {
        let seeded = seed_chunk::<CHUNK>(&angles, range.start);
        let dual = stack
            .with_angles(&seeded)
            .expect("angles of a validated stack stay valid")
            .stiffness();
        for k in 0..range.len() {
            out.push(dual.tangent(k));
        }
    }
    out
}

/// Run the command; the returned text goes to stdout.
pub fn run(
    path: &Path,
    overrides: &[String],
    only: Option<&str>,
    format: Format,
    derivatives: bool,
) -> Result<String, DeckError> {
    let (src, raw) = deck::load(path, overrides)?;
    let model = validate(&src, &raw)?;
    let selected: Vec<(&String, &LaminateDef)> = match only {
        Some(name) => {
            let def = model.laminates.get_key_value(name).ok_or_else(|| {
                let known: Vec<&str> = model.laminates.keys().map(String::as_str).collect();
                src.error(
                    None,
                    None,
                    format!(
                        "no laminate `{name}` in this deck{}",
                        suggestion(name, &known)
                    ),
                )
            })?;
            vec![def]
        }
        None => model.laminates.iter().collect(),
    };
    if selected.is_empty() {
        return Err(src.error(
            None,
            Some("laminate".into()),
            "the deck defines no [laminate.*] table",
        ));
    }
    let results: Vec<_> = selected
        .iter()
        .map(|(name, def)| {
            let values = def.stack.stiffness();
            let derivs = if derivatives {
                ply_angle_derivatives(&def.stack)
            } else {
                Vec::new()
            };
            (*name, *def, values, derivs)
        })
        .collect();
    Ok(match format {
        Format::Table => table(raw.title.as_deref(), &results),
        Format::Json => json_doc(&results),
        Format::Csv => csv(&results),
    })
}

type Row<'a> = (
    &'a String,
    &'a LaminateDef,
    LaminateStiffness<f64>,
    Vec<LaminateStiffness<f64>>,
);

fn ply_label(i: usize) -> String {
    format!("plies[{i}].angle")
}

fn table(title: Option<&str>, results: &[Row]) -> String {
    let mut s = String::new();
    if let Some(t) = title {
        let _ = writeln!(s, "{t}\n");
    }
    for (name, def, k, derivs) in results {
        let _ = writeln!(
            s,
            "laminate {name}: {} plies, reference surface {:?}, shear correction {:.4}",
            def.stack.plies().len(),
            def.stack.reference(),
            def.stack.shear_correction()
        );
        let _ = writeln!(
            s,
            "  {:>3}  {:<16} {:>12} {:>10}",
            "ply", "material", "thickness/m", "angle/deg"
        );
        for (i, p) in def.stack.plies().iter().enumerate() {
            let _ = writeln!(
                s,
                "  {i:>3}  {:<16} {:>12.4e} {:>10.3}",
                def.ply_materials[i],
                p.thickness,
                p.angle.to_degrees()
            );
        }
        for q in quantities(k) {
            write_quantity(&mut s, &q);
        }
        for (i, d) in derivs.iter().enumerate() {
            let _ = writeln!(
                s,
                "  -- d/d {} (per rad; mass terms do not depend on angles)",
                ply_label(i)
            );
            for q in quantities(d).iter().filter(|q| q.rows > 1) {
                write_quantity(&mut s, q);
            }
        }
        s.push('\n');
    }
    s
}

fn write_quantity(s: &mut String, q: &Quantity) {
    if q.rows == 1 && q.cols == 1 {
        let _ = writeln!(s, "  {:<16} {:>13.6e} {}", q.name, q.values[0], q.unit);
        return;
    }
    // round-off below 1e-12 of the largest entry is shown as 0 (JSON and CSV keep it)
    let scale = q.values.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    for r in 0..q.rows {
        let label = if r == 0 {
            format!("{} [{}]", q.name, q.unit)
        } else {
            String::new()
        };
        let _ = write!(s, "  {label:<16}");
        for c in 0..q.cols {
            let v = q.values[r * q.cols + c];
            let v = if v.abs() < 1e-12 * scale { 0.0 } else { v };
            let _ = write!(s, " {v:>13.6e}");
        }
        s.push('\n');
    }
}

fn json_doc(results: &[Row]) -> String {
    let q_json = |qs: Vec<Quantity>| {
        let mut map = serde_json::Map::new();
        for q in qs {
            let v = if q.rows == 1 && q.cols == 1 {
                json!(q.values[0])
            } else {
                json!(
                    (0..q.rows)
                        .map(|r| q.values[r * q.cols..(r + 1) * q.cols].to_vec())
                        .collect::<Vec<_>>()
                )
            };
            map.insert(q.name.to_string(), v);
        }
        serde_json::Value::Object(map)
    };
    let units: serde_json::Map<String, serde_json::Value> = quantities(&results[0].2)
        .iter()
        .map(|q| (q.name.to_string(), json!(q.unit)))
        .collect();
    let mut lams = serde_json::Map::new();
    for (name, def, k, derivs) in results {
        let plies: Vec<_> = def
            .stack
            .plies()
            .iter()
            .zip(&def.ply_materials)
            .map(|(p, m)| json!({"material": m, "thickness": p.thickness, "angle_deg": p.angle.to_degrees()}))
            .collect();
        let mut entry = json!({"plies": plies, "values": q_json(quantities(k))});
        if !derivs.is_empty() {
            let d: Vec<_> = derivs
                .iter()
                .enumerate()
                .map(|(i, d)| json!({"wrt": ply_label(i), "per": "rad", "values": q_json(quantities(d))}))
                .collect();
            entry["derivatives"] = json!(d);
        }
        lams.insert((*name).clone(), entry);
    }
    let doc = json!({"flexsens": env!("CARGO_PKG_VERSION"), "units": units, "laminates": lams});
    serde_json::to_string_pretty(&doc).expect("JSON of plain numbers") + "\n"
}

fn csv(results: &[Row]) -> String {
    let mut s = String::from("laminate,quantity,row,col,unit,wrt,value\n");
    for (name, _, k, derivs) in results {
        let mut blocks = vec![(String::new(), String::new(), quantities(k))];
        for (i, d) in derivs.iter().enumerate() {
            blocks.push((ply_label(i), "/rad".to_string(), quantities(d)));
        }
        for (wrt, per, qs) in blocks {
            for q in qs {
                for r in 0..q.rows {
                    for c in 0..q.cols {
                        let _ = writeln!(
                            s,
                            "{name},{},{r},{c},{}{per},{wrt},{:e}",
                            q.name,
                            q.unit,
                            q.values[r * q.cols + c]
                        );
                    }
                }
            }
        }
    }
    s
}
