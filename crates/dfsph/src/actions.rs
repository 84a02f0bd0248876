//! What a user can do to a running simulation. The viewer turns keys and mouse input into
//! these actions and the simulation applies them between steps, so every interaction can be
//! tested, recorded and replayed without a window.

use crate::par::prelude::*;
use glam::Vec2;
use serde::{Deserialize, Serialize};

use crate::boundary::{Body, BodyId, BoundarySamples};
use crate::forces::PointerForce;
use crate::neighbors::Grid;
use crate::rigid::{BodySpec, MAX_BODIES};
use crate::scene::{Packing, Scene, SceneError, SolverParams, TimeStepParams, ViscosityParams};
use crate::world::World;

/// One user action. Held actions (`ShakeTank`, `Push`) stay in force until replaced.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "action", rename_all = "snake_case", deny_unknown_fields)]
pub enum Action {
    /// Shake the tank: `direction` −1 slides it left, +1 right, 0 lets it spring back.
    /// Values are clamped to [−1, 1]; motion is bounded (see `simulation::MAX_SHAKE_*`).
    ShakeTank { direction: f32 },
    /// Set gravity, m/s² (tilting the tank is rotating gravity).
    SetGravity { gravity: Vec2 },
    /// Push fluid away from (`strength > 0`) or pull it towards (`strength < 0`) a point,
    /// until [`Action::ReleasePointer`]. Strength in m/s², bounded by
    /// [`crate::forces::MAX_POINTER_ACCELERATION`].
    Push {
        at: Vec2,
        radius: f32,
        strength: f32,
    },
    /// Stop pushing or pulling.
    ReleasePointer,
    /// Pour: add fluid on a disc of lattice sites around `at` (radius in m) with a velocity,
    /// skipping sites that overlap fluid or walls or lie outside the tank, within the scene's
    /// `max_particles`.
    Emit {
        at: Vec2,
        radius: f32,
        velocity: Vec2,
    },
    /// Add a wall along a polyline (m). Fluid under the new wall is removed.
    AddWall { polyline: Vec<Vec2> },
    /// Remove fluid and drawn walls (not the tank) within `radius` of `at`.
    Erase { at: Vec2, radius: f32 },
    /// Remove what is left of the `index`-th wall drawn since the start (0-based, in the
    /// order drawn; [`World::drawn_wall_count`]): the viewer's undo of a wall. The water
    /// the wall displaced is not brought back. Refused for an index not drawn yet.
    RemoveDrawnWall { index: usize },
    /// Remove the fluid particles whose id lies in `from..to`, wherever they are now: the
    /// viewer's undo of a pour (poured water takes the next ids in order,
    /// [`World::next_particle_id`]). Refused when `from > to`.
    RemoveParticles { from: u32, to: u32 },
    /// Drop a rigid body into the tank ([`crate::rigid`]): validated like a scene's `bodies`
    /// entry; fluid it covers is removed.
    AddBody { body: BodySpec },
    /// Take hold of the rigid body under `at` (m), until [`Action::ReleaseBody`]; rejected
    /// when there is none.
    GrabBody { at: Vec2 },
    /// Pull the held body's grabbed point towards `target` (m).
    DragBody { target: Vec2 },
    /// Let go of the held body.
    ReleaseBody,
    /// Replace the solver parameters (tolerances, iterations, method, ...).
    SetSolver { solver: SolverParams },
    /// Replace the viscosity parameters.
    SetViscosity { viscosity: ViscosityParams },
    /// Replace the time-step parameters.
    SetTimeStep { time_step: TimeStepParams },
    /// Start over: rebuild the simulation from `scene`, or, without one, from the current scene
    /// (which keeps parameter and gravity changes made since; the viewer's `r` key sends the scene
    /// as loaded instead). Time and step count restart at 0; shaking, the pointer, poured fluid and
    /// drawn walls are gone. The outcome counts every old fluid particle as removed and every new
    /// one as added.
    Reset {
        #[serde(default, skip_serializing_if = "Option::is_none")]
        scene: Option<Box<Scene>>,
    },
}

/// Most boundary particles one drawn wall may take ([`Action::AddWall`]).
pub const MAX_WALL_PARTICLES: usize = 1_000_000;

/// What an action changed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ActionOutcome {
    /// Fluid particles added.
    pub added: usize,
    /// Fluid particles removed.
    pub removed: usize,
    /// Boundary particles added (positive) or removed (negative).
    pub boundary_change: isize,
    /// The action was refused (invalid parameters, budget reached, ...), with the reason.
    pub rejected: Option<&'static str>,
}

