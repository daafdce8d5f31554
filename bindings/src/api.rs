//! The entry points: contexts, scenes, environments, renderers.
//!
//! Each `extern "C"` function checks its pointers, looks its handles up
//! ([`crate::handle`]), and runs its body inside [`crate::guard`]. Outputs are
//! written only after everything they depend on succeeded.

use std::ffi::{c_char, c_void, CStr};
use std::path::Path;
use std::sync::{Arc, Mutex};

use glam::{Mat3, Vec3};
use srug::frame::{Preset, RelightDecisions, RelightSettings, Relighter};
use srug::gpu::{Device, DeviceOptions, DeviceSelection, Timings};
use srug::scene::activate::GpuScene;
use srug::scene::demo::{demo_city, DemoOptions};
use srug::scene::{AttributeGroups, Bounds, Camera, Projection, Scene};
use srug::shade::{
    BrdfLut, BrdfTable, EnvironmentMap, EnvironmentPrep, PrepareSettings, PreparedEnvironment, ProceduralSky,
    ShadedFrame, ToneMap,
};
use srug::shadow::backward::GpuVisibilityLoss;
use srug::shadow::{ShadowMap, ShadowPass, Sun, VisibilityKind};
use srug::splat::{Channels, GpuGBuffer, SplatFrame, SplatSettings};

use crate::handle::{self, id_of, lock, ptr_of, Object};
use crate::{guard, srug_status, Failure, FfiResult};

fn invalid(message: impl Into<String>) -> Failure {
    Failure::new(srug_status::SRUG_ERROR_INVALID_ARGUMENT, message)
}

fn wrong_order(message: impl Into<String>) -> Failure {
    Failure::new(srug_status::SRUG_ERROR_WRONG_ORDER, message)
}

fn null(what: &str) -> Failure {
    Failure::new(srug_status::SRUG_ERROR_NULL_POINTER, format!("{what} is NULL"))
}

/// Writes `value` through an out-pointer checked for NULL.
///
/// # Safety
/// `p` must be NULL or valid for one write of `T`.
unsafe fn write_out<T>(p: *mut T, what: &str, value: T) -> FfiResult {
    if p.is_null() {
        return Err(null(what));
    }
    // SAFETY: non-null, and valid for a write by the caller's contract.
    unsafe { p.write(value) };
    Ok(())
}

