//! The DFSPH density solve by preconditioned conjugate gradients, for
//! `"pressure_solve": "conjugate_gradient"` (TVCG 2017, Algorithm 3's linear system, solved
//! with global reach).
//!
//! The density solve looks for stiffness values κ (m²/s, κ = Δt·p/ρ0) whose velocity change
//! `Δv = −Bᵀκ` ([`crate::solver::apply_pressure`]) makes the predicted relative density
//! `s_i + Δt·(B v)_i` equal to 1, where `(B v)_i = Dρ_i/Dt/ρ0` is the continuity equation's rate
//! ([`crate::solver::density_rates`]). With the error `e_i = source_i + Δt·(B v)_i` that is the
//! linear system
//!
//! `A κ = e⁰`, `A = Δt·B Bᵀ` (symmetric, positive semi-definite),
//!
//! on the particles that carry pressure. The paper's Jacobi iteration carries information
//! about one neighbourhood per iteration and stops on an average that a deep column falling
//! into its bottom rows does not move (docs/deep-columns.md). Here:
//!
//! * **Conjugate gradients**, preconditioned with the DFSPH factor (`a_i/Δt = 1/A_ii`), reach
//!   the whole fluid; each iteration costs the same two neighbour passes as a Jacobi iteration.
//! * **Deflation** by aggregates ([`super::deflation`], Saad et al. 2000): the smooth part of
//!   the error, which the diagonal preconditioner resolves one neighbourhood per iteration, is
//!   solved exactly on a coarse space of aggregates eight supports wide each iteration
//!   (`SolverSettings::coarse_cell_supports`). The start is corrected so that the residual
//!   sums to zero over every aggregate, and every search direction is made A-orthogonal to
//!   the aggregates.
//! * **A full warm start**: the previous step's pressure is the starting guess. In water at
//!   rest it balances gravity's `Δt·g`, so each step starts almost converged. (The Jacobi solve
//!   keeps half, which damps its own errors but throws away half of the support every step.)
//! * **A stopping rule that sees momentum**: besides the average and largest density error,
//!   the solve stops only once the velocity it has yet to correct is small
//!   ([`velocity_tolerance`]). For conjugate
//!   gradients `α_k (r_k·z_k) = ‖κ_{k+1} − κ_k‖²_A` is Δt times the squared velocity change of
//!   iteration k, and the sum over the last few iterations bounds the error's A-norm a few
//!   iterations back from below (Hestenes–Stiefel; Strakoš & Tichý 2002). A column in free
//!   fall has a tiny average density error and a large velocity error.
//! * **Free surface**: a particle more than [`SURFACE_DEFICIT`] below ρ0 keeps κ = 0 (the
//!   Dirichlet condition p = 0 of a free surface) unless its predicted density is compressed.
//!   Everyone else is solved for, expansion included: inside the fluid an incompressible flow
//!   can no more open up than compress. Existing compression is corrected, existing expansion is
//!   not (`source_i = clamp(s_i − 1 − band, 0, max_correction)`): pulling a slightly thin
//!   region together would be a surface tension of the solver's own, and compression within
//!   the band (`SolverSettings::compression_dead_band`, the lattice's own scatter) would take
//!   a deep column's whole pressure to remove in one step. Pressures below zero are stored
//!   as zero for the next warm start.
//!
//! It runs with the mirrored, hydrostatic walls ([`crate::boundary::MirroredWalls`]) and a
//! hydrostatic initial pressure ([`crate::simulation::hydrostatic_pressure`]), which make water
//! at rest the discrete equilibrium; [`ConjugateGradient`] names both. Its divergence solve is
//! the paper's Jacobi iteration ([`super::jacobi::divergence_solve`]).

use crate::par::prelude::*;
use glam::Vec2;

use super::deflation::{CoarseSpace, COLOURS, MIN_CELL_SUPPORTS};
use super::jacobi::{self, JacobiScratch};
use super::solve::{PressureSolver, SolveReport};
use crate::boundary::{BoundaryModel, MirroredWalls};
use crate::parallel::LIGHT_PASS_MIN_ITEMS;
use crate::particles::FluidParticles;
use crate::reduce;
use crate::solver::{apply_pressure, density_rates_into};
use crate::step::StepContext;

/// The density solve by conjugate gradients, with the mirrored walls; the divergence solve by
/// the paper's Jacobi iteration.
#[derive(Clone, Debug)]
pub(crate) struct ConjugateGradient {
    /// The lattice's gradient consistency c ([`crate::packing::gradient_consistency`]).
    gradient_consistency: f32,
    scratch: CgScratch,
    divergence: JacobiScratch,
}

