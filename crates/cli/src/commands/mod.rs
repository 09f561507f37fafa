//! The subcommands of `flexsens`.

pub mod check;
pub mod compare;
mod compute;
pub mod laminate;
pub mod modes;
pub mod optimize;
pub mod output;
pub mod report;
pub mod run;
mod run_files;
pub mod section;
pub(crate) mod sensitivity;
pub mod sweep;

/// How results are printed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Format {
    /// Aligned, human-readable tables.
    Table,
    /// One JSON document.
    Json,
    /// Long-format CSV: one value per row.
    Csv,
}
