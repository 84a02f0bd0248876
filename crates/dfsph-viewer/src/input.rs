//! Keyboard and mouse → viewer [`Command`]s and solver [`Action`]s.
//!
//! [`InputMapper`] reads one frame of egui input ([`egui::InputState`]) plus where the pointer
//! is in the world ([`ViewInput`]) and returns what should happen. It owns no window and no
//! simulation, so it is unit-tested by feeding an `egui::Context` synthetic events.

use dfsph::forces::MAX_POINTER_ACCELERATION;
use dfsph::scene::{BodyShape, BUILTIN_SCENES};
use dfsph::{Action, Vec2};
use eframe::egui::{self, Key, PointerButton};

/// Every key and mouse binding, as shown in the help overlay: (keys, what they do). The
/// built-in scenes' entry is added by [`key_help`], from their count.
pub const KEY_HELP: &[(&str, &str)] = &[
    ("A / D, ← / →", "shake the tank left / right while held"),
    ("Q / E", "tilt gravity left / right by 5° (up to ±45°)"),
    ("left drag", "pull water towards the cursor"),
    ("right drag", "push water away from the cursor"),
    (
        "F (held)",
        "pour water at the cursor (within the particle budget)",
    ),
    ("Shift + left drag", "draw a wall (added on release)"),
    (
        "B / O",
        "drop a box / a circle at the cursor (its density: the panel's body density)",
    ),
    (
        "left drag on a body",
        "drag the body (whatever the left-drag tool is)",
    ),
    (
        "X + left click/drag",
        "erase water and drawn walls under the cursor",
    ),
    ("Shift + wheel", "change the tool radius (the circle)"),
    ("wheel, pinch", "zoom about the cursor"),
    ("middle drag, Space + drag", "pan the view"),
    ("0", "fit the whole tank in the view again"),
    ("Space (tap)", "pause / resume"),
    ("N", "single step (pauses)"),
    (
        "R",
        "reset to the scene as loaded: water, walls, gravity, radius, settings \
         (drawn walls go)",
    ),
    ("C", "cycle the colouring (speed, density, pressure)"),
    ("P", "water as particles (dots) / as a surface"),
    (
        "] / [",
        "finer / coarser particles: twice / half as many (restarts the scene)",
    ),
    ("F12", "save a PNG screenshot to the current directory"),
    (
        "Ctrl+S",
        "save the state as a scene, scene-<time>.json in the current directory",
    ),
    ("Ctrl+O or drop a .json", "open a scene file"),
    (
        "Ctrl+Z",
        "undo: take away the last wall drawn or the last water poured",
    ),
    (
        "V",
        "record / stop a video (GIF, and MP4 with ffmpeg) into the current directory",
    ),
    ("H or ?", "show / hide this help (Esc closes it)"),
];

/// The number keys that load the built-in scenes, for `count` scenes: "1 – 5" (keys 1–9
/// only: there is no tenth number key); `None` without scenes.
pub fn scene_keys(count: usize) -> Option<String> {
    match count.min(9) {
        0 => None,
        1 => Some("1".into()),
        n => Some(format!("1 – {n}")),
    }
}

/// The keys that load the built-in scenes, in [`BUILTIN_SCENES`]'s order (those past its
/// end do nothing).
const SCENE_KEYS: [Key; 9] = [
    Key::Num1,
    Key::Num2,
    Key::Num3,
    Key::Num4,
    Key::Num5,
    Key::Num6,
    Key::Num7,
    Key::Num8,
    Key::Num9,
];

/// What the keys that write files do in the browser, where files are downloads.
#[cfg(target_arch = "wasm32")]
const WEB_KEY_HELP: &[(&str, &str)] = &[
    ("F12", "download a PNG of the water"),
    ("Ctrl+S", "download the state as a scene, scene-<time>.json"),
    (
        "Ctrl+O or drop a .json",
        "open a scene file (the browser's picker)",
    ),
    ("V", "record / stop a GIF video, downloaded when stopped"),
];

/// The help overlay's lines: [`KEY_HELP`] with the built-in scenes' keys after `R`.
pub fn key_help() -> Vec<(String, &'static str)> {
    let mut lines: Vec<(String, &'static str)> =
        KEY_HELP.iter().map(|(k, w)| (k.to_string(), *w)).collect();
    #[cfg(target_arch = "wasm32")]
    for (key, what) in &mut lines {
        if let Some((_, web)) = WEB_KEY_HELP.iter().find(|(k, _)| k == key) {
            *what = web;
        }
    }
    if let Some(keys) = scene_keys(BUILTIN_SCENES.len()) {
        let at = lines
            .iter()
            .position(|(k, _)| k == "R")
            .map_or(lines.len(), |i| i + 1);
        lines.insert(at, (keys, "load a built-in scene"));
    }
    lines
}

/// Whether `key` went down with Ctrl (Cmd on a Mac) this frame. The modifiers are the key
/// event's own: on a slow frame (a large scene, software rendering) the whole chord, Ctrl
/// released too, arrives within one frame, and the frame's modifier state has lost it.
fn command_pressed(input: &egui::InputState, key: Key) -> bool {
    input.events.iter().any(|e| {
        matches!(e, egui::Event::Key { key: k, pressed: true, modifiers, .. }
            if *k == key && modifiers.command)
    })
}

/// How many times `key` went down this frame without Ctrl, Cmd or Alt (Shift is allowed:
/// `B` is `b`), key repeat left out: a held key drops one body, and Ctrl+O opens a scene
/// without dropping a circle.
fn plain_presses(input: &egui::InputState, key: Key) -> usize {
    input
        .events
        .iter()
        .filter(|e| {
            matches!(e, egui::Event::Key { key: k, pressed: true, repeat: false, modifiers, .. }
                if *k == key && !(modifiers.command || modifiers.ctrl || modifiers.mac_cmd || modifiers.alt))
        })
        .count()
}

/// Gravity tilt per press of `q` / `e`, degrees.
pub const TILT_STEP_DEG: f32 = 5.0;
/// Largest gravity tilt, degrees either way.
pub const MAX_TILT_DEG: f32 = 45.0;
/// Speed of poured water, m/s (downwards).
pub const POUR_SPEED: f32 = 1.0;

/// Something the viewer should do in response to input.
#[derive(Clone, Debug, PartialEq)]
pub enum Command {
    /// Apply this action to the simulation before the next step.
    Sim(Action),
    /// Pause or resume.
    TogglePause,
    /// Take one solver step (and pause).
    Step,
    /// Restart the current scene.
    Reset,
    /// Load `BUILTIN_SCENES[index]`.
    LoadScene(usize),
    /// Switch to the next colouring.
    CycleColoring,
    /// Draw the water as dots or as a surface.
    ToggleLook,
    /// Take away the last wall drawn or the last water poured ([`crate::undo`]).
    Undo,
    /// Save a screenshot to the current directory.
    Screenshot,
    /// Start or stop recording a video into the current directory.
    ToggleRecording,
    /// Show or hide the help overlay.
    ToggleHelp,
    /// Hide the help overlay (Esc).
    CloseHelp,
    /// Restart the current scene with this particle radius, m (from the side panel).
    SetParticleRadius(f64),
    /// Restart the current scene with finer (`true`) or coarser particles: twice or half as
    /// many (`crate::resolution::KEY_FACTOR`).
    ChangeResolution { finer: bool },
    /// Save the state as a scene file in the current directory.
    SaveScene,
    /// Show the dialog that opens a scene file.
    OpenScene,
    /// Put a link that reproduces the scene in the address bar and on the clipboard.
    ShareLink,
    /// Multiply the view's zoom by `factor`, keeping the world point `about` (m) where it is
    /// on the screen.
    ZoomView { factor: f32, about: Vec2 },
    /// Move the view with the pointer by this many screen points.
    PanView { delta: egui::Vec2 },
    /// Fit the whole world in the view again.
    ResetView,
    /// Drop a rigid body of this shape (box or circle), centred at `at` (m, in the world as
    /// the view shows it) or, without a point, at the top of the tank's middle; sized for the
    /// scene and of the mapper's [`InputMapper::body_density`] (`crate::bodies::drop_spec`).
    DropBody { shape: BodyShape, at: Option<Vec2> },
}

/// Where the pointer is, as far as the simulation view is concerned.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ViewInput {
    /// The pointer in world coordinates (m) when it is over the view or dragging from it;
    /// `None` when it is elsewhere (side panel, outside the window).
    pub pointer: Option<Vec2>,
    /// The keyboard belongs to the viewer (no text field has focus).
    pub keyboard: bool,
    /// A rigid body lies under the pointer: pressing the primary button grabs it.
    pub over_body: bool,
}

