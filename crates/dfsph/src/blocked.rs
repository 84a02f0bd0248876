//! Fluid–fluid pairs in blocks of 16 particles, laid out for the pressure solver's SIMD passes.
//!
//! A Jacobi iteration walks every neighbour list twice (the density rate and the velocity
//! change), and each pair costs a load of its index and kernel gradient, a random read of the
//! neighbour's κ or velocity, and two multiply-adds. Walked one list at a time (CSR) that is a
//! chain of dependent scalar operations per particle. Here 16 consecutive particles (sorted by
//! cell, so their lists have similar lengths) are walked together: slot `k` of a block holds
//! the `k`-th neighbour of each of its 16 particles, so one AVX-512 gather reads 16 neighbour
//! values and one multiply-add handles 16 pairs. Shorter lists are padded with the particle's
//! own index and a zero gradient (9 % padding at 20k and 5 % at 80k on the dam break).
//!
//! The indices are stored relative to the block's first particle in 16 bits where every
//! neighbour lies within ±32k places of it (`SlotIndex`): the pressure solver's passes
//! then stream 10 bytes per entry instead of 12. With lists from a dense grid (sorted by
//! cell, row by row) a neighbour is at most about one row of cells away, so this holds
//! while a row of cells holds fewer than about 32,000 particles (840 in the 2 m wide
//! 100k-particle column); otherwise the indices stay absolute.
//!
//! Sums run over a particle's slots in list order in both the SIMD and the scalar path, so the
//! pair sums are deterministic; the two paths differ only in the rounding of multiply-adds.
//! The SIMD path is chosen at run time when the CPU has AVX-512F; the release binary stays
//! generic x86-64. How it reads the 16 neighbour values of a slot depends on the CPU
//! ([`Gather`]): on AMD, where gathers are slow, out of three windows of 32 consecutive
//! particles loaded once per block, since the neighbours of 16 particles sorted by cell
//! lie in three short runs (one per row of cells).

use glam::Vec2;
use std::ops::Range;

use rayon::prelude::*;

use crate::kernel::CubicSpline;
use crate::neighbors::NeighborLists;
use crate::simd::{lane_kernel, mul_add, SimdPath};

/// Particles per block: one AVX-512 vector of f32.
pub const LANES: usize = 16;

/// Neighbour indices and kernel gradients of every fluid–fluid pair, by block and slot.
#[derive(Clone, Debug, Default)]
pub struct BlockedPairs {
    /// Particles the blocks were built for.
    n: usize,
    /// Block `b` owns slots `slot_start[b]..slot_start[b + 1]`; slot `s` occupies entries
    /// `s·16 .. s·16 + 16` of the arrays below, one per lane.
    slot_start: Vec<u32>,
    /// Whether the indices are stored relative, in `relative`, or absolute, in `index`.
    narrow: bool,
    /// Neighbour index per slot and lane (< `n`, so every gather stays in bounds); empty
    /// while `narrow`.
    index: Vec<u32>,
    /// The same, as offsets from the block's first particle; empty unless `narrow`.
    relative: Vec<i16>,
    grad_x: Vec<f32>,
    grad_y: Vec<f32>,
    /// Per block, where its three windows start, or `None` where its neighbours do not fit
    /// in three ([`Gather::Windows`]); empty unless that way of reading is in use.
    window_start: Vec<Option<[u32; 3]>>,
    /// Per entry, the code that picks its neighbour out of its block's windows
    /// ([`window_codes`]); empty unless [`Gather::Windows`] is in use.
    window_code: Vec<u8>,
    /// The path the pair loops take ([`SimdPath`]), set by [`Self::prepare`].
    path: SimdPath,
    /// Whether that is [`SimdPath::Avx512`].
    avx512: bool,
    /// How the AVX-512 kernels read neighbour values; [`Gather::for_this_cpu`] unless set.
    gather: Option<Gather>,
    /// Set by [`Self::set_simd_path`]: the path to take instead of [`SimdPath::in_use`].
    forced_path: Option<SimdPath>,
    /// Set by [`Self::set_relative_indices`]: store absolute indices even where relative
    /// ones fit.
    absolute_only: bool,
}

