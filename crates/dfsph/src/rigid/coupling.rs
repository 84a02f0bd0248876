//! The impulse the fluid gives each rigid body in a step: the opposite of what the body's
//! boundary particles gave the fluid (Akinci et al. 2012, eq. 14 and 16, here summed from the
//! solves' own terms so that fluid and bodies together keep their momentum).
//!
//! A stiffness field κ changes a fluid particle's velocity by `−w·κ_i Σ_b Ψ_b ∇W_ib` through
//! the walls ([`crate::solver::apply_pressure`], w the boundary model's gradient weight);
//! the divergence solve applied κᵛ (`divergence_stiffness`), the density solve
//! `Δt·s·p/ρ0` (s the solver's pressure-force scale), and mirrored walls add their ghosts'
//! hydrostatic part `−Δt Σ_b Ψ_b (g_s·(x_b − x_i)) ∇W_ib` to the non-pressure
//! accelerations. Each pair's impulse `m·Δv` goes to the body with the opposite sign, and
//! its moment about the body's centre of mass, taken at the boundary particle, to its spin.

use glam::Vec2;

use crate::particles::FluidParticles;
use crate::step::StepContext;

/// The solve terms a step applied to the fluid through the walls.
pub(crate) struct WallTerms<'a> {
    /// The divergence solve's stiffness, m²/s (`None`: no divergence solve ran).
    pub divergence_stiffness: Option<&'a [f32]>,
    /// What turns the stored p/ρ0 into the density solve's κ: Δt times the pressure-force
    /// scale, s.
    pub pressure_to_kappa: f32,
    /// The boundary model's gradient weight w.
    pub weight: f32,
    /// The slope of the mirrored walls' hydrostatic ghost stiffness, if any.
    pub ghost_slope: Option<Vec2>,
}

/// What the fluid gave one rigid body in a step.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct BodyImpulse {
    /// Impulse, N·s per metre of depth.
    pub linear: Vec2,
    /// Its moment about the body's centre of mass, N·m·s per metre.
    pub angular: f32,
}

/// Per rigid body (indexed by `rigid_of[body id]`), the impulse the fluid gave it in the step
/// and its moment about `centres[k]`. Walls of other bodies (`rigid_of` is `None`) are
/// skipped.
pub(crate) fn body_impulses(
    step: &StepContext,
    fluid: &FluidParticles,
    terms: &WallTerms,
    particle_mass: f32,
    rigid_of: &[Option<u16>],
    centres: &[Vec2],
) -> Vec<BodyImpulse> {
    let boundary = step.boundary;
    let nb = &step.nb;
    let dt = step.dt;
    let mut sums = vec![(glam::DVec2::ZERO, 0.0f64); centres.len()];
    for i in 0..fluid.len() {
        if nb.boundary.of(i).is_empty() {
            continue;
        }
        let kappa = terms.divergence_stiffness.map_or(0.0, |k| k[i])
            + terms.pressure_to_kappa * fluid.pressure_over_rho0[i];
        let xi = fluid.position[i];
        for (b, g) in nb.walls_of(i) {
            let Some(k) = rigid_of[boundary.body[b] as usize] else {
                continue;
            };
            let k = k as usize;
            let psi = boundary.volume[b];
            let xb = boundary.position[b];
            let mut dv = -(terms.weight * kappa * psi) * g;
            if let Some(slope) = terms.ghost_slope {
                dv -= dt * psi * slope.dot(xb - xi) * g;
            }
            // The body gets what the fluid particle lost.
            let j = -particle_mass * dv;
            let r = xb - centres[k];
            sums[k].0 += j.as_dvec2();
            sums[k].1 += r.perp_dot(j) as f64;
        }
    }
    sums.into_iter()
        .map(|(j, t)| BodyImpulse {
            linear: j.as_vec2(),
            angular: t as f32,
        })
        .collect()
}
