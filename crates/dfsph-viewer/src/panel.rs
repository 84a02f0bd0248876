//! The side panel: scene picker, solver and viewer parameters, run controls, live plots.
//! Every solver parameter change becomes an [`Action`] (`SetSolver`, `SetViscosity`,
//! `SetTimeStep`, `SetGravity`) applied between steps, like any other input.

use dfsph::forces::MAX_POINTER_ACCELERATION;
use dfsph::rigid::spec::BODY_DENSITY_RANGE;
use dfsph::rigid::MAX_BODIES;
use dfsph::scene::{BodyShape, Method, BUILTIN_SCENES};
use dfsph::{Action, Simulation};
use dfsph_io::render::WaterLook;
use eframe::egui::{self, Slider};

use crate::input::{Command, InputMapper, PrimaryTool, MAX_TILT_DEG};
use crate::render::{ColorScale, Coloring};

/// Where the buttons put their files, in their hover texts.
#[cfg(not(target_arch = "wasm32"))]
const SAVE_HINT: &str = "Ctrl+S: the state as scene-<time>.json in the current directory";
#[cfg(target_arch = "wasm32")]
const SAVE_HINT: &str = "Ctrl+S: download the state as scene-<time>.json";
#[cfg(not(target_arch = "wasm32"))]
const SCREENSHOT_HINT: &str = "F12: the window as dfsph2d-<time>.png in the current directory";
#[cfg(target_arch = "wasm32")]
const SCREENSHOT_HINT: &str = "F12: download the water as dfsph2d-<time>.png";
#[cfg(not(target_arch = "wasm32"))]
const RECORD_HINT: &str = "A GIF (and an MP4 with ffmpeg) of the simulation, at simulated speed, into the current directory (V)";
#[cfg(target_arch = "wasm32")]
const RECORD_HINT: &str =
    "A GIF of the simulation, at simulated speed, downloaded when you stop (V)";

/// What the side panel reads and edits.
pub struct PanelState<'a> {
    pub sim: &'a Simulation,
    pub mapper: &'a mut InputMapper,
    /// Simulated seconds per wall second asked for.
    pub time_scale: &'a mut f64,
    pub coloring: &'a mut Coloring,
    /// The water as a surface or as dots.
    pub look: &'a mut WaterLook,
    /// What undo would take away now, if anything.
    pub undo: Option<crate::undo::Stroke>,
    /// The colour scale of each colouring, in [`Coloring::ALL`] order.
    pub scales: &'a mut [ColorScale; 3],
    /// The view shows the whole tank (no zoom or pan).
    pub view_fitted: bool,
    /// The particle radius slider's value, m (applied when the slider is let go).
    pub radius_edit: &'a mut f64,
    /// The radius slider's range, m ([`crate::scene_file::radius_range`]); `None` turns it
    /// off (a scene that lists its particles).
    pub radius_range: Option<(f64, f64)>,
    pub paused: bool,
    /// A video is being recorded.
    pub recording: bool,
    /// The last message for the user (rejected actions, saved files).
    pub status: Option<&'a str>,
    /// The file the scene was opened from, if it was.
    pub opened_file: Option<&'a str>,
}

/// What the scene list shows as the current scene: the file a scene was opened from (a saved
/// state keeps the name of the built-in scene it started as, which is not what runs), or
/// the scene's name.
pub fn scene_list_label(scene_name: &str, opened_file: Option<&str>) -> String {
    match opened_file {
        Some(file) => format!("{file} (file)"),
        None => scene_name.to_string(),
    }
}

