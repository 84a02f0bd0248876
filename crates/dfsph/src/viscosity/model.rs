//! What a viscosity model tells the step ([`super::Xsph`], [`super::Laplacian`]).

use crate::settings::SolverSettings;

/// What a viscosity model tells the step.
pub(crate) trait ViscosityModel {
    /// What its fluid pair sum is multiplied by in the acceleration, for a step of `dt`
    /// seconds (the sum's unit times this is m/s²); 0 when the model is off.
    fn pair_scale(&self, dt: f32) -> f32;

    /// The longest Δt, s, at which the model is stable at lattice spacing `spacing` (m);
    /// infinite when it sets no bound.
    fn max_time_step(&self, spacing: f32, settings: &SolverSettings) -> f32 {
        let _ = (spacing, settings);
        f32::INFINITY
    }
}
