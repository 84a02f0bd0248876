//! `dfsph2d run`'s watch for a simulation that blew up without raising NaN: energy the step
//! created, or a density solve that keeps ending at its iteration cap.
//!
//! In a closed tank without actions the mechanical energy of the water and the bodies
//! (`World::mechanical_energy`) can only fall: viscosity and the solves dissipate, and
//! gravity only turns potential into kinetic energy. Measured over 3 s of every built-in
//! scene, the largest rise above the lowest energy seen before it was 0.36 % of `M·|g|·H`
//! (the `floating` scene, whose bodies' spin is not counted; the dam break 0.10 %,
//! the hydrostatic tank 0.003 %). A rise of [`ENERGY_RISE_LIMIT`] (2 %) is energy the
//! solver made. A density solve stopped by its cap has not met its tolerances; a few such
//! steps in a splash are normal (the `drop` scene: 4 in a row), a run of
//! [`CAPPED_STEPS_LIMIT`] is a solve that cannot keep up.
//!
//! Actions (a replay's pushes, pours, shakes) put energy in: the energy reference starts
//! again after every step that followed one.

use dfsph::{Simulation, StepStats};

/// The largest rise of the mechanical energy above its lowest value since the last action,
/// as a share of the energy scale [`energy_scale`] (dimensionless, 0.02).
pub const ENERGY_RISE_LIMIT: f64 = 0.02;

/// This many density solves in a row ending at `solver.max_iterations` make a blow-up (20).
pub const CAPPED_STEPS_LIMIT: u64 = 20;

/// What the watch found, the first time it found it.
#[derive(Clone, Debug, PartialEq)]
pub struct BlowUp {
    /// The step at which it was seen, and its simulated time, s.
    pub step: u64,
    pub time: f64,
    /// What happened, in words, for the `error:` line.
    pub what: String,
}

/// The energy a rise is measured against, J per metre of depth: the water's and the bodies'
/// mass M times `|g|·H` (H the tank's height: the potential energy the tank can hold), plus
/// their kinetic energy at the start, and at least `M·(1 m/s)²/2` so that a scene without
/// gravity has a scale.
pub fn energy_scale(sim: &Simulation) -> f64 {
    let mass = sim.particle_mass() as f64 * sim.fluid_count() as f64
        + sim
            .rigid_bodies()
            .iter()
            .map(|b| b.mass as f64)
            .sum::<f64>();
    let (lo, hi) = sim.tank_interior();
    let potential = mass * sim.gravity().length() as f64 * (hi.y - lo.y) as f64;
    let kinetic = sim.stats().kinetic_energy;
    potential.max(0.5 * mass) + kinetic
}

/// Watches the steps of one run.
#[derive(Clone, Debug)]
pub struct BlowUpWatch {
    scale: f64,
    /// The lowest mechanical energy since the run started or since the last action.
    lowest: f64,
    /// Density solves in a row that ended at the cap.
    capped: u64,
    max_iterations: u32,
    /// The first blow-up seen.
    pub found: Option<BlowUp>,
}

impl BlowUpWatch {
    /// A watch for `sim` as it stands before its first step (or after a reset).
    pub fn new(sim: &Simulation) -> Self {
        Self {
            scale: energy_scale(sim),
            lowest: sim.mechanical_energy(),
            capped: 0,
            max_iterations: sim.scene().solver.max_iterations,
            found: None,
        }
    }

    /// Start again after a reset (a new scene, the clock at 0), keeping what was found.
    pub fn restart(&mut self, sim: &Simulation) {
        let found = self.found.take();
        *self = Self {
            found,
            ..Self::new(sim)
        };
    }

