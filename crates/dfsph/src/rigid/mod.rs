//! Rigid bodies two-way coupled with the fluid (Akinci et al. 2012, "Versatile rigid-fluid
//! coupling for incompressible SPH"). Each body is sampled with boundary particles that move
//! with it ([`sampling`]); the fluid sees them as walls with the body's velocity (in the
//! divergence and density solves, through the wall flux `Σ_b Ψ_b v_b·∇W_ib`), and the body
//! receives the opposite of every impulse those walls gave the fluid in the step
//! ([`coupling`]), as a force and a torque. Rapier (`rapier2d`) integrates the bodies and
//! resolves their contacts with each other and with the tank, and their joints.
//!
//! Bodies move inside the pressure solves ([`coupled`]): every stiffness increment that
//! pushes the water around a body pushes the body back within the same iteration, so the water
//! sees the body's answer at once and fluid and bodies keep their momentum at every step,
//! however light the body. A hinged body turns about its anchor in the solves; a body fixed by
//! a joint does not move. The impulses summed after the step ([`coupling`]) are the ones the
//! solves applied; rapier then moves the body with them, gravity, its joint and its contacts.

pub(crate) mod coupled;
pub(crate) mod coupling;
use coupled::Mobility;
pub use coupled::{BodyVelocity, CoupledBodies};
use coupling::BodyImpulse;
use outline::Outline;
pub(crate) use outline::{placed, signed_distance_of};
pub(crate) mod outline;
mod sampling;
pub mod spec;

use glam::Vec2;
use rapier2d::prelude as rp;

use crate::kernel::Kernel;
pub use spec::{BodyJoint, BodyShape, BodySpec, MAX_BODIES};

/// What a user or an output sees of one body.
#[derive(Clone, Debug, PartialEq)]
pub struct RigidBodyState {
    /// The body's position (the centre it was placed by), m.
    pub position: Vec2,
    /// Rotation, radians, counter-clockwise.
    pub angle: f32,
    /// Velocity of the position, m/s.
    pub velocity: Vec2,
    /// Spin, rad/s.
    pub angular_velocity: f32,
    /// Mass per metre of depth, kg/m.
    pub mass: f32,
    /// The body as specified, with its current position, angle and velocities.
    pub spec: BodySpec,
    /// The outline in the tank's frame, counter-clockwise (a circle as a 48-gon), m.
    pub outline: Vec<Vec2>,
}

/// How hard a grabbed body is pulled to the pointer: a critically damped spring of this
/// frequency, Hz, with the pull's acceleration capped at [`MAX_DRAG_ACCELERATION`].
const DRAG_FREQUENCY: f32 = 4.0;
/// The largest acceleration a drag gives a body, m/s² (about 10 g).
pub const MAX_DRAG_ACCELERATION: f32 = 100.0;

/// How many times stiffer than rapier's defaults the contacts' springs are ([`RigidBodies::new`]).
const CONTACT_STIFFENING: f32 = 4.0;

/// The bodies of a simulation and the rapier world they live in.
pub(crate) struct RigidBodies {
    world: rp::PhysicsWorld,
    /// The tank: a kinematic body whose four walls the bodies collide with; it follows the
    /// shaken tank.
    tank: rp::RigidBodyHandle,
    pub(crate) bodies: Vec<Rigid>,
    drag: Option<Drag>,
    /// The obstacles and drawn walls as the bodies meet them: a ball of radius d/2 on each of
    /// their boundary particles, fixed to the tank ([`Self::set_walls`]).
    wall_colliders: Vec<rp::ColliderHandle>,
}

/// One body: its specification, its rapier handle and the boundary particles' body id.
pub(crate) struct Rigid {
    pub spec: BodySpec,
    outline: Outline,
    handle: rp::RigidBodyHandle,
    /// A hinge's anchor in the tank body's frame, m.
    hinge: Option<Vec2>,
}

/// A body held by the pointer: the grabbed point, in the body's frame, is pulled to `target`.
#[derive(Clone, Copy, Debug)]
struct Drag {
    body: usize,
    anchor: Vec2,
    target: Vec2,
}

fn rv(v: Vec2) -> rp::Vector {
    rp::Vector::new(v.x, v.y)
}

fn gv(v: rp::Vector) -> Vec2 {
    Vec2::new(v.x, v.y)
}

