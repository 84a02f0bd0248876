//! The AVX-512F kernels of the grid: cell keys and query cells 16 points at a time, and the
//! candidate filter by AVX-512's compress. Each kernel has a safe entry that checks what it
//! needs (the CPU's AVX-512F, a dense grid) before it runs; the `unsafe` stays in this file,
//! part of the SIMD seam. They see a grid as a [`DenseGrid`]: the grid's own type is the
//! parent's, which calls them.

use crate::simd::avx512::{deinterleave, indices_from};
use glam::Vec2;
use std::arch::x86_64::*;

/// What the kernels read of a dense grid (`super::Grid`, never hashed here).
#[derive(Clone, Copy, Debug)]
pub(super) struct DenseGrid {
    pub origin: Vec2,
    pub inv_cell: f32,
    pub dims: [i64; 2],
    pub key_count: usize,
}

/// The cell coordinates along one axis of 16 points whose coordinates are `v`, floored
/// but not clamped, as two vectors of 8 (lanes 0–7, then 8–15): the operations of
/// [`super::Grid::cell_of`], `(v − origin)·inv` in f64 with no fused multiply-add, then
/// floor, so every value is the one `cell_of` floors to.
#[inline]
#[target_feature(enable = "avx512f")]
fn floored_cells(v: __m512, origin: f32, inv: f32) -> [__m512d; 2] {
    let (origin, inv) = (_mm512_set1_pd(origin as f64), _mm512_set1_pd(inv as f64));
    let v = _mm512_castps_pd(v);
    let halves = [_mm512_castpd512_pd256(v), _mm512_extractf64x4_pd::<1>(v)];
    let mut floored = [_mm512_setzero_pd(); 2];
    for (f, half) in floored.iter_mut().zip(halves) {
        let scaled = _mm512_mul_pd(
            _mm512_sub_pd(_mm512_cvtps_pd(_mm256_castpd_ps(half)), origin),
            inv,
        );
        *f = _mm512_roundscale_pd::<{ _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC }>(scaled);
    }
    floored
}

/// [`super::Grid::point_key`] of each of `points` into `keys`, 16 points per iteration,
/// for a dense grid: [`floored_cells`], then the clamp to the grid in f64, where the
/// scalar path converts to an integer first. Both give the same cell: the floored value
/// is an integer, and a NaN clamps to 0 either way (`max` returns its second operand for
/// a NaN, the scalar `as` gives 0). Returns how many points it keyed: a tail of fewer
/// than 16 is left to the scalar path.
///
/// # Safety
/// The CPU must have AVX-512F; the grid must be dense with at most `i32::MAX` cells.
#[target_feature(enable = "avx512f")]
unsafe fn dense_keys_unchecked(grid: &DenseGrid, points: &[Vec2], keys: &mut [u32]) -> usize {
    debug_assert!(grid.key_count <= i32::MAX as usize);
    let n = points.len().min(keys.len());
    let xy = points.as_ptr() as *const f32;
    let zero = _mm512_setzero_pd();
    let last = |axis: usize| _mm512_set1_pd((grid.dims[axis] - 1) as f64);
    let (last_x, last_y) = (last(0), last(1));
    let row = _mm256_set1_epi32(grid.dims[0] as i32);
    let mut i = 0;
    while i + 16 <= n {
        let (x, y) = deinterleave(
            _mm512_loadu_ps(xy.add(2 * i)),
            _mm512_loadu_ps(xy.add(2 * i + 16)),
        );
        let cx = floored_cells(x, grid.origin.x, grid.inv_cell);
        let cy = floored_cells(y, grid.origin.y, grid.inv_cell);
        for half in 0..2 {
            let clamp = |v: __m512d, last: __m512d| {
                _mm512_cvttpd_epi32(_mm512_min_pd(_mm512_max_pd(v, zero), last))
            };
            let (cx, cy) = (clamp(cx[half], last_x), clamp(cy[half], last_y));
            let key = _mm256_add_epi32(_mm256_mullo_epi32(cy, row), cx);
            _mm256_storeu_si256(keys.as_mut_ptr().add(i + 8 * half) as *mut __m256i, key);
        }
        i += 16;
    }
    i
}

/// The cells of up to 16 `points` in a dense `grid`, for [`super::Grid::dense_block`]:
/// [`floored_cells`], with each coordinate then clamped to `-2..=dims + 1` (a cell two or
/// more outside the grid has an empty block, as every cell further out does) and a NaN
/// coordinate to 0, as `cell_of` gives it. So every point gets the block `cell_of` would
/// give it.
///
/// # Safety
/// The CPU must have AVX-512F; the grid must be dense.
#[target_feature(enable = "avx512f")]
unsafe fn block_cells_unchecked(grid: &DenseGrid, points: &[Vec2], cells: &mut [[i64; 2]; 16]) {
    let n = points.len().min(16);
    let xy = points.as_ptr() as *const f32;
    let lo_mask: __mmask16 = if n >= 8 {
        0xffff
    } else {
        ((1u32 << (2 * n)) - 1) as u16
    };
    let hi_mask: __mmask16 = if n > 8 {
        ((1u32 << (2 * (n - 8))) - 1) as u16
    } else {
        0
    };
    // Masked lanes are not read; `wrapping_add` as the second half may start past the
    // slice.
    let (x, y) = deinterleave(
        _mm512_maskz_loadu_ps(lo_mask, xy),
        _mm512_maskz_loadu_ps(hi_mask, xy.wrapping_add(16)),
    );
    let below = _mm512_set1_pd(-2.0);
    let zero = _mm512_setzero_pd();
    let mut out = [[0i32; 16]; 2];
    for (axis, v) in [x, y].into_iter().enumerate() {
        let above = _mm512_set1_pd((grid.dims[axis] + 1) as f64);
        let floored = floored_cells(v, grid.origin[axis], grid.inv_cell);
        for (half, floored) in floored.into_iter().enumerate() {
            let nan = _mm512_cmp_pd_mask::<_CMP_UNORD_Q>(floored, floored);
            let clamped = _mm512_min_pd(_mm512_max_pd(floored, below), above);
            let cell = _mm512_cvttpd_epi32(_mm512_mask_blend_pd(nan, clamped, zero));
            _mm256_storeu_si256(out[axis].as_mut_ptr().add(8 * half) as *mut __m256i, cell);
        }
    }
    for (l, c) in cells.iter_mut().enumerate().take(n) {
        *c = [out[0][l] as i64, out[1][l] as i64];
    }
}

