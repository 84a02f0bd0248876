//! Heads-up display: frame and solver statistics over the view, live plots of the last few
//! seconds, and the help overlay.

use std::collections::VecDeque;

use dfsph::StepStats;
use eframe::egui::{self, Color32, RichText};
use egui_plot::{AxisHints, Legend, Line, Plot, PlotBounds, PlotPoints};

use crate::input::key_help;
use crate::ticks::{format_tick, grid_marks};

/// Simulated seconds the plots show.
pub const PLOT_WINDOW: f64 = 10.0;

/// One plotted sample: a frame's steps summarised.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Sample {
    /// Simulated time, s.
    pub time: f64,
    /// Mean of the steps' average density errors, %.
    pub density_error_pct: f64,
    /// Most density-solve iterations in a step.
    pub density_iterations: u32,
    /// Most divergence-solve iterations in a step.
    pub divergence_iterations: u32,
    /// Kinetic energy at the end, J/m.
    pub kinetic_energy: f64,
}

/// Accumulates the steps of one frame into a [`Sample`].
#[derive(Clone, Copy, Debug, Default)]
pub struct FrameStats {
    steps: u32,
    error_sum: f64,
    sample: Sample,
}

impl FrameStats {
    /// Add one step's statistics.
    pub fn add(&mut self, s: &StepStats) {
        self.steps += 1;
        self.error_sum += s.avg_density_error_pct;
        let x = &mut self.sample;
        x.time = s.time;
        x.density_iterations = x.density_iterations.max(s.density_iterations);
        x.divergence_iterations = x.divergence_iterations.max(s.divergence_iterations);
        x.kinetic_energy = s.kinetic_energy;
        x.density_error_pct = self.error_sum / self.steps as f64;
    }

    /// The summary, if any step was added.
    pub fn sample(&self) -> Option<Sample> {
        (self.steps > 0).then_some(self.sample)
    }
}

/// The last [`PLOT_WINDOW`] seconds of samples.
#[derive(Clone, Debug, Default)]
pub struct History {
    samples: VecDeque<Sample>,
}

impl History {
    /// Append a sample; a sample earlier than the last one (after a reset) starts over.
    pub fn push(&mut self, s: Sample) {
        if self.samples.back().is_some_and(|b| s.time < b.time) {
            self.samples.clear();
        }
        self.samples.push_back(s);
        while self
            .samples
            .front()
            .is_some_and(|f| s.time - f.time > PLOT_WINDOW)
        {
            self.samples.pop_front();
        }
    }

    /// Forget everything.
    pub fn clear(&mut self) {
        self.samples.clear();
    }

    /// Number of samples held.
    pub fn len(&self) -> usize {
        self.samples.len()
    }

    /// Whether no samples are held.
    pub fn is_empty(&self) -> bool {
        self.samples.is_empty()
    }

