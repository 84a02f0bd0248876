//! The simulation: owns the particle state, runs one DFSPH (or WCSPH) step at a time with CFL
//! time stepping, and reports diagnostics for every step.

use crate::par::{self, prelude::*};
use crate::parallel::{self, LIGHT_PASS_MIN_ITEMS};
use glam::Vec2;
use serde::Serialize;
use web_time::Instant;

use crate::boundary::{self, Body, BodyId, BoundaryModel, BoundarySamples};
use crate::forces::{self, PointerForce};
use crate::kernel::Kernel;
use crate::memory::MemoryLimits;
use crate::neighbors::{Grid, NeighborLists};
use crate::packing;
use crate::particles::{BoundaryParticles, FluidParticles, Scratch};
use crate::pressure::{self, PressureSolver, SolveReport};
use crate::retry::{AttemptCheck, Attempts, DensityStep};
use crate::rigid::coupling::{self, WallTerms};
use crate::rigid::{BodySpec, BodyVelocity, CoupledBodies, RigidBodies, RigidBodyState};
use crate::scene::{Method, Obstacle, Packing, PressureSolve, Scene, SceneError};
use crate::settings::SolverSettings;
use crate::solver::{self, Neighborhood, PairCache, Walls};
use crate::step::StepContext;
use crate::viscosity::Viscosity;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

pub use crate::displacement::{step_displacement_bound, MAX_STEP_DISPLACEMENT};
pub use crate::settings::PRESSURE_WAVE_STABILITY;

/// Diagnostics of one step.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct StepStats {
    /// Steps taken so far, this one included.
    pub step: u64,
    /// Simulated time at the end of the step, s.
    pub time: f64,
    /// The step's Δt, s.
    pub dt: f64,
    /// Fluid particles.
    pub n_fluid: usize,
    /// Boundary particles.
    pub n_boundary: usize,
    /// Iterations of the density solve (0 for WCSPH).
    pub density_iterations: u32,
    /// Iterations of the divergence solve (0 when it is off, and for WCSPH).
    pub divergence_iterations: u32,
    /// Average relative compression at the end of the density solve, percent (WCSPH: of the
    /// densities).
    pub avg_density_error_pct: f64,
    /// Largest single-particle compression, percent.
    pub max_density_error_pct: f64,
    /// Average relative density change per step left by the divergence solve, percent.
    pub divergence_error_pct: f64,
    /// Largest fluid speed after the step, m/s.
    pub max_speed: f64,
    /// Kinetic energy per metre of depth, J/m (2D).
    pub kinetic_energy: f64,
    /// Particles that left the tank this step and were put back: each one means the wall
    /// leaked. Should stay 0.
    pub clamped: u32,
    /// Particles whose position or velocity became NaN or infinite this step and were put
    /// back at rest. Should stay 0.
    pub non_finite: u32,
    /// Average neighbour count (fluid and boundary) per fluid particle.
    pub avg_neighbors: f64,
    /// Times this step was redone with half the time step because the try was unsound (a
    /// density solve at its iteration cap leaving a particle more than 5 % compressed, a
    /// non-finite velocity, or a particle about to jump more than a particle spacing). When
    /// every try is unsound the least bad is taken (`retry`). `dt` is the one finally taken.
    pub retries: u32,
}

/// The length in seconds that a step of `dt` (single precision, as the solver takes it) stands
/// for: the shortest decimal that reads back as `dt`. The 1 ms step is the `f32`
/// 0.0010000000474974513; it stands for 0.001, and the clock, which sums these in double
/// precision, reads 0.1 after a hundred such steps instead of 0.10000000474974513. The two
/// differ by less than half a unit in the last place of `dt`, below what the step itself
/// resolves.
pub fn step_seconds(dt: f32) -> f64 {
    // Rust prints the shortest decimal that reads back as the same f32; parsing it as f64 is
    // exact to the last bit and the same on every platform (the replays' fingerprints).
    dt.to_string().parse().unwrap_or(dt as f64)
}

/// Has a step of length `dt` (s) that ended at `time` reached `target`? Yes when it ended
/// at `target`, past it, or short of it by at most 1 % of its length: the clock sums steps
/// in double precision, so 0.02 s = 4 × 0.005 s may end a hair short and must not be taken
/// one step late. [`Simulation::has_reached`] for the last step; the command line's
/// snapshot schedule for each step it writes after.
pub fn reached(time: f64, dt: f64, target: f64) -> bool {
    time + 0.01 * dt >= target
}

/// Which of a step's terms [`Simulation::rigid_body_impulses`] sums.
#[derive(Clone, Copy, Debug)]
enum Terms {
    /// The mirrored walls' hydrostatic ghosts' (part of the non-pressure forces).
    Ghosts,
    /// Both solves' and the ghosts'.
    All,
}

/// The state of one running scene.
pub struct Simulation {
    pub(crate) scene: Scene,
    /// Set from outside to end the conjugate-gradient solves early ([`Self::set_stop_flag`]).
    pub(crate) stop_flag: Option<Arc<AtomicBool>>,
    /// The user's own memory limit, bytes, and its name (`--max-memory`, Python's `max_memory`), applied
    /// again when an action resets the simulation to another scene.
    pub(crate) max_memory: Option<(u64, &'static str)>,
    pub(crate) kernel: Kernel,
    /// Lattice spacing d, m.
    pub(crate) spacing: f32,
    /// Volume of one fluid particle V = m/ρ0, m² (chosen so the initial lattice is at ρ0).
    pub(crate) volume: f32,
    /// [`packing::gradient_consistency`] of the scene's lattice: the pressure force of a field
    /// p is that of c·p, so the conjugate-gradient solve stores c times its stiffness field as
    /// the physical pressure.
    gradient_consistency: f32,
    pub(crate) gravity: Vec2,
    pub(crate) fluid: FluidParticles,
    pub(crate) boundary: BoundaryParticles,
    /// Body 0 is the tank.
    pub(crate) bodies: Vec<Body>,
    /// The polylines of the walls drawn since the start ([`crate::Action::AddWall`]), as
    /// drawn: the bodies after the scene's obstacles, in order. A saved state writes them back
    /// as obstacles ([`Self::to_scene`]).
    pub(crate) drawn_walls: Vec<Vec<Vec2>>,
    /// How far the tank's first wall layer lies outside its interior, below and left of it
    /// and above and right of it, m ([`Self::tank_containment`]).
    tank_wall_margins: (Vec2, Vec2),
    /// γ of [`boundary::wall_volume_correction`].
    wall_gamma: f32,
    /// Cap on the DFSPH factor ([`SolverSettings::max_factor_ratio`] × the lattice factor).
    max_factor: f32,
    /// The stopping rules and safeguards, resolved from the scene ([`Self::resolve_scene`]).
    settings: SolverSettings,
    /// The pressure solver the scene names, with its scratch arrays.
    pressure: Box<dyn PressureSolver>,
    /// The viscosity models of the scene.
    viscosity: Viscosity,
    /// Boundary particles were added or removed: recompute volumes.
    pub(crate) boundary_changed: bool,
    /// The boundary grid was built for the wall positions as they stand and for this many
    /// fluid particles (its dense-cell floor): while both hold, it is not rebuilt.
    boundary_grid_for: Option<usize>,
    fluid_grid: Grid,
    boundary_grid: Grid,
    fluid_lists: NeighborLists,
    boundary_lists: NeighborLists,
    pair_cache: PairCache,
    scratch: Scratch,
    pub(crate) time: f64,
    pub(crate) step_count: u64,
    /// Δt of the previous step (the divergence solve measures its error over it).
    last_dt: f32,
    /// Upper bound on Δt after a step had to be redone: the Δt it was accepted at, grown by
    /// [`SolverSettings::retry_limit_growth`] per step until the CFL step is the smaller again (infinite
    /// then). It spares the following steps from failing at the same length first.
    retry_dt_limit: f32,
    /// Velocities and pressures after the divergence solve, to redo the rest of a step.
    retry_velocity: Vec<Vec2>,
    retry_pressure: Vec<f32>,
    pub(crate) next_id: u32,
    stats: StepStats,
    total_clamped: u64,
    total_non_finite: u64,
    pub(crate) pointer: Option<PointerForce>,
    /// Shaking: −1 (left) … 1 (right), held until changed.
    pub(crate) shake_drive: f32,
    /// When the last [`Self::step`] returned.
    last_step_end: Option<Instant>,
    /// The rigid bodies and their world, from the first body on.
    pub(crate) rigid: Option<RigidBodies>,
    /// Fluid removed and boundary particles added by the last [`crate::Action::AddBody`].
    pub(crate) last_body_change: (usize, usize),
    /// The obstacles or drawn walls changed since the rigid bodies were last told where they
    /// are ([`RigidBodies::set_walls`]).
    pub(crate) walls_moved_for_bodies: bool,
    /// The free rigid bodies the water touches in this step, which move inside its solves
    /// ([`crate::rigid::coupled`]), and the walls' share of the density rate at their
    /// velocities as the step began.
    coupled: Option<CoupledBodies>,
    wall_flux_at_start: Vec<f32>,
    /// The moving bodies' velocity change as the density solve of the attempt at hand began
    /// ([`Self::predict_rigid_bodies`]).
    rigid_predicted: Vec<BodyVelocity>,
}

/// Particle data in creation order, for output.
#[derive(Clone, Debug, Default)]
pub struct Snapshot {
    pub time: f64,
    pub id: Vec<u32>,
    pub position: Vec<Vec2>,
    pub velocity: Vec<Vec2>,
    /// kg/m³.
    pub density: Vec<f32>,
    /// Pa: [`Simulation::interpolated_pressures_over_rho0`] times ρ0.
    pub pressure: Vec<f32>,
}

impl Simulation {
    /// Build the initial state: fluid lattices, boundary particles with their volumes, and the
    /// particle mass that puts an interior lattice particle exactly at ρ0. A scene that needs
    /// more memory than this process may use ([`MemoryLimits::of_this_process`]) is refused
    /// with [`SceneError::Memory`] before anything large is allocated: every door that builds
    /// a simulation (the command line, the viewer's Open, a recording's reset, the page's
    /// links, Python) gets the same check and the same sentence.
    pub fn new(scene: &Scene) -> Result<Self, SceneError> {
        Self::new_within(scene, &MemoryLimits::of_this_process(None))
    }

