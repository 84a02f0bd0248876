//! The smoothing kernels, written with support radius `h` (`W = 0` for `r ≥ h`), `q = r/h`:
//!
//! - [`KernelShape::CubicSpline`]: Monaghan's (1992) cubic spline as Bender & Koschier and
//!   SPlisHSPlasH write it, `W = k·(6q³ − 6q² + 1)` for `q ≤ ½`, `W = 2k·(1 − q)³` for
//!   `½ < q ≤ 1`, `k = 40 / (7π h²)`.
//! - [`KernelShape::WendlandC2`]: Wendland's (1995) C2 function in 2D,
//!   `W = k·(1 − q)⁴·(1 + 4q)`, `k = 7 / (π h²)` (Dehnen & Aly 2012, Table 1). Unlike the
//!   cubic spline it does not pair particles at wide supports: its gradient grows all the way
//!   in to `q = 0`.
//!
//! Both integrate to one over the plane.

use glam::Vec2;
use serde::{Deserialize, Serialize};

use crate::simd::wide::Wide;

/// Which smoothing kernel the solver uses, and with it the support in particle spacings
/// (the scene's `solver.kernel`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum KernelShape {
    /// The cubic spline at support 2d (about 13 neighbours on the hexagonal lattice).
    #[default]
    CubicSpline,
    /// Wendland C2 at support 3.5d (about 40 neighbours): a particle's density depends less on
    /// how its neighbours are arranged, so pressure resists shear less (docs/deep-columns.md).
    WendlandC2,
}

impl KernelShape {
    /// The support radius in particle spacings d. The cubic spline's gradient peaks at a
    /// third of its support, so beyond about 2d it pairs particles; Wendland C2 does not,
    /// and at 3.5d its dam break drains and its waves run as the measurements in
    /// docs/deep-columns.md show.
    pub fn support_in_spacings(self) -> f64 {
        match self {
            KernelShape::CubicSpline => 2.0,
            KernelShape::WendlandC2 => 3.5,
        }
    }
}

/// A smoothing kernel with a precomputed support radius and normalisation constants.
#[derive(Clone, Copy, Debug)]
pub struct Kernel {
    shape: KernelShape,
    h: f32,
    inv_h: f32,
    /// `W`'s constant: `40 / (7π h²)` (cubic spline) or `7 / (π h²)` (Wendland C2).
    k: f32,
    /// `dW/dq`'s constant: `6k` (cubic spline: `l·q·(3q − 2)`, `−l·(1 − q)²`) or `−20k`
    /// (Wendland C2: `l·q·(1 − q)³`).
    l: f32,
}

impl Kernel {
    /// The cubic spline with support radius `h` (metres).
    pub fn cubic_spline(h: f32) -> Self {
        Self::new(KernelShape::CubicSpline, h)
    }

    /// A kernel of `shape` with support radius `h` (metres): `W(r) = 0` for `r ≥ h`.
    pub fn new(shape: KernelShape, h: f32) -> Self {
        let pi = std::f32::consts::PI;
        let (k, l) = match shape {
            KernelShape::CubicSpline => {
                let k = 40.0 / (7.0 * pi * h * h);
                (k, 6.0 * k)
            }
            KernelShape::WendlandC2 => {
                let k = 7.0 / (pi * h * h);
                (k, -20.0 * k)
            }
        };
        Self {
            shape,
            h,
            inv_h: 1.0 / h,
            k,
            l,
        }
    }

    /// Which kernel this is.
    #[inline]
    pub fn shape(&self) -> KernelShape {
        self.shape
    }

    /// Support radius in metres.
    #[inline]
    pub fn support(&self) -> f32 {
        self.h
    }

    /// `W(r)` in 1/m².
    #[inline]
    pub fn w(&self, r: f32) -> f32 {
        self.w_of_q(r * self.inv_h)
    }

    /// `W` at `q = r/h` ([`Self::w_of_q_wide`] on one lane: the formula is written once).
    #[inline]
    fn w_of_q(&self, q: f32) -> f32 {
        self.w_of_q_wide(q)
    }

    /// `W(0)`, the self-contribution to a particle's own sums.
    #[inline]
    pub fn w_zero(&self) -> f32 {
        self.k
    }

