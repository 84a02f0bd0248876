//! The scene's `bodies`: rigid bodies that float, sink and tumble in the water (two-way
//! coupled, [`super`]). Each is a box, a circle or a convex polygon with a density or a mass,
//! placed by its centre; this module holds their JSON form, its validation (every error names
//! the key) and their geometry in the body's own frame.

use serde::{Deserialize, Serialize};

use crate::scene::error::{finite, invalid, point, SceneError};
use crate::scene::shapes::{Point, Tank};

/// Fewest particle spacings a body must measure across: its boundary particles are two layers
/// thick inside the outline (at d/2 and 3d/2), and thinner the layers would cross.
pub const MIN_BODY_SPACINGS: f64 = 3.0;

/// Most rigid bodies a simulation may hold (the scene's and those dropped in later).
pub const MAX_BODIES: usize = 256;

/// The lightest and heaviest body densities accepted, kg/m³: from cork-like foam to twice
/// the density of lead. Outside it the coupling is not tested (a body of 1 kg/m³ is a balloon
/// that the water throws out at hundreds of m/s²).
pub const BODY_DENSITY_RANGE: (f64, f64) = (50.0, 25_000.0);

/// The largest initial speed (m/s) and spin (rad/s) of a body.
pub const MAX_BODY_SPEED: f64 = 100.0;
pub const MAX_BODY_SPIN: f64 = 1_000.0;

/// How far past the tank's walls a body may reach, in particle spacings: a body resting on
/// the floor sinks about 0.3 mm into it (rapier's allowed penetration), and the saved state
/// of such a body must load again.
pub const BODY_WALL_SLACK: f64 = 0.25;

/// Most vertices a polygon may have.
pub const MAX_POLYGON_VERTICES: usize = 64;

/// The outline of a body.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BodyShape {
    /// A rectangle of `size` = [width, height], m, centred on the position.
    Box,
    /// A disc of `radius`, m.
    Circle,
    /// A convex polygon through `points`, m, relative to the position (its centre of mass is
    /// where the body's position puts it only if the points are centred on the origin; the
    /// body turns about its centre of mass).
    Polygon,
}

/// How a body is held, if at all: a fixed joint keeps it where it starts, a hinge lets it turn
/// about `anchor` (m, in the tank's frame).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, tag = "type", rename_all = "snake_case")]
pub enum BodyJoint {
    Fixed,
    Hinge { anchor: Point },
}

/// One rigid body of the scene (`bodies[i]`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BodySpec {
    pub shape: BodyShape,
    /// Box: [width, height], m.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub size: Option<Point>,
    /// Circle: radius, m.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub radius: Option<f64>,
    /// Polygon: vertices relative to `position`, m, in either order; convex.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub points: Option<Vec<Point>>,
    /// Density, kg/m³ (water is 1,000). Give this or `mass`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub density: Option<f64>,
    /// Mass per metre of depth, kg/m (the simulation is 2D). Give this or `density`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mass: Option<f64>,
    /// Centre, m.
    pub position: Point,
    /// Rotation, radians, counter-clockwise.
    #[serde(default)]
    pub angle: f64,
    /// Velocity of the centre, m/s.
    #[serde(default)]
    pub velocity: Point,
    /// Spin, rad/s, counter-clockwise.
    #[serde(default)]
    pub angular_velocity: f64,
    /// Coulomb friction against the tank and other bodies (0 ice … 1 rubber).
    #[serde(default = "default_friction")]
    pub friction: f64,
    /// Held by a joint to the tank; free when left out.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub joint: Option<BodyJoint>,
}

fn default_friction() -> f64 {
    0.5
}

impl BodySpec {
    /// A box of `size` (m) and `density` (kg/m³) at rest with its centre at `position`.
    pub fn new_box(size: Point, density: f64, position: Point) -> Self {
        Self {
            size: Some(size),
            ..Self::bare(BodyShape::Box, density, position)
        }
    }

    /// A circle of `radius` (m) and `density` (kg/m³) at rest with its centre at `position`.
    pub fn new_circle(radius: f64, density: f64, position: Point) -> Self {
        Self {
            radius: Some(radius),
            ..Self::bare(BodyShape::Circle, density, position)
        }
    }

