//! The CPU backend's neighbourhoods: both particle sets sorted by cell, the fluid and wall
//! lists, densities and factors; what a step's passes read (`StepContext`); the output
//! pressure interpolated over the neighbourhoods.

use crate::par::prelude::*;
use crate::parallel::LIGHT_PASS_MIN_ITEMS;
use glam::Vec2;

use super::CpuBackend;
use crate::boundary;
use crate::particles::FluidParticles;
use crate::pressure::PressureSolver;
use crate::solver::{self, Neighborhood, Walls};
use crate::step::StepContext;
use crate::world::World;

impl CpuBackend {
    /// Sort both particle sets, rebuild neighbour lists, densities and factors.
    pub(super) fn update_neighborhoods(&mut self, world: &mut World) {
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
    pub(super) fn step_parts<'a>(
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

    /// The solve's pressures interpolated twice with the kernel (Shepard), as outputs show
    /// them ([`crate::Simulation::interpolated_pressures_over_rho0`] says why).
    pub(super) fn interpolated_pressures_over_rho0(&self, world: &World) -> Vec<f32> {
        let p = &world.fluid.pressure_over_rho0;
        if p.len() != world.fluid.len() || self.fluid_lists.len() != world.fluid.len() {
            // Before the first step or right after a pour: nothing to interpolate over yet.
            return p.clone();
        }
        self.shepard_interpolation(world, &self.shepard_interpolation(world, p))
    }

    /// `Σ_j W_ij f_j / Σ_j W_ij` at every fluid particle, j over its fluid neighbours and itself.
    pub(super) fn shepard_interpolation(&self, world: &World, f: &[f32]) -> Vec<f32> {
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
    pub(super) fn count_close(&self, world: &World, i: usize) -> usize {
        let mut count = 0usize;
        self.fluid_grid
            .for_each_near(world.fluid.position[i], |_, _| count += 1);
        count.saturating_sub(1)
    }
}