    fn series(&self, f: impl Fn(&Sample) -> f64) -> PlotPoints<'_> {
        self.samples.iter().map(|s| [s.time, f(s)]).collect()
    }

    /// The time axis: the [`PLOT_WINDOW`] seconds from the oldest sample held (so the
    /// curve grows from the left until the window is full, then scrolls).
    pub fn time_range(&self) -> (f64, f64) {
        let start = self.samples.front().map_or(0.0, |s| s.time);
        (start, start + PLOT_WINDOW)
    }

    /// The value axis for the quantity `f` of the samples held: see [`value_range`].
    pub fn value_range(&self, f: impl Fn(&Sample) -> f64) -> (f64, f64) {
        value_range(self.samples.iter().map(f))
    }

    /// Three small plots side by side: density error, iterations, kinetic energy, each with
    /// time in seconds along x and the quantity (its unit in the heading) along y.
    pub fn plots(&self, ui: &mut egui::Ui) {
        // Fill the panel below the labels, without asking it to grow.
        let height = (ui.available_height() - 24.0).max(30.0);
        let (t0, t1) = self.time_range();
        let plot = |id: &str| {
            Plot::new(id)
                .height(height)
                .allow_drag(false)
                .allow_zoom(false)
                .allow_scroll(false)
                .allow_boxed_zoom(false)
                .allow_double_click_reset(false)
                // egui_plot's default grid has steps of powers of ten only, and hides the
                // labels of steps closer than 20–60 points: on plots this small that leaves
                // a lone "0". Steps of 1, 2 or 5 × 10ⁿ, as many as fit, with labels close
                // enough to keep two or three on the shortest axis.
                .x_grid_spacer(|g| grid_marks(g, X_TICK_POINTS))
                .y_grid_spacer(|g| grid_marks(g, Y_TICK_POINTS))
                .custom_x_axes(vec![AxisHints::new_x()
                    .formatter(|m, _| format!("{} s", format_tick(m.value, m.step_size)))
                    .label_spacing(X_TICK_POINTS - 10.0..=X_TICK_POINTS)])
                .custom_y_axes(vec![AxisHints::new_y()
                    .formatter(|m, _| format_tick(m.value, m.step_size))
                    .label_spacing(Y_TICK_POINTS - 6.0..=Y_TICK_POINTS)
                    .min_thickness(30.0)])
        };
        let bounds = |(lo, hi): (f64, f64)| PlotBounds::from_min_max([t0, lo], [t1, hi]);
        // Headings on one line, cut short in narrow windows (the full text on hover).
        let heading = |ui: &mut egui::Ui, text: &str| {
            ui.add(egui::Label::new(text).truncate());
        };
        ui.columns(3, |cols| {
            heading(&mut cols[0], "avg density error (%)");
            let range = self.value_range(|s| s.density_error_pct);
            plot("plot-density-error").show(&mut cols[0], |p| {
                p.set_plot_bounds(bounds(range));
                p.line(Line::new(
                    "density error",
                    self.series(|s| s.density_error_pct),
                ));
            });
            heading(&mut cols[1], "solver iterations per step");
            let range = value_range(
                self.samples
                    .iter()
                    .flat_map(|s| [s.density_iterations as f64, s.divergence_iterations as f64]),
            );
            plot("plot-iterations")
                .legend(Legend::default().position(egui_plot::Corner::LeftTop))
                .show(&mut cols[1], |p| {
                    p.set_plot_bounds(bounds(range));
                    p.line(Line::new(
                        "density",
                        self.series(|s| s.density_iterations as f64),
                    ));
                    p.line(Line::new(
                        "divergence",
                        self.series(|s| s.divergence_iterations as f64),
                    ));
                });
            heading(&mut cols[2], "kinetic energy (J/m)");
            let range = self.value_range(|s| s.kinetic_energy);
            plot("plot-energy").show(&mut cols[2], |p| {
                p.set_plot_bounds(bounds(range));
                p.line(Line::new(
                    "kinetic energy",
                    self.series(|s| s.kinetic_energy),
                ));
            });
        });
    }
}

/// Least distance between labelled time ticks, points (labels such as "12.5 s").
const X_TICK_POINTS: f32 = 48.0;
/// Least distance between labelled value ticks, points (a line of text and a little air).
const Y_TICK_POINTS: f32 = 20.0;

/// The value axis for `values` (non-negative quantities: errors, counts, energies): from 0
/// (or the least value, if negative) to the greatest value plus a 10 % margin, so the curve
/// never touches the top. Never degenerate: all zero (or nothing yet) gives 0–1, and a span
/// is at least a millionth of the values' size. Non-finite values are left out.
pub fn value_range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((0.0f64, 0.0f64), |(lo, hi), v| (lo.min(v), hi.max(v)));
    let span = hi - lo;
    let size = lo.abs().max(hi.abs());
    if span <= 1e-6 * size || span < 1e-300 {
        let pad = if size > 0.0 { 0.1 * size } else { 1.0 };
        return (lo - if lo < 0.0 { pad } else { 0.0 }, hi + pad);
    }
    let margin = 0.1 * span;
    (if lo < 0.0 { lo - margin } else { lo }, hi + margin)
}

/// Exponentially smoothed rate of events per second (frames, steps).
#[derive(Clone, Copy, Debug, Default)]
pub struct Rate {
    per_second: f64,
}

impl Rate {
    /// Record `count` events over `seconds`.
    pub fn add(&mut self, count: f64, seconds: f64) {
        if seconds > 0.0 {
            let now = count / seconds;
            self.per_second = if self.per_second == 0.0 {
                now
            } else {
                self.per_second + 0.05 * (now - self.per_second)
            };
        }
    }

    /// Events per second.
    pub fn get(&self) -> f64 {
        self.per_second
    }
}

