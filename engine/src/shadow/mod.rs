//! Sun shadows: the sigmoid shadow map and the traced reference.
//!
//! The scene's depth is splatted from the sun by the splatting pipeline with
//! an orthographic light camera ([`light_camera`]) into a [`ShadowMap`]. Each
//! receiver pixel of a camera G-buffer is turned back into a world point,
//! projected into light space, and compared with the bilinearly sampled map
//! depth z_s through the paper's soft test V_e = σ(k·(z_s − z + bias)) (the
//! *sigmoid shadow map*; docs/conventions.md §5 has the numerics). `[ShadowPass::traced]`
//! computes the accurate transmittance toward the sun from the same light
//! splat, the reference the sigmoid test is measured against.
//!
//! Invariants:
//! - the logit is clamped to ±30 and σ evaluated as exp(−|x|)-based, so V_e
//!   is finite for every k and depth difference (k from 1e-3 to 1e9 tested);
//! - expected depths are normalised by alpha (Σwz / Σw); texels and receivers
//!   with alpha below `min_alpha` (or no median crossing) have no surface:
//!   empty texels read as the light's far depth, receivers without a surface
//!   and points outside the map are lit (V = 1);
//! - a sun at or below the horizon gives no sun light: no pass runs and
//!   [`ShadowPass::shadow_map`] returns `None`.
//!
//! [`cpu`] is the f64 twin.

pub mod backward;
pub mod completion;
pub mod cpu;
pub mod sun;

use bytemuck::{Pod, Zeroable};
use glam::Vec3;
use std::sync::Arc;

pub use self::sun::{solar_position, sun_path, SolarPosition, Sun, UtcTime};
use crate::error::{Error, Result};
use crate::gpu::{
    kernels, BindingKind, Buffer, Device, DeviceAddress, Kernel, KernelDecl, MemoryKind, Recording, SpecValue, Timings,
};
use crate::primitives::sort::RadixSort;
use crate::scene::activate::GpuScene;
use crate::scene::{Bounds, Camera, Projection};
use crate::splat::{Channels, GpuGBuffer, SplatFrame, SplatSettings, Splatter};

/// Which depth a G-buffer gives for shadows.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum DepthMode {
    /// Depth where transmittance first falls to 0.5: robust at silhouettes.
    #[default]
    Median,
    /// Alpha-normalised blended depth Σwz / Σw: smooth, differentiable, but
    /// mixes depths at silhouettes (light leaks, floating shadows).
    Expected,
    /// Shadow maps only: blended depth with empty space one scene depth
    /// beyond the light's far plane, Σwz + T·(2·far). Differentiable
    /// everywhere, also where nothing is yet (faint Gaussians cast faint
    /// shadows), so optimisation can grow occluders from nothing; a texel needs
    /// about half coverage to shadow what lies behind it.
    ExpectedOverFar,
}

impl DepthMode {
    /// Parses `median` or `expected`.
    pub fn parse(text: &str) -> Result<Self> {
        match text {
            "median" => Ok(Self::Median),
            "expected" => Ok(Self::Expected),
            "expected-over-far" => Ok(Self::ExpectedOverFar),
            other => {
                Err(Error::invalid(format!("depth mode \"{other}\""), "is not median, expected or expected-over-far"))
            }
        }
    }

    /// The depth a texel with nothing in it reads as, for a light camera whose
    /// far plane is `far`: `far` (median, expected), `2·far` (expected over far).
    pub fn empty_depth(self, far: f32) -> f32 {
        match self {
            Self::ExpectedOverFar => 2.0 * far,
            Self::Median | Self::Expected => far,
        }
    }

    fn code(self) -> u32 {
        match self {
            Self::Expected => 0,
            Self::Median => 1,
            Self::ExpectedOverFar => 2,
        }
    }
}

/// What the light camera covers.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ShadowFit {
    /// The whole scene's bounds.
    #[default]
    SceneBounds,
    /// The receiving camera's view frustum clipped to the scene bounds (finer
    /// texels for the same resolution; occluders anywhere in the bounds still
    /// cast, since the depth range stays the scene's).
    ViewFrustum,
}

