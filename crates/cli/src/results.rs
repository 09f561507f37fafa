//! Result files: a tree of groups, datasets and attributes, written to HDF5 (through the
//! pure-Rust `hdf5-pure`, no system library) and read back, and the dataset-by-dataset
//! comparison behind `flexsens compare`.

use std::collections::BTreeMap;
use std::path::Path;

use hdf5_pure::{AttrValue, FileBuilder};

use crate::error::CliError;

/// An attribute value.
#[derive(Clone, Debug, PartialEq)]
pub enum Attr {
    Text(String),
    F64(f64),
    I64(i64),
}

/// The values of a dataset.
#[derive(Clone, Debug, PartialEq)]
pub enum Data {
    F64(Vec<f64>),
    Text(Vec<String>),
}

impl Data {
    fn len(&self) -> usize {
        match self {
            Data::F64(v) => v.len(),
            Data::Text(v) => v.len(),
        }
    }
}

/// A dataset: row-major values of the given shape, with attributes (`units`, …).
#[derive(Clone, Debug, PartialEq)]
pub struct Dataset {
    pub shape: Vec<usize>,
    pub data: Data,
    pub attrs: BTreeMap<String, Attr>,
}

impl Dataset {
    /// Set an attribute (builder style).
    pub fn attr(&mut self, name: &str, value: Attr) -> &mut Self {
        self.attrs.insert(name.to_string(), value);
        self
    }

    /// Set the `units` attribute.
    pub fn units(&mut self, units: &str) -> &mut Self {
        self.attr("units", Attr::Text(units.to_string()))
    }
}

/// A group of datasets and subgroups.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Group {
    pub attrs: BTreeMap<String, Attr>,
    pub groups: BTreeMap<String, Group>,
    pub datasets: BTreeMap<String, Dataset>,
}

impl Group {
    /// The subgroup at a `/`-separated path, created if needed.
    pub fn group(&mut self, path: &str) -> &mut Group {
        path.split('/')
            .filter(|s| !s.is_empty())
            .fold(self, |g, name| {
                g.groups.entry(name.to_string()).or_default()
            })
    }

    /// Add (or replace) a numeric dataset at a `/`-separated path.
    ///
    /// # Panics
    /// If `values.len()` is not the product of `shape` (a programming error).
    pub fn put(&mut self, path: &str, shape: &[usize], values: Vec<f64>) -> &mut Dataset {
        assert_eq!(
            shape.iter().product::<usize>(),
            values.len(),
            "dataset {path}: shape and data disagree"
        );
        self.insert(
            path,
            Dataset {
                shape: shape.to_vec(),
                data: Data::F64(values),
                attrs: BTreeMap::new(),
            },
        )
    }

    /// Add (or replace) a one-dimensional text dataset.
    pub fn put_text(&mut self, path: &str, values: Vec<String>) -> &mut Dataset {
        self.insert(
            path,
            Dataset {
                shape: vec![values.len()],
                data: Data::Text(values),
                attrs: BTreeMap::new(),
            },
        )
    }

    fn insert(&mut self, path: &str, d: Dataset) -> &mut Dataset {
        let (dir, name) = path.rsplit_once('/').unwrap_or(("", path));
        let g = self.group(dir);
        g.datasets.insert(name.to_string(), d);
        g.datasets.get_mut(name).expect("just inserted")
    }

    /// Every dataset with its full path (`/a/b/name`), in a stable order.
    pub fn flatten(&self) -> Vec<(String, &Dataset)> {
        let mut out = Vec::new();
        self.collect("", &mut out);
        out
    }

    fn collect<'a>(&'a self, prefix: &str, out: &mut Vec<(String, &'a Dataset)>) {
        for (n, d) in &self.datasets {
            out.push((format!("{prefix}/{n}"), d));
        }
        for (n, g) in &self.groups {
            g.collect(&format!("{prefix}/{n}"), out);
        }
    }

    /// The dataset at a full path.
    pub fn get(&self, path: &str) -> Option<&Dataset> {
        let (dir, name) = path.rsplit_once('/').unwrap_or(("", path));
        let mut g = self;
        for part in dir.split('/').filter(|s| !s.is_empty()) {
            g = g.groups.get(part)?;
        }
        g.datasets.get(name)
    }

    /// The file image in HDF5 format.
    pub fn to_hdf5(&self) -> Result<Vec<u8>, String> {
        let mut fb = FileBuilder::new();
        for (n, v) in &self.attrs {
            fb.set_attr(n, attr_value(v));
        }
        for (n, d) in &self.datasets {
            write_dataset(fb.create_dataset(n), d)?;
        }
        for (n, g) in &self.groups {
            let gb = build_group(fb.create_group(n), g)?;
            fb.add_group(gb);
        }
        fb.finish().map_err(|e| e.to_string())
    }