/// A block's neighbour indices, as stored.
#[derive(Clone, Copy)]
enum Indices<'a> {
    Absolute(&'a [u32]),
    Relative(&'a [i16]),
}

/// A block's neighbour indices, to write.
enum IndicesMut<'a> {
    Absolute(&'a mut [u32]),
    Relative(&'a mut [i16]),
}

/// Runs `$body` with `$i` bound to the index slice of `$indices`, whichever type it has:
/// the body is compiled once per [`SlotIndex`] type, so the kernels it calls are too.
/// `with_indices!(mut ...)` does the same for an [`IndicesMut`].
macro_rules! with_indices {
    (mut $indices:expr, |$i:ident| $body:expr) => {
        match $indices {
            IndicesMut::Absolute($i) => $body,
            IndicesMut::Relative($i) => $body,
        }
    };
    ($indices:expr, |$i:ident| $body:expr) => {
        match $indices {
            Indices::Absolute($i) => $body,
            Indices::Relative($i) => $body,
        }
    };
}

/// A stored neighbour index: the particle index itself (`u32`), or its offset from the first
/// particle of its block (`i16`). The kernels read particle arrays from
/// `array[origin(first)..]` at [`Self::offset`], so both kinds take the same loads.
pub(crate) trait SlotIndex: Copy + Send + Sync + 'static {
    /// Stored as offsets from the block's first particle (16 bits, sign-extended).
    const RELATIVE: bool;
    /// Where the offsets count from in a block whose first particle is `first`.
    fn origin(first: usize) -> usize;
    /// The offset from [`Self::origin`].
    fn offset(self) -> isize;
    /// `j` stored for a block starting at `first`, or `None` where it does not fit.
    fn encode(j: u32, first: usize) -> Option<Self>;
    /// The particle index.
    #[inline]
    fn absolute(self, first: usize) -> usize {
        (Self::origin(first) as isize + self.offset()) as usize
    }
}

impl SlotIndex for u32 {
    const RELATIVE: bool = false;
    #[inline]
    fn origin(_: usize) -> usize {
        0
    }
    #[inline]
    fn offset(self) -> isize {
        self as isize
    }
    #[inline]
    fn encode(j: u32, _: usize) -> Option<Self> {
        Some(j)
    }
}

impl SlotIndex for i16 {
    const RELATIVE: bool = true;
    #[inline]
    fn origin(first: usize) -> usize {
        first
    }
    #[inline]
    fn offset(self) -> isize {
        self as isize
    }
    #[inline]
    fn encode(j: u32, first: usize) -> Option<Self> {
        i16::try_from(j as i64 - first as i64).ok()
    }
}

impl BlockedPairs {
    /// Number of blocks (the last may be partly filled).
    pub fn blocks(&self) -> usize {
        self.n.div_ceil(LANES)
    }

    /// Slots of all blocks together, times 16: the pair entries including padding.
    pub fn entries(&self) -> usize {
        self.grad_x.len()
    }

    /// Slots of blocks `0..b` together: a pass's cost up to block `b`, to balance shares.
    pub fn slots_before(&self, b: usize) -> usize {
        self.slot_start[b] as usize
    }

    /// Whether the indices are stored in 16 bits, relative to each block's first particle.
    pub fn relative_indices(&self) -> bool {
        self.narrow
    }

    /// Every entry's particle index, slot by slot, however stored.
    #[cfg(test)]
    fn absolute_indices(&self) -> Vec<u32> {
        (0..self.blocks())
            .flat_map(|b| {
                let (idx, _, _) = self.block(b);
                let first = b * LANES;
                with_indices!(idx, |idx| idx
                    .iter()
                    .map(|j| j.absolute(first) as u32)
                    .collect::<Vec<_>>())
            })
            .collect()
    }

    /// Store the indices relative where they fit (the default), or always absolute (tests
    /// and benchmarks compare the two). Takes effect at the next [`Self::prepare`].
    pub fn set_relative_indices(&mut self, on: bool) {
        self.absolute_only = !on;
    }

    /// Lay the blocks out for `lists` (fluid–fluid, self excluded): each block gets as many
    /// slots as its longest list. The entries are then written through [`Self::writers`].
    pub fn prepare(&mut self, lists: &NeighborLists) {
        let n = lists.len();
        self.n = n;
        self.path = self.forced_path.unwrap_or_else(SimdPath::in_use);
        self.avx512 = self.path == SimdPath::Avx512;
        let blocks = n.div_ceil(LANES);
        // In one parallel pass over the blocks: each block's width (its longest list), and
        // whether its lists fit relative indices. Ascending lists span from their first entry
        // to their last; a lane's padding is within its block.
        let try_relative = !self.absolute_only && lists.ascending();
        self.slot_start.resize(blocks + 1, 0);
        self.slot_start[0] = 0;
        self.narrow = self.slot_start[1..]
            .par_iter_mut()
            .enumerate()
            .map(|(b, width)| {
                let first = b * LANES;
                let particles = first..(first + LANES).min(n);
                *width = particles
                    .clone()
                    .map(|i| lists.offsets[i + 1] - lists.offsets[i])
                    .max()
                    .unwrap_or(0);
                try_relative
                    && particles.into_iter().all(|i| match lists.of(i) {
                        [] => true,
                        list => {
                            i16::encode(list[0], first).is_some()
                                && i16::encode(list[list.len() - 1], first).is_some()
                        }
                    })
            })
            // Not `all`: it would stop early and leave widths unwritten.
            .fold(|| true, |fit, block_fits| fit && block_fits)
            .reduce(|| true, |a, b| a && b)
            && try_relative;
        for b in 0..blocks {
            self.slot_start[b + 1] += self.slot_start[b];
        }
        let entries = self.slot_start[blocks] as usize * LANES;
        if self.narrow {
            self.index.clear();
            self.relative.resize(entries, 0);
        } else {
            self.relative.clear();
            self.index.resize(entries, 0);
        }
        self.grad_x.resize(entries, 0.0);
        self.grad_y.resize(entries, 0.0);
        if self.avx512 && self.gather() == Gather::Windows {
            self.window_start.resize(blocks, None);
            self.window_code.resize(entries, 0);
        } else {
            self.window_start.clear();
            self.window_code.clear();
        }
    }

    /// One writer per `blocks_per_writer` consecutive blocks, owning their entries, to fill in
    /// parallel after [`Self::prepare`]. Every lane of every block must be written, the lanes
    /// past the last particle included (with an empty list).
    pub fn writers(&mut self, blocks_per_writer: usize) -> Vec<BlockWriter<'_>> {
        let blocks = self.blocks();
        let n = self.n;
        let gather = self.gather();
        let mut out = Vec::with_capacity(blocks.div_ceil(blocks_per_writer));
        let (mut abs, mut rel, mut gx, mut gy) = (
            &mut self.index[..],
            &mut self.relative[..],
            &mut self.grad_x[..],
            &mut self.grad_y[..],
        );
        let windowed = !self.window_code.is_empty();
        let (mut starts, mut codes) = (&mut self.window_start[..], &mut self.window_code[..]);
        for first in (0..blocks).step_by(blocks_per_writer) {
            let last = (first + blocks_per_writer).min(blocks);
            let len = (self.slot_start[last] - self.slot_start[first]) as usize * LANES;
            let a = if self.narrow {
                let (a, rest) = std::mem::take(&mut rel).split_at_mut(len);
                rel = rest;
                IndicesMut::Relative(a)
            } else {
                let (a, rest) = std::mem::take(&mut abs).split_at_mut(len);
                abs = rest;
                IndicesMut::Absolute(a)
            };
            let (bx, rest_x) = std::mem::take(&mut gx).split_at_mut(len);
            let (by, rest_y) = std::mem::take(&mut gy).split_at_mut(len);
            (gx, gy) = (rest_x, rest_y);
            let windows = windowed.then(|| {
                let (s, rest_s) = std::mem::take(&mut starts).split_at_mut(last - first);
                let (c, rest_c) = std::mem::take(&mut codes).split_at_mut(len);
                (starts, codes) = (rest_s, rest_c);
                WindowsMut {
                    starts: s,
                    codes: c,
                }
            });
            out.push(BlockWriter {
                n,
                avx512: self.avx512,
                path: self.path,
                gather,
                slot_start: &self.slot_start,
                first_block: first,
                base: self.slot_start[first] as usize,
                index: a,
                grad_x: bx,
                grad_y: by,
                windows,
            });
        }
        out
    }

    /// Rebuild from CSR lists and their per-pair gradients `∇W_ij` (in list order).
    pub fn build(&mut self, lists: &NeighborLists, grads: &[Vec2]) {
        assert_eq!(grads.len(), lists.pair_count());
        self.prepare(lists);
        let (n, lanes) = (self.n, self.blocks() * LANES);
        self.writers(32)
            .into_par_iter()
            .enumerate()
            .for_each(|(w, mut writer)| {
                for i in w * 32 * LANES..((w + 1) * 32 * LANES).min(lanes) {
                    let (list, lane_grads) = if i < n {
                        (lists.of(i), &grads[lists.range(i)])
                    } else {
                        (&[][..], &[][..])
                    };
                    let mut g = lane_grads.iter();
                    writer.write_lane(i, list, |_| *g.next().unwrap());
                    if i % LANES == LANES - 1 {
                        writer.index_windows(i / LANES);
                    }
                }
            });
    }

    /// Block `b`'s indices and gradients, slot by slot.
    #[inline(always)]
    fn block(&self, b: usize) -> (Indices<'_>, &[f32], &[f32]) {
        match self.indices() {
            Indices::Relative(all) => {
                let (idx, gx, gy) = self.block_of(all, b);
                (Indices::Relative(idx), gx, gy)
            }
            Indices::Absolute(all) => {
                let (idx, gx, gy) = self.block_of(all, b);
                (Indices::Absolute(idx), gx, gy)
            }
        }
    }

    /// The entries of block `b` in the per-entry arrays.
    #[inline(always)]
    fn entry_range(&self, b: usize) -> std::ops::Range<usize> {
        self.slot_start[b] as usize * LANES..self.slot_start[b + 1] as usize * LANES
    }

    /// Block `b`'s part of `idx` (every block's indices, as [`Self::indices`] holds them)
    /// and of the gradients.
    #[inline(always)]
    fn block_of<'a, I>(&'a self, idx: &'a [I], b: usize) -> (&'a [I], &'a [f32], &'a [f32]) {
        let e = self.entry_range(b);
        (&idx[e.clone()], &self.grad_x[e.clone()], &self.grad_y[e])
    }

    /// Every block's indices, as stored.
    #[inline(always)]
    fn indices(&self) -> Indices<'_> {
        if self.narrow {
            Indices::Relative(&self.relative)
        } else {
            Indices::Absolute(&self.index)
        }
    }

    /// The particles of the consecutive blocks `blocks`.
    fn particles_of(&self, blocks: &Range<usize>) -> Range<usize> {
        let end = (blocks.end * LANES).min(self.n);
        (blocks.start * LANES).min(end)..end
    }

    /// Block `b`'s windows and codes, where [`Gather::Windows`] is in use and its neighbours
    /// fit.
    #[inline(always)]
    fn windows(&self, b: usize) -> Option<Windows<'_>> {
        let starts = (*self.window_start.get(b)?)?;
        let e = self.entry_range(b);
        Some(Windows {
            starts,
            codes: &self.window_code[e],
        })
    }

    /// Blocks whose neighbours are read through windows.
    #[cfg(test)]
    fn windowed_blocks(&self) -> usize {
        self.window_start.iter().filter(|w| w.is_some()).count()
    }

    /// `Σ_j s_j ∇W_ij` for the 16 particles of block `b` (x and y components per lane).
    #[inline]
    pub fn weighted_gradient_sums(&self, b: usize, s: &[f32]) -> ([f32; LANES], [f32; LANES]) {
        assert!(s.len() >= self.n, "one value per particle");
        let (idx, gx, gy) = self.block(b);
        let first = b * LANES;
        with_indices!(idx, |idx| {
            #[cfg(target_arch = "x86_64")]
            if self.avx512 {
                // SAFETY: the CPU has AVX-512F (checked in `prepare`), and every index is
                // below `self.n <= s.len()` (checked when written, by `BlockWriter`).
                return unsafe {
                    avx512::weighted_gradient_sums(
                        idx,
                        first,
                        gx,
                        gy,
                        s,
                        self.gather(),
                        self.windows(b),
                    )
                };
            }
            // SAFETY: every index is below `self.n <= s.len()`, and the path is one this
            // CPU runs.
            unsafe {
                lane_kernel!(
                    self.path,
                    lane_weighted_gradient_sums::<_>(idx, first, gx, gy, s)
                )
            }
        })
    }

    /// `Σ_j v_j·∇W_ij` for the 16 particles of block `b`.
    #[inline]
    pub fn velocity_gradient_dots(&self, b: usize, v: &[Vec2]) -> [f32; LANES] {
        assert!(v.len() >= self.n, "one velocity per particle");
        let (idx, gx, gy) = self.block(b);
        let first = b * LANES;
        with_indices!(idx, |idx| {
            #[cfg(target_arch = "x86_64")]
            if self.avx512 {
                // SAFETY: as above; `Vec2` is two consecutive f32, so component c of
                // particle j is element 2j + c of the flat array, below 2·v.len().
                return unsafe {
                    avx512::velocity_gradient_dots(
                        idx,
                        first,
                        gx,
                        gy,
                        v,
                        self.gather(),
                        self.windows(b),
                    )
                };
            }
            // SAFETY: as above.
            unsafe {
                lane_kernel!(
                    self.path,
                    lane_velocity_gradient_dots::<_>(idx, first, gx, gy, v)
                )
            }
        })
    }

    /// Particles of block `b`: 16, fewer in the last block.
    #[inline]
    fn lanes_of(&self, b: usize) -> usize {
        self.n.saturating_sub(b * LANES).min(LANES)
    }

    /// The residual pass of one Jacobi iteration over block `b` (see [`ResidualTerms`]):
    /// writes the relative density rates `r_i` of the block's particles into `rate` and
    /// their `Δκ_i` into `delta` (one entry per particle of the block in each), and their
    /// residuals `e_i` into `errors`, lane by lane (0 in the lanes past the last particle;
    /// [`crate::reduce::fold_block_sums`] sums them).
    #[inline]
    pub fn residual_block(
        &self,
        b: usize,
        vel: &[Vec2],
        terms: &ResidualTerms,
        delta: &mut [f32],
        rate: &mut [f32],
        errors: &mut [f32; LANES],
    ) {
        let lanes = self.lanes_of(b);
        assert!(vel.len() >= self.n && terms.holds(self.n));
        assert!(delta.len() == lanes && rate.len() == lanes);
        let (idx, gx, gy) = self.block(b);
        let first = b * LANES;
        with_indices!(idx, |idx| {
            #[cfg(target_arch = "x86_64")]
            if self.avx512 {
                // SAFETY: AVX-512F is present (checked in `prepare`), every index is below
                // `self.n <= vel.len()` (checked when written), and the per-particle arrays
                // hold the block's `lanes` particles from `b·16` on (asserted above).
                return unsafe {
                    avx512::residual_block(
                        idx,
                        gx,
                        gy,
                        vel,
                        first,
                        terms,
                        delta,
                        rate,
                        errors,
                        self.gather(),
                        self.windows(b),
                    )
                };
            }
            // SAFETY: every index is below `self.n <= vel.len()`, the per-particle arrays
            // hold the block's particles (asserted above), and the path is one this CPU runs.
            unsafe {
                lane_kernel!(
                    self.path,
                    lane_residual_block::<_>(idx, gx, gy, vel, first, terms, delta, rate, errors)
                )
            }
        })
    }

    /// Apply the stiffness field `kappa` to the velocities of block `b`'s particles (`vel`,
    /// one entry per particle of the block): `Δv_i = −(κ_i·g_i + V·Σ_j κ_j ∇W_ij)` with
    /// `g_i = grad_sum[i]` (TVCG 2017 eq. 8–9 with the walls' share cached in `g_i`), and add
    /// `κ_i` to `total` (the block's entries) when given.
    #[inline]
    pub fn apply_block(
        &self,
        b: usize,
        volume: f32,
        kappa: &[f32],
        grad_sum: &[Vec2],
        vel: &mut [Vec2],
        total: Option<&mut [f32]>,
    ) {
        let lanes = self.lanes_of(b);
        assert!(kappa.len() >= self.n && grad_sum.len() >= self.n && vel.len() == lanes);
        assert!(total.as_ref().is_none_or(|t| t.len() == lanes));
        let (idx, gx, gy) = self.block(b);
        let first = b * LANES;
        with_indices!(idx, |idx| {
            #[cfg(target_arch = "x86_64")]
            if self.avx512 {
                // SAFETY: AVX-512F is present, every index is below `self.n <= kappa.len()`,
                // and `kappa`, `grad_sum` hold the block's particles (asserted above).
                return unsafe {
                    avx512::apply_block(
                        idx,
                        gx,
                        gy,
                        kappa,
                        first,
                        grad_sum,
                        volume,
                        vel,
                        total,
                        self.gather(),
                        self.windows(b),
                    )
                };
            }
            // SAFETY: every index is below `self.n <= kappa.len()`, `kappa` and `grad_sum`
            // hold the block's particles (asserted above), and the path is one this CPU runs.
            unsafe {
                lane_kernel!(
                    self.path,
                    lane_apply_block::<_>(idx, gx, gy, kappa, first, grad_sum, volume, vel, total)
                )
            }
        })
    }

    /// [`Self::residual_block`] for the consecutive blocks `blocks`: `delta` and `rate` hold
    /// one entry per particle of the blocks, `errors` one row per block. The same results,
    /// with the per-block set-up inside one SIMD call instead of one call per block.
    #[inline]
    pub fn residual_blocks(
        &self,
        blocks: Range<usize>,
        vel: &[Vec2],
        terms: &ResidualTerms,
        delta: &mut [f32],
        rate: &mut [f32],
        errors: &mut [[f32; LANES]],
    ) {
        let particles = self.particles_of(&blocks);
        assert!(blocks.end <= self.blocks() && errors.len() == blocks.len());
        assert!(delta.len() == particles.len() && rate.len() == particles.len());
        assert!(vel.len() >= self.n && terms.holds(self.n));
        #[cfg(target_arch = "x86_64")]
        if self.avx512 {
            // SAFETY: AVX-512F is present (checked in `prepare`), every index is below
            // `self.n <= vel.len()` (checked when written), the per-particle arrays hold all
            // particles (asserted above), and `delta`, `rate` and `errors` the blocks'.
            return with_indices!(self.indices(), |idx| unsafe {
                avx512::residual_blocks(self, idx, blocks, vel, terms, delta, rate, errors)
            });
        }
        // SAFETY: as above, and the path is one this CPU runs.
        with_indices!(self.indices(), |idx| unsafe {
            lane_kernel!(
                self.path,
                lane_residual_blocks::<_>(self, idx, blocks, vel, terms, delta, rate, errors)
            )
        })
    }

    /// [`Self::apply_block`] for the consecutive blocks `blocks`: `vel` and `total`, when
    /// given, hold one entry per particle of the blocks. The same results, with the
    /// per-block set-up inside one SIMD call instead of one call per block.
    #[inline]
    pub fn apply_blocks(
        &self,
        blocks: Range<usize>,
        volume: f32,
        kappa: &[f32],
        grad_sum: &[Vec2],
        vel: &mut [Vec2],
        total: Option<&mut [f32]>,
    ) {
        let particles = self.particles_of(&blocks);
        assert!(blocks.end <= self.blocks() && vel.len() == particles.len());
        assert!(kappa.len() >= self.n && grad_sum.len() >= self.n);
        assert!(total.as_ref().is_none_or(|t| t.len() == particles.len()));
        #[cfg(target_arch = "x86_64")]
        if self.avx512 {
            // SAFETY: AVX-512F is present, every index is below `self.n <= kappa.len()`,
            // `kappa` and `grad_sum` hold all particles, `vel` and `total` the blocks'
            // (asserted above).
            return with_indices!(self.indices(), |idx| unsafe {
                avx512::apply_blocks(self, idx, blocks, volume, kappa, grad_sum, vel, total)
            });
        }
        // SAFETY: as above, and the path is one this CPU runs.
        with_indices!(self.indices(), |idx| unsafe {
            lane_kernel!(
                self.path,
                lane_apply_blocks::<_>(self, idx, blocks, volume, kappa, grad_sum, vel, total)
            )
        })
    }

    /// `value(i)` for each lane's particle `i` of block `b`. Lanes past the last particle
    /// take particle 0's value (zero when there are no particles); their sums are not used.
    fn per_lane(&self, b: usize, value: impl Fn(usize) -> Vec2) -> [Vec2; LANES] {
        std::array::from_fn(|l| {
            let i = b * LANES + l;
            if i < self.n {
                value(i)
            } else if self.n > 0 {
                value(0)
            } else {
                Vec2::ZERO
            }
        })
    }

    /// `Σ_j V·W(x̃_i − x̃_j)` over the fluid neighbours of the 16 particles of block `b`, at
    /// the positions `x̃ = x + Δt·v` a step of `dt` moves them to (the linearisation check,
    /// `solver::unseen_compression`), started from `start` per lane. Pairs whose advected
    /// distance reaches the support add nothing. Per lane the terms are added in list order,
    /// with the scalar expressions' roundings, so both paths give identical bits.
    #[allow(clippy::too_many_arguments)]
    #[inline]
    pub fn advected_kernel_sums(
        &self,
        b: usize,
        pos: &[Vec2],
        vel: &[Vec2],
        dt: f32,
        kernel: &CubicSpline,
        volume: f32,
        start: f32,
    ) -> [f32; LANES] {
        assert!(pos.len() >= self.n && vel.len() >= self.n);
        let (idx, _, _) = self.block(b);
        let first = b * LANES;
        let xi = self.per_lane(b, |i| pos[i] + dt * vel[i]);
        with_indices!(idx, |idx| {
            #[cfg(target_arch = "x86_64")]
            if self.avx512 {
                // SAFETY: AVX-512F is present (checked in `prepare`), and every index is
                // below `self.n <= pos.len(), vel.len()` (checked when written).
                return unsafe {
                    avx512::advected_kernel_sums(
                        first,
                        idx,
                        &xi,
                        pos,
                        vel,
                        dt,
                        kernel,
                        volume,
                        start,
                        self.gather(),
                        self.windows(b),
                    )
                };
            }
            let path = self.path;
            // SAFETY: every index is below `self.n <= pos.len(), vel.len()` (checked when
            // written), and the path is one this CPU runs.
            unsafe {
                lane_kernel!(
                    path,
                    lane_advected_kernel_sums::<_>(
                        idx, first, &xi, pos, vel, dt, kernel, volume, start
                    )
                )
            }
        })
    }

    /// The fluid–fluid viscosity sums of the 16 particles of block `b`, in list order:
    /// `Σ_j −(v_i − v_j)·W_ij` (XSPH) and, with `laplacian`, `Σ_j ∇W_ij·(v_ij·x_ij)/(|x_ij|² +
    /// eps2)` (the Laplacian model; zero otherwise). `W_ij` is evaluated from the positions,
    /// `∇W_ij` read from the blocks. The scalar expressions' roundings are kept, so both paths
    /// give identical bits.
    #[allow(clippy::too_many_arguments)]
    #[inline]
    pub fn viscosity_sums(
        &self,
        b: usize,
        pos: &[Vec2],
        vel: &[Vec2],
        kernel: &CubicSpline,
        eps2: f32,
        laplacian: bool,
    ) -> ([Vec2; LANES], [Vec2; LANES]) {
        assert!(pos.len() >= self.n && vel.len() >= self.n);
        let (idx, gx, gy) = self.block(b);
        let first = b * LANES;
        let (xi, vi) = (self.per_lane(b, |i| pos[i]), self.per_lane(b, |i| vel[i]));
        with_indices!(idx, |idx| {
            #[cfg(target_arch = "x86_64")]
            if self.avx512 {
                // SAFETY: AVX-512F is present (checked in `prepare`), the slices hold whole
                // slots, and every index is below `self.n <= pos.len(), vel.len()`.
                return unsafe {
                    avx512::viscosity_sums(
                        first,
                        idx,
                        gx,
                        gy,
                        &xi,
                        &vi,
                        pos,
                        vel,
                        kernel,
                        eps2,
                        laplacian,
                        self.gather(),
                        self.windows(b),
                    )
                };
            }
            let path = self.path;
            // SAFETY: the slices hold whole slots, every index is below `self.n <=
            // pos.len(), vel.len()`, and the path is one this CPU runs.
            unsafe {
                lane_kernel!(
                    path,
                    lane_viscosity_sums::<_>(
                        idx, first, gx, gy, &xi, &vi, pos, vel, kernel, eps2, laplacian
                    )
                )
            }
        })
    }

    /// Take `path` instead of [`SimdPath::in_use`] (tests and benchmarks compare paths). It
    /// must be one this CPU runs ([`SimdPath::available`]).
    pub fn set_simd_path(&mut self, path: SimdPath) {
        assert!(path.available(), "this CPU cannot run the {path} path");
        self.forced_path = Some(path);
        self.path = path;
        self.avx512 = path == SimdPath::Avx512;
    }

    /// The path the pair loops take.
    pub fn simd_path(&self) -> SimdPath {
        self.path
    }

    /// Read neighbour values the given way in the SIMD kernels rather than the one
    /// [`Gather::for_this_cpu`] picks (tests and benchmarks compare the two).
    pub fn set_gather(&mut self, gather: Gather) {
        self.gather = Some(gather);
    }

    fn gather(&self) -> Gather {
        self.gather.unwrap_or_else(Gather::for_this_cpu)
    }
}

