//! The CPU backend: the DFSPH step of Bender & Koschier on this machine's cores, with its
//! settings, scratch arrays, neighbourhoods and warm-start state; the world it advances is
//! passed in ([`crate::backend::Backend`]).

use crate::par::{self, prelude::*};
use crate::parallel::{self, LIGHT_PASS_MIN_ITEMS};
use glam::Vec2;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use web_time::Instant;

use crate::backend::{Backend, StepStats};
use crate::boundary::{self, BoundaryModel};
use crate::displacement::step_displacement_bound;
use crate::forces;
use crate::neighbors::{Grid, NeighborLists};
use crate::packing;
use crate::particles::{FluidParticles, Scratch};
use crate::pressure::{self, PressureSolver, SolveReport};
use crate::retry::{AttemptCheck, Attempts, DensityStep};
use crate::rigid::coupling::{self, WallTerms};
use crate::rigid::{BodyVelocity, CoupledBodies};
use crate::scene::Packing;
use crate::settings::SolverSettings;
use crate::solver::{self, Neighborhood, PairCache, Walls};
use crate::step::StepContext;
use crate::viscosity::Viscosity;
use crate::world::{step_seconds, World, MAX_SHAKE_ACCELERATION};

/// Which of a step's terms [`CpuBackend::rigid_body_impulses`] sums.
#[derive(Clone, Copy, Debug)]
enum Terms {
    /// The mirrored walls' hydrostatic ghosts' (part of the non-pressure forces).
    Ghosts,
    /// Both solves' and the ghosts'.
    All,
}

/// The DFSPH (or WCSPH) step on the CPU.
pub struct CpuBackend {
    /// Set from outside to end the pressure solves early ([`Backend::set_stop_flag`]).
    stop_flag: Option<Arc<AtomicBool>>,
    /// [`packing::gradient_consistency`] of the scene's lattice: the pressure force of a field
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
        let gradient_consistency = if scene.packing == Packing::Hexagonal {
            packing::hexagonal_gradient_consistency(&kernel, d, volume)
        } else {
            packing::square_gradient_consistency(&kernel, d, volume)
        };
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

    /// Sort both particle sets, rebuild neighbour lists, densities and factors.
    fn update_neighborhoods(&mut self, world: &mut World) {
        // Walls that have not moved since the last build are already sorted, and their grid
        // still holds: rebuilding would give the identity order (the sort is stable) and the
        // same cells. Shaking, drawing or erasing walls, and a change in the fluid count
        // (pouring, which sets the dense-cell floor) rebuild it.
        let n_fluid = world.fluid.position.len();
        if world.boundary_changed || world.walls_moved || self.boundary_grid_for != Some(n_fluid) {
            self.boundary_grid.set_dense_cells_floor(4 * n_fluid);
            let order = self.boundary_grid.build(&world.boundary.position).to_vec();
            world.boundary.permute(&order, &mut self.scratch);
            self.boundary_grid_for = Some(n_fluid);
            world.walls_moved = false;
        }
        if world.boundary_changed {
            boundary::volumes(
                &self.boundary_grid,
                &world.kernel,
                self.wall_gamma,
                &mut world.boundary.volume,
            );
            world.boundary_changed = false;
        }
        let order = self.fluid_grid.build(&world.fluid.position);
        world.fluid.permute(order, &mut self.scratch);
        for v in [&mut world.fluid.density_ratio, &mut world.fluid.factor] {
            v.resize(world.fluid.position.len(), 0.0);
        }
        world
            .fluid
            .acceleration
            .resize(world.fluid.position.len(), Vec2::ZERO);
        self.fluid_grid
            .neighbor_lists(&world.fluid.position, true, &mut self.fluid_lists);
        self.boundary_grid
            .neighbor_lists(&world.fluid.position, false, &mut self.boundary_lists);
        let walls = Walls {
            particles: &world.boundary,
            lists: &self.boundary_lists,
            weight: self.pressure.walls().gradient_weight(),
        };
        solver::density_and_factor(
            &world.kernel,
            world.volume,
            &mut world.fluid,
            &self.fluid_lists,
            walls,
            &mut self.pair_cache,
            self.max_factor,
        );
    }

