//! Library error type. Every variant names the file, field or limit involved and,
//! where there is one, the fix.

use std::path::PathBuf;

/// Errors from loading, validating and rendering.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file could not be opened, read or written. The I/O error is part of the message and
    /// deliberately not a `source()`: error chains (`anyhow`'s `{:#}`) would print it twice.
    #[error("{}: {err}", path.display())]
    Io { path: PathBuf, err: std::io::Error },
    /// A file was read but its contents are not what the format requires.
    #[error("{}: {msg}", path.display())]
    Format { path: PathBuf, msg: String },
    /// A scene or configuration value is missing, out of range or inconsistent.
    #[error("{field}: {msg}")]
    Invalid { field: String, msg: String },
    /// Data does not fit the adapter (or a fixed format limit).
    #[error("{what} exceeds the limit: {msg}")]
    Limit { what: String, msg: String },
    /// Anything wgpu reported: no adapter, device lost, validation failure.
    #[error("GPU: {0}")]
    Gpu(String),
}

/// Library result alias.
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    pub(crate) fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            err: source,
        }
    }
    pub(crate) fn format(path: impl Into<PathBuf>, msg: impl Into<String>) -> Self {
        Error::Format {
            path: path.into(),
            msg: msg.into(),
        }
    }
    pub(crate) fn invalid(field: impl Into<String>, msg: impl Into<String>) -> Self {
        Error::Invalid {
            field: field.into(),
            msg: msg.into(),
        }
    }
}

/// `Ok` when every value is finite; the error names `field`.
pub(crate) fn check_finite(field: &str, v: &[f64]) -> Result<()> {
    if v.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(Error::invalid(
            field,
            format!("must be finite numbers, got {v:?}"),
        ))
    }
}
