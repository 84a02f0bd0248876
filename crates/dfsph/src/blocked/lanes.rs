//! The lane kernels: every pair pass over the blocks written once over a slot's 16 lanes
//! (`[f32; 16]`), for the `fma` and `portable` paths of [`crate::simd`]. Each gathers a slot's
//! neighbour values with 16 plain loads, then does the slot's arithmetic lane by lane without
//! branches, which the compiler vectorises; `FUSED` selects fused multiply-adds for the
//! pressure solve's sums (the AVX-512 kernels' rounding), and the code is compiled for AVX2
//! and FMA where [`crate::simd::lane_kernel`] runs it on the `fma` path.

use std::ops::Range;

use glam::Vec2;

use super::layout::{BlockedPairs, FluidSums, ResidualTerms, SlotIndex, LANES};
use crate::kernel::Kernel;
use crate::simd::mul_add;

/// [`super::BlockWriter::fill_block`]'s pair loop on the lane path, slot by slot: each lane's
/// neighbour position, `∇W` (written to `gx`, `gy`; zero past the lane's list) and the
/// density sums, in list order with [`Kernel::w_and_grad`]'s operations, so every path
/// gives the same bits. `FUSED` only selects how the code is compiled ([`crate::simd::lane_kernel`]).
///
/// # Safety
/// `idx`, `gx` and `gy` must hold `width` whole slots, and every index be below `pos.len()`.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(super) unsafe fn lane_fluid_sums<I: SlotIndex, const FUSED: bool>(
    idx: &[I],
    first: usize,
    width: usize,
    gx: &mut [f32],
    gy: &mut [f32],
    lens: &[u32; LANES],
    xi: &[f32; LANES],
    yi: &[f32; LANES],
    pos: &[Vec2],
    kernel: &Kernel,
    volume: f32,
    start: f32,
) -> FluidSums {
    let mut sums = FluidSums {
        density: [start; LANES],
        ..Default::default()
    };
    let (mut rx, mut ry) = ([0.0f32; LANES], [0.0f32; LANES]);
    let (mut w, mut wx, mut wy) = ([0.0f32; LANES], [0.0f32; LANES], [0.0f32; LANES]);
    for s in 0..width {
        let k = s * LANES;
        let xj = gather(pos, first, &idx[k..k + LANES]);
        for l in 0..LANES {
            // `Vec2::new(x_i, y_i) − x_j`.
            (rx[l], ry[l]) = (xi[l] - xj[l].x, yi[l] - xj[l].y);
        }
        kernel.w_and_grad_lanes(&rx, &ry, &mut w, &mut wx, &mut wy);
        let (gx, gy) = (&mut gx[k..k + LANES], &mut gy[k..k + LANES]);
        for l in 0..LANES {
            let pair = (s as u32) < lens[l];
            let (vgx, vgy) = (volume * wx[l], volume * wy[l]);
            if pair {
                sums.density[l] += volume * w[l];
                sums.grad_x[l] += vgx;
                sums.grad_y[l] += vgy;
                // `length_squared`: x·x + y·y.
                sums.grad_sq[l] += vgx * vgx + vgy * vgy;
            }
            (gx[l], gy[l]) = if pair { (wx[l], wy[l]) } else { (0.0, 0.0) };
        }
    }
    sums
}

/// [`BlockedPairs::advected_kernel_sums`]'s lane kernel: per lane, from `start`, `V·W` of
/// every neighbour within the support at the advected positions, slot by slot in list order
/// with the scalar expressions' roundings (padding, the particle itself, skipped), so every
/// path gives the same bits. `FUSED` only selects how the code is compiled.
///
/// # Safety
/// `idx` must hold whole slots, and every index be below `pos.len()` and `vel.len()`.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(super) unsafe fn lane_advected_kernel_sums<I: SlotIndex, const FUSED: bool>(
    idx: &[I],
    first: usize,
    xi: &[Vec2; LANES],
    pos: &[Vec2],
    vel: &[Vec2],
    dt: f32,
    kernel: &Kernel,
    volume: f32,
    start: f32,
) -> [f32; LANES] {
    let support2 = kernel.support() * kernel.support();
    let mut sums = [start; LANES];
    let (mut r, mut w) = ([0.0f32; LANES], [0.0f32; LANES]);
    let mut near = [false; LANES];
    for slot in idx.chunks_exact(LANES) {
        let (pj, vj) = (gather(pos, first, slot), gather(vel, first, slot));
        for l in 0..LANES {
            // `x_j + Δt·v_j`, then `(x̃_i − x̃_j).length_squared()`.
            let (xj, yj) = (pj[l].x + dt * vj[l].x, pj[l].y + dt * vj[l].y);
            let (dx, dy) = (xi[l].x - xj, xi[l].y - yj);
            let r2 = dx * dx + dy * dy;
            // Padding repeats the particle itself, which is never its own neighbour.
            near[l] = r2 < support2 && slot[l].absolute(first) != first + l;
            r[l] = r2.sqrt();
        }
        kernel.w_lanes(&r, &mut w);
        for l in 0..LANES {
            if near[l] {
                sums[l] += volume * w[l];
            }
        }
    }
    sums
}

