//! `dfsph2d`: the interactive 2D water simulator and its headless runner.
//!
//! ```text
//! dfsph2d                                   open the viewer on the dam break
//! dfsph2d view [SCENE] [--exit-after S] [--save-on-exit DIR] [--record FILE]
//! dfsph2d scenes                            list built-in scenes
//! dfsph2d run SCENE --until S --out DIR [--every S] [--format csv,vtk,png,gif,mp4] [--threads N]
//! dfsph2d run SCENE --replay FILE --out DIR [--until S] ...
//! dfsph2d stress [SCENE] --seed N --steps K [--record FILE] [--density-bound PCT]
//! dfsph2d validate [--quick] --out DIR      validation report against experiments
//! dfsph2d bench [--quick] [--json FILE] [--threads N,..] [--sizes 5k,20k,80k,320k] [--plot F]
//! ```
//!
//! Exit codes: 0 success; 2 bad arguments or scene (nothing written), or a `run` whose
//! simulation produced non-finite values or clamped particles back into the tank (output
//! written); 74 an I/O error (a write failed: full disk, an output directory that cannot be
//! created, ...; what was completed is kept);
//! 1 any other failure (the viewer, a failed validation check, a `stress` violation, a replay
//! that diverged from its recording); 130 stopped by Ctrl-C, SIGTERM or SIGHUP (files complete
//! up to the last step).

mod backends;
mod bench;
mod blowup;
mod cli;
mod failure;
mod interrupt;
mod output;
mod probes_csv;
mod replay;
mod run;
mod schedule;
mod stress;
mod validate;
mod view;

use std::io::Write;
use std::process::ExitCode;

use clap::Parser;
use dfsph::{scene, Simulation};

use cli::{Cli, Command, RunArgs, ValidateArgs, ViewArgs};
use dfsph_io::input::{load_scene, one_line, terminal_safe};
use failure::{check_memory, Failure};

fn main() -> ExitCode {
    let cli = Cli::parse();
    // A bad `DFSPH2D_SIMD` is refused before anything runs; the library would quietly take
    // the fastest path instead.
    let result = match dfsph::simd::SimdPath::from_env() {
        Err(e) => Err(Failure::input(e.to_string())),
        Ok(_) => run_command(cli),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(f) => {
            // An empty message: the command already said why (`stress`'s summary line).
            if !f.message.is_empty() {
                // Not eprintln!: after SIGHUP the terminal may be gone, and a failed print
                // must not turn a clean stop into a panic.
                let _ = writeln!(
                    std::io::stderr(),
                    "error: {}",
                    terminal_safe(&one_line(&f.message))
                );
            }
            ExitCode::from(f.code)
        }
    }
}

/// Runs the command `cli` names.
fn run_command(cli: Cli) -> Result<(), Failure> {
    match cli.command {
        None => view(ViewArgs {
            scene: None,
            exit_after: None,
            save_on_exit: None,
            record: None,
            max_memory: None,
            backend: backends::Backend::Cpu,
        }),
        Some(Command::View(args)) => view(args),
        Some(Command::Scenes) => {
            list_scenes();
            Ok(())
        }
        Some(Command::Run(args)) => run(args),
        Some(Command::Stress(args)) => stress::command(args),
        Some(Command::Validate(args)) => validate_cmd(args),
        Some(Command::Bench(args)) => bench::bench(args).map_err(Failure::input),
        Some(Command::BenchRow(args)) => bench::run_row(args).map_err(Failure::input),
    }
}

/// `dfsph2d scenes`: one line per built-in scene, name and description.
fn list_scenes() {
    let width = scene::BUILTIN_SCENES
        .iter()
        .map(|b| b.name.len())
        .max()
        .unwrap_or(0);
    for b in scene::BUILTIN_SCENES {
        println!("{:width$}  {}", b.name, b.description);
    }
}

