//! The GPU backend: `dfsph::backend::Backend` with the step on the device
//! ([`DeviceStep`]). Each step uploads the world's fluid and walls, runs on the device and
//! reads its results back into the world once, so every action, output and probe works on
//! the world as with the CPU backend.
//!
//! What the device does not do yet, the CPU backend does, and [`GpuBackend::describe`]
//! says why: WCSPH, the Wendland C2 kernel, rigid bodies, more fluid than one dispatch
//! covers, and water spread so thinly that the deflation's coarse matrix would not fit. A
//! device that fails mid-run hands the world to the CPU backend the same way, never
//! silently.

use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};

use dfsph::backend::{Backend, StepStats};
use dfsph::boundary::{AkinciWalls, BoundaryModel, MirroredWalls};
use dfsph::cpu::CpuBackend;
use dfsph::forces::MAX_POINTER_ACCELERATION;
use dfsph::kernel::KernelShape;
use dfsph::pressure::MIN_CELL_SUPPORTS;
use dfsph::retry::{max_displacement, AttemptCheck, Attempts};
use dfsph::scene::Method;
use dfsph::settings::SolverSettings;
use dfsph::world::{step_seconds, World};
use dfsph::Vec2;

use crate::device::Gpu;
use crate::step::{
    coarse_capacity, CgSolve, DensitySolve, DeviceStep, Solve, StepConsts, StepInput,
    MAX_COARSE_ENTRIES,
};

/// The most fluid particles one dispatch covers (65,535 workgroups of 64).
const MAX_FLUID: usize = 65_535 * 64;

/// Steps on the device, or, for what the device does not do yet, on the CPU.
pub struct GpuBackend {
    gpu: Arc<Gpu>,
    step: DeviceStep,
    /// The CPU backend stepping the world instead, and why.
    cpu: Option<(CpuBackend, String)>,
    /// A device error that made the CPU take over for good.
    failed: Option<String>,
    settings: SolverSettings,
    /// The lattice's gradient consistency c (`World::gradient_consistency`).
    gradient_consistency: f32,
    /// The walls of the scene's density solve, and the scale of its stored pressure's
    /// force (1/c for the conjugate gradients, which store the physical pressure).
    wall_model: &'static dyn BoundaryModel,
    pressure_scale: f32,
    /// Δt of the previous step, s.
    last_dt: f32,
    /// Upper bound on Δt after a step had to be redone, growing back by
    /// `retry_limit_growth` a step (the CPU backend's rule; infinite otherwise).
    retry_dt_limit: f32,
    stats: StepStats,
    totals: (u64, u64),
    stop_flag: Option<Arc<AtomicBool>>,
    /// A grid over the fluid as it stood after a step, for [`Backend::close_fluid_count`]
    /// and the output pressure's smoothing, built the first time it is asked after that
    /// step ([`Self::with_near`]).
    near: Mutex<Option<NearGrid>>,
}

/// A grid of cells of the kernel's support over the fluid's positions after step `step`
/// (whose first and last positions were `ends`: an action between steps, or a reset, moves
/// them).
struct NearGrid {
    step: u64,
    ends: [Option<Vec2>; 2],
    grid: dfsph::neighbors::Grid,
    /// The particle at each sorted index.
    order: Vec<u32>,
}

impl GpuBackend {
    /// The backend for `world` as it stands (a world just built from its scene), on `gpu`.
    pub fn new(gpu: Arc<Gpu>, world: &mut World) -> Self {
        let step = DeviceStep::new(&gpu);
        let mut backend = Self {
            gpu,
            step,
            cpu: None,
            failed: None,
            settings: SolverSettings::from_scene(world.scene()),
            gradient_consistency: 1.0,
            wall_model: &AkinciWalls,
            pressure_scale: 1.0,
            last_dt: world.scene().time_step.max as f32,
            retry_dt_limit: f32::INFINITY,
            stats: StepStats::default(),
            totals: (0, 0),
            stop_flag: None,
            near: Mutex::new(None),
        };
        backend.resolve_scene(world);
        // The conjugate-gradient solve starts from the pressure of water at rest, as on the
        // CPU (`PressureSolver::initial_pressure`).
        if world.conjugate_gradient() {
            let d = world.spacing();
            let p = dfsph::pressure::hydrostatic_pressure(world.positions(), world.gravity(), d);
            world.fluid_mut().pressure_over_rho0 = p;
        }
        backend.choose(world);
        backend.stats.n_fluid = world.fluid_count();
        backend.stats.n_boundary = world.boundary().position.len();
        backend
    }