    /// Read an HDF5 file written by [`Group::to_hdf5`] (or any file of numeric and string
    /// datasets).
    pub fn read_hdf5(path: &Path) -> Result<Group, CliError> {
        let fail = |e: String| CliError::Runtime(format!("cannot read {}: {e}", path.display()));
        let bytes = crate::limits::read_input(path).map_err(fail)?;
        Self::from_hdf5_bytes(bytes).map_err(fail)
    }

    /// Read the bytes of an HDF5 file (see [`Group::read_hdf5`]). A malformed file is an
    /// error, never a panic: the HDF5 reader is a dependency, and a panic inside it on a
    /// crafted file is caught and reported as a malformed file.
    pub fn from_hdf5_bytes(bytes: Vec<u8>) -> Result<Group, String> {
        if !hdf5_pure::is_hdf5_bytes(&bytes) {
            return Err("not an HDF5 file".into());
        }
        let read = std::panic::catch_unwind(move || {
            let file = hdf5_pure::File::from_bytes(bytes).map_err(|e| e.to_string())?;
            read_group(&file.root(), 0)
        });
        read.unwrap_or_else(|_| Err("a malformed HDF5 file (its structure is inconsistent)".into()))
    }
}

fn attr_value(a: &Attr) -> AttrValue {
    match a {
        Attr::Text(s) => AttrValue::String(s.clone()),
        Attr::F64(x) => AttrValue::F64(*x),
        Attr::I64(x) => AttrValue::I64(*x),
    }
}

fn write_dataset(b: &mut hdf5_pure::DatasetBuilder, d: &Dataset) -> Result<(), String> {
    let shape: Vec<u64> = d.shape.iter().map(|&n| n as u64).collect();
    match &d.data {
        Data::F64(v) => {
            b.with_f64_data(v).with_shape(&shape);
        }
        Data::Text(v) => {
            let refs: Vec<&str> = v.iter().map(String::as_str).collect();
            b.with_vlen_strings(&refs);
        }
    }
    for (n, a) in &d.attrs {
        b.set_attr(n, attr_value(a));
    }
    Ok(())
}

fn build_group(
    mut gb: hdf5_pure::GroupBuilder,
    g: &Group,
) -> Result<hdf5_pure::FinishedGroup, String> {
    for (n, v) in &g.attrs {
        gb.set_attr(n, attr_value(v));
    }
    for (n, d) in &g.datasets {
        write_dataset(gb.create_dataset(n), d)?;
    }
    for (n, sub) in &g.groups {
        let child = build_group(gb.create_group(n), sub)?;
        gb.add_group(child);
    }
    Ok(gb.finish())
}

fn read_attr(v: &AttrValue) -> Option<Attr> {
    Some(match v {
        AttrValue::F64(x) => Attr::F64(*x),
        AttrValue::F32(x) => Attr::F64(f64::from(*x)),
        AttrValue::I64(x) => Attr::I64(*x),
        AttrValue::I32(x) => Attr::I64(i64::from(*x)),
        AttrValue::String(s) | AttrValue::AsciiString(s) => Attr::Text(s.clone()),
        _ => return None,
    })
}

/// Groups nested deeper than this are refused: a result file is a few levels deep, and a
/// malformed file can make a group its own descendant (a cycle the reader would follow until
/// the stack overflows).
const MAX_GROUP_DEPTH: usize = 32;

fn read_group(g: &hdf5_pure::Group, depth: usize) -> Result<Group, String> {
    if depth > MAX_GROUP_DEPTH {
        return Err(format!(
            "groups nested more than {MAX_GROUP_DEPTH} deep (a malformed file whose groups \
             contain themselves?)"
        ));
    }
    let e = |e: hdf5_pure::Error| e.to_string();
    let mut out = Group::default();
    for (n, v) in g.attrs().map_err(e)? {
        if let Some(a) = read_attr(&v) {
            out.attrs.insert(n, a);
        }
    }
    for n in g.datasets().map_err(e)? {
        let d = g.dataset(&n).map_err(e)?;
        let shape: Vec<usize> = d.shape().map_err(e)?.iter().map(|&x| x as usize).collect();
        let data = match d.read_f64() {
            Ok(v) => Data::F64(v),
            Err(_) => Data::Text(d.read_string().map_err(e)?),
        };
        let mut attrs = BTreeMap::new();
        for (an, av) in d.attrs().map_err(e)? {
            if let Some(a) = read_attr(&av) {
                attrs.insert(an, a);
            }
        }
        out.datasets.insert(n, Dataset { shape, data, attrs });
    }
    for n in g.groups().map_err(e)? {
        let sub = g.group(&n).map_err(e)?;
        out.groups.insert(n, read_group(&sub, depth + 1)?);
    }
    Ok(out)
}

