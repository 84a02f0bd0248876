//! Boundary particles (Akinci et al. 2012, "Versatile rigid-fluid coupling for incompressible
//! SPH", eq. 4–5): walls are sampled with particles that add `ρ0·Ψ_b·W` to the density of
//! nearby fluid and receive the mirrored pressure force.
//!
//! Sampling. Every wall is [`wall_layers`] layers thick with spacing d (⌈h/d⌉: two for the
//! cubic spline at h = 2d, four for Wendland C2 at 3.5d), placed so that it continues the
//! fluid lattice (the tank's layers sit at d/2, 3d/2, … outside its interior, exactly where the
//! next fluid rows would be). They cover the kernel support h of any fluid particle that has
//! not already crossed into the wall.
//!
//! Volume. Tank walls continue the fluid lattice exactly, so their particles simply take the
//! fluid particles' volume (scaled by their area when the tank is not a whole number of
//! spacings): fluid at rest then reads ρ0 everywhere, corners included. Obstacles and drawn
//! walls do not line up with the fluid, and use Akinci's estimate:  `Ψ_b = 1 / Σ_k W_bk` over boundary neighbours measures how densely the
//! wall is sampled, but a wall lacks the fluid-side rows of a full neighbourhood, so the plain
//! formula overestimates the volume of a lattice wall by the ratio of a full lattice sum to the
//! wall rows' sum (≈ 1.19 for the cubic spline at h = 2d and two rows), and fluid beside a wall
//! would start 3 % too dense. We multiply by γ = (wall rows' sum)/(full sum), computed
//! from the kernel, so that a straight wall reads like the fluid it continues; irregular
//! samplings keep Akinci's adaptivity.
//!
//! Models. How the walls take part in the pressure solve is a [`BoundaryModel`], one per file:
//! [`AkinciWalls`] (the wall feels the particle's own pressure once) and [`MirroredWalls`] (the
//! wall mirrors the fluid, with its hydrostatic pressure). The pressure solver names the model
//! it is meant for (`pressure::PressureSolver::walls`).

use glam::Vec2;

use crate::kernel::Kernel;
use crate::neighbors::Grid;

mod akinci;
mod mirrored;
mod model;

pub use akinci::AkinciWalls;
pub use mirrored::MirroredWalls;
pub use model::BoundaryModel;

/// Which body a boundary particle belongs to. Body 0 is the tank; every obstacle and drawn wall
/// is a body of its own so it can be moved or erased as a whole.
pub type BodyId = u16;

/// A rigid group of boundary particles with a common velocity.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Body {
    /// Velocity of every particle of the body, m/s.
    pub velocity: Vec2,
    /// Displacement of the body since it was created, metres.
    pub offset: Vec2,
    /// The rigid body ([`crate::rigid`]) this is, by index: its particles move with it rather
    /// than with the tank.
    pub rigid: Option<u16>,
}

/// Wall particles closer than this many spacings to one sampled before them are dropped
/// ([`BoundarySamples::merge_close`]). Every sampling here places a wall's particles at least
/// 0.67 d apart, so this only merges samples that repeat one another (a polyline over itself,
/// points stacked by a script).
pub const MERGE_DISTANCE: f32 = 0.25;

/// How many layers thick a wall must be for fluid beside it to see a full neighbourhood:
/// ⌈h/d⌉ (2 for the cubic spline at h = 2d, 4 for Wendland C2 at 3.5d).
pub fn wall_layers(kernel: &Kernel, d: f32) -> usize {
    // The small allowance keeps 2d/d = 2.0000002 from becoming 3 layers.
    ((kernel.support() / d) * (1.0 - 1.0e-5)).ceil().max(1.0) as usize
}

/// Sampled boundary particles before volumes are known.
#[derive(Clone, Debug)]
pub struct BoundarySamples {
    /// Layers of every wall sampled here ([`wall_layers`]).
    pub layers: usize,
    pub positions: Vec<Vec2>,
    pub bodies: Vec<BodyId>,
    /// The particle's area when it is part of a lattice that continues the fluid's (the tank
    /// walls): such a particle takes the fluid particles' own volume scaled by its area, which
    /// leaves fluid at rest exactly at ρ0 even in the corners. `None`: Akinci's estimate.
    pub lattice_area: Vec<Option<f32>>,
}

