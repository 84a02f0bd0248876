//! Rigid bodies in the viewer: the box or circle that `b` and `o` (or the panel's buttons)
//! drop, sized for the scene and kept inside the tank, and how bodies are drawn.

use dfsph::rigid::spec::MIN_BODY_SPACINGS;
use dfsph::rigid::RigidBodyState;
use dfsph::scene::{BodyShape, BodySpec};
use dfsph::{Simulation, Vec2};
use eframe::egui::{self, Color32, Shape, Stroke};

use crate::render::ViewTransform;

/// The density of the next dropped body before the panel changes it, kg/m³: pine wood, so
/// the first body a user drops floats half out of the water.
pub const DEFAULT_BODY_DENSITY: f64 = 500.0;

/// Fewest particle spacings a dropped body measures across: more than the solver's
/// [`MIN_BODY_SPACINGS`], so that it is visibly a body and not a clump of wall particles.
pub const DROP_SPACINGS: f64 = 4.0;
const _: () = assert!(DROP_SPACINGS >= MIN_BODY_SPACINGS);

/// The body `shape` dropped centred at `at` (m, where the tank stands now) or, without a
/// point, at the top of the tank's middle: a box 10 % of the tank's width by half that, or a
/// circle of radius 4 % of it, never under [`DROP_SPACINGS`] spacings across nor over half
/// the tank, of `density` (kg/m³), at rest, its centre moved so that it fits in the tank.
/// The position is in the tank's rest frame, as [`dfsph::Action::AddBody`] takes it.
pub fn drop_spec(sim: &Simulation, shape: BodyShape, at: Option<Vec2>, density: f64) -> BodySpec {
    let scene = sim.scene();
    let tank = &scene.tank;
    let d = scene.spacing();
    let (w, h) = (tank.max[0] - tank.min[0], tank.max[1] - tank.min[1]);
    let largest = 0.5 * w.min(h);
    let mut spec = match shape {
        BodyShape::Circle => {
            let r = (0.04 * w).max(0.5 * DROP_SPACINGS * d).min(0.5 * largest);
            BodySpec::new_circle(r, density, [0.0, 0.0])
        }
        // A polygon is not dropped by the viewer: a box stands in.
        BodyShape::Box | BodyShape::Polygon => {
            let height = (0.05 * w).max(DROP_SPACINGS * d).min(0.5 * largest);
            let width = (2.0 * height).min(largest);
            BodySpec::new_box([width, height], density, [0.0, 0.0])
        }
    };
    let e = spec.half_extent();
    // The tank's shake: the cursor is where the tank stands now, the body goes in its rest
    // frame.
    let (lo, _) = sim.tank_interior();
    let offset = [f64::from(lo.x) - tank.min[0], f64::from(lo.y) - tank.min[1]];
    let want = match at {
        Some(p) => [f64::from(p.x) - offset[0], f64::from(p.y) - offset[1]],
        None => [0.5 * (tank.min[0] + tank.max[0]), tank.max[1] - e[1] - d],
    };
    // Half a spacing clear of the walls, so that rounding never puts it outside.
    let margin = 0.5 * d;
    for axis in 0..2 {
        let lo = tank.min[axis] + e[axis] + margin;
        let hi = tank.max[axis] - e[axis] - margin;
        spec.position[axis] = if lo <= hi {
            want[axis].clamp(lo, hi)
        } else {
            0.5 * (tank.min[axis] + tank.max[axis])
        };
    }
    spec
}

/// Fill of a body of `density` (kg/m³): [`dfsph_io::colormap::body_fill`], the colour the
/// CPU rasteriser (`dfsph2d run --format png`, the recordings) fills it with too.
pub fn body_fill(density: f64) -> Color32 {
    let [r, g, b] = dfsph_io::colormap::body_fill(density);
    Color32::from_rgb(r, g, b)
}

/// Outline of every body: [`dfsph_io::colormap::BODY_EDGE`].
pub const BODY_EDGE: Color32 = {
    let [r, g, b] = dfsph_io::colormap::BODY_EDGE;
    Color32::from_rgb(r, g, b)
};

