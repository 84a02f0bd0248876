//! The paper's Jacobi iteration (TVCG 2017, Algorithms 2 and 3) for both DFSPH solves, with
//! Akinci's walls: `"pressure_solve": "jacobi"`.
//!
//! The density solve drives the predicted relative density `s*_i = s_i + Δt·Dρ_i/Dt/ρ0` to 1
//! with `Δκ_i = max(s*_i − 1, 0)·a_i/Δt` (only compression is corrected: the free surface
//! must not be pulled together); the divergence solve drives `Dρ_i/Dt` to 0 with
//! `Δκ_i = max(Dρ_i/Dt/ρ0, 0)·a_i`. Both are one loop, `jacobi_solve`, over a named
//! `JacobiProblem`; the notation is that of [`crate::solver`].

use std::ops::Range;
use std::sync::atomic::{AtomicBool, Ordering};

use crate::par::prelude::*;

use crate::lockstep::{self, Shared, Team};
use crate::parallel::LIGHT_PASS_MIN_ITEMS;

use super::solve::{PressureSolver, SolveReport};
use crate::blocked::{ResidualTerms, LANES};
use crate::particles::FluidParticles;
use crate::reduce;
use crate::rigid::coupled::{BodyVelocity, CoupledBodies};
use crate::settings::SolveLimits;
use crate::step::StepContext;
use glam::Vec2;

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
    /// The warm start applies only where a particle is compressed before it
    /// ([`Sweeps::warm_start`]).
    gated_warm_start: bool,
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
            // Everywhere: the divergence solve's warm start did not throw droplets back
            // (`a_droplet_thrown_at_a_wall_does_not_bounce_back` passes ungated), and the
            // gate costs a residual pass (about 4 % of a 20k benchmark step).
            gated_warm_start: false,
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
            gated_warm_start: true,
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
    /// Per particle, the stiffness the solve may start from (the warm start), applied only
    /// where the particle is compressed before it ([`Sweeps::warm_start`]).
    warm: Vec<f32>,
    /// Per particle, the walls' share of the density rate as the rigid bodies move in the
    /// solve ([`crate::rigid::coupled`]); unused without bodies.
    flux: Vec<f32>,
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
/// The whole iteration runs in one [`lockstep`] region, each of its passes a method of
/// [`Sweeps`]: each member starts every pass on the same share of parts, takes what the
/// others have not reached when its own is done, and the members meet at a barrier between
/// passes, instead of one rayon fork-join per pass (docs/PERFORMANCE.md has the measurements).
fn jacobi_solve(
    step: &StepContext,
    problem: &JacobiProblem,
    fluid: &mut FluidParticles,
    scratch: &mut JacobiScratch,
    total: &mut [f32],
) -> SolveReport {
    let limits = problem.limits;
    let diverging_error_growth = step.settings.diverging_error_growth;
    let warm = step.settings.warm_start;
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
    let mut part_sums = [(0.0, 0.0); reduce::MAX_PARTS];
    if step.bodies.is_some() {
        scratch.flux.clear();
        scratch.flux.extend_from_slice(step.nb.wall_flux);
    }
    let sweeps = Sweeps::new(step, problem, fluid, scratch, total, &mut part_sums);

    let outcomes = lockstep::run(|team| {
        let mine = sweeps.share(team);
        // The bodies' velocity change since the solve began: every member keeps its own
        // copy, summed from the same increments in the same order.
        let mut moved = Moved::new(step.bodies);
        // The buffer the next increments are written into, and the one holding the rates at
        // the velocities as they are.
        let (mut next, mut rates_now) = (0, 0);
        if warm {
            if problem.gated_warm_start {
                // The residuals before the warm start decide where it applies.
                sweeps.residuals(team, &mine, next);
            }
            sweeps.warm_start(team, &mine, next, problem.gated_warm_start);
            sweeps.apply(team, &mine, next, &mut moved);
            next = 1 - next;
            rates_now = next;
        }
        let (mut avg, mut max, mut stop) = sweeps.residuals(team, &mine, next);
        let mut iterations = 0;
        while limits.unmet(avg, max, iterations) && !stop {
            sweeps.apply(team, &mine, next, &mut moved);
            next = 1 - next;
            rates_now = next;
            let previous = (avg, max);
            (avg, max, stop) = sweeps.residuals(team, &mine, next);
            iterations += 1;
            if avg.is_nan() || avg > diverging_error_growth * previous.0 + limits.tolerance_pct {
                // Jacobi is not guaranteed to converge (dense clusters, e.g. fluid pulled
                // into a point): an iteration that makes the error grow is taken back and
                // the solve stops, rather than feeding the growth into the velocities.
                sweeps.take_back(team, &mine, 1 - next, &mut moved);
                // The velocities are back where the previous pass read them.
                rates_now = 1 - next;
                (avg, max) = previous;
                break;
            }
        }
        let report = SolveReport {
            iterations,
            avg_error_pct: avg,
            max_error_pct: max,
        };
        (report, next, rates_now)
    });
    let (report, next, rates_now) = outcomes[0];
    // The next increment and the current rates go back where the callers look for them.
    if next == 1 {
        std::mem::swap(&mut scratch.delta, &mut scratch.previous_delta);
    }
    if rates_now == 1 {
        std::mem::swap(&mut scratch.rate, &mut scratch.previous_rate);
    }
    report
}