fn view(args: ViewArgs) -> Result<(), Failure> {
    let scene = match &args.scene {
        Some(arg) => load_scene(arg).map_err(Failure::input)?,
        None => scene::builtin("dam-break").unwrap_or_default(),
    };
    if let Some(dir) = &args.save_on_exit {
        output::check_output_dir(dir).map_err(Failure::input)?;
    }
    // Before the display is looked for: a FIFO would block the viewer's start, a device
    // would swallow the recording.
    if let Some(path) = &args.record {
        dfsph_io::input::check_output_file(path, "--record").map_err(Failure::input)?;
    }
    // The viewer's pour budget: room for as much water again.
    let budgeted = dfsph_viewer::app::budgeted_scene(scene.clone(), scene.max_particles);
    check_memory(
        &format!("scene `{}`", args.scene.as_deref().unwrap_or("dam-break")),
        &budgeted.memory_estimate_for(budgeted.max_particles as u64),
        args.max_memory,
    )?;
    // The built-in scene a bare `dfsph2d` opens is fitted to this machine; a named one keeps
    // its resolution.
    let fit = args.scene.is_none();
    let scene_file = args.scene.as_deref().and_then(view::scene_file_name);
    let (backend, notes) = backends::factory(args.backend).map_err(Failure::input)?;
    for note in notes {
        let _ = writeln!(std::io::stderr(), "{}", terminal_safe(&note));
    }
    view::open(
        scene,
        scene_file,
        args.exit_after,
        args.save_on_exit,
        args.record,
        fit,
        backend,
    )
    .map_err(Failure::runtime)
}