    /// A flag that, once set (a signal handler's, for Ctrl-C), makes the pressure solves
    /// (conjugate gradients and Jacobi, density and divergence) end at their next iteration:
    /// a deep scene's step, whose solve may run to thousands of iterations, then ends within
    /// one and the caller can stop after it. The step so ended is not converged; a caller
    /// that goes on stepping should clear the flag first. (The Jacobi solve runs in lockstep
    /// across threads: one member reads the flag for all, so that all leave together.)
    pub fn set_stop_flag(&mut self, flag: Arc<AtomicBool>) {
        self.stop_flag = Some(flag);
    }

    /// [`Self::new`] within `limits` (e.g. with a user's `--max-memory`).
    pub fn new_within(scene: &Scene, limits: &MemoryLimits) -> Result<Self, SceneError> {
        scene.validate()?;
        limits
            .check(&scene.memory_estimate())
            .map_err(SceneError::Memory)?;
        let d = scene.spacing() as f32;
        let kernel = scene.kernel();
        let hexagonal = scene.packing == Packing::Hexagonal;
        let volume = 1.0
            / if hexagonal {
                packing::kernel_sum(&kernel, d)
            } else {
                lattice_kernel_sum(&kernel, d)
            };
        let gradient_consistency = if hexagonal {
            packing::hexagonal_gradient_consistency(&kernel, d, volume)
        } else {
            packing::square_gradient_consistency(&kernel, d, volume)
        };
        let settings = SolverSettings::from_scene(scene);
        let mut sim = Simulation {
            scene: scene.clone(),
            max_memory: limits.user(),
            stop_flag: None,
            kernel,
            spacing: d,
            volume,
            gradient_consistency,
            gravity: to_vec2(scene.gravity),
            fluid: FluidParticles::default(),
            boundary: BoundaryParticles::default(),
            bodies: Vec::new(),
            drawn_walls: Vec::new(),
            tank_wall_margins: (Vec2::ZERO, Vec2::ZERO),
            wall_gamma: boundary::wall_volume_correction(&kernel, d),
            max_factor: settings.max_factor_ratio * solver::lattice_factor(&kernel, d, volume),
            settings,
            pressure: pressure::for_scene(scene, gradient_consistency),
            viscosity: Viscosity::from_scene(&scene.viscosity),
            boundary_changed: true,
            boundary_grid_for: None,
            fluid_grid: Grid::new(kernel.support()),
            boundary_grid: Grid::new(kernel.support()),
            fluid_lists: NeighborLists::default(),
            boundary_lists: NeighborLists::default(),
            pair_cache: PairCache::default(),
            scratch: Scratch::default(),
            time: 0.0,
            step_count: 0,
            last_dt: scene.time_step.max as f32,
            retry_dt_limit: f32::INFINITY,
            retry_velocity: Vec::new(),
            retry_pressure: Vec::new(),
            next_id: 0,
            stats: StepStats::default(),
            total_clamped: 0,
            total_non_finite: 0,
            pointer: None,
            last_step_end: None,
            shake_drive: 0.0,
            rigid: None,
            last_body_change: (0, 0),
            walls_moved_for_bodies: true,
            coupled: None,
            wall_flux_at_start: Vec::new(),
            rigid_predicted: Vec::new(),
        };
        let mut samples = BoundarySamples::new(boundary::wall_layers(&kernel, d));
        if hexagonal {
            samples.add_hexagonal_tank(scene.tank.min, scene.tank.max, scene.spacing(), 0);
        } else {
            samples.add_tank(to_vec2(scene.tank.min), to_vec2(scene.tank.max), d, 0);
        }
        sim.bodies.push(Body::default());
        let tank_samples = samples.positions.len();
        sim.tank_wall_margins = boundary::first_layer_margins(
            &samples.positions,
            to_vec2(scene.tank.min),
            to_vec2(scene.tank.max),
            d,
        );
        for obstacle in &scene.obstacles {
            let body = sim.bodies.len() as BodyId;
            sim.bodies.push(Body::default());
            samples.add_obstacle(obstacle, d, scene.hexagonal_anchor(), body);
        }
        samples.merge_close(boundary::MERGE_DISTANCE * d);
        for spec in &scene.bodies {
            sim.add_rigid_body(spec);
        }
        // Lattice sites the obstacles cover stay empty: inside a solid box, or closer than one
        // spacing to an obstacle's wall particles (the rule for walls drawn over water, see
        // `add_wall`). Fluid there would start crushed into the wall.
        let mut obstacle_grid = Grid::new(d);
        obstacle_grid.build(&samples.positions[tank_samples..]);
        // Taken out while the fluid is placed, put back after.
        let bodies = sim.rigid.take();
        let covered = |p: Vec2| {
            let inside_box = scene.obstacles.iter().any(|o| match o {
                Obstacle::Rect { min, max } => {
                    p.cmpge(to_vec2(*min)).all() && p.cmple(to_vec2(*max)).all()
                }
                Obstacle::Polyline { .. } | Obstacle::Particles { .. } => false,
            });
            inside_box
                || obstacle_grid.any_near(p)
                || bodies.as_ref().is_some_and(|r| r.covers(p, d))
        };
        sim.fluid.reserve(scene.fluid_particle_count());
        let mut covered_sites = 0usize;
        let hexagonal_rows = if hexagonal {
            packing::rows_of_boxes(
                scene.tank.min,
                &scene.fluid_boxes(),
                scene.spacing(),
                scene.tank.edge_tolerance(),
            )
        } else {
            Vec::new()
        };
        for &(block, row) in &hexagonal_rows {
            let v = to_vec2(scene.fluid[block].velocity);
            for p in packing::row_sites(row, scene.spacing()) {
                if covered(p) {
                    covered_sites += 1;
                } else {
                    let id = sim.next_id;
                    sim.next_id += 1;
                    sim.fluid.push(p, v, id);
                }
            }
        }
        for block in scene.fluid.iter().filter(|_| !hexagonal) {
            let nx = scene.lattice_count(block.max[0] - block.min[0]);
            let ny = scene.lattice_count(block.max[1] - block.min[1]);
            let v = to_vec2(block.velocity);
            for j in 0..ny {
                for i in 0..nx {
                    // Lattice sites in f64, so long blocks stay exactly periodic.
                    let x = block.min[0] + (i as f64 + 0.5) * scene.spacing();
                    let y = block.min[1] + (j as f64 + 0.5) * scene.spacing();
                    let p = Vec2::new(x as f32, y as f32);
                    if covered(p) {
                        covered_sites += 1;
                        continue;
                    }
                    let id = sim.next_id;
                    sim.next_id += 1;
                    sim.fluid.push(p, v, id);
                }
            }
        }
        // Listed particles go exactly where the scene puts them, next to walls included: they
        // are a state saved while the water pressed against them.
        for (i, &p) in scene.particles.positions.iter().enumerate() {
            let id = sim.next_id;
            sim.next_id += 1;
            sim.fluid
                .push(to_vec2(p), to_vec2(scene.particles.velocity(i)), id);
        }
        if sim.fluid.is_empty() && covered_sites > 0 {
            return Err(crate::scene::invalid(
                "fluid",
                "every lattice site of the fluid blocks lies inside an obstacle or a body, or \
                 within a particle spacing of one: the scene would start without water",
            ));
        }
        sim.rigid = bodies;
        sim.add_boundary_samples(samples);
        if let Some(p) = sim
            .pressure
            .initial_pressure(&sim.fluid.position, sim.gravity, d)
        {
            sim.fluid.pressure_over_rho0 = p;
        }
        sim.update_neighborhoods();
        // Before the first step the diagnostics hold the particle counts (a replay of a
        // header alone, or Python's `step(0)`, reports the water it has, not none).
        sim.stats.n_fluid = sim.fluid.len();
        sim.stats.n_boundary = sim.boundary.len();
        Ok(sim)
    }