    /// Record the solves' iterations as `recording` says ([`crate::Recording`]; adaptive
    /// unless set).
    pub fn set_recording(&mut self, recording: crate::Recording) {
        self.step.set_recording(recording);
    }

    /// What the recording of the solves' iterations did since this backend was made.
    pub fn recording_counts(&self) -> Arc<crate::RecordingCounts> {
        self.step.recording_counts()
    }

    /// `f` of the grid over `world`'s fluid as it stands, built once a step (and again when
    /// an action between steps moved the fluid's ends, or a reset).
    fn with_near<R>(&self, world: &World, f: impl FnOnce(&NearGrid) -> R) -> R {
        let x = world.positions();
        let mut near = self.near.lock().unwrap_or_else(|e| e.into_inner());
        let (step, ends) = (world.step_count(), [x.first().copied(), x.last().copied()]);
        if near
            .as_ref()
            .is_none_or(|g| g.step != step || g.ends != ends)
        {
            let mut grid = dfsph::neighbors::Grid::new(world.kernel().support());
            let order = grid.build(x).to_vec();
            *near = Some(NearGrid {
                step,
                ends,
                grid,
                order,
            });
        }
        f(near.as_ref().expect("just built"))
    }

    /// What in `world`, stepped with `settings`, the device does not do yet, if anything.
    pub fn unsupported(world: &World, settings: &SolverSettings) -> Option<String> {
        let solver = &world.scene().solver;
        let reason = if solver.method != Method::Dfsph {
            "no WCSPH on the GPU yet"
        } else if Self::coarse_entries(world, settings) > MAX_COARSE_ENTRIES {
            "the water is spread too thinly for the GPU's coarse space"
        } else if solver.kernel != KernelShape::CubicSpline {
            "no Wendland C2 kernel on the GPU yet"
        } else if world.rigid_body_count() > 0 {
            "no rigid bodies on the GPU yet"
        } else if world.fluid_count() > MAX_FLUID {
            "more than 4,194,240 fluid particles for one GPU dispatch"
        } else {
            return None;
        };
        Some(reason.to_string())
    }

    /// The width of the deflation's aggregates, m (`SolverSettings::coarse_cell_supports`
    /// kernel supports, at least four; 0 without deflation).
    fn coarse_cell(world: &World, settings: &SolverSettings) -> f32 {
        let supports = settings.coarse_cell_supports;
        if world.conjugate_gradient() && supports > 0.0 {
            supports.max(MIN_CELL_SUPPORTS) * world.kernel().support()
        } else {
            0.0
        }
    }

    /// The most entries the coarse matrix of `world`'s water can need on the device.
    fn coarse_entries(world: &World, settings: &SolverSettings) -> usize {
        match Self::coarse_cell(world, settings) {
            0.0 => 0,
            cell => {
                let (aggregates, half_band) = coarse_capacity(world.positions(), cell);
                aggregates.saturating_mul(half_band + 1)
            }
        }
    }

    /// Step on the device when it can take `world`, else on the CPU (a CPU backend is made
    /// when the world first needs one, and dropped when it no longer does).
    fn choose(&mut self, world: &mut World) {
        let reason = self
            .failed
            .clone()
            .or_else(|| Self::unsupported(world, &self.settings));
        match (reason, &mut self.cpu) {
            (Some(reason), Some((_, why))) => *why = reason,
            (Some(reason), None) => {
                let mut cpu = CpuBackend::new(world);
                if let Some(flag) = &self.stop_flag {
                    cpu.set_stop_flag(flag.clone());
                }
                self.cpu = Some((cpu, reason));
            }
            (None, Some((cpu, _))) => {
                self.last_dt = cpu.stats().dt as f32;
                self.cpu = None;
            }
            (None, None) => {}
        }
    }