    fn bare(shape: BodyShape, density: f64, position: Point) -> Self {
        Self {
            shape,
            size: None,
            radius: None,
            points: None,
            density: Some(density),
            mass: None,
            position,
            angle: 0.0,
            velocity: [0.0, 0.0],
            angular_velocity: 0.0,
            friction: default_friction(),
            joint: None,
        }
    }

    /// The outline as a convex polygon in the body's frame, counter-clockwise, centred on the
    /// position (`None` for a circle, whose outline is [`Self::radius`]).
    pub fn polygon(&self) -> Option<Vec<Point>> {
        match self.shape {
            BodyShape::Box => {
                let [w, h] = self.size.unwrap_or([0.0, 0.0]);
                let (x, y) = (0.5 * w, 0.5 * h);
                Some(vec![[-x, -y], [x, -y], [x, y], [-x, y]])
            }
            BodyShape::Circle => None,
            BodyShape::Polygon => {
                let mut pts = self.points.clone().unwrap_or_default();
                if signed_area(&pts) < 0.0 {
                    pts.reverse();
                }
                Some(pts)
            }
        }
    }

    /// Area, m².
    pub fn area(&self) -> f64 {
        match self.polygon() {
            Some(p) => signed_area(&p),
            None => {
                let r = self.radius.unwrap_or(0.0);
                std::f64::consts::PI * r * r
            }
        }
    }

    /// Mass per metre of depth, kg/m: `mass`, or density × area.
    pub fn mass_per_depth(&self) -> f64 {
        self.mass
            .unwrap_or_else(|| self.density.unwrap_or(0.0) * self.area())
    }

    /// Density, kg/m³: `density`, or mass / area.
    pub fn mean_density(&self) -> f64 {
        self.density
            .unwrap_or_else(|| self.mass.unwrap_or(0.0) / self.area())
    }

    /// Half the extent of the axis-aligned box around the body in the tank's frame, m.
    pub fn half_extent(&self) -> Point {
        match self.polygon() {
            Some(p) => {
                let (s, c) = self.angle.sin_cos();
                let mut e = [0.0f64, 0.0];
                for v in p {
                    let (x, y) = (c * v[0] - s * v[1], s * v[0] + c * v[1]);
                    e = [e[0].max(x.abs()), e[1].max(y.abs())];
                }
                e
            }
            None => {
                let r = self.radius.unwrap_or(0.0);
                [r, r]
            }
        }
    }

    /// The smallest distance across the body, m (it must hold the sampling's two layers).
    pub fn thickness(&self) -> f64 {
        match self.shape {
            BodyShape::Box => {
                let [w, h] = self.size.unwrap_or([0.0, 0.0]);
                w.min(h)
            }
            BodyShape::Circle => 2.0 * self.radius.unwrap_or(0.0),
            BodyShape::Polygon => {
                // The polygon's width: over its edge directions, the extent across each.
                let p = self.polygon().unwrap_or_default();
                let mut width = f64::INFINITY;
                for k in 0..p.len() {
                    let (a, b) = (p[k], p[(k + 1) % p.len()]);
                    let (ex, ey) = (b[0] - a[0], b[1] - a[1]);
                    let len = ex.hypot(ey);
                    if len == 0.0 {
                        continue;
                    }
                    let (nx, ny) = (-ey / len, ex / len);
                    let across = p
                        .iter()
                        .map(|v| ((v[0] - a[0]) * nx + (v[1] - a[1]) * ny).abs())
                        .fold(0.0, f64::max);
                    width = width.min(across);
                }
                width
            }
        }
    }