/// [`BlockedPairs::viscosity_sums`]' lane kernel: XSPH and (with `laplacian`) Laplacian sums
/// per lane, slot by slot in list order with the scalar expressions' roundings (padding, the
/// particle itself, skipped), so every path gives the same bits. `FUSED` only selects how the
/// code is compiled.
///
/// # Safety
/// The three slices must hold whole slots, and every index be below `pos.len()` and
/// `vel.len()`.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(super) unsafe fn lane_viscosity_sums<I: SlotIndex, const FUSED: bool>(
    idx: &[I],
    first: usize,
    gx: &[f32],
    gy: &[f32],
    xi: &[Vec2; LANES],
    vi: &[Vec2; LANES],
    pos: &[Vec2],
    vel: &[Vec2],
    kernel: &Kernel,
    eps2: f32,
    laplacian: bool,
) -> ([Vec2; LANES], [Vec2; LANES]) {
    let (mut sx, mut sy) = ([0.0f32; LANES], [0.0f32; LANES]);
    let (mut lx, mut ly) = ([0.0f32; LANES], [0.0f32; LANES]);
    let (mut r, mut w) = ([0.0f32; LANES], [0.0f32; LANES]);
    let (mut x, mut y) = ([0.0f32; LANES], [0.0f32; LANES]);
    let (mut u, mut v) = ([0.0f32; LANES], [0.0f32; LANES]);
    for ((slot, gx), gy) in idx
        .chunks_exact(LANES)
        .zip(gx.chunks_exact(LANES))
        .zip(gy.chunks_exact(LANES))
    {
        let (pj, vj) = (gather(pos, first, slot), gather(vel, first, slot));
        for l in 0..LANES {
            (x[l], y[l]) = (xi[l].x - pj[l].x, xi[l].y - pj[l].y);
            (u[l], v[l]) = (vi[l].x - vj[l].x, vi[l].y - vj[l].y);
            // `x_ij.length()`.
            r[l] = (x[l] * x[l] + y[l] * y[l]).sqrt();
        }
        kernel.w_lanes(&r, &mut w);
        for l in 0..LANES {
            // Padding repeats the particle itself, which is never its own neighbour.
            let pair = slot[l].absolute(first) != first + l;
            if pair {
                sx[l] -= u[l] * w[l];
                sy[l] -= v[l] * w[l];
            }
            if laplacian && pair {
                // `∇W_ij · (v_ij·x_ij / (|x_ij|² + ε²))`.
                let ratio = (u[l] * x[l] + v[l] * y[l]) / (x[l] * x[l] + y[l] * y[l] + eps2);
                lx[l] += gx[l] * ratio;
                ly[l] += gy[l] * ratio;
            }
        }
    }
    let mut out = ([Vec2::ZERO; LANES], [Vec2::ZERO; LANES]);
    for l in 0..LANES {
        out.0[l] = Vec2::new(sx[l], sy[l]);
        out.1[l] = Vec2::new(lx[l], ly[l]);
    }
    out
}

