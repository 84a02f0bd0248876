//! The geometry a scene names: points, the tank and the obstacles.

use serde::{Deserialize, Serialize};

/// A point or vector in metres (or m/s², for gravity), as `[x, y]` in JSON.
pub type Point = [f64; 2];

/// The tank interior `[min, max]` in metres.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Tank {
    /// Lower-left corner of the interior, metres.
    pub min: Point,
    /// Upper-right corner of the interior, metres.
    pub max: Point,
}

impl Tank {
    /// The largest |coordinate| of the tank's corners, m, and the key that names it
    /// (`tank.min[0]` … `tank.max[1]`).
    pub fn farthest_coordinate(&self) -> (f64, String) {
        let corners = [("min", self.min), ("max", self.max)];
        let mut best = (0.0f64, "tank.max[0]".to_string());
        for (name, corner) in corners {
            for (axis, v) in corner.iter().enumerate() {
                if v.abs() > best.0 {
                    best = (v.abs(), format!("tank.{name}[{axis}]"));
                }
            }
        }
        best
    }

    /// Coordinates closer than this count as equal when a scene places something on or
    /// inside the tank's boundary (1e-9 of its larger side: rounding in a scene file), m.
    pub fn edge_tolerance(&self) -> f64 {
        1.0e-9 * (self.max[0] - self.min[0]).max(self.max[1] - self.min[1])
    }
}

/// A static obstacle, sampled with boundary particles two layers thick.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, tag = "type", rename_all = "snake_case")]
pub enum Obstacle {
    /// A solid axis-aligned box, metres.
    Rect { min: Point, max: Point },
    /// A wall along a polyline through the given points, metres.
    Polyline { points: Vec<Point> },
    /// A wall made of the boundary particles listed, metres: what is left of an obstacle or
    /// a drawn wall after part of it was erased in the viewer (a saved state).
    Particles { positions: Vec<Point> },
}
