//! srug-gpu: the Vulkan compute core of srug — device, memory, kernels,
//! recording and timing. It knows no Gaussian, scene, camera or shading type;
//! the renderer (`srug`) is built on it.
//!
//! # Contract
//! - **Safety.** All `unsafe` Vulkan calls live here. Public types are safe to
//!   use in any order: every object holds the device alive, and destruction of
//!   buffers, pipelines and per-recording objects is deferred until the GPU has
//!   finished every submission made before the drop.
//! - **Errors.** Vulkan results become [`GpuError`] in one place
//!   (`error::vk_error`); out-of-memory and device loss have their own variants.
//! - **Synchronization.** Each recorded command is preceded by a global memory
//!   barrier; each recording ends with a barrier toward host reads.
//! - **Validation.** With [`DeviceOptions::validation`] (or `SRUG_VALIDATION=1`)
//!   the Khronos layer runs with synchronization validation and every warning
//!   or error it emits is kept for [`Device::take_validation_messages`].
//! - **Host images.** On a host's device, [`HostImage`]s are copied to and
//!   from with layout barriers scoped to every stage, and submissions wait on
//!   and signal the host's semaphores ([`HostSync`], [`Device::submit_synced`]).
//! - **Large buffers.** Descriptor bindings are limited to
//!   `maxStorageBufferRange` (128 MiB on lavapipe); larger data is reached by
//!   device address (`shaders/include/address.glsl`).
//! - **Texel buffers.** A kernel may read a buffer through a `textureBuffer`
//!   ([`Texels`], bound with [`Recording::dispatch`]); the recording makes
//!   the view and checks `maxTexelBufferElements` and the offset alignment.
//!   On lavapipe a `texelFetch` with per-lane indices is a vector gather, while
//!   storage-buffer and device-address loads run lane by lane.
//!
//! - **Device addresses.** A kernel that reaches a buffer by address gets the
//!   address from [`Recording::addr`], which keeps the buffer borrowed until
//!   the recording is submitted; host structs that carry addresses use
//!   [`DeviceAddress`] fields and check their layout against the GLSL block
//!   ([`GpuLayout`], [`check_layout`]).
//!
//! # Module graph (no cycles)
//! `error`, `format`, `info`, `layout` and `sync` are leaves; `shared` (instance, device,
//! allocator, garbage of raw handles) imports only those; `device`, `buffer`,
//! `kernel` and `recording` import `shared` and the leaves, and `recording`
//! also imports `buffer`, `kernel` and `sync`; `host_image` (the host's
//! images) imports `buffer`, `device` and `recording`; `image` (images on
//! srug's own device) and `export` (images and semaphores exported as fds)
//! import `shared`, `device` and `host_image`, and `export` also `image`.

mod buffer;
mod device;
mod error;
mod export;
mod format;
mod host_image;
mod image;
mod info;
mod kernel;
mod layout;
mod recording;
pub mod selftest;
mod shared;
mod sync;

/// The Vulkan result a failed call returned (in [`GpuError::Vulkan`]).
/// The `ash` srug is built with: a host passing its own device ([`Device::from_raw`]) uses these types.
pub use ash;
pub use ash::vk::Result as VkResult;
pub use buffer::{Buffer, MemoryKind, Texels};
pub use device::{Device, DeviceOptions, DeviceSelection, EnabledFeatures, RawVulkan, DEVICE_ENV, VALIDATION_ENV};
pub use error::{GpuError, Result};
pub use export::{ExportedImage, ExportedImageInfo, ExportedSemaphore};
pub use format::TexelFormat;
pub use host_image::{HostBuffer, HostImage, HostImageAccess, HostImageFormat};
pub use image::DeviceImage;
pub use info::{AdapterSummary, DeviceInfo, MemoryUsage};
pub use kernel::{check_decl, full_subgroup_flags, specialized_workgroup_size, Kernel, KernelDecl, SpecValue};
pub use layout::{check_block, check_layout, DeviceAddress, GpuLayout};
pub use recording::{grid_1d, Binding, Grid, Recording, StageTime, Submission, Timings};
pub use shared::POOL_HEADROOM_BYTES;
pub use srug_spirv::{kernels, BindingInfo, BindingKind, BlockInfo, KernelInfo, MemberInfo, SpecConstantInfo};
pub use sync::{HostSync, SemaphoreSignal, SemaphoreWait};