/// Checks an out-pointer before the work that fills it.
fn check_out<T>(p: *mut T, what: &str) -> FfiResult {
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
unsafe fn text<'a>(p: *const c_char, what: &str) -> FfiResult<&'a str> {
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
unsafe fn slice<'a, T>(p: *const T, len: usize, what: &str) -> FfiResult<&'a [T]> {
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
unsafe fn slice_mut<'a, T>(p: *mut T, len: usize, what: &str) -> FfiResult<&'a mut [T]> {
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
unsafe fn floats<const N: usize>(p: *const f32, what: &str) -> FfiResult<[f32; N]> {
    // SAFETY: forwarded contract.
    let s = unsafe { slice(p, N, what) }?;
    let mut out = [0.0; N];
    out.copy_from_slice(s);
    if let Some(i) = out.iter().position(|v| !v.is_finite()) {
        return Err(invalid(format!("{what}[{i}] is {} (values must be finite)", out[i])));
    }
    Ok(out)
}

fn finite(v: f32, what: &str) -> FfiResult<f32> {
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
unsafe fn copy_text(s: &str, buf: *mut c_char, len: usize, written: *mut usize) -> FfiResult {
    if !written.is_null() {
        // SAFETY: the caller's contract.
        unsafe { written.write(s.len()) };
    }
    if len == 0 {
        return if s.is_empty() { Ok(()) } else { Err(too_small(s.len() + 1, 0, "bytes")) };
    }
    // SAFETY: the caller's contract.
    let out = unsafe { slice_mut(buf.cast::<u8>(), len, "buf") }?;
    if s.len() + 1 > len {
        return Err(too_small(s.len() + 1, len, "bytes"));
    }
    out[..s.len()].copy_from_slice(s.as_bytes());
    out[s.len()] = 0;
    Ok(())
}

fn too_small(needed: usize, given: usize, unit: &str) -> Failure {
    Failure::new(
        srug_status::SRUG_ERROR_BUFFER_TOO_SMALL,
        format!("the buffer holds {given} {unit}; {needed} are needed"),
    )
}

// ---------------------------------------------------------------------------
// Contexts

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
    device: Device,
}

fn context(p: *const srug_context) -> FfiResult<(u64, Arc<Context>)> {
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
        let messages = c.device.take_validation_messages();
        // SAFETY: checked non-null; the caller's contract.
        unsafe { count.write(messages.len()) };
        if len > 0 || !buf.is_null() {
            let mut text = messages.join("\n");
            let mut cut = text.len().min(len.saturating_sub(1));
            while !text.is_char_boundary(cut) {
                cut -= 1;
            }
            text.truncate(cut);
            // SAFETY: the caller's contract; the text fits after the cut.
            unsafe { copy_text(&text, buf, len, std::ptr::null_mut()) }?;
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

// ---------------------------------------------------------------------------
// Scenes

/// 3D Gaussians on the GPU. Thread-safe; calls on one scene are serialized.
pub struct srug_scene {
    _private: [u8; 0],
}

/// The object behind a scene handle.
pub(crate) struct SceneObject {
    device: Device,
    scene: Scene,
    gpu: GpuScene,
    attributes: AttributeGroups,
    bounds: Option<Bounds>,
    /// Bumped by every parameter update (a shadow pass remembers the one it saw).
    version: u64,
}

impl SceneObject {
    fn new(device: &Device, scene: Scene) -> FfiResult<Self> {
        let gpu = GpuScene::upload(device, &scene)?;
        Ok(Self {
            device: device.clone(),
            attributes: scene.attributes(),
            bounds: scene.bounds(),
            scene,
            gpu,
            version: 0,
        })
    }
}

fn scene(p: *const srug_scene) -> FfiResult<(u64, u64, Arc<Mutex<SceneObject>>)> {
    let id = id_of(p)?;
    match handle::get(id, "scene")? {
        (Object::Scene(s), ctx) => Ok((id, ctx, s)),
        _ => Err(Failure::new(srug_status::SRUG_ERROR_INVALID_HANDLE, "not a scene")),
    }
}

fn register_scene(ctx_id: u64, c: &Context, s: Scene, out: *mut *mut srug_scene) -> FfiResult {
    let obj = SceneObject::new(&c.device, s)?;
    let id = handle::insert(Object::Scene(Arc::new(Mutex::new(obj))), ctx_id);
    // SAFETY: `out` was checked by the caller of this helper; the C caller's contract.
    unsafe { write_out(out, "out", ptr_of(id)) }
}

/// Loads a 3DGS PLY file (INRIA layout, binary or ASCII, optional material
/// attributes) and uploads it. Malformed files fail with `SRUG_ERROR_BAD_FILE`
/// and a message naming the row and property.
///
/// # Safety
/// `path` a NUL-terminated string; `out` valid for one write.
#[no_mangle]
pub unsafe extern "C" fn srug_scene_from_file(
    ctx: *const srug_context,
    path: *const c_char,
    out: *mut *mut srug_scene,
) -> srug_status {
    guard("srug_scene_from_file", || {
        let (ctx_id, c) = context(ctx)?;
        check_out(out, "out")?;
        // SAFETY: the caller's contract.
        let path = unsafe { text(path, "path") }?;
        let s = srug::io::read_ply(Path::new(path))?;
        register_scene(ctx_id, &c, s, out)
    })
}

/// Parses a PLY file held in memory (`len` bytes; copied, the caller keeps its buffer).
///
/// # Safety
/// `data` valid for `len` bytes of reads; `out` valid for one write.
#[no_mangle]
pub unsafe extern "C" fn srug_scene_from_memory(
    ctx: *const srug_context,
    data: *const u8,
    len: usize,
    out: *mut *mut srug_scene,
) -> srug_status {
    guard("srug_scene_from_memory", || {
        let (ctx_id, c) = context(ctx)?;
        check_out(out, "out")?;
        // SAFETY: the caller's contract.
        let bytes = unsafe { slice(data, len, "data") }?;
        let s = srug::io::read_ply_bytes(bytes, "memory buffer").map_err(srug::Error::from)?;
        register_scene(ctx_id, &c, s, out)
    })
}

/// The built-in demo city (the one `srug demo` renders): `gaussians` ≥ 1000,
/// SH degree 1, every material attribute; the same seed gives the same scene.
///
/// # Safety
/// `out` valid for one write.
#[no_mangle]
pub unsafe extern "C" fn srug_scene_create_demo(
    ctx: *const srug_context,
    gaussians: usize,
    seed: u64,
    out: *mut *mut srug_scene,
) -> srug_status {
    guard("srug_scene_create_demo", || {
        let (ctx_id, c) = context(ctx)?;
        check_out(out, "out")?;
        let city = demo_city(&DemoOptions { seed, gaussians, sh_degree: 1 })?;
        register_scene(ctx_id, &c, city.scene, out)
    })
}

/// Destroys a scene (renderers keep what they need of it until their next
/// render). NULL is accepted and ignored.
///
/// # Safety
/// Any pointer value is accepted; it is never dereferenced.
#[no_mangle]
pub unsafe extern "C" fn srug_scene_destroy(scene: *mut srug_scene) -> srug_status {
    guard("srug_scene_destroy", || {
        if scene.is_null() {
            return Ok(());
        }
        handle::remove(id_of(scene)?, "scene")
    })
}

/// The number of Gaussians, and whether the scene has the material attributes
/// that relighting needs (`has_materials` is 1 or 0; either pointer may be NULL).
///
/// # Safety
/// `count` and `has_materials` each NULL or valid for one write.
#[no_mangle]
pub unsafe extern "C" fn srug_scene_info(
    scene: *const srug_scene,
    count: *mut usize,
    has_materials: *mut u32,
) -> srug_status {
    guard("srug_scene_info", || {
        let (_, _, s) = self::scene(scene)?;
        let s = lock(&s)?;
        if !count.is_null() {
            // SAFETY: non-null; the caller's contract.
            unsafe { count.write(s.scene.len()) };
        }
        if !has_materials.is_null() {
            // SAFETY: non-null; the caller's contract.
            unsafe { has_materials.write(u32::from(s.attributes.shadeable())) };
        }
        Ok(())
    })
}

/// Replaces the Gaussians' geometry (a training step): `means` and `log_scales`
/// 3 floats each, `rotations` 4 (w, x, y, z), `opacity_logits` 1, for all
/// `count` Gaussians (`count` must equal the scene's). Non-finite values are
/// refused, naming the first; nothing changes on failure.
///
/// # Safety
/// Each array valid for reads of its length.
#[no_mangle]
pub unsafe extern "C" fn srug_scene_set_gaussians(
    scene: *mut srug_scene,
    means: *const f32,
    log_scales: *const f32,
    rotations: *const f32,
    opacity_logits: *const f32,
    count: usize,
) -> srug_status {
    guard("srug_scene_set_gaussians", || {
        let (_, _, s) = self::scene(scene)?;
        let mut s = lock(&s)?;
        if count != s.scene.len() {
            return Err(invalid(format!("count is {count}; the scene has {} Gaussians", s.scene.len())));
        }
        let n3 = count.checked_mul(4).ok_or_else(|| invalid("count overflows"))?;
        // SAFETY: the caller's contract.
        let (m, l, r, o) = unsafe {
            (
                slice(means, 3 * count, "means")?,
                slice(log_scales, 3 * count, "log_scales")?,
                slice(rotations, n3, "rotations")?,
                slice(opacity_logits, count, "opacity_logits")?,
            )
        };
        for (name, values, k) in [("means", m, 3), ("log_scales", l, 3), ("rotations", r, 4), ("opacity_logits", o, 1)]
        {
            if let Some(i) = values.iter().position(|v| !v.is_finite()) {
                return Err(invalid(format!("{name}[{i}] (Gaussian {}) is {}", i / k, values[i])));
            }
        }
        let dev = s.device.clone();
        // Before writing: even a partial write must not leave a reused shadow map looking current.
        s.gpu.mark_changed();
        dev.write_buffer(&s.gpu.means, 0, m)?;
        dev.write_buffer(&s.gpu.log_scales, 0, l)?;
        dev.write_buffer(&s.gpu.rotations, 0, r)?;
        dev.write_buffer(&s.gpu.opacity_logits, 0, o)?;
        for i in 0..count {
            s.scene.means[i] = [m[3 * i], m[3 * i + 1], m[3 * i + 2]];
            s.scene.log_scales[i] = [l[3 * i], l[3 * i + 1], l[3 * i + 2]];
            s.scene.rotations[i] = [r[4 * i], r[4 * i + 1], r[4 * i + 2], r[4 * i + 3]];
            s.scene.opacity_logits[i] = o[i];
        }
        s.bounds = s.scene.bounds();
        s.version += 1;
        Ok(())
    })
}

// ---------------------------------------------------------------------------
// Environments

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

fn environment(p: *const srug_environment) -> FfiResult<(u64, Arc<EnvironmentObject>)> {
    let id = id_of(p)?;
    match handle::get(id, "environment")? {
        (Object::Environment(e), ctx) => Ok((ctx, e)),
        _ => Err(Failure::new(srug_status::SRUG_ERROR_INVALID_HANDLE, "not an environment")),
    }
}

fn register_environment(ctx_id: u64, e: EnvironmentObject, out: *mut *mut srug_environment) -> FfiResult {
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

// ---------------------------------------------------------------------------
// Renderers

/// Renders and relights scenes for one camera at a time; keeps its kernels,
/// its last frame and its shadow pass. Thread-safe; calls on one renderer are serialized.
pub struct srug_renderer {
    _private: [u8; 0],
}

/// A G-buffer or shading channel: an index for `srug_renderer_read_channel`
/// and, as `1u << channel`, a bit of `srug_renderer_create`'s channel mask.
pub type srug_channel = u32;
/// Colour over the background (3 floats per pixel); always rendered.
pub const SRUG_CHANNEL_RGB: srug_channel = 0;
/// Coverage, 1 − final transmittance (1 float); always rendered.
pub const SRUG_CHANNEL_ALPHA: srug_channel = 1;
/// Blended expected depth along the camera axis (1).
pub const SRUG_CHANNEL_DEPTH: srug_channel = 2;
/// Depth where transmittance crosses 0.5; 0 where it never does (1).
pub const SRUG_CHANNEL_MEDIAN_DEPTH: srug_channel = 3;
/// Blended world-space normal (3).
pub const SRUG_CHANNEL_NORMAL: srug_channel = 4;
/// Blended albedo (3).
pub const SRUG_CHANNEL_ALBEDO: srug_channel = 5;
/// Blended roughness (1).
pub const SRUG_CHANNEL_ROUGHNESS: srug_channel = 6;
/// Blended metallic (1).
pub const SRUG_CHANNEL_METALLIC: srug_channel = 7;
/// Blended ambient occlusion (1).
pub const SRUG_CHANNEL_AO: srug_channel = 8;
/// Blended fixed sun visibility V_f (1).
pub const SRUG_CHANNEL_VISIBILITY: srug_channel = 9;
/// Sun light L_sun of the surface (3); relit frames only.
pub const SRUG_CHANNEL_SUN_LIGHT: srug_channel = 10;
/// Sky light L_sky of the surface (3); relit frames only.
pub const SRUG_CHANNEL_SKY_LIGHT: srug_channel = 11;
/// Linear radiance over the background (3); relit frames only.
pub const SRUG_CHANNEL_RADIANCE: srug_channel = 12;

/// Floats per pixel of a channel; 0 for an unknown channel.
#[no_mangle]
pub extern "C" fn srug_channel_components(channel: srug_channel) -> u32 {
    match channel {
        SRUG_CHANNEL_RGB | SRUG_CHANNEL_NORMAL | SRUG_CHANNEL_ALBEDO => 3,
        SRUG_CHANNEL_SUN_LIGHT | SRUG_CHANNEL_SKY_LIGHT | SRUG_CHANNEL_RADIANCE => 3,
        SRUG_CHANNEL_ALPHA..=SRUG_CHANNEL_VISIBILITY => 1,
        _ => 0,
    }
}

/// Pixel formats of `srug_renderer_read_image`.
pub type srug_format = u32;
/// 4 bytes per pixel: display colour (sRGB-encoded; tone-mapped when relit) and coverage alpha.
pub const SRUG_FORMAT_RGBA8_SRGB: srug_format = 0;
/// 16 bytes per pixel: linear radiance when relit (the splatted colour otherwise) and coverage alpha.
pub const SRUG_FORMAT_RGBA32F_LINEAR: srug_format = 1;

/// Tone maps of `srug_renderer_set_exposure`.
pub type srug_tone_map = u32;
/// Clamp to [0, 1].
pub const SRUG_TONE_MAP_CLAMP: srug_tone_map = 0;
/// Reinhard.
pub const SRUG_TONE_MAP_REINHARD: srug_tone_map = 1;
/// ACES filmic (Narkowicz fit).
pub const SRUG_TONE_MAP_ACES: srug_tone_map = 2;

/// Per-Gaussian gradients written by `srug_renderer_shadow_backward`: caller-owned
/// arrays of `count` × 3, 3, 4 and 1 floats, laid out like `srug_scene_set_gaussians`'s.
#[repr(C)]
pub struct srug_gaussian_gradients {
    /// dL/d mean, 3 floats per Gaussian.
    pub means: *mut f32,
    /// dL/d log-scale, 3 floats per Gaussian.
    pub log_scales: *mut f32,
    /// dL/d quaternion (w, x, y, z), 4 floats per Gaussian.
    pub rotations: *mut f32,
    /// dL/d opacity logit, 1 float per Gaussian.
    pub opacity_logits: *mut f32,
    /// Gaussians the arrays hold; must equal the scene's count.
    pub count: usize,
}

/// The last rendered frame.
struct Frame {
    gbuffer: GpuGBuffer,
    shaded: Option<ShadedFrame>,
}

/// The last shadow forward pass, kept for the backward pass.
struct ShadowState {
    scene: u64,
    version: u64,
    map: ShadowMap,
    receivers: SplatFrame,
}

/// The object behind a renderer handle.
pub(crate) struct RendererObject {
    device: Device,
    width: u32,
    height: u32,
    settings: RelightSettings,
    camera: Option<Camera>,
    sun: Option<Sun>,
    environment: Option<Arc<EnvironmentObject>>,
    relighter: Relighter,
    prep: EnvironmentPrep,
    brdf: Option<BrdfTable>,
    /// The procedural sky for (sun direction, intensity, turbidity) as bits.
    sky: Option<([u32; 7], PreparedEnvironment)>,
    shadows: Option<ShadowPass>,
    frame: Option<Frame>,
    shadow: Option<ShadowState>,
    /// GPU stages of the last render or shadow pass.
    timings: Option<Timings>,
}

fn renderer(p: *const srug_renderer) -> FfiResult<(u64, Arc<Mutex<RendererObject>>)> {
    let id = id_of(p)?;
    match handle::get(id, "renderer")? {
        (Object::Renderer(r), ctx) => Ok((ctx, r)),
        _ => Err(Failure::new(srug_status::SRUG_ERROR_INVALID_HANDLE, "not a renderer")),
    }
}

/// Runs `f` on a renderer's object.
fn with_renderer(p: *const srug_renderer, f: impl FnOnce(&mut RendererObject) -> FfiResult) -> FfiResult {
    let (_, r) = renderer(p)?;
    let mut r = lock(&r)?;
    f(&mut r)
}

/// Runs `f` on a renderer and a scene of the same context.
fn with_renderer_and_scene(
    rp: *const srug_renderer,
    sp: *const srug_scene,
    f: impl FnOnce(&mut RendererObject, u64, &SceneObject) -> FfiResult,
) -> FfiResult {
    let (rctx, r) = renderer(rp)?;
    let (sid, sctx, s) = scene(sp)?;
    if rctx != sctx {
        return Err(invalid("the scene and the renderer belong to different contexts"));
    }
    // Lock order: renderer, then scene (the only calls that hold two locks).
    let mut r = lock(&r)?;
    let s = lock(&s)?;
    f(&mut r, sid, &s)
}

/// Makes a renderer of `width`×`height` pixels. `channels` is a mask of
/// `1u << SRUG_CHANNEL_*` bits for the G-buffer channels to keep besides those
/// the shading needs (rgb and alpha are always there). Defaults: no sun, the
/// procedural sky, shadow map 2048 texels with k = 50, bias 0.5 and median
/// receiver depth (as `srug relight`), exposure 0 with the ACES tone map.
///
/// # Safety
/// `out` valid for one write.
#[no_mangle]
pub unsafe extern "C" fn srug_renderer_create(
    ctx: *const srug_context,
    width: u32,
    height: u32,
    channels: u32,
    out: *mut *mut srug_renderer,
) -> srug_status {
    guard("srug_renderer_create", || {
        let (ctx_id, c) = context(ctx)?;
        check_out(out, "out")?;
        if width == 0 || height == 0 || width > 16384 || height > 16384 {
            return Err(invalid(format!("image size {width}x{height}: each side must lie in 1..=16384")));
        }
        let known = (1u32 << (SRUG_CHANNEL_VISIBILITY + 1)) - 1;
        if channels & !known != 0 {
            return Err(invalid(format!(
                "channel mask {channels:#x} has bits beyond SRUG_CHANNEL_VISIBILITY (shading outputs come with relit frames)"
            )));
        }
        let mut settings = RelightSettings::default();
        settings.shadow.bias = 0.5;
        settings.shadow.receiver_depth = srug::shadow::DepthMode::Median;
        settings.shade.tone_map = ToneMap::Aces;
        settings.extra_channels = Channels::from_bits(channels >> 2);
        let obj = RendererObject {
            device: c.device.clone(),
            width,
            height,
            settings,
            camera: None,
            sun: None,
            environment: None,
            relighter: Relighter::new(&c.device)?,
            prep: EnvironmentPrep::new(&c.device)?,
            brdf: None,
            sky: None,
            shadows: None,
            frame: None,
            shadow: None,
            timings: None,
        };
        let id = handle::insert(Object::Renderer(Arc::new(Mutex::new(obj))), ctx_id);
        // SAFETY: checked non-null above; the caller's contract.
        unsafe { write_out(out, "out", ptr_of(id)) }
    })
}

/// Destroys a renderer. NULL is accepted and ignored.
///
/// # Safety
/// Any pointer value is accepted; it is never dereferenced.
#[no_mangle]
pub unsafe extern "C" fn srug_renderer_destroy(renderer: *mut srug_renderer) -> srug_status {
    guard("srug_renderer_destroy", || {
        if renderer.is_null() {
            return Ok(());
        }
        handle::remove(id_of(renderer)?, "renderer")
    })
}

fn set_camera(
    r: &mut RendererObject,
    rotation: Mat3,
    position: Vec3,
    projection: Projection,
    near: f32,
    far: f32,
) -> FfiResult {
    if !(near > 0.0 && far > near && far.is_finite()) {
        return Err(invalid(format!("near {near} and far {far}: need 0 < near < far < ∞")));
    }
    let det = rotation.determinant();
    if !rotation.is_finite()
        || (det - 1.0).abs() > 1e-3
        || !(rotation.transpose() * rotation).abs_diff_eq(Mat3::IDENTITY, 1e-3)
    {
        return Err(invalid(format!("the camera rotation is not a rotation (determinant {det})")));
    }
    if !position.is_finite() {
        return Err(invalid(format!("the camera position {position} is not finite")));
    }
    r.camera = Some(Camera {
        name: "c-api".into(),
        width: r.width,
        height: r.height,
        rotation,
        position,
        projection,
        near,
        far,
    });
    Ok(())
}

/// Sets a pinhole camera: focal lengths and principal point in pixels, and the
/// camera-to-world transform as a column-major 4×4 matrix with OpenCV camera
/// axes (x right, y down, z forward; the last column is the camera centre).
///
/// # Safety
/// `camera_to_world` valid for 16 float reads.
#[no_mangle]
#[allow(clippy::too_many_arguments, reason = "a C signature: intrinsics, pose and clip planes")]
pub unsafe extern "C" fn srug_renderer_set_camera(
    renderer: *mut srug_renderer,
    fx: f32,
    fy: f32,
    cx: f32,
    cy: f32,
    camera_to_world: *const f32,
    near: f32,
    far: f32,
) -> srug_status {
    guard("srug_renderer_set_camera", || {
        // SAFETY: the caller's contract.
        let m = unsafe { floats::<16>(camera_to_world, "camera_to_world") }?;
        for (v, name) in [(fx, "fx"), (fy, "fy"), (cx, "cx"), (cy, "cy")] {
            finite(v, name)?;
        }
        if fx <= 0.0 || fy <= 0.0 {
            return Err(invalid(format!("focal lengths {fx}, {fy} must be positive")));
        }
        let c2w = glam::Mat4::from_cols_array(&m);
        let rotation = Mat3::from_mat4(c2w);
        let position = c2w.w_axis.truncate();
        with_renderer(renderer, |r| {
            set_camera(r, rotation, position, Projection::Pinhole { fx, fy, cx, cy }, near, far)
        })
    })
}

/// Sets the camera from OpenGL-convention matrices, column-major: `view` maps
/// world to camera space (camera looking down −z, y up), `projection` is a
/// perspective projection (gluPerspective/glFrustum form, NDC y up); focal
/// lengths, principal point and near/far come from it.
///
/// # Safety
/// `view` and `projection` each valid for 16 float reads.
#[no_mangle]
pub unsafe extern "C" fn srug_renderer_set_camera_matrices(
    renderer: *mut srug_renderer,
    view: *const f32,
    projection: *const f32,
) -> srug_status {
    guard("srug_renderer_set_camera_matrices", || {
        // SAFETY: the caller's contract.
        let (v, p) = unsafe { (floats::<16>(view, "view")?, floats::<16>(projection, "projection")?) };
        let (view, proj) = (glam::Mat4::from_cols_array(&v), glam::Mat4::from_cols_array(&p));
        if proj.z_axis.w != -1.0 || proj.w_axis.w != 0.0 {
            return Err(invalid(
                "the projection is not an OpenGL perspective projection (its w row must be 0, 0, −1, 0)",
            ));
        }
        with_renderer(renderer, |r| {
            let (w, h) = (r.width as f32, r.height as f32);
            // x_ndc = P00·x/z_cv − P02 (z_cv = −z_gl), u = (x_ndc + 1)·w/2; y flips.
            let (fx, fy) = (proj.x_axis.x * w / 2.0, proj.y_axis.y * h / 2.0);
            let (cx, cy) = ((1.0 - proj.z_axis.x) * w / 2.0, (1.0 + proj.z_axis.y) * h / 2.0);
            let (a, b) = (proj.z_axis.z, proj.w_axis.z);
            let (near, far) = (b / (a - 1.0), b / (a + 1.0));
            if !(fx > 0.0 && fy > 0.0) {
                return Err(invalid(format!("the projection's focal lengths {fx}, {fy} are not positive")));
            }
            let flip = Mat3::from_diagonal(Vec3::new(1.0, -1.0, -1.0));
            let world_to_cv = flip * Mat3::from_mat4(view);
            let rotation = world_to_cv.transpose();
            let position = -(rotation * (flip * view.w_axis.truncate()));
            set_camera(r, rotation, position, Projection::Pinhole { fx, fy, cx, cy }, near, far)
        })
    })
}

/// Sets a pinhole camera at `eye` looking at `target` with `up` roughly up in
/// the image, `fov_x_degrees` wide; near 0.01, far 10⁴.
///
/// # Safety
/// `eye`, `target`, `up` each valid for 3 float reads.
#[no_mangle]
pub unsafe extern "C" fn srug_renderer_set_camera_look_at(
    renderer: *mut srug_renderer,
    eye: *const f32,
    target: *const f32,
    up: *const f32,
    fov_x_degrees: f32,
) -> srug_status {
    guard("srug_renderer_set_camera_look_at", || {
        // SAFETY: the caller's contract.
        let (e, t, u) = unsafe { (floats::<3>(eye, "eye")?, floats::<3>(target, "target")?, floats::<3>(up, "up")?) };
        with_renderer(renderer, |r| {
            let cam = Camera::look_at(
                e.into(),
                t.into(),
                u.into(),
                finite(fov_x_degrees, "fov_x_degrees")?,
                r.width,
                r.height,
            )?;
            set_camera(r, cam.rotation, cam.position, cam.projection, cam.near, cam.far)
        })
    })
}

/// Sets the sun by azimuth (degrees from north toward east) and elevation
/// (degrees above the horizon) with an RGB intensity (`intensity` 3 floats ≥ 0).
/// A sun at or below the horizon gives no sun light and no shadow pass.
///
/// # Safety
/// `intensity` valid for 3 float reads.
#[no_mangle]
pub unsafe extern "C" fn srug_renderer_set_sun(
    renderer: *mut srug_renderer,
    azimuth_degrees: f32,
    elevation_degrees: f32,
    intensity: *const f32,
) -> srug_status {
    guard("srug_renderer_set_sun", || {
        // SAFETY: the caller's contract.
        let i = unsafe { floats::<3>(intensity, "intensity") }?;
        let sun = Sun::from_azimuth_elevation(azimuth_degrees, elevation_degrees, i)?;
        with_renderer(renderer, |r| {
            r.sun = Some(sun);
            Ok(())
        })
    })
}

/// Removes the sun: no sun light, no shadow pass.
#[no_mangle]
pub extern "C" fn srug_renderer_clear_sun(renderer: *mut srug_renderer) -> srug_status {
    guard("srug_renderer_clear_sun", || {
        with_renderer(renderer, |r| {
            r.sun = None;
            Ok(())
        })
    })
}

/// Sets the sky light: `env` (NULL for the default procedural sky), rotated
/// `rotation_degrees` about the up axis and scaled by `intensity` (≥ 0).
#[no_mangle]
pub extern "C" fn srug_renderer_set_environment(
    renderer: *mut srug_renderer,
    env: *const srug_environment,
    rotation_degrees: f32,
    intensity: f32,
) -> srug_status {
    guard("srug_renderer_set_environment", || {
        finite(rotation_degrees, "rotation_degrees")?;
        if !(intensity >= 0.0 && intensity.is_finite()) {
            return Err(invalid(format!("intensity {intensity} must be finite and ≥ 0")));
        }
        let (rctx, r) = self::renderer(renderer)?;
        let e = if env.is_null() {
            None
        } else {
            let (ectx, e) = environment(env)?;
            if ectx != rctx {
                return Err(invalid("the environment and the renderer belong to different contexts"));
            }
            Some(e)
        };
        let mut r = lock(&r)?;
        r.environment = e;
        r.settings.shade.env_rotation_degrees = rotation_degrees;
        r.settings.shade.env_intensity = intensity;
        Ok(())
    })
}

/// Shadow-map quality: `resolution` texels along the longer side (16..=16384),
/// sigmoid sharpness `k` per world unit (> 0), depth `bias` in world units (≥ 0).
#[no_mangle]
pub extern "C" fn srug_renderer_set_shadow(
    renderer: *mut srug_renderer,
    resolution: u32,
    k: f32,
    bias: f32,
) -> srug_status {
    guard("srug_renderer_set_shadow", || {
        with_renderer(renderer, |r| {
            let mut s = r.settings.shadow;
            s.resolution = resolution;
            s.k = k;
            s.bias = bias;
            s.validate()?;
            r.settings.shadow = s;
            Ok(())
        })
    })
}

/// Applies a quality preset by name: `"fast"`, `"balanced"` (the default) or
/// `"reference"` (docs/bench/trade.md measures them). It sets the shadow map
/// (resolution, k, bias, depth modes, sigmoid or traced test), the SH degree
/// and the render scale; exposure, tone map, channels and the sun are kept.
/// Below scale 1 the frame is rendered smaller and read back resampled
/// bilinearly to the renderer's size. `srug_renderer_set_shadow` after it
/// overrides its shadow values.
///
/// # Safety
/// `name` a NUL-terminated string.
#[no_mangle]
pub unsafe extern "C" fn srug_renderer_set_preset(renderer: *mut srug_renderer, name: *const c_char) -> srug_status {
    guard("srug_renderer_set_preset", || {
        // SAFETY: the caller's contract.
        let name = unsafe { text(name, "name") }?;
        let preset = Preset::parse(name)?;
        with_renderer(renderer, |r| {
            let mut s = RelightSettings::preset(preset);
            s.shade = r.settings.shade;
            s.normal_source = r.settings.normal_source;
            s.extra_channels = r.settings.extra_channels;
            (s.tile, s.shadow.tile) = (r.settings.tile, r.settings.shadow.tile);
            s.validate()?;
            r.settings = s;
            Ok(())
        })
    })
}

/// The splatting tile edge in pixels, 8, 16 (the default) or 32, for the
/// camera and the shadow map (presets keep it). It changes speed, not the
/// image beyond rounding. Which is faster depends on the scene and size: 8
/// lists more (splat, tile) pairs but blends fewer pixels per splat
/// (docs/bench/trade.md and docs/bench/splat.md have the measurements).
#[no_mangle]
pub extern "C" fn srug_renderer_set_tile(renderer: *mut srug_renderer, tile: u32) -> srug_status {
    guard("srug_renderer_set_tile", || {
        srug::splat::check_tile(tile)?;
        with_renderer(renderer, |r| {
            r.settings.tile = tile;
            r.settings.shadow.tile = tile;
            Ok(())
        })
    })
}

/// Keeps the shadow map between renders (off by default) and splats a new one
/// only when the scene (a different handle, or `srug_scene_set_gaussians`),
/// the sun's direction or the shadow map's settings change: with a fixed sun a frame then
/// costs the camera splat, the shadow test and the shading. The map's GPU
/// memory stays allocated while it is kept; turning reuse off frees it.
#[no_mangle]
pub extern "C" fn srug_renderer_set_shadow_map_reuse(renderer: *mut srug_renderer, on: bool) -> srug_status {
    guard("srug_renderer_set_shadow_map_reuse", || {
        with_renderer(renderer, |r| {
            r.relighter.set_shadow_map_reuse(on);
            Ok(())
        })
    })
}

/// Exposure in stops and the tone map (`SRUG_TONE_MAP_*`) of the display image.
#[no_mangle]
pub extern "C" fn srug_renderer_set_exposure(
    renderer: *mut srug_renderer,
    exposure_ev: f32,
    tone_map: srug_tone_map,
) -> srug_status {
    guard("srug_renderer_set_exposure", || {
        let tone_map = match tone_map {
            SRUG_TONE_MAP_CLAMP => ToneMap::Clamp,
            SRUG_TONE_MAP_REINHARD => ToneMap::Reinhard,
            SRUG_TONE_MAP_ACES => ToneMap::Aces,
            other => return Err(invalid(format!("unknown tone map {other}"))),
        };
        finite(exposure_ev, "exposure_ev")?;
        with_renderer(renderer, |r| {
            r.settings.shade.exposure_ev = exposure_ev;
            r.settings.shade.tone_map = tone_map;
            Ok(())
        })
    })
}

impl RendererObject {
    fn camera(&self) -> FfiResult<Camera> {
        self.camera.clone().ok_or_else(|| {
            wrong_order("the renderer has no camera yet (srug_renderer_set_camera, _matrices or _look_at first)")
        })
    }

    fn render(&mut self, scene: &SceneObject) -> FfiResult {
        let camera = self.camera()?;
        self.frame = None;
        self.timings = None;
        // The renderer's own decisions (what `srug info --plan` reports).
        let d = RelightDecisions::new(&scene.attributes, self.sun.as_ref(), &self.settings)?;
        let sun = d.sun;
        let bounds = match (&scene.bounds, d.shading) {
            (Some(b), true) => *b,
            _ => {
                // No materials (or nothing at all): plain 3DGS colour, no shading kernels.
                let settings = SplatSettings {
                    channels: d.channels,
                    sh_degree: self.settings.sh_degree,
                    tile: self.settings.tile,
                    ..SplatSettings::default()
                };
                let camera = self.settings.render_camera(&camera);
                let (gbuffer, stats) = self.relighter.splatter().render(&scene.gpu, &camera, &settings)?;
                self.frame = Some(Frame { gbuffer, shaded: None });
                self.timings = Some(stats.timings);
                return Ok(());
            }
        };
        if self.brdf.is_none() {
            self.brdf = Some(self.prep.brdf_table(BrdfLut::default(), 129, 1024)?);
        }
        let turbidity = match self.environment.as_deref() {
            Some(EnvironmentObject::Prepared(_)) => None,
            Some(EnvironmentObject::Sky(t)) => Some(*t),
            None => Some(3.0),
        };
        if let Some(t) = turbidity {
            // Without a sun the sky is made for one 10° below the horizon (dusk, nearly black).
            let (dir, power) = match sun {
                Some(s) => (s.direction, s.intensity[0]),
                None => (Vec3::new(0.0, 0.985, -0.174), 1.0),
            };
            let key = [dir.x, dir.y, dir.z, power, t, 0.0, 0.0].map(f32::to_bits);
            if self.sky.as_ref().is_none_or(|(k, _)| *k != key) {
                let mut sky = ProceduralSky::new(dir, power);
                sky.turbidity = t;
                let prepared = self.prep.prepare(&sky.render()?, &PrepareSettings::default())?;
                self.sky = Some((key, prepared));
            }
        }
        let env = match (self.environment.as_deref(), &self.sky) {
            (Some(EnvironmentObject::Prepared(p)), _) => p,
            (_, Some((_, p))) => p,
            _ => return Err(Failure::new(srug_status::SRUG_ERROR_PANIC, "no environment was prepared")),
        };
        let brdf = self.brdf.as_ref().ok_or_else(|| Failure::new(srug_status::SRUG_ERROR_PANIC, "no BRDF table"))?;
        let relit = self.relighter.render(
            &scene.gpu,
            &scene.attributes,
            &bounds,
            &camera,
            sun.as_ref(),
            env,
            brdf,
            &self.settings,
        )?;
        self.frame = Some(Frame { gbuffer: relit.gbuffer, shaded: Some(relit.shaded) });
        self.timings = Some(relit.timings);
        Ok(())
    }

    fn stage_timings(&self) -> FfiResult<&Timings> {
        self.timings.as_ref().ok_or_else(|| wrong_order("nothing rendered yet (srug_renderer_render first)"))
    }

    /// A buffer of `frame` (`k` floats per pixel) at the renderer's size:
    /// resampled bilinearly when the frame was rendered at a lower render scale.
    fn read_full_size(&self, frame: &Frame, buffer: &srug::gpu::Buffer, k: usize) -> FfiResult<Vec<f32>> {
        let values: Vec<f32> = self.device.read_buffer(buffer)?;
        let size = (frame.gbuffer.width, frame.gbuffer.height);
        if size == (self.width, self.height) {
            return Ok(values);
        }
        let n = k * size.0 as usize * size.1 as usize;
        Ok(srug::image::resample_bilinear(&values[..n.min(values.len())], size, k, (self.width, self.height))?)
    }

    fn frame(&self) -> FfiResult<&Frame> {
        self.frame.as_ref().ok_or_else(|| wrong_order("nothing rendered yet (srug_renderer_render first)"))
    }
}

/// Renders `scene` from the renderer's camera: relit (sun, sky, shadows) when
/// the scene has materials, its plain 3DGS colour otherwise. Needs a camera.
#[no_mangle]
pub extern "C" fn srug_renderer_render(renderer: *mut srug_renderer, scene: *const srug_scene) -> srug_status {
    guard("srug_renderer_render", || with_renderer_and_scene(renderer, scene, |r, _, s| r.render(s)))
}

/// Copies the last frame into `dst` (`dst_len` bytes) as `format` rows
/// `row_stride` bytes apart (0: tightly packed). Rows run top to bottom.
///
/// # Safety
/// `dst` valid for `dst_len` bytes of writes.
#[no_mangle]
pub unsafe extern "C" fn srug_renderer_read_image(
    renderer: *const srug_renderer,
    format: srug_format,
    dst: *mut c_void,
    dst_len: usize,
    row_stride: usize,
) -> srug_status {
    guard("srug_renderer_read_image", || {
        let pixel = match format {
            SRUG_FORMAT_RGBA8_SRGB => 4,
            SRUG_FORMAT_RGBA32F_LINEAR => 16,
            other => return Err(invalid(format!("unknown format {other}"))),
        };
        with_renderer(renderer.cast_mut(), |r| {
            let f = r.frame()?;
            let (w, h) = (r.width as usize, r.height as usize);
            let row = w * pixel;
            let stride = if row_stride == 0 { row } else { row_stride };
            if stride < row {
                return Err(invalid(format!("row_stride {stride} is below a row's {row} bytes")));
            }
            let needed = stride * (h - 1) + row;
            if dst_len < needed {
                return Err(too_small(needed, dst_len, "bytes"));
            }
            let colour_buf = match (&f.shaded, format) {
                (Some(s), SRUG_FORMAT_RGBA8_SRGB) => &s.display,
                (Some(s), _) => &s.radiance,
                (None, _) => f.gbuffer.rgb_buffer()?,
            };
            let colour = r.read_full_size(f, colour_buf, 3)?;
            let alpha = r.read_full_size(f, &f.gbuffer.alpha, 1)?;
            // SAFETY: the caller's contract.
            let out = unsafe { slice_mut(dst.cast::<u8>(), dst_len, "dst") }?;
            for y in 0..h {
                let line = &mut out[y * stride..y * stride + row];
                for x in 0..w {
                    let p = y * w + x;
                    let px = [colour[3 * p], colour[3 * p + 1], colour[3 * p + 2], alpha[p]];
                    if pixel == 4 {
                        for (o, v) in line[4 * x..4 * x + 4].iter_mut().zip(px) {
                            *o = srug::io::display_byte(v);
                        }
                    } else {
                        for (o, v) in line[16 * x..16 * x + 16].chunks_exact_mut(4).zip(px) {
                            o.copy_from_slice(&v.to_ne_bytes());
                        }
                    }
                }
            }
            Ok(())
        })
    })
}

/// Copies one channel of the last frame into `dst` (`dst_len` floats):
/// `srug_channel_components(channel)` floats per pixel, row-major. A channel not
/// rendered (not in the mask, or a shading output of a plain frame) is refused.
///
/// # Safety
/// `dst` valid for `dst_len` float writes.
#[no_mangle]
pub unsafe extern "C" fn srug_renderer_read_channel(
    renderer: *const srug_renderer,
    channel: srug_channel,
    dst: *mut f32,
    dst_len: usize,
) -> srug_status {
    guard("srug_renderer_read_channel", || {
        let k = srug_channel_components(channel) as usize;
        if k == 0 {
            return Err(invalid(format!("unknown channel {channel}")));
        }
        with_renderer(renderer.cast_mut(), |r| {
            let f = r.frame()?;
            let g = &f.gbuffer;
            let s = f.shaded.as_ref();
            let buffer = match channel {
                SRUG_CHANNEL_RGB => g.rgb.as_ref(),
                SRUG_CHANNEL_ALPHA => Some(&g.alpha),
                SRUG_CHANNEL_DEPTH => g.depth.as_ref(),
                SRUG_CHANNEL_MEDIAN_DEPTH => g.median_depth.as_ref(),
                SRUG_CHANNEL_NORMAL => g.normal.as_ref(),
                SRUG_CHANNEL_ALBEDO => g.albedo.as_ref(),
                SRUG_CHANNEL_ROUGHNESS => g.roughness.as_ref(),
                SRUG_CHANNEL_METALLIC => g.metallic.as_ref(),
                SRUG_CHANNEL_AO => g.ao.as_ref(),
                SRUG_CHANNEL_VISIBILITY => g.visibility.as_ref(),
                SRUG_CHANNEL_SUN_LIGHT => s.map(|s| &s.sun),
                SRUG_CHANNEL_SKY_LIGHT => s.map(|s| &s.sky),
                _ => s.map(|s| &s.radiance),
            };
            let buffer = buffer.ok_or_else(|| {
                wrong_order(format!(
                    "channel {channel} was not rendered (add 1u << {channel} to the renderer's channel mask; \
                     shading outputs exist only for scenes with materials)"
                ))
            })?;
            let needed = k * r.width as usize * r.height as usize;
            if dst_len < needed {
                return Err(too_small(needed, dst_len, "floats"));
            }
            let values = r.read_full_size(f, buffer, k)?;
            // SAFETY: the caller's contract.
            let out = unsafe { slice_mut(dst, dst_len, "dst") }?;
            out[..needed].copy_from_slice(&values[..needed]);
            Ok(())
        })
    })
}

/// The number of GPU stages the last render (or shadow pass) timed.
///
/// # Safety
/// `count` valid for one write.
#[no_mangle]
pub unsafe extern "C" fn srug_renderer_stage_count(renderer: *const srug_renderer, count: *mut usize) -> srug_status {
    guard("srug_renderer_stage_count", || {
        check_out(count, "count")?;
        with_renderer(renderer.cast_mut(), |r| {
            let n = r.stage_timings()?.stages.len();
            // SAFETY: checked non-null; the caller's contract.
            unsafe { write_out(count, "count", n) }
        })
    })
}

/// Stage `index` of the last render: its name (copied like `srug_last_error`'s
/// message; `name` may be NULL with `name_len` 0) and its GPU time in seconds.
///
/// # Safety
/// `name` valid for `name_len` bytes or NULL with 0; `seconds` valid for one write.
#[no_mangle]
pub unsafe extern "C" fn srug_renderer_stage(
    renderer: *const srug_renderer,
    index: usize,
    name: *mut c_char,
    name_len: usize,
    seconds: *mut f64,
) -> srug_status {
    guard("srug_renderer_stage", || {
        check_out(seconds, "seconds")?;
        with_renderer(renderer.cast_mut(), |r| {
            let stages = &r.stage_timings()?.stages;
            let s = stages
                .get(index)
                .ok_or_else(|| invalid(format!("stage {index} of {} (srug_renderer_stage_count)", stages.len())))?;
            // SAFETY: checked non-null; the caller's contract.
            unsafe { seconds.write(s.seconds) };
            if name_len > 0 {
                // SAFETY: the caller's contract.
                unsafe { copy_text(&s.name, name, name_len, std::ptr::null_mut()) }?;
            }
            Ok(())
        })
    })
}

/// The shadow test's forward pass for a training loop: renders the receivers
/// from the camera, splats the shadow map from the sun and writes the sigmoid
/// visibility V = sigmoid(k·(z_s − z + bias)) per pixel into `visibility`
/// (`len` ≥ width·height floats; 1 where no receiver). Needs a camera and a sun
/// above the horizon; kept for `srug_renderer_shadow_backward`.
///
/// # Safety
/// `visibility` valid for `len` float writes.
#[no_mangle]
pub unsafe extern "C" fn srug_renderer_shadow_forward(
    renderer: *mut srug_renderer,
    scene: *const srug_scene,
    visibility: *mut f32,
    len: usize,
) -> srug_status {
    guard("srug_renderer_shadow_forward", || {
        with_renderer_and_scene(renderer, scene, |r, sid, s| {
            let camera = r.camera()?;
            let pixels = r.width as usize * r.height as usize;
            if len < pixels {
                return Err(too_small(pixels, len, "floats"));
            }
            let sun = r.sun.filter(Sun::above_horizon).ok_or_else(|| {
                wrong_order("the shadow pass needs a sun above the horizon (srug_renderer_set_sun first)")
            })?;
            let bounds = s.bounds.ok_or_else(|| invalid("the scene is empty"))?;
            r.shadow = None;
            if r.shadows.is_none() {
                r.shadows = Some(ShadowPass::new(&r.device)?);
            }
            let settings = r.settings.shadow;
            let pass = r.shadows.as_ref().ok_or_else(|| Failure::new(srug_status::SRUG_ERROR_PANIC, "no pass"))?;
            let splatter = r.relighter.splatter();
            let receivers = splatter.render_frame(
                &s.gpu,
                &camera,
                &SplatSettings { channels: settings.receiver_channels(), ..SplatSettings::default() },
            )?;
            let map = pass
                .shadow_map(splatter, &s.gpu, &bounds, &sun, &settings, Some(&camera))?
                .ok_or_else(|| wrong_order("the sun is below the horizon"))?;
            let (v, t) = pass.visibility(&map, &receivers.gbuffer, &camera, &settings, VisibilityKind::Sigmoid)?;
            let values: Vec<f32> = r.device.read_buffer(&v)?;
            // SAFETY: the caller's contract.
            let out = unsafe { slice_mut(visibility, len, "visibility") }?;
            out[..pixels].copy_from_slice(&values[..pixels]);
            let mut timings = receivers.stats.timings.clone();
            timings.stages.extend(map.frame.stats.timings.stages.iter().cloned());
            timings.stages.extend(t.stages);
            r.timings = Some(timings);
            r.shadow = Some(ShadowState { scene: sid, version: s.version, map, receivers });
            Ok(())
        })
    })
}

/// The backward pass of the last `srug_renderer_shadow_forward` on the same
/// scene (unchanged since): takes dL/dV per pixel (`len` ≥ width·height floats)
/// and writes dL/d(every Gaussian's mean, log-scale, rotation, opacity logit)
/// through both paths, the shadow map's occluders and the receivers' depths.
///
/// # Safety
/// `dl_dv` valid for `len` float reads; `grads` valid, its arrays valid for its `count`.
#[no_mangle]
pub unsafe extern "C" fn srug_renderer_shadow_backward(
    renderer: *mut srug_renderer,
    scene: *const srug_scene,
    dl_dv: *const f32,
    len: usize,
    grads: *const srug_gaussian_gradients,
) -> srug_status {
    guard("srug_renderer_shadow_backward", || {
        if grads.is_null() {
            return Err(null("grads"));
        }
        // SAFETY: non-null; the caller's contract.
        let g = unsafe { &*grads };
        with_renderer_and_scene(renderer, scene, |r, sid, s| {
            let camera = r.camera()?;
            let pixels = r.width as usize * r.height as usize;
            // SAFETY: the caller's contract.
            let upstream = unsafe { slice(dl_dv, len, "dl_dv") }?;
            if len < pixels {
                return Err(too_small(pixels, len, "floats"));
            }
            if let Some(i) = upstream[..pixels].iter().position(|v| !v.is_finite()) {
                return Err(invalid(format!("dl_dv[{i}] is {}", upstream[i])));
            }
            let n = s.scene.len();
            if g.count != n {
                return Err(invalid(format!("grads.count is {}; the scene has {n} Gaussians", g.count)));
            }
            // SAFETY: the caller's contract on the gradient arrays.
            let (gm, gl, gr, go) = unsafe {
                (
                    slice_mut(g.means, 3 * n, "grads.means")?,
                    slice_mut(g.log_scales, 3 * n, "grads.log_scales")?,
                    slice_mut(g.rotations, 4 * n, "grads.rotations")?,
                    slice_mut(g.opacity_logits, n, "grads.opacity_logits")?,
                )
            };
            let state = match &r.shadow {
                Some(st) if st.scene == sid && st.version == s.version => st,
                Some(_) => {
                    return Err(wrong_order(
                        "the last shadow forward pass was for another scene or older Gaussians; run it again",
                    ))
                }
                None => return Err(wrong_order("no shadow forward pass yet (srug_renderer_shadow_forward first)")),
            };
            let settings = r.settings.shadow;
            let pass = r.shadows.as_mut().ok_or_else(|| wrong_order("no shadow forward pass yet"))?;
            let up = r.device.upload("dL/dV", &upstream[..pixels])?;
            let b = pass.backward(
                &state.map,
                &state.receivers.gbuffer,
                &camera,
                &settings,
                GpuVisibilityLoss::Upstream(&up),
            )?;
            let splatter = r.relighter.splatter();
            let a = splatter.backward(&state.map.frame, &s.gpu, &b.map, false)?.read(&r.device)?;
            let c = splatter.backward(&state.receivers, &s.gpu, &b.receiver, false)?.read(&r.device)?;
            for i in 0..n {
                for j in 0..3 {
                    gm[3 * i + j] = a.means[i][j] + c.means[i][j];
                    gl[3 * i + j] = a.log_scales[i][j] + c.log_scales[i][j];
                }
                for j in 0..4 {
                    gr[4 * i + j] = a.rotations[i][j] + c.rotations[i][j];
                }
                go[i] = a.opacity_logits[i] + c.opacity_logits[i];
            }
            Ok(())
        })
    })
}