/// What the pointer tool is doing this frame (for drawing the cursor circle).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Tool {
    /// Nothing pressed.
    #[default]
    Idle,
    /// Pulling water in (left drag).
    Pull,
    /// Pushing water away (right drag).
    Push,
    /// Pouring water (f held).
    Pour,
    /// Erasing (x + click).
    Erase,
    /// Drawing a wall (shift + drag).
    Wall,
    /// Moving the view (middle drag, space + drag).
    Pan,
    /// Dragging a rigid body (left drag that started on one).
    Drag,
}

/// What the primary button (a left drag, a finger on a touch screen) does. The other buttons
/// and the keys keep their own tools whatever is chosen here; on a phone, where one finger is
/// all there is, this is how push, pour, walls, erasing and panning are reached.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PrimaryTool {
    /// Pull water towards the pointer.
    #[default]
    Pull,
    /// Push water away.
    Push,
    /// Pour water.
    Pour,
    /// Draw a wall (added when the button or finger is lifted).
    Wall,
    /// Erase water and drawn walls.
    Erase,
    /// Move the view.
    Pan,
}

impl PrimaryTool {
    /// Every tool, in the order the panel shows them.
    pub const ALL: [PrimaryTool; 6] = [
        PrimaryTool::Pull,
        PrimaryTool::Push,
        PrimaryTool::Pour,
        PrimaryTool::Wall,
        PrimaryTool::Erase,
        PrimaryTool::Pan,
    ];

    /// The panel's name for it.
    pub fn label(self) -> &'static str {
        match self {
            PrimaryTool::Pull => "pull",
            PrimaryTool::Push => "push",
            PrimaryTool::Pour => "pour",
            PrimaryTool::Wall => "wall",
            PrimaryTool::Erase => "erase",
            PrimaryTool::Pan => "pan",
        }
    }
}

/// Turns egui input into commands, remembering what is held between frames.
#[derive(Clone, Debug)]
pub struct InputMapper {
    /// Radius of the pointer tools (push, pull, pour, erase), m.
    pub tool_radius: f32,
    /// Peak acceleration of push and pull, m/s² (at most `MAX_POINTER_ACCELERATION`).
    pub pointer_strength: f32,
    /// Smallest and largest tool radius, m.
    pub radius_limits: (f32, f32),
    /// Distance between recorded points of a drawn wall, m.
    pub wall_point_spacing: f32,
    /// What the primary button does (left drag, a finger).
    pub primary_tool: PrimaryTool,
    /// The side panel's shake buttons held: -1 left, 1 right, 0 none (set each frame).
    pub panel_shake: f32,
    /// Density of the next body dropped (`b`, `o`, the panel's buttons), kg/m³.
    pub body_density: f64,
    /// Magnitude of gravity, m/s².
    gravity_magnitude: f32,
    /// Gravity's angle from straight down, degrees (positive tips it towards +x).
    tilt_deg: f32,
    /// Shake direction last sent.
    shake: f32,
    /// A push or pull is in force.
    pointer_active: bool,
    /// The wall being drawn.
    wall: Option<Vec<Vec2>>,
    tool: Tool,
    /// Space is held: `Some(true)` once it was used to pan (then its release does not pause).
    space_held: Option<bool>,
    /// Where the pointer was when the view last moved with it, screen points (while panning).
    pan_from: Option<egui::Pos2>,
    /// A body is held (grabbed with the primary button): the last target sent, m.
    body_target: Option<Vec2>,
}

impl Default for InputMapper {
    fn default() -> Self {
        Self {
            tool_radius: 0.2,
            pointer_strength: MAX_POINTER_ACCELERATION,
            radius_limits: (0.02, 2.0),
            wall_point_spacing: 0.02,
            primary_tool: PrimaryTool::Pull,
            panel_shake: 0.0,
            body_density: crate::bodies::DEFAULT_BODY_DENSITY,
            gravity_magnitude: 9.81,
            tilt_deg: 0.0,
            shake: 0.0,
            pointer_active: false,
            wall: None,
            tool: Tool::Idle,
            space_held: None,
            pan_from: None,
            body_target: None,
        }
    }
}

