//! Decks: TOML input files, read in two stages.
//!
//! 1. [`raw`]: serde structs that mirror the file (`deny_unknown_fields`, values wrapped in
//!    `Spanned` so that validation can point at them);
//! 2. validation into the engine's types (`laminate::PlyStack`, …), where every error becomes a
//!    [`DeckError`] naming the file, line, column and dotted key.
//!
//! Only this module knows TOML; the engine crates never see it.

pub mod analysis;
pub mod bodies;
pub mod check;
pub mod design;
pub mod keys;
pub mod laminates;
pub mod mechanism;
pub mod operating;
pub mod optimize;
pub mod overrides;
pub mod raw;
pub mod responses;
pub mod sections;

use std::fmt;
use std::ops::Range;
use std::path::{Path, PathBuf};

pub use raw::RawDeck;

/// An error in a deck, located in its file.
#[derive(Debug, Clone)]
pub struct DeckError {
    pub file: PathBuf,
    /// 1-based line and column, when the error has a place in the file.
    pub line: Option<(usize, usize)>,
    /// The dotted key, e.g. `laminate.rod.plies[2].thickness`.
    pub key: Option<String>,
    pub message: String,
    /// The offending source line, for display.
    pub snippet: Option<String>,
    /// A closing remark (e.g. that `--set` edited the deck).
    pub note: Option<String>,
}

impl fmt::Display for DeckError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file.display())?;
        if let Some((l, c)) = self.line {
            write!(f, ":{l}:{c}")?;
        }
        write!(f, ": ")?;
        if let Some(k) = &self.key {
            write!(f, "key `{k}`: ")?;
        }
        write!(f, "{}", self.message)?;
        if let (Some(s), Some((l, c))) = (&self.snippet, self.line) {
            let gutter = l.to_string().len();
            write!(
                f,
                "\n{:gutter$} |\n{l} | {s}\n{:gutter$} | {:>c$}",
                "", "", "^"
            )?;
        }
        if let Some(n) = &self.note {
            write!(f, "\nnote: {n}")?;
        }
        Ok(())
    }
}

impl std::error::Error for DeckError {}

/// The text of a deck and where it came from, for locating errors.
pub struct Source {
    pub file: PathBuf,
    pub text: String,
    /// The `--set` arguments applied to `text`, if any.
    pub overrides: Vec<String>,
    /// The text as read, when `--set` arguments changed it.
    original: Option<String>,
    /// Warnings already printed: each once per run, however often the deck is validated
    /// (finite differences rebuild the model).
    warned: std::sync::Mutex<std::collections::BTreeSet<String>>,
}

impl Source {
    /// A deck's text and its file name (for messages).
    pub fn new(file: impl Into<PathBuf>, text: impl Into<String>) -> Self {
        Self {
            file: file.into(),
            text: text.into(),
            overrides: Vec::new(),
            original: None,
            warned: Default::default(),
        }
    }

    /// Print a warning on stderr (`warning: file:line:col: key …: message`): something legal
    /// but probably not meant. Each warning once.
    pub fn warn(
        &self,
        span: Option<Range<usize>>,
        key: Option<String>,
        message: impl Into<String>,
    ) {
        let text = self.error(span, key, message).to_string();
        let new = self
            .warned
            .lock()
            .map(|mut w| w.insert(text.clone()))
            .unwrap_or(false);
        if new {
            eprintln!("warning: {text}");
        }
    }

    /// Read a deck file.
    pub fn read(path: &Path) -> Result<Self, DeckError> {
        let text = crate::limits::read_text(path).map_err(|e| DeckError {
            file: path.to_path_buf(),
            line: None,
            key: None,
            message: format!("cannot read the deck: {e}"),
            snippet: None,
            note: None,
        })?;
        Ok(Self::new(path, text))
    }

    /// Apply `--set KEY=VALUE` overrides to the text (see [`overrides`]).
    pub fn with_overrides(mut self, args: &[String]) -> Result<Self, DeckError> {
        if args.is_empty() {
            return Ok(self);
        }
        let bad = |e: overrides::OverrideError| DeckError {
            file: self.file.clone(),
            line: None,
            key: None,
            message: e.to_string(),
            snippet: None,
            note: None,
        };
        let parsed = args
            .iter()
            .map(|a| overrides::Override::parse(a))
            .collect::<Result<Vec<_>, _>>()
            .map_err(bad)?;
        let text = overrides::apply(&self.text, &parsed).map_err(bad)?;
        self.original.get_or_insert_with(|| self.text.clone());
        self.text = text;
        self.overrides = args.to_vec();
        Ok(self)
    }

    /// This deck's file text (before any `--set`) with the `--set` arguments `args` applied
    /// (see [`overrides`]): another case of the same file, without reading it again.
    pub fn edited(&self, args: &[String]) -> Result<Self, DeckError> {
        Source::new(self.file.clone(), self.file_text().to_string()).with_overrides(args)
    }

    /// The text as read from the file.
    pub fn file_text(&self) -> &str {
        self.original.as_deref().unwrap_or(&self.text)
    }

    /// 1-based line and column of a byte offset.
    fn line_col(&self, offset: usize) -> (usize, usize) {
        let offset = offset.min(self.text.len());
        let before = &self.text[..offset];
        let line = before.matches('\n').count() + 1;
        let col = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
        (line, col)
    }

