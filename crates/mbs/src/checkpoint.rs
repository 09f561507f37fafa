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
//! sweep, going backwards, recomputes a dropped segment's states from its snapshot with the
//! same integrator steps: one more analysis at most (of the dropped part), the memory at most
//! the budget plus one segment.

use std::collections::VecDeque;

use crate::adjoint::StepHistory;
use crate::bdf::{BdfOptions, BdfSnapshot, OdeSystem, Statistics};
use crate::model::State;
use crate::sensitivity::{SensitivityError, interpolation};
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
    /// The recomputed states of a segment: `(its index, its states)`.
    loaded: Option<(usize, Vec<Vec<f64>>)>,
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

    fn states_of(&self, s: usize) -> Option<&Vec<Vec<f64>>> {
        match &self.loaded {
            Some((l, states)) if *l == s => Some(states),
            _ => self.segments[s].states.as_ref(),
        }
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

    /// Recompute segment `s`'s states from its snapshot (the loaded segment replaced).
    fn recompute(&mut self, sys: &mut MultibodySystem, s: usize) -> Result<(), SensitivityError> {
        let n = sys.dim();
        if let Some((_, states)) = self.loaded.take() {
            self.bytes -= 8 * n * states.len();
        }
        let seg = &self.segments[s];
        let progress = sys.take_progress();
        let result = (|| {
            let mut bdf = seg.snapshot.restore(sys)?;
            let mut states = Vec::with_capacity(seg.len);
            for m in 1..=seg.len {
                bdf.step(sys, self.t_end)?;
                let (t, y) = bdf.current();
                if t != self.times[seg.start + m] {
                    return Err(SensitivityError::Recomputation(format!(
                        "the recomputation from the checkpoint at t = {} reached t = {t} \
                         instead of the run's t = {}",
                        seg.snapshot.time(),
                        self.times[seg.start + m]
                    )));
                }
                states.push(y.to_vec());
            }
            Ok(states)
        })();
        sys.set_progress(progress);
        let states = result?;
        self.memory.recomputed_steps += states.len();
        self.bytes += 8 * n * states.len();
        self.memory.peak_bytes = self.memory.peak_bytes.max(self.bytes);
        self.loaded = Some((s, states));
        Ok(())
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
        if i > self.segments[s].start && self.states_of(s).is_none() {
            self.recompute(sys, s)?;
        }
        Ok(())
    }

    /// # Panics
    /// If point `i` is not readable: [`StepHistory::load`] makes the points it needs so.
    fn state(&self, i: usize) -> &[f64] {
        let s = self.segment_of(i);
        let seg = &self.segments[s];
        if i > seg.start
            && let Some(states) = self.states_of(s)
        {
            return &states[i - seg.start - 1];
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
    let n = y0.len();
    let mut bdf = crate::bdf::Bdf::new(bdf_options);
    bdf.init(sys, t0, &y0)?;
    let mut run = CheckpointedRun {
        n_q: sys.model().n_q(),
        times: vec![t0],
        orders: vec![0],
        statistics: Statistics::default(),
        t_end,
        segments: Vec::new(),
        loaded: None,
        bytes: 0,
        snapshot_bytes: 0,
        memory: CheckpointStatistics::default(),
    };
    // the recent states, most recent last, for the samples at the output times
    let mut window: VecDeque<Vec<f64>> = VecDeque::from([y0]);
    let mut outputs = Vec::with_capacity(t_out.len());
    let mut interval = FIRST_INTERVAL;
    loop {
        let i = run.times.len() - 1;
        while let Some(&t) = t_out.get(outputs.len())
            && t <= run.times[i]
        {
            let (p, w) = interpolation(&run.times, &run.orders, t);
            let mut y = vec![0.0; n];
            for (j, wj) in w.iter().enumerate() {
                let x = &window[window.len() - 1 - (i - p) - j];
                (y.iter_mut().zip(x)).for_each(|(a, b)| *a += wj * b);
            }
            outputs.push(y);
        }
        if bdf.current().0 >= t_end {
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
    Ok((run, outputs))
}