/// Draw the panel's contents; returns the commands the user gave.
pub fn side_panel(ui: &mut egui::Ui, st: PanelState) -> Vec<Command> {
    let mut out = Vec::new();
    let sim = st.sim;
    let scene = sim.scene();
    egui::ScrollArea::vertical().show(ui, |ui| {
        ui.heading("dfsph2d");
        ui.horizontal(|ui| {
            if ui
                .button(if st.paused { "▶ Resume" } else { "⏸ Pause" })
                .clicked()
            {
                out.push(Command::TogglePause);
            }
            if ui.button("Step").clicked() {
                out.push(Command::Step);
            }
            if ui
                .button("Reset")
                .on_hover_text(
                    "Back to the scene as loaded: its water, walls, gravity, radius and \
                     settings (drawn walls and poured water go)",
                )
                .clicked()
            {
                out.push(Command::Reset);
            }
            let undo = st.undo.map_or("nothing to undo".to_string(), |stroke| {
                format!("Ctrl+Z: take away {}", stroke.label())
            });
            if ui
                .add_enabled(st.undo.is_some(), egui::Button::new("Undo"))
                .on_hover_text(undo)
                .on_disabled_hover_text("Nothing to undo: draw a wall or pour water first")
                .clicked()
            {
                out.push(Command::Undo);
            }
        });
        ui.horizontal(|ui| {
            if ui
                .button("Screenshot")
                .on_hover_text(SCREENSHOT_HINT)
                .clicked()
            {
                out.push(Command::Screenshot);
            }
            let record = if st.recording {
                "⏹ Stop"
            } else {
                "⏺ Record"
            };
            if ui.button(record).on_hover_text(RECORD_HINT).clicked() {
                out.push(Command::ToggleRecording);
            }
            if ui.button("Help").clicked() {
                out.push(Command::ToggleHelp);
            }
            if ui
                .add_enabled(!st.view_fitted, egui::Button::new("Fit view"))
                .on_hover_text("Show the whole tank again (key 0); wheel zooms, middle drag pans")
                .clicked()
            {
                out.push(Command::ResetView);
            }
        });
        ui.horizontal(|ui| {
            if ui.button("Save scene…").on_hover_text(SAVE_HINT).clicked() {
                out.push(Command::SaveScene);
            }
            if ui
                .button("Open scene…")
                .on_hover_text("Ctrl+O, or drop a .json file on the window")
                .clicked()
            {
                out.push(Command::OpenScene);
            }
            #[cfg(target_arch = "wasm32")]
            if ui
                .button("Copy link")
                .on_hover_text(
                    "A link to this scene, with its walls and settings (the water as it \
                     started), in the address bar and on the clipboard",
                )
                .clicked()
            {
                out.push(Command::ShareLink);
            }
        });
        if let Some(msg) = st.status {
            ui.label(egui::RichText::new(msg).small());
        }
        ui.separator();

        egui::ComboBox::from_label("scene")
            .selected_text(scene_list_label(&scene.name, st.opened_file))
            .show_ui(ui, |ui| {
                for (i, b) in BUILTIN_SCENES.iter().enumerate() {
                    let current = b.name == scene.name && st.opened_file.is_none();
                    let r = ui
                        .selectable_label(current, format!("{} {}", i + 1, b.name))
                        .on_hover_text(b.description);
                    if r.clicked() {
                        out.push(Command::LoadScene(i));
                    }
                }
            });
        // The range always holds the scene's own radius, and the slider never changes a value
        // it did not edit: a scene runs at the radius it was written with.
        match st.radius_range {
            Some((lo, hi)) => {
                let r = ui
                    .add(
                        Slider::new(st.radius_edit, lo..=hi)
                            .logarithmic(true)
                            .clamping(egui::SliderClamping::Edits)
                            .text("particle radius (m)"),
                    )
                    .on_hover_text("Restarts the scene with the new resolution");
                // Apply once the slider is let go or the typed value is committed, not for
                // every intermediate value.
                let idle = !r.dragged() && !ui.ctx().egui_wants_keyboard_input();
                if idle && *st.radius_edit != scene.particle_radius {
                    out.push(Command::SetParticleRadius(*st.radius_edit));
                }
            }
            None => {
                ui.label(format!("particle radius {} m", scene.particle_radius))
                    .on_hover_text(
                        "Fixed: this scene lists its particles one by one, at one resolution",
                    );
            }
        }

        ui.separator();
        ui.label(egui::RichText::new("Solver").strong());
        let mut solver = scene.solver.clone();
        ui.horizontal(|ui| {
            ui.radio_value(&mut solver.method, Method::Dfsph, "DFSPH");
            ui.radio_value(&mut solver.method, Method::Wcsph, "WCSPH");
        });
        ui.checkbox(&mut solver.divergence_solve, "divergence solve");
        ui.checkbox(&mut solver.warm_start, "warm start");
        ui.add(
            Slider::new(&mut solver.density_tolerance_pct, 0.001..=1.0)
                .logarithmic(true)
                .text("density tol. (avg %)"),
        );
        ui.add(
            Slider::new(&mut solver.divergence_tolerance_pct, 0.01..=10.0)
                .logarithmic(true)
                .text("divergence tol. (avg %/step)"),
        );
        ui.add(Slider::new(&mut solver.min_iterations, 0..=50).text("min iterations"));
        ui.add(
            Slider::new(&mut solver.max_iterations, 1..=1000)
                .logarithmic(true)
                .text("max iterations"),
        );
        solver.max_iterations = solver.max_iterations.max(solver.min_iterations.max(1));
        if solver != scene.solver {
            out.push(Command::Sim(Action::SetSolver { solver }));
        }

        let mut time_step = scene.time_step.clone();
        ui.add(Slider::new(&mut time_step.cfl, 0.05..=1.0).text("CFL factor λ"));
        ui.add(
            Slider::new(&mut time_step.max, 1e-4..=0.02)
                .logarithmic(true)
                .text("max Δt (s)"),
        );
        time_step.min = time_step.min.min(time_step.max);
        if time_step != scene.time_step {
            out.push(Command::Sim(Action::SetTimeStep { time_step }));
        }

        let mut viscosity = scene.viscosity.clone();
        ui.add(Slider::new(&mut viscosity.xsph, 0.0..=0.5).text("XSPH viscosity"));
        ui.add(
            Slider::new(&mut viscosity.kinematic, 0.0..=0.1)
                .logarithmic(true)
                .smallest_positive(1e-7)
                .custom_formatter(sci)
                .custom_parser(|t| t.trim().parse().ok())
                .text("kinematic ν (m²/s)"),
        );
        ui.add(
            Slider::new(&mut viscosity.boundary_kinematic, 0.0..=0.1)
                .logarithmic(true)
                .smallest_positive(1e-7)
                .custom_formatter(sci)
                .custom_parser(|t| t.trim().parse().ok())
                .text("wall ν (m²/s)"),
        );
        if viscosity != scene.viscosity {
            out.push(Command::Sim(Action::SetViscosity { viscosity }));
        }

        ui.separator();
        ui.label(egui::RichText::new("World").strong());
        let mut magnitude = st.mapper.gravity_magnitude();
        let mut tilt = st.mapper.tilt_deg();
        let a = ui.add(Slider::new(&mut magnitude, 0.0..=30.0).text("gravity (m/s²)"));
        let b = ui.add(Slider::new(&mut tilt, -MAX_TILT_DEG..=MAX_TILT_DEG).text("tilt (°)"));
        if a.changed() || b.changed() {
            out.push(Command::Sim(st.mapper.set_gravity(magnitude, tilt)));
        }
        ui.add(
            Slider::new(st.time_scale, 0.05..=2.0)
                .logarithmic(true)
                .text("time scale"),
        );

        ui.separator();
        ui.label(egui::RichText::new("Tools").strong());
        ui.label("left drag / one finger:");
        ui.horizontal_wrapped(|ui| {
            for tool in PrimaryTool::ALL {
                ui.selectable_value(&mut st.mapper.primary_tool, tool, tool.label());
            }
        });
        ui.horizontal(|ui| {
            // Held like the keys A and D (and the only way to shake on a touch screen).
            let left = ui
                .button("◀ shake")
                .on_hover_text("Hold: shake the tank left (A)");
            let right = ui
                .button("shake ▶")
                .on_hover_text("Hold: shake the tank right (D)");
            st.mapper.panel_shake = f32::from(right.is_pointer_button_down_on())
                - f32::from(left.is_pointer_button_down_on());
        });
        let (lo, hi) = st.mapper.radius_limits;
        ui.add(Slider::new(&mut st.mapper.tool_radius, lo..=hi).text("tool radius (m)"));
        ui.add(
            Slider::new(
                &mut st.mapper.pointer_strength,
                1.0..=MAX_POINTER_ACCELERATION,
            )
            .text("push/pull (m/s²)"),
        );

        ui.separator();
        ui.label(egui::RichText::new("Bodies").strong());
        ui.horizontal(|ui| {
            let drop = [
                ("drop box", BodyShape::Box, "B: a box at the cursor"),
                (
                    "drop circle",
                    BodyShape::Circle,
                    "O: a circle at the cursor",
                ),
            ];
            for (label, shape, key) in drop {
                let hint = format!("At the top of the tank's middle ({key}); left drag moves it");
                if ui.button(label).on_hover_text(hint).clicked() {
                    out.push(Command::DropBody { shape, at: None });
                }
            }
        });
        let (lo, hi) = BODY_DENSITY_RANGE;
        ui.add(
            Slider::new(&mut st.mapper.body_density, lo..=hi)
                .logarithmic(true)
                .max_decimals(0)
                .text("next body density (kg/m³)"),
        )
        .on_hover_text(
            "Of the next box or circle dropped; water is 1,000: lighter floats, heavier sinks",
        );
        ui.label(format!(
            "bodies: {} of {MAX_BODIES}",
            sim.rigid_body_count()
        ));
        egui::ComboBox::from_label("colouring")
            .selected_text(st.coloring.label())
            .show_ui(ui, |ui| {
                for c in Coloring::ALL {
                    ui.selectable_value(st.coloring, c, c.label());
                }
            });
        let i = Coloring::ALL
            .iter()
            .position(|c| c == st.coloring)
            .unwrap_or(0);
        color_scale(ui, &mut st.scales[i]);
        let mut dots = *st.look == WaterLook::Particles;
        if ui
            .checkbox(&mut dots, "water as particles (P)")
            .on_hover_text("Off: the water is drawn as one surface; on: one dot per particle")
            .changed()
        {
            *st.look = if dots {
                WaterLook::Particles
            } else {
                WaterLook::Surface
            };
        }
    });
    out
}