fn run(args: RunArgs) -> Result<(), Failure> {
    // Everything is validated before the output directory is touched.
    let scene = load_scene(&args.scene).map_err(Failure::input)?;
    let (recording, cut_short) = match &args.replay {
        Some(path) => {
            let (recording, warning) =
                replay::load(path, &args.scene, &scene).map_err(Failure::input)?;
            (Some(recording), warning)
        }
        None => (None, None),
    };
    // A replay runs with the recording's thread count unless told otherwise: results are
    // bit-identical only for the same count. The header's count is bounded
    // (`recording::MAX_THREADS`) when the recording is parsed.
    let threads = args
        .threads
        .map(|n| n as usize)
        .or(recording.as_ref().map(|r| r.header.threads));
    if let Some(n) = threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()
            .map_err(|e| Failure::input(format!("cannot start {n} threads: {e}")))?;
    }
    // A replay starts from the scene exactly as recorded (with the recorder's pour budget).
    let scene = match &recording {
        Some(r) => r.header.scene.clone(),
        None => scene,
    };
    check_every(args.every, args.until, recording.as_ref(), &scene).map_err(Failure::input)?;
    // An MP4 is encoded by ffmpeg: without it the run would fail at its first frame, so it is
    // refused before anything is simulated or written.
    if args.format.contains(&cli::Format::Mp4) && dfsph_io::video::find_ffmpeg().is_none() {
        return Err(Failure::input(format!(
            "--format mp4: {}",
            dfsph_io::video::FFMPEG_MISSING
        )));
    }
    output::check_output_dir(&args.out).map_err(Failure::input)?;
    // A replay may pour up to the recorded scene's budget.
    let fluid = match &recording {
        Some(_) => scene.max_particles,
        None => scene.fluid_particle_count(),
    } as u64;
    let estimate = scene
        .memory_estimate_for(fluid)
        .with_output(output::buffer_bytes(
            &args.format,
            args.png_width,
            &scene,
            fluid,
        ));
    check_memory(
        &format!("scene `{}`", args.scene),
        &estimate,
        args.max_memory,
    )?;
    // Within --max-memory too: a recording's reset to another scene is checked against it.
    let limits = dfsph::memory::MemoryLimits::of_this_process(args.max_memory);
    let (factory, mut notes) = backends::factory(args.backend).map_err(Failure::input)?;
    let (mut sim, on) = backends::simulation(&scene, &limits, factory.as_ref())
        .map_err(|e| Failure::input(format!("scene `{}`: {e}", args.scene)))?;
    notes.extend(on);
    for note in notes {
        let _ = writeln!(std::io::stderr(), "{}", terminal_safe(&note));
    }
    // Ctrl-C also ends a long solve within an iteration, not only the run after its step.
    sim.set_stop_flag(interrupt::flag());
    if let Some(warning) = cut_short {
        let _ = writeln!(
            std::io::stderr(),
            "warning: {}",
            terminal_safe(&one_line(&warning))
        );
    }
    if let Some(note) = long_run_note(&sim, args.until) {
        let _ = writeln!(std::io::stderr(), "{note}");
    }
    if let Some(note) = scene.viscosity_note() {
        let _ = writeln!(std::io::stderr(), "{note}");
    }
    if let Some(note) = slow_gif_note(&args.format, args.every) {
        let _ = writeln!(std::io::stderr(), "{note}");
    }
    output::create_output_dir(&args.out).map_err(|e| match e {
        output::OutputDirError::Refused(m) => Failure::input(m),
        output::OutputDirError::Io(m) => Failure::io(m),
    })?;
    interrupt::install();

    let allow_blow_up = args.allow_blow_up;
    let plan = run::RunPlan {
        scene,
        // Without --until a replay runs to the recording's end.
        until: args.until.unwrap_or(f64::INFINITY),
        every: args.every,
        formats: args.format,
        out: args.out,
        picture: dfsph_io::render::RenderOptions {
            width: args.png_width,
            field: args.color_by,
            look: args.look,
            scale_max: None,
        },
    };
    // A failed write (a full disk) stops the run with one line naming the file; what was
    // completed stays (docs: `stats.csv` has every completed step).
    let kept = |e: anyhow::Error| {
        let mut f = Failure::runtime(e);
        f.message.push_str(&format!(
            "; the completed output is kept in `{}`",
            plan.out.display()
        ));
        f
    };
    let (outcome, replayed) = match &recording {
        Some(rec) => {
            let (outcome, report) =
                replay::execute(&plan, sim, rec, args.until.is_some()).map_err(kept)?;
            (outcome, Some(report))
        }
        None => (run::execute(&plan, sim).map_err(kept)?, None),
    };
    let summary = terminal_safe(&outcome.summary(&plan.out));
    let _ = match &replayed {
        Some(r) => writeln!(std::io::stdout(), "{summary}; {}", r.note),
        None => writeln!(std::io::stdout(), "{summary}"),
    };
    if outcome.interrupted {
        return Err(Failure {
            code: interrupt::EXIT_CODE,
            message: format!(
                "interrupted at step {} (t = {:.4} s); the output up to that step is complete in `{}`",
                outcome.steps,
                outcome.time,
                plan.out.display()
            ),
        });
    }
    if let Some((step, time)) = outcome.broke_at {
        return Err(Failure {
            code: SIMULATION_FAILED,
            message: format!(
                "the simulation produced non-finite values at step {step} (t = {time:.4} s) and \
                 was stopped; the output up to that step is in `{}`",
                plan.out.display()
            ),
        });
    }
    // A blow-up without NaN (`blowup`): energy the steps created, or a solve stuck at its
    // cap. Said as a warning when seen; the run is a failure unless the user accepts it.
    if let (Some(b), false) = (&outcome.blow_up, allow_blow_up) {
        return Err(Failure {
            code: SIMULATION_FAILED,
            message: format!(
                "the simulation blew up at step {} (t = {:.4} s): {}; the output is complete in \
                 `{}` (`--allow-blow-up` accepts such a run)",
                b.step,
                b.time,
                b.what,
                plan.out.display()
            ),
        });
    }
    // A clamp puts a particle that went through a wall back into the tank: the water leaked,
    // and the results are not to be trusted any more than with non-finite values. The run
    // goes on (the clamp keeps it in the tank) and writes everything, then says so.
    if outcome.clamped > 0 {
        return Err(Failure {
            code: SIMULATION_FAILED,
            message: format!(
                "{} clamped back into the tank over the run (water went through a wall{}); the \
                 output is complete in `{}`",
                if outcome.clamped == 1 {
                    "1 particle was".to_string()
                } else {
                    format!("{} particles were", outcome.clamped)
                },
                // The count includes those pushed back out of a rigid body.
                if outcome.bodies > 0 {
                    " or into a rigid body"
                } else {
                    ""
                },
                plan.out.display()
            ),
        });
    }
    match replayed.and_then(|r| r.diverged) {
        Some(why) => Err(Failure {
            code: 1,
            message: why,
        }),
        None => Ok(()),
    }
}