    /// Look at the step `stats` just taken; `acted` says whether an action applied before it.
    /// After an action, and while a held one is in force (a push or pull, a shake, a dragged
    /// body, the tank springing back to its place), the energy reference starts again from
    /// this step's energy.
    pub fn after_step(&mut self, sim: &Simulation, stats: &StepStats, acted: bool) {
        let energy = sim.mechanical_energy();
        if acted || driven(sim) {
            self.lowest = energy;
        }
        let rise = energy - self.lowest;
        self.lowest = self.lowest.min(energy);
        self.capped = if stats.density_iterations >= self.max_iterations {
            self.capped + 1
        } else {
            0
        };
        if self.found.is_some() {
            return;
        }
        let what = if rise > ENERGY_RISE_LIMIT * self.scale {
            Some(format!(
                "the mechanical energy rose by {:.1} J/m ({:.1} % of M·g·H = {:.1} J/m) without an \
                 action: the step created energy (fastest particle {:.3} m/s)",
                rise,
                100.0 * rise / self.scale,
                self.scale,
                stats.max_speed
            ))
        } else if self.capped >= CAPPED_STEPS_LIMIT {
            Some(format!(
                "the density solve ended at its cap of {} iterations in {} steps in a row \
                 (solver.max_iterations): its tolerances were not met",
                self.max_iterations, self.capped
            ))
        } else {
            None
        };
        self.found = what.map(|what| BlowUp {
            step: stats.step,
            time: stats.time,
            what,
        });
    }
}

/// Whether a held action is putting energy in: the pointer pushes or pulls, the tank is
/// driven or away from its place (its spring brings it back), or a body is dragged.
fn driven(sim: &Simulation) -> bool {
    let scene = &sim.scene().tank;
    let (lo, _) = sim.tank_interior();
    let moved = (lo.x as f64 - scene.min[0]).abs() + (lo.y as f64 - scene.min[1]).abs();
    sim.pointer().is_some()
        || sim.shake_direction() != 0.0
        || sim.dragged_body().is_some()
        || moved > 1.0e-6
}

#[cfg(test)]
mod tests {
    use super::*;
    use dfsph::{scene, Action, Scene, Vec2};

    #[test]
    fn the_built_in_dam_break_is_not_a_blow_up() {
        let mut sim = Simulation::new(&scene::builtin("dam-break").unwrap()).unwrap();
        let mut watch = BlowUpWatch::new(&sim);
        while sim.time() < 0.5 {
            let st = *sim.step();
            watch.after_step(&sim, &st, false);
        }
        assert_eq!(watch.found, None);
    }

    #[test]
    fn energy_put_in_by_hand_is_a_blow_up_unless_an_action_did_it() {
        let s = Scene::from_json(
            r#"{"particle_radius": 0.025, "tank": {"min": [0, 0], "max": [1, 1]},
                "fluid": [{"min": [0, 0], "max": [1, 0.5]}]}"#,
        )
        .unwrap();
        for acted in [false, true] {
            let mut sim = Simulation::new(&s).unwrap();
            let mut watch = BlowUpWatch::new(&sim);
            for _ in 0..5 {
                let st = *sim.step();
                watch.after_step(&sim, &st, false);
            }
            assert_eq!(watch.found, None);
            // Water poured in at 10 m/s: each particle brings 125 J/m, against a limit of
            // 2 % of M·g·H = 98 J/m.
            let outcome = sim.apply(&Action::Emit {
                at: Vec2::new(0.5, 0.8),
                radius: 0.1,
                velocity: Vec2::new(10.0, 0.0),
            });
            assert!(sim.fluid_count() > 200, "{outcome:?}");
            let st = *sim.step();
            watch.after_step(&sim, &st, acted);
            assert_eq!(watch.found.is_some(), !acted, "acted: {acted}");
        }
    }

    #[test]
    fn a_solve_at_its_cap_step_after_step_is_a_blow_up() {
        let s = Scene::from_json(
            r#"{"particle_radius": 0.01, "tank": {"min": [0, 0], "max": [1, 1]},
                "fluid": [{"min": [0, 0], "max": [1, 0.8]}],
                "solver": {"min_iterations": 1, "max_iterations": 1}}"#,
        )
        .unwrap();
        let mut sim = Simulation::new(&s).unwrap();
        let mut watch = BlowUpWatch::new(&sim);
        while watch.found.is_none() && sim.step_count() < 200 {
            let st = *sim.step();
            watch.after_step(&sim, &st, false);
        }
        let found = watch
            .found
            .expect("a one-iteration solve is capped every step");
        assert!(found.what.contains("solver.max_iterations"), "{found:?}");
        assert!(found.step >= CAPPED_STEPS_LIMIT);
    }
}
