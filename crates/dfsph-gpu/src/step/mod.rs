//! One DFSPH step on the device (Bender & Koschier, TVCG 2017, Algorithm 1, as the CPU
//! backend arranges it): the grid, densities and factors, the divergence solve, the CFL
//! Δt, the non-pressure forces and predicted velocities, the density solve, advection and
//! containment, recorded into one command buffer and submitted once. Nothing comes back to
//! the host inside the step: each solve's stopping rule runs on the device
//! (`jacobi_control.wgsl`, `cg_control.wgsl`), which writes the next iteration's workgroup
//! counts for an indirect dispatch (zero once the solve has ended), and Δt is computed there
//! too (`time_step.wgsl`). The step's results are read back once, after it.
//!
//! The divergence solve is the paper's Jacobi iteration; the density solve is the scene's:
//! the Jacobi iteration with Akinci's walls (`"pressure_solve": "jacobi"`), or the deflated
//! conjugate gradients with the mirrored walls and their hydrostatic ghosts
//! ([`conjugate_gradient`], every scene's default), each with the CPU backend's stopping
//! rules, warm start and take-back of a step that made the error grow.

mod conjugate_gradient;
pub(crate) mod layout;
pub mod recording;

use std::sync::Arc;

use glam::Vec2;

use crate::device::{Gpu, GpuError};
use crate::grid::{groups, GridBuffers, GridLayout, GridPass};
use crate::pairs::Params;
pub(crate) use conjugate_gradient::{coarse_capacity, MAX_COARSE_ENTRIES};
use conjugate_gradient::{CgBuffers, CgPass, StepBuffers};
pub use layout::{CgSolve, CgState, Control, Solve, StepConsts};
use layout::{Slot, WIDE};
use recording::{budget, count, Recording, RecordingCounts};

/// What one step starts from, as the host holds it.
pub struct StepInput<'a> {
    /// Fluid positions, m, velocities, m/s, the previous step's p/ρ0, m²/s², and κᵛ, m²/s.
    pub position: &'a [Vec2],
    pub velocity: &'a [Vec2],
    pub pressure: &'a [f32],
    pub divergence_stiffness: &'a [f32],
    /// Wall positions, m, volumes Ψ_b, m², and velocities, m/s.
    pub walls: &'a [Vec2],
    pub wall_volumes: &'a [f32],
    pub wall_velocities: &'a [Vec2],
    /// The cubic spline's support h, m; the fluid particles' volume V, m²; the cap on the
    /// DFSPH factor, m²; the walls' gradient weight (`BoundaryModel::gradient_weight`).
    pub support: f32,
    pub volume: f32,
    pub max_factor: f32,
    pub wall_weight: f32,
    /// The box the grid's cells of side h cover (points outside fall into its edge cells).
    pub bounds: (Vec2, Vec2),
    /// Forces, bounds on Δt, the tank.
    pub consts: StepConsts,
    /// The two solves' constants; no divergence solve when `None`. Their counts and
    /// workgroups are filled in here.
    pub divergence: Option<Solve>,
    pub density: DensitySolve,
    /// The previous step's Δt, s (the divergence solve measures its error over it).
    pub last_dt: f32,
}

/// The density solve of a step, and its constants.
#[derive(Clone, Copy, Debug)]
pub enum DensitySolve {
    /// The paper's Jacobi iteration (with Akinci's walls).
    Jacobi(Solve),
    /// Conjugate gradients (with the mirrored walls), without deflation.
    ConjugateGradient(CgSolve),
}

impl DensitySolve {
    fn max_iterations(&self) -> u32 {
        match self {
            Self::Jacobi(s) => s.max_iterations,
            Self::ConjugateGradient(s) => s.max_iterations,
        }
    }
}

