//! Viscosity models, one per file: [`Xsph`] velocity smoothing, the [`Laplacian`] viscosity
//! with a kinematic ν, and [`WallFriction`] with the walls' ν_b. A scene combines them (each
//! is off at zero, `viscosity` in the scene). Each is a force model
//! (`forces::model::AccelerationModel`) in the list of `forces::non_pressure_accelerations`;
//! [`Viscosity::max_time_step`] combines their Δt bounds.
//!
//! The fluid pair sums of XSPH and the Laplacian run together, in one pass over the blocks
//! (`blocked::BlockedPairs::viscosity_sums`, whose per-pair formulas are in
//! `blocked/formulas.rs`, once for the lane and the AVX-512 kernels): the pass reads each
//! pair's `W` and `∇W` once for both, and each model reads its own sum.

use crate::scene::ViscosityParams;
use crate::settings::SolverSettings;

mod laplacian;
mod model;
mod wall_friction;
mod xsph;

pub(crate) use laplacian::Laplacian;
pub(crate) use model::ViscosityModel;
pub(crate) use wall_friction::WallFriction;
pub(crate) use xsph::Xsph;

/// The viscosity models of a scene, in solver units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Viscosity {
    pub xsph: Xsph,
    pub laplacian: Laplacian,
}

impl Viscosity {
    /// The scene's `viscosity` section.
    pub fn from_scene(params: &ViscosityParams) -> Self {
        Self {
            xsph: Xsph::from_scene(params),
            laplacian: Laplacian::from_scene(params),
        }
    }

    /// The longest Δt at which every model is stable, s.
    ///
    /// The models act in one explicit update (`v += Δt·(a_xsph + a_lap)`), so their damping of
    /// the fastest particle-scale mode adds up: XSPH takes a share c of it each step, and the
    /// Laplacian's bound, met alone, is shortened by the factor `1 − c` so that the sum stays
    /// stable. Each alone was stable and together they were not: a dam break at r = 2.5 cm
    /// with c = 1 and ν = 1 m²/s reached 28 m/s within 0.5 s (c = 0.5: 16 m/s; 2.1 m/s with
    /// the shortened step), where either alone stays under 5 m/s.
    pub fn max_time_step(&self, spacing: f32, settings: &SolverSettings) -> f32 {
        let share_left = (1.0 - self.xsph.coefficient).max(0.0);
        let models: [&dyn ViscosityModel; 2] = [&self.xsph, &self.laplacian];
        let alone = models
            .iter()
            .map(|m| m.max_time_step(spacing, settings))
            .fold(f32::INFINITY, f32::min);
        if alone.is_finite() {
            alone * share_left
        } else {
            alone
        }
    }
}
