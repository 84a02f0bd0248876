//! The text of a caught panic, for the viewer's messages and `dfsph2d stress`.

/// The text of a caught panic (`std::panic::catch_unwind`'s payload): panics raised with a
/// message carry a `String` or a `&str`; anything else is reported as "unknown panic".
pub fn panic_message(payload: &(dyn std::any::Any + Send)) -> &str {
    payload
        .downcast_ref::<String>()
        .map(String::as_str)
        .or_else(|| payload.downcast_ref::<&str>().copied())
        .unwrap_or("unknown panic")
}
