//! Non-pressure accelerations, one model per file behind [`model::AccelerationModel`]:
//! gravity, XSPH and the Laplacian viscosity (`crate::viscosity`), friction against the
//! walls, the mirrored walls' hydrostatic ghost pressure and the user's pointer. The models
//! are listed once, in [`non_pressure_accelerations`]; a new one is its file and a line there.
//!
//! The models' fluid pair sums run in one pass over the solver's SIMD blocks
//! (`blocked::BlockedPairs::viscosity_sums`, whose per-pair formulas are in
//! `blocked/formulas.rs`): the pass reads each pair's `W` and `∇W` once for XSPH and the
//! Laplacian alike, and the models read its sums ([`model::Particle`]). A model with a fluid
//! pair sum of its own adds it to that pass (its formula once in `blocked/formulas.rs`, over
//! the lane type both kinds of kernels use).

use crate::par::prelude::*;
use glam::Vec2;

mod ghost_pressure;
mod gravity;
pub(crate) mod model;
mod pointer;

pub use pointer::{PointerForce, MAX_POINTER_ACCELERATION};

use crate::blocked::LANES;
use crate::particles::FluidParticles;
use crate::step::StepContext;
use crate::viscosity::{Laplacian, Viscosity, WallFriction};
use ghost_pressure::GhostPressure;
use gravity::Gravity;
use model::{AccelerationModel, Particle};

/// Fill `fluid.acceleration` with the models' accelerations for a step of `step.dt`: gravity,
/// the `viscosity` models, the walls' hydrostatic ghost pressure where `ghost_slope` is given
/// ([`GhostPressure`]: the slope of the solve's stiffness field at rest) and the `pointer`.
pub(crate) fn non_pressure_accelerations(
    step: &StepContext,
    viscosity: &Viscosity,
    pointer: Option<PointerForce>,
    ghost_slope: Option<Vec2>,
    fluid: &mut FluidParticles,
) {
    let gravity = Gravity(step.gravity);
    let (xsph, laplacian) = (&viscosity.xsph, &viscosity.laplacian);
    let wall_friction = WallFriction::new(laplacian, step.kernel);
    let ghosts = ghost_slope.map(|slope| GhostPressure { slope });
    let pointer = pointer.filter(PointerForce::acts);
    // XSPH and the Laplacian act through the fluid pair sums of the pass below.
    let (smooth_on, laplace_on) = (xsph.coefficient > 0.0, laplacian.kinematic > 0.0);
    // The models that act, in the order their accelerations are added.
    let models: Vec<&dyn AccelerationModel> = [
        Some(&gravity as &dyn AccelerationModel),
        smooth_on.then_some(xsph as &dyn AccelerationModel),
        laplace_on.then_some(laplacian as &dyn AccelerationModel),
        ghosts.as_ref().map(|g| g as &dyn AccelerationModel),
        wall_friction
            .acts()
            .then_some(&wall_friction as &dyn AccelerationModel),
        pointer.as_ref().map(|p| p as &dyn AccelerationModel),
    ]
    .into_iter()
    .flatten()
    .collect();
    let (kernel, nb) = (step.kernel, &step.nb);
    let h2 = Laplacian::regularisation(kernel);
    let (pos, vel) = (&fluid.position, &fluid.velocity);
    fluid
        .acceleration
        .par_chunks_mut(LANES)
        .enumerate()
        .for_each(|(b, acc_block)| {
            // The fluid pairs run 16 particles at a time on the solver's SIMD blocks (∇W is
            // cached there; W is evaluated again, once per step).
            let (smooth, laplace) = if smooth_on || laplace_on {
                nb.blocks
                    .viscosity_sums(b, pos, vel, kernel, h2, laplace_on)
            } else {
                Default::default()
            };
            for (l, a) in acc_block.iter_mut().enumerate() {
                let i = b * LANES + l;
                let particle = Particle {
                    index: i,
                    position: pos[i],
                    velocity: vel[i],
                    smooth: smooth[l],
                    laplace: laplace[l],
                    step,
                };
                let mut acc = Vec2::ZERO;
                for model in &models {
                    model.add_to(&particle, &mut acc);
                }
                *a = acc;
            }
        });
}