/// Draw every body, filled with its outline, in the particles' world-to-screen mapping;
/// a circle also gets a radius, so that its spin shows.
pub fn draw_bodies(painter: &egui::Painter, transform: &ViewTransform, bodies: &[RigidBodyState]) {
    for body in bodies {
        let points: Vec<_> = body
            .outline
            .iter()
            .map(|&p| transform.to_screen(p))
            .collect();
        if points.len() < 3 {
            continue;
        }
        let fill = body_fill(body.spec.mean_density());
        painter.add(Shape::convex_polygon(
            points.clone(),
            fill,
            Stroke::new(1.5_f32, BODY_EDGE),
        ));
        if body.spec.shape == BodyShape::Circle {
            let centre = transform.to_screen(body.position);
            painter.line_segment([centre, points[0]], Stroke::new(1.5_f32, BODY_EDGE));
        }
    }
}

/// Where a body's grabbed point is now: `local` is the point in the body's frame, as
/// [`body_frame_point`] gave it at the grab.
pub fn grabbed_point(body: &RigidBodyState, local: Vec2) -> Vec2 {
    body.position + Vec2::from_angle(body.angle).rotate(local)
}

/// The world point `at` (m) in `body`'s frame.
pub fn body_frame_point(body: &RigidBodyState, at: Vec2) -> Vec2 {
    Vec2::from_angle(-body.angle).rotate(at - body.position)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sim(name: &str) -> Simulation {
        let mut s = dfsph::scene::builtin(name).unwrap();
        s.particle_radius = 0.02;
        Simulation::new(&s).unwrap()
    }

    #[test]
    fn dropped_bodies_are_sized_for_the_tank_and_fit_in_it() {
        let sim = sim("dam-break");
        let tank = sim.scene().tank.clone();
        let w = tank.max[0] - tank.min[0];
        let d = sim.scene().spacing();
        let b = drop_spec(&sim, BodyShape::Box, Some(Vec2::new(2.0, 1.0)), 500.0);
        let size = b.size.unwrap();
        assert!((size[0] - 0.1 * w).abs() < 1e-9 && (size[1] - 0.05 * w).abs() < 1e-9);
        assert_eq!(b.position, [2.0, 1.0]);
        b.validate("body", d, &tank).unwrap();
        let c = drop_spec(&sim, BodyShape::Circle, None, 500.0);
        assert!((c.radius.unwrap() - 0.04 * w).abs() < 1e-9);
        c.validate("body", d, &tank).unwrap();
        // A drop in a corner, outside the tank, is moved in.
        for at in [Vec2::new(-5.0, -5.0), Vec2::new(50.0, 50.0)] {
            for shape in [BodyShape::Box, BodyShape::Circle] {
                let s = drop_spec(&sim, shape, Some(at), 500.0);
                s.validate("body", d, &tank).unwrap();
            }
        }
    }

    #[test]
    fn dropped_bodies_are_never_under_four_spacings_across() {
        let mut s = dfsph::scene::builtin("dam-break").unwrap();
        s.particle_radius = 0.05;
        let sim = Simulation::new(&s).unwrap();
        let d = sim.scene().spacing();
        let c = drop_spec(&sim, BodyShape::Circle, None, 500.0);
        assert!(2.0 * c.radius.unwrap() >= DROP_SPACINGS * d - 1e-12);
        let b = drop_spec(&sim, BodyShape::Box, None, 500.0);
        assert!(b.size.unwrap()[1] >= DROP_SPACINGS * d - 1e-12);
        b.validate("body", d, &sim.scene().tank).unwrap();
    }

    #[test]
    fn light_bodies_are_paler_than_heavy_ones() {
        let light = body_fill(100.0);
        let heavy = body_fill(8000.0);
        assert!(light.r() > heavy.r() && light.g() > heavy.g());
    }

    #[test]
    fn a_grabbed_point_turns_with_its_body() {
        let mut sim = sim("hydrostatic");
        let spec = drop_spec(&sim, BodyShape::Box, None, 500.0);
        assert!(sim
            .apply(&dfsph::Action::AddBody { body: spec })
            .rejected
            .is_none());
        let mut body = sim.rigid_bodies().remove(0);
        let at = body.position + Vec2::new(0.05, 0.01);
        let local = body_frame_point(&body, at);
        assert!((grabbed_point(&body, local) - at).length() < 1e-6);
        body.angle = std::f32::consts::FRAC_PI_2;
        let turned = grabbed_point(&body, local);
        assert!((turned - (body.position + Vec2::new(-0.01, 0.05))).length() < 1e-5);
    }
}