/// Everything the HUD text shows.
pub struct HudInfo<'a> {
    pub scene: &'a str,
    /// What steps the water (`cpu`, or the GPU and its adapter).
    pub backend: &'a str,
    pub fps: f64,
    pub steps_per_second: f64,
    pub particles: usize,
    pub budget: usize,
    pub time: f64,
    pub stats: &'a StepStats,
    pub paused: bool,
    /// The real-time factor: simulated seconds per wall second; `None` while paused.
    pub realtime: Option<f64>,
    /// Simulated time per wall time, relative to the time scale asked for, when it is
    /// noticeably below 1; `None` when on pace.
    pub slowed: Option<f64>,
    pub clamped: u64,
    pub non_finite: u64,
    /// The view's magnification when it is not the fitted view.
    pub zoom: Option<f32>,
    /// The particle size fitted to this machine, said once chosen
    /// ([`crate::resolution`]).
    pub resolution_note: Option<&'a str>,
}

/// Draw the statistics in the top-left corner of the view.
pub fn hud(ui: &mut egui::Ui, info: &HudInfo) {
    let s = info.stats;
    let mono = |t: String| RichText::new(t).monospace().color(Color32::from_gray(235));
    egui::Frame::NONE
        .fill(Color32::from_black_alpha(150))
        .corner_radius(4.0)
        .inner_margin(6.0)
        .show(ui, |ui| {
            ui.label(
                RichText::new(info.scene)
                    .strong()
                    .color(Color32::from_gray(250)),
            );
            ui.label(mono(format!(
                "{:5.1} FPS   {:6.0} steps/s",
                info.fps, info.steps_per_second
            )));
            ui.label(mono(format!("on {}", info.backend)));
            ui.label(mono(format!(
                "particles {:>7} / {} budget",
                info.particles, info.budget
            )));
            ui.label(mono(format!(
                "t = {:8.3} s   Δt = {:.2} ms",
                info.time,
                1e3 * s.dt
            )));
            ui.label(mono(format!(
                "iterations: density {:3}  divergence {:3}",
                s.density_iterations, s.divergence_iterations
            )));
            ui.label(mono(format!(
                "density error: mean {:.3} %  max {:.2} %",
                s.avg_density_error_pct, s.max_density_error_pct
            )));
            if info.clamped > 0 || info.non_finite > 0 {
                ui.label(
                    RichText::new(format!(
                        "leaks clamped {}   non-finite reset {}",
                        info.clamped, info.non_finite
                    ))
                    .monospace()
                    .color(Color32::from_rgb(255, 140, 90)),
                );
            }
            if info.paused {
                ui.label(RichText::new("PAUSED").strong().color(Color32::YELLOW));
            }
            if let Some(factor) = info.realtime {
                let digits = if factor >= 0.1 { 1 } else { 2 };
                let text = format!("real time x{factor:.digits$}");
                ui.label(match info.slowed {
                    Some(pace) => RichText::new(format!("{text}   slowed: x{pace:.digits$}"))
                        .strong()
                        .monospace()
                        .color(Color32::from_rgb(255, 180, 80)),
                    None => mono(text),
                });
                // The scene runs as written, whatever its size: say why it is slow, and
                // what to press.
                if info.slowed.is_some() {
                    ui.label(
                        RichText::new(format!(
                            "slower than real time: {} particles; {} for half as many",
                            crate::resolution::thousands(info.particles),
                            crate::resolution::COARSER_KEY,
                        ))
                        .strong()
                        .color(Color32::from_rgb(255, 180, 80)),
                    );
                }
            }
            if let Some(note) = info.resolution_note {
                ui.label(
                    RichText::new(note)
                        .strong()
                        .color(Color32::from_rgb(150, 210, 255)),
                );
            }
            if let Some(zoom) = info.zoom {
                ui.label(mono(format!("zoom x{zoom:.1}   0: fit the tank")));
            }
            ui.label(
                RichText::new("H or ? for help")
                    .small()
                    .color(Color32::GRAY),
            );
        });
}