impl InputMapper {
    /// A mapper for a scene with this gravity (m/s²) and particle spacing (m).
    pub fn new(gravity: Vec2, spacing: f32) -> Self {
        let mut m = Self::default();
        m.reset(gravity, spacing);
        m
    }

    /// Forget everything held (a new scene was loaded) and take the scene's gravity as the
    /// untilted reference if it points down, or as a tilt of its own otherwise.
    pub fn reset(&mut self, gravity: Vec2, spacing: f32) {
        self.gravity_magnitude = gravity.length();
        self.tilt_deg = if gravity.length_squared() > 0.0 {
            gravity.x.atan2(-gravity.y).to_degrees()
        } else {
            0.0
        };
        self.shake = 0.0;
        self.pointer_active = false;
        self.wall = None;
        self.body_target = None;
        self.tool = Tool::Idle;
        self.wall_point_spacing = 2.0 * spacing;
        self.radius_limits.0 = 2.0 * spacing;
        self.tool_radius = self
            .tool_radius
            .clamp(self.radius_limits.0, self.radius_limits.1);
    }

    /// Gravity as the tilt and magnitude make it, m/s².
    pub fn gravity(&self) -> Vec2 {
        let a = self.tilt_deg.to_radians();
        self.gravity_magnitude * Vec2::new(a.sin(), -a.cos())
    }

    /// Gravity's tilt from straight down, degrees.
    pub fn tilt_deg(&self) -> f32 {
        self.tilt_deg
    }

    /// Magnitude of gravity, m/s².
    pub fn gravity_magnitude(&self) -> f32 {
        self.gravity_magnitude
    }

    /// Set gravity from a magnitude (m/s², at least 0) and a tilt (degrees, clamped to
    /// ±[`MAX_TILT_DEG`]); returns the action that applies it.
    pub fn set_gravity(&mut self, magnitude: f32, tilt_deg: f32) -> Action {
        self.gravity_magnitude = magnitude.max(0.0);
        self.tilt_deg = tilt_deg.clamp(-MAX_TILT_DEG, MAX_TILT_DEG);
        Action::SetGravity {
            gravity: self.gravity(),
        }
    }

    /// The wall being drawn, for the preview.
    pub fn wall_preview(&self) -> Option<&[Vec2]> {
        self.wall.as_deref()
    }

    /// What the pointer did in the last frame.
    pub fn tool(&self) -> Tool {
        self.tool
    }

    /// Forget the held body without a [`Action::ReleaseBody`] (its grab was rejected: there
    /// was no body there after all).
    pub fn forget_body(&mut self) {
        self.body_target = None;
    }

    /// Map one frame of input to commands.
    pub fn update(&mut self, input: &egui::InputState, view: ViewInput) -> Vec<Command> {
        let mut out = Vec::new();
        if view.keyboard {
            self.keys(input, &mut out);
            for (key, shape) in [(Key::B, BodyShape::Box), (Key::O, BodyShape::Circle)] {
                for _ in 0..plain_presses(input, key) {
                    out.push(Command::DropBody {
                        shape,
                        at: view.pointer,
                    });
                }
            }
        } else {
            // A space released while a text field had the keys must not pause later.
            self.space_held = None;
        }
        let keys = if view.keyboard {
            let held = |a: Key, b: Key| input.key_down(a) || input.key_down(b);
            f32::from(held(Key::D, Key::ArrowRight)) - f32::from(held(Key::A, Key::ArrowLeft))
        } else {
            0.0
        };
        let shake = (keys + self.panel_shake).clamp(-1.0, 1.0);
        if shake != self.shake {
            self.shake = shake;
            out.push(Command::Sim(Action::ShakeTank { direction: shake }));
        }
        self.pointer(input, view, &mut out);
        out
    }

    fn keys(&mut self, input: &egui::InputState, out: &mut Vec<Command>) {
        for (key, step) in [(Key::Q, -TILT_STEP_DEG), (Key::E, TILT_STEP_DEG)] {
            for _ in 0..input.num_presses(key) {
                let tilt = self.tilt_deg + step;
                let action = self.set_gravity(self.gravity_magnitude, tilt);
                out.push(Command::Sim(action));
            }
        }
        // Space pauses when tapped, and pans while held with a drag: it acts on release,
        // unless it panned (so holding it to pan does not pause, nor does key repeat toggle).
        if input.key_pressed(Key::Space) && self.space_held.is_none() {
            self.space_held = Some(false);
        }
        if input.key_released(Key::Space) && self.space_held.take() == Some(false) {
            out.push(Command::TogglePause);
        }
        if input.key_pressed(Key::Num0) {
            out.push(Command::ResetView);
        }
        for _ in 0..input.num_presses(Key::N) {
            out.push(Command::Step);
        }
        if input.key_pressed(Key::R) {
            out.push(Command::Reset);
        }
        // `[` and `]` arrive as keys on some layouts and only as text on others.
        let typed = |c: &str| {
            input
                .events
                .iter()
                .any(|e| matches!(e, egui::Event::Text(t) if t == c))
        };
        if input.key_pressed(Key::CloseBracket) || typed("]") {
            out.push(Command::ChangeResolution { finer: true });
        } else if input.key_pressed(Key::OpenBracket) || typed("[") {
            out.push(Command::ChangeResolution { finer: false });
        }
        for (i, key) in SCENE_KEYS.iter().enumerate() {
            if i < BUILTIN_SCENES.len() && input.key_pressed(*key) {
                out.push(Command::LoadScene(i));
            }
        }
        // Two presses within one slow frame are two steps.
        for _ in 0..input.num_presses(Key::C) {
            out.push(Command::CycleColoring);
        }
        for _ in 0..input.num_presses(Key::P) {
            out.push(Command::ToggleLook);
        }
        if input.key_pressed(Key::F12) {
            out.push(Command::Screenshot);
        }
        if command_pressed(input, Key::S) {
            out.push(Command::SaveScene);
        }
        if command_pressed(input, Key::O) {
            out.push(Command::OpenScene);
        }
        if command_pressed(input, Key::Z) {
            out.push(Command::Undo);
        }
        if input.key_pressed(Key::V) {
            out.push(Command::ToggleRecording);
        }
        // `?` arrives as Key::Questionmark on some layouts and only as text on others.
        let question = input.key_pressed(Key::Questionmark)
            || input
                .events
                .iter()
                .any(|e| matches!(e, egui::Event::Text(t) if t == "?"));
        if input.key_pressed(Key::H) || question {
            out.push(Command::ToggleHelp);
        }
        if input.key_pressed(Key::Escape) {
            out.push(Command::CloseHelp);
        }
    }