    /// Check the body at `key` (`bodies[i]`) for a scene of spacing `d` in `tank`.
    pub fn validate(&self, key: &str, d: f64, tank: &Tank) -> Result<(), SceneError> {
        let positive = |k: &str, v: f64| -> Result<(), SceneError> {
            finite(k, v)?;
            if v > 0.0 {
                Ok(())
            } else {
                Err(invalid(k, format!("must be greater than 0, got {v}")))
            }
        };
        let (needs, other) = match self.shape {
            BodyShape::Box => (
                "size",
                [
                    ("radius", self.radius.is_some()),
                    ("points", self.points.is_some()),
                ],
            ),
            BodyShape::Circle => (
                "radius",
                [
                    ("size", self.size.is_some()),
                    ("points", self.points.is_some()),
                ],
            ),
            BodyShape::Polygon => (
                "points",
                [
                    ("size", self.size.is_some()),
                    ("radius", self.radius.is_some()),
                ],
            ),
        };
        let shape_name = match self.shape {
            BodyShape::Box => "box",
            BodyShape::Circle => "circle",
            BodyShape::Polygon => "polygon",
        };
        if let Some((extra, _)) = other.iter().find(|(_, given)| *given) {
            return Err(invalid(
                format!("{key}.{extra}"),
                format!("a {shape_name} takes `{needs}`, not `{extra}`"),
            ));
        }
        match self.shape {
            BodyShape::Box => {
                let Some(size) = self.size else {
                    return Err(invalid(
                        format!("{key}.size"),
                        "a box needs `size`: [width, height] in m",
                    ));
                };
                positive(&format!("{key}.size[0]"), size[0])?;
                positive(&format!("{key}.size[1]"), size[1])?;
            }
            BodyShape::Circle => {
                let Some(r) = self.radius else {
                    return Err(invalid(
                        format!("{key}.radius"),
                        "a circle needs `radius` in m",
                    ));
                };
                positive(&format!("{key}.radius"), r)?;
            }
            BodyShape::Polygon => {
                let Some(points) = &self.points else {
                    return Err(invalid(
                        format!("{key}.points"),
                        "a polygon needs `points`: its vertices in m",
                    ));
                };
                let pkey = format!("{key}.points");
                if points.len() < 3 || points.len() > MAX_POLYGON_VERTICES {
                    return Err(invalid(
                        pkey,
                        format!(
                            "a polygon needs 3 to {MAX_POLYGON_VERTICES} vertices, got {}",
                            points.len()
                        ),
                    ));
                }
                for (i, p) in points.iter().enumerate() {
                    point(&format!("{pkey}[{i}]"), *p)?;
                }
                if let Some(i) = first_non_convex_vertex(points) {
                    return Err(invalid(
                        format!("{pkey}[{i}]"),
                        "the polygon is not convex here (or its edges cross): give a convex \
                         outline, vertices in order around it",
                    ));
                }
            }
        }
        match (self.density, self.mass) {
            (Some(_), Some(_)) => {
                return Err(invalid(
                    format!("{key}.mass"),
                    "give `density` or `mass`, not both",
                ))
            }
            (None, None) => {
                return Err(invalid(
                    format!("{key}.density"),
                    "a body needs `density` (kg/m³) or `mass` (kg per metre of depth)",
                ))
            }
            (Some(rho), None) => positive(&format!("{key}.density"), rho)?,
            (None, Some(m)) => positive(&format!("{key}.mass"), m)?,
        }
        let rho = self.mean_density();
        let (lo, hi) = BODY_DENSITY_RANGE;
        if !(lo..=hi).contains(&rho) {
            let k = if self.density.is_some() {
                "density"
            } else {
                "mass"
            };
            return Err(invalid(
                format!("{key}.{k}"),
                format!("gives {rho:.1} kg/m³, outside the {lo}–{hi} kg/m³ a body may have"),
            ));
        }
        point(&format!("{key}.position"), self.position)?;
        finite(&format!("{key}.angle"), self.angle)?;
        point(&format!("{key}.velocity"), self.velocity)?;
        finite(&format!("{key}.angular_velocity"), self.angular_velocity)?;
        let speed = self.velocity[0].hypot(self.velocity[1]);
        if speed > MAX_BODY_SPEED {
            return Err(invalid(
                format!("{key}.velocity"),
                format!("{speed} m/s is faster than {MAX_BODY_SPEED} m/s"),
            ));
        }
        if self.angular_velocity.abs() > MAX_BODY_SPIN {
            return Err(invalid(
                format!("{key}.angular_velocity"),
                format!(
                    "{} rad/s spins faster than {MAX_BODY_SPIN} rad/s",
                    self.angular_velocity
                ),
            ));
        }
        finite(&format!("{key}.friction"), self.friction)?;
        if !(0.0..=10.0).contains(&self.friction) {
            return Err(invalid(
                format!("{key}.friction"),
                format!("must be within 0–10, got {}", self.friction),
            ));
        }
        if self.thickness() < MIN_BODY_SPACINGS * d * (1.0 - 1.0e-9) {
            let k = match self.shape {
                BodyShape::Box => "size",
                BodyShape::Circle => "radius",
                BodyShape::Polygon => "points",
            };
            return Err(invalid(
                format!("{key}.{k}"),
                format!(
                    "the body is {:.4} m across, less than {MIN_BODY_SPACINGS} particle spacings \
                     ({:.4} m): it could not hold its two layers of boundary particles",
                    self.thickness(),
                    MIN_BODY_SPACINGS * d
                ),
            ));
        }
        let e = self.half_extent();
        let eps = tank.edge_tolerance();
        // A body resting on the floor or against a wall sinks a fraction of a millimetre into
        // it (rapier's contacts allow that much), and a saved state must load again.
        let slack = BODY_WALL_SLACK * d + eps;
        for axis in 0..2 {
            let (a, b) = (self.position[axis] - e[axis], self.position[axis] + e[axis]);
            if a < tank.min[axis] - slack || b > tank.max[axis] + slack {
                return Err(invalid(
                    format!("{key}.position[{axis}]"),
                    format!(
                        "the body spans {a:.4}–{b:.4} m along {}, outside the tank ({}–{} m, \
                         give or take {:.4} m)",
                        ["x", "y"][axis],
                        tank.min[axis],
                        tank.max[axis],
                        slack
                    ),
                ));
            }
        }
        if let Some(BodyJoint::Hinge { anchor }) = &self.joint {
            point(&format!("{key}.joint.anchor"), *anchor)?;
            for (axis, &a) in anchor.iter().enumerate() {
                if a < tank.min[axis] - eps || a > tank.max[axis] + eps {
                    return Err(invalid(
                        format!("{key}.joint.anchor[{axis}]"),
                        format!("{a} lies outside the tank"),
                    ));
                }
            }
        }
        Ok(())
    }
}

