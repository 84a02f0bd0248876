//! The lane type the pair passes' formulas are written over once: 16 `f32`, one slot of a
//! block. Three backends: [`Lanes`], a plain array whose operations are loops the compiler
//! vectorises (the `fma` and `portable` paths), `f32` itself (one particle at a time, for the
//! per-particle terms of a block that may be partly filled), and, on x86-64, [`Zmm`], one
//! AVX-512 register (the `avx512` path). Each operation rounds as the scalar one does, so a
//! formula gives the same bits on every backend. (The pressure solve's multiply-adds, fused on
//! the `fma` and `avx512` paths and not on `portable`, are in the pair loops, not here.)
//!
//! How a slot's neighbour values are read (16 loads, a gather instruction, permutes out of
//! windows) stays with each backend's loop in `blocked/lanes.rs` and `blocked/avx512.rs`: that is where the
//! backends differ, not the physics.

// Each lane operation is a loop over the lane index, which the compiler vectorises.
#![allow(clippy::needless_range_loop)]

/// Lanes in a [`Wide`] value: one slot of a block.
pub const LANES: usize = 16;

/// 16 lanes of `f32` and the operations the pair passes' formulas use. Every method is
/// `#[inline(always)]`, so that it compiles for the target features of the kernel that calls
/// it ([`crate::simd::with_fma`], or an `avx512f` kernel).
pub(crate) trait Wide: Copy {
    /// One bit per lane.
    type Mask: Copy;

    fn splat(v: f32) -> Self;
    fn zero() -> Self {
        Self::splat(0.0)
    }
    fn add(self, b: Self) -> Self;
    fn sub(self, b: Self) -> Self;
    fn mul(self, b: Self) -> Self;
    fn div(self, b: Self) -> Self;
    fn sqrt(self) -> Self;
    /// `f32::max`: the other operand where one is NaN (here `b` is never NaN).
    fn max(self, b: Self) -> Self;
    /// `−self`, by the sign bit, as scalar negation.
    fn neg(self) -> Self;
    fn lt(self, b: Self) -> Self::Mask;
    fn le(self, b: Self) -> Self::Mask;
    /// `!(self <= b)`: true where either is NaN.
    fn not_le(self, b: Self) -> Self::Mask;
    /// `!(self >= b)`: true where either is NaN.
    fn not_ge(self, b: Self) -> Self::Mask;
    fn and(a: Self::Mask, b: Self::Mask) -> Self::Mask;
    /// `if m { a } else { b }` per lane.
    fn select(m: Self::Mask, a: Self, b: Self) -> Self;
    /// `self + x` where `m`, `self` elsewhere.
    fn add_where(self, m: Self::Mask, x: Self) -> Self {
        Self::select(m, self.add(x), self)
    }
    /// `self` where `m`, +0 elsewhere.
    fn keep(self, m: Self::Mask) -> Self {
        Self::select(m, self, Self::zero())
    }
}

/// The portable backend: an array, operated on lane by lane.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Lanes<const FUSED: bool>(pub [f32; LANES]);

impl<const FUSED: bool> Lanes<FUSED> {
    #[inline(always)]
    fn map(self, f: impl Fn(f32) -> f32) -> Self {
        let mut out = self.0;
        for o in &mut out {
            *o = f(*o);
        }
        Lanes(out)
    }

    #[inline(always)]
    fn zip(self, b: Self, f: impl Fn(f32, f32) -> f32) -> Self {
        let mut out = self.0;
        for (o, b) in out.iter_mut().zip(b.0) {
            *o = f(*o, b);
        }
        Lanes(out)
    }

    #[inline(always)]
    fn compare(self, b: Self, f: impl Fn(f32, f32) -> bool) -> LaneMask {
        let mut out = [0u32; LANES];
        for l in 0..LANES {
            out[l] = if f(self.0[l], b.0[l]) { u32::MAX } else { 0 };
        }
        LaneMask(out)
    }
}

/// [`Lanes`]' mask: all ones or all zeros per lane, the width of a lane, so that a compare
/// and a select compile to a vector compare and a blend (with `bool` lanes they need
/// conversions between widths).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct LaneMask(pub [u32; LANES]);

