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
//!   [`brdf::BrdfTable`] (Karis or height-correlated); sky diffuse is multiplied
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

pub mod brdf;
pub mod cpu;
pub mod env;
mod forward;
mod layout;
pub mod sky;

pub use forward::*;
pub(crate) use layout::*;

pub use self::brdf::{BrdfLut, BrdfTable};
pub use self::env::{EnvironmentPrep, PrepareSettings, PreparedEnvironment};
pub use self::sky::ProceduralSky;
use crate::error::{Error, Result};
use crate::gpu::{Buffer, Device, Timings};
/// The KTX2 reader and writer, now in [`crate::io::ktx`] (kept here for old paths).
pub use crate::io::ktx;
pub use crate::io::EnvironmentMap;
use crate::scene::Camera;
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

    pub(crate) fn code(self) -> u32 {
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
        let rules: [(bool, String, &str); 5] = [
            (
                self.exposure_ev.is_finite() && self.exposure_ev.abs() <= 64.0,
                format!("exposure {} EV", self.exposure_ev),
                "must be within ±64 stops",
            ),
            (
                self.min_alpha > 0.0 && self.min_alpha <= 1.0,
                format!("shading minimum alpha {}", self.min_alpha),
                "must be in (0, 1]",
            ),
            (
                self.env_rotation_degrees.is_finite(),
                format!("environment rotation {}°", self.env_rotation_degrees),
                "must be finite",
            ),
            (
                self.env_intensity.is_finite() && (0.0..=1.0e6).contains(&self.env_intensity),
                format!("environment intensity {}", self.env_intensity),
                "must be in 0..=1e6",
            ),
            (bg_ok, format!("background {:?}", self.background), "must be finite and ≥ 0"),
        ];
        match rules.into_iter().find(|(ok, ..)| !ok) {
            Some((_, what, why)) => Err(Error::invalid(what, why)),
            None => Ok(()),
        }
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

#[cfg(test)]
mod validate_tests {
    #![allow(clippy::unwrap_used, reason = "a failed unwrap is a failed test")]
    use super::*;

    /// Each rule names the one value at fault.
    #[test]
    fn settings_name_the_value_at_fault() {
        let e = ShadeSettings { env_intensity: 1e7, ..ShadeSettings::default() }.validate().unwrap_err().to_string();
        assert_eq!(e, "invalid argument: environment intensity 10000000: must be in 0..=1e6");
        let e = ShadeSettings { exposure_ev: 80.0, ..ShadeSettings::default() }.validate().unwrap_err().to_string();
        assert_eq!(e, "invalid argument: exposure 80 EV: must be within ±64 stops");
        assert!(ShadeSettings::default().validate().is_ok());
    }
}
