//! Pressure solvers: DFSPH (Bender & Koschier 2015; TVCG 2017, Algorithms 2 and 3) and the
//! WCSPH baseline (Becker & Teschner 2007).
//!
//! Notation. Everything is written with particle volumes V_j = m_j/ρ0 and relative densities
//! s_i = ρ_i/ρ0, which keeps the numbers near 1 in single precision:
//!
//! * density (eq. 2 of the 2017 paper, with Akinci boundary terms):
//!   `s_i = Σ_j V_j W_ij + Σ_b Ψ_b W_ib` (the sum over j includes i itself);
//! * factor (eq. 13, over ρ_i): `a_i = 1 / (|Σ_j V_j ∇W_ij + Σ_b Ψ_b ∇W_ib|² + Σ_j |V_j ∇W_ij|²)`;
//! * a pressure-like field κ (m²/s) changes velocities by
//!   `Δv_i = −Σ_j V_j (κ_i + κ_j) ∇W_ij − Σ_b Ψ_b κ_i ∇W_ib` (eq. 8–9, with the boundary term
//!   of Akinci et al. 2012, eq. 10: the wall feels the particle's own pressure once);
//!   κ = Δt·p/ρ0 for a pressure p.
//!
//! The density solve drives the predicted relative density `s*_i = s_i + Δt·Dρ_i/Dt/ρ0` to 1
//! with `Δκ_i = max(s*_i − 1, 0)·a_i/Δt` (only compression is corrected: the free surface
//! must not be pulled together); the divergence solve drives `Dρ_i/Dt` to 0 with
//! `Δκ_i = max(Dρ_i/Dt/ρ0, 0)·a_i`. Both are Jacobi iterations over the same two passes.

use std::ops::Range;

use crate::par::prelude::*;
use glam::Vec2;

use crate::lockstep::{self, Shared};
use crate::parallel::LIGHT_PASS_MIN_ITEMS;

use crate::blocked::{BlockedPairs, ResidualTerms, LANES};
use crate::kernel::CubicSpline;
use crate::neighbors::NeighborLists;
use crate::particles::{BoundaryParticles, FluidParticles};
use crate::reduce;

/// What [`density_and_factor`] caches for the rest of a step, valid while positions do not
/// change.
#[derive(Clone, Debug, Default)]
pub struct PairCache {
    /// `∇W_ib` per fluid–boundary pair, in list order.
    pub boundary_grad: Vec<Vec2>,
    /// Per particle, `Σ_j V_j ∇W_ij + Σ_b Ψ_b ∇W_ib`: what a uniform κ or velocity sees.
    pub grad_sum: Vec<Vec2>,
    /// Per particle, `Σ_b Ψ_b v_b·∇W_ib`: the walls' share of the density rate (walls keep
    /// their velocity for the whole step).
    pub wall_flux: Vec<f32>,
    /// Neighbour indices and `∇W_ij` of the fluid–fluid pairs, in blocks of 16 particles for
    /// the solver's SIMD passes.
    pub blocks: BlockedPairs,
}

/// Read-only view of one step's neighbourhoods: lists and the kernel gradients cached for
/// every pair, valid while positions do not change.
pub struct Neighborhood<'a> {
    /// Fluid–fluid lists (self excluded); their `∇W_ij` are in `blocks`.
    pub fluid: &'a NeighborLists,
    /// Fluid–boundary lists and `∇W_ib` per pair.
    pub boundary: &'a NeighborLists,
    pub boundary_grad: &'a [Vec2],
    /// [`PairCache::grad_sum`].
    pub grad_sum: &'a [Vec2],
    /// [`PairCache::wall_flux`].
    pub wall_flux: &'a [f32],
    /// [`PairCache::blocks`].
    pub blocks: &'a BlockedPairs,
}

impl<'a> Neighborhood<'a> {
    pub fn new(
        fluid: &'a NeighborLists,
        boundary: &'a NeighborLists,
        cache: &'a PairCache,
    ) -> Self {
        Self {
            fluid,
            boundary,
            boundary_grad: &cache.boundary_grad,
            grad_sum: &cache.grad_sum,
            wall_flux: &cache.wall_flux,
            blocks: &cache.blocks,
        }
    }
}

/// Compute `s_i`, the DFSPH factor, and cache all kernel gradients and the per-particle sums
/// of [`PairCache`] (TVCG 2017, Alg. 1 lines 2–3).
///
/// `wall_weight` multiplies the walls' share of the gradient sum and of the wall flux, not of
/// the density: 1 is Akinci et al.'s wall term ([`AKINCI_WALLS`]), 2 mirrors the fluid into the
/// wall ([`MIRRORED_WALLS`]). The gradient sum serves the density rate, the pressure push and
/// the factor alike, so either weight keeps the pressure operator symmetric.
#[allow(clippy::too_many_arguments)]
pub fn density_and_factor(
    kernel: &CubicSpline,
    volume: f32,
    fluid: &mut FluidParticles,
    boundary: &BoundaryParticles,
    fluid_lists: &NeighborLists,
    boundary_lists: &NeighborLists,
    cache: &mut PairCache,
    max_factor: f32,
    wall_weight: f32,
) {
    let n = fluid.len();
    cache.blocks.prepare(fluid_lists);
    cache
        .boundary_grad
        .resize(boundary_lists.pair_count(), Vec2::ZERO);
    cache.grad_sum.resize(n, Vec2::ZERO);
    cache.wall_flux.resize(n, 0.0);
    let pos = &fluid.position;
    let bpos = &boundary.position;
    let bvol = &boundary.volume;
    let bvel = &boundary.velocity;
    // The factor's guard: a particle whose gradient sums are this small has (almost) no
    // neighbours and gets no pressure (its density cannot be corrected anyway).
    let eps = 1.0e-6 / (kernel.support() * kernel.support());
    let self_w = volume * kernel.w_zero();

    // One parallel pass over chunks of particles; each chunk owns the gradient slots of its
    // particles' pairs (its blocks, for fluid pairs).
    fluid
        .density_ratio
        .par_chunks_mut(PAIR_CHUNK)
        .zip(fluid.factor.par_chunks_mut(PAIR_CHUNK))
        .zip(cache.grad_sum.par_chunks_mut(PAIR_CHUNK))
        .zip(cache.wall_flux.par_chunks_mut(PAIR_CHUNK))
        .zip(cache.blocks.writers(PAIR_CHUNK / LANES))
        .zip(split_by_chunk(&mut cache.boundary_grad, boundary_lists))
        .enumerate()
        .for_each(|(c, (((((s, a), gs), wf), mut fluid_pairs), mut bg))| {
            let base = c * PAIR_CHUNK;
            for block in (base / LANES)..(base + s.len()).div_ceil(LANES) {
                let fluid_sums =
                    fluid_pairs.fill_block(block, fluid_lists, pos, kernel, volume, self_w);
                for lane in 0..LANES {
                    let i = block * LANES + lane;
                    if i >= n {
                        break;
                    }
                    let xi = pos[i];
                    let mut density = fluid_sums.density[lane];
                    let mut grad_sum = Vec2::new(fluid_sums.grad_x[lane], fluid_sums.grad_y[lane]);
                    let grad_sq = fluid_sums.grad_sq[lane];
                    let walls = boundary_lists.of(i);
                    let (grads, rest) = std::mem::take(&mut bg).split_at_mut(walls.len());
                    bg = rest;
                    let mut flux = 0.0f32;
                    for (g, &b) in grads.iter_mut().zip(walls) {
                        let (w, grad) = kernel.w_and_grad(xi - bpos[b as usize]);
                        *g = grad;
                        let vb = bvol[b as usize];
                        density += vb * w;
                        grad_sum += wall_weight * vb * grad;
                        flux += wall_weight * vb * bvel[b as usize].dot(grad);
                    }
                    let k = i - base;
                    s[k] = density;
                    gs[k] = grad_sum;
                    wf[k] = flux;
                    let denom = grad_sum.length_squared() + grad_sq;
                    a[k] = if denom > eps {
                        (1.0 / denom).min(max_factor)
                    } else {
                        0.0
                    };
                }
            }
        });
}

