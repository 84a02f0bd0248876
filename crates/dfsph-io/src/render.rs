//! CPU rasteriser: draws one frame to an image with tiny-skia, no display or GPU needed.
//!
//! Boundary particles (tank walls, obstacles) are grey discs, fluid particles are discs at
//! their physical radius coloured by speed with [`viridis`](crate::colormap::viridis), and
//! rigid bodies are their outlines, filled by density ([`body_fill`]) and edged darker
//! ([`BODY_EDGE`]), over the water, as the interactive viewer draws them. A band
//! above the scene holds the legend: `0`, the colour bar, and the speed at its top end in m/s.
//! The scene keeps its aspect ratio; the image has the requested width.

use std::borrow::Cow;
use std::path::Path;

use anyhow::{anyhow, Context, Result};
use dfsph::rigid::RigidBodyState;
use dfsph::scene::BodyShape;
use dfsph::{Simulation, Snapshot, Vec2};
use tiny_skia::{Color, FillRule, LineJoin, Paint, PathBuilder, Pixmap, Rect, Stroke, Transform};

use crate::atomic::write_atomic;
use crate::colormap::{body_fill, viridis, BODY_EDGE};
use crate::font;
use crate::surface::{SurfaceGrid, SurfaceRaster};

/// Largest image side in pixels.
pub const MAX_SIDE: u32 = 16_384;
/// Smallest image width in pixels.
pub const MIN_WIDTH: u32 = 64;

const BACKGROUND: Color = Color::WHITE;
const WALL_GREY: u8 = 150;
const TEXT_GREY: u8 = 40;
/// Colour buckets: particles of one bucket are filled as one path.
const BUCKETS: usize = 256;

/// What a frame draws besides the fluid: the tank, the walls, the rigid bodies and the
/// particle size.
#[derive(Clone, Debug, Default)]
pub struct RenderGeometry<'a> {
    /// Tank interior, lower-left corner, m.
    pub tank_min: Vec2,
    /// Tank interior, upper-right corner, m.
    pub tank_max: Vec2,
    /// Wall particle positions (the tank's walls, obstacles), m, drawn as grey discs. Not
    /// the rigid bodies' particles: [`Self::bodies`] draws those bodies whole.
    pub boundary: Cow<'a, [Vec2]>,
    /// Particle radius, m (fluid and wall particles are drawn this size).
    pub particle_radius: f32,
    /// Rest density ρ0, kg/m³ (the density error's reference).
    pub rest_density: f32,
    /// The rigid bodies, each drawn as its outline filled with [`body_fill`] of its mean
    /// density, edged with [`BODY_EDGE`] (a circle also with a radius, so its spin shows).
    pub bodies: Vec<RigidBodyState>,
}

impl<'a> RenderGeometry<'a> {
    /// The geometry of a running simulation as it stands now. Without rigid bodies the
    /// walls are borrowed from `sim`; with them, the walls less the bodies' particles are
    /// copied.
    pub fn of(sim: &'a Simulation) -> Self {
        let (tank_min, tank_max) = sim.tank_interior();
        Self {
            tank_min,
            tank_max,
            boundary: wall_positions(sim),
            particle_radius: sim.particle_radius(),
            rest_density: sim.rest_density(),
            bodies: sim.rigid_bodies(),
        }
    }

    /// The same geometry owning its walls (to keep a frame past the simulation's next step,
    /// or send it to another thread).
    pub fn into_owned(self) -> RenderGeometry<'static> {
        RenderGeometry {
            tank_min: self.tank_min,
            tank_max: self.tank_max,
            boundary: Cow::Owned(self.boundary.into_owned()),
            particle_radius: self.particle_radius,
            rest_density: self.rest_density,
            bodies: self.bodies,
        }
    }
}

/// The positions of `sim`'s boundary particles that are not on a rigid body (the tank's
/// walls, obstacles), in [`Simulation::boundary_positions`]' order.
pub fn wall_positions(sim: &Simulation) -> Cow<'_, [Vec2]> {
    let positions = sim.boundary_positions();
    if sim.rigid_body_count() == 0 {
        return Cow::Borrowed(positions);
    }
    let ids = sim.boundary_bodies();
    let top = ids.iter().copied().max().unwrap_or(0);
    let rigid: Vec<bool> = (0..=top).map(|b| sim.rigid_body_of(b).is_some()).collect();
    Cow::Owned(
        positions
            .iter()
            .zip(ids)
            .filter(|(_, &b)| !rigid[usize::from(b)])
            .map(|(&p, _)| p)
            .collect(),
    )
}

/// The field the water is coloured by (the viewer's colourings).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum FrameField {
    /// Speed |v|, m/s, from 0 (viridis).
    #[default]
    Speed,
    /// Pressure, Pa (the snapshot's pressure field), from 0 (viridis).
    Pressure,
    /// Density error 100·(ρ/ρ0 − 1), %, symmetric about 0 (blue, white, red).
    DensityError,
}

impl FrameField {
    /// Every field, by the name `--color-by` takes.
    pub const NAMES: [(&'static str, FrameField); 3] = [
        ("speed", FrameField::Speed),
        ("pressure", FrameField::Pressure),
        ("density", FrameField::DensityError),
    ];

    /// The field named `name` (`speed`, `pressure`, `density`).
    pub fn from_name(name: &str) -> Option<Self> {
        by_name(&Self::NAMES, name)
    }
}

/// How the water is drawn.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum WaterLook {
    /// A smooth surface with an anti-aliased edge ([`crate::surface`]).
    #[default]
    Surface,
    /// One dot per particle, at the particle radius.
    Particles,
}

