//! Water drawn as a surface rather than as dots: the particles' smoothed indicator on a
//! pixel grid, cut at a level with an anti-aliased edge, coloured by the particles' own
//! colours (their weighted mean) and lightened in a thin rim just inside the edge.
//!
//! The indicator is `φ(x) = Σ_i w(|x − x_i| / R)`, `w(q) = (1 − q²)³` for q < 1, with
//! R = [`SMOOTHING_RADII`] particle radii. Inside water on a lattice of spacing 2r it reads
//! about πR²/(4·(2r)²) = 1.77; a lone particle peaks at 1. The edge is drawn where φ =
//! [`EDGE_LEVEL`]: a lone drop shows as a disc of about 1.2 radii, and the edge of a block
//! lies about a radius beyond its outermost particles' centres, where the dots' own edge is.
//! Anything thinner than a pixel is widened to one, as the dots are.
//!
//! One grid serves every picture: the viewer and the page upload it as a texture over the
//! tank ([`SurfaceRaster::rgba`]), the frames of `dfsph2d run` blend it into their image
//! ([`crate::render`]).

use dfsph::Vec2;

/// R, the indicator's smoothing radius, in particle radii: wide enough that water on the
/// lattice reads as one smooth field (the kernel reaches the second ring of neighbours),
/// narrow enough that a lone drop still shows.
pub const SMOOTHING_RADII: f32 = 3.0;

/// The indicator's level at the edge (a lone particle's peak is 1).
pub const EDGE_LEVEL: f32 = 0.6;

/// How much the rim just inside the edge is lightened towards white (0 to 1).
pub const RIM_LIGHTENING: f32 = 0.35;

/// The indicator's steepest slope across a flat edge, per smoothing radius, as a share of
/// its value inside the water (measured on the lattice: about 1.2).
const EDGE_SLOPE: f32 = 1.2 * 1.77;

/// Where the grid lies: pixel (0, 0)'s top-left corner at `top_left` (m, y up), `cell` m a
/// pixel, rows running down (−y).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceGrid {
    pub top_left: Vec2,
    pub cell: f32,
    pub width: u32,
    pub height: u32,
}

impl SurfaceGrid {
    /// The world position of pixel `(px, py)`'s centre.
    pub fn centre(&self, px: u32, py: u32) -> Vec2 {
        Vec2::new(
            self.top_left.x + (px as f32 + 0.5) * self.cell,
            self.top_left.y - (py as f32 + 0.5) * self.cell,
        )
    }

    /// The world position of the grid's bottom-right corner.
    pub fn bottom_right(&self) -> Vec2 {
        Vec2::new(
            self.top_left.x + self.width as f32 * self.cell,
            self.top_left.y - self.height as f32 * self.cell,
        )
    }
}

/// The surface of one picture, with the buffers kept between pictures.
#[derive(Clone, Debug, Default)]
pub struct SurfaceRaster {
    grid: Option<SurfaceGrid>,
    field: Vec<f32>,
    colour: Vec<[f32; 3]>,
    rgba: Vec<u8>,
}

