//! What the page does where the desktop window uses the file system: files are downloaded
//! (a saved scene, a screenshot), a scene is opened with the browser's file picker, and the
//! address bar carries a shared scene ([`crate::share`]).

use std::cell::RefCell;
use std::rc::Rc;

use wasm_bindgen::prelude::*;

/// Hand `bytes` to the browser as a download named `name`.
pub fn download(name: &str, mime: &str, bytes: &[u8]) -> Result<(), String> {
    let js = |e: JsValue| format!("{e:?}");
    let window = web_sys::window().ok_or("no window")?;
    let document = window.document().ok_or("no document")?;
    let parts = js_sys::Array::of1(&js_sys::Uint8Array::from(bytes));
    let options = web_sys::BlobPropertyBag::new();
    options.set_type(mime);
    let blob =
        web_sys::Blob::new_with_u8_array_sequence_and_options(&parts, &options).map_err(js)?;
    let url = web_sys::Url::create_object_url_with_blob(&blob).map_err(js)?;
    let a: web_sys::HtmlAnchorElement = document
        .create_element("a")
        .map_err(js)?
        .dyn_into()
        .map_err(|_| "not an anchor")?;
    a.set_href(&url);
    a.set_download(name);
    a.click();
    web_sys::Url::revoke_object_url(&url).map_err(js)?;
    Ok(())
}

/// A file the user picked: its name and text, or why it could not be read.
pub type Picked = (String, Result<String, String>);

/// The browser's file picker for scene files; what was picked arrives in a later frame
/// ([`Self::take`]).
#[derive(Default)]
pub struct FilePicker {
    picked: Rc<RefCell<Vec<Picked>>>,
}

impl FilePicker {
    /// Show the picker (`.json` files).
    pub fn open(&self) -> Result<(), String> {
        let js = |e: JsValue| format!("{e:?}");
        let document = web_sys::window()
            .and_then(|w| w.document())
            .ok_or("no document")?;
        let input: web_sys::HtmlInputElement = document
            .create_element("input")
            .map_err(js)?
            .dyn_into()
            .map_err(|_| "not an input")?;
        input.set_type("file");
        input.set_accept(".json,application/json");
        let picked = self.picked.clone();
        let chosen = input.clone();
        let on_change = Closure::once(move || {
            let Some(file) = chosen.files().and_then(|f| f.get(0)) else {
                return;
            };
            let name = file.name();
            wasm_bindgen_futures::spawn_local(async move {
                let text = wasm_bindgen_futures::JsFuture::from(file.text())
                    .await
                    .map(|t| t.as_string().unwrap_or_default())
                    .map_err(|e| format!("{e:?}"));
                picked.borrow_mut().push((name, text));
            });
        });
        input.set_onchange(Some(on_change.as_ref().unchecked_ref()));
        // The input lives as long as the page may call it back.
        on_change.forget();
        input.click();
        Ok(())
    }

    /// The files picked since the last call.
    pub fn take(&self) -> Vec<Picked> {
        std::mem::take(&mut *self.picked.borrow_mut())
    }
}

/// The part of the address after `#`, without it.
pub fn location_hash() -> String {
    web_sys::window()
        .and_then(|w| w.location().hash().ok())
        .map(|h| h.trim_start_matches('#').to_string())
        .unwrap_or_default()
}

/// Put `fragment` after `#` in the address bar without reloading or adding to the history;
/// returns the whole address.
pub fn set_location_hash(fragment: &str) -> Option<String> {
    let window = web_sys::window()?;
    let location = window.location();
    let base = format!(
        "{}{}{}",
        location.origin().ok()?,
        location.pathname().ok()?,
        location.search().ok()?
    );
    let url = format!("{base}#{fragment}");
    window
        .history()
        .ok()?
        .replace_state_with_url(&JsValue::NULL, "", Some(&url))
        .ok()?;
    Some(url)
}