/// The signed area of a polygon (positive counter-clockwise), m².
pub fn signed_area(p: &[Point]) -> f64 {
    let mut a = 0.0;
    for k in 0..p.len() {
        let (u, v) = (p[k], p[(k + 1) % p.len()]);
        a += u[0] * v[1] - v[0] * u[1];
    }
    0.5 * a
}

/// The first vertex where the polygon turns the other way than the rest, or is degenerate
/// (a zero-length edge, a straight angle, zero area, edges winding round more than once).
fn first_non_convex_vertex(p: &[Point]) -> Option<usize> {
    let n = p.len();
    let area = signed_area(p);
    let scale: f64 = p
        .iter()
        .map(|v| v[0].abs().max(v[1].abs()))
        .fold(0.0, f64::max);
    if area.abs() <= 1.0e-12 * scale * scale {
        return Some(0);
    }
    let sign = area.signum();
    for k in 0..n {
        let (a, b, c) = (p[(k + n - 1) % n], p[k], p[(k + 1) % n]);
        let (e1, e2) = ([b[0] - a[0], b[1] - a[1]], [c[0] - b[0], c[1] - b[1]]);
        let cross = e1[0] * e2[1] - e1[1] * e2[0];
        if cross * sign <= 0.0 {
            return Some(k);
        }
    }
    // A star winds round twice with every turn the same way: its exterior angles sum to 4π.
    let total: f64 = (0..n)
        .map(|k| {
            let (a, b, c) = (p[(k + n - 1) % n], p[k], p[(k + 1) % n]);
            let (e1, e2) = ([b[0] - a[0], b[1] - a[1]], [c[0] - b[0], c[1] - b[1]]);
            (e1[0] * e2[1] - e1[1] * e2[0])
                .atan2(e1[0] * e2[0] + e1[1] * e2[1])
                .abs()
        })
        .sum();
    if total > 2.0 * std::f64::consts::PI + 1.0e-6 {
        return Some(0);
    }
    None
}

