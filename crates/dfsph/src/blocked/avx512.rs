//! The AVX-512F kernels of the pair passes (the `avx512` path of [`crate::simd`]): each
//! reads a slot's neighbour values with gather instructions, plain loads or windows
//! ([`super::Gather`]) into `__m512` vectors and hands them to the pass's formula
//! (`formulas.rs`, over [`crate::simd::wide::Zmm`]), the lane kernels' sums in the same
//! order.

use super::formulas::{
    advected_slot, pushed, residual, DensitySums, ResidualInputs, ViscositySums,
};
use super::layout::{
    BlockedPairs, FluidSums, Gather, ResidualTerms, SlotIndex, Windows, LANES, WINDOW,
};
use crate::kernel::Kernel;
use crate::simd::avx512::{deinterleave, indices_from};
use crate::simd::wide::{Wide, Zmm};
use glam::Vec2;
use std::arch::x86_64::*;

/// The 16 lanes' neighbour lists of a block being filled, read slot by slot.
pub struct LaneLists<'a> {
    /// Each lane's list; an empty list is replaced by one placeholder entry, so that
    /// every lane has an entry to load.
    lists: [&'a [u32]; LANES],
    lens: [u32; LANES],
    /// What a lane holds past the end of its list: the particle itself, or the block's
    /// first particle for a lane past the last particle.
    pad: [u32; LANES],
    first: usize,
    /// Particles: every index must be below this.
    n: usize,
}

