//! Every stopping rule and safeguard of a step in one place: [`SolverSettings`], resolved once
//! from the scene's `solver` section (and again when a user changes it) plus the fixed values
//! below, each with the reason for its value.

use crate::scene::Scene;

pub use crate::displacement::MAX_STEP_DISPLACEMENT;

/// Largest Δt·√(p/ρ0)/d, p the hydrostatic pressure at the bottom of the water. Against the
/// pressure of a deep column the symmetric pressure force is a stiff spring on each particle's
/// place in the lattice (its pull grows with p, not with the pressure's gradient), integrated
/// explicitly like any spring: the 400-layer column of `a_deep_narrow_column_stays_at_rest`
/// burst at Δt·√(gH)/d = 0.89 and held still at 0.66, at d = 5 mm and at d = 1 cm alike
/// (docs/deep-columns.md). 0.6 leaves a margin of 1.5; flows rarely meet it, as their CFL
/// step is shorter.
pub const PRESSURE_WAVE_STABILITY: f32 = 0.6;

/// When an iterative solve stops: the average error is within `tolerance_pct`, no particle's
/// error is above `max_error_pct`, and at least `min_iterations` ran; or `max_iterations` ran.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SolveLimits {
    /// Largest average error at exit, percent.
    pub tolerance_pct: f64,
    /// Largest single-particle error accepted at exit, percent. The average alone lets a
    /// local hot spot through: ten particles 3 % compressed move the average of 20,000 by
    /// 0.0015 %, and such a spot, left for the next step, grows.
    pub max_error_pct: f64,
    /// Iterations run whatever the errors say.
    pub min_iterations: u32,
    /// Iterations after which the solve stops whatever the errors say.
    pub max_iterations: u32,
}

impl SolveLimits {
    /// Whether a solve at `iterations` iterations, its average and largest errors `avg_pct`
    /// and `max_pct`, goes on.
    #[inline]
    pub fn unmet(&self, avg_pct: f64, max_pct: f64, iterations: u32) -> bool {
        (avg_pct > self.tolerance_pct
            || max_pct > self.max_error_pct
            || iterations < self.min_iterations)
            && iterations < self.max_iterations
    }
}

/// The stopping rules and safeguards of the solves and of the step, resolved once from the
/// scene ([`Self::from_scene`]); the step reads nothing else to decide when to stop, retry or
/// give up.
#[derive(Clone, Debug, PartialEq)]
pub struct SolverSettings {
    // ---- The solves' stopping rules ----
    /// The density solve (Algorithm 3): the scene's `density_tolerance_pct`, `min_iterations`
    /// and `max_iterations`, and no particle compressed by more than 1 % (the average alone
    /// misses hot spots, see [`SolveLimits::max_error_pct`]).
    pub density: SolveLimits,
    /// The divergence solve (Algorithm 2): the scene's `divergence_tolerance_pct` and the
    /// density solve's iteration bounds; no bound on a single particle (the solve only keeps
    /// the velocity field divergence-free, the density solve guards the compression).
    pub divergence: SolveLimits,
    /// Run the divergence solve (the scene's `divergence_solve`).
    pub divergence_solve: bool,
    /// Start both solves from the previous step's stiffness values (the scene's `warm_start`).
    pub warm_start: bool,
    /// Share of the previous step's stiffness the Jacobi solves start from (dimensionless,
    /// 0.5). A full warm start ratchets: the compression-only solve can add stiffness but never
    /// take back an excess, so the stored pressure creeps upward from step to step.
    pub jacobi_warm_share: f32,
    /// A Jacobi iteration whose average error exceeds this multiple of the previous one (plus
    /// the tolerance) is taken back and ends the solve (dimensionless, 1.5): Jacobi is not
    /// guaranteed to converge (dense clusters, e.g. fluid pulled into a point), and the growth
    /// must not reach the velocities.
    pub diverging_error_growth: f64,
    /// The conjugate-gradient solve leaves at most this share of one step's gravity impulse
    /// `|g|·Δt` uncorrected (root mean square over the particles it solves for;
    /// dimensionless, 0.02). On the built-in `hydrostatic` tank (r = 1 cm) over 20 s, 2 %
    /// keeps the largest speed at 0.020 m/s (1 % of √(gH) is 0.031), 5 % lets it reach 0.042
    /// and 10 % 0.063, for 1–8 % fewer iterations. The bound is absolute (m/s), never relative
    /// to the flow: a rule that also accepted 1 % of the fastest particle's speed let a drop
    /// falling at 3 m/s loosen the solve everywhere, and a pool 300 layers deep 0.2 m from the
    /// drop reached 0.34 m/s before the drop landed (0.020 m/s with this bound alone). It
    /// tightens with the step: `|g|·Δt` falls to 10–100 µm/s in a splash's short steps, where
    /// the solve runs to its cap on this rule alone with every density error 100–1,000 times
    /// inside its tolerance (docs/deep-columns.md).
    pub gravity_impulse_tolerance: f32,
    /// The conjugate-gradient density solve is deflated by aggregates this many kernel
    /// supports wide (`pressure::deflation`; 8, at least 4; 0 turns deflation off). On a
    /// hexagonal dam break of 200 layers (20k particles, 0.3 s, with the velocity bound
    /// floored at 2 mm/s for the comparison) the iterations a step were about the same from 4
    /// to 8 supports (11–12, against 18 without); with the bound as it is, 45.8 against 60.5.
    /// Wider aggregates make a smaller coarse system (docs/deep-columns.md, "Deflation").
    pub coarse_cell_supports: f32,
    /// The conjugate-gradient density solve leaves existing compression up to this share of
    /// the average density tolerance uncorrected (dimensionless, 0.02: 0.001 % of ρ0 at the
    /// default 0.05 %). Removing a compression δ spread over water of depth H within one step
    /// takes a smooth pressure of about ρ0·δ·H²/Δt², which in deep water at the short steps
    /// it needs outgrows the hydrostatic pressure for δ of a few 10⁻⁶, the scatter of the
    /// lattice's own densities: a column 1,000 layers deep (5 m at d = 5 mm) swung its pressure
    /// by 3.6 % of ρ0·g·H in its first step and burst to 98 m/s within 10 ms; with this band
    /// its first step stays within 0.001 % and the column under 0.0096 m/s over 0.5 s
    /// (docs/deep-columns.md, "1,000 layers").
    pub compression_dead_band: f32,