/// What one step leaves, read back.
#[derive(Clone, Debug, Default)]
pub struct StepOutput {
    pub position: Vec<Vec2>,
    pub velocity: Vec<Vec2>,
    /// ρ/ρ0 and the DFSPH factor at the step's start, m².
    pub density_ratio: Vec<f32>,
    pub factor: Vec<f32>,
    /// p/ρ0 of the density solve, m²/s², and κᵛ of the divergence solve, m²/s.
    pub pressure: Vec<f32>,
    pub divergence_stiffness: Vec<f32>,
    /// Neighbours (fluid, itself excluded, and walls) per fluid particle, on average.
    pub avg_neighbours: f64,
    /// Δt, the solves' iterations and errors.
    pub control: Control,
    /// Particles put back into the tank, and non-finite particles reset.
    pub clamped: u32,
    pub non_finite: u32,
    /// How often the step was redone with a shorter Δt (set by the backend).
    pub retries: u32,
}

/// The step's pipelines, and its buffers, kept from step to step.
pub struct DeviceStep {
    grid: GridPass,
    density: wgpu::ComputePipeline,
    flux: wgpu::ComputePipeline,
    begin: wgpu::ComputePipeline,
    residual: wgpu::ComputePipeline,
    warm: wgpu::ComputePipeline,
    apply: wgpu::ComputePipeline,
    control: wgpu::ComputePipeline,
    end: wgpu::ComputePipeline,
    speed: wgpu::ComputePipeline,
    time_step: wgpu::ComputePipeline,
    forces: wgpu::ComputePipeline,
    wall_forces: wgpu::ComputePipeline,
    cg: CgPass,
    predict: wgpu::ComputePipeline,
    unseen_fluid: wgpu::ComputePipeline,
    unseen_walls: wgpu::ComputePipeline,
    unseen_fold: wgpu::ComputePipeline,
    advect: wgpu::ComputePipeline,
    buffers: Option<Buffers>,
    recording: Recording,
    /// The iterations the divergence and the density solve took in the last step.
    last_iterations: [Option<u32>; 2],
    counts: Arc<RecordingCounts>,
}

/// Bytes of one iteration's indirect dispatch sizes: three dispatches of three counts.
const DISPATCH_SLOT: u64 = 9 * 4;

/// The step's buffers: per fluid particle, per wall particle, and the small blocks.
struct Buffers {
    fluid_capacity: usize,
    wall_capacity: usize,
    fluid_grid: GridBuffers,
    wall_grid: GridBuffers,
    params: wgpu::Buffer,
    consts: wgpu::Buffer,
    /// The divergence and density solves' constants.
    solves: [wgpu::Buffer; 2],
    /// `slots[mode][parity]`.
    slots: [[wgpu::Buffer; 2]; 2],
    control: wgpu::Buffer,
    /// The uniform copy of `control` the passes read Δt from.
    clock: wgpu::Buffer,
    /// The solves' iterations the dispatch buffers hold slots for.
    max_iterations: u32,
    /// The indirect dispatch sizes of the even and the odd iterations
    /// (`jacobi_control.wgsl`).
    dispatch: [wgpu::Buffer; 2],
    counts: wgpu::Buffer,
    position: wgpu::Buffer,
    velocity: wgpu::Buffer,
    /// (ρ/ρ0, factor, g_i).
    densities: wgpu::Buffer,
    /// (wall flux, neighbour count).
    flux: wgpu::Buffer,
    /// A Jacobi solve's per-particle state (`jacobi_begin.wgsl`).
    jac: wgpu::Buffer,
    increments: [wgpu::Buffer; 2],
    acceleration: wgpu::Buffer,
    pressure: wgpu::Buffer,
    stiffness: wgpu::Buffer,
    partials: wgpu::Buffer,
    walls: wgpu::Buffer,
    wall_data: wgpu::Buffer,
    /// The conjugate-gradient solve's.
    cg: CgBuffers,
}

