//! How many iterations of each solve a step records.
//!
//! A solve's stopping rule runs on the device, so the host cannot know how many iterations
//! a step will take: it records iterations whose dispatch sizes the test before each writes,
//! zero once the solve has ended. Each recorded iteration costs even when it dispatches
//! nothing: the host encodes it, and the device processes the dispatch and the barrier around
//! it (five to eight dispatches an iteration). Recording every iteration up to the cap (100
//! by default, for each of the two solves) makes a step about a thousand dispatches, of which
//! a few dozen do work.
//!
//! [`Recording::Adaptive`] records what the last step needed with a margin instead, and the
//! device says, after the step, whether a solve was still going when the recorded
//! iterations ran out (`Control::div_unfinished`, `Control::den_unfinished`: the first
//! dispatch size of the iteration after the last one recorded). Such a step is run again
//! from the same input with every iteration of both solves recorded. The solves do the same
//! arithmetic in the same order either way, so the results are bit for bit those of
//! [`Recording::Every`]; only the work the host and the device spend on empty dispatches
//! changes.

use std::sync::atomic::{AtomicU64, Ordering};

/// How many iterations of each solve a step records.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Recording {
    /// Every iteration up to the solve's cap.
    Every,
    /// Twice the iterations the solve took in the last step, plus [`MARGIN`], at most the
    /// cap (every iteration in the first step); a step whose solve was still going after
    /// them is run again with every iteration recorded.
    #[default]
    Adaptive,
    /// This many iterations, at most the cap, every step (the same rerun when a solve
    /// needed more): for tests of the rerun.
    Fixed(u32),
}

/// Iterations recorded beyond twice the last step's.
pub const MARGIN: u32 = 8;

/// What the recording did since the backend started, for benchmarks and tests.
#[derive(Debug, Default)]
pub struct RecordingCounts {
    /// Steps taken on the device (each try of a step counts once).
    pub steps: AtomicU64,
    /// Steps run a second time because a solve needed more iterations than were recorded.
    pub reruns: AtomicU64,
    /// Iterations recorded, both solves, all runs.
    pub recorded: AtomicU64,
    /// Iterations the solves took, both solves, of the runs kept.
    pub taken: AtomicU64,
}

impl RecordingCounts {
    /// (steps, reruns, recorded iterations, iterations taken).
    pub fn read(&self) -> (u64, u64, u64, u64) {
        let get = |c: &AtomicU64| c.load(Ordering::Relaxed);
        (
            get(&self.steps),
            get(&self.reruns),
            get(&self.recorded),
            get(&self.taken),
        )
    }
}

/// Add `n` to `counter`.
pub(crate) fn count(counter: &AtomicU64, n: u64) {
    counter.fetch_add(n, Ordering::Relaxed);
}

/// The iterations to record for one solve whose cap is `cap`, after a step in which it took
/// `last` iterations (`None`: no step yet).
pub(crate) fn budget(recording: Recording, cap: u32, last: Option<u32>) -> u32 {
    match (recording, last) {
        (Recording::Adaptive, Some(last)) => cap.min(last.saturating_mul(2).saturating_add(MARGIN)),
        (Recording::Fixed(n), _) => cap.min(n),
        _ => cap,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_budget_is_twice_the_last_plus_the_margin_within_the_cap() {
        assert_eq!(budget(Recording::Adaptive, 100, None), 100);
        assert_eq!(budget(Recording::Adaptive, 100, Some(5)), 18);
        assert_eq!(budget(Recording::Adaptive, 100, Some(60)), 100);
        assert_eq!(budget(Recording::Adaptive, 0, Some(3)), 0);
        assert_eq!(budget(Recording::Every, 100, Some(5)), 100);
        assert_eq!(budget(Recording::Fixed(1), 100, None), 1);
        assert_eq!(budget(Recording::Fixed(200), 100, Some(5)), 100);
    }
}
