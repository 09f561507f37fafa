//! The `flexsens` binary: command line → commands → exit codes (see the library docs).

use std::io::{IsTerminal, Write};
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};

use clap::{Parser, Subcommand};

use flexsens::commands::{self, Format};
use flexsens::error::CliError;
use flexsens::limits::{self, Limits};

#[derive(Parser)]
#[command(
    name = "flexsens",
    version,
    allow_negative_numbers = true,
    about = "Flexible multibody dynamics of composite mechanisms with exact design sensitivities"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
    /// Override a deck value by its dotted path before reading it, e.g.
    /// `--set laminate.rod.plies.0.angle=30` (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE", global = true)]
    set: Vec<String>,
    /// No progress reports on stderr.
    #[arg(long, short = 'q', global = true)]
    quiet: bool,
    /// Largest mesh accepted, in elements (also per direction of a generated mesh).
    #[arg(long, value_name = "N", global = true, default_value_t = Limits::DEFAULT.elements,
          value_parser = limits::parse_count)]
    max_elements: usize,
    /// Largest number of time steps of a fixed-step run, or step attempts of an adaptive one.
    #[arg(long, value_name = "N", global = true, default_value_t = Limits::DEFAULT.steps,
          value_parser = limits::parse_count)]
    max_steps: usize,
    /// Largest number of cases of a sweep.
    #[arg(long, value_name = "N", global = true, default_value_t = Limits::DEFAULT.cases,
          value_parser = limits::parse_count)]
    max_cases: usize,
    /// Largest input file (deck, mesh, result file) read, in bytes.
    #[arg(long, value_name = "BYTES", global = true, default_value_t = Limits::DEFAULT.input_bytes,
          value_parser = limits::parse_bytes)]
    max_input_bytes: u64,
    /// Largest memory an analysis may need by its estimate, in bytes (a cross-section's
    /// warping analysis: about 32 KiB per element; a beam body's modal analysis 16 KiB, a
    /// shell body's 24 KiB per element).
    #[arg(long, value_name = "BYTES", global = true, default_value_t = Limits::DEFAULT.memory,
          value_parser = limits::parse_bytes)]
    max_memory: u64,
}

