//! What every entry point shares: argument checks and the failures they report.
//!
//! Each `extern "C"` function checks its pointers, looks its handles up
//! ([`crate::handle`]), and runs its body inside [`crate::guard`]. Outputs are
//! written only after everything they depend on succeeded.

use std::ffi::{c_char, CStr};

use crate::{srug_status, Failure, FfiResult};

pub(crate) fn invalid(message: impl Into<String>) -> Failure {
    Failure::new(srug_status::SRUG_ERROR_INVALID_ARGUMENT, message)
}

pub(crate) fn wrong_order(message: impl Into<String>) -> Failure {
    Failure::new(srug_status::SRUG_ERROR_WRONG_ORDER, message)
}

pub(crate) fn null(what: &str) -> Failure {
    Failure::new(srug_status::SRUG_ERROR_NULL_POINTER, format!("{what} is NULL"))
}

/// Writes `value` through an out-pointer checked for NULL.
///
/// # Safety
/// `p` must be NULL or valid for one write of `T`.
pub(crate) unsafe fn write_out<T>(p: *mut T, what: &str, value: T) -> FfiResult {
    if p.is_null() {
        return Err(null(what));
    }
    // SAFETY: non-null, and valid for a write by the caller's contract.
    unsafe { p.write(value) };
    Ok(())
}

/// Checks an out-pointer before the work that fills it.
pub(crate) fn check_out<T>(p: *mut T, what: &str) -> FfiResult {
    if p.is_null() {
        Err(null(what))
    } else {
        Ok(())
    }
}

/// A UTF-8 string argument.
///
/// # Safety
/// `p` must be NULL or a NUL-terminated string that outlives the call.
pub(crate) unsafe fn text<'a>(p: *const c_char, what: &str) -> FfiResult<&'a str> {
    if p.is_null() {
        return Err(null(what));
    }
    // SAFETY: non-null and NUL-terminated by the caller's contract.
    unsafe { CStr::from_ptr(p) }.to_str().map_err(|_| invalid(format!("{what} is not valid UTF-8")))
}

/// A slice argument of `len` elements (NULL allowed only when `len` is 0).
///
/// # Safety
/// `p` must be NULL or valid for `len` reads of `T` for the call's duration.
pub(crate) unsafe fn slice<'a, T>(p: *const T, len: usize, what: &str) -> FfiResult<&'a [T]> {
    if len == 0 {
        return Ok(&[]);
    }
    if p.is_null() {
        return Err(null(what));
    }
    if p.cast::<u8>().align_offset(std::mem::align_of::<T>()) != 0 {
        return Err(invalid(format!("{what} is not aligned to {} bytes", std::mem::align_of::<T>())));
    }
    // SAFETY: non-null, aligned, and valid for `len` reads by the caller's contract.
    Ok(unsafe { std::slice::from_raw_parts(p, len) })
}

/// A mutable slice argument; see [`slice`].
///
/// # Safety
/// `p` must be NULL or valid for `len` writes of `T`, not aliased during the call.
pub(crate) unsafe fn slice_mut<'a, T>(p: *mut T, len: usize, what: &str) -> FfiResult<&'a mut [T]> {
    if len == 0 {
        return Ok(&mut []);
    }
    if p.is_null() {
        return Err(null(what));
    }
    if p.cast::<u8>().align_offset(std::mem::align_of::<T>()) != 0 {
        return Err(invalid(format!("{what} is not aligned to {} bytes", std::mem::align_of::<T>())));
    }
    // SAFETY: non-null, aligned, valid for `len` writes and unaliased by the caller's contract.
    Ok(unsafe { std::slice::from_raw_parts_mut(p, len) })
}

/// `N` floats from a pointer.
///
/// # Safety
/// As [`slice`] with `len` = `N`.
pub(crate) unsafe fn floats<const N: usize>(p: *const f32, what: &str) -> FfiResult<[f32; N]> {
    // SAFETY: forwarded contract.
    let s = unsafe { slice(p, N, what) }?;
    let mut out = [0.0; N];
    out.copy_from_slice(s);
    if let Some(i) = out.iter().position(|v| !v.is_finite()) {
        return Err(invalid(format!("{what}[{i}] is {} (values must be finite)", out[i])));
    }
    Ok(out)
}

pub(crate) fn finite(v: f32, what: &str) -> FfiResult<f32> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(invalid(format!("{what} is {v} (must be finite)")))
    }
}

/// Copies `s` into a caller's buffer like [`crate::srug_last_error`] does.
///
/// # Safety
/// `buf` valid for `len` bytes of writes (or NULL with `len` 0); `written` NULL or valid.
pub(crate) unsafe fn copy_text(s: &str, buf: *mut c_char, len: usize, written: *mut usize) -> FfiResult {
    // A NULL buffer with a length is refused before anything is written.
    // SAFETY: the caller's contract.
    let out = if len > 0 { Some(unsafe { slice_mut(buf.cast::<u8>(), len, "buf") }?) } else { None };
    if !written.is_null() {
        // SAFETY: the caller's contract.
        unsafe { written.write(s.len()) };
    }
    let Some(out) = out else {
        return if s.is_empty() { Ok(()) } else { Err(too_small(s.len() + 1, 0, "bytes")) };
    };
    // The longest prefix that fits, cut at a UTF-8 boundary, always NUL-terminated.
    let mut n = s.len().min(len - 1);
    while !s.is_char_boundary(n) {
        n -= 1;
    }
    out[..n].copy_from_slice(&s.as_bytes()[..n]);
    out[n] = 0;
    if n < s.len() {
        return Err(too_small(s.len() + 1, len, "bytes"));
    }
    Ok(())
}

pub(crate) fn too_small(needed: usize, given: usize, unit: &str) -> Failure {
    Failure::new(
        srug_status::SRUG_ERROR_BUFFER_TOO_SMALL,
        format!("the buffer holds {given} {unit}; {needed} are needed"),
    )
}