/// Akinci et al. (2012)'s wall term: a wall particle feels the fluid particle's own pressure
/// once, `Δv_i = −κ_i Σ_b Ψ_b ∇W_ib`.
pub const AKINCI_WALLS: f32 = 1.0;

/// Walls that mirror the fluid: the wall's share of the density is the mirrored fluid's
/// (`Σ_b Ψ_b W_ib`), and its derivative, since the mirror image moves with the particle,
/// counts twice, in the density rate, the pressure push (`p_b = p_i`: `κ_i + κ_b = 2κ_i`) and
/// the factor. With it a particle next to a wall controls its own distance to the wall; with
/// [`AKINCI_WALLS`] a particle on the lattice next to a wall does not (its gradient sums cancel,
/// docs/deep-columns.md) and the fluid's pressure pushes it into the wall.
pub const MIRRORED_WALLS: f32 = 2.0;

/// The DFSPH factor of a particle inside an ideal square lattice of spacing `d` (its gradient
/// sum vanishes by symmetry): `1 / Σ_k |V ∇W(x_k)|²`.
pub fn lattice_factor(kernel: &CubicSpline, d: f32, volume: f32) -> f32 {
    let reach = (kernel.support() / d).ceil() as i32 + 1;
    let mut sum = 0.0f64;
    for j in -reach..=reach {
        for i in -reach..=reach {
            let g = volume * kernel.grad_w(Vec2::new(i as f32 * d, j as f32 * d));
            sum += g.length_squared() as f64;
        }
    }
    (1.0 / sum) as f32
}

/// A particle's factor is capped at this multiple of [`lattice_factor`]. Particles with a full
/// or a free-surface neighbourhood stay below about 2.5 times it. A droplet with one or two
/// fluid neighbours pressed into a wall does not: it sits almost on top of a wall particle,
/// where ∇W vanishes, its boundary gradients nearly cancel, and its factor grows without bound
/// (200 times the lattice value was seen in `dfsph2d stress`), so that the wall's few percent of
/// extra density became a kick of thousands of m/s. With the cap such a particle is pushed out
/// over a few iterations instead of one.
pub const MAX_FACTOR_RATIO: f32 = 4.0;

/// Particles per parallel work item of [`density_and_factor`].
const PAIR_CHUNK: usize = 512;

/// Split a per-pair array into one mutable slice per chunk of [`PAIR_CHUNK`] particles.
fn split_by_chunk<'a, T>(values: &'a mut [T], lists: &NeighborLists) -> Vec<&'a mut [T]> {
    let n = lists.len();
    let mut out = Vec::with_capacity(n.div_ceil(PAIR_CHUNK));
    let mut rest = values;
    for start in (0..n).step_by(PAIR_CHUNK) {
        let end = (start + PAIR_CHUNK).min(n);
        let len = lists.offsets[end] as usize - lists.offsets[start] as usize;
        let (head, tail) = rest.split_at_mut(len);
        out.push(head);
        rest = tail;
    }
    out
}

/// Relative rates of density change `Dρ_i/Dt / ρ0 = Σ_j V_j (v_i − v_j)·∇W_ij +
/// Σ_b Ψ_b (v_i − v_b)·∇W_ib` (continuity equation, TVCG 2017 eq. 7), in 1/s, of every fluid
/// particle at the velocities `vel`: one residual pass ([`BlockedPairs::residual_block`]) with
/// no source and no increment. (A solve leaves these in [`SolverScratch::density_rates`].)
pub fn density_rates(volume: f32, vel: &[Vec2], nb: &Neighborhood) -> Vec<f32> {
    let n = vel.len();
    let (zeros, mut unused) = (vec![0.0f32; n], vec![0.0f32; n]);
    let mut rates = vec![0.0f32; n];
    density_rates_into(
        volume,
        vel,
        nb,
        nb.wall_flux,
        &zeros,
        &mut unused,
        &mut rates,
    );
    rates
}

