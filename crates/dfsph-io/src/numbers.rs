//! How numbers are written in the text outputs.
//!
//! The solver computes in single precision. Its clock and its statistics are double, but a
//! statistic that came from an `f32` (a speed, a density error) printed as `f64` carries
//! digits that mean nothing (`0.016135525521491362` for the `f32` 0.016135526). Times are
//! sums of thousands of steps, whose last bits are rounding (`0.30000000000000004`).

/// A simulated time (s) as the outputs write it: rounded to 12 significant digits. That
/// drops the rounding of summing steps in double precision and keeps nanoseconds in a run
/// of 1,000 s (a step is at least 10 µs by default).
pub fn seconds(t: f64) -> f64 {
    if t == 0.0 || !t.is_finite() {
        return t;
    }
    format!("{t:.11e}").parse().unwrap_or(t)
}

/// A statistic to the solver's own precision: the shortest decimal that reads back as the
/// same `f32` (7 significant digits at most).
pub fn single(x: f64) -> f32 {
    x as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn times_lose_the_rounding_of_their_sums_and_keep_nanoseconds() {
        let mut t = 0.0f64;
        for _ in 0..300 {
            t += 0.001;
        }
        assert_ne!(t.to_string(), "0.3", "the sum itself carries rounding: {t}");
        assert_eq!(seconds(t).to_string(), "0.3");
        assert_eq!(seconds(999.999999999).to_string(), "999.999999999");
        assert_eq!(seconds(0.0).to_string(), "0");
        assert_eq!(seconds(1.0e-7).to_string(), "0.0000001");
    }

    #[test]
    fn statistics_print_the_single_precision_value() {
        // A speed the solver computed, widened to f64 for StepStats.
        let speed = 0.016135525f32 as f64;
        assert_eq!(speed.to_string(), "0.016135524958372116");
        assert_eq!(single(speed).to_string(), "0.016135525");
    }
}