/// The colour scale's controls: auto or fixed, and the fixed range's ends.
fn color_scale(ui: &mut egui::Ui, scale: &mut ColorScale) {
    let mut auto = scale.auto;
    ui.checkbox(&mut auto, "auto range")
        .on_hover_text("The colour range follows the data (1st to 99th percentile, smoothed); untick to fix it where it is and edit it");
    if auto != scale.auto {
        scale.set_auto(auto);
    }
    let (mut lo, mut hi) = scale.range;
    let speed = ((hi - lo).abs() * 0.005).max(1e-4);
    ui.horizontal(|ui| {
        ui.add_enabled_ui(!scale.auto, |ui| {
            ui.label("range");
            ui.add(egui::DragValue::new(&mut lo).speed(speed).max_decimals(4));
            ui.label("to");
            ui.add(egui::DragValue::new(&mut hi).speed(speed).max_decimals(4));
        });
    });
    if !scale.auto && (lo, hi) != scale.range {
        // Keep the range the right way round and not empty.
        let hi = if hi > lo { hi } else { lo + speed.max(1e-3) };
        scale.range = (lo, hi);
    }
}

/// Scientific notation for values spanning decades (viscosities).
fn sci(v: f64, _: std::ops::RangeInclusive<usize>) -> String {
    if v == 0.0 {
        "0".into()
    } else {
        format!("{v:.1e}")
    }
}