/// The help overlay listing every key.
pub fn help_window(ctx: &egui::Context, open: &mut bool) {
    egui::Window::new("Keys and mouse")
        .open(open)
        .collapsible(false)
        .resizable(false)
        .anchor(egui::Align2::CENTER_CENTER, egui::Vec2::ZERO)
        .show(ctx, |ui| {
            egui::Grid::new("help-grid")
                .num_columns(2)
                .spacing([16.0, 4.0])
                .striped(true)
                .show(ui, |ui| {
                    for (keys, what) in key_help() {
                        ui.label(RichText::new(keys).monospace().strong());
                        ui.label(what);
                        ui.end_row();
                    }
                });
        });
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ticks::{nice_step, ticks};

    #[test]
    fn history_keeps_the_last_window_and_restarts_after_reset() {
        let mut h = History::default();
        for k in 0..1200 {
            h.push(Sample {
                time: k as f64 / 60.0,
                ..Default::default()
            });
        }
        // 10 s at 60 samples per second, both ends included.
        assert!((600..=602).contains(&h.len()), "{}", h.len());
        h.push(Sample::default());
        assert_eq!(h.len(), 1);
    }

    #[test]
    fn value_range_fits_the_data_with_a_margin_and_is_never_degenerate() {
        // Density errors of a few thousandths of a percent: the range fits them, not 0–1.
        let (lo, hi) = value_range([0.002, 0.003, 0.0025].into_iter());
        assert_eq!(lo, 0.0);
        assert!(hi > 0.003 && hi < 0.0035, "{hi}");
        // Nothing yet, all zero, or one constant value: a usable range.
        assert_eq!(value_range(std::iter::empty()), (0.0, 1.0));
        assert_eq!(value_range([0.0, 0.0].into_iter()), (0.0, 1.0));
        let (lo, hi) = value_range([5.0, 5.0].into_iter());
        assert!(lo <= 0.0 && hi > 5.0, "{lo} {hi}");
        // Negative values get a margin below too; NaN and infinities are left out.
        let (lo, hi) = value_range([-2.0, 3.0, f64::NAN, f64::INFINITY].into_iter());
        assert!(lo < -2.0 && hi > 3.0 && hi < 4.0, "{lo} {hi}");
    }

    #[test]
    fn ticks_are_nice_fit_the_axis_and_are_labelled_with_their_step() {
        assert_eq!(nice_step(0.0013), 0.002);
        assert_eq!(nice_step(3.0), 5.0);
        assert_eq!(nice_step(7.0), 10.0);
        assert_eq!(nice_step(0.1), 0.1);
        // 0–0.0033 % on a 60-point axis with labels at least 20 points apart: 0, 0.001, ...
        let t = ticks(0.0, 0.0033, 60.0, 20.0);
        let values: Vec<String> = t
            .iter()
            .map(|m| format_tick(m.value, m.step_size))
            .collect();
        assert_eq!(values, ["0", "0.002"]);
        let t = ticks(0.0, 0.0033, 120.0, 20.0);
        let values: Vec<String> = t
            .iter()
            .map(|m| format_tick(m.value, m.step_size))
            .collect();
        assert_eq!(values, ["0", "0.001", "0.002", "0.003"]);
        // A 10 s window from t = 3.7 s on a 300-point axis, labels 48 points apart: every 2 s.
        let t = ticks(3.7, 13.7, 300.0, X_TICK_POINTS as f64);
        let values: Vec<f64> = t.iter().map(|m| m.value).collect();
        assert_eq!(values, [4.0, 6.0, 8.0, 10.0, 12.0]);
        assert!(ticks(1.0, 1.0, 100.0, 20.0).is_empty());
        assert!(ticks(0.0, 1.0, 0.0, 20.0).is_empty());
        // Labels: no spurious digits, thousands, tiny steps, an exact zero.
        assert_eq!(format_tick(0.25, 0.05), "0.25");
        assert_eq!(format_tick(40.0, 20.0), "40");
        assert_eq!(format_tick(12000.0, 2000.0), "12k");
        assert_eq!(format_tick(2500.0, 500.0), "2500");
        assert_eq!(format_tick(24282.0, 500.0), "24.3k");
        assert_eq!(format_tick(0.0015, 0.0005), "0.0015");
        assert_eq!(format_tick(3e-5, 1e-5), "3e-5");
        assert_eq!(format_tick(-1e-18, 0.001), "0");
    }

    #[test]
    fn the_time_axis_spans_the_window_from_the_oldest_sample() {
        let mut h = History::default();
        assert_eq!(h.time_range(), (0.0, PLOT_WINDOW));
        for k in 0..=600 {
            h.push(Sample {
                time: 5.0 + k as f64 / 30.0,
                ..Default::default()
            });
        }
        let (t0, t1) = h.time_range();
        assert!((t1 - 25.0).abs() < 0.05, "{t0}..{t1}");
        assert!((t1 - t0 - PLOT_WINDOW).abs() < 1e-9);
    }

    #[test]
    fn frame_stats_average_errors_and_keep_the_worst_iterations() {
        let mut f = FrameStats::default();
        assert!(f.sample().is_none());
        for (err, it) in [(0.1, 3), (0.3, 7)] {
            f.add(&StepStats {
                avg_density_error_pct: err,
                density_iterations: it,
                time: 1.0,
                ..Default::default()
            });
        }
        let s = f.sample().unwrap();
        assert!((s.density_error_pct - 0.2).abs() < 1e-12);
        assert_eq!(s.density_iterations, 7);
    }
}
