//! `dfsph2d bench`: the standard benchmark of `docs/BENCHMARK.md` (see `docs/PERFORMANCE.md`).
//!
//! The dam break at several resolutions, timed from t = 0 to the case's interval with no file
//! output, once for our solver and, when the binary is built with the `salva` feature, once for
//! the peer library salva2d on the same initial particles, walls, tolerance and interval.
//!
//! Every row runs in a child process (this binary re-executed with the hidden `bench-row`
//! subcommand), so that its peak resident memory (`VmHWM` of `/proc/self/status`) is its own:
//! in one process the high-water mark only grows. Writing `5` to `/proc/self/clear_refs`
//! resets it (checked on this machine's kernel), but memory freed by one row can stay in the
//! allocator and be reused by the next, so the next row's peak would be understated; a child
//! process has none of that, gets a fresh rayon pool of the requested size (the global pool
//! cannot be resized) and starts cold like a user's run.
//!
//! Progress goes to stderr, the table to stdout, and with `--json FILE` the rows to FILE.

mod plot;
mod row;
#[cfg(feature = "salva")]
mod salva;
mod types;

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use clap::{Args, ValueEnum};

use types::positive;
pub use types::{Code, Row, RowArgs, Settings};

/// Arguments of `dfsph2d bench`.
#[derive(Debug, Args)]
pub struct BenchArgs {
    /// A small dam break (1,250 particles) for 0.1 simulated seconds: a few seconds of wall
    /// time, to check that the benchmark works. Replaces `--sizes`.
    #[arg(long)]
    pub quick: bool,

    /// Also write the rows as a JSON array to this file.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,

    /// Worker threads; a comma-separated list runs every case once per count (e.g. `1,2`).
    /// Default: one per core.
    #[arg(long, value_name = "N", value_delimiter = ',',
          value_parser = clap::value_parser!(u32).range(1..=4096))]
    pub threads: Vec<u32>,

    /// Resolutions, comma-separated: 5k (d = 0.02 m, 1 s), 20k (d = 0.01 m, 0.5 s), 80k
    /// (d = 0.005 m, 1 s), 320k (d = 0.0025 m, 0.1 s), 1m (1.28 million, d = 0.00125 m,
    /// 0.02 s). Default: 5k,20k,80k.
    #[arg(long, value_name = "SIZES", value_delimiter = ',')]
    pub sizes: Vec<Size>,

    /// Simulated seconds for every case, instead of each case's standard interval.
    #[arg(long, value_name = "SECONDS", value_parser = positive)]
    pub until: Option<f64>,

    /// Run every row this many times and report the run with the median wall time.
    #[arg(long, value_name = "K", default_value_t = 1,
          value_parser = clap::value_parser!(u32).range(1..=100))]
    pub runs: u32,

    /// Codes to run, comma-separated: dfsph2d, salva2d. Default: both when this binary was
    /// built with the `salva` feature, else dfsph2d.
    #[arg(long, value_name = "CODES", value_delimiter = ',')]
    pub codes: Vec<Code>,

    /// salva2d's fixed time step in seconds, instead of each case's default (salva2d has no
    /// CFL control; the defaults are the largest steps found stable, see PERFORMANCE.md).
    #[arg(long, value_name = "SECONDS", value_parser = positive)]
    pub salva_dt: Option<f64>,

    /// Write an SVG plot of nanoseconds per particle-step against particle count.
    #[arg(long, value_name = "FILE")]
    pub plot: Option<PathBuf>,

    /// The real-time factor people feel: the dam break with the viewer's default settings
    /// (the built-in scene as the window opens it, only the particle size set by the case),
    /// 2 simulated seconds per case, on 2 threads unless `--threads` says otherwise. The
    /// table's `rt x` column is simulated seconds per wall second.
    #[arg(long, conflicts_with_all = ["codes", "salva_dt", "quick", "from_json"])]
    pub realtime: bool,

    /// Run nothing: read rows from these JSON files (written by `--json`), then print the
    /// table and write `--json`/`--plot` from them. Comma-separated.
    #[arg(long, value_name = "FILES", value_delimiter = ',')]
    pub from_json: Vec<PathBuf>,

    /// Which backend steps dfsph2d's water: `cpu`, `gpu` (a hardware adapter, else a software
    /// one, whose times say nothing about a GPU's speed) or `auto` (a hardware adapter, else
    /// the CPU). Both the benchmark's settings and `--realtime`'s (the viewer's) run on the
    /// GPU.
    #[arg(long, value_name = "BACKEND", value_enum, default_value_t = crate::backends::Backend::Cpu)]
    pub backend: crate::backends::Backend,
}