    /// Add a rigid body (validated) with its boundary particles; returns its index. Fluid it
    /// covers is left to the caller.
    pub(crate) fn add_rigid_body(&mut self, spec: &BodySpec) -> usize {
        let (lo, hi) = (to_vec2(self.scene.tank.min), to_vec2(self.scene.tank.max));
        let rigid = self
            .rigid
            .get_or_insert_with(|| RigidBodies::new(lo, hi, self.gravity));
        let body_id = self.bodies.len() as BodyId;
        let tank = self.bodies[0];
        let (k, local, volume) = rigid.add(spec, tank.offset, self.spacing, &self.kernel);
        self.bodies.push(Body {
            rigid: Some(k as u16),
            ..Default::default()
        });
        for (q, v) in local.into_iter().zip(volume) {
            let (x, u) = rigid.point_motion(k, q);
            self.boundary.position.push(x);
            self.boundary.velocity.push(u);
            self.boundary.volume.push(v);
            self.boundary.body.push(body_id);
            self.boundary.local.push(q);
        }
        self.boundary_changed = true;
        k
    }

    pub(crate) fn add_boundary_samples(&mut self, samples: BoundarySamples) {
        let cell = self.spacing * self.spacing;
        let n = samples.positions.len();
        self.boundary.position.reserve_exact(n);
        self.boundary.velocity.reserve_exact(n);
        self.boundary.volume.reserve_exact(n);
        self.boundary.body.reserve_exact(n);
        self.boundary.local.reserve_exact(n);
        for ((p, b), area) in samples
            .positions
            .into_iter()
            .zip(samples.bodies)
            .zip(samples.lattice_area)
        {
            self.boundary.position.push(p);
            self.boundary
                .velocity
                .push(self.bodies[b as usize].velocity);
            // Lattice walls carry their volume; 0 asks for Akinci's estimate.
            self.boundary
                .volume
                .push(area.map_or(0.0, |a| self.volume * a / cell));
            self.boundary.body.push(b);
            self.boundary.local.push(Vec2::ZERO);
        }
        self.boundary_changed = true;
    }

    /// The stopping rules and safeguards, the pressure solver and the viscosity models of the
    /// scene as it stands: resolved when the simulation is built, and again whenever an action
    /// changes the scene's parameters.
    pub(crate) fn resolve_scene(&mut self) {
        self.settings = SolverSettings::from_scene(&self.scene);
        self.pressure = pressure::for_scene(&self.scene, self.gradient_consistency);
        self.viscosity = Viscosity::from_scene(&self.scene.viscosity);
    }

    /// How the walls take part in the pressure terms (the pressure solver's choice).
    pub(crate) fn boundary_model(&self) -> &'static dyn BoundaryModel {
        self.pressure.walls()
    }

    /// Whether the density solve is [`PressureSolve::ConjugateGradient`] (with its mirrored,
    /// hydrostatic walls), rather than the paper's Jacobi iteration with Akinci walls.
    pub fn conjugate_gradient(&self) -> bool {
        let solver = &self.scene.solver;
        solver.method == Method::Dfsph && solver.pressure_solve == PressureSolve::ConjugateGradient
    }

    /// Sort both particle sets, rebuild neighbour lists, densities and factors.
    fn update_neighborhoods(&mut self) {
        // Walls that have not moved since the last build are already sorted, and their grid
        // still holds: rebuilding would give the identity order (the sort is stable) and the
        // same cells. Shaking, drawing or erasing walls, and a change in the fluid count
        // (pouring, which sets the dense-cell floor) rebuild it.
        let n_fluid = self.fluid.position.len();
        if self.boundary_changed || self.boundary_grid_for != Some(n_fluid) {
            self.boundary_grid.set_dense_cells_floor(4 * n_fluid);
            let order = self.boundary_grid.build(&self.boundary.position).to_vec();
            self.boundary.permute(&order, &mut self.scratch);
            self.boundary_grid_for = Some(n_fluid);
        }
        if self.boundary_changed {
            boundary::volumes(
                &self.boundary_grid,
                &self.kernel,
                self.wall_gamma,
                &mut self.boundary.volume,
            );
            self.boundary_changed = false;
        }
        let order = self.fluid_grid.build(&self.fluid.position);
        self.fluid.permute(order, &mut self.scratch);
        for v in [&mut self.fluid.density_ratio, &mut self.fluid.factor] {
            v.resize(self.fluid.position.len(), 0.0);
        }
        self.fluid
            .acceleration
            .resize(self.fluid.position.len(), Vec2::ZERO);
        self.fluid_grid
            .neighbor_lists(&self.fluid.position, true, &mut self.fluid_lists);
        self.boundary_grid
            .neighbor_lists(&self.fluid.position, false, &mut self.boundary_lists);
        let walls = Walls {
            particles: &self.boundary,
            lists: &self.boundary_lists,
            weight: self.pressure.walls().gradient_weight(),
        };
        solver::density_and_factor(
            &self.kernel,
            self.volume,
            &mut self.fluid,
            &self.fluid_lists,
            walls,
            &mut self.pair_cache,
            self.max_factor,
        );
    }

    /// What the passes of a step of `dt` read, and the fluid and the pressure solver they work
    /// on.
    fn step_parts(
        &mut self,
        dt: f32,
    ) -> (
        StepContext<'_>,
        &mut FluidParticles,
        &mut dyn PressureSolver,
    ) {
        let step = StepContext {
            kernel: &self.kernel,
            volume: self.volume,
            spacing: self.spacing,
            dt,
            gravity: self.gravity,
            settings: &self.settings,
            nb: Neighborhood::new(&self.fluid_lists, &self.boundary_lists, &self.pair_cache),
            boundary: &self.boundary,
            bodies: self.coupled.as_ref().filter(|c| !c.is_empty()),
            stop: self.stop_flag.as_deref(),
        };
        (step, &mut self.fluid, self.pressure.as_mut())
    }

    /// Advance by one time step (TVCG 2017, Algorithm 1, arranged so that a step starts from
    /// fresh neighbourhoods): neighbourhoods → densities and factors → divergence solve →
    /// non-pressure forces → CFL Δt → predicted velocities → density solve → advection.
    ///
    /// Called from outside rayon's pool, the step runs on one of its workers (one hand-off per
    /// step). Otherwise every one of the step's parallel passes, some fifty, would be handed
    /// to the pool from this thread, which then sleeps until the pass ends: a futex wait and
    /// wake per pass, which on a 2-core virtual machine took half the wall time of a
    /// 5,000-particle dam break. When steps follow each other closely (a batch run, the
    /// viewer's steps within a frame), the pool's other workers stand by for the whole step
    /// (`parallel::with_workers_at_hand`) rather than falling asleep between passes, unless
    /// another step (of another simulation, on another thread) is in progress meanwhile
    /// (`parallel::alone_in_flight`).
    pub fn step(&mut self) -> &StepStats {
        let back_to_back = self
            .last_step_end
            .is_some_and(|end| end.elapsed() < parallel::WORKERS_STILL_POLLING);
        let (_in_flight, alone) = parallel::alone_in_flight();
        if par::current_thread_index().is_some() {
            self.advance();
        } else if back_to_back && alone && par::current_num_threads() > 1 {
            parallel::with_workers_at_hand(|| self.advance());
        } else {
            par::on_a_worker(|| self.advance());
        }
        self.last_step_end = Some(Instant::now());
        &self.stats
    }

    /// [`Self::step`]'s work, on the current thread: Algorithm 1 of Bender & Koschier (TVCG
    /// 2017), its lines 11–14 moved to the start so that a step starts from fresh
    /// neighbourhoods.
    fn advance(&mut self) {
        // Lines 11–13: move the walls, sort the fluid by cell, find the neighbourhoods, and
        // compute the densities ρ_i and the factors α_i.
        self.update_body_motion();
        self.update_neighborhoods();
        self.couple_rigid_bodies();
        // Line 14, Algorithm 2: make the velocity field divergence-free, its error measured
        // over the previous step.
        let divergence = if self.settings.divergence_solve {
            let (step, fluid, pressure) = self.step_parts(self.last_dt);
            pressure.divergence_solve(&step, fluid)
        } else {
            SolveReport::default()
        };
        // What the divergence solve gave the free rigid bodies.
        let after_divergence = match (&self.coupled, self.settings.divergence_solve) {
            (Some(coupled), true) => coupled.velocity_change(&self.fluid.divergence_stiffness),
            (Some(coupled), false) => vec![BodyVelocity::default(); coupled.bodies()],
            (None, _) => Vec::new(),
        };
        // Line 7: Δt from the CFL condition and the stability bounds, no longer than a
        // recent retry allows.
        let cfl_dt = self.cfl_time_step();
        // Lines 6, 8 and 9, Algorithm 3: non-pressure forces, predicted velocities and the
        // density solve, redone with half the Δt while the step is unsound.
        let density =
            self.density_solve_until_sound(cfl_dt.min(self.retry_dt_limit), &after_divergence);
        // The rigid bodies take what their walls gave the fluid in both solves, and move.
        let impulses = self.rigid_body_impulses(density.dt, Terms::All);
        self.move_rigid_bodies(density.dt, &impulses);
        // Line 10: advect (and move the walls); put back what left the tank or entered a
        // body.
        self.advect(density.dt);
        let (clamped, non_finite) = self.enforce_tank();
        let clamped = clamped + self.enforce_rigid_bodies();
        self.record_statistics(cfl_dt, &density, &divergence, (clamped, non_finite));
    }

