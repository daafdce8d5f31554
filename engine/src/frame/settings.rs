//! What a relit frame depends on besides the scene and the camera, and the
//! named presets on the measured speed/accuracy curve.

use crate::error::{Error, Result};
use crate::scene::Camera;
use crate::shade::ShadeSettings;
use crate::shadow::{ShadowSettings, VisibilityKind};
use crate::splat::{Channels, NormalSource};

/// Everything a relit frame depends on besides the scene and the camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RelightSettings {
    /// Shading knobs.
    pub shade: ShadeSettings,
    /// Shadow-map knobs (editable visibility only).
    pub shadow: ShadowSettings,
    /// Where normals come from.
    pub normal_source: NormalSource,
    /// G-buffer channels to blend besides those the shading reads (for callers that read them).
    pub extra_channels: Channels,
    /// Also blend the scene's own colour (its spherical harmonics) into the
    /// G-buffer's rgb channel, for callers that read it. Shading never does: off,
    /// a relit frame reads no SH coefficient (most of an SH-3 scene's bytes).
    pub rgb: bool,
    /// How editable visibility is computed: the sigmoid test (differentiable)
    /// or the traced transmittance through the shadow map's splats (exact, slower).
    pub visibility_kind: VisibilityKind,
    /// Spherical-harmonic degree used for colour (`None`: the scene's).
    pub sh_degree: Option<u32>,
    /// The frame is rendered at this fraction of the camera's size in each
    /// direction (0 < s ≤ 1; 0 means 1); [`ShadedImage::resampled`](crate::shade::ShadedImage::resampled) brings it back.
    pub render_scale: f32,
    /// Tile edge of the camera's splatting ([`crate::splat::TILE_SIZES`]); the
    /// shadow map has its own, `shadow.tile`.
    pub tile: u32,
}

impl Default for RelightSettings {
    fn default() -> Self {
        Self {
            shade: ShadeSettings::default(),
            shadow: ShadowSettings::default(),
            normal_source: NormalSource::default(),
            extra_channels: Channels::default(),
            rgb: false,
            visibility_kind: VisibilityKind::default(),
            sh_degree: None,
            render_scale: 0.0,
            tile: crate::splat::DEFAULT_TILE,
        }
    }
}

impl RelightSettings {
    /// Checks the values.
    pub fn validate(&self) -> Result<()> {
        self.shade.validate()?;
        self.shadow.validate()?;
        crate::splat::check_tile(self.tile)?;
        if !(self.render_scale >= 0.0 && self.render_scale <= 1.0) {
            return Err(Error::invalid(format!("render scale {}", self.render_scale), "is not in (0, 1]"));
        }
        if let Some(d) = self.sh_degree.filter(|d| *d > 3) {
            return Err(Error::invalid(format!("SH degree {d}"), "is not 0 to 3"));
        }
        Ok(())
    }

    /// The size a `width`×`height` frame is rendered at: scaled by the render scale, at least 1×1.
    pub fn render_size(&self, width: u32, height: u32) -> (u32, u32) {
        let s = if self.render_scale > 0.0 { self.render_scale } else { 1.0 };
        let size = |n: u32| ((n as f32 * s).round() as u32).max(1);
        (size(width), size(height))
    }

    /// The camera a frame is rendered with: `camera` at the render scale.
    pub fn render_camera(&self, camera: &Camera) -> Camera {
        let (w, h) = self.render_size(camera.width, camera.height);
        if (w, h) == (camera.width, camera.height) {
            return camera.clone();
        }
        camera.resized(w, h)
    }

    /// The settings of a named quality preset.
    pub fn preset(preset: Preset) -> Self {
        // The shadow's bias, depths and filter are ShadowSettings::default(), chosen
        // on the analytic block (tests/tests/shadow_accuracy.rs, docs/bench/shadow.md):
        // surface depths with percentage-closer filtering, a slope bias of 3 texels
        // (the fast preset's acne on steep receivers) and 0.8 m, where rough splats'
        // off-plane jitter stops costing edge accuracy and contact leaks barely rise.
        // The map holds an occluder where coverage passes 0.6, not one half (less
        // false shadow beside every caster; more breaks low-sun shadows on rough
        // splats into specks), and a receiver holds a surface from 0.45 (a gappy
        // wall still receives, where the camera would see specks behind it).
        let mut s = RelightSettings::default();
        match preset {
            Preset::Fast => {
                // 1024, not 512: on the analytic block false shadow 1.46 → 1.10% (ideal) and
                // 1.83 → 1.41% (rough), edges 3.9 → 3.2 and 5.3 → 4.0 px, for one larger
                // map per sun (docs/bench/shadow.md).
                s.shadow.resolution = 1024;
                s.sh_degree = Some(0);
                s.render_scale = 0.5;
            }
            Preset::Balanced => {
                s.shadow.resolution = 2048;
            }
            Preset::Reference => {
                s.shadow.resolution = 4096;
                s.visibility_kind = VisibilityKind::Traced;
            }
        }
        s
    }
}

/// Named quality presets: points on the speed/accuracy curve `srug bench
/// trade` measures (docs/bench/trade.md).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Preset {
    /// Half-resolution render, SH degree 0, a 1024 shadow map, fp16 network activations.
    Fast,
    /// Full resolution, the scene's SH, a 2048 sigmoid shadow map, fp32 network.
    #[default]
    Balanced,
    /// Full resolution, a 4096 shadow map with traced visibility, fp32 network:
    /// the setting `srug bench trade` measures errors against.
    Reference,
}

impl Preset {
    /// Every preset, fastest first.
    pub const ALL: [Preset; 3] = [Preset::Fast, Preset::Balanced, Preset::Reference];

    /// Parses `fast`, `balanced` or `reference`.
    pub fn parse(name: &str) -> Result<Self> {
        match name.trim().to_ascii_lowercase().as_str() {
            "fast" => Ok(Preset::Fast),
            "balanced" => Ok(Preset::Balanced),
            "reference" => Ok(Preset::Reference),
            other => Err(Error::invalid(format!("preset \"{other}\""), "is not one of fast, balanced, reference")),
        }
    }

    /// The preset's name.
    pub fn name(self) -> &'static str {
        match self {
            Preset::Fast => "fast",
            Preset::Balanced => "balanced",
            Preset::Reference => "reference",
        }
    }

    /// Activation storage of the indirect network under this preset.
    pub fn indirect_precision(self) -> crate::indirect::StoragePrecision {
        match self {
            Preset::Fast => crate::indirect::StoragePrecision::Fp16,
            _ => crate::indirect::StoragePrecision::Fp32,
        }
    }
}
