//! When to take particle snapshots and when to stop, in simulated time.
//!
//! Steps have adaptive (CFL) lengths, so snapshot times are rarely hit exactly: snapshot `k`
//! is taken at the first step that reaches `k · every`. Simulated time is a sum of `f32`
//! steps, so a step that ends within 1 % of its own length short of a target counts as
//! reaching it (otherwise 0.02 s = 4 × 0.005 s could be missed by rounding and taken one
//! step late).

/// Has a step of length `dt` that ended at `time` reached `target`? The solver's rule,
/// which `Simulation::has_reached` applies too.
pub use dfsph::simulation::reached;

/// Snapshot times `every`, `2·every`, … (the snapshot at t = 0 is taken before stepping).
#[derive(Clone, Debug)]
pub struct SnapshotSchedule {
    every: f64,
    next: u64,
}

impl SnapshotSchedule {
    /// `every` in seconds, > 0.
    pub fn new(every: f64) -> Self {
        Self { every, next: 1 }
    }

    /// Call after each step: true when this step reached the next snapshot time. Snapshot
    /// times that the step jumped over are skipped (one snapshot per step at most).
    pub fn due(&mut self, time: f64, dt: f64) -> bool {
        if !reached(time, dt, self.next as f64 * self.every) {
            return false;
        }
        while reached(time, dt, self.next as f64 * self.every) {
            self.next += 1;
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(dt: f32, every: f64, until: f64) -> Vec<f64> {
        let mut s = SnapshotSchedule::new(every);
        let mut time = 0.0f64;
        let mut shots = vec![0.0];
        while !reached(time, dt as f64, until) {
            time += dt as f64;
            if s.due(time, dt as f64) {
                shots.push(time);
            }
        }
        shots
    }

    #[test]
    fn snapshots_on_exact_multiples_despite_f32_steps() {
        // 0.005f32 is slightly less than 0.005: 4 steps fall just short of 0.02.
        let shots = run(0.005, 0.02, 0.1);
        assert_eq!(shots.len(), 6, "{shots:?}");
        for (k, t) in shots.iter().enumerate() {
            assert!((t - 0.02 * k as f64).abs() < 1e-6, "{shots:?}");
        }
    }

    #[test]
    fn steps_longer_than_every_give_one_snapshot_each() {
        let shots = run(0.05, 0.02, 0.2);
        assert_eq!(shots.len(), 5, "{shots:?}");
    }

    #[test]
    fn first_step_past_the_target_is_taken() {
        let mut s = SnapshotSchedule::new(0.05);
        assert!(!s.due(0.03, 0.03));
        assert!(s.due(0.06, 0.03));
        assert!(!s.due(0.09, 0.03));
        assert!(s.due(0.12, 0.03));
    }
}
