//! Printing named quantities (scalars, vectors, matrices with units) as tables, JSON or CSV.
//!
//! Every command reduces its results to [`Report`]s of [`Quantity`]s: the values, and one block
//! per design variable for derivatives. The three formats are then uniform across commands.

use std::fmt::Write as _;

use serde_json::{Map, Value, json};

use crate::table::{CsvTable, number};

/// A named scalar, vector or matrix with its unit(s).
#[derive(Clone, Debug)]
pub struct Quantity {
    pub name: &'static str,
    pub rows: usize,
    pub cols: usize,
    /// Row-major entries.
    pub values: Vec<f64>,
    /// One unit for every entry, or one per entry (row-major).
    pub units: Vec<String>,
}

impl Quantity {
    pub fn scalar(name: &'static str, unit: &str, v: f64) -> Self {
        Self {
            name,
            rows: 1,
            cols: 1,
            values: vec![v],
            units: vec![unit.into()],
        }
    }

    /// A vector shown as one row.
    pub fn vector(name: &'static str, unit: &str, v: &[f64]) -> Self {
        Self {
            name,
            rows: 1,
            cols: v.len(),
            values: v.to_vec(),
            units: vec![unit.into()],
        }
    }

    /// A matrix given by an entry function.
    pub fn matrix(
        name: &'static str,
        unit: &str,
        rows: usize,
        cols: usize,
        f: impl Fn(usize, usize) -> f64,
    ) -> Self {
        let values = (0..rows)
            .flat_map(|r| (0..cols).map(move |c| (r, c)))
            .map(|(r, c)| f(r, c))
            .collect();
        Self {
            name,
            rows,
            cols,
            values,
            units: vec![unit.into()],
        }
    }

    /// The same quantity with a unit per entry.
    pub fn with_units(mut self, unit: impl Fn(usize, usize) -> String) -> Self {
        self.units = (0..self.rows)
            .flat_map(|r| (0..self.cols).map(move |c| (r, c)))
            .map(|(r, c)| unit(r, c))
            .collect();
        self
    }

    fn unit(&self, r: usize, c: usize) -> &str {
        if self.units.len() == 1 {
            &self.units[0]
        } else {
            &self.units[r * self.cols + c]
        }
    }

    /// The unit shown in a table heading.
    fn heading_unit(&self) -> String {
        if self.units.len() == 1 {
            self.units[0].clone()
        } else {
            let mut u: Vec<&str> = self.units.iter().map(String::as_str).collect();
            u.dedup();
            let mut seen = Vec::new();
            for x in u {
                if !seen.contains(&x) {
                    seen.push(x);
                }
            }
            seen.join(", ")
        }
    }

    /// `name [unit]`, as in a table.
    fn label(&self) -> String {
        format!("{} [{}]", self.name, self.heading_unit())
    }

    fn json_value(&self) -> Value {
        if self.rows == 1 && self.cols == 1 {
            json!(self.values[0])
        } else if self.rows == 1 {
            json!(self.values)
        } else {
            json!(
                (0..self.rows)
                    .map(|r| self.values[r * self.cols..(r + 1) * self.cols].to_vec())
                    .collect::<Vec<_>>()
            )
        }
    }

    fn json_unit(&self) -> Value {
        if self.units.len() == 1 {
            json!(self.units[0])
        } else {
            json!(
                (0..self.rows)
                    .map(|r| self.units[r * self.cols..(r + 1) * self.cols].to_vec())
                    .collect::<Vec<_>>()
            )
        }
    }
}

/// The quantities of one object (a laminate, a section, …): values, then derivatives.
pub struct Report {
    /// Kind and name, e.g. ("laminate", "rod").
    pub kind: &'static str,
    pub name: String,
    /// Lines printed before the quantities in a table (description of the object).
    pub preamble: Vec<String>,
    /// Extra JSON members describing the object (plies, mesh size, …).
    pub info: Map<String, Value>,
    pub values: Vec<Quantity>,
    pub derivatives: Vec<Derivative>,
}

/// The quantities of a report differentiated with respect to one design variable.
pub struct Derivative {
    /// The variable: a `[design.*]` name, or a ply (`rod.plies.2.angle`).
    pub wrt: String,
    /// The variable's unit: the derivatives are per one of it (`"deg"`, `"rad"`, `"Pa"`).
    pub per: &'static str,
    pub values: Vec<Quantity>,
}

