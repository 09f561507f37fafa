//! A run recorded for the backward sweep within a memory budget: checkpoints of the
//! integrator every few steps, the states between them kept while the budget allows and
//! recomputed from their checkpoint, bitwise, when the sweep reaches them (docs/design.md §3,
//! "Checkpointing").
//!
//! The run is cut into segments, each beginning with a [`BdfSnapshot`] (its history of up to 8
//! states and its step control: about 12 state vectors). The states of a segment are kept as
//! the run goes; when the kept states and snapshots outgrow the budget, the oldest segments'
//! states are dropped, and when the snapshots alone outgrow half of it, every other snapshot
//! is dropped (two segments become one, and the segments made later are twice as long). The
//! sweep, going backwards, recomputes a dropped segment from its snapshot with the same
//! integrator steps, as a run of its own within half the budget (itself cut into segments
//! and recomputed the same way if its states outgrow that): each level of recomputation costs
//! at most one more analysis of the dropped part, and the memory stays within about twice the
//! budget, however long the run.

use std::collections::VecDeque;

use crate::adjoint::StepHistory;
use crate::bdf::{Bdf, BdfOptions, BdfSnapshot, OdeSystem, Statistics};
use crate::model::State;
use crate::sensitivity::{SensitivityError, interpolation, mix};
use crate::system::MultibodySystem;

/// Steps per segment at the start (doubled each time the snapshots are thinned).
const FIRST_INTERVAL: usize = 64;

/// Points an interpolated sample mixes (an order-5 formula's 6) and a step's formula reaches
/// back to.
const WINDOW: usize = 6;

/// A segment of the run: the snapshot at point `start`, and the states of points
/// `start + 1 ..= start + len` if kept.
struct Segment {
    start: usize,
    len: usize,
    snapshot: BdfSnapshot,
    states: Option<Vec<Vec<f64>>>,
}

/// How a [`CheckpointedRun`] used its memory.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CheckpointStatistics {
    /// Segments (snapshots) at the end of the run.
    pub segments: usize,
    /// Segments whose states were dropped during the run.
    pub dropped_segments: usize,
    /// Steps recomputed for the backward sweep (0 if every state was kept).
    pub recomputed_steps: usize,
    /// The largest memory the states and snapshots took (bytes), during the run or the
    /// sweep's recomputations.
    pub peak_bytes: usize,
}

/// The accepted steps of a run ([`simulate_checkpointed`]): the times and orders of every
/// step, and its states within a memory budget (module documentation); a
/// [`StepHistory`] for [`crate::adjoint_sweep`], which recomputes the dropped states.
pub struct CheckpointedRun {
    pub n_q: usize,
    /// `t_0, t_1, …` (the integrator's steps).
    pub times: Vec<f64>,
    /// Order of the step that ended at `times[i]` (0 for the initial point).
    pub orders: Vec<usize>,
    /// The forward run's integrator counters.
    pub statistics: Statistics,
    /// The end time the run stepped to (the steps' limit, needed to recompute them).
    t_end: f64,
    segments: Vec<Segment>,
    /// The budget of the kept states and snapshots (bytes).
    budget: usize,
    /// A dropped segment recomputed: `(its index, its steps as a run of their own)`.
    loaded: Option<(usize, Box<CheckpointedRun>)>,
    /// The loaded run's recomputed steps already counted.
    nested_recomputed: usize,
    /// The memory of the kept states, snapshots and loaded states (bytes).
    bytes: usize,
    /// The snapshots' part of it.
    snapshot_bytes: usize,
    memory: CheckpointStatistics,
}

impl CheckpointedRun {
    /// How the run used its memory (complete after the sweep).
    pub fn checkpoint_statistics(&self) -> CheckpointStatistics {
        CheckpointStatistics {
            segments: self.segments.len(),
            ..self.memory
        }
    }

    /// The segment holding point `i` (`start < i ≤ start + len`; the first for point 0).
    fn segment_of(&self, i: usize) -> usize {
        self.segments.partition_point(|s| s.start < i).max(1) - 1
    }

