//! Probes: virtual instruments placed in a scene and read every step, as in a laboratory tank.
//!
//! - A **pressure probe** reads the fluid pressure at a point, in pascals. Put it inside the
//!   water for a point gauge, or on a wall face (for example on the tank's right wall,
//!   `x = tank.max[0]`) for a wall pressure sensor.
//! - A **water-level gauge** reads the height of the free surface above the tank floor at a
//!   given x, in metres, like a resistive wave gauge.
//!
//! Probe coordinates are scene coordinates and move with the tank when it is shaken (a sensor
//! is fixed to the tank, not to the room).
//!
//! ## Methods
//!
//! **Wall pressure.** A pressure probe on a face of the tank (`at` on the tank's boundary, for
//! example `x = tank.max[0]`) is a wall sensor, and reads what a transducer in the wall reads:
//! the normal force per unit length that the fluid exerts on the wall there. By Newton's third
//! law that force is the reaction to the wall's pressure force on the fluid (Akinci et al.
//! 2012, eq. 10, as the solver applies it):
//!
//! ```text
//! f_b = m · Σ_i (p_i/ρ0 + κᵛ_i/Δt) · Ψ_b ∇W(x_i − x_b)        (force on boundary particle b)
//! p_wall(x) = Σ_b (f_b · n) · ω(τ_b),  ω(τ) = (1 − |τ|/a)/a for |τ| < a
//! ```
//!
//! over the tank's boundary particles behind the face (both layers), n the face's normal into
//! the wall, τ_b the distance along the face from the sensor, a the spacing of the wall's
//! particle columns: the tent weights of columns spaced a apart sum to 1/a, so the reading is a
//! force per unit length, in pascals. Both solves' pressures count (κᵛ/Δt is the divergence
//! solve's impulse spread over the step; it carries much of an impact). In equilibrium the
//! readings integrate exactly to the weight of the water on the floor and to ½ρ0·g·H² on a
//! side wall, even though the fluid particles in the first layer carry a higher pressure than
//! the continuum would (the single-sided Akinci wall term needs it to hold them up): an
//! interpolation of those pressures onto the face reads up to 60 % high.
//!
//! **Pressure** at any other point `x`: the mechanical pressure, that is the force the fluid
//! transmits across lines near `x` per unit length, as a transducer membrane would feel it.
//! It is the virial (Irving & Kirkwood 1950; Hardy 1982) of the pressure forces the solver
//! applies between particle pairs, localised by the kernel W with support h as the window:
//!
//! ```text
//! f_ij = −m V0 (q_i + q_j) ∇W_ij,   f_ib = −m Ψ_b q_i ∇W_ib     (q = p/ρ0 + κᵛ/Δt, as above)
//! p(x) = ½ Σ_pairs (f_ij · x_ij) ∫₀¹ W(x − x_j − s·x_ij) ds / φ(x)  +  ρ0 g·(x − c(x))
//! ```
//!
//! over fluid–fluid and fluid–wall pairs, φ(x) = Σ_j V0 W(x − x_j) the fluid fraction of the
//! window and c(x) its fluid's centroid (g the current gravity vector). Dividing by φ averages
//! over the part of the window that holds fluid, and the last term carries that average from
//! the fluid's centroid to `x`, so that a probe near the free surface still reads the
//! hydrostatic pressure at its own height. The velocity-fluctuation (kinetic) part of the
//! virial is left out: in SPH it is numerical noise, not a pressure.
//!
//! Why not interpolate the particles' pressures: the pressure solve determines them only up to
//! modes that exert no force, such as rows of particles alternately above and below the mean
//! on a lattice (the SPH pressure operator cannot see them, so nothing removes them). In a
//! settled tank such a pattern sits on a few rows at ±15 % of ρ0·g·H, and a Shepard
//! interpolation centred on a row reads 36 % of the pattern's amplitude. The pair sums
//! q_i + q_j across rows do not see it at all, and the virial, which sees it only through the
//! pairs within a row, reads 12 % of it (the test below). A probe with no fluid particle within
//! h is **dry** and reads 0 (a dry wall sensor too).
//!
//! **Water level** at `x`: the fluid fraction `φ(y) = Σ_j V0 W((x, y) − x_j)` (V0 = m/ρ0, the
//! volume of a particle at rest; φ ≈ 1 inside the water, ≈ 0.5 on a flat free surface, 0 in
//! air) is sampled along the vertical line through `x` from the tank top down, every d/4
//! (d = particle spacing). The level is the highest y where φ ≥ 0.5, located between samples
//! by linear interpolation, measured from the tank floor. Detached spray counts if it is
//! dense enough to reach φ ≥ 0.5 on the line (a gauge in the laboratory sees it too). A dry
//! gauge reads 0. Place gauges at least h/2 = 2r from a side wall: on the wall face itself
//! the kernel is half cut off, φ stays near 0.5 and the gauge under-reads.

