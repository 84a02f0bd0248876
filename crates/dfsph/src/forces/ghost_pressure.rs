//! The hydrostatic part of the mirrored walls' ghost pressure
//! ([`crate::boundary::MirroredWalls`]).
//!
//! The ghost at wall particle b carries `κ_b = κ_i + Δt g_s·(x_b − x_i)` rather than `κ_i`,
//! where `g_s` is the slope of the solve's stiffness field at rest (gravity over the
//! lattice's gradient consistency). The extra part does not depend on the solve's unknowns,
//! so it is an acceleration `a_i −= Σ_b Ψ_b (g_s·(x_b − x_i)) ∇W_ib`, and the pressure
//! operator stays symmetric. With it ρ0 g (H − y) is the discrete equilibrium next to walls
//! as well: on the lattice the wall row's own pressure and the ghosts' gradient together give
//! it the same support against gravity as a particle inside the fluid (docs/deep-columns.md).

use glam::Vec2;

use super::model::{AccelerationModel, Particle};

/// The ghosts' hydrostatic push, with `slope` = g_s, m/s².
pub(crate) struct GhostPressure {
    pub slope: Vec2,
}

impl AccelerationModel for GhostPressure {
    fn add_to(&self, p: &Particle, acc: &mut Vec2) {
        let boundary = p.step.boundary;
        let mut push = Vec2::ZERO;
        for (b, g) in p.step.nb.walls_of(p.index) {
            push += boundary.volume[b] * self.slope.dot(boundary.position[b] - p.position) * g;
        }
        *acc -= push;
    }
}