impl WaterLook {
    /// Every look, by the name `--look` takes.
    pub const NAMES: [(&'static str, WaterLook); 2] = [
        ("surface", WaterLook::Surface),
        ("particles", WaterLook::Particles),
    ];

    /// The look named `name` (`surface`, `particles`).
    pub fn from_name(name: &str) -> Option<Self> {
        by_name(&Self::NAMES, name)
    }
}

/// The value `name` stands for in a table of names (a command-line choice).
pub fn by_name<T: Copy>(names: &[(&str, T)], name: &str) -> Option<T> {
    names.iter().find(|(n, _)| *n == name).map(|&(_, v)| v)
}

/// How to draw.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderOptions {
    /// Image width in pixels (clamped to [`MIN_WIDTH`], [`MAX_SIDE`]).
    pub width: u32,
    /// The field the water is coloured by.
    pub field: FrameField,
    /// Top of the colour scale in the field's unit (for the density error, the scale runs
    /// from minus this to this). `None`: the frame's largest value. Give a fixed value to
    /// keep colours comparable between frames ([`field_scale`]).
    pub scale_max: Option<f32>,
    /// The water as a surface or as dots.
    pub look: WaterLook,
}

impl Default for RenderOptions {
    fn default() -> Self {
        Self {
            width: 800,
            field: FrameField::Speed,
            scale_max: None,
            look: WaterLook::Surface,
        }
    }
}

/// World-to-pixel mapping: `px = (x − x0)·scale + left`, `py = top + (y1 − y)·scale`.
struct View {
    x0: f32,
    y1: f32,
    scale: f32,
    left: f32,
    top: f32,
}

impl View {
    fn map(&self, p: Vec2) -> (f32, f32) {
        (
            self.left + (p.x - self.x0) * self.scale,
            self.top + (self.y1 - p.y) * self.scale,
        )
    }
}

/// Where a frame's pixels go: the world-to-pixel mapping and the image's size.
struct Layout {
    view: View,
    width: u32,
    height: u32,
    /// Height of the legend band above the scene, pixels.
    band: u32,
}

/// The layout of a frame of `geometry` `width` pixels wide (clamped to [`MIN_WIDTH`],
/// [`MAX_SIDE`]).
fn layout(geometry: &RenderGeometry, width: u32) -> Result<Layout> {
    let r = geometry.particle_radius.max(0.0);
    // Scene extent: the tank interior and every wall particle, plus one radius and a margin.
    // (The rigid bodies stay in the tank.)
    let mut lo = geometry.tank_min.min(geometry.tank_max);
    let mut hi = geometry.tank_min.max(geometry.tank_max);
    for &p in geometry.boundary.iter().filter(|p| p.is_finite()) {
        lo = lo.min(p);
        hi = hi.max(p);
    }
    if !(lo.is_finite() && hi.is_finite()) {
        return Err(anyhow!("cannot render: the tank extent is not finite"));
    }
    let size = (hi - lo).max(Vec2::splat(1.0e-6));
    let pad = r + 0.02 * size.max_element();
    lo -= Vec2::splat(pad);
    hi += Vec2::splat(pad);
    let size = hi - lo;

    let width = width.clamp(MIN_WIDTH, MAX_SIDE);
    let band = band_height(width);
    let scale = (width as f32 / size.x).min((MAX_SIDE - band) as f32 / size.y);
    let scene_height = ((size.y * scale).ceil() as u32).max(1);
    Ok(Layout {
        view: View {
            x0: lo.x,
            y1: hi.y,
            scale,
            left: 0.5 * (width as f32 - size.x * scale),
            top: band as f32,
        },
        width,
        height: band + scene_height,
        band,
    })
}

