//! The pair passes' arithmetic, written once over the lane type
//! ([`crate::simd::wide::Wide`]): what one slot of a block (16 pairs) adds to each lane's
//! sums, and the pressure solve's per-particle terms. The lane kernels (`lanes.rs`) and the
//! AVX-512 kernels (`avx512.rs`) read a slot's neighbours their own way and hand the values
//! to these functions, so both paths compute the same formulas in the same order.

use crate::kernel::Kernel;
use crate::simd::wide::Wide;

/// A block's density sums per lane: `ρ/ρ0` from `start`, `Σ V∇W` (x, y) and `Σ |V∇W|²`.
#[derive(Clone, Copy)]
pub(super) struct DensitySums<W> {
    pub density: W,
    pub grad_x: W,
    pub grad_y: W,
    pub grad_sq: W,
}

impl<W: Wide> DensitySums<W> {
    #[inline(always)]
    pub fn new(start: f32) -> Self {
        DensitySums {
            density: W::splat(start),
            grad_x: W::zero(),
            grad_y: W::zero(),
            grad_sq: W::zero(),
        }
    }

    /// Add the slot whose offsets `x_i − x_j` are `(rx, ry)`, where `pair` (padding lanes
    /// keep their sums); returns the slot's `∇W`, +0 on padding and where there is none.
    #[inline(always)]
    pub fn add_slot(
        &mut self,
        kernel: &Kernel,
        (rx, ry): (W, W),
        pair: W::Mask,
        volume: f32,
    ) -> (W, W) {
        let (w, gx, gy) = kernel.w_and_grad_wide(rx, ry);
        let (gx, gy) = (gx.keep(pair), gy.keep(pair));
        let v = W::splat(volume);
        let (vx, vy) = (v.mul(gx), v.mul(gy));
        self.density = self.density.add_where(pair, v.mul(w));
        self.grad_x = self.grad_x.add_where(pair, vx);
        self.grad_y = self.grad_y.add_where(pair, vy);
        // `length_squared`: x·x + y·y.
        self.grad_sq = self.grad_sq.add_where(pair, vx.mul(vx).add(vy.mul(vy)));
        (gx, gy)
    }
}

/// `sum + V·W(x̃_i − x̃_j)` over the slot's pairs within the support, with the advected
/// positions `x̃ = x + Δt·v`: `(xi, yi)` the lanes' own, `p` and `v` the neighbours'
/// positions and velocities; `other` marks the lanes whose entry is not the particle itself.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(super) fn advected_slot<W: Wide>(
    kernel: &Kernel,
    sum: W,
    (xi, yi): (W, W),
    (px, py): (W, W),
    (vx, vy): (W, W),
    dt: f32,
    other: W::Mask,
    volume: f32,
) -> W {
    let (dt, support) = (W::splat(dt), kernel.support());
    // `x_j + Δt·v_j`, then `(x̃_i − x̃_j).length_squared()`.
    let (xj, yj) = (px.add(dt.mul(vx)), py.add(dt.mul(vy)));
    let (dx, dy) = (xi.sub(xj), yi.sub(yj));
    let r2 = dx.mul(dx).add(dy.mul(dy));
    let near = W::and(other, r2.lt(W::splat(support * support)));
    sum.add_where(near, W::splat(volume).mul(kernel.w_at_squared_wide(r2)))
}

/// A block's viscosity sums per lane: XSPH's `−Σ v_ij W_ij` and the Laplacian's
/// `Σ ∇W_ij (v_ij·x_ij / (|x_ij|² + ε²))`, x and y.
#[derive(Clone, Copy)]
pub(super) struct ViscositySums<W> {
    pub xsph: (W, W),
    pub laplacian: (W, W),
}

impl<W: Wide> ViscositySums<W> {
    #[inline(always)]
    pub fn new() -> Self {
        ViscositySums {
            xsph: (W::zero(), W::zero()),
            laplacian: (W::zero(), W::zero()),
        }
    }

    /// Add the slot whose offsets are `x_ij = (x, y)`, relative velocities `v_ij = (u, v)`
    /// and gradients `(gx, gy)`, where `pair`; the Laplacian's only with `laplacian`.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub fn add_slot(
        &mut self,
        kernel: &Kernel,
        (x, y): (W, W),
        (u, v): (W, W),
        (gx, gy): (W, W),
        pair: W::Mask,
        eps2: f32,
        laplacian: bool,
    ) {
        // `x_ij.length()`, then W.
        let r2 = x.mul(x).add(y.mul(y));
        let w = kernel.w_at_squared_wide(r2);
        let (sx, sy) = self.xsph;
        self.xsph = (
            W::select(pair, sx.sub(u.mul(w)), sx),
            W::select(pair, sy.sub(v.mul(w)), sy),
        );
        if laplacian {
            let ratio = u.mul(x).add(v.mul(y)).div(r2.add(W::splat(eps2)));
            let (lx, ly) = self.laplacian;
            self.laplacian = (
                lx.add_where(pair, gx.mul(ratio)),
                ly.add_where(pair, gy.mul(ratio)),
            );
        }
    }
}

/// The density-rate pass's constants per particle block (see [`super::ResidualTerms`]).
pub(super) struct ResidualInputs<W> {
    /// `v_i` and `g_i = Σ_j V∇W_ij + walls`.
    pub vel: (W, W),
    pub grad_sum: (W, W),
    pub wall_flux: W,
    pub source: W,
    pub factor: W,
}

/// The pressure solve's per-particle residual from the slot sums `fluid = Σ_j v_j·∇W_ij`:
/// `r_i = v_i·g_i − V·fluid − f_i`, `e_i = max(s_i + c·r_i, 0)`, `Δκ_i = e_i·a_i·c'`;
/// returns `(r, e, Δκ)`.
#[inline(always)]
pub(super) fn residual<W: Wide>(
    fluid: W,
    t: &ResidualInputs<W>,
    volume: f32,
    rate_scale: f32,
    increment_scale: f32,
) -> (W, W, W) {
    // v_i·g_i as glam's `dot`: x·x' + y·y'.
    let dot = t.vel.0.mul(t.grad_sum.0).add(t.vel.1.mul(t.grad_sum.1));
    let r = dot.sub(W::splat(volume).mul(fluid)).sub(t.wall_flux);
    let e = t.source.add(W::splat(rate_scale).mul(r)).max(W::zero());
    let d = e.mul(t.factor).mul(W::splat(increment_scale));
    (r, e, d)
}

/// The pressure push on a particle block: `v_i − (κ_i·g_i + V·s_i)` with `s_i = Σ_j κ_j ∇W_ij`.
#[inline(always)]
pub(super) fn pushed<W: Wide>(
    vel: (W, W),
    kappa: W,
    grad_sum: (W, W),
    sums: (W, W),
    volume: f32,
) -> (W, W) {
    let v = W::splat(volume);
    // Δv = −(κ_i·g_i + V·s), then v + Δv.
    let dvx = kappa.mul(grad_sum.0).add(v.mul(sums.0)).neg();
    let dvy = kappa.mul(grad_sum.1).add(v.mul(sums.1)).neg();
    (vel.0.add(dvx), vel.1.add(dvy))
}