/// [`density_rates`] into `out`, with the walls' share `wall_flux` (`nb.wall_flux`, or zeros
/// for the rates a velocity change alone causes), `zeros` holding n zeros and `unused` n
/// scratch values.
pub fn density_rates_into(
    volume: f32,
    vel: &[Vec2],
    nb: &Neighborhood,
    wall_flux: &[f32],
    zeros: &[f32],
    unused: &mut [f32],
    out: &mut [f32],
) {
    let terms = ResidualTerms {
        volume,
        grad_sum: nb.grad_sum,
        wall_flux,
        source: zeros,
        rate_scale: 1.0,
        factor: zeros,
        increment_scale: 0.0,
    };
    out.par_chunks_mut(LANES)
        .zip(unused.par_chunks_mut(LANES))
        .enumerate()
        .for_each(|(b, (r, d))| {
            nb.blocks
                .residual_block(b, vel, &terms, d, r, &mut [0.0; LANES]);
        });
}

/// Apply `Δv_i = −Σ_j V_j (κ_i + κ_j) ∇W_ij − κ_i Σ_b Ψ_b ∇W_ib` to every fluid velocity,
/// written as `−κ_i (Σ_j V_j ∇W_ij + Σ_b Ψ_b ∇W_ib) − V Σ_j κ_j ∇W_ij` with the first sum
/// cached for the step.
pub fn apply_pressure(volume: f32, kappa: &[f32], vel: &mut [Vec2], nb: &Neighborhood) {
    vel.par_chunks_mut(LANES).enumerate().for_each(|(b, v)| {
        nb.blocks
            .apply_block(b, volume, kappa, nb.grad_sum, v, None)
    });
}

/// Outcome of one solve.
#[derive(Clone, Copy, Debug, Default)]
pub struct SolveReport {
    pub iterations: u32,
    /// Average error at exit, percent.
    pub avg_error_pct: f64,
    /// Largest single-particle error at exit, percent.
    pub max_error_pct: f64,
}

/// Settings shared by both solves.
#[derive(Clone, Copy, Debug)]
pub struct SolveLimits {
    pub tolerance_pct: f64,
    /// Largest single-particle error accepted at exit, percent. The average alone lets a
    /// local hot spot through: ten particles 3 % compressed move the average of 20,000 by
    /// 0.0015 %, and such a spot, left for the next step, grows.
    pub max_error_pct: f64,
    pub min_iterations: u32,
    pub max_iterations: u32,
}

/// Scratch arrays of the Jacobi iterations.
#[derive(Default, Clone, Debug)]
pub struct SolverScratch {
    /// Per-particle stiffness increment of the current iteration.
    delta: Vec<f32>,
    /// The increment applied last, to take an iteration back.
    previous_delta: Vec<f32>,
    /// Per particle, the residual's part that does not depend on the velocities
    /// ([`ResidualTerms::source`]).
    source: Vec<f32>,
    /// Per particle, the relative density rate at the current velocities, written by each
    /// residual pass.
    rate: Vec<f32>,
    /// The rates before the increment applied last, to take an iteration back.
    previous_rate: Vec<f32>,
}

impl SolverScratch {
    /// Per fluid particle, the relative rate of density change `Dρ_i/Dt/ρ0` (TVCG 2017 eq. 7,
    /// see [`ResidualTerms`]) at the velocities the last Jacobi solve left. The density
    /// solve's linearisation check ([`unseen_compression`]) reads them here rather than
    /// walking every neighbour list again.
    pub fn density_rates(&self) -> &[f32] {
        &self.rate
    }
}

