//! Errors of the command line, with their exit codes.

use std::fmt;

use crate::deck::DeckError;

/// A failed command: bad input (exit code 2) or a runtime failure (exit code 1).
#[derive(Debug)]
pub enum CliError {
    /// The deck or the command line is wrong.
    Input(DeckError),
    /// The computation or writing the results failed, or a comparison found differences.
    Runtime(String),
    /// A command-line value is wrong (not tied to a deck).
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

impl fmt::Display for CliError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CliError::Input(e) => e.fmt(f),
            CliError::Runtime(m) | CliError::Usage(m) => f.write_str(m),
        }
    }
}

impl std::error::Error for CliError {}

impl From<DeckError> for CliError {
    fn from(e: DeckError) -> Self {
        CliError::Input(e)
    }
}