impl BoundarySamples {
    /// No samples yet; walls will be `layers` layers thick ([`wall_layers`]).
    pub fn new(layers: usize) -> Self {
        Self {
            layers: layers.max(1),
            positions: Vec::new(),
            bodies: Vec::new(),
            lattice_area: Vec::new(),
        }
    }

    /// Keep only the samples whose position passes `keep`.
    pub fn retain(&mut self, keep: impl Fn(Vec2) -> bool) {
        let keep: Vec<bool> = self.positions.iter().map(|&p| keep(p)).collect();
        self.keep_where(&keep);
    }

    /// Keep the samples whose entry of `keep` is true, in order; returns how many were dropped.
    fn keep_where(&mut self, keep: &[bool]) -> usize {
        let before = self.positions.len();
        let mut k = 0;
        for (i, &keep) in keep.iter().enumerate() {
            if keep {
                self.positions.swap(k, i);
                self.bodies.swap(k, i);
                self.lattice_area.swap(k, i);
                k += 1;
            }
        }
        self.positions.truncate(k);
        self.bodies.truncate(k);
        self.lattice_area.truncate(k);
        before - k
    }

    /// Drop every sample closer than `min_distance` to one kept before it (the samples in
    /// order: the tank's first). A polyline that runs over itself, or thousands of points in a
    /// small area, would otherwise stack wall particles without bound: each sums over all the
    /// others within the support (a 60,000-point polyline in 0.1 m² spent 20–40 minutes in
    /// [`volumes`] before the first step). A hash of cells `min_distance` wide makes this one
    /// pass. Returns how many were dropped.
    pub fn merge_close(&mut self, min_distance: f32) -> usize {
        use std::collections::HashMap;
        let cell = |p: Vec2| {
            (
                (p.x / min_distance).floor() as i64,
                (p.y / min_distance).floor() as i64,
            )
        };
        let mut kept: HashMap<(i64, i64), Vec<Vec2>> = HashMap::new();
        let min2 = min_distance * min_distance;
        let keep: Vec<bool> = self
            .positions
            .iter()
            .map(|&p| {
                let (cx, cy) = cell(p);
                let near = (-1..=1).any(|dx| {
                    (-1..=1).any(|dy| {
                        kept.get(&(cx + dx, cy + dy))
                            .is_some_and(|v| v.iter().any(|&q| (q - p).length_squared() < min2))
                    })
                });
                if !near {
                    kept.entry((cx, cy)).or_default().push(p);
                }
                !near
            })
            .collect();
        self.keep_where(&keep)
    }

    /// [`Self::layers`] layers outside the interior `[lo, hi]` of a box, corners filled: the
    /// tank walls.
    pub fn add_tank(&mut self, lo: Vec2, hi: Vec2, d: f32, body: BodyId) {
        let nx = ((hi.x - lo.x) / d).round().max(1.0) as i32;
        let ny = ((hi.y - lo.y) / d).round().max(1.0) as i32;
        // Spacing stretched to fit the interior exactly.
        let dx = (hi.x - lo.x) / nx as f32;
        let dy = (hi.y - lo.y) / ny as f32;
        let n = self.layers as i32;
        for j in -n..ny + n {
            for i in -n..nx + n {
                if (0..nx).contains(&i) && (0..ny).contains(&j) {
                    continue;
                }
                let p = Vec2::new(lo.x + (i as f32 + 0.5) * dx, lo.y + (j as f32 + 0.5) * dy);
                self.positions.push(p);
                self.bodies.push(body);
                self.lattice_area.push(Some(dx * dy));
            }
        }
    }