impl World {
    /// Apply a user action between steps; [`crate::Simulation::apply`] tells the backend what
    /// it changed.
    pub(crate) fn apply(&mut self, action: &Action) -> ActionOutcome {
        let mut out = ActionOutcome::default();
        match action {
            Action::ShakeTank { direction } => {
                if direction.is_finite() {
                    self.shake_drive = direction.clamp(-1.0, 1.0);
                } else {
                    out.rejected = Some("non-finite shake direction");
                }
            }
            Action::SetGravity { gravity } => {
                if gravity.is_finite() && gravity.length() <= 100.0 {
                    self.gravity = *gravity;
                    self.scene.gravity = [gravity.x as f64, gravity.y as f64];
                } else {
                    out.rejected = Some("gravity must be finite and at most 100 m/s²");
                }
            }
            Action::Push {
                at,
                radius,
                strength,
            } => {
                if at.is_finite() && radius.is_finite() && strength.is_finite() && *radius > 0.0 {
                    self.pointer = Some(PointerForce {
                        at: *at,
                        radius: *radius,
                        strength: *strength,
                    });
                } else {
                    out.rejected = Some("pointer needs a finite position, radius > 0 and strength");
                }
            }
            Action::ReleasePointer => self.pointer = None,
            Action::Emit {
                at,
                radius,
                velocity,
            } => {
                // Poured water may move no faster than a scene's water may start
                // (`scene::MAX_INITIAL_SPEED`): a pour at 1e20 m/s made every value
                // non-finite within a step.
                let max_speed = crate::scene::MAX_INITIAL_SPEED as f32;
                if !(at.is_finite() && radius.is_finite() && velocity.is_finite() && *radius >= 0.0)
                {
                    out.rejected = Some("emit needs a finite position, radius and velocity");
                } else if velocity.length() > max_speed {
                    out.rejected = Some("emit velocity is faster than 100 m/s");
                } else {
                    out.added = self.emit(*at, radius.min(1.0), *velocity);
                }
            }
            Action::AddWall { polyline } => {
                if polyline.len() < 2 || polyline.iter().any(|p| !p.is_finite()) {
                    out.rejected = Some("a wall needs at least two finite points");
                } else if !self.wall_fits(polyline) {
                    out.rejected =
                        Some("a wall must stay near the tank and within its length budget");
                } else if self.bodies.len() >= BodyId::MAX as usize {
                    out.rejected = Some("too many walls");
                } else {
                    let (removed, added) = self.add_wall(polyline);
                    out.removed = removed;
                    out.boundary_change = added as isize;
                }
            }
            Action::Erase { at, radius } => {
                if at.is_finite() && radius.is_finite() && *radius > 0.0 {
                    let (fluid, walls) = self.erase(*at, *radius);
                    out.removed = fluid;
                    out.boundary_change = -(walls as isize);
                } else {
                    out.rejected = Some("erase needs a finite position and radius > 0");
                }
            }
            Action::RemoveDrawnWall { index } => match self.drawn_wall_body(*index) {
                Some(body) => {
                    let keep: Vec<bool> = self.boundary.body.iter().map(|&b| b != body).collect();
                    out.boundary_change = -(self.remove_boundary(&keep) as isize);
                }
                None => out.rejected = Some("no such drawn wall"),
            },
            Action::RemoveParticles { from, to } => {
                if from > to {
                    out.rejected = Some("remove_particles needs from <= to");
                } else {
                    let ids = self.fluid.id.clone();
                    out.removed = self.fluid.retain(|i| !(*from..*to).contains(&ids[i]));
                }
            }
            Action::AddBody { body } => {
                if let Err(e) = self.add_body(body) {
                    out.rejected = Some(e);
                } else {
                    let (removed, added) = self.last_body_change;
                    out.removed = removed;
                    out.boundary_change = added as isize;
                }
            }
            Action::GrabBody { at } => {
                let grabbed = at
                    .is_finite()
                    .then(|| self.rigid.as_mut().and_then(|r| r.grab(*at)))
                    .flatten();
                if grabbed.is_none() {
                    out.rejected = Some("no body there");
                }
            }
            Action::DragBody { target } => {
                let held =
                    target.is_finite() && self.rigid.as_mut().is_some_and(|r| r.drag_to(*target));
                if !held {
                    out.rejected = Some("no body held, or a non-finite target");
                }
            }
            Action::ReleaseBody => {
                if let Some(r) = &mut self.rigid {
                    r.release();
                }
            }
            Action::SetSolver { solver } => {
                out.rejected =
                    self.change_scene(|s| s.solver = solver.clone(), "invalid solver parameters");
            }
            Action::SetViscosity { viscosity } => {
                out.rejected = self.change_scene(
                    |s| s.viscosity = viscosity.clone(),
                    "invalid viscosity parameters",
                );
            }
            Action::SetTimeStep { time_step } => {
                out.rejected = self.change_scene(
                    |s| s.time_step = time_step.clone(),
                    "invalid time-step parameters",
                );
            }
            Action::Reset { scene } => {
                let scene = match scene {
                    Some(scene) => scene.as_ref(),
                    None => &self.scene,
                };
                let limits = crate::memory::MemoryLimits::of_this_process_and_user(self.max_memory);
                match World::new_within(scene, &limits) {
                    Ok(sim) => {
                        out.removed = self.fluid.len();
                        out.added = sim.fluid_count();
                        out.boundary_change =
                            sim.boundary_positions().len() as isize - self.boundary.len() as isize;
                        *self = sim;
                    }
                    Err(SceneError::Memory(_)) => {
                        out.rejected = Some("the scene needs more memory than this process may use")
                    }
                    Err(_) => out.rejected = Some("invalid scene"),
                }
            }
        }
        out
    }

