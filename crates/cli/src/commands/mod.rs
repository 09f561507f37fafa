//! The subcommands of `flexsens`.

mod adjoint;
pub mod check;
pub mod compare;
mod compute;
pub(crate) mod dual_chunks;
mod eigenvector_adjoint;
pub mod laminate;
pub mod merge;
pub mod modes;
pub mod operating;
pub mod optimize;
pub mod output;
mod ply_stress;
pub mod report;
pub mod run;
mod run_files;
mod run_summary;
pub mod section;
pub(crate) mod sensitivity;
mod shard;
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

std::thread_local! {
    /// Whether this thread is one of several workers of a [`parallel_map`] (a sweep's cases, an
    /// optimisation's starts): the work inside it then runs on it alone.
    static SHARED_WORKER: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// The number of parallel jobs: `requested`, or the available cores (one inside a worker of a
/// parallel [`parallel_map`], whose siblings already use the others); at least 1, at most `n`.
pub(crate) fn job_count(requested: Option<usize>, n: usize) -> usize {
    requested
        .unwrap_or_else(|| {
            if SHARED_WORKER.with(|w| w.get()) {
                1
            } else {
                std::thread::available_parallelism().map_or(1, |c| c.get())
            }
        })
        .clamp(1, n.max(1))
}

/// `work(j)` for every `j` in `0..n` on `jobs` threads, each thread taking the next `j` when it
/// has finished one; the results in `j` order.
pub(crate) fn parallel_map<T: Send>(
    n: usize,
    jobs: usize,
    work: impl Fn(usize) -> T + Sync,
) -> Vec<T> {
    use std::sync::Mutex;
    use std::sync::atomic::{AtomicUsize, Ordering};
    let next = AtomicUsize::new(0);
    let results: Vec<Mutex<Option<T>>> = (0..n).map(|_| Mutex::new(None)).collect();
    let workers = jobs.clamp(1, n.max(1));
    std::thread::scope(|scope| {
        for _ in 0..workers {
            scope.spawn(|| {
                SHARED_WORKER.with(|w| w.set(workers > 1));
                loop {
                    let j = next.fetch_add(1, Ordering::SeqCst);
                    if j >= n {
                        break;
                    }
                    let r = work(j);
                    *results[j].lock().expect("no poisoned lock") = Some(r);
                }
            });
        }
    });
    results
        .into_iter()
        .map(|m| {
            m.into_inner()
                .expect("no poisoned lock")
                .expect("every job ran")
        })
        .collect()
}

/// A command's default output directory beside the deck: `<deck stem>.<kind>`, and for shard
/// `I/N` `<deck stem>.<kind>.shard-I-of-N`.
pub(crate) fn default_dir(
    deck: &std::path::Path,
    kind: &str,
    shard: Option<(usize, usize)>,
) -> std::path::PathBuf {
    let stem = deck
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "flexsens".into());
    let suffix = shard.map_or(String::new(), |(i, n)| format!(".shard-{i}-of-{n}"));
    deck.with_file_name(format!("{stem}.{kind}{suffix}"))
}

#[cfg(test)]
mod tests {
    use super::{job_count, parallel_map};

    #[test]
    fn work_inside_parallel_workers_runs_on_one_thread() {
        let cores = std::thread::available_parallelism().map_or(1, |c| c.get());
        assert_eq!(job_count(None, 64), cores.min(64));
        // several workers: nested work takes one thread each, unless asked for more
        assert_eq!(parallel_map(3, 2, |_| job_count(None, 64)), [1, 1, 1]);
        assert_eq!(parallel_map(2, 2, |_| job_count(Some(3), 64)), [3, 3]);
        // a single worker leaves the machine to the work inside it
        assert_eq!(
            parallel_map(2, 1, |_| job_count(None, 64)),
            [cores.min(64); 2]
        );
        // results in order
        assert_eq!(parallel_map(5, 2, |j| j * j), [0, 1, 4, 9, 16]);
    }
}
