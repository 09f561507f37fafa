//! Sharding for batch systems, shared by `flexsens sweep` and `flexsens optimize`: which cases
//! (or starts) shard `I/N` runs, the manifest each shard writes beside its cases, and the
//! checks and file moves of `flexsens merge` ([`super::merge`]).

use std::path::{Path, PathBuf};

use serde_json::Value;

use crate::error::CliError;
use crate::files::write_atomic;

fn usage(m: impl Into<String>) -> CliError {
    CliError::Usage(m.into())
}

/// `--shard I/N`: the I-th (1-based) of N slices.
pub(crate) fn parse_shard(arg: &str) -> Result<(usize, usize), CliError> {
    let bad = || {
        usage(format!(
            "--shard {arg}: expected I/N with 1 ≤ I ≤ N (e.g. --shard 2/8, or \
             --shard $SLURM_ARRAY_TASK_ID/$SLURM_ARRAY_TASK_COUNT)"
        ))
    };
    let (i, n) = arg.split_once('/').ok_or_else(bad)?;
    let (i, n) = (
        i.trim().parse::<usize>().map_err(|_| bad())?,
        n.trim().parse::<usize>().map_err(|_| bad())?,
    );
    if i == 0 || i > n {
        return Err(bad());
    }
    Ok((i, n))
}

/// The cases (0-based) of shard `i` of `n`: every n-th case from the (i−1)-th, so that each
/// shard gets a share of every part of the ranges (costs often grow along an axis).
pub(crate) fn shard_cases(n_cases: usize, shard: Option<(usize, usize)>) -> Vec<usize> {
    match shard {
        None => (0..n_cases).collect(),
        Some((i, n)) => (i - 1..n_cases).step_by(n).collect(),
    }
}

/// Remove `path` if it is there (an earlier run's file), naming it when that fails.
pub(crate) fn remove_old(path: &Path) -> Result<(), CliError> {
    match std::fs::remove_file(path) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(CliError::File {
            action: "remove the old",
            path: path.to_path_buf(),
            reason: e.to_string(),
        }),
        _ => Ok(()),
    }
}

/// What a shard writes beside its cases for `flexsens merge`.
pub(crate) const SHARD_FILE: &str = "shard.json";

/// A fingerprint of a deck's text (64-bit FNV-1a, hexadecimal): shards run on decks that differ
/// are not merged.
pub(crate) fn deck_fingerprint(text: &str) -> String {
    let hash = text.bytes().fold(0xcbf2_9ce4_8422_2325_u64, |h, b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    });
    format!("{hash:016x}")
}

/// Write shard `(i, n)`'s manifest (`shard.json`) into `out`: the command, the version, the
/// deck's absolute path and the fingerprint of its text as the shard read it (`deck_text`),
/// its `--set` arguments and the command's own `extra` fields. Written last, after the
/// shard's record: a shard that has it is complete.
pub(crate) fn write_manifest(
    out: &Path,
    command: &str,
    (path, deck_text): (&Path, &str),
    overrides: &[String],
    (i, n): (usize, usize),
    extra: Value,
) -> Result<(), CliError> {
    let mut manifest = serde_json::json!({
        "command": command,
        "flexsens_version": env!("CARGO_PKG_VERSION"),
        "deck": std::fs::canonicalize(path)
            .unwrap_or_else(|_| path.to_path_buf())
            .display()
            .to_string(),
        "deck_fingerprint": deck_fingerprint(deck_text),
        "set": overrides,
        "shard": [i, n],
    });
    if let (Value::Object(m), Value::Object(e)) = (&mut manifest, extra) {
        m.extend(e);
    }
    write_atomic(
        &out.join(SHARD_FILE),
        (serde_json::to_string_pretty(&manifest).expect("JSON") + "\n").as_bytes(),
    )
}

