//! Scenes: from a scene file or its bytes (any format srug reads) or the demo city; Gaussians replaced in place for training.

use std::ffi::c_char;
use std::path::Path;
use std::sync::{Arc, Mutex};

use srug::gpu::Device;
use srug::scene::activate::GpuScene;
use srug::scene::demo::{demo_city, DemoOptions};
use srug::scene::order::SceneOrder;
use srug::scene::{AttributeGroups, Bounds, Scene};

use crate::context::*;
use crate::ffi::*;
use crate::handle::{self, id_of, lock, ptr_of, Object};
use crate::{guard, srug_status, Failure, FfiResult};

/// 3D Gaussians on the GPU. Thread-safe; calls on one scene are serialized.
pub struct srug_scene {
    _private: [u8; 0],
}

/// The object behind a scene handle.
pub(crate) struct SceneObject {
    pub(crate) device: Device,
    pub(crate) scene: Scene,
    pub(crate) gpu: GpuScene,
    pub(crate) attributes: AttributeGroups,
    pub(crate) bounds: Option<Bounds>,
    /// Bumped by every parameter update (a shadow pass remembers the one it saw).
    pub(crate) version: u64,
}

impl SceneObject {
    fn new(device: &Device, scene: Scene) -> FfiResult<Self> {
        let mut gpu = GpuScene::upload(device, &scene)?;
        // A file in no spatial order renders faster arranged; every output stays in file order.
        gpu.arrange(device, SceneOrder::Auto)?;
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

pub(crate) fn scene(p: *const srug_scene) -> FfiResult<(u64, u64, Arc<Mutex<SceneObject>>)> {
    let id = id_of(p)?;
    match handle::get(id, "scene")? {
        (Object::Scene(s), ctx) => Ok((id, ctx, s)),
        _ => Err(Failure::new(srug_status::SRUG_ERROR_INVALID_HANDLE, "not a scene")),
    }
}

pub(crate) fn register_scene(ctx_id: u64, c: &Context, s: Scene, out: *mut *mut srug_scene) -> FfiResult {
    let obj = SceneObject::new(&c.device, s)?;
    let id = handle::insert(Object::Scene(Arc::new(Mutex::new(obj))), ctx_id);
    // SAFETY: `out` was checked by the caller of this helper; the C caller's contract.
    unsafe { write_out(out, "out", ptr_of(id)) }
}

/// Loads a scene file and uploads it: INRIA PLY (binary or ASCII, optional
/// material attributes), compressed PLY, `.splat`, `.spz`, SOG (`.sog` or
/// `meta.json`) or GLB, detected from the content. Malformed files fail with
/// `SRUG_ERROR_BAD_FILE` and a message naming the format and the field.
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
        let s = srug::io::read_scene(Path::new(path))?;
        register_scene(ctx_id, &c, s, out)
    })
}

/// Parses a scene file held in memory (any format but an unbundled SOG; `len`
/// bytes, copied, the caller keeps its buffer).
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
        let s = srug::io::read_scene_bytes(bytes, "memory buffer").map_err(srug::Error::from)?;
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
        // In file order whatever the device's (it marks the scene changed before its first write).
        s.gpu.write_geometry(&dev, m, l, r, o)?;
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