/// [`super::push_near`], 16 candidates per iteration.
///
/// # Safety
/// The CPU must have AVX-512F.
#[target_feature(enable = "avx512f")]
unsafe fn push_near_unchecked(
    candidates: &[Vec2],
    first: u32,
    p: Vec2,
    r2: f32,
    skip: u32,
    buf: &mut Vec<u32>,
) {
    // `Vec2` is two f32 (x, y); the candidates are read as one flat f32 array.
    let xy = candidates.as_ptr() as *const f32;
    let n = candidates.len();
    let (px, py) = (_mm512_set1_ps(p.x), _mm512_set1_ps(p.y));
    let radius2 = _mm512_set1_ps(r2);
    let skip = _mm512_set1_epi32(skip as i32);
    let mut k = 0;
    while k < n {
        let left = n - k;
        // Lanes past the end are masked out of the loads, so nothing beyond the slice is
        // read, and out of the result.
        let valid: __mmask16 = if left >= 16 {
            0xffff
        } else {
            (1u32 << left) as u16 - 1
        };
        let lo_mask: __mmask16 = if left >= 8 {
            0xffff
        } else {
            (1u32 << (2 * left)) as u16 - 1
        };
        let hi_mask: __mmask16 = if left >= 16 {
            0xffff
        } else if left > 8 {
            (1u32 << (2 * (left - 8))) as u16 - 1
        } else {
            0
        };
        // `wrapping_add`: near the end the second half's address may lie past the slice
        // (its lanes are all masked then, and a masked lane is never read).
        let lo = _mm512_maskz_loadu_ps(lo_mask, xy.wrapping_add(2 * k));
        let hi = _mm512_maskz_loadu_ps(hi_mask, xy.wrapping_add(2 * k + 16));
        let (x, y) = deinterleave(lo, hi);
        let (dx, dy) = (_mm512_sub_ps(px, x), _mm512_sub_ps(py, y));
        // dx·dx + dy·dy with two roundings and no fused multiply-add, as glam's scalar
        // `length_squared`.
        let d2 = _mm512_add_ps(_mm512_mul_ps(dx, dx), _mm512_mul_ps(dy, dy));
        let index = indices_from(first + k as u32);
        let near = _mm512_mask_cmp_ps_mask::<_CMP_LT_OQ>(valid, d2, radius2)
            & _mm512_cmpneq_epi32_mask(index, skip);
        if near != 0 {
            buf.reserve(16);
            let len = buf.len();
            // Compress in a register, then store all 16 lanes: the compress *store* to
            // memory is microcoded on AMD Zen 4 (one per ~140 cycles) and made this
            // function a sixth of a 100k step there. The lanes past the survivors land
            // in the reserved capacity and are not counted.
            let packed = _mm512_maskz_compress_epi32(near, index);
            _mm512_storeu_si512(buf.as_mut_ptr().add(len) as *mut _, packed);
            buf.set_len(len + near.count_ones() as usize);
        }
        k += 16;
    }
}

/// Whether this CPU runs AVX-512F (detected once, then a cached read).
fn cpu_has_avx512f() -> bool {
    std::arch::is_x86_feature_detected!("avx512f")
}

/// [`super::Grid::point_key`] of the leading points of `points` into `keys`, 16 at a time, by
/// [`dense_keys_unchecked`]; returns how many (the caller keys the tail of fewer than 16).
///
/// # Panics
/// Where the CPU lacks AVX-512F, or the grid has more than `i32::MAX` cells.
pub(super) fn dense_keys(grid: &DenseGrid, points: &[Vec2], keys: &mut [u32]) -> usize {
    assert!(cpu_has_avx512f(), "the AVX-512 grid keys need AVX-512F");
    assert!(grid.key_count <= i32::MAX as usize);
    // SAFETY: both conditions were checked above.
    unsafe { dense_keys_unchecked(grid, points, keys) }
}

/// The cells of up to 16 query `points`, by [`block_cells_unchecked`].
///
/// # Panics
/// Where the CPU lacks AVX-512F.
pub(super) fn block_cells(grid: &DenseGrid, points: &[Vec2], cells: &mut [[i64; 2]; 16]) {
    assert!(cpu_has_avx512f(), "the AVX-512 query cells need AVX-512F");
    // SAFETY: checked above; a `DenseGrid` is dense.
    unsafe { block_cells_unchecked(grid, points, cells) }
}

/// The candidates within `r2` of `p`, by [`push_near_unchecked`].
///
/// # Panics
/// Where the CPU lacks AVX-512F.
pub(super) fn push_near(
    candidates: &[Vec2],
    first: u32,
    p: Vec2,
    r2: f32,
    skip: u32,
    buf: &mut Vec<u32>,
) {
    assert!(
        cpu_has_avx512f(),
        "the AVX-512 candidate filter needs AVX-512F"
    );
    // SAFETY: checked above.
    unsafe { push_near_unchecked(candidates, first, p, r2, skip, buf) }
}
