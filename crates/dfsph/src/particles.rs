//! Structure-of-arrays particle storage. Fluid arrays are reordered every step by the
//! neighbour grid's cell order (see [`crate::neighbors`]); the stable `id` of each particle
//! travels with it so outputs can be written in a fixed order.

use glam::Vec2;

use crate::boundary::BodyId;
use crate::neighbors::permute;

/// Fluid particles. All arrays have the same length.
#[derive(Default, Clone, Debug)]
pub struct FluidParticles {
    /// Position, m.
    pub position: Vec<Vec2>,
    /// Velocity, m/s.
    pub velocity: Vec<Vec2>,
    /// Stable identity (creation order).
    pub id: Vec<u32>,
    /// Density relative to the rest density, ρ/ρ0.
    pub density_ratio: Vec<f32>,
    /// DFSPH factor `1 / (|Σ_j V_j ∇W_ij|² + Σ_j |V_j ∇W_ij|²)` in m² (Bender & Koschier 2017,
    /// eq. 13, divided by ρ_i and written with volumes instead of masses); 0 for particles
    /// with (almost) no neighbours.
    pub factor: Vec<f32>,
    /// Pressure divided by rest density, p/ρ0 in m²/s², from the density solve (DFSPH) or the
    /// equation of state (WCSPH). Kept between steps for the warm start.
    pub pressure_over_rho0: Vec<f32>,
    /// Accumulated divergence-solve stiffness κᵛ in m²/s, kept for the warm start.
    pub divergence_stiffness: Vec<f32>,
    /// Non-pressure acceleration of the current step, m/s².
    pub acceleration: Vec<Vec2>,
}

impl FluidParticles {
    /// Number of particles.
    pub fn len(&self) -> usize {
        self.position.len()
    }

    /// True when there are none.
    pub fn is_empty(&self) -> bool {
        self.position.is_empty()
    }

    /// Make room for `additional` more particles in every array, exactly: built by pushes
    /// alone the arrays could hold twice the capacity they use.
    pub fn reserve(&mut self, additional: usize) {
        self.position.reserve_exact(additional);
        self.velocity.reserve_exact(additional);
        self.id.reserve_exact(additional);
        self.density_ratio.reserve_exact(additional);
        self.factor.reserve_exact(additional);
        self.pressure_over_rho0.reserve_exact(additional);
        self.divergence_stiffness.reserve_exact(additional);
        self.acceleration.reserve_exact(additional);
    }

    /// Append one particle at rest density.
    pub fn push(&mut self, position: Vec2, velocity: Vec2, id: u32) {
        self.position.push(position);
        self.velocity.push(velocity);
        self.id.push(id);
        self.density_ratio.push(1.0);
        self.factor.push(0.0);
        self.pressure_over_rho0.push(0.0);
        self.divergence_stiffness.push(0.0);
        self.acceleration.push(Vec2::ZERO);
    }

    /// Keep only the particles for which `keep` is true; returns how many were removed.
    pub fn retain(&mut self, mut keep: impl FnMut(usize) -> bool) -> usize {
        let mask: Vec<bool> = (0..self.len()).map(&mut keep).collect();
        let before = self.len();
        filter(&mut self.position, &mask);
        filter(&mut self.velocity, &mask);
        filter(&mut self.id, &mask);
        filter(&mut self.density_ratio, &mask);
        filter(&mut self.factor, &mask);
        filter(&mut self.pressure_over_rho0, &mask);
        filter(&mut self.divergence_stiffness, &mask);
        filter(&mut self.acceleration, &mask);
        before - self.len()
    }

    /// Reorder every array by `order` (see [`crate::neighbors::Grid::build`]). Only the state
    /// that survives a step is moved; per-step quantities are recomputed after sorting.
    pub fn permute(&mut self, order: &[u32], scratch: &mut Scratch) {
        permute(&mut self.position, order, &mut scratch.vec2);
        permute(&mut self.velocity, order, &mut scratch.vec2);
        permute(&mut self.id, order, &mut scratch.uint);
        permute(&mut self.pressure_over_rho0, order, &mut scratch.float);
        permute(&mut self.divergence_stiffness, order, &mut scratch.float);
    }
}

/// Keep the entries of `v` whose `mask` entry is true.
fn filter<T: Copy>(v: &mut Vec<T>, mask: &[bool]) {
    let mut keep = mask.iter();
    v.retain(|_| *keep.next().expect("mask as long as the array"));
}

/// Reusable buffers for [`FluidParticles::permute`].
#[derive(Default, Clone, Debug)]
pub struct Scratch {
    pub vec2: Vec<Vec2>,
    pub float: Vec<f32>,
    pub uint: Vec<u32>,
    pub body: Vec<BodyId>,
}

/// Boundary particles, sorted by the boundary grid's cell order.
#[derive(Default, Clone, Debug)]
pub struct BoundaryParticles {
    /// Position, m.
    pub position: Vec<Vec2>,
    /// Velocity of the body the particle belongs to, m/s.
    pub velocity: Vec<Vec2>,
    /// Volume Ψ_b in m² (Akinci et al. 2012, with the wall correction of [`crate::boundary`]).
    pub volume: Vec<f32>,
    /// Owning body.
    pub body: Vec<BodyId>,
    /// Position in its rigid body's frame, m (zero for the tank, obstacles and walls).
    pub local: Vec<Vec2>,
}

impl BoundaryParticles {
    /// Number of particles.
    pub fn len(&self) -> usize {
        self.position.len()
    }

    /// True when there are none.
    pub fn is_empty(&self) -> bool {
        self.position.is_empty()
    }

    /// Keep the particles whose `keep` entry is true; returns how many were removed.
    pub fn retain(&mut self, keep: &[bool]) -> usize {
        let before = self.len();
        filter(&mut self.position, keep);
        filter(&mut self.velocity, keep);
        filter(&mut self.volume, keep);
        filter(&mut self.body, keep);
        filter(&mut self.local, keep);
        before - self.len()
    }

    /// Reorder every array by `order`.
    pub fn permute(&mut self, order: &[u32], scratch: &mut Scratch) {
        permute(&mut self.position, order, &mut scratch.vec2);
        permute(&mut self.velocity, order, &mut scratch.vec2);
        permute(&mut self.volume, order, &mut scratch.float);
        permute(&mut self.body, order, &mut scratch.body);
        permute(&mut self.local, order, &mut scratch.vec2);
    }
}