    /// The step's constants from `world`: forces, the bounds on Δt, the tank.
    fn consts(&self, world: &World) -> StepConsts {
        let scene = world.scene();
        let (ts, viscosity, d) = (&scene.time_step, &scene.viscosity, world.spacing());
        let h = world.kernel().support();
        let (lo, hi) = world.tank_interior();
        let (outer_lo, outer_hi) = world.tank_containment();
        let pointer = world.pointer().filter(|p| p.radius > 0.0);
        let g = world.gravity();
        let (accel, pulls) = world.displacement_acceleration();
        let upper =
            world.time_step_upper_bound(&self.settings, world.viscous_time_step(&self.settings));
        let (at, radius, strength) = pointer.map_or((Vec2::ZERO, 0.0, 0.0), |p| {
            let s = p
                .strength
                .clamp(-MAX_POINTER_ACCELERATION, MAX_POINTER_ACCELERATION);
            (p.at, p.radius, s)
        });
        StepConsts {
            gravity: g.to_array(),
            pointer_at: at.to_array(),
            tank_lo: lo.to_array(),
            tank_hi: hi.to_array(),
            outer_lo: outer_lo.to_array(),
            outer_hi: outer_hi.to_array(),
            wall_v: world.tank_velocity().to_array(),
            pointer_radius: radius,
            pointer_strength: strength,
            xsph: viscosity.xsph as f32,
            laplace: 8.0 * viscosity.kinematic as f32,
            friction: 8.0 * viscosity.boundary_kinematic as f32,
            eps2: 0.01 * h * h,
            cfl: ts.cfl as f32,
            dt_min: ts.min as f32,
            dt_upper: upper,
            accel,
            wall_speed: world.fastest_wall_speed(),
            pulls: pulls as u32,
            reach: self.settings.max_step_displacement * d,
            spacing: d,
            partials: 0,
            dt_cap: self.retry_dt_limit,
            ghost_slope: self
                .wall_model
                .hydrostatic_ghost_gradient(g)
                .map_or([0.0; 2], |g| (g / self.gradient_consistency).to_array()),
        }
    }

    /// The settings, walls and pressure scale of the scene as it stands (as the CPU
    /// backend's `PressureSolver` gives them): mirrored walls and the physical pressure for
    /// the conjugate gradients, Akinci's walls for the Jacobi iteration.
    fn resolve_scene(&mut self, world: &World) {
        self.settings = SolverSettings::from_scene(world.scene());
        self.gradient_consistency = world.gradient_consistency();
        (self.wall_model, self.pressure_scale) = if world.conjugate_gradient() {
            (
                &MirroredWalls as &dyn BoundaryModel,
                1.0 / self.gradient_consistency,
            )
        } else {
            (&AkinciWalls as &dyn BoundaryModel, 1.0)
        };
    }

    /// The solves' constants: the divergence solve's Jacobi iteration
    /// (`dfsph::pressure::jacobi`), and the density solve's, Jacobi or conjugate gradients
    /// (`dfsph::pressure::conjugate_gradient`).
    fn solves(&self, world: &World) -> (Option<Solve>, DensitySolve) {
        let s = &self.settings;
        let warm_share = if s.warm_start {
            s.jacobi_warm_share
        } else {
            0.0
        };
        let base = Solve {
            min_iterations: s.density.min_iterations,
            max_iterations: s.density.max_iterations,
            growth: s.diverging_error_growth as f32,
            warm_share,
            ..Solve::default()
        };
        let divergence = s.divergence_solve.then_some(Solve {
            density: 0,
            gated: 0,
            tolerance_pct: s.divergence.tolerance_pct as f32,
            max_error_pct: f32::MAX,
            min_neighbours: s.divergence_min_neighbors as f32,
            ..base
        });
        let (tolerance_pct, max_error_pct) = (
            s.density.tolerance_pct as f32,
            s.density.max_error_pct as f32,
        );
        let max_correction_rate = s.max_correction_speed / world.spacing();
        let density = if world.conjugate_gradient() {
            DensitySolve::ConjugateGradient(CgSolve {
                min_iterations: s.density.min_iterations,
                max_iterations: s.density.max_iterations,
                warm: s.warm_start as u32,
                tolerance_pct,
                max_error_pct,
                growth: s.diverging_error_growth as f32,
                min_neighbours: s.conjugate_gradient_min_neighbors as f32,
                max_correction_rate,
                dead_band: s.compression_dead_band * tolerance_pct / 100.0,
                consistency: self.gradient_consistency,
                coarse_cell: Self::coarse_cell(world, s),
                density_speed: tolerance_pct / 100.0 * world.spacing(),
                gravity_impulse: s.gravity_impulse_tolerance * world.gravity().length(),
                ..CgSolve::default()
            })
        } else {
            DensitySolve::Jacobi(Solve {
                density: 1,
                gated: 1,
                tolerance_pct,
                max_error_pct,
                max_correction_rate,
                ..base
            })
        };
        (divergence, density)
    }

