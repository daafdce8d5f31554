//! Environments: an EXR/HDR/KTX2 file, a prefiltered folder, or the procedural sky.

use std::ffi::c_char;
use std::path::Path;
use std::sync::Arc;

use srug::shade::{EnvironmentMap, EnvironmentPrep, PrepareSettings, PreparedEnvironment};

use crate::context::*;
use crate::ffi::*;
use crate::handle::{self, id_of, ptr_of, Object};
use crate::{guard, srug_status, Failure, FfiResult};

/// Sky light: a prepared environment map or the procedural sky. Immutable,
/// thread-safe; a renderer keeps the one it was given alive.
pub struct srug_environment {
    _private: [u8; 0],
}

/// The object behind an environment handle.
pub(crate) enum EnvironmentObject {
    /// Prefiltered once.
    Prepared(Box<PreparedEnvironment>),
    /// Made per sun (Preetham), with this turbidity.
    Sky(f32),
}

pub(crate) fn environment(p: *const srug_environment) -> FfiResult<(u64, Arc<EnvironmentObject>)> {
    let id = id_of(p)?;
    match handle::get(id, "environment")? {
        (Object::Environment(e), ctx) => Ok((ctx, e)),
        _ => Err(Failure::new(srug_status::SRUG_ERROR_INVALID_HANDLE, "not an environment")),
    }
}

pub(crate) fn register_environment(ctx_id: u64, e: EnvironmentObject, out: *mut *mut srug_environment) -> FfiResult {
    let id = handle::insert(Object::Environment(Arc::new(e)), ctx_id);
    // SAFETY: checked by the caller of this helper; the C caller's contract.
    unsafe { write_out(out, "out", ptr_of(id)) }
}

/// Loads an environment map (lat-long EXR or Radiance .hdr, KTX2 lat-long or
/// cube) and prefilters it once on the GPU; or loads a folder written by
/// `srug prefilter`.
///
/// # Safety
/// `path` a NUL-terminated string; `out` valid for one write.
#[no_mangle]
pub unsafe extern "C" fn srug_environment_from_file(
    ctx: *const srug_context,
    path: *const c_char,
    out: *mut *mut srug_environment,
) -> srug_status {
    guard("srug_environment_from_file", || {
        let (ctx_id, c) = context(ctx)?;
        check_out(out, "out")?;
        // SAFETY: the caller's contract.
        let path = Path::new(unsafe { text(path, "path") }?);
        let prepared = if path.is_dir() {
            PreparedEnvironment::load(&c.device, path)?
        } else {
            EnvironmentPrep::new(&c.device)?.prepare(&EnvironmentMap::load(path)?, &PrepareSettings::default())?
        };
        register_environment(ctx_id, EnvironmentObject::Prepared(Box::new(prepared)), out)
    })
}

/// The procedural (Preetham) sky, remade for each sun position; `turbidity` in [1.7, 10].
///
/// # Safety
/// `out` valid for one write.
#[no_mangle]
pub unsafe extern "C" fn srug_environment_sky(
    ctx: *const srug_context,
    turbidity: f32,
    out: *mut *mut srug_environment,
) -> srug_status {
    guard("srug_environment_sky", || {
        let (ctx_id, _) = context(ctx)?;
        check_out(out, "out")?;
        if !(1.7..=10.0).contains(&turbidity) {
            return Err(invalid(format!("turbidity {turbidity} is outside [1.7, 10]")));
        }
        register_environment(ctx_id, EnvironmentObject::Sky(turbidity), out)
    })
}

/// Destroys an environment (a renderer using it keeps it until it gets another).
/// NULL is accepted and ignored.
///
/// # Safety
/// Any pointer value is accepted; it is never dereferenced.
#[no_mangle]
pub unsafe extern "C" fn srug_environment_destroy(env: *mut srug_environment) -> srug_status {
    guard("srug_environment_destroy", || {
        if env.is_null() {
            return Ok(());
        }
        handle::remove(id_of(env)?, "environment")
    })
}