impl<'a> LaneLists<'a> {
    /// The lists of the block whose first particle is `first`, of `n` particles.
    pub fn new(lists: &[&'a [u32]; LANES], first: usize, n: usize) -> Self {
        const PLACEHOLDER: &[u32] = &[0];
        LaneLists {
            lists: std::array::from_fn(|l| match lists[l] {
                [] => PLACEHOLDER,
                list => list,
            }),
            lens: std::array::from_fn(|l| lists[l].len() as u32),
            pad: std::array::from_fn(|l| super::layout::padding(first + l, n)),
            first,
            n,
        }
    }

    /// Each lane's `s`-th neighbour, or its last one where the list is shorter (the
    /// placeholder for an empty list): always an entry of the list, so the load needs no
    /// branch.
    #[inline(always)]
    fn clamped_slot(&self, s: usize, out: &mut [u32; LANES]) {
        for (o, list) in out.iter_mut().zip(&self.lists) {
            // SAFETY: `list` is not empty, so `len - 1` is in bounds.
            *o = unsafe { *list.get_unchecked(s.min(list.len() - 1)) };
        }
    }
}

/// [`super::BlockWriter::fill_block`] 16 lanes at a time. Slot by slot, the lanes'
/// neighbours are read from their lists (padded where a list is shorter), checked
/// against the particle count, stored in `idx` and used to read the neighbours'
/// positions; then `∇W` and the density sums. Multiplies and adds are separate (no
/// fused multiply-add) and in the scalar code's order, so every result rounds exactly
/// as [`Kernel::w_and_grad`] and the scalar sums do.
///
/// # Safety
/// The CPU must have AVX-512F, and the three slices the same length (a multiple of 16,
/// at least 16 times the longest list).
#[allow(clippy::too_many_arguments)]
#[target_feature(enable = "avx512f")]
pub unsafe fn fill_fluid_block<I: SlotIndex>(
    lists: &LaneLists,
    idx: &mut [I],
    gx: &mut [f32],
    gy: &mut [f32],
    xi: &[f32; LANES],
    yi: &[f32; LANES],
    pos: &[Vec2],
    kernel: &Kernel,
    volume: f32,
    start: f32,
    gather: Gather,
) -> FluidSums {
    assert!(pos.len() >= lists.n);
    let (count, first) = (_mm512_set1_epi32(lists.n as i32), lists.first as i32);
    let base = pos.as_ptr() as *const f32;
    let (xi, yi) = (
        Zmm(_mm512_loadu_ps(xi.as_ptr())),
        Zmm(_mm512_loadu_ps(yi.as_ptr())),
    );
    let lens = _mm512_loadu_si512(lists.lens.as_ptr() as *const _);
    let pad = _mm512_loadu_si512(lists.pad.as_ptr() as *const _);
    let mut slot = [0u32; LANES];
    let mut sums = DensitySums::<Zmm>::new(start);
    for (s, kk) in (0..idx.len()).step_by(LANES).enumerate() {
        lists.clamped_slot(s, &mut slot);
        let clamped = _mm512_loadu_si512(slot.as_ptr() as *const _);
        // Every index is checked before it is used to read (unsigned: j < n).
        assert!(
            _mm512_cmpge_epu32_mask(clamped, count) == 0,
            "neighbour index out of range"
        );
        let pair = _mm512_cmplt_epu32_mask(_mm512_set1_epi32(s as i32), lens);
        let j = _mm512_mask_blend_epi32(pair, pad, clamped);
        let out = idx.as_mut_ptr().add(kk);
        if I::RELATIVE {
            // j − first must lie in [−32768, 32767]: j − first + 32768 in [0, 65535].
            let shifted = _mm512_sub_epi32(j, _mm512_set1_epi32(first - 32_768));
            assert!(
                _mm512_cmpgt_epu32_mask(shifted, _mm512_set1_epi32(65_535)) == 0,
                "a neighbour too far for 16-bit indices"
            );
            let relative = _mm512_sub_epi32(j, _mm512_set1_epi32(first));
            _mm256_storeu_si256(out as *mut __m256i, _mm512_cvtepi32_epi16(relative));
        } else {
            _mm512_storeu_si512(out as *mut _, j);
        }
        // The padding lanes read a real neighbour's position; their results are masked.
        let (xj, yj) = gather_xy(clamped, slot.as_ptr(), base, gather);
        let offset = (xi.sub(Zmm(xj)), yi.sub(Zmm(yj)));
        let (gxv, gyv) = sums.add_slot(kernel, offset, pair, volume);
        _mm512_storeu_ps(gx.as_mut_ptr().add(kk), gxv.0);
        _mm512_storeu_ps(gy.as_mut_ptr().add(kk), gyv.0);
    }
    let mut out = FluidSums::default();
    _mm512_storeu_ps(out.density.as_mut_ptr(), sums.density.0);
    _mm512_storeu_ps(out.grad_x.as_mut_ptr(), sums.grad_x.0);
    _mm512_storeu_ps(out.grad_y.as_mut_ptr(), sums.grad_y.0);
    _mm512_storeu_ps(out.grad_sq.as_mut_ptr(), sums.grad_sq.0);
    out
}

/// [`super::BlockedPairs::advected_kernel_sums`], 16 pairs at a time.
///
/// # Safety
/// The CPU must have AVX-512F, `idx` must hold whole slots, and every index (of the
/// block starting at `first`) must be below `pos.len()` and `vel.len()`, as must
/// every window of `windows`, where given (the block's).
#[allow(clippy::too_many_arguments)]
#[target_feature(enable = "avx512f")]
pub unsafe fn advected_kernel_sums<I: SlotIndex>(
    first: usize,
    idx: &[I],
    xi: &[Vec2; LANES],
    pos: &[Vec2],
    vel: &[Vec2],
    dt: f32,
    kernel: &Kernel,
    volume: f32,
    start: f32,
    gather: Gather,
    windows: Option<Windows>,
) -> [f32; LANES] {
    let neighbours = NeighbourStates::new::<I>(first, pos, vel, gather, windows);
    let own = indices_from((first - I::origin(first)) as u32);
    let (xi_x, xi_y) = split_xy(xi);
    let mut sum = Zmm::splat(start);
    for kk in (0..idx.len()).step_by(LANES) {
        let at = idx.as_ptr().add(kk);
        let j = load_indices(at);
        let ((px, py), (vx, vy)) = neighbours.slot(kk, j, at);
        // Padding repeats the particle itself, which is never its own neighbour.
        let other = _mm512_cmpneq_epi32_mask(j, own);
        sum = advected_slot(
            kernel,
            sum,
            (Zmm(xi_x), Zmm(xi_y)),
            (Zmm(px), Zmm(py)),
            (Zmm(vx), Zmm(vy)),
            dt,
            other,
            volume,
        );
    }
    let mut out = [0.0f32; LANES];
    _mm512_storeu_ps(out.as_mut_ptr(), sum.0);
    out
}

/// The positions and velocities of a block's neighbours, read slot by slot: through the
/// block's windows where given, else as `gather` reads them.
struct NeighbourStates<'a> {
    /// The flat position and velocity arrays from the block's origin on.
    pos: *const f32,
    vel: *const f32,
    gather: Gather,
    /// The codes and the position and velocity tables of the block's windows.
    windows: Option<(&'a [u8], PairTables, PairTables)>,
}

impl<'a> NeighbourStates<'a> {
    /// # Safety
    /// The CPU must have AVX-512F, and `windows`, where given, must be the block's (each
    /// window within `pos` and `vel`).
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn new<I: SlotIndex>(
        first: usize,
        pos: &[Vec2],
        vel: &[Vec2],
        gather: Gather,
        windows: Option<Windows<'a>>,
    ) -> Self {
        let origin = I::origin(first);
        NeighbourStates {
            pos: pos.as_ptr().add(origin) as *const f32,
            vel: vel.as_ptr().add(origin) as *const f32,
            gather,
            windows: windows.map(|w| {
                (
                    w.codes,
                    pair_windows(pos, w.starts),
                    pair_windows(vel, w.starts),
                )
            }),
        }
    }