use glam::Vec2;

use crate::scene::{Point, Probe, Scene};
use crate::Simulation;

/// Where the tank has moved since the start (shaking), m: probe positions follow it.
fn tank_offset(sim: &Simulation) -> Vec2 {
    let (lo, _) = sim.tank_interior();
    let s = sim.scene();
    lo - Vec2::new(s.tank.min[0] as f32, s.tank.min[1] as f32)
}

/// Read every probe of the simulation's scene, in order: Pa for pressure probes, m for
/// water-level gauges.
pub fn sample_all(sim: &Simulation) -> Vec<f64> {
    sim.scene().probes.iter().map(|p| sample(sim, p)).collect()
}

/// Read one probe (its position given in scene coordinates; it follows the tank).
pub fn sample(sim: &Simulation, probe: &Probe) -> f64 {
    let off = tank_offset(sim);
    match probe {
        Probe::Pressure { at, .. } => {
            let x = Vec2::new(at[0] as f32, at[1] as f32) + off;
            match tank_face_normal(sim.scene(), *at) {
                Some(normal) => wall_pressure_at(sim, x, normal),
                None => pressure_at(sim, x).unwrap_or(0.0),
            }
        }
        Probe::WaterLevel { x, .. } => water_level_at(sim, *x as f32 + off.x),
    }
}

/// The face of the tank that the scene point `at` lies on, as the unit normal pointing out of
/// the water into the wall; `None` inside the tank. In a corner the side wall wins.
pub fn tank_face_normal(scene: &Scene, at: Point) -> Option<Vec2> {
    let (lo, hi) = (scene.tank.min, scene.tank.max);
    let eps = scene.tank.edge_tolerance();
    if (at[0] - lo[0]).abs() <= eps {
        Some(Vec2::NEG_X)
    } else if (at[0] - hi[0]).abs() <= eps {
        Some(Vec2::X)
    } else if (at[1] - lo[1]).abs() <= eps {
        Some(Vec2::NEG_Y)
    } else if (at[1] - hi[1]).abs() <= eps {
        Some(Vec2::Y)
    } else {
        None
    }
}