/// Shadow quality knobs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShadowSettings {
    /// Shadow-map texels along its longer side.
    pub resolution: u32,
    /// Sigmoid sharpness k, per world unit.
    pub k: f32,
    /// Depth bias against self-shadowing, world units (added to z_s − z).
    pub bias: f32,
    /// Depth of the shadow map.
    pub map_depth: DepthMode,
    /// Depth of the receivers (the camera G-buffer).
    pub receiver_depth: DepthMode,
    /// Light camera fit.
    pub fit: ShadowFit,
    /// Alpha below which a texel or a receiver has no surface.
    pub min_alpha: f32,
    /// Fill outputs with this 32-bit word first (tests use NaN, so an
    /// unwritten pixel cannot pass for a value).
    pub prefill: Option<u32>,
    /// Tile edge of the shadow map's splatting ([`crate::splat::TILE_SIZES`]).
    pub tile: u32,
}

impl Default for ShadowSettings {
    fn default() -> Self {
        Self {
            resolution: 2048,
            k: 50.0,
            bias: 0.15,
            map_depth: DepthMode::Median,
            receiver_depth: DepthMode::Expected,
            fit: ShadowFit::SceneBounds,
            min_alpha: 0.5,
            prefill: None,
            tile: crate::splat::DEFAULT_TILE,
        }
    }
}

impl ShadowSettings {
    /// Checks the values.
    pub fn validate(&self) -> Result<()> {
        crate::splat::check_tile(self.tile)?;
        let ok = self.resolution > 0
            && self.resolution <= 16384
            && self.k.is_finite()
            && self.k > 0.0
            && self.bias.is_finite()
            && self.min_alpha > 0.0
            && self.min_alpha <= 1.0
            && self.receiver_depth != DepthMode::ExpectedOverFar;
        if ok {
            Ok(())
        } else {
            Err(Error::invalid(
                format!(
                    "shadow settings (resolution {}, k {}, bias {}, minimum alpha {}, receiver depth {:?})",
                    self.resolution, self.k, self.bias, self.min_alpha, self.receiver_depth
                ),
                "need a resolution in 1..=16384, k positive and finite, a finite bias, a minimum alpha in (0, 1] \
                 and a median or expected receiver depth",
            ))
        }
    }

    /// The G-buffer channels a receiver (camera) render needs for these settings.
    pub fn receiver_channels(&self) -> Channels {
        depth_channels(self.receiver_depth)
    }
}

/// The shadow map's G-buffer channel for a depth mode.
pub fn depth_channels(mode: DepthMode) -> Channels {
    match mode {
        DepthMode::Median => Channels { median_depth: true, ..Channels::default() },
        DepthMode::Expected | DepthMode::ExpectedOverFar => Channels { depth: true, ..Channels::default() },
    }
}