impl RigidBodies {
    /// An empty world for the tank interior `[lo, hi]` (m) under `gravity`.
    pub fn new(lo: Vec2, hi: Vec2, gravity: Vec2) -> Self {
        let mut world = rp::PhysicsWorld {
            gravity: rv(gravity),
            ..Default::default()
        };
        // Rapier's contacts are springs tuned for piles under gravity alone (30 Hz, 60 Hz
        // against the tank): a box pressed onto the floor with ten times its weight, as a
        // surge slamming it down does, sinks 3.3 mm into it in 0.5 s and goes on sinking, and
        // stress found boxes driven 2 cm in. Springs four times as stiff hold it within
        // 0.3 mm (sixteen times less; the test below).
        let params = &mut world.integration_parameters;
        params.contact_softness.natural_frequency *= CONTACT_STIFFENING;
        params.static_contact_softness.natural_frequency *= CONTACT_STIFFENING;
        // Contact recycling keeps a pair's contacts, distances included, until the bodies
        // have moved 5 cm relative to each other: five particle spacings here, where the
        // water moves the bodies every step and [`Self::touches_something`] reads the
        // distances. A handful of bodies costs little to update every step.
        params.contact_recycling = false;
        let (tank, _) = world.insert(
            rp::RigidBodyBuilder::kinematic_position_based(),
            rp::ColliderBuilder::cuboid(0.01, 0.01).sensor(true),
        );
        // The four walls as half-spaces (each the plane of a wall, solid beyond it). Their
        // contacts with a body are exact (the body's support feature against a plane). Thick
        // cuboids were not: parry meets a convex polygon and a cuboid by GJK, whose tolerance
        // grows with the shapes' size, and against a floor metres wide it lost a box resting
        // 0.2 mm above it (stress seed 8: the box then fell through the floor unopposed).
        let centre = 0.5 * (lo + hi);
        for (at, inward) in [
            (Vec2::new(lo.x, centre.y), Vec2::X),
            (Vec2::new(hi.x, centre.y), -Vec2::X),
            (Vec2::new(centre.x, lo.y), Vec2::Y),
            (Vec2::new(centre.x, hi.y), -Vec2::Y),
        ] {
            // Density zero: a half-space has no finite mass, and the tank is kinematic.
            let wall = rp::ColliderBuilder::new(rp::SharedShape::halfspace(rv(inward)))
                .translation(rv(at))
                .density(0.0)
                .friction(0.5);
            world
                .colliders
                .insert_with_parent(wall, tank, &mut world.bodies);
        }
        Self {
            world,
            tank,
            bodies: Vec::new(),
            drag: None,
            wall_colliders: Vec::new(),
        }
    }

    /// Let the bodies meet the obstacles and drawn walls whose boundary particles lie at
    /// `points` (m, in the tank's frame: their positions less the tank's offset), in place of
    /// those given before. A ball of radius d/2 on each particle reaches as far as the water
    /// the wall holds off: a body's outline then stops where its boundary particles lie a
    /// spacing from the wall's, as at the tank's walls.
    pub fn set_walls(&mut self, points: impl Iterator<Item = Vec2>, d: f32) {
        let world = &mut self.world;
        for handle in self.wall_colliders.drain(..) {
            world.colliders.remove(
                handle,
                &mut world.islands,
                &mut world.bodies,
                &mut world.soft_bodies,
                true,
            );
        }
        for p in points {
            let ball = rp::ColliderBuilder::ball(0.5 * d)
                .translation(rv(p))
                .friction(0.5);
            self.wall_colliders.push(world.colliders.insert_with_parent(
                ball,
                self.tank,
                &mut world.bodies,
            ));
        }
    }

    /// Number of bodies.
    pub fn len(&self) -> usize {
        self.bodies.len()
    }

