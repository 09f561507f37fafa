//! `flexsens merge SHARD_DIR… -o OUT`: gather the shards of one sweep or optimisation (written
//! with `--shard I/N`) into `OUT` as a single-machine run would have written it.

use std::path::{Path, PathBuf};

use super::shard::{check_shard_set, read_manifest};
use crate::error::CliError;

/// Merge the shards in `dirs` into `out`: all N of one sweep or optimisation (same deck, `--set`
/// and `--vary` or starts), each once. The returned flag says whether every case or start ran.
pub fn merge(dirs: &[PathBuf], out: &Path) -> Result<(String, bool), CliError> {
    if dirs.is_empty() {
        return Err(CliError::Usage("merge needs the shard directories".into()));
    }
    let manifests = dirs
        .iter()
        .map(|d| read_manifest(d))
        .collect::<Result<Vec<_>, _>>()?;
    let n = check_shard_set(dirs, &manifests)?;
    let _lock = crate::files::DirLock::acquire(out, "merge")?;
    if manifests[0]["command"] == "optimize" {
        return super::optimize::merge(dirs, &manifests, out).map(|(t, code)| (t, code == 0));
    }
    super::sweep::merge_shards(dirs, manifests, n, out)
}