/// Simulated seconds of each `bench --realtime` case: the dam break's first surge to the far
/// wall and back, what a person opening the window sees first.
const REALTIME_INTERVAL: f64 = 2.0;
/// Threads of `bench --realtime` unless `--threads` is given: the two cores the issue's
/// targets are stated for.
const REALTIME_THREADS: u32 = 2;

/// A standard resolution of the dam break.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Size {
    #[value(name = "quick")]
    Quick,
    #[value(name = "5k")]
    K5,
    #[value(name = "20k")]
    K20,
    #[value(name = "80k")]
    K80,
    #[value(name = "320k")]
    K320,
    /// 1.28 million particles (`scripts/gpu-bench.sh`, for the GPU backend).
    #[value(name = "1m")]
    M1,
}

impl Size {
    fn name(self) -> &'static str {
        match self {
            Size::Quick => "quick",
            Size::K5 => "5k",
            Size::K20 => "20k",
            Size::K80 => "80k",
            Size::K320 => "320k",
            Size::M1 => "1m",
        }
    }

    /// Lattice spacing d, m.
    fn spacing(self) -> f64 {
        match self {
            Size::Quick => 0.04,
            Size::K5 => 0.02,
            Size::K20 => 0.01,
            Size::K80 => 0.005,
            Size::K320 => 0.0025,
            Size::M1 => 0.00125,
        }
    }

    /// Standard simulated interval, s (docs/BENCHMARK.md: 1 s at 80k, 0.5 s at 20k; 320k is cut
    /// to 0.1 s and 1m to 0.02 s so that they finish in minutes).
    fn interval(self) -> f64 {
        match self {
            Size::Quick => 0.1,
            Size::K5 => 1.0,
            Size::K20 => 0.5,
            Size::K80 => 1.0,
            Size::K320 => 0.1,
            Size::M1 => 0.02,
        }
    }

    /// salva2d's default fixed Δt, s: 0.05 s/m · d, about our mean CFL step at each size and
    /// found stable for the dam break at 5k over 1 s (PERFORMANCE.md). Smaller steps are
    /// not safer for salva2d: its first steps push the wall-side particles out with a speed
    /// that grows as 1/Δt (its wall volumes start the fluid 3 % compressed), which makes the
    /// front run ahead.
    fn salva_dt(self) -> f64 {
        0.05 * self.spacing()
    }
}

/// Run one row and print it as one JSON line on stdout.
pub fn run_row(args: RowArgs) -> Result<(), String> {
    row::exit_with_parent(args.parent);
    if let Some(n) = args.threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n as usize)
            .build_global()
            .map_err(|e| format!("cannot start {n} threads: {e}"))?;
    }
    if args.code == Code::Salva2d && args.settings == Settings::Viewer {
        return Err("salva2d rows run with the benchmark settings only".into());
    }
    let baseline = row::proc_status_bytes("VmRSS").unwrap_or(0);
    let mut row = match args.code {
        Code::Dfsph2d => row::run_dfsph(&args)?,
        #[cfg(feature = "salva")]
        Code::Salva2d => salva::run(&args)?,
        #[cfg(not(feature = "salva"))]
        Code::Salva2d => return Err("salva2d is not compiled into this binary".into()),
    };
    row.peak_rss_bytes = row::proc_status_bytes("VmHWM").unwrap_or(0);
    row.baseline_rss_bytes = baseline;
    row.bytes_per_particle =
        row.peak_rss_bytes.saturating_sub(baseline) as f64 / row.n.max(1) as f64;
    println!("{}", serde_json::to_string(&row).expect("a row serialises"));
    Ok(())
}