/// A shard's manifest (`shard.json`).
pub(crate) fn read_manifest(dir: &Path) -> Result<Value, CliError> {
    let input = |m: String| CliError::Usage(format!("{}: {m}", dir.display()));
    let text = crate::limits::read_text(&dir.join(SHARD_FILE)).map_err(|e| {
        input(format!(
            "not a shard of a sweep or an optimisation ({SHARD_FILE}: {e}; shards are written \
             by `flexsens sweep --shard I/N` and `flexsens optimize --shard I/N`)"
        ))
    })?;
    serde_json::from_str(&text).map_err(|e| input(format!("{SHARD_FILE} is not valid JSON: {e}")))
}

/// Check that `manifests` are all N shards of one sweep or optimisation, each once; returns N.
pub(crate) fn check_shard_set(dirs: &[PathBuf], manifests: &[Value]) -> Result<usize, CliError> {
    let first = &manifests[0];
    for key in [
        "command",
        "deck",
        "deck_fingerprint",
        "set",
        "vary",
        "cases",
        "starts",
        "flexsens_version",
    ] {
        if let Some(k) = manifests.iter().position(|m| m[key] != first[key]) {
            let why = if key == "deck_fingerprint" {
                format!(
                    "the deck {} changed between them: run every shard on one version of it",
                    first["deck"].as_str().unwrap_or("?")
                )
            } else {
                format!(
                    "their `{key}` differ: {} against {}",
                    first[key], manifests[k][key]
                )
            };
            return Err(usage(format!(
                "{} and {} are shards of different runs ({why})",
                dirs[0].display(),
                dirs[k].display()
            )));
        }
    }
    let n = first["shard"][1].as_u64().unwrap_or(0) as usize;
    if n == 0 || n > dirs.len() {
        // incomplete whatever the rest says: name the first shard missing (without sizing
        // anything by the file's count)
        let given: Vec<u64> = manifests
            .iter()
            .filter_map(|m| m["shard"][0].as_u64())
            .collect();
        let missing = (1..).find(|i| !given.contains(i)).unwrap_or(1);
        return Err(usage(format!(
            "shard {missing}/{n} is missing: give the directories of all {n} shards"
        )));
    }
    let mut seen = vec![None::<&Path>; n];
    for (dir, m) in dirs.iter().zip(manifests) {
        let i = m["shard"][0].as_u64().unwrap_or(0) as usize;
        let ni = m["shard"][1].as_u64().unwrap_or(0) as usize;
        if ni != n || i == 0 || i > n {
            return Err(usage(format!(
                "{}: shard {i}/{ni} does not belong to a run of {n} shards",
                dir.display()
            )));
        }
        if let Some(other) = seen[i - 1].replace(dir) {
            return Err(usage(format!(
                "{} and {} are both shard {i}/{n}",
                other.display(),
                dir.display()
            )));
        }
    }
    if let Some(missing) = seen.iter().position(Option::is_none) {
        return Err(usage(format!(
            "shard {}/{n} is missing: give the directories of all {n} shards",
            missing + 1
        )));
    }
    Ok(n)
}

/// The strings of the array `key` of a shard manifest (its `--vary` or `--set` arguments).
pub(crate) fn manifest_strings(manifest: &Value, key: &str) -> Vec<String> {
    manifest[key]
        .as_array()
        .map(|a| {
            a.iter()
                .filter_map(|v| v.as_str().map(String::from))
                .collect()
        })
        .unwrap_or_default()
}

/// Move a directory, or copy it and remove the original where a rename cannot (another file
/// system).
pub(crate) fn move_dir(from: &Path, to: &Path) -> std::io::Result<()> {
    if std::fs::rename(from, to).is_ok() {
        return Ok(());
    }
    fn copy(from: &Path, to: &Path) -> std::io::Result<()> {
        std::fs::create_dir_all(to)?;
        for entry in std::fs::read_dir(from)? {
            let entry = entry?;
            let target = to.join(entry.file_name());
            if entry.file_type()?.is_dir() {
                copy(&entry.path(), &target)?;
            } else {
                std::fs::copy(entry.path(), target)?;
            }
        }
        Ok(())
    }
    copy(from, to)?;
    std::fs::remove_dir_all(from)
}