/// Draw one frame.
pub fn render_frame(
    geometry: &RenderGeometry,
    snapshot: &Snapshot,
    options: &RenderOptions,
) -> Result<Pixmap> {
    let Layout {
        view,
        width,
        height,
        band,
    } = layout(geometry, options.width)?;
    let mut pixmap = Pixmap::new(width, height)
        .ok_or_else(|| anyhow!("cannot allocate a {width}x{height} image"))?;
    pixmap.fill(BACKGROUND);
    // Discs thinner than a pixel would vanish under anti-aliasing.
    let r_px = (geometry.particle_radius.max(0.0) * view.scale).max(0.6);

    // Walls.
    let mut walls = PathBuilder::new();
    for &p in geometry.boundary.iter().filter(|p| p.is_finite()) {
        let (x, y) = view.map(p);
        walls.push_circle(x, y, r_px);
    }
    fill(&mut pixmap, walls, [WALL_GREY; 3]);

    // Fluid, coloured by the field.
    let n = snapshot.position.len();
    let values: Vec<f32> = match options.field {
        FrameField::Speed => (0..n)
            .map(|i| snapshot.velocity.get(i).map_or(0.0, |v| v.length()))
            .collect(),
        FrameField::Pressure => (0..n)
            .map(|i| snapshot.pressure.get(i).copied().unwrap_or(0.0))
            .collect(),
        FrameField::DensityError => {
            let rho0 = geometry.rest_density;
            (0..n)
                .map(|i| {
                    snapshot
                        .density
                        .get(i)
                        .map_or(0.0, |&rho| 100.0 * (rho / rho0 - 1.0))
                })
                .collect()
        }
    };
    let top = match options.scale_max {
        Some(s) if s.is_finite() && s > 0.0 => s,
        _ => values
            .iter()
            .map(|v| v.abs())
            .filter(|v| v.is_finite())
            .fold(0.0, f32::max),
    };
    let top = if top > 0.0 { top } else { 1.0 };
    // The colour bucket of a value.
    let colour_of = |value: f32| {
        let t = scale_position(options.field, value, top);
        ((if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) }) * (BUCKETS - 1) as f32).round() as usize
    };
    match options.look {
        WaterLook::Surface => {
            // Pixel (px, py) of the scene below the band has its centre at
            // x0 + (px + 0.5 − left)/scale, y1 − (py + 0.5)/scale.
            let grid = SurfaceGrid {
                top_left: Vec2::new(view.x0 - view.left / view.scale, view.y1),
                cell: 1.0 / view.scale,
                width,
                height: height - band,
            };
            let mut raster = SurfaceRaster::default();
            raster.draw(grid, &snapshot.position, geometry.particle_radius, |i| {
                let k = colour_of(values.get(i).copied().unwrap_or(0.0));
                field_colour(options.field, k as f32 / (BUCKETS - 1) as f32)
            });
            blend_below(&mut pixmap, band, raster.rgba());
        }
        WaterLook::Particles => {
            let mut buckets: Vec<Option<PathBuilder>> = (0..BUCKETS).map(|_| None).collect();
            for (&p, &value) in snapshot.position.iter().zip(&values) {
                if !p.is_finite() {
                    continue;
                }
                let (x, y) = view.map(p);
                buckets[colour_of(value)]
                    .get_or_insert_with(PathBuilder::new)
                    .push_circle(x, y, r_px);
            }
            for (k, path) in buckets.into_iter().enumerate() {
                if let Some(path) = path {
                    fill(
                        &mut pixmap,
                        path,
                        field_colour(options.field, k as f32 / (BUCKETS - 1) as f32),
                    );
                }
            }
        }
    }

    // Bodies over the water, as in the viewer: water pressed against a body reaches its
    // outline, and the edge stays whole.
    let edge_px = (width as f32 / 500.0).max(1.0);
    for body in &geometry.bodies {
        draw_body(&mut pixmap, &view, body, edge_px);
    }

    draw_legend(&mut pixmap, band, options.field, top);
    Ok(pixmap)
}

/// Fill `body`'s outline (a convex polygon) with its density's colour and stroke its edge
/// `edge_px` wide; a circle also gets the radius to its outline's first point. A body with
/// fewer than three points or a non-finite one is left out.
fn draw_body(pixmap: &mut Pixmap, view: &View, body: &RigidBodyState, edge_px: f32) {
    if body.outline.len() < 3 || !body.outline.iter().all(|p| p.is_finite()) {
        return;
    }
    let mut outline = PathBuilder::new();
    for (k, &p) in body.outline.iter().enumerate() {
        let (x, y) = view.map(p);
        if k == 0 {
            outline.move_to(x, y);
        } else {
            outline.line_to(x, y);
        }
    }
    outline.close();
    let Some(outline) = outline.finish() else {
        return;
    };
    let mut paint = Paint {
        anti_alias: true,
        ..Paint::default()
    };
    let [r, g, b] = body_fill(body.spec.mean_density());
    paint.set_color_rgba8(r, g, b, 255);
    pixmap.fill_path(
        &outline,
        &paint,
        FillRule::Winding,
        Transform::identity(),
        None,
    );
    let stroke = Stroke {
        width: edge_px,
        line_join: LineJoin::Round,
        ..Stroke::default()
    };
    let [r, g, b] = BODY_EDGE;
    paint.set_color_rgba8(r, g, b, 255);
    pixmap.stroke_path(&outline, &paint, &stroke, Transform::identity(), None);
    if body.spec.shape == BodyShape::Circle && body.position.is_finite() {
        let mut spoke = PathBuilder::new();
        let (x, y) = view.map(body.position);
        spoke.move_to(x, y);
        let (x, y) = view.map(body.outline[0]);
        spoke.line_to(x, y);
        if let Some(spoke) = spoke.finish() {
            pixmap.stroke_path(&spoke, &paint, &stroke, Transform::identity(), None);
        }
    }
}

/// Height of the legend band above the scene in an image `width` pixels wide.
fn band_height(width: u32) -> u32 {
    (width / 20).clamp(16, 64)
}

/// Write the simulated time, `t = 0.350 s` with `decimals` digits after the point, at the
/// right end of the legend band of a frame drawn by [`render_frame`] (the videos' frames:
/// a still picture has its time in `index.csv`). The band's right part is free: the legend
/// takes its left half.
pub fn stamp_time(pixmap: &mut Pixmap, time: f64, decimals: usize) {
    let band = band_height(pixmap.width());
    let text_scale = (band / 10).max(1);
    let text = format!("t = {time:.decimals$} s");
    let margin = band / 4;
    let x = pixmap
        .width()
        .saturating_sub(font::text_width(&text, text_scale) + margin);
    let y = 0.5 * (band as f32 - font::text_height(text_scale) as f32);
    let grey = Color::from_rgba8(TEXT_GREY, TEXT_GREY, TEXT_GREY, 255);
    font::draw_text(pixmap, x as f32, y, text_scale, &text, grey);
}