    /// Lines 6, 8 and 9 of Algorithm 1 for a step of `dt`: the non-pressure forces, the
    /// predicted velocities and the density solve. An unsound attempt is redone from the
    /// divergence-free velocities with a shorter Δt ([`Attempts`]); the attempt taken is
    /// returned.
    ///
    /// `after_divergence` is what the divergence solve gave each free rigid body: with it,
    /// gravity and the walls' ghosts, the density solve starts from the bodies' predicted
    /// velocities, as the water's.
    fn density_solve_until_sound(
        &mut self,
        dt: f32,
        after_divergence: &[BodyVelocity],
    ) -> DensityStep {
        let mut attempts = Attempts::new(dt, self.scene.time_step.min as f32);
        self.retry_velocity.clone_from(&self.fluid.velocity);
        self.retry_pressure
            .clone_from(&self.fluid.pressure_over_rho0);
        loop {
            let dt = attempts.dt;
            self.predict_velocities(dt);
            self.predict_rigid_bodies(dt, after_divergence);
            let (step, fluid, pressure) = self.step_parts(dt);
            let report = pressure.density_solve(&step, fluid);
            // The check advects the bodies' walls as the solves moved them.
            self.move_rigid_walls_as_solved(dt);
            let (step, fluid, pressure) = self.step_parts(dt);
            if attempts.is_last()
                || !attempts.redo(
                    &AttemptCheck::of(&step, &report, pressure, fluid),
                    step.settings,
                )
            {
                let retries = attempts.retries;
                return DensityStep {
                    dt,
                    report,
                    retries,
                };
            }
            // Redo the step from the divergence-free velocities (and the bodies' walls from
            // their velocities as the step began).
            self.place_rigid_particles();
            self.fluid.velocity.clone_from(&self.retry_velocity);
            self.fluid
                .pressure_over_rho0
                .clone_from(&self.retry_pressure);
        }
    }

    /// Lines 6 and 8 of Algorithm 1: the non-pressure accelerations a (gravity, viscosity,
    /// the walls' hydrostatic ghosts, the pointer) and the predicted velocities `v* = v + Δt·a`.
    fn predict_velocities(&mut self, dt: f32) {
        // The walls' ghosts continue the solve's stiffness field, whose slope at rest is g/c
        // (see `gradient_consistency`).
        let ghost_slope = self
            .pressure
            .walls()
            .hydrostatic_ghost_gradient(self.gravity)
            .map(|g| g / self.gradient_consistency);
        let (viscosity, pointer) = (self.viscosity, self.pointer);
        let (step, fluid, _) = self.step_parts(dt);
        forces::non_pressure_accelerations(&step, &viscosity, pointer, ghost_slope, fluid);
        fluid
            .velocity
            .par_iter_mut()
            .zip(fluid.acceleration.par_iter())
            .with_min_len(LIGHT_PASS_MIN_ITEMS)
            .for_each(|(v, &a)| *v += dt * a);
    }

    /// Line 10 of Algorithm 1: `x += Δt·v`; the walls move with their bodies.
    fn advect(&mut self, dt: f32) {
        self.fluid
            .position
            .par_iter_mut()
            .zip(self.fluid.velocity.par_iter())
            .with_min_len(LIGHT_PASS_MIN_ITEMS)
            .for_each(|(x, &v)| *x += dt * v);
        self.move_bodies(dt);
    }

    /// Close the step taken (`density`, after the divergence solve's report `divergence`,
    /// with `cfl_dt` the CFL step and `(clamped, non_finite)` what [`Self::enforce_tank`] put
    /// back): advance the clock, relax the bound a retry set on Δt, and fill [`StepStats`].
    fn record_statistics(
        &mut self,
        cfl_dt: f32,
        density: &DensityStep,
        divergence: &SolveReport,
        (clamped, non_finite): (u32, u32),
    ) {
        let dt = density.dt;
        let avg_neighbors = if self.fluid.is_empty() {
            0.0
        } else {
            (self.fluid_lists.pair_count() + self.boundary_lists.pair_count()) as f64
                / self.fluid.len() as f64
        };
        self.time += step_seconds(dt);
        self.step_count += 1;
        self.last_dt = dt;
        let growth = self.settings.retry_limit_growth;
        self.retry_dt_limit = if density.retries > 0 {
            dt
        } else if self.retry_dt_limit * growth >= cfl_dt {
            f32::INFINITY
        } else {
            self.retry_dt_limit * growth
        };
        self.total_clamped += clamped as u64;
        self.total_non_finite += non_finite as u64;
        let (max_speed, kinetic_energy) = self.speed_and_energy();
        self.stats = StepStats {
            step: self.step_count,
            time: self.time,
            dt: step_seconds(dt),
            n_fluid: self.fluid.len(),
            n_boundary: self.boundary.len(),
            density_iterations: density.report.iterations,
            divergence_iterations: divergence.iterations,
            avg_density_error_pct: density.report.avg_error_pct,
            max_density_error_pct: density.report.max_error_pct,
            divergence_error_pct: divergence.avg_error_pct,
            max_speed,
            kinetic_energy,
            clamped,
            non_finite,
            avg_neighbors,
            retries: density.retries,
        };
    }

    /// The Δt the next step starts from: the CFL step and its bounds (gravity, the
    /// viscosity's stability limit, deep water, `time_step`), before any retry shortens it.
    pub fn next_time_step(&self) -> f32 {
        self.cfl_time_step()
    }

    /// The pressure's bound on Δt, `pressure_wave_stability·d/√(|g|·D)`, D the fluid's extent
    /// along gravity: the hydrostatic pressure at the bottom of the deepest water there can
    /// be. It stays put while water rests. A bound on the solved pressure's maximum followed
    /// its jitter of a few percent from step to step, and a column at rest under a Δt that
    /// varies that much sloshed (the 400-layer column at 0.06 m/s, against 0.006 m/s under a
    /// fixed Δt of the same length). Pressure peaks of impacts are brief and come with
    /// speeds whose CFL step is shorter anyway.
    fn pressure_wave_time_step(&self) -> f32 {
        let g = self.gravity.length();
        if g == 0.0 || self.fluid.is_empty() {
            return f32::INFINITY;
        }
        let down = self.gravity / g;
        let (lo, hi) = self
            .fluid
            .position
            .par_iter()
            .with_min_len(LIGHT_PASS_MIN_ITEMS)
            .map(|p| {
                let depth = p.dot(down);
                (depth, depth)
            })
            .reduce(
                || (f32::INFINITY, f32::NEG_INFINITY),
                |a, b| (a.0.min(b.0), a.1.max(b.1)),
            );
        let extent = (hi - lo).max(0.0) + self.spacing;
        self.settings.pressure_wave_stability * self.spacing / (g * extent).sqrt()
    }