    /// An error at a span of the file.
    pub fn error(
        &self,
        span: Option<Range<usize>>,
        key: Option<String>,
        message: impl Into<String>,
    ) -> DeckError {
        let line = span.as_ref().map(|s| self.line_col(s.start));
        let snippet = line.and_then(|(l, _)| self.text.lines().nth(l - 1).map(str::to_string));
        let note = (!self.overrides.is_empty()).then(|| {
            format!(
                "the deck was edited by --set {} before it was read",
                self.overrides.join(" --set ")
            )
        });
        DeckError {
            file: self.file.clone(),
            line,
            key,
            message: message.into(),
            snippet,
            note,
        }
    }

    /// The bare key assigned at a value's position (`thickness` in `thickness = "x"`), for errors
    /// whose message does not name it.
    fn key_before(&self, offset: usize) -> Option<String> {
        let line_start = self.text[..offset.min(self.text.len())]
            .rfind('\n')
            .map_or(0, |i| i + 1);
        let head = &self.text[line_start..offset.min(self.text.len())];
        let eq = head.rfind('=')?;
        let key: String = head[..eq]
            .trim_end()
            .chars()
            .rev()
            .take_while(|c| c.is_alphanumeric() || *c == '_' || *c == '-' || *c == '.')
            .collect::<Vec<_>>()
            .into_iter()
            .rev()
            .collect();
        (!key.is_empty()).then_some(key)
    }

    /// The key written at `offset` (`width` in `width = 0.04` at the start of the line).
    fn key_at(&self, offset: usize) -> Option<String> {
        let rest = self.text.get(offset..)?;
        let line = rest.lines().next()?;
        let key = line.split('=').next()?.trim();
        let bare = |c: char| c.is_alphanumeric() || matches!(c, '_' | '-' | '.' | '"');
        (line.contains('=') && !key.is_empty() && key.chars().all(bare)).then(|| key.to_string())
    }

    /// Parse the raw deck; TOML syntax errors, type errors and unknown keys carry their place.
    pub fn parse(&self) -> Result<RawDeck, DeckError> {
        toml::from_str::<RawDeck>(&self.text).map_err(|e| {
            let mut message = plain_type_names(e.message().trim_end());
            if let Some(hint) = unknown_key_hint(&message) {
                message.push_str(&hint);
            }
            // the key: the one a field error names, the one a duplicate starts with, or the
            // one assigned before a bad value; never a token of the message (a value, a bracket)
            let at = e.span().map(|s| s.start);
            let key =
                if message.starts_with("unknown field") || message.starts_with("missing field") {
                    key_from_message(&message)
                } else if message.starts_with("duplicate key") {
                    at.and_then(|s| self.key_at(s))
                } else {
                    None
                }
                .or_else(|| at.and_then(|s| self.key_before(s)));
            self.error(e.span(), key, message)
        })
    }
}

/// A serde message with the reader's type names (`struct RawPly`) said as what they are in
/// the deck (`a table`, here `{ material, thickness, angle }`).
fn plain_type_names(message: &str) -> String {
    let mut out = String::new();
    let mut rest = message;
    while let Some(i) = rest.find("struct Raw") {
        out.push_str(&rest[..i]);
        let after = &rest[i + "struct Raw".len()..];
        let end = after
            .find(|c: char| !c.is_ascii_alphanumeric())
            .unwrap_or(after.len());
        out.push_str(match &after[..end] {
            "Ply" => "a ply table { material, thickness, angle }",
            "SectionPly" => "a ply table { material, thickness, angle, elements }",
            "Marker" => "a marker table { body, point | node | coupling, … }",
            _ => "a table",
        });
        rest = &after[end..];
    }
    out.push_str(rest);
    out
}

/// "; did you mean `x`?" for serde's "unknown field `y`, expected one of `a`, `b`, …" when one
/// of the expected keys is close to the unknown one.
fn unknown_key_hint(message: &str) -> Option<String> {
    let rest = message.strip_prefix("unknown field `")?;
    let (word, rest) = rest.split_once('`')?;
    let expected: Vec<&str> = rest.split('`').skip(1).step_by(2).collect();
    let hint = check::suggestion(word, &expected);
    hint.starts_with(", did you mean")
        .then(|| hint.replacen(", ", "; ", 1))
}

/// The key named in a serde message such as "unknown field `E4`, expected …".
fn key_from_message(message: &str) -> Option<String> {
    let start = message.find('`')? + 1;
    let len = message[start..].find('`')?;
    Some(message[start..start + len].to_string())
}

/// The named tables of one kind to work on: `only` (with a "did you mean" when it is not
/// there), or all of them; an error when the deck has none.
pub fn select<'a, T>(
    src: &Source,
    tables: &'a std::collections::BTreeMap<String, T>,
    only: Option<&str>,
    kind: &str,
) -> Result<Vec<(&'a String, &'a T)>, DeckError> {
    let selected: Vec<_> = match only {
        Some(name) => {
            let found = tables.get_key_value(name).ok_or_else(|| {
                let known: Vec<&str> = tables.keys().map(String::as_str).collect();
                src.error(
                    None,
                    None,
                    format!(
                        "no {kind} `{name}` in this deck{}",
                        check::suggestion(name, &known)
                    ),
                )
            })?;
            vec![found]
        }
        None => tables.iter().collect(),
    };
    if selected.is_empty() {
        return Err(src.error(
            None,
            Some(kind.to_string()),
            format!("the deck defines no [{kind}.*] table"),
        ));
    }
    Ok(selected)
}

/// Read a deck file, apply `--set` overrides and parse it.
pub fn load(path: &Path, overrides: &[String]) -> Result<(Source, RawDeck), DeckError> {
    let source = Source::read(path)?.with_overrides(overrides)?;
    let raw = source.parse()?;
    Ok((source, raw))
}
