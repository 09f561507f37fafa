//! The `flexsens` binary: command line → commands → exit codes (see the library docs).

use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

use flexsens::commands::{self, Format};

#[derive(Parser)]
#[command(
    name = "flexsens",
    version,
    about = "Flexible multibody dynamics of composite mechanisms with exact design sensitivities"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
    /// Override a deck value by its dotted path before reading it, e.g.
    /// `--set laminate.rod.plies.0.angle=30` (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE", global = true)]
    set: Vec<String>,
}

#[derive(Subcommand)]
enum Command {
    /// Plate stiffness (A, B, D, transverse shear) and inertia of the deck's laminates.
    Laminate {
        /// The deck (TOML).
        deck: PathBuf,
        /// Only this laminate (default: all).
        #[arg(long, value_name = "NAME")]
        laminate: Option<String>,
        /// Output format.
        #[arg(long, value_enum, default_value_t = Format::Table)]
        format: Format,
        /// Also print the derivatives with respect to each ply angle (per radian).
        #[arg(long)]
        derivatives: bool,
    },
    /// Cross-section analysis of the deck's beam sections: 6×6 Timoshenko stiffness, classical
    /// stiffness, mass properties, tension and shear centres.
    Section {
        /// The deck (TOML).
        deck: PathBuf,
        /// Only this section (default: all).
        #[arg(long, value_name = "NAME")]
        section: Option<String>,
        /// Output format.
        #[arg(long, value_enum, default_value_t = Format::Table)]
        format: Format,
        /// Also print the derivatives with respect to each ply (region) angle, per radian.
        #[arg(long)]
        derivatives: bool,
    },
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match &cli.command {
        Command::Laminate {
            deck,
            laminate,
            format,
            derivatives,
        } => commands::laminate::run(deck, &cli.set, laminate.as_deref(), *format, *derivatives),
        Command::Section {
            deck,
            section,
            format,
            derivatives,
        } => commands::section::run(deck, &cli.set, section.as_deref(), *format, *derivatives),
    };
    match result {
        Ok(text) => {
            // a closed pipe (e.g. `| head`) is not an error worth a panic
            let _ = std::io::stdout().write_all(text.as_bytes());
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(2)
        }
    }
}
