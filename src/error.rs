//! The library's error type: every way an input can be invalid or a device can fail.

use std::path::PathBuf;

/// Everything that can go wrong in matedit, each variant with a message that names the
/// offending item.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// An input (normals, environment map, material, camera, upstream gradient) is invalid.
    /// The string names the input and the item, e.g. `normals: pixel (12, 40) is NaN`.
    #[error("{}", one_line(.0))]
    Invalid(String),

    /// The inputs of a batch disagree with each other (sizes, camera, convention).
    #[error("batch: {}", one_line(.0))]
    Batch(String),

    /// No GPU adapter could be found.
    #[error(
        "no GPU adapter found{detail}; install a Vulkan driver (on Debian/Ubuntu: \
         `apt-get install mesa-vulkan-drivers libvulkan1`), or use the CPU with --device cpu"
    )]
    NoAdapter {
        /// Extra context, e.g. which WGPU_BACKEND / WGPU_ADAPTER_NAME filter was applied.
        detail: String,
    },

    /// The GPU device failed (request, out of memory, lost device, readback).
    #[error("GPU: {0}")]
    Gpu(String),

    /// A file could not be read, written or understood. The message names the file, the
    /// item and what is wrong.
    #[error("{}: {}", one_line(&path.display().to_string()), one_line(message))]
    File {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        message: String,
    },
}

impl Error {
    /// An [`Error::File`] for `path` with `message`.
    pub fn file(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        Error::File {
            path: path.into(),
            message: message.into(),
        }
    }

    /// Whether the error is the user's input (exit code 2) rather than a runtime failure
    /// (exit code 1).
    pub fn is_input_error(&self) -> bool {
        matches!(
            self,
            Error::Invalid(_) | Error::Batch(_) | Error::File { .. }
        )
    }
}

/// `s` with its control characters escaped (a newline as `\n`), so that a message quoting
/// the user's text (a key of a JSON file, a file name) stays one line.
pub fn one_line(s: &str) -> std::borrow::Cow<'_, str> {
    if !s.chars().any(char::is_control) {
        return s.into();
    }
    s.chars()
        .map(|c| {
            if c.is_control() {
                c.escape_default().to_string()
            } else {
                c.to_string()
            }
        })
        .collect::<String>()
        .into()
}

/// `Result` with [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Shorthand for an [`Error::Invalid`] built with `format!`.
macro_rules! invalid {
    ($($arg:tt)*) => { $crate::error::Error::Invalid(format!($($arg)*)) };
}
pub(crate) use invalid;