    fn pointer(&mut self, input: &egui::InputState, view: ViewInput, out: &mut Vec<Command>) {
        let p = &input.pointer;
        let primary = p.button_down(PointerButton::Primary);
        let secondary = p.button_down(PointerButton::Secondary);
        let middle = p.button_down(PointerButton::Middle);
        let keys = |k: Key| view.keyboard && input.key_down(k);
        self.tool = Tool::Idle;

        // A wall in progress ends when the button is released, wherever the pointer is.
        if self.wall.is_some() && !primary {
            let wall = self.wall.take().unwrap_or_default();
            if wall.len() >= 2 {
                out.push(Command::Sim(Action::AddWall { polyline: wall }));
            }
        }
        // So does a held body.
        if self.body_target.is_some() && (!primary || view.pointer.is_none()) {
            self.body_target = None;
            out.push(Command::Sim(Action::ReleaseBody));
        }

        let Some(at) = view.pointer else {
            self.pan_from = None;
            self.release(out);
            return;
        };

        // The wheel zooms about the cursor, as in map and drawing programs (the first thing a
        // new user tries), and so do pinching and Ctrl + wheel (egui's zoom gesture); with
        // Shift (the modifier of the tools: Shift + drag draws) it sizes the tool instead.
        let m = input.modifiers;
        // About 10 % per wheel notch (egui reports 40-50 points per line). Shift turns the
        // wheel into a horizontal scroll in egui: take both directions.
        let wheel = wheel_points(input);
        let notches = (wheel.x + wheel.y) / 50.0;
        if m.shift {
            if notches != 0.0 {
                let factor = 1.1f32.powf(notches);
                self.tool_radius =
                    (self.tool_radius * factor).clamp(self.radius_limits.0, self.radius_limits.1);
            }
        } else {
            let mut zoom = input.zoom_delta();
            if !(m.ctrl || m.command || m.alt) {
                zoom *= 1.1f32.powf(wheel.y / 50.0);
            }
            if zoom != 1.0 && zoom.is_finite() {
                out.push(Command::ZoomView {
                    factor: zoom,
                    about: at,
                });
            }
        }

        // A body under the pointer when the primary button goes down is grabbed, whatever
        // the primary tool; Shift (a wall), X (erasing) and Space (panning) keep their own
        // meaning. It follows the pointer until the button is released.
        if let Some(last) = self.body_target {
            self.tool = Tool::Drag;
            if last != at {
                self.body_target = Some(at);
                out.push(Command::Sim(Action::DragBody { target: at }));
            }
            self.release(out);
            return;
        }
        let modified = input.modifiers.shift || keys(Key::X) || self.space_held.is_some();
        if primary && p.primary_pressed() && view.over_body && !modified && self.wall.is_none() {
            self.tool = Tool::Drag;
            self.body_target = Some(at);
            self.release(out);
            out.push(Command::Sim(Action::GrabBody { at }));
            return;
        }

        // Panning: middle drag, or left drag with Space held. It takes the pointer from the
        // tools (a wall being drawn keeps it).
        let space_pan =
            primary && (self.space_held.is_some() || self.primary_tool == PrimaryTool::Pan);
        if self.wall.is_none() && (middle || space_pan) {
            self.tool = Tool::Pan;
            if space_pan && self.space_held.is_some() {
                self.space_held = Some(true);
            }
            // From where the button went down, not from last frame's pointer: on a slow
            // frame the move to the press and the press arrive together, and that move is
            // not part of the drag.
            let from = self.pan_from.or_else(|| p.press_origin());
            if let (Some(from), Some(now)) = (from, p.latest_pos()) {
                let delta = now - from;
                if delta != egui::Vec2::ZERO {
                    out.push(Command::PanView { delta });
                }
                self.pan_from = Some(now);
            }
            self.release(out);
            return;
        }
        self.pan_from = None;

        if let Some(wall) = &mut self.wall {
            self.tool = Tool::Wall;
            if wall
                .last()
                .is_none_or(|last| last.distance(at) >= self.wall_point_spacing)
            {
                wall.push(at);
            }
            self.release(out);
            return;
        }
        let tool = self.primary_tool;
        if primary && p.primary_pressed() && (input.modifiers.shift || tool == PrimaryTool::Wall) {
            self.wall = Some(vec![at]);
            self.tool = Tool::Wall;
            self.release(out);
            return;
        }
        // A click may press and release the button within one slow frame: it still erases.
        let clicked = primary || p.primary_pressed();
        if clicked && (keys(Key::X) || tool == PrimaryTool::Erase) {
            self.tool = Tool::Erase;
            self.release(out);
            out.push(Command::Sim(Action::Erase {
                at,
                radius: self.tool_radius,
            }));
            return;
        }
        let pour_by_button = primary && tool == PrimaryTool::Pour;
        if keys(Key::F) || pour_by_button {
            self.tool = Tool::Pour;
            out.push(Command::Sim(Action::Emit {
                at,
                radius: self.tool_radius,
                velocity: Vec2::new(0.0, -POUR_SPEED),
            }));
        }
        // The primary button pulls (or pushes, when that is its tool); the secondary pushes.
        let pulling = primary && tool == PrimaryTool::Pull;
        let pushing = secondary || (primary && tool == PrimaryTool::Push);
        if pulling || pushing {
            self.tool = if pulling { Tool::Pull } else { Tool::Push };
            let strength = self.pointer_strength.clamp(0.0, MAX_POINTER_ACCELERATION);
            self.pointer_active = true;
            out.push(Command::Sim(Action::Push {
                at,
                radius: self.tool_radius,
                strength: if pulling { -strength } else { strength },
            }));
        } else {
            self.release(out);
        }
    }

    fn release(&mut self, out: &mut Vec<Command>) {
        if self.pointer_active {
            self.pointer_active = false;
            out.push(Command::Sim(Action::ReleasePointer));
        }
    }
}

/// The wheel's movement this frame in points, as the events reported it (lines at egui's
/// line scroll speed, pages at the window's height): egui's smoothed scroll would spread a
/// notch's zoom over several frames.
fn wheel_points(input: &egui::InputState) -> egui::Vec2 {
    let line = egui::InputOptions::default().line_scroll_speed;
    let page = input.viewport_rect().height();
    input
        .events
        .iter()
        .fold(egui::Vec2::ZERO, |sum, event| match event {
            egui::Event::MouseWheel { unit, delta, .. } => {
                sum + match unit {
                    egui::MouseWheelUnit::Point => *delta,
                    egui::MouseWheelUnit::Line => line * *delta,
                    egui::MouseWheelUnit::Page => page * *delta,
                }
            }
            _ => sum,
        })
}

