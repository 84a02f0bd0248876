//! Drawing the particles: the world-to-screen transform, the colourings with their colour
//! maps and legend, and one batched mesh (a textured quad per particle) for all particles.

use dfsph::simulation::MAX_SHAKE_OFFSET;
use dfsph::{Simulation, Vec2};
use dfsph_io::render::WaterLook;
use dfsph_io::surface::{SurfaceGrid, SurfaceRaster};
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
        Self::centred(0.5 * (world_min + world_max), scale, screen.center())
    }

    /// `centre` (m) at the screen point `at`, `scale` screen points per metre.
    pub fn centred(centre: Vec2, scale: f32, at: Pos2) -> Self {
        Self {
            origin: pos2(at.x - centre.x * scale, at.y + centre.y * scale),
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
    let mut img = ColorImage::filled([N, N], Color32::TRANSPARENT);
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

    /// The same field for the CPU rasteriser's pictures (recordings, the page's screenshot).
    pub fn frame_field(self) -> dfsph_io::render::FrameField {
        match self {
            Coloring::Speed => dfsph_io::render::FrameField::Speed,
            Coloring::Density => dfsph_io::render::FrameField::DensityError,
            Coloring::Pressure => dfsph_io::render::FrameField::Pressure,
        }
    }

    /// Name with unit, for the legend and the panel.
    pub fn label(self) -> &'static str {
        match self {
            Coloring::Speed => "speed (m/s)",
            Coloring::Density => "density error (%)",
            Coloring::Pressure => "pressure (Pa)",
        }
    }

    /// A fixed value range for this simulation's scene, in the colouring's unit: what a
    /// fixed colour scale starts from before the user has seen any auto range.
    pub fn scene_range(self, sim: &Simulation) -> (f32, f32) {
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
            Coloring::Density => (-1.0, 1.0),
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

    /// Whether the colour scale follows the data when the viewer starts.
    ///
    /// Speed and pressure: auto. Their scale changes with what the user does (pouring deepens
    /// the water, shaking and pushing speed it up), so any fixed scale saturates or washes
    /// out sooner or later. Density error: fixed (±1 %). It measures the solver's accuracy,
    /// whose meaning is absolute (tolerances are a few hundredths of a percent): a fixed scale
    /// lets a user compare settings, and stays white where the solve converges, whereas an
    /// auto scale would stretch noise of 0.01 % to full colour and make a converged solve look
    /// alarming.
    pub fn auto_by_default(self) -> bool {
        !matches!(self, Coloring::Density)
    }

    /// The smallest span an auto range may have, in the colouring's unit (water at rest must
    /// not blow its noise up to full colour).
    fn min_span(self) -> f32 {
        match self {
            Coloring::Speed => 0.05,
            Coloring::Density => 0.1,
            Coloring::Pressure => 10.0,
        }
    }

    /// Fill `out` with the field this colouring shows, one value per fluid particle in
    /// [`dfsph::world::World::positions`] order, in the colouring's unit.
    pub fn values(self, sim: &Simulation, out: &mut Vec<f32>) {
        out.clear();
        match self {
            Coloring::Speed => out.extend(sim.velocities().iter().map(|v| v.length())),
            Coloring::Density => out.extend(sim.density_ratios().iter().map(|r| 100.0 * (r - 1.0))),
            Coloring::Pressure => {
                let rho0 = sim.rest_density();
                out.extend(
                    sim.interpolated_pressures_over_rho0()
                        .iter()
                        .map(|p| p * rho0),
                )
            }
        }
        // Before the first step the per-particle fields may still be empty.
        out.resize(sim.positions().len(), 0.0);
    }

    /// The range an auto scale aims at for these values: robust percentiles (the 1st and the
    /// 99th, so that a few splashing or freshly poured particles do not set the scale),
    /// widened to [`Self::min_span`]. Speed and pressure start at 0 (still water is the
    /// colour map's start); density error is symmetric about 0 (white = rest density), its
    /// half-width set by compression alone, since the free surface, where the kernel is
    /// cut off, always reads expanded by 10 % and more and would swamp the scale. `None`
    /// without finite values.
    pub fn auto_target(self, values: &[f32], scratch: &mut Vec<f32>) -> Option<(f32, f32)> {
        scratch.clear();
        scratch.extend(values.iter().copied().filter(|v| v.is_finite()));
        if scratch.is_empty() {
            return None;
        }
        let n = scratch.len();
        let mut percentile = |q: f64| {
            let k = ((q * (n - 1) as f64).round() as usize).min(n - 1);
            *scratch.select_nth_unstable_by(k, f32::total_cmp).1
        };
        let (lo, hi) = (percentile(0.01), percentile(0.99));
        let span = self.min_span();
        Some(match self {
            Coloring::Speed => (0.0, hi.max(span)),
            Coloring::Pressure => (lo.min(0.0), hi.max(lo.min(0.0) + span)),
            Coloring::Density => {
                let half = hi.max(0.5 * span);
                (-half, half)
            }
        })
    }

    /// Fill `out` with one colour per value, `range` mapping to the colour map's ends.
    pub fn colors(self, values: &[f32], range: (f32, f32), out: &mut Vec<Color32>) {
        let (lo, hi) = range;
        let inv = 1.0 / (hi - lo).max(1e-9);
        out.clear();
        out.extend(values.iter().map(|&v| self.color((v - lo) * inv)));
    }
}

/// The colour scale of one colouring: auto (following the data, smoothed) or fixed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ColorScale {
    /// The range follows the data.
    pub auto: bool,
    /// The range in use, in the colouring's unit; the user's while fixed.
    pub range: (f32, f32),
    /// Whether `range` holds anything yet (an auto scale starts at its first target).
    started: bool,
}

