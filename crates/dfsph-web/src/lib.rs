//! # dfsph-web — the dfsph2d viewer in a browser tab
//!
//! The desktop viewer ([`dfsph_viewer`]) compiled to WebAssembly and started on the page's
//! canvas by eframe's web runner, with the solver built serial (the page has one thread).
//! `scripts/build-web.sh OUTDIR` builds the site; `index.html` beside this crate is its page.
//!
//! With the `threads` feature (WebAssembly threads: nightly, atomics; the site's `threads/`)
//! the solver is parallel on rayon's pool of Web Workers and the simulation steps on it: the
//! page first calls [`init_thread_pool`] (`initThreadPool(n)`, wasm-bindgen-rayon's), then
//! [`start`] itself. `index.html` loads that build where the page is cross-origin isolated
//! (served with the COOP/COEP headers SharedArrayBuffer needs), the single-threaded one
//! elsewhere.
//!
//! The page's address may carry a scene (`#scene=NAME` for a built-in one, `#s=...` for a
//! shared one: [`dfsph_viewer::share`]). For tests and scripts the page exposes
//! `window.dfsph2d.state()`: `{particles, time, mean_x, steps, realtime, fps, scene, fitted,
//! threads}`
//! of the last frame drawn, or `null` before the first.
//!
//! On any other target the crate is empty: the host builds it only to run its browser test
//! (`tests/browser.rs`).
#![cfg(target_arch = "wasm32")]

use std::cell::RefCell;
use std::rc::Rc;

use dfsph_viewer::app::{FrameReport, ViewerApp};
use dfsph_viewer::{share, web, ViewerOptions};
use wasm_bindgen::prelude::*;
/// `initThreadPool(n)`: start rayon's pool of `n` Web Workers; the threaded page awaits it
/// before [`start`].
#[cfg(feature = "threads")]
pub use wasm_bindgen_rayon::init_thread_pool;

/// The id of the page's canvas (`index.html`).
const CANVAS_ID: &str = "dfsph2d-canvas";

thread_local! {
    /// What the last frame showed, for [`state`].
    static LAST_FRAME: RefCell<Option<FrameReport>> = const { RefCell::new(None) };
    /// The running viewer (kept alive for the page's lifetime).
    static RUNNER: RefCell<Option<eframe::WebRunner>> = const { RefCell::new(None) };
}

/// Start the viewer on the page's canvas, with the scene the address names (or the default
/// dam break). Called by wasm-bindgen's generated module when it loads; in the threaded
/// build by the page, once the pool is up (the viewer's first frame already uses it).
#[cfg_attr(not(feature = "threads"), wasm_bindgen(start))]
#[cfg_attr(feature = "threads", wasm_bindgen)]
pub fn start() -> Result<(), JsValue> {
    let canvas = web_sys::window()
        .and_then(|w| w.document())
        .and_then(|d| d.get_element_by_id(CANVAS_ID))
        .ok_or_else(|| JsValue::from_str(&format!("the page has no #{CANVAS_ID}")))?
        .dyn_into::<web_sys::HtmlCanvasElement>()?;
    let share::InitialScene {
        scene,
        note,
        fit_to_machine,
    } = share::initial_scene(&web::location_hash());
    let runner = eframe::WebRunner::new();
    RUNNER.with(|r| *r.borrow_mut() = Some(runner.clone()));
    wasm_bindgen_futures::spawn_local(async move {
        let started = runner
            .start(
                canvas,
                eframe::WebOptions::default(),
                Box::new(move |cc| {
                    let failures = Rc::new(RefCell::new(Vec::new()));
                    let options = ViewerOptions {
                        fit_to_machine,
                        ..ViewerOptions::new(scene)
                    };
                    let app = ViewerApp::new(cc, options, failures)?
                        .with_note(note)
                        .on_frame(|report| {
                            LAST_FRAME.with(|last| *last.borrow_mut() = Some(report.clone()));
                        });
                    Ok(Box::new(app) as Box<dyn eframe::App>)
                }),
            )
            .await;
        if let Err(e) = started {
            web_sys::console::error_1(&e);
            show_start_failure(&e);
        }
    });
    Ok(())
}

/// Say on the page why the viewer did not start (no WebGL, most often: Chromium blocklists
/// software GL under a virtual display), in the page's `#loading` box, which index.html has
/// already taken away by then, and in `window.dfsph2d.error` for scripts. Without it the
/// page stayed blank.
fn show_start_failure(error: &JsValue) {
    let reason = error
        .as_string()
        .or_else(|| {
            js_sys::Reflect::get(error, &JsValue::from_str("message"))
                .ok()
                .and_then(|m| m.as_string())
        })
        .unwrap_or_else(|| format!("{error:?}"));
    let text = format!(
        "dfsph2d could not start in this browser: {reason}. It draws with WebGL: turn on \
         hardware acceleration (or WebGL) in the browser's settings, or try a current \
         Chrome, Firefox, Safari or Edge."
    );
    let Some(window) = web_sys::window() else {
        return;
    };
    let Some(document) = window.document() else {
        return;
    };
    let element = document.get_element_by_id(MESSAGE_ID).or_else(|| {
        let element = document.create_element("div").ok()?;
        element.set_id(MESSAGE_ID);
        document.body()?.append_child(&element).ok()?;
        Some(element)
    });
    if let Some(element) = element {
        element.set_text_content(Some(&text));
    }
    if let Some(api) = js_sys::Reflect::get(&window, &JsValue::from_str("dfsph2d"))
        .ok()
        .filter(|api| api.is_object())
    {
        let _ = js_sys::Reflect::set(&api, &JsValue::from_str("error"), &JsValue::from_str(&text));
    }
}

/// The page's message box (index.html styles it over the canvas).
const MESSAGE_ID: &str = "loading";

/// `window.dfsph2d.state()`: the last frame's particles (fluid count), simulated time (s),
/// mean x of the fluid (m), steps taken, real-time factor and frames per second, the
/// scene's name, what fitting the default scene to this machine did (`fitted`: the HUD's
/// line, `null` until it has), and the solver's threads (the pool's size; 1 in the
/// single-threaded build); `null` before the first frame.
#[wasm_bindgen]
pub fn state() -> JsValue {
    LAST_FRAME.with(|last| {
        let last = last.borrow();
        let Some(r) = last.as_ref() else {
            return JsValue::NULL;
        };
        let o = js_sys::Object::new();
        let set = |k: &str, v: JsValue| {
            let _ = js_sys::Reflect::set(&o, &JsValue::from_str(k), &v);
        };
        set("particles", (r.particles as f64).into());
        set("time", r.time.into());
        set("mean_x", r.mean_x.into());
        set("steps", (r.steps as f64).into());
        set("realtime", r.realtime.into());
        set("fps", r.fps.into());
        set("scene", JsValue::from_str(&r.scene));
        set(
            "fitted",
            r.fitted.as_deref().map_or(JsValue::NULL, JsValue::from_str),
        );
        #[cfg(feature = "threads")]
        let threads = rayon::current_num_threads();
        #[cfg(not(feature = "threads"))]
        let threads = 1;
        set("threads", (threads as f64).into());
        o.into()
    })
}
