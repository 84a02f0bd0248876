//! Non-pressure accelerations: gravity, viscosity (XSPH and a Laplacian model with kinematic
//! viscosity), and the user's pointer force.

use crate::par::prelude::*;
use glam::Vec2;
use serde::{Deserialize, Serialize};

use crate::blocked::LANES;
use crate::kernel::CubicSpline;
use crate::particles::{BoundaryParticles, FluidParticles};
use crate::solver::Neighborhood;

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

/// Viscosity settings in solver units.
#[derive(Clone, Copy, Debug)]
pub struct Viscosity {
    /// XSPH coefficient (dimensionless).
    pub xsph: f32,
    /// Kinematic viscosity ν, m²/s.
    pub kinematic: f32,
    /// Kinematic viscosity against walls, m²/s.
    pub boundary_kinematic: f32,
}

/// Fill `fluid.acceleration` with gravity, viscosity and the pointer force.
///
/// * XSPH (Monaghan 1989; as an acceleration over the step as in SPlisHSPlasH):
///   `a_i += (c/Δt) Σ_j V_j (v_j − v_i) W_ij`.
/// * Laplacian viscosity (Morris et al. 1997; Monaghan 2005, 2D so `2(d+2) = 8`):
///   `a_i += 8ν Σ_j V_j (v_ij·x_ij)/(|x_ij|² + 0.01h²) ∇W_ij`, and the same against boundary
///   particles with their velocity and `ν_b`.
/// * With `hydrostatic_walls: Some(g_s)`, the hydrostatic part of the mirrored walls' pressure
///   ([`crate::solver::MIRRORED_WALLS`]; Band et al. 2018, "Pressure boundaries for implicit
///   incompressible SPH", pressure extrapolation): the ghost at wall particle b carries
///   `κ_b = κ_i + Δt g_s·(x_b − x_i)` rather than `κ_i`, where `g_s` is the slope of the
///   solve's stiffness field at rest (gravity over the lattice's gradient consistency). The
///   extra part does not depend on the solve's unknowns, so it is an acceleration
///   `a_i −= Σ_b Ψ_b (g_s·(x_b − x_i)) ∇W_ib`, and the pressure operator stays symmetric. With it
///   ρ0 g (H − y) is the discrete equilibrium next to walls as well: on the lattice the wall
///   row's own pressure and the ghosts' gradient together give it the same support against
///   gravity as a particle inside the fluid (docs/deep-columns.md).
#[allow(clippy::too_many_arguments)]
pub fn non_pressure_accelerations(
    kernel: &CubicSpline,
    volume: f32,
    dt: f32,
    gravity: Vec2,
    viscosity: Viscosity,
    pointer: Option<PointerForce>,
    hydrostatic_walls: Option<Vec2>,
    fluid: &mut FluidParticles,
    boundary: &BoundaryParticles,
    nb: &Neighborhood,
) {
    let pos = &fluid.position;
    let vel = &fluid.velocity;
    let h2 = 0.01 * kernel.support() * kernel.support();
    let xsph = viscosity.xsph / dt;
    let lap = 8.0 * viscosity.kinematic;
    let lap_b = 8.0 * viscosity.boundary_kinematic;
    let pointer = pointer.filter(|p| p.radius > 0.0 && p.strength != 0.0);
    // Everything but the fluid pair sums, for particle i.
    let accelerate = |i: usize, smooth: Vec2, laplace: Vec2| {
        let xi = pos[i];
        let vi = vel[i];
        let mut acc = gravity;
        if xsph > 0.0 || lap > 0.0 {
            acc += volume * (xsph * smooth + lap * laplace);
        }
        if let Some(slope) = hydrostatic_walls {
            let r = nb.boundary.range(i);
            let mut push = Vec2::ZERO;
            for (&b, &g) in nb.boundary.of(i).iter().zip(&nb.boundary_grad[r]) {
                let b = b as usize;
                push += boundary.volume[b] * slope.dot(boundary.position[b] - xi) * g;
            }
            acc -= push;
        }
        if lap_b > 0.0 {
            let r = nb.boundary.range(i);
            let mut laplace = Vec2::ZERO;
            for (&b, &g) in nb.boundary.of(i).iter().zip(&nb.boundary_grad[r]) {
                let b = b as usize;
                let xib = xi - boundary.position[b];
                let vib = vi - boundary.velocity[b];
                laplace += boundary.volume[b] * g * (vib.dot(xib) / (xib.length_squared() + h2));
            }
            acc += lap_b * laplace;
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