/// The rectangle [`stamp_time`] draws into, as `(x, y, width, height)` in pixels: the right
/// half of the legend band (for tests that compare stamps).
pub fn stamp_region(width: u32) -> (u32, u32, u32, u32) {
    (width / 2, 0, width - width / 2, band_height(width))
}

/// A fixed top of the colour scale for a whole run of `scene`, so colours mean the same speed
/// in every frame: the speed of a fall from the top of the tank, `√(2·|g|·H)`, plus the
/// fastest initial block velocity. `None` (scale per frame) when that is zero.
pub fn speed_scale(scene: &dfsph::Scene) -> Option<f32> {
    let g = scene.gravity[0].hypot(scene.gravity[1]);
    let height = scene.tank.max[1] - scene.tank.min[1];
    let initial = scene
        .fluid
        .iter()
        .map(|b| b.velocity[0].hypot(b.velocity[1]))
        .fold(0.0, f64::max);
    let v = (2.0 * g * height).sqrt() + initial;
    (v.is_finite() && v > 0.0).then_some(v as f32)
}

/// A fixed top of `field`'s colour scale for a whole run of `scene` (see
/// [`RenderOptions::scale_max`]): the speed of [`speed_scale`]; the hydrostatic pressure
/// ρ0·|g|·D at the bottom of the deepest water the scene starts with; ±1 % of ρ0 for the
/// density error (the solver's tolerances are a few hundredths of a percent: a converged
/// solve stays white).
pub fn field_scale(scene: &dfsph::Scene, field: FrameField) -> Option<f32> {
    match field {
        FrameField::Speed => speed_scale(scene),
        FrameField::Pressure => {
            let g = scene.gravity[0].hypot(scene.gravity[1]);
            let depth = scene
                .fluid
                .iter()
                .map(|b| b.max[1] - scene.tank.min[1])
                .fold(0.0, f64::max);
            let p = scene.rest_density * g * depth;
            (p.is_finite() && p > 0.0).then_some(p as f32)
        }
        FrameField::DensityError => Some(1.0),
    }
}

/// Where `value` sits on the colour scale, 0 to 1: from 0 to `top`, or for the density
/// error from `-top` (0) through 0 (0.5) to `top` (1).
fn scale_position(field: FrameField, value: f32, top: f32) -> f32 {
    match field {
        FrameField::DensityError => 0.5 + 0.5 * value / top,
        _ => value / top,
    }
}

/// The colour at `t` (0 to 1) of `field`'s scale: viridis, or for the density error blue
/// through white to red.
pub(crate) fn field_colour(field: FrameField, t: f32) -> [u8; 3] {
    match field {
        FrameField::DensityError => {
            const BLUE: [f32; 3] = [59.0, 76.0, 192.0];
            const WHITE: [f32; 3] = [242.0, 242.0, 242.0];
            const RED: [f32; 3] = [180.0, 4.0, 38.0];
            let t = t.clamp(0.0, 1.0);
            let (a, b, s) = if t < 0.5 {
                (BLUE, WHITE, 2.0 * t)
            } else {
                (WHITE, RED, 2.0 * t - 1.0)
            };
            [0, 1, 2].map(|k| (a[k] + (b[k] - a[k]) * s).round() as u8)
        }
        _ => viridis(t),
    }
}

/// Blend `rgba` (straight alpha, the pixmap's width, rows from `top` down) over the opaque
/// `pixmap`.
fn blend_below(pixmap: &mut Pixmap, top: u32, rgba: &[u8]) {
    let start = 4 * top as usize * pixmap.width() as usize;
    let dst = &mut pixmap.data_mut()[start..];
    for (d, s) in dst.chunks_exact_mut(4).zip(rgba.chunks_exact(4)) {
        let a = s[3] as u32;
        if a == 0 {
            continue;
        }
        for k in 0..3 {
            d[k] = ((s[k] as u32 * a + d[k] as u32 * (255 - a) + 127) / 255) as u8;
        }
        d[3] = 255;
    }
}

fn fill(pixmap: &mut Pixmap, path: PathBuilder, rgb: [u8; 3]) {
    if let Some(path) = path.finish() {
        let mut paint = Paint {
            anti_alias: true,
            ..Paint::default()
        };
        paint.set_color_rgba8(rgb[0], rgb[1], rgb[2], 255);
        pixmap.fill_path(
            &path,
            &paint,
            FillRule::Winding,
            Transform::identity(),
            None,
        );
    }
}