/// Normal pressure on the tank wall at the world point `x` of a face with outward (into the
/// wall) normal `normal`, Pa: the fluid's force on the wall's boundary particles per unit
/// length (see the module documentation). 0 when no fluid touches the wall there.
pub fn wall_pressure_at(sim: &Simulation, x: Vec2, normal: Vec2) -> f64 {
    let kernel = sim.kernel();
    let h = kernel.support();
    let d = sim.spacing();
    let tangent = normal.perp();
    let (lo, hi) = sim.tank_interior();
    // Half-width of the window along the face: the spacing of the wall's particles along it.
    // The square sampling stretches d to fit the wall exactly; the hexagonal lattice has its
    // row spacing along floor and ceiling. Along the sides its rows alternate between two
    // depths, so the window spans two rows and weighs both kinds alike.
    let a = match sim.scene().packing {
        crate::scene::Packing::Square => {
            let length = ((hi - lo) * tangent).abs().max_element();
            length / (length / d).round().max(1.0)
        }
        crate::scene::Packing::Hexagonal if normal.y != 0.0 => {
            crate::packing::ROW_SPACING as f32 * d
        }
        crate::scene::Packing::Hexagonal => 2.0 * crate::packing::ROW_DISTANCE as f32 * d,
    };
    // The walls' share of the push, as the solver applies it: Akinci's wall feels the
    // particle's own pressure once; the mirrored walls of the conjugate-gradient solve feel it
    // twice, plus the hydrostatic part of the ghost pressure, g·(x_b − x_i)
    // (`forces::non_pressure_accelerations`).
    let walls = sim.boundary_model();
    let wall_weight = walls.gradient_weight();
    let gravity = walls
        .hydrostatic_ghost_gradient(sim.gravity())
        .unwrap_or(Vec2::ZERO);
    let mass = sim.particle_mass() as f64;
    let push = sim.applied_pressure_over_rho0();
    // The wall's particles under the sensor: tank body, behind the face, within a of the
    // sensor along it.
    let walls: Vec<(Vec2, f32, f32)> = sim
        .boundary_positions()
        .iter()
        .zip(sim.boundary_volumes())
        .zip(sim.boundary_bodies())
        .filter_map(|((&xb, &vb), &body)| {
            let depth = (xb - x).dot(normal);
            let along = (xb - x).dot(tangent).abs();
            (body == 0 && depth > 0.0 && depth < 2.5 * d && along < a)
                .then(|| (xb, vb, (1.0 - along / a) / a))
        })
        .collect();
    if walls.is_empty() {
        return 0.0;
    }
    let reach = a + h + 2.5 * d;
    let mut reading = 0.0f64;
    for (i, &xi) in sim.positions().iter().enumerate() {
        if (xi - x).length_squared() >= reach * reach {
            continue;
        }
        let push_i = wall_weight * push(i);
        if push_i == 0.0 && gravity == Vec2::ZERO {
            continue;
        }
        for &(xb, vb, weight) in &walls {
            let r = xi - xb;
            if r.length_squared() < h * h {
                let push_ib = push_i + gravity.dot(xb - xi);
                let force = vb * push_ib * kernel.grad_w(r).dot(normal);
                reading += mass * (force * weight) as f64;
            }
        }
    }
    reading
}

/// Points along a bond at which the window weight is sampled (midpoint rule): the cubic
/// spline is smooth enough that 8 points integrate it to well under 1 % on bonds up to h long.
const BOND_SAMPLES: usize = 8;