#[cfg(test)]
mod tests {
    use super::*;
    use egui::{Event, Modifiers, Pos2, RawInput};

    /// Runs frames of synthetic egui input through a mapper, like the window would.
    struct Harness {
        ctx: egui::Context,
        mapper: InputMapper,
        pointer: Option<Vec2>,
        /// A body lies under the pointer.
        over_body: bool,
    }

    impl Harness {
        fn new() -> Self {
            Self {
                ctx: egui::Context::default(),
                mapper: InputMapper::new(Vec2::new(0.0, -9.81), 0.02),
                pointer: Some(Vec2::new(1.0, 0.5)),
                over_body: false,
            }
        }

        fn frame(&mut self, events: Vec<Event>) -> Vec<Command> {
            self.frame_with(events, Modifiers::NONE)
        }

        fn frame_with(&mut self, events: Vec<Event>, modifiers: Modifiers) -> Vec<Command> {
            let mut all = vec![Event::ModifiersChanged(modifiers)];
            all.extend(events);
            let raw = RawInput {
                events: all,
                ..Default::default()
            };
            let mut out = Vec::new();
            let view = ViewInput {
                pointer: self.pointer,
                keyboard: true,
                over_body: self.over_body,
            };
            let _ = self.ctx.run_ui(raw, |ui| {
                out = ui.ctx().input(|i| self.mapper.update(i, view));
            });
            out
        }
    }

    fn key(key: Key, pressed: bool) -> Event {
        Event::Key {
            key,
            physical_key: None,
            pressed,
            repeat: false,
            modifiers: Modifiers::NONE,
        }
    }

    fn button(button: PointerButton, pressed: bool, modifiers: Modifiers) -> Event {
        Event::PointerButton {
            pos: Pos2::new(100.0, 100.0),
            button,
            pressed,
            modifiers,
        }
    }

    fn moved() -> Event {
        Event::PointerMoved(Pos2::new(100.0, 100.0))
    }

    fn shake(direction: f32) -> Command {
        Command::Sim(Action::ShakeTank { direction })
    }

    #[test]
    fn the_panels_shake_buttons_shake_like_the_keys() {
        let mut h = Harness::new();
        h.mapper.panel_shake = -1.0;
        assert_eq!(h.frame(vec![]), vec![shake(-1.0)]);
        assert_eq!(h.frame(vec![]), vec![]);
        // A key the other way cancels it, as A and D do.
        assert_eq!(h.frame(vec![key(Key::D, true)]), vec![shake(0.0)]);
        h.mapper.panel_shake = 0.0;
        assert_eq!(h.frame(vec![]), vec![shake(1.0)]);
    }

    #[test]
    fn d_shakes_right_while_held_and_release_stops() {
        let mut h = Harness::new();
        assert_eq!(h.frame(vec![key(Key::D, true)]), vec![shake(1.0)]);
        // Held: nothing new.
        assert_eq!(h.frame(vec![]), vec![]);
        assert_eq!(h.frame(vec![key(Key::D, false)]), vec![shake(0.0)]);
        assert_eq!(h.frame(vec![]), vec![]);
    }

    #[test]
    fn a_and_arrows_shake_and_opposite_keys_cancel() {
        let mut h = Harness::new();
        assert_eq!(h.frame(vec![key(Key::A, true)]), vec![shake(-1.0)]);
        assert_eq!(h.frame(vec![key(Key::ArrowRight, true)]), vec![shake(0.0)]);
        assert_eq!(h.frame(vec![key(Key::A, false)]), vec![shake(1.0)]);
        assert_eq!(h.frame(vec![key(Key::ArrowRight, false)]), vec![shake(0.0)]);
    }

    #[test]
    fn keys_are_ignored_while_a_text_field_has_focus() {
        let mut h = Harness::new();
        let raw = RawInput {
            events: vec![key(Key::D, true), key(Key::R, true)],
            ..Default::default()
        };
        let mut out = Vec::new();
        let _ = h.ctx.run_ui(raw, |ui| {
            let view = ViewInput {
                pointer: None,
                keyboard: false,
                over_body: false,
            };
            out = ui.ctx().input(|i| h.mapper.update(i, view));
        });
        assert_eq!(out, vec![]);
    }

    #[test]
    fn q_and_e_tilt_gravity_within_bounds() {
        let mut h = Harness::new();
        let out = h.frame(vec![key(Key::E, true), key(Key::E, false)]);
        let [Command::Sim(Action::SetGravity { gravity })] = out.as_slice() else {
            panic!("expected one SetGravity, got {out:?}");
        };
        assert!((gravity.length() - 9.81).abs() < 1e-4);
        assert!(gravity.x > 0.0, "e tips gravity towards +x: {gravity}");
        assert!((h.mapper.tilt_deg() - TILT_STEP_DEG).abs() < 1e-4);
        for _ in 0..20 {
            h.frame(vec![key(Key::Q, true), key(Key::Q, false)]);
        }
        assert!((h.mapper.tilt_deg() + MAX_TILT_DEG).abs() < 1e-4);
        let g = h.mapper.gravity();
        assert!(
            (g.x - g.y).abs() < 1e-3 && g.x < 0.0,
            "tilted 45° left: {g}"
        );
    }

    #[test]
    fn single_keys_map_to_viewer_commands() {
        let mut h = Harness::new();
        let cases = [
            (Key::Space, Command::TogglePause),
            (Key::Num0, Command::ResetView),
            (Key::N, Command::Step),
            (Key::R, Command::Reset),
            (Key::Num1, Command::LoadScene(0)),
            (Key::Num2, Command::LoadScene(1)),
            (Key::C, Command::CycleColoring),
            (Key::P, Command::ToggleLook),
            (Key::F12, Command::Screenshot),
            (Key::V, Command::ToggleRecording),
            (Key::H, Command::ToggleHelp),
            (Key::Questionmark, Command::ToggleHelp),
        ];
        for (k, want) in cases {
            assert_eq!(
                h.frame(vec![key(k, true), key(k, false)]),
                vec![want],
                "{k:?}"
            );
        }
        // Scenes that do not exist are ignored.
        assert_eq!(h.frame(vec![key(Key::Num9, true)]), vec![]);
    }

