//! Contexts: a device (choice, validation), its memory and validation messages.

use std::ffi::{c_char, c_void};
use std::sync::Arc;

use srug::gpu::ash::{self, vk, vk::Handle};
use srug::gpu::{Device, DeviceOptions, DeviceSelection, EnabledFeatures, RawVulkan};

use crate::ffi::*;
use crate::handle::{self, id_of, ptr_of, Object};
use crate::{guard, srug_status, Failure, FfiResult};

/// A Vulkan device and everything made on it. Thread-safe.
pub struct srug_context {
    _private: [u8; 0],
}

/// `srug_context_create` flag: run the Khronos validation layer (with
/// synchronization validation); its messages are counted by
/// `srug_context_take_validation_messages`.
pub const SRUG_CONTEXT_VALIDATION: u32 = 1;

/// The object behind a context handle.
pub(crate) struct Context {
    pub(crate) device: Device,
}

pub(crate) fn context(p: *const srug_context) -> FfiResult<(u64, Arc<Context>)> {
    let id = id_of(p)?;
    match handle::get(id, "context")? {
        (Object::Context(c), _) => Ok((id, c)),
        _ => Err(Failure::new(srug_status::SRUG_ERROR_INVALID_HANDLE, "not a context")),
    }
}

/// Opens a Vulkan device. `device` selects it: NULL or "" for automatic (a GPU
/// when there is one, else a CPU device such as lavapipe; the `SRUG_DEVICE`
/// environment variable applies), "gpu", "cpu", an index from `srug devices`, or
/// part of a device name. `flags`: 0 or `SRUG_CONTEXT_VALIDATION` (with 0 the
/// `SRUG_VALIDATION` environment variable decides).
///
/// # Safety
/// `device` NULL or a NUL-terminated string; `out` valid for one write.
#[no_mangle]
pub unsafe extern "C" fn srug_context_create(
    device: *const c_char,
    flags: u32,
    out: *mut *mut srug_context,
) -> srug_status {
    guard("srug_context_create", || {
        check_out(out, "out")?;
        if flags & !SRUG_CONTEXT_VALIDATION != 0 {
            return Err(invalid(format!("unknown flags {flags:#x}")));
        }
        let selection = if device.is_null() {
            None
        } else {
            // SAFETY: the caller's contract.
            let t = unsafe { text(device, "device") }?;
            (!t.trim().is_empty()).then(|| DeviceSelection::parse(t))
        };
        let validation = (flags & SRUG_CONTEXT_VALIDATION != 0).then_some(true);
        let device = Device::new(&DeviceOptions { selection, validation })?;
        let id = handle::insert(Object::Context(Arc::new(Context { device })), 0);
        // SAFETY: checked non-null above; the caller's contract.
        unsafe { write_out(out, "out", ptr_of(id)) }
    })
}

/// `srug_vulkan_device::enabled_features` bit: `bufferDeviceAddress` (required).
pub const SRUG_VULKAN_FEATURE_BUFFER_DEVICE_ADDRESS: u32 = 1;
/// `srug_vulkan_device::enabled_features` bit: `shaderInt64` (required).
pub const SRUG_VULKAN_FEATURE_SHADER_INT64: u32 = 2;
/// `srug_vulkan_device::enabled_features` bit: `shaderInt16`.
pub const SRUG_VULKAN_FEATURE_SHADER_INT16: u32 = 4;
/// `srug_vulkan_device::enabled_features` bit: `shaderFloat16`.
pub const SRUG_VULKAN_FEATURE_SHADER_FLOAT16: u32 = 8;
/// `srug_vulkan_device::enabled_features` bit: `storageBuffer16BitAccess`.
pub const SRUG_VULKAN_FEATURE_STORAGE_BUFFER_16BIT_ACCESS: u32 = 16;
/// `srug_vulkan_device::enabled_features` bit: `computeFullSubgroups`
/// (`VK_EXT_subgroup_size_control` or Vulkan 1.3), which GPUs' sort block
/// digits need (without it srug sorts with 4-bit digits).
pub const SRUG_VULKAN_FEATURE_COMPUTE_FULL_SUBGROUPS: u32 = 32;

