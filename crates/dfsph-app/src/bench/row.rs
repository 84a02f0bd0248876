//! One benchmark row, run by the hidden `dfsph2d bench-row` in its own process.

use std::time::{Duration, Instant};

use dfsph::neighbors::Grid;
use dfsph::scene::{self, Method, Scene, TimeStepParams};
use dfsph::simd::SimdPath;
use dfsph::Vec2;

use super::types::{Code, Row, RowArgs, Settings};

/// XSPH coefficient of both codes (dimensionless; our scene default).
pub const XSPH: f64 = 0.01;
/// A particle is part of the front when it has at least this many fluid neighbours.
pub const FRONT_NEIGHBORS: usize = 3;
/// Time at which the front is also recorded, s.
pub const FRONT_CHECK_TIME: f64 = 0.4;

/// The benchmark scene: the built-in dam break at spacing `d` with docs/BENCHMARK.md's solver
/// settings.
pub fn bench_scene(d: f64) -> Scene {
    let mut scene = scene::builtin("dam-break").expect("the dam break is built in");
    scene.particle_radius = 0.5 * d;
    scene.solver.method = Method::Dfsph;
    scene.solver.density_tolerance_pct = 0.01;
    scene.solver.divergence_tolerance_pct = 0.1;
    scene.solver.min_iterations = 2;
    scene.solver.max_iterations = 100;
    scene.solver.divergence_solve = true;
    scene.solver.warm_start = true;
    // Our CFL factor multiplies the spacing d (Δt = cfl·d/v_max), as in docs/BENCHMARK.md.
    scene.time_step = TimeStepParams {
        cfl: 0.2,
        min: 1.0e-5,
        max: 5.0e-3,
    };
    scene.viscosity.xsph = XSPH;
    scene.viscosity.kinematic = 0.0;
    scene.viscosity.boundary_kinematic = 0.0;
    with_room(scene)
}

/// `scene` with `max_particles` raised to the particles its blocks hold: the 1m case's
/// 1.28 million are more than the default bound of a million, which guards scenes typed by
/// hand, not the benchmark's own sizes.
fn with_room(mut scene: Scene) -> Scene {
    scene.max_particles = scene.max_particles.max(scene.fluid_particle_count());
    scene
}

/// The dam break as the viewer opens it, at spacing `d`: the built-in scene's own settings.
pub fn viewer_scene(d: f64) -> Scene {
    let mut scene = scene::builtin("dam-break").expect("the dam break is built in");
    scene.particle_radius = 0.5 * d;
    with_room(scene)
}

pub(super) fn run_dfsph(args: &RowArgs) -> Result<Row, String> {
    let scene = match args.settings {
        Settings::Benchmark => bench_scene(args.spacing),
        Settings::Viewer => viewer_scene(args.spacing),
    };
    let setup = Instant::now();
    let (factory, notes) = crate::backends::factory(args.backend)?;
    for note in notes {
        eprintln!("{note}");
    }
    let limits = dfsph::memory::MemoryLimits::of_this_process(None);
    let (mut sim, _) = crate::backends::simulation(&scene, &limits, factory.as_ref())
        .map_err(|e| format!("benchmark scene: {e}"))?;
    let setup_seconds = setup.elapsed().as_secs_f64();
    let mut progress = Progress::new(Code::Dfsph2d, &args.case, args.until);

    let (mut density_its, mut divergence_its, mut steps) = (0u64, 0u64, 0u64);
    let mut retries = 0u64;
    let mut front_at_check = None;
    let mut untimed = Duration::ZERO;
    let start = Instant::now();
    while !sim.has_reached(args.until) {
        let s = sim.step();
        density_its += s.density_iterations as u64;
        divergence_its += s.divergence_iterations as u64;
        retries += s.retries as u64;
        steps += 1;
        if front_at_check.is_none() && s.time >= FRONT_CHECK_TIME {
            let t = Instant::now();
            front_at_check = sim.front_position(FRONT_NEIGHBORS);
            untimed += t.elapsed();
        }
        progress.tick(sim.time(), steps);
    }
    let wall = (start.elapsed() - untimed).as_secs_f64();
    let n = sim.fluid_count();
    let mut row = base_row(Code::Dfsph2d, args, n, sim.boundary_positions().len());
    row.backend = sim.backend_description();
    row.setup_seconds = setup_seconds;
    row.sim_seconds = sim.time();
    row.dt_rule = format!(
        "CFL {}*d/v_max in [{:e}, {:e}] s",
        scene.time_step.cfl, scene.time_step.min, scene.time_step.max
    );
    row.avg_density_iterations = Some(density_its as f64 / steps.max(1) as f64);
    row.avg_divergence_iterations = Some(divergence_its as f64 / steps.max(1) as f64);
    row.front_x = sim.front_position(FRONT_NEIGHBORS).unwrap_or(0.0);
    row.front_x_at_0_4 = front_at_check;
    row.leaked = sim.total_clamped();
    row.non_finite = sim.total_non_finite();
    row.retries = retries;
    row.xsph = scene.viscosity.xsph;
    row.finish_timing(wall, steps);
    Ok(row)
}

impl Row {
    /// Fill the derived timing columns.
    pub fn finish_timing(&mut self, wall: f64, steps: u64) {
        self.wall_seconds = wall;
        self.wall_seconds_runs = vec![wall];
        self.steps = steps;
        self.mean_dt = self.sim_seconds / steps.max(1) as f64;
        self.particle_steps_per_second = self.n as f64 * steps as f64 / wall.max(1.0e-12);
        self.ns_per_particle_step = 1.0e9 / self.particle_steps_per_second.max(1.0e-12);
        self.wall_per_sim_second = wall / self.sim_seconds.max(1.0e-12);
    }
}

