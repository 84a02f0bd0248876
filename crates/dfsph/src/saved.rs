//! A running simulation written back as a scene ([`World::to_scene`]): every fluid
//! particle's position and velocity in `particles`, the scene's obstacles and the walls drawn
//! since in `obstacles`, and gravity and every parameter as they stand. `dfsph2d run` and
//! `dfsph2d view` accept the result like any scene file, and
//! [`crate::Simulation::new`] places the particles exactly where they were.

use glam::Vec2;

use crate::boundary::BoundarySamples;
use crate::scene::{Obstacle, ParticleList, Point, Scene};
use crate::world::World;

/// `x` as the f64 with the fewest decimal digits that reads back as the same f32, so a saved
/// scene writes 0.005 rather than 0.004999999888241291 and loads to the same bits.
fn short(x: f32) -> f64 {
    // Rust prints a float with the shortest digits that parse back to it.
    format!("{x}").parse().unwrap_or(f64::from(x))
}

fn point(p: Vec2) -> Point {
    [short(p.x), short(p.y)]
}

impl World {
    /// The current state as a scene: the fluid as listed particles (`particles`, no
    /// blocks), the obstacles and drawn walls, gravity and every parameter as they stand.
    ///
    /// Positions are in the tank's frame: a tank shaken off centre is put back, with
    /// everything in it. Walls keep their shape where they are whole: a scene obstacle as it
    /// was written, a drawn wall as the polyline it was drawn along; one that was partly
    /// erased becomes the boundary particles left of it (`{"type": "particles"}`), and one
    /// erased completely is left out. Time starts again at 0, and a shake or a push in
    /// progress is not kept.
    pub fn to_scene(&self) -> Scene {
        let tank_offset = self.bodies[0].offset;
        let mut scene = self.scene.clone();
        scene.fluid.clear();
        let moving = self.fluid.velocity.iter().any(|v| *v != Vec2::ZERO);
        scene.particles = ParticleList {
            positions: self
                .fluid
                .position
                .iter()
                .map(|&p| point(p - tank_offset))
                .collect(),
            velocities: if moving {
                self.fluid.velocity.iter().map(|&v| point(v)).collect()
            } else {
                Vec::new()
            },
        };

        let mut by_body: Vec<Vec<Vec2>> = vec![Vec::new(); self.bodies.len()];
        for (&p, &b) in self.boundary.position.iter().zip(&self.boundary.body) {
            by_body[b as usize].push(p - tank_offset);
        }
        let d = self.spacing;
        // Body ids: the tank, the scene's obstacles and rigid bodies, then the walls drawn
        // and the bodies dropped since, in the order they came.
        let mut drawn = 0;
        let drawn_index: Vec<usize> = self
            .bodies
            .iter()
            .enumerate()
            .map(|(body, _)| {
                drawn += self.is_drawn_wall(body) as usize;
                drawn.saturating_sub(1)
            })
            .collect();
        scene.obstacles = by_body
            .iter()
            .enumerate()
            .skip(1)
            .filter(|&(body, left)| !left.is_empty() && self.bodies[body].rigid.is_none())
            .map(|(body, left)| {
                let whole = if body <= self.scene.obstacles.len() {
                    self.scene.obstacles[body - 1].clone()
                } else {
                    // A drawn wall moves with the tank from the moment it was drawn.
                    let shift = self.bodies[body].offset - tank_offset;
                    Obstacle::Polyline {
                        points: self.drawn_walls[drawn_index[body]]
                            .iter()
                            .map(|&p| point(p + shift))
                            .collect(),
                    }
                };
                if sample_count(&whole, d, &self.scene) == left.len() {
                    whole
                } else {
                    Obstacle::Particles {
                        positions: left.iter().map(|&p| point(p)).collect(),
                    }
                }
            })
            .collect();
        // The rigid bodies as they stand: where they are, turned and moving as they are.
        scene.bodies = self
            .rigid_bodies()
            .into_iter()
            .map(|b| {
                let mut spec = b.spec;
                spec.position = point(b.position - tank_offset);
                spec
            })
            .collect();
        scene
    }
}

/// How many boundary particles `Simulation::new` samples for an obstacle of `scene` at
/// spacing `d` (on the scene's lattice, as many layers thick as its kernel needs).
fn sample_count(obstacle: &Obstacle, d: f32, scene: &Scene) -> usize {
    if let Obstacle::Particles { positions } = obstacle {
        return positions.len();
    }
    let mut samples = BoundarySamples::new(scene.wall_layers());
    samples.add_obstacle(obstacle, d, scene.hexagonal_anchor(), 0);
    samples.positions.len()
}