/// [`BlockedPairs::residual_block`]'s lane kernel: the pair loop of
/// [`lane_velocity_gradient_dots`], then the per-particle terms lane by lane (the AVX-512
/// kernel's operations in its order).
///
/// # Safety
/// The three slices must hold whole slots, every index be below `vel.len()`, `vel` and the
/// arrays of `terms` must hold the `delta.len()` (≤ 16) particles from `first` on, and `rate`
/// as many entries as `delta`.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(super) unsafe fn lane_residual_block<I: SlotIndex, const FUSED: bool>(
    idx: &[I],
    gx: &[f32],
    gy: &[f32],
    vel: &[Vec2],
    first: usize,
    terms: &ResidualTerms,
    delta: &mut [f32],
    rate: &mut [f32],
    errors: &mut [f32; LANES],
) {
    let fluid = lane_velocity_gradient_dots::<I, FUSED>(idx, first, gx, gy, vel);
    let particles = first..first + delta.len();
    let (vel, grad_sum) = (&vel[particles.clone()], &terms.grad_sum[particles.clone()]);
    let (flux, source) = (
        &terms.wall_flux[particles.clone()],
        &terms.source[particles.clone()],
    );
    let factor = &terms.factor[particles];
    *errors = [0.0; LANES];
    for l in 0..delta.len() {
        // r_i = v_i·g_i − V·Σ_j v_j·∇W_ij − f_i, e_i = max(s_i + c·r_i, 0), Δκ_i = e_i·a_i·c'.
        let r = vel[l].dot(grad_sum[l]) - terms.volume * fluid[l] - flux[l];
        let e = (source[l] + terms.rate_scale * r).max(0.0);
        rate[l] = r;
        delta[l] = e * factor[l] * terms.increment_scale;
        errors[l] = e;
    }
}

/// [`BlockedPairs::apply_block`]'s lane kernel: the pair loop of
/// [`lane_weighted_gradient_sums`], then `Δv` and the running total lane by lane (the AVX-512
/// kernel's operations in its order).
///
/// # Safety
/// The three slices must hold whole slots, every index be below `kappa.len()`, `kappa` and
/// `grad_sum` must hold the `vel.len()` (≤ 16) particles from `first` on, and `total`, when
/// given, as many entries as `vel`.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(super) unsafe fn lane_apply_block<I: SlotIndex, const FUSED: bool>(
    idx: &[I],
    gx: &[f32],
    gy: &[f32],
    kappa: &[f32],
    first: usize,
    grad_sum: &[Vec2],
    volume: f32,
    vel: &mut [Vec2],
    total: Option<&mut [f32]>,
) {
    let (sx, sy) = lane_weighted_gradient_sums::<I, FUSED>(idx, first, gx, gy, kappa);
    let particles = first..first + vel.len();
    let (ki, gi) = (&kappa[particles.clone()], &grad_sum[particles]);
    for l in 0..vel.len() {
        // Δv_i = −(κ_i·g_i + V·Σ_j κ_j ∇W_ij).
        vel[l] += -(ki[l] * gi[l] + volume * Vec2::new(sx[l], sy[l]));
    }
    if let Some(t) = total {
        for (t, k) in t.iter_mut().zip(ki) {
            *t += k;
        }
    }
}

/// [`BlockedPairs::residual_blocks`]' lane kernel: [`lane_residual_block`] block by block,
/// with `idx` every block's indices.
///
/// # Safety
/// As [`lane_residual_block`] for each block: `idx` must be `pairs`' indices, every index
/// below `vel.len()`, `vel` and the arrays of `terms` must hold all particles, and `delta`,
/// `rate` and `errors` those of `blocks`.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(super) unsafe fn lane_residual_blocks<I: SlotIndex, const FUSED: bool>(
    pairs: &BlockedPairs,
    idx: &[I],
    blocks: Range<usize>,
    vel: &[Vec2],
    terms: &ResidualTerms,
    delta: &mut [f32],
    rate: &mut [f32],
    errors: &mut [[f32; LANES]],
) {
    let lanes = delta.chunks_mut(LANES).zip(rate.chunks_mut(LANES));
    for ((b, (d, r)), e) in blocks.zip(lanes).zip(errors) {
        let (idx, gx, gy) = pairs.block_of(idx, b);
        lane_residual_block::<I, FUSED>(idx, gx, gy, vel, b * LANES, terms, d, r, e);
    }
}

