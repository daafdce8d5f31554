//! Relighting one camera: splat the G-buffers the shading needs, splat the
//! shadow map from the sun and run the sigmoid test when the editable
//! visibility is asked for, then shade. The sun and the environment change
//! at render time; the scene is never touched.
//!
//! Only what the inputs require runs: no sun above the horizon → no shadow
//! map, no shadow test and no sun term; fixed or no visibility → no shadow
//! pass; no network weights → no indirect stage. A scene without albedo cannot
//! be shaded ([`Relighter::render`] refuses it; render its colour instead).

use super::{BrdfTable, PreparedEnvironment, ShadeInputs, ShadeSettings, ShadedFrame, Shader, VisibilitySource};
use crate::error::{Error, Result};
use crate::gpu::{Device, Timings};
use crate::scene::activate::GpuScene;
use crate::scene::{AttributeGroups, Bounds, Camera};
use crate::shadow::{ShadowPass, ShadowSettings, Sun, VisibilityKind};
use crate::splat::{Channels, GpuGBuffer, NormalSource, SplatSettings, Splatter};

/// Everything a relit frame depends on besides the scene and the camera.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RelightSettings {
    /// Shading knobs.
    pub shade: ShadeSettings,
    /// Shadow-map knobs (editable visibility only).
    pub shadow: ShadowSettings,
    /// Where normals come from.
    pub normal_source: NormalSource,
    /// G-buffer channels to blend besides those the shading reads (for callers that read them).
    pub extra_channels: Channels,
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
    /// Whether a shadow map was splatted and tested.
    pub shadow_pass_ran: bool,
    /// The camera's G-buffers (the shading's channels and the extra ones asked for).
    pub gbuffer: GpuGBuffer,
}

/// The relighting pipeline: splatting, shadows and shading kernels, reused across frames.
pub struct Relighter {
    splatter: Splatter,
    shadows: ShadowPass,
    shader: Shader,
    network: Option<crate::indirect::UNet>,
}

impl Relighter {
    /// Builds the kernels.
    pub fn new(device: &Device) -> Result<Self> {
        Ok(Self {
            splatter: Splatter::new(device)?,
            shadows: ShadowPass::new(device)?,
            shader: Shader::new(device)?,
            network: None,
        })
    }

    /// The indirect-light network; with `None` (the default) no inference runs.
    pub fn set_network(&mut self, network: Option<crate::indirect::UNet>) {
        self.network = network;
    }

    /// The splatter, for plain renders of the same scene.
    pub fn splatter(&mut self) -> &mut Splatter {
        &mut self.splatter
    }

    /// Renders `camera` of `scene` (attribute groups `attributes`, bounds
    /// `bounds` for the light camera) under `sun` and `environment`.
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
        let d = RelightDecisions::new(attributes, sun, settings)?;
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
            ..SplatSettings::default()
        };
        let (gbuffer, stats) = self.splatter.render(scene, camera, &splat)?;
        let mut timings = stats.timings;
        let mut visibility = None;
        if let (true, Some(s)) = (editable, sun) {
            let map = self
                .shadows
                .shadow_map(&mut self.splatter, scene, bounds, s, &settings.shadow, Some(camera))?
                .ok_or_else(|| Error::InvalidArgument("the sun is below the horizon".into()))?;
            timings.stages.extend(map.frame.stats.timings.stages.iter().cloned());
            let (v, t) = self.shadows.visibility(&map, &gbuffer, camera, &settings.shadow, VisibilityKind::Sigmoid)?;
            timings.stages.extend(t.stages);
            visibility = Some(v);
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
        Ok(RelitFrame { shaded, timings, shadow_pass_ran: visibility.is_some(), gbuffer })
    }
}