    /// The tank walls for the hexagonal packing: the sites of the fluid's hexagonal lattice
    /// ([`crate::packing`], anchored at `lo`) outside the interior `[lo, hi]` and within
    /// [`Self::layers`] spacings of it, each with the fluid's area d², so that fluid next to a wall sees its
    /// lattice continue.
    pub fn add_hexagonal_tank(&mut self, lo: [f64; 2], hi: [f64; 2], d: f64, body: BodyId) {
        let reach = self.layers as f64 * d;
        let outer = (
            [lo[0] - reach, lo[1] - reach],
            [hi[0] + reach, hi[1] + reach],
        );
        let tolerance = 1.0e-9 * (hi[0] - lo[0]).max(hi[1] - lo[1]);
        // The four bands along the walls, not the whole tank: a tank 40 m x 30 m at
        // d = 2 cm has 3.4 million interior sites (27 MB, for a few thousand wall particles).
        let bands = [
            (outer.0, [outer.1[0], lo[1]]),
            ([outer.0[0], hi[1]], outer.1),
            (outer.0, [lo[0], outer.1[1]]),
            ([hi[0], outer.0[1]], outer.1),
        ];
        let mut rows = crate::packing::rows_of_boxes(lo, &bands, d, 0.0);
        // Row by row from the bottom, left to right, as the lattice is numbered.
        rows.sort_unstable_by_key(|(_, r)| (r.j, r.i0));
        for p in rows
            .iter()
            .flat_map(|&(_, r)| crate::packing::row_sites(r, d))
        {
            let (x, y) = (p.x as f64, p.y as f64);
            let inside = x >= lo[0] - tolerance
                && x <= hi[0] + tolerance
                && y >= lo[1] - tolerance
                && y <= hi[1] + tolerance;
            if !inside {
                self.positions.push(p);
                self.bodies.push(body);
                self.lattice_area.push(Some((d * d) as f32));
            }
        }
    }

    /// The wall particles of a scene's obstacle. `hexagonal_anchor` is the corner the
    /// scene's hexagonal lattice is anchored at (the tank's lower-left), `None` on the square
    /// packing: a box is then sampled on the fluid's own lattice
    /// ([`Self::add_hexagonal_rect`]), as the tank is.
    pub fn add_obstacle(
        &mut self,
        obstacle: &crate::scene::shapes::Obstacle,
        d: f32,
        hexagonal_anchor: Option<[f64; 2]>,
        body: BodyId,
    ) {
        use crate::scene::shapes::Obstacle;
        let v = |p: &[f64; 2]| Vec2::new(p[0] as f32, p[1] as f32);
        match obstacle {
            Obstacle::Rect { min, max } => match hexagonal_anchor {
                Some(anchor) => self.add_hexagonal_rect(anchor, *min, *max, d as f64, body),
                None => self.add_rect(v(min), v(max), d, body),
            },
            Obstacle::Polyline { points } => {
                let pts: Vec<Vec2> = points.iter().map(v).collect();
                self.add_polyline(&pts, d, body)
            }
            Obstacle::Particles { positions } => {
                let pts: Vec<Vec2> = positions.iter().map(v).collect();
                self.add_points(&pts, body)
            }
        }
    }

    /// A solid box: its [`Self::layers`] outermost layers (the inside is never reached by
    /// fluid).
    pub fn add_rect(&mut self, lo: Vec2, hi: Vec2, d: f32, body: BodyId) {
        let nx = ((hi.x - lo.x) / d).round().max(1.0) as i32;
        let ny = ((hi.y - lo.y) / d).round().max(1.0) as i32;
        let dx = (hi.x - lo.x) / nx as f32;
        let dy = (hi.y - lo.y) / ny as f32;
        for j in 0..ny {
            for i in 0..nx {
                let depth = i.min(j).min(nx - 1 - i).min(ny - 1 - j);
                if depth < self.layers as i32 {
                    self.positions.push(Vec2::new(
                        lo.x + (i as f32 + 0.5) * dx,
                        lo.y + (j as f32 + 0.5) * dy,
                    ));
                    self.bodies.push(body);
                    self.lattice_area.push(None);
                }
            }
        }
    }