#[cfg(test)]
mod tests {
    use crate::scene::Scene;

    /// The error for a dam break whose `bodies` is `bodies` (JSON).
    fn error(bodies: &str) -> String {
        Scene::from_json(&format!(
            r#"{{"particle_radius": 0.02, "bodies": {bodies}}}"#
        ))
        .expect_err(bodies)
        .to_string()
    }

    #[test]
    fn the_issues_example_is_accepted() {
        let s = Scene::from_json(
            r#"{"bodies": [{"shape": "box", "size": [0.4, 0.2], "density": 500, "position": [1.0, 0.8]},
                {"shape": "circle", "radius": 0.1, "density": 250, "position": [0.5, 0.8]}]}"#,
        )
        .unwrap();
        assert_eq!(s.bodies.len(), 2);
        assert!((s.bodies[0].mass_per_depth() - 40.0).abs() < 1e-9);
        // Written back, a scene reads the same.
        assert_eq!(Scene::from_json(&s.to_json()).unwrap(), s);
    }

    #[test]
    fn bad_bodies_are_refused_naming_the_key() {
        for (bodies, key) in [
            (
                r#"[{"shape": "box", "size": [0.4, 0.2], "density": 500, "position": [3.9, 0.8]}]"#,
                "`bodies[0].position[0]`",
            ),
            (
                r#"[{"shape": "box", "size": [0.4, 0.2], "density": 500, "position": [1, -0.05]}]"#,
                "`bodies[0].position[1]`",
            ),
            (
                r#"[{"shape": "box", "size": [0.4, 0], "density": 500, "position": [1, 1]}]"#,
                "`bodies[0].size[1]`",
            ),
            (
                r#"[{"shape": "box", "size": [-0.4, 0.2], "density": 500, "position": [1, 1]}]"#,
                "`bodies[0].size[0]`",
            ),
            (
                r#"[{"shape": "circle", "radius": 0, "density": 500, "position": [1, 1]}]"#,
                "`bodies[0].radius`",
            ),
            (
                r#"[{"shape": "box", "size": [0.4, 0.2], "density": 0, "position": [1, 1]}]"#,
                "`bodies[0].density`",
            ),
            (
                r#"[{"shape": "box", "size": [0.4, 0.2], "density": -5, "position": [1, 1]}]"#,
                "`bodies[0].density`",
            ),
            (
                r#"[{"shape": "box", "size": [0.4, 0.2], "mass": 0, "position": [1, 1]}]"#,
                "`bodies[0].mass`",
            ),
            (
                r#"[{"shape": "box", "size": [0.4, 0.2], "position": [1, 1]}]"#,
                "`bodies[0].density`",
            ),
            (
                r#"[{"shape": "box", "size": [0.4, 0.2], "density": 5, "position": [1, 1]}]"#,
                "`bodies[0].density`",
            ),
            (
                r#"[{"shape": "box", "size": [0.4, 0.2], "density": 500, "mass": 3, "position": [1, 1]}]"#,
                "`bodies[0].mass`",
            ),
            (
                r#"[{"shape": "box", "radius": 0.2, "density": 500, "position": [1, 1]}]"#,
                "`bodies[0].radius`",
            ),
            (
                r#"[{"shape": "box", "size": [0.4, 0.05], "density": 500, "position": [1, 1]}]"#,
                "`bodies[0].size`",
            ),
            (
                r#"[{"shape": "polygon", "points": [[0, 0], [0.4, 0], [0.1, 0.1], [0, 0.4]], "density": 500, "position": [1, 1]}]"#,
                "`bodies[0].points[2]`",
            ),
            (
                r#"[{"shape": "polygon", "points": [[0, 0], [0.4, 0], [0.8, 0]], "density": 500, "position": [1, 1]}]"#,
                "`bodies[0].points",
            ),
            (
                r#"[{"shape": "polygon", "points": [[0, 0], [0.4, 0]], "density": 500, "position": [1, 1]}]"#,
                "`bodies[0].points`",
            ),
            (
                r#"[{"shape": "box", "size": [0.4, 0.2], "density": 500, "position": [1, 1], "velocity": [1000, 0]}]"#,
                "`bodies[0].velocity`",
            ),
            (
                r#"[{"shape": "box", "size": [0.4, 0.2], "density": 500, "position": [1, 1], "joint": {"type": "hinge", "anchor": [9, 1]}}]"#,
                "`bodies[0].joint.anchor[0]`",
            ),
            (
                r#"[{"shape": "cone", "size": [0.4, 0.2], "density": 500, "position": [1, 1]}]"#,
                "bodies[0].shape",
            ),
            (
                r#"[{"shape": "box", "size": [0.4, 0.2], "density": 500, "position": [1, 1], "colour": 3}]"#,
                "bodies[0]",
            ),
            (
                r#"[{"shape": "box", "size": [0.4, 0.2], "density": 500, "position": [1, 1]}], "solver": {"method": "wcsph"}"#,
                "`solver.method`",
            ),
            (
                r#"[{"shape": "box", "size": [0.4, 0.2], "density": 500, "position": [1, 1]},
                    {"shape": "circle", "radius": 0.1, "density": 500, "position": [1.25, 1.05]}]"#,
                "`bodies[1].position`: the body overlaps bodies[0]",
            ),
            (
                r#"[{"shape": "box", "size": [0.4, 0.2], "density": 500, "position": [1, 1]}],
                    "obstacles": [{"type": "rect", "min": [1.1, 0], "max": [1.5, 0.95]}]"#,
                "`bodies[0].position`: the body overlaps obstacles[0]",
            ),
            (
                r#"[{"shape": "box", "size": [0.4, 0.2], "density": 500, "position": [1, 1]}],
                    "obstacles": [{"type": "polyline", "points": [[0.5, 0.5], [1.5, 1.5]]}]"#,
                "`bodies[0].position`: the body overlaps obstacles[0]",
            ),
        ] {
            let e = error(bodies);
            assert!(e.contains(key), "{bodies}: {e} does not name {key}");
            assert!(!e.contains("  "), "a run of spaces in: {e}");
        }
        // Touching is allowed: side by side, and a box on a rect obstacle.
        for ok in [
            r#"[{"shape": "box", "size": [0.4, 0.2], "density": 500, "position": [1, 1]},
                {"shape": "box", "size": [0.4, 0.2], "density": 500, "position": [1.4, 1]}]"#,
            r#"[{"shape": "box", "size": [0.4, 0.2], "density": 500, "position": [1, 1]}],
                "obstacles": [{"type": "rect", "min": [0.5, 0.5], "max": [1.5, 0.9]}]"#,
        ] {
            Scene::from_json(&format!(r#"{{"particle_radius": 0.02, "bodies": {ok}}}"#)).unwrap();
        }
    }

    #[test]
    fn a_star_that_turns_the_same_way_at_every_vertex_is_not_convex() {
        // A pentagram: every turn is to the left, but it winds round twice.
        let star: Vec<String> = (0..5)
            .map(|k| {
                let a = std::f64::consts::TAU * (2 * k) as f64 / 5.0;
                format!("[{:.6}, {:.6}]", 0.3 * a.cos(), 0.3 * a.sin())
            })
            .collect();
        let e = error(&format!(
            r#"[{{"shape": "polygon", "points": [{}], "density": 500, "position": [2, 1.5]}}]"#,
            star.join(", ")
        ));
        assert!(e.contains("`bodies[0].points"), "{e}");
        // The same vertices in order round the outline form a convex pentagon.
        let pentagon: Vec<String> = (0..5)
            .map(|k| {
                let a = std::f64::consts::TAU * k as f64 / 5.0;
                format!("[{:.6}, {:.6}]", 0.3 * a.cos(), 0.3 * a.sin())
            })
            .collect();
        Scene::from_json(&format!(
            r#"{{"particle_radius": 0.02, "bodies": [{{"shape": "polygon", "points": [{}], "density": 500, "position": [2, 1.5]}}]}}"#,
            pentagon.join(", ")
        ))
        .unwrap();
    }
}
