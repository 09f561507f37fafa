//! Writing output files so that an interrupted or failed run never leaves one that looks
//! complete: everything is written to a temporary name in the same directory and renamed when
//! complete ([`write_atomic`]); a command that writes several files stages them all first and
//! renames them only once every one is written ([`Staged`]), so that a failure (a full disk)
//! leaves none of them. A target that exists and is not a regular file (a named pipe,
//! `/dev/null`, `/dev/stdout`) is written into directly, never replaced.

use std::io::Write;
use std::path::{Path, PathBuf};

use crate::error::CliError;

/// The lock file of an output directory ([`DirLock`]).
pub const LOCK_FILE: &str = ".flexsens.lock";

/// The output directories this process holds: a command nested in another (the optimum's run
/// inside `optimize`) writing into a directory its caller holds takes no second lock.
static HELD: std::sync::Mutex<std::collections::BTreeSet<PathBuf>> =
    std::sync::Mutex::new(std::collections::BTreeSet::new());

/// An advisory lock on an output directory, held while a command writes there: a second
/// flexsens writing into the same directory fails at once (exit 1) naming the holder, instead
/// of mixing its files with the first's. The lock is on `DIR/.flexsens.lock` (which holds the
/// holder's process id and command, and stays after it), released when dropped or when the
/// process ends, however it ends. On a file system without locks the command writes unguarded.
pub struct DirLock {
    _file: Option<std::fs::File>,
    held: Option<PathBuf>,
}

impl DirLock {
    /// Lock `dir` (created if needed) for `command`.
    pub fn acquire(dir: &Path, command: &str) -> Result<DirLock, CliError> {
        std::fs::create_dir_all(dir).map_err(|e| failure(dir, "create the output directory", e))?;
        let key = std::fs::canonicalize(dir).unwrap_or_else(|_| dir.to_path_buf());
        let mut held = HELD.lock().unwrap_or_else(|e| e.into_inner());
        if held.contains(&key) {
            return Ok(DirLock {
                _file: None,
                held: None,
            });
        }
        let path = dir.join(LOCK_FILE);
        let mut file = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(&path)
            .map_err(|e| failure(&path, "open the lock file", e))?;
        match file.try_lock() {
            Ok(()) => {}
            Err(std::fs::TryLockError::WouldBlock) => {
                let holder = std::fs::read_to_string(&path).unwrap_or_default();
                let holder = holder.trim();
                return Err(CliError::Runtime(format!(
                    "{}: another flexsens is writing into this directory ({}); wait for it to \
                     finish, or write elsewhere (-o)",
                    dir.display(),
                    if holder.is_empty() {
                        "its process is not recorded".to_string()
                    } else {
                        format!("process {holder}")
                    }
                )));
            }
            // a file system without locks (some network ones): write without the guard rather
            // than refuse to write at all
            Err(std::fs::TryLockError::Error(_)) => {
                return Ok(DirLock {
                    _file: None,
                    held: None,
                });
            }
        }
        // the holder, for the message of a second writer
        let _ = file
            .set_len(0)
            .and_then(|_| writeln!(file, "{} (flexsens {command})", std::process::id()));
        held.insert(key.clone());
        Ok(DirLock {
            _file: Some(file),
            held: Some(key),
        })
    }
}

impl Drop for DirLock {
    fn drop(&mut self) {
        if let Some(key) = &self.held {
            HELD.lock().unwrap_or_else(|e| e.into_inner()).remove(key);
        }
    }
}

/// The prefix of the temporary names of `name` (`.NAME.partial-`), followed by the process id.
fn partial_prefix(name: &str) -> String {
    format!(".{name}.partial-")
}

/// The temporary name used while `path` is being written.
fn partial_name(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!("{}{}", partial_prefix(&name), std::process::id()))
}

fn failure(path: &Path, action: &'static str, e: std::io::Error) -> CliError {
    CliError::File {
        action,
        path: path.to_path_buf(),
        reason: e.to_string(),
    }
}

/// Whether `path` exists and is something other than a regular file (or a link to one).
fn special(path: &Path) -> bool {
    std::fs::metadata(path).is_ok_and(|m| !m.is_file() && !m.is_dir())
}

/// An output file written under its temporary name, waiting for [`Staged::commit`]; dropped
/// without a commit, the temporary file is removed.
pub struct Staged {
    path: PathBuf,
    /// The temporary file, or `None` for a target written into directly at the commit.
    tmp: Option<PathBuf>,
    /// The bytes for a direct write.
    direct: Option<Vec<u8>>,
}

