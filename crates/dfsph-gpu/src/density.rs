//! The SPH density of every fluid particle on the GPU (TVCG 2017, eq. 1, relative to ρ0,
//! with Akinci et al.'s wall volumes): `ρ_i/ρ0 = Σ_j V W_ij + Σ_b Ψ_b W_ib`.

use crate::device::{Gpu, GpuError};
use crate::grid::{groups, GridLayout, GridPass};

/// The particles and walls of a density computation, as the CPU solver holds them.
pub struct DensityInput<'a> {
    /// Fluid positions, m.
    pub fluid: &'a [[f32; 2]],
    /// Wall particle positions, m, and their volumes Ψ_b, m².
    pub walls: &'a [[f32; 2]],
    pub wall_volumes: &'a [f32],
    /// The fluid particles' volume V = m/ρ0, m².
    pub volume: f32,
    /// The cubic spline's support radius h, m.
    pub support: f32,
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Params {
    origin: [f32; 2],
    inv_cell: f32,
    n: u32,
    nx: u32,
    ny: u32,
    h: f32,
    k: f32,
    volume: f32,
    pad: [u32; 3],
}

/// The density pass and the grid it builds first.
pub struct DensityPass {
    grid: GridPass,
    density: wgpu::ComputePipeline,
}

impl DensityPass {
    pub fn new(gpu: &Gpu) -> Self {
        Self {
            grid: GridPass::new(gpu),
            density: gpu.pipeline(include_str!("shaders/density.wgsl"), "density_ratio"),
        }
    }

    /// ρ_i/ρ0 of every fluid particle of `input`, in its order.
    pub fn density_ratios(&self, gpu: &Gpu, input: &DensityInput) -> Result<Vec<f32>, GpuError> {
        assert_eq!(
            input.walls.len(),
            input.wall_volumes.len(),
            "one volume per wall"
        );
        let h = input.support;
        let all: Vec<[f32; 2]> = input.fluid.iter().chain(input.walls).copied().collect();
        // One set of cells for both, so that a particle's 3 × 3 cells are the same in each.
        let layout = GridLayout::covering(&all, h, 0);
        let fluid = self
            .grid
            .build(gpu, layout.for_points(input.fluid.len()), input.fluid);
        let walls = self
            .grid
            .build(gpu, layout.for_points(input.walls.len()), input.walls);
        let n = input.fluid.len();
        let params = Params {
            origin: layout.origin,
            inv_cell: layout.inv_cell,
            n: n as u32,
            nx: layout.nx,
            ny: layout.ny,
            h,
            k: 40.0 / (7.0 * std::f32::consts::PI * h * h),
            volume: input.volume,
            pad: [0; 3],
        };
        let uniform = gpu.uniform("density", &params);
        let volumes = gpu.storage("wall volumes", input.wall_volumes);
        let out = gpu.zeroed::<f32>("density", n);
        let group = gpu.bind(
            &self.density,
            &[
                &uniform,
                &fluid.positions,
                &fluid.sorted,
                &fluid.starts,
                &walls.positions,
                &volumes,
                &walls.sorted,
                &walls.starts,
                &out,
            ],
        );
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            pass.set_pipeline(&self.density);
            pass.set_bind_group(0, &group, &[]);
            pass.dispatch_workgroups(groups(n as u32, 64), 1, 1);
        }
        gpu.queue.submit([encoder.finish()]);
        gpu.read(&out, n)
    }
}
