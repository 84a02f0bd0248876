//! The data the pair kernels read: the blocks of fluid–fluid pairs ([`BlockedPairs`]), how a
//! block's neighbour indices are stored ([`SlotIndex`]) and read ([`Gather`], [`Windows`]), and
//! the per-particle terms and sums of the passes. The passes themselves, and their dispatch to
//! the lane kernels (`lanes.rs`) or the AVX-512 ones (`avx512.rs`), are in the parent module.

use glam::Vec2;

use crate::simd::SimdPath;

/// Particles per block: one value of the lane type (one AVX-512 vector of f32).
pub use crate::simd::wide::LANES;

/// Neighbour indices and kernel gradients of every fluid–fluid pair, by block and slot.
#[derive(Clone, Debug, Default)]
pub struct BlockedPairs {
    /// Particles the blocks were built for.
    pub(super) n: usize,
    /// Block `b` owns slots `slot_start[b]..slot_start[b + 1]`; slot `s` occupies entries
    /// `s·16 .. s·16 + 16` of the arrays below, one per lane.
    pub(super) slot_start: Vec<u32>,
    /// Whether the indices are stored relative, in `relative`, or absolute, in `index`.
    pub(super) narrow: bool,
    /// Neighbour index per slot and lane (< `n`, so every gather stays in bounds); empty
    /// while `narrow`.
    pub(super) index: Vec<u32>,
    /// The same, as offsets from the block's first particle; empty unless `narrow`.
    pub(super) relative: Vec<i16>,
    pub(super) grad_x: Vec<f32>,
    pub(super) grad_y: Vec<f32>,
    /// Per block, where its three windows start, or `None` where its neighbours do not fit
    /// in three ([`Gather::Windows`]); empty unless that way of reading is in use.
    pub(super) window_start: Vec<Option<[u32; 3]>>,
    /// Per entry, the code that picks its neighbour out of its block's windows
    /// ([`super::avx512::window_codes`]); empty unless [`Gather::Windows`] is in use.
    pub(super) window_code: Vec<u8>,
    /// The path the pair loops take ([`SimdPath`]), set by [`Self::prepare`].
    pub(super) path: SimdPath,
    /// How the AVX-512 kernels read neighbour values; [`Gather::for_this_cpu`] unless set.
    pub(super) gather: Option<Gather>,
    /// Set by [`Self::set_simd_path`]: the path to take instead of [`SimdPath::in_use`].
    pub(super) forced_path: Option<SimdPath>,
    /// Set by [`Self::set_relative_indices`]: store absolute indices even where relative
    /// ones fit.
    pub(super) absolute_only: bool,
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
    /// The entries of block `b` in the per-entry arrays.
    #[inline(always)]
    pub(super) fn entry_range(&self, b: usize) -> std::ops::Range<usize> {
        self.slot_start[b] as usize * LANES..self.slot_start[b + 1] as usize * LANES
    }

    /// Block `b`'s part of `idx` (every block's indices, as [`Self::indices`] holds them)
    /// and of the gradients.
    #[inline(always)]
    pub(super) fn block_of<'a, I>(
        &'a self,
        idx: &'a [I],
        b: usize,
    ) -> (&'a [I], &'a [f32], &'a [f32]) {
        let e = self.entry_range(b);
        (&idx[e.clone()], &self.grad_x[e.clone()], &self.grad_y[e])
    }

    /// Block `b`'s windows and codes, where [`Gather::Windows`] is in use and its neighbours
    /// fit.
    #[inline(always)]
    pub(super) fn windows(&self, b: usize) -> Option<Windows<'_>> {
        let starts = (*self.window_start.get(b)?)?;
        let e = self.entry_range(b);
        Some(Windows {
            starts,
            codes: &self.window_code[e],
        })
    }

    pub(super) fn gather(&self) -> Gather {
        self.gather.unwrap_or_else(Gather::for_this_cpu)
    }
}

/// Particles in a window: the 32 values one two-vector permute picks from.
pub(super) const WINDOW: usize = 32;

/// A block's three windows ([`Gather::Windows`]): where each starts (an index of the
/// particle arrays), and per entry a one-byte code, the window in bits 5–6 and the place
/// in it in bits 0–4.
#[derive(Clone, Copy)]
pub(crate) struct Windows<'a> {
    pub(super) starts: [u32; 3],
    pub(super) codes: &'a [u8],
}

/// What lane `i` holds past the end of its list: the particle itself, or for a lane past the
/// last particle `n - 1`, its block's first particle (a valid index, and one a relative
/// index can always express).
#[inline]
pub(super) fn padding(i: usize, n: usize) -> u32 {
    (if i < n { i } else { i - i % LANES }) as u32
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
    pub(super) fn holds(&self, n: usize) -> bool {
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
