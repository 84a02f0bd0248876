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

use crate::par::prelude::*;

use crate::kernel::Kernel;
use crate::neighbors::NeighborLists;
use crate::simd::{lane_kernel, SimdPath};

mod formulas;
mod lanes;
mod layout;
use lanes::{
    lane_advected_kernel_sums, lane_apply_block, lane_apply_blocks, lane_fluid_sums,
    lane_residual_block, lane_residual_blocks, lane_velocity_gradient_dots, lane_viscosity_sums,
    lane_weighted_gradient_sums,
};
use layout::padding;
pub(crate) use layout::SlotIndex;
pub use layout::{BlockedPairs, FluidSums, Gather, ResidualTerms, LANES};

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
        if self.avx512() && self.gather() == Gather::Windows {
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
            if self.avx512() {
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
            if self.avx512() {
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
    /// `reduce::fold_block_sums` sums them).
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
            if self.avx512() {
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
            if self.avx512() {
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
        if self.avx512() {
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
        if self.avx512() {
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
        kernel: &Kernel,
        volume: f32,
        start: f32,
    ) -> [f32; LANES] {
        assert!(pos.len() >= self.n && vel.len() >= self.n);
        let (idx, _, _) = self.block(b);
        let first = b * LANES;
        let xi = self.per_lane(b, |i| pos[i] + dt * vel[i]);
        with_indices!(idx, |idx| {
            #[cfg(target_arch = "x86_64")]
            if self.avx512() {
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
        kernel: &Kernel,
        eps2: f32,
        laplacian: bool,
    ) -> ([Vec2; LANES], [Vec2; LANES]) {
        assert!(pos.len() >= self.n && vel.len() >= self.n);
        let (idx, gx, gy) = self.block(b);
        let first = b * LANES;
        let (xi, vi) = (self.per_lane(b, |i| pos[i]), self.per_lane(b, |i| vel[i]));
        with_indices!(idx, |idx| {
            #[cfg(target_arch = "x86_64")]
            if self.avx512() {
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
    }

    /// The path the pair loops take.
    pub fn simd_path(&self) -> SimdPath {
        self.path
    }

    /// Whether the AVX-512 kernels run.
    #[inline(always)]
    fn avx512(&self) -> bool {
        self.path == SimdPath::Avx512
    }

    /// Read neighbour values the given way in the SIMD kernels rather than the one
    /// [`Gather::for_this_cpu`] picks (tests and benchmarks compare the two).
    pub fn set_gather(&mut self, gather: Gather) {
        self.gather = Some(gather);
    }
}

/// Writes the lanes of some consecutive blocks of a [`BlockedPairs`].
pub struct BlockWriter<'a> {
    /// Particles of the whole layout.
    n: usize,
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
    /// Whether the AVX-512 kernels run.
    #[inline(always)]
    fn avx512(&self) -> bool {
        self.path == SimdPath::Avx512
    }

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
    /// [`Kernel::w_and_grad`], so both paths give identical bits.
    pub fn fill_block(
        &mut self,
        b: usize,
        lists: &NeighborLists,
        pos: &[Vec2],
        kernel: &Kernel,
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
        if self.avx512() {
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

#[cfg(target_arch = "x86_64")]
pub(crate) mod avx512;

#[cfg(test)]
mod tests;
