//! Drawing the particles: the world-to-screen transform, the colourings with their colour
//! maps and legend, and one batched mesh (a textured quad per particle) for all particles.

use dfsph::simulation::MAX_SHAKE_OFFSET;
use dfsph::{Simulation, Vec2};
use eframe::egui::{
    self, pos2, vec2, Color32, ColorImage, Mesh, Pos2, Rect, Shape, Stroke, TextureHandle,
    TextureOptions,
};

/// Maps world coordinates (m, y up) to screen points (y down), fitting a world rectangle
/// into a screen rectangle with the aspect ratio kept.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ViewTransform {
    /// Screen position of the world origin.
    origin: Pos2,
    /// Screen points per metre.
    scale: f32,
}

impl ViewTransform {
    /// Fit `[world_min, world_max]` centred into `screen`.
    pub fn fit(world_min: Vec2, world_max: Vec2, screen: Rect) -> Self {
        let size = (world_max - world_min).max(Vec2::splat(1e-6));
        let scale = (screen.width() / size.x)
            .min(screen.height() / size.y)
            .max(1e-6);
        let centre = 0.5 * (world_min + world_max);
        let c = screen.center();
        Self {
            origin: pos2(c.x - centre.x * scale, c.y + centre.y * scale),
            scale,
        }
    }

    /// Screen points per metre.
    pub fn scale(&self) -> f32 {
        self.scale
    }

    /// World (m) → screen.
    pub fn to_screen(&self, p: Vec2) -> Pos2 {
        pos2(
            self.origin.x + p.x * self.scale,
            self.origin.y - p.y * self.scale,
        )
    }

    /// Screen → world (m).
    pub fn to_world(&self, p: Pos2) -> Vec2 {
        Vec2::new(
            (p.x - self.origin.x) / self.scale,
            (self.origin.y - p.y) / self.scale,
        )
    }
}

/// The world rectangle the view shows: the tank at rest, widened by how far it can be
/// shaken, plus room for the boundary layers.
pub fn world_bounds(sim: &Simulation) -> (Vec2, Vec2) {
    let tank = &sim.scene().tank;
    let margin = 4.0 * sim.particle_radius() + 0.05;
    let lo = Vec2::new(tank.min[0] as f32, tank.min[1] as f32);
    let hi = Vec2::new(tank.max[0] as f32, tank.max[1] as f32);
    let shake = Vec2::new(MAX_SHAKE_OFFSET, 0.0);
    (
        lo - shake - Vec2::splat(margin),
        hi + shake + Vec2::splat(margin),
    )
}

/// A white disc with a soft edge; tinted per particle through the vertex colour.
pub fn disc_texture(ctx: &egui::Context) -> TextureHandle {
    const N: usize = 64;
    let mut img = ColorImage::new([N, N], Color32::TRANSPARENT);
    let c = 0.5 * N as f32;
    for y in 0..N {
        for x in 0..N {
            let d = vec2(x as f32 + 0.5 - c, y as f32 + 0.5 - c).length();
            // One texel of anti-aliasing at the rim.
            let a = (c - d).clamp(0.0, 1.0);
            img.pixels[y * N + x] = Color32::from_white_alpha((a * 255.0).round() as u8);
        }
    }
    ctx.load_texture("particle-disc", img, TextureOptions::LINEAR)
}

/// What the fluid particles' colour shows.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Coloring {
    /// |v|, m/s.
    #[default]
    Speed,
    /// Density error ρ/ρ0 − 1, percent.
    Density,
    /// Pressure, Pa.
    Pressure,
}

impl Coloring {
    /// Every colouring, in the order `c` cycles through them. (A per-particle divergence
    /// error is not exposed by the solver, so it is not offered.)
    pub const ALL: [Coloring; 3] = [Coloring::Speed, Coloring::Density, Coloring::Pressure];

    /// The next colouring.
    pub fn next(self) -> Self {
        let i = Self::ALL.iter().position(|&c| c == self).unwrap_or(0);
        Self::ALL[(i + 1) % Self::ALL.len()]
    }

