//! The Δt a step of a world may take, for every backend: the CFL condition and the
//! stability bounds (the viscosity's, the deep water's, the largest displacement).

use crate::par::prelude::*;
use crate::parallel::LIGHT_PASS_MIN_ITEMS;

use crate::displacement::step_displacement_bound;
use crate::forces;
use crate::settings::SolverSettings;
use crate::viscosity::Viscosity;
use crate::world::{World, MAX_SHAKE_ACCELERATION};

impl World {
    /// The scene's viscosity's stability bound on Δt, s (infinite without viscosity).
    pub fn viscous_time_step(&self, settings: &SolverSettings) -> f32 {
        Viscosity::from_scene(&self.scene.viscosity).max_time_step(self.spacing, settings)
    }

    /// The pressure's bound on Δt, `stability·d/√(|g|·D)`, D the fluid's extent along
    /// gravity: the hydrostatic pressure at the bottom of the deepest water there can be
    /// (`stability` is [`SolverSettings::pressure_wave_stability`]). It stays put while
    /// water rests. A bound on the solved pressure's maximum followed its jitter of a few
    /// percent from step to step, and a column at rest under a Δt that varies that much
    /// sloshed (the 400-layer column at 0.06 m/s, against 0.006 m/s under a fixed Δt of the
    /// same length). Pressure peaks of impacts are brief and come with speeds whose CFL step
    /// is shorter anyway.
    pub fn pressure_wave_time_step(&self, stability: f32) -> f32 {
        let g = self.gravity.length();
        if g == 0.0 || self.fluid.is_empty() {
            return f32::INFINITY;
        }
        let down = self.gravity / g;
        let (lo, hi) = self
            .fluid
            .position
            .par_iter()
            .with_min_len(LIGHT_PASS_MIN_ITEMS)
            .map(|p| {
                let depth = p.dot(down);
                (depth, depth)
            })
            .reduce(
                || (f32::INFINITY, f32::NEG_INFINITY),
                |a, b| (a.0.min(b.0), a.1.max(b.1)),
            );
        let extent = (hi - lo).max(0.0) + self.spacing;
        stability * self.spacing / (g * extent).sqrt()
    }

    /// The bound on Δt that is not the flow's, s: the scene's `time_step.max`, the viscosity's
    /// `viscous_bound` and [`Self::pressure_wave_time_step`]. The explicit viscosity is stable
    /// only below its bound (`viscosity::Laplacian`); like the others it beats the scene's
    /// minimum Δt: a step below the minimum is slow, one above the bound blows up.
    pub fn time_step_upper_bound(&self, settings: &SolverSettings, viscous_bound: f32) -> f32 {
        (self.scene.time_step.max as f32)
            .min(viscous_bound)
            .min(self.pressure_wave_time_step(settings.pressure_wave_stability))
    }

    /// The acceleration the displacement bound allows for, m/s², besides a pull's damping:
    /// gravity's, the pointer's and the shaken tank's; and whether the pointer pulls (its
    /// damping adds 4·|v| of the fastest particle).
    pub fn displacement_acceleration(&self) -> (f32, bool) {
        let mut acceleration = self.gravity.length();
        let pointer = self.pointer.filter(|p| p.radius > 0.0);
        if let Some(p) = pointer {
            acceleration += p.strength.abs().min(forces::MAX_POINTER_ACCELERATION);
        }
        if self.shake_drive != 0.0 || self.fastest_wall_speed() > 0.0 {
            acceleration += MAX_SHAKE_ACCELERATION;
        }
        (acceleration, pointer.is_some_and(|p| p.strength < 0.0))
    }

    /// CFL condition `Δt = λ·d / v_max` (v_max includes moving walls; WCSPH adds the speed of
    /// sound), at most `√(λ·d/|g|)`, clamped to the scene's bounds; then at most the viscous
    /// stability bound, [`Self::pressure_wave_time_step`] and [`step_displacement_bound`],
    /// which all beat `time_step.min`.
    /// `viscous_bound` is the viscosity's stability bound (s), `sound_speed` WCSPH's (m/s).
    pub fn cfl_time_step(
        &self,
        settings: &SolverSettings,
        viscous_bound: f32,
        sound_speed: Option<f32>,
    ) -> f32 {
        let ts = &self.scene.time_step;
        let fluid_max = self
            .fluid
            .velocity
            .par_iter()
            .with_min_len(LIGHT_PASS_MIN_ITEMS)
            .map(|v| v.length_squared())
            .reduce(|| 0.0, f32::max)
            .sqrt();
        let wall_max = self.fastest_wall_speed();
        let mut v_max = fluid_max.max(wall_max);
        if let Some(sound) = sound_speed {
            v_max += sound;
        }
        let mut dt = if v_max > 0.0 {
            ts.cfl as f32 * self.spacing / v_max
        } else {
            ts.max as f32
        };
        // The speed gravity adds during the step, |g|·Δt, must obey the same condition:
        // Δt ≤ λ·d / (|g|·Δt). It binds only for a still fluid under a large `max`, whose
        // first step would otherwise drop every particle by ½·|g|·max².
        let g = self.gravity.length();
        if g > 0.0 {
            dt = dt.min((ts.cfl as f32 * self.spacing / g).sqrt());
        }
        let upper = self.time_step_upper_bound(settings, viscous_bound);
        // No step may carry water through a wall: the distance a particle travels in it under
        // the step's accelerations, |v|·Δt + ½|a|·Δt², stays within MAX_STEP_DISPLACEMENT·d
        // ([`step_displacement_bound`]). Like the viscous bound it beats the scene's minimum
        // (the validator refuses a `time_step.min` above it from rest; later, a fast flow can
        // bring it lower). The speed is the fastest particle's plus the fastest wall's (they
        // may close on each other); the acceleration is gravity's, the pointer's, and the
        // shaken tank's.
        let (mut acceleration, pulls) = self.displacement_acceleration();
        if pulls {
            // A pull also damps the velocity relative to the pointer (4·|v| at most).
            acceleration += 4.0 * fluid_max;
        }
        let bound = step_displacement_bound(
            (fluid_max + wall_max) as f64,
            acceleration as f64,
            self.spacing as f64,
        ) as f32;
        dt.clamp((ts.min as f32).min(upper), upper).min(bound)
    }
}
