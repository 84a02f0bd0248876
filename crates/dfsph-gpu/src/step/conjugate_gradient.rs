//! The conjugate-gradient density solve on the device (`dfsph::pressure::conjugate_gradient`):
//! the same start, preconditioner, deflation, stopping rules and take-back of a step that
//! made the error grow, recorded into the step's command buffer. Each iteration is six
//! passes: the search direction's push (`cg_push`) and rate (`cg_rate`), the step length
//! (`cg_alpha`, one workgroup), the step (`cg_step`), the stopping test (`cg_control`, one
//! workgroup) and the next direction or the take-back (`cg_direction`), which, deflated,
//! needs the coarse restriction (`coarse_restrict`, one invocation per aggregate) and the
//! coarse solve (`coarse_solve`, one workgroup) before it. The stopping test writes the next
//! iteration's indirect dispatch sizes (zero once the solve has ended), so nothing comes back
//! to the host inside the step.
//!
//! The deflation's coarse space (`dfsph::pressure::deflation`) is built on the device at the
//! solve's start: the grid of aggregates over the particles that carry pressure
//! (`coarse_layout`), each particle's aggregate (`coarse_assign`), the four colour products
//! `A W_k 1` (`coarse_colour`, `cg_push`, `coarse_product`), the coarse matrix in band
//! storage (`coarse_rows`, `coarse_band`; every cell of the grid is an aggregate, an empty
//! one a dropped pivot) and its Cholesky factor (`coarse_factor`, one workgroup). Sums over
//! an aggregate gather its particles through the fine grid's cells, in their order.

use glam::Vec2;

use super::layout::{CgSolve, CgState, Coarse, Control, Slot, WIDE};
use crate::device::Gpu;

/// The step's buffers the solve reads and writes.
pub(super) struct StepBuffers<'a> {
    pub params: &'a wgpu::Buffer,
    /// The uniform copy of the step's `Control` (Δt), and the `Control` the solve reports in.
    pub clock: &'a wgpu::Buffer,
    pub control: &'a wgpu::Buffer,
    pub position: &'a wgpu::Buffer,
    /// The fluid grid's sorted indices and cell starts.
    pub sorted: &'a wgpu::Buffer,
    pub starts: &'a wgpu::Buffer,
    pub densities: &'a wgpu::Buffer,
    pub flux: &'a wgpu::Buffer,
    pub velocity: &'a wgpu::Buffer,
    /// p/ρ0: the previous step's in, this step's out.
    pub pressure: &'a wgpu::Buffer,
}

/// Bytes of one iteration's dispatch sizes: eight dispatches of three counts
/// (`shaders/cg_sizes.wgsl`).
const SLOT: u64 = 24 * 4;

/// The most coarse-matrix entries the device keeps (2²⁶ floats, 256 MB); a coarser water
/// (spread thinly over a large tank) steps on the CPU.
pub(crate) const MAX_COARSE_ENTRIES: usize = 1 << 26;

/// How large the coarse space of fluid at `positions` can be, for aggregates at least
/// `cell` wide (m): (aggregates, half bandwidth). The device lays its grid over the
/// particles that carry pressure (a subset) with cells at least this wide, so it never
/// needs more.
pub(crate) fn coarse_capacity(positions: &[Vec2], cell: f32) -> (usize, usize) {
    let (lo, hi) = positions
        .iter()
        .fold((Vec2::INFINITY, Vec2::NEG_INFINITY), |(lo, hi), &p| {
            (lo.min(p), hi.max(p))
        });
    if positions.is_empty() || cell <= 0.0 {
        return (1, 1);
    }
    let cells = ((hi - lo) / cell).floor() + 1.0;
    let (cx, cy) = (cells.x as usize, cells.y as usize);
    let most = 4 * positions.len() + 16;
    let short = cx.min(cy).min((most as f64).sqrt() as usize + 1);
    ((cx * cy).min(most).max(1), short + 1)
}