    /// One step on the device; an error leaves the fluid as the step found it (the tank
    /// already driven).
    fn step_on_device(&mut self, world: &mut World) -> Result<(), crate::GpuError> {
        world.drive_tank(self.last_dt);
        world.refresh_wall_volumes();
        let n = world.fluid_count();
        let consts = self.consts(world);
        if n == 0 {
            // Nothing to solve: the clock and the walls move on.
            let dt = world.cfl_time_step(
                &self.settings,
                world.viscous_time_step(&self.settings),
                None,
            );
            self.finish(world, dt, None);
            return Ok(());
        }
        let kernel = *world.kernel();
        let volume = world.particle_volume();
        let max_factor = self.settings.max_factor_ratio
            * dfsph::solver::lattice_factor(&kernel, world.spacing(), volume);
        let (divergence, density) = self.solves(world);
        let walls = world.boundary();
        // The grid covers the tank with its walls; fluid cannot leave it.
        let (lo, hi) = world.tank_containment();
        let h = kernel.support();
        let bounds = walls
            .position
            .iter()
            .fold((lo - Vec2::splat(h), hi + Vec2::splat(h)), |(a, b), &p| {
                (a.min(p), b.max(p))
            });
        let run = |step: &mut DeviceStep, consts| {
            let input = StepInput {
                position: world.positions(),
                velocity: world.velocities(),
                pressure: world.pressures_over_rho0(),
                divergence_stiffness: world.divergence_stiffnesses(),
                walls: &walls.position,
                wall_volumes: &walls.volume,
                wall_velocities: &walls.velocity,
                support: h,
                volume,
                max_factor,
                wall_weight: self.wall_model.gradient_weight(),
                bounds,
                consts,
                divergence,
                density,
                last_dt: self.last_dt,
            };
            step.run(&self.gpu, &input)
        };
        // An unsound attempt is redone from the step's start with a shorter Δt, by the CPU
        // backend's rules (`dfsph::retry`).
        let mut out = run(&mut self.step, consts)?;
        let first = out.control;
        let (settings, spacing) = (&self.settings, world.spacing());
        let mut attempts = Attempts::new(first.dt, world.scene().time_step.min as f32);
        loop {
            let c = out.control;
            let check = AttemptCheck {
                overcompressed: c.den_iterations >= settings.density.max_iterations
                    && c.den_max as f64 > settings.retry_density_error_pct,
                unseen_pct: 100.0 * c.unseen as f64,
                displacement: max_displacement(&out.velocity, c.dt, spacing),
            };
            if attempts.is_last() || !attempts.redo(&check, settings) {
                break;
            }
            out = run(
                &mut self.step,
                StepConsts {
                    dt_cap: attempts.dt,
                    ..consts
                },
            )?;
        }
        // After a retry the next steps may grow by `retry_limit_growth` a step until the
        // bounds take over again.
        let growth = self.settings.retry_limit_growth;
        self.retry_dt_limit = if attempts.retries > 0 {
            out.control.dt
        } else if self.retry_dt_limit * growth >= first.cfl_dt {
            f32::INFINITY
        } else {
            self.retry_dt_limit * growth
        };
        out.retries = attempts.retries;
        let dt = out.control.dt;
        let fluid = world.fluid_mut();
        std::mem::swap(&mut fluid.position, &mut out.position);
        std::mem::swap(&mut fluid.velocity, &mut out.velocity);
        std::mem::swap(&mut fluid.density_ratio, &mut out.density_ratio);
        std::mem::swap(&mut fluid.factor, &mut out.factor);
        std::mem::swap(&mut fluid.pressure_over_rho0, &mut out.pressure);
        std::mem::swap(
            &mut fluid.divergence_stiffness,
            &mut out.divergence_stiffness,
        );
        fluid.acceleration.resize(n, Vec2::ZERO);
        self.finish(world, dt, Some(&out));
        Ok(())
    }

    /// Close a step of `dt`: move the walls, advance the clock, fill the statistics.
    fn finish(&mut self, world: &mut World, dt: f32, out: Option<&crate::step::StepOutput>) {
        world.move_walls(dt);
        world.advance_clock(dt);
        self.last_dt = dt;
        let (max_speed, kinetic_energy) = world.speed_and_energy();
        let c = out.map(|o| o.control).unwrap_or_default();
        let (clamped, non_finite) = out.map_or((0, 0), |o| (o.clamped, o.non_finite));
        self.totals.0 += clamped as u64;
        self.totals.1 += non_finite as u64;
        self.stats = StepStats {
            step: world.step_count(),
            time: world.time(),
            dt: step_seconds(dt),
            n_fluid: world.fluid_count(),
            n_boundary: world.boundary().position.len(),
            density_iterations: c.den_iterations,
            divergence_iterations: c.div_iterations,
            avg_density_error_pct: c.den_avg as f64,
            max_density_error_pct: c.den_max as f64,
            divergence_error_pct: c.div_avg as f64,
            max_speed,
            kinetic_energy,
            clamped,
            non_finite,
            avg_neighbors: out.map_or(0.0, |o| o.avg_neighbours),
            retries: out.map_or(0, |o| o.retries),
        };
    }
}

