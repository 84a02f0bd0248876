//! The world: the state of one running scene, apart from the step that advances it. The
//! scene, the particles (each with a stable id; in the order the backend keeps them), the
//! walls and their bodies, the rigid bodies, the tank's drive, the pointer, the clock, and
//! what changed since the last step. Actions ([`crate::actions`]) change it between steps; a
//! backend ([`crate::backend::Backend`]) advances it by a step.

use crate::par::prelude::*;
use crate::parallel::LIGHT_PASS_MIN_ITEMS;
use glam::Vec2;

use crate::boundary::{self, Body, BodyId, BoundarySamples};
use crate::forces::PointerForce;
use crate::kernel::Kernel;
use crate::memory::MemoryLimits;
use crate::neighbors::Grid;
use crate::packing;
use crate::particles::{BoundaryParticles, FluidParticles};
use crate::rigid::{BodySpec, RigidBodies, RigidBodyState};
use crate::scene::{Method, Obstacle, Packing, PressureSolve, Scene, SceneError};

/// How far the tank slides when shaken, m.
pub const MAX_SHAKE_OFFSET: f32 = 0.4;
/// Natural frequency of the tank's return spring, Hz.
pub const SHAKE_FREQUENCY: f32 = 1.0;
/// Bound on the tank's acceleration, m/s².
pub const MAX_SHAKE_ACCELERATION: f32 = 15.0;
/// Bound on the tank's speed, m/s.
pub const MAX_SHAKE_SPEED: f32 = 2.0;

