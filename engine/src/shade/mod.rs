//! Physically based deferred shading and relighting: the final image from
//! the G-buffers as the SRUG paper computes it (appendix, docs/conventions.md §6):
//! L_o = L_sun + L_sky + L_ind, composited over the background, then
//! exposure, tone mapping and sRGB encoding.
//!
//! - **Sun**: f_r · S_i · V · max(N·L, 0) with the simplified Cook–Torrance
//!   BRDF: diffuse (1 − m)·a/π; specular D·F·G / (4 (N·L)(N·V)) with GGX D
//!   (α = r²), Schlick F (F0 = mix(0.04, albedo, metallic)), Schlick–Smith G
//!   with k = (r + 1)²/8. V is the fixed visibility blended from the Gaussians
//!   (novel views), the editable sigmoid-shadow-map visibility (relighting),
//!   or none.
//! - **Sky**: split-sum image-based lighting from a [`env::PreparedEnvironment`]
//!   (GGX-prefiltered chain indexed by roughness, irradiance map) and a
//!   [`env::BrdfTable`] (Karis or height-correlated); sky diffuse is multiplied
//!   by the blended ambient occlusion.
//! - **Indirect**: an optional per-pixel L_ind buffer (the U-Net's); without
//!   one nothing runs for it.
//!
//! Two kernels: `shade_lights.comp` writes L_sun and L_sky (inputs of the
//! indirect network), `shade_compose.comp` sums, composites and encodes.
//! Invariants: G-buffer channels are premultiplied by alpha and divided by it
//! here (clamped to [0, 1]); pixels with alpha below `min_alpha` show only the
//! background; N·V is clamped to ≥ 1e-4; every output is finite for finite
//! inputs (roughness 0 and 1, N·V = 0, N·L < 0 and radiance 1e5 are tested).
//! [`cpu`] is the f64 twin.

pub mod cpu;
pub mod env;
pub mod ktx;
pub mod sky;

use std::sync::Arc;

use bytemuck::{Pod, Zeroable};

pub use self::env::{BrdfLut, BrdfTable, EnvironmentMap, EnvironmentPrep, PrepareSettings, PreparedEnvironment};
pub use self::sky::ProceduralSky;
use crate::error::{Error, Result};
use crate::gpu::{
    kernels, BindingKind, Buffer, Device, DeviceAddress, Kernel, KernelDecl, MemoryKind, Recording, SpecValue, Timings,
};
use crate::scene::{Camera, Projection};
use crate::shadow::Sun;
use crate::splat::{Channels, GpuGBuffer};

/// Which sun visibility V multiplies L_sun.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum VisibilitySource {
    /// V = 1: no shadows.
    None,
    /// The fixed visibility V_f blended from the Gaussians (novel views under the captured sun).
    Fixed,
    /// The editable visibility V_e from the sigmoid shadow map (relighting).
    #[default]
    Editable,
}

impl VisibilitySource {
    /// Parses `none`, `fixed` or `editable`.
    pub fn parse(text: &str) -> Result<Self> {
        match text {
            "none" => Ok(Self::None),
            "fixed" => Ok(Self::Fixed),
            "editable" => Ok(Self::Editable),
            other => Err(Error::invalid(format!("visibility \"{other}\""), "is not none, fixed or editable")),
        }
    }

    fn code(self) -> u32 {
        match self {
            Self::None => 0,
            Self::Fixed => 1,
            Self::Editable => 2,
        }
    }
}

/// Which terms of L_sun and L_sky are added (the `TERMS` specialization constant).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ShadeTerms {
    /// Sun diffuse.
    pub sun_diffuse: bool,
    /// Sun specular.
    pub sun_specular: bool,
    /// Sky diffuse (times ambient occlusion).
    pub sky_diffuse: bool,
    /// Sky specular.
    pub sky_specular: bool,
}

impl Default for ShadeTerms {
    fn default() -> Self {
        Self::ALL
    }
}

impl ShadeTerms {
    /// Every term.
    pub const ALL: Self = Self { sun_diffuse: true, sun_specular: true, sky_diffuse: true, sky_specular: true };

    /// Bit mask: 1 sun diffuse, 2 sun specular, 4 sky diffuse, 8 sky specular.
    pub fn bits(self) -> u32 {
        u32::from(self.sun_diffuse)
            | u32::from(self.sun_specular) << 1
            | u32::from(self.sky_diffuse) << 2
            | u32::from(self.sky_specular) << 3
    }
}

/// Display transform after exposure.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum ToneMap {
    /// Clamp to [0, 1] (the paper: gamma correction only).
    #[default]
    Clamp,
    /// c / (1 + c).
    Reinhard,
    /// Narkowicz's ACES filmic fit.
    Aces,
}