impl Backend for GpuBackend {
    fn step(&mut self, world: &mut World) -> &StepStats {
        self.choose(world);
        if self.cpu.is_none() {
            if let Err(e) = self.step_on_device(world) {
                // The results come back only whole, so the world holds the step's start
                // (the tank already driven): the CPU takes it from here, and says why.
                self.failed = Some(format!("the GPU failed ({e})"));
                self.choose(world);
            }
        }
        match &mut self.cpu {
            Some((cpu, _)) => cpu.step(world),
            None => &self.stats,
        }
    }

    fn scene_changed(&mut self, world: &World) {
        self.resolve_scene(world);
        if let Some((cpu, _)) = &mut self.cpu {
            cpu.scene_changed(world);
        }
    }

    fn stats(&self) -> &StepStats {
        match &self.cpu {
            Some((cpu, _)) => cpu.stats(),
            None => &self.stats,
        }
    }

    fn totals(&self) -> (u64, u64) {
        let cpu = self.cpu.as_ref().map_or((0, 0), |(c, _)| c.totals());
        (self.totals.0 + cpu.0, self.totals.1 + cpu.1)
    }

    fn next_time_step(&self, world: &World) -> f32 {
        match &self.cpu {
            Some((cpu, _)) => cpu.next_time_step(world),
            None => world.cfl_time_step(
                &self.settings,
                world.viscous_time_step(&self.settings),
                None,
            ),
        }
    }

    fn set_stop_flag(&mut self, flag: Arc<AtomicBool>) {
        if let Some((cpu, _)) = &mut self.cpu {
            cpu.set_stop_flag(flag.clone());
        }
        self.stop_flag = Some(flag);
    }

    fn stop_flag(&self) -> Option<Arc<AtomicBool>> {
        self.stop_flag.clone()
    }

    fn output_pressures_over_rho0(&self, world: &World) -> Vec<f32> {
        match &self.cpu {
            Some((cpu, _)) => cpu.output_pressures_over_rho0(world),
            None => self.with_near(world, |near| {
                let once = shepard(world, near, world.pressures_over_rho0());
                shepard(world, near, &once)
            }),
        }
    }

    fn applied_pressure_over_rho0(&self, world: &World, i: usize) -> f32 {
        match &self.cpu {
            Some((cpu, _)) => cpu.applied_pressure_over_rho0(world, i),
            None => {
                let dt = self.stats.dt as f32;
                let kv = if self.settings.divergence_solve && dt > 0.0 {
                    world.divergence_stiffnesses()[i] / dt
                } else {
                    0.0
                };
                world.pressures_over_rho0()[i] * self.pressure_scale + kv
            }
        }
    }

    fn pressure_force_scale(&self) -> f32 {
        match &self.cpu {
            Some((cpu, _)) => cpu.pressure_force_scale(),
            None => self.pressure_scale,
        }
    }

    fn wall_model(&self) -> &'static dyn BoundaryModel {
        match &self.cpu {
            Some((cpu, _)) => cpu.wall_model(),
            None => self.wall_model,
        }
    }

    fn describe(&self) -> String {
        match &self.cpu {
            Some((_, why)) => format!("cpu ({why})"),
            None => format!("gpu: {}", self.gpu.adapter()),
        }
    }

    fn close_fluid_count(&self, world: &World, i: usize) -> Option<usize> {
        match &self.cpu {
            Some((cpu, _)) => cpu.close_fluid_count(world, i),
            None => {
                let x = world.positions();
                if x.len() != self.stats.n_fluid {
                    return None;
                }
                // One grid a step, not a scan of every particle a call: the front of the
                // fluid asks for every particle (1.28 million of them in the 1m benchmark).
                self.with_near(world, |g| {
                    let mut count = 0;
                    g.grid.for_each_near(x[i], |j, _| {
                        count += usize::from(g.order[j as usize] as usize != i);
                    });
                    Some(count)
                })
            }
        }
    }
}

/// `Σ_j W_ij f_j / Σ_j W_ij` at every fluid particle of `world`, j over its fluid neighbours
/// (found in `near`, the grid over them) and itself: the CPU backend's smoothing of the
/// output pressure.
fn shepard(world: &World, near: &NearGrid, f: &[f32]) -> Vec<f32> {
    let kernel = world.kernel();
    world
        .positions()
        .iter()
        .map(|&p| {
            let (mut sum, mut weight) = (0.0, 0.0);
            near.grid.for_each_near(p, |j, offset| {
                let w = kernel.w(offset.length());
                sum += w * f[near.order[j as usize] as usize];
                weight += w;
            });
            sum / weight
        })
        .collect()
}
