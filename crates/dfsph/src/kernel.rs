//! The 2D cubic spline kernel (Monaghan 1992) written with support radius `h`, as used by
//! Bender & Koschier and SPlisHSPlasH: `W(r) = k·(6q³ − 6q² + 1)` for `q = r/h ≤ ½`,
//! `W(r) = 2k·(1 − q)³` for `½ < q ≤ 1`, `W = 0` beyond, with the 2D normalisation
//! `k = 40 / (7π h²)` so that `∫ W dA = 1`.

use glam::Vec2;

/// Cubic spline kernel with a precomputed support radius and normalisation constants.
#[derive(Clone, Copy, Debug)]
pub struct CubicSpline {
    h: f32,
    inv_h: f32,
    /// `k = 40 / (7π h²)`.
    k: f32,
    /// `l = 240 / (7π h²)`, the derivative's constant (`6k`).
    l: f32,
}

impl CubicSpline {
    /// A kernel with support radius `h` (metres): `W(r) = 0` for `r ≥ h`.
    pub fn new(h: f32) -> Self {
        let pi = std::f32::consts::PI;
        let k = 40.0 / (7.0 * pi * h * h);
        Self {
            h,
            inv_h: 1.0 / h,
            k,
            l: 6.0 * k,
        }
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

    /// `W` at `q = r/h`.
    #[inline]
    fn w_of_q(&self, q: f32) -> f32 {
        if q <= 0.5 {
            let q2 = q * q;
            self.k * (6.0 * q2 * q - 6.0 * q2 + 1.0)
        } else if q < 1.0 {
            let a = 1.0 - q;
            2.0 * self.k * a * a * a
        } else {
            0.0
        }
    }

    /// `dW/dq` for `0 ≤ q < 1`.
    #[inline]
    fn dw_dq(&self, q: f32) -> f32 {
        if q <= 0.5 {
            self.l * q * (3.0 * q - 2.0)
        } else {
            let a = 1.0 - q;
            -self.l * a * a
        }
    }

    /// `(k, l, 1/h)`: the constants of [`Self::w`] and of `dW/dq`, for the SIMD density pass,
    /// which evaluates the same expressions 16 pairs at a time.
    #[inline]
    pub(crate) fn constants(&self) -> (f32, f32, f32) {
        (self.k, self.l, self.inv_h)
    }

    /// `W(0)`, the self-contribution to a particle's own sums.
    #[inline]
    pub fn w_zero(&self) -> f32 {
        self.k
    }

    /// `∇_i W(x_i − x_j)` for the offset `r = x_i − x_j`, in 1/m³.
    #[inline]
    pub fn grad_w(&self, r: Vec2) -> Vec2 {
        let rl = r.length();
        let q = rl * self.inv_h;
        if rl <= 1.0e-9 || q >= 1.0 {
            return Vec2::ZERO;
        }
        // dW/dq · (1/h) · r/|r|
        r * (self.dw_dq(q) * self.inv_h / rl)
    }

    /// `W` and `∇W` together, sharing the square root.
    #[inline]
    pub fn w_and_grad(&self, r: Vec2) -> (f32, Vec2) {
        // One square root for both: this is the per-pair work of the density pass.
        let rl = r.length();
        let q = rl * self.inv_h;
        if rl <= 1.0e-9 || q >= 1.0 {
            return (self.w_of_q(q), Vec2::ZERO);
        }
        (self.w_of_q(q), r * (self.dw_dq(q) * self.inv_h / rl))
    }

    /// [`Self::w_of_q`] without branches: each piece of the spline evaluated, one kept, with
    /// the same operations, so the same bits. The lane forms below are built on it.
    #[inline(always)]
    fn w_of_q_selected(&self, q: f32) -> f32 {
        let (q2, a) = (q * q, 1.0 - q);
        let inner = self.k * (6.0 * q2 * q - 6.0 * q2 + 1.0);
        let outer = 2.0 * self.k * a * a * a;
        if q <= 0.5 {
            inner
        } else if q < 1.0 {
            outer
        } else {
            0.0
        }
    }

    /// [`Self::w`] for the 16 distances `r`, into `w`: the same bits, vectorisable.
    #[inline(always)]
    pub(crate) fn w_lanes(&self, r: &[f32; 16], w: &mut [f32; 16]) {
        for l in 0..16 {
            w[l] = self.w_of_q_selected(r[l] * self.inv_h);
        }
    }

    /// [`Self::w_and_grad`] for the 16 offsets `(rx[l], ry[l])`: `W` into `w`, `∇W` into
    /// `(gx, gy)`. No branches (each lane evaluates both pieces of the spline and keeps one),
    /// so the compiler can vectorise it; the same operations in the same order as the scalar
    /// form, so the same bits.
    #[inline(always)]
    pub(crate) fn w_and_grad_lanes(
        &self,
        rx: &[f32; 16],
        ry: &[f32; 16],
        w: &mut [f32; 16],
        gx: &mut [f32; 16],
        gy: &mut [f32; 16],
    ) {
        for l in 0..16 {
            let (x, y) = (rx[l], ry[l]);
            // `Vec2::length`: √(x·x + y·y).
            let rl = (x * x + y * y).sqrt();
            let q = rl * self.inv_h;
            w[l] = self.w_of_q_selected(q);
            let a = 1.0 - q;
            let dw = if q <= 0.5 {
                self.l * q * (3.0 * q - 2.0)
            } else {
                -self.l * a * a
            };
            let scale = dw * self.inv_h / rl;
            let outside = rl <= 1.0e-9 || q >= 1.0;
            gx[l] = if outside { 0.0 } else { x * scale };
            gy[l] = if outside { 0.0 } else { y * scale };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// ∫W over the plane by the midpoint rule on a fine grid, in f64 for the sum.
    fn integral(kernel: &CubicSpline, cells: i32) -> f64 {
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
        for h in [0.01f32, 0.04, 1.0] {
            let k = CubicSpline::new(h);
            let s = integral(&k, 800);
            assert!((s - 1.0).abs() < 1.0e-3, "∫W = {s} for h = {h}");
        }
    }

    #[test]
    fn vanishes_at_and_beyond_support() {
        let k = CubicSpline::new(0.04);
        assert_eq!(k.w(0.04), 0.0);
        assert_eq!(k.w(0.05), 0.0);
        assert_eq!(k.grad_w(Vec2::new(0.04, 0.0)), Vec2::ZERO);
        assert_eq!(k.grad_w(Vec2::new(0.03, 0.03)), Vec2::ZERO);
        assert!(k.w(0.0399) > 0.0);
    }

    #[test]
    fn w_and_grad_agrees_with_w_and_grad_w_exactly() {
        // The density pass uses the fused form; the solver's other passes use grad_w.
        let k = CubicSpline::new(0.04);
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
        // Both pieces of the spline, their joins, the support's edge, beyond it, zero, and
        // a NaN offset.
        let k = CubicSpline::new(0.04);
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
            let (mut w, mut gx, mut gy) = ([0.0; 16], [0.0; 16], [0.0; 16]);
            k.w_and_grad_lanes(&rx, &ry, &mut w, &mut gx, &mut gy);
            let (lengths, mut w_of_r) = (chunk.map(|r| r.length()), [0.0; 16]);
            k.w_lanes(&lengths, &mut w_of_r);
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
        let k = CubicSpline::new(1.0);
        let below = k.w(0.5 - 1e-6);
        let above = k.w(0.5 + 1e-6);
        assert!((below - above).abs() < 1e-4);
    }

    #[test]
    fn gradient_matches_finite_differences() {
        let k = CubicSpline::new(0.04);
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
        let k = CubicSpline::new(1.0);
        let g = k.grad_w(Vec2::new(0.3, 0.0));
        assert!(g.x < 0.0 && g.y == 0.0);
    }
}