    #[test]
    fn ctrl_s_saves_and_ctrl_o_opens_but_plain_s_does_nothing() {
        let mut h = Harness::new();
        let ctrl = |k: Key| Event::Key {
            key: k,
            physical_key: None,
            pressed: true,
            repeat: false,
            modifiers: Modifiers::COMMAND,
        };
        assert_eq!(
            h.frame_with(vec![ctrl(Key::S)], Modifiers::COMMAND),
            vec![Command::SaveScene]
        );
        assert_eq!(
            h.frame_with(vec![ctrl(Key::O)], Modifiers::COMMAND),
            vec![Command::OpenScene]
        );
        assert_eq!(h.frame(vec![key(Key::S, true)]), vec![]);
        // A whole chord within one slow frame: Ctrl is up again by the frame's end, but it
        // was down when S went down.
        assert_eq!(
            h.frame_with(vec![ctrl(Key::S), key(Key::S, false)], Modifiers::NONE),
            vec![Command::SaveScene]
        );
    }

    #[test]
    fn left_drag_pulls_right_drag_pushes_and_release_lets_go() {
        let mut h = Harness::new();
        let at = h.pointer.unwrap();
        let s = MAX_POINTER_ACCELERATION;
        let r = h.mapper.tool_radius;
        let out = h.frame(vec![
            moved(),
            button(PointerButton::Primary, true, Modifiers::NONE),
        ]);
        assert_eq!(
            out,
            vec![Command::Sim(Action::Push {
                at,
                radius: r,
                strength: -s
            })]
        );
        assert_eq!(h.mapper.tool(), Tool::Pull);
        // Dragging follows the pointer.
        h.pointer = Some(Vec2::new(1.5, 0.7));
        let out = h.frame(vec![moved()]);
        assert_eq!(
            out,
            vec![Command::Sim(Action::Push {
                at: Vec2::new(1.5, 0.7),
                radius: r,
                strength: -s
            })]
        );
        let out = h.frame(vec![button(PointerButton::Primary, false, Modifiers::NONE)]);
        assert_eq!(out, vec![Command::Sim(Action::ReleasePointer)]);
        let out = h.frame(vec![button(
            PointerButton::Secondary,
            true,
            Modifiers::NONE,
        )]);
        assert!(matches!(
            out.as_slice(),
            [Command::Sim(Action::Push { strength, .. })] if *strength == s
        ));
        assert_eq!(h.mapper.tool(), Tool::Push);
        // Leaving the view lets go too.
        h.pointer = None;
        assert_eq!(h.frame(vec![]), vec![Command::Sim(Action::ReleasePointer)]);
    }

    /// One finger down, then up: what a touch screen sends through egui (a touch becomes the
    /// primary button), whatever the primary tool is.
    fn press_and_release(h: &mut Harness) -> (Vec<Command>, Vec<Command>, Vec<Command>) {
        let down = h.frame(vec![
            moved(),
            button(PointerButton::Primary, true, Modifiers::NONE),
        ]);
        h.pointer = Some(Vec2::new(1.4, 0.6));
        let drag = h.frame(vec![moved_to(140.0, 120.0)]);
        let up = h.frame(vec![button(PointerButton::Primary, false, Modifiers::NONE)]);
        h.pointer = Some(Vec2::new(1.0, 0.5));
        (down, drag, up)
    }

    #[test]
    fn the_primary_tool_gives_one_finger_every_tool() {
        let mut h = Harness::new();
        let s = MAX_POINTER_ACCELERATION;
        h.mapper.primary_tool = PrimaryTool::Push;
        let (down, _, up) = press_and_release(&mut h);
        assert!(
            matches!(down.as_slice(), [Command::Sim(Action::Push { strength, .. })] if *strength == s),
            "{down:?}"
        );
        assert_eq!(up, vec![Command::Sim(Action::ReleasePointer)]);

        h.mapper.primary_tool = PrimaryTool::Pour;
        let (down, _, _) = press_and_release(&mut h);
        assert!(
            matches!(down.as_slice(), [Command::Sim(Action::Emit { .. })]),
            "{down:?}"
        );
        assert_eq!(
            h.mapper.tool(),
            Tool::Idle,
            "lifting the finger stops the pour"
        );

        h.mapper.primary_tool = PrimaryTool::Wall;
        let (down, _, up) = press_and_release(&mut h);
        assert_eq!(down, vec![]);
        assert!(
            matches!(up.as_slice(), [Command::Sim(Action::AddWall { polyline })] if polyline.len() == 2),
            "{up:?}"
        );

        h.mapper.primary_tool = PrimaryTool::Erase;
        let (down, _, _) = press_and_release(&mut h);
        assert!(
            matches!(down.as_slice(), [Command::Sim(Action::Erase { .. })]),
            "{down:?}"
        );

        h.mapper.primary_tool = PrimaryTool::Pan;
        let (_, drag, _) = press_and_release(&mut h);
        assert_eq!(
            drag,
            vec![Command::PanView {
                delta: egui::vec2(40.0, 20.0)
            }]
        );
        // Panning with the tool leaves Space alone: a tap still pauses.
        assert_eq!(h.frame(vec![key(Key::Space, true)]), vec![]);
        assert_eq!(
            h.frame(vec![key(Key::Space, false)]),
            vec![Command::TogglePause]
        );

        // The right button keeps pushing whatever the primary tool is.
        h.mapper.primary_tool = PrimaryTool::Pour;
        let out = h.frame(vec![button(
            PointerButton::Secondary,
            true,
            Modifiers::NONE,
        )]);
        assert!(
            matches!(out.as_slice(), [Command::Sim(Action::Push { strength, .. })] if *strength == s),
            "{out:?}"
        );
    }

    fn wheel(modifiers: Modifiers) -> Event {
        Event::MouseWheel {
            unit: egui::MouseWheelUnit::Line,
            delta: egui::vec2(0.0, 1.0),
            phase: egui::TouchPhase::Move,
            modifiers,
        }
    }

    fn moved_to(x: f32, y: f32) -> Event {
        Event::PointerMoved(Pos2::new(x, y))
    }