impl ToneMap {
    /// Parses `clamp`, `reinhard` or `aces`.
    pub fn parse(text: &str) -> Result<Self> {
        match text {
            "clamp" => Ok(Self::Clamp),
            "reinhard" => Ok(Self::Reinhard),
            "aces" => Ok(Self::Aces),
            other => Err(Error::invalid(format!("tone map \"{other}\""), "is not clamp, reinhard or aces")),
        }
    }

    fn code(self) -> u32 {
        match self {
            Self::Clamp => 0,
            Self::Reinhard => 1,
            Self::Aces => 2,
        }
    }
}

/// What uncovered pixels show.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Background {
    /// The environment along the view ray.
    Environment,
    /// A constant radiance.
    Color([f32; 3]),
}

/// Shading knobs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShadeSettings {
    /// Sun visibility.
    pub visibility: VisibilitySource,
    /// Terms added.
    pub terms: ShadeTerms,
    /// Exposure in stops (radiance × 2^ev before tone mapping).
    pub exposure_ev: f32,
    /// Tone map.
    pub tone_map: ToneMap,
    /// Background of uncovered pixels.
    pub background: Background,
    /// Alpha below which a pixel has no surface.
    pub min_alpha: f32,
    /// Environment rotation about the up axis, degrees toward east.
    pub env_rotation_degrees: f32,
    /// Environment radiance scale.
    pub env_intensity: f32,
    /// Fill outputs with this 32-bit word first (tests use NaN).
    pub prefill: Option<u32>,
}

impl Default for ShadeSettings {
    fn default() -> Self {
        Self {
            visibility: VisibilitySource::Editable,
            terms: ShadeTerms::ALL,
            exposure_ev: 0.0,
            tone_map: ToneMap::Clamp,
            background: Background::Environment,
            min_alpha: 1.0 / 255.0,
            env_rotation_degrees: 0.0,
            env_intensity: 1.0,
            prefill: None,
        }
    }
}

impl ShadeSettings {
    /// Checks the values.
    pub fn validate(&self) -> Result<()> {
        let bg_ok = match self.background {
            Background::Environment => true,
            Background::Color(c) => c.iter().all(|v| v.is_finite() && *v >= 0.0),
        };
        if !(self.exposure_ev.is_finite()
            && self.exposure_ev.abs() <= 64.0
            && self.min_alpha.is_finite()
            && self.min_alpha > 0.0
            && self.min_alpha <= 1.0
            && self.env_rotation_degrees.is_finite()
            && self.env_intensity.is_finite()
            && self.env_intensity >= 0.0
            && bg_ok)
        {
            return Err(Error::invalid(format!("shading settings {self:?}"), "are out of range"));
        }
        Ok(())
    }

    /// The G-buffer channels shading reads (normal and albedo always; the
    /// material channels the scene has; fixed visibility when selected).
    pub fn gbuffer_channels(&self, scene: &crate::scene::AttributeGroups) -> Channels {
        Channels {
            normal: true,
            albedo: true,
            roughness: scene.roughness,
            metallic: scene.metallic,
            ao: scene.ao,
            visibility: self.visibility == VisibilitySource::Fixed,
            ..Channels::default()
        }
    }
}

/// What one shading pass reads.
pub struct ShadeInputs<'a> {
    /// The camera's G-buffers (normal and albedo required).
    pub gbuffer: &'a GpuGBuffer,
    /// The camera they were rendered from.
    pub camera: &'a Camera,
    /// The sky.
    pub environment: &'a PreparedEnvironment,
    /// The environment BRDF table.
    pub brdf: &'a BrdfTable,
    /// The sun; `None` or below the horizon: no sun light.
    pub sun: Option<&'a Sun>,
    /// V_e per pixel, required with [`VisibilitySource::Editable`] and a sun.
    pub editable_visibility: Option<&'a Buffer>,
    /// L_ind computed elsewhere (planar RGB: three planes of floats); for the
    /// network's own, see [`Shader::shade_with_network`].
    pub indirect: Option<&'a Buffer>,
}

/// Shading outputs on the GPU, RGB floats per pixel.
pub struct ShadedFrame {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// L_sun of the surface (alpha-normalised attributes).
    pub sun: Buffer,
    /// L_sky of the surface.
    pub sky: Buffer,
    /// Linear radiance composited over the background.
    pub radiance: Buffer,
    /// Display values in [0, 1] (exposure, tone map, sRGB).
    pub display: Buffer,
    /// L_ind predicted by the indirect network (planar RGB), when it ran.
    pub indirect: Option<Buffer>,
    /// Per-stage GPU times.
    pub timings: Timings,
}

