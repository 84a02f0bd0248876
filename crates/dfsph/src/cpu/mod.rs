//! The CPU backend: the DFSPH step of Bender & Koschier on this machine's cores, with its
//! settings, scratch arrays, neighbourhoods and warm-start state; the world it advances is
//! passed in ([`crate::backend::Backend`]). Its methods are spread over the children by
//! concern: `neighbourhoods`, `advance` (the step), `time_step`, `rigid_coupling`.

mod advance;
mod neighbourhoods;
mod rigid_coupling;
mod time_step;

use glam::Vec2;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use web_time::Instant;

use crate::backend::{Backend, StepStats};
use crate::boundary::{self, BoundaryModel};
use crate::neighbors::{Grid, NeighborLists};
use crate::particles::Scratch;
use crate::pressure::{self, PressureSolver};
use crate::rigid::{BodyVelocity, CoupledBodies};
use crate::settings::SolverSettings;
use crate::solver::{self, PairCache};
use crate::viscosity::Viscosity;
use crate::world::World;

/// The DFSPH (or WCSPH) step on the CPU.
pub struct CpuBackend {
    /// Set from outside to end the pressure solves early ([`Backend::set_stop_flag`]).
    stop_flag: Option<Arc<AtomicBool>>,
    /// [`crate::packing::gradient_consistency`] of the scene's lattice: the pressure force of a field
    /// p is that of c·p, so the conjugate-gradient solve stores c times its stiffness field as
    /// the physical pressure.
    gradient_consistency: f32,
    /// γ of [`boundary::wall_volume_correction`].
    wall_gamma: f32,
    /// Cap on the DFSPH factor ([`SolverSettings::max_factor_ratio`] × the lattice factor).
    max_factor: f32,
    /// The stopping rules and safeguards, resolved from the scene ([`Self::resolve_scene`]).
    settings: SolverSettings,
    /// The pressure solver the scene names, with its scratch arrays.
    pressure: Box<dyn PressureSolver>,
    /// The viscosity models of the scene.
    viscosity: Viscosity,
    /// The boundary grid was built for the wall positions as they stand and for this many
    /// fluid particles (its dense-cell floor): while both hold, it is not rebuilt.
    boundary_grid_for: Option<usize>,
    fluid_grid: Grid,
    boundary_grid: Grid,
    fluid_lists: NeighborLists,
    boundary_lists: NeighborLists,
    pair_cache: PairCache,
    scratch: Scratch,
    /// Δt of the previous step (the divergence solve measures its error over it).
    last_dt: f32,
    /// Upper bound on Δt after a step had to be redone: the Δt it was accepted at, grown by
    /// [`SolverSettings::retry_limit_growth`] per step until the CFL step is the smaller again (infinite
    /// then). It spares the following steps from failing at the same length first.
    retry_dt_limit: f32,
    /// Velocities and pressures after the divergence solve, to redo the rest of a step.
    retry_velocity: Vec<Vec2>,
    retry_pressure: Vec<f32>,
    stats: StepStats,
    total_clamped: u64,
    total_non_finite: u64,
    /// When the last [`Backend::step`] returned.
    last_step_end: Option<Instant>,
    /// The free rigid bodies the water touches in this step, which move inside its solves
    /// ([`crate::rigid::coupled`]), and the walls' share of the density rate at their
    /// velocities as the step began.
    coupled: Option<CoupledBodies>,
    wall_flux_at_start: Vec<f32>,
    /// The moving bodies' velocity change as the density solve of the attempt at hand began
    /// ([`Self::predict_rigid_bodies`]).
    rigid_predicted: Vec<BodyVelocity>,
}

impl CpuBackend {
    /// The backend for `world` as it stands (a world just built from its scene): the first
    /// guess of the pressure, the neighbourhoods, densities and factors of the first step.
    pub fn new(world: &mut World) -> Self {
        let (scene, kernel, d, volume) = (&world.scene, world.kernel, world.spacing, world.volume);
        let gradient_consistency = world.gradient_consistency();
        let settings = SolverSettings::from_scene(scene);
        let mut cpu = CpuBackend {
            stop_flag: None,
            gradient_consistency,
            wall_gamma: boundary::wall_volume_correction(&kernel, d),
            max_factor: settings.max_factor_ratio * solver::lattice_factor(&kernel, d, volume),
            settings,
            pressure: pressure::for_scene(scene, gradient_consistency),
            viscosity: Viscosity::from_scene(&scene.viscosity),
            boundary_grid_for: None,
            fluid_grid: Grid::new(kernel.support()),
            boundary_grid: Grid::new(kernel.support()),
            fluid_lists: NeighborLists::default(),
            boundary_lists: NeighborLists::default(),
            pair_cache: PairCache::default(),
            scratch: Scratch::default(),
            last_dt: scene.time_step.max as f32,
            retry_dt_limit: f32::INFINITY,
            retry_velocity: Vec::new(),
            retry_pressure: Vec::new(),
            stats: StepStats::default(),
            total_clamped: 0,
            total_non_finite: 0,
            last_step_end: None,
            coupled: None,
            wall_flux_at_start: Vec::new(),
            rigid_predicted: Vec::new(),
        };
        if let Some(p) = cpu
            .pressure
            .initial_pressure(&world.fluid.position, world.gravity, d)
        {
            world.fluid.pressure_over_rho0 = p;
        }
        cpu.update_neighborhoods(world);
        // Before the first step the diagnostics hold the particle counts (a replay of a
        // header alone, or Python's `step(0)`, reports the water it has, not none).
        cpu.stats.n_fluid = world.fluid.len();
        cpu.stats.n_boundary = world.boundary.len();
        cpu
    }