/// `0 [colour bar] 6.3 m/s` in the band at the top of the image (pressure: `0 [bar] 4.9 kPa`;
/// density error: `-1 % [bar] +1 %`).
fn draw_legend(pixmap: &mut Pixmap, band: u32, field: FrameField, top: f32) {
    let text_scale = (band / 10).max(1);
    let text_h = font::text_height(text_scale) as f32;
    let margin = (band / 4) as f32;
    let y_text = 0.5 * (band as f32 - text_h);
    let grey = Color::from_rgba8(TEXT_GREY, TEXT_GREY, TEXT_GREY, 255);
    let (low, high) = match field {
        FrameField::Speed => ("0".to_string(), format!("{} m/s", scale_label(top))),
        FrameField::Pressure if top >= 1000.0 => (
            "0".to_string(),
            format!("{} kPa", scale_label(top / 1000.0)),
        ),
        FrameField::Pressure => ("0".to_string(), format!("{} Pa", scale_label(top))),
        FrameField::DensityError => (
            format!("-{} %", scale_label(top)),
            format!("+{} %", scale_label(top)),
        ),
    };

    let mut x = margin;
    font::draw_text(pixmap, x, y_text, text_scale, &low, grey);
    x += (font::text_width(&low, text_scale) as f32 + margin * 0.5).round();

    let bar_w = (0.25 * pixmap.width() as f32).round().max(16.0);
    let bar_h = (band as f32 * 0.5).round().max(4.0);
    let bar_y = 0.5 * (band as f32 - bar_h);
    let steps = bar_w as usize;
    let mut paint = Paint {
        anti_alias: false,
        ..Paint::default()
    };
    for k in 0..steps {
        let c = field_colour(field, k as f32 / (steps - 1).max(1) as f32);
        paint.set_color_rgba8(c[0], c[1], c[2], 255);
        if let Some(rect) = Rect::from_xywh(x + k as f32, bar_y, 1.0, bar_h) {
            pixmap.fill_rect(rect, &paint, Transform::identity(), None);
        }
    }
    x += bar_w + margin * 0.5;
    font::draw_text(pixmap, x, y_text, text_scale, &high, grey);
}

/// A scale's end (m/s, kPa, %) with two or three significant digits.
fn scale_label(v: f32) -> String {
    if v >= 100.0 {
        format!("{v:.0}")
    } else if v >= 10.0 {
        format!("{v:.1}")
    } else if v >= 0.1 {
        format!("{v:.2}")
    } else {
        format!("{v:.1e}")
    }
}

/// Render a frame and write it as a PNG.
pub fn write_png(
    path: impl AsRef<Path>,
    geometry: &RenderGeometry,
    snapshot: &Snapshot,
    options: &RenderOptions,
) -> Result<()> {
    write_pixmap_png(path, &render_frame(geometry, snapshot, options)?)
}

