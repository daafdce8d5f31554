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
    /// An argument is outside what the API accepts.
    #[error("invalid argument: {0}")]
    InvalidArgument(String),
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
