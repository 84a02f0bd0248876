//! The two operators every pressure solve is built from, on the GPU: the density rate a
//! velocity field causes (`dfsph::solver::density_rates`) and the velocity change a
//! stiffness field causes (`dfsph::solver::apply_pressure`), with the walls' flux.

use crate::density::DeviceDensities;
use crate::device::Gpu;
use crate::pairs::DeviceParticles;

/// The operators' pipelines.
pub struct Operators {
    flux: wgpu::ComputePipeline,
    rate: wgpu::ComputePipeline,
    push: wgpu::ComputePipeline,
}

impl Operators {
    pub fn new(gpu: &Gpu) -> Self {
        Self {
            flux: gpu.pair_pipeline(
                include_str!("shaders/neighbour_flux.wgsl"),
                "neighbour_flux",
            ),
            rate: gpu.pair_pipeline(include_str!("shaders/density_rate.wgsl"), "density_rate"),
            push: gpu.pair_pipeline(include_str!("shaders/pressure_push.wgsl"), "pressure_push"),
        }
    }

    /// (f_i, neighbour count) per fluid particle: f_i = w Σ_b Ψ_b v_b·∇W_ib, the walls'
    /// share of the density rate at their velocities, and the fluid (itself excluded) and
    /// wall particles within the support.
    pub fn wall_flux(&self, gpu: &Gpu, particles: &DeviceParticles) -> wgpu::Buffer {
        let n = particles.len();
        let flux = gpu.zeroed::<[f32; 2]>("wall flux and neighbour count", n);
        gpu.over_fluid(
            &self.flux,
            n,
            &[
                &particles.uniform,
                &particles.fluid.positions,
                &particles.fluid.sorted,
                &particles.fluid.starts,
                &particles.walls.positions,
                &particles.wall_data,
                &particles.walls.sorted,
                &particles.walls.starts,
                &flux,
            ],
        );
        flux
    }

    /// r_i = v_i·g_i − V Σ_j v_j·∇W_ij − f_i for the fluid velocities `velocity` (one
    /// `[f32; 2]` per particle) and the walls' share `flux` ([`Self::wall_flux`]), 1/s.
    pub fn density_rates(
        &self,
        gpu: &Gpu,
        particles: &DeviceParticles,
        densities: &DeviceDensities,
        velocity: &wgpu::Buffer,
        flux: &wgpu::Buffer,
    ) -> wgpu::Buffer {
        let n = particles.len();
        let rate = gpu.zeroed::<f32>("density rate", n);
        gpu.over_fluid(
            &self.rate,
            n,
            &[
                &particles.uniform,
                &particles.fluid.positions,
                &particles.fluid.sorted,
                &particles.fluid.starts,
                &densities.buffer,
                velocity,
                flux,
                &rate,
            ],
        );
        rate
    }

    /// Δv_i = −κ_i g_i − V Σ_j κ_j ∇W_ij for the stiffness field `kappa`, m/s.
    pub fn pressure_push(
        &self,
        gpu: &Gpu,
        particles: &DeviceParticles,
        densities: &DeviceDensities,
        kappa: &wgpu::Buffer,
    ) -> wgpu::Buffer {
        let n = particles.len();
        let dv = gpu.zeroed::<[f32; 2]>("velocity change", n);
        gpu.over_fluid(
            &self.push,
            n,
            &[
                &particles.uniform,
                &particles.fluid.positions,
                &particles.fluid.sorted,
                &particles.fluid.starts,
                &densities.buffer,
                kappa,
                &dv,
            ],
        );
        dv
    }
}
