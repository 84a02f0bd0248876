//! `dfsph2d run`: step a scene headless to a given simulated time, writing statistics every
//! step and snapshots on a schedule.

use std::io::IsTerminal;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::Result;
use dfsph::{Scene, Simulation};
use dfsph_io::StatsCsvWriter;
use indicatif::{ProgressBar, ProgressStyle};

use crate::blowup::{BlowUp, BlowUpWatch};
use crate::cli::Format;
use crate::output::{FrameWriter, Manifest};
use crate::probes_csv::ProbesCsvWriter;
use crate::schedule::{reached, SnapshotSchedule};

/// A validated run: everything was checked before this is built.
pub struct RunPlan {
    pub scene: Scene,
    /// Simulated end time, s (> 0).
    pub until: f64,
    /// Simulated time between snapshots, s (> 0).
    pub every: f64,
    pub formats: Vec<Format>,
    pub out: PathBuf,
    /// How PNG frames and videos are drawn: width, the field colouring the water, the
    /// water's look (the colour scale is set from the scene).
    pub picture: dfsph_io::render::RenderOptions,
}

/// What happened.
#[derive(Clone, Debug)]
pub struct RunOutcome {
    pub scene_name: String,
    pub steps: u64,
    /// Simulated time reached, s.
    pub time: f64,
    pub wall: Duration,
    pub frames: usize,
    pub n_fluid: usize,
    pub n_boundary: usize,
    /// Particles put back into the tank, or out of a rigid body, over the run (wall leaks).
    pub clamped: u64,
    /// Rigid bodies at the end.
    pub bodies: usize,
    /// Particles reset after becoming NaN/infinite over the run.
    pub non_finite: u64,
    /// The first step that produced non-finite values, and its time; the run stopped there.
    pub broke_at: Option<(u64, f64)>,
    /// Ctrl-C (or SIGTERM, SIGHUP) stopped the run early; the files are complete up to that
    /// step.
    pub interrupted: bool,
    /// The first blow-up the watch saw ([`crate::blowup`]); the run went on to the end.
    pub blow_up: Option<BlowUp>,
}

/// Something that acts on the simulation between steps (`run --replay`: a recording).
pub trait Driver {
    /// Called before every step: apply what is due. Returns true when the simulation was
    /// rebuilt (a reset: time and step count start again at 0).
    fn before_step(&mut self, sim: &mut Simulation) -> Result<bool>;
    /// True when the run should stop before the next step.
    fn finished(&self) -> bool;
    /// Called once after the last step, before the final snapshot. Returns true on a reset.
    fn after_last_step(&mut self, sim: &mut Simulation) -> Result<bool>;
    /// Whether the last `before_step` applied an action (the blow-up watch then takes the
    /// energy after that step as its new reference).
    fn acted(&self) -> bool {
        false
    }
    /// Fraction done, for the progress bar, when the driver knows better than `until`.
    fn progress(&self) -> Option<f64> {
        None
    }
}

/// A plain run: no actions.
struct NoDriver;

impl Driver for NoDriver {
    fn before_step(&mut self, _: &mut Simulation) -> Result<bool> {
        Ok(false)
    }
    fn finished(&self) -> bool {
        false
    }
    fn after_last_step(&mut self, _: &mut Simulation) -> Result<bool> {
        Ok(false)
    }
}

impl RunOutcome {
    /// The one-line summary printed at the end.
    pub fn summary(&self, out: &std::path::Path) -> String {
        let wall = self.wall.as_secs_f64();
        format!(
            "{}: {} steps to t = {:.4} s in {:.2} s wall ({:.1} steps/s); {} fluid + {} boundary \
             particles; {} frames in {}; {} clamped, {} non-finite",
            self.scene_name,
            self.steps,
            self.time,
            wall,
            self.steps as f64 / wall.max(1e-9),
            self.n_fluid,
            self.n_boundary,
            self.frames,
            out.display(),
            self.clamped,
            self.non_finite,
        )
    }
}

/// Run `plan` on `sim` (built from `plan.scene`). The output directory must exist already
/// (see [`crate::output::create_output_dir`]). Stops early at the first step that produced
/// non-finite values, with everything up to and including that step written.
pub fn execute(plan: &RunPlan, sim: Simulation) -> Result<RunOutcome> {
    execute_with(plan, sim, &mut NoDriver)
}