/// The orthographic camera looking along the sunlight that covers `bounds`
/// (padded), or with [`ShadowFit::ViewFrustum`] the part of them `view`
/// sees, with `resolution` texels along its longer side and square texels.
pub fn light_camera(
    bounds: &Bounds,
    sun: &Sun,
    resolution: u32,
    fit: ShadowFit,
    view: Option<&Camera>,
) -> Result<Camera> {
    if resolution == 0 || resolution > 16384 {
        return Err(Error::invalid(format!("shadow-map resolution {resolution}"), "is not in 1..=16384"));
    }
    let (lo, hi) = (Vec3::from_array(bounds.min), Vec3::from_array(bounds.max));
    if !lo.is_finite() || !hi.is_finite() || lo.cmpgt(hi).any() {
        return Err(Error::invalid(format!("scene bounds {lo}..{hi}"), "are not a box"));
    }
    let diagonal = (hi - lo).length();
    let pad = 0.02 * diagonal + 1e-3 * (lo.abs().max(hi.abs()).max_element() + 1.0);
    let (lo, hi) = (lo - pad, hi + pad);
    let centre = 0.5 * (lo + hi);
    let towards = -sun.direction;
    let up = if sun.direction.z.abs() > 0.999 { Vec3::Y } else { Vec3::Z };
    let rotation = crate::camera::look_rotation(centre, centre + towards, up)?;
    let to_light = |p: Vec3| rotation.transpose() * (p - centre);
    let corners = |a: Vec3, b: Vec3| {
        (0..8).map(move |i| Vec3::new([a.x, b.x][i & 1], [a.y, b.y][(i >> 1) & 1], [a.z, b.z][i >> 2]))
    };
    let depth_range =
        corners(lo, hi).map(|c| to_light(c).z).fold((f32::MAX, f32::MIN), |(a, b), z| (a.min(z), b.max(z)));
    let (xy_lo, xy_hi) = match (fit, view) {
        (ShadowFit::ViewFrustum, Some(v)) => frustum_box(v, lo, hi).unwrap_or((lo, hi)),
        (ShadowFit::ViewFrustum, None) => {
            return Err(Error::invalid("view-frustum shadow fit", "needs the view camera"))
        }
        (ShadowFit::SceneBounds, _) => (lo, hi),
    };
    let (mut min, mut max) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
    for c in corners(xy_lo, xy_hi) {
        let l = to_light(c);
        min = min.min(l);
        max = max.max(l);
    }
    let extent = (max - min).truncate().max(glam::Vec2::splat(1e-6 * diagonal.max(1e-6)));
    let long = extent.max_element();
    let width = ((resolution as f32 * extent.x / long).round() as u32).max(1);
    let height = ((resolution as f32 * extent.y / long).round() as u32).max(1);
    let depth = depth_range.1 - depth_range.0;
    let near = 1e-3 * depth.max(1e-6);
    let eye_light = Vec3::new(0.5 * (min.x + max.x), 0.5 * (min.y + max.y), depth_range.0 - 2.0 * near);
    let eye = centre + rotation * eye_light;
    // Texels are square: the extent along the shorter side is rounded up to whole texels.
    let texel = long / resolution as f32;
    let mut camera = Camera::orthographic(
        eye,
        towards,
        up,
        width as f32 * texel,
        height as f32 * texel,
        width,
        height,
        near,
        depth + 4.0 * near,
    )?;
    camera.name = "sun".into();
    Ok(camera)
}

/// The box of `view`'s frustum (far plane at the farthest bounds corner)
/// clipped to [lo, hi]; `None` where they do not meet.
fn frustum_box(view: &Camera, lo: Vec3, hi: Vec3) -> Option<(Vec3, Vec3)> {
    let far = (0..8)
        .map(|i| Vec3::new([lo.x, hi.x][i & 1], [lo.y, hi.y][(i >> 1) & 1], [lo.z, hi.z][i >> 2]))
        .map(|c| view.world_to_camera(c).z)
        .fold(view.near, f32::max)
        .min(view.far);
    let (w, h) = (view.width as f32, view.height as f32);
    let mut bmin = Vec3::splat(f32::MAX);
    let mut bmax = Vec3::splat(f32::MIN);
    for z in [view.near, far] {
        for (u, v) in [(0.0, 0.0), (w, 0.0), (0.0, h), (w, h)] {
            let c = match view.projection {
                Projection::Pinhole { fx, fy, cx, cy } => Vec3::new((u - cx) / fx * z, (v - cy) / fy * z, z),
                Projection::Orthographic { sx, sy, cx, cy } => Vec3::new((u - cx) / sx, (v - cy) / sy, z),
            };
            let p = view.rotation * c + view.position;
            bmin = bmin.min(p);
            bmax = bmax.max(p);
        }
    }
    let (a, b) = (bmin.max(lo), bmax.min(hi));
    (a.cmplt(b).all() && a.is_finite() && b.is_finite()).then_some((a, b))
}

/// A shadow map: the scene splatted from the sun, with the frame kept for the
/// traced pass.
pub struct ShadowMap {
    /// The light camera.
    pub camera: Camera,
    /// The sun it was made for.
    pub sun: Sun,
    /// Which depth its texels hold.
    pub depth: DepthMode,
    /// The light-space splat (G-buffers: alpha plus the depth channel).
    pub frame: SplatFrame,
}

impl ShadowMap {
    /// The texels' depth z_s on the host (empty texels: [`DepthMode::empty_depth`]).
    pub fn read_depth(&self, device: &Device, min_alpha: f32) -> Result<Vec<f32>> {
        let g = self.frame.gbuffer.read(device)?;
        Ok(cpu::resolve_depths(self.depth, &g, min_alpha, self.depth.empty_depth(self.camera.far)))
    }
}