/// Exit code of a `run` whose simulation failed, with its output written: non-finite values
/// (the run stops at that step) or particles clamped back into the tank (it runs to the end).
/// The same code as bad input, as the scene's parameters are what let the simulation fail.
const SIMULATION_FAILED: u8 = 2;

/// The most particle snapshots `--every` may ask for over a run. Each is a file per format, and
/// finding the next snapshot time counts through the ones a step jumps over, so an `--every`
/// of 1e-300 s hung before step 1; a million frames is more than any run can usefully write.
const MAX_SNAPSHOTS: f64 = 1_000_000.0;

/// A run of at least this many steps is announced before it starts.
const LONG_RUN_STEPS: f64 = 1.0e6;

/// A `note:` line when a run to `until` would take at least [`LONG_RUN_STEPS`] steps at the
/// first step's Δt (a legal but very viscous or finely resolved scene): the user learns up
/// front why it is slow, and that Ctrl-C stops it with its output complete.
fn long_run_note(sim: &Simulation, until: Option<f64>) -> Option<String> {
    let dt = sim.next_time_step() as f64;
    let steps = (until? - sim.time()) / dt;
    (dt > 0.0 && steps >= LONG_RUN_STEPS).then(|| {
        format!(
            "note: this run will take at least {steps:.2e} steps (Δt ≤ {dt:.2e} s from the \
             scene's time step and stability bounds); Ctrl-C stops it with its output complete"
        )
    })
}

/// A `note:` line when `--format gif` is asked for snapshots closer together than a GIF
/// frame can last ([`dfsph_io::video::GIF_MIN_DELAY_CS`]): every snapshot is kept, so the GIF
/// plays slower than real time, and the user is told by how much.
fn slow_gif_note(formats: &[cli::Format], every: f64) -> Option<String> {
    let shortest = dfsph_io::video::GIF_MIN_DELAY_CS as f64 / 100.0;
    (formats.contains(&cli::Format::Gif) && every < shortest).then(|| {
        format!(
            "note: a GIF frame lasts at least {shortest} s, so with --every {every} s {} plays \
             at {:.3}× real time (the time stamps show the simulated time)",
            output::GIF_FILE,
            every / shortest
        )
    })
}

/// Refuse an `--every` that would give more than [`MAX_SNAPSHOTS`] snapshots over `--until`,
/// or, for a replay without `--until`, over the longest the recording can last (its steps at
/// the scene's largest time step). `every` is already finite and positive (the parser).
fn check_every(
    every: f64,
    until: Option<f64>,
    recording: Option<&dfsph::recording::Recording>,
    scene: &dfsph::Scene,
) -> Result<(), String> {
    let (span, what) = match (until, recording) {
        (Some(until), _) => (until, format!("over --until {until} s")),
        (None, Some(r)) => {
            let span = r.steps() as f64 * scene.time_step.max;
            (
                span,
                format!(
                    "over the recording's {} steps (up to {span} s at time_step.max; give \
                     --until to replay part of it)",
                    r.steps()
                ),
            )
        }
        (None, None) => return Ok(()),
    };
    let frames = span / every;
    if frames.is_finite() && frames <= MAX_SNAPSHOTS {
        return Ok(());
    }
    Err(format!(
        "--every {every:e} s would take {frames:.3e} snapshots {what}; at most {} are allowed \
         (use a larger --every)",
        MAX_SNAPSHOTS as u64
    ))
}