#[derive(Subcommand)]
enum Command {
    /// Plate stiffness (A, B, D, transverse shear) and inertia of the deck's laminates.
    #[command(allow_negative_numbers = true)]
    Laminate {
        /// The deck (TOML).
        deck: PathBuf,
        /// Only this laminate (default: all).
        #[arg(long, value_name = "NAME")]
        laminate: Option<String>,
        /// Output format.
        #[arg(long, value_enum, default_value_t = Format::Table)]
        format: Format,
        /// Also print the derivatives with respect to each ply angle (per radian), or to each
        /// [design.*] variable that moves the laminate (per its unit).
        #[arg(long)]
        derivatives: bool,
        /// Plate resultants to load the laminate with, `NAME=VALUE` (repeatable or
        /// comma-separated; NAME one of Nx, Ny, Nxy, Qx, Qy in N/m and Mx, My, Mxy in N):
        /// prints each ply's stresses and strains and, for plies whose material has strengths,
        /// their failure indices and the least reserve factor per criterion (with
        /// --derivatives, their derivatives too, the reserve factors aside).
        #[arg(long = "load", value_name = "NAME=VALUE", allow_hyphen_values = true)]
        load: Vec<String>,
    },
    /// Cross-section analysis of the deck's beam sections: 6×6 Timoshenko stiffness, classical
    /// stiffness, mass properties, tension and shear centres.
    #[command(allow_negative_numbers = true)]
    Section {
        /// The deck (TOML).
        deck: PathBuf,
        /// Only this section (default: all).
        #[arg(long, value_name = "NAME")]
        section: Option<String>,
        /// Output format.
        #[arg(long, value_enum, default_value_t = Format::Table)]
        format: Format,
        /// Also print the derivatives with respect to each ply (region) angle, per radian, or
        /// to each [design.*] variable that moves the section (per its unit).
        #[arg(long)]
        derivatives: bool,
        /// Section forces to load the section with, `NAME=VALUE` (repeatable or
        /// comma-separated; NAME one of F1, F2, F3 in N and M1, M2, M3 in N·m, about the
        /// section's origin): prints each region's stress extremes in its material axes and,
        /// for regions whose material has strengths, their failure indices and the least
        /// reserve factor per criterion (with --derivatives, the extremes' and indices'
        /// derivatives too).
        #[arg(long = "load", value_name = "NAME=VALUE", allow_hyphen_values = true)]
        load: Vec<String>,
    },
    /// Vibration modes of the deck's flexible bodies: frequencies, modal masses, damping, and
    /// their ply-angle derivatives (updated-mode, Nelson's method).
    #[command(allow_negative_numbers = true)]
    Modes {
        /// The deck (TOML).
        deck: PathBuf,
        /// Only this body (default: all).
        #[arg(long, value_name = "NAME")]
        body: Option<String>,
        /// Output format.
        #[arg(long, value_enum, default_value_t = Format::Table)]
        format: Format,
        /// Also print the derivatives of the frequencies with respect to each ply angle, or to
        /// each [design.*] variable (per its unit).
        #[arg(long)]
        derivatives: bool,
        /// Write the mesh and mode shapes as a legacy VTK file (ParaView); needs one body.
        #[arg(long, value_name = "FILE")]
        vtk: Option<PathBuf>,
        /// Write K, M (and dK per design variable with --derivatives) in Matrix Market format,
        /// with the dof map, into this directory.
        #[arg(long, value_name = "DIR")]
        export_matrices: Option<PathBuf>,
    },
    /// Simulate the deck's mechanism and write `results.h5` and `history.csv`.
    #[command(allow_negative_numbers = true)]
    Run {
        /// The deck (TOML).
        deck: PathBuf,
        /// Output directory (default: `<deck name>.out` beside the deck).
        #[arg(short = 'o', long = "output", value_name = "DIR")]
        output: Option<PathBuf>,
        /// Print a one-line JSON summary (for scripts) instead of the table.
        #[arg(long)]
        json: bool,
    },
    /// The static equilibrium of the deck's mechanism, or its steady spins at the [operating]
    /// speeds: the modes linearised about each (frequencies, damping ratios), the responses
    /// and their design derivatives there, a Campbell diagram of a speed sweep; written to
    /// `operating.csv`, `frequencies.csv`, `sensitivities.csv` and `campbell.svg`/`.png`.
    /// With `[operating] at = [t, …]`, the run's states at those times instead (frozen-time
    /// modes in the bodies' moving frames).
    #[command(allow_negative_numbers = true)]
    Static {
        /// The deck (TOML).
        deck: PathBuf,
        /// Output directory (default: `<deck name>.static` beside the deck).
        #[arg(short = 'o', long = "output", value_name = "DIR")]
        output: Option<PathBuf>,
        /// Print a JSON summary (for scripts) instead of the table.
        #[arg(long)]
        json: bool,
        /// Also write each flexible body's mesh and mode shapes at each operating point as
        /// legacy VTK files, `modes_I_BODY.vtk` (ParaView).
        #[arg(long)]
        vtk: bool,
    },
    /// Run a deck for every combination of varied values (in parallel) and write one row per
    /// case, with its objectives and gradients, to `DIR/summary.csv`.
    #[command(allow_negative_numbers = true)]
    Sweep {
        /// The deck (TOML).
        deck: PathBuf,
        /// A deck value to vary: `KEY=START:STEP:END` (inclusive) or `KEY=V1,V2,…`; `KEY` is a
        /// dotted deck path as for --set, or `design.NAME` for a design variable (repeatable;
        /// all combinations are run).
        #[arg(long, value_name = "KEY=VALUES", required = true)]
        vary: Vec<String>,
        /// Output directory (default: `<deck name>.sweep` beside the deck); case `i` is written
        /// to `DIR/case_00i`.
        #[arg(short = 'o', long = "output", value_name = "DIR")]
        output: Option<PathBuf>,
        /// Number of cases run at once (default: the number of cores).
        #[arg(short = 'j', long, value_name = "N")]
        jobs: Option<usize>,
        /// Run only the I-th of N deterministic slices of the cases (every N-th case from the
        /// I-th), e.g. one task of a Slurm job array; gather the shards with `flexsens merge`.
        #[arg(long, value_name = "I/N")]
        shard: Option<String>,
    },
    /// Optimise the deck's [design.*] variables for its [optimize] problem (SLSQP with exact
    /// gradients): writes the optimum deck, iterations.csv, convergence plots and the
    /// optimum's run into DIR; Ctrl-C stops and writes the best feasible design so far.
    #[command(allow_negative_numbers = true)]
    Optimize {
        /// The deck (TOML) with [design.*] variables (with lower, upper) and [optimize].
        deck: PathBuf,
        /// Output directory (default: `<deck name>.optimize` beside the deck).
        #[arg(short = 'o', long = "output", value_name = "DIR")]
        output: Option<PathBuf>,
        /// Starts run at once (default: the number of cores).
        #[arg(short = 'j', long, value_name = "N")]
        jobs: Option<usize>,
        /// Run only the I-th of N deterministic slices of the starts (every N-th from the
        /// I-th), e.g. one task of a Slurm job array; gather the shards with `flexsens merge`.
        #[arg(long, value_name = "I/N")]
        shard: Option<String>,
    },
    /// Gather the shards of a sweep or an optimisation (`--shard I/N`, each in its own
    /// directory) into one directory, exactly as a run on one machine would have written it.
    #[command(allow_negative_numbers = true)]
    Merge {
        /// The shards' output directories (all N shards of one sweep).
        #[arg(required = true, value_name = "SHARD_DIR")]
        shards: Vec<PathBuf>,
        /// The merged sweep's directory (its case directories are moved there).
        #[arg(short = 'o', long = "output", value_name = "DIR", required = true)]
        output: PathBuf,
    },
    /// Regenerate the paper's §5 figures (mid-node deflection, direct sensitivities against
    /// finite differences, fixed against updated modes) for several lay-ups, as SVG and PNG,
    /// with a summary (summary.md, summary.json).
    #[command(allow_negative_numbers = true)]
    Report {
        /// The deck (TOML): one [design.*] variable (the lay-up angle) and a
        /// mid-node-deflection response.
        deck: PathBuf,
        /// Lay-ups: comma-separated values of the deck's first design variable, degrees.
        #[arg(
            long,
            value_name = "ANGLES",
            default_value = "0,15,30",
            allow_hyphen_values = true
        )]
        layups: String,
        /// Output directory (default: `<deck name>.report` beside the deck).
        #[arg(short = 'o', long = "output", value_name = "DIR")]
        output: Option<PathBuf>,
        /// Step of the fixed-step runs, s (default: a tenth of the output step).
        #[arg(long, value_name = "SECONDS")]
        fixed_step: Option<f64>,
        /// Runs at once (default: the available cores).
        #[arg(short = 'j', long, value_name = "N")]
        jobs: Option<usize>,
    },
    /// Validate a deck without running it: keys, values, names, meshes, modal analyses, and
    /// the assembly of the mechanism (redundant joint equations are reported).
    #[command(allow_negative_numbers = true)]
    Check {
        /// The deck (TOML).
        deck: PathBuf,
    },
    /// Compare two result files dataset by dataset (golden-file checks): exit code 1 on a
    /// mismatch, listing the largest differences with their dataset and time.
    #[command(allow_negative_numbers = true)]
    Compare {
        /// The result file to check.
        a: PathBuf,
        /// The reference result file.
        b: PathBuf,
        /// Relative tolerance: |a − b| ≤ atol + rtol |b|.
        #[arg(long, default_value_t = 1e-6)]
        rtol: f64,
        /// Absolute tolerance.
        #[arg(long, default_value_t = 1e-12)]
        atol: f64,
    },
}