impl ConjugateGradient {
    pub fn new(gradient_consistency: f32) -> Self {
        Self {
            gradient_consistency,
            scratch: CgScratch::default(),
            divergence: JacobiScratch::default(),
        }
    }
}

impl PressureSolver for ConjugateGradient {
    fn divergence_solve(&mut self, step: &StepContext, fluid: &mut FluidParticles) -> SolveReport {
        jacobi::divergence_solve(step, fluid, &mut self.divergence)
    }

    fn density_solve(&mut self, step: &StepContext, fluid: &mut FluidParticles) -> SolveReport {
        density_solve(step, self.gradient_consistency, fluid, &mut self.scratch)
    }

    fn density_rates(&self) -> Option<&[f32]> {
        Some(&self.scratch.rate)
    }

    fn walls(&self) -> &'static dyn BoundaryModel {
        &MirroredWalls
    }

    /// `1/c`: the solve stores the physical pressure `c·κ/Δt` (see [`density_solve`]).
    fn pressure_force_scale(&self) -> f32 {
        1.0 / self.gradient_consistency
    }

    /// The solve's starting guess for the first step: water at rest then starts in
    /// equilibrium instead of falling into its bottom rows while the pressure builds up.
    fn initial_pressure(&self, position: &[Vec2], gravity: Vec2, d: f32) -> Option<Vec<f32>> {
        Some(super::hydrostatic::hydrostatic_pressure(
            position, gravity, d,
        ))
    }
}

/// The share of the starting `rᵀz` (the preconditioned residual's square norm) at which the
/// solve stops whatever its other rules say (1e-12: the residual 10⁻⁶ of where it started,
/// near single precision's resolution of the sums it is made of). Past it `pᵀAp` is
/// round-off too, and the step `rᵀz/pᵀAp` is noise over noise: a droplet of three particles
/// pressed into a corner, solved exactly within three iterations, went on (the velocity rule
/// wants four) with steps of 10¹¹ and left at 1,000 m/s.
pub const ROUND_OFF: f64 = 1.0e-12;

/// A particle this far (relative) below ρ0 is at the free surface. The row below a free
/// surface has its full neighbourhood (the support is two spacings); the surface row misses
/// about a fifth of its density.
pub const SURFACE_DEFICIT: f32 = 0.02;

/// The velocity error (m/s, root mean square) at which the solve may stop: the speed that
/// would create the density tolerance over one step of `step.dt` at spacing d, and where
/// g > 0 at most [`SolverSettings::gravity_impulse_tolerance`] of the gravity impulse
/// `g·Δt`. Absolute: how fast the fastest particle moves does not loosen it (a falling
/// drop would loosen the solve in the deep water it has not reached yet).
///
/// [`SolverSettings::gravity_impulse_tolerance`]: crate::settings::SolverSettings::gravity_impulse_tolerance
pub(crate) fn velocity_tolerance(step: &StepContext) -> f32 {
    let settings = step.settings;
    let (d, g, dt) = (step.spacing, step.gravity.length(), step.dt);
    let from_density = (settings.density.tolerance_pct / 100.0) as f32 * d / dt;
    let from_gravity = settings.gravity_impulse_tolerance * g * dt;
    if from_gravity > 0.0 {
        from_density.min(from_gravity)
    } else {
        from_density
    }
}

/// Scratch arrays of the conjugate-gradient solve.
#[derive(Default, Clone, Debug)]
struct CgScratch {
    active: Vec<f32>,
    residual: Vec<f32>,
    direction: Vec<f32>,
    dir_velocity: Vec<Vec2>,
    dir_rate: Vec<f32>,
    zeros: Vec<f32>,
    unused: Vec<f32>,
    /// Rates at the current velocities.
    pub rate: Vec<f32>,
    /// The walls' share of the rates after the warm start moved the rigid bodies.
    flux: Vec<f32>,
    /// The deflated solve's coarse space and a coarse vector.
    coarse: CoarseSpace,
    coarse_rhs: Vec<f64>,
}

/// `y_i += a·x_i`: a step of `a` along a search direction, for stiffnesses, velocities and
/// rates alike.
fn add_scaled<T>(y: &mut [T], x: &[T], a: f32)
where
    T: Copy + Send + Sync + std::ops::AddAssign,
    f32: std::ops::Mul<T, Output = T>,
{
    y.par_iter_mut()
        .zip(x.par_iter())
        .with_min_len(LIGHT_PASS_MIN_ITEMS)
        .for_each(|(y, &x)| *y += a * x);
}