/// A row with the run's identity filled in and the measurements zeroed.
pub fn base_row(code: Code, args: &RowArgs, n: usize, n_boundary: usize) -> Row {
    Row {
        code,
        case: args.case.clone(),
        n,
        n_boundary,
        spacing: args.spacing,
        sim_seconds: 0.0,
        wall_seconds: 0.0,
        setup_seconds: 0.0,
        steps: 0,
        mean_dt: 0.0,
        dt_rule: String::new(),
        particle_steps_per_second: 0.0,
        ns_per_particle_step: 0.0,
        wall_per_sim_second: 0.0,
        avg_density_iterations: None,
        avg_divergence_iterations: None,
        peak_rss_bytes: 0,
        baseline_rss_bytes: 0,
        bytes_per_particle: 0.0,
        threads: rayon::current_num_threads(),
        front_x: 0.0,
        front_x_at_0_4: None,
        leaked: 0,
        non_finite: 0,
        retries: 0,
        backend: String::new(),
        xsph: XSPH,
        float: "f32".into(),
        cpu: cpu_model(),
        compiled_simd: compiled_simd(),
        runtime_simd: runtime_simd(),
        settings: args.settings,
        wall_seconds_runs: Vec::new(),
    }
}

/// The front as [`Simulation::front_position`] measures it, for any particle set: the largest
/// x of a particle with at least [`FRONT_NEIGHBORS`] neighbours closer than `support`. Used for
/// the salva2d rows.
#[cfg_attr(not(feature = "salva"), allow(dead_code))]
pub fn front_of(positions: &[Vec2], support: f32, tank_min_x: f32) -> Option<f64> {
    let mut grid = Grid::new(support);
    grid.build(positions);
    positions
        .iter()
        .filter(|&&p| {
            let mut count = 0usize;
            grid.for_each_near(p, |_, _| count += 1);
            count.saturating_sub(1) >= FRONT_NEIGHBORS
        })
        .map(|p| (p.x - tank_min_x) as f64)
        .fold(None, |m: Option<f64>, x| Some(m.map_or(x, |m| m.max(x))))
}

/// Progress on stderr, every few seconds of wall time.
pub struct Progress {
    label: String,
    until: f64,
    start: Instant,
    last: Instant,
}

impl Progress {
    pub fn new(code: Code, case: &str, until: f64) -> Self {
        let now = Instant::now();
        Self {
            label: format!("{} {case}", code.name()),
            until,
            start: now,
            last: now,
        }
    }

    pub fn tick(&mut self, time: f64, steps: u64) {
        if self.last.elapsed() >= Duration::from_secs(5) {
            self.last = Instant::now();
            eprintln!(
                "  {}: t = {time:.3} / {} s, {steps} steps, {:.0} s",
                self.label,
                self.until,
                self.start.elapsed().as_secs_f64()
            );
        }
    }
}

/// A `kB` line of `/proc/self/status`, in bytes.
pub(super) fn proc_status_bytes(key: &str) -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with(key))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

fn cpu_model() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|m| m.trim().to_string())
        })
        .unwrap_or_else(|| "unknown".into())
}

/// The path the solver's pair loops take ([`SimdPath::in_use`]: `DFSPH2D_SIMD` or the
/// fastest), and on AVX-512 how they read neighbour values.
fn runtime_simd() -> String {
    use dfsph::blocked::Gather;
    match (SimdPath::in_use(), Gather::for_this_cpu()) {
        (SimdPath::Avx512, Gather::Instruction) => "avx512f-gathers".into(),
        (SimdPath::Avx512, Gather::Loads) => "avx512f-loads".into(),
        (SimdPath::Avx512, Gather::Windows) => "avx512f-windows".into(),
        (path, _) => path.name().into(),
    }
}

/// The widest SIMD level the compiler was allowed to use.
fn compiled_simd() -> String {
    if cfg!(target_feature = "avx512f") {
        "avx512f"
    } else if cfg!(target_feature = "avx2") {
        "avx2"
    } else if cfg!(target_feature = "sse2") {
        "sse2 (no target-cpu)"
    } else if cfg!(target_arch = "aarch64") {
        "neon"
    } else {
        "none"
    }
    .into()
}

/// Make this row process end when the `dfsph2d bench` that started it (process `parent`)
/// does. Killing the parent (Ctrl-C in a terminal reaches both, but `kill PID` or a closed CI
/// job does not) left the row running, taking the CPU from whatever was measured next. On
/// Linux the kernel sends SIGKILL to the row when its parent dies; the row writes no files, so
/// nothing is left half-written. A parent that died before the request was made is caught by
/// comparing with the pid the parent passed: under load a row can take a while to get here.
pub(super) fn exit_with_parent(parent: Option<u32>) {
    #[cfg(target_os = "linux")]
    {
        let parent = parent.unwrap_or_else(std::os::unix::process::parent_id);
        // SAFETY: prctl with PR_SET_PDEATHSIG only sets a flag on this process.
        unsafe {
            libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGKILL);
        }
        if std::os::unix::process::parent_id() != parent {
            std::process::exit(1);
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = parent;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_benchmark_size_is_a_valid_scene() {
        // 1m: 1.28 million particles, more than the default `max_particles`.
        for d in [0.02, 0.01, 0.005, 0.0025, 0.00125] {
            for scene in [bench_scene(d), viewer_scene(d)] {
                assert!(scene.validate().is_ok(), "d = {d}: {:?}", scene.validate());
            }
        }
        assert!(bench_scene(0.00125).fluid_particle_count() > 1_000_000);
    }
}