    /// `∇_i W(x_i − x_j)` for the offset `r = x_i − x_j`, in 1/m³.
    #[inline]
    pub fn grad_w(&self, r: Vec2) -> Vec2 {
        self.w_and_grad(r).1
    }

    /// `W` and `∇W` together, sharing the square root ([`Self::w_and_grad_wide`] on one
    /// lane).
    #[inline]
    pub fn w_and_grad(&self, r: Vec2) -> (f32, Vec2) {
        let (w, gx, gy) = self.w_and_grad_wide(r.x, r.y);
        (w, Vec2::new(gx, gy))
    }

    /// `W` at `q = r/h` on the lanes of any [`Wide`] backend (16 lanes, or one `f32`):
    /// every piece evaluated, one kept per lane, so the same bits on every backend.
    #[inline(always)]
    pub(crate) fn w_of_q_wide<W: Wide>(&self, q: W) -> W {
        let c = W::splat;
        let inside = q.lt(c(1.0));
        let a = c(1.0).sub(q);
        let w = match self.shape {
            // `k·(6q³ − 6q² + 1)` for q ≤ ½, `2k·(1 − q)³` beyond.
            KernelShape::CubicSpline => {
                let q2 = q.mul(q);
                let six_q2 = c(6.0).mul(q2);
                let inner = c(self.k).mul(six_q2.mul(q).sub(six_q2).add(c(1.0)));
                let outer = c(2.0 * self.k).mul(a).mul(a).mul(a);
                W::select(q.le(c(0.5)), inner, outer)
            }
            // Wendland C2's `k·(1 − q)⁴·(1 + 4q)` as `(k·(a²·a²))·(1 + 4q)`, a = 1 − q.
            KernelShape::WendlandC2 => {
                let a2 = a.mul(a);
                c(self.k).mul(a2.mul(a2)).mul(c(1.0).add(c(4.0).mul(q)))
            }
        };
        w.keep(inside)
    }

    /// `dW/dq` on 16 lanes for q < 1 (beyond, a value the caller masks): the cubic
    /// spline's `l·q·(3q − 2)` for q ≤ ½ and `−l·(1 − q)²` beyond, Wendland C2's
    /// `(l·q)·(a·a·a)`.
    #[inline(always)]
    fn dw_of_q_wide<W: Wide>(&self, q: W) -> W {
        let c = W::splat;
        let a = c(1.0).sub(q);
        match self.shape {
            KernelShape::CubicSpline => {
                let inner = c(self.l).mul(q).mul(c(3.0).mul(q).sub(c(2.0)));
                let outer = c(-self.l).mul(a).mul(a);
                W::select(q.le(c(0.5)), inner, outer)
            }
            // `l·q·(1 − q)³` with `l = −20k`, as `(l·q)·(a·a·a)`.
            KernelShape::WendlandC2 => c(self.l).mul(q).mul(a.mul(a).mul(a)),
        }
    }

    /// [`Self::w`] at the 16 squared distances `r2`.
    #[inline(always)]
    pub(crate) fn w_at_squared_wide<W: Wide>(&self, r2: W) -> W {
        self.w_of_q_wide(r2.sqrt().mul(W::splat(self.inv_h)))
    }

