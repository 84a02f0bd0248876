//! The quantities of DFSPH (Bender & Koschier 2015; TVCG 2017) that a step's pressure solves
//! share.
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
//! This module holds what every pressure solver ([`crate::pressure`]) works on: the densities
//! and factors of a step with the kernel gradients and sums they cache ([`PairCache`],
//! [`Neighborhood`]), the two operators of the pressure terms ([`density_rates`] and
//! [`apply_pressure`]), and the check of a step's linearisation ([`unseen_compression`]).

use crate::par::prelude::*;
use glam::Vec2;

use crate::blocked::{ResidualTerms, LANES};
use crate::kernel::Kernel;
use crate::neighbors::NeighborLists;
use crate::particles::{BoundaryParticles, FluidParticles};
use crate::step::StepContext;
pub use crate::step::{Neighborhood, PairCache};

/// Compute `s_i`, the DFSPH factor, and cache all kernel gradients and the per-particle sums
/// of [`PairCache`] (TVCG 2017, Alg. 1 lines 2–3).
///
/// `walls.weight` multiplies the walls' share of the gradient sum and of the wall flux, not of
/// the density ([`BoundaryModel::gradient_weight`](crate::boundary::BoundaryModel)). Each
/// particle's factor is at most `max_factor` (m², see
/// [`SolverSettings::max_factor_ratio`](crate::settings::SolverSettings::max_factor_ratio)).
pub fn density_and_factor(
    kernel: &Kernel,
    volume: f32,
    fluid: &mut FluidParticles,
    fluid_lists: &NeighborLists,
    walls: Walls,
    cache: &mut PairCache,
    max_factor: f32,
) {
    let Walls {
        particles: boundary,
        lists: boundary_lists,
        weight: wall_weight,
    } = walls;
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

/// The walls as [`density_and_factor`] sees them.
#[derive(Clone, Copy)]
pub struct Walls<'a> {
    /// The wall particles.
    pub particles: &'a BoundaryParticles,
    /// Each fluid particle's wall neighbours.
    pub lists: &'a NeighborLists,
    /// The boundary model's [`gradient_weight`](crate::boundary::BoundaryModel::gradient_weight).
    pub weight: f32,
}

/// The DFSPH factor of a particle inside an ideal square lattice of spacing `d` (its gradient
/// sum vanishes by symmetry): `1 / Σ_k |V ∇W(x_k)|²`.
pub fn lattice_factor(kernel: &Kernel, d: f32, volume: f32) -> f32 {
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
/// no source and no increment. (A solve leaves these in
/// `PressureSolver::density_rates`.)
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
/// what the density solve left, `PressureSolver::density_rates`), `dt` is `step.dt`.
pub fn unseen_compression(step: &StepContext, fluid: &FluidParticles, rates: &[f32]) -> f32 {
    let (kernel, volume, dt, nb) = (step.kernel, step.volume, step.dt, &step.nb);
    let boundary = step.boundary;
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::boundary::{AkinciWalls, BoundaryModel};
    use crate::neighbors::Grid;
    use crate::settings::SolverSettings;
    use crate::simd::SimdPath;

    /// Walls weighed as Akinci et al.'s.
    fn akinci_walls<'a>(particles: &'a BoundaryParticles, lists: &'a NeighborLists) -> Walls<'a> {
        Walls {
            particles,
            lists,
            weight: AkinciWalls.gradient_weight(),
        }
    }

    /// A disordered patch of fluid on a floor of wall particles that move, with neighbour
    /// lists and the step's cache, built as the simulation builds them.
    struct Patch {
        kernel: Kernel,
        volume: f32,
        fluid: FluidParticles,
        boundary: BoundaryParticles,
        fluid_lists: NeighborLists,
        boundary_lists: NeighborLists,
        cache: PairCache,
        settings: SolverSettings,
    }

    impl Patch {
        /// The patch as a step of `dt` sees it, with the default scene's settings.
        fn context<'a>(&'a self, nb: Neighborhood<'a>, dt: f32) -> StepContext<'a> {
            StepContext {
                kernel: &self.kernel,
                volume: self.volume,
                spacing: 0.5 * self.kernel.support(),
                dt,
                gravity: Vec2::ZERO,
                settings: &self.settings,
                nb,
                boundary: &self.boundary,
                bodies: None,
                stop: None,
            }
        }
    }

    /// A deterministic jitter in [−0.5, 0.5).
    fn jitter(k: u32) -> f32 {
        let h = k.wrapping_mul(2_654_435_761).rotate_left(13) ^ 0x9e37_79b9;
        (h.wrapping_mul(2_246_822_519) >> 8) as f32 / (1u32 << 24) as f32 - 0.5
    }

    fn patch() -> Patch {
        let d = 0.02f32;
        let kernel = Kernel::cubic_spline(2.0 * d);
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
            boundary.local.push(Vec2::ZERO);
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
            &fluid_lists,
            akinci_walls(&boundary, &boundary_lists),
            &mut cache,
            f32::INFINITY,
        );
        Patch {
            kernel,
            volume,
            fluid,
            boundary,
            fluid_lists,
            boundary_lists,
            cache,
            settings: SolverSettings::from_scene(&crate::scene::Scene::default()),
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
            unseen_compression(&p.context(*nb, dt), &p.fluid, &rates)
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
            &p.fluid_lists,
            akinci_walls(&p.boundary, &p.boundary_lists),
            &mut p.cache,
            f32::INFINITY,
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
                unseen_compression(&p.context(*nb, dt), &p.fluid, &rates).to_bits()
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
            &p.fluid_lists,
            akinci_walls(&p.boundary, &p.boundary_lists),
            &mut portable,
            f32::INFINITY,
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