    /// Apply a parameter change to the scene if the result still validates; otherwise keep
    /// the scene and return `rejection`.
    fn change_scene(
        &mut self,
        change: impl FnOnce(&mut crate::scene::Scene),
        rejection: &'static str,
    ) -> Option<&'static str> {
        let mut scene = self.scene.clone();
        change(&mut scene);
        match scene.validate() {
            Ok(()) => {
                self.scene = scene;
                None
            }
            Err(_) => Some(rejection),
        }
    }

    /// How many walls were drawn since the start ([`Action::AddWall`]), erased or not.
    pub fn drawn_wall_count(&self) -> usize {
        self.drawn_walls.len()
    }

    /// The id the next fluid particle added (poured) will take: the ids of a pour are the
    /// range from this before it to this after it ([`Action::RemoveParticles`]).
    pub fn next_particle_id(&self) -> u32 {
        self.next_id
    }

    /// The body id of the `index`-th drawn wall: body ids run over the tank, the scene's
    /// obstacles and rigid bodies, then the walls drawn and the bodies dropped since, in the
    /// order they came.
    fn drawn_wall_body(&self, index: usize) -> Option<BodyId> {
        (0..self.bodies.len())
            .filter(|&body| self.is_drawn_wall(body))
            .nth(index)
            .map(|body| body as BodyId)
    }

    /// Whether body id `body` is a wall drawn since the start: not the tank (0), not one of
    /// the scene's obstacles (the ids after it), not a rigid body.
    pub(crate) fn is_drawn_wall(&self, body: usize) -> bool {
        body > self.scene.obstacles.len() && self.bodies[body].rigid.is_none()
    }

    /// The shake drive in force, −1 … 1.
    pub fn shake_direction(&self) -> f32 {
        self.shake_drive
    }

    /// The pointer force in force, if any.
    pub fn pointer(&self) -> Option<PointerForce> {
        self.pointer
    }

    fn emit(&mut self, at: Vec2, radius: f32, velocity: Vec2) -> usize {
        let d = self.spacing;
        let budget = self.scene.max_particles.saturating_sub(self.fluid.len());
        if budget == 0 {
            return 0;
        }
        let (lo, hi) = self.tank_interior();
        // Poured water takes the scene's lattice (`packing`), anchored where the scene's
        // blocks are: on the hexagonal one it rests on water of the same lattice, where square
        // sites would rearrange under its weight.
        let candidates: Vec<Vec2> = match self.scene.packing {
            Packing::Square => {
                let reach = (radius / d).ceil() as i32;
                (-reach..=reach)
                    .flat_map(|j| {
                        (-reach..=reach).map(move |i| at + Vec2::new(i as f32, j as f32) * d)
                    })
                    .collect()
            }
            Packing::Hexagonal => {
                let corner = |p: Vec2| [p.x as f64, p.y as f64];
                crate::packing::sites(
                    corner(lo),
                    corner(at - Vec2::splat(radius)),
                    corner(at + Vec2::splat(radius)),
                    d as f64,
                    0.0,
                )
            }
        };
        let lo = lo + Vec2::splat(0.5 * d);
        let hi = hi - Vec2::splat(0.5 * d);
        let mut sites: Vec<Vec2> = candidates
            .into_iter()
            .filter(|&p| {
                (p - at).length() <= radius + 1.0e-6
                    && p.x >= lo.x
                    && p.x <= hi.x
                    && p.y >= lo.y
                    && p.y <= hi.y
            })
            .collect();
        // Keep sites clear of existing fluid and walls: closer than 0.9 d would start the new
        // particles badly compressed.
        let clear = 0.9 * d;
        let fluid = &self.fluid.position;
        let walls = &self.boundary.position;
        // A rigid body's particles only line its outline: its inside is kept clear too.
        let bodies = self.rigid.as_ref();
        sites.retain(|&p| {
            let near = |q: &Vec2| (*q - p).length_squared() < clear * clear;
            !fluid.par_iter().any(near)
                && !walls.par_iter().any(near)
                && !bodies.is_some_and(|r| r.covers(p, d))
        });
        sites.truncate(budget);
        for &p in &sites {
            let id = self.next_id;
            self.next_id += 1;
            self.fluid.push(p, velocity, id);
        }
        sites.len()
    }

    /// A drawn wall may start or end outside the tank, but not farther out than the tank is
    /// large, and may take at most [`MAX_WALL_PARTICLES`] boundary particles: a wall from a
    /// corrupt or hostile recording must not exhaust memory.
    fn wall_fits(&self, polyline: &[Vec2]) -> bool {
        let (lo, hi) = self.tank_interior();
        let size = hi - lo;
        let near = |p: &Vec2| p.cmpge(lo - size).all() && p.cmple(hi + size).all();
        let length: f32 = polyline.windows(2).map(|w| (w[1] - w[0]).length()).sum();
        let layers = crate::boundary::wall_layers(&self.kernel, self.spacing) as f32;
        let samples = layers * (length / self.spacing + polyline.len() as f32);
        polyline.iter().all(near) && samples <= MAX_WALL_PARTICLES as f32
    }

    /// Add a drawn wall; returns (fluid removed, boundary particles added).
    fn add_wall(&mut self, polyline: &[Vec2]) -> (usize, usize) {
        let body = self.bodies.len() as BodyId;
        // Drawn walls move with the tank (see `update_body_motion`), from the moment they are
        // drawn.
        self.bodies.push(Body {
            velocity: self.bodies[0].velocity,
            ..Default::default()
        });
        self.drawn_walls.push(polyline.to_vec());
        self.walls_moved_for_bodies = true;
        let mut samples =
            BoundarySamples::new(crate::boundary::wall_layers(&self.kernel, self.spacing));
        samples.add_polyline(polyline, self.spacing, body);
        samples.merge_close(crate::boundary::MERGE_DISTANCE * self.spacing);
        // A wall drawn through a rigid body would trap it: rapier pushes the body out of the
        // wall's balls (radius d/2, `RigidBodies::set_walls`) against the floor or another
        // wall, and through that (stress found a box pushed 2 cm into the floor). The wall
        // stops short of each body instead, its balls half a spacing clear of the outline.
        if let Some(rigid) = &self.rigid {
            let clear = self.spacing;
            samples.retain(|p| (0..rigid.len()).all(|k| rigid.signed_distance(k, p) >= clear));
        }
        let added = samples.positions.len();
        // Fluid inside the new wall would be crushed: remove what lies within a spacing of it.
        let mut grid = Grid::new(self.spacing);
        grid.build(&samples.positions);
        let pos = self.fluid.position.clone();
        let removed = self.fluid.retain(|i| !grid.any_near(pos[i]));
        self.add_boundary_samples(samples);
        (removed, added)
    }

    /// Add a rigid body where the tank stands now, removing the fluid it covers; the counts
    /// go to `last_body_change`.
    fn add_body(&mut self, spec: &BodySpec) -> Result<(), &'static str> {
        if self.rigid_body_count() >= MAX_BODIES || self.bodies.len() >= BodyId::MAX as usize {
            return Err("too many bodies");
        }
        if self.scene.solver.method != crate::scene::Method::Dfsph {
            return Err("rigid bodies need the DFSPH method");
        }
        if spec
            .validate("body", self.scene.spacing(), &self.scene.tank)
            .is_err()
        {
            return Err("invalid body: it must fit in the tank, be 3 spacings across and have a density of 50–25,000 kg/m³");
        }
        let offset = self.bodies[0].offset;
        let centre = Vec2::new(spec.position[0] as f32, spec.position[1] as f32) + offset;
        // Bodies may touch but not overlap (as in a scene file, `Scene::check_body_overlaps`):
        // rapier pushes overlapping bodies apart at once, through whatever lies beyond (256
        // bodies added at nearly one spot left through the floor and the lid).
        let d = self.spacing;
        let probe = crate::rigid::signed_distance_of(spec, centre);
        if let Some(r) = self.rigid.as_ref() {
            // The new body where it goes (in the shaken tank's frame), the others as they
            // stand now.
            let mut here = spec.clone();
            here.position = [centre.x as f64, centre.y as f64];
            let new = crate::rigid::placed(&here, d);
            let centre_inside = (0..r.len()).any(|k| r.signed_distance(k, centre) < 0.0);
            if centre_inside
                || r.states()
                    .iter()
                    .any(|other| crate::rigid::placed(&other.spec, d).overlaps(&new, d))
            {
                return Err("another body is there");
            }
        }
        // A body dropped onto an obstacle or a drawn wall would be pushed out of it by
        // rapier, through whatever lies beyond (the floor): it is refused, as on another body.
        // A new body must clear the walls' balls (radius d/2); a scene file may have one
        // resting on them, a quarter spacing in (`Scene::check_body_overlaps`).
        let walls = self
            .boundary
            .position
            .iter()
            .zip(&self.boundary.body)
            .filter(|&(_, &b)| b != 0 && self.bodies[b as usize].rigid.is_none());
        if walls.into_iter().any(|(&p, _)| probe(p) < 0.5 * d) {
            return Err("a wall is there");
        }
        let before = self.boundary.len();
        let k = self.add_rigid_body(spec);
        let rigid = self.rigid.as_ref().expect("a body was just added");
        let d = self.spacing;
        let margin = 0.5 * d * (1.0 - 1.0e-3);
        let pos = self.fluid.position.clone();
        let removed = self
            .fluid
            .retain(|i| rigid.signed_distance(k, pos[i]) >= margin);
        self.last_body_change = (removed, self.boundary.len() - before);
        Ok(())
    }

    /// Remove fluid and drawn-wall particles near a point; returns (fluid, wall) counts.
    fn erase(&mut self, at: Vec2, radius: f32) -> (usize, usize) {
        let r2 = radius * radius;
        let pos = self.fluid.position.clone();
        let removed = self.fluid.retain(|i| (pos[i] - at).length_squared() >= r2);
        let b = &self.boundary;
        let keep: Vec<bool> = (0..b.len())
            .map(|k| {
                let body = b.body[k];
                body == 0
                    || self.bodies[body as usize].rigid.is_some()
                    || (b.position[k] - at).length_squared() >= r2
            })
            .collect();
        (removed, self.remove_boundary(&keep))
    }

    /// Keep the boundary particles whose `keep` entry is true; returns how many went. The
    /// walls' volumes and the rigid bodies' walls are brought up to date at the next step.
    fn remove_boundary(&mut self, keep: &[bool]) -> usize {
        let walls = self.boundary.retain(keep);
        if walls > 0 {
            self.boundary_changed = true;
            self.walls_moved_for_bodies = true;
        }
        walls
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene;
    use crate::Simulation;

    /// A built-in scene at particle radius `radius` with a rectangular obstacle added.
    fn with_box(name: &str, radius: f64, min: [f64; 2], max: [f64; 2]) -> scene::Scene {
        let mut s = scene::builtin(name).unwrap();
        s.particle_radius = radius;
        s.obstacles.push(scene::Obstacle::Rect { min, max });
        s
    }

    /// Poured water takes the scene's lattice: on the hexagonal packing each new particle's
    /// nearest new neighbour is a row spacing (1.0746 d) away, on the square one d.
    #[test]
    fn poured_water_takes_the_scenes_packing() {
        for (packing, nearest) in [("square", 1.0), ("hexagonal", crate::packing::ROW_SPACING)] {
            let scene = scene::Scene::from_json(&format!(
                r#"{{"particle_radius": 0.01, "tank": {{"min": [0, 0], "max": [1, 1]}},
                    "fluid": [{{"min": [0, 0], "max": [1, 0.2]}}], "packing": "{packing}"}}"#
            ))
            .unwrap();
            let mut sim = Simulation::new(&scene).unwrap();
            let before = sim.fluid_count();
            let outcome = sim.apply(&Action::Emit {
                at: Vec2::new(0.5, 0.7),
                radius: 0.1,
                velocity: Vec2::ZERO,
            });
            assert_eq!(outcome.rejected, None);
            let d = sim.spacing();
            let new = &sim.positions()[before..];
            // Roughly the disc's area over the area per particle, d².
            let expected = std::f32::consts::PI * 0.1 * 0.1 / (d * d);
            assert!(
                (new.len() as f32 - expected).abs() < 0.1 * expected,
                "{packing}: {} particles",
                new.len()
            );
            for (i, p) in new.iter().enumerate() {
                let closest = new
                    .iter()
                    .enumerate()
                    .filter(|&(k, _)| k != i)
                    .map(|(_, q)| (*q - *p).length())
                    .fold(f32::INFINITY, f32::min);
                assert!(
                    (closest / d - nearest as f32).abs() < 1.0e-3,
                    "{packing}: nearest neighbour at {} d",
                    closest / d
                );
            }
        }
    }

    #[test]
    fn a_wall_stops_short_of_a_rigid_body_and_a_body_is_not_dropped_onto_a_wall() {
        // Either overlap would have rapier push the body out through the floor.
        let scene = scene::Scene::from_json(
            r#"{"particle_radius": 0.01, "tank": {"min": [0, 0], "max": [2, 1]},
                "fluid": [{"min": [0, 0], "max": [2, 0.3]}],
                "bodies": [{"shape": "box", "size": [0.4, 0.2], "density": 500,
                            "position": [1.0, 0.6]}]}"#,
        )
        .unwrap();
        let mut sim = Simulation::new(&scene).unwrap();
        let d = sim.spacing();
        let wall = sim.apply(&Action::AddWall {
            polyline: vec![Vec2::new(0.4, 0.6), Vec2::new(1.6, 0.6)],
        });
        assert_eq!(wall.rejected, None);
        let drawn: Vec<Vec2> = sim
            .boundary_positions()
            .iter()
            .zip(sim.boundary_bodies())
            .filter(|&(_, &b)| b != 0 && sim.rigid_body_of(b).is_none())
            .map(|(&p, _)| p)
            .collect();
        assert_eq!(drawn.len(), wall.boundary_change as usize);
        // The box spans x 0.8-1.2: the wall is drawn on both sides, and not within a spacing
        // of it.
        assert!(drawn.iter().any(|p| p.x < 0.8 - d) && drawn.iter().any(|p| p.x > 1.2 + d));
        assert!(
            drawn
                .iter()
                .all(|p| p.x < 0.8 - 0.99 * d || p.x > 1.2 + 0.99 * d),
            "a wall particle within a spacing of the box"
        );
        let circle = |at: [f64; 2]| Action::AddBody {
            body: BodySpec::new_circle(0.05, 500.0, at),
        };
        assert_eq!(
            sim.apply(&circle([0.55, 0.62])).rejected,
            Some("a wall is there")
        );
        assert_eq!(sim.apply(&circle([0.55, 0.75])).rejected, None);
    }

    /// A body may touch another but not overlap it, whether or not its centre lies inside:
    /// of 256 boxes added a little apart at one spot one is taken, and the bodies stay in the
    /// tank.
    #[test]
    fn a_body_overlapping_another_is_refused() {
        let mut sim = sim();
        let d = sim.spacing as f64;
        let square = |x: f64, y: f64| Action::AddBody {
            body: BodySpec::new_box([0.4, 0.4], 600.0, [x, y]),
        };
        assert_eq!(sim.apply(&square(2.0, 1.5)).rejected, None);
        // Centre outside the first box, half of it inside.
        assert_eq!(
            sim.apply(&square(2.3, 1.5)).rejected,
            Some("another body is there")
        );
        // And the first inside a larger second one.
        let large = Action::AddBody {
            body: BodySpec::new_box([1.2, 1.2], 600.0, [2.0, 1.5]),
        };
        assert_eq!(sim.apply(&large).rejected, Some("another body is there"));
        // Side by side, a spacing apart: taken.
        assert_eq!(sim.apply(&square(2.4 + d, 1.5)).rejected, None);
        let mut taken = 0;
        for k in 0..256 {
            let a = sim.apply(&square(1.0 + 0.001 * k as f64, 2.2));
            taken += usize::from(a.rejected.is_none());
        }
        assert_eq!(taken, 1);
        for _ in 0..100 {
            sim.step();
        }
        let (lo, hi) = sim.tank_interior();
        for b in sim.rigid_bodies() {
            let p = b.position;
            assert!(
                p.cmpge(lo).all() && p.cmple(hi).all(),
                "{p} outside the tank"
            );
        }
    }

    fn sim() -> Simulation {
        let mut s = scene::builtin("dam-break").unwrap();
        s.particle_radius = 0.05;
        Simulation::new(&s).unwrap()
    }

    #[test]
    fn erase_removes_fluid_and_drawn_walls_but_not_the_tank() {
        let mut sim = sim();
        let wall = sim.apply(&Action::AddWall {
            polyline: vec![Vec2::new(2.0, 0.5), Vec2::new(3.0, 0.5)],
        });
        assert!(wall.boundary_change > 0);
        let tank_particles = sim.boundary_bodies().iter().filter(|&&b| b == 0).count();
        let n = sim.fluid_count();
        let out = sim.apply(&Action::Erase {
            at: Vec2::new(0.0, 0.0),
            radius: 0.3,
        });
        assert!(out.removed > 0 && sim.fluid_count() == n - out.removed);
        let out = sim.apply(&Action::Erase {
            at: Vec2::new(2.5, 0.5),
            radius: 2.0,
        });
        assert_eq!(out.boundary_change, -wall.boundary_change);
        let tank_after = sim.boundary_bodies().iter().filter(|&&b| b == 0).count();
        assert_eq!(tank_after, tank_particles);
        sim.step();
        assert!(sim.positions().iter().all(|p| p.is_finite()));
    }

    /// Undo in the viewer: a drawn wall taken away whole (the one drawn after it and the
    /// scene's obstacle stay), a pour's particles taken away by their ids wherever they went.
    #[test]
    fn a_drawn_wall_and_a_pours_particles_can_be_taken_away() {
        let s = with_box("dam-break", 0.05, [2.0, 0.0], [2.2, 0.4]);
        let mut sim = Simulation::new(&s).unwrap();
        let count = |sim: &Simulation, body: BodyId| {
            sim.boundary_bodies().iter().filter(|&&b| b == body).count()
        };
        let obstacle = count(&sim, 1);
        assert_eq!(sim.drawn_wall_count(), 0);
        let first = sim.apply(&Action::AddWall {
            polyline: vec![Vec2::new(2.5, 0.5), Vec2::new(3.0, 0.5)],
        });
        let second = sim.apply(&Action::AddWall {
            polyline: vec![Vec2::new(3.2, 1.0), Vec2::new(3.6, 1.0)],
        });
        assert_eq!(sim.drawn_wall_count(), 2);
        let gone = sim.apply(&Action::RemoveDrawnWall { index: 0 });
        assert_eq!(gone.boundary_change, -first.boundary_change);
        assert_eq!(count(&sim, 2), 0);
        assert_eq!(count(&sim, 3) as isize, second.boundary_change);
        assert_eq!(count(&sim, 1), obstacle);
        let none = sim.apply(&Action::RemoveDrawnWall { index: 2 });
        assert_eq!(none.rejected, Some("no such drawn wall"));

        let n = sim.fluid_count();
        let from = sim.next_particle_id();
        let poured = sim.apply(&Action::Emit {
            at: Vec2::new(3.4, 2.0),
            radius: 0.3,
            velocity: Vec2::ZERO,
        });
        assert!(poured.added > 0);
        let to = sim.next_particle_id();
        assert_eq!((to - from) as usize, poured.added);
        for _ in 0..20 {
            sim.step();
        }
        let undo = sim.apply(&Action::RemoveParticles { from, to });
        assert_eq!(undo.removed, poured.added);
        assert_eq!(sim.fluid_count(), n);
        assert!(sim.snapshot().id.iter().all(|id| !(from..to).contains(id)));
        let bad = sim.apply(&Action::RemoveParticles { from: 5, to: 4 });
        assert!(bad.rejected.is_some());
        sim.step();
        assert!(sim.positions().iter().all(|p| p.is_finite()));
    }

    #[test]
    fn obstacles_and_drawn_walls_move_with_the_shaken_tank() {
        let s = with_box("dam-break", 0.05, [2.0, 0.0], [2.2, 0.4]);
        let mut sim = Simulation::new(&s).unwrap();
        let start: Vec<Vec2> = sim.boundary_positions().to_vec();
        let start_bodies: Vec<BodyId> = sim.boundary_bodies().to_vec();
        sim.apply(&Action::ShakeTank { direction: 1.0 });
        for _ in 0..20 {
            sim.step();
        }
        // A wall drawn while the tank is moving moves with it from then on. Bodies: 0 the
        // tank, 1 the rectangle, 2 the drawn wall.
        sim.apply(&Action::AddWall {
            polyline: vec![Vec2::new(3.0, 1.0), Vec2::new(3.5, 1.0)],
        });
        let drawn: Vec<Vec2> = sim
            .boundary_positions()
            .iter()
            .zip(sim.boundary_bodies())
            .filter(|(_, &b)| b == 2)
            .map(|(p, _)| *p)
            .collect();
        assert!(!drawn.is_empty());
        let (tank_lo, _) = sim.tank_interior();
        let moved_before = tank_lo.x - s.tank.min[0] as f32;
        for _ in 0..60 {
            sim.step();
        }
        let (tank_lo, _) = sim.tank_interior();
        let moved = tank_lo.x - s.tank.min[0] as f32;
        assert!(moved > 0.01, "the tank moved {moved} m");
        // Particles are re-sorted every step: compare each body's mean position.
        let mean = |pos: &[Vec2], bodies: &[BodyId], body: BodyId| -> Vec2 {
            let (sum, n) = pos
                .iter()
                .zip(bodies)
                .filter(|(_, &b)| b == body)
                .fold((Vec2::ZERO, 0.0), |(s, n), (p, _)| (s + *p, n + 1.0));
            sum / n
        };
        for body in [0, 1] {
            let shift = mean(sim.boundary_positions(), sim.boundary_bodies(), body)
                - mean(&start, &start_bodies, body);
            assert!(
                (shift.x - moved).abs() < 1.0e-4 && shift.y.abs() < 1.0e-6,
                "body {body} moved by {shift:?}, the tank by {moved}"
            );
        }
        let now = mean(sim.boundary_positions(), sim.boundary_bodies(), 2);
        let then = drawn.iter().copied().sum::<Vec2>() / drawn.len() as f32;
        let shift = now - then;
        assert!(
            (shift.x - (moved - moved_before)).abs() < 1.0e-4,
            "the drawn wall moved by {shift:?}, the tank by {}",
            moved - moved_before
        );
    }

    #[test]
    fn fluid_is_not_placed_inside_or_against_obstacles() {
        // A box standing in the water and a wall across it.
        let mut s = with_box("hydrostatic", 0.025, [0.8, 0.0], [1.2, 0.6]);
        s.obstacles.push(scene::Obstacle::Polyline {
            points: vec![[0.1, 0.5], [0.6, 0.2]],
        });
        let sim = Simulation::new(&s).unwrap();
        let d = s.spacing() as f32;
        let walls: Vec<Vec2> = sim
            .boundary_positions()
            .iter()
            .zip(sim.boundary_bodies())
            .filter(|(_, &b)| b != 0)
            .map(|(p, _)| *p)
            .collect();
        for p in sim.positions() {
            let in_box = p.x >= 0.8 && p.x <= 1.2 && p.y <= 0.6;
            assert!(!in_box, "fluid particle at {p:?} inside the box");
            let nearest = walls
                .iter()
                .map(|w| (*w - *p).length())
                .fold(f32::INFINITY, f32::min);
            assert!(
                nearest >= d,
                "fluid particle at {p:?} {nearest} m from a wall particle"
            );
        }
        let removed = s.fluid_particle_count() - sim.fluid_count();
        // At d = 5 cm the box alone covers 8 x 12 sites of the 40 x 20 lattice; the 0.58 m
        // wall a band about three sites wide.
        assert!(removed > 8 * 12, "only {removed} sites left empty");
        assert!(removed < 8 * 12 + 80, "{removed} sites left empty");
    }

    #[test]
    fn invalid_parameters_are_refused_and_valid_ones_taken() {
        let mut sim = sim();
        let mut solver = sim.scene().solver.clone();
        solver.max_iterations = 0;
        let out = sim.apply(&Action::SetSolver { solver });
        assert_eq!(out.rejected, Some("invalid solver parameters"));
        assert_eq!(sim.scene().solver.max_iterations, 100);
        let mut viscosity = sim.scene().viscosity.clone();
        viscosity.xsph = 0.05;
        assert_eq!(
            sim.apply(&Action::SetViscosity { viscosity }).rejected,
            None
        );
        assert_eq!(sim.scene().viscosity.xsph, 0.05);
    }

    #[test]
    fn reset_rebuilds_from_the_current_or_a_given_scene() {
        let mut sim = sim();
        let n = sim.fluid_count();
        let gravity = Vec2::new(1.0, -9.0);
        sim.apply(&Action::SetGravity { gravity });
        sim.apply(&Action::Erase {
            at: Vec2::new(0.2, 0.2),
            radius: 0.3,
        });
        for _ in 0..5 {
            sim.step();
        }
        let m = sim.fluid_count();
        let out = sim.apply(&Action::Reset { scene: None });
        assert_eq!((out.removed, out.added, out.rejected), (m, n, None));
        assert_eq!(
            (sim.step_count(), sim.time(), sim.fluid_count()),
            (0, 0.0, n)
        );
        assert_eq!(sim.gravity(), gravity, "parameter changes survive a reset");

        let mut other = scene::builtin("hydrostatic").unwrap();
        other.particle_radius = 0.05;
        let out = sim.apply(&Action::Reset {
            scene: Some(Box::new(other.clone())),
        });
        assert_eq!(out.added, other.fluid_particle_count());
        assert_eq!(sim.scene(), &other);

        let mut bad = other.clone();
        bad.particle_radius = -1.0;
        let out = sim.apply(&Action::Reset {
            scene: Some(Box::new(bad)),
        });
        assert_eq!(out.rejected, Some("invalid scene"));
        assert_eq!(sim.scene(), &other);
    }

    /// A pour no faster than a scene's water may start is taken; a faster one is refused,
    /// and the water is left as it was.
    #[test]
    fn a_pour_faster_than_a_scene_allows_is_refused() {
        let mut s = scene::builtin("dam-break").unwrap();
        s.particle_radius = 0.04;
        let mut sim = Simulation::new(&s).unwrap();
        let n = sim.fluid_count();
        let pour = |v: f32| Action::Emit {
            at: Vec2::new(3.0, 2.0),
            radius: 0.2,
            velocity: Vec2::new(v, 0.0),
        };
        let out = sim.apply(&pour(1.0e20));
        assert_eq!(out.rejected, Some("emit velocity is faster than 100 m/s"));
        assert_eq!(sim.fluid_count(), n);
        let out = sim.apply(&pour(-90.0));
        assert_eq!(out.rejected, None);
        assert!(out.added > 0 && sim.fluid_count() == n + out.added);
    }

    /// Building a simulation and resetting one to another scene are both held to the memory
    /// limit the simulation was built within (here a user's, like `--max-memory`): one
    /// refusal that names memory, the simulation untouched, nothing large allocated.
    #[test]
    fn a_scene_too_large_for_the_memory_limit_is_refused_at_build_and_at_reset() {
        use crate::memory::{Limit, LimitSource, MemoryLimits};
        let limits = MemoryLimits {
            limits: vec![Limit {
                source: LimitSource::User("--max-memory"),
                bytes: 64 << 20,
                set_to: None,
            }],
        };
        let mut small = scene::builtin("dam-break").unwrap();
        small.particle_radius = 0.04;
        let mut large = small.clone();
        large.particle_radius = 0.002; // 400 times the particles: 125,000, over 64 MiB
        match Simulation::new_within(&large, &limits) {
            Err(SceneError::Memory(m)) => assert!(m.contains("needs about"), "{m}"),
            other => panic!("not refused for memory: {:?}", other.err()),
        }
        let mut sim = Simulation::new_within(&small, &limits).unwrap();
        let n = sim.fluid_count();
        let out = sim.apply(&Action::Reset {
            scene: Some(Box::new(large)),
        });
        assert_eq!(
            out.rejected,
            Some("the scene needs more memory than this process may use")
        );
        assert_eq!((sim.scene(), sim.fluid_count()), (&small, n));
    }

    #[test]
    fn actions_round_trip_through_json() {
        let actions = [
            Action::Reset { scene: None },
            Action::Push {
                at: Vec2::new(0.1, 2.0 / 3.0),
                radius: 0.2,
                strength: -80.0,
            },
        ];
        for a in actions {
            let text = serde_json::to_string(&a).unwrap();
            assert_eq!(serde_json::from_str::<Action>(&text).unwrap(), a, "{text}");
        }
        assert_eq!(
            serde_json::to_string(&Action::Reset { scene: None }).unwrap(),
            r#"{"action":"reset"}"#
        );
    }
}