    /// CFL condition `Δt = λ·d / v_max` (v_max includes moving walls; WCSPH adds the speed of
    /// sound), at most `√(λ·d/|g|)`, clamped to the scene's bounds; then at most the viscous
    /// stability bound, [`Self::pressure_wave_time_step`] and [`step_displacement_bound`],
    /// which all beat `time_step.min`.
    fn cfl_time_step(&self) -> f32 {
        let ts = &self.scene.time_step;
        let fluid_max = self
            .fluid
            .velocity
            .par_iter()
            .with_min_len(LIGHT_PASS_MIN_ITEMS)
            .map(|v| v.length_squared())
            .reduce(|| 0.0, f32::max)
            .sqrt();
        let wall_max = self
            .bodies
            .iter()
            .map(|b| b.velocity.length())
            .fold(0.0, f32::max);
        let mut v_max = fluid_max.max(wall_max);
        if let Some(sound) = self.pressure.sound_speed() {
            v_max += sound;
        }
        let mut dt = if v_max > 0.0 {
            ts.cfl as f32 * self.spacing / v_max
        } else {
            ts.max as f32
        };
        // The speed gravity adds during the step, |g|·Δt, must obey the same condition:
        // Δt ≤ λ·d / (|g|·Δt). It binds only for a still fluid under a large `max`, whose
        // first step would otherwise drop every particle by ½·|g|·max².
        let g = self.gravity.length();
        if g > 0.0 {
            dt = dt.min((ts.cfl as f32 * self.spacing / g).sqrt());
        }
        // The explicit viscosity is stable only below a bound (`viscosity::Laplacian`). This
        // bound beats the scene's minimum Δt: a step below the minimum is slow, one above the
        // bound blows up.
        let upper = (ts.max as f32)
            .min(self.viscosity.max_time_step(self.spacing, &self.settings))
            .min(self.pressure_wave_time_step());
        // No step may carry water through a wall: the distance a particle travels in it under
        // the step's accelerations, |v|·Δt + ½|a|·Δt², stays within MAX_STEP_DISPLACEMENT·d
        // ([`step_displacement_bound`]). Like the viscous bound it beats the scene's minimum
        // (the validator refuses a `time_step.min` above it from rest; later, a fast flow can
        // bring it lower). The speed is the fastest particle's plus the fastest wall's (they
        // may close on each other); the acceleration is gravity's, the pointer's, and the
        // shaken tank's.
        let mut acceleration = g;
        if let Some(p) = self.pointer.filter(|p| p.radius > 0.0) {
            let strength = p.strength.abs().min(forces::MAX_POINTER_ACCELERATION);
            acceleration += strength;
            if p.strength < 0.0 {
                // A pull also damps the velocity relative to the pointer (4·|v| at most).
                acceleration += 4.0 * fluid_max;
            }
        }
        if self.shake_drive != 0.0 || wall_max > 0.0 {
            acceleration += MAX_SHAKE_ACCELERATION;
        }
        let bound = step_displacement_bound(
            (fluid_max + wall_max) as f64,
            acceleration as f64,
            self.spacing as f64,
        ) as f32;
        dt.clamp((ts.min as f32).min(upper), upper).min(bound)
    }

    /// Tank motion from the shake drive: a critically damped spring pulls the tank towards
    /// `drive · MAX_SHAKE_OFFSET`, with bounded acceleration and speed, so holding a key
    /// slides the tank over and releasing it brings the tank back. Every body (obstacles,
    /// drawn walls) moves with the tank.
    fn update_body_motion(&mut self) {
        let dt = self.last_dt;
        let tank = &mut self.bodies[0];
        let target = self.shake_drive * MAX_SHAKE_OFFSET;
        let omega = 2.0 * std::f32::consts::PI * SHAKE_FREQUENCY;
        let acc = (omega * omega * (target - tank.offset.x) - 2.0 * omega * tank.velocity.x)
            .clamp(-MAX_SHAKE_ACCELERATION, MAX_SHAKE_ACCELERATION);
        let vx = (tank.velocity.x + acc * dt).clamp(-MAX_SHAKE_SPEED, MAX_SHAKE_SPEED);
        if vx != tank.velocity.x || tank.velocity.y != 0.0 {
            // Obstacles and drawn walls are fixed to the tank, as the probes are: shaking
            // moves the container as one. A static wall that the tank's own wall swept past
            // would trap and crush the water between them (seen in `dfsph2d stress`).
            let v = Vec2::new(vx, 0.0);
            for body in self.bodies.iter_mut().filter(|b| b.rigid.is_none()) {
                body.velocity = v;
            }
            let bodies = &self.bodies;
            self.boundary
                .velocity
                .par_iter_mut()
                .zip(self.boundary.body.par_iter())
                .with_min_len(LIGHT_PASS_MIN_ITEMS)
                .for_each(|(u, &b)| {
                    if bodies[b as usize].rigid.is_none() {
                        *u = v
                    }
                });
        }
    }

    fn move_bodies(&mut self, dt: f32) {
        if self
            .bodies
            .iter()
            .all(|b| b.velocity == Vec2::ZERO || b.rigid.is_some())
        {
            return;
        }
        for b in self.bodies.iter_mut().filter(|b| b.rigid.is_none()) {
            b.offset += dt * b.velocity;
        }
        self.boundary_grid_for = None;
        let bodies = &self.bodies;
        self.boundary
            .position
            .par_iter_mut()
            .zip(self.boundary.velocity.par_iter())
            .zip(self.boundary.body.par_iter())
            .with_min_len(LIGHT_PASS_MIN_ITEMS)
            .for_each(|((x, &v), &b)| {
                if bodies[b as usize].rigid.is_none() {
                    *x += dt * v
                }
            });
    }

    /// Find which fluid particles touch which free rigid body, so that the bodies move inside
    /// the solves ([`crate::rigid::coupled`]), and lower those particles' factors to match.
    fn couple_rigid_bodies(&mut self) {
        let Some(rigid) = &self.rigid else {
            self.coupled = None;
            return;
        };
        let mobility: Vec<_> = (0..rigid.len()).map(|k| rigid.mobility(k)).collect();
        let (bodies, boundary) = (&self.bodies, &self.boundary);
        let (lists, grads) = (&self.boundary_lists, &self.pair_cache.boundary_grad);
        let coupled = CoupledBodies::new(
            self.fluid.len(),
            |i| (lists.of(i), &grads[lists.range(i)]),
            |b| bodies[boundary.body[b] as usize].rigid,
            &boundary.position,
            &boundary.volume,
            &mobility,
            self.particle_mass(),
            self.pressure.walls().gradient_weight(),
        );
        coupled.damp_factors(&mut self.fluid.factor);
        self.wall_flux_at_start
            .clone_from(&self.pair_cache.wall_flux);
        self.coupled = Some(coupled);
    }

    /// Line 8 of Algorithm 1 for the free rigid bodies: their velocities as the density solve
    /// of a step of `dt` starts, after the divergence solve (`after_divergence`), gravity and
    /// the walls' ghosts, given to the solve through the walls' share of the density rate.
    fn predict_rigid_bodies(&mut self, dt: f32, after_divergence: &[BodyVelocity]) {
        let (Some(rigid), Some(_)) = (&self.rigid, &self.coupled) else {
            return;
        };
        let mut moved = rigid.gravity_velocity_change(self.gravity, dt);
        for (m, &a) in moved.iter_mut().zip(after_divergence) {
            *m += a;
        }
        if self
            .pressure
            .walls()
            .hydrostatic_ghost_gradient(self.gravity)
            .is_some()
        {
            let ghosts = self.rigid_velocity_change(dt, Terms::Ghosts);
            for (m, g) in moved.iter_mut().zip(ghosts) {
                *m += g;
            }
        }
        let Some(coupled) = &self.coupled else {
            return;
        };
        let flux = &mut self.pair_cache.wall_flux;
        flux.clone_from(&self.wall_flux_at_start);
        let n = flux.len();
        coupled.add_flux(flux, 0..n, &moved, 1.0);
        self.rigid_predicted = moved;
    }

    /// Give the moving bodies' boundary particles the velocity the step's solves gave their
    /// bodies (the prediction of [`Self::predict_rigid_bodies`] and the density solve's
    /// impulses), for the step's linearisation check; rapier's step puts them where the
    /// bodies went afterwards ([`Self::place_rigid_particles`]).
    fn move_rigid_walls_as_solved(&mut self, dt: f32) {
        let (Some(rigid), Some(coupled)) = (&self.rigid, &self.coupled) else {
            return;
        };
        let kappa_per_pressure = dt * self.pressure.pressure_force_scale();
        let mut moved = self.rigid_predicted.clone();
        let density =
            coupled.velocity_change_of(&self.fluid.pressure_over_rho0, kappa_per_pressure);
        for (m, d) in moved.iter_mut().zip(density) {
            *m += d;
        }
        // A body that touches something moves as its contacts let it, which the solves do
        // not see: its walls keep their velocity from before the step, the check's cautious
        // assumption.
        for (k, m) in moved.iter_mut().enumerate() {
            if rigid.touches_something(k) {
                *m = BodyVelocity::default();
            }
        }
        let centres: Vec<Vec2> = (0..rigid.len()).map(|k| rigid.mobility(k).centre).collect();
        let bodies = &self.bodies;
        self.boundary
            .position
            .par_iter()
            .zip(self.boundary.velocity.par_iter_mut())
            .zip(self.boundary.body.par_iter())
            .with_min_len(LIGHT_PASS_MIN_ITEMS)
            .for_each(|((&x, v), &b)| {
                if let Some(k) = bodies[b as usize].rigid {
                    let (k, m) = (
                        k as usize,
                        moved.get(k as usize).copied().unwrap_or_default(),
                    );
                    *v += m.linear + m.angular * (x - centres[k]).perp();
                }
            });
    }

    /// The velocity change of each rigid body from what the walls gave the fluid in `terms`
    /// of the step of `dt`, about its mobility centre ([`RigidBodies::mobility`]: zero for a
    /// fixed body, a turn about the anchor for a hinged one).
    fn rigid_velocity_change(&mut self, dt: f32, terms: Terms) -> Vec<BodyVelocity> {
        let impulses = self.rigid_body_impulses(dt, terms);
        let Some(rigid) = &self.rigid else {
            return Vec::new();
        };
        impulses
            .iter()
            .enumerate()
            .map(|(k, j)| {
                let mobile = rigid.mobility(k);
                // The impulse's moment about the centre of mass, moved to the mobility centre.
                let r = rigid.centre_of_mass(k) - mobile.centre;
                BodyVelocity {
                    linear: mobile.inverse_mass * j.linear,
                    angular: mobile.inverse_inertia * (j.angular + r.perp_dot(j.linear)),
                }
            })
            .collect()
    }

