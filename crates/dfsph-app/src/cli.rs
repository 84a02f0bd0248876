//! The command line, declared with clap. Argument values are checked here (positive finite
//! times, known formats, thread counts), so a bad argument is reported before anything is
//! read or written.

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand, ValueEnum};

use crate::backends::Backend;

/// dfsph2d: an interactive 2D water simulator (Divergence-Free SPH) and a headless runner.
///
/// Without a subcommand, opens the viewer on the dam break.
#[derive(Debug, Parser)]
#[command(name = "dfsph2d", version)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Option<Command>,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Open the interactive viewer on a scene.
    View(ViewArgs),
    /// List the built-in scenes, one per line: name and description.
    Scenes,
    /// Run a scene headless and write statistics and particle snapshots.
    ///
    /// Exits with 2, after writing its output, when the simulation produced non-finite values
    /// (it stops at that step) or clamped particles back into the tank (water went through a
    /// wall; the run goes on to the end); with 74 when a write fails (a full disk, an output
    /// directory that cannot be created), naming the file and keeping the statistics and
    /// frames completed before it; with 130 when stopped by Ctrl-C, SIGTERM or SIGHUP (after
    /// the current step, its files complete).
    /// stats.csv and particles/index.csv grow a line at a time, so even a killed run keeps
    /// the statistics of its completed steps.
    Run(RunArgs),
    /// Drive a scene with a seeded random sequence of the viewer's actions and check it.
    #[command(long_about = STRESS_ABOUT)]
    Stress(StressArgs),
    /// Run the validation cases against experiments and write DIR/report.md with plots;
    /// exits with 1 if any check fails.
    Validate(ValidateArgs),
    /// The standard benchmark (docs/BENCHMARK.md, docs/PERFORMANCE.md): the dam break at several
    /// resolutions, with the salva2d peer when built with `--features salva`.
    Bench(crate::bench::BenchArgs),
    /// One benchmark row in its own process (used by `bench`).
    #[command(name = "bench-row", hide = true)]
    BenchRow(crate::bench::RowArgs),
}

const STRESS_ABOUT: &str = "\
Drive a scene with a seeded random sequence of the viewer's actions, for K steps, checking the
simulation after every action and every step. Prints one summary line (with the deepest water
seen: the fluid's area per unit width in the fullest strip across gravity); exits with code 1
at the first violation, naming it and its step.

Actions (all at full strength, anywhere in and around the tank): shake the tank left and right,
push and pull with the pointer, pour (up to the viewer's particle budget: the scene's fluid and
as much again, at least 2,000 more, within max_particles), draw walls through the water, erase,
tilt and scale gravity (0-30 m/s², ±45°), change viscosity (XSPH 0-0.5, kinematic 0-0.1 m²/s)
live, change the solver's tolerances (density 0.001-0.5 %, divergence 0.01-10 %, 100-1000
iterations) and the time step (CFL 0.1-0.6, max Δt 0.25-2.5 ms) live, and reset. Rigid bodies:
at the start (and after each reset) two to four boxes and circles of 100-8,000 kg/m³ dropped
downstream of the water, on the floor and in the air, for the surge to slam into the far wall;
later more dropped from above (up to 8), and bodies grabbed and dragged about. (The viewer's
time scale only changes how many steps a frame takes, which a step-by-step run does not see.)

Violations:
  - a non-finite position, velocity or statistic, or a particle the solver reset because it
    became non-finite;
  - a fluid particle outside the tank (beyond the centre line of its first wall layer, at least
    d/2 outside the interior);
  - a fluid particle count that differs from initial + poured − erased (− the water a dropped
    body covered), or exceeds the budget;
  - a particle clamped back into the tank or pushed out of a rigid body (a wall leaked);
  - a fluid particle inside a rigid body: its centre more than d/2 within the body's outline;
  - a rigid body that is not finite, or reaches more than one spacing d out of the tank;
  - a density error above the bound: the largest single-particle compression after the density
    solve, (ρ − ρ0)/ρ0, above --density-bound percent (default 5 %) in any step;
  - a panic in the solver.

With --record FILE the actions are written as they happen (docs/recording.md); `dfsph2d run
SCENE --replay FILE --out DIR` replays them and checks that it reaches the same final state.";

#[derive(Debug, Args)]
pub struct ViewArgs {
    /// A built-in scene name (see `dfsph2d scenes`) or the path of a JSON scene file.
    /// Default: dam-break.
    #[arg(value_name = "SCENE")]
    pub scene: Option<String>,

    /// Close the viewer after this many seconds of wall-clock time (0: after the first
    /// frame).
    #[arg(long, value_name = "SECONDS", value_parser = non_negative_seconds)]
    pub exit_after: Option<f64>,

