//! Where the world appears in the window: zoom and pan on top of the fitted view, and the
//! layout that keeps the HUD and the colour bar beside the tank rather than over it.

use dfsph::Vec2;
use eframe::egui::{pos2, vec2, Pos2, Rect};

use crate::render::ViewTransform;

/// Smallest zoom: the fitted view shrunk to a quarter (more would only show empty space).
pub const MIN_ZOOM: f32 = 0.25;
/// Largest zoom: about a particle across a quarter of a small window at the default radius.
pub const MAX_ZOOM: f32 = 64.0;

/// The user's zoom and pan, relative to the view that fits the world into the screen. Kept
/// relative (not as a screen transform) so that resizing the window or shaking the tank keeps
/// the same part of the world in view.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Magnification over the fitted view (1 = fitted).
    zoom: f32,
    /// World point at the centre of the screen rectangle, relative to the world's centre, m.
    offset: Vec2,
}

impl Default for Camera {
    fn default() -> Self {
        Self {
            zoom: 1.0,
            offset: Vec2::ZERO,
        }
    }
}

impl Camera {
    /// Magnification over the fitted view.
    pub fn zoom(&self) -> f32 {
        self.zoom
    }

    /// World offset of the view's centre from the world's centre, m.
    pub fn offset(&self) -> Vec2 {
        self.offset
    }

    /// Back to the fitted view.
    pub fn reset(&mut self) {
        *self = Self::default();
    }

    /// Whether the view is the fitted one.
    pub fn is_fitted(&self) -> bool {
        *self == Self::default()
    }

    /// The transform showing `[world_min, world_max]` in `screen` at this zoom and pan.
    pub fn transform(&self, world_min: Vec2, world_max: Vec2, screen: Rect) -> ViewTransform {
        let fit = ViewTransform::fit(world_min, world_max, screen);
        let centre = 0.5 * (world_min + world_max) + self.offset;
        ViewTransform::centred(centre, fit.scale() * self.zoom, screen.center())
    }

    /// Multiply the zoom by `factor` (within [`MIN_ZOOM`]–[`MAX_ZOOM`]) keeping the world
    /// point `about` where it is on the screen (the point under the cursor stays under it).
    pub fn zoom_about(
        &mut self,
        factor: f32,
        about: Vec2,
        world_min: Vec2,
        world_max: Vec2,
        screen: Rect,
    ) {
        if !(factor.is_finite() && factor > 0.0) {
            return;
        }
        let before = self.transform(world_min, world_max, screen);
        let at = before.to_screen(about);
        self.zoom = (self.zoom * factor).clamp(MIN_ZOOM, MAX_ZOOM);
        let after = self.transform(world_min, world_max, screen);
        // Move the view so that `about` lands on `at` again.
        let drift = after.to_world(at) - about;
        self.offset -= drift;
    }

    /// Move the view with the pointer: the world follows a drag of `delta` screen points.
    pub fn pan(&mut self, delta: eframe::egui::Vec2, scale: f32) {
        if scale > 0.0 && delta.is_finite() {
            // Screen y points down, world y up.
            self.offset -= Vec2::new(delta.x, -delta.y) / scale;
        }
    }
}

/// Where the overlays go in the view: the tank's rectangle and, beside it, the HUD and the
/// colour bar.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Layout {
    /// The rectangle the world is fitted into (and clipped to).
    pub world: Rect,
    /// Top-left corner of the HUD.
    pub hud: Pos2,
    /// The colour bar's rectangle, labels included.
    pub legend: Rect,
    /// The colour bar runs along x (under the tank) rather than along y (beside it).
    pub legend_horizontal: bool,
}

/// Size of the colour bar standing beside the tank, labels included, points.
pub const LEGEND_VERTICAL: eframe::egui::Vec2 = vec2(96.0, 190.0);
/// Height of the colour bar lying under the tank, labels included, points (as wide as the
/// view allows, up to 320).
pub const LEGEND_HORIZONTAL_HEIGHT: f32 = 46.0;
/// Gap between the view's edge, the overlays and the world, points.
const GAP: f32 = 6.0;