/// The solve's pipelines.
pub(super) struct CgPass {
    begin: wgpu::ComputePipeline,
    warm: wgpu::ComputePipeline,
    residual: wgpu::ComputePipeline,
    start: wgpu::ComputePipeline,
    push: wgpu::ComputePipeline,
    rate: wgpu::ComputePipeline,
    alpha: wgpu::ComputePipeline,
    step: wgpu::ComputePipeline,
    control: wgpu::ComputePipeline,
    direction: wgpu::ComputePipeline,
    end: wgpu::ComputePipeline,
    layout: wgpu::ComputePipeline,
    assign: wgpu::ComputePipeline,
    colour: wgpu::ComputePipeline,
    product: wgpu::ComputePipeline,
    rows: wgpu::ComputePipeline,
    band: wgpu::ComputePipeline,
    factor: wgpu::ComputePipeline,
    restrict: wgpu::ComputePipeline,
    solve: wgpu::ComputePipeline,
    prolong: wgpu::ComputePipeline,
    first: wgpu::ComputePipeline,
}

/// The solve's buffers: per fluid particle, its state and the dispatch sizes of the even and
/// the odd iterations.
pub(super) struct CgBuffers {
    solve: wgpu::Buffer,
    state: wgpu::Buffer,
    /// κ, the search direction p, the error e, whether the particle carries pressure.
    total: wgpu::Buffer,
    direction: wgpu::Buffer,
    residual: wgpu::Buffer,
    active: wgpu::Buffer,
    /// The direction's velocity change Δv and rate change q.
    change: wgpu::Buffer,
    rate: wgpu::Buffer,
    /// (Σ, max, Σ, Σ) per workgroup of 256.
    partials: wgpu::Buffer,
    dispatch: [wgpu::Buffer; 2],
    /// The bounds of the particles that carry pressure, per workgroup of 256.
    bounds: wgpu::Buffer,
    /// The coarse space: its grid, the per-aggregate passes' dispatch size, each particle's
    /// aggregate and `A W` entries (one per colour), the rows before symmetrising (nine per
    /// aggregate), the band of E and its factor, E's diagonal, and a coarse vector.
    coarse: wgpu::Buffer,
    coarse_sizes: wgpu::Buffer,
    aggregate: wgpu::Buffer,
    aw: wgpu::Buffer,
    rows: wgpu::Buffer,
    band: wgpu::Buffer,
    diagonal: wgpu::Buffer,
    y: wgpu::Buffer,
    /// `Slot`s naming a colour (`parity`) and a restriction (`mode`).
    colours: [wgpu::Buffer; 4],
    restrictions: [wgpu::Buffer; 2],
    /// The aggregates and the coarse matrix's entries these buffers hold.
    pub aggregates: usize,
    pub entries: usize,
}

impl CgBuffers {
    /// Buffers for `fluid` particles, solves of up to `max_iterations` iterations, and a
    /// coarse space of `aggregates` and `entries` band entries.
    pub fn new(
        gpu: &Gpu,
        fluid: usize,
        max_iterations: u32,
        aggregates: usize,
        entries: usize,
    ) -> Self {
        let slot = |parity: u32, mode: u32| {
            gpu.uniform(
                "coarse slot",
                &Slot {
                    parity,
                    mode,
                    pad: [0; 2],
                },
            )
        };
        let storage_indirect = |label, size: u64| {
            gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::INDIRECT
                    | wgpu::BufferUsages::COPY_DST
                    | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            })
        };
        let dispatch = |label| storage_indirect(label, (max_iterations as u64 / 2 + 1) * SLOT);
        let partials = fluid.div_ceil(WIDE as usize);
        Self {
            solve: gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("cg solve"),
                size: std::mem::size_of::<CgSolve>() as u64,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            state: gpu.zeroed::<CgState>("cg state", 1),
            total: gpu.zeroed::<f32>("cg total", fluid),
            direction: gpu.zeroed::<f32>("cg direction", fluid),
            residual: gpu.zeroed::<f32>("cg residual", fluid),
            active: gpu.zeroed::<f32>("cg active", fluid),
            change: gpu.zeroed::<[f32; 2]>("cg velocity change", fluid),
            rate: gpu.zeroed::<f32>("cg rate change", fluid),
            partials: gpu.zeroed::<[f32; 4]>("cg partials", partials),
            dispatch: [dispatch("cg dispatch even"), dispatch("cg dispatch odd")],
            bounds: gpu.zeroed::<[f32; 4]>("cg bounds", partials),
            coarse: gpu.zeroed::<Coarse>("coarse grid", 1),
            coarse_sizes: storage_indirect("coarse dispatch", 12),
            aggregate: gpu.zeroed::<u32>("aggregates", fluid),
            aw: gpu.zeroed::<[f32; 4]>("A W", fluid),
            rows: gpu.zeroed::<f32>("coarse rows", 9 * aggregates),
            band: gpu.zeroed::<f32>("coarse band", entries),
            diagonal: gpu.zeroed::<f32>("coarse diagonal", aggregates),
            y: gpu.zeroed::<f32>("coarse vector", aggregates),
            colours: [slot(0, 0), slot(1, 0), slot(2, 0), slot(3, 0)],
            restrictions: [slot(0, 0), slot(0, 1)],
            aggregates,
            entries,
        }
    }
}

