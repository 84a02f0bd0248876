//! The simulation: a [`World`] and the [`Backend`] that advances it, as one object for the
//! command line, the viewer, the page, Python and embedders. It reads as its world
//! (`Deref`): positions, velocities, bodies, the scene. Steps go to the backend, actions to
//! the world, and the backend hears of what they changed.

use glam::Vec2;
use std::ops::Deref;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use crate::actions::{Action, ActionOutcome};
use crate::backend::Backend;
use crate::boundary::BoundaryModel;
use crate::cpu::CpuBackend;
use crate::memory::MemoryLimits;
use crate::scene::{Scene, SceneError};
use crate::world::World;

pub use crate::backend::StepStats;
pub use crate::displacement::{step_displacement_bound, MAX_STEP_DISPLACEMENT};
pub use crate::settings::PRESSURE_WAVE_STABILITY;
pub use crate::world::{
    lattice_kernel_sum, reached, step_seconds, MAX_SHAKE_ACCELERATION, MAX_SHAKE_OFFSET,
    MAX_SHAKE_SPEED, SHAKE_FREQUENCY,
};

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

/// Makes the backend that steps a world: when a simulation is built, and again on every
/// reset (a new world). [`Simulation::new`] takes the CPU backend's.
pub type BackendFactory = Arc<dyn Fn(&mut World) -> Box<dyn Backend> + Send + Sync>;

/// One running scene: its world and the backend that steps it.
pub struct Simulation {
    pub(crate) world: World,
    backend: Box<dyn Backend>,
    /// Makes the next backend on a reset; the CPU backend's when `None`.
    factory: Option<BackendFactory>,
}

impl Deref for Simulation {
    type Target = World;

    fn deref(&self) -> &World {
        &self.world
    }
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

    /// [`Self::new`] within `limits` (e.g. with a user's `--max-memory`).
    pub fn new_within(scene: &Scene, limits: &MemoryLimits) -> Result<Self, SceneError> {
        let mut world = World::new_within(scene, limits)?;
        let backend = Box::new(CpuBackend::new(&mut world));
        Ok(Simulation {
            world,
            backend,
            factory: None,
        })
    }

    /// [`Self::new_within`] with the backend `factory` makes (e.g. the GPU's, from the
    /// `dfsph-gpu` crate), now and on every reset.
    pub fn with_backend(
        scene: &Scene,
        limits: &MemoryLimits,
        factory: BackendFactory,
    ) -> Result<Self, SceneError> {
        let mut world = World::new_within(scene, limits)?;
        let backend = factory(&mut world);
        Ok(Simulation {
            world,
            backend,
            factory: Some(factory),
        })
    }

    /// What steps this simulation, in words: `cpu`, or the GPU backend and its adapter (and,
    /// where it hands the step to the CPU, why).
    pub fn backend_description(&self) -> String {
        self.backend.describe()
    }

    /// The world this simulation steps.
    pub fn world(&self) -> &World {
        &self.world
    }

    /// A flag that, once set (a signal handler's, for Ctrl-C), makes the pressure solves
    /// (conjugate gradients and Jacobi, density and divergence) end at their next iteration:
    /// a deep scene's step, whose solve may run to thousands of iterations, then ends within
    /// one and the caller can stop after it. The step so ended is not converged; a caller
    /// that goes on stepping should clear the flag first. (The Jacobi solve runs in lockstep
    /// across threads: one member reads the flag for all, so that all leave together.)
    pub fn set_stop_flag(&mut self, flag: Arc<AtomicBool>) {
        self.backend.set_stop_flag(flag);
    }

    /// Advance by one time step (TVCG 2017, Algorithm 1, arranged so that a step starts from
    /// fresh neighbourhoods): neighbourhoods → densities and factors → divergence solve →
    /// non-pressure forces → CFL Δt → predicted velocities → density solve → advection.
    pub fn step(&mut self) -> &StepStats {
        self.backend.step(&mut self.world)
    }

    /// Apply a user action between steps.
    pub fn apply(&mut self, action: &Action) -> ActionOutcome {
        let out = self.world.apply(action);
        if out.rejected.is_none() {
            match action {
                // A new world: a backend of its own, which keeps the caller's stop flag
                // (Ctrl-C in `run`), as the world keeps the memory limit.
                Action::Reset { .. } => {
                    let flag = self.backend.stop_flag();
                    self.backend = match &self.factory {
                        Some(factory) => factory(&mut self.world),
                        None => Box::new(CpuBackend::new(&mut self.world)),
                    };
                    if let Some(flag) = flag {
                        self.backend.set_stop_flag(flag);
                    }
                }
                Action::SetSolver { .. }
                | Action::SetViscosity { .. }
                | Action::SetTimeStep { .. } => self.backend.scene_changed(&self.world),
                _ => {}
            }
        }
        out
    }

    /// The Δt the next step starts from: the CFL step and its bounds (gravity, the
    /// viscosity's stability limit, deep water, `time_step`), before any retry shortens it.
    pub fn next_time_step(&self) -> f32 {
        self.backend.next_time_step(&self.world)
    }