/// `dfsph2d bench`.
pub fn bench(args: BenchArgs) -> Result<(), String> {
    let mut rows = Vec::new();
    if !args.from_json.is_empty() {
        for path in &args.from_json {
            let text = std::fs::read_to_string(path)
                .map_err(|e| format!("cannot read `{}`: {e}", path.display()))?;
            let mut more: Vec<Row> = serde_json::from_str(&text)
                .map_err(|e| format!("`{}` is not a bench JSON file: {e}", path.display()))?;
            rows.append(&mut more);
        }
    } else {
        let codes = if args.realtime {
            vec![Code::Dfsph2d]
        } else {
            codes(&args.codes)?
        };
        let settings = if args.realtime {
            Settings::Viewer
        } else {
            Settings::Benchmark
        };
        let sizes = if args.quick {
            vec![Size::Quick]
        } else if args.sizes.is_empty() {
            vec![Size::K5, Size::K20, Size::K80]
        } else {
            args.sizes.clone()
        };
        let threads: Vec<Option<u32>> = if args.threads.is_empty() {
            vec![args.realtime.then_some(REALTIME_THREADS)]
        } else {
            args.threads.iter().map(|&t| Some(t)).collect()
        };
        // Check the output paths before minutes of work.
        for path in [&args.json, &args.plot].into_iter().flatten() {
            check_writable(path)?;
        }
        let exe = std::env::current_exe()
            .map_err(|e| format!("cannot find this program to re-run it: {e}"))?;
        for &size in &sizes {
            for &t in &threads {
                for &code in &codes {
                    let until = args.until.unwrap_or(if args.realtime {
                        REALTIME_INTERVAL
                    } else {
                        size.interval()
                    });
                    let salva_dt = args.salva_dt.unwrap_or(size.salva_dt());
                    let mut runs = Vec::new();
                    for k in 0..args.runs {
                        eprintln!(
                            "bench: {} {} ({} particles, d = {} m, {} settings), {} s, threads {}, run {}/{}",
                            code.name(),
                            size.name(),
                            expected_particles(size.spacing()),
                            size.spacing(),
                            settings.name(),
                            until,
                            t.map_or("all".to_string(), |t| t.to_string()),
                            k + 1,
                            args.runs
                        );
                        runs.push(run_child(
                            &exe,
                            code,
                            size,
                            settings,
                            until,
                            t,
                            salva_dt,
                            args.backend,
                        )?);
                    }
                    rows.push(median_row(runs));
                }
            }
        }
    }
    print!("{}", table(&rows));
    if let Some(path) = &args.json {
        let text = serde_json::to_string_pretty(&rows).expect("rows serialise");
        std::fs::write(path, text + "\n")
            .map_err(|e| format!("cannot write `{}`: {e}", path.display()))?;
        eprintln!(
            "bench: rows written to {}",
            dfsph_io::input::terminal_safe(&path.display().to_string())
        );
    }
    if let Some(path) = &args.plot {
        std::fs::write(path, plot::svg(&rows))
            .map_err(|e| format!("cannot write `{}`: {e}", path.display()))?;
        eprintln!(
            "bench: plot written to {}",
            dfsph_io::input::terminal_safe(&path.display().to_string())
        );
    }
    Ok(())
}

/// The codes to run, with a clear note when salva2d is asked for (or would be run) but was not
/// compiled in.
fn codes(asked: &[Code]) -> Result<Vec<Code>, String> {
    const HOW: &str = "build with the `salva` feature: \
        `cargo run --release -p dfsph-app --features salva -- bench`";
    let compiled = cfg!(feature = "salva");
    if asked.is_empty() {
        if compiled {
            return Ok(vec![Code::Dfsph2d, Code::Salva2d]);
        }
        eprintln!(
            "note: salva2d (the peer in docs/BENCHMARK.md) is not compiled into this binary; {HOW}"
        );
        return Ok(vec![Code::Dfsph2d]);
    }
    if asked.contains(&Code::Salva2d) && !compiled {
        return Err(format!("salva2d is not compiled into this binary; {HOW}"));
    }
    let mut codes = asked.to_vec();
    codes.dedup();
    Ok(codes)
}

fn check_writable(path: &Path) -> Result<(), String> {
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        return Err(format!(
            "cannot write `{}`: directory `{}` does not exist",
            path.display(),
            dir.display()
        ));
    }
    if path.is_dir() {
        return Err(format!(
            "cannot write `{}`: it is a directory",
            path.display()
        ));
    }
    Ok(())
}

/// Fluid particles of the dam-break column at spacing d.
fn expected_particles(d: f64) -> usize {
    let count = |len: f64| ((len / d) + 1.0e-6).floor() as usize;
    count(1.0) * count(2.0)
}

/// Run one row in a child process and parse its JSON line (each argument is one of the
/// row's command-line arguments).
#[allow(clippy::too_many_arguments)]
fn run_child(
    exe: &Path,
    code: Code,
    size: Size,
    settings: Settings,
    until: f64,
    threads: Option<u32>,
    salva_dt: f64,
    backend: crate::backends::Backend,
) -> Result<Row, String> {
    let mut cmd = Command::new(exe);
    cmd.args(["bench-row", "--code", code.name(), "--case", size.name()])
        .args(["--backend", backend.name()])
        .args(["--spacing", &size.spacing().to_string()])
        .args(["--until", &until.to_string()])
        .args(["--salva-dt", &salva_dt.to_string()])
        .args(["--settings", settings.name()])
        .args(["--parent", &std::process::id().to_string()]);
    if let Some(t) = threads {
        cmd.args(["--threads", &t.to_string()]);
    }
    let out = cmd
        .stdin(Stdio::null())
        .stderr(Stdio::inherit())
        .output()
        .map_err(|e| format!("cannot run `{}`: {e}", exe.display()))?;
    if !out.status.success() {
        return Err(format!(
            "the {} {} row failed ({})",
            code.name(),
            size.name(),
            out.status
        ));
    }
    let text = String::from_utf8_lossy(&out.stdout);
    serde_json::from_str(text.trim()).map_err(|e| {
        format!(
            "the {} {} row printed no row: {e}",
            code.name(),
            size.name()
        )
    })
}