/// [`BlockedPairs::apply_blocks`]' lane kernel: [`lane_apply_block`] block by block, with
/// `idx` every block's indices.
///
/// # Safety
/// As [`lane_apply_block`] for each block: `idx` must be `pairs`' indices, every index below
/// `kappa.len()`, `kappa` and `grad_sum` must hold all particles, and `vel` and `total`,
/// when given, those of `blocks`.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(super) unsafe fn lane_apply_blocks<I: SlotIndex, const FUSED: bool>(
    pairs: &BlockedPairs,
    idx: &[I],
    blocks: Range<usize>,
    volume: f32,
    kappa: &[f32],
    grad_sum: &[Vec2],
    vel: &mut [Vec2],
    mut total: Option<&mut [f32]>,
) {
    for (k, (b, v)) in blocks.zip(vel.chunks_mut(LANES)).enumerate() {
        let (idx, gx, gy) = pairs.block_of(idx, b);
        let t = total
            .as_deref_mut()
            .map(|t| &mut t[k * LANES..k * LANES + v.len()]);
        lane_apply_block::<I, FUSED>(idx, gx, gy, kappa, b * LANES, grad_sum, volume, v, t);
    }
}

/// The 16 values `values[j]` of the neighbours `slot` of the block starting at `first`:
/// the lane kernels' gather, as 16 loads.
///
/// # Safety
/// Every index in `slot` must be below `values.len()`.
#[inline(always)]
unsafe fn gather<T: Copy + Default, I: SlotIndex>(
    values: &[T],
    first: usize,
    slot: &[I],
) -> [T; LANES] {
    // `origin(first)` is 0 or `first`, and `first` is an index of the block's own first
    // particle, so below `values.len()`.
    let base = values.as_ptr().add(I::origin(first));
    // A plain loop, not `array::from_fn`: that is not inlined into `with_fma`'s kernels.
    let mut out = [T::default(); LANES];
    for (o, j) in out.iter_mut().zip(slot) {
        *o = *base.offset(j.offset());
    }
    out
}

/// `(Σ_j a_j ∂W_ij/∂x, Σ_j b_j ∂W_ij/∂y)` per lane, with `(a_j, b_j) = parts(values[j])`,
/// slot by slot in list order, with fused multiply-adds where `FUSED`: the pair loop of the
/// pressure solve's two passes (the AVX-512 kernels' sums, in their order).
///
/// # Safety
/// The three slices must hold whole slots, and every index must be below `values.len()`.
#[inline(always)]
unsafe fn lane_gradient_sums<I: SlotIndex, T: Copy + Default, const FUSED: bool>(
    idx: &[I],
    first: usize,
    gx: &[f32],
    gy: &[f32],
    values: &[T],
    parts: impl Fn(T) -> (f32, f32),
) -> ([f32; LANES], [f32; LANES]) {
    let mut ax = [0.0f32; LANES];
    let mut ay = [0.0f32; LANES];
    for ((slot, x), y) in idx
        .chunks_exact(LANES)
        .zip(gx.chunks_exact(LANES))
        .zip(gy.chunks_exact(LANES))
    {
        let vj = gather(values, first, slot);
        for l in 0..LANES {
            let (a, b) = parts(vj[l]);
            ax[l] = mul_add::<FUSED>(a, x[l], ax[l]);
            ay[l] = mul_add::<FUSED>(b, y[l], ay[l]);
        }
    }
    (ax, ay)
}

/// `Σ_j s_j ∇W_ij` per lane, x and y: the lane kernel of
/// [`BlockedPairs::weighted_gradient_sums`].
///
/// # Safety
/// The three slices must hold whole slots, and every index must be below `s.len()`.
#[inline(always)]
pub(super) unsafe fn lane_weighted_gradient_sums<I: SlotIndex, const FUSED: bool>(
    idx: &[I],
    first: usize,
    gx: &[f32],
    gy: &[f32],
    s: &[f32],
) -> ([f32; LANES], [f32; LANES]) {
    lane_gradient_sums::<I, f32, FUSED>(idx, first, gx, gy, s, |sj| (sj, sj))
}

/// `Σ_j v_j·∇W_ij` per lane, x and y summed apart, then added: the lane kernel of
/// [`BlockedPairs::velocity_gradient_dots`] (the AVX-512 kernel's order).
///
/// # Safety
/// The three slices must hold whole slots, and every index must be below `v.len()`.
#[inline(always)]
pub(super) unsafe fn lane_velocity_gradient_dots<I: SlotIndex, const FUSED: bool>(
    idx: &[I],
    first: usize,
    gx: &[f32],
    gy: &[f32],
    v: &[Vec2],
) -> [f32; LANES] {
    let (ax, ay) = lane_gradient_sums::<I, Vec2, FUSED>(idx, first, gx, gy, v, |vj| (vj.x, vj.y));
    std::array::from_fn(|l| ax[l] + ay[l])
}