/// Place the HUD (of size `hud`) and the colour bar in `view` so that neither covers the
/// fitted world (`world_size`, m): every arrangement of the two in margins beside, above or
/// below the world is tried, and the one leaving the world the largest scale wins.
pub fn layout(view: Rect, hud: eframe::egui::Vec2, world_size: Vec2) -> Layout {
    let inner = view.shrink(GAP);
    let scale_in = |r: Rect| {
        if r.width() <= 0.0 || r.height() <= 0.0 {
            return 0.0;
        }
        (r.width() / world_size.x.max(1e-6)).min(r.height() / world_size.y.max(1e-6))
    };
    let legend_h_width = inner.width().min(320.0);
    let mut best: Option<(f32, Layout)> = None;
    let mut consider = |world: Rect, hud_at: Pos2, legend: Rect, horizontal: bool| {
        // The overlays must fit in the view without covering each other.
        let hud_rect = Rect::from_min_size(hud_at, hud);
        if !inner.expand(0.5).contains_rect(legend) || hud_rect.intersects(legend) {
            return;
        }
        let world = world.shrink(GAP);
        let s = scale_in(world);
        if best.as_ref().is_none_or(|(b, _)| s > *b + 1e-3) {
            best = Some((
                s,
                Layout {
                    world,
                    hud: hud_at,
                    legend,
                    legend_horizontal: horizontal,
                },
            ));
        }
    };
    let lv = LEGEND_VERTICAL;
    let lh = LEGEND_HORIZONTAL_HEIGHT;
    let legend_right = Rect::from_min_size(pos2(inner.right() - lv.x, inner.top()), lv);
    let legend_bottom = Rect::from_min_size(
        pos2(inner.right() - legend_h_width, inner.bottom() - lh),
        vec2(legend_h_width, lh),
    );
    // 1. HUD in a column on the left, colour bar in a column on the right.
    consider(
        Rect::from_x_y_ranges(inner.left() + hud.x..=inner.right() - lv.x, inner.y_range()),
        inner.left_top(),
        legend_right,
        false,
    );
    // 2. HUD on the left, colour bar under the world.
    consider(
        Rect::from_x_y_ranges(
            inner.left() + hud.x..=inner.right(),
            inner.top()..=inner.bottom() - lh,
        ),
        inner.left_top(),
        legend_bottom,
        true,
    );
    // 3. HUD above the world, colour bar in a column on the right (under the HUD's level
    //    when both do not fit across).
    let legend_right_low =
        Rect::from_min_size(pos2(inner.right() - lv.x, inner.top() + hud.y + GAP), lv);
    for legend in [legend_right, legend_right_low] {
        consider(
            Rect::from_x_y_ranges(
                inner.left()..=inner.right() - lv.x,
                inner.top() + hud.y..=inner.bottom(),
            ),
            inner.left_top(),
            legend,
            false,
        );
    }
    // 4. HUD above, colour bar under the world.
    consider(
        Rect::from_x_y_ranges(inner.x_range(), inner.top() + hud.y..=inner.bottom() - lh),
        inner.left_top(),
        legend_bottom,
        true,
    );
    // 5. HUD and colour bar side by side above the world, when both fit across.
    if hud.x + GAP + lv.x <= inner.width() {
        consider(
            Rect::from_x_y_ranges(
                inner.x_range(),
                inner.top() + hud.y.max(lv.y)..=inner.bottom(),
            ),
            inner.left_top(),
            legend_right,
            false,
        );
    }
    // 6. HUD on the left, colour bar under the HUD, when the HUD is narrow enough.
    consider(
        Rect::from_x_y_ranges(
            inner.left() + hud.x.max(lv.x)..=inner.right(),
            inner.y_range(),
        ),
        inner.left_top(),
        Rect::from_min_size(pos2(inner.left(), inner.top() + hud.y + GAP), lv),
        false,
    );
    best.map(|(_, l)| l).unwrap_or(Layout {
        world: inner,
        hud: inner.left_top(),
        legend: legend_right,
        legend_horizontal: false,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn screen() -> Rect {
        Rect::from_min_size(pos2(20.0, 10.0), vec2(800.0, 600.0))
    }

    const LO: Vec2 = Vec2::new(-0.2, -0.1);
    const HI: Vec2 = Vec2::new(4.2, 3.1);

    #[test]
    fn zooming_about_a_point_keeps_that_point_under_the_cursor() {
        let mut cam = Camera::default();
        let about = Vec2::new(0.7, 0.4);
        let at = cam.transform(LO, HI, screen()).to_screen(about);
        cam.zoom_about(3.0, about, LO, HI, screen());
        let t = cam.transform(LO, HI, screen());
        assert!((cam.zoom() - 3.0).abs() < 1e-6);
        assert!(
            (t.to_screen(about) - at).length() < 1e-3,
            "{:?} vs {at:?}",
            t.to_screen(about)
        );
        // Another point moved away from it, three times as far.
        let other = Vec2::new(1.7, 0.4);
        let fitted = Camera::default().transform(LO, HI, screen());
        let d0 = (fitted.to_screen(other) - fitted.to_screen(about)).length();
        let d1 = (t.to_screen(other) - t.to_screen(about)).length();
        assert!((d1 - 3.0 * d0).abs() < 1e-2, "{d1} vs 3 x {d0}");
        // Zooming back out about the same point returns to the fitted view.
        cam.zoom_about(1.0 / 3.0, about, LO, HI, screen());
        assert!((cam.zoom() - 1.0).abs() < 1e-5);
        assert!(cam.offset().length() < 1e-4, "{:?}", cam.offset());
    }

    #[test]
    fn zoom_is_bounded_and_ignores_nonsense() {
        let mut cam = Camera::default();
        let about = Vec2::new(2.0, 1.5);
        cam.zoom_about(1e9, about, LO, HI, screen());
        assert_eq!(cam.zoom(), MAX_ZOOM);
        cam.zoom_about(1e-9, about, LO, HI, screen());
        assert_eq!(cam.zoom(), MIN_ZOOM);
        let before = cam;
        cam.zoom_about(f32::NAN, about, LO, HI, screen());
        cam.zoom_about(0.0, about, LO, HI, screen());
        assert_eq!(cam, before);
    }

    #[test]
    fn panning_moves_the_world_with_the_pointer_and_reset_fits_again() {
        let mut cam = Camera::default();
        cam.zoom_about(2.0, Vec2::new(1.0, 1.0), LO, HI, screen());
        let t = cam.transform(LO, HI, screen());
        let p = Vec2::new(2.5, 0.5);
        let before = t.to_screen(p);
        cam.pan(vec2(30.0, -12.0), t.scale());
        let after = cam.transform(LO, HI, screen()).to_screen(p);
        assert!((after - before - vec2(30.0, -12.0)).length() < 1e-3);
        // Screen ↔ world still round-trips when zoomed and panned: the tools act where the
        // cursor is.
        let t = cam.transform(LO, HI, screen());
        let cursor = pos2(345.0, 123.0);
        assert!((t.to_screen(t.to_world(cursor)) - cursor).length() < 1e-3);
        cam.reset();
        assert!(cam.is_fitted());
        assert_eq!(
            cam.transform(LO, HI, screen()),
            ViewTransform::fit(LO, HI, screen())
        );
    }

    /// The fitted world's screen rectangle.
    fn world_on_screen(l: &Layout) -> Rect {
        let t = ViewTransform::fit(LO, HI, l.world);
        Rect::from_two_pos(t.to_screen(LO), t.to_screen(HI))
    }

    #[test]
    fn the_hud_and_colour_bar_never_cover_the_tank() {
        let hud = vec2(300.0, 160.0);
        // Views of a small window (640x480 less the side panel and plots), the default
        // window, a tall narrow one and a wide flat one.
        for view in [
            Rect::from_min_size(pos2(0.0, 0.0), vec2(340.0, 384.0)),
            Rect::from_min_size(pos2(0.0, 0.0), vec2(980.0, 650.0)),
            Rect::from_min_size(pos2(0.0, 0.0), vec2(400.0, 900.0)),
            Rect::from_min_size(pos2(0.0, 0.0), vec2(1600.0, 400.0)),
        ] {
            let l = layout(view, hud, HI - LO);
            let tank = world_on_screen(&l);
            let hud_rect = Rect::from_min_size(l.hud, hud);
            assert!(view.contains_rect(tank.shrink(0.01)), "{view:?}: {tank:?}");
            assert!(
                !tank.intersects(hud_rect),
                "{view:?}: HUD {hud_rect:?} on {tank:?}"
            );
            assert!(
                !tank.intersects(l.legend),
                "{view:?}: legend {:?} on {tank:?}",
                l.legend
            );
            assert!(view.contains_rect(l.legend), "{view:?}: {:?}", l.legend);
            assert!(!hud_rect.intersects(l.legend), "{view:?}: {l:?}");
            // The reservation costs little: at least 55 % of the scale the bare view allows.
            let bare = ViewTransform::fit(LO, HI, view).scale();
            let t = ViewTransform::fit(LO, HI, l.world).scale();
            assert!(t > 0.55 * bare, "{view:?}: {t} of {bare}");
        }
    }
}