impl SurfaceRaster {
    /// Draw the water of the particles at `positions` (radius `radius`, m), particle i
    /// coloured `colour(i)`, on `grid`. Particles off the grid, or not finite, add nothing
    /// where they are not seen.
    pub fn draw(
        &mut self,
        grid: SurfaceGrid,
        positions: &[Vec2],
        radius: f32,
        mut colour: impl FnMut(usize) -> [u8; 3],
    ) {
        let (w, h) = (grid.width as usize, grid.height as usize);
        let n = w * h;
        self.grid = Some(grid);
        self.field.clear();
        self.field.resize(n, 0.0);
        self.colour.clear();
        self.colour.resize(n, [0.0; 3]);
        self.rgba.clear();
        self.rgba.resize(4 * n, 0);
        if n == 0 || !(grid.cell > 0.0 && grid.cell.is_finite()) {
            return;
        }
        // In pixels; never thinner than a pixel, as a dot is never drawn thinner.
        let r_px = (radius.max(0.0) / grid.cell).max(0.5);
        let reach = SMOOTHING_RADII * r_px;
        let inv_reach2 = 1.0 / (reach * reach);
        for (i, &p) in positions.iter().enumerate() {
            if !p.is_finite() {
                continue;
            }
            // Pixel coordinates of the particle, in units where pixel centres are integers.
            let fx = (p.x - grid.top_left.x) / grid.cell - 0.5;
            let fy = (grid.top_left.y - p.y) / grid.cell - 0.5;
            if fx + reach < 0.0
                || fy + reach < 0.0
                || fx - reach > (w - 1) as f32
                || fy - reach > (h - 1) as f32
            {
                continue;
            }
            let c = colour(i).map(f32::from);
            let x0 = (fx - reach).ceil().max(0.0) as usize;
            let x1 = ((fx + reach).floor() as usize).min(w - 1);
            let y0 = (fy - reach).ceil().max(0.0) as usize;
            let y1 = ((fy + reach).floor() as usize).min(h - 1);
            for py in y0..=y1 {
                let dy = py as f32 - fy;
                let row = py * w;
                for px in x0..=x1 {
                    let dx = px as f32 - fx;
                    let q2 = (dx * dx + dy * dy) * inv_reach2;
                    if q2 < 1.0 {
                        let s = 1.0 - q2;
                        let wgt = s * s * s;
                        self.field[row + px] += wgt;
                        let sum = &mut self.colour[row + px];
                        for k in 0..3 {
                            sum[k] += wgt * c[k];
                        }
                    }
                }
            }
        }
        // The field's change across one pixel at an edge, and the edge's and rim's widths in
        // field units: a pixel and a half of anti-aliasing, a rim of about half a radius
        // (at least a pixel and a half).
        let per_pixel = EDGE_SLOPE / reach;
        let half_edge = (0.75 * per_pixel).clamp(0.02, 0.35);
        let rim = per_pixel * (0.5 * r_px).max(1.5);
        for (k, (&phi, sum)) in self.field.iter().zip(&self.colour).enumerate() {
            if phi <= EDGE_LEVEL - half_edge {
                continue;
            }
            let alpha = smoothstep(EDGE_LEVEL - half_edge, EDGE_LEVEL + half_edge, phi);
            let light = RIM_LIGHTENING * (1.0 - smoothstep(EDGE_LEVEL, EDGE_LEVEL + rim, phi));
            let px = &mut self.rgba[4 * k..4 * k + 4];
            for c in 0..3 {
                let mean = sum[c] / phi;
                px[c] = (mean + light * (255.0 - mean)).round().clamp(0.0, 255.0) as u8;
            }
            px[3] = (255.0 * alpha).round() as u8;
        }
    }

    /// The grid of the last [`Self::draw`].
    pub fn grid(&self) -> Option<SurfaceGrid> {
        self.grid
    }

    /// The picture: RGBA, 8 bits each, alpha not premultiplied, row by row from the top.
    pub fn rgba(&self) -> &[u8] {
        &self.rgba
    }

    /// Pixel `(px, py)` as RGBA.
    pub fn pixel(&self, px: u32, py: u32) -> [u8; 4] {
        let w = self.grid.map_or(0, |g| g.width) as usize;
        let k = 4 * (py as usize * w + px as usize);
        [
            self.rgba[k],
            self.rgba[k + 1],
            self.rgba[k + 2],
            self.rgba[k + 3],
        ]
    }
}

