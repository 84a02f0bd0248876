//! Fitting a scene to this machine: the particle size at which the window keeps real time.
//!
//! The cost of one simulated second goes as 1/r³: the particles as 1/r², the steps as 1/r
//! (the CFL step is proportional to the spacing at a given speed). From the pace measured at
//! radius r (simulated seconds per wall second spent stepping: the pace the window shows is
//! held to real time, so it cannot say how much faster a scene could go), the pace at r' is
//! then about
//! `pace · (r'/r)³`, and the radius that keeps [`TARGET_PACE`] is
//! `r · (TARGET_PACE / pace)^(1/3)`. That ignores what does not scale so (drawing, a
//! step's fixed costs, fewer iterations in a smaller tank's solve), so the window measures
//! again after a change, and if it is still slow fits once more with the exponent the two
//! measurements show ([`measured_exponent`]), at most [`MAX_FITS`] times.
//!
//! Only the built-in scene the window opens with is fitted by itself; a scene the user
//! chose keeps its resolution, and the HUD offers the keys instead ([`FINER_KEY`],
//! [`COARSER_KEY`]), which change the radius by [`KEY_FACTOR`] (half or twice the
//! particles, about).

/// Below this pace (simulated seconds per wall second of stepping, over
/// [`MEASURE_SECONDS`]) the window fits the scene to the machine: the stepping needs
/// headroom over real time, as the drawing shares the cores.
pub const FIT_BELOW_PACE: f64 = 1.2;

/// How the pace grows with the radius before anything is measured: `pace ∝ r^3`.
pub const COST_EXPONENT: f64 = 3.0;

/// The pace a fitted scene aims at: headroom over real time for the drawing, splashes (more
/// iterations a step) and the pointer tools.
pub const TARGET_PACE: f64 = 1.5;

/// Wall seconds of stepping the pace is measured over (after [`SETTLE_SECONDS`]).
pub const MEASURE_SECONDS: f64 = 2.0;

/// Wall seconds left out at the start of a measurement: the first frames build the window,
/// the thread pool and the caches.
pub const SETTLE_SECONDS: f64 = 0.5;

/// Fits after which the window stops trying (the scene stays as the last fit left it).
pub const MAX_FITS: u32 = 3;

/// Radius factor of one press of [`FINER_KEY`] or [`COARSER_KEY`]: 2^(1/2), half or twice
/// the particles.
pub const KEY_FACTOR: f64 = std::f64::consts::SQRT_2;

/// The key that makes the particles smaller (more of them).
pub const FINER_KEY: &str = "]";
/// The key that makes the particles larger (fewer of them).
pub const COARSER_KEY: &str = "[";

/// The radius (m) at which a scene measured at `pace` with particles of `radius` should
/// keep [`TARGET_PACE`] if the pace goes as `r^exponent`, within `limits` (the scene's
/// allowed radii, [`dfsph::Scene::particle_radius_limits`]); `None` when it keeps real
/// time already or cannot be made coarser. Rounded up to two significant digits (a radius
/// a user can read and type).
pub fn radius_for_pace(radius: f64, pace: f64, exponent: f64, limits: (f64, f64)) -> Option<f64> {
    if !(pace.is_finite() && radius > 0.0) || pace >= FIT_BELOW_PACE {
        return None;
    }
    let wanted = radius * (TARGET_PACE / pace.max(1e-6)).powf(1.0 / exponent);
    let fitted = round_up_2_digits(wanted).min(limits.1);
    (fitted > radius).then_some(fitted)
}

/// The exponent k of `pace ∝ r^k` that two measurements `(radius, pace)` show, within
/// [1, [`COST_EXPONENT`]]: at least as cautious as the model, never more than linear.
pub fn measured_exponent(a: (f64, f64), b: (f64, f64)) -> f64 {
    let k = (b.1 / a.1).ln() / (b.0 / a.0).ln();
    if k.is_finite() {
        k.clamp(1.0, COST_EXPONENT)
    } else {
        COST_EXPONENT
    }
}