/// Write a frame drawn by [`render_frame`] as a PNG (atomically).
pub fn write_pixmap_png(path: impl AsRef<Path>, pixmap: &Pixmap) -> Result<()> {
    let path = path.as_ref();
    let bytes = pixmap
        .encode_png()
        .with_context(|| format!("cannot encode `{}`", path.display()))?;
    write_atomic(path, |w| w.write_all(&bytes))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 1 m x 1 m tank with one wall layer and a 0.4 m x 0.2 m block of water at its
    /// bottom-left, the left half moving fast.
    fn scene() -> (Vec<Vec2>, Snapshot) {
        let r = 0.01;
        let d = 2.0 * r;
        let mut walls = Vec::new();
        for i in -1..=51 {
            let x = (i as f32 + 0.5) * d;
            walls.push(Vec2::new(x, -r));
            walls.push(Vec2::new(-r, x));
            walls.push(Vec2::new(1.0 + r, x));
        }
        let mut snap = Snapshot::default();
        for j in 0..10 {
            for i in 0..20 {
                let p = Vec2::new((i as f32 + 0.5) * d, (j as f32 + 0.5) * d);
                snap.id.push(snap.position.len() as u32);
                snap.position.push(p);
                snap.velocity.push(if i < 10 {
                    Vec2::new(2.0, 0.0)
                } else {
                    Vec2::ZERO
                });
                snap.density.push(1000.0);
                snap.pressure.push(0.0);
            }
        }
        (walls, snap)
    }

    fn pixel(p: &Pixmap, x: u32, y: u32) -> [u8; 3] {
        let c = p.pixel(x, y).unwrap();
        [c.red(), c.green(), c.blue()]
    }

    #[test]
    fn png_decodes_with_water_coloured_by_speed() {
        let (walls, snap) = scene();
        let geometry = RenderGeometry {
            rest_density: 1000.0,
            tank_min: Vec2::ZERO,
            tank_max: Vec2::ONE,
            boundary: Cow::Borrowed(&walls[..]),
            bodies: Vec::new(),
            particle_radius: 0.01,
        };
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("00000.png");
        let options = RenderOptions {
            width: 400,
            field: FrameField::Speed,
            scale_max: Some(2.0),
            look: WaterLook::Surface,
        };
        write_png(&path, &geometry, &snap, &options).unwrap();

        let img = Pixmap::load_png(&path).expect("the PNG decodes");
        assert_eq!(img.width(), 400);
        let band = 400 / 20;
        // Square scene: the part below the legend band is (nearly) square.
        assert!((img.height() as i32 - band as i32 - 400).abs() <= 1);

        // Map world points to pixels the way the renderer does.
        let view_lo = -0.02 - 0.01 - 0.02 * 1.04;
        let span = 1.04 + 2.0 * (0.01 + 0.02 * 1.04);
        let s = 400.0 / span;
        let to_px = |x: f32, y: f32| {
            (
                ((x - view_lo) * s) as u32,
                (band as f32 + (1.0 + 0.02 + 0.01 + 0.02 * 1.04 - y) * s) as u32,
            )
        };
        // Fast water (left half) is yellow, still water (right half) dark purple.
        let (x, y) = to_px(0.1, 0.1);
        let fast = pixel(&img, x, y);
        assert!(fast[0] > 200 && fast[1] > 200 && fast[2] < 100, "{fast:?}");
        let (x, y) = to_px(0.3, 0.1);
        let slow = pixel(&img, x, y);
        assert!(slow[2] > slow[1] + 30 && slow[0] < 120, "{slow:?}");
        // Air above the water is background, the floor is grey.
        let (x, y) = to_px(0.5, 0.7);
        assert_eq!(pixel(&img, x, y), [255, 255, 255]);
        let (x, y) = to_px(0.5, -0.01);
        let wall = pixel(&img, x, y);
        assert!(
            wall[0] == wall[1] && wall[1] == wall[2] && wall[0] < 200,
            "{wall:?}"
        );
        // The legend band holds the colour bar: dark purple at its left, yellow at its right.
        let row: Vec<[u8; 3]> = (0..img.width()).map(|x| pixel(&img, x, band / 2)).collect();
        assert!(row.iter().any(|c| *c == viridis(0.0)));
        assert!(row.iter().any(|c| *c == viridis(1.0)));
    }

    /// The water of the test scene is one surface: between two particles of a row, where
    /// dots leave the background showing through on the diagonal gaps of the square lattice,
    /// the surface is water; above it both are background.
    #[test]
    fn the_surface_closes_the_gaps_that_dots_leave() {
        let (walls, snap) = scene();
        let geometry = RenderGeometry {
            rest_density: 1000.0,
            tank_min: Vec2::ZERO,
            tank_max: Vec2::ONE,
            boundary: Cow::Borrowed(&walls[..]),
            bodies: Vec::new(),
            particle_radius: 0.01,
        };
        let draw = |look| {
            let options = RenderOptions {
                width: 1000,
                field: FrameField::Speed,
                scale_max: Some(2.0),
                look,
            };
            let view = layout(&geometry, options.width).unwrap().view;
            let img = render_frame(&geometry, &snap, &options).unwrap();
            (view, img)
        };
        let at = |(view, img): &(View, Pixmap), p: Vec2| {
            let (x, y) = view.map(p);
            pixel(img, x as u32, y as u32)
        };
        let surface = draw(WaterLook::Surface);
        let dots = draw(WaterLook::Particles);
        // The corner between four still particles (spacing d = 0.02, centres at odd
        // multiples of 0.01).
        let gap = Vec2::new(0.32, 0.08);
        assert_eq!(at(&dots, gap), [255, 255, 255]);
        let water = at(&surface, gap);
        assert_eq!(water, at(&surface, Vec2::new(0.33, 0.09)), "{water:?}");
        assert_ne!(water, [255, 255, 255]);
        for picture in [&surface, &dots] {
            assert_eq!(at(picture, Vec2::new(0.5, 0.5)), [255, 255, 255]);
        }
    }

    /// The same block coloured by pressure (the left half at 2,000 Pa, the right at 0) and by
    /// density error (the left half 1 % compressed, the right 1 % light, one column at ρ0).
    #[test]
    fn water_is_coloured_by_pressure_or_density_error() {
        let (walls, mut snap) = scene();
        for (k, p) in snap.position.iter().enumerate() {
            let left = p.x < 0.2;
            snap.pressure[k] = if left { 2000.0 } else { 0.0 };
            snap.density[k] = if left { 1010.0 } else { 990.0 };
            if (p.x - 0.21).abs() < 0.005 {
                snap.density[k] = 1000.0;
            }
        }
        let geometry = RenderGeometry {
            rest_density: 1000.0,
            tank_min: Vec2::ZERO,
            tank_max: Vec2::ONE,
            boundary: Cow::Borrowed(&walls[..]),
            bodies: Vec::new(),
            particle_radius: 0.01,
        };
        let band = 400 / 20;
        let view_lo = -0.02 - 0.01 - 0.02 * 1.04;
        let span = 1.04 + 2.0 * (0.01 + 0.02 * 1.04);
        let s = 400.0 / span;
        // The colours drawn inside a world rectangle.
        let colours = |img: &Pixmap, x0: f32, x1: f32| -> Vec<[u8; 3]> {
            let px = |x: f32| ((x - view_lo) * s) as u32;
            let py = |y: f32| (band as f32 + (1.0 + 0.02 + 0.01 + 0.02 * 1.04 - y) * s) as u32;
            let mut out = Vec::new();
            for y in py(0.15)..py(0.05) {
                for x in px(x0)..px(x1) {
                    out.push(pixel(img, x, y));
                }
            }
            out
        };
        let draw = |field, scale_max| {
            let options = RenderOptions {
                width: 400,
                field,
                scale_max,
                // Dots: one column's own colour is not mixed with its neighbours'.
                look: WaterLook::Particles,
            };
            render_frame(&geometry, &snap, &options).unwrap()
        };
        let pressure = draw(FrameField::Pressure, Some(2000.0));
        assert!(colours(&pressure, 0.03, 0.17).contains(&viridis(1.0)));
        assert!(!colours(&pressure, 0.03, 0.17).contains(&viridis(0.0)));
        assert!(colours(&pressure, 0.25, 0.38).contains(&viridis(0.0)));
        let density = draw(FrameField::DensityError, Some(1.0));
        let red = field_colour(FrameField::DensityError, 1.0);
        let blue = field_colour(FrameField::DensityError, 0.0);
        // ρ0 is the middle bucket of the scale.
        let middle = ((BUCKETS - 1) as f32 * 0.5).round() / (BUCKETS - 1) as f32;
        let white = field_colour(FrameField::DensityError, middle);
        assert!(red[0] > 150 && red[1] < 60, "{red:?}");
        assert!(blue[2] > 150 && blue[0] < 100, "{blue:?}");
        assert!(white.iter().all(|&c| c > 230), "{white:?}");
        assert!(colours(&density, 0.03, 0.17).contains(&red));
        assert!(colours(&density, 0.25, 0.38).contains(&blue));
        assert!(colours(&density, 0.19, 0.23).contains(&white));
        assert!(!colours(&density, 0.03, 0.17).contains(&blue));
        // Unscaled, the density error's scale is its largest magnitude, symmetric about 0.
        let auto = draw(FrameField::DensityError, None);
        assert!(colours(&auto, 0.03, 0.17).contains(&red));
    }

    #[test]
    fn field_names_and_scene_scales() {
        assert_eq!(
            FrameField::from_name("pressure"),
            Some(FrameField::Pressure)
        );
        assert_eq!(
            FrameField::from_name("density"),
            Some(FrameField::DensityError)
        );
        assert_eq!(FrameField::from_name("temperature"), None);
        let s = dfsph::scene::builtin("dam-break").unwrap();
        // The 2 m column: ρ0·g·H at its bottom.
        let p = field_scale(&s, FrameField::Pressure).unwrap();
        assert!((p - 1000.0 * 9.81 * 2.0).abs() < 1.0, "{p}");
        assert_eq!(field_scale(&s, FrameField::DensityError), Some(1.0));
        assert_eq!(field_scale(&s, FrameField::Speed), speed_scale(&s));
    }

    #[test]
    fn width_is_kept_and_aspect_follows_the_tank() {
        let walls = [];
        let snap = Snapshot::default();
        let geometry = RenderGeometry {
            rest_density: 1000.0,
            tank_min: Vec2::ZERO,
            tank_max: Vec2::new(4.0, 1.0),
            boundary: Cow::Borrowed(&walls[..]),
            bodies: Vec::new(),
            particle_radius: 0.01,
        };
        let img = render_frame(
            &geometry,
            &snap,
            &RenderOptions {
                width: 800,
                field: FrameField::Speed,
                scale_max: None,
                look: WaterLook::Surface,
            },
        )
        .unwrap();
        assert_eq!(img.width(), 800);
        let scene_h = img.height() - 800 / 20;
        let expected = 800.0 * (1.0 + 2.0 * (0.01 + 0.08)) / (4.0 + 2.0 * (0.01 + 0.08));
        assert!(
            (scene_h as f32 - expected).abs() <= 1.0,
            "{scene_h} vs {expected}"
        );
    }

    #[test]
    fn non_finite_particles_are_skipped_not_fatal() {
        let walls = [Vec2::new(f32::NAN, 0.0)];
        let snap = Snapshot {
            position: vec![Vec2::new(f32::INFINITY, 0.5), Vec2::new(0.5, 0.5)],
            velocity: vec![Vec2::new(f32::NAN, 0.0), Vec2::ZERO],
            ..Snapshot::default()
        };
        let geometry = RenderGeometry {
            rest_density: 1000.0,
            tank_min: Vec2::ZERO,
            tank_max: Vec2::ONE,
            boundary: Cow::Borrowed(&walls[..]),
            bodies: Vec::new(),
            particle_radius: 0.05,
        };
        let img = render_frame(&geometry, &snap, &RenderOptions::default()).unwrap();
        assert!(img.encode_png().is_ok());
    }

    #[test]
    fn speed_scale_is_a_fall_from_the_tank_top() {
        let s = dfsph::scene::builtin("dam-break").unwrap();
        let v = speed_scale(&s).unwrap();
        assert!((v - (2.0f32 * 9.81 * 3.0).sqrt()).abs() < 1e-3);
        let mut still = s.clone();
        still.gravity = [0.0, 0.0];
        assert_eq!(speed_scale(&still), None);
    }

    #[test]
    fn time_stamps_differ_in_the_stamp_region_only() {
        let walls = [];
        let snap = Snapshot::default();
        let geometry = RenderGeometry {
            rest_density: 1000.0,
            tank_min: Vec2::ZERO,
            tank_max: Vec2::new(2.0, 1.0),
            boundary: Cow::Borrowed(&walls[..]),
            bodies: Vec::new(),
            particle_radius: 0.01,
        };
        let plain = render_frame(&geometry, &snap, &RenderOptions::default()).unwrap();
        let mut a = plain.clone();
        let mut b = plain.clone();
        stamp_time(&mut a, 0.35, 3);
        stamp_time(&mut b, 0.4, 3);
        let (x0, y0, w, h) = stamp_region(plain.width());
        let differs = |p: &Pixmap, q: &Pixmap, inside: bool| {
            (0..p.height()).any(|y| {
                (0..p.width()).any(|x| {
                    let within = x >= x0 && x < x0 + w && y >= y0 && y < y0 + h;
                    within == inside && p.pixel(x, y) != q.pixel(x, y)
                })
            })
        };
        assert!(differs(&a, &plain, true), "the stamp draws something");
        assert!(differs(&a, &b, true), "different times, different stamps");
        assert!(!differs(&a, &plain, false), "nothing outside the region");
    }

    /// The built-in `floating` scene (four bodies, two of them circles) at a coarse 5 cm.
    fn floating() -> Simulation {
        let mut s = dfsph::scene::builtin("floating").unwrap();
        s.particle_radius = 0.05;
        Simulation::new(&s).unwrap()
    }

    /// Whether `p` lies in the convex counter-clockwise polygon `outline`, at least `margin`
    /// from each of its edges (m).
    fn inside(outline: &[Vec2], p: Vec2, margin: f32) -> bool {
        (0..outline.len()).all(|k| {
            let (a, b) = (outline[k], outline[(k + 1) % outline.len()]);
            (b - a).normalize().perp_dot(p - a) >= margin
        })
    }

    /// Distance from `p` to the segment `a`–`b`.
    fn to_segment(p: Vec2, a: Vec2, b: Vec2) -> f32 {
        let t = ((p - a).dot(b - a) / (b - a).length_squared()).clamp(0.0, 1.0);
        (a + t * (b - a) - p).length()
    }

    /// Every pixel of `img` with the world point at its centre (`layout`'s mapping), m.
    fn pixels_in_world(img: &Pixmap, view: &View) -> Vec<(u32, u32, Vec2)> {
        (0..img.height())
            .flat_map(|y| (0..img.width()).map(move |x| (x, y)))
            .map(|(x, y)| {
                let w = Vec2::new(
                    view.x0 + (x as f32 + 0.5 - view.left) / view.scale,
                    view.y1 - (y as f32 + 0.5 - view.top) / view.scale,
                );
                (x, y, w)
            })
            .collect()
    }

    #[test]
    fn bodies_are_filled_outlines_and_their_particles_are_not_wall_dots() {
        let sim = floating();
        let geometry = RenderGeometry::of(&sim);
        assert_eq!(geometry.bodies.len(), 4);
        // The walls are the boundary particles less the bodies', and none is in a body.
        let on_bodies = sim
            .boundary_bodies()
            .iter()
            .filter(|&&b| sim.rigid_body_of(b).is_some())
            .count();
        assert!(on_bodies > 0);
        assert_eq!(
            geometry.boundary.len(),
            sim.boundary_positions().len() - on_bodies
        );
        for body in &geometry.bodies {
            assert!(geometry
                .boundary
                .iter()
                .all(|&p| !inside(&body.outline, p, 0.0)));
        }

        let options = RenderOptions {
            width: 800,
            field: FrameField::Speed,
            scale_max: None,
            look: WaterLook::Surface,
        };
        let view = layout(&geometry, options.width).unwrap().view;
        let img = render_frame(&geometry, &sim.snapshot(), &options).unwrap();
        let pixels = pixels_in_world(&img, &view);
        // Three pixels clear of the edge (and of a circle's radius line), a body is its fill.
        let clear = 3.0 / view.scale;
        for body in &geometry.bodies {
            let fill = body_fill(body.spec.mean_density());
            let spoke = (body.spec.shape == BodyShape::Circle).then_some(body.outline[0]);
            let mut filled = 0;
            for &(x, y, w) in &pixels {
                if inside(&body.outline, w, clear)
                    && spoke.is_none_or(|s| to_segment(w, body.position, s) > clear)
                {
                    assert_eq!(pixel(&img, x, y), fill, "({x}, {y}) in {:?}", body.spec);
                    filled += 1;
                }
            }
            assert!(filled > 200, "{filled} pixels of {:?}", body.spec);
            // Its edge is darker than its fill.
            let mid = 0.5 * (body.outline[0] + body.outline[1]);
            let (x, y) = view.map(mid);
            let edge = pixel(&img, x as u32, y as u32);
            let sum = |c: [u8; 3]| c.iter().map(|&v| u32::from(v)).sum::<u32>();
            assert!(sum(edge) + 60 < sum(fill), "edge {edge:?}, fill {fill:?}");
            if spoke.is_some() {
                let (x, y) = view.map(0.5 * (body.position + body.outline[0]));
                assert!(sum(pixel(&img, x as u32, y as u32)) + 60 < sum(fill));
            }
        }
        // The bodies' fills differ by density: the 300 kg/m³ box is paler than the
        // 2,000 kg/m³ circle.
        assert_ne!(
            body_fill(geometry.bodies[0].spec.mean_density()),
            body_fill(geometry.bodies[3].spec.mean_density())
        );

        // Drawn without the bodies, no wall grey is left where they are (which there is when
        // their particles are drawn as walls).
        let grey_in_bodies = |g: &RenderGeometry| {
            let img = render_frame(g, &sim.snapshot(), &options).unwrap();
            pixels.iter().any(|&(x, y, w)| {
                let c = pixel(&img, x, y);
                let grey = c[0] == c[1] && c[1] == c[2] && c[0] < 255;
                grey && geometry.bodies.iter().any(|b| inside(&b.outline, w, 0.0))
            })
        };
        let bare = RenderGeometry {
            bodies: Vec::new(),
            ..geometry.clone()
        };
        assert!(!grey_in_bodies(&bare));
        let all_particles = RenderGeometry {
            boundary: Cow::Borrowed(sim.boundary_positions()),
            ..bare
        };
        assert!(grey_in_bodies(&all_particles));
    }

    #[test]
    fn a_body_with_a_bad_outline_is_left_out() {
        let sim = floating();
        let mut geometry = RenderGeometry::of(&sim).into_owned();
        geometry.bodies[0].outline[1] = Vec2::NAN;
        geometry.bodies[1].outline.truncate(2);
        let img = render_frame(&geometry, &sim.snapshot(), &RenderOptions::default()).unwrap();
        assert!(img.encode_png().is_ok());
    }

    #[test]
    fn scale_labels() {
        assert_eq!(scale_label(6.26), "6.26");
        assert_eq!(scale_label(12.34), "12.3");
        assert_eq!(scale_label(250.0), "250");
        assert_eq!(scale_label(0.05), "5.0e-2");
    }
}