    /// Add a body (validated); `tank_offset` is how far the tank has moved (the body's position is in the tank's frame at rest). Returns
    /// the body's index, its particles in its own frame and their volumes.
    pub fn add(
        &mut self,
        spec: &BodySpec,
        tank_offset: Vec2,
        d: f32,
        kernel: &Kernel,
    ) -> (usize, Vec<Vec2>, Vec<f32>) {
        let position = Vec2::new(spec.position[0] as f32, spec.position[1] as f32) + tank_offset;
        let builder = rp::RigidBodyBuilder::dynamic()
            .translation(rv(position))
            .rotation(spec.angle as f32)
            .linvel(rp::Vector::new(
                spec.velocity[0] as f32,
                spec.velocity[1] as f32,
            ))
            .angvel(spec.angular_velocity as f32)
            .can_sleep(false);
        let collider = match spec.polygon() {
            Some(points) => {
                let pts: Vec<rp::Vector> = points
                    .iter()
                    .map(|p| rp::Vector::new(p[0] as f32, p[1] as f32))
                    .collect();
                rp::ColliderBuilder::convex_hull(&pts).expect("a validated convex polygon")
            }
            None => rp::ColliderBuilder::ball(spec.radius.unwrap_or(0.0) as f32),
        };
        let area = spec.area() as f32;
        let collider = collider
            .density(spec.mass_per_depth() as f32 / area)
            .friction(spec.friction as f32)
            .restitution(0.0);
        let (handle, _) = self.world.insert(builder, collider);
        let mut hinge = None;
        match &spec.joint {
            None => {}
            Some(BodyJoint::Fixed) => {
                let frame = rp::Pose::new(
                    rv(position - tank_offset_of(&self.world, self.tank)),
                    spec.angle as f32,
                );
                let joint = rp::FixedJointBuilder::new().local_frame1(frame);
                self.world
                    .impulse_joints
                    .insert(self.tank, handle, joint, true);
            }
            Some(BodyJoint::Hinge { anchor }) => {
                let anchor = Vec2::new(anchor[0] as f32, anchor[1] as f32);
                let (s, c) = (spec.angle as f32).sin_cos();
                let rel = anchor + tank_offset - position;
                let local = Vec2::new(c * rel.x + s * rel.y, -s * rel.x + c * rel.y);
                let in_tank = anchor + tank_offset - tank_offset_of(&self.world, self.tank);
                hinge = Some(in_tank);
                let joint = rp::RevoluteJointBuilder::new()
                    .local_anchor1(rv(in_tank))
                    .local_anchor2(rv(local));
                self.world
                    .impulse_joints
                    .insert(self.tank, handle, joint, true);
            }
        }
        let (local, volume) = sampling::sample(spec, d, kernel);
        self.bodies.push(Rigid {
            spec: spec.clone(),
            outline: Outline::of(spec),
            handle,
            hinge,
        });
        (self.bodies.len() - 1, local, volume)
    }

    /// Body `k`'s position, angle, velocity and spin.
    fn pose(&self, k: usize) -> (Vec2, f32, Vec2, f32) {
        let rb = &self.world.bodies[self.bodies[k].handle];
        (
            gv(rb.translation()),
            rb.rotation().angle(),
            gv(rb.linvel()),
            rb.angvel(),
        )
    }

    /// The world position and velocity of the point at `local` (body frame) of body `k`.
    pub fn point_motion(&self, k: usize, local: Vec2) -> (Vec2, Vec2) {
        let rb = &self.world.bodies[self.bodies[k].handle];
        let x = gv(rb.position().transform_point(rv(local)));
        (x, gv(rb.velocity_at_point(rv(x))))
    }

    /// Body `k`'s centre of mass, m.
    pub fn centre_of_mass(&self, k: usize) -> Vec2 {
        gv(self.world.bodies[self.bodies[k].handle].center_of_mass())
    }

    /// The world position of body `k`'s hinge, if a hinge holds it.
    fn hinge(&self, k: usize) -> Option<Vec2> {
        let in_tank = self.bodies[k].hinge?;
        Some(tank_offset_of(&self.world, self.tank) + in_tank)
    }

    /// How body `k` takes part in the solves: a free body moves and turns about its centre
    /// of mass; a hinged one turns about its anchor, with its moment of inertia about it
    /// (`I + M r²`); one fixed by a joint does not move (inverse mass and inertia zero).
    pub(crate) fn mobility(&self, k: usize) -> Mobility {
        let rb = &self.world.bodies[self.bodies[k].handle];
        let (mass, com) = (rb.mass(), gv(rb.center_of_mass()));
        let inertia = rb.mass_properties().effective_angular_inertia();
        let inverse = |x: f32| if x > 0.0 { 1.0 / x } else { 0.0 };
        match (&self.bodies[k].spec.joint, self.hinge(k)) {
            (None, _) => Mobility {
                centre: com,
                inverse_mass: inverse(mass),
                inverse_inertia: inverse(inertia),
            },
            (Some(BodyJoint::Hinge { .. }), Some(anchor)) => Mobility {
                centre: anchor,
                inverse_mass: 0.0,
                inverse_inertia: inverse(inertia + mass * (com - anchor).length_squared()),
            },
            _ => Mobility {
                centre: com,
                inverse_mass: 0.0,
                inverse_inertia: 0.0,
            },
        }
    }

