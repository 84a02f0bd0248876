//! The paper's Jacobi iteration (TVCG 2017, Algorithms 2 and 3) for both DFSPH solves, with
//! Akinci's walls: `"pressure_solve": "jacobi"`.
//!
//! The density solve drives the predicted relative density `s*_i = s_i + Δt·Dρ_i/Dt/ρ0` to 1
//! with `Δκ_i = max(s*_i − 1, 0)·a_i/Δt` (only compression is corrected: the free surface
//! must not be pulled together); the divergence solve drives `Dρ_i/Dt` to 0 with
//! `Δκ_i = max(Dρ_i/Dt/ρ0, 0)·a_i`. Both are one loop, `jacobi_solve`, over a named
//! `JacobiProblem`; the notation is that of [`crate::solver`].

use std::ops::Range;

use crate::par::prelude::*;

use crate::lockstep::{self, Shared};
use crate::parallel::LIGHT_PASS_MIN_ITEMS;

use super::{PressureSolver, SolveReport};
use crate::blocked::{ResidualTerms, LANES};
use crate::particles::FluidParticles;
use crate::reduce;
use crate::settings::SolveLimits;
use crate::solver::apply_pressure;
use crate::step::StepContext;

/// The paper's DFSPH: both solves by Jacobi iterations.
#[derive(Clone, Debug, Default)]
pub struct Jacobi {
    scratch: JacobiScratch,
}

impl PressureSolver for Jacobi {
    fn divergence_solve(&mut self, step: &StepContext, fluid: &mut FluidParticles) -> SolveReport {
        divergence_solve(step, fluid, &mut self.scratch)
    }

    fn density_solve(&mut self, step: &StepContext, fluid: &mut FluidParticles) -> SolveReport {
        density_solve(step, fluid, &mut self.scratch)
    }

    fn density_rates(&self) -> Option<&[f32]> {
        Some(self.scratch.density_rates())
    }
}

/// What one Jacobi solve drives to zero, and when it stops: the residual
/// `e_i = max(source_i + rate_scale·Dρ_i/Dt/ρ0, 0)` (`source` prepared by the caller), its
/// average reported in percent after `to_pct`, and the stiffness increment
/// `Δκ_i = e_i·a_i·increment_scale`.
#[derive(Clone, Copy, Debug)]
struct JacobiProblem {
    /// The stopping rule.
    limits: SolveLimits,
    /// What multiplies the density rate in the residual, s (or 1).
    rate_scale: f32,
    /// What turns the average residual into the reported error, percent.
    to_pct: f64,
    /// What turns a residual times the factor into a stiffness increment.
    increment_scale: f32,
}

impl JacobiProblem {
    /// Algorithm 2: `Dρ_i/Dt = 0`. The residual is the relative density rate (1/s); its
    /// error, the relative density change over one step of `step.dt`.
    fn divergence_free(step: &StepContext) -> Self {
        Self {
            limits: step.settings.divergence,
            rate_scale: 1.0,
            to_pct: step.dt as f64 * 100.0,
            increment_scale: 1.0,
        }
    }

    /// Algorithm 3: the predicted density `s_i + Δt·Dρ_i/Dt/ρ0` is 1. The residual is the
    /// predicted relative compression; the increment, over `Δt`, a stiffness.
    fn constant_density(step: &StepContext) -> Self {
        Self {
            limits: step.settings.density,
            rate_scale: step.dt,
            to_pct: 100.0,
            increment_scale: 1.0 / step.dt,
        }
    }
}

