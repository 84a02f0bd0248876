//! The uniform neighbour grid on the GPU: a counting sort of points by cell.
//!
//! Four passes: each point's cell key and its rank among its cell's arrivals (an atomic
//! counter per cell, in no fixed order); an exclusive prefix sum of the counts (one
//! workgroup); the scatter of every point to its cell's slots; and a sort of each cell's few
//! points by index. The last pass makes the order that of a stable counting sort, the CPU's
//! (`dfsph::neighbors::Grid`), so that sums over a cell run in the same order on every run.

use crate::device::{Gpu, GpuError};

/// A dense grid of square cells over a box, as the shaders read it (`struct Grid`).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct GridLayout {
    /// The box's lower-left corner, m.
    pub origin: [f32; 2],
    /// 1 / the cell size, 1/m.
    pub inv_cell: f32,
    /// Points in the grid.
    pub n: u32,
    /// Cells along x and y.
    pub nx: u32,
    pub ny: u32,
    /// nx·ny.
    pub cells: u32,
    pad: u32,
}

impl GridLayout {
    /// Cells of side `cell` (m) over the bounding box of `points` (a point outside the box
    /// later falls into the nearest cell), for `n` points.
    pub fn covering(points: &[[f32; 2]], cell: f32, n: usize) -> Self {
        let (mut lo, mut hi) = ([f32::INFINITY; 2], [f32::NEG_INFINITY; 2]);
        for p in points {
            for k in 0..2 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        if points.is_empty() {
            (lo, hi) = ([0.0; 2], [0.0; 2]);
        }
        let count = |k: usize| (((hi[k] - lo[k]) / cell).floor() as u32 + 1).max(1);
        let (nx, ny) = (count(0), count(1));
        Self {
            origin: lo,
            inv_cell: 1.0 / cell,
            n: n as u32,
            nx,
            ny,
            cells: nx * ny,
            pad: 0,
        }
    }

    /// The same cells for `n` other points.
    pub fn for_points(self, n: usize) -> Self {
        Self {
            n: n as u32,
            ..self
        }
    }
}

/// The grid's pipelines, built once per device.
pub struct GridPass {
    keys: wgpu::ComputePipeline,
    scan: wgpu::ComputePipeline,
    scatter: wgpu::ComputePipeline,
    cell_sort: wgpu::ComputePipeline,
}

/// Points sorted by cell, on the device: `sorted[starts[c]..starts[c + 1]]` are the indices
/// of the points in cell `c`, in increasing order.
pub struct SortedGrid {
    pub layout: GridLayout,
    pub uniform: wgpu::Buffer,
    pub positions: wgpu::Buffer,
    pub starts: wgpu::Buffer,
    pub sorted: wgpu::Buffer,
}

/// Workgroups of `size` invocations covering `n` items.
pub(crate) fn groups(n: u32, size: u32) -> u32 {
    n.div_ceil(size).max(1)
}

impl GridPass {
    pub fn new(gpu: &Gpu) -> Self {
        // Each pass is the grid's prelude (`struct Grid`), then its own body.
        let pipeline = |body: &str, entry| {
            let source = format!("{}\n{body}", include_str!("shaders/grid_prelude.wgsl"));
            gpu.pipeline(&source, entry)
        };
        Self {
            keys: pipeline(include_str!("shaders/grid_keys.wgsl"), "grid_keys"),
            scan: pipeline(include_str!("shaders/grid_scan.wgsl"), "grid_scan"),
            scatter: pipeline(include_str!("shaders/grid_scatter.wgsl"), "grid_scatter"),
            cell_sort: pipeline(
                include_str!("shaders/grid_cell_sort.wgsl"),
                "grid_cell_sort",
            ),
        }
    }

    /// Sort `points` into `layout`'s cells on the device.
    pub fn build(&self, gpu: &Gpu, layout: GridLayout, points: &[[f32; 2]]) -> SortedGrid {
        assert_eq!(layout.n as usize, points.len(), "the layout's point count");
        let positions = gpu.upload("positions", points);
        let buffers = GridBuffers::new(gpu, points.len(), layout.cells as usize);
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        self.record(gpu, &mut encoder, &layout, &positions, &buffers);
        gpu.queue.submit([encoder.finish()]);
        SortedGrid {
            layout,
            uniform: buffers.uniform,
            positions,
            starts: buffers.starts,
            sorted: buffers.sorted,
        }
    }