/// Writes the lanes of some consecutive blocks of a [`BlockedPairs`].
pub struct BlockWriter<'a> {
    /// Particles of the whole layout.
    n: usize,
    /// Whether to run the AVX-512 kernels.
    avx512: bool,
    /// The path the pair loops take.
    path: SimdPath,
    gather: Gather,
    slot_start: &'a [u32],
    /// The writer's first block.
    first_block: usize,
    /// First slot of the writer's first block.
    base: usize,
    index: IndicesMut<'a>,
    grad_x: &'a mut [f32],
    grad_y: &'a mut [f32],
    /// The windows of the writer's blocks, where [`Gather::Windows`] is in use.
    windows: Option<WindowsMut<'a>>,
}

/// The window starts (per block) and codes (per entry) of some consecutive blocks, to write.
struct WindowsMut<'a> {
    starts: &'a mut [Option<[u32; 3]>],
    codes: &'a mut [u8],
}

impl BlockWriter<'_> {
    /// Block `b`'s entries within the writer's arrays.
    fn entries(&self, b: usize) -> std::ops::Range<usize> {
        let first = self.slot_start[b] as usize - self.base;
        let width = (self.slot_start[b + 1] - self.slot_start[b]) as usize;
        first * LANES..(first + width) * LANES
    }

    /// Write particle `i`'s neighbour indices `list` into its lane, padded up to the block's
    /// width with the particle itself (the block's first particle for a lane past the last
    /// particle). Every index is checked against the particle count here, once, so that the
    /// gathers that read through these indices stay in bounds.
    fn lane_indices(&mut self, i: usize, list: &[u32]) {
        let e = self.entries(i / LANES);
        assert!(
            list.len() * LANES <= e.len(),
            "the blocks were laid out for other lists"
        );
        assert!(
            list.iter().all(|&j| (j as usize) < self.n),
            "neighbour index out of range"
        );
        with_indices!(mut &mut self.index, |index| write_lane_indices(
            &mut index[e],
            i,
            self.n,
            list
        ))
    }

    /// Find block `b`'s windows and write its codes ([`Gather::Windows`]), once all its
    /// lanes' indices are written.
    fn index_windows(&mut self, b: usize) {
        let e = self.entries(b);
        let Some(WindowsMut { starts, codes }) = &mut self.windows else {
            return;
        };
        let (first, n) = (b * LANES, self.n);
        let codes = &mut codes[e.clone()];
        #[cfg(target_arch = "x86_64")]
        {
            // SAFETY: windows are only set up where the CPU has AVX-512F (`prepare`), and
            // `codes` holds one byte per entry of the block's indices.
            starts[b - self.first_block] = unsafe {
                match &self.index {
                    IndicesMut::Absolute(index) => avx512::window_codes(&index[e], first, n, codes),
                    IndicesMut::Relative(index) => avx512::window_codes(&index[e], first, n, codes),
                }
            };
        }
    }

    /// Write particle `i`'s lane: its neighbours `list` with gradients `grad(j)` (called once
    /// per neighbour, in list order), then padding (the particle itself, zero gradient) up to
    /// the block's width. `i` must lie in one of the writer's blocks.
    #[inline]
    pub fn write_lane(&mut self, i: usize, list: &[u32], mut grad: impl FnMut(u32) -> Vec2) {
        self.lane_indices(i, list);
        let e = self.entries(i / LANES);
        let lane = i % LANES;
        let slots = self.grad_x[e.clone()]
            .chunks_exact_mut(LANES)
            .zip(self.grad_y[e].chunks_exact_mut(LANES));
        for (s, (x, y)) in slots.enumerate() {
            let g = list.get(s).map_or(Vec2::ZERO, |&j| grad(j));
            x[lane] = g.x;
            y[lane] = g.y;
        }
    }

    /// Fill block `b` from the fluid lists and positions: the neighbour indices, and
    /// `∇W(x_i − x_j)` for every pair, evaluated 16 pairs at a time where the CPU allows.
    /// Returns the per-lane sums of the density pass over the fluid neighbours, started from
    /// `start` (the particle's own `V·W(0)`): the same expressions, in the same order, as
    /// summing `V·W_ij`, `V·∇W_ij` and `|V·∇W_ij|²` pair by pair with
    /// [`CubicSpline::w_and_grad`], so both paths give identical bits.
    pub fn fill_block(
        &mut self,
        b: usize,
        lists: &NeighborLists,
        pos: &[Vec2],
        kernel: &CubicSpline,
        volume: f32,
        start: f32,
    ) -> FluidSums {
        assert!(pos.len() >= self.n && lists.len() == self.n);
        let e = self.entries(b);
        let width = e.len() / LANES;
        let first = b * LANES;
        let mut lane_lists = [&[][..]; LANES];
        let mut xi = [0.0f32; LANES];
        let mut yi = [0.0f32; LANES];
        for (lane, list) in lane_lists.iter_mut().enumerate() {
            let i = first + lane;
            if i < self.n {
                *list = lists.of(i);
                (xi[lane], yi[lane]) = (pos[i].x, pos[i].y);
            }
        }
        let lens: [u32; LANES] = std::array::from_fn(|l| lane_lists[l].len() as u32);
        #[cfg(target_arch = "x86_64")]
        if self.avx512 {
            assert!(
                lens.iter().all(|&len| len as usize <= width),
                "the blocks were laid out for other lists"
            );
            let (gx, gy) = (&mut self.grad_x[e.clone()], &mut self.grad_y[e.clone()]);
            let lists = avx512::LaneLists::new(&lane_lists, first, self.n);
            // SAFETY: AVX-512F is present (checked in `prepare`), the slices hold `width`
            // slots, no list is longer than that (asserted above), and `pos` holds the `n`
            // particles the kernel checks every index against.
            let sums = unsafe {
                with_indices!(mut &mut self.index, |index| avx512::fill_fluid_block(
                    &lists,
                    &mut index[e],
                    gx,
                    gy,
                    &xi,
                    &yi,
                    pos,
                    kernel,
                    volume,
                    start,
                    self.gather,
                ))
            };
            self.index_windows(b);
            return sums;
        }
        for (lane, list) in lane_lists.iter().enumerate() {
            self.lane_indices(first + lane, list);
        }
        self.index_windows(b);
        let (gx, gy) = (&mut self.grad_x[e.clone()], &mut self.grad_y[e.clone()]);
        let idx = match &self.index {
            IndicesMut::Absolute(index) => Indices::Absolute(&index[e]),
            IndicesMut::Relative(index) => Indices::Relative(&index[e]),
        };
        let path = self.path;
        // SAFETY: the slices hold `width` slots, every index was checked against
        // `self.n <= pos.len()` when written (`lane_indices`), and the path is one this CPU
        // runs.
        with_indices!(idx, |idx| unsafe {
            lane_kernel!(
                path,
                lane_fluid_sums::<_>(
                    idx, first, width, gx, gy, &lens, &xi, &yi, pos, kernel, volume, start,
                )
            )
        })
    }
}

