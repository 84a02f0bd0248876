//! A probe as a scene names it: what it reads and where, and the checks of its keys. The
//! readings are taken by [`crate::probes`].

use serde::{Deserialize, Serialize};

use super::error::{invalid, SceneError};
use super::shapes::{Point, Tank};

/// One probe of a scene's `probes` list.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, tag = "type", rename_all = "snake_case")]
pub enum Probe {
    /// Fluid pressure at a point (inside the water, or on a wall face), Pa.
    Pressure {
        /// Column name in `probes.csv`.
        name: String,
        /// Position, m.
        at: Point,
    },
    /// Height of the free surface above the tank floor along the vertical line at `x`, m.
    WaterLevel {
        /// Column name in `probes.csv`.
        name: String,
        /// Horizontal position, m.
        x: f64,
    },
}

impl Probe {
    /// The probe's name (its column in `probes.csv`).
    pub fn name(&self) -> &str {
        match self {
            Probe::Pressure { name, .. } | Probe::WaterLevel { name, .. } => name,
        }
    }

    /// Unit of the reading.
    pub fn unit(&self) -> &'static str {
        match self {
            Probe::Pressure { .. } => "Pa",
            Probe::WaterLevel { .. } => "m",
        }
    }
}

/// Check a scene's `probes` in its `tank`: names non-empty, unique, usable as CSV column names and not
/// `time`; positions finite and inside the tank (its walls included). Called by
/// [`super::Scene::validate`].
pub(crate) fn validate(tank: &Tank, probes: &[Probe]) -> Result<(), SceneError> {
    let eps = tank.edge_tolerance();
    let inside = |key: String, v: f64, axis: usize| -> Result<(), SceneError> {
        if !v.is_finite() {
            return Err(invalid(key, format!("must be a finite number, got {v}")));
        }
        if v < tank.min[axis] - eps || v > tank.max[axis] + eps {
            return Err(invalid(
                key,
                format!(
                    "{v} lies outside the tank ({} to {}); a probe must be inside it or on a wall",
                    tank.min[axis], tank.max[axis]
                ),
            ));
        }
        Ok(())
    };
    let mut seen: Vec<&str> = Vec::new();
    for (i, probe) in probes.iter().enumerate() {
        let key = format!("probes[{i}]");
        let name = probe.name();
        if name.trim().is_empty() {
            return Err(invalid(format!("{key}.name"), "must not be empty"));
        }
        if name.chars().any(|c| matches!(c, ',' | '"' | '\n' | '\r')) || name != name.trim() {
            return Err(invalid(
                format!("{key}.name"),
                format!(
                    "{name:?} cannot be a CSV column name (no commas, quotes, line breaks or \
                     surrounding spaces)"
                ),
            ));
        }
        if name == "time" {
            return Err(invalid(
                format!("{key}.name"),
                "`time` is the first column of probes.csv; choose another name",
            ));
        }
        if seen.contains(&name) {
            return Err(invalid(
                format!("{key}.name"),
                format!("{name:?} is used by another probe; names must be unique"),
            ));
        }
        seen.push(name);
        match probe {
            Probe::Pressure { at, .. } => {
                inside(format!("{key}.at[0]"), at[0], 0)?;
                inside(format!("{key}.at[1]"), at[1], 1)?;
            }
            Probe::WaterLevel { x, .. } => inside(format!("{key}.x"), *x, 0)?,
        }
    }
    Ok(())
}