    /// The `(x, y)` positions and velocities of the slot at entry `k`, whose offsets `j`
    /// are also stored at `at`.
    ///
    /// # Safety
    /// The CPU must have AVX-512F, and every offset of the slot must be within the arrays.
    #[inline]
    #[target_feature(enable = "avx512f")]
    unsafe fn slot<I: SlotIndex>(
        &self,
        k: usize,
        j: __m512i,
        at: *const I,
    ) -> ((__m512, __m512), (__m512, __m512)) {
        match &self.windows {
            Some((codes, p, v)) => {
                let code = codes.as_ptr().add(k);
                (pick_pairs(code, p), pick_pairs(code, v))
            }
            None => (
                gather_xy(j, at, self.pos, self.gather),
                gather_xy(j, at, self.vel, self.gather),
            ),
        }
    }
}

/// 16 stored indices from `at`, sign- or zero-extended to 32 bits: offsets from
/// [`SlotIndex::origin`].
#[inline]
#[target_feature(enable = "avx512f")]
unsafe fn load_indices<I: SlotIndex>(at: *const I) -> __m512i {
    if I::RELATIVE {
        _mm512_cvtepi16_epi32(_mm256_loadu_si256(at as *const __m256i))
    } else {
        _mm512_loadu_si512(at as *const _)
    }
}

/// The `Vec2` entries `j` (16 offsets, also stored at `at`) of the flat array at `base`
/// (its element [`SlotIndex::origin`]), as x and y vectors: 16 64-bit `(x, y)` pairs,
/// de-interleaved. With [`Gather::Instruction`], two gathers of 8 pairs: a gather costs
/// about one load per element, so this reads 16 pairs for the price of 16 elements where
/// separate x and y gathers cost 32.
#[inline]
#[target_feature(enable = "avx512f")]
unsafe fn gather_xy<I: SlotIndex>(
    j: __m512i,
    at: *const I,
    base: *const f32,
    gather: Gather,
) -> (__m512, __m512) {
    let (lo, hi) = match gather {
        Gather::Instruction => {
            let base = base as *const i64;
            let half = |j| _mm512_castsi512_ps(_mm512_i32gather_epi64::<8>(j, base));
            (
                half(_mm512_castsi512_si256(j)),
                half(_mm512_extracti64x4_epi64::<1>(j)),
            )
        }
        Gather::Loads | Gather::Windows => {
            let base = base as *const u64;
            let mut pairs = [0u64; LANES];
            for (l, pair) in pairs.iter_mut().enumerate() {
                *pair = *base.offset((*at.add(l)).offset());
            }
            let flat = pairs.as_ptr() as *const f32;
            (_mm512_loadu_ps(flat), _mm512_loadu_ps(flat.add(16)))
        }
    };
    deinterleave(lo, hi)
}

/// The f32 entries `j` (16 offsets, also stored at `at`) of the array at `base` (its
/// element [`SlotIndex::origin`]).
#[inline]
#[target_feature(enable = "avx512f")]
unsafe fn gather_f32<I: SlotIndex>(
    j: __m512i,
    at: *const I,
    base: *const f32,
    gather: Gather,
) -> __m512 {
    match gather {
        Gather::Instruction => _mm512_i32gather_ps::<4>(j, base),
        Gather::Loads | Gather::Windows => {
            let mut values = [0.0f32; LANES];
            for (l, value) in values.iter_mut().enumerate() {
                *value = *base.offset((*at.add(l)).offset());
            }
            _mm512_loadu_ps(values.as_ptr())
        }
    }
}

/// 16 lanes of `(x, y)` pairs as two vectors of x and of y.
#[inline]
#[target_feature(enable = "avx512f")]
unsafe fn split_xy(v: &[Vec2; LANES]) -> (__m512, __m512) {
    let flat = v.as_ptr() as *const f32;
    deinterleave(_mm512_loadu_ps(flat), _mm512_loadu_ps(flat.add(16)))
}

/// [`super::BlockedPairs::viscosity_sums`], 16 pairs at a time.
///
/// # Safety
/// The CPU must have AVX-512F, the three slices must hold whole slots, and every index
/// (of the block starting at `first`) must be below `pos.len()` and `vel.len()`, as must
/// every window of `windows`, where given (the block's).
#[allow(clippy::too_many_arguments)]
#[target_feature(enable = "avx512f")]
pub unsafe fn viscosity_sums<I: SlotIndex>(
    first: usize,
    idx: &[I],
    gx: &[f32],
    gy: &[f32],
    xi: &[Vec2; LANES],
    vi: &[Vec2; LANES],
    pos: &[Vec2],
    vel: &[Vec2],
    kernel: &Kernel,
    eps2: f32,
    laplacian: bool,
    gather: Gather,
    windows: Option<Windows>,
) -> ([Vec2; LANES], [Vec2; LANES]) {
    let neighbours = NeighbourStates::new::<I>(first, pos, vel, gather, windows);
    let own = indices_from((first - I::origin(first)) as u32);
    let (xi_x, xi_y) = split_xy(xi);
    let (vi_x, vi_y) = split_xy(vi);
    let mut sums = ViscositySums::<Zmm>::new();
    for kk in (0..idx.len()).step_by(LANES) {
        let at = idx.as_ptr().add(kk);
        let j = load_indices(at);
        let pair = _mm512_cmpneq_epi32_mask(j, own);
        let ((xj, yj), (vxj, vyj)) = neighbours.slot(kk, j, at);
        let x = (Zmm(_mm512_sub_ps(xi_x, xj)), Zmm(_mm512_sub_ps(xi_y, yj)));
        let u = (Zmm(_mm512_sub_ps(vi_x, vxj)), Zmm(_mm512_sub_ps(vi_y, vyj)));
        let g = (
            Zmm(_mm512_loadu_ps(gx.as_ptr().add(kk))),
            Zmm(_mm512_loadu_ps(gy.as_ptr().add(kk))),
        );
        sums.add_slot(kernel, x, u, g, pair, eps2, laplacian);
    }
    let store = |(x, y): (Zmm, Zmm)| {
        let (mut ax, mut ay) = ([0.0f32; LANES], [0.0f32; LANES]);
        _mm512_storeu_ps(ax.as_mut_ptr(), x.0);
        _mm512_storeu_ps(ay.as_mut_ptr(), y.0);
        std::array::from_fn(|l| Vec2::new(ax[l], ay[l]))
    };
    (store(sums.xsph), store(sums.laplacian))
}

/// Load masks of the two halves of `lanes` (x, y) pairs read as a flat f32 array.
#[inline]
fn pair_masks(lanes: usize) -> (__mmask16, __mmask16) {
    let mask = |floats: usize| ((1u32 << floats.min(16)) - 1) as __mmask16;
    (mask(2 * lanes), mask((2 * lanes).saturating_sub(16)))
}

/// Lanes `0..lanes` set.
#[inline]
fn lane_mask(lanes: usize) -> __mmask16 {
    ((1u32 << lanes) - 1) as __mmask16
}

/// `lanes` (≤ 16) consecutive `Vec2` from `p` as x and y vectors; the lanes past them
/// read 0 and nothing past them is read.
#[inline]
#[target_feature(enable = "avx512f")]
unsafe fn load_pairs(p: *const Vec2, lanes: usize) -> (__m512, __m512) {
    let (lo, hi) = pair_masks(lanes);
    let flat = p as *const f32;
    // `wrapping_add`: with 8 or fewer lanes the second half lies past the data, and
    // all its lanes are masked (a masked lane is never read).
    deinterleave(
        _mm512_maskz_loadu_ps(lo, flat),
        _mm512_maskz_loadu_ps(hi, flat.wrapping_add(16)),
    )
}

/// Store the first `lanes` of `x` and `y` as (x, y) pairs at `p`, writing nothing past
/// them.
#[inline]
#[target_feature(enable = "avx512f")]
unsafe fn store_pairs(p: *mut Vec2, lanes: usize, x: __m512, y: __m512) {
    let first = _mm512_setr_epi32(0, 16, 1, 17, 2, 18, 3, 19, 4, 20, 5, 21, 6, 22, 7, 23);
    let second = _mm512_setr_epi32(8, 24, 9, 25, 10, 26, 11, 27, 12, 28, 13, 29, 14, 30, 15, 31);
    let (lo, hi) = pair_masks(lanes);
    let flat = p as *mut f32;
    _mm512_mask_storeu_ps(flat, lo, _mm512_permutex2var_ps(x, first, y));
    _mm512_mask_storeu_ps(
        flat.wrapping_add(16),
        hi,
        _mm512_permutex2var_ps(x, second, y),
    );
}

/// [`super::BlockedPairs::residual_blocks`]: [`residual_block`] block by block, with
/// `idx` every block's indices.
///
/// # Safety
/// The CPU must have AVX-512F, `idx` must be `pairs`' indices, every index below
/// `vel.len()`, `vel` and the arrays of `terms` must hold all particles, and `delta`,
/// `rate` and `errors` those of `blocks` (one entry per particle, one row per block).
#[allow(clippy::too_many_arguments)]
#[target_feature(enable = "avx512f")]
pub unsafe fn residual_blocks<I: SlotIndex>(
    pairs: &BlockedPairs,
    idx: &[I],
    blocks: std::ops::Range<usize>,
    vel: &[Vec2],
    terms: &ResidualTerms,
    delta: &mut [f32],
    rate: &mut [f32],
    errors: &mut [[f32; LANES]],
) {
    let gather = pairs.gather();
    let lanes = delta.chunks_mut(LANES).zip(rate.chunks_mut(LANES));
    for ((b, (d, r)), e) in blocks.zip(lanes).zip(errors) {
        let (idx, gx, gy) = pairs.block_of(idx, b);
        residual_block(
            idx,
            gx,
            gy,
            vel,
            b * LANES,
            terms,
            d,
            r,
            e,
            gather,
            pairs.windows(b),
        );
    }
}

/// [`super::BlockedPairs::apply_blocks`]: [`apply_block`] block by block, with `idx`
/// every block's indices.
///
/// # Safety
/// The CPU must have AVX-512F, `idx` must be `pairs`' indices, every index below
/// `kappa.len()`, `kappa` and `grad_sum` must hold all particles, and `vel` and `total`,
/// when given, those of `blocks`.
#[allow(clippy::too_many_arguments)]
#[target_feature(enable = "avx512f")]
pub unsafe fn apply_blocks<I: SlotIndex>(
    pairs: &BlockedPairs,
    idx: &[I],
    blocks: std::ops::Range<usize>,
    volume: f32,
    kappa: &[f32],
    grad_sum: &[Vec2],
    vel: &mut [Vec2],
    mut total: Option<&mut [f32]>,
) {
    let gather = pairs.gather();
    for (k, (b, v)) in blocks.zip(vel.chunks_mut(LANES)).enumerate() {
        let (idx, gx, gy) = pairs.block_of(idx, b);
        let t = total
            .as_deref_mut()
            .map(|t| &mut t[k * LANES..k * LANES + v.len()]);
        apply_block(
            idx,
            gx,
            gy,
            kappa,
            b * LANES,
            grad_sum,
            volume,
            v,
            t,
            gather,
            pairs.windows(b),
        );
    }
}

/// [`super::BlockedPairs::residual_block`]: the pair loop of [`velocity_gradient_dots`],
/// then the per-particle terms 16 lanes at a time, with the portable code's operations
/// in its order (so the two differ only by the pair loop's fused multiply-adds).
///
/// # Safety
/// The CPU must have AVX-512F, the three slices the same length (a multiple of 16),
/// every index below `vel.len()`, `vel` and the arrays of `terms` must hold the
/// `delta.len()` (≤ 16) particles from `first` on, and `rate` as many entries as `delta`.
#[allow(clippy::too_many_arguments)]
#[inline]
#[target_feature(enable = "avx512f")]
pub unsafe fn residual_block<I: SlotIndex>(
    idx: &[I],
    gx: &[f32],
    gy: &[f32],
    vel: &[Vec2],
    first: usize,
    terms: &ResidualTerms,
    delta: &mut [f32],
    rate: &mut [f32],
    errors: &mut [f32; LANES],
    gather: Gather,
    windows: Option<Windows>,
) {
    let lanes = delta.len();
    let fluid = velocity_gradient_dot_lanes(idx, first, gx, gy, vel, gather, windows);
    let m = lane_mask(lanes);
    let load = |a: &[f32]| Zmm(_mm512_maskz_loadu_ps(m, a.as_ptr().add(first)));
    let pairs = |p: &[Vec2]| {
        let (x, y) = load_pairs(p.as_ptr().add(first), lanes);
        (Zmm(x), Zmm(y))
    };
    let inputs = ResidualInputs {
        vel: pairs(vel),
        grad_sum: pairs(terms.grad_sum),
        wall_flux: load(terms.wall_flux),
        source: load(terms.source),
        factor: load(terms.factor),
    };
    let (r, e, d) = residual(
        Zmm(fluid),
        &inputs,
        terms.volume,
        terms.rate_scale,
        terms.increment_scale,
    );
    _mm512_mask_storeu_ps(rate.as_mut_ptr(), m, r.0);
    _mm512_mask_storeu_ps(delta.as_mut_ptr(), m, d.0);
    _mm512_storeu_ps(errors.as_mut_ptr(), e.keep(m).0);
}

/// [`super::BlockedPairs::apply_block`]: the pair loop of [`weighted_gradient_sums`],
/// then `Δv` and the running total 16 lanes at a time, with the portable code's
/// operations in its order.
///
/// # Safety
/// The CPU must have AVX-512F, the three slices the same length (a multiple of 16),
/// every index below `kappa.len()`, `kappa` and `grad_sum` must hold the `vel.len()`
/// (≤ 16) particles from `first` on, and `total`, when given, as many entries as `vel`.
#[allow(clippy::too_many_arguments)]
#[inline]
#[target_feature(enable = "avx512f")]
pub unsafe fn apply_block<I: SlotIndex>(
    idx: &[I],
    gx: &[f32],
    gy: &[f32],
    kappa: &[f32],
    first: usize,
    grad_sum: &[Vec2],
    volume: f32,
    vel: &mut [Vec2],
    total: Option<&mut [f32]>,
    gather: Gather,
    windows: Option<Windows>,
) {
    let lanes = vel.len();
    let (sx, sy) = weighted_gradient_sum_lanes(idx, first, gx, gy, kappa, gather, windows);
    let m = lane_mask(lanes);
    let ki = _mm512_maskz_loadu_ps(m, kappa.as_ptr().add(first));
    let (gsx, gsy) = load_pairs(grad_sum.as_ptr().add(first), lanes);
    let (vx, vy) = load_pairs(vel.as_ptr(), lanes);
    let (vx, vy) = pushed(
        (Zmm(vx), Zmm(vy)),
        Zmm(ki),
        (Zmm(gsx), Zmm(gsy)),
        (Zmm(sx), Zmm(sy)),
        volume,
    );
    store_pairs(vel.as_mut_ptr(), lanes, vx.0, vy.0);
    if let Some(t) = total {
        let sum = _mm512_add_ps(_mm512_maskz_loadu_ps(m, t.as_ptr()), ki);
        _mm512_mask_storeu_ps(t.as_mut_ptr(), m, sum);
    }
}

/// `Σ_j s_j ∇W_ij` per lane, x and y, read through `windows` where given.
///
/// # Safety
/// The CPU must have AVX-512F, the three slices the same length (a multiple of 16),
/// every index (of the block starting at `first`) below `s.len()`, and `windows`, where
/// given, the block's (so each of its windows ends within `s`).
#[inline]
#[target_feature(enable = "avx512f")]
unsafe fn weighted_gradient_sum_lanes<I: SlotIndex>(
    idx: &[I],
    first: usize,
    gx: &[f32],
    gy: &[f32],
    s: &[f32],
    gather: Gather,
    windows: Option<Windows>,
) -> (__m512, __m512) {
    if let Some(w) = windows {
        return weighted_gradient_sum_windows(w, gx, gy, s);
    }
    let base = s.as_ptr().add(I::origin(first));
    let mut ax = _mm512_setzero_ps();
    let mut ay = _mm512_setzero_ps();
    for k in (0..idx.len()).step_by(LANES) {
        let at = idx.as_ptr().add(k);
        let sj = gather_f32(load_indices(at), at, base, gather);
        ax = _mm512_fmadd_ps(sj, _mm512_loadu_ps(gx.as_ptr().add(k)), ax);
        ay = _mm512_fmadd_ps(sj, _mm512_loadu_ps(gy.as_ptr().add(k)), ay);
    }
    (ax, ay)
}

/// # Safety
/// As [`weighted_gradient_sum_lanes`].
#[target_feature(enable = "avx512f")]
pub unsafe fn weighted_gradient_sums<I: SlotIndex>(
    idx: &[I],
    first: usize,
    gx: &[f32],
    gy: &[f32],
    s: &[f32],
    gather: Gather,
    windows: Option<Windows>,
) -> ([f32; LANES], [f32; LANES]) {
    let (ax, ay) = weighted_gradient_sum_lanes(idx, first, gx, gy, s, gather, windows);
    let mut out = ([0.0f32; LANES], [0.0f32; LANES]);
    _mm512_storeu_ps(out.0.as_mut_ptr(), ax);
    _mm512_storeu_ps(out.1.as_mut_ptr(), ay);
    out
}

/// `Σ_j v_j·∇W_ij` per lane, read through `windows` where given.
///
/// # Safety
/// As [`weighted_gradient_sum_lanes`], with `v` for `s`.
#[inline]
#[target_feature(enable = "avx512f")]
unsafe fn velocity_gradient_dot_lanes<I: SlotIndex>(
    idx: &[I],
    first: usize,
    gx: &[f32],
    gy: &[f32],
    v: &[Vec2],
    gather: Gather,
    windows: Option<Windows>,
) -> __m512 {
    if let Some(w) = windows {
        return velocity_gradient_dot_windows(w, gx, gy, v);
    }
    let base = v.as_ptr().add(I::origin(first)) as *const f32;
    // Two accumulators, so that consecutive multiply-adds do not wait for each other.
    let mut ax = _mm512_setzero_ps();
    let mut ay = _mm512_setzero_ps();
    for k in (0..idx.len()).step_by(LANES) {
        let at = idx.as_ptr().add(k);
        // Pair j of the flat array is v_j; the gather's scale of 8 bytes steps by Vec2.
        let (vx, vy) = gather_xy(load_indices(at), at, base, gather);
        ax = _mm512_fmadd_ps(vx, _mm512_loadu_ps(gx.as_ptr().add(k)), ax);
        ay = _mm512_fmadd_ps(vy, _mm512_loadu_ps(gy.as_ptr().add(k)), ay);
    }
    _mm512_add_ps(ax, ay)
}

/// # Safety
/// As [`velocity_gradient_dot_lanes`].
#[target_feature(enable = "avx512f")]
pub unsafe fn velocity_gradient_dots<I: SlotIndex>(
    idx: &[I],
    first: usize,
    gx: &[f32],
    gy: &[f32],
    v: &[Vec2],
    gather: Gather,
    windows: Option<Windows>,
) -> [f32; LANES] {
    let mut out = [0.0f32; LANES];
    let dots = velocity_gradient_dot_lanes(idx, first, gx, gy, v, gather, windows);
    _mm512_storeu_ps(out.as_mut_ptr(), dots);
    out
}

/// Cover the neighbours `idx` of the block starting at `first` (padding included) with
/// three windows of 32 consecutive particles, and write each entry's code (see
/// [`Windows`]) into `codes`. Lists from a grid sorted row by row of cells reach into
/// three rows, each a short run of particles: on the dam break 99.5 % of blocks fit
/// (none would with windows of 16). Returns the windows' starts, or `None` where the
/// neighbours do not fit or there are fewer than 32 particles (`n`), for the block to
/// be read with loads.
///
/// # Safety
/// The CPU must have AVX-512F, `idx` must hold whole slots, and `codes` as many entries.
#[target_feature(enable = "avx512f")]
pub unsafe fn window_codes<I: SlotIndex>(
    idx: &[I],
    first: usize,
    n: usize,
    codes: &mut [u8],
) -> Option<[u32; 3]> {
    assert!(idx.len().is_multiple_of(LANES) && codes.len() == idx.len());
    if idx.is_empty() || n < WINDOW {
        return None;
    }
    let span = WINDOW as i32;
    // Greedy cover, in offsets from the origin: each window starts at the lowest
    // neighbour the windows before it leave out; they fit if none is left past the third.
    let w0 = lowest_from(idx, i32::MIN);
    let w1 = lowest_from(idx, w0 + span);
    let w2 = if w1 == i32::MAX {
        w1
    } else {
        lowest_from(idx, w1 + span)
    };
    if w2 != i32::MAX {
        let mut high = _mm512_set1_epi32(i32::MIN);
        for k in (0..idx.len()).step_by(LANES) {
            high = _mm512_max_epi32(high, load_indices(idx.as_ptr().add(k)));
        }
        if _mm512_reduce_max_epi32(high) >= w2 + span {
            return None;
        }
    }
    // Where a window reaches past the last particle it starts earlier: a neighbour is
    // below `n`, so it stays inside.
    let origin = I::origin(first) as i64;
    let last_start = (n - WINDOW) as i64;
    let start = |w: i32| (origin + w as i64).min(last_start) as u32;
    let s0 = start(w0);
    let starts = [
        s0,
        if w1 == i32::MAX { s0 } else { start(w1) },
        if w2 == i32::MAX { s0 } else { start(w2) },
    ];
    // Each entry's place in the first window that holds it (unsigned: 0 ≤ place < 32).
    let from_origin = |s: u32| _mm512_set1_epi32((s as i64 - origin) as i32);
    let (o0, o1, o2) = (
        from_origin(starts[0]),
        from_origin(starts[1]),
        from_origin(starts[2]),
    );
    let (width, second, third) = (
        _mm512_set1_epi32(span),
        _mm512_set1_epi32(1 << 5),
        _mm512_set1_epi32(2 << 5),
    );
    for k in (0..idx.len()).step_by(LANES) {
        let v = load_indices(idx.as_ptr().add(k));
        let (p0, p1, p2) = (
            _mm512_sub_epi32(v, o0),
            _mm512_sub_epi32(v, o1),
            _mm512_sub_epi32(v, o2),
        );
        let in0 = _mm512_cmplt_epu32_mask(p0, width);
        let in1 = _mm512_cmplt_epu32_mask(p1, width);
        let code =
            _mm512_mask_blend_epi32(in1, _mm512_or_si512(p2, third), _mm512_or_si512(p1, second));
        let code = _mm512_mask_blend_epi32(in0, code, p0);
        _mm_storeu_si128(
            codes.as_mut_ptr().add(k) as *mut __m128i,
            _mm512_cvtepi32_epi8(code),
        );
    }
    Some(starts)
}

/// The lowest offset in `idx` at or above `floor` (`i32::MAX` where none is).
#[inline]
#[target_feature(enable = "avx512f")]
unsafe fn lowest_from<I: SlotIndex>(idx: &[I], floor: i32) -> i32 {
    let floor = _mm512_set1_epi32(floor);
    let mut low = _mm512_set1_epi32(i32::MAX);
    for k in (0..idx.len()).step_by(LANES) {
        let v = load_indices(idx.as_ptr().add(k));
        low = _mm512_mask_min_epi32(low, _mm512_cmpge_epi32_mask(v, floor), low, v);
    }
    _mm512_reduce_min_epi32(low)
}

/// A slot's 16 codes ([`Windows`]) as 32-bit lanes.
#[inline]
#[target_feature(enable = "avx512f")]
unsafe fn load_codes(at: *const u8) -> __m512i {
    _mm512_cvtepu8_epi32(_mm_loadu_si128(at as *const __m128i))
}

/// The lanes whose code names window 1, and those naming window 2.
#[inline]
#[target_feature(enable = "avx512f")]
fn window_masks(code: __m512i) -> (__mmask16, __mmask16) {
    (
        _mm512_test_epi32_mask(code, _mm512_set1_epi32(1 << 5)),
        _mm512_test_epi32_mask(code, _mm512_set1_epi32(2 << 5)),
    )
}

/// Each lane's value out of three windows of 32 values (two vectors each): the permutes
/// read the place in bits 0–4 of the code, the masks say which window's pick to keep.
#[inline]
#[target_feature(enable = "avx512f")]
fn pick(code: __m512i, (in1, in2): (__mmask16, __mmask16), w: &[(__m512, __m512); 3]) -> __m512 {
    let v0 = _mm512_permutex2var_ps(w[0].0, code, w[0].1);
    let v1 = _mm512_permutex2var_ps(w[1].0, code, w[1].1);
    let v2 = _mm512_permutex2var_ps(w[2].0, code, w[2].1);
    _mm512_mask_mov_ps(_mm512_mask_mov_ps(v0, in1, v1), in2, v2)
}

/// [`weighted_gradient_sum_lanes`] through a block's windows of `s`.
///
/// # Safety
/// The CPU must have AVX-512F, `gx`, `gy` and the codes the same length (a multiple of
/// 16), and every window within `s`.
#[inline]
#[target_feature(enable = "avx512f")]
unsafe fn weighted_gradient_sum_windows(
    w: Windows,
    gx: &[f32],
    gy: &[f32],
    s: &[f32],
) -> (__m512, __m512) {
    let mut table = [(_mm512_setzero_ps(), _mm512_setzero_ps()); 3];
    for (t, &start) in table.iter_mut().zip(&w.starts) {
        let at = s.as_ptr().add(start as usize);
        *t = (_mm512_loadu_ps(at), _mm512_loadu_ps(at.add(LANES)));
    }
    let mut ax = _mm512_setzero_ps();
    let mut ay = _mm512_setzero_ps();
    for k in (0..gx.len()).step_by(LANES) {
        let code = load_codes(w.codes.as_ptr().add(k));
        let sj = pick(code, window_masks(code), &table);
        ax = _mm512_fmadd_ps(sj, _mm512_loadu_ps(gx.as_ptr().add(k)), ax);
        ay = _mm512_fmadd_ps(sj, _mm512_loadu_ps(gy.as_ptr().add(k)), ay);
    }
    (ax, ay)
}

/// A block's three windows of a `Vec2` array, each window's 32 entries split into a
/// table of x and one of y ([`pick`]).
///
/// # Safety
/// The CPU must have AVX-512F, and every window must lie within `v`.
#[inline]
#[target_feature(enable = "avx512f")]
unsafe fn pair_windows(v: &[Vec2], starts: [u32; 3]) -> PairTables {
    let zero = (_mm512_setzero_ps(), _mm512_setzero_ps());
    let (mut x, mut y) = ([zero; 3], [zero; 3]);
    for (r, &start) in starts.iter().enumerate() {
        let at = v.as_ptr().add(start as usize) as *const f32;
        let (x_lo, y_lo) = deinterleave(_mm512_loadu_ps(at), _mm512_loadu_ps(at.add(16)));
        let (x_hi, y_hi) = deinterleave(_mm512_loadu_ps(at.add(32)), _mm512_loadu_ps(at.add(48)));
        (x[r], y[r]) = ((x_lo, x_hi), (y_lo, y_hi));
    }
    (x, y)
}

/// The x and y tables of [`pair_windows`].
type PairTables = ([(__m512, __m512); 3], [(__m512, __m512); 3]);

/// A slot's 16 `(x, y)` values out of [`pair_windows`] tables, by the codes at `at`.
///
/// # Safety
/// The CPU must have AVX-512F, and `at` must hold 16 codes.
#[inline]
#[target_feature(enable = "avx512f")]
unsafe fn pick_pairs(at: *const u8, (x, y): &PairTables) -> (__m512, __m512) {
    let code = load_codes(at);
    let masks = window_masks(code);
    (pick(code, masks, x), pick(code, masks, y))
}

/// [`velocity_gradient_dot_lanes`] through a block's windows of `v`.
///
/// # Safety
/// As [`weighted_gradient_sum_windows`], with `v` for `s`.
#[inline]
#[target_feature(enable = "avx512f")]
unsafe fn velocity_gradient_dot_windows(w: Windows, gx: &[f32], gy: &[f32], v: &[Vec2]) -> __m512 {
    let table = pair_windows(v, w.starts);
    let mut ax = _mm512_setzero_ps();
    let mut ay = _mm512_setzero_ps();
    for k in (0..gx.len()).step_by(LANES) {
        let (vx, vy) = pick_pairs(w.codes.as_ptr().add(k), &table);
        ax = _mm512_fmadd_ps(vx, _mm512_loadu_ps(gx.as_ptr().add(k)), ax);
        ay = _mm512_fmadd_ps(vy, _mm512_loadu_ps(gy.as_ptr().add(k)), ay);
    }
    _mm512_add_ps(ax, ay)
}