impl CgPass {
    pub fn new(gpu: &Gpu) -> Self {
        let prelude = include_str!("../shaders/step_prelude.wgsl");
        let pair =
            |body: &str, entry: &str| gpu.pair_pipeline(&format!("{prelude}\n{body}"), entry);
        let alone = |body: &str, entry: &str| gpu.pipeline(&format!("{prelude}\n{body}"), entry);
        let push = include_str!("../shaders/cg_push.wgsl");
        Self {
            begin: pair(include_str!("../shaders/cg_begin.wgsl"), "cg_begin"),
            warm: pair(push, "cg_warm"),
            residual: pair(include_str!("../shaders/cg_residual.wgsl"), "cg_residual"),
            start: alone(include_str!("../shaders/cg_start.wgsl"), "cg_start"),
            push: pair(push, "cg_push"),
            rate: pair(include_str!("../shaders/cg_rate.wgsl"), "cg_rate"),
            alpha: alone(include_str!("../shaders/cg_alpha.wgsl"), "cg_alpha"),
            step: pair(include_str!("../shaders/cg_step.wgsl"), "cg_step"),
            control: alone(include_str!("../shaders/cg_control.wgsl"), "cg_control"),
            direction: pair(include_str!("../shaders/cg_direction.wgsl"), "cg_direction"),
            end: pair(include_str!("../shaders/cg_end.wgsl"), "cg_end"),
            layout: alone(
                include_str!("../shaders/coarse_layout.wgsl"),
                "coarse_layout",
            ),
            assign: pair(
                include_str!("../shaders/coarse_assign.wgsl"),
                "coarse_assign",
            ),
            colour: pair(
                include_str!("../shaders/coarse_colour.wgsl"),
                "coarse_colour",
            ),
            product: pair(
                include_str!("../shaders/coarse_product.wgsl"),
                "coarse_product",
            ),
            rows: pair(include_str!("../shaders/coarse_rows.wgsl"), "coarse_rows"),
            band: alone(include_str!("../shaders/coarse_band.wgsl"), "coarse_band"),
            factor: alone(
                include_str!("../shaders/coarse_factor.wgsl"),
                "coarse_factor",
            ),
            restrict: pair(
                include_str!("../shaders/coarse_restrict.wgsl"),
                "coarse_restrict",
            ),
            solve: alone(include_str!("../shaders/coarse_solve.wgsl"), "coarse_solve"),
            prolong: pair(
                include_str!("../shaders/coarse_prolong.wgsl"),
                "coarse_prolong",
            ),
            first: alone(include_str!("../shaders/coarse_first.wgsl"), "coarse_first"),
        }
    }

