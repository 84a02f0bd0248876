//! What the passes of one step read: [`StepContext`], built by the simulation for each solve
//! from the state it owns, in place of the long argument lists the passes once took.

use glam::Vec2;

use crate::blocked::BlockedPairs;
use crate::kernel::Kernel;
use crate::neighbors::NeighborLists;
use crate::particles::BoundaryParticles;
use crate::rigid::coupled::CoupledBodies;
use crate::settings::SolverSettings;

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

/// What [`crate::solver::density_and_factor`] caches for the rest of a step, valid while positions do not
/// change.
#[derive(Clone, Debug, Default)]
pub struct PairCache {
    /// `∇W_ib` per fluid–boundary pair, in list order.
    pub boundary_grad: Vec<Vec2>,
    /// Per particle, `Σ_j V_j ∇W_ij + Σ_b Ψ_b ∇W_ib`: what a uniform κ or velocity sees.
    pub grad_sum: Vec<Vec2>,
    /// Per particle, `Σ_b Ψ_b v_b·∇W_ib`: the walls' share of the density rate (walls keep
    /// their velocity for the whole step).
    pub wall_flux: Vec<f32>,
    /// Neighbour indices and `∇W_ij` of the fluid–fluid pairs, in blocks of 16 particles for
    /// the solver's SIMD passes.
    pub blocks: BlockedPairs,
}

/// Read-only view of one step's neighbourhoods: lists and the kernel gradients cached for
/// every pair, valid while positions do not change.
#[derive(Clone, Copy)]
pub struct Neighborhood<'a> {
    /// Fluid–fluid lists (self excluded); their `∇W_ij` are in `blocks`.
    pub fluid: &'a NeighborLists,
    /// Fluid–boundary lists and `∇W_ib` per pair.
    pub boundary: &'a NeighborLists,
    pub boundary_grad: &'a [Vec2],
    /// [`PairCache::grad_sum`].
    pub grad_sum: &'a [Vec2],
    /// [`PairCache::wall_flux`].
    pub wall_flux: &'a [f32],
    /// [`PairCache::blocks`].
    pub blocks: &'a BlockedPairs,
}

impl<'a> Neighborhood<'a> {
    pub fn new(
        fluid: &'a NeighborLists,
        boundary: &'a NeighborLists,
        cache: &'a PairCache,
    ) -> Self {
        Self {
            fluid,
            boundary,
            boundary_grad: &cache.boundary_grad,
            grad_sum: &cache.grad_sum,
            wall_flux: &cache.wall_flux,
            blocks: &cache.blocks,
        }
    }

    /// Fluid particle `i`'s wall neighbours, with the `∇W_ib` cached for each, in list order.
    pub fn walls_of(&self, i: usize) -> impl Iterator<Item = (usize, Vec2)> + '_ {
        let grads = &self.boundary_grad[self.boundary.range(i)];
        self.boundary
            .of(i)
            .iter()
            .zip(grads)
            .map(|(&b, &g)| (b as usize, g))
    }
}