/// Shading outputs on the host.
#[derive(Clone, Debug, PartialEq)]
pub struct ShadedImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// L_sun.
    pub sun: Vec<f32>,
    /// L_sky.
    pub sky: Vec<f32>,
    /// Linear radiance over the background.
    pub radiance: Vec<f32>,
    /// Display values.
    pub display: Vec<f32>,
}

impl ShadedImage {
    /// Every output resampled bilinearly to `width`×`height` (a frame rendered
    /// at a lower render scale brought to the camera's size).
    pub fn resampled(&self, width: u32, height: u32) -> Result<ShadedImage> {
        if (width, height) == (self.width, self.height) {
            return Ok(self.clone());
        }
        let r = |v: &[f32]| crate::image::resample_bilinear(v, (self.width, self.height), 3, (width, height));
        Ok(ShadedImage {
            width,
            height,
            sun: r(&self.sun)?,
            sky: r(&self.sky)?,
            radiance: r(&self.radiance)?,
            display: r(&self.display)?,
        })
    }
}

impl ShadedFrame {
    /// Reads every output back.
    pub fn read(&self, device: &Device) -> Result<ShadedImage> {
        Ok(ShadedImage {
            width: self.width,
            height: self.height,
            sun: device.read_buffer(&self.sun)?,
            sky: device.read_buffer(&self.sky)?,
            radiance: device.read_buffer(&self.radiance)?,
            display: device.read_buffer(&self.display)?,
        })
    }
}

/// The shading kernels' uniform: `Shade` in `shade.glsl` (std140; checked
/// against it by `check_layout`). Addresses are filled by
/// `ShadeUniform::record` in the recording that dispatches with it.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct ShadeUniform {
    cam_rot0: [f32; 4],
    cam_rot1: [f32; 4],
    cam_rot2: [f32; 4],
    cam_pos: [f32; 4],
    cam_intr: [f32; 4],
    size: [u32; 4],
    env_size: [u32; 4],
    sun_dir: [f32; 4],
    sun_radiance: [f32; 4],
    env: [f32; 4],
    background: [f32; 4],
    display: [f32; 4],
    modes: [u32; 4],
    normal: DeviceAddress,
    albedo: DeviceAddress,
    roughness: DeviceAddress,
    metallic: DeviceAddress,
    ao: DeviceAddress,
    fixed_visibility: DeviceAddress,
    editable_visibility: DeviceAddress,
    alpha: DeviceAddress,
    specular: DeviceAddress,
    irradiance: DeviceAddress,
    brdf: DeviceAddress,
    l_sun: DeviceAddress,
    l_sky: DeviceAddress,
    l_ind: DeviceAddress,
    out_radiance: DeviceAddress,
    out_display: DeviceAddress,
}
crate::gpu::gpu_layout!(
    ShadeUniform,
    "Shade",
    [
        cam_rot0,
        cam_rot1,
        cam_rot2,
        cam_pos,
        cam_intr,
        size,
        env_size,
        sun_dir,
        sun_radiance,
        env,
        background,
        display,
        modes,
        normal,
        albedo,
        roughness,
        metallic,
        ao,
        fixed_visibility,
        editable_visibility,
        alpha,
        specular,
        irradiance,
        brdf,
        l_sun,
        l_sky,
        l_ind,
        out_radiance,
        out_display
    ]
);

/// The buffers the shading kernels reach by address.
struct ShadeBuffers<'b> {
    inputs: &'b ShadeInputs<'b>,
    /// The shadow test's V_e when the visibility is editable.
    editable: Option<&'b Buffer>,
    /// L_ind: given, or the network's output.
    indirect: Option<&'b Buffer>,
    sun: &'b Buffer,
    sky: &'b Buffer,
    radiance: &'b Buffer,
    display: &'b Buffer,
}