/// The Jacobi iteration shared by the density and divergence solves: compute every residual
/// `e_i = max(source_i + rate_scale·Dρ_i/Dt/ρ0, 0)` ([`ResidualTerms`], `source` taken from
/// `scratch.source`), stop when their average (in percent, after `to_pct`) is within
/// tolerance, else turn them into stiffness increments `Δκ_i = e_i·a_i·increment_scale`,
/// apply them, and accumulate them into `total`.
///
/// Only compression is corrected: residuals are clamped at zero, so within one solve a
/// particle's stiffness only grows. What a previous step left too high is not taken back here;
/// the warm start keeps only part of it (see [`warm_factor`]).
///
/// The whole iteration runs in one [`lockstep`] region: each worker starts every pass on
/// the same share of parts, takes what the other has not reached when its own is done, and
/// the workers meet at a barrier between passes, instead of one rayon fork-join per pass
/// (docs/PERFORMANCE.md has the measurements).
#[allow(clippy::too_many_arguments)]
fn jacobi_solve(
    volume: f32,
    fluid: &mut FluidParticles,
    nb: &Neighborhood,
    limits: SolveLimits,
    scratch: &mut SolverScratch,
    rate_scale: f32,
    to_pct: f64,
    increment_scale: f32,
    total: &mut [f32],
) -> SolveReport {
    let n = fluid.len();
    for v in [
        &mut scratch.delta,
        &mut scratch.previous_delta,
        &mut scratch.rate,
        &mut scratch.previous_rate,
    ] {
        v.resize(n, 0.0);
    }
    if n == 0 {
        return SolveReport::default();
    }
    let terms = ResidualTerms {
        volume,
        grad_sum: nb.grad_sum,
        wall_flux: nb.wall_flux,
        source: &scratch.source,
        rate_scale,
        factor: &fluid.factor,
        increment_scale,
    };
    // The residual sum decides when to stop, so it is taken in an order that does not
    // depend on the work split (`reduce`): per part of `blocks_per_part` blocks, then the
    // parts in order.
    let blocks = n.div_ceil(LANES);
    let blocks_per_part = reduce::part_units(blocks, 16);
    let parts = blocks.div_ceil(blocks_per_part);
    let mut part_sums = [(0.0, 0.0); reduce::MAX_PARTS];
    let part_sums = Shared::new(&mut part_sums[..parts]);
    let velocity = Shared::new(&mut fluid.velocity);
    let total = Shared::new(total);
    // Two increment buffers and two rate buffers: the residual pass writes the next into
    // one while the other keeps the increment applied last, to take an iteration back.
    let increments = [
        Shared::new(&mut scratch.delta),
        Shared::new(&mut scratch.previous_delta),
    ];
    let rates = [
        Shared::new(&mut scratch.rate),
        Shared::new(&mut scratch.previous_rate),
    ];
    // Part `p`'s blocks and particles.
    let part = |p: usize| -> (Range<usize>, Range<usize>) {
        let part_blocks = p * blocks_per_part..((p + 1) * blocks_per_part).min(blocks);
        let items = part_blocks.start * LANES..(part_blocks.end * LANES).min(n);
        (part_blocks, items)
    };

    let outcomes = lockstep::run(|team| {
        // Shares cut at part bounds, balanced by neighbour slots.
        let my_parts = team.share(parts, |p| {
            nb.blocks.slots_before((p * blocks_per_part).min(blocks)) as u64
        });

        // The residuals at the current velocities, part by part, written into
        // `increments[buffer]` and `rates[buffer]` with the next increments; then, after the
        // barrier, the average and largest residual over all parts (every worker takes the
        // same sum in the same order, so all decide alike).
        let residuals = |buffer: usize| -> (f64, f64) {
            // SAFETY: in this pass the velocities are only read; each part's items and sum
            // are written by the one worker that took the part; the barrier below ends the
            // pass.
            let vel = unsafe { velocity.read() };
            for p in team.parts(my_parts.clone()) {
                let (part_blocks, items) = part(p);
                let (d, r, sum) = unsafe {
                    (
                        increments[buffer].part_mut(items.clone()),
                        rates[buffer].part_mut(items),
                        &mut part_sums.part_mut(p..p + 1)[0],
                    )
                };
                // The residuals of a few blocks at a time, summed together.
                const GROUP: usize = reduce::BLOCKS_TOGETHER;
                let mut errors = [[0.0f32; LANES]; GROUP];
                let mut acc = (0.0, 0.0);
                let groups = d.chunks_mut(GROUP * LANES).zip(r.chunks_mut(GROUP * LANES));
                for (g, (d, r)) in groups.enumerate() {
                    let count = d.len().div_ceil(LANES);
                    let first = part_blocks.start + g * GROUP;
                    let e = &mut errors[..count];
                    nb.blocks
                        .residual_blocks(first..first + count, vel, &terms, d, r, e);
                    acc = reduce::fold_block_sums(acc, &errors, count);
                }
                *sum = acc;
            }
            team.wait();
            // SAFETY: the part sums are written only in the residual pass, which every
            // worker has finished; the next one starts after another barrier.
            let (sum, max) = unsafe { part_sums.read() }
                .iter()
                .copied()
                .fold((0.0, 0.0), reduce::add_sum_max);
            (sum / n as f64 * to_pct, max * to_pct)
        };
        // Apply the increments in `increments[buffer]` to the velocities and add them to the
        // running totals, part by part.
        let apply = |buffer: usize| {
            // SAFETY: in this pass the increments are only read; each part's velocities and
            // totals are written by the one worker that took the part; the barrier below
            // ends the pass.
            let kappa = unsafe { increments[buffer].read() };
            for p in team.parts(my_parts.clone()) {
                let (part_blocks, items) = part(p);
                let (vel, sum) =
                    unsafe { (velocity.part_mut(items.clone()), total.part_mut(items)) };
                nb.blocks
                    .apply_blocks(part_blocks, volume, kappa, nb.grad_sum, vel, Some(sum));
            }
            team.wait();
        };

        let mut current = 0;
        let mut rates_current = 0;
        let (mut avg, mut max) = residuals(current);
        let mut iterations = 0;
        while (avg > limits.tolerance_pct
            || max > limits.max_error_pct
            || iterations < limits.min_iterations)
            && iterations < limits.max_iterations
        {
            apply(current);
            current = 1 - current;
            rates_current = current;
            let previous = (avg, max);
            (avg, max) = residuals(current);
            iterations += 1;
            if avg.is_nan() || avg > DIVERGING_ERROR_GROWTH * previous.0 + limits.tolerance_pct {
                // Jacobi is not guaranteed to converge (dense clusters, e.g. fluid pulled
                // into a point): an iteration that makes the error grow is taken back and
                // the solve stops, rather than feeding the growth into the velocities.
                let applied = 1 - current;
                for p in team.parts(my_parts.clone()) {
                    let (_, items) = part(p);
                    // SAFETY: each part is negated by the worker that took it; the barrier
                    // orders this before the pass that reads the increments.
                    unsafe { increments[applied].part_mut(items) }
                        .iter_mut()
                        .for_each(|d| *d = -*d);
                }
                team.wait();
                apply(applied);
                // The velocities are back where the previous pass read them.
                rates_current = applied;
                (avg, max) = previous;
                break;
            }
        }
        (
            SolveReport {
                iterations,
                avg_error_pct: avg,
                max_error_pct: max,
            },
            current,
            rates_current,
        )
    });
    let (report, current, rates_current) = outcomes[0];
    // The next increment and the current rates go back where the callers look for them.
    if current == 1 {
        std::mem::swap(&mut scratch.delta, &mut scratch.previous_delta);
    }
    if rates_current == 1 {
        std::mem::swap(&mut scratch.rate, &mut scratch.previous_rate);
    }
    report
}

/// Divergence solve (TVCG 2017, Algorithm 2): make `Dρ/Dt = 0` so the velocity field is
/// divergence-free. The error is the average relative density change over one step, `dt`.
/// With `warm_start`, the previous step's κᵛ is applied first.
#[allow(clippy::too_many_arguments)]
pub fn divergence_solve(
    volume: f32,
    dt: f32,
    warm_start: bool,
    fluid: &mut FluidParticles,
    nb: &Neighborhood,
    limits: SolveLimits,
    scratch: &mut SolverScratch,
) -> SolveReport {
    let mut total = std::mem::take(&mut fluid.divergence_stiffness);
    if warm_start {
        let w = warm_factor();
        total
            .par_iter_mut()
            .with_min_len(LIGHT_PASS_MIN_ITEMS)
            .for_each(|k| *k = k.max(0.0) * w);
        apply_pressure(volume, &total, &mut fluid.velocity, nb);
    } else {
        total.iter_mut().for_each(|k| *k = 0.0);
    }
    // Particles with too few neighbours for a meaningful rate are left out: their residual
    // is max(−∞ + rate, 0) = 0.
    scratch.source.resize(fluid.len(), 0.0);
    scratch
        .source
        .par_iter_mut()
        .with_min_len(LIGHT_PASS_MIN_ITEMS)
        .enumerate()
        .for_each(|(i, s)| {
            let neighbors = nb.fluid.range(i).len() + nb.boundary.range(i).len();
            *s = if neighbors < MIN_NEIGHBORS_DIVERGENCE {
                f32::NEG_INFINITY
            } else {
                0.0
            };
        });
    let report = jacobi_solve(
        volume,
        fluid,
        nb,
        limits,
        scratch,
        1.0,
        dt as f64 * 100.0,
        1.0,
        &mut total,
    );
    fluid.divergence_stiffness = total;
    report
}

