//! `dfsph2d`: the interactive 2D water simulator and its headless runner.
//!
//! ```text
//! dfsph2d                                   open the viewer on the dam break
//! dfsph2d view [SCENE] [--exit-after S] [--save-on-exit DIR]
//! dfsph2d scenes                            list built-in scenes
//! dfsph2d run SCENE --until S --out DIR [--every S] [--format csv,vtk,png] [--threads N]
//! ```
//!
//! Exit codes: 0 success; 2 bad arguments or scene (nothing written), or a simulation that
//! produced non-finite values; 1 any other failure (I/O while writing, the viewer).

mod cli;
mod output;
mod run;
mod scene_arg;
mod schedule;
mod view;

use std::process::ExitCode;

use clap::Parser;
use dfsph::{scene, Simulation};

use cli::{Cli, Command, RunArgs, ViewArgs};
use scene_arg::{load_scene, one_line};

/// A failure with its exit code; printed as one `error: ...` line.
struct Failure {
    code: u8,
    message: String,
}

impl Failure {
    /// Bad input (arguments, scene, output path): exit code 2.
    fn input(message: impl Into<String>) -> Self {
        Self {
            code: 2,
            message: message.into(),
        }
    }

    /// Anything else: exit code 1.
    fn runtime(error: anyhow::Error) -> Self {
        Self {
            code: 1,
            message: format!("{error:#}"),
        }
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        None => view(ViewArgs {
            scene: None,
            exit_after: None,
            save_on_exit: None,
        }),
        Some(Command::View(args)) => view(args),
        Some(Command::Scenes) => {
            list_scenes();
            Ok(())
        }
        Some(Command::Run(args)) => run(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(f) => {
            eprintln!("error: {}", one_line(&f.message));
            ExitCode::from(f.code)
        }
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
    view::open(scene, args.exit_after, args.save_on_exit).map_err(Failure::runtime)
}

fn run(args: RunArgs) -> Result<(), Failure> {
    // Everything is validated before the output directory is touched.
    if let Some(n) = args.threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n as usize)
            .build_global()
            .map_err(|e| Failure::input(format!("cannot start {n} threads: {e}")))?;
    }
    let scene = load_scene(&args.scene).map_err(Failure::input)?;
    output::check_output_dir(&args.out).map_err(Failure::input)?;
    let sim = Simulation::new(&scene)
        .map_err(|e| Failure::input(format!("scene `{}`: {e}", args.scene)))?;
    output::create_output_dir(&args.out).map_err(Failure::input)?;

    let plan = run::RunPlan {
        scene,
        until: args.until,
        every: args.every,
        formats: args.format,
        out: args.out,
        png_width: args.png_width,
    };
    let outcome = run::execute(&plan, sim).map_err(Failure::runtime)?;
    println!("{}", outcome.summary(&plan.out));
    match outcome.broke_at {
        Some((step, time)) => Err(Failure {
            code: 2,
            message: format!(
                "the simulation produced non-finite values at step {step} (t = {time:.4} s) and \
                 was stopped; the output up to that step is in `{}`",
                plan.out.display()
            ),
        }),
        None => Ok(()),
    }
}