    /// A solid box for the hexagonal packing: the sites of the fluid's hexagonal lattice
    /// (anchored at `anchor`) in its [`Self::layers`] outermost layers, each with the fluid's area d², so
    /// that water beside the box sees its own lattice continue: ρ0·g·(H − y) is then the
    /// equilibrium beside the box as beside the tank's walls (a box sampled on the square grid
    /// next to hexagonal water moved a pool 1.5 m deep at 4.9 m/s beside its face). The outer
    /// layer on each side is the lattice's row (or column of sites) nearest to where the square
    /// grid's would be, d/2 inside the face, so a face stands within half a lattice step of
    /// where the scene puts it. A box thinner than two spacings either way keeps the square
    /// grid, which covers it whatever its size.
    pub fn add_hexagonal_rect(
        &mut self,
        anchor: [f64; 2],
        lo: [f64; 2],
        hi: [f64; 2],
        d: f64,
        body: BodyId,
    ) {
        let (w, h) = (hi[0] - lo[0], hi[1] - lo[1]);
        if w < 2.0 * d || h < 2.0 * d {
            let v = |p: [f64; 2]| Vec2::new(p[0] as f32, p[1] as f32);
            return self.add_rect(v(lo), v(hi), d as f32, body);
        }
        // Where the square grid's outer layer lies, and half a lattice step either way.
        let (inner_lo, inner_hi) = (
            [lo[0] + 0.5 * d, lo[1] + 0.5 * d],
            [hi[0] - 0.5 * d, hi[1] - 0.5 * d],
        );
        let half = [
            0.5 * crate::packing::ROW_SPACING * d,
            0.5 * crate::packing::ROW_DISTANCE * d,
        ];
        let reach_lo = [inner_lo[0] - half[0], inner_lo[1] - half[1]];
        let reach_hi = [inner_hi[0] + half[0], inner_hi[1] + half[1]];
        for p in crate::packing::sites(anchor, reach_lo, reach_hi, d, 0.0) {
            let (x, y) = (p.x as f64, p.y as f64);
            let depth = (x - inner_lo[0])
                .min(inner_hi[0] - x)
                .min(y - inner_lo[1])
                .min(inner_hi[1] - y);
            if depth < (self.layers as f64 - 0.5) * d {
                self.positions.push(p);
                self.bodies.push(body);
                self.lattice_area.push(Some((d * d) as f32));
            }
        }
    }

    /// Boundary particles exactly where given (a wall saved particle by particle), with
    /// Akinci's volume estimate like the other obstacles.
    pub fn add_points(&mut self, points: &[Vec2], body: BodyId) {
        for &p in points {
            self.positions.push(p);
            self.bodies.push(body);
            self.lattice_area.push(None);
        }
    }

    /// A wall along a polyline: [`Self::layers`] parallel rows, d apart and centred on the
    /// line (±d/2 for two), spacing ≈ d.
    pub fn add_polyline(&mut self, points: &[Vec2], d: f32, body: BodyId) {
        for seg in points.windows(2) {
            let (a, b) = (seg[0], seg[1]);
            let len = (b - a).length();
            if len < 1.0e-6 {
                continue;
            }
            let t = (b - a) / len;
            let n = Vec2::new(-t.y, t.x);
            let count = (len / d).round().max(1.0) as i32;
            let step = len / count as f32;
            // Include the end point of the last segment only; inner joints are shared.
            for k in 0..count {
                let c = a + t * (k as f32 + 0.5) * step;
                for row in 0..self.layers {
                    let side = row as f32 - 0.5 * (self.layers as f32 - 1.0);
                    self.positions.push(c + n * side * d);
                    self.bodies.push(body);
                    self.lattice_area.push(None);
                }
            }
        }
    }
}

/// How far outside the interior `[lo, hi]` of a tank the centre line of its first wall layer
/// lies on each side, as (left, bottom) and (right, top) distances, m: per side, the nearest
/// of the tank's wall samples `walls` beyond that side (within the interior's span along it),
/// and at least `d/2`. On the square lattice every side's is about `d/2` (the walls are
/// stretched to fit); the hexagonal walls continue the fluid's lattice, whose rows and columns
/// need not meet the tank at `d/2` (the ceiling's first row lies anywhere up to a row
/// distance, 0.93 d, above it; the right wall's nearest column up to 0.54 d right of it).
/// A particle is through a wall only past its first layer's centre line.
pub fn first_layer_margins(walls: &[Vec2], lo: Vec2, hi: Vec2, d: f32) -> (Vec2, Vec2) {
    let half = 0.5 * d;
    let mut near_lo = Vec2::INFINITY;
    let mut near_hi = Vec2::INFINITY;
    for &p in walls {
        let within_x = p.x >= lo.x && p.x <= hi.x;
        let within_y = p.y >= lo.y && p.y <= hi.y;
        if within_y && p.x < lo.x {
            near_lo.x = near_lo.x.min(lo.x - p.x);
        }
        if within_y && p.x > hi.x {
            near_hi.x = near_hi.x.min(p.x - hi.x);
        }
        if within_x && p.y < lo.y {
            near_lo.y = near_lo.y.min(lo.y - p.y);
        }
        if within_x && p.y > hi.y {
            near_hi.y = near_hi.y.min(p.y - hi.y);
        }
    }
    // A side without samples (none here: the tank is closed) keeps d/2.
    let margin = |m: f32| if m.is_finite() { m.max(half) } else { half };
    (
        Vec2::new(margin(near_lo.x), margin(near_lo.y)),
        Vec2::new(margin(near_hi.x), margin(near_hi.y)),
    )
}

