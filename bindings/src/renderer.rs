//! Renderers: camera, sun, environment, shadow and preset settings; rendering;
//! reading images, channels and timings; the shadow forward and backward.

use std::ffi::{c_char, c_void};
use std::sync::{Arc, Mutex};

use glam::{Mat3, Vec3};
use srug::frame::host_images::FrameChannel;
use srug::frame::{HostDepthImage, Preset, RelightDecisions, RelightSettings, Relighter};
use srug::gpu::{Device, Timings};
use srug::scene::{Camera, Projection};
use srug::shade::{
    Background, BrdfLut, BrdfTable, EnvironmentPrep, PrepareSettings, PreparedEnvironment, ProceduralSky, ShadedFrame,
    ToneMap,
};
use srug::shadow::backward::GpuVisibilityLoss;
use srug::shadow::{ShadowFilter, ShadowFit, ShadowMap, ShadowPass, Sun, VisibilityKind};
use srug::splat::{Channels, GpuGBuffer, HostDepth, SplatFrame, SplatSettings};

use crate::context::*;
use crate::environment::*;
use crate::ffi::*;
use crate::handle::{self, id_of, lock, ptr_of, Object};
use crate::scene::*;
use crate::{guard, srug_status, Failure, FfiResult};
use srug::splat::Channel;

/// Renders and relights scenes for one camera at a time; keeps its kernels,
/// its last frame and its shadow pass. Thread-safe; calls on one renderer are serialized.
pub struct srug_renderer {
    _private: [u8; 0],
}

/// A G-buffer or shading channel: an index for `srug_renderer_read_channel`
/// and, as `1u << channel`, a bit of `srug_renderer_create`'s channel mask.
pub type srug_channel = u32;
/// The scene's own (3DGS) colour over the background (3 floats per pixel):
/// always rendered in plain frames; in relit frames only when the renderer's
/// channel mask has its bit (shading never reads it, and without it a relit
/// frame reads no spherical-harmonic coefficient).
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

/// What the shadow map covers (`srug_renderer_set_shadow_fit`).
pub type srug_shadow_fit = u32;
/// The whole scene's bounds (the default).
pub const SRUG_SHADOW_FIT_SCENE: srug_shadow_fit = 0;
/// The camera's view frustum within the scene's bounds: finer texels for the
/// same resolution; casters anywhere in the bounds still cast.
pub const SRUG_SHADOW_FIT_VIEW: srug_shadow_fit = 1;
/// A map per slice of the camera's view depth (`srug_renderer_set_shadow_cascades`
/// maps, 3 by default): fine texels near the camera, coarse far away, snapped to a
/// grid fixed in the world; pinhole cameras; not differentiated.
pub const SRUG_SHADOW_FIT_CASCADES: srug_shadow_fit = 2;

/// How the shadow test reads the map (`srug_renderer_set_shadow_filter`).
pub type srug_shadow_filter = u32;
/// Percentage-closer filtering (the presets): the four nearest texels' tests
/// weighted bilinearly; edges a texel wide, where the map's outline is.
pub const SRUG_SHADOW_FILTER_PCF: srug_shadow_filter = 0;
/// One test of the bilinearly interpolated depth: the paper's razor edge.
pub const SRUG_SHADOW_FILTER_DEPTH: srug_shadow_filter = 1;

/// How `srug_renderer_set_host_depth`'s values encode depth.
pub type srug_depth_convention = u32;
/// Camera z in world units (0, negative or infinite: nothing there).
pub const SRUG_DEPTH_CAMERA_Z: srug_depth_convention = 0;
/// Vulkan's [0, 1] perspective depth, 0 at `near`, 1 at `far` (1: nothing there).
pub const SRUG_DEPTH_VULKAN: srug_depth_convention = 1;
/// Reversed-Z: 1 at `near`, 0 at `far`, which may be `INFINITY` (0: nothing there).
pub const SRUG_DEPTH_REVERSED_Z: srug_depth_convention = 2;

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
pub(crate) struct Frame {
    pub(crate) gbuffer: GpuGBuffer,
    pub(crate) shaded: Option<ShadedFrame>,
    /// A relit frame's exposure (EV) and tone map.
    pub(crate) display: Option<(f32, ToneMap)>,
}

/// The last shadow forward pass, kept for the backward pass.
pub(crate) struct ShadowState {
    pub(crate) scene: u64,
    pub(crate) version: u64,
    pub(crate) map: ShadowMap,
    pub(crate) receivers: SplatFrame,
}