/// faer's worker threads (its sparse factorisations) cost more than they give on small
/// machines (measured on 2 cores: a 20 000-element section 17 % slower in wall time, a
/// 98 000-dof shell 5 %) and oversubscribe the cores that `-j` gives to parallel cases, so
/// they are off unless FLEXSENS_SOLVER_THREADS asks for them (docs/performance.md).
fn set_solver_threads() {
    let threads = std::env::var("FLEXSENS_SOLVER_THREADS")
        .ok()
        .and_then(|v| v.parse::<usize>().ok())
        .unwrap_or(1);
    faer::set_global_parallelism(if threads > 1 {
        faer::Par::rayon(threads)
    } else {
        faer::Par::Seq
    });
}

/// The limits of the command line for this process.
fn set_limits(cli: &Cli) {
    limits::set(Limits {
        elements: cli.max_elements,
        steps: cli.max_steps,
        cases: cli.max_cases,
        input_bytes: cli.max_input_bytes,
        memory: cli.max_memory,
    });
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    set_solver_threads();
    set_limits(&cli);
    // text for stdout and the exit code, or an error
    let result: Result<(String, u8), CliError> = match &cli.command {
        Command::Laminate {
            deck,
            laminate,
            format,
            derivatives,
            load,
        } => commands::laminate::run(
            deck,
            &cli.set,
            laminate.as_deref(),
            *format,
            (*derivatives, load),
        )
        .map(|t| (t, 0)),
        Command::Section {
            deck,
            section,
            format,
            derivatives,
            load,
        } => commands::section::run(
            deck,
            &cli.set,
            section.as_deref(),
            *format,
            (*derivatives, load),
        )
        .map(|t| (t, 0)),
        Command::Modes {
            deck,
            body,
            format,
            derivatives,
            vtk,
            export_matrices,
        } => {
            let req = commands::modes::ModesRequest {
                only: body.as_deref(),
                format: *format,
                derivatives: *derivatives,
                vtk: vtk.as_deref(),
                export_matrices: export_matrices.as_deref(),
            };
            commands::modes::run(deck, &cli.set, &req).map(|t| (t, 0))
        }
        Command::Run { deck, output, json } => {
            let req = commands::run::RunRequest {
                out: output.as_deref(),
                json: *json,
                progress: !cli.quiet && std::io::stderr().is_terminal(),
            };
            commands::run::run(deck, &cli.set, &req).map(|t| (t, 0))
        }
        Command::Static {
            deck,
            output,
            json,
            vtk,
        } => {
            let req = commands::operating::StaticRequest {
                out: output.as_deref(),
                json: *json,
                vtk: *vtk,
            };
            commands::operating::run(deck, &cli.set, &req).map(|t| (t, 0))
        }
        Command::Sweep {
            deck,
            vary,
            output,
            jobs,
            shard,
        } => {
            let req = commands::sweep::SweepRequest {
                vary,
                out: output.as_deref(),
                jobs: *jobs,
                quiet: cli.quiet,
                shard: shard.as_deref(),
            };
            commands::sweep::run(deck, &cli.set, &req).map(|(t, ok)| (t, if ok { 0 } else { 1 }))
        }
        Command::Optimize {
            deck,
            output,
            jobs,
            shard,
        } => {
            let stop: &'static AtomicBool = Box::leak(Box::new(AtomicBool::new(false)));
            // Ctrl-C (or a termination signal) stops the optimiser, which writes its best
            // design; a second one ends the process at once
            let _ = ctrlc::set_handler(move || {
                if stop.swap(true, Ordering::SeqCst) {
                    std::process::exit(130);
                }
            });
            let req = commands::optimize::OptimizeRequest {
                out: output.as_deref(),
                jobs: *jobs,
                quiet: cli.quiet,
                stop,
                shard: shard.as_deref(),
            };
            commands::optimize::run(deck, &cli.set, &req)
        }
        Command::Merge { shards, output } => {
            commands::merge::merge(shards, output).map(|(t, ok)| (t, if ok { 0 } else { 1 }))
        }
        Command::Report {
            deck,
            layups,
            output,
            fixed_step,
            jobs,
        } => {
            let req = commands::report::ReportRequest {
                out: output.as_deref(),
                layups,
                fixed_step: *fixed_step,
                jobs: *jobs,
            };
            commands::report::run(deck, &cli.set, &req).map(|t| (t, 0))
        }
        Command::Check { deck } => commands::check::run(deck, &cli.set).map(|t| (t, 0)),
        Command::Compare { a, b, rtol, atol } => commands::compare::run(a, b, *rtol, *atol)
            .map(|(text, same)| (text, if same { 0 } else { 1 })),
    };
    match result {
        Ok((text, code)) => {
            // a closed pipe (e.g. `| head`) is not an error worth a panic
            let _ = std::io::stdout().write_all(text.as_bytes());
            ExitCode::from(code)
        }
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(e.exit_code())
        }
    }
}