/// γ: the ratio of the kernel sum over a wall's [`wall_layers`] lattice rows to the sum over
/// a full lattice neighbourhood, so that a straight wall gets exactly the fluid's volume d².
pub fn wall_volume_correction(kernel: &Kernel, d: f32) -> f32 {
    let reach = (kernel.support() / d).ceil() as i32 + 1;
    let layers = wall_layers(kernel, d) as i32;
    let mut full = 0.0f64;
    let mut wall_rows = 0.0f64;
    for j in -reach..=reach {
        for i in -reach..=reach {
            let w = kernel.w(Vec2::new(i as f32 * d, j as f32 * d).length()) as f64;
            full += w;
            // The particle's own row and the rows behind it.
            if (-layers + 1..=0).contains(&j) {
                wall_rows += w;
            }
        }
    }
    (wall_rows / full) as f32
}

/// Akinci volumes `Ψ_b = γ / Σ_k W_bk` of boundary particles already sorted in `grid`, for
/// the particles whose `volume` entry is not already positive (lattice walls come with theirs).
pub fn volumes(grid: &Grid, kernel: &Kernel, gamma: f32, volume: &mut [f32]) {
    use crate::par::prelude::*;
    let pts = grid.sorted_points();
    volume
        .par_iter_mut()
        .zip(pts.par_iter())
        .for_each(|(v, &p)| {
            if *v > 0.0 {
                return;
            }
            let mut sum = 0.0f32;
            grid.for_each_near(p, |_, r| sum += kernel.w(r.length()));
            *v = gamma / sum.max(kernel.w_zero());
        });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn correction_is_two_rows_over_three_for_h_equal_2d() {
        let d = 0.02;
        let k = Kernel::cubic_spline(2.0 * d);
        let g = wall_volume_correction(&k, d);
        // W(0) = k, W(d) = k/4, W(√2 d) ≈ 0.0503k: full = 2.201k, two rows = 1.8505k.
        assert!((g - 0.8408).abs() < 1e-3, "gamma = {g}");
    }

    #[test]
    fn straight_wall_particles_get_the_lattice_volume() {
        let d = 0.02;
        let k = Kernel::cubic_spline(2.0 * d);
        let mut s = BoundarySamples::new(2);
        s.add_tank(Vec2::ZERO, Vec2::new(2.0, 1.0), d, 0);
        let mut grid = Grid::new(k.support());
        grid.build(&s.positions);
        let mut vol = vec![0.0; s.positions.len()];
        volumes(&grid, &k, wall_volume_correction(&k, d), &mut vol);
        // A wall particle in the middle of the floor: the same volume as a fluid particle.
        let lattice_sum = 1.0 / (k.w_zero() + 4.0 * k.w(d) + 4.0 * k.w(d * 2f32.sqrt()));
        let mid = grid
            .sorted_points()
            .iter()
            .position(|p| (p.x - 1.01).abs() < 1e-4 && (p.y + 0.01).abs() < 1e-4)
            .expect("a floor particle at (1.01, -0.01)");
        assert!(
            (vol[mid] / lattice_sum - 1.0).abs() < 1e-4,
            "{} vs {}",
            vol[mid],
            lattice_sum
        );
    }

    #[test]
    fn the_first_wall_layer_is_half_a_spacing_out_on_the_square_lattice_and_the_rows_on_the_hexagonal(
    ) {
        let (lo, hi, d) = (Vec2::new(0.0, 0.0), Vec2::new(2.66, 1.25), 0.15);
        let mut square = BoundarySamples::new(2);
        square.add_tank(lo, hi, d, 0);
        let (m_lo, m_hi) = first_layer_margins(&square.positions, lo, hi, d);
        // The square walls are stretched to fit the interior: their first layer is half a
        // (stretched) spacing out, within a few percent of d/2.
        for m in [m_lo.x, m_lo.y, m_hi.x, m_hi.y] {
            assert!((m - 0.5 * d).abs() < 0.05 * d, "{m}");
        }
        // The hexagonal lattice's rows lie at d/2 + k·row: a ceiling at 1.06 m is just above
        // row 7 (1.052 m), and row 8 lies 0.88 d above it.
        let (row, along) = (
            crate::packing::ROW_DISTANCE as f32 * d,
            crate::packing::ROW_SPACING as f32 * d,
        );
        let hi = Vec2::new(2.66, 1.06);
        let mut hexagonal = BoundarySamples::new(2);
        hexagonal.add_hexagonal_tank([0.0, 0.0], [2.66, 1.06], d as f64, 0);
        let (m_lo, m_hi) = first_layer_margins(&hexagonal.positions, lo, hi, d);
        assert!(
            (m_hi.y - (0.5 * d + 8.0 * row - 1.06)).abs() < 1e-5,
            "{m_hi}"
        );
        assert!(m_hi.y > 0.8 * d);
        // Anchored at the lower-left corner, the lattice's wall rows and columns there lie
        // closer than d/2 (0.43 d below, 0.04 d left): the rule's d/2 stands.
        assert_eq!(m_lo, Vec2::splat(0.5 * d));
        // The columns alternate by half a spacing: the nearest beyond the right side is
        // within that.
        assert!(m_hi.x >= 0.5 * d && m_hi.x <= 0.5 * along + 1e-5, "{m_hi}");
        // A ceiling just below a row keeps the rule's d/2.
        let (_, m_hi) = first_layer_margins(&hexagonal.positions, lo, Vec2::new(2.66, 1.18), d);
        assert_eq!(m_hi.y, 0.5 * d);
    }

    #[test]
    fn tank_walls_are_two_layers_all_round() {
        let d = 0.1;
        let mut s = BoundarySamples::new(2);
        s.add_tank(Vec2::ZERO, Vec2::new(1.0, 0.5), d, 0);
        // (10 + 4) x (5 + 4) minus the 10 x 5 interior.
        assert_eq!(s.positions.len(), 14 * 9 - 50);
        assert!(s
            .positions
            .iter()
            .all(|p| p.x < 0.0 || p.x > 1.0 || p.y < 0.0 || p.y > 0.5));
    }

    /// A polyline that runs over itself thousands of times keeps one wall's worth of
    /// particles, and samples that do not repeat one another are all kept.
    #[test]
    fn stacked_wall_samples_are_merged_and_others_kept() {
        let d = 0.02;
        let mut once = BoundarySamples::new(2);
        once.add_polyline(&[Vec2::new(0.0, 0.0), Vec2::new(0.5, 0.0)], d, 1);
        let n = once.positions.len();
        assert_eq!(once.merge_close(MERGE_DISTANCE * d), 0);
        assert_eq!(once.positions.len(), n);
        let back_and_forth: Vec<Vec2> = (0..2000)
            .map(|k| Vec2::new(if k % 2 == 0 { 0.0 } else { 0.5 }, 0.0))
            .collect();
        let mut stacked = BoundarySamples::new(2);
        stacked.add_polyline(&back_and_forth, d, 1);
        assert!(stacked.positions.len() > 1000 * n);
        stacked.merge_close(MERGE_DISTANCE * d);
        assert!(
            stacked.positions.len() <= n + 4,
            "{} kept of a {n}-particle wall",
            stacked.positions.len()
        );
        assert_eq!(stacked.positions.len(), stacked.bodies.len());
        assert_eq!(stacked.positions.len(), stacked.lattice_area.len());
    }
}