/// Density solve (TVCG 2017, Algorithm 3): correct the predicted velocities so that the
/// predicted density `s_i + Δt·Dρ_i/Dt/ρ0` is 1 wherever the fluid is compressed. Afterwards
/// `fluid.pressure_over_rho0` holds p/ρ0 of the step, used as the next warm start.
///
/// At most `max_correction` of a particle's existing compression `s_i − 1` is removed in this
/// step (see [`max_compression_correction`]); the rest waits for the next steps.
#[allow(clippy::too_many_arguments)]
pub fn density_solve(
    volume: f32,
    dt: f32,
    max_correction: f32,
    warm_start: bool,
    fluid: &mut FluidParticles,
    nb: &Neighborhood,
    limits: SolveLimits,
    scratch: &mut SolverScratch,
) -> SolveReport {
    // κ = Δt·p/ρ0; the stored pressure does not depend on Δt, so it carries over when Δt
    // changes.
    let mut total = std::mem::take(&mut fluid.pressure_over_rho0);
    if warm_start {
        let w = warm_factor();
        total
            .par_iter_mut()
            .with_min_len(LIGHT_PASS_MIN_ITEMS)
            .for_each(|p| *p = p.max(0.0) * dt * w);
        apply_pressure(volume, &total, &mut fluid.velocity, nb);
    } else {
        total.iter_mut().for_each(|k| *k = 0.0);
    }
    scratch.source.resize(fluid.len(), 0.0);
    scratch
        .source
        .par_iter_mut()
        .zip(fluid.density_ratio.par_iter())
        .with_min_len(LIGHT_PASS_MIN_ITEMS)
        .for_each(|(s, &density)| *s = (density - 1.0).min(max_correction));
    let report = jacobi_solve(
        volume,
        fluid,
        nb,
        limits,
        scratch,
        dt,
        100.0,
        1.0 / dt,
        &mut total,
    );
    total
        .par_iter_mut()
        .with_min_len(LIGHT_PASS_MIN_ITEMS)
        .for_each(|k| *k /= dt);
    fluid.pressure_over_rho0 = total;
    report
}

/// WCSPH: pressure from the Tait equation `p = B·((ρ/ρ0)^γ − 1)` (clamped at 0 so the free
/// surface is not pulled together) and the symmetric pressure acceleration
/// `a_i = −Σ_j m_j (p_i/ρ_i² + p_j/ρ_j²) ∇W_ij − Σ_b ρ0 Ψ_b p_i/ρ_i² ∇W_ib` (Akinci et al.
/// 2012), applied to the
/// velocities over `dt`. Returns the average and maximum compression in percent.
#[allow(clippy::too_many_arguments)]
pub fn wcsph_pressure(
    volume: f32,
    dt: f32,
    rest_density: f32,
    stiffness: f32,
    exponent: f32,
    fluid: &mut FluidParticles,
    nb: &Neighborhood,
    scratch: &mut SolverScratch,
) -> SolveReport {
    let n = fluid.len();
    scratch.delta.resize(n, 0.0);
    fluid
        .pressure_over_rho0
        .par_iter_mut()
        .zip(scratch.delta.par_iter_mut())
        .zip(fluid.density_ratio.par_iter())
        .for_each(|((p, k), &s)| {
            let pressure = (stiffness * (s.powf(exponent) - 1.0)).max(0.0);
            *p = pressure / rest_density;
            // In the κ form: m_j p/ρ² = V_j ρ0 p/(ρ0 s)² = V_j (p/ρ0)/s², times Δt.
            *k = dt * *p / (s * s);
        });
    apply_pressure(volume, &scratch.delta, &mut fluid.velocity, nb);
    let (sum, max) = reduce::sum_and_max(&fluid.density_ratio, |&s| (s - 1.0).max(0.0) as f64);
    SolveReport {
        iterations: 0,
        avg_error_pct: if n > 0 { sum / n as f64 * 100.0 } else { 0.0 },
        max_error_pct: max * 100.0,
    }
}

/// The compression a step of `dt` with the current velocities creates that the density
/// solve could not see: the largest `min(s̃_i − ŝ_i, s̃_i − 1)` over particles where both are
/// positive, as a fraction of ρ0 (0 if there is none).
///
/// The solve works with the linear prediction `ŝ_i = s_i + Δt·Dρ_i/Dt/ρ0`; `s̃_i` is the
/// density the kernel gives at the positions `x + Δt·v` the step moves to (over the step's
/// neighbour lists). A neighbour at q > 1/3 of the support sits where the cubic spline is
/// convex, so any relative displacement δ adds about 0.34·(δ/d)² per pair that the linear
/// prediction misses, and a particle on a square lattice next to a wall (or between two rows
/// moving in opposite directions) can fall towards a neighbour without changing its linear
/// prediction at all. In the 80k dam break at Δt = 5 ms the solve's first steps
/// drive the bottom rows' predicted density to 1 while they end 3–25 % compressed; the
/// compression builds up step after step until the bottom rows burst (docs/deep-columns.md).
/// A step with a large unseen compression is too long for the linearisation and is redone
/// with a shorter Δt.
///
/// `rates` are the particles' `Dρ_i/Dt/ρ0` at the current velocities ([`density_rates`], or
/// what the density solve left in [`SolverScratch::density_rates`]).
pub fn unseen_compression(
    kernel: &CubicSpline,
    volume: f32,
    dt: f32,
    fluid: &FluidParticles,
    boundary: &BoundaryParticles,
    nb: &Neighborhood,
    rates: &[f32],
) -> f32 {
    assert_eq!(
        rates.len(),
        fluid.len(),
        "one density rate per fluid particle"
    );
    let pos = &fluid.position;
    let vel = &fluid.velocity;
    let density = &fluid.density_ratio;
    let self_w = volume * kernel.w_zero();
    let support2 = kernel.support() * kernel.support();
    (0..pos.len().div_ceil(LANES))
        .into_par_iter()
        .map(|b| {
            let fluid_sums = nb
                .blocks
                .advected_kernel_sums(b, pos, vel, dt, kernel, volume, self_w);
            let mut worst = 0.0f32;
            for (l, mut advected) in fluid_sums.into_iter().enumerate() {
                let i = b * LANES + l;
                if i >= pos.len() {
                    break;
                }
                let rate = rates[i];
                let xi = pos[i] + dt * vel[i];
                for &w in nb.boundary.of(i) {
                    let w = w as usize;
                    let xw = boundary.position[w] + dt * boundary.velocity[w];
                    let r2 = (xi - xw).length_squared();
                    if r2 < support2 {
                        advected += boundary.volume[w] * kernel.w(r2.sqrt());
                    }
                }
                let unseen = (advected - (density[i] + dt * rate)).min(advected - 1.0);
                worst = worst.max(unseen);
            }
            worst
        })
        .reduce(|| 0.0, f32::max)
}

