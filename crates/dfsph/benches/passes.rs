//! Micro-benchmarks of the solver's hot passes, each in isolation, on a dam-break state a few
//! dozen steps in (20k and 80k fluid particles, d = 0.01 m and 0.005 m):
//!
//! * `neighbors/grid_build` — counting sort of the fluid positions into the grid;
//! * `neighbors/fluid_lists`, `neighbors/boundary_lists` — CSR neighbour lists;
//! * `density_and_factor` — densities, DFSPH factors α and the cached kernel gradients;
//! * `pressure/apply` — one `Δv = −Σ V (κ_i + κ_j) ∇W` pass;
//! * `pressure/residual` — one residual pass (a density solve stopped after 0 iterations);
//! * `pressure/iteration_plus_residual` — a density solve with exactly 1 iteration: one
//!   residual pass more than `pressure/residual`, so one solver iteration costs the difference.
//!
//! `cargo bench -p dfsph --bench passes` (add `-- density` to run a subset). Threads: rayon's
//! default (one per core); `RAYON_NUM_THREADS=1` for one.

use std::time::Duration;

use criterion::{criterion_group, criterion_main, BatchSize, BenchmarkId, Criterion, Throughput};
use dfsph::blocked::Gather;
use dfsph::boundary::{volumes, wall_volume_correction, AkinciWalls, BoundaryModel};
use dfsph::kernel::Kernel;
use dfsph::neighbors::{Grid, NeighborLists};
use dfsph::particles::{BoundaryParticles, FluidParticles};
use dfsph::pressure::jacobi::{self, JacobiScratch};
use dfsph::scene;
use dfsph::settings::{SolveLimits, SolverSettings};
use dfsph::simd::SimdPath;
use dfsph::simulation::lattice_kernel_sum;
use dfsph::solver::{self, Neighborhood, PairCache, Walls};
use dfsph::step::StepContext;
use dfsph::{Simulation, Vec2};

/// Everything the passes read, rebuilt through the public API from a running simulation.
struct State {
    kernel: Kernel,
    volume: f32,
    fluid: FluidParticles,
    boundary: BoundaryParticles,
    fluid_grid: Grid,
    boundary_grid: Grid,
    fluid_lists: NeighborLists,
    boundary_lists: NeighborLists,
    pair_cache: PairCache,
    /// The factor cap the simulation uses.
    max_factor: f32,
    /// The scene's stopping rules and safeguards.
    settings: SolverSettings,
}

impl State {
    /// Particle spacing d, m.
    fn spacing(&self) -> f32 {
        0.5 * self.kernel.support()
    }

    /// Densities, factors and cached gradients, as at the start of a step.
    fn density_and_factor(&mut self) {
        let walls = Walls {
            particles: &self.boundary,
            lists: &self.boundary_lists,
            weight: AkinciWalls.gradient_weight(),
        };
        solver::density_and_factor(
            &self.kernel,
            self.volume,
            &mut self.fluid,
            &self.fluid_lists,
            walls,
            &mut self.pair_cache,
            self.max_factor,
        );
    }
}

/// The dam break at spacing `d`, `steps` steps in.
fn state(d: f64, steps: usize) -> State {
    let mut sc = scene::builtin("dam-break").expect("built in");
    sc.particle_radius = 0.5 * d;
    sc.time_step.max = 5.0e-3;
    sc.time_step.cfl = 0.2;
    let mut sim = Simulation::new(&sc).expect("valid scene");
    for _ in 0..steps {
        sim.step();
    }
    let kernel = *sim.kernel();
    let d = d as f32;
    let volume = 1.0 / lattice_kernel_sum(&kernel, d);

    let settings = SolverSettings::from_scene(&sc);
    let mut boundary_grid = Grid::new(kernel.support());
    // As the simulation sizes it (`CpuBackend::update_neighborhoods`).
    boundary_grid.set_dense_cells_floor(4 * sim.positions().len());
    let order = boundary_grid.build(sim.boundary_positions()).to_vec();
    let mut boundary = BoundaryParticles::default();
    for &i in &order {
        boundary.position.push(sim.boundary_positions()[i as usize]);
        boundary.velocity.push(Vec2::ZERO);
        boundary.volume.push(0.0);
        boundary.body.push(0);
    }
    volumes(
        &boundary_grid,
        &kernel,
        wall_volume_correction(&kernel, d),
        &mut boundary.volume,
    );

    let mut fluid_grid = Grid::new(kernel.support());
    let order = fluid_grid.build(sim.positions()).to_vec();
    let mut fluid = FluidParticles::default();
    for &i in &order {
        let i = i as usize;
        fluid.push(sim.positions()[i], sim.velocities()[i], sim.ids()[i]);
    }
    let mut fluid_lists = NeighborLists::default();
    let mut boundary_lists = NeighborLists::default();
    fluid_grid.neighbor_lists(&fluid.position, true, &mut fluid_lists);
    boundary_grid.neighbor_lists(&fluid.position, false, &mut boundary_lists);
    let mut s = State {
        kernel,
        volume,
        fluid,
        boundary,
        fluid_grid,
        boundary_grid,
        fluid_lists,
        boundary_lists,
        pair_cache: PairCache::default(),
        max_factor: settings.max_factor_ratio * solver::lattice_factor(&kernel, d, volume),
        settings,
    };
    s.density_and_factor();
    s
}