/// Pressure at the world point `x`, Pa: the mechanical (virial) pressure of the pair forces
/// inside a window of radius h, with the hydrostatic correction (see the module
/// documentation). `None` when no fluid particle lies within h (dry).
pub fn pressure_at(sim: &Simulation, x: Vec2) -> Option<f64> {
    let kernel = sim.kernel();
    let h = kernel.support();
    let h2 = h * h;
    let rho0 = sim.rest_density() as f64;
    let mass = sim.particle_mass();
    let v0 = mass / sim.rest_density();
    let push = sim.applied_pressure_over_rho0();
    // A bond reaches the window when one of its ends is within h (window) + h (bond length).
    let reach2 = 4.0 * h2;
    let fluid: Vec<(Vec2, f32)> = sim
        .positions()
        .iter()
        .enumerate()
        .filter(|(_, &xi)| (xi - x).length_squared() < reach2)
        .map(|(i, &xi)| (xi, push(i)))
        .collect();
    // Fluid fraction of the window and the centroid of its fluid.
    let (mut phi, mut centroid) = (0.0f64, glam::DVec2::ZERO);
    for &(xi, _) in &fluid {
        let r2 = (x - xi).length_squared();
        if r2 < h2 {
            let w = (v0 * kernel.w(r2.sqrt())) as f64;
            phi += w;
            centroid += w * xi.as_dvec2();
        }
    }
    if phi <= 0.0 {
        return None;
    }
    centroid /= phi;
    // Share of the bond from `a` to `b` that lies in the window, weighted by W(x − ·).
    let bond_weight = |a: Vec2, b: Vec2| -> f64 {
        let ab = b - a;
        (0..BOND_SAMPLES)
            .map(|k| {
                let s = (k as f32 + 0.5) / BOND_SAMPLES as f32;
                kernel.w((x - (a + s * ab)).length()) as f64
            })
            .sum::<f64>()
            / BOND_SAMPLES as f64
    };
    // Virial: Σ over pairs of (force on i from j)·(x_i − x_j). The solver's pair force is
    // f_ij = −m V0 (q_i + q_j) ∇W_ij (q = push), and against a wall particle b it is
    // f_ib = −m Ψ_b q_i ∇W_ib.
    let mut virial = 0.0f64;
    for (k, &(xi, qi)) in fluid.iter().enumerate() {
        for &(xj, qj) in &fluid[k + 1..] {
            let r = xi - xj;
            if r.length_squared() < h2 && qi + qj != 0.0 {
                let f_dot_r = -mass * v0 * (qi + qj) * kernel.grad_w(r).dot(r);
                virial += f_dot_r as f64 * bond_weight(xj, xi);
            }
        }
    }
    for (&xb, &vb) in sim.boundary_positions().iter().zip(sim.boundary_volumes()) {
        if (xb - x).length_squared() >= reach2 {
            continue;
        }
        for &(xi, qi) in &fluid {
            let r = xi - xb;
            if r.length_squared() < h2 && qi != 0.0 {
                let f_dot_r = -mass * vb * qi * kernel.grad_w(r).dot(r);
                virial += f_dot_r as f64 * bond_weight(xb, xi);
            }
        }
    }
    // In two dimensions p = tr(σ)/2 = virial / (2·area); the window's fluid area is φ.
    let g = sim.gravity().as_dvec2();
    Some(0.5 * virial / phi + rho0 * g.dot(x.as_dvec2() - centroid))
}

/// Fluid fraction `Σ_j V0 W(x − x_j)` at the world point `x` (≈ 1 inside the water, ≈ 0.5
/// on the free surface, 0 in air).
pub fn fluid_fraction_at(sim: &Simulation, x: Vec2) -> f64 {
    let kernel = sim.kernel();
    let h2 = kernel.support() * kernel.support();
    let v0 = (sim.particle_mass() / sim.rest_density()) as f64;
    sim.positions()
        .iter()
        .filter_map(|&xj| {
            let r2 = (x - xj).length_squared();
            (r2 < h2).then(|| v0 * kernel.w(r2.sqrt()) as f64)
        })
        .sum()
}

