//! Real-time pacing: each frame advances a fixed slice of simulated time with as many CFL
//! substeps as it takes, up to a wall-time budget. Past the budget the rest of the slice is
//! dropped, so simulated time slows down instead of the UI freezing.

use std::time::{Duration, Instant};

/// Simulated time per frame at time scale 1, s.
pub const FRAME_SLICE: f64 = 1.0 / 60.0;
/// Wall time a frame may spend stepping, before simulated time slows down.
pub const STEP_BUDGET: Duration = Duration::from_millis(12);

/// What one frame's stepping did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SliceReport {
    /// Solver steps taken.
    pub steps: u32,
    /// Simulated time advanced, s.
    pub simulated: f64,
    /// Simulated time that was owed but dropped because the budget ran out, s.
    pub dropped: f64,
    /// Wall time spent stepping.
    pub wall: Duration,
}

/// Carries the fraction of a slice that the last CFL step overshot into the next frame, and
/// smooths how much slower than asked the simulation runs.
#[derive(Clone, Debug)]
pub struct FrameClock {
    /// Simulated time still owed (negative: the last step ran ahead), s.
    owed: f64,
    /// Smoothed fraction of the asked-for simulated time actually simulated (1 = on pace).
    pace: f64,
}

impl Default for FrameClock {
    fn default() -> Self {
        Self {
            owed: 0.0,
            pace: 1.0,
        }
    }
}

impl FrameClock {
    /// Advance by `slice` seconds of simulated time: call `step` (which returns the Δt it
    /// took) until the slice is covered or `budget` of wall time is spent. At least one step
    /// is taken whenever time is owed.
    pub fn advance(
        &mut self,
        slice: f64,
        budget: Duration,
        mut step: impl FnMut() -> f64,
    ) -> SliceReport {
        let start = Instant::now();
        // Running ahead by more than a slice (a huge Δt) is not carried further.
        self.owed = self.owed.max(-slice) + slice;
        let mut report = SliceReport::default();
        while self.owed > 0.0 {
            if report.steps > 0 && start.elapsed() >= budget {
                report.dropped = self.owed;
                self.owed = 0.0;
                break;
            }
            let dt = step();
            report.steps += 1;
            if !(dt.is_finite() && dt > 0.0) {
                // A broken step must not spin this loop: give up on the slice.
                report.dropped = self.owed;
                self.owed = 0.0;
                break;
            }
            report.simulated += dt;
            self.owed -= dt;
        }
        report.wall = start.elapsed();
        if slice > 0.0 {
            let pace = ((slice - report.dropped) / slice).clamp(0.0, 1.0);
            self.pace += 0.1 * (pace - self.pace);
        }
        report
    }

    /// Smoothed ratio of simulated to asked-for time, 0–1.
    pub fn pace(&self) -> f64 {
        self.pace
    }

    /// Whether simulated time is running noticeably slower than asked.
    pub fn slowed(&self) -> bool {
        self.pace < 0.95
    }

    /// Forget the carry and the pace (after a reset or a pause).
    pub fn reset(&mut self) {
        *self = Self::default();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fast_steps_cover_the_slice_and_carry_the_overshoot() {
        let mut clock = FrameClock::default();
        let mut total = 0.0;
        let mut steps = 0;
        for _ in 0..600 {
            let r = clock.advance(FRAME_SLICE, Duration::from_secs(1), || 0.005);
            total += r.simulated;
            steps += r.steps;
            assert_eq!(r.dropped, 0.0);
        }
        // Ten seconds asked for, ten seconds simulated (to within one step).
        assert!((total - 10.0).abs() <= 0.005, "{total}");
        assert_eq!(steps, 2000);
        assert!(!clock.slowed());
    }

    #[test]
    fn slow_steps_stop_at_the_budget_and_slow_time_down() {
        let mut clock = FrameClock::default();
        for _ in 0..40 {
            let r = clock.advance(FRAME_SLICE, Duration::from_millis(3), || {
                std::thread::sleep(Duration::from_millis(2));
                0.001
            });
            assert!(r.steps >= 1 && r.steps < 16, "{r:?}");
            assert!(r.dropped > 0.0);
        }
        assert!(clock.slowed());
        assert!(clock.pace() < 0.5, "{}", clock.pace());
    }

    #[test]
    fn a_broken_step_does_not_hang() {
        let mut clock = FrameClock::default();
        let r = clock.advance(FRAME_SLICE, Duration::from_secs(5), || f64::NAN);
        assert_eq!(r.steps, 1);
        let r = clock.advance(FRAME_SLICE, Duration::from_secs(5), || 0.0);
        assert_eq!(r.steps, 1);
    }
}
