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

use std::cell::RefCell;
use std::path::PathBuf;
use std::rc::Rc;

use anyhow::anyhow;
use eframe::egui;

pub mod app;
pub mod export;
pub mod hud;
pub mod input;
pub mod panel;
pub mod render;
pub mod stepper;
pub mod video;

/// What to show and how long.
#[derive(Clone, Debug)]
pub struct ViewerOptions {
    /// The scene to run.
    pub scene: dfsph::Scene,
    /// Close the window after this many seconds of wall time.
    pub exit_after: Option<f64>,
    /// When closing because of `exit_after` (and only then), write `particles.csv` (`x,y,vx,vy,density,
    /// pressure`), `screenshot.png` and `session.json` (run statistics and the applied
    /// actions) into this directory.
    pub save_on_exit: Option<PathBuf>,
    /// Record every action with the step at which it applies into this file (JSON lines,
    /// `docs/recording.md`), for `dfsph2d run SCENE --replay FILE`.
    pub record: Option<PathBuf>,
}

impl ViewerOptions {
    /// Show `scene` until the user closes the window.
    pub fn new(scene: dfsph::Scene) -> Self {
        Self {
            scene,
            exit_after: None,
            save_on_exit: None,
            record: None,
        }
    }
}

/// What to tell a user whose machine cannot open the window.
const HEADLESS_HINT: &str = "for headless runs use `dfsph2d run SCENE --until SECONDS --out DIR` \
     (add `--format png` for rendered frames)";

/// Open the viewer window and run until it is closed (or `exit_after` passes).
///
/// Returns an error, without panicking, when there is no display to open a window on or the
/// window or its OpenGL context cannot be created, when the scene is invalid, and when
/// `save_on_exit` files could not be written.
pub fn run(opts: ViewerOptions) -> anyhow::Result<()> {
    check_display()?;
    // Validate before opening a window, for a clear message.
    opts.scene
        .validate()
        .map_err(|e| anyhow!("scene `{}`: {e}", opts.scene.name))?;
    if let Some(t) = opts.exit_after {
        if !(t.is_finite() && t >= 0.0) {
            return Err(anyhow!(
                "--exit-after must be a non-negative number of seconds, got {t}"
            ));
        }
    }
    if let Some(dir) = &opts.save_on_exit {
        std::fs::create_dir_all(dir)
            .map_err(|e| anyhow!("cannot create {}: {e}", dir.display()))?;
    }

    let recorder = match &opts.record {
        Some(path) => Some(app::SessionRecorder::create(path, &opts.scene)?),
        None => None,
    };

    let native = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default()
            .with_title(app::window_title(&opts.scene))
            .with_app_id("dfsph2d")
            .with_inner_size([1280.0, 800.0])
            .with_min_inner_size([480.0, 320.0]),
        renderer: eframe::Renderer::Glow,
        vsync: true,
        ..Default::default()
    };
    let failures: app::Failures = Rc::new(RefCell::new(Vec::new()));
    let app_failures = failures.clone();
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(move || {
        eframe::run_native(
            "dfsph2d",
            native,
            Box::new(move |cc| {
                app::ViewerApp::new(cc, opts, app_failures)
                    .map(|a| a.with_recorder(recorder))
                    .map(|a| Box::new(a) as Box<dyn eframe::App>)
                    .map_err(Into::into)
            }),
        )
    }));
    match result {
        Ok(Ok(())) => {}
        Ok(Err(e)) => {
            return Err(anyhow!(
                "could not open the viewer window: {e}\n{HEADLESS_HINT}"
            ))
        }
        Err(panic) => {
            let msg = panic_message(panic.as_ref());
            return Err(anyhow!("the viewer window failed: {msg}\n{HEADLESS_HINT}"));
        }
    }
    let mut failures = failures.borrow_mut();
    match failures.len() {
        0 => Ok(()),
        1 => Err(failures.remove(0)),
        n => Err(anyhow!("{n} errors, the first: {:#}", failures.remove(0))),
    }
}

/// On Unix desktops a window needs an X11 or Wayland display.
fn check_display() -> anyhow::Result<()> {
    if cfg!(all(unix, not(target_os = "macos"), not(target_os = "ios"))) {
        let set = |k: &str| std::env::var_os(k).is_some_and(|v| !v.is_empty());
        if !set("DISPLAY") && !set("WAYLAND_DISPLAY") {
            return Err(anyhow!(
                "no display: neither DISPLAY nor WAYLAND_DISPLAY is set, so the viewer cannot \
                 open a window.\n{HEADLESS_HINT}"
            ));
        }
    }
    Ok(())
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn no_display_is_a_clear_error_not_a_panic() {
        if cfg!(not(all(unix, not(target_os = "macos")))) {
            return;
        }
        // Only meaningful when this test process has no display itself.
        if std::env::var_os("DISPLAY").is_some() || std::env::var_os("WAYLAND_DISPLAY").is_some() {
            return;
        }
        let err = run(ViewerOptions::new(dfsph::Scene::default())).unwrap_err();
        let msg = format!("{err:#}");
        assert!(msg.contains("dfsph2d run"), "{msg}");
        assert!(msg.contains("DISPLAY"), "{msg}");
    }

    #[test]
    fn panic_message_reads_formatted_static_and_foreign_payloads() {
        let quiet = std::panic::take_hook();
        std::panic::set_hook(Box::new(|_| {}));
        let formatted = std::panic::catch_unwind(|| panic!("step {} failed", 7)).unwrap_err();
        let fixed = std::panic::catch_unwind(|| panic!("no fluid")).unwrap_err();
        let foreign = std::panic::catch_unwind(|| std::panic::panic_any(42u32)).unwrap_err();
        std::panic::set_hook(quiet);
        assert_eq!(panic_message(formatted.as_ref()), "step 7 failed");
        assert_eq!(panic_message(fixed.as_ref()), "no fluid");
        assert_eq!(panic_message(foreign.as_ref()), "unknown panic");
    }
}