impl ShadeUniform {
    /// Takes every address from `b` through `rec` (which keeps the buffers
    /// borrowed until it is submitted) and writes the uniform into `uniform`.
    fn record<'a>(mut self, rec: &mut Recording<'a>, uniform: &'a Buffer, b: &ShadeBuffers<'a>) -> Result<()> {
        let g = b.inputs.gbuffer;
        let env = b.inputs.environment;
        self.normal = rec.addr_or_null(g.normal.as_ref())?;
        self.albedo = rec.addr_or_null(g.albedo.as_ref())?;
        self.roughness = rec.addr_or_null(g.roughness.as_ref())?;
        self.metallic = rec.addr_or_null(g.metallic.as_ref())?;
        self.ao = rec.addr_or_null(g.ao.as_ref())?;
        self.fixed_visibility = rec.addr_or_null(g.visibility.as_ref())?;
        self.editable_visibility = rec.addr_or_null(b.editable)?;
        self.alpha = rec.addr(&g.alpha)?;
        self.specular = rec.addr(&env.specular)?;
        self.irradiance = rec.addr(&env.irradiance)?;
        self.brdf = rec.addr(&b.inputs.brdf.buffer)?;
        self.l_sun = rec.addr(b.sun)?;
        self.l_sky = rec.addr(b.sky)?;
        self.l_ind = rec.addr_or_null(b.indirect)?;
        self.out_radiance = rec.addr(b.radiance)?;
        self.out_display = rec.addr(b.display)?;
        Ok(rec.update(uniform, 0, &self)?)
    }
}

/// The shading kernels.
pub struct Shader {
    device: Device,
    compose: Arc<Kernel>,
}

fn uniform_kernel(
    device: &Device,
    info: &'static srug_gpu::KernelInfo,
    spec: &[(u32, SpecValue)],
) -> Result<Arc<Kernel>> {
    Ok(Kernel::cached(
        device,
        info,
        &KernelDecl { bindings: &[BindingKind::UniformBuffer], push_constant_size: 0, specialization: spec },
    )?)
}

impl Shader {
    /// Builds the compose kernel (light kernels are built per term set on first use).
    pub fn new(device: &Device) -> Result<Self> {
        Ok(Self { device: device.clone(), compose: uniform_kernel(device, &kernels::SHADE_COMPOSE, &[])? })
    }

    /// The uniform for `inputs`; output addresses filled by the caller.
    fn uniform(inputs: &ShadeInputs<'_>, settings: &ShadeSettings) -> Result<ShadeUniform> {
        settings.validate()?;
        let (g, camera) = (inputs.gbuffer, inputs.camera);
        if (g.width, g.height) != (camera.width, camera.height) {
            return Err(Error::invalid(
                format!("G-buffer {}x{}", g.width, g.height),
                format!("does not match camera {}x{}", camera.width, camera.height),
            ));
        }
        if g.normal.is_none() || g.albedo.is_none() {
            return Err(Error::invalid(
                "G-buffer",
                "lacks the normal and albedo channels shading needs (a scene without albedo renders plain colour, \
                 unshaded)",
            ));
        }
        let sun = inputs.sun.filter(|s| s.above_horizon());
        let mut visibility = settings.visibility;
        if sun.is_none() {
            visibility = VisibilitySource::None;
        }
        if visibility == VisibilitySource::Fixed && g.visibility.is_none() {
            return Err(Error::invalid("fixed visibility", "needs the visibility G-buffer channel"));
        }
        let pixels = u64::from(g.width) * u64::from(g.height);
        if visibility == VisibilitySource::Editable {
            let v = inputs
                .editable_visibility
                .ok_or_else(|| Error::invalid("editable visibility", "needs the shadow pass's visibility buffer"))?;
            if v.size() < pixels * 4 {
                return Err(Error::invalid("editable visibility buffer", "is smaller than the image"));
            }
        }
        if let Some(ind) = inputs.indirect {
            if ind.size() < pixels * 12 {
                return Err(Error::invalid("indirect light buffer", "is smaller than the image"));
            }
        }
        let env = inputs.environment;
        let mut u = ShadeUniform::zeroed();
        let r = camera.rotation;
        for (row, i) in [&mut u.cam_rot0, &mut u.cam_rot1, &mut u.cam_rot2].into_iter().zip(0..3) {
            *row = [r.x_axis[i], r.y_axis[i], r.z_axis[i], 0.0];
        }
        let (k, kind) = match camera.projection {
            Projection::Pinhole { fx, fy, cx, cy } => ([fx, fy, cx, cy], 0.0),
            Projection::Orthographic { sx, sy, cx, cy } => ([sx, sy, cx, cy], 1.0),
        };
        u.cam_pos = [camera.position.x, camera.position.y, camera.position.z, kind];
        u.cam_intr = k;
        u.size = [g.width, g.height, env.levels, inputs.brdf.size];
        u.env_size = [env.base.0, env.base.1, env.irradiance_size.0, env.irradiance_size.1];
        if let Some(s) = sun {
            u.sun_dir = [s.direction.x, s.direction.y, s.direction.z, 1.0];
            u.sun_radiance = [s.intensity[0], s.intensity[1], s.intensity[2], 0.0];
        }
        let rho = f64::from(settings.env_rotation_degrees).to_radians();
        u.env = [rho.cos() as f32, rho.sin() as f32, settings.env_intensity, settings.min_alpha];
        u.background = match settings.background {
            Background::Environment => [0.0, 0.0, 0.0, 1.0],
            Background::Color(c) => [c[0], c[1], c[2], 0.0],
        };
        u.display = [2f32.powf(settings.exposure_ev), settings.tone_map.code() as f32, 0.0, 0.0];
        u.modes = [visibility.code(), 0, 0, 0];
        Ok(u)
    }

