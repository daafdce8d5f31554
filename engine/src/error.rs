//! The crate's error type. Vulkan results are mapped to it in one place,
//! `vk_error`, so out-of-memory and device loss always surface the same way.

use std::path::PathBuf;

use ash::vk;

/// Everything that can go wrong in srug.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The Vulkan loader library could not be opened.
    #[error("cannot load the Vulkan loader (install libvulkan1 and a driver such as mesa-vulkan-drivers): {0}")]
    Loader(String),
    /// A required instance layer or extension is not installed.
    #[error("{0}")]
    MissingComponent(String),
    /// No Vulkan device matched the selection, or none is usable.
    #[error("no usable Vulkan device: {0}")]
    NoDevice(String),
    /// A Vulkan call failed with a result other than the ones below.
    #[error("Vulkan call {call} failed: {result}")]
    Vulkan {
        /// The Vulkan entry point.
        call: &'static str,
        /// What it returned.
        result: vk::Result,
    },
    /// Host or device memory ran out.
    #[error("out of memory: {0}")]
    OutOfMemory(String),
    /// The device was lost (driver crash, reset, or a hung kernel).
    #[error("the GPU device was lost during {0}")]
    DeviceLost(&'static str),
    /// A kernel's Rust declaration disagrees with its SPIR-V, or is misused.
    #[error("kernel {kernel}: {message}")]
    Kernel {
        /// The kernel's name in the SPIR-V table.
        kernel: &'static str,
        /// What disagrees.
        message: String,
    },
    /// The device lacks a feature an operation needs.
    #[error("unsupported on this device: {0}")]
    Unsupported(String),
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

/// Maps a failed Vulkan call to an [`Error`]; the single place that does so.
pub(crate) fn vk_error(call: &'static str) -> impl FnOnce(vk::Result) -> Error {
    move |result| match result {
        vk::Result::ERROR_OUT_OF_HOST_MEMORY => Error::OutOfMemory(format!("host memory ({call})")),
        vk::Result::ERROR_OUT_OF_DEVICE_MEMORY => Error::OutOfMemory(format!("device memory ({call})")),
        vk::Result::ERROR_DEVICE_LOST => Error::DeviceLost(call),
        vk::Result::ERROR_LAYER_NOT_PRESENT => Error::MissingComponent(format!(
            "{call}: a requested Vulkan layer is not installed (for validation: the vulkan-validationlayers package)"
        )),
        result => Error::Vulkan { call, result },
    }
}

impl Error {
    /// An [`Error::Io`] for `path`.
    pub fn io(path: impl Into<PathBuf>) -> impl FnOnce(std::io::Error) -> Error {
        let path = path.into();
        move |source| Error::Io { path, source }
    }
}
