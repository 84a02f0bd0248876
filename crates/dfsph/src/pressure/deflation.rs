//! A coarse space for the conjugate-gradient density solve: deflation by aggregates (Nicolaides
//! 1987; Saad, Yeung, Erhel & Guyomarc'h 2000, "A deflated version of the conjugate gradient
//! algorithm").
//!
//! The diagonal preconditioner lets conjugate gradients move information about one
//! neighbourhood per iteration: a pressure change that spans many layers (a deep pool
//! disturbed by a drop, a column starting to collapse) takes about as many iterations as the
//! water has layers. Deflation solves the smooth part of the error exactly, every iteration,
//! on a coarse space: the particles that carry stiffness are grouped into square cells
//! (aggregates), and `W` is the matrix whose column `c` is 1 on the particles of aggregate `c`
//! and 0 elsewhere (piecewise-constant stiffness). With `E = Wᵀ A W` (the Galerkin coarse
//! operator, one unknown per aggregate) deflated CG keeps every residual's sum over each
//! aggregate at zero and every search direction A-orthogonal to `W`: the iteration only has to
//! resolve what varies inside an aggregate, whatever the water's depth.
//!
//! `A W` is found with the solve's own products: an aggregate at least twice the reach of `A`
//! (two kernel supports) wide meets, within that reach of any particle, at most one aggregate
//! of each of the four colours of a checkerboard of 2 × 2 cells. So `A W_k 1` (`W_k` the
//! columns of colour k) gives every particle's entry for the one aggregate of colour k near
//! it: four products `A p` per step (the cost of four iterations) in place of a pass over
//! every pair. Free rigid bodies couple every particle along a body's outline, beyond that
//! reach: with bodies the solve runs without deflation. Each iteration then needs `(A W)ᵀ z`
//! (a sparse product over the stored entries) and two solves with `E`, which is factorised
//! once per step by Cholesky on its envelope (the aggregates numbered along the shorter side
//! of the water, so that the envelope is about one row of aggregates wide).

use crate::par::prelude::*;
use glam::Vec2;

/// No aggregate: the particle carries no stiffness.
const NONE: u32 = u32::MAX;
/// The narrowest aggregate, in kernel supports: twice the reach of `A` (two supports), so
/// that the colouring holds.
pub const MIN_CELL_SUPPORTS: f32 = 4.0;
/// Colours of the aggregates' checkerboard (2 × 2).
pub(crate) const COLOURS: usize = 4;

/// The coarse space of one step: aggregates, `A W` and the factorised `E`.
#[derive(Clone, Debug, Default)]
pub(crate) struct CoarseSpace {
    /// Aggregate of each fluid particle, or [`NONE`].
    aggregate: Vec<u32>,
    /// Aggregates in use.
    count: usize,
    /// The grid: lower corner, cell width, cells along x and y, and the aggregate of each cell
    /// (by [`Self::key`]) or [`NONE`].
    origin: glam::Vec2,
    cell: f32,
    cells: glam::UVec2,
    cell_aggregate: Vec<u32>,
    /// Cell of each aggregate.
    aggregate_cell: Vec<glam::UVec2>,
    /// `A W_k 1` per colour k, per particle, as the products gave it.
    aw: [Vec<f32>; COLOURS],
    /// Each particle's entry of `A W` per colour, (aggregate, value): scratch of
    /// [`Self::factorise`].
    colour_entries: Vec<[(u32, f32); COLOURS]>,
    /// `A W` by aggregate: entries `aw_t_start[c]..aw_t_start[c + 1]` of `aw_t_row` and
    /// `aw_t_val`, for `(A W)ᵀ z` in parallel and in a fixed order.
    aw_t_start: Vec<u32>,
    aw_t_row: Vec<u32>,
    aw_t_val: Vec<f32>,
    /// Members of each aggregate, `members_start[c]..members_start[c + 1]` of `members`.
    members_start: Vec<u32>,
    members: Vec<u32>,
    /// `E` and then its Cholesky factor L, row by row from each row's first column
    /// (`first[c]`) to the diagonal: row c at `row_start[c]..row_start[c + 1]`.
    first: Vec<u32>,
    row_start: Vec<usize>,
    factor: Vec<f64>,
}