/// The object behind a renderer handle.
pub(crate) struct RendererObject {
    pub(crate) device: Device,
    pub(crate) width: u32,
    pub(crate) height: u32,
    pub(crate) settings: RelightSettings,
    pub(crate) camera: Option<Camera>,
    pub(crate) sun: Option<Sun>,
    pub(crate) environment: Option<Arc<EnvironmentObject>>,
    pub(crate) relighter: Relighter,
    pub(crate) prep: EnvironmentPrep,
    pub(crate) brdf: Option<BrdfTable>,
    /// The procedural sky for (sun direction, intensity, turbidity) as bits.
    pub(crate) sky: Option<([u32; 7], PreparedEnvironment)>,
    pub(crate) shadows: Option<ShadowPass>,
    pub(crate) frame: Option<Frame>,
    pub(crate) shadow: Option<ShadowState>,
    /// GPU stages of the last render or shadow pass.
    pub(crate) timings: Option<Timings>,
    /// The image exported to a host on another device (`srug_renderer_export_image`).
    /// With whether srug has released it to the host (after a render).
    pub(crate) exported: Option<(srug::gpu::ExportedImage, bool)>,
    /// The semaphore each render to the exported image signals (`srug_renderer_export_semaphore`).
    pub(crate) exported_semaphore: Option<srug::gpu::ExportedSemaphore>,
}

pub(crate) fn renderer(p: *const srug_renderer) -> FfiResult<(u64, Arc<Mutex<RendererObject>>)> {
    let id = id_of(p)?;
    match handle::get(id, "renderer")? {
        (Object::Renderer(r), ctx) => Ok((ctx, r)),
        _ => Err(Failure::new(srug_status::SRUG_ERROR_INVALID_HANDLE, "not a renderer")),
    }
}

/// Runs `f` on a renderer's object.
pub(crate) fn with_renderer(p: *const srug_renderer, f: impl FnOnce(&mut RendererObject) -> FfiResult) -> FfiResult {
    let (_, r) = renderer(p)?;
    let mut r = lock(&r)?;
    f(&mut r)
}

/// Runs `f` on a renderer and a scene of the same context.
pub(crate) fn with_renderer_and_scene(
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
/// the shading needs (alpha is always there, and rgb in plain frames; relit
/// frames splat the scene's own colour only with `1u << SRUG_CHANNEL_RGB`). Defaults: no sun, the
/// procedural sky, the balanced preset's shadows as `srug relight` has them (a
/// 2048-texel map, k = 50, a bias of 0.8 m plus 3 texels of slope bias, surface
/// median depths, percentage-closer filtering), exposure 0 with the ACES tone map.
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
        // The balanced preset, the header's default.
        let mut settings = RelightSettings::preset(Preset::Balanced);
        settings.shade.tone_map = ToneMap::Aces;
        settings.extra_channels = Channels::from_bits(channels >> 2);
        // Relit frames splat the scene's own colour only when the mask asks (plain frames always do).
        settings.rgb = channels & (1 << SRUG_CHANNEL_RGB) != 0;
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
            exported: None,
            exported_semaphore: None,
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

/// A pinhole camera of the renderer's size (not yet validated).
fn renderer_camera(
    r: &RendererObject,
    rotation: Mat3,
    position: Vec3,
    projection: Projection,
    near: f32,
    far: f32,
) -> Camera {
    Camera {
        name: "c-api".into(),
        width: r.width,
        height: r.height,
        rotation,
        position,
        projection,
        near,
        far,
        lens: srug::camera::lens::Lens::Pinhole,
    }
}

pub(crate) fn set_camera(
    r: &mut RendererObject,
    rotation: Mat3,
    position: Vec3,
    projection: Projection,
    near: f32,
    far: f32,
) -> FfiResult {
    let camera = renderer_camera(r, rotation, position, projection, near, far);
    camera.validate()?;
    r.camera = Some(camera);
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
            let position = srug::camera::centre_of(rotation, flip * view.w_axis.truncate());
            set_camera(r, rotation, position, Projection::Pinhole { fx, fy, cx, cy }, near, far)
        })
    })
}

