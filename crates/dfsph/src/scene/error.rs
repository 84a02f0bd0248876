//! Why a scene is refused, and the checks of single values that name their key.

use super::shapes::Point;

/// Why a scene was rejected. The message names the offending key (`solver.max_iterations`,
/// `fluid[1].max`, ...).
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
pub enum SceneError {
    /// The text is not valid JSON or does not match the schema (wrong type, unknown key).
    #[error("{0}")]
    Parse(String),
    /// A value is of the right type but impossible.
    #[error("`{key}`: {message}")]
    Invalid { key: String, message: String },
    /// The scene is valid but needs more memory than this process may use
    /// ([`crate::memory::MemoryLimits::check`]'s sentence).
    #[error("{0}")]
    Memory(String),
}

pub(crate) fn invalid(key: impl Into<String>, message: impl Into<String>) -> SceneError {
    SceneError::Invalid {
        key: key.into(),
        message: message.into(),
    }
}

/// `v` at `key` is a finite number, in the single precision the solver computes in as well
/// as in the file's double precision: a body's `angle` of 1e39 is finite as read and infinite
/// as used, and it once removed all the water.
pub(crate) fn finite(key: &str, v: f64) -> Result<(), SceneError> {
    if !v.is_finite() {
        Err(invalid(key, format!("must be a finite number, got {v}")))
    } else if !(v as f32).is_finite() {
        Err(invalid(
            key,
            format!(
                "{v} is beyond the solver's single precision (at most {:e} in size)",
                f32::MAX
            ),
        ))
    } else {
        Ok(())
    }
}

/// Both coordinates of `p` at `key` are finite (`key[0]`, `key[1]` in the error).
pub(crate) fn point(key: &str, p: Point) -> Result<(), SceneError> {
    finite(&format!("{key}[0]"), p[0])?;
    finite(&format!("{key}[1]"), p[1])
}