impl CoarseSpace {
    /// Group the active particles (`active[i] > 0`) into square cells `cell` wide (m; at
    /// least four kernel supports, twice the reach of `A`, for the colouring to hold) and
    /// number the cells in use row by row along the shorter side of their bounding box.
    pub fn aggregate(&mut self, position: &[Vec2], active: &[f32], cell: f32) {
        let n = position.len();
        let (lo, hi) = (0..n)
            .filter(|&i| active[i] > 0.0)
            .fold((Vec2::INFINITY, Vec2::NEG_INFINITY), |(lo, hi), i| {
                (lo.min(position[i]), hi.max(position[i]))
            });
        self.aggregate.clear();
        self.aggregate.resize(n, NONE);
        self.count = 0;
        self.members_start.clear();
        self.members.clear();
        self.aggregate_cell.clear();
        self.cell_aggregate.clear();
        self.cells = glam::UVec2::ZERO;
        if lo.x > hi.x {
            self.members_start.push(0);
            return;
        }
        // The grid is dense over the active particles' bounding box: water spread thinly over
        // a large tank widens the cells until the grid has at most four cells per particle.
        let mut cell = cell;
        let cells_for = |cell: f32| ((hi - lo) / cell).floor().as_dvec2() + 1.0;
        while cells_for(cell).element_product() > 4.0 * n as f64 + 16.0 {
            cell *= 2.0;
        }
        self.origin = lo;
        self.cell = cell;
        self.cells = ((hi - lo) / cell).floor().as_uvec2() + 1;
        self.cell_aggregate
            .resize((self.cells.x * self.cells.y) as usize, NONE);
        // Each active particle's cell key first, its aggregate once the cells are numbered.
        for i in 0..n {
            if active[i] > 0.0 {
                let k = self.key(self.cell_of(position[i]).0);
                self.cell_aggregate[k] = 0;
                self.aggregate[i] = k as u32;
            }
        }
        // Number the cells in use in key order (along the shorter side).
        let short_side = self.cells.x.min(self.cells.y);
        for (k, a) in self.cell_aggregate.iter_mut().enumerate() {
            if *a == 0 {
                *a = self.count as u32;
                self.count += 1;
                let (row, column) = (k as u32 / short_side, k as u32 % short_side);
                self.aggregate_cell.push(if self.cells.x <= self.cells.y {
                    glam::UVec2::new(column, row)
                } else {
                    glam::UVec2::new(row, column)
                });
            }
        }
        let mut start = vec![0u32; self.count + 1];
        for a in self.aggregate.iter_mut().filter(|a| **a != NONE) {
            *a = self.cell_aggregate[*a as usize];
            start[*a as usize + 1] += 1;
        }
        for c in 0..self.count {
            start[c + 1] += start[c];
        }
        self.members.resize(start[self.count] as usize, 0);
        let mut next = start.clone();
        for (i, &a) in self.aggregate.iter().enumerate() {
            if a != NONE {
                self.members[next[a as usize] as usize] = i as u32;
                next[a as usize] += 1;
            }
        }
        self.members_start = start;
    }

    /// A cell's key: its index along the shorter side first.
    fn key(&self, c: glam::UVec2) -> usize {
        if self.cells.x <= self.cells.y {
            (c.y * self.cells.x + c.x) as usize
        } else {
            (c.x * self.cells.y + c.y) as usize
        }
    }

    /// The cell a point lies in (clamped to the grid) and where in it, in [0, 1)².
    fn cell_of(&self, p: Vec2) -> (glam::UVec2, Vec2) {
        let f = ((p - self.origin) / self.cell).max(Vec2::ZERO);
        let c = f.floor().as_uvec2().min(self.cells - 1);
        (c, f - c.as_vec2())
    }