    #[test]
    fn wheel_zooms_about_the_cursor_and_shift_wheel_sizes_the_tool() {
        let mut h = Harness::new();
        let r0 = h.mapper.tool_radius;
        let out = h.frame(vec![moved(), wheel(Modifiers::NONE)]);
        let [Command::ZoomView { factor, about }] = out.as_slice() else {
            panic!("expected one ZoomView, got {out:?}");
        };
        assert!(*factor > 1.05 && *factor < 1.5, "one notch in: {factor}");
        assert_eq!(*about, h.pointer.unwrap());
        assert_eq!(h.mapper.tool_radius, r0);
        // Shift + wheel: the tool grows, the view stays.
        let out = h.frame_with(vec![moved(), wheel(Modifiers::SHIFT)], Modifiers::SHIFT);
        assert_eq!(out, vec![]);
        assert!(h.mapper.tool_radius > r0, "{} > {r0}", h.mapper.tool_radius);
        // Pinch (egui's zoom event) zooms too.
        let out = h.frame(vec![moved(), Event::Zoom(1.5)]);
        assert!(
            matches!(out.as_slice(), [Command::ZoomView { factor, .. }] if (*factor - 1.5).abs() < 1e-6),
            "{out:?}"
        );
        // Off the view the wheel does nothing here (the panel scrolls).
        h.pointer = None;
        assert_eq!(h.frame(vec![moved(), wheel(Modifiers::NONE)]), vec![]);
    }

    #[test]
    fn middle_drag_pans_and_does_not_pour() {
        let mut h = Harness::new();
        h.frame(vec![moved_to(100.0, 100.0)]);
        let out = h.frame(vec![button(PointerButton::Middle, true, Modifiers::NONE)]);
        assert_eq!(out, vec![]);
        assert_eq!(h.mapper.tool(), Tool::Pan);
        let out = h.frame(vec![moved_to(110.0, 95.0)]);
        assert_eq!(
            out,
            vec![Command::PanView {
                delta: egui::vec2(10.0, -5.0)
            }]
        );
        h.frame(vec![button(PointerButton::Middle, false, Modifiers::NONE)]);
        assert_eq!(h.mapper.tool(), Tool::Idle);
        // A slow frame: the move to (300, 300) and the press there arrive together; the
        // view moves only with what comes after the press.
        let press_at = |pos: Pos2, pressed: bool| Event::PointerButton {
            pos,
            button: PointerButton::Middle,
            pressed,
            modifiers: Modifiers::NONE,
        };
        let out = h.frame(vec![
            moved_to(300.0, 300.0),
            press_at(Pos2::new(300.0, 300.0), true),
        ]);
        assert_eq!(out, vec![]);
        let out = h.frame(vec![moved_to(302.0, 303.0)]);
        assert_eq!(
            out,
            vec![Command::PanView {
                delta: egui::vec2(2.0, 3.0)
            }]
        );
    }

    #[test]
    fn space_tap_pauses_and_space_drag_pans_without_pausing_or_pulling() {
        let mut h = Harness::new();
        // A tap: press and release (in one frame or two) toggles the pause once.
        assert_eq!(
            h.frame(vec![key(Key::Space, true), key(Key::Space, false)]),
            vec![Command::TogglePause]
        );
        assert_eq!(h.frame(vec![key(Key::Space, true)]), vec![]);
        assert_eq!(
            h.frame(vec![key(Key::Space, false)]),
            vec![Command::TogglePause]
        );
        // Held with a left drag: pans; no pull, and no pause on release.
        h.frame(vec![moved_to(100.0, 100.0), key(Key::Space, true)]);
        let out = h.frame(vec![button(PointerButton::Primary, true, Modifiers::NONE)]);
        assert_eq!(out, vec![]);
        let out = h.frame(vec![moved_to(90.0, 120.0)]);
        assert_eq!(
            out,
            vec![Command::PanView {
                delta: egui::vec2(-10.0, 20.0)
            }]
        );
        h.frame(vec![button(PointerButton::Primary, false, Modifiers::NONE)]);
        assert_eq!(h.frame(vec![key(Key::Space, false)]), vec![]);
        // Afterwards a left drag pulls again.
        let out = h.frame(vec![button(PointerButton::Primary, true, Modifiers::NONE)]);
        assert!(
            matches!(out.as_slice(), [Command::Sim(Action::Push { strength, .. })] if *strength < 0.0),
            "{out:?}"
        );
    }

    #[test]
    fn shift_drag_draws_a_wall_added_on_release() {
        let mut h = Harness::new();
        h.pointer = Some(Vec2::new(1.0, 1.0));
        let out = h.frame_with(
            vec![
                moved(),
                button(PointerButton::Primary, true, Modifiers::SHIFT),
            ],
            Modifiers::SHIFT,
        );
        assert_eq!(out, vec![]);
        for x in [1.1, 1.2, 1.3] {
            h.pointer = Some(Vec2::new(x, 1.0));
            assert_eq!(h.frame_with(vec![moved()], Modifiers::SHIFT), vec![]);
        }
        assert_eq!(h.mapper.wall_preview().map(<[Vec2]>::len), Some(4));
        let out = h.frame(vec![button(PointerButton::Primary, false, Modifiers::NONE)]);
        let [Command::Sim(Action::AddWall { polyline })] = out.as_slice() else {
            panic!("expected AddWall, got {out:?}");
        };
        assert_eq!(polyline.len(), 4);
        assert_eq!(polyline[0], Vec2::new(1.0, 1.0));
        assert!(h.mapper.wall_preview().is_none());
    }

    #[test]
    fn x_click_erases_under_the_cursor() {
        let mut h = Harness::new();
        let out = h.frame(vec![
            key(Key::X, true),
            moved(),
            button(PointerButton::Primary, true, Modifiers::NONE),
        ]);
        assert_eq!(
            out,
            vec![Command::Sim(Action::Erase {
                at: h.pointer.unwrap(),
                radius: h.mapper.tool_radius
            })]
        );
        assert_eq!(h.mapper.tool(), Tool::Erase);
    }

    #[test]
    fn a_quick_x_click_within_one_frame_still_erases() {
        // At a low frame rate the press and the release arrive in the same frame.
        let mut h = Harness::new();
        let out = h.frame(vec![
            key(Key::X, true),
            moved(),
            button(PointerButton::Primary, true, Modifiers::NONE),
            button(PointerButton::Primary, false, Modifiers::NONE),
        ]);
        assert_eq!(
            out,
            vec![Command::Sim(Action::Erase {
                at: h.pointer.unwrap(),
                radius: h.mapper.tool_radius
            })]
        );
    }

    #[test]
    fn escape_closes_the_help() {
        let mut h = Harness::new();
        let out = h.frame(vec![key(Key::Escape, true)]);
        assert_eq!(out, vec![Command::CloseHelp]);
    }

