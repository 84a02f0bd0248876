//! # dfsph-viewer — the interactive window of `dfsph2d`
//!
//! An eframe/egui (glow) window that runs a [`dfsph::Simulation`] in real time and lets the
//! user play with it: shake the tank, tilt gravity, push, pull, pour, draw walls, erase, and
//! change every solver parameter live, with a HUD, live plots and a colour legend.
//!
//! The viewer only uses the solver's public API: input becomes [`dfsph::Action`]s applied
//! between steps ([`input`]); the simulation steps on its own thread, on the wall clock, while
//! each frame is drawn ([`stepper`]). All particles are drawn as one textured mesh
//! ([`render`]).
//!
//! ```no_run
//! let scene = dfsph::scene::builtin("dam-break").unwrap();
//! dfsph_viewer::run(dfsph_viewer::ViewerOptions::new(scene)).unwrap();
//! ```

use std::path::PathBuf;

pub mod app;
pub mod bodies;
pub mod export;
pub mod hud;
pub mod input;
pub mod panel;
pub mod render;
pub mod resolution;
pub mod scene_file;
pub mod share;
pub mod stepper;
#[cfg(not(target_arch = "wasm32"))]
pub mod threads;
pub mod undo;
pub mod video;
pub mod view;
#[cfg(target_arch = "wasm32")]
pub mod web;
#[cfg(not(target_arch = "wasm32"))]
mod window;

#[cfg(not(target_arch = "wasm32"))]
pub use window::run;

/// What to show and how long.
#[derive(Clone, Debug)]
pub struct ViewerOptions {
    /// The scene to run.
    pub scene: dfsph::Scene,
    /// Close the window after this many seconds of wall time.
    pub exit_after: Option<f64>,
    /// When closing because of `exit_after` (and only then), write `particles.csv` (`x,y,vx,vy,density,
    /// pressure`), `screenshot.png`, `session.json` (run statistics and the applied
    /// actions) and `scene.json` (the state as a scene that `run` and `view` load) into this
    /// directory.
    pub save_on_exit: Option<PathBuf>,
    /// Record every action with the step at which it applies into this file (JSON lines,
    /// `docs/recording.md`), for `dfsph2d run SCENE --replay FILE`.
    pub record: Option<PathBuf>,
    /// Fit the scene's particle size to this machine's speed in the first seconds
    /// ([`resolution`]): for the built-in scene the window opens with when none is named;
    /// a scene the user names keeps its resolution.
    pub fit_to_machine: bool,
    /// The file the scene was read from (`view FILE`): the scene list names it, as after
    /// Open, rather than the scene's own `name`. `None` for a built-in scene.
    pub scene_file: Option<String>,
}

impl ViewerOptions {
    /// Show `scene` until the user closes the window.
    pub fn new(scene: dfsph::Scene) -> Self {
        Self {
            scene,
            exit_after: None,
            save_on_exit: None,
            record: None,
            fit_to_machine: false,
            scene_file: None,
        }
    }
}

/// The text of a caught panic (`std::panic::catch_unwind`'s payload): panics raised with a
/// message carry a `String` or a `&str`; anything else is reported as "unknown panic".
pub fn panic_message(payload: &(dyn std::any::Any + Send)) -> &str {
    payload
        .downcast_ref::<String>()
        .map(String::as_str)
        .or_else(|| payload.downcast_ref::<&str>().copied())
        .unwrap_or("unknown panic")
}