/// A host application's Vulkan device for `srug_context_create_from_vulkan`
/// (handles as `void *`, so this header needs no `vulkan.h`).
#[repr(C)]
pub struct srug_vulkan_device {
    /// `VkInstance` (Vulkan 1.2 or newer).
    pub instance: *mut c_void,
    /// `VkPhysicalDevice` the device was created on.
    pub physical_device: *mut c_void,
    /// `VkDevice`.
    pub device: *mut c_void,
    /// A queue family of the device with compute.
    pub queue_family: u32,
    /// The queue of that family srug submits to (see `srug_context_create_from_vulkan`):
    /// below the `queueCount` the host created that family with (Vulkan cannot tell
    /// srug that count; srug checks the family's own `queueCount`).
    pub queue_index: u32,
    /// `PFN_vkGetInstanceProcAddr` the host loaded Vulkan with; NULL: the system loader's.
    pub get_instance_proc_addr: *mut c_void,
    /// `SRUG_VULKAN_FEATURE_*` bits: the features the host enabled on the device.
    pub enabled_features: u32,
}

/// Makes a context on a host application's Vulkan device instead of opening
/// one: srug allocates its own memory there, submits to the given queue,
/// and destroys only what it created (the host keeps owning the instance,
/// device and queue, and must keep them alive until the context is
/// destroyed). Needs Vulkan 1.2 and `bufferDeviceAddress` and `shaderInt64`
/// enabled (`SRUG_ERROR_NO_DEVICE` naming what is missing). srug locks the
/// queue around its own submissions; the host must not submit to the same
/// queue concurrently, and every srug call has finished its GPU work when it
/// returns. `flags`: 0 or `SRUG_CONTEXT_VALIDATION`, which adds a debug
/// messenger to the host's instance (needs `VK_EXT_debug_utils` enabled on it)
/// for `srug_context_take_validation_messages`. Destroying the context leaves
/// the host's device working.
///
/// # Safety
/// `vulkan` NULL or valid for reads, its handles valid and belonging together
/// as described; `out` valid for one write.
#[no_mangle]
pub unsafe extern "C" fn srug_context_create_from_vulkan(
    vulkan: *const srug_vulkan_device,
    flags: u32,
    out: *mut *mut srug_context,
) -> srug_status {
    guard("srug_context_create_from_vulkan", || {
        check_out(out, "out")?;
        if vulkan.is_null() {
            return Err(Failure::new(srug_status::SRUG_ERROR_NULL_POINTER, "vulkan is NULL"));
        }
        if flags & !SRUG_CONTEXT_VALIDATION != 0 {
            return Err(invalid(format!("unknown flags {flags:#x}")));
        }
        // SAFETY: non-null, and the caller's contract.
        let v = unsafe { &*vulkan };
        for (p, name) in [(v.instance, "instance"), (v.physical_device, "physical_device"), (v.device, "device")] {
            if p.is_null() {
                return Err(Failure::new(srug_status::SRUG_ERROR_NULL_POINTER, format!("vulkan->{name} is NULL")));
            }
        }
        let known = 63;
        if v.enabled_features & !known != 0 {
            return Err(invalid(format!("unknown feature bits {:#x}", v.enabled_features & !known)));
        }
        let entry = if v.get_instance_proc_addr.is_null() {
            // SAFETY: loading the system Vulkan loader.
            unsafe { ash::Entry::load() }.map_err(|e| srug::Error::from(srug::gpu::GpuError::Loader(e.to_string())))?
        } else {
            // SAFETY: the caller passes its PFN_vkGetInstanceProcAddr, a function of this signature.
            let gipa: vk::PFN_vkGetInstanceProcAddr = unsafe { std::mem::transmute(v.get_instance_proc_addr) };
            // SAFETY: the static function table of a working loader entry point.
            unsafe { ash::Entry::from_static_fn(ash::StaticFn { get_instance_proc_addr: gipa }) }
        };
        let instance_handle = vk::Instance::from_raw(v.instance as u64);
        // SAFETY: the caller's valid instance, loaded through its entry point.
        let instance = unsafe { ash::Instance::load(entry.static_fn(), instance_handle) };
        // SAFETY: the caller's valid device of that instance.
        let device = unsafe { ash::Device::load(instance.fp_v1_0(), vk::Device::from_raw(v.device as u64)) };
        let bit = |b: u32| v.enabled_features & b != 0;
        let raw = RawVulkan {
            entry,
            instance,
            physical_device: vk::PhysicalDevice::from_raw(v.physical_device as u64),
            device,
            queue_family: v.queue_family,
            queue_index: v.queue_index,
            enabled: EnabledFeatures {
                buffer_device_address: bit(SRUG_VULKAN_FEATURE_BUFFER_DEVICE_ADDRESS),
                shader_int64: bit(SRUG_VULKAN_FEATURE_SHADER_INT64),
                shader_int16: bit(SRUG_VULKAN_FEATURE_SHADER_INT16),
                shader_float16: bit(SRUG_VULKAN_FEATURE_SHADER_FLOAT16),
                storage_buffer_16bit_access: bit(SRUG_VULKAN_FEATURE_STORAGE_BUFFER_16BIT_ACCESS),
                compute_full_subgroups: bit(SRUG_VULKAN_FEATURE_COMPUTE_FULL_SUBGROUPS),
            },
            validation_messages: flags & SRUG_CONTEXT_VALIDATION != 0,
        };
        // SAFETY: the caller's contract covers the handles.
        let device = unsafe { Device::from_raw(raw) }?;
        let id = handle::insert(Object::Context(Arc::new(Context { device })), 0);
        // SAFETY: checked non-null above; the caller's contract.
        unsafe { write_out(out, "out", ptr_of(id)) }
    })
}