/// `dfsph2d validate`: run the cases, write the report; exit 1 when a check fails.
fn validate_cmd(args: ValidateArgs) -> Result<(), Failure> {
    if let Some(n) = args.threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n as usize)
            .build_global()
            .map_err(|e| Failure::input(format!("cannot start {n} threads: {e}")))?;
    }
    // An unavailable GPU is one line before any case runs.
    let (_, notes) = backends::factory(args.backend).map_err(Failure::input)?;
    for note in notes {
        let _ = writeln!(std::io::stderr(), "{}", terminal_safe(&note));
    }
    let settings = validate::Settings {
        quick: args.quick,
        perturb: None,
        backend: args.backend,
    };
    for scene in validate::scenes(settings) {
        check_memory(
            &format!(
                "validation scene `{}` (r = {} m)",
                scene.name, scene.particle_radius
            ),
            &scene.memory_estimate(),
            args.max_memory,
        )?;
    }
    if args.out.exists() && !args.out.is_dir() {
        return Err(Failure::input(format!(
            "output directory `{}` exists and is not a directory",
            args.out.display()
        )));
    }
    std::fs::create_dir_all(&args.out).map_err(|e| {
        Failure::io(format!(
            "cannot create output directory `{}`: {e}",
            args.out.display()
        ))
    })?;
    let outcome = validate::run(&args.out, settings).map_err(Failure::runtime)?;
    let report = terminal_safe(&outcome.report.display().to_string());
    if args.quick {
        println!(
            "validation (quick): {} smoke checks, {} failed ({:.0} s); {} comparisons with \
             experiments reported, not checked at this resolution (run `validate` without \
             --quick); report: {report}",
            outcome.checks, outcome.failed, outcome.wall_s, outcome.reported_only
        );
    } else {
        println!(
            "validation: {} checks, {} failed ({:.0} s); report: {report}",
            outcome.checks, outcome.failed, outcome.wall_s
        );
    }
    validate_exit(&outcome)
}

/// `validate`'s exit: 1, naming the count, when a counted check failed.
fn validate_exit(outcome: &validate::Outcome) -> Result<(), Failure> {
    if outcome.failed > 0 {
        return Err(Failure {
            code: 1,
            message: format!(
                "{} of {} validation checks failed; see `{}`",
                outcome.failed,
                outcome.checks,
                terminal_safe(&outcome.report.display().to_string())
            ),
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `validate --quick` exits 1 when the physics is broken: gravity 5 % too strong makes
    /// the resting tank's pressure 5 % above ρ0·g·(H − y), which its smoke check (1 %) sees.
    /// (A healthy build exiting 0 is `tests/validate.rs`.)
    #[test]
    fn quick_validation_exits_1_when_a_smoke_check_breaks() {
        let dir = tempfile::tempdir().unwrap();
        let settings = validate::Settings {
            quick: true,
            perturb: Some(|scene| scene.gravity[1] *= 1.05),
            ..Default::default()
        };
        let outcome = validate::run(dir.path(), settings).unwrap();
        let report = std::fs::read_to_string(&outcome.report).unwrap();
        let failed_row = report
            .lines()
            .find(|l| l.contains("output pressure of every particle") && l.contains("**FAIL**"));
        assert!(failed_row.is_some(), "{report}");
        let exit = validate_exit(&outcome).unwrap_err();
        assert_eq!(exit.code, 1);
        assert!(exit.message.contains("validation checks failed"));
    }
}
