//! What the benchmark's parts share: the codes, the settings, one row's arguments and its
//! result.

use clap::{Args, ValueEnum};
use serde::{Deserialize, Serialize};

/// Arguments of the hidden `dfsph2d bench-row`: one row, printed as JSON on stdout.
#[derive(Debug, Args)]
pub struct RowArgs {
    #[arg(long)]
    pub code: Code,
    #[arg(long)]
    pub case: String,
    /// Lattice spacing d, m.
    #[arg(long, value_parser = positive)]
    pub spacing: f64,
    /// Simulated seconds.
    #[arg(long, value_parser = positive)]
    pub until: f64,
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=4096))]
    pub threads: Option<u32>,
    /// salva2d's fixed Δt, s.
    #[arg(long, value_parser = positive)]
    pub salva_dt: Option<f64>,
    /// Which settings the dam break runs with.
    #[arg(long, value_enum, default_value_t = Settings::Benchmark)]
    pub settings: Settings,
    /// Process id of the `dfsph2d bench` that started this row: the row ends if that process
    /// is gone before the row has asked to be killed with it.
    #[arg(long)]
    pub parent: Option<u32>,
    /// Which backend steps the water.
    #[arg(long, value_enum, default_value_t = crate::backends::Backend::Cpu)]
    pub backend: crate::backends::Backend,
}

/// A code under test.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, ValueEnum, Serialize, Deserialize)]
pub enum Code {
    /// This project's solver.
    #[value(name = "dfsph2d")]
    #[serde(rename = "dfsph2d")]
    Dfsph2d,
    /// The peer library salva2d (DFSPH), from crates.io.
    #[value(name = "salva2d")]
    #[serde(rename = "salva2d")]
    Salva2d,
}

impl Code {
    pub fn name(self) -> &'static str {
        match self {
            Code::Dfsph2d => "dfsph2d",
            Code::Salva2d => "salva2d",
        }
    }
}

/// The solver settings of a row's dam break.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, ValueEnum, Serialize, Deserialize)]
pub enum Settings {
    /// docs/BENCHMARK.md's (tolerances, CFL 0.2, Δt up to 5 ms, XSPH 0.01).
    #[default]
    #[value(name = "benchmark")]
    #[serde(rename = "benchmark")]
    Benchmark,
    /// The built-in scene's, as the viewer opens it (`bench --realtime`).
    #[value(name = "viewer")]
    #[serde(rename = "viewer")]
    Viewer,
}

impl Settings {
    pub(super) fn name(self) -> &'static str {
        match self {
            Settings::Benchmark => "benchmark",
            Settings::Viewer => "viewer",
        }
    }
}

/// One benchmark row: one code at one resolution and thread count. The keys are the JSON
/// schema of `--json` (documented in docs/PERFORMANCE.md).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Row {
    /// `dfsph2d` or `salva2d`.
    pub code: Code,
    /// Resolution name: quick, 5k, 20k, 80k, 320k.
    pub case: String,
    /// Fluid particles.
    pub n: usize,
    /// Boundary particles.
    pub n_boundary: usize,
    /// Lattice spacing d, m.
    pub spacing: f64,
    /// Simulated time at the end (the last step may overshoot the interval), s.
    pub sim_seconds: f64,
    /// Wall time of the stepping loop (set-up excluded), s.
    pub wall_seconds: f64,
    /// Wall time of building the initial state, s.
    pub setup_seconds: f64,
    /// Time steps taken.
    pub steps: u64,
    /// Mean Δt, s.
    pub mean_dt: f64,
    /// How Δt was chosen.
    pub dt_rule: String,
    /// `n · steps / wall_seconds`.
    pub particle_steps_per_second: f64,
    /// `1e9 / particle_steps_per_second`.
    pub ns_per_particle_step: f64,
    /// Wall seconds per simulated second.
    pub wall_per_sim_second: f64,
    /// Mean density-solve iterations per step (null for salva2d, which does not report them).
    pub avg_density_iterations: Option<f64>,
    /// Mean divergence-solve iterations per step (null for salva2d).
    pub avg_divergence_iterations: Option<f64>,
    /// Peak resident memory of the process (`VmHWM`), bytes.
    pub peak_rss_bytes: u64,
    /// Resident memory before the state was built (`VmRSS`), bytes.
    pub baseline_rss_bytes: u64,
    /// `(peak_rss_bytes − baseline_rss_bytes) / n`.
    pub bytes_per_particle: f64,
    /// Rayon worker threads.
    pub threads: usize,
    /// Surge front at the end: the largest x, m, of a fluid particle with at least 3 fluid
    /// neighbours, from the tank's left wall.
    pub front_x: f64,
    /// The front at the first step ending at or after t = 0.4 s (sanity: near 2.0 m).
    pub front_x_at_0_4: Option<f64>,
    /// Particles put back into the tank by the last-resort clamp (dfsph2d) or found outside
    /// the tank at the end (salva2d). Should be 0.
    pub leaked: u64,
    /// Particles that became NaN/infinite. Must be 0.
    pub non_finite: u64,
    /// Attempts redone with half the Δt, summed over the steps (dfsph2d; each costs one more
    /// solve, and the steps after it start shorter). 0 for salva2d and in rows saved before
    /// it was recorded.
    #[serde(default)]
    pub retries: u64,
    /// What stepped the water (`cpu`, or the GPU backend and its adapter); empty for salva2d
    /// and in rows saved before it was recorded.
    #[serde(default)]
    pub backend: String,
    /// XSPH viscosity coefficient.
    pub xsph: f64,
    /// Float type of the solver.
    pub float: String,
    /// CPU model (from /proc/cpuinfo).
    pub cpu: String,
    /// SIMD features the binary was compiled for (`-C target-cpu`), e.g. `sse2` or `avx2`.
    pub compiled_simd: String,
    /// What the solver's pair loops run on this CPU: `avx512f-gathers`, `avx512f-loads` or
    /// `avx512f-windows` (AVX-512F detected at run time; neighbour values read with gather
    /// instructions, with plain loads, or on AMD with plain loads and, in the pressure
    /// solver, permutes of windows: see `dfsph::blocked::Gather`) or `portable`. `avx512f` in
    /// rows saved before the two were told apart (those always gathered); empty in rows
    /// saved before it was recorded.
    #[serde(default)]
    pub runtime_simd: String,
    /// The solver settings: `benchmark` (docs/BENCHMARK.md) or `viewer` (the built-in scene's
    /// defaults, `bench --realtime`). `benchmark` in rows saved before it was recorded.
    #[serde(default)]
    pub settings: Settings,
    /// Wall seconds of every run of this row; the row's other numbers are the median run's.
    pub wall_seconds_runs: Vec<f64>,
}

/// A finite number above zero, for the command line's lengths and times.
pub(super) fn positive(text: &str) -> Result<f64, String> {
    match text.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!(
            "must be a finite number greater than 0, got `{text}`"
        )),
    }
}