    /// The impulse the fluid gave each rigid body through `terms` of the step of `dt`, with
    /// its moment about the body's centre of mass ([`coupling`]).
    fn rigid_body_impulses(&mut self, dt: f32, terms: Terms) -> Vec<coupling::BodyImpulse> {
        let Some(rigid) = &self.rigid else {
            return Vec::new();
        };
        let rigid_of: Vec<Option<u16>> = self.bodies.iter().map(|b| b.rigid).collect();
        let centres: Vec<Vec2> = (0..rigid.len()).map(|k| rigid.centre_of_mass(k)).collect();
        let walls = self.pressure.walls();
        let ghost_slope = walls
            .hydrostatic_ghost_gradient(self.gravity)
            .map(|g| g / self.gradient_consistency);
        let (weight, mass) = (walls.gradient_weight(), self.particle_mass());
        let pressure_to_kappa = dt * self.pressure.pressure_force_scale();
        let (step, fluid, _) = self.step_parts(dt);
        // Scenes with bodies run DFSPH (`Scene::validate`), whose solves apply these terms.
        let solves = matches!(terms, Terms::All);
        let terms = WallTerms {
            divergence_stiffness: (solves && step.settings.divergence_solve)
                .then_some(&fluid.divergence_stiffness[..]),
            pressure_to_kappa: if solves { pressure_to_kappa } else { 0.0 },
            weight,
            ghost_slope,
        };
        coupling::body_impulses(&step, fluid, &terms, mass, &rigid_of, &centres)
    }

    /// Advance the rigid bodies by `dt` under gravity and the fluid's `impulses`, and put
    /// their boundary particles where the bodies went, with the bodies' velocities there.
    fn move_rigid_bodies(&mut self, dt: f32, impulses: &[coupling::BodyImpulse]) {
        let Some(rigid) = &mut self.rigid else {
            return;
        };
        let tank_offset = self.bodies[0].offset;
        if self.walls_moved_for_bodies {
            let bodies = &self.bodies;
            let walls = self
                .boundary
                .position
                .iter()
                .zip(&self.boundary.body)
                .filter(|&(_, &b)| b != 0 && bodies[b as usize].rigid.is_none())
                .map(|(&p, _)| p - tank_offset);
            rigid.set_walls(walls, self.spacing);
            self.walls_moved_for_bodies = false;
        }
        rigid.step(dt, self.gravity, impulses, tank_offset);
        self.place_rigid_particles();
    }

    /// Put every rigid body's boundary particles where its body stands, with its velocity.
    pub(crate) fn place_rigid_particles(&mut self) {
        let Some(rigid) = &self.rigid else {
            return;
        };
        let bodies = &self.bodies;
        self.boundary
            .position
            .par_iter_mut()
            .zip(self.boundary.velocity.par_iter_mut())
            .zip(
                self.boundary
                    .body
                    .par_iter()
                    .zip(self.boundary.local.par_iter()),
            )
            .with_min_len(LIGHT_PASS_MIN_ITEMS)
            .for_each(|((x, v), (&b, &q))| {
                if let Some(k) = bodies[b as usize].rigid {
                    (*x, *v) = rigid.point_motion(k as usize, q);
                }
            });
        self.boundary_grid_for = None;
    }

    /// Last-resort containment for the rigid bodies, like [`Self::enforce_tank`]'s: a fluid
    /// particle past the centre line of a body's first boundary layer (half a spacing inside
    /// its outline) has gone through it; it is put back on the outline, its velocity into
    /// the body removed, and counted.
    fn enforce_rigid_bodies(&mut self) -> u32 {
        let Some(rigid) = &self.rigid else {
            return 0;
        };
        let margin = 0.5 * self.spacing;
        self.fluid
            .position
            .par_iter_mut()
            .zip(self.fluid.velocity.par_iter_mut())
            .with_min_len(LIGHT_PASS_MIN_ITEMS)
            .map(|(x, v)| rigid.push_out(x, v, margin) as u32)
            .sum()
    }

    /// The interior of the tank as it stands now (it moves when shaken), m.
    pub fn tank_interior(&self) -> (Vec2, Vec2) {
        let off = self.bodies[0].offset;
        (
            to_vec2(self.scene.tank.min) + off,
            to_vec2(self.scene.tank.max) + off,
        )
    }

    /// The box a fluid particle stays in unless it went through a wall, m: the tank's
    /// interior grown on each side to the centre line of the first wall layer, at least d/2
    /// out ([`boundary::first_layer_margins`]; on the hexagonal lattice the floor's and the
    /// ceiling's rows can lie further out).
    pub fn tank_containment(&self) -> (Vec2, Vec2) {
        let (lo, hi) = self.tank_interior();
        (lo - self.tank_wall_margins.0, hi + self.tank_wall_margins.1)
    }

