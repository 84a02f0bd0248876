//! The rigid bodies inside the pressure solves: a strong coupling, in which a body moves
//! with every stiffness increment the solve applies to the water around it, so that the water
//! sees the body's answer within the same solve instead of one step late.
//!
//! A stiffness field κ changes a fluid particle's velocity through the walls of body k by
//! `−w κ_i G_ik` with `G_ik = Σ_b Ψ_b ∇W_ib` over the body's boundary particles b
//! ([`crate::solver::apply_pressure`]); the body receives the opposite impulse, `m w κ_i G_ik`
//! (m the fluid particle's mass), and its moment `m w κ_i H_ik` with
//! `H_ik = Σ_b Ψ_b (x_b − c_k) × ∇W_ib` about its centre of mass c_k. Its velocity V_k and
//! spin ω_k change by
//!
//! `ΔV_k = (m w / M_k) Σ_i κ_i G_ik`,  `Δω_k = (m w / I_k) Σ_i κ_i H_ik`,
//!
//! and the walls' share of each neighbour's density rate, `w Σ_b Ψ_b v_b·∇W_ib` with
//! `v_b = V_k + ω_k (x_b − c_k)^⊥`, by `w (ΔV_k·G_ik + Δω_k H_ik)`. Fluid and bodies together
//! are then one linear system, `Δt·B M⁻¹ Bᵀ` with the bodies' masses and moments among the
//! particles' (symmetric: Batty et al. 2007; in SPH, Gissler et al. 2019, "Interlinked SPH
//! pressure solvers for strong fluid-rigid coupling"), and momentum is kept at every iteration:
//! each increment gives the body exactly what it takes from the water.
//!
//! The Jacobi iteration updates every particle as if it alone pushed the body, so the hundred
//! particles along a light body's face would together move it a hundred times too far. Each
//! particle's factor therefore also counts what its neighbours along the same body do to its
//! rate (the Gershgorin bound of the body's rows, [`CoupledBodies::damp_factors`]), which keeps
//! the iteration from overshooting however light the body is. A hinged body takes part as a
//! rotation about its anchor (`c_k` the anchor, `I_k` the moment about it, `1/M_k` zero); a body
//! fixed by a joint does not move and is left out.

use std::ops::Range;

use glam::{DVec2, Vec2};

/// A body's velocity and spin, or a change of them.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BodyVelocity {
    /// m/s.
    pub linear: Vec2,
    /// rad/s.
    pub angular: f32,
}

impl std::ops::AddAssign for BodyVelocity {
    fn add_assign(&mut self, other: Self) {
        self.linear += other.linear;
        self.angular += other.angular;
    }
}

/// What a body needs to take part in the solves.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Mobility {
    /// The point the body turns about, m: its centre of mass, or a hinge's anchor.
    pub centre: Vec2,
    /// 1/M, per kg/m (0: the body does not move with the solve).
    pub inverse_mass: f32,
    /// 1/I about `centre`, per kg·m (0: the body does not turn with the solve).
    pub inverse_inertia: f32,
}

/// The contacts of the fluid with the moving rigid bodies in one step, for the solves.
#[derive(Clone, Debug, Default)]
pub struct CoupledBodies {
    /// Per contact, the fluid particle, ascending.
    particle: Vec<u32>,
    /// Per contact, the body (index of [`crate::rigid::RigidBodies`]).
    body: Vec<u16>,
    /// Per contact, `G_ik = Σ_b Ψ_b ∇W_ib`, 1/m.
    g: Vec<Vec2>,
    /// Per contact, `H_ik = Σ_b Ψ_b (x_b − c_k) × ∇W_ib`.
    h: Vec<f32>,
    /// Per body, `m w / M_k` and `m w / I_k`.
    linear: Vec<f32>,
    angular: Vec<f32>,
    /// The boundary model's gradient weight w.
    weight: f32,
}