    /// Whether body `k` touches another body, the tank or a wall: rapier's contacts, not the
    /// water, then decide part of its motion in the coming step. Touching means a solver
    /// contact closer than rapier's allowed error (5 mm): rapier also keeps speculative
    /// contacts up to its prediction distance (2 cm) away, which do not hold the body, and a
    /// box falling onto a film of water would count as touching the floor under it.
    pub(crate) fn touches_something(&self, k: usize) -> bool {
        let near = self.world.integration_parameters.allowed_linear_error();
        let rb = &self.world.bodies[self.bodies[k].handle];
        rb.colliders().iter().any(|&c| {
            self.world.contact_pairs_with(c).any(|pair| {
                pair.manifolds().iter().any(|m| {
                    m.data
                        .solver_contacts
                        .iter()
                        .any(|contact| contact.dist <= near)
                })
            })
        })
    }

    /// Every body's velocity change under gravity over `dt`, as the solves see it, about its
    /// [`Self::mobility`] centre: a free body falls, a hinged one turns under its weight's
    /// moment about the anchor, a fixed one stays.
    pub(crate) fn gravity_velocity_change(&self, gravity: Vec2, dt: f32) -> Vec<BodyVelocity> {
        (0..self.bodies.len())
            .map(|k| {
                let mobile = self.mobility(k);
                let rb = &self.world.bodies[self.bodies[k].handle];
                let (mass, com) = (rb.mass(), gv(rb.center_of_mass()));
                BodyVelocity {
                    linear: mobile.inverse_mass * mass * dt * gravity,
                    angular: mobile.inverse_inertia
                        * (com - mobile.centre).perp_dot(mass * gravity)
                        * dt,
                }
            })
            .collect()
    }

    /// Advance the bodies by `dt` under gravity, the fluid's impulses over the step
    /// (`impulses[k]`: N·s/m and N·s about the centre of mass) and the drag, with the tank at
    /// `tank_offset` (m) moving at `tank_velocity`.
    pub fn step(&mut self, dt: f32, gravity: Vec2, impulses: &[BodyImpulse], tank_offset: Vec2) {
        self.world.gravity = rv(gravity);
        self.world.integration_parameters.dt = dt;
        self.world.bodies[self.tank].set_next_kinematic_translation(rv(tank_offset));
        for (k, body) in self.bodies.iter().enumerate() {
            let rb = &mut self.world.bodies[body.handle];
            let mass = rb.mass();
            let inertia = rb.mass_properties().effective_angular_inertia();
            let fluid = impulses.get(k).copied().unwrap_or_default();
            let (impulse, angular) = (fluid.linear, fluid.angular);
            // The fluid's and gravity's velocity change, as the solves moved the body; a
            // joint's constraint and contacts are rapier's.
            let dv = impulse / mass + dt * gravity;
            let dw = angular / inertia.max(f32::MIN_POSITIVE);
            let (accel, alpha) = (dv / dt, dw / dt);
            rb.reset_forces(false);
            rb.reset_torques(false);
            // Rapier adds gravity itself.
            rb.add_force(rv(mass * (accel - gravity)), true);
            rb.add_torque(inertia * alpha, true);
        }
        if let Some(drag) = self.drag {
            if let Some(body) = self.bodies.get(drag.body) {
                let rb = &mut self.world.bodies[body.handle];
                let at = gv(rb.position().transform_point(rv(drag.anchor)));
                let v = gv(rb.velocity_at_point(rv(at)));
                let omega = std::f32::consts::TAU * DRAG_FREQUENCY;
                let pull = (omega * omega * (drag.target - at) - 2.0 * omega * v)
                    .clamp_length_max(MAX_DRAG_ACCELERATION);
                let mass = rb.mass();
                rb.add_force_at_point(rv(mass * pull), rv(at), true);
            }
        }
        self.world.step();
    }

    /// Grab the body under `at` (m), if any: from now on [`Self::drag_to`] pulls the grabbed
    /// point. Returns the body's index.
    pub fn grab(&mut self, at: Vec2) -> Option<usize> {
        let k = self.body_at(at)?;
        let rb = &self.world.bodies[self.bodies[k].handle];
        let anchor = gv(rb.position().inverse_transform_point(rv(at)));
        self.drag = Some(Drag {
            body: k,
            anchor,
            target: at,
        });
        Some(k)
    }

