//! The SIMD seam: which of three paths the pair loops take, chosen once per process.
//!
//! - [`SimdPath::Avx512`]: the AVX-512F kernels (`blocked::avx512`, the neighbour search's
//!   candidate filter), on x86-64 CPUs that have AVX-512F.
//! - [`SimdPath::Fma`]: the lane kernels (`blocked::lanes`), over 16 `f32` lanes (one slot of
//!   a block), compiled with AVX2 and fused multiply-add enabled on x86-64 CPUs that have
//!   both (`with_fma`), and for NEON on aarch64. The compiler turns each slot's arithmetic
//!   into vector instructions. The pressure solve's multiply-adds are fused, as in the AVX-512
//!   kernels, and every other operation is the same in both and in the same order, so the
//!   two paths give the same bits (tested where the CPU runs both).
//! - [`SimdPath::Portable`]: the same lane kernels with separate multiplies and adds, for
//!   any target (wasm32 included; with `-C target-feature=+simd128` the compiler vectorises
//!   them there too). Its pressure sums round differently from the other two paths.
//!
//! The physics is written once: the kernel (`Kernel::w_and_grad_wide`) and every pair
//! pass's arithmetic (`blocked::formulas`) are generic over the lane type [`wide::Wide`],
//! whose backends are an array of 16 lanes (the lane kernels), one `f32` (a block's
//! per-particle terms) and one AVX-512 register. What the two kinds of kernels keep apart is
//! how they read a slot's 16 neighbour values: the lane kernels with 16 loads, which the
//! compiler cannot do better; the AVX-512 kernels with a gather instruction, or, on AMD, by
//! permutes out of three windows of 32 particles loaded once per block
//! (`blocked::Gather::Windows`), and the neighbour search compresses the candidates that
//! pass into its list in one instruction. Compiled for AVX-512 instead, the lane kernels
//! took 1.75 times the AVX-512 kernels' wall time on the 20k benchmark (AMD Zen 5,
//! docs/PERFORMANCE.md); on an Intel Xeon with AVX-512 the `fma` path takes 1.34 times the
//! `avx512` path's.
//!
//! Each path sums every particle's pairs in list order, so results are bit-identical across
//! thread counts on any one path. A recording notes the path that made it
//! (`recording::Header::simd`).
//!
//! The environment variable `DFSPH2D_SIMD` picks a path: `auto` (the default: the fastest
//! the CPU has), `avx512`, `fma` or `portable`. The command line checks it with
//! [`SimdPath::from_env`] and refuses a bad value; the library falls back to `auto` then.

use std::fmt;
use std::sync::OnceLock;

pub(crate) mod wide;

/// The environment variable that forces a path.
pub const ENV: &str = "DFSPH2D_SIMD";

/// Which kernels run the pair loops. The default is the one every CPU runs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum SimdPath {
    /// Hand-written AVX-512F kernels.
    Avx512,
    /// Lane kernels with fused multiply-adds, compiled for AVX2 + FMA (x86-64) or NEON.
    Fma,
    /// Lane kernels with separate multiplies and adds: any CPU, any target.
    #[default]
    Portable,
}

impl SimdPath {
    /// Every path, fastest first.
    pub const ALL: [SimdPath; 3] = [SimdPath::Avx512, SimdPath::Fma, SimdPath::Portable];

    /// The name used in `DFSPH2D_SIMD`, recordings and benchmark rows.
    pub fn name(self) -> &'static str {
        match self {
            SimdPath::Avx512 => "avx512",
            SimdPath::Fma => "fma",
            SimdPath::Portable => "portable",
        }
    }

    /// The path called `name` ([`Self::name`]).
    pub fn from_name(name: &str) -> Option<SimdPath> {
        Self::ALL.into_iter().find(|p| p.name() == name)
    }

    /// Whether this CPU can run the path.
    pub fn available(self) -> bool {
        match self {
            SimdPath::Portable => true,
            #[cfg(target_arch = "x86_64")]
            SimdPath::Avx512 => {
                // Every AVX-512F CPU has AVX2 and FMA too; the lane kernels count on them.
                std::arch::is_x86_feature_detected!("avx512f") && SimdPath::Fma.available()
            }
            #[cfg(target_arch = "x86_64")]
            SimdPath::Fma => {
                std::arch::is_x86_feature_detected!("avx2")
                    && std::arch::is_x86_feature_detected!("fma")
            }
            #[cfg(target_arch = "aarch64")]
            SimdPath::Fma => true,
            #[allow(unreachable_patterns)]
            _ => false,
        }
    }

    /// The paths this CPU can run, fastest first.
    pub fn available_paths() -> impl Iterator<Item = SimdPath> {
        Self::ALL.into_iter().filter(|p| p.available())
    }

    /// The fastest path this CPU can run.
    pub fn fastest() -> SimdPath {
        Self::available_paths().next().unwrap_or(SimdPath::Portable)
    }

    /// The path `DFSPH2D_SIMD` asks for: `None` where it is unset or `auto`, an error where it
    /// names no path or one this CPU cannot run.
    pub fn from_env() -> Result<Option<SimdPath>, SimdEnvError> {
        match std::env::var(ENV) {
            Err(std::env::VarError::NotPresent) => Ok(None),
            Err(std::env::VarError::NotUnicode(v)) => {
                Err(SimdEnvError::Unknown(v.to_string_lossy().into_owned()))
            }
            Ok(v) if v.is_empty() || v == "auto" => Ok(None),
            Ok(v) => match SimdPath::from_name(&v) {
                None => Err(SimdEnvError::Unknown(v)),
                Some(p) if !p.available() => Err(SimdEnvError::Unavailable(p)),
                Some(p) => Ok(Some(p)),
            },
        }
    }

    /// The path this process runs: the one `DFSPH2D_SIMD` names, else (unset, `auto` or
    /// refused) the fastest. Read once.
    pub fn in_use() -> SimdPath {
        static IN_USE: OnceLock<SimdPath> = OnceLock::new();
        *IN_USE.get_or_init(|| {
            SimdPath::from_env()
                .ok()
                .flatten()
                .unwrap_or_else(SimdPath::fastest)
        })
    }

    /// Whether the lane kernels fuse their multiply-adds on this path.
    pub(crate) fn fused(self) -> bool {
        self != SimdPath::Portable
    }
}

