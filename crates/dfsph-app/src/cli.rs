//! The command line, declared with clap. Argument values are checked here (positive finite
//! times, known formats, thread counts), so a bad argument is reported before anything is
//! read or written.

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand, ValueEnum};

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
    Run(RunArgs),
}

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

    /// When the viewer closes, save the scene and a snapshot into this directory.
    #[arg(long, value_name = "DIR")]
    pub save_on_exit: Option<PathBuf>,
}

#[derive(Debug, Args)]
pub struct RunArgs {
    /// A built-in scene name (see `dfsph2d scenes`) or the path of a JSON scene file.
    #[arg(value_name = "SCENE")]
    pub scene: String,

    /// Simulated time to run, in seconds.
    #[arg(long, value_name = "SECONDS", value_parser = positive_seconds)]
    pub until: f64,

    /// Output directory (created if missing; existing files in it are overwritten).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,

    /// Simulated time between particle snapshots, in seconds.
    #[arg(long, value_name = "SECONDS", default_value = "0.05", value_parser = positive_seconds)]
    pub every: f64,

    /// Snapshot formats, comma-separated: csv, vtk (.vtu for ParaView), png.
    #[arg(
        long,
        value_name = "FORMATS",
        value_delimiter = ',',
        default_value = "csv",
        num_args = 1..,
    )]
    pub format: Vec<Format>,

    /// Worker threads (default: one per core).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=4096))]
    pub threads: Option<u32>,

    /// Width of PNG frames in pixels.
    #[arg(long, value_name = "PIXELS", default_value_t = 800,
          value_parser = clap::value_parser!(u32).range(64..=16384))]
    pub png_width: u32,
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
}

impl Format {
    /// File extension of this format's snapshot files.
    pub fn extension(self) -> &'static str {
        match self {
            Format::Csv => "csv",
            Format::Vtk => "vtu",
            Format::Png => "png",
        }
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
        let cli = Cli::try_parse_from([
            "dfsph2d",
            "run",
            "drop",
            "--until",
            "1",
            "--out",
            "o",
            "--format",
            "csv,vtk,png",
        ])
        .unwrap();
        let Some(Command::Run(args)) = cli.command else {
            panic!("expected run");
        };
        assert_eq!(args.format, [Format::Csv, Format::Vtk, Format::Png]);
        assert_eq!(args.every, 0.05);
        assert!(Cli::try_parse_from([
            "dfsph2d", "run", "drop", "--until", "1", "--out", "o", "--format", "csv,gif",
        ])
        .is_err());
    }
}