    /// `W` and `∇W` at the offsets `(rx, ry)`: +0 where there is no gradient (q ≥ 1 or
    /// |r| ≤ 10⁻⁹). One square root for both: this is the per-pair work of the density pass.
    #[inline(always)]
    pub(crate) fn w_and_grad_wide<W: Wide>(&self, rx: W, ry: W) -> (W, W, W) {
        let c = W::splat;
        // `Vec2::length`: √(x·x + y·y).
        let rl = rx.mul(rx).add(ry.mul(ry)).sqrt();
        let q = rl.mul(c(self.inv_h));
        // The scalar form's `rl <= 1e-9 || q >= 1` has no gradient; a NaN offset has one (NaN).
        let has_grad = W::and(q.not_ge(c(1.0)), rl.not_le(c(1.0e-9)));
        let scale = self.dw_of_q_wide(q).mul(c(self.inv_h)).div(rl);
        (
            self.w_of_q_wide(q),
            rx.mul(scale).keep(has_grad),
            ry.mul(scale).keep(has_grad),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SHAPES: [KernelShape; 2] = [KernelShape::CubicSpline, KernelShape::WendlandC2];

    /// ∫W over the plane by the midpoint rule on a fine grid, in f64 for the sum.
    fn integral(kernel: &Kernel, cells: i32) -> f64 {
        let h = kernel.support() as f64;
        let dx = 2.0 * h / cells as f64;
        let mut sum = 0.0f64;
        for i in 0..cells {
            for j in 0..cells {
                let x = -h + (i as f64 + 0.5) * dx;
                let y = -h + (j as f64 + 0.5) * dx;
                sum += kernel.w((x * x + y * y).sqrt() as f32) as f64 * dx * dx;
            }
        }
        sum
    }

    #[test]
    fn integrates_to_one() {
        for shape in SHAPES {
            for h in [0.01f32, 0.04, 1.0] {
                let k = Kernel::new(shape, h);
                let s = integral(&k, 800);
                assert!((s - 1.0).abs() < 1.0e-3, "∫W = {s} for {shape:?}, h = {h}");
            }
        }
    }

    #[test]
    fn vanishes_at_and_beyond_support() {
        for k in SHAPES.map(|s| Kernel::new(s, 0.04)) {
            vanishes_at_and_beyond(k);
        }
    }

    fn vanishes_at_and_beyond(k: Kernel) {
        assert_eq!(k.w(0.04), 0.0);
        assert_eq!(k.w(0.05), 0.0);
        assert_eq!(k.grad_w(Vec2::new(0.04, 0.0)), Vec2::ZERO);
        assert_eq!(k.grad_w(Vec2::new(0.03, 0.03)), Vec2::ZERO);
        assert!(k.w(0.0399) > 0.0);
    }

    #[test]
    fn w_and_grad_agrees_with_w_and_grad_w_exactly() {
        for k in SHAPES.map(|s| Kernel::new(s, 0.04)) {
            fused_agrees(k);
        }
    }

    fn fused_agrees(k: Kernel) {
        // The density pass uses the fused form; the solver's other passes use grad_w.
        let mut points = vec![
            Vec2::ZERO,
            Vec2::new(1.0e-10, 0.0),
            Vec2::new(0.02, 0.0),
            Vec2::new(0.0, -0.04),
            Vec2::new(0.05, 0.01),
        ];
        for i in 0..400 {
            let a = i as f32 * 0.37;
            let r = (i as f32 / 400.0) * 0.045;
            points.push(Vec2::new(r * a.cos(), r * a.sin()));
        }
        for r in points {
            let (w, g) = k.w_and_grad(r);
            assert_eq!(w, k.w(r.length()), "W at {r:?}");
            assert_eq!(g, k.grad_w(r), "∇W at {r:?}");
        }
    }

    #[test]
    fn the_lane_form_gives_the_scalar_bits() {
        for k in SHAPES.map(|s| Kernel::new(s, 0.04)) {
            lanes_give_scalar_bits(k);
        }
    }

    fn lanes_give_scalar_bits(k: Kernel) {
        // Both pieces of the spline, their joins, the support's edge, beyond it, zero, and
        // a NaN offset.
        let mut offsets = vec![
            Vec2::ZERO,
            Vec2::new(1.0e-10, 0.0),
            Vec2::new(0.02, 0.0),
            Vec2::new(0.0, -0.04),
            Vec2::new(0.05, 0.01),
            Vec2::new(f32::NAN, 0.01),
        ];
        for i in 0..634 {
            let a = i as f32 * 0.37;
            let r = (i as f32 / 600.0) * 0.045;
            offsets.push(Vec2::new(r * a.cos(), r * a.sin()));
        }
        for chunk in offsets.chunks_exact(16) {
            let chunk: &[Vec2; 16] = chunk.try_into().unwrap();
            let rx = std::array::from_fn(|l| chunk[l].x);
            let ry = std::array::from_fn(|l| chunk[l].y);
            use crate::simd::wide::Lanes;
            let (w, gx, gy) = k.w_and_grad_wide(Lanes::<false>(rx), Lanes::<false>(ry));
            let (w, gx, gy) = (w.0, gx.0, gy.0);
            let squares = chunk.map(|r| r.length_squared());
            let w_of_r = k.w_at_squared_wide(Lanes::<false>(squares)).0;
            for (l, &r) in chunk.iter().enumerate() {
                assert_eq!(w_of_r[l].to_bits(), k.w(r.length()).to_bits(), "W({r:?})");
                let (ws, gs) = k.w_and_grad(r);
                assert_eq!(w[l].to_bits(), ws.to_bits(), "W at {r:?}");
                assert_eq!(gx[l].to_bits(), gs.x.to_bits(), "∇W x at {r:?}");
                assert_eq!(gy[l].to_bits(), gs.y.to_bits(), "∇W y at {r:?}");
            }
        }
    }

    #[test]
    fn continuous_at_half_support() {
        let k = Kernel::cubic_spline(1.0);
        let below = k.w(0.5 - 1e-6);
        let above = k.w(0.5 + 1e-6);
        assert!((below - above).abs() < 1e-4);
    }

    #[test]
    fn gradient_matches_finite_differences() {
        for k in SHAPES.map(|s| Kernel::new(s, 0.04)) {
            gradient_matches_differences(k);
        }
    }

    fn gradient_matches_differences(k: Kernel) {
        for &(x, y) in &[
            (0.003, 0.001),
            (0.012, -0.007),
            (-0.02, 0.015),
            (0.0, 0.031),
            (-0.025, -0.02),
            (0.019, 0.0005),
        ] {
            let g = k.grad_w(Vec2::new(x as f32, y as f32));
            // Central differences of W evaluated in f64 through the f32 kernel would be
            // noisy; a wide step on a smooth kernel keeps the truncation error small.
            let wf = |x: f64, y: f64| k.w((x * x + y * y).sqrt() as f32) as f64;
            let step = 1.0e-5;
            let gx = (wf(x + step, y) - wf(x - step, y)) / (2.0 * step);
            let gy = (wf(x, y + step) - wf(x, y - step)) / (2.0 * step);
            let scale = k.grad_w(Vec2::new(0.0133, 0.0)).length() as f64;
            assert!(
                (g.x as f64 - gx).abs() < 2e-3 * scale && (g.y as f64 - gy).abs() < 2e-3 * scale,
                "at ({x},{y}): analytic {g:?}, numeric ({gx},{gy})"
            );
        }
    }

    #[test]
    fn gradient_points_inward() {
        // W decreases with distance, so ∇_i W(x_i − x_j) points from i towards j's side:
        // along −r.
        for k in SHAPES.map(|s| Kernel::new(s, 1.0)) {
            let g = k.grad_w(Vec2::new(0.3, 0.0));
            assert!(g.x < 0.0 && g.y == 0.0);
        }
    }

    /// Wendland C2's value and slope at a few points, from its formula in f64:
    /// `W = 7/(πh²)·(1 − q)⁴(1 + 4q)`, `dW/dr = −140/(πh³)·q(1 − q)³`.
    #[test]
    fn wendland_matches_its_formula() {
        let h = 0.035f32;
        let k = Kernel::new(KernelShape::WendlandC2, h);
        assert_eq!(k.support(), h);
        let pi = std::f64::consts::PI;
        let h64 = h as f64;
        for q in [0.0f64, 0.1, 0.33, 0.5, 0.77, 0.99] {
            let w = 7.0 / (pi * h64 * h64) * (1.0 - q).powi(4) * (1.0 + 4.0 * q);
            let got = k.w((q * h64) as f32) as f64;
            assert!(
                (got - w).abs() <= 1e-5 * w.max(1.0),
                "W at q = {q}: {got} against {w}"
            );
            if q > 0.0 {
                let slope = -140.0 / (pi * h64.powi(3)) * q * (1.0 - q).powi(3);
                let g = k.grad_w(Vec2::new((q * h64) as f32, 0.0)).x as f64;
                assert!((g - slope).abs() <= 1e-4 * slope.abs(), "dW/dr at q = {q}");
            }
        }
        assert_eq!(k.w(h), 0.0);
    }
}