/// [`execute`], with `driver` acting on the simulation between steps. A run stops early, with
/// every file complete, when Ctrl-C was pressed (see [`crate::interrupt`]).
pub fn execute_with(
    plan: &RunPlan,
    mut sim: Simulation,
    driver: &mut dyn Driver,
) -> Result<RunOutcome> {
    let started = Instant::now();
    let progress = progress_bar();
    let mut manifest = Manifest::create(&plan.out)?;
    manifest.record("scene.json")?;
    dfsph_io::write_atomic(plan.out.join("scene.json"), |w| {
        w.write_all(plan.scene.to_json().as_bytes())?;
        w.write_all(b"\n")
    })?;
    manifest.record("stats.csv")?;
    let mut stats = StatsCsvWriter::create(plan.out.join("stats.csv"))?;
    if !sim.scene().probes.is_empty() {
        manifest.record("probes.csv")?;
    }
    let mut probes = ProbesCsvWriter::create(plan.out.join("probes.csv"), &sim)?;
    if let Some(p) = probes.as_mut() {
        p.push(&sim)?;
    }
    let mut frames = FrameWriter::create(
        &plan.out,
        &plan.formats,
        &plan.scene,
        plan.picture,
        plan.every,
        &mut manifest,
    )?;
    let mut schedule = SnapshotSchedule::new(plan.every);
    frames.write(&sim, &mut manifest)?;

    let mut broke_at = None;
    let mut interrupted = false;
    let mut watch = BlowUpWatch::new(&sim);
    loop {
        if crate::interrupt::requested() {
            interrupted = true;
            break;
        }
        if driver.finished() {
            break;
        }
        if driver.before_step(&mut sim)? {
            // Reset: simulated time starts again at 0; snapshot the new start.
            watch.restart(&sim);
            frames.new_epoch();
            schedule = SnapshotSchedule::new(plan.every);
            frames.write(&sim, &mut manifest)?;
        }
        // The driver stops applying a long run of actions on Ctrl-C (a recording of a
        // million `emit`s): stop before stepping.
        if crate::interrupt::requested() {
            interrupted = true;
            break;
        }
        let s = *sim.step();
        let seen = watch.found.is_some();
        watch.after_step(&sim, &s, driver.acted());
        if let (false, Some(b)) = (seen, &watch.found) {
            // Said at once: a long run goes on writing what may be worthless.
            progress.suspend(|| {
                eprintln!(
                    "warning: step {} (t = {:.4} s): {}",
                    b.step,
                    b.time,
                    dfsph_io::input::terminal_safe(&b.what)
                )
            });
        }
        stats.push(&s)?;
        if let Some(p) = probes.as_mut() {
            p.push(&sim)?;
        }
        if s.non_finite > 0 {
            broke_at = Some((s.step, s.time));
        }
        if schedule.due(s.time, s.dt) {
            frames.write(&sim, &mut manifest)?;
        }
        let done = driver.progress().unwrap_or(s.time / plan.until);
        progress.set_position((done.min(1.0) * 1000.0) as u64);
        progress.set_message(format!(
            "t = {:.3}/{} s, step {}, {} frames",
            s.time,
            plan.until,
            s.step,
            frames.count()
        ));
        if broke_at.is_some() || reached(s.time, s.dt, plan.until) {
            break;
        }
    }
    if !interrupted && driver.after_last_step(&mut sim)? {
        frames.new_epoch();
    }
    interrupted |= crate::interrupt::requested();
    frames.write(&sim, &mut manifest)?;
    let frame_count = frames.count();
    frames.finish()?;
    stats.finish()?;
    if let Some(p) = probes {
        p.finish()?;
    }
    progress.finish_and_clear();

    let last = sim.stats();
    Ok(RunOutcome {
        scene_name: plan.scene.name.clone(),
        steps: sim.step_count(),
        time: sim.time(),
        wall: started.elapsed(),
        frames: frame_count,
        n_fluid: last.n_fluid,
        n_boundary: last.n_boundary,
        clamped: sim.total_clamped(),
        bodies: sim.rigid_body_count(),
        non_finite: sim.total_non_finite(),
        broke_at,
        interrupted,
        blow_up: watch.found,
    })
}

/// A progress bar on stderr when it is a terminal; hidden otherwise (logs, pipes, tests).
fn progress_bar() -> ProgressBar {
    if !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(1000);
    if let Ok(style) =
        ProgressStyle::with_template("{spinner} {elapsed_precise} [{bar:30}] {msg} (eta {eta})")
    {
        bar.set_style(style.progress_chars("=> "));
    }
    bar.enable_steady_tick(Duration::from_millis(200));
    bar
}