fn dot3(a: &[f32], b: &[f32], m: &[f32]) -> f64 {
    reduce::sum_and_max_of(a.len(), |i| a[i] as f64 * b[i] as f64 * m[i] as f64).0
}

/// Density solve by preconditioned conjugate gradients. Leaves the step's p/ρ0 in
/// `fluid.pressure_over_rho0` and the final rates in `scratch.rate`. The pressure is the
/// physical one, `c·κ/Δt` with c the lattice's `gradient_consistency`
/// ([`crate::packing::gradient_consistency`]): the SPH gradient recovers c times a field's
/// gradient, so a stiffness field κ pushes like the continuous pressure `c·κ/Δt`; at rest
/// it reads ρ0·g·(H − y).
fn density_solve(
    step: &StepContext,
    gradient_consistency: f32,
    fluid: &mut FluidParticles,
    scratch: &mut CgScratch,
) -> SolveReport {
    let (volume, dt, nb, settings) = (step.volume, step.dt, &step.nb, step.settings);
    let max_correction = settings.max_compression_correction(dt, step.spacing);
    let dead_band =
        settings.compression_dead_band * (settings.density.tolerance_pct / 100.0) as f32;
    let (warm_start, limits) = (settings.warm_start, settings.density);
    let velocity_tolerance = velocity_tolerance(step);
    let min_neighbors = settings.conjugate_gradient_min_neighbors;
    let n = fluid.len();
    scratch.active.resize(n, 0.0);
    scratch.residual.resize(n, 0.0);
    scratch.direction.resize(n, 0.0);
    scratch.dir_velocity.resize(n, Vec2::ZERO);
    scratch.dir_rate.resize(n, 0.0);
    scratch.zeros.clear();
    scratch.zeros.resize(n, 0.0);
    scratch.unused.resize(n, 0.0);
    scratch.rate.resize(n, 0.0);
    let mut total = std::mem::take(&mut fluid.pressure_over_rho0);
    total.resize(n, 0.0);
    if n == 0 {
        fluid.pressure_over_rho0 = total;
        return SolveReport::default();
    }
    let full = |i: usize| nb.fluid.range(i).len() + nb.boundary.range(i).len() >= min_neighbors;
    let inside = |i: usize| full(i) && fluid.density_ratio[i] >= 1.0 - SURFACE_DEFICIT;
    total
        .par_iter_mut()
        .enumerate()
        .with_min_len(LIGHT_PASS_MIN_ITEMS)
        .for_each(|(i, k)| {
            *k = if warm_start && inside(i) {
                k.max(0.0) * dt / gradient_consistency
            } else {
                0.0
            };
        });
    apply_pressure(volume, &total, &mut fluid.velocity, nb);
    // The free rigid bodies move with the water (`crate::rigid::coupled`): the warm start
    // pushes them, and each search direction's velocity change carries theirs, so that the
    // system solved is the one of water and bodies together.
    let wall_flux = match step.bodies {
        Some(bodies) => {
            scratch.flux.clear();
            scratch.flux.extend_from_slice(nb.wall_flux);
            bodies.add_flux(
                &mut scratch.flux,
                0..n,
                &bodies.velocity_change(&total),
                1.0,
            );
            &scratch.flux[..]
        }
        None => nb.wall_flux,
    };
    density_rates_into(
        volume,
        &fluid.velocity,
        nb,
        wall_flux,
        &scratch.zeros,
        &mut scratch.unused,
        &mut scratch.rate,
    );
    let density = &fluid.density_ratio;
    let factor = &fluid.factor;
    scratch
        .residual
        .par_iter_mut()
        .zip(scratch.active.par_iter_mut())
        .zip(scratch.rate.par_iter())
        .enumerate()
        .with_min_len(LIGHT_PASS_MIN_ITEMS)
        .for_each(|(i, ((e, a), &rate))| {
            *e = (density[i] - 1.0 - dead_band).clamp(0.0, max_correction.max(0.0)) + dt * rate;
            let on = inside(i) || (full(i) && *e > 0.0);
            *a = if on && factor[i] > 0.0 { 1.0 } else { 0.0 };
        });
    let errors = |e: &[f32], active: &[f32]| -> (f64, f64) {
        let (sum, max) = reduce::sum_and_max_of(n, |i| (active[i] * e[i]).abs() as f64);
        (sum / n as f64 * 100.0, max * 100.0)
    };
    let precondition = 1.0 / dt;
    let mut iterations = 0;
    let deflation_cell = deflation_cell(step).filter(|_| !step.stop_requested());
    if let Some(cell) = deflation_cell {
        // Deflated CG (Saad et al. 2000): start from the guess whose residual sums to zero
        // over every aggregate, κ += W E⁻¹ Wᵀ r, taken as a line search along W E⁻¹ Wᵀ r.
        let support = step.kernel.support();
        scratch.coarse.aggregate(
            &fluid.position,
            &scratch.active,
            cell.max(MIN_CELL_SUPPORTS) * support,
        );
        for k in 0..COLOURS {
            scratch.coarse.colour_indicator(k, &mut scratch.direction);
            direction_products(step, n, scratch);
            // A p = −Δt·B(−Bᵀ p), on the active particles.
            let (rate, active) = (&scratch.dir_rate, &scratch.active);
            let product = rate.iter().zip(active).map(|(&r, &a)| -dt * r * a);
            scratch.coarse.set_colour_product(k, product);
        }
        scratch.coarse.factorise(&fluid.position, &scratch.active);
        let (active, residual) = (&scratch.active, &scratch.residual);
        let coarse = &mut scratch.coarse;
        coarse.restrict(
            |i| (active[i] * residual[i]) as f64,
            &mut scratch.coarse_rhs,
        );
        coarse.solve(&mut scratch.coarse_rhs);
        let y = &scratch.coarse_rhs;
        scratch
            .direction
            .par_iter_mut()
            .enumerate()
            .with_min_len(LIGHT_PASS_MIN_ITEMS)
            .for_each(|(i, p)| *p = coarse.prolong(y, i));
        let pq = direction_products(step, n, scratch);
        let rp = dot3(&scratch.direction, &scratch.residual, &scratch.active);
        if pq > 0.0 && pq.is_finite() && rp.is_finite() {
            take_step(
                (rp / pq) as f32,
                dt,
                &mut total,
                &mut fluid.velocity,
                scratch,
            );
            iterations += 1;
        }
    }
    new_direction(precondition, factor, 0.0, deflation_cell.is_some(), scratch);
    let mut rz: f64 = rz_of(precondition, factor, scratch);
    // Below this the residual is single precision's round-off of the one the iteration
    // started from: a further step divides noise by noise.
    let round_off = rz * ROUND_OFF;
    let (mut avg, mut max) = errors(&scratch.residual, &scratch.active);
    let n_active = scratch.active.iter().filter(|&&a| a > 0.0).count().max(1) as f64;
    // α_k·(r_k·z_k) = ||κ_{k+1} − κ_k||²_A: Δt times the squared velocity change of
    // iteration k. Summed over the last DELAY iterations it bounds the A-norm error DELAY
    // iterations back from below (Hestenes–Stiefel; Strakoš & Tichý 2002).
    const DELAY: usize = 4;
    let mut energy = [f64::INFINITY; DELAY];
    let velocity_error =
        |energy: &[f64; DELAY]| (energy.iter().sum::<f64>() / (dt as f64 * n_active)).sqrt();
    while (avg > limits.tolerance_pct
        || max > limits.max_error_pct
        || velocity_error(&energy) > velocity_tolerance as f64
        || iterations < limits.min_iterations)
        && iterations < limits.max_iterations
        && rz > round_off
        && !step.stop_requested()
    {
        let pq = direction_products(step, n, scratch);
        if pq <= 0.0 || !pq.is_finite() {
            break;
        }
        let alpha = (rz / pq) as f32;
        take_step(alpha, dt, &mut total, &mut fluid.velocity, scratch);
        // A step that makes the worst particle's error grow past the settings' bound is
        // taken back and ends the solve, as in the Jacobi solve
        // (`SolverSettings::diverging_error_growth`): on a droplet of a few particles
        // pressed into a wall the system is nearly singular, and a solve that went on
        // threw six particles at 138 m/s through the wall.
        let (avg_new, max_new) = errors(&scratch.residual, &scratch.active);
        if max_new > settings.diverging_error_growth * max + limits.max_error_pct {
            take_step(-alpha, dt, &mut total, &mut fluid.velocity, scratch);
            break;
        }
        energy[iterations as usize % DELAY] = rz / pq * rz;
        let rz_new = rz_of(precondition, factor, scratch);
        let beta = (rz_new / rz) as f32;
        rz = rz_new;
        new_direction(
            precondition,
            factor,
            beta,
            deflation_cell.is_some(),
            scratch,
        );
        (avg, max) = (avg_new, max_new);
        iterations += 1;
    }
    total
        .par_iter_mut()
        .with_min_len(LIGHT_PASS_MIN_ITEMS)
        .for_each(|k| *k *= gradient_consistency / dt);
    fluid.pressure_over_rho0 = total;
    SolveReport {
        iterations,
        avg_error_pct: avg,
        max_error_pct: max,
    }
}

