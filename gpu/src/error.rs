//! The core's error type. Vulkan results become [`GpuError`] in one place,
//! [`vk_error`], so out-of-memory and device loss always surface the same way.

use ash::vk;

/// Everything that can go wrong in the Vulkan core.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
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
    /// A call on a core object that its state or arguments do not allow
    /// (an out-of-range copy, a buffer of another device...).
    #[error("invalid argument: {what}: {why}")]
    InvalidArgument {
        /// The object or argument at fault (a buffer's name, "recording").
        what: String,
        /// What is wrong with it.
        why: String,
    },
}

impl GpuError {
    /// A [`GpuError::InvalidArgument`].
    pub fn invalid(what: impl Into<String>, why: impl Into<String>) -> Self {
        Self::InvalidArgument { what: what.into(), why: why.into() }
    }
}

/// Shorthand for results in the core.
pub type Result<T, E = GpuError> = std::result::Result<T, E>;

/// Maps a failed Vulkan call to a [`GpuError`]; the single place that does so.
pub(crate) fn vk_error(call: &'static str) -> impl FnOnce(vk::Result) -> GpuError {
    move |result| match result {
        vk::Result::ERROR_OUT_OF_HOST_MEMORY => GpuError::OutOfMemory(format!("host memory ({call})")),
        vk::Result::ERROR_OUT_OF_DEVICE_MEMORY => GpuError::OutOfMemory(format!("device memory ({call})")),
        vk::Result::ERROR_DEVICE_LOST => GpuError::DeviceLost(call),
        vk::Result::ERROR_LAYER_NOT_PRESENT => GpuError::MissingComponent(format!(
            "{call}: a requested Vulkan layer is not installed (for validation: the vulkan-validationlayers package)"
        )),
        result => GpuError::Vulkan { call, result },
    }
}