    /// Record the density solve `solve` (its counts and workgroups filled in): the start
    /// (warm start, first residual; when deflating, the coarse space and the deflated first
    /// step; the first test), `recorded` iterations (at most the cap) dispatched with the
    /// sizes the test before each wrote, the last direction pass (a take-back of the last
    /// iteration) and the end, which stores p/ρ0 in `b.pressure`; then whether the solve
    /// would have gone on is copied into the control block (`den_unfinished`).
    pub fn record(
        &self,
        gpu: &Gpu,
        encoder: &mut wgpu::CommandEncoder,
        b: &StepBuffers,
        cg: &CgBuffers,
        solve: &CgSolve,
        recorded: u32,
    ) {
        gpu.queue
            .write_buffer(&cg.solve, 0, bytemuck::bytes_of(solve));
        // Slots no test writes in this solve dispatch nothing; the state starts at zero (no
        // iterations, no coarse space).
        for buffer in &cg.dispatch {
            encoder.clear_buffer(buffer, 0, None);
        }
        encoder.clear_buffer(&cg.state, 0, None);
        let deflate = solve.coarse_cell > 0.0;
        let (groups64, partials) = (solve.groups, solve.partials);
        let cells = [b.params, b.position, b.sorted, b.starts];
        fn and<'a>(
            cells: &[&'a wgpu::Buffer],
            extra: &[&'a wgpu::Buffer],
        ) -> Vec<&'a wgpu::Buffer> {
            [cells, extra].concat()
        }
        let bind = |pipeline: &wgpu::ComputePipeline, buffers: &[&wgpu::Buffer]| {
            gpu.bind(pipeline, buffers)
        };
        let begin = bind(
            &self.begin,
            &[
                b.params,
                &cg.solve,
                b.clock,
                b.densities,
                b.flux,
                b.pressure,
                &cg.total,
            ],
        );
        let warm = bind(
            &self.warm,
            &and(&cells, &[b.densities, &cg.total, b.velocity]),
        );
        let residual = bind(
            &self.residual,
            &[
                b.params,
                &cg.solve,
                b.clock,
                b.position,
                b.sorted,
                b.starts,
                b.densities,
                b.flux,
                b.velocity,
                &cg.residual,
                &cg.active,
                &cg.direction,
                &cg.partials,
                &cg.bounds,
            ],
        );
        let test = |pipeline: &wgpu::ComputePipeline, writes: usize| {
            bind(
                pipeline,
                &[
                    &cg.solve,
                    b.clock,
                    &cg.partials,
                    &cg.state,
                    b.control,
                    &cg.dispatch[writes],
                ],
            )
        };
        let start = test(&self.start, 0);
        let push = bind(
            &self.push,
            &and(&cells, &[b.densities, &cg.direction, &cg.change]),
        );
        let rate = bind(
            &self.rate,
            &and(
                &cells,
                &[
                    b.densities,
                    &cg.change,
                    &cg.direction,
                    &cg.active,
                    &cg.rate,
                    &cg.partials,
                    &cg.residual,
                ],
            ),
        );
        let alpha = bind(&self.alpha, &[&cg.solve, b.clock, &cg.partials, &cg.state]);
        let step = bind(
            &self.step,
            &[
                b.params,
                b.clock,
                &cg.state,
                b.densities,
                &cg.direction,
                &cg.change,
                &cg.rate,
                &cg.active,
                &cg.total,
                b.velocity,
                &cg.residual,
                &cg.partials,
            ],
        );
        // `controls[p]` writes the sizes of the iterations of parity p.
        let controls = [test(&self.control, 0), test(&self.control, 1)];
        let direction = bind(
            &self.direction,
            &[
                b.params,
                b.clock,
                &cg.state,
                b.densities,
                &cg.residual,
                &cg.active,
                &cg.change,
                &cg.total,
                b.velocity,
                &cg.direction,
                &cg.solve,
                &cg.aggregate,
                &cg.y,
            ],
        );
        let end = bind(
            &self.end,
            &[b.params, &cg.solve, b.clock, &cg.total, b.pressure],
        );
        let restrict = |mode: usize| {
            bind(
                &self.restrict,
                &[
                    b.params,
                    &cg.restrictions[mode],
                    b.clock,
                    &cg.coarse,
                    b.position,
                    b.sorted,
                    b.starts,
                    b.densities,
                    &cg.aggregate,
                    &cg.aw,
                    &cg.active,
                    &cg.residual,
                    &cg.y,
                ],
            )
        };
        let restrict_aw = restrict(1);
        let coarse_solve = bind(&self.solve, &[&cg.coarse, &cg.band, &cg.y]);

        let mut pass = encoder.begin_compute_pass(&Default::default());
        let run = |pass: &mut wgpu::ComputePass,
                   pipeline: &wgpu::ComputePipeline,
                   group: &wgpu::BindGroup,
                   count: u32| {
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, group, &[]);
            pass.dispatch_workgroups(count, 1, 1);
        };
        let indirect = |pass: &mut wgpu::ComputePass,
                        pipeline: &wgpu::ComputePipeline,
                        group: &wgpu::BindGroup,
                        sizes: &wgpu::Buffer,
                        at: u64| {
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, group, &[]);
            pass.dispatch_workgroups_indirect(sizes, at);
        };
        run(&mut pass, &self.begin, &begin, groups64);
        if solve.warm == 1 {
            run(&mut pass, &self.warm, &warm, groups64);
        }
        run(&mut pass, &self.residual, &residual, partials);
        if deflate {
            let layout = bind(
                &self.layout,
                &[
                    &cg.solve,
                    &cg.bounds,
                    &cg.coarse,
                    &cg.state,
                    &cg.coarse_sizes,
                ],
            );
            run(&mut pass, &self.layout, &layout, 1);
            let assign = bind(
                &self.assign,
                &[b.params, &cg.coarse, b.position, &cg.active, &cg.aggregate],
            );
            run(&mut pass, &self.assign, &assign, groups64);
            // A W_k 1 for the four colours, with the solve's own products.
            for colour in &cg.colours {
                let indicator = bind(
                    &self.colour,
                    &[b.params, colour, &cg.coarse, &cg.aggregate, &cg.direction],
                );
                run(&mut pass, &self.colour, &indicator, groups64);
                run(&mut pass, &self.push, &push, groups64);
                let product = bind(
                    &self.product,
                    &[
                        b.params,
                        colour,
                        b.clock,
                        b.position,
                        b.sorted,
                        b.starts,
                        b.densities,
                        &cg.change,
                        &cg.active,
                        &cg.aw,
                    ],
                );
                run(&mut pass, &self.product, &product, groups64);
            }
            let sizes = &cg.coarse_sizes;
            let rows = bind(
                &self.rows,
                &[
                    b.params,
                    &cg.coarse,
                    b.position,
                    b.sorted,
                    b.starts,
                    &cg.aggregate,
                    &cg.aw,
                    &cg.rows,
                ],
            );
            indirect(&mut pass, &self.rows, &rows, sizes, 0);
            let band = bind(&self.band, &[&cg.coarse, &cg.rows, &cg.band, &cg.diagonal]);
            indirect(&mut pass, &self.band, &band, sizes, 0);
            let factor = bind(&self.factor, &[&cg.coarse, &cg.diagonal, &cg.band]);
            run(&mut pass, &self.factor, &factor, 1);
            // The deflated start: a line search along W E⁻¹ Wᵀ(a e).
            indirect(&mut pass, &self.restrict, &restrict(0), sizes, 0);
            run(&mut pass, &self.solve, &coarse_solve, 1);
            let prolong = bind(
                &self.prolong,
                &[b.params, &cg.aggregate, &cg.y, &cg.direction],
            );
            run(&mut pass, &self.prolong, &prolong, groups64);
            run(&mut pass, &self.push, &push, groups64);
            run(&mut pass, &self.rate, &rate, partials);
            let first = bind(&self.first, &[&cg.solve, b.clock, &cg.partials, &cg.state]);
            run(&mut pass, &self.first, &first, 1);
            run(&mut pass, &self.step, &step, partials);
            // The first direction, deflated.
            indirect(&mut pass, &self.restrict, &restrict_aw, sizes, 0);
            run(&mut pass, &self.solve, &coarse_solve, 1);
            run(&mut pass, &self.direction, &direction, groups64);
        }
        run(&mut pass, &self.start, &start, 1);
        // Iteration k reads the slot k/2 of the buffer of its parity: first what the
        // direction of iteration k − 1 needs, then its own five passes.
        for k in 0..=recorded as usize {
            let (sizes, at) = (&cg.dispatch[k % 2], (k / 2) as u64 * SLOT);
            if k > 0 {
                indirect(&mut pass, &self.restrict, &restrict_aw, sizes, at);
                indirect(&mut pass, &self.solve, &coarse_solve, sizes, at + 12);
                indirect(&mut pass, &self.direction, &direction, sizes, at + 24);
            }
            if k == recorded as usize {
                break;
            }
            indirect(&mut pass, &self.push, &push, sizes, at + 36);
            indirect(&mut pass, &self.rate, &rate, sizes, at + 48);
            indirect(&mut pass, &self.alpha, &alpha, sizes, at + 60);
            indirect(&mut pass, &self.step, &step, sizes, at + 72);
            indirect(
                &mut pass,
                &self.control,
                &controls[(k + 1) % 2],
                sizes,
                at + 84,
            );
        }
        run(&mut pass, &self.end, &end, groups64);
        drop(pass);
        // The push pass's workgroups of iteration `recorded`, which its test wrote.
        let r = recorded as u64;
        encoder.copy_buffer_to_buffer(
            &cg.dispatch[(r % 2) as usize],
            r / 2 * SLOT + 36,
            b.control,
            std::mem::offset_of!(Control, den_unfinished) as u64,
            4,
        );
    }
}