/// Seconds an auto range takes to grow by 63 % of the way to a wider target: quick, so a
/// splash is not drawn saturated for long.
pub const AUTO_GROW_SECONDS: f32 = 0.15;
/// Seconds an auto range takes to shrink by 63 % of the way to a narrower target: slow, so
/// the colours do not flicker as the fastest particles come and go.
pub const AUTO_SHRINK_SECONDS: f32 = 1.5;

impl ColorScale {
    /// A scale, auto or fixed at `range`.
    pub fn new(auto: bool, range: (f32, f32)) -> Self {
        Self {
            auto,
            range,
            started: !auto,
        }
    }

    /// Move an auto range towards `target` over `seconds` of wall time (a fixed one stays).
    pub fn follow(&mut self, target: Option<(f32, f32)>, seconds: f32) {
        let Some((lo, hi)) = target.filter(|_| self.auto) else {
            return;
        };
        if !self.started {
            self.range = (lo, hi);
            self.started = true;
            return;
        }
        let step = |now: f32, to: f32, grows: bool| {
            let tau = if grows {
                AUTO_GROW_SECONDS
            } else {
                AUTO_SHRINK_SECONDS
            };
            now + (1.0 - (-seconds.max(0.0) / tau).exp()) * (to - now)
        };
        let (a, b) = self.range;
        self.range = (step(a, lo, lo < a), step(b, hi, hi > b));
    }

    /// Fix the range where it is now (the user unticked auto) or let it follow again.
    pub fn set_auto(&mut self, auto: bool) {
        self.auto = auto;
    }

