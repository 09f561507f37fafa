//! `--set KEY=VALUE`: override any deck value by its dotted path before the deck is read.
//!
//! The path walks tables by key and arrays by index, e.g. `laminate.rod.plies.0.angle=30` or
//! `material.cfrp.E1=130e9`. The deck text is edited in place (formatting, comments and line
//! numbers are kept), so errors still point at the user's file. `VALUE` is a TOML value
//! (`30`, `1.5e9`, `true`, `"text"`, `[1, 2]`); a bare word that is not one is taken as a string.
//!
//! A path into one of the deck's single tables ([`CREATABLE`]: `[analysis]`, `[sensitivity]`,
//! `[finite_differences]`, `[optimize]`, `[operating]`) creates the table, or a table inside
//! it, when the deck leaves it out (its keys then take their defaults). Any other missing path
//! is an error, so a misspelt name (`body.rdo.modes`) is not taken for a new body.

use toml_edit::{DocumentMut, Item, Table, Value};

/// Why an override could not be applied.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum OverrideError {
    #[error("--set {0}: expected KEY=VALUE")]
    Syntax(String),
    #[error("--set {arg}: `{prefix}` {reason}")]
    Path {
        arg: String,
        prefix: String,
        reason: String,
    },
}

/// One parsed `KEY=VALUE`.
#[derive(Debug, Clone)]
pub struct Override {
    pub arg: String,
    pub path: Vec<String>,
    pub value: Value,
}

impl Override {
    /// Parse `KEY=VALUE`.
    pub fn parse(arg: &str) -> Result<Self, OverrideError> {
        let (key, value) = arg
            .split_once('=')
            .ok_or_else(|| OverrideError::Syntax(arg.to_string()))?;
        let key = key.trim();
        if key.is_empty() || key.split('.').any(str::is_empty) {
            return Err(OverrideError::Syntax(arg.to_string()));
        }
        let text = value.trim();
        let value = text.parse::<Value>().unwrap_or_else(|_| Value::from(text));
        Ok(Self {
            arg: arg.to_string(),
            path: key.split('.').map(str::to_string).collect(),
            value,
        })
    }
}

/// Apply overrides to a deck's text; returns the edited text.
pub fn apply(text: &str, overrides: &[Override]) -> Result<String, OverrideError> {
    if overrides.is_empty() {
        return Ok(text.to_string());
    }
    // A deck that does not parse is reported by the normal reader, with its location.
    let Ok(mut doc) = text.parse::<DocumentMut>() else {
        return Ok(text.to_string());
    };
    for o in overrides {
        set(doc.as_table_mut(), o)?;
    }
    Ok(doc.to_string())
}

fn path_error(o: &Override, depth: usize, reason: impl Into<String>) -> OverrideError {
    OverrideError::Path {
        arg: o.arg.clone(),
        prefix: o.path[..=depth].join("."),
        reason: reason.into(),
    }
}

/// The new value, keeping the comments and spacing around the value it replaces.
fn replacement(o: &Override, old: Option<&Value>) -> Value {
    let mut v = o.value.clone();
    match old {
        Some(old) => *v.decor_mut() = old.decor().clone(),
        None => v.decor_mut().set_prefix(" "),
    }
    v
}

fn set(root: &mut Table, o: &Override) -> Result<(), OverrideError> {
    in_table(root, o, 0)
}

/// The deck's single tables, every key of which has a default or is named by the error that
/// asks for it: `--set` creates them when the deck leaves them out.
pub const CREATABLE: [&str; 5] = [
    "analysis",
    "sensitivity",
    "finite_differences",
    "optimize",
    "operating",
];

/// `o.path[depth]` is a key of table `t`.
fn in_table(t: &mut Table, o: &Override, depth: usize) -> Result<(), OverrideError> {
    let key = &o.path[depth];
    if depth + 1 == o.path.len() {
        let v = replacement(o, t.get(key).and_then(Item::as_value));
        t.insert(key, Item::Value(v));
        return Ok(());
    }
    if !t.contains_key(key) && CREATABLE.contains(&o.path[0].as_str()) {
        // a new table is written after everything else, so the deck's lines keep their numbers
        let mut new = Table::new();
        new.set_implicit(depth > 0);
        new.set_position(Some(isize::MAX));
        t.insert(key, Item::Table(new));
    }
    let item = t
        .get_mut(key)
        .ok_or_else(|| path_error(o, depth, "is not in the deck"))?;
    in_item(item, o, depth + 1)
}

/// `o.path[depth]` selects inside `item`.
fn in_item(item: &mut Item, o: &Override, depth: usize) -> Result<(), OverrideError> {
    match item {
        Item::Table(t) => in_table(t, o, depth),
        Item::Value(v) => in_value(v, o, depth),
        Item::ArrayOfTables(a) => {
            let len = a.len();
            let idx = o.path[depth].parse::<usize>().map_err(|_| {
                path_error(o, depth - 1, "is an array: the next key must be an index")
            })?;
            let t = a
                .get_mut(idx)
                .ok_or_else(|| path_error(o, depth, format!("is out of range ({len} entries)")))?;
            if depth + 1 == o.path.len() {
                return Err(path_error(o, depth, "is a table: set one of its keys"));
            }
            in_table(t, o, depth + 1)
        }
        Item::None => Err(path_error(o, depth - 1, "is not in the deck")),
    }
}

/// `o.path[depth]` selects inside the inline value `v`.
fn in_value(v: &mut Value, o: &Override, depth: usize) -> Result<(), OverrideError> {
    let last = depth + 1 == o.path.len();
    let key = &o.path[depth];
    match v {
        Value::InlineTable(t) => {
            if last {
                let v = replacement(o, t.get(key));
                t.insert(key, v);
                return Ok(());
            }
            let inner = t
                .get_mut(key)
                .ok_or_else(|| path_error(o, depth, "is not in the deck"))?;
            in_value(inner, o, depth + 1)
        }
        Value::Array(a) => {
            let len = a.len();
            let idx = key.parse::<usize>().map_err(|_| {
                path_error(o, depth - 1, "is an array: the next key must be an index")
            })?;
            if idx >= len {
                return Err(path_error(
                    o,
                    depth,
                    format!("is out of range ({len} entries)"),
                ));
            }
            if last {
                let v = replacement(o, a.get(idx));
                a.replace(idx, v);
                return Ok(());
            }
            in_value(a.get_mut(idx).expect("index checked"), o, depth + 1)
        }
        _ => Err(path_error(
            o,
            depth - 1,
            "is a value, not a table or an array",
        )),
    }
}
