//! The desktop window: opening it, and one clear error when the machine cannot.

use std::cell::RefCell;
use std::rc::Rc;

use anyhow::anyhow;
use eframe::egui;

use crate::{app, panic_message, ViewerOptions};

/// What to tell a user whose machine cannot open the window.
const HEADLESS_HINT: &str = "for headless runs use `dfsph2d run SCENE --until SECONDS --out DIR` \
     (add `--format png` for rendered frames)";

/// The shared libraries winit and glutin load at run time on Linux, by Debian package: a
/// missing one fails only when the window opens, with a message that names a library file
/// or nothing at all.
const LINUX_PACKAGES_HINT: &str = "on Linux the window needs X11 or Wayland and OpenGL \
     libraries; on Debian/Ubuntu: `apt-get install libxkbcommon-x11-0 libxcursor1 libxrandr2 \
     libxi6 libegl1 libgl1-mesa-dri` (Wayland: `libwayland-client0 libwayland-egl1 \
     libxkbcommon0`)";

/// A panic hook, as `std::panic::take_hook` returns it.
type PanicHook = dyn Fn(&std::panic::PanicHookInfo<'_>) + Sync + Send + 'static;

/// The error for a window that could not be opened: the cause, then what to install and how
/// to run without a window.
fn window_failure(what: &str, cause: &str) -> anyhow::Error {
    let packages = if cfg!(all(unix, not(target_os = "macos"), not(target_os = "ios"))) {
        format!("\n{LINUX_PACKAGES_HINT}")
    } else {
        String::new()
    };
    anyhow!("{what}: {cause}{packages}\n{HEADLESS_HINT}")
}

/// Open the viewer window and run until it is closed (or `exit_after` passes).
///
/// Returns an error, without panicking, when there is no display to open a window on or the
/// window or its OpenGL context cannot be created, when the scene is invalid, and when
/// `save_on_exit` files could not be written.
pub fn run(opts: ViewerOptions) -> anyhow::Result<()> {
    check_display()?;
    crate::threads::limit_software_rasteriser();
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
        ..Default::default()
    };
    let failures: app::Failures = Rc::new(RefCell::new(Vec::new()));
    let app_failures = failures.clone();
    // A panic on this thread while the window is open (a missing system library) becomes the
    // one error below, with its place: the default hook would print it first as a crash
    // report. Other threads' panics (the stepper's) keep the default hook. Put back after.
    let default_hook: std::sync::Arc<PanicHook> = std::panic::take_hook().into();
    let window_thread = std::thread::current().id();
    let panic_place = std::sync::Arc::new(std::sync::Mutex::new(None::<String>));
    {
        let (default_hook, panic_place) = (default_hook.clone(), panic_place.clone());
        std::panic::set_hook(Box::new(move |info| {
            if std::thread::current().id() == window_thread {
                if let Some(at) = info.location() {
                    *panic_place.lock().unwrap_or_else(|e| e.into_inner()) = Some(at.to_string());
                }
            } else {
                default_hook(info);
            }
        }));
    }
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
    std::panic::set_hook(Box::new(move |info| default_hook(info)));
    match result {
        Ok(Ok(())) => {}
        Ok(Err(e)) => {
            return Err(window_failure(
                "could not open the viewer window",
                &e.to_string(),
            ))
        }
        Err(panic) => {
            let msg = panic_message(panic.as_ref());
            let place = panic_place.lock().unwrap_or_else(|e| e.into_inner()).take();
            let cause = match place {
                Some(at) => format!("{msg} (at {at})"),
                None => msg.to_string(),
            };
            return Err(window_failure("the viewer window failed", &cause));
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
    fn a_window_failure_names_the_cause_the_packages_and_the_headless_command() {
        let msg = format!(
            "{:#}",
            window_failure("the viewer window failed", "libxkbcommon-x11.so")
        );
        assert!(msg.starts_with("the viewer window failed: libxkbcommon-x11.so"));
        if cfg!(target_os = "linux") {
            assert!(msg.contains("apt-get install libxkbcommon-x11-0"), "{msg}");
        }
        assert!(msg.contains("dfsph2d run"), "{msg}");
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
