//! Relighting one camera: splat the G-buffers the shading needs, splat the
//! shadow map from the sun and run the sigmoid test when the editable
//! visibility is asked for, then shade. The sun and the environment change
//! at render time; the scene is never touched.
//!
//! Only what the inputs require runs: no sun above the horizon → no shadow
//! map, no shadow test and no sun term; fixed or no visibility → no shadow
//! pass; no network weights → no indirect stage. A scene without albedo cannot
//! be shaded ([`Relighter::render`] refuses it; render its colour instead).

use glam::Vec3;

use super::{BrdfTable, PreparedEnvironment, ShadeInputs, ShadeSettings, ShadedFrame, Shader, VisibilitySource};
use crate::error::{Error, Result};
use crate::gpu::{Device, Timings};
use crate::scene::activate::GpuScene;
use crate::scene::{AttributeGroups, Bounds, Camera};
use crate::shadow::{light_camera, DepthMode, ShadowMap, ShadowPass, ShadowSettings, Sun, VisibilityKind};
use crate::splat::{Channels, GpuGBuffer, NormalSource, SplatSettings, Splatter};

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
    /// How editable visibility is computed: the sigmoid test (differentiable)
    /// or the traced transmittance through the shadow map's splats (exact, slower).
    pub visibility_kind: VisibilityKind,
    /// Spherical-harmonic degree used for colour (`None`: the scene's).
    pub sh_degree: Option<u32>,
    /// The frame is rendered at this fraction of the camera's size in each
    /// direction (0 < s ≤ 1; 0 means 1); [`ShadedImage::resampled`](super::ShadedImage::resampled) brings it back.
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
            return Err(Error::InvalidArgument(format!("render scale {} is not in (0, 1]", self.render_scale)));
        }
        if let Some(d) = self.sh_degree.filter(|d| *d > 3) {
            return Err(Error::InvalidArgument(format!("SH degree {d} is not 0 to 3")));
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
        let mut s = RelightSettings::default();
        s.shadow.bias = 0.5;
        s.shadow.receiver_depth = DepthMode::Median;
        match preset {
            Preset::Fast => {
                s.shadow.resolution = 512;
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
/// trade` measures (README: "Speed against accuracy").
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Preset {
    /// Half-resolution render, SH degree 0, a 512 shadow map, fp16 network activations.
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
            other => Err(Error::InvalidArgument(format!("preset \"{other}\" is not one of fast, balanced, reference"))),
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

/// What a relit frame runs, decided from the scene's attributes, the sun and
/// the settings alone, before anything runs: [`Relighter::render`] follows it
/// and [`crate::plan`] reports it, so the two cannot disagree.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RelightDecisions {
    /// Shading runs (the scene has albedo); otherwise only its plain colour can be rendered.
    pub shading: bool,
    /// The sun, when there is one above the horizon (no sun light otherwise).
    pub sun: Option<Sun>,
    /// A shadow map is splatted from the sun and tested (editable visibility with a sun).
    pub shadow_pass: bool,
    /// The visibility the shading uses (none without a sun).
    pub visibility: VisibilitySource,
    /// The camera's G-buffer channels besides rgb and alpha.
    pub channels: Channels,
}

impl RelightDecisions {
    /// Decides; fixed visibility without the scene's visibility attribute is an error.
    pub fn new(attributes: &AttributeGroups, sun: Option<&Sun>, settings: &RelightSettings) -> Result<Self> {
        let shading = attributes.shadeable();
        let sun = sun.filter(|s| s.above_horizon()).copied();
        let mut visibility = settings.shade.visibility;
        if shading && visibility == VisibilitySource::Fixed && !attributes.visibility {
            return Err(Error::InvalidArgument("fixed visibility needs the scene's visibility attribute".into()));
        }
        if sun.is_none() {
            visibility = VisibilitySource::None;
        }
        let shadow_pass = shading && sun.is_some() && visibility == VisibilitySource::Editable;
        let mut channels = settings.extra_channels;
        if shading {
            let needed = ShadeSettings { visibility, ..settings.shade }.gbuffer_channels(attributes);
            channels = Channels::from_bits(channels.bits() | needed.bits());
        }
        if shadow_pass {
            let r = settings.shadow.receiver_channels();
            channels.depth |= r.depth;
            channels.median_depth |= r.median_depth;
        }
        Ok(Self {
            shading,
            sun,
            shadow_pass,
            visibility: if shading { visibility } else { VisibilitySource::None },
            channels,
        })
    }
}

/// A relit frame.
pub struct RelitFrame {
    /// Shading outputs.
    pub shaded: ShadedFrame,
    /// Every stage's GPU time: splat, shadow map, shadow test, shading.
    pub timings: Timings,
    /// Whether the shadow pass ran (a shadow map tested, splatted for this frame or reused).
    pub shadow_pass_ran: bool,
    /// Whether the shadow map was the previous frame's (see [`Relighter::set_shadow_map_reuse`]):
    /// its splat then cost nothing and is absent from `timings`.
    pub shadow_map_reused: bool,
    /// The camera's G-buffers (the shading's channels and the extra ones asked for).
    pub gbuffer: GpuGBuffer,
    /// Per-pixel sun visibility from the shadow pass, when it ran.
    pub visibility: Option<crate::gpu::Buffer>,
    /// (Gaussian, tile) pairs the camera splat sorted.
    pub pairs: u64,
}

/// The relighting pipeline: splatting, shadows and shading kernels, reused across frames.
pub struct Relighter {
    splatter: Splatter,
    shadows: ShadowPass,
    shader: Shader,
    network: Option<crate::indirect::UNet>,
    /// Keep the shadow map for the next frame.
    reuse_shadow_map: bool,
    /// The last shadow map and what it was made from (only while reuse is on).
    shadow_map: Option<(ShadowMapKey, ShadowMap)>,
}

/// Everything a shadow map's contents depend on: equal keys, equal maps.
#[derive(Clone, Debug, PartialEq)]
struct ShadowMapKey {
    /// [`GpuScene::version`].
    scene: u64,
    light: Camera,
    /// The sun's direction: its intensity does not change the map.
    direction: Vec3,
    depth: DepthMode,
    tile: u32,
}

impl Relighter {
    /// Builds the kernels.
    pub fn new(device: &Device) -> Result<Self> {
        Ok(Self {
            splatter: Splatter::new(device)?,
            shadows: ShadowPass::new(device)?,
            shader: Shader::new(device)?,
            network: None,
            reuse_shadow_map: false,
            shadow_map: None,
        })
    }

    /// Keeps the shadow map between frames and splats a new one only when
    /// the scene ([`GpuScene::version`]), the sun's direction (not its
    /// intensity), or the light camera
    /// (resolution, fit; the view with [`crate::shadow::ShadowFit::ViewFrustum`])
    /// or the map's depth mode or tile change. With a fixed sun the per-frame
    /// shadow cost is then the sigmoid test alone. Off by default: the map's
    /// buffers stay allocated between frames, and a scene whose buffers are
    /// written in place must be marked with [`GpuScene::mark_changed`].
    /// Turning it off frees the kept map.
    pub fn set_shadow_map_reuse(&mut self, on: bool) {
        self.reuse_shadow_map = on;
        if !on {
            self.shadow_map = None;
        }
    }

    /// Whether shadow maps are kept between frames.
    pub fn shadow_map_reuse(&self) -> bool {
        self.reuse_shadow_map
    }

    /// The indirect-light network; with `None` (the default) no inference runs.
    pub fn set_network(&mut self, network: Option<crate::indirect::UNet>) {
        self.network = network;
    }

    /// Takes the indirect-light network out (none is left).
    pub fn take_network(&mut self) -> Option<crate::indirect::UNet> {
        self.network.take()
    }

    /// The splatter, for plain renders of the same scene.
    pub fn splatter(&mut self) -> &mut Splatter {
        &mut self.splatter
    }

    /// Renders `camera` of `scene` (attribute groups `attributes`, bounds
    /// `bounds` for the light camera) under `sun` and `environment`, at the
    /// settings' render scale (the frame's size is the scaled camera's).
    #[allow(clippy::too_many_arguments, reason = "the scene, the view and the lighting are separate inputs")]
    pub fn render(
        &mut self,
        scene: &GpuScene,
        attributes: &AttributeGroups,
        bounds: &Bounds,
        camera: &Camera,
        sun: Option<&Sun>,
        environment: &PreparedEnvironment,
        brdf: &BrdfTable,
        settings: &RelightSettings,
    ) -> Result<RelitFrame> {
        settings.validate()?;
        let d = RelightDecisions::new(attributes, sun, settings)?;
        let camera = &settings.render_camera(camera);
        if !d.shading {
            return Err(Error::InvalidArgument(
                "the scene has no albedo attribute: it cannot be relit (render its colour with `srug render`)".into(),
            ));
        }
        let (sun, editable, channels) = (d.sun.as_ref(), d.shadow_pass, d.channels);
        let mut shade = settings.shade;
        shade.visibility = d.visibility;
        let splat = SplatSettings {
            channels,
            normal_source: settings.normal_source,
            prefill: shade.prefill,
            sh_degree: settings.sh_degree,
            tile: settings.tile,
            ..SplatSettings::default()
        };
        let (gbuffer, stats) = self.splatter.render(scene, camera, &splat)?;
        let (mut timings, pairs) = (stats.timings, stats.pairs);
        let mut visibility = None;
        let mut reused = false;
        if let (true, Some(s)) = (editable, sun) {
            let shadow = &settings.shadow;
            let key = ShadowMapKey {
                scene: scene.version(),
                light: light_camera(bounds, s, shadow.resolution, shadow.fit, Some(camera))?,
                direction: s.direction,
                depth: shadow.map_depth,
                tile: shadow.tile,
            };
            reused = self.reuse_shadow_map && self.shadow_map.as_ref().is_some_and(|(k, _)| *k == key);
            if !reused {
                // Free the old map before splatting the new one.
                self.shadow_map = None;
                let light = key.light.clone();
                let map = self.shadows.shadow_map_from(&mut self.splatter, scene, light, s, shadow)?;
                // Its stages are named "shadow map …" already.
                timings.stages.extend(map.frame.stats.timings.stages.iter().cloned());
                self.shadow_map = Some((key, map));
            }
            let Some((_, map)) = &self.shadow_map else {
                return Err(Error::InvalidArgument("no shadow map".into()));
            };
            let (v, t) = self.shadows.visibility(map, &gbuffer, camera, shadow, settings.visibility_kind)?;
            timings.stages.extend(t.stages);
            visibility = Some(v);
            if !self.reuse_shadow_map {
                self.shadow_map = None;
            }
        }
        let inputs = ShadeInputs {
            gbuffer: &gbuffer,
            camera,
            environment,
            brdf,
            sun,
            editable_visibility: visibility.as_ref(),
            indirect: None,
        };
        let shaded = match self.network.as_mut() {
            Some(net) => self.shader.shade_with_network(&inputs, &shade, net)?,
            None => self.shader.shade(&inputs, &shade)?,
        };
        timings.stages.extend(shaded.timings.stages.iter().cloned());
        Ok(RelitFrame {
            shaded,
            timings,
            shadow_pass_ran: visibility.is_some(),
            shadow_map_reused: reused,
            gbuffer,
            visibility,
            pairs,
        })
    }
}