    /// Last-resort containment: a particle whose centre has crossed the centre line of the
    /// tank's first boundary layer ([`Self::tank_containment`]) has gone through the wall; it
    /// is put back on the interior's edge, its outward velocity removed, and counted. A
    /// non-finite particle is reset to rest at the tank centre and counted. Both counts
    /// should stay zero.
    fn enforce_tank(&mut self) -> (u32, u32) {
        let (lo, hi) = self.tank_interior();
        let (outer_lo, outer_hi) = self.tank_containment();
        let centre = 0.5 * (lo + hi);
        let wall_v = self.bodies[0].velocity;
        self.fluid
            .position
            .par_iter_mut()
            .zip(self.fluid.velocity.par_iter_mut())
            .with_min_len(LIGHT_PASS_MIN_ITEMS)
            .map(|(x, v)| {
                if !(x.is_finite() && v.is_finite()) {
                    *x = centre;
                    *v = Vec2::ZERO;
                    return (0u32, 1u32);
                }
                if x.x >= outer_lo.x && x.x <= outer_hi.x && x.y >= outer_lo.y && x.y <= outer_hi.y
                {
                    return (0, 0);
                }
                *x = x.clamp(lo, hi);
                if (x.x <= lo.x && v.x < wall_v.x) || (x.x >= hi.x && v.x > wall_v.x) {
                    v.x = wall_v.x;
                }
                if (x.y <= lo.y && v.y < wall_v.y) || (x.y >= hi.y && v.y > wall_v.y) {
                    v.y = wall_v.y;
                }
                (1, 0)
            })
            .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1))
    }

    fn speed_and_energy(&self) -> (f64, f64) {
        let (sum2, max2) =
            crate::reduce::sum_and_max(&self.fluid.velocity, |v| v.length_squared() as f64);
        let mass = self.particle_mass() as f64;
        (max2.sqrt(), 0.5 * mass * sum2)
    }

    // ---- Read access: the library API used by the viewer, the CLI and embedders. ----

    /// The mechanical energy of the water and the rigid bodies, J per metre of depth:
    /// kinetic `½ m |v|²` plus potential `−m g·(x − x0)`, x0 the tank's lower-left corner
    /// (a body's spin is left out; bodies held fixed do not count). In a closed tank without
    /// actions it can only fall (viscosity and the solves dissipate); a rise beyond the
    /// solver's tolerance is energy the step created (`dfsph2d run` reports it as a blow-up).
    pub fn mechanical_energy(&self) -> f64 {
        let (origin, g) = (self.tank_interior().0, self.gravity);
        let m = self.particle_mass() as f64;
        let fluid = crate::reduce::sum_and_max_of(self.fluid.len(), |i| {
            let (x, v) = (self.fluid.position[i], self.fluid.velocity[i]);
            m * (0.5 * v.length_squared() as f64 - g.dot(x - origin) as f64)
        })
        .0;
        // Read from the bodies in place: `rigid_bodies()` would build every outline.
        let bodies = self
            .rigid
            .as_ref()
            .map_or(0.0, |r| r.mechanical_energy(g, origin));
        fluid + bodies
    }

    /// The rigid bodies as they stand, in order (scene's first, then those added).
    pub fn rigid_bodies(&self) -> Vec<RigidBodyState> {
        self.rigid.as_ref().map_or_else(Vec::new, |r| r.states())
    }

    /// Number of rigid bodies.
    pub fn rigid_body_count(&self) -> usize {
        self.rigid.as_ref().map_or(0, |r| r.len())
    }

    /// The rigid body whose outline contains `at` (m), if any.
    pub fn rigid_body_at(&self, at: Vec2) -> Option<usize> {
        self.rigid.as_ref().and_then(|r| r.body_at(at))
    }

    /// The rigid body (index into [`Self::rigid_bodies`]) whose boundary particles carry the
    /// id `body` of [`Self::boundary_bodies`]; `None` for the tank, obstacles and drawn walls.
    pub fn rigid_body_of(&self, body: BodyId) -> Option<usize> {
        self.bodies
            .get(body as usize)
            .and_then(|b| b.rigid)
            .map(usize::from)
    }

    /// The rigid body the pointer holds and where it pulls it, m.
    pub fn dragged_body(&self) -> Option<(usize, Vec2)> {
        self.rigid.as_ref().and_then(|r| r.dragged())
    }

    /// Total linear momentum of the fluid and the rigid bodies, kg·m/s per metre of depth.
    pub fn momentum(&self) -> Vec2 {
        let fluid: glam::DVec2 = self.fluid.velocity.iter().map(|v| v.as_dvec2()).sum();
        let bodies = self.rigid.as_ref().map_or(Vec2::ZERO, |r| r.momentum());
        (fluid * self.particle_mass() as f64).as_vec2() + bodies
    }

    /// The scene this simulation runs, with any parameter changes applied since.
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// Simulated time, s.
    pub fn time(&self) -> f64 {
        self.time
    }

    /// Steps taken.
    pub fn step_count(&self) -> u64 {
        self.step_count
    }

    /// Whether the clock has reached `target` (s): whether the last step ended at `target`
    /// or past it, give or take 1 % of that step. The clock is a sum of steps in double
    /// precision, so a hundred steps of 0.001 may end at 0.09999999999999999; without the
    /// slack a loop `while time < 0.1` would take a 101st step.
    pub fn has_reached(&self, target: f64) -> bool {
        reached(self.time, self.stats.dt, target)
    }

    /// Diagnostics of the last step (before the first: the particle counts, the rest zero).
    pub fn stats(&self) -> &StepStats {
        &self.stats
    }

    /// Particles clamped back into the tank since the start. Non-zero means a leak.
    pub fn total_clamped(&self) -> u64 {
        self.total_clamped
    }

    /// Non-finite particles reset since the start. Non-zero means the solver broke down.
    pub fn total_non_finite(&self) -> u64 {
        self.total_non_finite
    }

    /// Number of fluid particles.
    pub fn fluid_count(&self) -> usize {
        self.fluid.len()
    }

    /// Fluid positions, m, in the solver's current (cell-sorted) order.
    pub fn positions(&self) -> &[Vec2] {
        &self.fluid.position
    }

    /// Fluid velocities, m/s, same order as [`Self::positions`].
    pub fn velocities(&self) -> &[Vec2] {
        &self.fluid.velocity
    }

    /// Stable particle ids, same order as [`Self::positions`].
    pub fn ids(&self) -> &[u32] {
        &self.fluid.id
    }

    /// Density relative to ρ0 at the start of the last step, same order as
    /// [`Self::positions`].
    pub fn density_ratios(&self) -> &[f32] {
        &self.fluid.density_ratio
    }

    /// Pressure divided by ρ0, m²/s², same order as [`Self::positions`]. Multiply by
    /// [`Self::rest_density`] for pascals.
    pub fn pressures_over_rho0(&self) -> &[f32] {
        &self.fluid.pressure_over_rho0
    }

    /// The pressure field at each particle, divided by ρ0 (m²/s², same order as
    /// [`Self::positions`]): the solve's pressures interpolated twice over each particle's
    /// neighbourhood with the kernel, normalised by its kernel sum (Shepard),
    /// `p̄_i = Σ_j W_ij p_j / Σ_j W_ij`, j over the fluid neighbours and i itself.
    ///
    /// This is the pressure outputs show (CSV, VTK, the viewer's pressure colours). The solve's
    /// own values ([`Self::pressures_over_rho0`]) carry particle-scale patterns that exert no
    /// force, which the solve neither sees nor removes: alternate rows of the hexagonal lattice
    /// sit above and below ρ0·g·(H − y), by up to 4.5 % of ρ0·g·H in a column 300 layers deep.
    /// One interpolation keeps about a quarter of that pattern (the kernel's weight on a
    /// particle's own row against the rows beside it), two keep about 7 %; both keep a linear
    /// field exactly inside a uniform lattice. Next to the free surface and walls, where the
    /// neighbourhood is one-sided, the result leans towards the interior's value by a fraction
    /// of a spacing's pressure difference. Where the pressure varies over a few spacings (an
    /// impact), the output is that much smoother than the solve's field.
    pub fn interpolated_pressures_over_rho0(&self) -> Vec<f32> {
        let p = &self.fluid.pressure_over_rho0;
        if p.len() != self.fluid.len() || self.fluid_lists.len() != self.fluid.len() {
            // Before the first step or right after a pour: nothing to interpolate over yet.
            return p.clone();
        }
        self.shepard_interpolation(&self.shepard_interpolation(p))
    }

    /// `Σ_j W_ij f_j / Σ_j W_ij` at every fluid particle, j over its fluid neighbours and itself.
    fn shepard_interpolation(&self, f: &[f32]) -> Vec<f32> {
        let x = &self.fluid.position;
        let w0 = self.kernel.w(0.0);
        (0..x.len())
            .into_par_iter()
            .with_min_len(LIGHT_PASS_MIN_ITEMS)
            .map(|i| {
                let (mut sum, mut weight) = (w0 * f[i], w0);
                for &j in self.fluid_lists.of(i) {
                    let w = self.kernel.w((x[i] - x[j as usize]).length());
                    sum += w * f[j as usize];
                    weight += w;
                }
                sum / weight
            })
            .collect()
    }

    /// What the pressure force of the stored pressures is scaled by: the lattice's gradient
    /// consistency c for the conjugate-gradient solve, which stores the physical pressure
    /// c·κ/Δt (see `pressure::conjugate_gradient`); 1 for the Jacobi solve and WCSPH.
    pub fn pressure_force_scale(&self) -> f32 {
        self.pressure.pressure_force_scale()
    }

    /// p/ρ0 (m²/s²) with which each fluid particle, by index, pushed its neighbours and the
    /// walls in the last step, as the pressure solver applies it
    /// (`PressureSolver::applied_pressure`): what a wall's force is read from (`probes`).
    pub fn applied_pressure_over_rho0(&self) -> impl Fn(usize) -> f32 + '_ {
        let (dt, divergence_solve) = (self.stats.dt as f32, self.settings.divergence_solve);
        move |i| {
            self.pressure
                .applied_pressure(&self.fluid, i, dt, divergence_solve)
        }
    }

    /// Boundary particle positions, m.
    pub fn boundary_positions(&self) -> &[Vec2] {
        &self.boundary.position
    }

    /// Boundary particle volumes Ψ_b (Akinci et al. 2012), m², same order as
    /// [`Self::boundary_positions`].
    pub fn boundary_volumes(&self) -> &[f32] {
        &self.boundary.volume
    }

    /// Divergence-solve stiffness κᵛ of the last step, m²/s, same order as
    /// [`Self::positions`] (zero when the divergence solve is off or for WCSPH).
    pub fn divergence_stiffnesses(&self) -> &[f32] {
        &self.fluid.divergence_stiffness
    }

    /// Particle spacing d = 2r of the fluid lattice and of the tank walls' sampling, m.
    pub fn spacing(&self) -> f32 {
        self.spacing
    }

    /// The body of each boundary particle (0 = tank).
    pub fn boundary_bodies(&self) -> &[BodyId] {
        &self.boundary.body
    }

    /// ρ0, kg/m³.
    pub fn rest_density(&self) -> f32 {
        self.scene.rest_density as f32
    }

    /// Particle radius r, m.
    pub fn particle_radius(&self) -> f32 {
        0.5 * self.spacing
    }

    /// Mass of one fluid particle per metre of depth, kg/m: `ρ0 / Σ_j W(x_i − x_j)` over the
    /// ideal lattice, so the initial lattice is at ρ0 exactly.
    pub fn particle_mass(&self) -> f32 {
        self.scene.rest_density as f32 * self.volume
    }

    /// Current gravity, m/s².
    pub fn gravity(&self) -> Vec2 {
        self.gravity
    }

    /// The kernel in use.
    pub fn kernel(&self) -> &Kernel {
        &self.kernel
    }

    /// Particle data sorted by id, densities in kg/m³ and pressures in Pa.
    pub fn snapshot(&self) -> Snapshot {
        let mut order: Vec<usize> = (0..self.fluid.len()).collect();
        order.sort_unstable_by_key(|&i| self.fluid.id[i]);
        let rho0 = self.rest_density();
        let pressure = self.interpolated_pressures_over_rho0();
        Snapshot {
            time: self.time,
            id: order.iter().map(|&i| self.fluid.id[i]).collect(),
            position: order.iter().map(|&i| self.fluid.position[i]).collect(),
            velocity: order.iter().map(|&i| self.fluid.velocity[i]).collect(),
            density: order
                .iter()
                .map(|&i| self.fluid.density_ratio[i] * rho0)
                .collect(),
            pressure: order.iter().map(|&i| pressure[i] * rho0).collect(),
        }
    }

    /// Front of the fluid: the largest x of a fluid particle with at least `min_neighbors`
    /// fluid neighbours (an isolated spray particle is not the front), measured from the
    /// tank's left wall. `None` when no particle qualifies.
    pub fn front_position(&self, min_neighbors: usize) -> Option<f64> {
        let (lo, _) = self.tank_interior();
        (0..self.fluid.len())
            .filter(|&i| {
                self.fluid_lists.len() == self.fluid.len() && self.count_close(i) >= min_neighbors
            })
            .map(|i| (self.fluid.position[i].x - lo.x) as f64)
            .fold(None, |m: Option<f64>, x| Some(m.map_or(x, |m| m.max(x))))
    }

    /// Fluid neighbours of particle `i` at its current position.
    fn count_close(&self, i: usize) -> usize {
        let mut count = 0usize;
        self.fluid_grid
            .for_each_near(self.fluid.position[i], |_, _| count += 1);
        count.saturating_sub(1)
    }
}

