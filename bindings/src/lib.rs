//! The C ABI of srug. The opaque-handle API arrives with the C ABI issue;
//! until then this crate exposes only the version queries.

use std::ffi::c_char;

/// The library version as a NUL-terminated string with static lifetime.
#[no_mangle]
pub extern "C" fn srug_version() -> *const c_char {
    concat!(env!("CARGO_PKG_VERSION"), "\0").as_ptr().cast()
}

/// The ABI version; it changes whenever a C caller must be rebuilt.
#[no_mangle]
pub extern "C" fn srug_abi_version() -> u32 {
    0
}