    /// The aggregate of colour `k` within reach of a particle at `p`: its own cell's if that
    /// has the colour, else the neighbour cell on the nearer side, per axis.
    fn aggregate_of_colour(&self, p: Vec2, k: usize) -> u32 {
        let (c, f) = self.cell_of(p);
        let pick = |c: u32, f: f32, parity: u32, cells: u32| -> Option<u32> {
            if c % 2 == parity {
                Some(c)
            } else if f >= 0.5 {
                (c + 1 < cells).then_some(c + 1)
            } else {
                c.checked_sub(1)
            }
        };
        let (kx, ky) = ((k & 1) as u32, (k >> 1) as u32);
        match (
            pick(c.x, f.x, kx, self.cells.x),
            pick(c.y, f.y, ky, self.cells.y),
        ) {
            (Some(x), Some(y)) => self.cell_aggregate[self.key(glam::UVec2::new(x, y))],
            _ => NONE,
        }
    }

    /// `W_k 1`: 1 on the active particles of colour-k aggregates, 0 elsewhere.
    pub fn colour_indicator(&self, k: usize, out: &mut [f32]) {
        let (aggregate, cells) = (&self.aggregate, &self.aggregate_cell);
        out.par_iter_mut().enumerate().for_each(|(i, o)| {
            *o = match aggregate[i] {
                NONE => 0.0,
                a => {
                    let c = cells[a as usize];
                    f32::from((c.x % 2 + 2 * (c.y % 2)) as usize == k)
                }
            }
        });
    }

    /// Take `A W_k 1` for colour k, one value per fluid particle.
    pub fn set_colour_product(&mut self, k: usize, product: impl Iterator<Item = f32>) {
        self.aw[k].clear();
        self.aw[k].extend(product);
    }

    /// After the four colour products: `A W` by aggregate, `E = Wᵀ A W` (symmetrised) and its
    /// Cholesky factor. `position` and `active` as given to [`Self::aggregate`].
    pub fn factorise(&mut self, position: &[Vec2], active: &[f32]) {
        let n = position.len();
        // Each active particle's entry per colour: (aggregate, value).
        let mut entries = std::mem::take(&mut self.colour_entries);
        entries.clear();
        entries.resize(n, [(NONE, 0.0); COLOURS]);
        entries.par_iter_mut().enumerate().for_each(|(i, e)| {
            if active[i] > 0.0 {
                for (k, e) in e.iter_mut().enumerate() {
                    let v = self.aw[k][i];
                    if v != 0.0 {
                        *e = (self.aggregate_of_colour(position[i], k), v);
                    }
                }
            }
        });
        let count = self.count;
        let mut start = vec![0u32; count + 1];
        self.first.clear();
        self.first.extend(0..count as u32);
        for (i, e) in entries.iter().enumerate() {
            for &(c, _) in e {
                if c != NONE {
                    start[c as usize + 1] += 1;
                    let a = self.aggregate[i];
                    let (hi, lo) = (a.max(c) as usize, a.min(c));
                    self.first[hi] = self.first[hi].min(lo);
                }
            }
        }
        for c in 0..count {
            start[c + 1] += start[c];
        }
        let total = start[count] as usize;
        self.aw_t_row.clear();
        self.aw_t_row.resize(total, 0);
        self.aw_t_val.clear();
        self.aw_t_val.resize(total, 0.0);
        self.row_start.clear();
        self.row_start.push(0);
        for c in 0..count {
            let width = c + 1 - self.first[c] as usize;
            self.row_start.push(self.row_start[c] + width);
        }
        self.factor.clear();
        self.factor.resize(self.row_start[count], 0.0);
        let mut next = start.clone();
        for (i, e) in entries.iter().enumerate() {
            let a = self.aggregate[i];
            for &(c, v) in e {
                if c == NONE {
                    continue;
                }
                let slot = next[c as usize] as usize;
                self.aw_t_row[slot] = i as u32;
                self.aw_t_val[slot] = v;
                next[c as usize] += 1;
                // E_ac += (A W)_ic over i in a; each off-diagonal pair is met from both
                // sides: half each is the symmetric part.
                let (hi, lo) = (a.max(c) as usize, a.min(c) as usize);
                let share = if hi == lo { 1.0 } else { 0.5 };
                self.factor[self.row_start[hi] + lo - self.first[hi] as usize] += share * v as f64;
            }
        }
        self.aw_t_start = start;
        self.colour_entries = entries;
        self.cholesky();
    }