    // ---- The solves' safeguards ----
    /// A particle's DFSPH factor is capped at this multiple of the lattice's
    /// ([`crate::solver::lattice_factor`]; dimensionless, 4). Particles with a full or a
    /// free-surface neighbourhood stay below about 2.5 times it. A droplet with one or two
    /// fluid neighbours pressed into a wall does not: it sits almost on top of a wall
    /// particle, where ∇W vanishes, its boundary gradients nearly cancel, and its factor grows
    /// without bound (200 times the lattice value was seen in `dfsph2d stress`), so that the
    /// wall's few percent of extra density became a kick of thousands of m/s. With the cap
    /// such a particle is pushed out over a few iterations instead of one.
    pub max_factor_ratio: f32,
    /// The fastest a density solve may push particles apart to undo compression that already
    /// exists at the start of a step, m/s (2).
    ///
    /// A well-resolved flow starts each step less than 1 % compressed, and removing that over
    /// one step takes a few cm/s. A user can create far more: a wall drawn over the water,
    /// fluid pulled into a gap narrower than a particle, a pour onto a moving surface. Undoing
    /// a compression δ in one step takes a speed of about δ·d/Δt, which grows as Δt shrinks: a
    /// 30 % overlap undone in a 10 µs step throws particles at hundreds of m/s, the next
    /// step's CFL Δt is smaller still, and the kicks feed on themselves (seen in `dfsph2d
    /// stress`, which ended in particles at 1,900 m/s). Capping the part of the source term
    /// that comes from existing compression spreads such a correction over several steps at
    /// this speed instead; the part from the velocities (`Δt·Dρ/Dt`) is never capped, so the
    /// fluid still cannot compress further.
    pub max_correction_speed: f32,
    /// A particle with fewer neighbours than this (fluid and boundary, itself excluded) takes
    /// no part in the divergence solve (7). Its neighbourhood is too thin for `Dρ/Dt` to mean
    /// anything: a splash droplet grazing a wall would otherwise get a stiffness from a
    /// near-zero gradient sum and kick its few neighbours to hundreds of m/s. Eight is the
    /// count of a full square lattice at support 2d; the free surface (five) is excluded, as
    /// in SPlisHSPlasH's 2D DFSPH.
    pub divergence_min_neighbors: usize,
    /// A particle with fewer neighbours than this (fluid and walls, itself excluded) takes no
    /// part in the conjugate-gradient density solve (5): its density rate means nothing (a
    /// splash droplet).
    pub conjugate_gradient_min_neighbors: usize,

