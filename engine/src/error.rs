//! The crate's error type. Failures of the Vulkan core arrive whole as
//! [`Error::Gpu`]; everything srug adds (files, scenes, arguments) has its own variant.

use std::path::PathBuf;

use srug_gpu::GpuError;

/// Everything that can go wrong in srug.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The Vulkan core failed: no device, out of memory, device lost, a kernel
    /// that disagrees with its SPIR-V, a missing feature...
    #[error(transparent)]
    Gpu(#[from] GpuError),
    /// An argument is outside what the API accepts: which one, and why.
    #[error("invalid argument: {what}: {why}")]
    InvalidArgument {
        /// The argument or object at fault, as the caller named it (with its value
        /// where that helps: `tile size 12`, `preset "best"`, `camera 3`).
        what: String,
        /// What is wrong with it.
        why: String,
    },
    /// A state srug's own code should never reach: a defect to report, not a bad input.
    #[error("internal error: {0}")]
    Internal(String),
    /// A scene or camera file is malformed.
    #[error(transparent)]
    Scene(#[from] crate::scene::SceneError),
    /// An environment map is malformed or in a form srug cannot use.
    #[error("environment map {origin}: {message}")]
    Environment {
        /// The file (or what the map was made from).
        origin: String,
        /// What is wrong.
        message: String,
    },
    /// A file could not be read or written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The OS error.
        source: std::io::Error,
    },
}

/// Shorthand for results in srug.
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    /// An [`Error::InvalidArgument`]: `what` is at fault, `why`.
    pub fn invalid(what: impl Into<String>, why: impl Into<String>) -> Self {
        Self::InvalidArgument { what: what.into(), why: why.into() }
    }

    /// An [`Error::Gpu`] for a feature the device lacks.
    pub fn unsupported(what: impl Into<String>) -> Self {
        Self::Gpu(GpuError::Unsupported(what.into()))
    }

    /// An [`Error::Io`] for `path`.
    pub fn io(path: impl Into<PathBuf>) -> impl FnOnce(std::io::Error) -> Error {
        let path = path.into();
        move |source| Error::Io { path, source }
    }
}