    /// Shades one frame: L_sun and L_sky, then the composite and display image.
    pub fn shade(&mut self, inputs: &ShadeInputs<'_>, settings: &ShadeSettings) -> Result<ShadedFrame> {
        self.shade_impl(inputs, settings, None)
    }

    /// Shades one frame with the indirect network: L_sun and L_sky, the
    /// network's L_ind from them and the G-buffers, then the composite.
    pub fn shade_with_network(
        &mut self,
        inputs: &ShadeInputs<'_>,
        settings: &ShadeSettings,
        network: &mut crate::indirect::UNet,
    ) -> Result<ShadedFrame> {
        if inputs.indirect.is_some() {
            return Err(Error::invalid("indirect light", "give either an L_ind buffer or a network, not both"));
        }
        self.shade_impl(inputs, settings, Some(network))
    }

    fn shade_impl(
        &mut self,
        inputs: &ShadeInputs<'_>,
        settings: &ShadeSettings,
        network: Option<&mut crate::indirect::UNet>,
    ) -> Result<ShadedFrame> {
        let u = Self::uniform(inputs, settings)?;
        let device = self.device.clone();
        let g = inputs.gbuffer;
        let pixels = u64::from(g.width) * u64::from(g.height);
        let make = |name: &str| device.create_buffer(name, pixels * 12, MemoryKind::Storage);
        let (sun, sky, radiance, display) = (make("L_sun")?, make("L_sky")?, make("radiance")?, make("display")?);
        let uniform =
            device.create_buffer("shade uniform", std::mem::size_of::<ShadeUniform>() as u64, MemoryKind::Storage)?;
        // The visibility the uniform settled on (none without a sun above the horizon).
        let editable = if u.modes[0] == VisibilitySource::Editable.code() { inputs.editable_visibility } else { None };
        let bits = settings.terms.bits();
        let lights = uniform_kernel(&device, &kernels::SHADE_LIGHTS, &[(0, SpecValue::U32(bits))])?;
        let lights: &Kernel = &lights;
        let mut timings = device.run(|rec| -> Result<()> {
            let buffers = ShadeBuffers {
                inputs,
                editable,
                indirect: inputs.indirect,
                sun: &sun,
                sky: &sky,
                radiance: &radiance,
                display: &display,
            };
            u.record(rec, &uniform, &buffers)?;
            if let Some(word) = settings.prefill {
                for b in [&sun, &sky, &radiance, &display] {
                    rec.fill(b, word)?;
                }
            }
            rec.begin_stage("shade lights");
            rec.dispatch_1d(lights, &[&uniform], &(), pixels)?;
            rec.end_stage();
            Ok(())
        })?;
        let mut indirect = None;
        if let Some(net) = network {
            let inputs =
                crate::indirect::NetworkInputs { gbuffer: g, sun: &sun, sky: &sky, min_alpha: settings.min_alpha };
            let out = net.predict(&inputs)?;
            timings.stages.extend(out.timings.stages);
            indirect = Some(out.output);
        }
        let compose = &self.compose;
        let t = device.run(|rec| -> Result<()> {
            let buffers = ShadeBuffers {
                inputs,
                editable,
                indirect: indirect.as_ref().or(inputs.indirect),
                sun: &sun,
                sky: &sky,
                radiance: &radiance,
                display: &display,
            };
            u.record(rec, &uniform, &buffers)?;
            rec.begin_stage("shade compose");
            rec.dispatch_1d(compose, &[&uniform], &(), pixels)?;
            rec.end_stage();
            Ok(())
        })?;
        timings.stages.extend(t.stages);
        Ok(ShadedFrame { width: g.width, height: g.height, sun, sky, radiance, display, indirect, timings })
    }
}

#[cfg(test)]
mod layout_tests {
    use super::ShadeUniform;
    use crate::gpu::{check_layout, kernels};

    /// The host struct matches the `Shade` block of both shading kernels.
    #[test]
    fn uniform_layout_matches_glsl() {
        assert_eq!(check_layout::<ShadeUniform>(&[&kernels::SHADE_LIGHTS, &kernels::SHADE_COMPOSE]), Ok(2));
    }
}
