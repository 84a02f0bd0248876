//! Non-pressure accelerations: gravity, viscosity (the models of `crate::viscosity`), the
//! walls' hydrostatic ghost pressure, and the user's pointer force.

use crate::par::prelude::*;
use glam::Vec2;
use serde::{Deserialize, Serialize};

use crate::blocked::LANES;
use crate::particles::FluidParticles;
use crate::step::StepContext;
use crate::viscosity::{Laplacian, Viscosity, ViscosityModel};

/// A force field around a point that the user drags: it pushes fluid away from `at`
/// (`strength > 0`) or pulls it in (`strength < 0`), fading linearly to zero at `radius`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct PointerForce {
    /// Centre, m.
    pub at: Vec2,
    /// Reach, m.
    pub radius: f32,
    /// Peak acceleration at the centre, m/s² (positive pushes, negative pulls).
    pub strength: f32,
}

/// The largest pointer acceleration the simulation accepts, m/s² (about 8 g): strong enough to
/// throw water across the tank, weak enough that the CFL step stays reasonable.
pub const MAX_POINTER_ACCELERATION: f32 = 80.0;

/// Fill `fluid.acceleration` with gravity, the viscosity models' accelerations
/// (`crate::viscosity`), the walls' hydrostatic ghost pressure and the pointer force, for a
/// step of `step.dt`.
///
/// With `ghost_slope: Some(g_s)`, the hydrostatic part of the walls' ghost pressure
/// ([`crate::boundary::MirroredWalls`]): the ghost at wall particle b carries
/// `κ_b = κ_i + Δt g_s·(x_b − x_i)` rather than `κ_i`, where `g_s` is the slope of the solve's
/// stiffness field at rest (gravity over the lattice's gradient consistency). The extra part
/// does not depend on the solve's unknowns, so it is an acceleration
/// `a_i −= Σ_b Ψ_b (g_s·(x_b − x_i)) ∇W_ib`, and the pressure operator stays symmetric. With it
/// ρ0 g (H − y) is the discrete equilibrium next to walls as well: on the lattice the wall
/// row's own pressure and the ghosts' gradient together give it the same support against
/// gravity as a particle inside the fluid (docs/deep-columns.md).
pub(crate) fn non_pressure_accelerations(
    step: &StepContext,
    viscosity: &Viscosity,
    pointer: Option<PointerForce>,
    ghost_slope: Option<Vec2>,
    fluid: &mut FluidParticles,
) {
    let (kernel, volume, gravity, nb) = (step.kernel, step.volume, step.gravity, &step.nb);
    let boundary = step.boundary;
    let pos = &fluid.position;
    let vel = &fluid.velocity;
    let h2 = Laplacian::regularisation(kernel);
    let xsph = viscosity.xsph.pair_scale(step.dt);
    let lap = viscosity.laplacian.pair_scale(step.dt);
    let lap_b = viscosity.laplacian.wall_scale();
    let pointer = pointer.filter(|p| p.radius > 0.0 && p.strength != 0.0);
    // Everything but the fluid pair sums, for particle i.
    let accelerate = |i: usize, smooth: Vec2, laplace: Vec2| {
        let xi = pos[i];
        let vi = vel[i];
        let mut acc = gravity;
        if xsph > 0.0 || lap > 0.0 {
            acc += volume * (xsph * smooth + lap * laplace);
        }
        if let Some(slope) = ghost_slope {
            let r = nb.boundary.range(i);
            let mut push = Vec2::ZERO;
            for (&b, &g) in nb.boundary.of(i).iter().zip(&nb.boundary_grad[r]) {
                let b = b as usize;
                push += boundary.volume[b] * slope.dot(boundary.position[b] - xi) * g;
            }
            acc -= push;
        }
        if lap_b > 0.0 {
            acc += lap_b * Laplacian::wall_sum(step, i, xi, vi, h2);
        }
        if let Some(p) = pointer {
            let r = xi - p.at;
            let dist = r.length();
            if dist < p.radius {
                let fade = 1.0 - dist / p.radius;
                let dir = if dist > 1.0e-6 { r / dist } else { Vec2::ZERO };
                let strength = p
                    .strength
                    .clamp(-MAX_POINTER_ACCELERATION, MAX_POINTER_ACCELERATION);
                acc += dir * strength * fade;
                // A pull also damps the motion relative to the pointer, so water gathers
                // under the cursor instead of orbiting it.
                if strength < 0.0 {
                    acc -= vi * (fade * 4.0);
                }
            }
        }
        acc
    };
    fluid
        .acceleration
        .par_chunks_mut(LANES)
        .enumerate()
        .for_each(|(b, acc_block)| {
            // The fluid pairs run 16 particles at a time on the solver's SIMD blocks (∇W is
            // cached there; W is evaluated again, once per step).
            let (smooth, laplace) = if xsph > 0.0 || lap > 0.0 {
                nb.blocks.viscosity_sums(b, pos, vel, kernel, h2, lap > 0.0)
            } else {
                Default::default()
            };
            for (l, a) in acc_block.iter_mut().enumerate() {
                let i = b * LANES + l;
                *a = accelerate(i, smooth[l], laplace[l]);
            }
        });
}