impl CoupledBodies {
    /// The contacts of the step: for each fluid particle `i`, its wall neighbours
    /// `walls(i)` with their `∇W_ib` `grads(i)`; `body_of(b)` is the rigid body boundary
    /// particle b belongs to, if any, `position[b]` and `volume[b]` its position and Ψ_b.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn new<'a>(
        fluid_count: usize,
        walls: impl Fn(usize) -> (&'a [u32], &'a [Vec2]),
        body_of: impl Fn(usize) -> Option<u16>,
        position: &[Vec2],
        volume: &[f32],
        bodies: &[Mobility],
        particle_mass: f32,
        weight: f32,
    ) -> Self {
        let mut out = Self {
            linear: bodies
                .iter()
                .map(|b| particle_mass * weight * b.inverse_mass)
                .collect(),
            angular: bodies
                .iter()
                .map(|b| particle_mass * weight * b.inverse_inertia)
                .collect(),
            weight,
            ..Self::default()
        };
        let mut sums: Vec<(usize, Vec2, f32)> = Vec::new();
        for i in 0..fluid_count {
            let (list, grads) = walls(i);
            sums.clear();
            for (&b, &grad) in list.iter().zip(grads) {
                let b = b as usize;
                let Some(k) = body_of(b) else { continue };
                let k = k as usize;
                let mobile = bodies[k];
                if mobile.inverse_mass == 0.0 && mobile.inverse_inertia == 0.0 {
                    continue;
                }
                let g = volume[b] * grad;
                let h = (position[b] - mobile.centre).perp_dot(g);
                match sums.iter_mut().find(|s| s.0 == k) {
                    Some(s) => {
                        s.1 += g;
                        s.2 += h;
                    }
                    None => sums.push((k, g, h)),
                }
            }
            for &(k, g, h) in &sums {
                out.particle.push(i as u32);
                out.body.push(k as u16);
                out.g.push(g);
                out.h.push(h);
            }
        }
        out
    }

    /// Whether no fluid particle touches a body that moves.
    pub fn is_empty(&self) -> bool {
        self.particle.is_empty()
    }

    /// Number of bodies.
    pub(crate) fn bodies(&self) -> usize {
        self.linear.len()
    }

    /// Each body's change of velocity and spin when the stiffness field `kappa` (m²/s) acts
    /// on the water around it (module doc). Summed in one fixed order, so every worker that
    /// asks gets the same bits.
    pub fn velocity_change(&self, kappa: &[f32]) -> Vec<BodyVelocity> {
        self.velocity_change_of(kappa, 1.0)
    }

    /// [`Self::velocity_change`] of the stiffness field `scale·values`.
    pub fn velocity_change_of(&self, values: &[f32], scale: f32) -> Vec<BodyVelocity> {
        let mut sums = vec![(DVec2::ZERO, 0.0f64); self.bodies()];
        for c in 0..self.particle.len() {
            let k = (scale * values[self.particle[c] as usize]) as f64;
            let s = &mut sums[self.body[c] as usize];
            s.0 += k * self.g[c].as_dvec2();
            s.1 += k * self.h[c] as f64;
        }
        sums.iter()
            .enumerate()
            .map(|(k, &(g, h))| BodyVelocity {
                linear: (self.linear[k] as f64 * g).as_vec2(),
                angular: (self.angular[k] as f64 * h) as f32,
            })
            .collect()
    }

    /// Add `scale` times the walls' share of the density rate that the bodies' velocity
    /// changes `dv` make, `w (ΔV_k·G_ik + Δω_k H_ik)`, to `flux`, which holds particles
    /// `items` (`flux[0]` is particle `items.start`).
    pub fn add_flux(&self, flux: &mut [f32], items: Range<usize>, dv: &[BodyVelocity], scale: f32) {
        let contacts = self.contacts_of(items.clone());
        for c in contacts {
            let v = dv[self.body[c] as usize];
            let i = self.particle[c] as usize - items.start;
            flux[i] += scale * self.weight * (v.linear.dot(self.g[c]) + v.angular * self.h[c]);
        }
    }

    /// Lower the DFSPH factor `a_i` of each particle that touches a free body by what the
    /// body's motion adds to its rate: `1/a_i` grows by
    /// `w (m w / M_k) |G_ik| Σ_j |G_jk| + w (m w / I_k) |H_ik| Σ_j |H_jk|`, the sum of the
    /// magnitudes of body k's terms in particle i's row of the system, over every particle j
    /// touching it. A Jacobi iteration with these factors cannot move a body further than
    /// the water pushing it asks for, whatever its mass.
    pub fn damp_factors(&self, factor: &mut [f32]) {
        let mut spread = vec![(0.0f32, 0.0f32); self.bodies()];
        for c in 0..self.particle.len() {
            let s = &mut spread[self.body[c] as usize];
            s.0 += self.g[c].length();
            s.1 += self.h[c].abs();
        }
        for c in 0..self.particle.len() {
            let k = self.body[c] as usize;
            let a = &mut factor[self.particle[c] as usize];
            if *a <= 0.0 {
                continue;
            }
            let extra = self.weight
                * (self.linear[k] * self.g[c].length() * spread[k].0
                    + self.angular[k] * self.h[c].abs() * spread[k].1);
            *a = 1.0 / (1.0 / *a + extra);
        }
    }

    /// The contacts of particles `items`.
    fn contacts_of(&self, items: Range<usize>) -> Range<usize> {
        let start = self
            .particle
            .partition_point(|&p| (p as usize) < items.start);
        let end = self.particle.partition_point(|&p| (p as usize) < items.end);
        start..end
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernel::Kernel;

    /// A body of two layers of boundary particles along a flat face and a corner, fluid
    /// particles in front of it, every fluid–wall pair within the support.
    struct Contact {
        kernel: Kernel,
        fluid: Vec<Vec2>,
        walls: Vec<Vec2>,
        volume: Vec<f32>,
        /// Per fluid particle, its wall neighbours and their ∇W_ib.
        lists: Vec<(Vec<u32>, Vec<Vec2>)>,
        mobility: Mobility,
    }

    fn contact(inverse_mass: f32) -> Contact {
        let d = 0.01f32;
        let kernel = Kernel::cubic_spline(2.0 * d);
        let mut walls = Vec::new();
        for layer in 0..2 {
            for i in 0..12 {
                walls.push(Vec2::new(i as f32 * d, -(layer as f32 + 0.5) * d));
            }
            walls.push(Vec2::new(-(layer as f32 + 0.5) * d, 0.3 * d));
        }
        let volume = (0..walls.len())
            .map(|b| (0.7 + 0.02 * b as f32) * d * d)
            .collect();
        let fluid: Vec<Vec2> = (0..10)
            .map(|i| Vec2::new((i as f32 + 0.3) * d, (0.5 + 0.1 * (i % 3) as f32) * d))
            .collect();
        let lists = fluid
            .iter()
            .map(|&x| {
                let near: Vec<u32> = (0..walls.len() as u32)
                    .filter(|&b| (x - walls[b as usize]).length() < kernel.support())
                    .collect();
                let grads = near
                    .iter()
                    .map(|&b| kernel.grad_w(x - walls[b as usize]))
                    .collect();
                (near, grads)
            })
            .collect();
        Contact {
            kernel,
            fluid,
            walls,
            volume,
            lists,
            mobility: Mobility {
                centre: Vec2::new(0.05, -0.05),
                inverse_mass,
                inverse_inertia: 40.0 * inverse_mass,
            },
        }
    }

    const MASS: f32 = 0.1;
    const WEIGHT: f32 = 1.0;

    fn coupled(c: &Contact) -> CoupledBodies {
        CoupledBodies::new(
            c.fluid.len(),
            |i| (&c.lists[i].0[..], &c.lists[i].1[..]),
            |_| Some(0),
            &c.walls,
            &c.volume,
            &[c.mobility],
            MASS,
            WEIGHT,
        )
    }

    #[test]
    fn the_body_gets_what_each_pair_gives_the_water_and_the_walls_move_with_it() {
        let c = contact(2.0);
        let bodies = coupled(&c);
        assert!(!bodies.is_empty());
        let kappa: Vec<f32> = (0..c.fluid.len())
            .map(|i| 1e-4 * (1.0 + i as f32))
            .collect();
        // Pair by pair: the water loses m·w·κ_i·Ψ_b·∇W_ib through each wall particle, the body
        // gains it, and its moment about the centre of mass.
        let (mut linear, mut angular) = (DVec2::ZERO, 0.0f64);
        for (i, (near, grads)) in c.lists.iter().enumerate() {
            for (&b, &g) in near.iter().zip(grads) {
                let j = MASS * WEIGHT * kappa[i] * c.volume[b as usize] * g;
                linear += j.as_dvec2();
                angular += (c.walls[b as usize] - c.mobility.centre).perp_dot(j) as f64;
            }
        }
        let dv = bodies.velocity_change(&kappa)[0];
        let want = (linear * c.mobility.inverse_mass as f64).as_vec2();
        assert!(
            (dv.linear - want).length() <= 1e-5 * want.length(),
            "{dv:?} {want}"
        );
        let want = angular * c.mobility.inverse_inertia as f64;
        assert!(
            (dv.angular as f64 - want).abs() <= 1e-5 * want.abs(),
            "{dv:?} {want}"
        );
        assert!(dv.linear.length() > 0.0 && dv.angular != 0.0, "a real test");
        // The walls' share of the density rate, `w Σ_b Ψ_b v_b·∇W_ib`, written out with each
        // wall particle's velocity V + ω (x_b − c)^⊥, against the cached sums.
        let moved = [BodyVelocity {
            linear: Vec2::new(0.3, -0.7),
            angular: 2.5,
        }];
        let mut flux = vec![0.5f32; c.fluid.len()];
        bodies.add_flux(&mut flux[2..], 2..c.fluid.len(), &moved, 1.0);
        for (i, (near, grads)) in c.lists.iter().enumerate() {
            let mut want = 0.5f32;
            if i >= 2 {
                for (&b, &g) in near.iter().zip(grads) {
                    let r = c.walls[b as usize] - c.mobility.centre;
                    let v = moved[0].linear + moved[0].angular * r.perp();
                    want += WEIGHT * c.volume[b as usize] * v.dot(g);
                }
            }
            assert!((flux[i] - want).abs() <= 1e-4 * want.abs().max(1.0), "{i}");
        }
        let _ = c.kernel;
    }

    #[test]
    fn a_body_held_by_a_joint_takes_no_part() {
        let mut c = contact(0.0);
        c.mobility.inverse_inertia = 0.0;
        assert!(coupled(&c).is_empty());
    }

    /// The body's part of the system alone, `A = c·(m w²/M) G Gᵀ + D` with D the water's own
    /// diagonal: Jacobi with the plain factors `1/A_ii` diverges for a light body, with the
    /// damped factors it converges.
    #[test]
    fn damped_factors_keep_the_jacobi_iteration_from_overshooting_a_light_body() {
        for (inverse_mass, damped, converges) in
            [(50.0, false, false), (50.0, true, true), (0.01, true, true)]
        {
            let mut c = contact(inverse_mass);
            c.mobility.inverse_inertia = 0.0;
            let bodies = coupled(&c);
            let n = c.fluid.len();
            let own: Vec<f32> = (0..n)
                .map(|i| {
                    let g = bodies.g[i];
                    2.0 * g.length_squared()
                })
                .collect();
            // Rates of κ: the water's own diagonal and the body's motion.
            let rates = |kappa: &[f32]| -> Vec<f32> {
                let dv = bodies.velocity_change(kappa);
                let mut r: Vec<f32> = (0..n).map(|i| -own[i] * kappa[i]).collect();
                bodies.add_flux(&mut r, 0..n, &dv, -1.0);
                r
            };
            let mut factor: Vec<f32> = own.iter().map(|&a| 1.0 / a).collect();
            if damped {
                bodies.damp_factors(&mut factor);
            }
            let source = vec![1.0f32; n];
            let mut kappa = vec![0.0f32; n];
            let residual = |kappa: &[f32]| -> f32 {
                let r = rates(kappa);
                (0..n).map(|i| (source[i] + r[i]).abs()).sum()
            };
            let first = residual(&kappa);
            for _ in 0..50 {
                let r = rates(&kappa);
                for i in 0..n {
                    kappa[i] += factor[i] * (source[i] + r[i]);
                }
            }
            let last = residual(&kappa);
            assert_eq!(
                last < 0.5 * first,
                converges,
                "1/M = {inverse_mass}, damped {damped}: residual {first} -> {last}"
            );
        }
    }
}
