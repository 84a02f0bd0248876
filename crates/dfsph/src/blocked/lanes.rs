//! The lane kernels: every pair pass over the blocks over a slot's 16 lanes, for the `fma`
//! and `portable` paths of [`crate::simd`]. Each reads a slot's neighbour values with 16
//! plain loads and hands them to the pass's formula (`formulas.rs`, over
//! [`crate::simd::wide::Lanes`], whose operations are loops the compiler vectorises); `FUSED`
//! selects fused multiply-adds for the pressure solve's sums (the AVX-512 kernels'
//! rounding), and the code is compiled for AVX2 and FMA where [`crate::simd::lane_kernel`]
//! runs it on the `fma` path.

use std::ops::Range;

use glam::Vec2;

use super::formulas::{
    advected_slot, pushed, residual, DensitySums, ResidualInputs, ViscositySums,
};
use super::layout::{BlockedPairs, FluidSums, ResidualTerms, SlotIndex, LANES};
use crate::kernel::Kernel;
use crate::simd::mul_add;
use crate::simd::wide::{LaneMask, Lanes, Wide};

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
    let mut sums = DensitySums::<Lanes<FUSED>>::new(start);
    let (xi, yi) = (Lanes(*xi), Lanes(*yi));
    for s in 0..width {
        let k = s * LANES;
        let (xj, yj) = split(&gather(pos, first, &idx[k..k + LANES]));
        let pair = LaneMask::from_fn(|l| (s as u32) < lens[l]);
        let (sx, sy) = sums.add_slot(kernel, (xi.sub(xj), yi.sub(yj)), pair, volume);
        gx[k..k + LANES].copy_from_slice(&sx.0);
        gy[k..k + LANES].copy_from_slice(&sy.0);
    }
    FluidSums {
        density: sums.density.0,
        grad_x: sums.grad_x.0,
        grad_y: sums.grad_y.0,
        grad_sq: sums.grad_sq.0,
    }
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
    let own = split(xi);
    let mut sum = Lanes::<FUSED>::splat(start);
    for slot in idx.chunks_exact(LANES) {
        let (pj, vj) = (gather(pos, first, slot), gather(vel, first, slot));
        // Padding repeats the particle itself, which is never its own neighbour.
        let other = LaneMask::from_fn(|l| slot[l].absolute(first) != first + l);
        sum = advected_slot(kernel, sum, own, split(&pj), split(&vj), dt, other, volume);
    }
    sum.0
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
    let (own_x, own_v) = (split::<FUSED>(xi), split::<FUSED>(vi));
    let mut sums = ViscositySums::new();
    for ((slot, gx), gy) in idx
        .chunks_exact(LANES)
        .zip(gx.chunks_exact(LANES))
        .zip(gy.chunks_exact(LANES))
    {
        let (pj, vj) = (
            split(&gather(pos, first, slot)),
            split(&gather(vel, first, slot)),
        );
        let x = (own_x.0.sub(pj.0), own_x.1.sub(pj.1));
        let u = (own_v.0.sub(vj.0), own_v.1.sub(vj.1));
        let g = (Lanes(to_lanes(gx)), Lanes(to_lanes(gy)));
        // Padding repeats the particle itself, which is never its own neighbour.
        let pair = LaneMask::from_fn(|l| slot[l].absolute(first) != first + l);
        sums.add_slot(kernel, x, u, g, pair, eps2, laplacian);
    }
    let vectors = |(x, y): (Lanes<FUSED>, Lanes<FUSED>)| {
        let mut out = [Vec2::ZERO; LANES];
        for (l, o) in out.iter_mut().enumerate() {
            *o = Vec2::new(x.0[l], y.0[l]);
        }
        out
    };
    (vectors(sums.xsph), vectors(sums.laplacian))
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
    // One particle at a time: a block's last lanes may be empty, and whole-block lanes
    // with copies in and out measured 25 % slower on the 20k benchmark. The slices have the
    // block's length, so that the loop has no bounds checks.
    let particles = first..first + delta.len();
    let (vel, grad_sum) = (&vel[particles.clone()], &terms.grad_sum[particles.clone()]);
    let (flux, source) = (
        &terms.wall_flux[particles.clone()],
        &terms.source[particles.clone()],
    );
    let factor = &terms.factor[particles];
    *errors = [0.0; LANES];
    for l in 0..delta.len() {
        let inputs = ResidualInputs {
            vel: (vel[l].x, vel[l].y),
            grad_sum: (grad_sum[l].x, grad_sum[l].y),
            wall_flux: flux[l],
            source: source[l],
            factor: factor[l],
        };
        let (r, e, d) = residual(
            fluid[l],
            &inputs,
            terms.volume,
            terms.rate_scale,
            terms.increment_scale,
        );
        (rate[l], delta[l], errors[l]) = (r, d, e);
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
    // One particle at a time, as in `lane_residual_block`.
    let particles = first..first + vel.len();
    let (ki, gi) = (&kappa[particles.clone()], &grad_sum[particles]);
    for l in 0..vel.len() {
        let (v, g) = (vel[l], gi[l]);
        let (x, y) = pushed((v.x, v.y), ki[l], (g.x, g.y), (sx[l], sy[l]), volume);
        vel[l] = Vec2::new(x, y);
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

/// 16 lanes of `(x, y)` pairs as the lanes of x and of y.
#[inline(always)]
fn split<const FUSED: bool>(v: &[Vec2; LANES]) -> (Lanes<FUSED>, Lanes<FUSED>) {
    let (mut x, mut y) = ([0.0f32; LANES], [0.0f32; LANES]);
    for l in 0..LANES {
        (x[l], y[l]) = (v[l].x, v[l].y);
    }
    (Lanes(x), Lanes(y))
}

/// A whole slot (16 entries) as lanes.
#[inline(always)]
fn to_lanes(v: &[f32]) -> [f32; LANES] {
    let mut out = [0.0f32; LANES];
    for (o, v) in out.iter_mut().zip(&v[..LANES]) {
        *o = *v;
    }
    out
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