impl Scene {
    /// [`Scene::to_json`] with every pair of numbers (`[x, y]`) on one line: a saved state
    /// lists tens of thousands of particles, which take four lines each otherwise.
    pub fn to_json_compact_points(&self) -> String {
        let pretty = self.to_json();
        let lines: Vec<&str> = pretty.lines().collect();
        let number = |l: &str| l.trim().trim_end_matches(',').parse::<f64>().is_ok();
        let mut out = String::with_capacity(pretty.len() / 2);
        let mut i = 0;
        while i < lines.len() {
            let pair = lines[i].ends_with('[')
                && i + 3 < lines.len()
                && number(lines[i + 1])
                && lines[i + 1].ends_with(',')
                && number(lines[i + 2])
                && !lines[i + 2].ends_with(',')
                && matches!(lines[i + 3].trim(), "]" | "],");
            if pair {
                out.push_str(lines[i]);
                out.push_str(lines[i + 1].trim());
                out.push(' ');
                out.push_str(lines[i + 2].trim());
                out.push_str(lines[i + 3].trim());
                i += 4;
            } else {
                out.push_str(lines[i]);
                i += 1;
            }
            out.push('\n');
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene;
    use crate::Action;
    use crate::Simulation;

    fn coarse(name: &str) -> Scene {
        let mut s = scene::builtin(name).unwrap();
        s.particle_radius = 0.05;
        s
    }

    /// Non-tank boundary positions, sorted, for comparing walls regardless of order.
    fn walls(sim: &Simulation) -> Vec<[u32; 2]> {
        let mut w: Vec<[u32; 2]> = sim
            .boundary_positions()
            .iter()
            .zip(sim.boundary_bodies())
            .filter(|(_, &b)| b != 0)
            .map(|(p, _)| [p.x.to_bits(), p.y.to_bits()])
            .collect();
        w.sort_unstable();
        w
    }

    #[test]
    fn a_saved_state_loads_back_to_the_same_particles_and_walls() {
        let mut sim = Simulation::new(&coarse("obstacle")).unwrap();
        for _ in 0..30 {
            sim.step();
        }
        // A drawn wall kept whole, one partly erased, and gravity and a parameter changed.
        sim.apply(&Action::AddWall {
            polyline: vec![Vec2::new(1.5, 2.0), Vec2::new(2.5, 2.2)],
        });
        sim.apply(&Action::AddWall {
            polyline: vec![Vec2::new(0.5, 2.5), Vec2::new(1.5, 2.5)],
        });
        let erased = sim.apply(&Action::Erase {
            at: Vec2::new(0.5, 2.5),
            radius: 0.2,
        });
        assert!(erased.boundary_change < 0);
        sim.apply(&Action::SetGravity {
            gravity: Vec2::new(1.0, -5.0),
        });
        let mut viscosity = sim.scene().viscosity.clone();
        viscosity.xsph = 0.2;
        sim.apply(&Action::SetViscosity { viscosity });
        for _ in 0..5 {
            sim.step();
        }

        let saved = sim.to_scene();
        assert!(saved.fluid.is_empty());
        assert_eq!(saved.particles.len(), sim.fluid_count());
        // The ramp and the block as written, the whole drawn wall as a polyline, the erased
        // one as particles.
        assert_eq!(&saved.obstacles[..2], &sim.scene().obstacles[..]);
        assert!(matches!(&saved.obstacles[2], Obstacle::Polyline { points } if points.len() == 2));
        assert!(matches!(&saved.obstacles[3], Obstacle::Particles { .. }));

        let text = saved.to_json_compact_points();
        let back = Scene::from_json(&text).unwrap();
        assert_eq!(back, saved);
        let loaded = Simulation::new(&back).unwrap();
        let bits = |v: &[Vec2]| -> Vec<[u32; 2]> {
            v.iter().map(|p| [p.x.to_bits(), p.y.to_bits()]).collect()
        };
        assert_eq!(bits(loaded.positions()), bits(sim.positions()));
        assert_eq!(bits(loaded.velocities()), bits(sim.velocities()));
        assert_eq!(loaded.gravity(), Vec2::new(1.0, -5.0));
        assert_eq!(loaded.scene().viscosity.xsph, 0.2);
        assert_eq!(walls(&loaded), walls(&sim));
    }

    /// A box on the hexagonal packing, with walls as deep as either kernel needs, is saved as
    /// the box it is (its samples are counted as `Simulation::new` makes them), not particle
    /// by particle.
    #[test]
    fn a_box_on_the_hexagonal_packing_is_saved_as_a_box() {
        for kernel in [
            crate::kernel::KernelShape::CubicSpline,
            crate::kernel::KernelShape::WendlandC2,
        ] {
            let mut scene = Scene::from_json(
                r#"{"particle_radius": 0.02, "tank": {"min": [0, 0], "max": [2, 1.5]},
                    "packing": "hexagonal", "fluid": [{"min": [0, 0], "max": [2, 1]}],
                    "obstacles": [{"type": "rect", "min": [0.8, 0], "max": [1.2, 0.6]}]}"#,
            )
            .unwrap();
            scene.solver.kernel = kernel;
            let mut sim = Simulation::new(&scene).unwrap();
            sim.step();
            let saved = sim.to_scene();
            assert_eq!(saved.obstacles, scene.obstacles, "{kernel:?}");
        }
    }

    #[test]
    fn a_state_saved_while_the_tank_is_shaken_is_put_back_in_the_tank() {
        let mut sim = Simulation::new(&coarse("dam-break")).unwrap();
        sim.apply(&Action::ShakeTank { direction: 1.0 });
        for _ in 0..40 {
            sim.step();
        }
        let (lo, _) = sim.tank_interior();
        let offset = lo.x - sim.scene().tank.min[0] as f32;
        assert!(offset > 0.01, "the tank moved {offset} m");
        let saved = sim.to_scene();
        saved.validate().unwrap();
        let mean_x = |xs: &[Point]| xs.iter().map(|p| p[0]).sum::<f64>() / xs.len() as f64;
        let now =
            sim.positions().iter().map(|p| p.x as f64).sum::<f64>() / sim.fluid_count() as f64;
        assert!((now - offset as f64 - mean_x(&saved.particles.positions)).abs() < 1e-4);
    }

    #[test]
    fn compact_points_are_one_line_each_and_read_back() {
        let mut s = coarse("dam-break");
        s.particles.positions = vec![[3.0, 2.5], [3.5, 2.5]];
        s.particles.velocities = vec![[0.25, -1.0], [0.0, 0.0]];
        let text = s.to_json_compact_points();
        assert!(text.contains("[3.0, 2.5],"), "{text}");
        assert!(text.contains("\"gravity\": [0.0, -9.81],"), "{text}");
        assert_eq!(Scene::from_json(&text).unwrap(), s);
    }
}