impl LaneMask {
    /// The lanes where `f(lane)` holds: a plain loop (`array::from_fn` is not inlined into
    /// `with_fma`'s kernels).
    #[inline(always)]
    pub(crate) fn from_fn(f: impl Fn(usize) -> bool) -> Self {
        let mut out = [0u32; LANES];
        for (l, o) in out.iter_mut().enumerate() {
            *o = if f(l) { u32::MAX } else { 0 };
        }
        LaneMask(out)
    }
}

impl<const FUSED: bool> Wide for Lanes<FUSED> {
    type Mask = LaneMask;

    #[inline(always)]
    fn splat(v: f32) -> Self {
        Lanes([v; LANES])
    }
    #[inline(always)]
    fn add(self, b: Self) -> Self {
        self.zip(b, |a, b| a + b)
    }
    #[inline(always)]
    fn sub(self, b: Self) -> Self {
        self.zip(b, |a, b| a - b)
    }
    #[inline(always)]
    fn mul(self, b: Self) -> Self {
        self.zip(b, |a, b| a * b)
    }
    #[inline(always)]
    fn div(self, b: Self) -> Self {
        self.zip(b, |a, b| a / b)
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        self.map(f32::sqrt)
    }
    #[inline(always)]
    fn max(self, b: Self) -> Self {
        self.zip(b, f32::max)
    }
    #[inline(always)]
    fn neg(self) -> Self {
        self.map(|a| -a)
    }
    #[inline(always)]
    fn lt(self, b: Self) -> Self::Mask {
        self.compare(b, |a, b| a < b)
    }
    #[inline(always)]
    fn le(self, b: Self) -> Self::Mask {
        self.compare(b, |a, b| a <= b)
    }
    // Negated comparisons on purpose: true where a lane is NaN.
    #[allow(clippy::neg_cmp_op_on_partial_ord)]
    #[inline(always)]
    fn not_le(self, b: Self) -> Self::Mask {
        self.compare(b, |a, b| !(a <= b))
    }
    #[allow(clippy::neg_cmp_op_on_partial_ord)]
    #[inline(always)]
    fn not_ge(self, b: Self) -> Self::Mask {
        self.compare(b, |a, b| !(a >= b))
    }
    #[inline(always)]
    fn and(a: Self::Mask, b: Self::Mask) -> Self::Mask {
        let mut out = a.0;
        for (o, b) in out.iter_mut().zip(b.0) {
            *o &= b;
        }
        LaneMask(out)
    }
    #[inline(always)]
    fn select(m: Self::Mask, a: Self, b: Self) -> Self {
        let mut out = [0.0f32; LANES];
        for l in 0..LANES {
            let bits = (a.0[l].to_bits() & m.0[l]) | (b.0[l].to_bits() & !m.0[l]);
            out[l] = f32::from_bits(bits);
        }
        Lanes(out)
    }
}

/// One lane: the formulas applied to one particle at a time, where a kernel's lanes are
/// fewer than 16 (a block's last particles), as the scalar code would.
impl Wide for f32 {
    type Mask = bool;

    #[inline(always)]
    fn splat(v: f32) -> Self {
        v
    }
    #[inline(always)]
    fn add(self, b: Self) -> Self {
        self + b
    }
    #[inline(always)]
    fn sub(self, b: Self) -> Self {
        self - b
    }
    #[inline(always)]
    fn mul(self, b: Self) -> Self {
        self * b
    }
    #[inline(always)]
    fn div(self, b: Self) -> Self {
        self / b
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        f32::sqrt(self)
    }
    #[inline(always)]
    fn max(self, b: Self) -> Self {
        f32::max(self, b)
    }
    #[inline(always)]
    fn neg(self) -> Self {
        -self
    }
    #[inline(always)]
    fn lt(self, b: Self) -> bool {
        self < b
    }
    #[inline(always)]
    fn le(self, b: Self) -> bool {
        self <= b
    }
    #[allow(clippy::neg_cmp_op_on_partial_ord)]
    #[inline(always)]
    fn not_le(self, b: Self) -> bool {
        !(self <= b)
    }
    #[allow(clippy::neg_cmp_op_on_partial_ord)]
    #[inline(always)]
    fn not_ge(self, b: Self) -> bool {
        !(self >= b)
    }
    #[inline(always)]
    fn and(a: bool, b: bool) -> bool {
        a & b
    }
    #[inline(always)]
    fn select(m: bool, a: Self, b: Self) -> Self {
        if m {
            a
        } else {
            b
        }
    }
}

