//! What a non-pressure force model is: the acceleration it adds to one particle.

use glam::Vec2;

use crate::step::StepContext;

/// One fluid particle as the models see it, in a step of `step.dt`.
pub(crate) struct Particle<'a> {
    /// Its index in the fluid arrays (and in the step's neighbour lists).
    pub index: usize,
    /// Position, m.
    pub position: Vec2,
    /// Velocity at the start of the step, m/s.
    pub velocity: Vec2,
    /// The fluid pair sums of the step's one pass over the blocks
    /// ([`crate::blocked::BlockedPairs::viscosity_sums`]): XSPH's `Σ_j W_ij (v_j − v_i)`
    /// and the Laplacian's `Σ_j ∇W_ij (v_ij·x_ij)/(|x_ij|² + 0.01h²)`, zero where no model
    /// uses them.
    pub smooth: Vec2,
    pub laplace: Vec2,
    /// What the step's passes read (kernel, volume, Δt, neighbourhoods, walls).
    pub step: &'a StepContext<'a>,
}

/// A non-pressure force (gravity, viscosity, wall friction, the walls' ghost pressure, the
/// pointer): the models are listed once, in `forces::non_pressure_accelerations`, and each
/// adds its acceleration, in list order, to every fluid particle's.
pub(crate) trait AccelerationModel: Sync {
    /// Add this model's acceleration on `p`, m/s², to `acc`.
    fn add_to(&self, p: &Particle, acc: &mut Vec2);
}