    /// Record the sort of the first `layout.n` points of `positions` (on the device) into
    /// `buffers`, which must hold that many points and `layout.cells` cells. The layout is
    /// written into `buffers.uniform` when the queue next submits.
    pub(crate) fn record(
        &self,
        gpu: &Gpu,
        encoder: &mut wgpu::CommandEncoder,
        layout: &GridLayout,
        positions: &wgpu::Buffer,
        buffers: &GridBuffers,
    ) {
        let (n, cells) = (layout.n, layout.cells);
        assert!(
            n as usize <= buffers.points && cells as usize <= buffers.cells,
            "the grid's buffers hold the points and cells"
        );
        gpu.queue
            .write_buffer(&buffers.uniform, 0, bytemuck::bytes_of(layout));
        encoder.clear_buffer(&buffers.counts, 0, None);
        let GridBuffers {
            uniform,
            keys,
            counts,
            rank,
            starts,
            sorted,
            ..
        } = buffers;
        let mut pass = encoder.begin_compute_pass(&Default::default());
        let steps: [(&wgpu::ComputePipeline, Vec<&wgpu::Buffer>, u32); 4] = [
            (
                &self.keys,
                vec![uniform, positions, keys, counts, rank],
                groups(n, 64),
            ),
            (&self.scan, vec![uniform, counts, starts], 1),
            (
                &self.scatter,
                vec![uniform, keys, rank, starts, sorted],
                groups(n, 64),
            ),
            (
                &self.cell_sort,
                vec![uniform, starts, sorted],
                groups(cells, 64),
            ),
        ];
        for (pipeline, buffers, workgroups) in steps {
            let group = gpu.bind(pipeline, &buffers);
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, &group, &[]);
            pass.dispatch_workgroups(workgroups, 1, 1);
        }
    }
}

/// The buffers of one grid on the device, kept from build to build (grown when a build
/// needs more).
pub(crate) struct GridBuffers {
    /// Points and cells the buffers hold.
    points: usize,
    cells: usize,
    /// The layout (`struct Grid` of the shaders).
    pub uniform: wgpu::Buffer,
    keys: wgpu::Buffer,
    counts: wgpu::Buffer,
    rank: wgpu::Buffer,
    /// `starts[c]..starts[c + 1]` are cell c's slots in `sorted`.
    pub starts: wgpu::Buffer,
    pub sorted: wgpu::Buffer,
}

impl GridBuffers {
    pub fn new(gpu: &Gpu, points: usize, cells: usize) -> Self {
        let uniform = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("grid"),
            size: std::mem::size_of::<GridLayout>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Self {
            points,
            cells,
            uniform,
            keys: gpu.zeroed::<u32>("keys", points),
            counts: gpu.zeroed::<u32>("counts", cells),
            rank: gpu.zeroed::<u32>("rank", points),
            starts: gpu.zeroed::<u32>("starts", cells + 1),
            sorted: gpu.zeroed::<u32>("sorted", points),
        }
    }

    /// Grow the buffers to hold `points` points and `cells` cells (with room to spare, so
    /// that a growing pour does not reallocate every step).
    pub fn reserve(&mut self, gpu: &Gpu, points: usize, cells: usize) {
        if points > self.points || cells > self.cells {
            let grow = |have: usize, need: usize| if need > have { need + need / 4 } else { have };
            *self = Self::new(gpu, grow(self.points, points), grow(self.cells, cells));
        }
    }
}

impl SortedGrid {
    /// The sorted indices and the cells' starts, read back (for tests and checks).
    pub fn read(&self, gpu: &Gpu) -> Result<(Vec<u32>, Vec<u32>), GpuError> {
        Ok((
            gpu.read(&self.sorted, self.layout.n as usize)?,
            gpu.read(&self.starts, self.layout.cells as usize + 1)?,
        ))
    }
}