/// Particles in a window: the 32 values one two-vector permute picks from.
const WINDOW: usize = 32;

/// A block's three windows ([`Gather::Windows`]): where each starts (an index of the
/// particle arrays), and per entry a one-byte code, the window in bits 5–6 and the place
/// in it in bits 0–4.
#[derive(Clone, Copy)]
pub(crate) struct Windows<'a> {
    starts: [u32; 3],
    codes: &'a [u8],
}

/// What lane `i` holds past the end of its list: the particle itself, or for a lane past the
/// last particle `n - 1`, its block's first particle (a valid index, and one a relative
/// index can always express).
#[inline]
fn padding(i: usize, n: usize) -> u32 {
    (if i < n { i } else { i - i % LANES }) as u32
}

/// Write particle `i`'s lane of a block (`index`, whole slots): its neighbours `list`, then
/// padding with the particle itself, or with the block's first particle for a lane past the
/// last particle `n - 1`. The indices must be below `n`.
fn write_lane_indices<I: SlotIndex>(index: &mut [I], i: usize, n: usize, list: &[u32]) {
    let (first, lane) = (i - i % LANES, i % LANES);
    let pad = padding(i, n);
    let encode = |j| I::encode(j, first).expect("a neighbour too far for 16-bit indices");
    let pad = encode(pad);
    for (s, slot) in index.chunks_exact_mut(LANES).enumerate() {
        slot[lane] = list.get(s).map_or(pad, |&j| encode(j));
    }
}

