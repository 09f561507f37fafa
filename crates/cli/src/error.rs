//! Errors of the command line, with their exit codes.

use std::path::PathBuf;

use crate::deck::DeckError;

/// A failed command: bad input (exit code 2) or a runtime failure (exit code 1).
#[derive(Debug, thiserror::Error)]
pub enum CliError {
    /// The deck or the command line is wrong.
    #[error(transparent)]
    Input(#[from] DeckError),
    /// A file or directory could not be read, written, created or removed.
    #[error("cannot {action} {}: {reason}", path.display())]
    File {
        /// What was tried (`"write"`, `"remove the old"`, `"create the output directory"`).
        action: &'static str,
        path: PathBuf,
        reason: String,
    },
    /// The model of the deck `file` could not be built at a design other than the deck's:
    /// `item` (a body, a design variable) at the design `design` (one value per variable).
    #[error("{}: {item} at the design {design:?}: {reason}", file.display())]
    AtDesign {
        file: PathBuf,
        item: String,
        design: Vec<f64>,
        reason: String,
    },
    /// The computation of the deck `file` failed (assembly, integration, a solve).
    #[error("{}: {reason}", file.display())]
    Computation { file: PathBuf, reason: String },
    /// Another runtime failure, or a comparison found differences.
    #[error("{0}")]
    Runtime(String),
    /// A command-line value is wrong (not tied to a deck).
    #[error("{0}")]
    Usage(String),
}

impl CliError {
    /// A failure of the computation of the deck `src` ([`CliError::Computation`]).
    pub(crate) fn computation(src: &crate::deck::Source, reason: impl std::fmt::Display) -> Self {
        CliError::Computation {
            file: src.file.clone(),
            reason: reason.to_string(),
        }
    }

    /// The process exit code.
    pub fn exit_code(&self) -> u8 {
        match self {
            CliError::Input(_) | CliError::Usage(_) => 2,
            CliError::Runtime(_)
            | CliError::File { .. }
            | CliError::AtDesign { .. }
            | CliError::Computation { .. } => 1,
        }
    }
}
