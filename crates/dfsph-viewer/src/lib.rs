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

pub mod app;
pub mod bodies;
pub mod export;
pub mod file_names;
pub mod hud;
pub mod input;
mod options;
pub mod panel;
mod panic_message;
pub mod render;
pub mod resolution;
pub mod scene_file;
pub mod share;
pub mod stepper;
#[cfg(not(target_arch = "wasm32"))]
pub mod threads;
pub mod ticks;
pub mod undo;
pub mod video;
pub mod view;
#[cfg(target_arch = "wasm32")]
pub mod web;
#[cfg(not(target_arch = "wasm32"))]
mod window;

pub use options::ViewerOptions;
pub use panic_message::panic_message;
#[cfg(not(target_arch = "wasm32"))]
pub use window::run;