/// [`BlockWriter::fill_block`]'s pair loop on the lane path, slot by slot: each lane's
/// neighbour position, `∇W` (written to `gx`, `gy`; zero past the lane's list) and the
/// density sums, in list order with [`CubicSpline::w_and_grad`]'s operations, so every path
/// gives the same bits. `FUSED` only selects how the code is compiled ([`lane_kernel`]).
///
/// # Safety
/// `idx`, `gx` and `gy` must hold `width` whole slots, and every index be below `pos.len()`.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
unsafe fn lane_fluid_sums<I: SlotIndex, const FUSED: bool>(
    idx: &[I],
    first: usize,
    width: usize,
    gx: &mut [f32],
    gy: &mut [f32],
    lens: &[u32; LANES],
    xi: &[f32; LANES],
    yi: &[f32; LANES],
    pos: &[Vec2],
    kernel: &CubicSpline,
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
unsafe fn lane_advected_kernel_sums<I: SlotIndex, const FUSED: bool>(
    idx: &[I],
    first: usize,
    xi: &[Vec2; LANES],
    pos: &[Vec2],
    vel: &[Vec2],
    dt: f32,
    kernel: &CubicSpline,
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
unsafe fn lane_viscosity_sums<I: SlotIndex, const FUSED: bool>(
    idx: &[I],
    first: usize,
    gx: &[f32],
    gy: &[f32],
    xi: &[Vec2; LANES],
    vi: &[Vec2; LANES],
    pos: &[Vec2],
    vel: &[Vec2],
    kernel: &CubicSpline,
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
unsafe fn lane_residual_block<I: SlotIndex, const FUSED: bool>(
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
unsafe fn lane_apply_block<I: SlotIndex, const FUSED: bool>(
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
unsafe fn lane_residual_blocks<I: SlotIndex, const FUSED: bool>(
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
unsafe fn lane_apply_blocks<I: SlotIndex, const FUSED: bool>(
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

/// The per-particle terms of a Jacobi iteration's residual pass
/// ([`BlockedPairs::residual_block`]). Particle i's relative density rate is
/// `r_i = v_i·g_i − V·Σ_j v_j·∇W_ij − f_i` (`g` = `grad_sum`, `f` = `wall_flux`: TVCG 2017
/// eq. 7 with the walls' share cached), its residual `e_i = max(source_i + rate_scale·r_i, 0)`
/// and its stiffness increment `Δκ_i = e_i·factor_i·increment_scale`.
#[derive(Clone, Copy, Debug)]
pub struct ResidualTerms<'a> {
    /// Fluid particle volume V, m².
    pub volume: f32,
    pub grad_sum: &'a [Vec2],
    pub wall_flux: &'a [f32],
    /// The part of the residual that does not depend on the velocities.
    pub source: &'a [f32],
    pub rate_scale: f32,
    /// The DFSPH factor a_i.
    pub factor: &'a [f32],
    pub increment_scale: f32,
}

impl ResidualTerms<'_> {
    /// Whether every per-particle array holds at least `n` particles.
    fn holds(&self, n: usize) -> bool {
        [
            self.grad_sum.len(),
            self.wall_flux.len(),
            self.source.len(),
            self.factor.len(),
        ]
        .iter()
        .all(|&len| len >= n)
    }
}

/// Per-lane sums of the density pass over a block's fluid neighbours.
#[derive(Clone, Copy, Debug, Default)]
pub struct FluidSums {
    /// `V·W(0) + Σ_j V·W_ij`.
    pub density: [f32; LANES],
    /// `Σ_j V·∇W_ij`, x and y.
    pub grad_x: [f32; LANES],
    pub grad_y: [f32; LANES],
    /// `Σ_j |V·∇W_ij|²`.
    pub grad_sq: [f32; LANES],
}

/// How the AVX-512 pair loops read the 16 neighbour values of a slot. Both read the same
/// values, so results do not depend on the choice.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Gather {
    /// One gather instruction (two for `(x, y)` pairs): the fast way on Intel.
    #[default]
    Instruction,
    /// Sixteen ordinary loads into a buffer, then one vector load. AMD Zen 4 runs gathers as
    /// long microcoded sequences: there a slot's 16 loads took 4.3 ns against 5.2 ns for a
    /// gather of 16 f32, and 5.6 ns against 9.6 ns for 16 `(x, y)` pairs (one thread, a
    /// synthetic loop over 80k particles' slots).
    Loads,
    /// Where a block's neighbours fit, in every pass after the density pass (whose pair
    /// loop writes the indices): the block's three windows of 32 consecutive particles are
    /// loaded once per pass as whole vectors, and each slot's 16 values are picked out of
    /// them by permutes through one-byte codes. In the density pass, and for
    /// blocks that do not fit, as [`Gather::Loads`]. On Zen 4 this took the 5k benchmark
    /// from 1.70 to 1.36 s (two threads) and the 100k column's run time down by 15 %, then
    /// 4 % more with the windows in the viscosity and linearisation passes.
    Windows,
}

impl Gather {
    /// The faster way on this CPU: [`Gather::Windows`] on AMD processors, else
    /// [`Gather::Instruction`].
    pub fn for_this_cpu() -> Gather {
        #[cfg(target_arch = "x86_64")]
        {
            static AMD: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
            let amd = *AMD.get_or_init(|| {
                // Leaf 0: the vendor string, "AuthenticAMD" in ebx, edx, ecx.
                let id = std::arch::x86_64::__cpuid(0);
                (id.ebx, id.edx, id.ecx) == (0x6874_7541, 0x6974_6e65, 0x444d_4163)
            });
            if amd {
                return Gather::Windows;
            }
        }
        Gather::Instruction
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

/// `Σ_j s_j ∇W_ij` per lane, x and y, slot by slot in list order: the lane kernel of
/// [`BlockedPairs::weighted_gradient_sums`] (the same sums as the AVX-512 kernel's, with
/// fused multiply-adds where `FUSED`).
///
/// # Safety
/// The three slices must hold whole slots, and every index must be below `s.len()`.
#[inline(always)]
unsafe fn lane_weighted_gradient_sums<I: SlotIndex, const FUSED: bool>(
    idx: &[I],
    first: usize,
    gx: &[f32],
    gy: &[f32],
    s: &[f32],
) -> ([f32; LANES], [f32; LANES]) {
    let mut ax = [0.0f32; LANES];
    let mut ay = [0.0f32; LANES];
    for ((slot, x), y) in idx
        .chunks_exact(LANES)
        .zip(gx.chunks_exact(LANES))
        .zip(gy.chunks_exact(LANES))
    {
        let sj = gather(s, first, slot);
        for l in 0..LANES {
            ax[l] = mul_add::<FUSED>(sj[l], x[l], ax[l]);
            ay[l] = mul_add::<FUSED>(sj[l], y[l], ay[l]);
        }
    }
    (ax, ay)
}

/// `Σ_j v_j·∇W_ij` per lane: x and y summed apart, slot by slot in list order, then added —
/// the lane kernel of [`BlockedPairs::velocity_gradient_dots`] (the AVX-512 kernel's order,
/// with fused multiply-adds where `FUSED`).
///
/// # Safety
/// The three slices must hold whole slots, and every index must be below `v.len()`.
#[inline(always)]
unsafe fn lane_velocity_gradient_dots<I: SlotIndex, const FUSED: bool>(
    idx: &[I],
    first: usize,
    gx: &[f32],
    gy: &[f32],
    v: &[Vec2],
) -> [f32; LANES] {
    let mut ax = [0.0f32; LANES];
    let mut ay = [0.0f32; LANES];
    for ((slot, x), y) in idx
        .chunks_exact(LANES)
        .zip(gx.chunks_exact(LANES))
        .zip(gy.chunks_exact(LANES))
    {
        let vj = gather(v, first, slot);
        for l in 0..LANES {
            ax[l] = mul_add::<FUSED>(vj[l].x, x[l], ax[l]);
            ay[l] = mul_add::<FUSED>(vj[l].y, y[l], ay[l]);
        }
    }
    std::array::from_fn(|l| ax[l] + ay[l])
}

#[cfg(target_arch = "x86_64")]
pub(crate) mod avx512 {
    use super::{FluidSums, Gather, SlotIndex, Windows, LANES, WINDOW};
    use crate::kernel::CubicSpline;
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
                pad: std::array::from_fn(|l| super::padding(first + l, n)),
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
    /// as [`CubicSpline::w_and_grad`] and the scalar sums do.
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
        kernel: &CubicSpline,
        volume: f32,
        start: f32,
        gather: Gather,
    ) -> FluidSums {
        assert!(pos.len() >= lists.n);
        let (count, first) = (_mm512_set1_epi32(lists.n as i32), lists.first as i32);
        let (k, l, inv_h) = kernel.constants();
        let base = pos.as_ptr() as *const f32;
        let (xi, yi) = (_mm512_loadu_ps(xi.as_ptr()), _mm512_loadu_ps(yi.as_ptr()));
        let lens = _mm512_loadu_si512(lists.lens.as_ptr() as *const _);
        let pad = _mm512_loadu_si512(lists.pad.as_ptr() as *const _);
        let mut slot = [0u32; LANES];
        let c = |v: f32| _mm512_set1_ps(v);
        let (mut dens, mut sx, mut sy, mut sq) = (
            c(start),
            _mm512_setzero_ps(),
            _mm512_setzero_ps(),
            _mm512_setzero_ps(),
        );
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
            let (rx, ry) = (_mm512_sub_ps(xi, xj), _mm512_sub_ps(yi, yj));
            let rl = _mm512_sqrt_ps(_mm512_add_ps(_mm512_mul_ps(rx, rx), _mm512_mul_ps(ry, ry)));
            let q = _mm512_mul_ps(rl, c(inv_h));
            let inner = _mm512_cmp_ps_mask::<_CMP_LE_OQ>(q, c(0.5));
            let inside = _mm512_cmp_ps_mask::<_CMP_LT_OQ>(q, c(1.0));
            // W: k·(6q³ − 6q² + 1) inside q ≤ ½, 2k·(1 − q)³ up to 1, 0 beyond.
            let w = cubic_w(q, inner, inside, k);
            let a = _mm512_sub_ps(c(1.0), q);
            // dW/dq: l·q·(3q − 2) inside q ≤ ½, −l·(1 − q)² beyond.
            let d_in = _mm512_mul_ps(
                _mm512_mul_ps(c(l), q),
                _mm512_sub_ps(_mm512_mul_ps(c(3.0), q), c(2.0)),
            );
            let d_out = _mm512_mul_ps(_mm512_mul_ps(c(-l), a), a);
            let d = _mm512_mask_blend_ps(inner, d_out, d_in);
            // ∇W = r·(dW/dq·(1/h)/|r|) where 1e-9 < |r| and q < 1, else 0.
            let has_grad = inside & _mm512_cmp_ps_mask::<_CMP_GT_OQ>(rl, c(1.0e-9)) & pair;
            let scale = _mm512_maskz_div_ps(has_grad, _mm512_mul_ps(d, c(inv_h)), rl);
            // Padding stores +0 (its r, taken from another particle, could carry a sign).
            let (gxv, gyv) = (
                _mm512_maskz_mul_ps(pair, rx, scale),
                _mm512_maskz_mul_ps(pair, ry, scale),
            );
            _mm512_storeu_ps(gx.as_mut_ptr().add(kk), gxv);
            _mm512_storeu_ps(gy.as_mut_ptr().add(kk), gyv);
            // Sums over real pairs only (padding lanes keep their value).
            dens = _mm512_mask_add_ps(dens, pair, dens, _mm512_mul_ps(c(volume), w));
            let (vx, vy) = (_mm512_mul_ps(c(volume), gxv), _mm512_mul_ps(c(volume), gyv));
            sx = _mm512_mask_add_ps(sx, pair, sx, vx);
            sy = _mm512_mask_add_ps(sy, pair, sy, vy);
            let len2 = _mm512_add_ps(_mm512_mul_ps(vx, vx), _mm512_mul_ps(vy, vy));
            sq = _mm512_mask_add_ps(sq, pair, sq, len2);
        }
        let mut out = FluidSums::default();
        _mm512_storeu_ps(out.density.as_mut_ptr(), dens);
        _mm512_storeu_ps(out.grad_x.as_mut_ptr(), sx);
        _mm512_storeu_ps(out.grad_y.as_mut_ptr(), sy);
        _mm512_storeu_ps(out.grad_sq.as_mut_ptr(), sq);
        out
    }

    /// The cubic spline's `W` at `q` for 16 lanes, as [`CubicSpline::w`] computes it
    /// (separate multiplies and adds in its order): `k·(6q³ − 6q² + 1)` where `inner`
    /// (q ≤ ½), `2k·(1 − q)³` elsewhere in `inside` (q < 1), 0 beyond.
    #[inline]
    #[target_feature(enable = "avx512f")]
    fn cubic_w(q: __m512, inner: __mmask16, inside: __mmask16, k: f32) -> __m512 {
        let c = |v: f32| _mm512_set1_ps(v);
        let q2 = _mm512_mul_ps(q, q);
        let six_q2 = _mm512_mul_ps(c(6.0), q2);
        let w_in = _mm512_mul_ps(
            c(k),
            _mm512_add_ps(_mm512_sub_ps(_mm512_mul_ps(six_q2, q), six_q2), c(1.0)),
        );
        let a = _mm512_sub_ps(c(1.0), q);
        let w_out = _mm512_mul_ps(_mm512_mul_ps(_mm512_mul_ps(c(2.0 * k), a), a), a);
        _mm512_maskz_mov_ps(inside, _mm512_mask_blend_ps(inner, w_out, w_in))
    }

    /// [`cubic_w`] at the squared distances `r2`, as [`CubicSpline::w`] of `√r2`.
    #[inline]
    #[target_feature(enable = "avx512f")]
    fn cubic_w_at(r2: __m512, inv_h: f32, k: f32) -> __m512 {
        let q = _mm512_mul_ps(_mm512_sqrt_ps(r2), _mm512_set1_ps(inv_h));
        let inner = _mm512_cmp_ps_mask::<_CMP_LE_OQ>(q, _mm512_set1_ps(0.5));
        let inside = _mm512_cmp_ps_mask::<_CMP_LT_OQ>(q, _mm512_set1_ps(1.0));
        cubic_w(q, inner, inside, k)
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
        kernel: &CubicSpline,
        volume: f32,
        start: f32,
        gather: Gather,
        windows: Option<Windows>,
    ) -> [f32; LANES] {
        let (k, _, inv_h) = kernel.constants();
        let c = |v: f32| _mm512_set1_ps(v);
        let support2 = c(kernel.support() * kernel.support());
        let neighbours = NeighbourStates::new::<I>(first, pos, vel, gather, windows);
        let own = indices_from((first - I::origin(first)) as u32);
        let (xi_x, xi_y) = split_xy(xi);
        let dtv = c(dt);
        let mut sum = c(start);
        for kk in (0..idx.len()).step_by(LANES) {
            let at = idx.as_ptr().add(kk);
            let j = load_indices(at);
            // x_j + Δt·v_j, multiply then add, as the scalar `Vec2` expression.
            let ((px, py), (vx, vy)) = neighbours.slot(kk, j, at);
            let xj = _mm512_add_ps(px, _mm512_mul_ps(dtv, vx));
            let yj = _mm512_add_ps(py, _mm512_mul_ps(dtv, vy));
            let (rx, ry) = (_mm512_sub_ps(xi_x, xj), _mm512_sub_ps(xi_y, yj));
            let r2 = _mm512_add_ps(_mm512_mul_ps(rx, rx), _mm512_mul_ps(ry, ry));
            // Padding repeats the particle itself, which is never its own neighbour.
            let pair =
                _mm512_cmpneq_epi32_mask(j, own) & _mm512_cmp_ps_mask::<_CMP_LT_OQ>(r2, support2);
            let w = cubic_w_at(r2, inv_h, k);
            sum = _mm512_mask_add_ps(sum, pair, sum, _mm512_mul_ps(c(volume), w));
        }
        let mut out = [0.0f32; LANES];
        _mm512_storeu_ps(out.as_mut_ptr(), sum);
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

    /// `(x0, y0, …, x7, y7)` and `(x8, y8, …, x15, y15)` as `(x0 … x15)` and `(y0 … y15)`.
    #[inline]
    #[target_feature(enable = "avx512f")]
    pub(crate) fn deinterleave(lo: __m512, hi: __m512) -> (__m512, __m512) {
        let even = _mm512_setr_epi32(0, 2, 4, 6, 8, 10, 12, 14, 16, 18, 20, 22, 24, 26, 28, 30);
        let odd = _mm512_setr_epi32(1, 3, 5, 7, 9, 11, 13, 15, 17, 19, 21, 23, 25, 27, 29, 31);
        (
            _mm512_permutex2var_ps(lo, even, hi),
            _mm512_permutex2var_ps(lo, odd, hi),
        )
    }

    /// The 16 consecutive indices `first, first + 1, …, first + 15`.
    #[inline]
    #[target_feature(enable = "avx512f")]
    pub(crate) fn indices_from(first: u32) -> __m512i {
        let lane = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
        _mm512_add_epi32(_mm512_set1_epi32(first as i32), lane)
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
        kernel: &CubicSpline,
        eps2: f32,
        laplacian: bool,
        gather: Gather,
        windows: Option<Windows>,
    ) -> ([Vec2; LANES], [Vec2; LANES]) {
        let (k, _, inv_h) = kernel.constants();
        let c = |v: f32| _mm512_set1_ps(v);
        let neighbours = NeighbourStates::new::<I>(first, pos, vel, gather, windows);
        let own = indices_from((first - I::origin(first)) as u32);
        let (xi_x, xi_y) = split_xy(xi);
        let (vi_x, vi_y) = split_xy(vi);
        let (mut sx, mut sy) = (_mm512_setzero_ps(), _mm512_setzero_ps());
        let (mut lx, mut ly) = (_mm512_setzero_ps(), _mm512_setzero_ps());
        for kk in (0..idx.len()).step_by(LANES) {
            let at = idx.as_ptr().add(kk);
            let j = load_indices(at);
            let pair = _mm512_cmpneq_epi32_mask(j, own);
            let ((xj, yj), (vxj, vyj)) = neighbours.slot(kk, j, at);
            let (rx, ry) = (_mm512_sub_ps(xi_x, xj), _mm512_sub_ps(xi_y, yj));
            let (ux, uy) = (_mm512_sub_ps(vi_x, vxj), _mm512_sub_ps(vi_y, vyj));
            let r2 = _mm512_add_ps(_mm512_mul_ps(rx, rx), _mm512_mul_ps(ry, ry));
            let w = cubic_w_at(r2, inv_h, k);
            sx = _mm512_mask_sub_ps(sx, pair, sx, _mm512_mul_ps(ux, w));
            sy = _mm512_mask_sub_ps(sy, pair, sy, _mm512_mul_ps(uy, w));
            if laplacian {
                let dot = _mm512_add_ps(_mm512_mul_ps(ux, rx), _mm512_mul_ps(uy, ry));
                let ratio = _mm512_div_ps(dot, _mm512_add_ps(r2, c(eps2)));
                let gxv = _mm512_loadu_ps(gx.as_ptr().add(kk));
                let gyv = _mm512_loadu_ps(gy.as_ptr().add(kk));
                lx = _mm512_mask_add_ps(lx, pair, lx, _mm512_mul_ps(gxv, ratio));
                ly = _mm512_mask_add_ps(ly, pair, ly, _mm512_mul_ps(gyv, ratio));
            }
        }
        let store = |x: __m512, y: __m512| {
            let (mut ax, mut ay) = ([0.0f32; LANES], [0.0f32; LANES]);
            _mm512_storeu_ps(ax.as_mut_ptr(), x);
            _mm512_storeu_ps(ay.as_mut_ptr(), y);
            std::array::from_fn(|l| Vec2::new(ax[l], ay[l]))
        };
        (store(sx, sy), store(lx, ly))
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
        let second =
            _mm512_setr_epi32(8, 24, 9, 25, 10, 26, 11, 27, 12, 28, 13, 29, 14, 30, 15, 31);
        let (lo, hi) = pair_masks(lanes);
        let flat = p as *mut f32;
        _mm512_mask_storeu_ps(flat, lo, _mm512_permutex2var_ps(x, first, y));
        _mm512_mask_storeu_ps(
            flat.wrapping_add(16),
            hi,
            _mm512_permutex2var_ps(x, second, y),
        );
    }

    /// `−x` by flipping the sign bit, exactly as scalar negation (also for zeros).
    #[inline]
    #[target_feature(enable = "avx512f")]
    fn negate(x: __m512) -> __m512 {
        let sign = _mm512_set1_epi32(i32::MIN);
        _mm512_castsi512_ps(_mm512_xor_si512(_mm512_castps_si512(x), sign))
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
        pairs: &super::BlockedPairs,
        idx: &[I],
        blocks: std::ops::Range<usize>,
        vel: &[Vec2],
        terms: &super::ResidualTerms,
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
        pairs: &super::BlockedPairs,
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
        terms: &super::ResidualTerms,
        delta: &mut [f32],
        rate: &mut [f32],
        errors: &mut [f32; LANES],
        gather: Gather,
        windows: Option<Windows>,
    ) {
        let lanes = delta.len();
        let fluid = velocity_gradient_dot_lanes(idx, first, gx, gy, vel, gather, windows);
        let m = lane_mask(lanes);
        let c = |v: f32| _mm512_set1_ps(v);
        let load = |a: &[f32]| _mm512_maskz_loadu_ps(m, a.as_ptr().add(first));
        let (vx, vy) = load_pairs(vel.as_ptr().add(first), lanes);
        let (gsx, gsy) = load_pairs(terms.grad_sum.as_ptr().add(first), lanes);
        // v_i·g_i as glam's `dot`: x·x' + y·y'.
        let dot = _mm512_add_ps(_mm512_mul_ps(vx, gsx), _mm512_mul_ps(vy, gsy));
        let r = _mm512_sub_ps(
            _mm512_sub_ps(dot, _mm512_mul_ps(c(terms.volume), fluid)),
            load(terms.wall_flux),
        );
        _mm512_mask_storeu_ps(rate.as_mut_ptr(), m, r);
        // `max` returns its second operand, 0, for a NaN, as `f32::max` does.
        let e = _mm512_max_ps(
            _mm512_add_ps(load(terms.source), _mm512_mul_ps(c(terms.rate_scale), r)),
            _mm512_setzero_ps(),
        );
        let d = _mm512_mul_ps(
            _mm512_mul_ps(e, load(terms.factor)),
            c(terms.increment_scale),
        );
        _mm512_mask_storeu_ps(delta.as_mut_ptr(), m, d);
        _mm512_storeu_ps(errors.as_mut_ptr(), _mm512_maskz_mov_ps(m, e));
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
        let vol = _mm512_set1_ps(volume);
        // Δv = −(κ_i·g_i + V·s), then v + Δv.
        let dvx = negate(_mm512_add_ps(
            _mm512_mul_ps(ki, gsx),
            _mm512_mul_ps(vol, sx),
        ));
        let dvy = negate(_mm512_add_ps(
            _mm512_mul_ps(ki, gsy),
            _mm512_mul_ps(vol, sy),
        ));
        let (vx, vy) = load_pairs(vel.as_ptr(), lanes);
        store_pairs(
            vel.as_mut_ptr(),
            lanes,
            _mm512_add_ps(vx, dvx),
            _mm512_add_ps(vy, dvy),
        );
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
            let code = _mm512_mask_blend_epi32(
                in1,
                _mm512_or_si512(p2, third),
                _mm512_or_si512(p1, second),
            );
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
    fn pick(
        code: __m512i,
        (in1, in2): (__mmask16, __mmask16),
        w: &[(__m512, __m512); 3],
    ) -> __m512 {
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
            let (x_hi, y_hi) =
                deinterleave(_mm512_loadu_ps(at.add(32)), _mm512_loadu_ps(at.add(48)));
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
    unsafe fn velocity_gradient_dot_windows(
        w: Windows,
        gx: &[f32],
        gy: &[f32],
        v: &[Vec2],
    ) -> __m512 {
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
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Deterministic pseudo-random numbers in [0, 1).
    fn unit(k: u64) -> f32 {
        let x = k.wrapping_mul(0x9E37_79B9_7F4A_7C15).rotate_left(29);
        (x >> 40) as f32 / (1u64 << 24) as f32
    }

    /// Lists of random lengths (0 to 20, some empty) with random neighbours and gradients.
    fn random_lists(n: usize) -> (NeighborLists, Vec<Vec2>) {
        random_lists_ending_with(n, None)
    }

    /// [`random_lists`], with the last pair's neighbour replaced by `last` when given.
    fn random_lists_ending_with(n: usize, last: Option<u32>) -> (NeighborLists, Vec<Vec2>) {
        let mut raw: Vec<Vec<u32>> = Vec::new();
        let mut grads = Vec::new();
        for i in 0..n {
            let len = (unit(i as u64) * 21.0) as usize;
            let mut list = Vec::new();
            for k in 0..len {
                let key = (i * 31 + k) as u64;
                list.push((unit(key) * n as f32) as u32);
                grads.push(Vec2::new(unit(key + 7) - 0.5, unit(key + 13) - 0.5));
            }
            raw.push(list);
        }
        if let Some(j) = last {
            let list = raw.iter_mut().rfind(|l| !l.is_empty()).expect("some pair");
            *list.last_mut().unwrap() = j;
        }
        let mut lists = NeighborLists::default();
        for list in &raw {
            lists.push(list);
        }
        (lists, grads)
    }

    #[test]
    fn both_paths_give_the_per_list_sums() {
        // 16 particles exactly, a partial last block, and none at all.
        for n in [16usize, 1000, 0] {
            let (lists, grads) = random_lists(n);
            let s: Vec<f32> = (0..n).map(|k| unit(k as u64 + 99) - 0.3).collect();
            let v: Vec<Vec2> = (0..n)
                .map(|k| Vec2::new(unit(k as u64 + 5), unit(k as u64 + 6)) - 0.5)
                .collect();
            let mut blocks = BlockedPairs::default();
            blocks.build(&lists, &grads);
            assert_eq!(blocks.blocks(), n.div_ceil(LANES));
            for path in SimdPath::available_paths() {
                blocks.set_simd_path(path);
                for b in 0..blocks.blocks() {
                    let (sx, sy) = blocks.weighted_gradient_sums(b, &s);
                    let dots = blocks.velocity_gradient_dots(b, &v);
                    for l in 0..LANES {
                        let i = b * LANES + l;
                        if i >= n {
                            continue;
                        }
                        let r = lists.range(i);
                        let (mut want, mut dot) = (glam::DVec2::ZERO, 0.0f64);
                        for (&j, g) in lists.of(i).iter().zip(&grads[r]) {
                            want += (s[j as usize] * *g).as_dvec2();
                            dot += v[j as usize].dot(*g) as f64;
                        }
                        let got = glam::DVec2::new(sx[l] as f64, sy[l] as f64);
                        assert!(
                            (got - want).length() < 1e-5,
                            "n {n}, path {path}, particle {i}: {got} against {want}"
                        );
                        assert!(
                            (dots[l] as f64 - dot).abs() < 1e-5,
                            "n {n}, path {path}, particle {i}: {} against {dot}",
                            dots[l]
                        );
                    }
                }
            }
        }
    }

    /// The fused block passes of the Jacobi iterations: the per-particle terms on top of the
    /// pair sums, checked against the formulas written out per particle. On each path the
    /// terms are the scalar expressions in their order, so they must match the path's own
    /// pair sums followed by those expressions bit for bit (a reordered or fused term fails).
    #[test]
    fn block_passes_add_the_per_particle_terms_of_the_scalar_code() {
        for n in [16usize, 1000, 37] {
            let (lists, grads) = random_lists(n);
            let val = |k: usize, salt: u64| unit(k as u64 * 7 + salt) - 0.3;
            let vec = |k: usize, salt: u64| Vec2::new(val(k, salt), val(k, salt + 1));
            let kappa: Vec<f32> = (0..n).map(|k| val(k, 1)).collect();
            let vel: Vec<Vec2> = (0..n).map(|k| vec(k, 2)).collect();
            let grad_sum: Vec<Vec2> = (0..n).map(|k| vec(k, 4)).collect();
            let wall_flux: Vec<f32> = (0..n).map(|k| val(k, 6)).collect();
            // Some sources of −∞ (particles left out), some residuals clamped at 0.
            let source: Vec<f32> = (0..n)
                .map(|k| {
                    if k % 9 == 4 {
                        f32::NEG_INFINITY
                    } else {
                        val(k, 7)
                    }
                })
                .collect();
            let factor: Vec<f32> = (0..n).map(|k| 1.0 + val(k, 8)).collect();
            let terms = ResidualTerms {
                volume: 0.7,
                grad_sum: &grad_sum,
                wall_flux: &wall_flux,
                source: &source,
                rate_scale: 0.25,
                factor: &factor,
                increment_scale: 3.0,
            };
            let mut blocks = BlockedPairs::default();
            blocks.build(&lists, &grads);
            for path in SimdPath::available_paths() {
                blocks.set_simd_path(path);
                let mut moved = vel.clone();
                let mut total: Vec<f32> = (0..n).map(|k| val(k, 9)).collect();
                let mut delta = vec![0.0f32; n];
                let mut rates = vec![0.0f32; n];
                for b in 0..blocks.blocks() {
                    let r = b * LANES..((b + 1) * LANES).min(n);
                    let mut errors = [f32::NAN; LANES];
                    blocks.residual_block(
                        b,
                        &vel,
                        &terms,
                        &mut delta[r.clone()],
                        &mut rates[r.clone()],
                        &mut errors,
                    );
                    // Lanes past the last particle hold 0, which adds nothing to the sums.
                    assert!(errors[r.len()..].iter().all(|e| e.to_bits() == 0));
                    blocks.apply_block(
                        b,
                        terms.volume,
                        &kappa,
                        &grad_sum,
                        &mut moved[r.clone()],
                        Some(&mut total[r.clone()]),
                    );
                    let dots = blocks.velocity_gradient_dots(b, &vel);
                    let (sx, sy) = blocks.weighted_gradient_sums(b, &kappa);
                    let (mut want_sum, mut want_max) = (0.0f64, 0.0f64);
                    for i in r {
                        let l = i - b * LANES;
                        let rate = vel[i].dot(grad_sum[i]) - 0.7 * dots[l] - wall_flux[i];
                        assert_eq!(rates[i].to_bits(), rate.to_bits(), "path {path}, {i}");
                        let e = (source[i] + 0.25 * rate).max(0.0);
                        assert_eq!(errors[l].to_bits(), e.to_bits(), "path {path}, {i}");
                        let d = e * factor[i] * 3.0;
                        assert_eq!(delta[i].to_bits(), d.to_bits(), "path {path}, n {n}, {i}");
                        (want_sum, want_max) = (want_sum + e as f64, want_max.max(e as f64));
                        let dv = -(kappa[i] * grad_sum[i] + 0.7 * Vec2::new(sx[l], sy[l]));
                        let v = vel[i] + dv;
                        assert_eq!(
                            (moved[i].x.to_bits(), moved[i].y.to_bits()),
                            (v.x.to_bits(), v.y.to_bits()),
                            "path {path}, n {n}, particle {i}"
                        );
                        let t = val(i, 9) + kappa[i];
                        assert_eq!(total[i].to_bits(), t.to_bits(), "path {path}, {i}");
                        // The left-out particles, and the formula against f64.
                        if source[i] == f32::NEG_INFINITY {
                            assert_eq!(d, 0.0);
                        }
                        let rate64 = vel[i].as_dvec2().dot(grad_sum[i].as_dvec2())
                            - 0.7 * dots[l] as f64
                            - wall_flux[i] as f64;
                        let e64 = (source[i] as f64 + 0.25 * rate64).max(0.0);
                        assert!((e as f64 - e64).abs() < 1e-5, "path {path}, {i}");
                    }
                    let mut group = [[0.0; LANES]; crate::reduce::BLOCKS_TOGETHER];
                    group[0] = errors;
                    let (sum, max) = crate::reduce::fold_block_sums((0.0, 0.0), &group, 1);
                    assert_eq!(sum.to_bits(), want_sum.to_bits(), "path {path}, block {b}");
                    assert_eq!(max, want_max, "path {path}, block {b}");
                }
                // Every particle was written: none of the placeholder zeros remain where a
                // residual is positive somewhere in the block.
                assert!(delta.iter().any(|&d| d > 0.0), "path {path}: a real test");
            }
        }
    }

    /// [`random_lists`] with every list (and its gradients) sorted by neighbour index, as a
    /// dense grid's are.
    fn sorted_random_lists(n: usize) -> (NeighborLists, Vec<Vec2>) {
        let (raw, raw_grads) = random_lists(n);
        let (mut lists, mut grads) = (NeighborLists::default(), Vec::new());
        for i in 0..n {
            let mut pairs: Vec<(u32, Vec2)> = raw
                .of(i)
                .iter()
                .copied()
                .zip(raw_grads[raw.range(i)].iter().copied())
                .collect();
            pairs.sort_by_key(|p| p.0);
            lists.push(&pairs.iter().map(|p| p.0).collect::<Vec<_>>());
            grads.extend(pairs.iter().map(|p| p.1));
        }
        assert!(lists.ascending());
        (lists, grads)
    }

    /// The bits of every kernel's results over all blocks, and of the blocks `fill_block`
    /// writes, for blocks set up by `setup` before they are built.
    fn all_kernel_bits(
        lists: &NeighborLists,
        grads: &[Vec2],
        setup: impl Fn(&mut BlockedPairs),
    ) -> Vec<u32> {
        let n = lists.len();
        let val = |k: usize, salt: u64| unit(k as u64 * 5 + salt) - 0.4;
        let s: Vec<f32> = (0..n).map(|k| val(k, 1)).collect();
        let pos: Vec<Vec2> = (0..n)
            .map(|k| Vec2::new(val(k, 2), val(k, 3)) * 0.05)
            .collect();
        let vel: Vec<Vec2> = (0..n).map(|k| Vec2::new(val(k, 4), val(k, 5))).collect();
        let kernel = CubicSpline::new(0.04);
        let mut blocks = BlockedPairs::default();
        setup(&mut blocks);
        blocks.build(lists, grads);
        let mut bits = Vec::new();
        let mut push = |v: &[f32]| bits.extend(v.iter().map(|x| x.to_bits()));
        for b in 0..blocks.blocks() {
            let (sx, sy) = blocks.weighted_gradient_sums(b, &s);
            push(&sx);
            push(&sy);
            push(&blocks.velocity_gradient_dots(b, &vel));
            push(&blocks.advected_kernel_sums(b, &pos, &vel, 1e-3, &kernel, 0.5, 0.1));
            let (smooth, laplace) = blocks.viscosity_sums(b, &pos, &vel, &kernel, 1e-6, true);
            for v in smooth.iter().chain(&laplace) {
                push(&[v.x, v.y]);
            }
        }
        let mut writer_sums = Vec::new();
        let mut filled = BlockedPairs::default();
        setup(&mut filled);
        filled.prepare(lists);
        for (b, mut w) in filled.writers(1).into_iter().enumerate() {
            let sums = w.fill_block(b, lists, &pos, &kernel, 0.5, 0.1);
            writer_sums.extend(
                sums.density
                    .iter()
                    .chain(&sums.grad_sq)
                    .map(|x| x.to_bits()),
            );
        }
        // The density pass writes the same indices as `build` (the SIMD path reads them from
        // the lists itself).
        assert_eq!(filled.absolute_indices(), blocks.absolute_indices());
        assert_eq!(filled.relative_indices(), blocks.relative_indices());
        assert_eq!(filled.window_start, blocks.window_start);
        assert_eq!(filled.window_code, blocks.window_code);
        bits.extend(writer_sums);
        bits.extend(
            filled
                .grad_x
                .iter()
                .chain(&filled.grad_y)
                .map(|x| x.to_bits()),
        );
        bits
    }

    /// Gather instructions and plain loads read the same values, so every SIMD kernel must
    /// give the same bits either way, with either kind of index. (Without AVX-512 both runs
    /// take the portable path.)
    #[test]
    fn gathers_and_loads_give_identical_bits() {
        for (lists, grads) in [random_lists(333), sorted_random_lists(333)] {
            let run = |gather: Gather| {
                all_kernel_bits(&lists, &grads, |blocks| blocks.set_gather(gather))
            };
            let (instruction, loads) = (run(Gather::Instruction), run(Gather::Loads));
            assert_eq!(instruction.len(), loads.len());
            assert!(
                instruction == loads,
                "the two ways of reading neighbours differ"
            );
        }
    }

    /// The passes over runs of blocks give the bits of one call per block: on both paths,
    /// reading through windows and with loads, for runs that end in the partial last block
    /// (a run that read another block's entries, or wrote a lane past its particles, would
    /// differ).
    #[test]
    fn passes_over_runs_of_blocks_give_the_per_block_bits() {
        let n = 1000;
        let (lists, grads) = lattice_lists(n, 40, Some(485));
        let val = |k: usize, salt: u64| unit(k as u64 * 3 + salt) - 0.3;
        let vec = |k: usize, salt: u64| Vec2::new(val(k, salt), val(k, salt + 1));
        let kappa: Vec<f32> = (0..n).map(|k| val(k, 1)).collect();
        let vel: Vec<Vec2> = (0..n).map(|k| vec(k, 2)).collect();
        let grad_sum: Vec<Vec2> = (0..n).map(|k| vec(k, 4)).collect();
        let wall_flux: Vec<f32> = (0..n).map(|k| val(k, 6)).collect();
        let source: Vec<f32> = (0..n).map(|k| val(k, 7)).collect();
        let factor: Vec<f32> = (0..n).map(|k| 1.0 + val(k, 8)).collect();
        let terms = ResidualTerms {
            volume: 0.7,
            grad_sum: &grad_sum,
            wall_flux: &wall_flux,
            source: &source,
            rate_scale: 0.25,
            factor: &factor,
            increment_scale: 3.0,
        };
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        let pair_bits = |v: &[Vec2]| {
            v.iter()
                .flat_map(|p| [p.x.to_bits(), p.y.to_bits()])
                .collect::<Vec<_>>()
        };
        let ways = [
            (SimdPath::Avx512, Gather::Windows),
            (SimdPath::Avx512, Gather::Loads),
            (SimdPath::Fma, Gather::Loads),
            (SimdPath::Portable, Gather::Loads),
        ];
        for (path, gather) in ways.into_iter().filter(|(p, _)| p.available()) {
            let mut blocks = BlockedPairs::default();
            blocks.set_simd_path(path);
            blocks.set_gather(gather);
            blocks.build(&lists, &grads);
            let count = blocks.blocks();
            // Both ways: (delta, rates, errors, velocities, totals).
            let mut outs = Vec::new();
            for run in [1, 5] {
                let (mut delta, mut rates) = (vec![0.0f32; n], vec![0.0f32; n]);
                let mut errors = vec![[f32::NAN; LANES]; count];
                let mut moved = vel.clone();
                let mut total: Vec<f32> = (0..n).map(|k| val(k, 9)).collect();
                for start in (0..count).step_by(run) {
                    let blocks_run = start..(start + run).min(count);
                    let p = start * LANES..(blocks_run.end * LANES).min(n);
                    if run == 1 {
                        let e = &mut errors[start];
                        blocks.residual_block(
                            start,
                            &vel,
                            &terms,
                            &mut delta[p.clone()],
                            &mut rates[p.clone()],
                            e,
                        );
                        blocks.apply_block(
                            start,
                            0.7,
                            &kappa,
                            &grad_sum,
                            &mut moved[p.clone()],
                            Some(&mut total[p]),
                        );
                    } else {
                        let e = &mut errors[blocks_run.clone()];
                        blocks.residual_blocks(
                            blocks_run.clone(),
                            &vel,
                            &terms,
                            &mut delta[p.clone()],
                            &mut rates[p.clone()],
                            e,
                        );
                        blocks.apply_blocks(
                            blocks_run,
                            0.7,
                            &kappa,
                            &grad_sum,
                            &mut moved[p.clone()],
                            Some(&mut total[p]),
                        );
                    }
                }
                let flat: Vec<f32> = errors.iter().flatten().copied().collect();
                outs.push((
                    bits(&delta),
                    bits(&rates),
                    bits(&flat),
                    pair_bits(&moved),
                    bits(&total),
                ));
            }
            assert!(outs[0] == outs[1], "path {path}, {gather:?}");
            assert!(
                outs[0].4 != bits(&(0..n).map(|k| val(k, 9)).collect::<Vec<_>>()),
                "a real test"
            );
        }
    }

    /// Lists of a lattice `width` points wide, numbered row by row, as a grid sorted by cell
    /// gives them: each point's neighbours are the other points of its 3×3 patch, with
    /// random gradients. Particle `far`, where given, also has the last point as neighbour.
    fn lattice_lists(n: usize, width: usize, far: Option<usize>) -> (NeighborLists, Vec<Vec2>) {
        let (mut lists, mut grads) = (NeighborLists::default(), Vec::new());
        for i in 0..n {
            let (x, y) = ((i % width) as i64, (i / width) as i64);
            let mut list = Vec::new();
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let (nx, ny) = (x + dx, y + dy);
                    let j = ny * width as i64 + nx;
                    if (dx, dy) != (0, 0)
                        && (0..width as i64).contains(&nx)
                        && (0..n as i64).contains(&j)
                    {
                        list.push(j as u32);
                    }
                }
            }
            if far == Some(i) {
                list.push(n as u32 - 1);
            }
            for k in 0..list.len() {
                let key = (i * 31 + k) as u64;
                grads.push(Vec2::new(unit(key + 7) - 0.5, unit(key + 13) - 0.5));
            }
            lists.push(&list);
        }
        assert!(lists.ascending());
        (lists, grads)
    }

    /// Reading through windows gives every kernel the bits loads give: on lattice lists
    /// whose blocks fit (but for one), on random lists that do not, and with fewer
    /// particles than a window. (Without AVX-512 both runs take the portable path.)
    #[test]
    fn windows_and_loads_give_identical_bits() {
        let cases = [
            lattice_lists(1000, 40, None),
            lattice_lists(1000, 40, Some(485)),
            lattice_lists(37, 7, None),
            lattice_lists(20, 5, None),
            sorted_random_lists(333),
        ];
        for (c, (lists, grads)) in cases.iter().enumerate() {
            let run =
                |gather: Gather| all_kernel_bits(lists, grads, |blocks| blocks.set_gather(gather));
            assert!(run(Gather::Windows) == run(Gather::Loads), "case {c}");
        }
    }

    /// Every windowed entry's code names its neighbour, every window lies inside the
    /// particles, and a block whose neighbours span four runs is read with loads.
    #[test]
    fn window_codes_name_each_neighbour() {
        if !SimdPath::Avx512.available() {
            return; // Windows exist on the AVX-512 path only.
        }
        let n = 1000;
        // Particle 485 (block 30, rows 11–13 of the lattice) also reaches the last point.
        let (lists, grads) = lattice_lists(n, 40, Some(485));
        let mut blocks = BlockedPairs::default();
        blocks.set_gather(Gather::Windows);
        blocks.build(&lists, &grads);
        assert!(blocks.windows(30).is_none());
        assert_eq!(blocks.windowed_blocks(), blocks.blocks() - 1);
        let absolute = blocks.absolute_indices();
        for b in 0..blocks.blocks() {
            let Some(w) = blocks.windows(b) else {
                continue;
            };
            assert!(
                w.starts.iter().all(|&s| s as usize + WINDOW <= n),
                "block {b}"
            );
            let entries = &absolute[blocks.slots_before(b) * LANES..];
            for (&code, &j) in w.codes.iter().zip(entries) {
                let (window, place) = ((code >> 5) as usize, (code & 31) as u32);
                assert_eq!(w.starts[window] + place, j, "block {b}");
            }
        }
    }

    /// The same lists stored with relative and with absolute indices give the same bits in
    /// every kernel, on both paths (a kernel that read an offset as an index, or missed the
    /// own-particle test, would differ).
    #[test]
    fn relative_and_absolute_indices_give_identical_bits() {
        for n in [1000, 37, 16] {
            let (lists, grads) = sorted_random_lists(n);
            for path in SimdPath::available_paths() {
                let run = |relative: bool| {
                    all_kernel_bits(&lists, &grads, |blocks| {
                        blocks.set_simd_path(path);
                        blocks.set_relative_indices(relative);
                    })
                };
                assert!(run(true) == run(false), "n {n}, path {path}");
            }
            let mut blocks = BlockedPairs::default();
            blocks.build(&lists, &grads);
            assert!(
                blocks.relative_indices(),
                "n {n}: sorted lists near their blocks"
            );
            assert!(blocks.index.is_empty() && blocks.relative.len() == blocks.entries());
            blocks.set_relative_indices(false);
            blocks.build(&lists, &grads);
            assert!(!blocks.relative_indices());
            assert!(blocks.relative.is_empty() && blocks.index.len() == blocks.entries());
        }
        // Unordered lists: their span is unknown without reading them all.
        let (lists, grads) = random_lists(100);
        let mut blocks = BlockedPairs::default();
        blocks.build(&lists, &grads);
        assert!(!blocks.relative_indices());
    }

    /// A neighbour 32,767 places after its block's first particle or 32,768 before still
    /// fits in 16 bits; one place further does not, and then every block stores absolute
    /// indices, with the same sums.
    #[test]
    fn neighbours_beyond_16_bits_keep_absolute_indices() {
        let n = 40_000;
        // Particle 3 (block 0) and particle 32_790 (block 2,049, first particle 32,784).
        let cases = [
            (3, 32_767, true),
            (3, 32_768, false),
            (32_790, 16, true),
            (32_790, 15, false),
        ];
        for (i, j, fits) in cases {
            let mut lists = NeighborLists::default();
            let mut grads = Vec::new();
            for k in 0..n {
                let list: Vec<u32> = if k == i {
                    vec![j]
                } else if k % 500 == 7 {
                    vec![k as u32 - 1, k as u32 + 1]
                } else {
                    vec![]
                };
                grads.extend(list.iter().map(|&j| Vec2::new(1.0, j as f32 * 1e-4)));
                lists.push(&list);
            }
            let mut blocks = BlockedPairs::default();
            blocks.build(&lists, &grads);
            assert_eq!(
                blocks.relative_indices(),
                fits,
                "particle {i}, neighbour {j}"
            );
            let s: Vec<f32> = (0..n).map(|k| 1.0 + k as f32).collect();
            for k in [i, 7, 39_507] {
                let (sx, sy) = blocks.weighted_gradient_sums(k / LANES, &s);
                let (mut wx, mut wy) = (0.0f32, 0.0f32);
                for (&j, g) in lists.of(k).iter().zip(&grads[lists.range(k)]) {
                    wx += s[j as usize] * g.x;
                    wy += s[j as usize] * g.y;
                }
                let l = k % LANES;
                assert!(
                    (sx[l] - wx).abs() <= 1e-3 * wx.abs(),
                    "{i}, {j}, particle {k}"
                );
                assert!(
                    (sy[l] - wy).abs() <= 1e-3 * wy.abs().max(1.0),
                    "{i}, {j}, {k}"
                );
            }
        }
    }

    #[test]
    fn padding_stays_inside_the_particle_arrays() {
        let (lists, grads) = random_lists(100);
        let mut blocks = BlockedPairs::default();
        blocks.build(&lists, &grads);
        // 7 blocks; every block is as wide as its longest list.
        assert_eq!(blocks.blocks(), 7);
        assert!(blocks.index.iter().all(|&j| (j as usize) < 100));
        let real = lists.pair_count();
        assert!(blocks.entries() >= real);
        let padded = blocks.grad_x.iter().zip(&blocks.grad_y);
        assert_eq!(
            padded.filter(|(x, y)| **x != 0.0 || **y != 0.0).count(),
            grads.iter().filter(|g| **g != Vec2::ZERO).count()
        );
    }

    #[test]
    #[should_panic(expected = "neighbour index out of range")]
    fn a_neighbour_index_past_the_particles_is_refused() {
        // The gathers read through these indices unchecked, so they are checked when written.
        let (lists, grads) = random_lists_ending_with(40, Some(40));
        let mut blocks = BlockedPairs::default();
        blocks.build(&lists, &grads);
    }

    #[test]
    #[should_panic(expected = "neighbour index out of range")]
    fn the_density_pass_refuses_a_neighbour_index_past_the_particles() {
        // The SIMD path reads the lists itself; it checks before it reads positions.
        let (lists, _) = random_lists_ending_with(40, Some(40));
        let pos = vec![Vec2::ZERO; 40];
        let kernel = CubicSpline::new(0.04);
        let mut blocks = BlockedPairs::default();
        blocks.prepare(&lists);
        for (b, mut w) in blocks.writers(1).into_iter().enumerate() {
            w.fill_block(b, &lists, &pos, &kernel, 0.5, 0.1);
        }
    }

    #[test]
    #[should_panic(expected = "one value per particle")]
    fn a_short_value_array_is_refused() {
        let (lists, grads) = random_lists(40);
        let mut blocks = BlockedPairs::default();
        blocks.build(&lists, &grads);
        blocks.weighted_gradient_sums(0, &[0.0; 39]);
    }
}