/// The shadow kernels' uniform: `Shadow` in `shadow.glsl` (std140; checked
/// against it by `check_layout`). Addresses are filled by
/// `ShadowUniform::record` in the recording that dispatches with it.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct ShadowUniform {
    cam_rot0: [f32; 4],
    cam_rot1: [f32; 4],
    cam_rot2: [f32; 4],
    cam_pos: [f32; 4],
    cam_intr: [f32; 4],
    light_rot0: [f32; 4],
    light_rot1: [f32; 4],
    light_rot2: [f32; 4],
    light_t: [f32; 4],
    light_intr: [f32; 4],
    size: [u32; 4],
    params: [f32; 4],
    modes: [u32; 4],
    receiver_depth: DeviceAddress,
    receiver_alpha: DeviceAddress,
    map_depth: DeviceAddress,
    map_alpha: DeviceAddress,
    visibility: DeviceAddress,
    unused0: DeviceAddress,
    splats: DeviceAddress,
    sorted_gaussians: DeviceAddress,
    ranges: DeviceAddress,
    unused1: DeviceAddress,
}
crate::gpu::gpu_layout!(
    ShadowUniform,
    "Shadow",
    [
        cam_rot0,
        cam_rot1,
        cam_rot2,
        cam_pos,
        cam_intr,
        light_rot0,
        light_rot1,
        light_rot2,
        light_t,
        light_intr,
        size,
        params,
        modes,
        receiver_depth,
        receiver_alpha,
        map_depth,
        map_alpha,
        visibility,
        unused0,
        splats,
        sorted_gaussians,
        ranges,
        unused1
    ]
);

impl ShadowUniform {
    /// Takes every address through `rec` (which keeps the buffers borrowed
    /// until it is submitted) and writes the uniform into `uniform`.
    /// `visibility` is the forward's output (none in the backward pass).
    pub(crate) fn record<'a>(
        mut self,
        rec: &mut Recording<'a>,
        uniform: &'a Buffer,
        inputs: &ShadowInputs<'a>,
        visibility: Option<&'a Buffer>,
    ) -> Result<()> {
        self.receiver_depth = rec.addr(inputs.receiver_depth)?;
        self.receiver_alpha = rec.addr(inputs.receiver_alpha)?;
        self.map_depth = rec.addr(inputs.map_depth)?;
        self.map_alpha = rec.addr(&inputs.map.frame.gbuffer.alpha)?;
        self.visibility = rec.addr_or_null(visibility)?;
        self.splats = rec.addr(&inputs.map.frame.splats)?;
        self.sorted_gaussians = rec.addr(&inputs.map.frame.sorted_gaussians)?;
        self.ranges = rec.addr(&inputs.map.frame.ranges)?;
        Ok(rec.update(uniform, 0, &self)?)
    }
}

fn intrinsics(camera: &Camera) -> ([f32; 4], f32) {
    match camera.projection {
        Projection::Pinhole { fx, fy, cx, cy } => ([fx, fy, cx, cy], 0.0),
        Projection::Orthographic { sx, sy, cx, cy } => ([sx, sy, cx, cy], 1.0),
    }
}

/// The shadow kernels (forward and backward) and the backward's sort scratch.
pub struct ShadowPass {
    device: Device,
    test: Arc<Kernel>,
    traced: Arc<Kernel>,
    backward_upstream: Arc<Kernel>,
    backward_bce: Arc<Kernel>,
    bins: Arc<Kernel>,
    gather: Arc<Kernel>,
    sort: RadixSort,
}

/// Which visibility [`ShadowPass::visibility`] computes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum VisibilityKind {
    /// The sigmoid shadow test V_e.
    #[default]
    Sigmoid,
    /// The traced transmittance V_t.
    Traced,
}

