//! What a scene's values are checked against and how a bad one is told: a file of its own so
//! that the chain's parameters, checked the same way, do not depend on the scene.

/// Speed of light in vacuum, m/s.
pub const C0: f64 = 299_792_458.0;

/// A scene file or change that cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    #[error("scene file {path}: {message}")]
    Parse { path: String, message: String },
    #[error("scene field `{field}`: {message}")]
    Invalid { field: String, message: String },
    #[error("scene file {path}, line {line}: `{field}`: {message}")]
    Field {
        path: String,
        line: usize,
        field: String,
        message: String,
    },
    #[error("cannot synthesise a capture: {0}")]
    Synthesis(String),
}

pub(super) fn invalid(field: impl Into<String>, message: impl Into<String>) -> SceneError {
    SceneError::Invalid {
        field: field.into(),
        message: message.into(),
    }
}

pub(super) fn finite_in(field: &str, v: f64, lo: f64, hi: f64) -> Result<(), SceneError> {
    if v.is_finite() && v >= lo && v <= hi {
        Ok(())
    } else {
        Err(invalid(
            field,
            format!(
                "{} is outside the allowed range {} ..= {}",
                readable(v),
                readable(lo),
                readable(hi)
            ),
        ))
    }
}

/// A number as a person writes it: `1e300`, not three hundred digits.
fn readable(v: f64) -> String {
    let magnitude = v.abs();
    if magnitude != 0.0 && !(1e-3..1e6).contains(&magnitude) {
        format!("{v:e}")
    } else {
        v.to_string()
    }
}