    /// Forget the data seen (another scene): an auto range starts over at its next target.
    pub fn restart(&mut self) {
        if self.auto {
            self.started = false;
        }
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

/// One mesh for every particle: boundary particles (grey) first, fluid on top (unless the
/// water is drawn as a surface: `look`), each drawn at the physical particle radius (never
/// smaller than half a screen point). The rigid bodies' boundary particles are left out:
/// the bodies are drawn whole (`crate::bodies`).
pub fn particle_mesh(
    sim: &Simulation,
    transform: &ViewTransform,
    texture: egui::TextureId,
    fluid_colors: &[Color32],
    look: WaterLook,
) -> Mesh {
    let mut mesh = Mesh::with_texture(texture);
    let radius = (sim.particle_radius() * transform.scale()).max(0.5);
    let color = |body: u16| {
        if body == 0 {
            TANK_COLOR
        } else {
            WALL_COLOR
        }
    };
    let bodies = sim.boundary_bodies();
    if sim.rigid_body_count() == 0 {
        push_discs(
            &mut mesh,
            transform,
            sim.boundary_positions(),
            radius,
            |i| color(bodies.get(i).copied().unwrap_or(0)),
        );
    } else {
        let top = bodies.iter().copied().max().unwrap_or(0);
        let rigid: Vec<bool> = (0..=top).map(|b| sim.rigid_body_of(b).is_some()).collect();
        let (walls, ids): (Vec<Vec2>, Vec<u16>) = sim
            .boundary_positions()
            .iter()
            .zip(bodies)
            .filter(|(_, &b)| !rigid[b as usize])
            .map(|(&p, &b)| (p, b))
            .unzip();
        push_discs(&mut mesh, transform, &walls, radius, |i| color(ids[i]));
    }
    if look == WaterLook::Particles {
        push_discs(&mut mesh, transform, sim.positions(), radius, |i| {
            fluid_colors.get(i).copied().unwrap_or(Color32::LIGHT_BLUE)
        });
    }
    mesh
}

/// The largest side of the surface's texture, pixels: a coarser grid beyond it (the page's
/// WebGL 2 guarantees 2,048).
const MAX_SURFACE_SIDE: f32 = 2048.0;

/// The most pixels the surface's grid has: a coarser grid beyond it. Drawing costs about
/// 15 ns a pixel on one core of the 2-core test host (5,000 particles on 615 × 330 pixels:
/// 4 ms), so a full-window grid stays near 20 ms.
const MAX_SURFACE_PIXELS: f32 = 1.5e6;

/// The water as one surface ([`dfsph_io::surface`]): drawn on the CPU into a grid of
/// physical pixels over the water seen, uploaded as a texture, and drawn as one quad.
#[derive(Default)]
pub struct SurfaceLayer {
    raster: SurfaceRaster,
    texture: Option<TextureHandle>,
}

impl SurfaceLayer {
    /// Draw the fluid of `sim`, particle i coloured `fluid_colors[i]`, into `painter` (whose
    /// clip rectangle is the view), at `pixels_per_point` physical pixels a screen point.
    pub fn draw(
        &mut self,
        painter: &egui::Painter,
        transform: &ViewTransform,
        pixels_per_point: f32,
        sim: &Simulation,
        fluid_colors: &[Color32],
    ) {
        let Some(grid) = surface_grid(
            transform,
            painter.clip_rect(),
            pixels_per_point,
            sim.positions(),
            sim.particle_radius(),
        ) else {
            return;
        };
        self.raster
            .draw(grid, sim.positions(), sim.particle_radius(), |i| {
                let c = fluid_colors.get(i).copied().unwrap_or(Color32::LIGHT_BLUE);
                [c.r(), c.g(), c.b()]
            });
        let size = [grid.width as usize, grid.height as usize];
        let image = ColorImage::from_rgba_unmultiplied(size, self.raster.rgba());
        let options = TextureOptions::LINEAR;
        let texture = match &mut self.texture {
            Some(t) => {
                t.set(image, options);
                t
            }
            None => {
                self.texture
                    .insert(painter.ctx().load_texture("water-surface", image, options))
            }
        };
        let rect = Rect::from_min_max(
            transform.to_screen(grid.top_left),
            transform.to_screen(grid.bottom_right()),
        );
        let mut mesh = Mesh::with_texture(texture.id());
        let uv = Rect::from_min_max(pos2(0.0, 0.0), pos2(1.0, 1.0));
        mesh.add_rect_with_uv(rect, uv, Color32::WHITE);
        painter.add(Shape::mesh(mesh));
    }
}

/// The grid the surface is drawn on: the water's extent (plus the indicator's reach) within
/// the view `clip` (screen points), in cells of one physical pixel, or of a quarter particle
/// radius when zoomed in further (the texture's filtering smooths between), never more than
/// [`MAX_SURFACE_SIDE`] a side nor [`MAX_SURFACE_PIXELS`] in all. `None` when no water is in
/// view.
pub fn surface_grid(
    transform: &ViewTransform,
    clip: Rect,
    pixels_per_point: f32,
    positions: &[Vec2],
    radius: f32,
) -> Option<SurfaceGrid> {
    let (mut lo, mut hi) = (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY));
    for &p in positions.iter().filter(|p| p.is_finite()) {
        lo = lo.min(p);
        hi = hi.max(p);
    }
    let reach = Vec2::splat(dfsph_io::surface::SMOOTHING_RADII * radius);
    let (a, b) = (
        transform.to_world(clip.left_bottom()),
        transform.to_world(clip.right_top()),
    );
    let lo = (lo - reach).max(a);
    let hi = (hi + reach).min(b);
    if !(lo.x < hi.x && lo.y < hi.y) {
        return None;
    }
    let size = hi - lo;
    let pixel = 1.0 / (transform.scale() * pixels_per_point.max(0.1));
    let cell = pixel
        .max(0.25 * radius)
        .max(size.x / MAX_SURFACE_SIDE)
        .max(size.y / MAX_SURFACE_SIDE)
        .max((size.x * size.y / MAX_SURFACE_PIXELS).sqrt());
    Some(SurfaceGrid {
        top_left: Vec2::new(lo.x, hi.y),
        cell,
        width: (size.x / cell).ceil().max(1.0) as u32,
        height: (size.y / cell).ceil().max(1.0) as u32,
    })
}

/// Draw the colour legend into `rect` (see [`crate::view::layout`]): the colour bar with
/// its range's ends and middle labelled, the colouring's name and unit, and whether the
/// range follows the data. Upright beside the tank, or lying under it when `horizontal`.
pub fn legend(
    painter: &egui::Painter,
    rect: Rect,
    horizontal: bool,
    coloring: Coloring,
    scale: &ColorScale,
) {
    let (lo, hi) = scale.range;
    let font = egui::FontId::proportional(12.0);
    let small = egui::FontId::proportional(11.0);
    let text = Color32::from_gray(230);
    let dim = Color32::from_gray(160);
    // Labels with two or three significant digits: "6.8", "0.35", "1200", "12k".
    let step = crate::ticks::nice_step(((hi - lo).abs() as f64 / 60.0).max(1e-9));
    let fmt = |v: f32| crate::ticks::format_tick(v as f64, step);
    let mode = if scale.auto {
        "auto range"
    } else {
        "fixed range"
    };
    let bar = if horizontal {
        painter.text(
            rect.left_top(),
            egui::Align2::LEFT_TOP,
            format!("{}  ·  {mode}", coloring.label()),
            font.clone(),
            text,
        );
        Rect::from_min_size(rect.left_top() + vec2(0.0, 16.0), vec2(rect.width(), 12.0))
    } else {
        painter.text(
            rect.right_top(),
            egui::Align2::RIGHT_TOP,
            coloring.label(),
            font.clone(),
            text,
        );
        painter.text(
            rect.right_top() + vec2(0.0, 15.0),
            egui::Align2::RIGHT_TOP,
            mode,
            small.clone(),
            dim,
        );
        Rect::from_min_size(
            rect.left_top() + vec2(rect.width() - 70.0, 36.0),
            vec2(16.0, rect.height() - 44.0),
        )
    };
    let mut mesh = Mesh::default();
    const N: usize = 48;
    for k in 0..N {
        let t0 = k as f32 / N as f32;
        let t1 = (k + 1) as f32 / N as f32;
        let r = if horizontal {
            Rect::from_x_y_ranges(
                (bar.left() + t0 * bar.width())..=(bar.left() + t1 * bar.width()),
                bar.y_range(),
            )
        } else {
            Rect::from_x_y_ranges(
                bar.x_range(),
                (bar.bottom() - t1 * bar.height())..=(bar.bottom() - t0 * bar.height()),
            )
        };
        mesh.add_colored_rect(r, coloring.color(0.5 * (t0 + t1)));
    }
    painter.add(Shape::mesh(mesh));
    painter.rect_stroke(
        bar,
        0.0,
        Stroke::new(1.0_f32, Color32::GRAY),
        egui::StrokeKind::Middle,
    );
    for (t, v) in [(0.0, lo), (0.5, 0.5 * (lo + hi)), (1.0, hi)] {
        if horizontal {
            let x = bar.left() + t * bar.width();
            let align = [
                egui::Align2::LEFT_TOP,
                egui::Align2::CENTER_TOP,
                egui::Align2::RIGHT_TOP,
            ][(2.0 * t) as usize];
            painter.text(
                pos2(x, bar.bottom() + 2.0),
                align,
                fmt(v),
                small.clone(),
                text,
            );
        } else {
            let y = bar.bottom() - t * bar.height();
            painter.line_segment(
                [pos2(bar.right(), y), pos2(bar.right() + 4.0, y)],
                Stroke::new(1.0_f32, Color32::GRAY),
            );
            painter.text(
                pos2(bar.right() + 6.0, y),
                egui::Align2::LEFT_CENTER,
                fmt(v),
                small.clone(),
                text,
            );
        }
    }
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
        let mut values = Vec::new();
        Coloring::Speed.values(&sim, &mut values);
        let mut colors = Vec::new();
        Coloring::Speed.colors(&values, Coloring::Speed.scene_range(&sim), &mut colors);
        assert_eq!(colors.len(), sim.positions().len());
        let mesh = particle_mesh(
            &sim,
            &t,
            egui::TextureId::default(),
            &colors,
            WaterLook::Particles,
        );
        let n = sim.positions().len() + sim.boundary_positions().len();
        assert_eq!(mesh.vertices.len(), 4 * n);
        assert_eq!(mesh.indices.len(), 6 * n);
        // Every particle lies inside the view.
        assert!(mesh
            .vertices
            .iter()
            .all(|v| screen.expand(20.0).contains(v.pos)));
        // As a surface, the water is not in the mesh: only the walls are.
        let walls = particle_mesh(
            &sim,
            &t,
            egui::TextureId::default(),
            &colors,
            WaterLook::Surface,
        );
        assert_eq!(walls.vertices.len(), 4 * sim.boundary_positions().len());
    }