impl Buffers {
    fn new(
        gpu: &Gpu,
        fluid: usize,
        walls: usize,
        cells: usize,
        max_iterations: u32,
        (aggregates, entries): (usize, usize),
    ) -> Self {
        let uniform = |label: &str, size: usize| {
            gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: size as u64,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        let slot = |mode: u32, parity: u32| {
            gpu.uniform(
                "slot",
                &Slot {
                    parity,
                    mode,
                    pad: [0; 2],
                },
            )
        };
        let dispatch = |label| {
            gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: (max_iterations as u64 / 2 + 1) * DISPATCH_SLOT,
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::INDIRECT
                    | wgpu::BufferUsages::COPY_DST
                    | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            })
        };
        Self {
            fluid_capacity: fluid,
            wall_capacity: walls,
            fluid_grid: GridBuffers::new(gpu, fluid, cells),
            wall_grid: GridBuffers::new(gpu, walls, cells),
            params: uniform("pair parameters", std::mem::size_of::<Params>()),
            consts: uniform("step constants", std::mem::size_of::<StepConsts>()),
            solves: [
                uniform("divergence solve", std::mem::size_of::<Solve>()),
                uniform("density solve", std::mem::size_of::<Solve>()),
            ],
            slots: [[slot(0, 0), slot(0, 1)], [slot(1, 0), slot(1, 1)]],
            control: gpu.zeroed::<Control>("control", 1),
            clock: uniform("clock", std::mem::size_of::<Control>()),
            max_iterations,
            dispatch: [dispatch("dispatch even"), dispatch("dispatch odd")],
            counts: gpu.zeroed::<u32>("containment counts", 2),
            position: gpu.zeroed::<[f32; 2]>("positions", fluid),
            velocity: gpu.zeroed::<[f32; 2]>("velocities", fluid),
            densities: gpu.zeroed::<[f32; 4]>("densities", fluid),
            flux: gpu.zeroed::<[f32; 2]>("wall flux and neighbours", fluid),
            jac: gpu.zeroed::<[f32; 4]>("jacobi state", fluid),
            increments: [
                gpu.zeroed::<f32>("increments 0", fluid),
                gpu.zeroed::<f32>("increments 1", fluid),
            ],
            acceleration: gpu.zeroed::<[f32; 2]>("accelerations", fluid),
            pressure: gpu.zeroed::<f32>("pressures", fluid),
            stiffness: gpu.zeroed::<f32>("divergence stiffness", fluid),
            partials: gpu.zeroed::<[f32; 2]>("partials", fluid.div_ceil(WIDE as usize)),
            walls: gpu.zeroed::<[f32; 2]>("wall positions", walls),
            wall_data: gpu.zeroed::<[f32; 4]>("wall data", walls),
            cg: CgBuffers::new(gpu, fluid, max_iterations, aggregates, entries),
        }
    }
}

impl DeviceStep {
    pub fn new(gpu: &Gpu) -> Self {
        let pair = |body: &str, entry: &str| {
            gpu.pair_pipeline(
                &format!("{}\n{body}", include_str!("../shaders/step_prelude.wgsl")),
                entry,
            )
        };
        let alone = |body: &str, entry: &str| {
            gpu.pipeline(
                &format!("{}\n{body}", include_str!("../shaders/step_prelude.wgsl")),
                entry,
            )
        };
        Self {
            grid: GridPass::new(gpu),
            density: gpu.pair_pipeline(
                include_str!("../shaders/density_factor.wgsl"),
                "density_factor",
            ),
            flux: gpu.pair_pipeline(
                include_str!("../shaders/neighbour_flux.wgsl"),
                "neighbour_flux",
            ),
            begin: pair(include_str!("../shaders/jacobi_begin.wgsl"), "jacobi_begin"),
            residual: pair(
                include_str!("../shaders/jacobi_residual.wgsl"),
                "jacobi_residual",
            ),
            warm: pair(include_str!("../shaders/jacobi_warm.wgsl"), "jacobi_warm"),
            apply: pair(include_str!("../shaders/jacobi_apply.wgsl"), "jacobi_apply"),
            control: alone(
                include_str!("../shaders/jacobi_control.wgsl"),
                "jacobi_control",
            ),
            end: pair(include_str!("../shaders/jacobi_end.wgsl"), "jacobi_end"),
            speed: pair(include_str!("../shaders/speed.wgsl"), "speed"),
            time_step: alone(include_str!("../shaders/time_step.wgsl"), "time_step"),
            forces: pair(include_str!("../shaders/forces.wgsl"), "forces"),
            wall_forces: pair(include_str!("../shaders/wall_forces.wgsl"), "wall_forces"),
            cg: CgPass::new(gpu),
            predict: pair(include_str!("../shaders/predict.wgsl"), "predict"),
            unseen_fluid: pair(include_str!("../shaders/unseen_fluid.wgsl"), "unseen_fluid"),
            unseen_walls: pair(include_str!("../shaders/unseen_walls.wgsl"), "unseen_walls"),
            unseen_fold: alone(include_str!("../shaders/unseen_fold.wgsl"), "unseen_fold"),
            advect: pair(include_str!("../shaders/advect.wgsl"), "advect"),
            buffers: None,
            recording: Recording::default(),
            last_iterations: [None; 2],
            counts: Arc::default(),
        }
    }