    /// Name with unit, for the legend and the panel.
    pub fn label(self) -> &'static str {
        match self {
            Coloring::Speed => "speed (m/s)",
            Coloring::Density => "density error (%)",
            Coloring::Pressure => "pressure (Pa)",
        }
    }

    /// The value range the colour map spans for this simulation.
    pub fn range(self, sim: &Simulation) -> (f32, f32) {
        let g = sim.gravity().length().max(1.0);
        let scene = sim.scene();
        let depth = scene
            .fluid
            .iter()
            .map(|b| b.max[1] - scene.tank.min[1])
            .fold(0.0f64, f64::max)
            .max(0.1) as f32;
        match self {
            // The speed a column of this depth reaches falling freely over its own height,
            // rounded up.
            Coloring::Speed => (0.0, (g * depth).sqrt().ceil()),
            Coloring::Density => (-3.0, 3.0),
            Coloring::Pressure => (0.0, sim.rest_density() * g * depth),
        }
    }

    /// Colour map from 0–1 to a colour.
    pub fn color(self, t: f32) -> Color32 {
        match self {
            Coloring::Speed => ramp(WATER, t),
            Coloring::Density => ramp(COOLWARM, t),
            Coloring::Pressure => {
                let [r, g, b] = dfsph_io::colormap::viridis(t);
                Color32::from_rgb(r, g, b)
            }
        }
    }

    /// Fill `out` with one colour per fluid particle, in [`Simulation::positions`] order.
    pub fn colors(self, sim: &Simulation, out: &mut Vec<Color32>) {
        let (lo, hi) = self.range(sim);
        let inv = 1.0 / (hi - lo).max(1e-9);
        let map = |v: f32| self.color((v - lo) * inv);
        out.clear();
        match self {
            Coloring::Speed => out.extend(sim.velocities().iter().map(|v| map(v.length()))),
            Coloring::Density => {
                out.extend(sim.density_ratios().iter().map(|r| map(100.0 * (r - 1.0))))
            }
            Coloring::Pressure => {
                let rho0 = sim.rest_density();
                out.extend(
                    sim.interpolated_pressures_over_rho0()
                        .iter()
                        .map(|p| map(p * rho0)),
                )
            }
        }
        // Before the first step the per-particle fields may still be empty.
        out.resize(sim.positions().len(), self.color(0.0));
    }
}

/// Deep blue (still) → cyan → white (fast): reads as water.
const WATER: &[[u8; 3]] = &[
    [16, 52, 138],
    [24, 110, 200],
    [60, 175, 230],
    [160, 225, 245],
    [255, 255, 255],
];
/// Blue (expanded) → white (at rest density) → red (compressed).
const COOLWARM: &[[u8; 3]] = &[[59, 76, 192], [221, 221, 221], [180, 4, 38]];

/// Piecewise-linear colour ramp through `stops` at `t` in 0–1 (clamped; NaN maps to 0).
fn ramp(stops: &[[u8; 3]], t: f32) -> Color32 {
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
    let x = t * (stops.len() - 1) as f32;
    let i = (x.floor() as usize).min(stops.len() - 2);
    let f = x - i as f32;
    let (a, b) = (stops[i], stops[i + 1]);
    let mix = |k: usize| (a[k] as f32 + f * (b[k] as f32 - a[k] as f32)).round() as u8;
    Color32::from_rgb(mix(0), mix(1), mix(2))
}

/// Colour of tank wall particles.
pub const TANK_COLOR: Color32 = Color32::from_rgb(120, 120, 128);
/// Colour of obstacles and drawn walls.
pub const WALL_COLOR: Color32 = Color32::from_rgb(170, 160, 140);

/// Append a quad of half-size `radius` (screen points) at each position, tinted `color`.
pub fn push_discs(
    mesh: &mut Mesh,
    transform: &ViewTransform,
    positions: &[Vec2],
    radius: f32,
    mut color: impl FnMut(usize) -> Color32,
) {
    let uv = Rect::from_min_max(pos2(0.0, 0.0), pos2(1.0, 1.0));
    mesh.reserve_vertices(4 * positions.len());
    mesh.reserve_triangles(2 * positions.len());
    for (i, &p) in positions.iter().enumerate() {
        let c = transform.to_screen(p);
        let rect = Rect::from_center_size(c, vec2(2.0 * radius, 2.0 * radius));
        mesh.add_rect_with_uv(rect, uv, color(i));
    }
}

/// One mesh for every particle: boundary particles (grey) first, fluid on top, each drawn at
/// the physical particle radius (never smaller than half a screen point).
pub fn particle_mesh(
    sim: &Simulation,
    transform: &ViewTransform,
    texture: egui::TextureId,
    fluid_colors: &[Color32],
) -> Mesh {
    let mut mesh = Mesh::with_texture(texture);
    let radius = (sim.particle_radius() * transform.scale()).max(0.5);
    let bodies = sim.boundary_bodies();
    push_discs(
        &mut mesh,
        transform,
        sim.boundary_positions(),
        radius,
        |i| {
            if bodies.get(i).copied().unwrap_or(0) == 0 {
                TANK_COLOR
            } else {
                WALL_COLOR
            }
        },
    );
    push_discs(&mut mesh, transform, sim.positions(), radius, |i| {
        fluid_colors.get(i).copied().unwrap_or(Color32::LIGHT_BLUE)
    });
    mesh
}