/// Aggregate width of the deflated solve, in kernel supports
/// ([`SolverSettings::coarse_cell_supports`]), or `None` without deflation (0).
///
/// [`SolverSettings::coarse_cell_supports`]: crate::settings::SolverSettings::coarse_cell_supports
///
/// Not with free rigid bodies: a body couples every particle that touches it, anywhere along
/// its outline, and the colour products that give `A W` need `A` to reach no further than two
/// supports (with the bodies' share left out, the coarse space was wrong enough to hold a
/// floating box's steps at the iteration cap).
fn deflation_cell(step: &StepContext) -> Option<f32> {
    let cell = step.settings.coarse_cell_supports;
    (cell > 0.0 && step.bodies.is_none()).then_some(cell)
}

/// The search direction's velocity change `−Bᵀ p` and rate change `B(−Bᵀ p)` (bodies
/// included), and `pᵀ A p = −Δt·p·B(−Bᵀ p)` over the active particles.
fn direction_products(step: &StepContext, n: usize, scratch: &mut CgScratch) -> f64 {
    let (volume, nb) = (step.volume, &step.nb);
    scratch
        .dir_velocity
        .par_iter_mut()
        .for_each(|v| *v = Vec2::ZERO);
    apply_pressure(volume, &scratch.direction, &mut scratch.dir_velocity, nb);
    density_rates_into(
        volume,
        &scratch.dir_velocity,
        nb,
        &scratch.zeros,
        &scratch.zeros,
        &mut scratch.unused,
        &mut scratch.dir_rate,
    );
    if let Some(bodies) = step.bodies {
        let moved = bodies.velocity_change(&scratch.direction);
        bodies.add_flux(&mut scratch.dir_rate, 0..n, &moved, -1.0);
    }
    -(step.dt as f64) * dot3(&scratch.direction, &scratch.dir_rate, &scratch.active)
}