    /// Record the solves' iterations as `recording` says from the next step on.
    pub fn set_recording(&mut self, recording: Recording) {
        self.recording = recording;
    }

    /// What the recording did since this step was made.
    pub fn recording_counts(&self) -> Arc<RecordingCounts> {
        self.counts.clone()
    }

    /// Take one step from `input` on the device and read its results back. `input` must
    /// hold at least one fluid particle. The solves' iterations are recorded as
    /// [`Self::set_recording`] says; a step whose solve needed more is run again from
    /// `input` with every iteration of both solves recorded ([`recording`]).
    pub fn run(&mut self, gpu: &Gpu, input: &StepInput) -> Result<StepOutput, GpuError> {
        let caps = [
            input.divergence.map_or(0, |s| s.max_iterations),
            input.density.max_iterations(),
        ];
        let mut recorded = [0, 1].map(|k| budget(self.recording, caps[k], self.last_iterations[k]));
        let counts = self.counts.clone();
        // At most two runs: the second records every iteration, so nothing is unfinished.
        let mut out = loop {
            count(&counts.steps, 1);
            count(&counts.recorded, (recorded[0] + recorded[1]) as u64);
            let out = self.run_recorded(gpu, input, recorded)?;
            let c = out.control;
            if (c.div_unfinished == 0 && c.den_unfinished == 0) || recorded == caps {
                break out;
            }
            count(&counts.reruns, 1);
            recorded = caps;
        };
        let c = &mut out.control;
        self.last_iterations = [Some(c.div_iterations), Some(c.den_iterations)];
        count(&counts.taken, (c.div_iterations + c.den_iterations) as u64);
        (c.div_unfinished, c.den_unfinished) = (0, 0);
        Ok(out)
    }

