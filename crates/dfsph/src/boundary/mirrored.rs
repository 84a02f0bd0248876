//! Walls that mirror the fluid, for the conjugate-gradient density solve.
//!
//! The wall's share of the density is the mirrored fluid's (`Σ_b Ψ_b W_ib`), and its
//! derivative, since the mirror image moves with the particle, counts twice, in the density
//! rate, the pressure push (`p_b = p_i`: `κ_i + κ_b = 2κ_i`) and the factor. With it a particle
//! next to a wall controls its own distance to the wall; with [`super::AkinciWalls`] a
//! particle on the lattice next to a wall does not (its gradient sums cancel,
//! docs/deep-columns.md) and the fluid's pressure pushes it into the wall.
//!
//! The ghosts also carry the hydrostatic part of the pressure (Band et al. 2018, "Pressure
//! boundaries for implicit incompressible SPH", pressure extrapolation): the ghost at wall
//! particle b carries `p_b = p_i + ρ0 g·(x_b − x_i)` rather than `p_i`
//! (`forces::non_pressure_accelerations` applies the extra part). With it ρ0 g (H − y) is the
//! discrete equilibrium next to walls as well.

use glam::Vec2;

use super::model::BoundaryModel;

/// Walls that mirror the fluid's pressure, with its hydrostatic gradient.
#[derive(Clone, Copy, Debug, Default)]
pub struct MirroredWalls;

impl BoundaryModel for MirroredWalls {
    fn gradient_weight(&self) -> f32 {
        2.0
    }

    fn hydrostatic_ghost_gradient(&self, gravity: Vec2) -> Option<Vec2> {
        Some(gravity)
    }
}
