//! The progress bar of long runs: on stderr, shown only after a second, only on a terminal and
//! without `--quiet`; it never touches stdout or the result files.

use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, OnceLock};
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// Bar resolution.
const TICKS: u64 = 1000;

struct Inner {
    start: Instant,
    t0: f64,
    t_end: f64,
    /// Integrations of the run (the analysis, then each finite-difference run).
    phases: AtomicUsize,
    phase: AtomicUsize,
    /// Highest position reached (ticks).
    position: AtomicU64,
    bar: OnceLock<ProgressBar>,
}

/// Progress of one `flexsens run`: its integrations from `t0` to `t_end` one after the other.
#[derive(Clone)]
pub(crate) struct RunProgress(Arc<Inner>);

impl RunProgress {
    pub(crate) fn new(t0: f64, t_end: f64) -> Self {
        Self(Arc::new(Inner {
            start: Instant::now(),
            t0,
            t_end,
            phases: AtomicUsize::new(1),
            phase: AtomicUsize::new(0),
            position: AtomicU64::new(0),
            bar: OnceLock::new(),
        }))
    }

    /// The observer to hand to the integrated system.
    pub(crate) fn observer(&self) -> mbs::Progress {
        let inner = self.0.clone();
        Arc::new(move |t: f64| inner.update(t))
    }

    /// `n` more integrations follow.
    pub(crate) fn add_phases(&self, n: usize) {
        self.0.phases.fetch_add(n, Ordering::SeqCst);
    }

    /// The next integration starts.
    pub(crate) fn next_phase(&self) {
        self.0.phase.fetch_add(1, Ordering::SeqCst);
    }

    /// Remove the bar (the run is over, whatever its outcome).
    pub(crate) fn finish(&self) {
        if let Some(b) = self.0.bar.get() {
            b.finish_and_clear();
        }
    }
}

impl Inner {
    fn update(&self, t: f64) {
        let span = (self.t_end - self.t0).max(f64::MIN_POSITIVE);
        let within = ((t - self.t0) / span).clamp(0.0, 1.0);
        let phases = self.phases.load(Ordering::SeqCst).max(1) as f64;
        let phase = self.phase.load(Ordering::SeqCst) as f64;
        let ticks = (((phase + within) / phases).min(1.0) * TICKS as f64) as u64;
        let before = self.position.fetch_max(ticks, Ordering::SeqCst);
        if ticks <= before || self.start.elapsed() < Duration::from_secs(1) {
            return;
        }
        let bar = self.bar.get_or_init(|| {
            let b = ProgressBar::with_draw_target(Some(TICKS), ProgressDrawTarget::stderr());
            b.set_style(
                ProgressStyle::with_template("{elapsed:>4} [{bar:40}] {percent:>3}% eta {eta}")
                    .expect("a valid template")
                    .progress_chars("=> "),
            );
            b
        });
        bar.set_position(ticks);
    }
}
