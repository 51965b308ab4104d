//! Library errors. Every variant says *what* went wrong and *where* (file, field, dataset),
//! so the CLI can print it as-is and exit non-zero.

use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// Reading or writing a file failed.
    /// The I/O error is part of the message, not a separate source, so that a chain of
    /// contexts prints it once.
    #[error("{}: {cause}", path.display())]
    Io {
        path: PathBuf,
        cause: std::io::Error,
    },
    /// A file was read but its content is not what it must be (size, header, encoding...).
    #[error("{}: {message}", path.display())]
    Format { path: PathBuf, message: String },
    /// A configuration value is malformed or out of its allowed range.
    /// `source_name` is the file (or `--set`, or the command-line flag) the value came from.
    #[error("{source_name}: field `{field}`: {message}")]
    Config {
        source_name: String,
        field: String,
        message: String,
    },
    /// A dataset name that resolves to nothing.
    #[error("unknown dataset `{name}`; available: {available}")]
    UnknownDataset { name: String, available: String },
    /// Any other invalid request (image size, camera, ...), with what is wrong in the message.
    #[error("{0}")]
    Invalid(String),
}

pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            cause: source,
        }
    }
    pub fn format(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        Error::Format {
            path: path.into(),
            message: message.into(),
        }
    }
    pub fn config(
        source_name: impl Into<String>,
        field: impl Into<String>,
        message: impl Into<String>,
    ) -> Self {
        Error::Config {
            source_name: source_name.into(),
            field: field.into(),
            message: message.into(),
        }
    }

    /// A configuration error re-attributed to the file it was read from (other errors as
    /// they are).
    pub fn with_source(self, source: &str) -> Self {
        match self {
            Error::Config { field, message, .. } => Error::config(source, field, message),
            other => other,
        }
    }
}