    /// Cholesky on the envelope, in place: `L_rc = (E_rc − Σ_k L_rk L_ck) / L_cc`, k from the
    /// later of the two rows' first columns. A pivot that has lost all but a 1e-10 share of its
    /// diagonal marks an aggregate whose stiffness the others already fix: it is dropped (the
    /// solve gives it 0).
    fn cholesky(&mut self) {
        for r in 0..self.count {
            let (fr, sr) = (self.first[r] as usize, self.row_start[r]);
            for c in fr..=r {
                let (fc, sc) = (self.first[c] as usize, self.row_start[c]);
                let k0 = fr.max(fc);
                let row_r = &self.factor[sr + k0 - fr..sr + c - fr];
                let row_c = &self.factor[sc + k0 - fc..sc + c - fc];
                let dot: f64 = row_r.iter().zip(row_c).map(|(a, b)| a * b).sum();
                let sum = self.factor[sr + c - fr] - dot;
                if c < r {
                    let pivot = self.factor[sc + c - fc];
                    self.factor[sr + c - fr] = if pivot > 0.0 { sum / pivot } else { 0.0 };
                } else {
                    let diagonal = self.factor[sr + r - fr];
                    self.factor[sr + r - fr] = if sum > 1e-10 * diagonal {
                        sum.sqrt()
                    } else {
                        0.0
                    };
                }
            }
        }
    }

    /// `y = E⁻¹ y` with the factor (forward and back substitution); dropped rows give 0.
    pub fn solve(&self, y: &mut [f64]) {
        let count = self.count;
        for r in 0..count {
            let (fr, sr) = (self.first[r] as usize, self.row_start[r]);
            let row = &self.factor[sr..sr + r - fr];
            let sum = y[r] - row.iter().zip(&y[fr..r]).map(|(l, y)| l * y).sum::<f64>();
            let pivot = self.factor[sr + r - fr];
            y[r] = if pivot > 0.0 { sum / pivot } else { 0.0 };
        }
        for r in (0..count).rev() {
            let (fr, sr) = (self.first[r] as usize, self.row_start[r]);
            let pivot = self.factor[sr + r - fr];
            let yr = if pivot > 0.0 { y[r] / pivot } else { 0.0 };
            y[r] = yr;
            let row = &self.factor[sr..sr + r - fr];
            for (y, l) in y[fr..r].iter_mut().zip(row) {
                *y -= l * yr;
            }
        }
    }

    /// `Wᵀ x`: the sum of `x` over each aggregate's particles.
    pub fn restrict(&self, x: impl Fn(usize) -> f64 + Sync, out: &mut Vec<f64>) {
        out.clear();
        out.resize(self.count, 0.0);
        out.par_iter_mut().enumerate().for_each(|(c, o)| {
            let m = self.members_start[c] as usize..self.members_start[c + 1] as usize;
            *o = self.members[m].iter().map(|&i| x(i as usize)).sum();
        });
    }

    /// `(A W)ᵀ x`.
    pub fn restrict_aw(&self, x: impl Fn(usize) -> f64 + Sync, out: &mut Vec<f64>) {
        out.clear();
        out.resize(self.count, 0.0);
        out.par_iter_mut().enumerate().for_each(|(c, o)| {
            let e = self.aw_t_start[c] as usize..self.aw_t_start[c + 1] as usize;
            *o = self.aw_t_row[e.clone()]
                .iter()
                .zip(&self.aw_t_val[e])
                .map(|(&i, &v)| v as f64 * x(i as usize))
                .sum();
        });
    }

    /// `W y` at particle i: its aggregate's value, 0 without one.
    #[inline]
    pub fn prolong(&self, y: &[f64], i: usize) -> f32 {
        match self.aggregate[i] {
            NONE => 0.0,
            a => y[a as usize] as f32,
        }
    }
}