    /// Move the pull's target (m).
    pub fn drag_to(&mut self, target: Vec2) -> bool {
        match &mut self.drag {
            Some(drag) => {
                drag.target = target;
                true
            }
            None => false,
        }
    }

    /// Let go of the grabbed body.
    pub fn release(&mut self) {
        self.drag = None;
    }

    /// The grabbed body and the pull's target, if any.
    pub fn dragged(&self) -> Option<(usize, Vec2)> {
        self.drag.map(|d| (d.body, d.target))
    }

    /// The body whose outline contains `at`, if any (the last added first).
    pub fn body_at(&self, at: Vec2) -> Option<usize> {
        (0..self.bodies.len())
            .rev()
            .find(|&k| self.signed_distance(k, at) <= 0.0)
    }

    /// Whether a fluid particle at `p` would sit inside a body or closer than half the
    /// spacing `d` to its outline, where the body's boundary particles would crush it.
    pub fn covers(&self, p: Vec2, d: f32) -> bool {
        let margin = 0.5 * d * (1.0 - 1.0e-3);
        (0..self.bodies.len()).any(|k| self.signed_distance(k, p) < margin)
    }

    /// Distance from `p` to body `k`'s outline, m: negative inside.
    pub fn signed_distance(&self, k: usize, p: Vec2) -> f32 {
        let rb = &self.world.bodies[self.bodies[k].handle];
        let q = gv(rb.position().inverse_transform_point(rv(p)));
        self.bodies[k].outline.signed_distance(q)
    }

    /// Push `p` (with velocity `v`) out of every body it has entered beyond `margin` (m)
    /// inside the outline: onto the outline, its velocity into the body taken away. Returns
    /// whether it had to be moved.
    pub fn push_out(&self, p: &mut Vec2, v: &mut Vec2, margin: f32) -> bool {
        let mut moved = false;
        for body in &self.bodies {
            let rb = &self.world.bodies[body.handle];
            let c = gv(rb.translation());
            if (*p - c).length_squared() > body.outline.bound().powi(2) {
                continue;
            }
            let q = gv(rb.position().inverse_transform_point(rv(*p)));
            let dist = body.outline.signed_distance(q);
            if dist >= -margin {
                continue;
            }
            let n_local = body.outline.outward_normal(q);
            let n = gv(rb.position().transform_vector(rv(n_local)));
            *p += (-dist) * n;
            let vb = gv(rb.velocity_at_point(rv(*p)));
            let into = (*v - vb).dot(n);
            if into < 0.0 {
                *v -= into * n;
            }
            moved = true;
        }
        moved
    }

    /// Every body's state, in order.
    pub fn states(&self) -> Vec<RigidBodyState> {
        (0..self.bodies.len())
            .map(|k| {
                let (position, angle, velocity, angular_velocity) = self.pose(k);
                let rb = &self.world.bodies[self.bodies[k].handle];
                let mut spec = self.bodies[k].spec.clone();
                spec.angle = angle as f64;
                spec.velocity = [velocity.x as f64, velocity.y as f64];
                spec.angular_velocity = angular_velocity as f64;
                let outline = self.bodies[k]
                    .outline
                    .vertices()
                    .into_iter()
                    .map(|q| gv(rb.position().transform_point(rv(q))))
                    .collect();
                RigidBodyState {
                    position,
                    angle,
                    velocity,
                    angular_velocity,
                    mass: rb.mass(),
                    spec,
                    outline,
                }
            })
            .collect()
    }

    /// The mechanical energy of the bodies that can move, J per metre of depth: `½ m |v|²`
    /// of the centre plus `−m g·(x − origin)` (spin left out; a body held fixed by a joint
    /// does not count).
    pub fn mechanical_energy(&self, gravity: Vec2, origin: Vec2) -> f64 {
        self.bodies
            .iter()
            .filter(|b| b.spec.joint != Some(BodyJoint::Fixed))
            .map(|b| {
                let rb = &self.world.bodies[b.handle];
                let (x, v) = (gv(rb.translation()), gv(rb.linvel()));
                rb.mass() as f64
                    * (0.5 * v.length_squared() as f64 - gravity.dot(x - origin) as f64)
            })
            .sum()
    }

