//! The SPH density and the DFSPH factor of every fluid particle on the GPU (TVCG 2017, eq. 1
//! relative to ρ0 and eq. 13 in volumes, with Akinci et al.'s wall volumes):
//! `dfsph::solver::density_and_factor`.

use crate::device::{Gpu, GpuError};
use crate::grid::{groups, GridLayout, GridPass};

/// The particles and walls of a density computation, as the CPU solver holds them. The
/// kernel is the 2D cubic spline.
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
    /// The walls' share of the gradient sum (`BoundaryModel::gradient_weight`).
    pub wall_weight: f32,
    /// Cap on the factor, m² (`SolverSettings::max_factor_ratio` × the lattice's factor).
    pub max_factor: f32,
}

/// What [`DensityPass::run`] gives per fluid particle, in the input's order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Densities {
    /// ρ_i/ρ0.
    pub ratio: Vec<f32>,
    /// The DFSPH factor, m².
    pub factor: Vec<f32>,
    /// g_i = Σ_j V ∇W_ij + w Σ_b Ψ_b ∇W_ib, 1/m.
    pub grad_sum: Vec<[f32; 2]>,
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
    wall_weight: f32,
    max_factor: f32,
    eps: f32,
}

/// The density and factor pass and the grid it builds first.
pub struct DensityPass {
    grid: GridPass,
    density: wgpu::ComputePipeline,
}

impl DensityPass {
    pub fn new(gpu: &Gpu) -> Self {
        Self {
            grid: GridPass::new(gpu),
            density: gpu.pipeline(
                include_str!("shaders/density_factor.wgsl"),
                "density_factor",
            ),
        }
    }

    /// The densities and factors of every fluid particle of `input`.
    pub fn run(&self, gpu: &Gpu, input: &DensityInput) -> Result<Densities, GpuError> {
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
            wall_weight: input.wall_weight,
            max_factor: input.max_factor,
            // The CPU's guard: a particle with (almost) no neighbours gets no pressure.
            eps: 1.0e-6 / (h * h),
        };
        let uniform = gpu.uniform("density", &params);
        let volumes = gpu.storage("wall volumes", input.wall_volumes);
        let out = gpu.zeroed::<[f32; 4]>("density and factor", n);
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
        let values: Vec<[f32; 4]> = gpu.read(&out, n)?;
        Ok(Densities {
            ratio: values.iter().map(|v| v[0]).collect(),
            factor: values.iter().map(|v| v[1]).collect(),
            grad_sum: values.iter().map(|v| [v[2], v[3]]).collect(),
        })
    }
}