    /// What the passes of a step of `dt` read, and the fluid and the pressure solver they work
    /// on.
    fn step_parts<'a>(
        &'a mut self,
        world: &'a mut World,
        dt: f32,
    ) -> (
        StepContext<'a>,
        &'a mut FluidParticles,
        &'a mut dyn PressureSolver,
    ) {
        let step = StepContext {
            kernel: &world.kernel,
            volume: world.volume,
            spacing: world.spacing,
            dt,
            gravity: world.gravity,
            settings: &self.settings,
            nb: Neighborhood::new(&self.fluid_lists, &self.boundary_lists, &self.pair_cache),
            boundary: &world.boundary,
            bodies: self.coupled.as_ref().filter(|c| !c.is_empty()),
            stop: self.stop_flag.as_deref(),
        };
        (step, &mut world.fluid, self.pressure.as_mut())
    }

    /// Advance by one time step (TVCG 2017, Algorithm 1, arranged so that a step starts from
    /// fresh neighbourhoods): neighbourhoods → densities and factors → divergence solve →
    /// non-pressure forces → CFL Δt → predicted velocities → density solve → advection.
    ///
    /// Called from outside rayon's pool, the step runs on one of its workers (one hand-off per
    /// step). Otherwise every one of the step's parallel passes, some fifty, would be handed
    /// to the pool from this thread, which then sleeps until the pass ends: a futex wait and
    /// wake per pass, which on a 2-core virtual machine took half the wall time of a
    /// 5,000-particle dam break. When steps follow each other closely (a batch run, the
    /// viewer's steps within a frame), the pool's other workers stand by for the whole step
    /// (`parallel::with_workers_at_hand`) rather than falling asleep between passes, unless
    /// another step (of another simulation, on another thread) is in progress meanwhile
    /// (`parallel::alone_in_flight`).
    fn step_on_a_worker(&mut self, world: &mut World) {
        let back_to_back = self
            .last_step_end
            .is_some_and(|end| end.elapsed() < parallel::WORKERS_STILL_POLLING);
        let (_in_flight, alone) = parallel::alone_in_flight();
        if par::current_thread_index().is_some() {
            self.advance(world);
        } else if back_to_back && alone && par::current_num_threads() > 1 {
            parallel::with_workers_at_hand(|| self.advance(world));
        } else {
            par::on_a_worker(|| self.advance(world));
        }
        self.last_step_end = Some(Instant::now());
    }

    /// [`Self::step`]'s work, on the current thread: Algorithm 1 of Bender & Koschier (TVCG
    /// 2017), its lines 11–14 moved to the start so that a step starts from fresh
    /// neighbourhoods.
    fn advance(&mut self, world: &mut World) {
        // Lines 11–13: move the walls, sort the fluid by cell, find the neighbourhoods, and
        // compute the densities ρ_i and the factors α_i.
        world.drive_tank(self.last_dt);
        self.update_neighborhoods(world);
        self.couple_rigid_bodies(world);
        // Line 14, Algorithm 2: make the velocity field divergence-free, its error measured
        // over the previous step.
        let divergence = if self.settings.divergence_solve {
            let (step, fluid, pressure) = self.step_parts(world, self.last_dt);
            pressure.divergence_solve(&step, fluid)
        } else {
            SolveReport::default()
        };
        // What the divergence solve gave the free rigid bodies.
        let after_divergence = match (&self.coupled, self.settings.divergence_solve) {
            (Some(coupled), true) => coupled.velocity_change(&world.fluid.divergence_stiffness),
            (Some(coupled), false) => vec![BodyVelocity::default(); coupled.bodies()],
            (None, _) => Vec::new(),
        };
        // Line 7: Δt from the CFL condition and the stability bounds, no longer than a
        // recent retry allows.
        let cfl_dt = self.cfl_time_step(world);
        // Lines 6, 8 and 9, Algorithm 3: non-pressure forces, predicted velocities and the
        // density solve, redone with half the Δt while the step is unsound.
        let density = self.density_solve_until_sound(
            world,
            cfl_dt.min(self.retry_dt_limit),
            &after_divergence,
        );
        // The rigid bodies take what their walls gave the fluid in both solves, and move.
        let impulses = self.rigid_body_impulses(world, density.dt, Terms::All);
        self.move_rigid_bodies(world, density.dt, &impulses);
        // Line 10: advect (and move the walls); put back what left the tank or entered a
        // body.
        self.advect(world, density.dt);
        let (clamped, non_finite) = self.enforce_tank(world);
        let clamped = clamped + self.enforce_rigid_bodies(world);
        self.record_statistics(world, cfl_dt, &density, &divergence, (clamped, non_finite));
    }

    /// Lines 6, 8 and 9 of Algorithm 1 for a step of `dt`: the non-pressure forces, the
    /// predicted velocities and the density solve. An unsound attempt is redone from the
    /// divergence-free velocities with a shorter Δt ([`Attempts`]); the attempt taken is
    /// returned.
    ///
    /// `after_divergence` is what the divergence solve gave each free rigid body: with it,
    /// gravity and the walls' ghosts, the density solve starts from the bodies' predicted
    /// velocities, as the water's.
    fn density_solve_until_sound(
        &mut self,
        world: &mut World,
        dt: f32,
        after_divergence: &[BodyVelocity],
    ) -> DensityStep {
        let mut attempts = Attempts::new(dt, world.scene.time_step.min as f32);
        self.retry_velocity.clone_from(&world.fluid.velocity);
        self.retry_pressure
            .clone_from(&world.fluid.pressure_over_rho0);
        loop {
            let dt = attempts.dt;
            self.predict_velocities(world, dt);
            self.predict_rigid_bodies(world, dt, after_divergence);
            let (step, fluid, pressure) = self.step_parts(world, dt);
            let report = pressure.density_solve(&step, fluid);
            // The check advects the bodies' walls as the solves moved them.
            self.move_rigid_walls_as_solved(world, dt);
            let (step, fluid, pressure) = self.step_parts(world, dt);
            if attempts.is_last()
                || !attempts.redo(
                    &AttemptCheck::of(&step, &report, pressure, fluid),
                    step.settings,
                )
            {
                let retries = attempts.retries;
                return DensityStep {
                    dt,
                    report,
                    retries,
                };
            }
            // Redo the step from the divergence-free velocities (and the bodies' walls from
            // their velocities as the step began).
            world.place_rigid_particles();
            world.fluid.velocity.clone_from(&self.retry_velocity);
            world
                .fluid
                .pressure_over_rho0
                .clone_from(&self.retry_pressure);
        }
    }

    /// Lines 6 and 8 of Algorithm 1: the non-pressure accelerations a (gravity, viscosity,
    /// the walls' hydrostatic ghosts, the pointer) and the predicted velocities `v* = v + Δt·a`.
    fn predict_velocities(&mut self, world: &mut World, dt: f32) {
        // The walls' ghosts continue the solve's stiffness field, whose slope at rest is g/c
        // (see `gradient_consistency`).
        let ghost_slope = self
            .pressure
            .walls()
            .hydrostatic_ghost_gradient(world.gravity)
            .map(|g| g / self.gradient_consistency);
        let (viscosity, pointer) = (self.viscosity, world.pointer);
        let (step, fluid, _) = self.step_parts(world, dt);
        forces::non_pressure_accelerations(&step, &viscosity, pointer, ghost_slope, fluid);
        fluid
            .velocity
            .par_iter_mut()
            .zip(fluid.acceleration.par_iter())
            .with_min_len(LIGHT_PASS_MIN_ITEMS)
            .for_each(|(v, &a)| *v += dt * a);
    }

    /// Line 10 of Algorithm 1: `x += Δt·v`; the walls move with their bodies.
    fn advect(&mut self, world: &mut World, dt: f32) {
        world
            .fluid
            .position
            .par_iter_mut()
            .zip(world.fluid.velocity.par_iter())
            .with_min_len(LIGHT_PASS_MIN_ITEMS)
            .for_each(|(x, &v)| *x += dt * v);
        world.move_walls(dt);
    }

    /// Close the step taken (`density`, after the divergence solve's report `divergence`,
    /// with `cfl_dt` the CFL step and `(clamped, non_finite)` what [`Self::enforce_tank`] put
    /// back): advance the clock, relax the bound a retry set on Δt, and fill [`StepStats`].
    fn record_statistics(
        &mut self,
        world: &mut World,
        cfl_dt: f32,
        density: &DensityStep,
        divergence: &SolveReport,
        (clamped, non_finite): (u32, u32),
    ) {
        let dt = density.dt;
        let avg_neighbors = if world.fluid.is_empty() {
            0.0
        } else {
            (self.fluid_lists.pair_count() + self.boundary_lists.pair_count()) as f64
                / world.fluid.len() as f64
        };
        world.time += step_seconds(dt);
        world.step_count += 1;
        self.last_dt = dt;
        let growth = self.settings.retry_limit_growth;
        self.retry_dt_limit = if density.retries > 0 {
            dt
        } else if self.retry_dt_limit * growth >= cfl_dt {
            f32::INFINITY
        } else {
            self.retry_dt_limit * growth
        };
        self.total_clamped += clamped as u64;
        self.total_non_finite += non_finite as u64;
        let (max_speed, kinetic_energy) = world.speed_and_energy();
        self.stats = StepStats {
            step: world.step_count,
            time: world.time,
            dt: step_seconds(dt),
            n_fluid: world.fluid.len(),
            n_boundary: world.boundary.len(),
            density_iterations: density.report.iterations,
            divergence_iterations: divergence.iterations,
            avg_density_error_pct: density.report.avg_error_pct,
            max_density_error_pct: density.report.max_error_pct,
            divergence_error_pct: divergence.avg_error_pct,
            max_speed,
            kinetic_energy,
            clamped,
            non_finite,
            avg_neighbors,
            retries: density.retries,
        };
    }

    /// The pressure's bound on Δt, `pressure_wave_stability·d/√(|g|·D)`, D the fluid's extent
    /// along gravity: the hydrostatic pressure at the bottom of the deepest water there can
    /// be. It stays put while water rests. A bound on the solved pressure's maximum followed
    /// its jitter of a few percent from step to step, and a column at rest under a Δt that
    /// varies that much sloshed (the 400-layer column at 0.06 m/s, against 0.006 m/s under a
    /// fixed Δt of the same length). Pressure peaks of impacts are brief and come with
    /// speeds whose CFL step is shorter anyway.
    fn pressure_wave_time_step(&self, world: &World) -> f32 {
        let g = world.gravity.length();
        if g == 0.0 || world.fluid.is_empty() {
            return f32::INFINITY;
        }
        let down = world.gravity / g;
        let (lo, hi) = world
            .fluid
            .position
            .par_iter()
            .with_min_len(LIGHT_PASS_MIN_ITEMS)
            .map(|p| {
                let depth = p.dot(down);
                (depth, depth)
            })
            .reduce(
                || (f32::INFINITY, f32::NEG_INFINITY),
                |a, b| (a.0.min(b.0), a.1.max(b.1)),
            );
        let extent = (hi - lo).max(0.0) + world.spacing;
        self.settings.pressure_wave_stability * world.spacing / (g * extent).sqrt()
    }

    /// CFL condition `Δt = λ·d / v_max` (v_max includes moving walls; WCSPH adds the speed of
    /// sound), at most `√(λ·d/|g|)`, clamped to the scene's bounds; then at most the viscous
    /// stability bound, [`Self::pressure_wave_time_step`] and [`step_displacement_bound`],
    /// which all beat `time_step.min`.
    fn cfl_time_step(&self, world: &World) -> f32 {
        let ts = &world.scene.time_step;
        let fluid_max = world
            .fluid
            .velocity
            .par_iter()
            .with_min_len(LIGHT_PASS_MIN_ITEMS)
            .map(|v| v.length_squared())
            .reduce(|| 0.0, f32::max)
            .sqrt();
        let wall_max = world
            .bodies
            .iter()
            .map(|b| b.velocity.length())
            .fold(0.0, f32::max);
        let mut v_max = fluid_max.max(wall_max);
        if let Some(sound) = self.pressure.sound_speed() {
            v_max += sound;
        }
        let mut dt = if v_max > 0.0 {
            ts.cfl as f32 * world.spacing / v_max
        } else {
            ts.max as f32
        };
        // The speed gravity adds during the step, |g|·Δt, must obey the same condition:
        // Δt ≤ λ·d / (|g|·Δt). It binds only for a still fluid under a large `max`, whose
        // first step would otherwise drop every particle by ½·|g|·max².
        let g = world.gravity.length();
        if g > 0.0 {
            dt = dt.min((ts.cfl as f32 * world.spacing / g).sqrt());
        }
        // The explicit viscosity is stable only below a bound (`viscosity::Laplacian`). This
        // bound beats the scene's minimum Δt: a step below the minimum is slow, one above the
        // bound blows up.
        let upper = (ts.max as f32)
            .min(self.viscosity.max_time_step(world.spacing, &self.settings))
            .min(self.pressure_wave_time_step(world));
        // No step may carry water through a wall: the distance a particle travels in it under
        // the step's accelerations, |v|·Δt + ½|a|·Δt², stays within MAX_STEP_DISPLACEMENT·d
        // ([`step_displacement_bound`]). Like the viscous bound it beats the scene's minimum
        // (the validator refuses a `time_step.min` above it from rest; later, a fast flow can
        // bring it lower). The speed is the fastest particle's plus the fastest wall's (they
        // may close on each other); the acceleration is gravity's, the pointer's, and the
        // shaken tank's.
        let mut acceleration = g;
        if let Some(p) = world.pointer.filter(|p| p.radius > 0.0) {
            let strength = p.strength.abs().min(forces::MAX_POINTER_ACCELERATION);
            acceleration += strength;
            if p.strength < 0.0 {
                // A pull also damps the velocity relative to the pointer (4·|v| at most).
                acceleration += 4.0 * fluid_max;
            }
        }
        if world.shake_drive != 0.0 || wall_max > 0.0 {
            acceleration += MAX_SHAKE_ACCELERATION;
        }
        let bound = step_displacement_bound(
            (fluid_max + wall_max) as f64,
            acceleration as f64,
            world.spacing as f64,
        ) as f32;
        dt.clamp((ts.min as f32).min(upper), upper).min(bound)
    }

    /// Find which fluid particles touch which free rigid body, so that the bodies move inside
    /// the solves ([`crate::rigid::coupled`]), and lower those particles' factors to match.
    fn couple_rigid_bodies(&mut self, world: &mut World) {
        let Some(rigid) = &world.rigid else {
            self.coupled = None;
            return;
        };
        let mobility: Vec<_> = (0..rigid.len()).map(|k| rigid.mobility(k)).collect();
        let (bodies, boundary) = (&world.bodies, &world.boundary);
        let (lists, grads) = (&self.boundary_lists, &self.pair_cache.boundary_grad);
        let coupled = CoupledBodies::new(
            world.fluid.len(),
            |i| (lists.of(i), &grads[lists.range(i)]),
            |b| bodies[boundary.body[b] as usize].rigid,
            &boundary.position,
            &boundary.volume,
            &mobility,
            world.particle_mass(),
            self.pressure.walls().gradient_weight(),
        );
        coupled.damp_factors(&mut world.fluid.factor);
        self.wall_flux_at_start
            .clone_from(&self.pair_cache.wall_flux);
        self.coupled = Some(coupled);
    }

    /// Line 8 of Algorithm 1 for the free rigid bodies: their velocities as the density solve
    /// of a step of `dt` starts, after the divergence solve (`after_divergence`), gravity and
    /// the walls' ghosts, given to the solve through the walls' share of the density rate.
    fn predict_rigid_bodies(
        &mut self,
        world: &mut World,
        dt: f32,
        after_divergence: &[BodyVelocity],
    ) {
        let (Some(rigid), Some(_)) = (&world.rigid, &self.coupled) else {
            return;
        };
        let mut moved = rigid.gravity_velocity_change(world.gravity, dt);
        for (m, &a) in moved.iter_mut().zip(after_divergence) {
            *m += a;
        }
        if self
            .pressure
            .walls()
            .hydrostatic_ghost_gradient(world.gravity)
            .is_some()
        {
            let ghosts = self.rigid_velocity_change(world, dt, Terms::Ghosts);
            for (m, g) in moved.iter_mut().zip(ghosts) {
                *m += g;
            }
        }
        let Some(coupled) = &self.coupled else {
            return;
        };
        let flux = &mut self.pair_cache.wall_flux;
        flux.clone_from(&self.wall_flux_at_start);
        let n = flux.len();
        coupled.add_flux(flux, 0..n, &moved, 1.0);
        self.rigid_predicted = moved;
    }

    /// Give the moving bodies' boundary particles the velocity the step's solves gave their
    /// bodies (the prediction of [`Self::predict_rigid_bodies`] and the density solve's
    /// impulses), for the step's linearisation check; rapier's step puts them where the
    /// bodies went afterwards ([`Self::place_rigid_particles`]).
    fn move_rigid_walls_as_solved(&mut self, world: &mut World, dt: f32) {
        let (Some(rigid), Some(coupled)) = (&world.rigid, &self.coupled) else {
            return;
        };
        let kappa_per_pressure = dt * self.pressure.pressure_force_scale();
        let mut moved = self.rigid_predicted.clone();
        let density =
            coupled.velocity_change_of(&world.fluid.pressure_over_rho0, kappa_per_pressure);
        for (m, d) in moved.iter_mut().zip(density) {
            *m += d;
        }
        // A body that touches something moves as its contacts let it, which the solves do
        // not see: its walls keep their velocity from before the step, the check's cautious
        // assumption.
        for (k, m) in moved.iter_mut().enumerate() {
            if rigid.touches_something(k) {
                *m = BodyVelocity::default();
            }
        }
        let centres: Vec<Vec2> = (0..rigid.len()).map(|k| rigid.mobility(k).centre).collect();
        let bodies = &world.bodies;
        world
            .boundary
            .position
            .par_iter()
            .zip(world.boundary.velocity.par_iter_mut())
            .zip(world.boundary.body.par_iter())
            .with_min_len(LIGHT_PASS_MIN_ITEMS)
            .for_each(|((&x, v), &b)| {
                if let Some(k) = bodies[b as usize].rigid {
                    let (k, m) = (
                        k as usize,
                        moved.get(k as usize).copied().unwrap_or_default(),
                    );
                    *v += m.linear + m.angular * (x - centres[k]).perp();
                }
            });
    }

    /// The velocity change of each rigid body from what the walls gave the fluid in `terms`
    /// of the step of `dt`, about its mobility centre ([`RigidBodies::mobility`]: zero for a
    /// fixed body, a turn about the anchor for a hinged one).
    fn rigid_velocity_change(
        &mut self,
        world: &mut World,
        dt: f32,
        terms: Terms,
    ) -> Vec<BodyVelocity> {
        let impulses = self.rigid_body_impulses(world, dt, terms);
        let Some(rigid) = &world.rigid else {
            return Vec::new();
        };
        impulses
            .iter()
            .enumerate()
            .map(|(k, j)| {
                let mobile = rigid.mobility(k);
                // The impulse's moment about the centre of mass, moved to the mobility centre.
                let r = rigid.centre_of_mass(k) - mobile.centre;
                BodyVelocity {
                    linear: mobile.inverse_mass * j.linear,
                    angular: mobile.inverse_inertia * (j.angular + r.perp_dot(j.linear)),
                }
            })
            .collect()
    }

    /// The impulse the fluid gave each rigid body through `terms` of the step of `dt`, with
    /// its moment about the body's centre of mass ([`coupling`]).
    fn rigid_body_impulses(
        &mut self,
        world: &mut World,
        dt: f32,
        terms: Terms,
    ) -> Vec<coupling::BodyImpulse> {
        let Some(rigid) = &world.rigid else {
            return Vec::new();
        };
        let rigid_of: Vec<Option<u16>> = world.bodies.iter().map(|b| b.rigid).collect();
        let centres: Vec<Vec2> = (0..rigid.len()).map(|k| rigid.centre_of_mass(k)).collect();
        let walls = self.pressure.walls();
        let ghost_slope = walls
            .hydrostatic_ghost_gradient(world.gravity)
            .map(|g| g / self.gradient_consistency);
        let (weight, mass) = (walls.gradient_weight(), world.particle_mass());
        let pressure_to_kappa = dt * self.pressure.pressure_force_scale();
        let (step, fluid, _) = self.step_parts(world, dt);
        // Scenes with bodies run DFSPH (`Scene::validate`), whose solves apply these terms.
        let solves = matches!(terms, Terms::All);
        let terms = WallTerms {
            divergence_stiffness: (solves && step.settings.divergence_solve)
                .then_some(&fluid.divergence_stiffness[..]),
            pressure_to_kappa: if solves { pressure_to_kappa } else { 0.0 },
            weight,
            ghost_slope,
        };
        coupling::body_impulses(&step, fluid, &terms, mass, &rigid_of, &centres)
    }

    /// Advance the rigid bodies by `dt` under gravity and the fluid's `impulses`, and put
    /// their boundary particles where the bodies went, with the bodies' velocities there.
    fn move_rigid_bodies(
        &mut self,
        world: &mut World,
        dt: f32,
        impulses: &[coupling::BodyImpulse],
    ) {
        let Some(rigid) = &mut world.rigid else {
            return;
        };
        let tank_offset = world.bodies[0].offset;
        if world.walls_moved_for_bodies {
            let bodies = &world.bodies;
            let walls = world
                .boundary
                .position
                .iter()
                .zip(&world.boundary.body)
                .filter(|&(_, &b)| b != 0 && bodies[b as usize].rigid.is_none())
                .map(|(&p, _)| p - tank_offset);
            rigid.set_walls(walls, world.spacing);
            world.walls_moved_for_bodies = false;
        }
        rigid.step(dt, world.gravity, impulses, tank_offset);
        world.place_rigid_particles();
    }

    /// Last-resort containment for the rigid bodies, like [`Self::enforce_tank`]'s: a fluid
    /// particle past the centre line of a body's first boundary layer (half a spacing inside
    /// its outline) has gone through it; it is put back on the outline, its velocity into
    /// the body removed, and counted.
    fn enforce_rigid_bodies(&mut self, world: &mut World) -> u32 {
        let Some(rigid) = &world.rigid else {
            return 0;
        };
        let margin = 0.5 * world.spacing;
        world
            .fluid
            .position
            .par_iter_mut()
            .zip(world.fluid.velocity.par_iter_mut())
            .with_min_len(LIGHT_PASS_MIN_ITEMS)
            .map(|(x, v)| rigid.push_out(x, v, margin) as u32)
            .sum()
    }

    /// Last-resort containment: a particle whose centre has crossed the centre line of the
    /// tank's first boundary layer ([`Self::tank_containment`]) has gone through the wall; it
    /// is put back on the interior's edge, its outward velocity removed, and counted. A
    /// non-finite particle is reset to rest at the tank centre and counted. Both counts
    /// should stay zero.
    fn enforce_tank(&mut self, world: &mut World) -> (u32, u32) {
        let (lo, hi) = world.tank_interior();
        let (outer_lo, outer_hi) = world.tank_containment();
        let centre = 0.5 * (lo + hi);
        let wall_v = world.bodies[0].velocity;
        world
            .fluid
            .position
            .par_iter_mut()
            .zip(world.fluid.velocity.par_iter_mut())
            .with_min_len(LIGHT_PASS_MIN_ITEMS)
            .map(|(x, v)| {
                if !(x.is_finite() && v.is_finite()) {
                    *x = centre;
                    *v = Vec2::ZERO;
                    return (0u32, 1u32);
                }
                if x.x >= outer_lo.x && x.x <= outer_hi.x && x.y >= outer_lo.y && x.y <= outer_hi.y
                {
                    return (0, 0);
                }
                *x = x.clamp(lo, hi);
                if (x.x <= lo.x && v.x < wall_v.x) || (x.x >= hi.x && v.x > wall_v.x) {
                    v.x = wall_v.x;
                }
                if (x.y <= lo.y && v.y < wall_v.y) || (x.y >= hi.y && v.y > wall_v.y) {
                    v.y = wall_v.y;
                }
                (1, 0)
            })
            .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1))
    }

    /// The solve's pressures interpolated twice with the kernel (Shepard), as outputs show
    /// them ([`crate::Simulation::interpolated_pressures_over_rho0`] says why).
    fn interpolated_pressures_over_rho0(&self, world: &World) -> Vec<f32> {
        let p = &world.fluid.pressure_over_rho0;
        if p.len() != world.fluid.len() || self.fluid_lists.len() != world.fluid.len() {
            // Before the first step or right after a pour: nothing to interpolate over yet.
            return p.clone();
        }
        self.shepard_interpolation(world, &self.shepard_interpolation(world, p))
    }

    /// `Σ_j W_ij f_j / Σ_j W_ij` at every fluid particle, j over its fluid neighbours and itself.
    fn shepard_interpolation(&self, world: &World, f: &[f32]) -> Vec<f32> {
        let x = &world.fluid.position;
        let w0 = world.kernel.w(0.0);
        (0..x.len())
            .into_par_iter()
            .with_min_len(LIGHT_PASS_MIN_ITEMS)
            .map(|i| {
                let (mut sum, mut weight) = (w0 * f[i], w0);
                for &j in self.fluid_lists.of(i) {
                    let w = world.kernel.w((x[i] - x[j as usize]).length());
                    sum += w * f[j as usize];
                    weight += w;
                }
                sum / weight
            })
            .collect()
    }

    /// Fluid neighbours of particle `i` at its current position.
    fn count_close(&self, world: &World, i: usize) -> usize {
        let mut count = 0usize;
        self.fluid_grid
            .for_each_near(world.fluid.position[i], |_, _| count += 1);
        count.saturating_sub(1)
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