/// The radius one key press away: `finer` divides by [`KEY_FACTOR`], otherwise multiplies,
/// rounded to two significant digits, within `limits`; `None` at a limit.
pub fn radius_after_key(radius: f64, finer: bool, limits: (f64, f64)) -> Option<f64> {
    let next = if finer {
        round_2_digits(radius / KEY_FACTOR).max(limits.0)
    } else {
        round_2_digits(radius * KEY_FACTOR).min(limits.1)
    };
    (next != radius && next > 0.0).then_some(next)
}

/// The particle count as the HUD says it: `2,000`.
pub fn thousands(n: usize) -> String {
    let digits = n.to_string();
    let mut out = String::new();
    for (i, c) in digits.chars().enumerate() {
        if i > 0 && (digits.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}

fn round_2_digits(x: f64) -> f64 {
    let scale = 10f64.powi(1 - x.log10().floor() as i32);
    (x * scale).round() / scale
}

fn round_up_2_digits(x: f64) -> f64 {
    let scale = 10f64.powi(1 - x.log10().floor() as i32);
    // A hair under the next step is that step: no 0.0130000001 from rounding noise.
    ((x * scale) - 1e-9).ceil() / scale
}

#[cfg(test)]
mod tests {
    use super::*;

    const LIMITS: (f64, f64) = (0.001, 0.5);

    #[test]
    fn a_slow_scene_gets_the_radius_whose_pace_is_the_target() {
        // Measured at 0.4x real time with r = 1 cm: the cost scales as 1/r³, so
        // r' = 0.01·(1.5/0.4)^(1/3) = 0.01554 → 0.016 m.
        let r = radius_for_pace(0.01, 0.4, COST_EXPONENT, LIMITS).unwrap();
        assert_eq!(r, 0.016);
        // The pace that radius predicts reaches the target.
        assert!(0.4 * (r / 0.01f64).powi(3) >= TARGET_PACE);
        // Ten times too slow: about 2.3 times the radius, 5 times fewer particles.
        assert_eq!(
            radius_for_pace(0.01, 0.13, COST_EXPONENT, LIMITS),
            Some(0.023)
        );
        // Where the pace was seen to grow only as r²: (1.5/0.4)^(1/2) = 1.94 times.
        assert_eq!(radius_for_pace(0.01, 0.4, 2.0, LIMITS), Some(0.02));
    }

    #[test]
    fn a_scene_in_real_time_or_at_its_coarsest_is_left_alone() {
        let fit = |r, pace| radius_for_pace(r, pace, COST_EXPONENT, LIMITS);
        assert_eq!(fit(0.01, FIT_BELOW_PACE), None);
        assert_eq!(fit(0.01, 2.0), None);
        assert_eq!(fit(0.01, f64::NAN), None);
        // The tank allows no coarser particles.
        assert_eq!(fit(0.5, 0.2), None);
        // Capped at the coarsest the tank allows.
        assert_eq!(fit(0.3, 0.05), Some(0.5));
    }

    #[test]
    fn the_exponent_comes_from_two_measurements() {
        // Paces 0.29 at r = 1 cm and 0.95 at 1.8 cm: the pace grew as r^2.0, not r^3.
        let k = measured_exponent((0.01, 0.29), (0.018, 0.95));
        assert!((k - 2.02).abs() < 0.01, "{k}");
        assert_eq!(measured_exponent((0.01, 0.3), (0.02, 0.31)), 1.0);
        assert_eq!(measured_exponent((0.01, 0.1), (0.02, 10.0)), COST_EXPONENT);
        assert_eq!(measured_exponent((0.01, 0.3), (0.01, 0.4)), COST_EXPONENT);
    }

    #[test]
    fn keys_halve_or_double_the_particles_within_the_limits() {
        assert_eq!(radius_after_key(0.01, true, LIMITS), Some(0.0071));
        assert_eq!(radius_after_key(0.01, false, LIMITS), Some(0.014));
        assert_eq!(radius_after_key(0.001, true, LIMITS), None);
        assert_eq!(radius_after_key(0.5, false, LIMITS), None);
        assert_eq!(radius_after_key(0.45, false, LIMITS), Some(0.5));
    }

    #[test]
    fn counts_read_with_thousands_separators() {
        assert_eq!(thousands(0), "0");
        assert_eq!(thousands(999), "999");
        assert_eq!(thousands(2000), "2,000");
        assert_eq!(thousands(1234567), "1,234,567");
    }
}