    /// Keep the states and snapshots within `budget`: the oldest segments' states dropped
    /// (never the last's, being filled), then every other snapshot if they alone take more
    /// than half.
    fn enforce(&mut self, budget: usize, n: usize, interval: &mut usize) {
        for s in 0..self.segments.len().saturating_sub(1) {
            if self.bytes <= budget {
                break;
            }
            if let Some(states) = self.segments[s].states.take() {
                self.bytes -= 8 * n * states.len();
                self.memory.dropped_segments += 1;
            }
        }
        if 2 * self.snapshot_bytes > budget && self.segments.len() > 2 {
            let old = std::mem::take(&mut self.segments);
            let last = old.len() - 1;
            let mut merged: Vec<Segment> = Vec::with_capacity(old.len() / 2 + 1);
            for (k, seg) in old.into_iter().enumerate() {
                // the last segment, being filled, stays on its own
                match merged.last_mut() {
                    Some(prev) if k % 2 == 1 && k != last => {
                        self.bytes -= seg.snapshot.bytes();
                        self.snapshot_bytes -= seg.snapshot.bytes();
                        prev.len += seg.len;
                        match (&mut prev.states, seg.states) {
                            (Some(a), Some(b)) => a.extend(b),
                            (a, b) => {
                                let lost =
                                    a.take().map_or(0, |a| a.len()) + b.map_or(0, |b| b.len());
                                self.bytes -= 8 * n * lost;
                            }
                        }
                    }
                    _ => merged.push(seg),
                }
            }
            self.segments = merged;
            *interval *= 2;
        }
    }

    /// Recompute segment `s` from its snapshot, as a run of its own within half the budget
    /// (itself checkpointed if its states outgrow it; the loaded segment replaced).
    fn recompute(&mut self, sys: &mut MultibodySystem, s: usize) -> Result<(), SensitivityError> {
        self.loaded = None;
        let seg = &self.segments[s];
        let progress = sys.take_progress();
        let result = (|| {
            let bdf = seg.snapshot.restore(sys)?;
            Self::record(sys, bdf, (self.t_end, seg.len), self.budget / 2, |_, _| {})
        })();
        sys.set_progress(progress);
        let nested = result?;
        let expected = &self.times[seg.start..=seg.start + seg.len];
        if nested.times != expected {
            let k = (nested.times.iter().zip(expected)).position(|(a, b)| a != b);
            return Err(SensitivityError::Recomputation(format!(
                "the steps from the checkpoint at t = {} differ from the run's{}",
                seg.snapshot.time(),
                k.map_or(String::new(), |k| format!(
                    " at t = {} (the run's t = {})",
                    nested.times[k], expected[k]
                ))
            )));
        }
        self.memory.recomputed_steps += seg.len;
        self.loaded = Some((s, Box::new(nested)));
        self.nested_recomputed = 0;
        self.note_nested();
        Ok(())
    }

    /// The peak and recomputed steps of the loaded segment's run taken into this one's.
    fn note_nested(&mut self) {
        if let Some((_, nested)) = &self.loaded {
            let inner = nested.memory;
            self.memory.peak_bytes = (self.memory.peak_bytes).max(self.bytes + inner.peak_bytes);
            self.memory.recomputed_steps += inner.recomputed_steps - self.nested_recomputed;
            self.nested_recomputed = inner.recomputed_steps;
        }
    }

    /// The steps of `bdf` from its current point, to `t_end` or for `steps` steps, its states
    /// kept within `budget` (module documentation); `sample(run, window)` called at every
    /// point with the run so far and its last states (up to 6, the current one last).
    fn record(
        sys: &mut MultibodySystem,
        mut bdf: Bdf,
        (t_end, steps): (f64, usize),
        budget: usize,
        mut sample: impl FnMut(&CheckpointedRun, &VecDeque<Vec<f64>>),
    ) -> Result<CheckpointedRun, SensitivityError> {
        let (t0, y0) = bdf.current();
        let n = y0.len();
        let mut run = CheckpointedRun {
            n_q: sys.model().n_q(),
            times: vec![t0],
            orders: vec![0],
            statistics: Statistics::default(),
            t_end,
            budget,
            segments: Vec::new(),
            loaded: None,
            nested_recomputed: 0,
            bytes: 0,
            snapshot_bytes: 0,
            memory: CheckpointStatistics::default(),
        };
        let mut window: VecDeque<Vec<f64>> = VecDeque::from([y0.to_vec()]);
        let mut interval = FIRST_INTERVAL;
        loop {
            sample(&run, &window);
            let i = run.times.len() - 1;
            if bdf.current().0 >= t_end || i >= steps {
                break;
            }
            if run.segments.last().is_none_or(|s| s.len >= interval) {
                let snapshot = bdf.snapshot();
                run.bytes += snapshot.bytes();
                run.snapshot_bytes += snapshot.bytes();
                run.segments.push(Segment {
                    start: i,
                    len: 0,
                    snapshot,
                    states: Some(Vec::new()),
                });
            }
            bdf.step(sys, t_end)?;
            let st = bdf.last_step();
            run.times.push(st.times[0]);
            run.orders.push(st.order);
            let y = st.states[0].to_vec();
            let seg = run.segments.last_mut().expect("a segment");
            seg.len += 1;
            if let Some(states) = seg.states.as_mut() {
                states.push(y.clone());
                run.bytes += 8 * n;
            }
            window.push_back(y);
            if window.len() > WINDOW {
                window.pop_front();
            }
            run.memory.peak_bytes = run.memory.peak_bytes.max(run.bytes);
            run.enforce(budget, n, &mut interval);
        }
        run.statistics = bdf.statistics();
        Ok(run)
    }
}

