//! The CPU backend's Δt: the CFL condition and the stability bounds of
//! [`crate::time_step`], with the backend's viscosity and pressure solver.

use super::CpuBackend;
use crate::world::World;

impl CpuBackend {
    /// The CFL step of `world` and its bounds ([`World::cfl_time_step`]) with this
    /// backend's settings, viscosity and (WCSPH) speed of sound.
    pub(super) fn cfl_time_step(&self, world: &World) -> f32 {
        world.cfl_time_step(
            &self.settings,
            self.viscosity.max_time_step(world.spacing, &self.settings),
            self.pressure.sound_speed(),
        )
    }
}