impl Staged {
    /// Write `bytes` to a temporary name beside `path` (creating the directory), flushed to
    /// disk.
    pub fn new(path: &Path, bytes: &[u8]) -> Result<Self, CliError> {
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir)
                .map_err(|e| failure(path, "create the directory of", e))?;
        }
        if std::fs::metadata(path).is_ok_and(|m| m.is_dir()) {
            return Err(CliError::File {
                action: "write",
                path: path.to_path_buf(),
                reason: "it is a directory".into(),
            });
        }
        if special(path) {
            return Ok(Self {
                path: path.to_path_buf(),
                tmp: None,
                direct: Some(bytes.to_vec()),
            });
        }
        let tmp = partial_name(path);
        let staged = Self {
            path: path.to_path_buf(),
            tmp: Some(tmp.clone()),
            direct: None,
        };
        let written = (|| {
            let mut f = std::fs::File::create(&tmp)?;
            f.write_all(bytes)?;
            f.sync_all()
        })();
        // on an error `staged` is dropped, which removes the temporary file
        written.map_err(|e| failure(path, "write", e))?;
        Ok(staged)
    }

    /// Give the file its name.
    pub fn commit(mut self) -> Result<(), CliError> {
        if let Some(bytes) = self.direct.take() {
            return std::fs::OpenOptions::new()
                .write(true)
                .open(&self.path)
                .and_then(|mut f| f.write_all(&bytes))
                .map_err(|e| failure(&self.path, "write", e));
        }
        let tmp = self.tmp.take().expect("a staged file has a temporary name");
        std::fs::rename(&tmp, &self.path).map_err(|e| {
            let _ = std::fs::remove_file(&tmp);
            failure(&self.path, "write", e)
        })
    }
}

impl Drop for Staged {
    fn drop(&mut self) {
        if let Some(tmp) = self.tmp.take() {
            let _ = std::fs::remove_file(tmp);
        }
    }
}

/// Write `bytes` to `path` atomically (temporary file, flush, rename); a target that is not a
/// regular file is written into.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), CliError> {
    Staged::new(path, bytes)?.commit()
}

/// Remove the temporary files of `names` in `dir` left by processes that no longer run (a
/// run that was killed). Only where the process table can be read (`/proc`); errors are
/// ignored, as the files are harmless.
pub fn remove_stale_partials(dir: &Path, names: &[&str]) {
    let proc_fs = Path::new("/proc");
    if !proc_fs.join("self").exists() {
        return;
    }
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let file = entry.file_name().to_string_lossy().into_owned();
        let pid = names
            .iter()
            .find_map(|n| file.strip_prefix(&partial_prefix(n)))
            .and_then(|p| p.parse::<u32>().ok());
        if let Some(pid) = pid
            && pid != std::process::id()
            && !proc_fs.join(pid.to_string()).exists()
        {
            let _ = std::fs::remove_file(entry.path());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn staged_files_appear_only_when_committed() {
        let dir = tempfile::tempdir().unwrap();
        let a = dir.path().join("sub/a.csv");
        let staged = Staged::new(&a, b"1,2\n").unwrap();
        assert!(!a.exists());
        staged.commit().unwrap();
        assert_eq!(std::fs::read(&a).unwrap(), b"1,2\n");
        // dropped without a commit: nothing is left, not even the temporary file
        drop(Staged::new(&dir.path().join("b.csv"), b"x").unwrap());
        let names: Vec<_> = std::fs::read_dir(dir.path().join("sub"))
            .unwrap()
            .chain(std::fs::read_dir(dir.path()).unwrap())
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names.len(), 2, "{names:?}"); // sub/a.csv and sub
    }

    /// As `flexsens run` stages its files: when one cannot be written (here its name is taken
    /// by a directory; a full disk fails the same way), those staged before it are removed
    /// and none appears.
    #[test]
    fn a_failure_while_staging_leaves_none_of_the_files() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("results.h5")).unwrap();
        let files: [(&str, &[u8]); 2] = [("history.csv", b"t\n0\n"), ("results.h5", b"HDF5..")];
        let staged = files
            .iter()
            .map(|(name, bytes)| Staged::new(&dir.path().join(name), bytes))
            .collect::<Result<Vec<_>, _>>();
        assert!(staged.is_err());
        let left: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        assert_eq!(
            left,
            vec!["results.h5".to_string()],
            "only the directory is left"
        );
    }

    #[test]
    fn a_named_pipe_is_written_into_not_replaced() {
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("pipe");
        let made = std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .is_ok_and(|s| s.success());
        if !made {
            return; // no mkfifo on this system
        }
        let reader = {
            let fifo = fifo.clone();
            std::thread::spawn(move || std::fs::read(fifo).unwrap())
        };
        write_atomic(&fifo, b"abc").unwrap();
        assert_eq!(reader.join().unwrap(), b"abc");
        let m = std::fs::metadata(&fifo).unwrap();
        assert!(!m.is_file(), "the pipe is still a pipe");
    }

    #[test]
    fn a_directory_is_not_a_file_to_write() {
        let dir = tempfile::tempdir().unwrap();
        let e = write_atomic(dir.path(), b"x").unwrap_err().to_string();
        assert!(e.contains("it is a directory"), "{e}");
    }

    #[test]
    fn stale_temporary_files_of_dead_processes_are_removed() {
        let dir = tempfile::tempdir().unwrap();
        // a process id above the kernel's maximum (4194304) never runs
        let dead = dir.path().join(".results.h5.partial-4294967295");
        let mine = dir
            .path()
            .join(format!(".results.h5.partial-{}", std::process::id()));
        let other = dir.path().join(".notes.txt.partial-4294967295");
        for p in [&dead, &mine, &other] {
            std::fs::write(p, b"x").unwrap();
        }
        remove_stale_partials(dir.path(), &["results.h5"]);
        if Path::new("/proc/self").exists() {
            assert!(!dead.exists());
        }
        assert!(mine.exists() && other.exists());
    }
}