    #[test]
    fn the_surface_grid_covers_the_water_in_view_at_the_screens_pixels() {
        let mut scene = dfsph::scene::builtin("dam-break").unwrap();
        scene.particle_radius = 0.01;
        let sim = Simulation::new(&scene).unwrap();
        let (lo, hi) = world_bounds(&sim);
        let screen = Rect::from_min_size(Pos2::ZERO, vec2(640.0, 480.0));
        let t = ViewTransform::fit(lo, hi, screen);
        let r = sim.particle_radius();
        assert!(1.0 / (2.0 * t.scale()) > 0.25 * r, "a pixel is the coarser");
        let grid = surface_grid(&t, screen, 2.0, sim.positions(), r).unwrap();
        // One cell a physical pixel (two a screen point) while that is finer than r/4.
        assert!(
            (grid.cell - 1.0 / (2.0 * t.scale())).abs() < 1e-6,
            "{grid:?}"
        );
        let (far_lo, far_hi) = sim.positions().iter().fold(
            (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY)),
            |(a, b), &p| (a.min(p), b.max(p)),
        );
        let reach = dfsph_io::surface::SMOOTHING_RADII * r;
        assert!(
            (grid.top_left.x - (far_lo.x - reach)).abs() < 1e-4,
            "{grid:?}"
        );
        assert!(
            (grid.top_left.y - (far_hi.y + reach)).abs() < 1e-4,
            "{grid:?}"
        );
        let end = grid.bottom_right();
        assert!(end.x >= far_hi.x + reach - 1e-4 && end.y <= far_lo.y - reach + 1e-4);
        // Zoomed far in: a quarter radius a cell, at most 2,048 cells a side.
        let zoomed = ViewTransform::centred(far_lo, 1.0e5, screen.center());
        let grid = surface_grid(&zoomed, screen, 1.0, sim.positions(), r).unwrap();
        assert!((grid.cell - 0.25 * r).abs() < 1e-7, "{grid:?}");
        let whole = ViewTransform::fit(lo, hi, Rect::from_min_size(Pos2::ZERO, vec2(1e5, 1e5)));
        let big = Rect::from_min_size(Pos2::ZERO, vec2(1e5, 1e5));
        let grid = surface_grid(&whole, big, 1.0, sim.positions(), r).unwrap();
        assert!(grid.width <= 2048 && grid.height <= 2048, "{grid:?}");
        assert!(grid.width as f32 * grid.height as f32 <= 1.51e6, "{grid:?}");
        // No water in view: nothing to draw.
        let away = ViewTransform::centred(Vec2::new(100.0, 100.0), t.scale(), screen.center());
        assert!(surface_grid(&away, screen, 1.0, sim.positions(), r).is_none());
    }

    #[test]
    fn auto_range_follows_robust_percentiles_and_ignores_outliers() {
        let mut scratch = Vec::new();
        // 1000 particles at 0–1 m/s and ten splashing at 40 m/s: the scale follows the bulk.
        let mut speeds: Vec<f32> = (0..1000).map(|k| k as f32 / 1000.0).collect();
        speeds.extend([40.0; 10]);
        let (lo, hi) = Coloring::Speed.auto_target(&speeds, &mut scratch).unwrap();
        assert_eq!(lo, 0.0);
        assert!(hi > 0.95 && hi < 1.1, "{hi}");
        // Water at rest: the range does not collapse onto the noise.
        let still = vec![1e-4f32; 100];
        let (_, hi) = Coloring::Speed.auto_target(&still, &mut scratch).unwrap();
        assert!(hi >= 0.05, "{hi}");
        // Density error: symmetric, set by compression (the surface's -20 % is left out).
        let mut errors = vec![0.2f32; 900];
        errors.extend([-20.0; 100]);
        let (lo, hi) = Coloring::Density
            .auto_target(&errors, &mut scratch)
            .unwrap();
        assert_eq!(lo, -hi);
        assert!((hi - 0.2).abs() < 1e-6, "{hi}");
        // Pressure: from 0 up; NaN is skipped; nothing finite gives no target.
        let p = [0.0, 5000.0, f32::NAN, 9000.0, 10000.0];
        let (lo, hi) = Coloring::Pressure.auto_target(&p, &mut scratch).unwrap();
        assert_eq!(lo, 0.0);
        assert!((9000.0..=10000.0).contains(&hi), "{hi}");
        assert_eq!(
            Coloring::Pressure.auto_target(&[f32::NAN], &mut scratch),
            None
        );
    }

    #[test]
    fn auto_scale_grows_fast_shrinks_slowly_and_a_fixed_scale_stays() {
        let mut s = ColorScale::new(true, (0.0, 1.0));
        // The first target is taken at once.
        s.follow(Some((0.0, 2.0)), 0.016);
        assert_eq!(s.range, (0.0, 2.0));
        // A wider target: most of the way within half a second.
        for _ in 0..30 {
            s.follow(Some((0.0, 4.0)), 0.016);
        }
        assert!(s.range.1 > 3.8, "{:?}", s.range);
        // A narrower one: still well above it after the same time (no flicker), there in
        // the end.
        for _ in 0..30 {
            s.follow(Some((0.0, 1.0)), 0.016);
        }
        assert!(s.range.1 > 2.5, "{:?}", s.range);
        for _ in 0..1000 {
            s.follow(Some((0.0, 1.0)), 0.016);
        }
        assert!((s.range.1 - 1.0).abs() < 1e-3, "{:?}", s.range);
        // Fixed: stays where it was fixed, whatever the data.
        s.set_auto(false);
        s.follow(Some((0.0, 9.0)), 1.0);
        assert!((s.range.1 - 1.0).abs() < 1e-3);
        let mut fixed = ColorScale::new(false, (-1.0, 1.0));
        fixed.follow(Some((0.0, 9.0)), 1.0);
        assert_eq!(fixed.range, (-1.0, 1.0));
        // Auto again after a restart (another scene): takes the next target at once.
        s.set_auto(true);
        s.restart();
        s.follow(Some((0.0, 7.0)), 0.016);
        assert_eq!(s.range, (0.0, 7.0));
    }
}
