//! A body's outline in its own frame, prepared once for the queries every step makes of it:
//! the signed distance and the outward normal at a point (containment, hit tests), the
//! bounding radius, and the vertices to draw.

use glam::Vec2;

use super::spec::BodySpec;

/// Vertices of the polygon a circle is drawn as.
const CIRCLE_VERTICES: usize = 48;

/// A convex polygon (its edges' starts and outward unit normals, counter-clockwise) or a
/// circle, centred on the body's position.
#[derive(Clone, Debug)]
pub(crate) enum Outline {
    Polygon {
        edges: Vec<(Vec2, Vec2)>,
        bound: f32,
    },
    Circle {
        radius: f32,
    },
}

impl Outline {
    pub fn of(spec: &BodySpec) -> Self {
        match spec.polygon() {
            Some(p) => {
                let v: Vec<Vec2> = p
                    .iter()
                    .map(|q| Vec2::new(q[0] as f32, q[1] as f32))
                    .collect();
                let n = v.len();
                let edges = (0..n)
                    .map(|k| {
                        let e = (v[(k + 1) % n] - v[k]).normalize_or_zero();
                        (v[k], Vec2::new(e.y, -e.x))
                    })
                    .collect();
                let bound = v.iter().map(|q| q.length()).fold(0.0, f32::max);
                Self::Polygon { edges, bound }
            }
            None => Self::Circle {
                radius: spec.radius.unwrap_or(0.0) as f32,
            },
        }
    }

    /// The largest distance from the centre to the outline, m.
    pub fn bound(&self) -> f32 {
        match self {
            Self::Polygon { bound, .. } => *bound,
            Self::Circle { radius } => *radius,
        }
    }

    /// Distance from `q` to the outline, negative inside; for a polygon, the largest distance
    /// beyond its edges' lines (exact inside, a lower bound outside near a corner).
    pub fn signed_distance(&self, q: Vec2) -> f32 {
        match self {
            Self::Polygon { edges, .. } => edges
                .iter()
                .map(|&(a, n)| (q - a).dot(n))
                .fold(f32::NEG_INFINITY, f32::max),
            Self::Circle { radius } => q.length() - radius,
        }
    }

    /// The outward normal of the side nearest to `q` (inside the outline).
    pub fn outward_normal(&self, q: Vec2) -> Vec2 {
        match self {
            Self::Polygon { edges, .. } => edges
                .iter()
                .max_by(|x, y| (q - x.0).dot(x.1).total_cmp(&(q - y.0).dot(y.1)))
                .map_or(Vec2::Y, |&(_, n)| n),
            Self::Circle { .. } => q.try_normalize().unwrap_or(Vec2::Y),
        }
    }

    /// The vertices, counter-clockwise (a circle as a 48-gon).
    pub fn vertices(&self) -> Vec<Vec2> {
        match self {
            Self::Polygon { edges, .. } => edges.iter().map(|&(a, _)| a).collect(),
            Self::Circle { radius } => (0..CIRCLE_VERTICES)
                .map(|k| {
                    let a = std::f32::consts::TAU * k as f32 / CIRCLE_VERTICES as f32;
                    radius * Vec2::new(a.cos(), a.sin())
                })
                .collect(),
        }
    }
}

/// The signed distance (m, negative inside) to the outline of a body placed by `spec` with
/// its centre at `centre` (m), before it is added.
pub(crate) fn signed_distance_of(spec: &BodySpec, centre: Vec2) -> impl Fn(Vec2) -> f32 {
    let outline = Outline::of(spec);
    let unrotate = Vec2::from_angle(-(spec.angle as f32));
    move |p| outline.signed_distance(unrotate.rotate(p - centre))
}

/// A body placed by `spec` (its centre at `spec.position`, m) as the overlap test sees it:
/// points along its outline half a spacing apart, and its signed distance.
pub(crate) struct Placed<F> {
    pub outline: Vec<Vec2>,
    pub distance: F,
}

/// [`Placed`] for the body `spec` at spacing `d` (m).
pub(crate) fn placed(spec: &BodySpec, d: f32) -> Placed<impl Fn(Vec2) -> f32> {
    let centre = Vec2::new(spec.position[0] as f32, spec.position[1] as f32);
    Placed {
        outline: outline_points(spec, 0.5 * d),
        distance: signed_distance_of(spec, centre),
    }
}

impl<F: Fn(Vec2) -> f32> Placed<F> {
    /// Whether two bodies overlap: an outline point of either lies more than a quarter
    /// spacing `d` inside the other. Bodies may touch: a scene file may have one resting on
    /// another, their boundary particles' balls (radius d/2) meeting.
    pub fn overlaps(&self, other: &Self, d: f32) -> bool {
        let inside =
            |points: &[Vec2], distance: &F| points.iter().any(|&p| distance(p) < -0.25 * d);
        inside(&self.outline, &other.distance) || inside(&other.outline, &self.distance)
    }
}

/// Points along the outline of a body placed by `spec` (m, the tank's frame), at most `step`
/// (m) apart.
pub(crate) fn outline_points(spec: &BodySpec, step: f32) -> Vec<Vec2> {
    let centre = Vec2::new(spec.position[0] as f32, spec.position[1] as f32);
    let rotate = Vec2::from_angle(spec.angle as f32);
    let corners: Vec<Vec2> = Outline::of(spec)
        .vertices()
        .into_iter()
        .map(|q| centre + rotate.rotate(q))
        .collect();
    let mut points = Vec::new();
    for (k, &a) in corners.iter().enumerate() {
        let b = corners[(k + 1) % corners.len()];
        let n = ((b - a).length() / step).ceil().max(1.0) as usize;
        points.extend((0..n).map(|i| a.lerp(b, i as f32 / n as f32)));
    }
    points
}