/// The passes of a Jacobi solve, run by every member of its [`lockstep`] region, and the arrays
/// they share. A pass works part by part (a part is `blocks_per_part` blocks of [`LANES`]
/// particles); each part is written by the one member that took it, and the pass ends at a
/// barrier. The increment and rate arrays come in two buffers: the residual pass writes the
/// next increments into one while the other keeps the increments applied last, to take an
/// iteration back.
struct Sweeps<'a> {
    step: &'a StepContext<'a>,
    terms: ResidualTerms<'a>,
    /// What turns the average residual into the reported error, percent.
    to_pct: f64,
    n: usize,
    blocks: usize,
    blocks_per_part: usize,
    parts: usize,
    velocity: Shared<'a, Vec2>,
    total: Shared<'a, f32>,
    increments: [Shared<'a, f32>; 2],
    rates: [Shared<'a, f32>; 2],
    /// The warm-start stiffness of each particle ([`JacobiScratch::warm`]).
    warm: &'a [f32],
    /// The free rigid bodies, which move with each increment ([`crate::rigid::coupled`]).
    bodies: Option<&'a CoupledBodies>,
    /// The walls' share of the density rate as the solve began, and, with bodies, as they
    /// have moved since ([`JacobiScratch::flux`]).
    base_flux: &'a [f32],
    flux: Shared<'a, f32>,
    /// Per part, the (sum, max) of its residuals: the residual sum decides when to stop, so
    /// it is taken in an order that does not depend on the work split (`reduce`), per part,
    /// then the parts in order.
    part_sums: Shared<'a, (f64, f64)>,
    /// Whether the caller's stop flag was set, as the first member read it in the last
    /// residual pass: every member must leave the loop at the same iteration (a member
    /// reading the flag on its own could leave while the others wait at a barrier for it).
    stop_seen: AtomicBool,
}

impl<'a> Sweeps<'a> {
    fn new(
        step: &'a StepContext<'a>,
        problem: &JacobiProblem,
        fluid: &'a mut FluidParticles,
        scratch: &'a mut JacobiScratch,
        total: &'a mut [f32],
        part_sums: &'a mut [(f64, f64); reduce::MAX_PARTS],
    ) -> Self {
        let n = fluid.len();
        let blocks = n.div_ceil(LANES);
        let blocks_per_part = reduce::part_units(blocks, 16);
        let parts = blocks.div_ceil(blocks_per_part);
        // A part's particles in the per-particle arrays; one sum per part in `part_sums`.
        let part_len = blocks_per_part * LANES;
        Self {
            step,
            terms: ResidualTerms {
                volume: step.volume,
                grad_sum: step.nb.grad_sum,
                wall_flux: step.nb.wall_flux,
                source: &scratch.source,
                rate_scale: problem.rate_scale,
                factor: &fluid.factor,
                increment_scale: problem.increment_scale,
            },
            to_pct: problem.to_pct,
            n,
            blocks,
            blocks_per_part,
            parts,
            velocity: Shared::new(&mut fluid.velocity, part_len),
            total: Shared::new(total, part_len),
            increments: [
                Shared::new(&mut scratch.delta, part_len),
                Shared::new(&mut scratch.previous_delta, part_len),
            ],
            rates: [
                Shared::new(&mut scratch.rate, part_len),
                Shared::new(&mut scratch.previous_rate, part_len),
            ],
            warm: &scratch.warm,
            stop_seen: AtomicBool::new(false),
            bodies: step.bodies,
            base_flux: step.nb.wall_flux,
            flux: Shared::new(&mut scratch.flux, part_len),
            part_sums: Shared::new(&mut part_sums[..parts], 1),
        }
    }

    /// This member's share of the parts, the same in every pass, cut at part bounds and
    /// balanced by neighbour slots.
    fn share(&self, team: &Team) -> Range<usize> {
        let (blocks, per_part) = (self.blocks, self.blocks_per_part);
        team.share(self.parts, |p| {
            self.step.nb.blocks.slots_before((p * per_part).min(blocks)) as u64
        })
    }

    /// Part `p`'s blocks and particles.
    fn part(&self, p: usize) -> (Range<usize>, Range<usize>) {
        let part_blocks =
            p * self.blocks_per_part..((p + 1) * self.blocks_per_part).min(self.blocks);
        let items = part_blocks.start * LANES..(part_blocks.end * LANES).min(self.n);
        (part_blocks, items)
    }

    /// The residuals at the current velocities, part by part, written into
    /// `increments[buffer]` and `rates[buffer]` with the next increments; then, after the
    /// barrier, the average and largest residual over all parts, in percent (every member
    /// takes the same sum in the same order, so all decide alike).
    /// The residuals at the velocities as they are into `rates[buffer]` and the next
    /// increments into `increments[buffer]`; returns the average and largest error, percent,
    /// and whether a stop was requested (the same three values to every member).
    fn residuals(&self, team: &mut Team, mine: &Range<usize>, buffer: usize) -> (f64, f64, bool) {
        // In this pass the velocities and the wall flux are only read; each part's items and
        // sum are written by the one member that took the part.
        let pass = team.pass();
        let vel = self.velocity.read(&pass);
        let terms = ResidualTerms {
            wall_flux: match self.bodies {
                Some(_) => self.flux.read(&pass),
                None => self.base_flux,
            },
            ..self.terms
        };
        for part in pass.parts(mine.clone()) {
            let (part_blocks, _) = self.part(part.index());
            let d = self.increments[buffer].part_mut(&part);
            let r = self.rates[buffer].part_mut(&part);
            let sum = &mut self.part_sums.part_mut(&part)[0];
            // The residuals of a few blocks at a time, summed together.
            const GROUP: usize = reduce::BLOCKS_TOGETHER;
            let mut errors = [[0.0f32; LANES]; GROUP];
            let mut acc = (0.0, 0.0);
            let groups = d.chunks_mut(GROUP * LANES).zip(r.chunks_mut(GROUP * LANES));
            for (g, (d, r)) in groups.enumerate() {
                let count = d.len().div_ceil(LANES);
                let first = part_blocks.start + g * GROUP;
                let e = &mut errors[..count];
                self.step
                    .nb
                    .blocks
                    .residual_blocks(first..first + count, vel, &terms, d, r, e);
                acc = reduce::fold_block_sums(acc, &errors, count);
            }
            *sum = acc;
        }
        // Read and written around the barrier like the part sums: the next write comes in
        // the next residual pass, after the barrier that ends the pass between.
        if pass.index() == 0 {
            self.stop_seen
                .store(self.step.stop_requested(), Ordering::Relaxed);
        }
        pass.end();
        let stop = self.stop_seen.load(Ordering::Relaxed);
        // The part sums are read by every member in the next pass; the next residual pass,
        // which writes them, starts after another barrier.
        let pass = team.pass();
        let (sum, max) = self
            .part_sums
            .read(&pass)
            .iter()
            .copied()
            .fold((0.0, 0.0), reduce::add_sum_max);
        (sum / self.n as f64 * self.to_pct, max * self.to_pct, stop)
    }

    /// The warm start, as the increments in `increments[buffer]`, part by part: every
    /// particle's warm-start stiffness, or, `gated`, only that of each particle the residual
    /// pass just found compressed at the velocities as they are (residual above zero, its
    /// rate in `rates[buffer]`) and zero for every other. A particle that is not compressed
    /// needs no pressure: a droplet that hit a wall in the last step has stopped, and its
    /// stopping stiffness, applied again, would throw it back (a lone particle met the
    /// ceiling at 10 m/s and left it at 3.8–9.5 m/s with the density solve's warm start
    /// applied to all). SPlisHSPlasH's DFSPH gates its warm start the same way.
    fn warm_start(&self, team: &mut Team, mine: &Range<usize>, buffer: usize, gated: bool) {
        let (source, rate_scale) = (self.terms.source, self.terms.rate_scale);
        // Each part's increments are written by the one member that took it, and its rates
        // (written in the residual pass, which the barrier ended) read by it.
        let pass = team.pass();
        for part in pass.parts(mine.clone()) {
            let (_, items) = self.part(part.index());
            let d = self.increments[buffer].part_mut(&part);
            let r = self.rates[buffer].part_mut(&part);
            for (k, i) in items.enumerate() {
                let compressed = !gated || source[i] + rate_scale * r[k] > 0.0;
                d[k] = if compressed { self.warm[i] } else { 0.0 };
            }
        }
        pass.end();
    }

    /// Apply the increments in `increments[buffer]` to the velocities and add them to the
    /// running totals, part by part; then, with rigid bodies, move them by what the
    /// increments gave them (`moved`, this member's running sum) and bring the walls' share
    /// of the density rate up to date, part by part.
    fn apply(&self, team: &mut Team, mine: &Range<usize>, buffer: usize, moved: &mut Moved) {
        // In this pass the increments are only read; each part's velocities and totals are
        // written by the one member that took the part.
        let pass = team.pass();
        let kappa = self.increments[buffer].read(&pass);
        let nb = &self.step.nb;
        for part in pass.parts(mine.clone()) {
            let (part_blocks, _) = self.part(part.index());
            let vel = self.velocity.part_mut(&part);
            let sum = self.total.part_mut(&part);
            nb.blocks.apply_blocks(
                part_blocks,
                self.step.volume,
                kappa,
                nb.grad_sum,
                vel,
                Some(sum),
            );
        }
        pass.end();
        if let Some(bodies) = self.bodies {
            // The increments are still only read; each part's flux is written by the one
            // member that took it, before the residual pass that reads it.
            let pass = team.pass();
            let kappa = self.increments[buffer].read(&pass);
            for (total, dv) in moved.0.iter_mut().zip(bodies.velocity_change(kappa)) {
                *total += dv;
            }
            for part in pass.parts(mine.clone()) {
                let (_, items) = self.part(part.index());
                let flux = self.flux.part_mut(&part);
                flux.copy_from_slice(&self.base_flux[items.clone()]);
                bodies.add_flux(flux, items, &moved.0, 1.0);
            }
            pass.end();
        }
    }

    /// Take back the increments of `increments[buffer]`, applied last: negate them, part by
    /// part, and apply them.
    fn take_back(&self, team: &mut Team, mine: &Range<usize>, buffer: usize, moved: &mut Moved) {
        // Each part is negated by the member that took it, before the pass that reads the
        // increments.
        let pass = team.pass();
        for part in pass.parts(mine.clone()) {
            self.increments[buffer]
                .part_mut(&part)
                .iter_mut()
                .for_each(|d| *d = -*d);
        }
        pass.end();
        self.apply(team, mine, buffer, moved);
    }
}

/// One member's running sum of the rigid bodies' velocity changes in a solve.
struct Moved(Vec<BodyVelocity>);

impl Moved {
    fn new(bodies: Option<&CoupledBodies>) -> Self {
        Self(vec![
            BodyVelocity::default();
            bodies.map_or(0, |b| b.bodies())
        ])
    }
}

/// The warm start of both solves: the stiffness each may start from is a share
/// ([`SolverSettings::jacobi_warm_share`](crate::settings::SolverSettings::jacobi_warm_share))
/// of the previous step's, times `scale` (1 for κᵛ; Δt for the stored p/ρ0, whence κ = Δt·p/ρ0),
/// its negative part dropped, into `warm`; `total` starts at zero (the solve adds the warm
/// start to it where it applies it, see [`Sweeps::warm_start`]).
fn warm_start(step: &StepContext, total: &mut [f32], scale: f32, warm: &mut Vec<f32>) {
    warm.resize(total.len(), 0.0);
    let w = if step.settings.warm_start {
        step.settings.jacobi_warm_share
    } else {
        0.0
    };
    total
        .par_iter_mut()
        .zip(warm.par_iter_mut())
        .with_min_len(LIGHT_PASS_MIN_ITEMS)
        .for_each(|(k, warm)| {
            *warm = k.max(0.0) * scale * w;
            *k = 0.0;
        });
}

/// Divergence solve (TVCG 2017, Algorithm 2): make `Dρ/Dt = 0` so the velocity field is
/// divergence-free. The error is the average relative density change over one step,
/// `step.dt`. With the warm start, a share of the previous step's κᵛ is applied first.
pub fn divergence_solve(
    step: &StepContext,
    fluid: &mut FluidParticles,
    scratch: &mut JacobiScratch,
) -> SolveReport {
    let (nb, settings) = (&step.nb, step.settings);
    let mut total = std::mem::take(&mut fluid.divergence_stiffness);
    warm_start(step, &mut total, 1.0, &mut scratch.warm);
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
    let (dt, settings) = (step.dt, step.settings);
    let max_correction = settings.max_compression_correction(dt, step.spacing);
    // κ = Δt·p/ρ0; the stored pressure does not depend on Δt, so it carries over when Δt
    // changes.
    let mut total = std::mem::take(&mut fluid.pressure_over_rho0);
    warm_start(step, &mut total, dt, &mut scratch.warm);
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
