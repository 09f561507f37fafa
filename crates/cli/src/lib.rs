//! `flexsens` — the command-line front end: decks, commands and outputs.
//!
//! This is the only crate that reads or writes files or knows about decks. The binary
//! (`src/main.rs`) parses the command line and maps results to exit codes: 0 success,
//! 1 runtime failure, 2 bad input (deck or command line). The library half exists so that tests
//! can drive decks and commands in-process.

// A deck error carries its file, location, key and snippet; it is built at most once per run, so
// its size on the error path does not matter.
#![allow(clippy::result_large_err)]

pub mod commands;
pub mod deck;
pub mod error;
pub mod files;
pub mod limits;
pub mod plot;
mod progress;
pub mod results;
pub(crate) mod study;
pub(crate) mod table;
