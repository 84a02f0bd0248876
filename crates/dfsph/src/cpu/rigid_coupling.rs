//! The free rigid bodies inside the CPU backend's step: which fluid touches them, their
//! predicted velocities inside the solves, the impulses the fluid gave them, and rapier's
//! step that moves them ([`crate::rigid`] holds the bodies and the coupling's terms).

use crate::par::prelude::*;
use crate::parallel::LIGHT_PASS_MIN_ITEMS;
use glam::Vec2;

use super::CpuBackend;
use crate::rigid::coupling::{self, WallTerms};
use crate::rigid::{BodyVelocity, CoupledBodies};
use crate::world::World;

/// Which of a step's terms [`CpuBackend::rigid_body_impulses`] sums.
#[derive(Clone, Copy, Debug)]
pub(super) enum Terms {
    /// The mirrored walls' hydrostatic ghosts' (part of the non-pressure forces).
    Ghosts,
    /// Both solves' and the ghosts'.
    All,
}

impl CpuBackend {
    /// Find which fluid particles touch which free rigid body, so that the bodies move inside
    /// the solves ([`crate::rigid::coupled`]), and lower those particles' factors to match.
    pub(super) fn couple_rigid_bodies(&mut self, world: &mut World) {
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
    pub(super) fn predict_rigid_bodies(
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
    pub(super) fn move_rigid_walls_as_solved(&mut self, world: &mut World, dt: f32) {
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
    pub(super) fn rigid_velocity_change(
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
    pub(super) fn rigid_body_impulses(
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
    pub(super) fn move_rigid_bodies(
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
}