/// The fastest a density solve may push particles apart to undo compression that already
/// exists at the start of a step, m/s.
///
/// A well-resolved flow starts each step less than 1 % compressed, and removing that over one
/// step takes a few cm/s. A user can create far more: a wall drawn over the water, fluid pulled
/// into a gap narrower than a particle, a pour onto a moving surface. Undoing a compression δ
/// in one step takes a speed of about δ·d/Δt, which grows as Δt shrinks: a 30 % overlap
/// undone in a 10 µs step throws particles at hundreds of m/s, the next step's CFL Δt is
/// smaller still, and the kicks feed on themselves (seen in `dfsph2d stress`, which ended in
/// particles at 1,900 m/s). Capping the part of the source term that comes from existing
/// compression spreads such a correction over several steps at this speed instead; the part
/// from the velocities (`Δt·Dρ/Dt`) is never capped, so the fluid still cannot compress
/// further.
pub const MAX_CORRECTION_SPEED: f32 = 2.0;

/// The largest existing relative compression one step of length `dt` removes, for particle
/// spacing `d`: a correction of that size moves particles apart at about
/// [`MAX_CORRECTION_SPEED`].
pub fn max_compression_correction(dt: f32, d: f32) -> f32 {
    MAX_CORRECTION_SPEED * dt / d
}

/// Share of the previous step's stiffness applied as the warm start. A full warm start
/// ratchets: the compression-only solve can add stiffness but never take back an excess, so
/// the stored pressure creeps upward from step to step.
fn warm_factor() -> f32 {
    0.5
}

/// An iteration whose average error exceeds this multiple of the previous one (plus the
/// tolerance) is taken back and ends the solve.
const DIVERGING_ERROR_GROWTH: f64 = 1.5;