/// The reports in the requested format; `collection` names them in JSON (`"sections"`), `kind`
/// heads the CSV column of names (`"section"`).
pub fn render(
    format: super::Format,
    title: Option<&str>,
    collection: &str,
    kind: &str,
    reports: &[Report],
) -> String {
    match format {
        super::Format::Table => table(title, reports),
        super::Format::Json => json_doc(collection, reports),
        super::Format::Csv => csv(kind, reports),
    }
}

/// Aligned, human-readable tables.
pub fn table(title: Option<&str>, reports: &[Report]) -> String {
    let mut s = String::new();
    if let Some(t) = title {
        let _ = writeln!(s, "{t}\n");
    }
    for r in reports {
        let _ = writeln!(s, "{} {}:", r.kind, r.name);
        for l in &r.preamble {
            let _ = writeln!(s, "  {l}");
        }
        let width = r
            .values
            .iter()
            .map(|q| q.label().chars().count())
            .max()
            .unwrap_or(0);
        for q in &r.values {
            write_quantity(&mut s, q, width);
        }
        for d in &r.derivatives {
            let _ = writeln!(s, "  -- d/d {} (per {})", d.wrt, d.per);
            for q in &d.values {
                write_quantity(&mut s, q, width);
            }
        }
        s.push('\n');
    }
    s
}

fn write_quantity(s: &mut String, q: &Quantity, width: usize) {
    if q.rows == 1 && q.cols == 1 {
        let _ = writeln!(s, "  {:<width$} {:>13.6e}", q.label(), q.values[0]);
        return;
    }
    // round-off below 1e-12 of the largest entry is shown as 0 (JSON and CSV keep it)
    let scale = q.values.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    for r in 0..q.rows {
        let label = if r == 0 { q.label() } else { String::new() };
        let _ = write!(s, "  {label:<width$}");
        for c in 0..q.cols {
            let v = q.values[r * q.cols + c];
            let v = if v.abs() < 1e-12 * scale { 0.0 } else { v };
            let _ = write!(s, " {v:>13.6e}");
        }
        s.push('\n');
    }
}

/// One JSON document: `{flexsens, <kind>s: {name: {…info, values, units, derivatives}}}`.
pub fn json_doc(collection: &str, reports: &[Report]) -> String {
    let mut objs = Map::new();
    for r in reports {
        let mut o = r.info.clone();
        o.insert(
            "values".into(),
            Value::Object(
                r.values
                    .iter()
                    .map(|q| (q.name.to_string(), q.json_value()))
                    .collect(),
            ),
        );
        o.insert(
            "units".into(),
            Value::Object(
                r.values
                    .iter()
                    .map(|q| (q.name.to_string(), q.json_unit()))
                    .collect(),
            ),
        );
        if !r.derivatives.is_empty() {
            let d: Vec<Value> = r
                .derivatives
                .iter()
                .map(|d| {
                    let values: Map<String, Value> = d
                        .values
                        .iter()
                        .map(|q| (q.name.to_string(), q.json_value()))
                        .collect();
                    json!({"wrt": d.wrt, "per": d.per, "values": values})
                })
                .collect();
            o.insert("derivatives".into(), json!(d));
        }
        objs.insert(r.name.clone(), Value::Object(o));
    }
    let mut doc = Map::new();
    doc.insert("flexsens".into(), json!(env!("CARGO_PKG_VERSION")));
    doc.insert(collection.into(), Value::Object(objs));
    serde_json::to_string_pretty(&Value::Object(doc)).expect("JSON of plain numbers") + "\n"
}

/// Long-format CSV, one value per row: `<kind>,quantity,row,col,unit,wrt,value`.
pub fn csv(kind: &str, reports: &[Report]) -> String {
    let mut t = CsvTable::new();
    t.row([kind, "quantity", "row", "col", "unit", "wrt", "value"]);
    for r in reports {
        let mut blocks = vec![("", String::new(), &r.values)];
        for d in &r.derivatives {
            blocks.push((d.wrt.as_str(), format!("/{}", d.per), &d.values));
        }
        for (wrt, per, qs) in blocks {
            for q in qs {
                for row in 0..q.rows {
                    for col in 0..q.cols {
                        t.row([
                            r.name.clone(),
                            q.name.to_string(),
                            row.to_string(),
                            col.to_string(),
                            format!("{}{per}", q.unit(row, col)),
                            wrt.to_string(),
                            number(q.values[row * q.cols + col]),
                        ]);
                    }
                }
            }
        }
    }
    t.finish()
}