impl fmt::Display for SimdPath {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Why `DFSPH2D_SIMD` was refused.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum SimdEnvError {
    /// The value names no path.
    Unknown(String),
    /// The path exists but this CPU cannot run it.
    Unavailable(SimdPath),
}

impl fmt::Display for SimdEnvError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SimdEnvError::Unknown(v) => write!(
                f,
                "{ENV}={v:?} names no SIMD path: use auto, avx512, fma or portable"
            ),
            SimdEnvError::Unavailable(p) => write!(
                f,
                "{ENV}={p}: this CPU cannot run that path (it runs {})",
                SimdPath::fastest()
            ),
        }
    }
}

impl std::error::Error for SimdEnvError {}

/// `a·b + c`, rounded once where `FUSED` (the [`SimdPath::Fma`] path), else twice.
#[inline(always)]
pub(crate) fn mul_add<const FUSED: bool>(a: f32, b: f32, c: f32) -> f32 {
    if FUSED {
        a.mul_add(b, c)
    } else {
        a * b + c
    }
}

/// Runs `kernel` compiled with AVX2 and FMA enabled: the lane kernels it inlines (marked
/// `#[inline(always)]`) are then vectorised for them, and `f32::mul_add` becomes one
/// instruction instead of a library call.
///
/// # Safety
/// The CPU must have AVX2 and FMA ([`SimdPath::Fma`]`.available()`).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
pub(crate) unsafe fn with_fma<R>(kernel: impl FnOnce() -> R) -> R {
    kernel()
}

/// Runs `kernel`: on aarch64 NEON and fused multiply-add are part of the base target.
///
/// # Safety
/// None; `unsafe` to match the x86-64 version.
#[cfg(not(target_arch = "x86_64"))]
#[inline(always)]
pub(crate) unsafe fn with_fma<R>(kernel: impl FnOnce() -> R) -> R {
    kernel()
}

/// Calls the lane kernel `$kernel::<..., FUSED>($args)` for the path `$path`: with `FUSED`
/// and compiled for FMA ([`with_fma`]) on [`SimdPath::Fma`] (and [`SimdPath::Avx512`], for a
/// pass that has no AVX-512 kernel), else without.
///
/// Use it inside `unsafe`: it calls [`with_fma`], which is sound because a path is only in
/// use where the CPU runs it ([`SimdPath::available`]; `Avx512` implies AVX2 and FMA).
macro_rules! lane_kernel {
    ($path:expr, $kernel:ident::<$($t:ty),*>($($arg:expr),* $(,)?)) => {
        if $path.fused() {
            $crate::simd::with_fma(
                #[inline(always)]
                || $kernel::<$($t,)* true>($($arg),*),
            )
        } else {
            $kernel::<$($t,)* false>($($arg),*)
        }
    };
}
pub(crate) use lane_kernel;

/// AVX-512 building blocks that several kernels share (the pair kernels of
/// `blocked/avx512.rs`, the neighbour search's).
#[cfg(target_arch = "x86_64")]
pub(crate) mod avx512 {
    use std::arch::x86_64::*;

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
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_the_fastest_path_is_available() {
        for p in SimdPath::ALL {
            assert_eq!(SimdPath::from_name(p.name()), Some(p));
        }
        assert_eq!(SimdPath::from_name("avx2"), None);
        assert!(SimdPath::Portable.available());
        assert!(SimdPath::fastest().available());
        assert!(SimdPath::in_use().available());
    }

    #[test]
    fn fused_and_separate_multiply_adds_round_differently() {
        // 1 + 2⁻²³ squared is 1 + 2⁻²² + 2⁻⁴⁶; minus (1 + 2⁻²²) that leaves 2⁻⁴⁶ when
        // rounded once and 0 when the product is rounded first.
        let a = 1.0 + f32::EPSILON;
        let c = -(1.0 + 2.0 * f32::EPSILON);
        assert_eq!(mul_add::<false>(a, a, c), 0.0);
        assert_eq!(mul_add::<true>(a, a, c), 2f32.powi(-46));
        if SimdPath::Fma.available() {
            // SAFETY: just checked.
            let fused = unsafe { with_fma(|| mul_add::<true>(a, a, c)) };
            assert_eq!(fused, 2f32.powi(-46));
        }
    }
}