    // ---- The step's safeguards: retries of unsound steps ----
    /// A density solve that reaches its iteration cap with a particle compressed by more than
    /// this, percent (5), makes the step unsound (it is redone with half the Δt). A solve
    /// that is merely slow to converge (a deep column building up its pressure) is not: a
    /// smaller Δt cannot help it.
    pub retry_density_error_pct: f64,
    /// A step that would leave a particle compressed by more than this, percent, beyond what
    /// the density solve predicted is redone with half the Δt (see
    /// `solver::unseen_compression`). The same bound as the density solve's
    /// [`SolveLimits::max_error_pct`] (1 %): the solve's promise must hold for the positions
    /// the step really produces.
    pub max_unseen_compression_pct: f64,
    /// A step is redone for its unseen compression only while each halving of Δt cuts it
    /// below this share of the attempt before (dimensionless, 0.75; a purely second-order
    /// error would fall to a quarter). In the 80k dam break at Δt = 5 ms: 2.92 % at 2.5 ms,
    /// 1.92 % at 1.25 ms, then 1.64, 1.44 and 1.35 % down to 0.16 ms: the later halvings only
    /// cost solves.
    pub unseen_retry_gain: f64,
    /// Largest displacement in one step, in particle spacings ([`MAX_STEP_DISPLACEMENT`],
    /// whose note gives the reason).
    pub max_step_displacement: f32,
    /// How often one step may be redone with half the time step before it is taken as it is
    /// (4: Δt/16, after which the least bad attempt is taken).
    pub max_step_retries: u32,
    /// After a step was redone, each following step may be this much longer than the one
    /// before until the CFL step takes over again (dimensionless, 1.2). It spares the
    /// following steps from failing at the same length first.
    pub retry_limit_growth: f32,

    // ---- The step's safeguards: bounds on Δt besides CFL ----
    /// Largest Δt·ν/d² of the explicit Laplacian viscosity (dimensionless, 0.125; Morris et
    /// al. 1997: Δt ≤ 0.125 h²/ν). Without it a tank at rest with ν = 0.1 m²/s, d = 2 cm and
    /// Δt = 2.5 ms (five times over) reached 16 m/s within 50 steps.
    pub viscous_stability: f32,
    /// Largest Δt·√(p/ρ0)/d at the bottom of the water ([`PRESSURE_WAVE_STABILITY`], whose
    /// note gives the reason).
    pub pressure_wave_stability: f32,
}

impl SolverSettings {
    /// The scene's `solver` section, completed with the fixed safeguards above.
    pub fn from_scene(scene: &Scene) -> Self {
        let s = &scene.solver;
        let density = SolveLimits {
            tolerance_pct: s.density_tolerance_pct,
            max_error_pct: 1.0,
            min_iterations: s.min_iterations,
            max_iterations: s.max_iterations,
        };
        Self {
            density,
            divergence: SolveLimits {
                tolerance_pct: s.divergence_tolerance_pct,
                max_error_pct: f64::INFINITY,
                ..density
            },
            divergence_solve: s.divergence_solve,
            warm_start: s.warm_start,
            jacobi_warm_share: 0.5,
            diverging_error_growth: 1.5,
            gravity_impulse_tolerance: 0.02,
            coarse_cell_supports: 8.0,
            compression_dead_band: 0.02,
            max_factor_ratio: 4.0,
            max_correction_speed: 2.0,
            divergence_min_neighbors: 7,
            conjugate_gradient_min_neighbors: 5,
            retry_density_error_pct: 5.0,
            max_unseen_compression_pct: density.max_error_pct,
            unseen_retry_gain: 0.75,
            max_step_displacement: MAX_STEP_DISPLACEMENT,
            max_step_retries: 4,
            retry_limit_growth: 1.2,
            viscous_stability: 0.125,
            pressure_wave_stability: PRESSURE_WAVE_STABILITY,
        }
    }

    /// The largest existing relative compression one step of length `dt` (s) removes, for
    /// particle spacing `d` (m): a correction of that size moves particles apart at about
    /// [`Self::max_correction_speed`].
    pub fn max_compression_correction(&self, dt: f32, d: f32) -> f32 {
        self.max_correction_speed * dt / d
    }
}