    /// [`Self::run`] with `recorded` iterations of the divergence and the density solve
    /// recorded.
    fn run_recorded(
        &mut self,
        gpu: &Gpu,
        input: &StepInput,
        recorded: [u32; 2],
    ) -> Result<StepOutput, GpuError> {
        let n = input.position.len();
        let m = input.walls.len();
        assert!(n > 0, "a step on the device needs fluid");
        assert!(
            input.velocity.len() == n
                && input.pressure.len() == n
                && input.divergence_stiffness.len() == n,
            "one velocity, pressure and stiffness per fluid particle"
        );
        assert!(
            input.wall_volumes.len() == m && input.wall_velocities.len() == m,
            "one volume and one velocity per wall particle"
        );
        let h = input.support;
        let (lo, hi) = input.bounds;
        let layout = GridLayout::covering(&[lo.to_array(), hi.to_array()], h, n);
        let cells = layout.cells as usize;
        let max_iterations = input
            .divergence
            .map_or(0, |s| s.max_iterations)
            .max(input.density.max_iterations());
        let coarse = match input.density {
            DensitySolve::ConjugateGradient(s) if s.coarse_cell > 0.0 => {
                let (aggregates, half_band) = coarse_capacity(input.position, s.coarse_cell);
                (aggregates, aggregates * (half_band + 1))
            }
            _ => (1, 1),
        };
        self.reserve(gpu, n, m, cells, max_iterations, coarse);
        let b = self.buffers.as_ref().expect("reserved");

        // The inputs.
        let params = Params::new(
            &layout,
            n,
            h,
            input.volume,
            input.wall_weight,
            input.max_factor,
        );
        let q = &gpu.queue;
        q.write_buffer(&b.params, 0, bytemuck::bytes_of(&params));
        let groups64 = groups(n as u32, 64);
        let partials = groups(n as u32, WIDE);
        let consts = StepConsts {
            partials,
            ..input.consts
        };
        q.write_buffer(&b.consts, 0, bytemuck::bytes_of(&consts));
        let complete = |s: Solve| Solve {
            partials,
            groups: groups64,
            n: n as u32,
            ..s
        };
        let divergence = input.divergence.map(complete);
        let density = match input.density {
            DensitySolve::Jacobi(s) => DensitySolve::Jacobi(complete(s)),
            DensitySolve::ConjugateGradient(s) => DensitySolve::ConjugateGradient(CgSolve {
                partials,
                groups: groups64,
                n: n as u32,
                ..s
            }),
        };
        if let Some(s) = &divergence {
            q.write_buffer(&b.solves[0], 0, bytemuck::bytes_of(s));
        }
        if let DensitySolve::Jacobi(s) = &density {
            q.write_buffer(&b.solves[1], 0, bytemuck::bytes_of(s));
        }
        let control = Control {
            dt: input.last_dt,
            last_dt: input.last_dt,
            ..Control::default()
        };
        q.write_buffer(&b.control, 0, bytemuck::bytes_of(&control));
        q.write_buffer(&b.clock, 0, bytemuck::bytes_of(&control));
        q.write_buffer(&b.position, 0, bytemuck::cast_slice(input.position));
        q.write_buffer(&b.velocity, 0, bytemuck::cast_slice(input.velocity));
        q.write_buffer(&b.pressure, 0, bytemuck::cast_slice(input.pressure));
        q.write_buffer(
            &b.stiffness,
            0,
            bytemuck::cast_slice(input.divergence_stiffness),
        );
        if m > 0 {
            q.write_buffer(&b.walls, 0, bytemuck::cast_slice(input.walls));
            let velocities: Vec<[f32; 2]> =
                input.wall_velocities.iter().map(|v| v.to_array()).collect();
            let data = crate::pairs::wall_data(input.wall_volumes, &velocities);
            q.write_buffer(&b.wall_data, 0, bytemuck::cast_slice(&data));
        }

        // The step, recorded.
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        encoder.clear_buffer(&b.counts, 0, None);
        self.grid
            .record(gpu, &mut encoder, &layout, &b.position, &b.fluid_grid);
        self.grid.record(
            gpu,
            &mut encoder,
            &layout.for_points(m),
            &b.walls,
            &b.wall_grid,
        );
        let (fg, wg) = (&b.fluid_grid, &b.wall_grid);
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            let neighbours = [
                &b.params,
                &b.position,
                &fg.sorted,
                &fg.starts,
                &b.walls,
                &b.wall_data,
                &wg.sorted,
                &wg.starts,
            ];
            for (pipeline, out) in [(&self.density, &b.densities), (&self.flux, &b.flux)] {
                let mut buffers = neighbours.to_vec();
                buffers.push(out);
                dispatch(gpu, &mut pass, pipeline, &buffers, groups64);
            }
        }
        // Algorithm 2: the divergence solve, over the previous step's Δt.
        if let Some(solve) = &divergence {
            self.record_solve(gpu, &mut encoder, b, 0, solve, recorded[0], &b.stiffness);
        }
        // Line 7: Δt, from the velocities the divergence solve left.
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            dispatch(
                gpu,
                &mut pass,
                &self.speed,
                &[&b.params, &b.velocity, &b.partials],
                partials,
            );
            dispatch(
                gpu,
                &mut pass,
                &self.time_step,
                &[&b.consts, &b.partials, &b.control],
                1,
            );
        }
        let control_size = std::mem::size_of::<Control>() as u64;
        encoder.copy_buffer_to_buffer(&b.control, 0, &b.clock, 0, control_size);
        // Lines 6 and 8: the non-pressure forces and the predicted velocities.
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            dispatch(
                gpu,
                &mut pass,
                &self.forces,
                &[
                    &b.params,
                    &b.consts,
                    &b.clock,
                    &b.position,
                    &fg.sorted,
                    &fg.starts,
                    &b.velocity,
                    &b.acceleration,
                ],
                groups64,
            );
            if input.consts.friction > 0.0 || input.consts.ghost_slope != [0.0; 2] {
                dispatch(
                    gpu,
                    &mut pass,
                    &self.wall_forces,
                    &[
                        &b.params,
                        &b.consts,
                        &b.position,
                        &b.velocity,
                        &b.walls,
                        &b.wall_data,
                        &wg.sorted,
                        &wg.starts,
                        &b.acceleration,
                    ],
                    groups64,
                );
            }
            dispatch(
                gpu,
                &mut pass,
                &self.predict,
                &[&b.params, &b.clock, &b.acceleration, &b.velocity],
                groups64,
            );
        }
        // Algorithm 3: the density solve.
        match &density {
            DensitySolve::Jacobi(s) => {
                self.record_solve(gpu, &mut encoder, b, 1, s, recorded[1], &b.pressure)
            }
            DensitySolve::ConjugateGradient(s) => {
                let step = StepBuffers {
                    params: &b.params,
                    clock: &b.clock,
                    control: &b.control,
                    position: &b.position,
                    sorted: &b.fluid_grid.sorted,
                    starts: &b.fluid_grid.starts,
                    densities: &b.densities,
                    flux: &b.flux,
                    velocity: &b.velocity,
                    pressure: &b.pressure,
                };
                self.cg
                    .record(gpu, &mut encoder, &step, &b.cg, s, recorded[1])
            }
        }
        // What the step would compress beyond the solve's prediction (the retries' check;
        // the accelerations are spent, their buffer holds the fluid's part).
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            dispatch(
                gpu,
                &mut pass,
                &self.unseen_fluid,
                &[
                    &b.params,
                    &b.clock,
                    &b.position,
                    &fg.sorted,
                    &fg.starts,
                    &b.velocity,
                    &b.densities,
                    &b.flux,
                    &b.acceleration,
                ],
                groups64,
            );
            dispatch(
                gpu,
                &mut pass,
                &self.unseen_walls,
                &[
                    &b.params,
                    &b.clock,
                    &b.position,
                    &b.velocity,
                    &b.walls,
                    &b.wall_data,
                    &wg.sorted,
                    &wg.starts,
                    &b.acceleration,
                    &b.partials,
                ],
                partials,
            );
            dispatch(
                gpu,
                &mut pass,
                &self.unseen_fold,
                &[&b.consts, &b.partials, &b.control],
                1,
            );
        }
        // Line 10: advection, and the containment.
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            dispatch(
                gpu,
                &mut pass,
                &self.advect,
                &[
                    &b.params,
                    &b.consts,
                    &b.clock,
                    &b.position,
                    &b.velocity,
                    &b.counts,
                ],
                groups64,
            );
        }

        // The results, copied into one staging buffer and read once.
        let parts: [(&wgpu::Buffer, usize); 8] = [
            (&b.position, 8 * n),
            (&b.velocity, 8 * n),
            (&b.densities, 16 * n),
            (&b.flux, 8 * n),
            (&b.pressure, 4 * n),
            (&b.stiffness, 4 * n),
            (&b.control, control_size as usize),
            (&b.counts, 8),
        ];
        let bytes = gpu.read_many(encoder, &parts)?;
        let [position, velocity, densities, flux, pressure, stiffness, control, counts] = bytes;
        let densities: Vec<[f32; 4]> = bytemuck::pod_collect_to_vec(&densities);
        let flux: Vec<[f32; 2]> = bytemuck::pod_collect_to_vec(&flux);
        let counts: Vec<u32> = bytemuck::pod_collect_to_vec(&counts);
        Ok(StepOutput {
            position: bytemuck::pod_collect_to_vec(&position),
            velocity: bytemuck::pod_collect_to_vec(&velocity),
            density_ratio: densities.iter().map(|d| d[0]).collect(),
            factor: densities.iter().map(|d| d[1]).collect(),
            pressure: bytemuck::pod_collect_to_vec(&pressure),
            divergence_stiffness: bytemuck::pod_collect_to_vec(&stiffness),
            avg_neighbours: flux.iter().map(|f| f[1] as f64).sum::<f64>() / n as f64,
            control: bytemuck::pod_read_unaligned(&control),
            clamped: counts[0],
            non_finite: counts[1],
            retries: 0,
        })
    }

    /// Buffers for `n` fluid particles, `m` walls, `cells` grid cells, solves of up to
    /// `max_iterations` iterations and a coarse space of `coarse` (aggregates, band entries).
    fn reserve(
        &mut self,
        gpu: &Gpu,
        n: usize,
        m: usize,
        cells: usize,
        max_iterations: u32,
        coarse: (usize, usize),
    ) {
        let grow = |need: usize| need + need / 4;
        match &mut self.buffers {
            Some(b)
                if b.fluid_capacity >= n
                    && b.wall_capacity >= m
                    && b.max_iterations >= max_iterations
                    && b.cg.aggregates >= coarse.0
                    && b.cg.entries >= coarse.1 =>
            {
                b.fluid_grid.reserve(gpu, n, cells);
                b.wall_grid.reserve(gpu, m, cells);
            }
            _ => {
                self.buffers = Some(Buffers::new(
                    gpu,
                    grow(n),
                    grow(m.max(1)),
                    grow(cells),
                    max_iterations,
                    (grow(coarse.0), grow(coarse.1)),
                ))
            }
        }
    }

    /// Record one Jacobi solve (`which`: 0 divergence, 1 density) whose running total ends
    /// in `stored` (κᵛ, or p/ρ0) and whose warm start is read from it: the start, the warm
    /// start, the first residual and control, then `recorded` iterations (at most the cap)
    /// of apply, residual and control, each dispatched with the workgroup counts the control
    /// before it wrote (none once the solve has ended), then the take-back of a growing
    /// iteration and the end; then whether it would have gone on is copied into the
    /// control block (`div_unfinished` or `den_unfinished`).
    #[allow(clippy::too_many_arguments)]
    fn record_solve(
        &self,
        gpu: &Gpu,
        encoder: &mut wgpu::CommandEncoder,
        b: &Buffers,
        which: usize,
        solve: &Solve,
        recorded: u32,
        stored: &wgpu::Buffer,
    ) {
        let (fg, groups64, partials) = (&b.fluid_grid, solve.groups, solve.partials);
        let solve_buf = &b.solves[which];
        let residual = |parity: usize| {
            gpu.bind(
                &self.residual,
                &[
                    &b.params,
                    solve_buf,
                    &b.clock,
                    &b.position,
                    &fg.sorted,
                    &fg.starts,
                    &b.densities,
                    &b.velocity,
                    &b.jac,
                    &b.increments[parity],
                    &b.partials,
                ],
            )
        };
        let apply = |mode: usize, parity: usize| {
            gpu.bind(
                &self.apply,
                &[
                    &b.params,
                    &b.slots[mode][parity],
                    &b.control,
                    &b.position,
                    &fg.sorted,
                    &fg.starts,
                    &b.densities,
                    &b.increments[parity],
                    &b.velocity,
                    &b.jac,
                ],
            )
        };
        // The control pass after increments of `parity` writes the dispatch sizes of the
        // iteration after it into the buffer `writes`.
        let control = |mode: usize, parity: usize, writes: usize| {
            gpu.bind(
                &self.control,
                &[
                    solve_buf,
                    &b.slots[mode][parity],
                    &b.clock,
                    &b.partials,
                    &b.control,
                    &b.dispatch[writes],
                ],
            )
        };
        let residuals = [residual(0), residual(1)];
        let applies = [apply(0, 0), apply(0, 1)];
        let take_backs = [apply(1, 0), apply(1, 1)];
        // `controls[k % 2][p]`: iteration k's, after increments of parity p.
        let controls = [
            [control(0, 0, 1), control(0, 1, 1)],
            [control(0, 0, 0), control(0, 1, 0)],
        ];
        // Slots no control pass writes in this solve dispatch nothing.
        for buffer in &b.dispatch {
            encoder.clear_buffer(buffer, 0, None);
        }
        let mut pass = encoder.begin_compute_pass(&Default::default());
        let run = |pass: &mut wgpu::ComputePass,
                   pipeline: &wgpu::ComputePipeline,
                   group: &wgpu::BindGroup,
                   count: u32| {
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, group, &[]);
            pass.dispatch_workgroups(count, 1, 1);
        };
        let begin = gpu.bind(
            &self.begin,
            &[
                &b.params,
                solve_buf,
                &b.clock,
                &b.densities,
                &b.flux,
                stored,
                &b.jac,
            ],
        );
        run(&mut pass, &self.begin, &begin, groups64);
        let warm = solve.warm_share > 0.0;
        if warm {
            if solve.gated == 1 {
                // The residuals before the warm start decide where it applies.
                run(&mut pass, &self.residual, &residuals[0], partials);
            }
            let group = gpu.bind(
                &self.warm,
                &[&b.params, solve_buf, &b.jac, &b.increments[0]],
            );
            run(&mut pass, &self.warm, &group, groups64);
            run(&mut pass, &self.apply, &applies[0], groups64);
        }
        // Iteration k applies the increments of parity (base + k) % 2 and writes the next
        // into the other buffer.
        let base = warm as usize;
        run(&mut pass, &self.residual, &residuals[base], partials);
        let first = control(1, base, 0);
        run(&mut pass, &self.control, &first, 1);
        for k in 0..recorded as usize {
            let p = (base + k) % 2;
            let (sizes, at) = (&b.dispatch[k % 2], (k / 2) as u64 * DISPATCH_SLOT);
            pass.set_pipeline(&self.apply);
            pass.set_bind_group(0, &applies[p], &[]);
            pass.dispatch_workgroups_indirect(sizes, at);
            pass.set_pipeline(&self.residual);
            pass.set_bind_group(0, &residuals[1 - p], &[]);
            pass.dispatch_workgroups_indirect(sizes, at + 12);
            pass.set_pipeline(&self.control);
            pass.set_bind_group(0, &controls[k % 2][p], &[]);
            pass.dispatch_workgroups_indirect(sizes, at + 24);
        }
        for group in &take_backs {
            run(&mut pass, &self.apply, group, groups64);
        }
        let end = gpu.bind(&self.end, &[&b.params, solve_buf, &b.clock, &b.jac, stored]);
        run(&mut pass, &self.end, &end, groups64);
        drop(pass);
        // The apply pass's workgroups of iteration `recorded`, which its control wrote.
        let unfinished = if which == 0 {
            std::mem::offset_of!(Control, div_unfinished)
        } else {
            std::mem::offset_of!(Control, den_unfinished)
        };
        let r = recorded as u64;
        encoder.copy_buffer_to_buffer(
            &b.dispatch[(r % 2) as usize],
            r / 2 * DISPATCH_SLOT,
            &b.control,
            unfinished as u64,
            4,
        );
    }
}

/// Bind `buffers` to `pipeline` and dispatch `groups` workgroups in `pass`.
fn dispatch(
    gpu: &Gpu,
    pass: &mut wgpu::ComputePass,
    pipeline: &wgpu::ComputePipeline,
    buffers: &[&wgpu::Buffer],
    groups: u32,
) {
    let group = gpu.bind(pipeline, buffers);
    pass.set_pipeline(pipeline);
    pass.set_bind_group(0, &group, &[]);
    pass.dispatch_workgroups(groups, 1, 1);
}
