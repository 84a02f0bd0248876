//! One step of the CPU backend: Algorithm 1 of Bender & Koschier (TVCG 2017), the retries of
//! the density solve, advection, containment and the step's statistics.

use crate::par::{self, prelude::*};
use crate::parallel::{self, LIGHT_PASS_MIN_ITEMS};
use glam::Vec2;
use web_time::Instant;

use super::rigid_coupling::Terms;
use super::CpuBackend;
use crate::backend::StepStats;
use crate::forces;
use crate::pressure::SolveReport;
use crate::retry::{AttemptCheck, Attempts, DensityStep};
use crate::rigid::BodyVelocity;
use crate::world::{step_seconds, World};

impl CpuBackend {
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
    pub(super) fn step_on_a_worker(&mut self, world: &mut World) {
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
    pub(super) fn advance(&mut self, world: &mut World) {
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
    pub(super) fn density_solve_until_sound(
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
    pub(super) fn predict_velocities(&mut self, world: &mut World, dt: f32) {
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
    pub(super) fn advect(&mut self, world: &mut World, dt: f32) {
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
    pub(super) fn record_statistics(
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

    /// Last-resort containment for the rigid bodies, like [`Self::enforce_tank`]'s: a fluid
    /// particle past the centre line of a body's first boundary layer (half a spacing inside
    /// its outline) has gone through it; it is put back on the outline, its velocity into
    /// the body removed, and counted.
    pub(super) fn enforce_rigid_bodies(&mut self, world: &mut World) -> u32 {
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
    pub(super) fn enforce_tank(&mut self, world: &mut World) -> (u32, u32) {
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
}
