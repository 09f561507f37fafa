//! `flexsens merge` of a sweep's shards: each shard's record read back, checked (every case
//! once, complete results) and gathered into one directory as a single sweep writes it.

use super::*;

/// One shard's record, read back by [`merge_shards`].
struct Shard {
    dir: PathBuf,
    manifest: Value,
    results: Vec<CaseResult>,
}

fn read_shard(dir: &Path, manifest: Value) -> Result<Shard, CliError> {
    let input = |m: String| CliError::Usage(format!("{}: {m}", dir.display()));
    let cases_text = crate::limits::read_text(&dir.join(CASES_FILE))
        .map_err(|e| input(format!("{CASES_FILE}: {e}")))?;
    let mut results = Vec::new();
    for (n, line) in cases_text.lines().enumerate() {
        let bad = |m: &str| input(format!("{CASES_FILE} line {}: {m}", n + 1));
        let v: Value = serde_json::from_str(line).map_err(|e| bad(&e.to_string()))?;
        let case = v["case"]
            .as_u64()
            .filter(|&c| c >= 1)
            .ok_or_else(|| bad("no case number"))? as usize;
        let outcome = match (&v["summary"], v["error"].as_str()) {
            (Value::Object(_), _) => Ok(v["summary"].clone()),
            (_, Some(e)) => Err(e.to_string()),
            _ => return Err(bad("neither a summary nor an error")),
        };
        results.push(CaseResult {
            index: case - 1,
            values: Vec::new(),
            outcome,
        });
    }
    Ok(Shard {
        dir: dir.to_path_buf(),
        manifest,
        results,
    })
}

/// Gather the shards of one sweep (written by `sweep --shard I/N`; their manifests read and
/// checked as one set of `n` by [`super::merge::merge`]) into `OUT` as a single-machine sweep would
/// have written it — the case directories moved to `OUT/case_NNN` and the same `summary.csv`,
/// byte for byte. The returned flag says whether every case ran.
pub(crate) fn merge_shards(
    dirs: &[PathBuf],
    manifests: Vec<Value>,
    n: usize,
    out: &Path,
) -> Result<(String, bool), CliError> {
    let shards = dirs
        .iter()
        .zip(manifests)
        .map(|(d, m)| read_shard(d, m))
        .collect::<Result<Vec<_>, _>>()?;
    let first = &shards[0];
    let vary = manifest_strings(&first.manifest, "vary");
    let Plan { axes, n_cases } = plan(&vary)?;
    if first.manifest["cases"].as_u64() != Some(n_cases as u64) {
        return Err(usage(format!(
            "{}: the shard's case count does not match its --vary ranges",
            first.dir.display()
        )));
    }
    check_case_results(&shards, n, n_cases, out)?;
    // every case once, from the shard it belongs to
    let mut merged: Vec<Option<CaseResult>> = (0..n_cases).map(|_| None).collect();
    for s in shards {
        let i = s.manifest["shard"][0].as_u64().unwrap_or(0) as usize;
        let expected = shard_cases(n_cases, Some((i, n)));
        let got: Vec<usize> = s.results.iter().map(|r| r.index).collect();
        if got != expected {
            return Err(usage(format!(
                "{}: shard {i}/{n} holds {} of its {} cases (interrupted? run it again)",
                s.dir.display(),
                got.len(),
                expected.len()
            )));
        }
        for mut r in s.results {
            let name = case_name(r.index, n_cases);
            let (from, to) = (s.dir.join(&name), out.join(&name));
            // the same directory however spelled (`-o` naming a shard's own directory)
            let same = match (std::fs::canonicalize(&from), std::fs::canonicalize(&to)) {
                (Ok(f), Ok(t)) => f == t,
                _ => from == to,
            };
            if !same && from.exists() {
                if to.exists() {
                    std::fs::remove_dir_all(&to).map_err(|e| CliError::File {
                        action: "remove the old",
                        path: to.clone(),
                        reason: e.to_string(),
                    })?;
                }
                std::fs::create_dir_all(out).map_err(|e| CliError::File {
                    action: "create the output directory",
                    path: out.to_path_buf(),
                    reason: e.to_string(),
                })?;
                move_dir(&from, &to).map_err(|e| CliError::File {
                    action: "move",
                    path: from.clone(),
                    reason: format!("{e} (into {})", to.display()),
                })?;
            }
            r.values = case_values(&axes, r.index);
            let index = r.index;
            merged[index] = Some(r);
        }
    }
    let results: Vec<CaseResult> = merged.into_iter().flatten().collect();
    let csv = summary_csv(&axes, &results, &|i| out.join(case_name(i, n_cases)));
    let summary_path = out.join("summary.csv");
    write_atomic(&summary_path, csv.as_bytes())?;
    let failed = results.iter().filter(|r| r.outcome.is_err()).count();
    Ok((
        format!(
            "{n} shards, {} cases ({failed} failed); summary: {}\n",
            results.len(),
            summary_path.display()
        ),
        failed == 0,
    ))
}

/// Before anything moves: every case a shard lists as run has its complete results
/// (`results.h5`), in its shard's directory or — merged before into `out` — there; a case
/// whose directory is gone or incomplete is named with its shard (exit 1).
fn check_case_results(
    shards: &[Shard],
    n: usize,
    n_cases: usize,
    out: &Path,
) -> Result<(), CliError> {
    for s in shards {
        let i = s.manifest["shard"][0].as_u64().unwrap_or(0);
        for r in s.results.iter().filter(|r| r.outcome.is_ok()) {
            let name = case_name(r.index, n_cases);
            let (from, to) = (s.dir.join(&name), out.join(&name));
            let complete = |d: &Path| d.join("results.h5").is_file();
            if !complete(&from) && !complete(&to) {
                return Err(CliError::Runtime(format!(
                    "{}: case {} of shard {i}/{n} ran, but neither {} nor {} holds its complete \
                     results (results.h5): its directory was removed, moved by a merge into \
                     another directory, or cut short; run the shard again",
                    s.dir.display(),
                    r.index + 1,
                    from.display(),
                    to.display()
                )));
            }
        }
    }
    Ok(())
}