    /// Whether the clock has reached `target` (s): whether the last step ended at `target`
    /// or past it, give or take 1 % of that step. The clock is a sum of steps in double
    /// precision, so a hundred steps of 0.001 may end at 0.09999999999999999; without the
    /// slack a loop `while time < 0.1` would take a 101st step.
    pub fn has_reached(&self, target: f64) -> bool {
        reached(self.world.time, self.stats().dt, target)
    }

    /// Diagnostics of the last step (before the first: the particle counts, the rest zero).
    pub fn stats(&self) -> &StepStats {
        self.backend.stats()
    }

    /// Particles clamped back into the tank since the start. Non-zero means a leak.
    pub fn total_clamped(&self) -> u64 {
        self.backend.totals().0
    }

    /// Non-finite particles reset since the start. Non-zero means the solver broke down.
    pub fn total_non_finite(&self) -> u64 {
        self.backend.totals().1
    }

    /// The pressure field at each particle, divided by ρ0 (m²/s², same order as
    /// [`World::positions`]): the solve's pressures interpolated twice over each particle's
    /// neighbourhood with the kernel, normalised by its kernel sum (Shepard),
    /// `p̄_i = Σ_j W_ij p_j / Σ_j W_ij`, j over the fluid neighbours and i itself.
    ///
    /// This is the pressure outputs show (CSV, VTK, the viewer's pressure colours). The solve's
    /// own values ([`World::pressures_over_rho0`]) carry particle-scale patterns that exert no
    /// force, which the solve neither sees nor removes: alternate rows of the hexagonal lattice
    /// sit above and below ρ0·g·(H − y), by up to 4.5 % of ρ0·g·H in a column 300 layers deep.
    /// One interpolation keeps about a quarter of that pattern (the kernel's weight on a
    /// particle's own row against the rows beside it), two keep about 7 %; both keep a linear
    /// field exactly inside a uniform lattice. Next to the free surface and walls, where the
    /// neighbourhood is one-sided, the result leans towards the interior's value by a fraction
    /// of a spacing's pressure difference. Where the pressure varies over a few spacings (an
    /// impact), the output is that much smoother than the solve's field.
    pub fn interpolated_pressures_over_rho0(&self) -> Vec<f32> {
        self.backend.output_pressures_over_rho0(&self.world)
    }

    /// What the pressure force of the stored pressures is scaled by: the lattice's gradient
    /// consistency c for the conjugate-gradient solve, which stores the physical pressure
    /// c·κ/Δt (see `pressure::conjugate_gradient`); 1 for the Jacobi solve and WCSPH.
    pub fn pressure_force_scale(&self) -> f32 {
        self.backend.pressure_force_scale()
    }

    /// p/ρ0 (m²/s²) with which each fluid particle, by index, pushed its neighbours and the
    /// walls in the last step, as the pressure solver applies it
    /// (`PressureSolver::applied_pressure`): what a wall's force is read from (`probes`).
    pub fn applied_pressure_over_rho0(&self) -> impl Fn(usize) -> f32 + '_ {
        move |i| self.backend.applied_pressure_over_rho0(&self.world, i)
    }

    /// How the walls take part in the pressure terms (the pressure solver's choice).
    pub(crate) fn boundary_model(&self) -> &'static dyn BoundaryModel {
        self.backend.wall_model()
    }

    /// Particle data sorted by id, densities in kg/m³ and pressures in Pa.
    pub fn snapshot(&self) -> Snapshot {
        let fluid = &self.world.fluid;
        let mut order: Vec<usize> = (0..fluid.len()).collect();
        order.sort_unstable_by_key(|&i| fluid.id[i]);
        let rho0 = self.rest_density();
        let pressure = self.interpolated_pressures_over_rho0();
        Snapshot {
            time: self.world.time,
            id: order.iter().map(|&i| fluid.id[i]).collect(),
            position: order.iter().map(|&i| fluid.position[i]).collect(),
            velocity: order.iter().map(|&i| fluid.velocity[i]).collect(),
            density: order
                .iter()
                .map(|&i| fluid.density_ratio[i] * rho0)
                .collect(),
            pressure: order.iter().map(|&i| pressure[i] * rho0).collect(),
        }
    }

    /// Front of the fluid: the largest x of a fluid particle with at least `min_neighbors`
    /// fluid neighbours (an isolated spray particle is not the front), measured from the
    /// tank's left wall. `None` when no particle qualifies.
    pub fn front_position(&self, min_neighbors: usize) -> Option<f64> {
        let (lo, _) = self.tank_interior();
        let fluid = &self.world.fluid;
        (0..fluid.len())
            .filter(|&i| {
                self.backend
                    .close_fluid_count(&self.world, i)
                    .is_some_and(|n| n >= min_neighbors)
            })
            .map(|i| (fluid.position[i].x - lo.x) as f64)
            .fold(None, |m: Option<f64>, x| Some(m.map_or(x, |m| m.max(x))))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
        sim.world.fluid.pressure_over_rho0 = sim
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