/// The state of one running scene.
pub struct World {
    pub(crate) scene: Scene,
    /// The user's own memory limit, bytes, and its name (`--max-memory`, Python's `max_memory`), applied
    /// again when an action resets the world to another scene.
    pub(crate) max_memory: Option<(u64, &'static str)>,
    pub(crate) kernel: Kernel,
    /// Lattice spacing d, m.
    pub(crate) spacing: f32,
    /// Volume of one fluid particle V = m/ρ0, m² (chosen so the initial lattice is at ρ0).
    pub(crate) volume: f32,
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
    pub(crate) tank_wall_margins: (Vec2, Vec2),
    /// The rigid bodies and their world, from the first body on.
    pub(crate) rigid: Option<RigidBodies>,
    pub(crate) time: f64,
    pub(crate) step_count: u64,
    pub(crate) next_id: u32,
    pub(crate) pointer: Option<PointerForce>,
    /// Shaking: −1 (left) … 1 (right), held until changed.
    pub(crate) shake_drive: f32,
    // What changed since the last step, for the backend.
    /// Boundary particles were added or removed: their volumes are to be recomputed.
    pub(crate) boundary_changed: bool,
    /// Walls moved (shaken, or rigid bodies placed): the walls' grid is to be rebuilt.
    pub(crate) walls_moved: bool,
    /// Fluid removed and boundary particles added by the last [`crate::Action::AddBody`].
    pub(crate) last_body_change: (usize, usize),
    /// The obstacles or drawn walls changed since the rigid bodies were last told where they
    /// are ([`RigidBodies::set_walls`]).
    pub(crate) walls_moved_for_bodies: bool,
}

impl World {
    /// The initial state of `scene`: fluid lattices, boundary particles with their volumes, and
    /// the particle volume that puts an interior lattice particle exactly at ρ0; refused
    /// with [`SceneError::Memory`] before anything large is allocated when the scene needs
    /// more memory than `limits` allow. The solver's fields (densities, pressures) are the
    /// backend's to fill ([`crate::backend::Backend`]).
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
        let mut sim = World {
            scene: scene.clone(),
            max_memory: limits.user(),
            kernel,
            spacing: d,
            volume,
            gravity: to_vec2(scene.gravity),
            fluid: FluidParticles::default(),
            boundary: BoundaryParticles::default(),
            bodies: Vec::new(),
            drawn_walls: Vec::new(),
            tank_wall_margins: (Vec2::ZERO, Vec2::ZERO),
            rigid: None,
            time: 0.0,
            step_count: 0,
            next_id: 0,
            pointer: None,
            shake_drive: 0.0,
            boundary_changed: true,
            walls_moved: true,
            last_body_change: (0, 0),
            walls_moved_for_bodies: true,
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

    /// Tank motion from the shake drive: a critically damped spring pulls the tank towards
    /// `drive · MAX_SHAKE_OFFSET`, with bounded acceleration and speed, so holding a key
    /// slides the tank over and releasing it brings the tank back. Every body (obstacles,
    /// drawn walls) moves with the tank.
    pub fn drive_tank(&mut self, dt: f32) {
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

    /// Move the tank and the walls fixed to it by their velocities over `dt` (s): what a step
    /// does after advecting the fluid.
    pub fn move_walls(&mut self, dt: f32) {
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
        self.walls_moved = true;
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
        self.walls_moved = true;
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

    /// The fastest fluid particle's speed, m/s, and the fluid's kinetic energy, J/m.
    pub fn speed_and_energy(&self) -> (f64, f64) {
        let (sum2, max2) =
            crate::reduce::sum_and_max(&self.fluid.velocity, |v| v.length_squared() as f64);
        let mass = self.particle_mass() as f64;
        (max2.sqrt(), 0.5 * mass * sum2)
    }

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

    /// Whether the density solve is [`PressureSolve::ConjugateGradient`] (with its mirrored,
    /// hydrostatic walls), rather than the paper's Jacobi iteration with Akinci walls.
    pub fn conjugate_gradient(&self) -> bool {
        let solver = &self.scene.solver;
        solver.method == Method::Dfsph && solver.pressure_solve == PressureSolve::ConjugateGradient
    }

    /// How much of a linear field's gradient the SPH gradient recovers on the scene's lattice
    /// ([`packing::gradient_consistency`]): the conjugate-gradient solve stores the physical
    /// pressure `c·κ/Δt`, and its walls' ghosts continue the stiffness field's slope at rest,
    /// g/c.
    pub fn gradient_consistency(&self) -> f32 {
        let (kernel, d, volume) = (&self.kernel, self.spacing, self.volume);
        if self.scene.packing == Packing::Hexagonal {
            packing::hexagonal_gradient_consistency(kernel, d, volume)
        } else {
            packing::square_gradient_consistency(kernel, d, volume)
        }
    }
}

/// What a backend outside this crate reads and writes (the CPU backend, inside it, reaches
/// the fields themselves): the fluid's arrays, the walls, the tank's motion, the pointer and
/// the clock. A backend advances the world only through these.
impl World {
    /// The fluid particles, to be advanced by a step (their order is the backend's: keep
    /// every array the same length and permute them together, ids included).
    pub fn fluid_mut(&mut self) -> &mut FluidParticles {
        &mut self.fluid
    }

    /// The wall particles: positions, velocities, volumes Ψ_b and bodies.
    pub fn boundary(&self) -> &BoundaryParticles {
        &self.boundary
    }

    /// Volume of one fluid particle V = m/ρ0, m².
    pub fn particle_volume(&self) -> f32 {
        self.volume
    }

    /// The tank's velocity, m/s (it moves when shaken; obstacles and drawn walls move with it).
    pub fn tank_velocity(&self) -> Vec2 {
        self.bodies[0].velocity
    }

    /// The fastest moving wall's speed, m/s (the tank's and the rigid bodies').
    pub fn fastest_wall_speed(&self) -> f32 {
        self.bodies
            .iter()
            .map(|b| b.velocity.length())
            .fold(0.0, f32::max)
    }

    /// Whether the user is shaking the tank (its drive is not at rest).
    pub fn is_shaken(&self) -> bool {
        self.shake_drive != 0.0
    }

    /// When wall particles were added or removed since the last call (a drawn or erased wall,
    /// a body), compute the volume Ψ_b of those that have none (Akinci et al. 2012, with the
    /// CPU backend's correction γ; lattice walls come with theirs) and say so; also clear the
    /// flag that walls moved.
    pub fn refresh_wall_volumes(&mut self) -> bool {
        self.walls_moved = false;
        if !self.boundary_changed {
            return false;
        }
        let mut grid = Grid::new(self.kernel.support());
        let order = grid.build(&self.boundary.position).to_vec();
        let gamma = boundary::wall_volume_correction(&self.kernel, self.spacing);
        // Lattice walls come with their volumes; only the others' (zero) are computed.
        let mut sorted: Vec<f32> = order
            .iter()
            .map(|&i| self.boundary.volume[i as usize])
            .collect();
        boundary::volumes(&grid, &self.kernel, gamma, &mut sorted);
        for (k, &i) in order.iter().enumerate() {
            self.boundary.volume[i as usize] = sorted[k];
        }
        self.boundary_changed = false;
        true
    }

    /// Count a step of `dt` (s) on the clock.
    pub fn advance_clock(&mut self, dt: f32) {
        self.time += step_seconds(dt);
        self.step_count += 1;
    }
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
/// one step late. [`crate::Simulation::has_reached`] for the last step; the command line's
/// snapshot schedule for each step it writes after.
pub fn reached(time: f64, dt: f64, target: f64) -> bool {
    time + 0.01 * dt >= target
}

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
