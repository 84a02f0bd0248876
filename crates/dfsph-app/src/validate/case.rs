//! One validation case's vocabulary: running a scene and recording it ([`simulate`],
//! [`Trace`]), the comparisons with their tolerances ([`Check`]) and what a case reports.

use std::time::Instant;

use anyhow::Result;
use dfsph::{probes, Scene, Simulation, StepStats};

/// One comparison with a stated tolerance.
#[derive(Clone, Debug)]
pub struct Check {
    /// Short case name, e.g. "Dam break".
    pub case: String,
    /// What is compared.
    pub name: String,
    /// The measured value, formatted with its unit.
    pub value: String,
    /// The tolerance, formatted with its unit.
    pub tolerance: String,
    /// Value over tolerance (≤ 1 passes), used to find where we are furthest off.
    pub ratio: f64,
    pub pass: bool,
    /// Only the full resolution can meet this check (a comparison with an experiment or an
    /// exact solution): `--quick` reports its value but does not count it.
    pub needs_full_run: bool,
}

impl Check {
    /// A check that passes when `value <= limit` (both in the same unit, `fmt` formats them).
    pub fn at_most(
        case: &str,
        name: impl Into<String>,
        value: f64,
        limit: f64,
        fmt: impl Fn(f64) -> String,
    ) -> Self {
        let pass = value.is_finite() && value <= limit;
        Self {
            case: case.to_string(),
            name: name.into(),
            value: fmt(value),
            tolerance: format!("≤ {}", fmt(limit)),
            ratio: if value.is_finite() {
                value / limit
            } else {
                f64::INFINITY
            },
            pass,
            needs_full_run: false,
        }
    }

    /// Mark the check as one only the full resolution can meet (see [`Self::needs_full_run`]).
    pub fn full_run_only(mut self) -> Self {
        self.needs_full_run = true;
        self
    }

    /// Whether the check decides the outcome of a run with `settings`.
    pub fn counts(&self, settings: Settings) -> bool {
        !(settings.quick && self.needs_full_run)
    }
}

/// Check that a run reached its end time without non-finite values (a run that broke down
/// stops there, and every comparison after that point is missing).
pub fn completion_check(case: &str, trace: &Trace, until: f64) -> Check {
    let i = &trace.info;
    let pass = i.non_finite == 0 && i.sim_time >= until - 1e-9;
    Check {
        case: case.to_string(),
        name: format!(
            "{}: the run reaches t = {until:.3} s without non-finite values",
            i.label
        ),
        value: format!(
            "reached t = {:.3} s; {} non-finite, {} clamped (wall leaks)",
            i.sim_time, i.non_finite, i.clamped
        ),
        tolerance: "end time reached, non-finite ≤ 0".into(),
        ratio: if pass { 0.0 } else { f64::INFINITY },
        pass,
        needs_full_run: false,
    }
}

/// What one case contributes to the report.
pub struct CaseReport {
    pub title: String,
    /// Markdown: setup, method, observations.
    pub text: String,
    pub checks: Vec<Check>,
    pub plots: Vec<super::plot::Plot>,
    pub runs: Vec<RunInfo>,
}

/// One simulation run, for the table of run times.
#[derive(Clone, Debug)]
pub struct RunInfo {
    pub label: String,
    pub particle_radius: f64,
    pub n_fluid: usize,
    pub steps: u64,
    pub sim_time: f64,
    pub wall_s: f64,
    pub clamped: u64,
    pub non_finite: u64,
}

/// Resolution and duration settings of a validation run.
#[derive(Clone, Copy, Debug, Default)]
pub struct Settings {
    pub quick: bool,
    /// Applied to every scene before it runs. `None` in `dfsph2d validate`; the tests use it
    /// to break the physics on purpose and see the checks fail.
    pub perturb: Option<fn(&mut Scene)>,
    /// The backend every case runs on (`--backend`).
    pub backend: crate::backends::Backend,
}