/// A particle with fewer neighbours than this (fluid and boundary, itself excluded) takes no
/// part in the divergence solve. Its neighbourhood is too thin for `Dρ/Dt` to mean anything:
/// a splash droplet grazing a wall would otherwise get a stiffness from a near-zero gradient
/// sum and kick its few neighbours to hundreds of m/s. Eight is the count of a full square
/// lattice at support 2d; the free surface (five) is excluded, as in SPlisHSPlasH's 2D DFSPH.
const MIN_NEIGHBORS_DIVERGENCE: usize = 7;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::neighbors::Grid;
    use crate::simd::SimdPath;

    /// A disordered patch of fluid on a floor of wall particles that move, with neighbour
    /// lists and the step's cache, built as the simulation builds them.
    struct Patch {
        kernel: CubicSpline,
        volume: f32,
        fluid: FluidParticles,
        boundary: BoundaryParticles,
        fluid_lists: NeighborLists,
        boundary_lists: NeighborLists,
        cache: PairCache,
    }

    /// A deterministic jitter in [−0.5, 0.5).
    fn jitter(k: u32) -> f32 {
        let h = k.wrapping_mul(2_654_435_761).rotate_left(13) ^ 0x9e37_79b9;
        (h.wrapping_mul(2_246_822_519) >> 8) as f32 / (1u32 << 24) as f32 - 0.5
    }

    fn patch() -> Patch {
        let d = 0.02f32;
        let kernel = CubicSpline::new(2.0 * d);
        let volume = d * d;
        let mut points = Vec::new();
        for j in 0..12 {
            for i in 0..15 {
                let k = (j * 15 + i) as u32;
                let x = Vec2::new(
                    (i as f32 + 0.5 + 0.4 * jitter(2 * k)) * d,
                    (j as f32 + 0.5 + 0.4 * jitter(2 * k + 1)) * d,
                );
                points.push((x, Vec2::new(jitter(7 * k), jitter(7 * k + 3))));
            }
        }
        let mut fluid_grid = Grid::new(kernel.support());
        let order = fluid_grid
            .build(&points.iter().map(|p| p.0).collect::<Vec<_>>())
            .to_vec();
        let mut fluid = FluidParticles::default();
        for &o in &order {
            let (x, v) = points[o as usize];
            fluid.push(x, v, o);
        }
        let n = fluid.len();
        fluid.density_ratio.resize(n, 0.0);
        fluid.factor.resize(n, 0.0);
        // Two layers of floor, moving along and into the fluid.
        let mut walls = Vec::new();
        for layer in 0..2 {
            for i in -3..18 {
                walls.push(Vec2::new(i as f32 * d, -(layer as f32 + 0.5) * d));
            }
        }
        let mut boundary_grid = Grid::new(kernel.support());
        let order = boundary_grid.build(&walls).to_vec();
        let mut boundary = BoundaryParticles::default();
        for &o in &order {
            boundary.position.push(walls[o as usize]);
            boundary
                .velocity
                .push(Vec2::new(0.7, 0.2 + 0.1 * jitter(o)));
            boundary.volume.push(0.6 * volume);
            boundary.body.push(0);
        }
        let mut fluid_lists = NeighborLists::default();
        let mut boundary_lists = NeighborLists::default();
        fluid_grid.neighbor_lists(&fluid.position, true, &mut fluid_lists);
        boundary_grid.neighbor_lists(&fluid.position, false, &mut boundary_lists);
        let mut cache = PairCache::default();
        density_and_factor(
            &kernel,
            volume,
            &mut fluid,
            &boundary,
            &fluid_lists,
            &boundary_lists,
            &mut cache,
            f32::INFINITY,
            AKINCI_WALLS,
        );
        Patch {
            kernel,
            volume,
            fluid,
            boundary,
            fluid_lists,
            boundary_lists,
            cache,
        }
    }

    /// The iterations use per-particle sums cached once per step instead of the pair sums of
    /// TVCG 2017 eq. 7 and eq. 8–9; they must agree with those sums, written out directly
    /// from positions, including walls that move.
    #[test]
    fn cached_sums_give_the_direct_density_rate_and_velocity_change() {
        let p = patch();
        let nb = Neighborhood::new(&p.fluid_lists, &p.boundary_lists, &p.cache);
        let (x, v) = (&p.fluid.position, &p.fluid.velocity);
        let kappa: Vec<f32> = (0..p.fluid.len() as u32)
            .map(|k| 1.0e-3 * (1.0 + jitter(11 * k)))
            .collect();
        let mut changed = v.clone();
        apply_pressure(p.volume, &kappa, &mut changed, &nb);
        let rates = density_rates(p.volume, v, &nb);
        let h = p.kernel.support();
        let mut wall_pairs = 0;
        for i in 0..p.fluid.len() {
            let (mut rate, mut scale) = (0.0f64, 0.0f64);
            let mut dv = glam::DVec2::ZERO;
            for j in 0..p.fluid.len() {
                let r = x[i] - x[j];
                if j != i && r.length() < h {
                    let g = p.kernel.grad_w(r);
                    let term = (p.volume * (v[i] - v[j]).dot(g)) as f64;
                    rate += term;
                    scale += term.abs();
                    dv -= (p.volume * (kappa[i] + kappa[j]) * g).as_dvec2();
                }
            }
            for (b, &xb) in p.boundary.position.iter().enumerate() {
                let r = x[i] - xb;
                if r.length() < h {
                    let g = p.kernel.grad_w(r);
                    let vb = p.boundary.volume[b];
                    let term = (vb * (v[i] - p.boundary.velocity[b]).dot(g)) as f64;
                    rate += term;
                    scale += term.abs();
                    dv -= (kappa[i] * vb * g).as_dvec2();
                    wall_pairs += 1;
                }
            }
            let cached = rates[i] as f64;
            assert!(
                (cached - rate).abs() <= 1.0e-5 * scale.max(1.0),
                "particle {i}: rate {cached} from the cache, {rate} directly"
            );
            let got = (changed[i] - v[i]).as_dvec2();
            assert!(
                (got - dv).length() <= 1.0e-4 * dv.length().max(1.0e-6),
                "particle {i}: Δv {got} from the cache, {dv} directly"
            );
        }
        assert!(wall_pairs > 50, "the walls must take part: {wall_pairs}");
    }

    /// The largest compression the linear prediction misses, written out from positions: the
    /// kernel sum at `x + Δt·v` against `s_i + Δt·Dρ_i/Dt/ρ0`.
    fn unseen_compression_directly(p: &Patch, dt: f32) -> f32 {
        let (x, v) = (&p.fluid.position, &p.fluid.velocity);
        let h = p.kernel.support();
        let mut worst = 0.0f32;
        for i in 0..p.fluid.len() {
            let xi = x[i] + dt * v[i];
            let (mut advected, mut rate) = (0.0f32, 0.0f32);
            for j in 0..p.fluid.len() {
                let r = x[i] - x[j];
                if r.length() < h {
                    advected += p.volume * p.kernel.w((xi - x[j] - dt * v[j]).length());
                    rate += p.volume * (v[i] - v[j]).dot(p.kernel.grad_w(r));
                }
            }
            for (b, &xb) in p.boundary.position.iter().enumerate() {
                let (vb, wb) = (p.boundary.velocity[b], p.boundary.volume[b]);
                let r = x[i] - xb;
                if r.length() < h {
                    advected += wb * p.kernel.w((xi - xb - dt * vb).length());
                    rate += wb * (v[i] - vb).dot(p.kernel.grad_w(r));
                }
            }
            let predicted = p.fluid.density_ratio[i] + dt * rate;
            worst = worst.max((advected - predicted).min(advected - 1.0));
        }
        worst
    }

    #[test]
    fn unseen_compression_is_what_the_linear_prediction_misses() {
        let mut p = patch();
        let nb = Neighborhood::new(&p.fluid_lists, &p.boundary_lists, &p.cache);
        let check = |p: &Patch, nb: &Neighborhood, dt: f32| {
            let rates = density_rates(p.volume, &p.fluid.velocity, nb);
            unseen_compression(&p.kernel, p.volume, dt, &p.fluid, &p.boundary, nb, &rates)
        };
        // The patch's velocities are random at up to 0.7 m/s against a 2 cm spacing: a step
        // of 10 ms moves neighbours by up to 0.5 d relative to each other, a clearly
        // nonlinear step; 0.1 ms is a linear one.
        for dt in [1.0e-4f32, 1.0e-2] {
            let got = check(&p, &nb, dt);
            let want = unseen_compression_directly(&p, dt);
            assert!(
                (got - want).abs() <= 1.0e-5,
                "Δt {dt}: {got} from the pass, {want} directly"
            );
        }
        let long = check(&p, &nb, 1.0e-2);
        let short = check(&p, &nb, 1.0e-4);
        assert!(long > 0.01, "a long step misses percents: {long}");
        assert!(short < 1.0e-4, "a short step is linear: {short}");
        // A rigid translation of fluid and walls together changes no density.
        let drift = Vec2::new(0.4, -0.3);
        p.fluid.velocity.iter_mut().for_each(|v| *v = drift);
        p.boundary.velocity.iter_mut().for_each(|v| *v = drift);
        // (The walls' share of the density rate is cached with their velocity.)
        density_and_factor(
            &p.kernel,
            p.volume,
            &mut p.fluid,
            &p.boundary,
            &p.fluid_lists,
            &p.boundary_lists,
            &mut p.cache,
            f32::INFINITY,
            AKINCI_WALLS,
        );
        let nb = Neighborhood::new(&p.fluid_lists, &p.boundary_lists, &p.cache);
        let rigid = check(&p, &nb, 1.0e-2);
        assert!(rigid < 1.0e-5, "a rigid motion: {rigid}");
    }

    /// XSPH and the Laplacian viscosity run on the blocks; both paths must give the same bits
    /// and the pair formulas of `forces::non_pressure_accelerations`, written out directly.
    #[test]
    fn viscosity_sums_on_the_blocks_are_the_pair_formulas() {
        let p = patch();
        let mut portable = p.cache.clone();
        portable.blocks.set_simd_path(SimdPath::Portable);
        let (x, v) = (&p.fluid.position, &p.fluid.velocity);
        let h = p.kernel.support();
        let eps2 = 0.01 * h * h;
        let mut nonzero = 0;
        for b in 0..p.cache.blocks.blocks() {
            let simd = p
                .cache
                .blocks
                .viscosity_sums(b, x, v, &p.kernel, eps2, true);
            let port = portable
                .blocks
                .viscosity_sums(b, x, v, &p.kernel, eps2, true);
            let bits = |s: &[Vec2; LANES]| s.map(|g| (g.x.to_bits(), g.y.to_bits()));
            assert_eq!(bits(&simd.0), bits(&port.0), "XSPH, block {b}");
            assert_eq!(bits(&simd.1), bits(&port.1), "Laplacian, block {b}");
            for l in 0..LANES {
                let i = b * LANES + l;
                if i >= p.fluid.len() {
                    continue;
                }
                let (mut smooth, mut laplace) = (glam::DVec2::ZERO, glam::DVec2::ZERO);
                for j in 0..p.fluid.len() {
                    let (xij, vij) = (x[i] - x[j], v[i] - v[j]);
                    if j != i && xij.length() < h {
                        smooth -= (vij * p.kernel.w(xij.length())).as_dvec2();
                        let ratio = vij.dot(xij) / (xij.length_squared() + eps2);
                        laplace += (p.kernel.grad_w(xij) * ratio).as_dvec2();
                    }
                }
                let (got_s, got_l) = (simd.0[l].as_dvec2(), simd.1[l].as_dvec2());
                assert!(
                    (got_s - smooth).length() <= 1.0e-4 * smooth.length().max(1.0),
                    "particle {i}: XSPH {got_s} on the blocks, {smooth} directly"
                );
                assert!(
                    (got_l - laplace).length() <= 1.0e-4 * laplace.length().max(1.0),
                    "particle {i}: Laplacian {got_l} on the blocks, {laplace} directly"
                );
                nonzero += usize::from(smooth.length() > 1.0 && laplace.length() > 1.0);
            }
        }
        assert!(nonzero > 100, "a real test needs real sums: {nonzero}");
    }

    #[test]
    fn simd_and_portable_linearisation_checks_agree_bit_for_bit() {
        // The advected kernel sums repeat the scalar expressions operation by operation on
        // every path: here the path in use (AVX-512 or `fma`) against `portable`.
        let p = patch();
        let mut portable = p.cache.clone();
        portable.blocks.set_simd_path(SimdPath::Portable);
        let simd_nb = Neighborhood::new(&p.fluid_lists, &p.boundary_lists, &p.cache);
        let portable_nb = Neighborhood::new(&p.fluid_lists, &p.boundary_lists, &portable);
        let (x, v) = (&p.fluid.position, &p.fluid.velocity);
        for dt in [1.0e-4f32, 1.0e-2] {
            for b in 0..p.cache.blocks.blocks() {
                let sums = |nb: &Neighborhood| {
                    nb.blocks
                        .advected_kernel_sums(b, x, v, dt, &p.kernel, p.volume, 0.5)
                        .map(f32::to_bits)
                };
                assert_eq!(sums(&simd_nb), sums(&portable_nb), "block {b}, Δt {dt}");
            }
            let check = |nb: &Neighborhood| {
                let rates = density_rates(p.volume, v, nb);
                unseen_compression(&p.kernel, p.volume, dt, &p.fluid, &p.boundary, nb, &rates)
                    .to_bits()
            };
            assert_eq!(check(&simd_nb), check(&portable_nb), "Δt {dt}");
        }
    }

    #[test]
    fn simd_and_portable_density_passes_agree_bit_for_bit() {
        // Every path evaluates the kernel with the scalar code's operations in the scalar
        // code's order: here the path in use (AVX-512 or `fma`) against `portable`.
        let p = patch();
        let mut fluid = p.fluid.clone();
        let mut portable = PairCache::default();
        portable.blocks.set_simd_path(SimdPath::Portable);
        density_and_factor(
            &p.kernel,
            p.volume,
            &mut fluid,
            &p.boundary,
            &p.fluid_lists,
            &p.boundary_lists,
            &mut portable,
            f32::INFINITY,
            AKINCI_WALLS,
        );
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        let vbits = |v: &[Vec2]| {
            v.iter()
                .map(|g| (g.x.to_bits(), g.y.to_bits()))
                .collect::<Vec<_>>()
        };
        assert_eq!(bits(&fluid.density_ratio), bits(&p.fluid.density_ratio));
        assert_eq!(bits(&fluid.factor), bits(&p.fluid.factor));
        assert_eq!(vbits(&portable.grad_sum), vbits(&p.cache.grad_sum));
        assert_eq!(bits(&portable.wall_flux), bits(&p.cache.wall_flux));
        // The cached gradients: the same sums of them, both read on the portable path.
        let mut simd = p.cache.clone();
        simd.blocks.set_simd_path(SimdPath::Portable);
        let kappa: Vec<f32> = (0..fluid.len() as u32).map(|k| 1.0 + jitter(k)).collect();
        for b in 0..simd.blocks.blocks() {
            let (a, c) = (
                simd.blocks.weighted_gradient_sums(b, &kappa),
                portable.blocks.weighted_gradient_sums(b, &kappa),
            );
            assert_eq!(
                (bits(&a.0), bits(&a.1)),
                (bits(&c.0), bits(&c.1)),
                "block {b}"
            );
        }
        assert!(fluid.density_ratio.iter().all(|&s| s > 0.5), "a real patch");
    }
}
