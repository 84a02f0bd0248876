//! Wall friction: the Laplacian viscosity between fluid particles and the walls next to
//! them, with the walls' velocity and its own kinematic viscosity ν_b (the scene's
//! `viscosity.boundary_kinematic`): `a_i += 8ν_b Σ_b Ψ_b (v_ib·x_ib)/(|x_ib|² + 0.01h²) ∇W_ib`.
//! Its Δt bound is the Laplacian's ([`super::Laplacian`]), which takes the larger of ν and ν_b.

use glam::Vec2;

use super::laplacian::Laplacian;
use crate::forces::model::{AccelerationModel, Particle};
use crate::kernel::Kernel;

/// Friction against the walls, `8ν_b` and the regularisation `0.01h²`.
pub(crate) struct WallFriction {
    /// `8ν_b`, m²/s; 0 when the walls have no friction.
    scale: f32,
    /// `0.01h²`, m².
    eps2: f32,
}

impl WallFriction {
    /// The friction of `laplacian`'s ν_b with `kernel`'s support.
    pub fn new(laplacian: &Laplacian, kernel: &Kernel) -> Self {
        Self {
            scale: 8.0 * laplacian.boundary_kinematic,
            eps2: Laplacian::regularisation(kernel),
        }
    }

    /// Whether the walls have friction at all.
    pub fn acts(&self) -> bool {
        self.scale > 0.0
    }
}

impl AccelerationModel for WallFriction {
    /// `8ν_b Σ_b Ψ_b (v_ib·x_ib)/(|x_ib|² + eps2) ∇W_ib` over the particle's wall neighbours
    /// (with their cached `∇W_ib`).
    fn add_to(&self, p: &Particle, acc: &mut Vec2) {
        let boundary = p.step.boundary;
        let mut laplace = Vec2::ZERO;
        for (b, g) in p.step.nb.walls_of(p.index) {
            let xib = p.position - boundary.position[b];
            let vib = p.velocity - boundary.velocity[b];
            laplace += boundary.volume[b] * g * (vib.dot(xib) / (xib.length_squared() + self.eps2));
        }
        *acc += self.scale * laplace;
    }
}