/// Per-step record of one run: index 0 is the initial state.
pub struct Trace {
    /// Simulated time, s.
    pub t: Vec<f64>,
    /// Step statistics (index 0: all zero but the particle count).
    pub stats: Vec<StepStats>,
    /// Front position from the left wall, m (`Simulation::front_position(3)`); NaN if none.
    pub front: Vec<f64>,
    /// Probe readings (Pa, m) in the order of the scene's probes.
    pub probes: Vec<Vec<f64>>,
    pub info: RunInfo,
}

impl Trace {
    /// Column `k` of the probe readings.
    pub fn probe(&self, k: usize) -> Vec<f64> {
        self.probes.iter().map(|r| r[k]).collect()
    }
}

/// Run `scene` (with `settings.perturb` applied) until `until` seconds, recording the front
/// and the probes every step.
pub fn simulate(
    settings: Settings,
    label: &str,
    scene: &Scene,
    until: f64,
) -> Result<(Trace, Simulation)> {
    let started = Instant::now();
    let mut scene = scene.clone();
    if let Some(perturb) = settings.perturb {
        perturb(&mut scene);
    }
    let scene = &scene;
    let (factory, _) = crate::backends::factory(settings.backend).map_err(anyhow::Error::msg)?;
    let limits = dfsph::memory::MemoryLimits::of_this_process(None);
    let (mut sim, _) = crate::backends::simulation(scene, &limits, factory.as_ref())?;
    let mut trace = Trace {
        t: vec![0.0],
        stats: vec![StepStats {
            n_fluid: sim.fluid_count(),
            ..StepStats::default()
        }],
        front: vec![sim.front_position(3).unwrap_or(f64::NAN)],
        probes: vec![probes::sample_all(&sim)],
        info: RunInfo {
            label: label.to_string(),
            particle_radius: scene.particle_radius,
            n_fluid: sim.fluid_count(),
            steps: 0,
            sim_time: 0.0,
            wall_s: 0.0,
            clamped: 0,
            non_finite: 0,
        },
    };
    while !sim.has_reached(until) {
        let s = *sim.step();
        trace.t.push(s.time);
        trace.stats.push(s);
        trace.front.push(sim.front_position(3).unwrap_or(f64::NAN));
        trace.probes.push(probes::sample_all(&sim));
        if s.non_finite > 0 {
            break;
        }
    }
    trace.info.steps = sim.step_count();
    trace.info.sim_time = sim.time();
    trace.info.wall_s = started.elapsed().as_secs_f64();
    trace.info.clamped = sim.total_clamped();
    trace.info.non_finite = sim.total_non_finite();
    eprintln!(
        "validate:   {label}: {} particles, {} steps to t = {:.3} s in {:.1} s",
        trace.info.n_fluid, trace.info.steps, trace.info.sim_time, trace.info.wall_s
    );
    Ok((trace, sim))
}

/// Linear interpolation of (xs, ys) at x; xs increasing. NaN outside the range.
pub fn interp(xs: &[f64], ys: &[f64], x: f64) -> f64 {
    if xs.is_empty() || x < xs[0] || x > xs[xs.len() - 1] {
        return f64::NAN;
    }
    let i = xs.partition_point(|&v| v < x);
    if i == 0 {
        return ys[0];
    }
    let (x0, x1, y0, y1) = (xs[i - 1], xs[i], ys[i - 1], ys[i]);
    if x1 <= x0 {
        return y1;
    }
    y0 + (y1 - y0) * (x - x0) / (x1 - x0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interpolation_is_linear_and_nan_outside() {
        let xs = [0.0, 1.0, 3.0];
        let ys = [0.0, 2.0, 6.0];
        assert_eq!(interp(&xs, &ys, 0.5), 1.0);
        assert_eq!(interp(&xs, &ys, 2.0), 4.0);
        assert_eq!(interp(&xs, &ys, 3.0), 6.0);
        assert!(interp(&xs, &ys, 3.5).is_nan());
    }

    #[test]
    fn checks_pass_at_the_limit_and_fail_above_or_on_nan() {
        let f = |v: f64| format!("{v:.1} %");
        assert!(Check::at_most("c", "n", 10.0, 10.0, f).pass);
        assert!(!Check::at_most("c", "n", 10.1, 10.0, f).pass);
        assert!(!Check::at_most("c", "n", f64::NAN, 10.0, f).pass);
    }
}