impl StepHistory for CheckpointedRun {
    fn times(&self) -> &[f64] {
        &self.times
    }

    fn orders(&self) -> &[usize] {
        &self.orders
    }

    fn load(&mut self, sys: &mut MultibodySystem, i: usize) -> Result<(), SensitivityError> {
        let s = self.segment_of(i);
        // the sweep has passed the later segments: their kept or recomputed states go
        let n = sys.dim();
        for seg in &mut self.segments[s + 1..] {
            if let Some(states) = seg.states.take() {
                self.bytes -= 8 * n * states.len();
            }
        }
        if matches!(&self.loaded, Some((l, _)) if *l > s) {
            self.loaded = None;
        }
        let start = self.segments[s].start;
        if i <= start || self.segments[s].states.is_some() {
            return Ok(());
        }
        if !matches!(&self.loaded, Some((l, _)) if *l == s) {
            self.recompute(sys, s)?;
        }
        if let Some((_, nested)) = self.loaded.as_mut() {
            nested.load(sys, i - start)?;
        }
        self.note_nested();
        Ok(())
    }

    /// # Panics
    /// If point `i` is not readable: [`StepHistory::load`] makes the points it needs so.
    fn state(&self, i: usize) -> &[f64] {
        let s = self.segment_of(i);
        let seg = &self.segments[s];
        if i > seg.start {
            if let Some(states) = &seg.states {
                return &states[i - seg.start - 1];
            }
            if let Some((l, nested)) = &self.loaded
                && *l == s
            {
                return nested.state(i - seg.start);
            }
        }
        // the history of the first snapshot at or after point i
        let next = if i > seg.start { s + 1 } else { s };
        (self.segments.get(next))
            .and_then(|n| n.snapshot.history(n.start - i))
            .expect("a loaded state")
    }
}

/// Integrate from the (assembled) `state` at `t0` to `t_end` as [`crate::simulate_steps`]
/// does, keeping the states for the backward sweep within `budget` bytes (module
/// documentation), and the states at the output times `t_out` (within `[t0, t_end]`,
/// increasing): as [`crate::SensitivityRun::resample`] interpolates them, bitwise.
pub fn simulate_checkpointed(
    sys: &mut MultibodySystem,
    state: &State,
    (t0, t_end): (f64, f64),
    bdf_options: BdfOptions,
    t_out: &[f64],
    budget: usize,
) -> Result<(CheckpointedRun, Vec<Vec<f64>>), SensitivityError> {
    let increasing = t_out.windows(2).all(|w| w[0] <= w[1]);
    if !increasing || t_out.iter().any(|&t| !(t >= t0 && t <= t_end)) {
        return Err(SensitivityError::Layout(format!(
            "output times must be increasing within the run [{t0}, {t_end}]"
        )));
    }
    let y0 = state.to_vec();
    let mut bdf = Bdf::new(bdf_options);
    bdf.init(sys, t0, &y0)?;
    let mut outputs = Vec::with_capacity(t_out.len());
    let sample = |run: &CheckpointedRun, window: &VecDeque<Vec<f64>>| {
        // the outputs up to the current point: all mix it (p = i)
        let i = run.times.len() - 1;
        while let Some(&t) = t_out.get(outputs.len())
            && t <= run.times[i]
        {
            let (p, w) = interpolation(&run.times, &run.orders, t);
            outputs.push(mix(&w, |j| &window[window.len() - 1 - (i - p) - j]));
        }
    };
    let run = CheckpointedRun::record(sys, bdf, (t_end, usize::MAX), budget, sample)?;
    Ok((run, outputs))
}