/// Scratch arrays of the Jacobi iterations.
#[derive(Default, Clone, Debug)]
pub struct JacobiScratch {
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

impl JacobiScratch {
    /// Per fluid particle, the relative rate of density change `Dρ_i/Dt/ρ0` (TVCG 2017 eq. 7,
    /// see [`ResidualTerms`]) at the velocities the last Jacobi solve left. The density
    /// solve's linearisation check ([`crate::solver::unseen_compression`]) reads them here rather than
    /// walking every neighbour list again.
    pub fn density_rates(&self) -> &[f32] {
        &self.rate
    }
}

/// The Jacobi iteration shared by the density and divergence solves, on `problem`: compute
/// every residual `e_i = max(source_i + rate_scale·Dρ_i/Dt/ρ0, 0)` ([`ResidualTerms`],
/// `source` taken from `scratch.source`), stop when their average (in percent, after
/// `to_pct`) is within tolerance, else turn them into stiffness increments
/// `Δκ_i = e_i·a_i·increment_scale`, apply them, and accumulate them into `total`.
///
/// Only compression is corrected: residuals are clamped at zero, so within one solve a
/// particle's stiffness only grows. What a previous step left too high is not taken back here;
/// the warm start keeps only part of it
/// ([`SolverSettings::jacobi_warm_share`](crate::settings::SolverSettings::jacobi_warm_share)).
///
/// The whole iteration runs in one [`lockstep`] region: each worker starts every pass on
/// the same share of parts, takes what the other has not reached when its own is done, and
/// the workers meet at a barrier between passes, instead of one rayon fork-join per pass
/// (docs/PERFORMANCE.md has the measurements).
fn jacobi_solve(
    step: &StepContext,
    problem: &JacobiProblem,
    fluid: &mut FluidParticles,
    scratch: &mut JacobiScratch,
    total: &mut [f32],
) -> SolveReport {
    let (volume, nb) = (step.volume, &step.nb);
    let JacobiProblem {
        limits,
        rate_scale,
        to_pct,
        increment_scale,
    } = *problem;
    let diverging_error_growth = step.settings.diverging_error_growth;
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
            if avg.is_nan() || avg > diverging_error_growth * previous.0 + limits.tolerance_pct {
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
/// divergence-free. The error is the average relative density change over one step,
/// `step.dt`. With the warm start, a share of the previous step's κᵛ is applied first.
pub fn divergence_solve(
    step: &StepContext,
    fluid: &mut FluidParticles,
    scratch: &mut JacobiScratch,
) -> SolveReport {
    let (volume, nb, settings) = (step.volume, &step.nb, step.settings);
    let mut total = std::mem::take(&mut fluid.divergence_stiffness);
    if settings.warm_start {
        let w = settings.jacobi_warm_share;
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
            *s = if neighbors < settings.divergence_min_neighbors {
                f32::NEG_INFINITY
            } else {
                0.0
            };
        });
    let report = jacobi_solve(
        step,
        &JacobiProblem::divergence_free(step),
        fluid,
        scratch,
        &mut total,
    );
    fluid.divergence_stiffness = total;
    report
}

/// Density solve (TVCG 2017, Algorithm 3): correct the predicted velocities so that the
/// predicted density `s_i + Δt·Dρ_i/Dt/ρ0` is 1 wherever the fluid is compressed. Afterwards
/// `fluid.pressure_over_rho0` holds p/ρ0 of the step, used as the next warm start.
///
/// At most `SolverSettings::max_compression_correction` of a particle's existing compression
/// `s_i − 1` is removed in this step (see
/// [`SolverSettings::max_correction_speed`](crate::settings::SolverSettings::max_correction_speed));
/// the rest waits for the next steps.
pub fn density_solve(
    step: &StepContext,
    fluid: &mut FluidParticles,
    scratch: &mut JacobiScratch,
) -> SolveReport {
    let (volume, dt, nb, settings) = (step.volume, step.dt, &step.nb, step.settings);
    let max_correction = settings.max_compression_correction(dt, step.spacing);
    // κ = Δt·p/ρ0; the stored pressure does not depend on Δt, so it carries over when Δt
    // changes.
    let mut total = std::mem::take(&mut fluid.pressure_over_rho0);
    if settings.warm_start {
        let w = settings.jacobi_warm_share;
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
        step,
        &JacobiProblem::constant_density(step),
        fluid,
        scratch,
        &mut total,
    );
    total
        .par_iter_mut()
        .with_min_len(LIGHT_PASS_MIN_ITEMS)
        .for_each(|k| *k /= dt);
    fluid.pressure_over_rho0 = total;
    report
}