/// The AVX-512 backend: one `__m512`. Its methods use AVX-512F instructions without being
/// compiled for them on their own: only kernels with `#[target_feature(enable = "avx512f")]`
/// may call them, which inline them (`#[inline(always)]`).
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy, Debug)]
pub(crate) struct Zmm(pub std::arch::x86_64::__m512);

#[cfg(target_arch = "x86_64")]
mod zmm {
    use super::{Wide, Zmm};
    use std::arch::x86_64::*;

    // SAFETY (every method): a `Zmm` exists only inside the AVX-512 kernels, which run where
    // the CPU has AVX-512F (`SimdPath::Avx512` is used only where it is available).
    impl Wide for Zmm {
        type Mask = __mmask16;

        #[inline(always)]
        fn splat(v: f32) -> Self {
            Zmm(unsafe { _mm512_set1_ps(v) })
        }
        #[inline(always)]
        fn zero() -> Self {
            Zmm(unsafe { _mm512_setzero_ps() })
        }
        #[inline(always)]
        fn add(self, b: Self) -> Self {
            Zmm(unsafe { _mm512_add_ps(self.0, b.0) })
        }
        #[inline(always)]
        fn sub(self, b: Self) -> Self {
            Zmm(unsafe { _mm512_sub_ps(self.0, b.0) })
        }
        #[inline(always)]
        fn mul(self, b: Self) -> Self {
            Zmm(unsafe { _mm512_mul_ps(self.0, b.0) })
        }
        #[inline(always)]
        fn div(self, b: Self) -> Self {
            Zmm(unsafe { _mm512_div_ps(self.0, b.0) })
        }
        #[inline(always)]
        fn sqrt(self) -> Self {
            Zmm(unsafe { _mm512_sqrt_ps(self.0) })
        }
        #[inline(always)]
        fn max(self, b: Self) -> Self {
            // `vmaxps` returns its second operand where either is NaN, as `f32::max` does
            // for a NaN first operand.
            Zmm(unsafe { _mm512_max_ps(self.0, b.0) })
        }
        #[inline(always)]
        fn neg(self) -> Self {
            Zmm(unsafe {
                let sign = _mm512_set1_epi32(i32::MIN);
                _mm512_castsi512_ps(_mm512_xor_si512(_mm512_castps_si512(self.0), sign))
            })
        }
        #[inline(always)]
        fn lt(self, b: Self) -> Self::Mask {
            unsafe { _mm512_cmp_ps_mask::<_CMP_LT_OQ>(self.0, b.0) }
        }
        #[inline(always)]
        fn le(self, b: Self) -> Self::Mask {
            unsafe { _mm512_cmp_ps_mask::<_CMP_LE_OQ>(self.0, b.0) }
        }
        #[inline(always)]
        fn not_le(self, b: Self) -> Self::Mask {
            unsafe { _mm512_cmp_ps_mask::<_CMP_NLE_UQ>(self.0, b.0) }
        }
        #[inline(always)]
        fn not_ge(self, b: Self) -> Self::Mask {
            unsafe { _mm512_cmp_ps_mask::<_CMP_NGE_UQ>(self.0, b.0) }
        }
        #[inline(always)]
        fn and(a: Self::Mask, b: Self::Mask) -> Self::Mask {
            a & b
        }
        #[inline(always)]
        fn select(m: Self::Mask, a: Self, b: Self) -> Self {
            Zmm(unsafe { _mm512_mask_blend_ps(m, b.0, a.0) })
        }
        #[inline(always)]
        fn add_where(self, m: Self::Mask, x: Self) -> Self {
            Zmm(unsafe { _mm512_mask_add_ps(self.0, m, self.0, x.0) })
        }
        #[inline(always)]
        fn keep(self, m: Self::Mask) -> Self {
            Zmm(unsafe { _mm512_maskz_mov_ps(m, self.0) })
        }
    }
}