/// Draw the colour legend (a vertical bar with its range) in the top-right corner of `rect`.
pub fn legend(painter: &egui::Painter, rect: Rect, coloring: Coloring, range: (f32, f32)) {
    let bar = Rect::from_min_size(rect.right_top() + vec2(-90.0, 30.0), vec2(16.0, 160.0));
    let mut mesh = Mesh::default();
    const N: usize = 32;
    for k in 0..N {
        let t0 = k as f32 / N as f32;
        let t1 = (k + 1) as f32 / N as f32;
        let r = Rect::from_x_y_ranges(
            bar.x_range(),
            (bar.bottom() - t1 * bar.height())..=(bar.bottom() - t0 * bar.height()),
        );
        mesh.add_colored_rect(r, coloring.color(0.5 * (t0 + t1)));
    }
    painter.add(Shape::mesh(mesh));
    painter.rect_stroke(bar, 0.0, Stroke::new(1.0, Color32::GRAY));
    let font = egui::FontId::proportional(12.0);
    let text = Color32::from_gray(230);
    let fmt = |v: f32| {
        if v.abs() >= 10.0 || v == v.round() {
            format!("{v:.0}")
        } else {
            format!("{v:.1}")
        }
    };
    painter.text(
        bar.right_top() + vec2(4.0, 0.0),
        egui::Align2::LEFT_TOP,
        fmt(range.1),
        font.clone(),
        text,
    );
    painter.text(
        bar.right_bottom() + vec2(4.0, 0.0),
        egui::Align2::LEFT_BOTTOM,
        fmt(range.0),
        font.clone(),
        text,
    );
    painter.text(
        bar.center_top() - vec2(0.0, 6.0),
        egui::Align2::CENTER_BOTTOM,
        coloring.label(),
        font,
        text,
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn transform_keeps_aspect_and_round_trips() {
        let screen = Rect::from_min_size(pos2(10.0, 20.0), vec2(800.0, 400.0));
        let t = ViewTransform::fit(Vec2::ZERO, Vec2::new(4.0, 3.0), screen);
        // 400 px high for 3 m: the height limits the scale.
        assert!((t.scale() - 400.0 / 3.0).abs() < 1e-3);
        let p = Vec2::new(1.25, 2.5);
        assert!((t.to_world(t.to_screen(p)) - p).length() < 1e-5);
        // y points up in the world and down on screen; the box is centred.
        assert!(t.to_screen(Vec2::new(0.0, 3.0)).y < t.to_screen(Vec2::ZERO).y);
        assert!((t.to_screen(Vec2::new(2.0, 1.5)) - screen.center()).length() < 1e-3);
        assert!((t.to_screen(Vec2::ZERO).y - screen.bottom()).abs() < 1e-3);
    }

    #[test]
    fn colorings_cycle_and_ramps_clamp() {
        assert_eq!(Coloring::Speed.next(), Coloring::Density);
        assert_eq!(Coloring::Pressure.next(), Coloring::Speed);
        assert_eq!(ramp(WATER, -1.0), Color32::from_rgb(16, 52, 138));
        assert_eq!(ramp(WATER, 2.0), Color32::WHITE);
        assert_eq!(ramp(WATER, f32::NAN), ramp(WATER, 0.0));
        assert_eq!(ramp(COOLWARM, 0.5), Color32::from_rgb(221, 221, 221));
        // Pressure uses the colour map of the PNG frames (dfsph-io's viridis).
        assert_eq!(
            Coloring::Pressure.color(0.0),
            Color32::from_rgb(0x44, 0x01, 0x54)
        );
        assert_eq!(
            Coloring::Pressure.color(1.0),
            Color32::from_rgb(0xfd, 0xe7, 0x25)
        );
    }

    #[test]
    fn mesh_has_one_quad_per_particle() {
        let mut scene = dfsph::scene::builtin("hydrostatic").unwrap();
        scene.particle_radius = 0.05;
        let sim = Simulation::new(&scene).unwrap();
        let (lo, hi) = world_bounds(&sim);
        let screen = Rect::from_min_size(Pos2::ZERO, vec2(640.0, 480.0));
        let t = ViewTransform::fit(lo, hi, screen);
        let mut colors = Vec::new();
        Coloring::Speed.colors(&sim, &mut colors);
        assert_eq!(colors.len(), sim.positions().len());
        let mesh = particle_mesh(&sim, &t, egui::TextureId::default(), &colors);
        let n = sim.positions().len() + sim.boundary_positions().len();
        assert_eq!(mesh.vertices.len(), 4 * n);
        assert_eq!(mesh.indices.len(), 6 * n);
        // Every particle lies inside the view.
        assert!(mesh
            .vertices
            .iter()
            .all(|v| screen.expand(20.0).contains(v.pos)));
    }
}