    /// When the viewer closes after --exit-after, save into this directory: particles.csv,
    /// screenshot.png, session.json, and scene.json, the state as a scene that `run` and
    /// `view` load.
    #[arg(long, value_name = "DIR")]
    pub save_on_exit: Option<PathBuf>,

    /// Record every action with the step at which it applies into FILE (JSON lines, see
    /// docs/recording.md), for `dfsph2d run SCENE --replay FILE`.
    #[arg(long, value_name = "FILE")]
    pub record: Option<PathBuf>,

    /// Refuse a scene whose estimated memory is above BYTES (suffixes K, M, G, T are powers
    /// of 1024: 512M, 2G). The memory available, a cgroup's limit and the address-space limit
    /// (ulimit -v) are checked in any case.
    #[arg(long, value_name = "BYTES", value_parser = dfsph::memory::parse_bytes)]
    pub max_memory: Option<u64>,

    /// Which backend steps the water: `cpu`; `gpu`, on a hardware adapter, else on a software
    /// one such as Mesa's lavapipe (right, but slow), an error where there is neither; or
    /// `auto`, the GPU on a hardware adapter, else the CPU. The GPU backend does both DFSPH
    /// solves; it hands WCSPH, Wendland C2 and rigid bodies to the CPU and says why.
    #[arg(long, value_name = "BACKEND", value_enum, default_value_t = Backend::Cpu)]
    pub backend: Backend,
}

#[derive(Debug, Args)]
pub struct StressArgs {
    /// A built-in scene name (see `dfsph2d scenes`) or the path of a JSON scene file.
    #[arg(value_name = "SCENE", default_value = "dam-break")]
    pub scene: String,

    /// Seed of the random action sequence.
    #[arg(long, value_name = "N", default_value_t = 0)]
    pub seed: u64,

    /// Steps to run.
    #[arg(long, value_name = "K", default_value_t = 1000,
          value_parser = clap::value_parser!(u64).range(1..=100_000_000))]
    pub steps: u64,

    /// Largest allowed single-particle density error (compression), percent.
    #[arg(long, value_name = "PCT", default_value = "5", value_parser = positive_percent)]
    pub density_bound: f64,

    /// Drop no rigid bodies in (the scene's own stay): the water's actions alone, which keeps
    /// a `--backend gpu` run on the device (it has no rigid bodies yet). The other actions of
    /// a seed stay as they are.
    #[arg(long)]
    pub no_bodies: bool,

    /// Write the actions, with the step at which each applies, into FILE.
    #[arg(long, value_name = "FILE")]
    pub record: Option<PathBuf>,

    /// Worker threads (default: one per core), 1 to 1,024: as many as a recording may name,
    /// so that what is recorded can be replayed.
    #[arg(long, value_name = "N", allow_negative_numbers = true,
          value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub threads: Option<u32>,

    /// Refuse a scene whose estimated memory is above BYTES (suffixes K, M, G, T are powers
    /// of 1024: 512M, 2G). The memory available, a cgroup's limit and the address-space limit
    /// (ulimit -v) are checked in any case.
    #[arg(long, value_name = "BYTES", value_parser = dfsph::memory::parse_bytes)]
    pub max_memory: Option<u64>,

    /// Which backend steps the water: `cpu`; `gpu`, on a hardware adapter, else on a software
    /// one such as Mesa's lavapipe (right, but slow), an error where there is neither; or
    /// `auto`, the GPU on a hardware adapter, else the CPU. The GPU backend does both DFSPH
    /// solves; it hands WCSPH, Wendland C2 and rigid bodies to the CPU and says why.
    #[arg(long, value_name = "BACKEND", value_enum, default_value_t = Backend::Cpu)]
    pub backend: Backend,
}

#[derive(Debug, Args)]
pub struct RunArgs {
    /// A built-in scene name (see `dfsph2d scenes`) or the path of a JSON scene file.
    #[arg(value_name = "SCENE")]
    pub scene: String,

