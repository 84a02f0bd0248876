//! Weakly compressible SPH (Becker & Teschner 2007), the baseline DFSPH is compared with:
//! `"method": "wcsph"`. The pressure follows from the density by an equation of state, with
//! no solve and no divergence solve; Δt must resolve the speed of sound
//! ([`PressureSolver::sound_speed`]).

use crate::par::prelude::*;

use super::solve::{PressureSolver, SolveReport};
use crate::particles::FluidParticles;
use crate::reduce;
use crate::scene::Scene;
use crate::solver::apply_pressure;
use crate::step::StepContext;

/// WCSPH with the Tait equation of state.
#[derive(Clone, Debug)]
pub(crate) struct Wcsph {
    /// ρ0, kg/m³.
    rest_density: f32,
    /// B of the Tait equation, Pa (the scene's `wcsph_stiffness`).
    stiffness: f32,
    /// γ of the Tait equation (the scene's `wcsph_exponent`).
    exponent: f32,
    /// The numerical speed of sound `√(γB/ρ0)`, m/s.
    sound_speed: f32,
    /// Per particle, `Δt·(p/ρ0)/s²`: the pressure in the κ form of `apply_pressure`.
    kappa: Vec<f32>,
}

impl Wcsph {
    pub fn from_scene(scene: &Scene) -> Self {
        let s = &scene.solver;
        Self {
            rest_density: scene.rest_density as f32,
            stiffness: s.wcsph_stiffness as f32,
            exponent: s.wcsph_exponent as f32,
            sound_speed: (s.wcsph_exponent * s.wcsph_stiffness / scene.rest_density).sqrt() as f32,
            kappa: Vec::new(),
        }
    }
}

impl PressureSolver for Wcsph {
    /// WCSPH has none: the equation of state alone sets the pressure.
    fn divergence_solve(&mut self, _: &StepContext, _: &mut FluidParticles) -> SolveReport {
        SolveReport::default()
    }

    fn density_solve(&mut self, step: &StepContext, fluid: &mut FluidParticles) -> SolveReport {
        wcsph_pressure(self, step, fluid)
    }

    /// None: there is no linear prediction to check, nor a solve to stop at its cap.
    fn density_rates(&self) -> Option<&[f32]> {
        None
    }

    fn sound_speed(&self) -> Option<f32> {
        Some(self.sound_speed)
    }

    /// `p/ρ0` over `(ρ/ρ0)²`, the symmetric form's own weight (below); there is no divergence
    /// solve.
    fn applied_pressure(&self, fluid: &FluidParticles, i: usize, _: f32, _: bool) -> f32 {
        let s = fluid.density_ratio[i].max(1.0e-3);
        fluid.pressure_over_rho0[i] * self.pressure_force_scale() / (s * s)
    }
}

/// WCSPH: pressure from the Tait equation `p = B·((ρ/ρ0)^γ − 1)` (clamped at 0 so the free
/// surface is not pulled together) and the symmetric pressure acceleration
/// `a_i = −Σ_j m_j (p_i/ρ_i² + p_j/ρ_j²) ∇W_ij − Σ_b ρ0 Ψ_b p_i/ρ_i² ∇W_ib` (Akinci et al.
/// 2012), applied to the velocities over `step.dt`. Returns the average and maximum
/// compression in percent.
fn wcsph_pressure(
    wcsph: &mut Wcsph,
    step: &StepContext,
    fluid: &mut FluidParticles,
) -> SolveReport {
    let (volume, dt, nb) = (step.volume, step.dt, &step.nb);
    let (rest_density, stiffness, exponent) = (wcsph.rest_density, wcsph.stiffness, wcsph.exponent);
    let n = fluid.len();
    wcsph.kappa.resize(n, 0.0);
    fluid
        .pressure_over_rho0
        .par_iter_mut()
        .zip(wcsph.kappa.par_iter_mut())
        .zip(fluid.density_ratio.par_iter())
        .for_each(|((p, k), &s)| {
            let pressure = (stiffness * (s.powf(exponent) - 1.0)).max(0.0);
            *p = pressure / rest_density;
            // In the κ form: m_j p/ρ² = V_j ρ0 p/(ρ0 s)² = V_j (p/ρ0)/s², times Δt.
            *k = dt * *p / (s * s);
        });
    apply_pressure(volume, &wcsph.kappa, &mut fluid.velocity, nb);
    let (sum, max) = reduce::sum_and_max(&fluid.density_ratio, |&s| (s - 1.0).max(0.0) as f64);
    SolveReport {
        iterations: 0,
        avg_error_pct: if n > 0 { sum / n as f64 * 100.0 } else { 0.0 },
        max_error_pct: max * 100.0,
    }
}
