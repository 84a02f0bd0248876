//! The Laplacian viscosity with a kinematic ν (Morris et al. 1997; Monaghan 2005, 2D so
//! `2(d+2) = 8`):
//!
//! `a_i += 8ν Σ_j V_j (v_ij·x_ij)/(|x_ij|² + 0.01h²) ∇W_ij`,
//!
//! and the same against boundary particles with their velocity and `ν_b` (wall friction,
//! [`super::WallFriction`]).
//! Explicit, so stable only for `Δt ≤ 0.125·d²/ν` (`SolverSettings::viscous_stability`).

use glam::Vec2;

use super::model::ViscosityModel;
use crate::forces::model::{AccelerationModel, Particle};
use crate::kernel::Kernel;
use crate::scene::ViscosityParams;
use crate::settings::SolverSettings;

/// The Laplacian viscosity: ν between fluid particles and ν_b between fluid and walls.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Laplacian {
    /// ν, m²/s (the scene's `viscosity.kinematic`).
    pub kinematic: f32,
    /// ν_b, m²/s (the scene's `viscosity.boundary_kinematic`).
    pub boundary_kinematic: f32,
}

impl Laplacian {
    pub fn from_scene(params: &ViscosityParams) -> Self {
        Self {
            kinematic: params.kinematic as f32,
            boundary_kinematic: params.boundary_kinematic as f32,
        }
    }

    /// `0.01h²`, m²: keeps `(v_ij·x_ij)/|x_ij|²` finite for particles on top of each other.
    pub fn regularisation(kernel: &Kernel) -> f32 {
        0.01 * kernel.support() * kernel.support()
    }
}

impl ViscosityModel for Laplacian {
    /// `8ν`, m²/s, times `V Σ_j ∇W_ij (v_ij·x_ij)/(|x_ij|² + 0.01h²)`.
    fn pair_scale(&self, _dt: f32) -> f32 {
        8.0 * self.kinematic
    }

    /// `viscous_stability·d²/ν` with the larger of ν and ν_b (Morris et al. 1997, eq. 34, h
    /// the smoothing length, our spacing d).
    fn max_time_step(&self, spacing: f32, settings: &SolverSettings) -> f32 {
        let nu = self.kinematic.max(self.boundary_kinematic);
        if nu > 0.0 {
            settings.viscous_stability * spacing * spacing / nu
        } else {
            f32::INFINITY
        }
    }
}

impl AccelerationModel for Laplacian {
    /// `V·8ν·Σ_j ∇W_ij (v_ij·x_ij)/(|x_ij|² + 0.01h²)`, from the step's fluid pair sums.
    fn add_to(&self, p: &Particle, acc: &mut Vec2) {
        *acc += p.step.volume * (self.pair_scale(p.step.dt) * p.laplace);
    }
}