/// A step of `alpha` along the search direction: stiffness, velocities, rates and residual.
fn take_step(
    alpha: f32,
    dt: f32,
    total: &mut [f32],
    velocity: &mut [Vec2],
    scratch: &mut CgScratch,
) {
    let (dir, dv, dr) = (&scratch.direction, &scratch.dir_velocity, &scratch.dir_rate);
    add_scaled(total, dir, alpha);
    add_scaled(velocity, dv, alpha);
    add_scaled(&mut scratch.rate, dr, alpha);
    add_scaled(&mut scratch.residual, dr, alpha * dt);
}

/// `r·z` with the preconditioned residual `z = D r` (D the DFSPH factor over Δt).
fn rz_of(precondition: f32, factor: &[f32], scratch: &CgScratch) -> f64 {
    let (active, residual) = (&scratch.active, &scratch.residual);
    reduce::sum_and_max_of(residual.len(), |i| {
        (active[i] * factor[i] * precondition * residual[i]) as f64 * residual[i] as f64
    })
    .0
}

/// The next search direction `p = z + β p` (`p = z` for β = 0, whatever p held), made
/// A-orthogonal to the coarse space when deflating: `p −= W E⁻¹ (A W)ᵀ z`.
fn new_direction(
    precondition: f32,
    factor: &[f32],
    beta: f32,
    deflate: bool,
    scratch: &mut CgScratch,
) {
    let (active, residual) = (&scratch.active, &scratch.residual);
    let z = |i: usize| active[i] * factor[i] * precondition * residual[i];
    if deflate {
        let coarse = &scratch.coarse;
        coarse.restrict_aw(|i| z(i) as f64, &mut scratch.coarse_rhs);
        coarse.solve(&mut scratch.coarse_rhs);
    }
    let y = &scratch.coarse_rhs;
    let coarse = &scratch.coarse;
    scratch
        .direction
        .par_iter_mut()
        .enumerate()
        .with_min_len(LIGHT_PASS_MIN_ITEMS)
        .for_each(|(i, p)| {
            *p = if beta == 0.0 { z(i) } else { z(i) + beta * *p };
            if deflate {
                *p -= coarse.prolong(y, i);
            }
        });
}