impl ShadowPass {
    /// Builds the kernels.
    pub fn new(device: &Device) -> Result<Self> {
        let decl = KernelDecl { bindings: &[BindingKind::UniformBuffer], push_constant_size: 0, specialization: &[] };
        let two = [BindingKind::UniformBuffer, BindingKind::UniformBuffer];
        let backward = |loss: u32| {
            let spec = [(0, SpecValue::U32(loss))];
            Kernel::cached(
                device,
                &kernels::SHADOW_BACKWARD,
                &KernelDecl { bindings: &two, push_constant_size: 4, specialization: &spec },
            )
        };
        let plain = KernelDecl { bindings: &two, push_constant_size: 0, specialization: &[] };
        Ok(Self {
            device: device.clone(),
            test: Kernel::cached(device, &kernels::SHADOW_TEST, &decl)?,
            traced: Kernel::cached(device, &kernels::SHADOW_TRACED, &decl)?,
            backward_upstream: backward(0)?,
            backward_bce: backward(1)?,
            bins: Kernel::cached(
                device,
                &kernels::SHADOW_BINS,
                &KernelDecl {
                    bindings: &[],
                    push_constant_size: std::mem::size_of::<backward::BinsPush>(),
                    specialization: &[],
                },
            )?,
            gather: Kernel::cached(device, &kernels::SHADOW_TEXEL_GRADS, &plain)?,
            sort: RadixSort::new(device)?,
        })
    }

    /// Splats the scene from the sun; `None` when the sun is at or below the
    /// horizon (no sun light, nothing runs). `bounds` are the scene's; `view`
    /// is needed for [`ShadowFit::ViewFrustum`].
    pub fn shadow_map(
        &self,
        splatter: &mut Splatter,
        scene: &GpuScene,
        bounds: &Bounds,
        sun: &Sun,
        settings: &ShadowSettings,
        view: Option<&Camera>,
    ) -> Result<Option<ShadowMap>> {
        settings.validate()?;
        if !sun.above_horizon() {
            return Ok(None);
        }
        let camera = light_camera(bounds, sun, settings.resolution, settings.fit, view)?;
        self.shadow_map_from(splatter, scene, camera, sun, settings).map(Some)
    }

    /// Splats the scene into a shadow map from a given light camera (fixed
    /// across optimisation steps, say); the sun must be above the horizon.
    pub fn shadow_map_from(
        &self,
        splatter: &mut Splatter,
        scene: &GpuScene,
        camera: Camera,
        sun: &Sun,
        settings: &ShadowSettings,
    ) -> Result<ShadowMap> {
        settings.validate()?;
        if !sun.above_horizon() || !matches!(camera.projection, Projection::Orthographic { .. }) {
            return Err(Error::invalid("shadow map", "needs a sun above the horizon and an orthographic camera"));
        }
        let splat = SplatSettings {
            channels: depth_channels(settings.map_depth),
            tile: settings.tile,
            // The map is depth and alpha only: no colour to evaluate or read.
            rgb: false,
            ..SplatSettings::default()
        };
        let mut frame = splatter.render_frame(scene, &camera, &splat)?;
        for stage in &mut frame.stats.timings.stages {
            stage.name = format!("shadow map {}", stage.name);
        }
        Ok(ShadowMap { camera, sun: *sun, depth: settings.map_depth, frame })
    }

    /// Per-pixel visibility of the receivers in `gbuffer` (rendered from
    /// `camera` with [`ShadowSettings::receiver_channels`]): the sigmoid test or
    /// the traced reference. Returns the buffer (float per pixel) and its GPU time.
    pub fn visibility(
        &self,
        map: &ShadowMap,
        gbuffer: &GpuGBuffer,
        camera: &Camera,
        settings: &ShadowSettings,
        kind: VisibilityKind,
    ) -> Result<(Buffer, Timings)> {
        let device = &self.device;
        let pixels = u64::from(camera.width) * u64::from(camera.height);
        let out = device.create_buffer("visibility", pixels * 4, MemoryKind::Storage)?;
        let (u, inputs) = shadow_uniform(map, gbuffer, camera, settings)?;
        let uniform =
            device.create_buffer("shadow uniform", std::mem::size_of::<ShadowUniform>() as u64, MemoryKind::Storage)?;
        let (kernel, stage) = match kind {
            VisibilityKind::Sigmoid => (&self.test, "sigmoid shadow test"),
            VisibilityKind::Traced => (&self.traced, "traced visibility"),
        };
        let timings = device.run(|rec| -> Result<()> {
            u.record(rec, &uniform, &inputs, Some(&out))?;
            if let Some(word) = settings.prefill {
                rec.fill(&out, word)?;
            }
            rec.begin_stage(stage);
            rec.dispatch_1d(kernel, &[&uniform], &(), pixels)?;
            rec.end_stage();
            Ok(())
        })?;
        Ok((out, timings))
    }
}

