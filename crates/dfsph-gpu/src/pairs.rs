//! The particles of a pair pass on the device: fluid and walls sorted into one set of cells,
//! and the parameters every pair shader reads (`shaders/pairs_prelude.wgsl`).

use crate::device::Gpu;
use crate::grid::{GridLayout, GridPass, SortedGrid};

/// The particles and walls as the CPU solver holds them. The kernel is the 2D cubic spline.
pub struct ParticleInput<'a> {
    /// Fluid positions, m.
    pub fluid: &'a [[f32; 2]],
    /// Wall particle positions, m, their volumes Ψ_b, m², and velocities, m/s.
    pub walls: &'a [[f32; 2]],
    pub wall_volumes: &'a [f32],
    pub wall_velocities: &'a [[f32; 2]],
    /// The fluid particles' volume V = m/ρ0, m².
    pub volume: f32,
    /// The cubic spline's support radius h, m.
    pub support: f32,
    /// The walls' share of the gradient sum and of the wall flux
    /// (`BoundaryModel::gradient_weight`).
    pub wall_weight: f32,
    /// Cap on the DFSPH factor, m² (`SolverSettings::max_factor_ratio` × the lattice's).
    pub max_factor: f32,
}

/// (Ψ_b, v_b, 0) per wall particle, as the shaders read the walls beside their positions.
pub(crate) fn wall_data(volumes: &[f32], velocities: &[[f32; 2]]) -> Vec<[f32; 4]> {
    volumes
        .iter()
        .zip(velocities)
        .map(|(&psi, v)| [psi, v[0], v[1], 0.0])
        .collect()
}

/// What every pair shader reads (`struct Params` of the prelude).
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct Params {
    pub origin: [f32; 2],
    pub inv_cell: f32,
    pub n: u32,
    pub nx: u32,
    pub ny: u32,
    pub h: f32,
    pub k: f32,
    pub volume: f32,
    pub wall_weight: f32,
    pub max_factor: f32,
    pub eps: f32,
}

impl Params {
    /// The parameters of `layout`'s cells (side h), for the cubic spline of support `h`.
    pub fn new(
        layout: &GridLayout,
        n: usize,
        h: f32,
        volume: f32,
        wall_weight: f32,
        max_factor: f32,
    ) -> Self {
        Self {
            origin: layout.origin,
            inv_cell: layout.inv_cell,
            n: n as u32,
            nx: layout.nx,
            ny: layout.ny,
            h,
            k: 40.0 / (7.0 * std::f32::consts::PI * h * h),
            volume,
            wall_weight,
            max_factor,
            // The CPU's guard: a particle with (almost) no neighbours gets no pressure.
            eps: 1.0e-6 / (h * h),
        }
    }
}

/// The particles on the device, sorted into cells of side h.
pub struct DeviceParticles {
    pub(crate) params: Params,
    pub(crate) uniform: wgpu::Buffer,
    pub(crate) fluid: SortedGrid,
    pub(crate) walls: SortedGrid,
    /// (Ψ_b, v_b, 0) per wall particle.
    pub(crate) wall_data: wgpu::Buffer,
}

impl DeviceParticles {
    /// Upload `input` and sort both sets into one set of cells (so that a particle's 3 × 3
    /// cells are the same in each).
    pub fn upload(gpu: &Gpu, grid: &GridPass, input: &ParticleInput) -> Self {
        let nw = input.walls.len();
        assert!(
            input.wall_volumes.len() == nw && input.wall_velocities.len() == nw,
            "one volume and one velocity per wall particle"
        );
        let h = input.support;
        let all: Vec<[f32; 2]> = input.fluid.iter().chain(input.walls).copied().collect();
        let layout = GridLayout::covering(&all, h, 0);
        let fluid = grid.build(gpu, layout.for_points(input.fluid.len()), input.fluid);
        let walls = grid.build(gpu, layout.for_points(nw), input.walls);
        let params = Params::new(
            &layout,
            input.fluid.len(),
            h,
            input.volume,
            input.wall_weight,
            input.max_factor,
        );
        Self {
            params,
            uniform: gpu.uniform("pair parameters", &params),
            fluid,
            walls,
            wall_data: gpu.upload(
                "wall data",
                &wall_data(input.wall_volumes, input.wall_velocities),
            ),
        }
    }

    /// Fluid particles.
    pub fn len(&self) -> usize {
        self.params.n as usize
    }

    /// True when there are none.
    pub fn is_empty(&self) -> bool {
        self.params.n == 0
    }
}

impl Gpu {
    /// A pair shader's pipeline: the prelude, then `body` (and the library functions it
    /// calls, `Gpu::pipeline`).
    pub(crate) fn pair_pipeline(&self, body: &str, entry: &str) -> wgpu::ComputePipeline {
        let source = format!("{}\n{body}", include_str!("shaders/pairs_prelude.wgsl"));
        self.pipeline(&source, entry)
    }

    /// Run `pipeline` once over the fluid particles, with `buffers` bound in order.
    pub(crate) fn over_fluid(
        &self,
        pipeline: &wgpu::ComputePipeline,
        n: usize,
        buffers: &[&wgpu::Buffer],
    ) {
        let group = self.bind(pipeline, buffers);
        let mut encoder = self.device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, &group, &[]);
            pass.dispatch_workgroups(crate::grid::groups(n as u32, 64), 1, 1);
        }
        self.queue.submit([encoder.finish()]);
    }
}
