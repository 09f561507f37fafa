//! `flexsens run`: the dynamic analysis of the deck's mechanism and, when the deck declares
//! design variables, the direct sensitivities of every response, objectives with gradients
//! and finite-difference comparisons (`commands/sensitivity.rs`); written as a result file (HDF5)
//! and CSV tables.

use std::path::{Path, PathBuf};

use super::compute::{Computed, compute};
use super::run_files::{gradients_csv, history_csv, results, sensitivities_csv};
use super::run_summary::{summary, summary_text};
use super::shard::remove_old;
use crate::deck::{self, Source};
use crate::error::CliError;
use crate::files::{DirLock, Staged, remove_stale_partials};
use crate::progress::RunProgress;
use crate::study::Mechanism;

/// What `flexsens run` was asked for.
pub struct RunRequest<'a> {
    /// Output directory (default: `<deck stem>.out` beside the deck).
    pub out: Option<&'a Path>,
    /// A one-line JSON summary on stdout instead of the table.
    pub json: bool,
    /// A progress bar on stderr for runs longer than a second.
    pub progress: bool,
}

/// The output files a run may write; those a run does not write are removed, so that a
/// directory never mixes two runs.
pub(crate) const OUTPUT_FILES: [&str; 4] = [
    "history.csv",
    "sensitivities.csv",
    "gradients.csv",
    "results.h5",
];

/// Run the command; the returned text goes to stdout.
pub fn run(path: &Path, overrides: &[String], req: &RunRequest) -> Result<String, CliError> {
    let (src, raw) = deck::load(path, overrides)?;
    let mech = Mechanism::validate(&src, &raw, true)?;
    let progress = req.progress.then(|| {
        let t_end = *mech.times.last().expect("output times");
        RunProgress::new(mech.times[0], t_end)
    });
    let out = req
        .out
        .map(Path::to_path_buf)
        .unwrap_or_else(|| super::default_dir(path, "out", None));
    let _lock = DirLock::acquire(&out, "run")?;
    let done = run_study(&src, &mech, &out, progress.as_ref())?;
    if req.json {
        return Ok(done.summary.to_string() + "\n");
    }
    Ok(summary_text(
        &mech,
        &done.computed,
        &done.summary,
        &done.written,
    ))
}

/// A finished run: what it computed, its summary (the JSON of `--json`) and the files it
/// wrote.
pub(crate) struct Done {
    pub(crate) computed: Computed,
    pub(crate) summary: serde_json::Value,
    pub(crate) written: Vec<PathBuf>,
}

/// Run the study `mech` (of the deck `src`) into the directory `out`: the old run's files
/// removed first, every file written under a temporary name and committed once all are
/// encoded, `results.h5` last (its presence means the run completed).
pub(crate) fn run_study(
    src: &Source,
    mech: &Mechanism,
    out: &Path,
    progress: Option<&RunProgress>,
) -> Result<Done, CliError> {
    // a failed run must not leave the previous run's files looking like its own, nor a killed
    // one its temporary files
    std::fs::create_dir_all(out).map_err(|e| CliError::File {
        action: "create the output directory",
        path: out.to_path_buf(),
        reason: e.to_string(),
    })?;
    remove_stale_partials(out, &OUTPUT_FILES);
    for f in OUTPUT_FILES {
        remove_old(&out.join(f))?;
    }
    let computed = compute(src, mech, progress);
    if let Some(p) = progress {
        p.finish();
    }
    let computed = computed?;
    let g = results(src, mech, &computed);
    let bytes = g
        .to_hdf5()
        .map_err(|e| CliError::Runtime(format!("cannot encode the results: {e}")))?;
    // every file is written under a temporary name first: a failure (a full disk) leaves none
    let mut files = vec![(
        out.join("history.csv"),
        history_csv(mech, &computed).into_bytes(),
    )];
    if let Some(csv) = sensitivities_csv(mech, &computed) {
        files.push((out.join("sensitivities.csv"), csv.into_bytes()));
    }
    if !computed.objectives.is_empty() {
        files.push((
            out.join("gradients.csv"),
            gradients_csv(mech, &computed).into_bytes(),
        ));
    }
    // results.h5 last: its presence means the run completed
    files.push((out.join("results.h5"), bytes));
    let staged = files
        .iter()
        .map(|(path, bytes)| Staged::new(path, bytes))
        .collect::<Result<Vec<_>, _>>()?;
    for s in staged {
        s.commit()?;
    }
    let written: Vec<PathBuf> = files.into_iter().map(|(path, _)| path).collect();
    let summary = summary(src, mech, &computed, out);
    Ok(Done {
        computed,
        summary,
        written,
    })
}
