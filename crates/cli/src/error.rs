//! Errors of the command line, with their exit codes.

use crate::deck::DeckError;

/// A failed command: bad input (exit code 2) or a runtime failure (exit code 1).
#[derive(Debug, thiserror::Error)]
pub enum CliError {
    /// The deck or the command line is wrong.
    #[error(transparent)]
    Input(#[from] DeckError),
    /// The computation or writing the results failed, or a comparison found differences.
    #[error("{0}")]
    Runtime(String),
    /// A command-line value is wrong (not tied to a deck).
    #[error("{0}")]
    Usage(String),
}

impl CliError {
    /// The process exit code.
    pub fn exit_code(&self) -> u8 {
        match self {
            CliError::Input(_) | CliError::Usage(_) => 2,
            CliError::Runtime(_) => 1,
        }
    }
}