/// Sets a camera of any COLMAP camera model: `model` names it as COLMAP does
/// (PINHOLE, SIMPLE_RADIAL, OPENCV, FULL_OPENCV, OPENCV_FISHEYE, FOV, EUCM,
/// DIVISION, THIN_PRISM_FISHEYE, RAD_TAN_THIN_PRISM_FISHEYE, EQUIRECTANGULAR,
/// ...) and `params` holds its `param_count` parameters in COLMAP's order, in
/// pixels of the renderer's image; `camera_to_world`, `near` and `far` as for
/// `srug_renderer_set_camera` (an equirectangular camera's near and far are
/// distances). A lens whose distortion folds back inside the image is refused.
///
/// # Safety
/// `model` a NUL-terminated string; `params` valid for `param_count` double
/// reads; `camera_to_world` valid for 16 float reads.
#[no_mangle]
pub unsafe extern "C" fn srug_renderer_set_camera_model(
    renderer: *mut srug_renderer,
    model: *const c_char,
    params: *const f64,
    param_count: usize,
    camera_to_world: *const f32,
    near: f32,
    far: f32,
) -> srug_status {
    guard("srug_renderer_set_camera_model", || {
        // SAFETY: the caller's contract.
        let (model, params, m) = unsafe {
            (
                text(model, "model")?,
                slice(params, param_count, "params")?,
                floats::<16>(camera_to_world, "camera_to_world")?,
            )
        };
        if let Some(i) = params.iter().position(|v| !v.is_finite()) {
            return Err(invalid(format!("params[{i}] is {} (values must be finite)", params[i])));
        }
        let intr = srug::camera::lens::Intrinsics::from_colmap(model, params).ok_or_else(|| {
            invalid(format!(
                "camera model {model} with {param_count} parameters is not a COLMAP model srug knows (names as \
                 COLMAP writes them, parameters in its order)"
            ))
        })?;
        let c2w = glam::Mat4::from_cols_array(&m);
        let projection = Projection::Pinhole {
            fx: intr.focal[0] as f32,
            fy: intr.focal[1] as f32,
            cx: intr.centre[0] as f32,
            cy: intr.centre[1] as f32,
        };
        with_renderer(renderer, |r| {
            let camera = Camera {
                lens: intr.lens,
                ..renderer_camera(r, Mat3::from_mat4(c2w), c2w.w_axis.truncate(), projection, near, far)
            };
            camera.validate()?;
            r.camera = Some(camera);
            Ok(())
        })
    })
}

