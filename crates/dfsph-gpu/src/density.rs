//! The SPH density and the DFSPH factor of every fluid particle on the GPU (TVCG 2017, eq. 1
//! relative to ρ0 and eq. 13 in volumes, with Akinci et al.'s wall volumes):
//! `dfsph::solver::density_and_factor`.

use crate::device::{Gpu, GpuError};
use crate::pairs::DeviceParticles;

/// Per fluid particle on the device: (ρ_i/ρ0, the DFSPH factor in m², g_i in 1/m), with
/// g_i = Σ_j V ∇W_ij + w Σ_b Ψ_b ∇W_ib.
pub struct DeviceDensities {
    pub(crate) buffer: wgpu::Buffer,
    n: usize,
}

/// [`DeviceDensities`] read back, in the input's order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Densities {
    /// ρ_i/ρ0.
    pub ratio: Vec<f32>,
    /// The DFSPH factor, m².
    pub factor: Vec<f32>,
    /// g_i, 1/m.
    pub grad_sum: Vec<[f32; 2]>,
}

/// The density and factor pass.
pub struct DensityPass {
    density: wgpu::ComputePipeline,
}

impl DensityPass {
    pub fn new(gpu: &Gpu) -> Self {
        Self {
            density: gpu.pair_pipeline(
                include_str!("shaders/density_factor.wgsl"),
                "density_factor",
            ),
        }
    }

    /// The densities, factors and gradient sums of `particles`.
    pub fn run(&self, gpu: &Gpu, particles: &DeviceParticles) -> DeviceDensities {
        let n = particles.len();
        let buffer = gpu.zeroed::<[f32; 4]>("density and factor", n);
        gpu.over_fluid(
            &self.density,
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
                &buffer,
            ],
        );
        DeviceDensities { buffer, n }
    }
}

impl DeviceDensities {
    /// Read the values back.
    pub fn read(&self, gpu: &Gpu) -> Result<Densities, GpuError> {
        let values: Vec<[f32; 4]> = gpu.read(&self.buffer, self.n)?;
        Ok(Densities {
            ratio: values.iter().map(|v| v[0]).collect(),
            factor: values.iter().map(|v| v[1]).collect(),
            grad_sum: values.iter().map(|v| [v[2], v[3]]).collect(),
        })
    }
}