/// Water level along the vertical world line at `x`, m above the tank floor: the highest y
/// where the fluid fraction reaches 0.5 (see the module documentation); 0 when dry.
pub fn water_level_at(sim: &Simulation, x: f32) -> f64 {
    let kernel = sim.kernel();
    let h = kernel.support();
    let v0 = (sim.particle_mass() / sim.rest_density()) as f64;
    let (lo, hi) = sim.tank_interior();
    // The particles that can touch the line, sorted from the top down.
    let mut near: Vec<Vec2> = sim
        .positions()
        .iter()
        .copied()
        .filter(|p| (p.x - x).abs() < h)
        .collect();
    if near.is_empty() {
        return 0.0;
    }
    near.sort_unstable_by(|a, b| b.y.total_cmp(&a.y));
    let fraction = |y: f32| -> f64 {
        let p = Vec2::new(x, y);
        near.iter()
            .filter(|q| (q.y - y).abs() < h)
            .map(|&q| v0 * kernel.w((p - q).length()) as f64)
            .sum()
    };
    let step = 0.5 * sim.particle_radius();
    // Start just above the highest particle that touches the line (φ = 0 there).
    let top = (near[0].y + h).min(hi.y + h);
    let mut y_above = top;
    let mut phi_above = 0.0;
    let mut y = top - step;
    while y >= lo.y - 0.5 * step {
        let y_here = y.max(lo.y);
        let phi = fraction(y_here);
        if phi >= 0.5 {
            // Linear interpolation between the two samples that bracket φ = 0.5.
            let t = if phi > phi_above {
                ((phi - 0.5) / (phi - phi_above)).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let level = y_here as f64 + t * (y_above - y_here) as f64;
            return (level - lo.y as f64).max(0.0);
        }
        y_above = y_here;
        phi_above = phi;
        y -= step;
    }
    0.0
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{self, Probe};

    fn hydrostatic(radius: f64, probes: Vec<Probe>) -> Scene {
        let mut s = scene::builtin("hydrostatic").unwrap();
        s.particle_radius = radius;
        s.probes = probes;
        s
    }

    fn probe_err(json: &str) -> String {
        Scene::from_json(json).unwrap_err().to_string()
    }

    #[test]
    fn probes_parse_and_round_trip() {
        let s = Scene::from_json(
            r#"{"probes": [
                {"type": "pressure", "name": "p_floor", "at": [2.0, 0.0]},
                {"type": "water_level", "name": "h1", "x": 1.5}
            ]}"#,
        )
        .unwrap();
        assert_eq!(s.probes.len(), 2);
        assert_eq!(s.probes[0].name(), "p_floor");
        assert_eq!(s.probes[1].unit(), "m");
        assert_eq!(Scene::from_json(&s.to_json()).unwrap(), s);
    }

    #[test]
    fn bad_probes_name_the_key() {
        let cases = [
            (
                r#"{"probes": [{"type": "pressure", "name": "a"}]}"#,
                "probes[0]",
            ),
            (
                r#"{"probes": [{"type": "pressure", "name": "a", "at": [0, 0], "radius": 1}]}"#,
                "probes[0]",
            ),
            (
                r#"{"probes": [{"type": "thermometer", "name": "a"}]}"#,
                "probes[0]",
            ),
            (
                r#"{"probes": [{"type": "pressure", "name": "a", "at": [5, 0]}]}"#,
                "probes[0].at[0]",
            ),
            (
                r#"{"probes": [{"type": "water_level", "name": "a", "x": -1}]}"#,
                "probes[0].x",
            ),
            (
                r#"{"probes": [{"type": "water_level", "name": "", "x": 1}]}"#,
                "probes[0].name",
            ),
            (
                r#"{"probes": [{"type": "water_level", "name": "a,b", "x": 1}]}"#,
                "probes[0].name",
            ),
            (
                r#"{"probes": [{"type": "water_level", "name": "time", "x": 1}]}"#,
                "probes[0].name",
            ),
            (
                r#"{"probes": [{"type": "water_level", "name": "a", "x": 1},
                               {"type": "pressure", "name": "a", "at": [1, 1]}]}"#,
                "probes[1].name",
            ),
        ];
        for (json, needle) in cases {
            let msg = probe_err(json);
            assert!(msg.contains(needle), "{json}: {msg:?} lacks {needle:?}");
        }
    }

    #[test]
    fn gauge_reads_the_initial_water_height_within_a_particle_diameter() {
        let r = 0.02;
        let s = hydrostatic(
            r,
            vec![
                Probe::WaterLevel {
                    name: "mid".into(),
                    x: 1.0,
                },
                Probe::WaterLevel {
                    name: "near_wall".into(),
                    x: 2.0 * r,
                },
            ],
        );
        let sim = Simulation::new(&s).unwrap();
        for level in sample_all(&sim) {
            assert!((level - 1.0).abs() < 2.0 * r, "level {level}");
        }
        // Dry gauges read 0.
        let mut dry = s.clone();
        dry.fluid[0].max[0] = 0.5;
        let sim = Simulation::new(&dry).unwrap();
        assert_eq!(sample_all(&sim)[0], 0.0);
    }

    #[test]
    fn dry_pressure_probe_reads_zero() {
        let s = hydrostatic(
            0.02,
            vec![Probe::Pressure {
                name: "air".into(),
                at: [1.0, 1.8],
            }],
        );
        let sim = Simulation::new(&s).unwrap();
        assert_eq!(pressure_at(&sim, Vec2::new(1.0, 1.8)), None);
        assert_eq!(sample_all(&sim), vec![0.0]);
    }

    #[test]
    fn hydrostatic_pressures_inside_and_on_the_walls_after_settling() {
        let depth = 1.0;
        let probe = |name: &str, at: [f64; 2]| Probe::Pressure {
            name: name.into(),
            at,
        };
        let s = hydrostatic(
            0.025,
            vec![
                probe("mid", [1.0, 0.5]),
                probe("floor", [1.0, 0.0]),
                probe("left_wall", [0.0, 0.25]),
                probe("right_wall", [2.0, 0.5]),
            ],
        );
        assert_eq!(tank_face_normal(&s, [1.0, 0.0]), Some(Vec2::NEG_Y));
        assert_eq!(tank_face_normal(&s, [2.0, 0.5]), Some(Vec2::X));
        assert_eq!(tank_face_normal(&s, [1.0, 0.5]), None);
        let mut sim = Simulation::new(&s).unwrap();
        let mut sums = [0.0f64; 4];
        let mut count = 0;
        while sim.time() < 1.5 {
            sim.step();
            if sim.time() > 1.0 {
                for (sum, reading) in sums.iter_mut().zip(sample_all(&sim)) {
                    *sum += reading;
                }
                count += 1;
            }
        }
        let rho_g = 1000.0 * 9.81;
        for ((name, y), sum) in [
            ("mid", 0.5),
            ("floor", 0.0),
            ("left_wall", 0.25),
            ("right_wall", 0.5),
        ]
        .iter()
        .zip(sums)
        {
            let mean = sum / count as f64;
            let expected = rho_g * (depth - y);
            assert!(
                (mean - expected).abs() < 0.03 * rho_g * depth,
                "{name}: {mean:.1} Pa, expected {expected:.1} Pa"
            );
        }
    }

    #[test]
    fn pressure_probe_reads_forces_and_barely_sees_a_force_free_row_pattern() {
        let r = 0.02f32;
        let d = 2.0 * r;
        let rho_g_h = 1000.0 * 9.81f32;
        let mut sim = Simulation::new(&hydrostatic(r as f64, vec![])).unwrap();
        // Hydrostatic pressures on the initial lattice (rows at y = r + k·d), plus rows
        // alternately +δ and −δ: every interior particle has the same rows above and below it,
        // so the pattern exerts no net force on any of them.
        let mut set = |delta: f32| {
            for i in 0..sim.fluid.len() {
                let y = sim.fluid.position[i].y;
                let row = ((y - r) / d).round() as i32;
                let sign = if row % 2 == 0 { 1.0 } else { -1.0 };
                sim.world.fluid.pressure_over_rho0[i] =
                    (rho_g_h * (1.0 - y) + sign * delta) / 1000.0;
            }
            let mid = pressure_at(&sim, Vec2::new(1.0, 0.5)).unwrap();
            let near_surface = pressure_at(&sim, Vec2::new(1.0, 0.98)).unwrap();
            (mid, near_surface)
        };
        let (mid, near_surface) = set(0.0);
        // The pressure at the probe's own height, also 2 cm under the surface where half the
        // window is air.
        assert!(
            (mid - 0.5 * rho_g_h as f64).abs() < 0.02 * rho_g_h as f64,
            "{mid}"
        );
        assert!(
            (near_surface - 0.02 * rho_g_h as f64).abs() < 0.02 * rho_g_h as f64,
            "{near_surface}"
        );
        // y = 0.5 is a row centre (r + 12·d): an interpolation of the particles' pressures
        // there moves by about a third of δ.
        let delta = 0.1 * rho_g_h;
        let (mid_pattern, _) = set(delta);
        let shift = (mid_pattern - mid).abs();
        assert!(
            shift < 0.2 * delta as f64,
            "moved {shift:.1} Pa for δ = {delta} Pa"
        );
    }
}