/// Destroys a context. Fails with `SRUG_ERROR_WRONG_ORDER` while scenes,
/// environments or renderers made on it are alive. NULL is accepted and ignored.
///
/// # Safety
/// Any pointer value is accepted; it is never dereferenced.
#[no_mangle]
pub unsafe extern "C" fn srug_context_destroy(ctx: *mut srug_context) -> srug_status {
    guard("srug_context_destroy", || {
        if ctx.is_null() {
            return Ok(());
        }
        handle::remove(id_of(ctx)?, "context")
    })
}

/// The device's name (e.g. "llvmpipe (LLVM 15.0.6, 256 bits)"), copied like
/// `srug_last_error` copies its message.
///
/// # Safety
/// `buf` valid for `len` bytes (or NULL with `len` 0); `written` NULL or valid for one write.
#[no_mangle]
pub unsafe extern "C" fn srug_context_device_name(
    ctx: *const srug_context,
    buf: *mut c_char,
    len: usize,
    written: *mut usize,
) -> srug_status {
    guard("srug_context_device_name", || {
        let (_, c) = context(ctx)?;
        // SAFETY: the caller's contract.
        unsafe { copy_text(&c.device.info().name, buf, len, written) }
    })
}

/// GPU memory the context's objects hold now and at most since its creation, in bytes
/// (buffers kept for reuse not counted: `srug_context_memory_pool`).
///
/// # Safety
/// `current` and `peak` each NULL or valid for one write (at least one non-NULL).
#[no_mangle]
pub unsafe extern "C" fn srug_context_memory(
    ctx: *const srug_context,
    current: *mut u64,
    peak: *mut u64,
) -> srug_status {
    guard("srug_context_memory", || {
        let (_, c) = context(ctx)?;
        let m = c.device.memory_usage();
        // SAFETY: each NULL or valid for one write; the caller's contract.
        unsafe { write_either([("current", current, m.current_bytes), ("peak", peak, m.peak_bytes)]) }
    })
}

/// Writes each value whose pointer is not NULL; all NULL is an error naming them.
///
/// # Safety
/// Each pointer NULL or valid for one write.
unsafe fn write_either<const N: usize>(outs: [(&str, *mut u64, u64); N]) -> FfiResult {
    if outs.iter().all(|o| o.1.is_null()) {
        let names: Vec<&str> = outs.iter().map(|o| o.0).collect();
        return Err(null(&format!("all of {}", names.join(" and "))));
    }
    for (_, out, value) in outs {
        if !out.is_null() {
            // SAFETY: non-null; the caller's contract.
            unsafe { out.write(value) };
        }
    }
    Ok(())
}

