//! Reductions on the device (a sum, a maximum, a dot product), each to one value that stays
//! on the device: the solves' stopping rules and the time step read them there, with no
//! round trip to the host inside a step. A fixed tree of 256-value workgroups, level after
//! level, so the same input gives the same bits on every run.

use crate::device::Gpu;

/// What a reduction computes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fold {
    Sum,
    Max,
    /// Σ a_i·b_i.
    Dot,
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Params {
    n: u32,
    op: u32,
    pad: [u32; 2],
}

/// The reduction's pipeline.
pub struct Reductions {
    level: wgpu::ComputePipeline,
}

/// Workgroups per level: 256 values each.
const WIDTH: usize = 256;

impl Reductions {
    pub fn new(gpu: &Gpu) -> Self {
        Self {
            level: gpu.pipeline(include_str!("shaders/reduce.wgsl"), "reduce_level"),
        }
    }

    /// Fold the first `n` values of `a` (and of `b`, for [`Fold::Dot`]) into a one-value
    /// buffer. A maximum of no values is −3.4·10³⁸, a sum 0.
    pub fn fold(
        &self,
        gpu: &Gpu,
        fold: Fold,
        a: &wgpu::Buffer,
        b: Option<&wgpu::Buffer>,
        n: usize,
    ) -> wgpu::Buffer {
        assert!(
            (fold == Fold::Dot) == b.is_some(),
            "a dot product takes two inputs, the others one"
        );
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        let mut input = (a.clone(), b.unwrap_or(a).clone(), n, fold);
        loop {
            let groups = input.2.div_ceil(WIDTH).max(1);
            let partial = gpu.zeroed::<f32>("partial", groups);
            let op = match input.3 {
                Fold::Sum => 0,
                Fold::Max => 1,
                Fold::Dot => 2,
            };
            let params = gpu.uniform(
                "reduce",
                &Params {
                    n: input.2 as u32,
                    op,
                    pad: [0; 2],
                },
            );
            let group = gpu.bind(&self.level, &[&params, &input.0, &input.1, &partial]);
            {
                let mut pass = encoder.begin_compute_pass(&Default::default());
                pass.set_pipeline(&self.level);
                pass.set_bind_group(0, &group, &[]);
                // Past 65,535 workgroups along x, the rest go along y.
                let x = groups.min(65_535);
                pass.dispatch_workgroups(x as u32, groups.div_ceil(x) as u32, 1);
            }
            let next = if input.3 == Fold::Max {
                Fold::Max
            } else {
                Fold::Sum
            };
            input = (partial.clone(), partial, groups, next);
            if groups == 1 {
                break;
            }
        }
        gpu.queue.submit([encoder.finish()]);
        input.0
    }
}