/// The buffers the shadow kernels read: the receiver's and the map's depth
/// channels the settings select, the receiver's alpha, and the map itself.
pub(crate) struct ShadowInputs<'a> {
    pub(crate) receiver_depth: &'a Buffer,
    pub(crate) receiver_alpha: &'a Buffer,
    pub(crate) map_depth: &'a Buffer,
    pub(crate) map: &'a ShadowMap,
}

/// The shadow kernels' uniform (without addresses) for `map`, receivers
/// `gbuffer` seen from `camera`, and `settings`, and the buffers it reads.
fn shadow_uniform<'a>(
    map: &'a ShadowMap,
    gbuffer: &'a GpuGBuffer,
    camera: &Camera,
    settings: &ShadowSettings,
) -> Result<(ShadowUniform, ShadowInputs<'a>)> {
    settings.validate()?;
    if (gbuffer.width, gbuffer.height) != (camera.width, camera.height) {
        return Err(Error::invalid(
            format!("G-buffer {}x{}", gbuffer.width, gbuffer.height),
            format!("does not match camera {}x{}", camera.width, camera.height),
        ));
    }
    if settings.map_depth != map.depth {
        return Err(Error::invalid(
            format!("shadow map of {:?} depth", map.depth),
            format!("does not match the settings' {:?} depth", settings.map_depth),
        ));
    }
    let receiver_depth = match settings.receiver_depth {
        DepthMode::Median => gbuffer.median_depth.as_ref(),
        DepthMode::Expected | DepthMode::ExpectedOverFar => gbuffer.depth.as_ref(),
    }
    .ok_or_else(|| {
        Error::invalid(
            "receiver G-buffer",
            format!("lacks the {:?} depth channel the shadow settings ask for", settings.receiver_depth),
        )
    })?;
    let g = &map.frame.gbuffer;
    let map_depth = match map.depth {
        DepthMode::Median => g.median_depth.as_ref(),
        DepthMode::Expected | DepthMode::ExpectedOverFar => g.depth.as_ref(),
    }
    .ok_or_else(|| Error::Internal("the shadow map lacks its depth channel".into()))?;
    let mut u = ShadowUniform::zeroed();
    let r = camera.rotation;
    for (row, i) in [&mut u.cam_rot0, &mut u.cam_rot1, &mut u.cam_rot2].into_iter().zip(0..3) {
        *row = [r.x_axis[i], r.y_axis[i], r.z_axis[i], 0.0];
    }
    let (cam_k, cam_kind) = intrinsics(camera);
    u.cam_pos = [camera.position.x, camera.position.y, camera.position.z, cam_kind];
    u.cam_intr = cam_k;
    let l = &map.camera;
    let w = l.rotation.transpose();
    for (row, i) in [&mut u.light_rot0, &mut u.light_rot1, &mut u.light_rot2].into_iter().zip(0..3) {
        *row = [w.x_axis[i], w.y_axis[i], w.z_axis[i], 0.0];
    }
    let t = -(w * l.position);
    u.light_t = [t.x, t.y, t.z, l.far];
    u.light_intr = intrinsics(l).0;
    u.size = [camera.width, camera.height, l.width, l.height];
    u.params = [settings.k, settings.bias, settings.min_alpha, map.depth.empty_depth(l.far)];
    u.modes = [map.depth.code(), settings.receiver_depth.code(), map.frame.tiles().0, map.frame.tile];
    Ok((u, ShadowInputs { receiver_depth, receiver_alpha: &gbuffer.alpha, map_depth, map }))
}

#[cfg(test)]
mod layout_tests {
    use super::backward::{BinsPush, ShadowBackwardUniform};
    use super::ShadowUniform;
    use crate::gpu::{check_layout, kernels};

    /// The host structs match the GLSL blocks of every kernel that declares them.
    #[test]
    fn uniform_layouts_match_glsl() {
        let shadow = check_layout::<ShadowUniform>(kernels::ALL);
        assert!(shadow.as_ref().is_ok_and(|n| *n >= 4), "{shadow:?}");
        let backward = check_layout::<ShadowBackwardUniform>(kernels::ALL);
        assert!(backward.as_ref().is_ok_and(|n| *n >= 2), "{backward:?}");
        assert_eq!(check_layout::<BinsPush>(&[&kernels::SHADOW_BINS]), Ok(1));
    }
}
