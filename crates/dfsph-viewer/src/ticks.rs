//! Axis ticks of the HUD's plots and the colour bar: a round step for a range, the marks at
//! its multiples that fit an axis, and their labels.

use egui_plot::{GridInput, GridMark};

/// egui_plot's default `grid_spacing` minimum, points: `GridInput::base_step_size` is this
/// many points in plot units.
const GRID_INPUT_POINTS: f64 = 8.0;

/// The smallest "nice" step (1, 2 or 5 × 10ⁿ) at least `raw`; 1 for nonsense.
pub fn nice_step(raw: f64) -> f64 {
    if !(raw.is_finite() && raw > 0.0) {
        return 1.0;
    }
    let decade = 10f64.powf(raw.log10().floor());
    let m = raw / decade;
    let f = [1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .find(|f| m <= f * (1.0 + 1e-9))
        .unwrap_or(10.0);
    f * decade
}

/// Ticks at multiples of a nice step across `lo`–`hi`, at least `min_points` apart on an
/// axis `points` long. Empty for an empty or degenerate axis.
pub fn ticks(lo: f64, hi: f64, points: f64, min_points: f64) -> Vec<GridMark> {
    let span = hi - lo;
    if !(span > 0.0 && span.is_finite() && points > 0.0) {
        return Vec::new();
    }
    let step = nice_step(span * min_points.max(1.0) / points);
    let first = (lo / step - 1e-9).ceil() as i64;
    let last = (hi / step + 1e-9).floor() as i64;
    (first..=last.min(first + 1000))
        .map(|k| GridMark {
            value: k as f64 * step,
            step_size: step,
        })
        .collect()
}

/// [`ticks`] for egui_plot's grid, from what it tells a grid spacer.
pub(crate) fn grid_marks(g: GridInput, min_points: f32) -> Vec<GridMark> {
    let (lo, hi) = g.bounds;
    let points = (hi - lo) * GRID_INPUT_POINTS / g.base_step_size;
    ticks(lo, hi, points, min_points as f64)
}

/// A tick label: as many decimals as the step needs and no more ("0.003", "0.25", "40"), thousands
/// as "k" ("12k", "24.3k") and tiny or huge steps in scientific notation ("2e-5"); exactly "0" at
/// zero.
pub fn format_tick(value: f64, step: f64) -> String {
    if !value.is_finite() {
        return String::new();
    }
    if value.abs() < 1e-9 * step.abs().max(f64::MIN_POSITIVE) {
        return "0".into();
    }
    let step = step.abs();
    if !(1e-4..1e7).contains(&step) {
        let digits = (value.abs().log10().floor() - step.log10().floor()).max(0.0) as usize;
        return format!("{value:.digits$e}");
    }
    // Thousands as "k" where the step is, or the value has five digits or more.
    if step >= 1000.0 || (value.abs() >= 10_000.0 && step >= 100.0) {
        let digits = (3.0 - step.log10().floor()).max(0.0) as usize;
        return format!("{:.digits$}k", value / 1000.0);
    }
    // A step of 0.0005 needs four decimals, one of 0.002 three.
    let decimals = (-step.log10() - 1e-9).ceil().max(0.0) as usize;
    format!("{value:.decimals$}")
}