/// One difference found by [`compare`].
#[derive(Clone, Debug, PartialEq)]
pub struct Difference {
    pub dataset: String,
    /// Flat index of the entry, and its row's time when the dataset runs along `/time`.
    pub index: usize,
    pub time: Option<f64>,
    pub a: f64,
    pub b: f64,
    /// `|a − b| / (atol + rtol |b|)`: above 1 is a mismatch.
    pub excess: f64,
}

/// The outcome of comparing two result trees.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Comparison {
    /// Structural problems: datasets missing on one side, different shapes or types, different
    /// text, different units.
    pub problems: Vec<String>,
    /// The largest numeric differences beyond the tolerance, largest first (at most one per
    /// dataset).
    pub differences: Vec<Difference>,
    /// Datasets and values compared.
    pub datasets: usize,
    pub values: usize,
}

impl Comparison {
    pub fn matches(&self) -> bool {
        self.problems.is_empty() && self.differences.is_empty()
    }
}

/// Datasets that describe the run rather than its results (they may differ between two runs
/// of the same deck): skipped by [`compare`].
const PROVENANCE: [&str; 1] = ["/meta"];

/// Compare `a` with `b` (the reference): every dataset of either must be in both with the same
/// shape, units and, within `|a − b| ≤ atol + rtol |b|`, values.
pub fn compare(a: &Group, b: &Group, rtol: f64, atol: f64) -> Comparison {
    let skip = |p: &str| {
        PROVENANCE
            .iter()
            .any(|q| p == *q || p.starts_with(&format!("{q}/")))
    };
    let fa: BTreeMap<String, &Dataset> =
        a.flatten().into_iter().filter(|(p, _)| !skip(p)).collect();
    let fb: BTreeMap<String, &Dataset> =
        b.flatten().into_iter().filter(|(p, _)| !skip(p)).collect();
    let time = b.get("/time").and_then(|d| match &d.data {
        Data::F64(t) => Some(t.clone()),
        Data::Text(_) => None,
    });
    let mut out = Comparison::default();
    for p in fa.keys().filter(|p| !fb.contains_key(*p)) {
        out.problems.push(format!("{p}: only in the first file"));
    }
    for p in fb.keys().filter(|p| !fa.contains_key(*p)) {
        out.problems.push(format!("{p}: only in the second file"));
    }
    for (p, da) in &fa {
        let Some(db) = fb.get(p) else { continue };
        out.datasets += 1;
        if da.shape != db.shape {
            out.problems
                .push(format!("{p}: shape {:?} vs {:?}", da.shape, db.shape));
            continue;
        }
        if da.attrs.get("units") != db.attrs.get("units") {
            out.problems.push(format!(
                "{p}: units {:?} vs {:?}",
                da.attrs.get("units"),
                db.attrs.get("units")
            ));
        }
        match (&da.data, &db.data) {
            (Data::F64(va), Data::F64(vb)) => {
                out.values += va.len();
                let mut worst: Option<Difference> = None;
                for (i, (&x, &y)) in va.iter().zip(vb).enumerate() {
                    let excess = if x == y || (x.is_nan() && y.is_nan()) {
                        0.0
                    } else {
                        let d = (x - y).abs() / (atol + rtol * y.abs());
                        if d.is_nan() { f64::INFINITY } else { d }
                    };
                    if excess > 1.0 && worst.as_ref().is_none_or(|w| excess > w.excess) {
                        let row = if da.shape.is_empty() {
                            0
                        } else {
                            i / (da.data.len() / da.shape[0]).max(1)
                        };
                        let t = time
                            .as_ref()
                            .filter(|t| da.shape.first() == Some(&t.len()))
                            .map(|t| t[row]);
                        worst = Some(Difference {
                            dataset: p.clone(),
                            index: i,
                            time: t,
                            a: x,
                            b: y,
                            excess,
                        });
                    }
                }
                out.differences.extend(worst);
            }
            (Data::Text(ta), Data::Text(tb)) => {
                if ta != tb {
                    out.problems.push(format!("{p}: text differs"));
                }
            }
            _ => out
                .problems
                .push(format!("{p}: numeric in one file, text in the other")),
        }
    }
    out.differences
        .sort_by(|x, y| y.excess.total_cmp(&x.excess));
    out
}
