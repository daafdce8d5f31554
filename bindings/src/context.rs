//! Contexts: a device (choice, validation), its memory and validation messages.

use std::ffi::c_char;
use std::sync::Arc;

use srug::gpu::{Device, DeviceOptions, DeviceSelection};

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

/// GPU memory the context's objects hold now and at most since its creation, in bytes.
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
        if current.is_null() && peak.is_null() {
            return Err(null("both current and peak"));
        }
        let m = c.device.memory_usage();
        if !current.is_null() {
            // SAFETY: non-null; the caller's contract.
            unsafe { current.write(m.current_bytes) };
        }
        if !peak.is_null() {
            // SAFETY: non-null; the caller's contract.
            unsafe { peak.write(m.peak_bytes) };
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