    /// Simulated time to run, in seconds (with --replay: by default until the recording ends).
    #[arg(long, value_name = "SECONDS", allow_negative_numbers = true, value_parser = positive_seconds,
          required_unless_present = "replay")]
    pub until: Option<f64>,

    /// Replay the actions recorded in FILE (`view --record`, `stress --record`), each at its
    /// step, and check that the final state matches the recording's.
    #[arg(long, value_name = "FILE")]
    pub replay: Option<PathBuf>,

    /// Output directory, created if missing. In an existing DIR, a run first removes the
    /// files an earlier run wrote there (listed in DIR/.dfsph2d-manifest: frames, stats.csv,
    /// probes.csv, particles.pvd, ...) and overwrites any other file of a name it writes;
    /// every other file is kept. DIR/particles must not be a symbolic link; a symbolic link
    /// where a file goes is replaced by the file, never written through.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,

    /// Simulated time between particle snapshots, in seconds (at most 1,000,000 snapshots over
    /// the run).
    #[arg(long, value_name = "SECONDS", default_value = "0.05", allow_negative_numbers = true,
          value_parser = positive_seconds)]
    pub every: f64,

    /// Snapshot formats, comma-separated: csv, vtk (.vtu for ParaView), png, and the videos
    /// gif (DIR/video.gif) and mp4 (DIR/video.mp4, encoded by ffmpeg, which must be on PATH):
    /// one frame per snapshot, stamped with its simulated time, each shown for --every
    /// seconds so the video plays at real-time speed (a GIF frame lasts at least 0.02 s: a
    /// smaller --every plays in slow motion).
    #[arg(
        long,
        value_name = "FORMATS",
        value_delimiter = ',',
        default_value = "csv",
        num_args = 1..,
    )]
    pub format: Vec<Format>,

    /// Worker threads (default: one per core), 1 to 1,024: as many as a recording may name,
    /// so that what is recorded can be replayed.
    #[arg(long, value_name = "N", allow_negative_numbers = true,
          value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub threads: Option<u32>,

    /// Refuse a scene whose estimated memory is above BYTES (suffixes K, M, G, T are powers
    /// of 1024: 512M, 2G). The memory available, a cgroup's limit and the address-space limit
    /// (ulimit -v) are checked in any case.
    #[arg(long, value_name = "BYTES", value_parser = dfsph::memory::parse_bytes)]
    pub max_memory: Option<u64>,

    /// Which backend steps the water: `cpu`; `gpu`, on a hardware adapter, else on a software
    /// one such as Mesa's lavapipe (right, but slow), an error where there is neither; or
    /// `auto`, the GPU on a hardware adapter, else the CPU. The GPU backend does both DFSPH
    /// solves; it hands WCSPH, Wendland C2 and rigid bodies to the CPU and says why.
    #[arg(long, value_name = "BACKEND", value_enum, default_value_t = Backend::Cpu)]
    pub backend: Backend,

    /// Width of PNG frames in pixels.
    #[arg(long, value_name = "PIXELS", default_value_t = 800,
          value_parser = clap::value_parser!(u32).range(64..=16384))]
    pub png_width: u32,

    /// What colours the water in PNG frames and videos: speed (m/s), pressure (Pa) or
    /// density (the density error, ±1 % of ρ0), as the viewer's `c` key cycles them. Each
    /// scale is fixed for the whole run (speed: a fall from the tank's top; pressure: the
    /// hydrostatic pressure at the bottom of the deepest water).
    #[arg(long, value_name = "FIELD", default_value = "speed", value_parser = color_by)]
    pub color_by: dfsph_io::render::FrameField,

    /// How PNG frames and videos draw the water: surface (a smooth surface with a light rim,
    /// as the viewer opens) or particles (one dot per particle, the viewer's `p` key).
    #[arg(long, value_name = "LOOK", default_value = "surface", value_parser = look)]
    pub look: dfsph_io::render::WaterLook,

    /// Exit 0 even when the run blew up without NaN: the water's energy rose by more than
    /// 2 % of M·g·H without an action, or the density solve ended at its iteration cap 20
    /// steps in a row. Without it such a run still writes everything, warns when it
    /// happens, and exits with 2.
    #[arg(long)]
    pub allow_blow_up: bool,
}

#[derive(Debug, Args)]
pub struct ValidateArgs {
    /// Coarse resolutions and shorter runs (about a minute): a smoke test of the machinery.
    #[arg(long)]
    pub quick: bool,

    /// Output directory for report.md and the plots (created if missing; files in it are
    /// overwritten).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,

    /// Worker threads (default: one per core), 1 to 1,024: as many as a recording may name,
    /// so that what is recorded can be replayed.
    #[arg(long, value_name = "N", allow_negative_numbers = true,
          value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub threads: Option<u32>,

    /// Refuse a scene whose estimated memory is above BYTES (suffixes K, M, G, T are powers
    /// of 1024: 512M, 2G). The memory available, a cgroup's limit and the address-space limit
    /// (ulimit -v) are checked in any case.
    #[arg(long, value_name = "BYTES", value_parser = dfsph::memory::parse_bytes)]
    pub max_memory: Option<u64>,

    /// Which backend steps the water: `cpu`; `gpu`, on a hardware adapter, else on a software
    /// one such as Mesa's lavapipe (right, but slow), an error where there is neither; or
    /// `auto`, the GPU on a hardware adapter, else the CPU. The GPU backend does both DFSPH
    /// solves; it hands WCSPH, Wendland C2 and rigid bodies to the CPU and says why.
    #[arg(long, value_name = "BACKEND", value_enum, default_value_t = Backend::Cpu)]
    pub backend: Backend,
}

