//! Heads-up display: frame and solver statistics over the view, live plots of the last few
//! seconds, and the help overlay.

use std::collections::VecDeque;

use dfsph::StepStats;
use eframe::egui::{self, Color32, RichText};
use egui_plot::{Legend, Line, Plot, PlotPoints};

use crate::input::KEY_HELP;

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

    fn series(&self, f: impl Fn(&Sample) -> f64) -> PlotPoints {
        self.samples.iter().map(|s| [s.time, f(s)]).collect()
    }

    /// Three small plots side by side: density error, iterations, kinetic energy.
    pub fn plots(&self, ui: &mut egui::Ui) {
        // Fill the panel below the labels, without asking it to grow.
        let height = (ui.available_height() - 24.0).max(30.0);
        let plot = |id: &str| {
            Plot::new(id)
                .height(height)
                .allow_drag(false)
                .allow_zoom(false)
                .allow_scroll(false)
                .allow_boxed_zoom(false)
                .allow_double_click_reset(false)
                .include_y(0.0)
                .y_axis_min_width(36.0)
        };
        ui.columns(3, |cols| {
            cols[0].label("avg density error (%) vs time (s)");
            plot("plot-density-error").show(&mut cols[0], |p| {
                p.line(Line::new(self.series(|s| s.density_error_pct)).name("density error"));
            });
            cols[1].label("solver iterations per step");
            plot("plot-iterations")
                .legend(Legend::default().position(egui_plot::Corner::LeftTop))
                .show(&mut cols[1], |p| {
                    p.line(Line::new(self.series(|s| s.density_iterations as f64)).name("density"));
                    p.line(
                        Line::new(self.series(|s| s.divergence_iterations as f64))
                            .name("divergence"),
                    );
                });
            cols[2].label("kinetic energy (J/m)");
            plot("plot-energy").show(&mut cols[2], |p| {
                p.line(Line::new(self.series(|s| s.kinetic_energy)).name("kinetic energy"));
            });
        });
    }
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
}

/// Draw the statistics in the top-left corner of the view.
pub fn hud(ui: &mut egui::Ui, info: &HudInfo) {
    let s = info.stats;
    let mono = |t: String| RichText::new(t).monospace().color(Color32::from_gray(235));
    egui::Frame::none()
        .fill(Color32::from_black_alpha(150))
        .rounding(4.0)
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
                // The scene runs as written, whatever its size: say why it is slow.
                if info.slowed.is_some() {
                    ui.label(
                        RichText::new(format!(
                            "slower than real time: {} particles",
                            info.particles
                        ))
                        .strong()
                        .color(Color32::from_rgb(255, 180, 80)),
                    );
                }
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
                    for (keys, what) in KEY_HELP {
                        ui.label(RichText::new(*keys).monospace().strong());
                        ui.label(*what);
                        ui.end_row();
                    }
                });
        });
}

#[cfg(test)]
mod tests {
    use super::*;

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