/// Sets the camera to camera `index` of a cameras file: INRIA cameras.json, a
/// COLMAP sparse model (its folder or its cameras/images file, text or binary)
/// or a nerfstudio/instant-ngp transforms.json, detected from the content;
/// the camera's lens comes with it and its intrinsics are scaled to the
/// renderer's size. Writes the number of cameras the file holds to `count`
/// (NULL: not asked) on success.
///
/// # Safety
/// `path` a NUL-terminated string; `count` NULL or valid for one write.
#[no_mangle]
pub unsafe extern "C" fn srug_renderer_set_camera_from_file(
    renderer: *mut srug_renderer,
    path: *const c_char,
    index: usize,
    count: *mut usize,
) -> srug_status {
    guard("srug_renderer_set_camera_from_file", || {
        // SAFETY: the caller's contract.
        let path = unsafe { text(path, "path") }?;
        let cameras = srug::io::read_cameras(std::path::Path::new(path))?;
        let n = cameras.len();
        let chosen = cameras
            .into_iter()
            .nth(index)
            .ok_or_else(|| invalid(format!("camera index {index}: {path} holds {n} cameras")))?;
        with_renderer(renderer, |r| {
            let camera = chosen.resized(r.width, r.height);
            camera.validate()?;
            r.camera = Some(camera);
            Ok(())
        })?;
        if !count.is_null() {
            // SAFETY: non-null and valid for one write by the caller's contract.
            unsafe { count.write_unaligned(n) };
        }
        Ok(())
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

/// The sun the renderer shades with, for a host that lights its own meshes
/// the same way: `direction` gets the world-space unit vector toward the sun
/// (srug's world axes, z up), `radiance` its RGB intensity (what
/// `srug_renderer_set_sun` was given); a surface of albedo ρ and normal n
/// receives ρ/π · radiance · max(n·direction, 0) from it, as srug's diffuse
/// term. No sun set: `SRUG_ERROR_WRONG_ORDER`.
///
/// # Safety
/// `direction` and `radiance` each valid for 3 float writes.
#[no_mangle]
pub unsafe extern "C" fn srug_renderer_get_sun(
    renderer: *const srug_renderer,
    direction: *mut f32,
    radiance: *mut f32,
) -> srug_status {
    guard("srug_renderer_get_sun", || {
        check_out(direction, "direction")?;
        check_out(radiance, "radiance")?;
        with_renderer(renderer.cast_mut(), |r| {
            let sun = r.sun.as_ref().ok_or_else(|| wrong_order("no sun set (srug_renderer_set_sun first)"))?;
            // SAFETY: the caller's contract: 3 floats each, checked non-null.
            let (d, l) = unsafe { (slice_mut(direction, 3, "direction")?, slice_mut(radiance, 3, "radiance")?) };
            d.copy_from_slice(&sun.direction.to_array());
            l.copy_from_slice(&sun.intensity);
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

/// The geometric shadow bias: `slope_bias` shadow-map texels times tan θ
/// (θ between a receiver's normal and the sun) added to the depth bias, and
/// each receiver moved `normal_offset` texels times sin θ along its normal;
/// each 0 to 100 (the presets: 3 and 0).
#[no_mangle]
pub extern "C" fn srug_renderer_set_shadow_geometry_bias(
    renderer: *mut srug_renderer,
    slope_bias: f32,
    normal_offset: f32,
) -> srug_status {
    guard("srug_renderer_set_shadow_geometry_bias", || {
        with_renderer(renderer, |r| {
            let mut s = r.settings.shadow;
            s.slope_bias = slope_bias;
            s.normal_offset = normal_offset;
            s.validate()?;
            r.settings.shadow = s;
            Ok(())
        })
    })
}

/// The frame channel `SRUG_CHANNEL_*` names, if any.
pub(crate) fn frame_channel(channel: srug_channel) -> Option<FrameChannel> {
    Some(match channel {
        SRUG_CHANNEL_RGB => FrameChannel::Rgb,
        SRUG_CHANNEL_ALPHA => FrameChannel::Alpha,
        SRUG_CHANNEL_DEPTH => FrameChannel::GBuffer(Channel::Depth),
        SRUG_CHANNEL_MEDIAN_DEPTH => FrameChannel::GBuffer(Channel::MedianDepth),
        SRUG_CHANNEL_NORMAL => FrameChannel::GBuffer(Channel::Normal),
        SRUG_CHANNEL_ALBEDO => FrameChannel::GBuffer(Channel::Albedo),
        SRUG_CHANNEL_ROUGHNESS => FrameChannel::GBuffer(Channel::Roughness),
        SRUG_CHANNEL_METALLIC => FrameChannel::GBuffer(Channel::Metallic),
        SRUG_CHANNEL_AO => FrameChannel::GBuffer(Channel::Ao),
        SRUG_CHANNEL_VISIBILITY => FrameChannel::GBuffer(Channel::Visibility),
        SRUG_CHANNEL_SUN_LIGHT => FrameChannel::SunLight,
        SRUG_CHANNEL_SKY_LIGHT => FrameChannel::SkyLight,
        SRUG_CHANNEL_RADIANCE => FrameChannel::Radiance,
        _ => return None,
    })
}

/// The depth convention `SRUG_DEPTH_*` with its planes (checked).
pub(crate) fn depth_convention(convention: srug_depth_convention, near: f32, far: f32) -> FfiResult<HostDepth> {
    let c = match convention {
        SRUG_DEPTH_CAMERA_Z => HostDepth::CameraZ,
        SRUG_DEPTH_VULKAN => HostDepth::Vulkan { near, far },
        SRUG_DEPTH_REVERSED_Z => HostDepth::ReversedZ { near, far },
        other => return Err(invalid(format!("unknown depth convention {other}"))),
    };
    c.validate()?;
    Ok(c)
}

/// Hides the splats behind the host's depth in the renders that follow, for
/// compositing over the host's meshes: `depth` holds one value per pixel of
/// the renderer's size (row-major, `count` = width × height) in `convention`
/// (`SRUG_DEPTH_*`; `near` and `far` are the planes of the Vulkan and
/// reversed-Z conventions); a splat whose depth at a pixel is not in front of
/// the host's is hidden there: it neither colours nor covers the pixel, so the
/// alpha channel is the coverage by the splats in front of the host's meshes.
/// With a black background (`srug_renderer_set_background`) the linear
/// radiance (`SRUG_FORMAT_RGBA32F_LINEAR`) is premultiplied: composite it as
/// `rgb + (1 − alpha)·host` in linear light. Shadows are unchanged. NULL `depth` stops hiding. The values are copied. A preset
/// rendering below full size (fast) then fails at render with a size mismatch.
///
/// # Safety
/// `depth` NULL or valid for `count` floats.
#[no_mangle]
pub unsafe extern "C" fn srug_renderer_set_host_depth(
    renderer: *mut srug_renderer,
    depth: *const f32,
    count: usize,
    convention: srug_depth_convention,
    near: f32,
    far: f32,
) -> srug_status {
    guard("srug_renderer_set_host_depth", || {
        let convention = depth_convention(convention, near, far)?;
        with_renderer(renderer, |r| {
            if depth.is_null() {
                r.relighter.set_host_depth(None)?;
                return Ok(());
            }
            convention.validate()?;
            let pixels = r.width as usize * r.height as usize;
            if count != pixels {
                return Err(invalid(format!(
                    "host depth of {count} values for a {}x{} renderer ({pixels} pixels)",
                    r.width, r.height
                )));
            }
            // SAFETY: the caller's contract: `count` floats at `depth`.
            let values = unsafe { std::slice::from_raw_parts(depth, count) };
            if let Some(i) = values.iter().position(|v| v.is_nan()) {
                return Err(invalid(format!("host depth value {i} is NaN")));
            }
            let buffer = r.device.upload("host depth", values)?;
            r.relighter.set_host_depth(Some(HostDepthImage {
                buffer,
                width: r.width,
                height: r.height,
                convention,
            }))?;
            Ok(())
        })
    })
}

/// What relit frames show behind the splats: `rgb` a constant linear radiance
/// (3 finite floats ≥ 0; black gives premultiplied radiance for compositing),
/// or NULL for the sky light's environment (the default).
///
/// # Safety
/// `rgb` NULL or valid for 3 floats.
#[no_mangle]
pub unsafe extern "C" fn srug_renderer_set_background(renderer: *mut srug_renderer, rgb: *const f32) -> srug_status {
    guard("srug_renderer_set_background", || {
        let background = if rgb.is_null() {
            Background::Environment
        } else {
            // SAFETY: the caller's contract: 3 floats.
            let c = unsafe { std::slice::from_raw_parts(rgb, 3) };
            Background::Color([c[0], c[1], c[2]])
        };
        with_renderer(renderer, |r| {
            let mut shade = r.settings.shade;
            shade.background = background;
            shade.validate()?;
            r.settings.shade = shade;
            Ok(())
        })
    })
}

/// What the shadow map covers (`SRUG_SHADOW_FIT_*`); `srug_renderer_set_preset` resets it.
#[no_mangle]
pub extern "C" fn srug_renderer_set_shadow_fit(renderer: *mut srug_renderer, fit: srug_shadow_fit) -> srug_status {
    guard("srug_renderer_set_shadow_fit", || {
        let fit = match fit {
            SRUG_SHADOW_FIT_SCENE => ShadowFit::SceneBounds,
            SRUG_SHADOW_FIT_VIEW => ShadowFit::ViewFrustum,
            SRUG_SHADOW_FIT_CASCADES => ShadowFit::Cascades,
            other => return Err(invalid(format!("unknown shadow fit {other}"))),
        };
        with_renderer(renderer, |r| {
            r.settings.shadow.fit = fit;
            Ok(())
        })
    })
}

/// How many maps `SRUG_SHADOW_FIT_CASCADES` uses, 2 to 4 (3 by default; each
/// of the shadow resolution); `srug_renderer_set_preset` resets it.
#[no_mangle]
pub extern "C" fn srug_renderer_set_shadow_cascades(renderer: *mut srug_renderer, count: u32) -> srug_status {
    guard("srug_renderer_set_shadow_cascades", || {
        with_renderer(renderer, |r| {
            let mut s = r.settings.shadow;
            s.cascades = count;
            s.validate()?;
            r.settings.shadow = s;
            Ok(())
        })
    })
}

/// How the shadow test reads the map (`SRUG_SHADOW_FILTER_*`; both
/// differentiable); `srug_renderer_set_preset` resets it.
#[no_mangle]
pub extern "C" fn srug_renderer_set_shadow_filter(
    renderer: *mut srug_renderer,
    filter: srug_shadow_filter,
) -> srug_status {
    guard("srug_renderer_set_shadow_filter", || {
        let filter = match filter {
            SRUG_SHADOW_FILTER_PCF => ShadowFilter::Pcf,
            SRUG_SHADOW_FILTER_DEPTH => ShadowFilter::Depth,
            other => return Err(invalid(format!("unknown shadow filter {other}"))),
        };
        with_renderer(renderer, |r| {
            r.settings.shadow.filter = filter;
            Ok(())
        })
    })
}

/// Shadow maps splatted only where the frame's receivers look them up even
/// with `srug_renderer_set_shadow_map_reuse` on (off by default): the same
/// shadows for less, but a map per camera, so a kept map is reused only for
/// the same camera. Without reuse the renderer culls anyway (its map serves
/// one frame).
#[no_mangle]
pub extern "C" fn srug_renderer_set_shadow_cull(renderer: *mut srug_renderer, on: bool) -> srug_status {
    guard("srug_renderer_set_shadow_cull", || {
        with_renderer(renderer, |r| {
            r.settings.shadow.cull_to_receivers = on;
            Ok(())
        })
    })
}

/// Surface depths on or off: each splat's depth at a pixel where the pixel's
/// ray meets the splat's plane (its shortest axis) rather than its centre's,
/// for the depth channels and the shadow's receivers (on by default, as in
/// the presets; differentiated by `srug_renderer_shadow_backward`).
#[no_mangle]
pub extern "C" fn srug_renderer_set_surface_depth(renderer: *mut srug_renderer, on: bool) -> srug_status {
    guard("srug_renderer_set_surface_depth", || {
        with_renderer(renderer, |r| {
            r.settings.shadow.surface_depth = on;
            Ok(())
        })
    })
}

/// Surface depths for the shadow map's occluders too (off by default, as in
/// the presets: docs/stages.md says why).
#[no_mangle]
pub extern "C" fn srug_renderer_set_map_surface_depth(renderer: *mut srug_renderer, on: bool) -> srug_status {
    guard("srug_renderer_set_map_surface_depth", || {
        with_renderer(renderer, |r| {
            r.settings.shadow.map_surface_depth = on;
            Ok(())
        })
    })
}

/// The coverages the shadow test reads its depths at (median depths), each
/// strictly between 0 and 1 (the presets: 0.6 and 0.45): `map` for a
/// shadow-map texel to hold an occluder (at 0.5 each splat's half-coverage
/// outline casts, so shadows come out wider than their casters; more draws
/// them in), `receivers` for a pixel to receive (below 0.5 a wall whose
/// splats leave gaps still receives where the camera sees through them; the
/// median depth channel read back follows it). docs/stages.md, "Map coverage".
#[no_mangle]
pub extern "C" fn srug_renderer_set_shadow_coverage(
    renderer: *mut srug_renderer,
    map: f32,
    receivers: f32,
) -> srug_status {
    guard("srug_renderer_set_shadow_coverage", || {
        with_renderer(renderer, |r| {
            let mut s = r.settings.shadow;
            (s.map_coverage, s.receiver_coverage) = (map, receivers);
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
            s.rgb = r.settings.rgb;
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
        if !(-64.0..=64.0).contains(&exposure_ev) {
            return Err(invalid(format!("exposure_ev {exposure_ev} is outside -64..=64 stops")));
        }
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

    pub(crate) fn render(&mut self, scene: &SceneObject) -> FfiResult {
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
                    surface_depth: self.settings.shadow.surface_depth,
                    ..SplatSettings::default()
                };
                let camera = self.settings.render_camera(&camera);
                let (gbuffer, stats) = self.relighter.splat_camera(&scene.gpu, &camera, &settings)?;
                self.frame = Some(Frame { gbuffer, shaded: None, display: None });
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
        self.frame = Some(Frame {
            gbuffer: relit.gbuffer,
            shaded: Some(relit.shaded),
            display: Some((relit.exposure_ev, relit.tone_map)),
        });
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
            let needed = stride
                .checked_mul(h - 1)
                .and_then(|v| v.checked_add(row))
                .ok_or_else(|| invalid(format!("row_stride {stride} × {h} rows overflows the address space")))?;
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
            let which = frame_channel(channel).ok_or_else(|| invalid(format!("unknown channel {channel}")))?;
            let buffer = which.resolve(&f.gbuffer, f.shaded.as_ref()).ok_or_else(|| {
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
            if name_len > 0 {
                // SAFETY: the caller's contract. A name that does not fit is
                // copied cut (like `srug_last_error`) and `seconds` is not written.
                unsafe { copy_text(&s.name, name, name_len, std::ptr::null_mut()) }?;
            }
            // SAFETY: checked non-null; the caller's contract.
            unsafe { seconds.write(s.seconds) };
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
            let receivers = splatter.render_frame(&s.gpu, &camera, &settings.receiver_splat())?;
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