    /// The stopping rules and safeguards, the pressure solver and the viscosity models of the
    /// scene as it stands: resolved when the simulation is built, and again whenever an action
    /// changes the scene's parameters.
    pub(crate) fn resolve_scene(&mut self, world: &World) {
        self.settings = SolverSettings::from_scene(&world.scene);
        self.pressure = pressure::for_scene(&world.scene, self.gradient_consistency);
        self.viscosity = Viscosity::from_scene(&world.scene.viscosity);
    }
}

impl Backend for CpuBackend {
    /// One step (TVCG 2017, Algorithm 1, arranged so that a step starts from fresh
    /// neighbourhoods): neighbourhoods → densities and factors → divergence solve →
    /// non-pressure forces → CFL Δt → predicted velocities → density solve → advection.
    fn step(&mut self, world: &mut World) -> &StepStats {
        self.step_on_a_worker(world);
        &self.stats
    }

    fn scene_changed(&mut self, world: &World) {
        self.resolve_scene(world);
    }

    fn stats(&self) -> &StepStats {
        &self.stats
    }

    fn totals(&self) -> (u64, u64) {
        (self.total_clamped, self.total_non_finite)
    }

    fn next_time_step(&self, world: &World) -> f32 {
        self.cfl_time_step(world)
    }

    fn set_stop_flag(&mut self, flag: Arc<AtomicBool>) {
        self.stop_flag = Some(flag);
    }

    fn stop_flag(&self) -> Option<Arc<AtomicBool>> {
        self.stop_flag.clone()
    }

    fn output_pressures_over_rho0(&self, world: &World) -> Vec<f32> {
        self.interpolated_pressures_over_rho0(world)
    }

    fn applied_pressure_over_rho0(&self, world: &World, i: usize) -> f32 {
        let (dt, divergence_solve) = (self.stats.dt as f32, self.settings.divergence_solve);
        self.pressure
            .applied_pressure(&world.fluid, i, dt, divergence_solve)
    }

    fn pressure_force_scale(&self) -> f32 {
        self.pressure.pressure_force_scale()
    }

    fn wall_model(&self) -> &'static dyn BoundaryModel {
        self.pressure.walls()
    }

    fn describe(&self) -> String {
        "cpu".to_string()
    }

    fn close_fluid_count(&self, world: &World, i: usize) -> Option<usize> {
        (self.fluid_lists.len() == world.fluid.len()).then(|| self.count_close(world, i))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::actions::Action;
    use crate::memory::MemoryLimits;

    /// The fluid–wall lists of a fresh neighbourhood update, against brute force over every
    /// wall particle.
    fn assert_wall_lists_are_exact(world: &mut World, cpu: &mut CpuBackend) {
        cpu.update_neighborhoods(world);
        let h2 = world.kernel.support() * world.kernel.support();
        let mut pairs = 0;
        for (i, &x) in world.fluid.position.iter().enumerate() {
            let mut got = cpu.boundary_lists.of(i).to_vec();
            got.sort_unstable();
            let want: Vec<u32> = (0..world.boundary.len() as u32)
                .filter(|&b| (x - world.boundary.position[b as usize]).length_squared() < h2)
                .collect();
            assert_eq!(got, want, "fluid particle {i} at {x:?}");
            pairs += want.len();
        }
        assert!(pairs > 100, "the fluid must touch the walls: {pairs} pairs");
    }

    /// The wall grid is kept between steps while the walls stand still; the fluid–wall lists
    /// must stay exact through a shaken tank (which fails without the rebuild), a drawn wall
    /// and a pour.
    #[test]
    fn wall_lists_stay_exact_while_the_wall_grid_is_reused() {
        let mut scene = crate::scene::builtin("dam-break").unwrap();
        scene.particle_radius = 0.04;
        let mut world = World::new_within(&scene, &MemoryLimits::of_this_process(None)).unwrap();
        let mut cpu = CpuBackend::new(&mut world);
        for _ in 0..5 {
            cpu.step(&mut world);
        }
        assert_wall_lists_are_exact(&mut world, &mut cpu);
        world.apply(&Action::ShakeTank { direction: 1.0 });
        for _ in 0..10 {
            cpu.step(&mut world);
            assert_wall_lists_are_exact(&mut world, &mut cpu);
        }
        world.apply(&Action::ShakeTank { direction: 0.0 });
        world.apply(&Action::AddWall {
            polyline: vec![Vec2::new(1.2, 0.1), Vec2::new(1.8, 0.5)],
        });
        cpu.step(&mut world);
        assert_wall_lists_are_exact(&mut world, &mut cpu);
        // Pouring changes the fluid count, which sets the wall grid's dense-cell floor.
        let poured = world.apply(&Action::Emit {
            at: Vec2::new(3.0, 0.4),
            radius: 0.3,
            velocity: Vec2::ZERO,
        });
        assert!(poured.added > 0, "{poured:?}");
        cpu.step(&mut world);
        assert_wall_lists_are_exact(&mut world, &mut cpu);
    }
}
