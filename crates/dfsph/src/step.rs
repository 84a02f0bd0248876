//! What the passes of one step read: [`StepContext`], built by the simulation for each solve
//! from the state it owns, in place of the long argument lists the passes once took.

use glam::Vec2;

use crate::kernel::Kernel;
use crate::particles::BoundaryParticles;
use crate::rigid::CoupledBodies;
use crate::settings::SolverSettings;
use crate::solver::Neighborhood;

/// The read-only inputs of a step's passes: the kernel and the fluid's constants, the Δt of
/// the solve at hand, the step's neighbourhoods and the walls, and the stopping rules and
/// safeguards. The particles a pass changes, and the solvers' scratch, are passed beside it.
#[derive(Clone, Copy)]
pub struct StepContext<'a> {
    /// The smoothing kernel W.
    pub kernel: &'a Kernel,
    /// Volume of one fluid particle V = m/ρ0, m².
    pub volume: f32,
    /// Lattice spacing d, m.
    pub spacing: f32,
    /// Δt of the solve at hand, s: the step's own for the density solve and the non-pressure
    /// forces, the previous step's for the divergence solve (it measures its error over it).
    pub dt: f32,
    /// Gravity, m/s².
    pub gravity: Vec2,
    /// The stopping rules and safeguards.
    pub settings: &'a SolverSettings,
    /// Neighbour lists and the kernel gradients cached for the step.
    pub nb: Neighborhood<'a>,
    /// The wall particles.
    pub boundary: &'a BoundaryParticles,
    /// The free rigid bodies the water touches, which move inside the solves; `None` without
    /// bodies. `nb.wall_flux` is the walls' share of the density rate at the bodies'
    /// velocities as the solve at hand starts.
    pub bodies: Option<&'a CoupledBodies>,
    /// Set from outside (Ctrl-C in `run`): the conjugate-gradient solve ends at its next
    /// iteration, so that a step of a deep scene, whose solve may run to thousands of
    /// iterations, can be stopped ([`crate::Simulation::set_stop_flag`]).
    pub stop: Option<&'a std::sync::atomic::AtomicBool>,
}

impl StepContext<'_> {
    /// Whether the solves are asked to stop ([`Self::stop`]).
    pub fn stop_requested(&self) -> bool {
        self.stop
            .is_some_and(|s| s.load(std::sync::atomic::Ordering::Relaxed))
    }
}