fn smoothstep(lo: f32, hi: f32, x: f32) -> f32 {
    let t = ((x - lo) / (hi - lo)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A grid of `cell` m pixels covering [0, size]².
    fn grid(size: f32, cell: f32) -> SurfaceGrid {
        let n = (size / cell).round() as u32;
        SurfaceGrid {
            top_left: Vec2::new(0.0, size),
            cell,
            width: n,
            height: n,
        }
    }

    /// Particles of radius r on the square lattice of spacing 2r filling [lo, hi]².
    fn block(lo: f32, hi: f32, r: f32) -> Vec<Vec2> {
        let mut out = Vec::new();
        let mut y = lo + r;
        while y < hi {
            let mut x = lo + r;
            while x < hi {
                out.push(Vec2::new(x, y));
                x += 2.0 * r;
            }
            y += 2.0 * r;
        }
        out
    }

    /// The pixel whose centre is nearest to `p`.
    fn at(g: &SurfaceGrid, p: Vec2) -> (u32, u32) {
        (
            ((p.x - g.top_left.x) / g.cell) as u32,
            ((g.top_left.y - p.y) / g.cell) as u32,
        )
    }

    #[test]
    fn a_block_is_opaque_inside_in_its_own_colour_and_ends_about_a_radius_out() {
        let r = 0.01;
        let g = grid(1.0, 0.001);
        let water = block(0.3, 0.7, r);
        let outer = water.iter().map(|p| p.x).fold(0.0, f32::max);
        let mut raster = SurfaceRaster::default();
        raster.draw(g, &water, r, |_| [20, 90, 200]);
        let (x, y) = at(&g, Vec2::new(0.5, 0.5));
        let inside = raster.pixel(x, y);
        assert_eq!(inside[3], 255, "{inside:?}");
        assert_eq!(&inside[..3], &[20, 90, 200], "no rim deep inside");
        // Along the middle row, the edge (alpha crossing one half) lies between half a
        // radius and one and a half radii beyond the outermost centres.
        let row = at(&g, Vec2::new(0.5, 0.5)).1;
        let edge = (0..g.width)
            .rev()
            .find(|&px| raster.pixel(px, row)[3] >= 128)
            .map(|px| g.centre(px, row).x)
            .expect("an edge");
        let beyond = (edge - outer) / r;
        assert!((0.5..=1.5).contains(&beyond), "edge {beyond} radii out");
        let (x, y) = at(&g, Vec2::new(outer + 3.0 * r, 0.5));
        assert_eq!(raster.pixel(x, y)[3], 0, "clear outside");
        // The rim just inside the edge is lighter than the water's colour.
        let (x, y) = at(&g, Vec2::new(edge - 0.2 * r, 0.5));
        let rim = raster.pixel(x, y);
        assert!(rim[0] > 20 && rim[1] > 90, "{rim:?}");
    }

    #[test]
    fn a_lone_drop_shows_as_a_disc_of_about_its_radius() {
        let r = 0.01;
        let g = grid(0.2, 0.0005);
        let mut raster = SurfaceRaster::default();
        let centre = Vec2::new(0.1, 0.1);
        raster.draw(g, &[centre], r, |_| [200, 0, 0]);
        let alpha = |d: f32| {
            let (x, y) = at(&g, centre + Vec2::new(d, 0.0));
            raster.pixel(x, y)[3]
        };
        assert_eq!(alpha(0.0), 255);
        assert!(alpha(1.0 * r) >= 128, "{}", alpha(1.0 * r));
        assert!(alpha(1.5 * r) < 128, "{}", alpha(1.5 * r));
        assert_eq!(alpha(2.5 * r), 0);
    }

    #[test]
    fn each_waters_colour_is_its_own_particles_mean() {
        let r = 0.01;
        let g = grid(1.0, 0.002);
        let mut water = block(0.1, 0.5, r);
        let left = water.len();
        water.extend(block(0.5, 0.9, r));
        let mut raster = SurfaceRaster::default();
        raster.draw(g, &water, r, |i| {
            if i < left {
                [0, 0, 255]
            } else {
                [255, 0, 0]
            }
        });
        let (x, y) = at(&g, Vec2::new(0.3, 0.3));
        assert_eq!(raster.pixel(x, y), [0, 0, 255, 255]);
        let (x, y) = at(&g, Vec2::new(0.7, 0.7));
        assert_eq!(raster.pixel(x, y), [255, 0, 0, 255]);
    }

    #[test]
    fn particles_off_the_grid_or_not_finite_draw_nothing_and_tiny_drops_stay_visible() {
        let g = grid(0.1, 0.01);
        let mut raster = SurfaceRaster::default();
        let far = [Vec2::new(5.0, 5.0), Vec2::new(-5.0, 0.05), Vec2::NAN];
        raster.draw(g, &far, 0.001, |_| [255; 3]);
        assert!(raster.rgba().iter().all(|&b| b == 0));
        // A radius of a tenth of a pixel is still drawn, a pixel wide, as a dot would be.
        raster.draw(g, &[Vec2::new(0.055, 0.055)], 0.001, |_| [255; 3]);
        let (x, y) = at(&g, Vec2::new(0.055, 0.055));
        assert!(raster.pixel(x, y)[3] >= 128);
    }
}