/// How far the tank slides when shaken, m.
pub const MAX_SHAKE_OFFSET: f32 = 0.4;
/// Natural frequency of the tank's return spring, Hz.
pub const SHAKE_FREQUENCY: f32 = 1.0;
/// Bound on the tank's acceleration, m/s².
pub const MAX_SHAKE_ACCELERATION: f32 = 15.0;
/// Bound on the tank's speed, m/s.
pub const MAX_SHAKE_SPEED: f32 = 2.0;

/// `Σ_j W(x_i − x_j)` over an infinite square lattice of spacing `d` (the particle itself
/// included): the reciprocal of the volume that puts the lattice at rest density.
pub fn lattice_kernel_sum(kernel: &Kernel, d: f32) -> f32 {
    let reach = (kernel.support() / d).ceil() as i32 + 1;
    let mut sum = 0.0f64;
    for j in -reach..=reach {
        for i in -reach..=reach {
            sum += kernel.w(Vec2::new(i as f32 * d, j as f32 * d).length()) as f64;
        }
    }
    sum as f32
}

pub(crate) fn to_vec2(p: [f64; 2]) -> Vec2 {
    Vec2::new(p[0] as f32, p[1] as f32)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::actions::Action;

    /// The fluid–wall lists of a fresh neighbourhood update, against brute force over every
    /// wall particle.
    fn assert_wall_lists_are_exact(sim: &mut Simulation) {
        sim.update_neighborhoods();
        let h2 = sim.kernel.support() * sim.kernel.support();
        let mut pairs = 0;
        for (i, &x) in sim.fluid.position.iter().enumerate() {
            let mut got = sim.boundary_lists.of(i).to_vec();
            got.sort_unstable();
            let want: Vec<u32> = (0..sim.boundary.len() as u32)
                .filter(|&b| (x - sim.boundary.position[b as usize]).length_squared() < h2)
                .collect();
            assert_eq!(got, want, "fluid particle {i} at {x:?}");
            pairs += want.len();
        }
        assert!(pairs > 100, "the fluid must touch the walls: {pairs} pairs");
    }

    #[test]
    fn water_entirely_inside_obstacles_is_refused_naming_fluid() {
        for packing in ["square", "hexagonal"] {
            let scene = |obstacle_max: f64| {
                Scene::from_json(&format!(
                    r#"{{"packing": "{packing}", "tank": {{"min": [0, 0], "max": [1, 1]}},
                        "fluid": [{{"min": [0.2, 0], "max": [0.4, 0.2]}}],
                        "obstacles": [{{"type": "rect", "min": [0.1, 0], "max": [{obstacle_max}, 0.3]}}]}}"#
                ))
                .unwrap()
            };
            let e = Simulation::new(&scene(0.5)).err().unwrap().to_string();
            assert!(
                e.starts_with("`fluid`: every lattice site of the fluid blocks lies inside"),
                "{packing}: {e}"
            );
            // Half of it outside: the rest starts as water.
            assert!(Simulation::new(&scene(0.3)).unwrap().fluid_count() > 0);
        }
    }

    #[test]
    fn output_pressure_keeps_a_linear_field_and_damps_the_row_pattern() {
        // The hexagonal tank, given a linear pressure plus a pattern alternating row by row
        // (what the solve leaves at rest): inside the water the output keeps the linear field
        // and at most 10 % of the pattern.
        let mut scene = crate::scene::builtin("hydrostatic").unwrap();
        scene.particle_radius = 0.02;
        let mut sim = Simulation::new(&scene).unwrap();
        let d = sim.spacing;
        let row_distance = crate::packing::ROW_DISTANCE as f32 * d;
        let linear = |p: Vec2| 10.0 - 9.81 * p.y + 0.5 * p.x;
        let pattern = |p: Vec2| {
            let row = ((p.y - 0.5 * d) / row_distance).round() as i64;
            if row % 2 == 0 {
                0.5
            } else {
                -0.5
            }
        };
        sim.fluid.pressure_over_rho0 = sim
            .fluid
            .position
            .iter()
            .map(|&p| linear(p) + pattern(p))
            .collect();
        let out = sim.interpolated_pressures_over_rho0();
        let top = sim.fluid.position.iter().map(|p| p.y).fold(0.0, f32::max);
        let mut checked = 0;
        for (&p, &q) in sim.fluid.position.iter().zip(&out) {
            if p.x > 4.0 * d && p.x < 2.0 - 4.0 * d && p.y > 4.0 * d && p.y < top - 4.0 * d {
                assert!((q - linear(p)).abs() < 0.05, "{p} {q} {}", linear(p));
                checked += 1;
            }
        }
        assert!(checked > 100, "{checked}");
    }

    /// The wall grid is kept between steps while the walls stand still; the fluid–wall lists
    /// must stay exact through a shaken tank (which fails without the rebuild), a drawn wall
    /// and a pour.
    #[test]
    fn wall_lists_stay_exact_while_the_wall_grid_is_reused() {
        let mut scene = crate::scene::builtin("dam-break").unwrap();
        scene.particle_radius = 0.04;
        let mut sim = Simulation::new(&scene).unwrap();
        for _ in 0..5 {
            sim.step();
        }
        assert_wall_lists_are_exact(&mut sim);
        sim.apply(&Action::ShakeTank { direction: 1.0 });
        for _ in 0..10 {
            sim.step();
            assert_wall_lists_are_exact(&mut sim);
        }
        sim.apply(&Action::ShakeTank { direction: 0.0 });
        sim.apply(&Action::AddWall {
            polyline: vec![Vec2::new(1.2, 0.1), Vec2::new(1.8, 0.5)],
        });
        sim.step();
        assert_wall_lists_are_exact(&mut sim);
        // Pouring changes the fluid count, which sets the wall grid's dense-cell floor.
        let poured = sim.apply(&Action::Emit {
            at: Vec2::new(3.0, 0.4),
            radius: 0.3,
            velocity: Vec2::ZERO,
        });
        assert!(poured.added > 0, "{poured:?}");
        sim.step();
        assert_wall_lists_are_exact(&mut sim);
    }

    /// A step gives the same bits on any number of threads, and whether it is called from
    /// inside rayon's pool or from outside it (where it hands itself to a worker): no pass
    /// may cut its work by the thread count, and the float sums that steer a step or that it
    /// reports are taken in a fixed order (`crate::reduce`, whose own test shows rayon's
    /// `reduce` failing that).
    #[test]
    // Thread counts matter only where the solver runs in rayon's pools.
    #[cfg(feature = "parallel")]
    fn steps_give_the_same_bits_on_any_thread_count() {
        // The dam break with the Jacobi solve, and the hydrostatic tank with the
        // conjugate-gradient solve (whose dot products decide every iteration).
        for (name, radius) in [("dam-break", 0.01), ("hydrostatic", 0.025)] {
            let mut scene = crate::scene::builtin(name).unwrap();
            scene.particle_radius = radius;
            let run = |threads: Option<usize>| {
                let mut sim = Simulation::new(&scene).unwrap();
                let mut errors = Vec::new();
                let mut advance = || {
                    for _ in 0..60 {
                        let s = sim.step();
                        errors.push([
                            s.avg_density_error_pct.to_bits(),
                            s.divergence_error_pct.to_bits(),
                            s.kinetic_energy.to_bits(),
                        ]);
                    }
                };
                match threads {
                    Some(n) => rayon::ThreadPoolBuilder::new()
                        .num_threads(n)
                        .build()
                        .unwrap()
                        .install(advance),
                    None => advance(),
                }
                (crate::recording::fingerprint(&sim), errors)
            };
            let outside = run(None);
            assert!(outside.1.iter().any(|e| f64::from_bits(e[0]) > 0.0));
            // 8 workers: more than the cores, so the solver's lockstep barrier must yield to
            // let the late ones run.
            for threads in [1, 2, 3, 8] {
                let inside = run(Some(threads));
                assert_eq!(inside.0, outside.0, "{name}: {threads} threads");
                for (step, (a, b)) in inside.1.iter().zip(&outside.1).enumerate() {
                    assert_eq!(a, b, "{name}: {threads} threads, step {step}");
                }
            }
        }
    }
}