fn passes(c: &mut Criterion) {
    for (name, d) in [("20k", 0.01), ("80k", 0.005)] {
        let mut s = state(d, 40);
        let n = s.fluid.len() as u64;
        let pairs = (s.fluid_lists.pair_count() + s.boundary_lists.pair_count()) as f64;
        eprintln!(
            "{name}: {n} fluid particles, {:.2} neighbours per particle (fluid + boundary)",
            pairs / n as f64
        );
        eprintln!(
            "{name}: SIMD blocks hold {} entries for {} fluid pairs ({:.1} % padding, {} indices); AVX-512 {}",
            s.pair_cache.blocks.entries(),
            s.fluid_lists.pair_count(),
            100.0
                * (s.pair_cache.blocks.entries() as f64 / s.fluid_lists.pair_count() as f64 - 1.0),
            if s.pair_cache.blocks.relative_indices() {
                "16-bit relative"
            } else {
                "32-bit"
            },
            dfsph::simd::SimdPath::in_use()
        );

        let mut g = c.benchmark_group("neighbors");
        g.throughput(Throughput::Elements(n));
        let positions = s.fluid.position.clone();
        let mut grid = Grid::new(s.kernel.support());
        g.bench_function(BenchmarkId::new("grid_build", name), |b| {
            b.iter(|| grid.build(&positions).len())
        });
        let mut lists = NeighborLists::default();
        // `fluid_lists_portable`: the same lists with the scalar candidate filter (the path of
        // CPUs without AVX-512F), for the before/after of the SIMD filter.
        let (fastest, portable) = (SimdPath::fastest(), SimdPath::Portable);
        for (label, path) in [("fluid_lists", fastest), ("fluid_lists_portable", portable)] {
            s.fluid_grid.set_simd_path(path);
            g.bench_function(BenchmarkId::new(label, name), |b| {
                b.iter(|| {
                    s.fluid_grid
                        .neighbor_lists(&s.fluid.position, true, &mut lists);
                    lists.pair_count()
                })
            });
        }
        s.fluid_grid.set_simd_path(fastest);
        g.bench_function(BenchmarkId::new("boundary_lists", name), |b| {
            b.iter(|| {
                s.boundary_grid
                    .neighbor_lists(&s.fluid.position, false, &mut lists);
                lists.pair_count()
            })
        });
        g.finish();

        let mut g = c.benchmark_group("density_and_factor");
        g.throughput(Throughput::Elements(n));
        g.bench_function(BenchmarkId::from_parameter(name), |b| {
            b.iter(|| s.density_and_factor())
        });
        g.finish();

        let dt = 1.0e-3f32;
        // A stiffness field like a solve's: positive where compressed.
        let kappa: Vec<f32> = s
            .fluid
            .density_ratio
            .iter()
            .zip(&s.fluid.factor)
            .map(|(&r, &a)| (r - 1.0).max(1.0e-4) * a / dt)
            .collect();
        let mut g = c.benchmark_group("pressure");
        g.throughput(Throughput::Elements(n));
        let mut vel = s.fluid.velocity.clone();
        // The pressure passes as this CPU runs them, and (`_loads`) reading neighbour values
        // with plain loads, for the before/after of `Gather::Windows` (AMD).
        let runs = if Gather::for_this_cpu() == Gather::Loads {
            vec![("", Gather::Loads)]
        } else {
            vec![("", Gather::for_this_cpu()), ("_loads", Gather::Loads)]
        };
        for (suffix, gather) in runs {
            s.pair_cache.blocks.set_gather(gather);
            s.density_and_factor();
            let nb = Neighborhood::new(&s.fluid_lists, &s.boundary_lists, &s.pair_cache);
            g.bench_function(BenchmarkId::new(format!("apply{suffix}"), name), |b| {
                b.iter(|| solver::apply_pressure(s.volume, &kappa, &mut vel, &nb))
            });
            for (label, iterations) in [("residual", 0), ("iteration_plus_residual", 1)] {
                let settings = SolverSettings {
                    density: SolveLimits {
                        tolerance_pct: 0.0,
                        max_error_pct: f64::INFINITY,
                        min_iterations: iterations,
                        max_iterations: iterations,
                    },
                    warm_start: false,
                    ..s.settings.clone()
                };
                let step = StepContext {
                    kernel: &s.kernel,
                    volume: s.volume,
                    spacing: s.spacing(),
                    dt,
                    gravity: Vec2::ZERO,
                    settings: &settings,
                    nb,
                    boundary: &s.boundary,
                    bodies: None,
                    stop: None,
                };
                let mut scratch = JacobiScratch::default();
                g.bench_function(BenchmarkId::new(format!("{label}{suffix}"), name), |b| {
                    b.iter_batched_ref(
                        || s.fluid.clone(),
                        |fluid| jacobi::density_solve(&step, fluid, &mut scratch).iterations,
                        BatchSize::LargeInput,
                    )
                });
            }
        }
        g.finish();
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .sample_size(20)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(3));
    targets = passes
}
criterion_main!(benches);