    #[test]
    fn every_binding_is_in_the_help() {
        let text: String = key_help().iter().map(|(k, _)| k.as_str()).collect();
        for needle in [
            "A / D",
            "Q / E",
            "left drag",
            "right drag",
            "Shift + wheel",
            "wheel, pinch",
            "middle drag",
            "Space + drag",
            "0",
            "F",
            "Shift",
            "X",
            "Space",
            "N",
            "R",
            "1",
            "C",
            "P",
            "F12",
            "V",
            "H or ?",
            "Ctrl+S",
            "Ctrl+O",
            "Ctrl+Z",
            "B / O",
            "on a body",
        ] {
            assert!(text.contains(needle), "{needle}");
        }
    }

    #[test]
    fn the_help_names_as_many_scene_keys_as_there_are_built_in_scenes() {
        assert_eq!(scene_keys(0), None);
        assert_eq!(scene_keys(1).as_deref(), Some("1"));
        assert_eq!(scene_keys(5).as_deref(), Some("1 – 5"));
        assert_eq!(scene_keys(14).as_deref(), Some("1 – 9"));
        let help = key_help();
        let want = scene_keys(BUILTIN_SCENES.len()).unwrap();
        let line = help.iter().find(|(_, w)| w.contains("built-in scene"));
        assert_eq!(line.map(|(k, _)| k.as_str()), Some(want.as_str()));
        // The key after the last scene does nothing.
        if BUILTIN_SCENES.len() < 9 {
            let mut h = Harness::new();
            let next = SCENE_KEYS[BUILTIN_SCENES.len()];
            assert_eq!(h.frame(vec![key(next, true)]), vec![]);
        }
    }

    #[test]
    fn b_and_o_drop_a_box_and_a_circle_at_the_cursor_but_ctrl_o_does_not() {
        let mut h = Harness::new();
        let at = h.pointer;
        assert_eq!(
            h.frame(vec![key(Key::B, true), key(Key::B, false)]),
            vec![Command::DropBody {
                shape: BodyShape::Box,
                at
            }]
        );
        assert_eq!(
            h.frame(vec![key(Key::O, true), key(Key::O, false)]),
            vec![Command::DropBody {
                shape: BodyShape::Circle,
                at
            }]
        );
        // Key repeat while held drops nothing more (egui marks a press of a key already
        // down as a repeat).
        assert_eq!(h.frame(vec![key(Key::B, true)]).len(), 1);
        assert_eq!(h.frame(vec![key(Key::B, true)]), vec![]);
        h.frame(vec![key(Key::B, false)]);
        // Ctrl+O opens a scene, and only that.
        let ctrl_o = Event::Key {
            key: Key::O,
            physical_key: None,
            pressed: true,
            repeat: false,
            modifiers: Modifiers::COMMAND,
        };
        assert_eq!(
            h.frame_with(vec![ctrl_o], Modifiers::COMMAND),
            vec![Command::OpenScene]
        );
        // Off the view: dropped at the tank's top (the app decides where).
        h.pointer = None;
        assert_eq!(
            h.frame(vec![key(Key::B, true)]),
            vec![Command::DropBody {
                shape: BodyShape::Box,
                at: None
            }]
        );
    }

    #[test]
    fn a_left_press_on_a_body_grabs_it_whatever_the_tool_and_release_lets_go() {
        for tool in PrimaryTool::ALL {
            let mut h = Harness::new();
            h.mapper.primary_tool = tool;
            h.over_body = true;
            let at = h.pointer.unwrap();
            let (down, drag, up) = press_and_release(&mut h);
            assert_eq!(
                down,
                vec![Command::Sim(Action::GrabBody { at })],
                "{tool:?}"
            );
            assert_eq!(
                drag,
                vec![Command::Sim(Action::DragBody {
                    target: Vec2::new(1.4, 0.6)
                })],
                "{tool:?}"
            );
            assert_eq!(up, vec![Command::Sim(Action::ReleaseBody)], "{tool:?}");
            assert_eq!(h.mapper.tool(), Tool::Idle);
        }
    }

    #[test]
    fn a_held_body_follows_the_pointer_only_when_it_moves_and_off_the_view_is_let_go() {
        let mut h = Harness::new();
        h.over_body = true;
        h.frame(vec![
            moved(),
            button(PointerButton::Primary, true, Modifiers::NONE),
        ]);
        assert_eq!(h.mapper.tool(), Tool::Drag);
        // The pointer leaves the body behind (the body lags): still dragging.
        h.over_body = false;
        assert_eq!(h.frame(vec![]), vec![]);
        h.pointer = Some(Vec2::new(2.0, 1.0));
        assert_eq!(
            h.frame(vec![moved_to(120.0, 90.0)]),
            vec![Command::Sim(Action::DragBody {
                target: Vec2::new(2.0, 1.0)
            })]
        );
        h.pointer = None;
        assert_eq!(h.frame(vec![]), vec![Command::Sim(Action::ReleaseBody)]);
    }

    #[test]
    fn shift_and_x_on_a_body_keep_their_tools_and_a_rejected_grab_is_forgotten() {
        let mut h = Harness::new();
        h.over_body = true;
        let out = h.frame_with(
            vec![
                moved(),
                button(PointerButton::Primary, true, Modifiers::SHIFT),
            ],
            Modifiers::SHIFT,
        );
        assert_eq!(out, vec![]);
        assert_eq!(h.mapper.tool(), Tool::Wall);
        h.frame(vec![button(PointerButton::Primary, false, Modifiers::NONE)]);
        let out = h.frame(vec![
            key(Key::X, true),
            button(PointerButton::Primary, true, Modifiers::NONE),
        ]);
        assert!(
            matches!(out.as_slice(), [Command::Sim(Action::Erase { .. })]),
            "{out:?}"
        );
        h.frame(vec![
            key(Key::X, false),
            button(PointerButton::Primary, false, Modifiers::NONE),
        ]);
        // A grab the simulation refused: no drags, no release follow it.
        let out = h.frame(vec![button(PointerButton::Primary, true, Modifiers::NONE)]);
        assert!(matches!(
            out.as_slice(),
            [Command::Sim(Action::GrabBody { .. })]
        ));
        h.mapper.forget_body();
        h.over_body = false;
        h.pointer = Some(Vec2::new(1.2, 0.5));
        let out = h.frame(vec![moved_to(110.0, 100.0)]);
        assert!(
            matches!(out.as_slice(), [Command::Sim(Action::Push { .. })]),
            "back to pulling: {out:?}"
        );
    }
}
