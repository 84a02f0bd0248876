//! The seam between the world and what advances it: a backend takes a [`World`] one step
//! further and exposes the fields it computes (densities, pressures, the walls' push). The
//! CPU backend ([`crate::cpu::CpuBackend`]) is today's; a GPU backend is the next.

use serde::Serialize;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use crate::boundary::BoundaryModel;
use crate::world::World;

/// Diagnostics of one step.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct StepStats {
    /// Steps taken so far, this one included.
    pub step: u64,
    /// Simulated time at the end of the step, s.
    pub time: f64,
    /// The step's Δt, s.
    pub dt: f64,
    /// Fluid particles.
    pub n_fluid: usize,
    /// Boundary particles.
    pub n_boundary: usize,
    /// Iterations of the density solve (0 for WCSPH).
    pub density_iterations: u32,
    /// Iterations of the divergence solve (0 when it is off, and for WCSPH).
    pub divergence_iterations: u32,
    /// Average relative compression at the end of the density solve, percent (WCSPH: of the
    /// densities).
    pub avg_density_error_pct: f64,
    /// Largest single-particle compression, percent.
    pub max_density_error_pct: f64,
    /// Average relative density change per step left by the divergence solve, percent.
    pub divergence_error_pct: f64,
    /// Largest fluid speed after the step, m/s.
    pub max_speed: f64,
    /// Kinetic energy per metre of depth, J/m (2D).
    pub kinetic_energy: f64,
    /// Particles that left the tank this step and were put back: each one means the wall
    /// leaked. Should stay 0.
    pub clamped: u32,
    /// Particles whose position or velocity became NaN or infinite this step and were put
    /// back at rest. Should stay 0.
    pub non_finite: u32,
    /// Average neighbour count (fluid and boundary) per fluid particle.
    pub avg_neighbors: f64,
    /// Times this step was redone with half the time step because the try was unsound (a
    /// density solve at its iteration cap leaving a particle more than 5 % compressed, a
    /// non-finite velocity, or a particle about to jump more than a particle spacing). When
    /// every try is unsound the least bad is taken (`retry`). `dt` is the one finally taken.
    pub retries: u32,
}

/// What advances a [`World`] by one step, and the fields of the step that it alone knows.
///
/// A backend holds the solver's settings, its scratch and its warm-start state, never the
/// world's: the world it is given may have changed between steps (actions), and it reads
/// what changed from the world's flags. [`crate::Simulation`] pairs a world with one.
pub trait Backend: Send {
    /// Advance `world` by one step and report it.
    fn step(&mut self, world: &mut World) -> &StepStats;

    /// The scene's parameters changed (an action): resolve the stopping rules, the pressure
    /// solver and the viscosity from `world`'s scene again.
    fn scene_changed(&mut self, world: &World);

    /// Diagnostics of the last step (before the first: the particle counts, the rest zero).
    fn stats(&self) -> &StepStats;

    /// Particles put back into the tank, and non-finite particles reset, since the start.
    fn totals(&self) -> (u64, u64);

    /// The Δt the next step of `world` starts from, s, before any retry shortens it.
    fn next_time_step(&self, world: &World) -> f32;

    /// A flag that, once set, makes the pressure solves end at their next iteration.
    fn set_stop_flag(&mut self, flag: Arc<AtomicBool>);

    /// The flag of [`Self::set_stop_flag`], if any.
    fn stop_flag(&self) -> Option<Arc<AtomicBool>>;

    /// The pressure field at each fluid particle of `world`, p/ρ0 in m²/s², same order as
    /// its positions, as outputs show it (smoothed over the neighbourhood; see
    /// [`crate::Simulation::interpolated_pressures_over_rho0`]).
    fn output_pressures_over_rho0(&self, world: &World) -> Vec<f32>;

    /// p/ρ0 (m²/s²) with which fluid particle `i` pushed its neighbours and the walls in the
    /// last step, as the pressure solve applied it.
    fn applied_pressure_over_rho0(&self, world: &World, i: usize) -> f32;

    /// What the pressure force of the stored pressures is scaled by.
    fn pressure_force_scale(&self) -> f32;

    /// How the walls take part in the pressure terms.
    fn wall_model(&self) -> &'static dyn BoundaryModel;

    /// What this backend is, in words, for a HUD, a log or a recording's header: `cpu`, or
    /// the GPU and its adapter (and, where it hands steps to the CPU, why).
    fn describe(&self) -> String;

    /// Fluid particles within the kernel's support of fluid particle `i` (not counting
    /// itself) as the last step's neighbourhoods found them; `None` when `world`'s fluid has
    /// changed since (a pour).
    fn close_fluid_count(&self, world: &World, i: usize) -> Option<usize>;
}
