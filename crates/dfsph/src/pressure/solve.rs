//! What every pressure solver is: the `PressureSolver` trait the step calls, and the report
//! of one solve.

use glam::Vec2;

use crate::boundary::{AkinciWalls, BoundaryModel};
use crate::particles::FluidParticles;
use crate::step::StepContext;

/// Outcome of one solve.
#[derive(Clone, Copy, Debug, Default)]
pub struct SolveReport {
    /// Iterations run.
    pub iterations: u32,
    /// Average error at exit, percent.
    pub avg_error_pct: f64,
    /// Largest single-particle error at exit, percent.
    pub max_error_pct: f64,
}

/// A way to find the pressure of a step: DFSPH's two solves (TVCG 2017, Algorithms 2 and 3),
/// or what stands in for them. Each solver keeps its own scratch arrays.
pub(crate) trait PressureSolver: Send + Sync {
    /// Algorithm 2: make the velocity field divergence-free (`Dρ/Dt = 0`), its error measured
    /// over `step.dt`, leaving the stiffness in `fluid.divergence_stiffness` for the next warm
    /// start.
    fn divergence_solve(&mut self, step: &StepContext, fluid: &mut FluidParticles) -> SolveReport;

    /// Algorithm 3: correct the predicted velocities so that the density after a step of
    /// `step.dt` is ρ0, leaving p/ρ0 in `fluid.pressure_over_rho0`.
    fn density_solve(&mut self, step: &StepContext, fluid: &mut FluidParticles) -> SolveReport;

    /// The relative density rates `Dρ_i/Dt/ρ0` at the velocities the last density solve left,
    /// for the step's linearisation check (`solver::unseen_compression`). `None` for a method
    /// that does not predict the density linearly, which is then neither checked for it nor
    /// for a solve stopped at its cap.
    fn density_rates(&self) -> Option<&[f32]>;

    /// How the walls take part in the pressure terms.
    fn walls(&self) -> &'static dyn BoundaryModel {
        &AkinciWalls
    }

    /// A speed the CFL condition must resolve besides the flow's, m/s: the speed of sound of a
    /// weakly compressible method.
    fn sound_speed(&self) -> Option<f32> {
        None
    }

    /// What the pressure force of the stored pressures (`fluid.pressure_over_rho0`) is scaled
    /// by.
    fn pressure_force_scale(&self) -> f32 {
        1.0
    }

    /// p/ρ0 (m²/s²) with which fluid particle `i` pushed its neighbours and the walls in the
    /// step just taken, of `dt`, exactly as this solver applies it: the stored pressure times
    /// [`Self::pressure_force_scale`], plus, where the divergence solve ran, its stiffness
    /// κᵛ/Δt (its impulse spread over the step; it carries much of an impact). The probes read
    /// the walls' forces off it.
    fn applied_pressure(
        &self,
        fluid: &FluidParticles,
        i: usize,
        dt: f32,
        divergence_solve: bool,
    ) -> f32 {
        let p = fluid.pressure_over_rho0[i] * self.pressure_force_scale();
        let kv = if divergence_solve && dt > 0.0 {
            fluid.divergence_stiffness[i] / dt
        } else {
            0.0
        };
        p + kv
    }

    /// The pressure over ρ0 (m²/s²) the first step starts from, for particles at `position`
    /// under `gravity` at spacing `d`; `None` for zero.
    fn initial_pressure(&self, position: &[Vec2], gravity: Vec2, d: f32) -> Option<Vec<f32>> {
        let _ = (position, gravity, d);
        None
    }
}