/// Freed buffers srug keeps for reuse (not in `srug_context_memory`'s
/// `current`) into `pooled`, and into `fresh` how many of its allocations
/// since the context was made took new memory rather than a kept buffer
/// (steady frames take few or none). srug keeps at most an eighth of the
/// device's largest device-local heap (256 MiB to 4 GiB), and never so much
/// that in use and kept would pass the most it ever had in use at once
/// (staging buffers: 32 MiB more): a new allocation frees the oldest first.
///
/// # Safety
/// `pooled` and `fresh` each NULL or valid for one write (at least one non-NULL).
#[no_mangle]
pub unsafe extern "C" fn srug_context_memory_pool(
    ctx: *const srug_context,
    pooled: *mut u64,
    fresh: *mut u64,
) -> srug_status {
    guard("srug_context_memory_pool", || {
        let (_, c) = context(ctx)?;
        let m = c.device.memory_usage();
        // SAFETY: each NULL or valid for one write; the caller's contract.
        unsafe { write_either([("pooled", pooled, m.pooled_bytes), ("fresh", fresh, m.fresh_allocations)]) }
    })
}

/// Frees the buffers srug keeps for reuse (`srug_context_memory_pool`; srug
/// also frees them itself when one of its own allocations finds no memory or
/// would pass the most it ever had in use): for a host that wants that memory
/// back now. The bytes released go into `released` where it is not NULL.
///
/// # Safety
/// `ctx` a live context; `released` NULL or valid for one write.
#[no_mangle]
pub unsafe extern "C" fn srug_context_release_pooled_memory(
    ctx: *const srug_context,
    released: *mut u64,
) -> srug_status {
    guard("srug_context_release_pooled_memory", || {
        let (_, c) = context(ctx)?;
        let bytes = c.device.release_pooled_memory();
        if !released.is_null() {
            // SAFETY: non-null; the caller's contract.
            unsafe { released.write(bytes) };
        }
        Ok(())
    })
}

/// Takes the validation messages collected since the last call: their number
/// into `count`, and the messages (one per line) into `buf` like
/// `srug_last_error` copies text (`buf` may be NULL with `len` 0). Without
/// validation the count is always 0.
///
/// # Safety
/// `count` valid for one write; `buf` valid for `len` bytes or NULL with `len` 0.
#[no_mangle]
pub unsafe extern "C" fn srug_context_take_validation_messages(
    ctx: *const srug_context,
    count: *mut usize,
    buf: *mut c_char,
    len: usize,
) -> srug_status {
    guard("srug_context_take_validation_messages", || {
        let (_, c) = context(ctx)?;
        check_out(count, "count")?;
        if len > 0 && buf.is_null() {
            // Refused before the messages are taken, so none is lost.
            check_out(buf, "buf")?;
        }
        let messages = c.device.take_validation_messages();
        // SAFETY: checked non-null; the caller's contract.
        unsafe { count.write(messages.len()) };
        if len > 0 {
            // Cut to fit: the count says how many there were.
            let text = messages.join("\n");
            // SAFETY: the caller's contract.
            match unsafe { copy_text(&text, buf, len, std::ptr::null_mut()) } {
                Err(f) if f.status == srug_status::SRUG_ERROR_BUFFER_TOO_SMALL => {}
                other => other?,
            }
        }
        Ok(())
    })
}

/// The number of live handles of every kind in the process, for callers that
/// check their own clean-up (0 after destroying everything they made).
///
/// # Safety
/// `count` valid for one write.
#[no_mangle]
pub unsafe extern "C" fn srug_live_handle_count(count: *mut usize) -> srug_status {
    guard("srug_live_handle_count", || {
        // SAFETY: the caller's contract.
        unsafe { write_out(count, "count", handle::live()) }
    })
}