/// A snapshot file format.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, ValueEnum)]
pub enum Format {
    /// `NNNNN.csv`: x,y,vx,vy,density,pressure.
    Csv,
    /// `NNNNN.vtu`: VTK XML UnstructuredGrid, plus `particles.pvd` listing the frame times.
    Vtk,
    /// `NNNNN.png`: a picture of the frame, fluid coloured by speed.
    Png,
    /// `video.gif`: the pictures of every frame as one animated GIF.
    Gif,
    /// `video.mp4`: the pictures of every frame as one H.264 video, encoded by ffmpeg.
    Mp4,
}

impl Format {
    /// File extension of this format's files.
    pub fn extension(self) -> &'static str {
        match self {
            Format::Csv => "csv",
            Format::Vtk => "vtu",
            Format::Png => "png",
            Format::Gif => "gif",
            Format::Mp4 => "mp4",
        }
    }

    /// One file for the whole run (`video.gif`), not one per snapshot.
    pub fn is_video(self) -> bool {
        matches!(self, Format::Gif | Format::Mp4)
    }

    /// Drawn by the rasteriser (a PNG, or a video's frame).
    pub fn is_picture(self) -> bool {
        matches!(self, Format::Png | Format::Gif | Format::Mp4)
    }
}

/// A time in seconds: a finite number greater than zero.
fn positive_seconds(text: &str) -> Result<f64, String> {
    let v: f64 = text
        .trim()
        .parse()
        .map_err(|_| format!("`{text}` is not a number of seconds"))?;
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(format!(
            "must be a finite number of seconds greater than 0, got {text}"
        ))
    }
}

/// A percentage: a finite number greater than zero.
fn positive_percent(text: &str) -> Result<f64, String> {
    let v: f64 = text
        .trim()
        .parse()
        .map_err(|_| format!("`{text}` is not a percentage"))?;
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(format!(
            "must be a finite percentage greater than 0, got {text}"
        ))
    }
}

/// A time in seconds: a finite number, zero or more.
fn non_negative_seconds(text: &str) -> Result<f64, String> {
    let v: f64 = text
        .trim()
        .parse()
        .map_err(|_| format!("`{text}` is not a number of seconds"))?;
    if v.is_finite() && v >= 0.0 {
        Ok(v)
    } else {
        Err(format!(
            "must be a finite number of seconds, 0 or more, got {text}"
        ))
    }
}

/// `--color-by`: one of the names of [`dfsph_io::render::FrameField::NAMES`].
fn color_by(name: &str) -> Result<dfsph_io::render::FrameField, String> {
    one_of(&dfsph_io::render::FrameField::NAMES, "a field", name)
}

/// `--look`: one of the names of [`dfsph_io::render::WaterLook::NAMES`].
fn look(name: &str) -> Result<dfsph_io::render::WaterLook, String> {
    one_of(&dfsph_io::render::WaterLook::NAMES, "a look", name)
}

/// The value `name` stands for in `names`, or a message that lists them all (`what`: what
/// a name names, "a field").
fn one_of<T: Copy>(names: &[(&str, T)], what: &str, name: &str) -> Result<T, String> {
    dfsph_io::render::by_name(names, name).ok_or_else(|| {
        let all: Vec<&str> = names.iter().map(|(n, _)| *n).collect();
        format!("{name:?} is not {what}; one of {}", all.join(", "))
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    #[test]
    fn cli_definition_is_consistent() {
        Cli::command().debug_assert();
    }

    #[test]
    fn seconds_must_be_positive_and_finite() {
        assert_eq!(positive_seconds("0.05"), Ok(0.05));
        for bad in ["0", "-1", "inf", "NaN", "abc", ""] {
            assert!(positive_seconds(bad).is_err(), "{bad}");
        }
        assert_eq!(non_negative_seconds("0"), Ok(0.0));
        assert!(non_negative_seconds("-0.5").is_err());
        assert!(non_negative_seconds("inf").is_err());
    }

    #[test]
    fn formats_are_comma_separated() {
        let parse = |formats: &str| {
            let cli = Cli::try_parse_from([
                "dfsph2d", "run", "drop", "--until", "1", "--out", "o", "--format", formats,
            ])?;
            let Some(Command::Run(args)) = cli.command else {
                panic!("expected run");
            };
            Ok::<_, clap::Error>(args)
        };
        let args = parse("csv,vtk,png").unwrap();
        assert_eq!(args.format, [Format::Csv, Format::Vtk, Format::Png]);
        assert_eq!(args.every, 0.05);
        assert!(parse("csv,avi").is_err());
        let args = parse("png,gif,mp4").unwrap();
        assert_eq!(args.format, [Format::Png, Format::Gif, Format::Mp4]);
    }
}