/// The run with the median wall time, carrying every run's wall time.
fn median_row(mut runs: Vec<Row>) -> Row {
    let walls: Vec<f64> = runs.iter().map(|r| r.wall_seconds).collect();
    runs.sort_by(|a, b| a.wall_seconds.total_cmp(&b.wall_seconds));
    let mut row = runs.swap_remove((runs.len() - 1) / 2);
    row.wall_seconds_runs = walls;
    row
}

/// What the table's columns are, printed under it.
const TABLE_LEGEND: &str = "\
thr: worker threads; n: fluid particles; sim s: simulated seconds; wall s: wall seconds of the
  stepping (set-up excluded; the median of the runs); rt x: simulated seconds per wall second
  (1 = real time); steps: time steps; mean dt: mean step, s; dens, div: mean iterations a step
  of the density and divergence solves; p-steps/s: particle steps per wall second; ns/p-st:
  nanoseconds per particle step; peak MiB: peak resident memory; B/p: bytes per particle;
  front: surge front at the end, m from the left wall; fr@0.4: the front at t = 0.4 s (about
  2.0 m for the dam break)
";

/// The benchmark table and its legend, then the peer ratios.
pub fn table(rows: &[Row]) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let opt = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.1}"));
    let _ = writeln!(
        s,
        "{:<8} {:>5} {:>3} {:>7} {:>6} {:>8} {:>6} {:>6} {:>9} {:>6} {:>6} {:>10} {:>8} {:>8} {:>6} {:>7} {:>7}",
        "code", "case", "thr", "n", "sim s", "wall s", "rt x", "steps", "mean dt", "dens", "div",
        "p-steps/s", "ns/p-st", "peak MiB", "B/p", "front", "fr@0.4"
    );
    for r in rows {
        let mut runs = if r.wall_seconds_runs.len() > 1 {
            format!(" (median of {})", r.wall_seconds_runs.len())
        } else {
            String::new()
        };
        if r.settings == Settings::Viewer {
            runs.push_str(" (viewer settings)");
        }
        // The CPU is the default and says nothing; anything else is named.
        if !r.backend.is_empty() && r.backend != "cpu" {
            runs.push_str(&format!(" (on {})", r.backend));
        }
        let _ = writeln!(
            s,
            "{:<8} {:>5} {:>3} {:>7} {:>6.3} {:>8.2} {:>6.3} {:>6} {:>9.2e} {:>6} {:>6} {:>10.3e} {:>8.1} {:>8.1} {:>6.0} {:>7.3} {:>7}{}",
            r.code.name(),
            r.case,
            r.threads,
            r.n,
            r.sim_seconds,
            r.wall_seconds,
            r.sim_seconds / r.wall_seconds.max(1.0e-12),
            r.steps,
            r.mean_dt,
            opt(r.avg_density_iterations),
            opt(r.avg_divergence_iterations),
            r.particle_steps_per_second,
            r.ns_per_particle_step,
            r.peak_rss_bytes as f64 / (1024.0 * 1024.0),
            r.bytes_per_particle,
            r.front_x,
            r.front_x_at_0_4.map_or("-".to_string(), |v| format!("{v:.3}")),
            runs
        );
    }
    s.push_str(TABLE_LEGEND);
    for ours in rows.iter().filter(|r| r.code == Code::Dfsph2d) {
        for peer in rows
            .iter()
            // Same case, threads and simulated interval (within 10 %).
            .filter(|r| {
                r.code == Code::Salva2d
                    && r.case == ours.case
                    && r.threads == ours.threads
                    && (r.sim_seconds - ours.sim_seconds).abs() <= 0.1 * ours.sim_seconds
            })
        {
            let _ = writeln!(
                s,
                "{} threads {}: salva2d / dfsph2d wall time per simulated second = {:.2} / {:.2} = {:.2}x",
                ours.case,
                ours.threads,
                peer.wall_per_sim_second,
                ours.wall_per_sim_second,
                peer.wall_per_sim_second / ours.wall_per_sim_second
            );
        }
    }
    s
}