    /// Total linear momentum of the bodies, kg·m/s per metre of depth.
    pub fn momentum(&self) -> Vec2 {
        self.bodies
            .iter()
            .map(|b| {
                let rb = &self.world.bodies[b.handle];
                rb.mass() * gv(rb.linvel())
            })
            .sum()
    }
}

/// Where the tank's kinematic body stands.
fn tank_offset_of(world: &rp::PhysicsWorld, tank: rp::RigidBodyHandle) -> Vec2 {
    gv(world.bodies[tank].translation())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_box_pressed_onto_the_floor_with_ten_times_its_weight_stays_out_of_it() {
        // What a surge slamming a box onto the floor does to it (stress found boxes driven
        // 2 cm in with rapier's default contact springs).
        let (d, dt, g) = (0.01, 0.0005, Vec2::new(0.0, -9.81));
        let mut bodies = RigidBodies::new(Vec2::ZERO, Vec2::new(2.0, 1.0), g);
        let spec = BodySpec::new_box([0.4, 0.2], 1000.0, [1.0, 0.1]);
        bodies.add(&spec, Vec2::ZERO, d, &Kernel::cubic_spline(2.0 * d));
        let mass = 1000.0 * 0.4 * 0.2;
        let push = BodyImpulse {
            linear: 10.0 * mass * dt * g,
            angular: 0.0,
        };
        let mut deepest = 0.0f32;
        for _ in 0..1000 {
            bodies.step(dt, g, &[push], Vec2::ZERO);
            deepest = deepest.max(0.1 - bodies.centre_of_mass(0).y);
        }
        assert!(deepest < 1.0e-3, "the box went {deepest} m into the floor");
    }

    #[test]
    fn the_tank_walls_find_a_box_resting_a_fifth_of_a_millimetre_from_them_wherever_it_stands() {
        // Stress seed 8: a box resting 0.16 mm above the floor lost its contact with it (parry
        // met the box and a cuboid floor metres wide by GJK, which missed one pose in eleven)
        // and fell through the floor. The contact query rapier's narrow phase relies on must
        // find the floor and the side walls at every tank offset and body position.
        let g = Vec2::new(0.0, -9.81);
        let (lo, hi) = (Vec2::ZERO, Vec2::new(4.0, 3.0));
        let bodies = RigidBodies::new(lo, hi, g);
        let walls: Vec<&rp::Collider> = bodies.world.bodies[bodies.tank]
            .colliders()
            .iter()
            .map(|&c| &bodies.world.colliders[c])
            .filter(|c| !c.is_sensor())
            .collect();
        let half = Vec2::new(0.117_545_99, 0.127_633_04);
        let corners = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
            .map(|(sx, sy)| rp::Vector::new(sx * half.x, sy * half.y));
        let block = rp::SharedShape::convex_hull(&corners).unwrap();
        let gap = 1.6e-4;
        let (mut checked, mut missed) = (0, Vec::new());
        for i in 0..400 {
            let tank = rp::Pose::from_translation(rv(Vec2::new(-0.04 + 2.0e-4 * i as f32, 0.0)));
            for j in 0..20 {
                let x = lo.x + 0.3 + 0.17 * j as f32;
                // On the floor, and against the left wall turned a quarter.
                for (centre, angle) in [
                    (Vec2::new(x, lo.y + half.y + gap), -2.5e-5),
                    (
                        Vec2::new(lo.x + half.y + gap, lo.y + 0.3 + 0.12 * j as f32),
                        std::f32::consts::FRAC_PI_2,
                    ),
                ] {
                    let centre = centre + gv(tank.translation);
                    let pose = rp::Pose::new(rv(centre), angle);
                    let nearest = walls
                        .iter()
                        .filter_map(|wall| {
                            let at = tank * *wall.position_wrt_parent().unwrap();
                            rapier2d::parry::query::contact(
                                &at,
                                wall.shape(),
                                &pose,
                                block.as_ref(),
                                0.002,
                            )
                            .unwrap()
                            .map(|c| c.dist)
                        })
                        .fold(f32::INFINITY, f32::min);
                    checked += 1;
                    if (nearest - gap).abs() > 2.0e-5 {
                        missed.push((centre, nearest));
                    }
                }
            }
        }
        assert!(
            missed.is_empty(),
            "{} of {checked} poses: the nearest wall contact was wrong, e.g. {:?}",
            missed.len(),
            &missed[..missed.len().min(3)]
        );
    }
}
