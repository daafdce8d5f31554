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

use crate::error::{Error, Result};
use crate::gpu::{Device, Timings};
use crate::scene::activate::GpuScene;
use crate::scene::{AttributeGroups, Bounds, Camera};
use crate::shade::{BrdfTable, PreparedEnvironment, ShadeInputs, ShadedFrame, Shader};
use crate::shadow::{light_camera, DepthMode, ShadowFit, ShadowMap, ShadowPass, Sun, VisibilityKind};
use crate::splat::{GpuGBuffer, SplatSettings, Splatter};

use super::host_images::{FrameChannel, FrameOutputs, HostImageWriter, HostPixels, HostTargets};
use super::{RelightDecisions, RelightSettings};

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
    /// The exposure the display values were made with (EV).
    pub exposure_ev: f32,
    /// The tone map the display values were made with.
    pub tone_map: crate::shade::ToneMap,
}

/// What every frame of one scene, sun and settings runs, decided before
/// anything runs (the plan reports the same).
struct FramePlan {
    decisions: RelightDecisions,
    /// The shading settings, with the visibility the decisions chose.
    shade: crate::shade::ShadeSettings,
    /// The camera splat: only the channels the shading needs.
    splat: SplatSettings,
}

impl FramePlan {
    fn new(attributes: &AttributeGroups, sun: Option<&Sun>, settings: &RelightSettings) -> Result<Self> {
        settings.validate()?;
        let decisions = RelightDecisions::new(attributes, sun, settings)?;
        if !decisions.shading {
            return Err(Error::invalid(
                "scene",
                "has no albedo attribute: it cannot be relit (render its colour with `srug render`)",
            ));
        }
        let mut shade = settings.shade;
        shade.visibility = decisions.visibility;
        let splat = SplatSettings {
            channels: decisions.channels,
            normal_source: settings.normal_source,
            prefill: shade.prefill,
            sh_degree: settings.sh_degree,
            tile: settings.tile,
            // The shadow test's receivers are these pixels: their depths follow its definition.
            surface_depth: settings.shadow.surface_depth,
            median_coverage: settings.shadow.receiver_coverage,
            // Shading reads the features; nothing differentiates them.
            packed_features: true,
            // Records only for the Gaussians a camera can see.
            compact_splats: true,
            // Nor the scene's own colour: its SH are read only where asked for.
            rgb: settings.rgb,
            ..SplatSettings::default()
        };
        Ok(Self { decisions, shade, splat })
    }
}

/// The light a frame is shaded under, and the bounds its light camera fits.
struct Lights<'a> {
    bounds: &'a Bounds,
    sun: Option<&'a Sun>,
    environment: &'a PreparedEnvironment,
    brdf: &'a BrdfTable,
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
    /// A host's depth the camera's splats are hidden behind.
    host_depth: Option<HostDepthImage>,
    /// Writes frames into host images (made on first use).
    host_writer: Option<HostImageWriter>,
    device: Device,
}

/// A frame whose buffers can be written into host images.
pub trait HostFrameSource {
    /// The buffers [`HostImageWriter::write`] reads, with `channels` resolved
    /// in order (`None` where the frame lacks one).
    fn outputs(&self, channels: &[FrameChannel]) -> Result<FrameOutputs<'_>>;
}

impl HostFrameSource for RelitFrame {
    fn outputs(&self, channels: &[FrameChannel]) -> Result<FrameOutputs<'_>> {
        let (g, s) = (&self.gbuffer, &self.shaded);
        Ok(FrameOutputs {
            width: g.width,
            height: g.height,
            colour: &s.radiance,
            alpha: &g.alpha,
            median_depth: g.get(crate::splat::Channel::MedianDepth),
            display: Some((self.exposure_ev, self.tone_map)),
            channels: channels.iter().map(|c| c.resolve(g, Some(s))).collect(),
        })
    }
}

/// A host's depth per pixel for [`Relighter::set_host_depth`]: one f32 per
/// pixel of a `width`×`height` frame, row-major, in `convention`.
#[derive(Debug)]
pub struct HostDepthImage {
    /// The values.
    pub buffer: crate::gpu::Buffer,
    /// Frame width in pixels.
    pub width: u32,
    /// Frame height in pixels.
    pub height: u32,
    /// How the values encode depth.
    pub convention: crate::splat::HostDepth,
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
    surface_depth: bool,
    coverage: f32,
    /// The receivers' cameras, where the map is splatted only for them.
    receivers: Option<Vec<Camera>>,
    /// Whether the map keeps its splats (the traced test reads them).
    splats_kept: bool,
}

/// One frame's shadow test: the visibility per pixel, whether its map was
/// an earlier frame's, and the GPU times of the map (when splatted) and the test.
struct FrameShadow {
    visibility: crate::gpu::Buffer,
    reused: bool,
    timings: Timings,
}

impl Relighter {
    /// Builds the kernels.
    pub fn new(device: &Device) -> Result<Self> {
        Ok(Self {
            splatter: Splatter::new(device)?,
            // Its maps are never differentiated: no pair tiles.
            shadows: {
                let mut shadows = ShadowPass::new(device)?;
                shadows.set_map_pair_tiles(false);
                shadows
            },
            shader: Shader::new(device)?,
            network: None,
            reuse_shadow_map: false,
            shadow_map: None,
            host_depth: None,
            host_writer: None,
            device: device.clone(),
        })
    }

    /// Renders as [`Relighter::render`] does, into the host's images
    /// ([`HostTargets`]; module [`super::host_images`]): with `composite`, the
    /// splats behind the host's depth image are hidden and the rest blend
    /// over its colour (the background is then black). The images' size must
    /// be the rendered frame's (the settings' render scale applied). The
    /// frame's buffers are returned too; its timings include the copies.
    #[allow(clippy::too_many_arguments, reason = "Relighter::render's inputs, with the host's images")]
    pub fn render_to_host(
        &mut self,
        scene: &GpuScene,
        attributes: &AttributeGroups,
        bounds: &Bounds,
        camera: &Camera,
        sun: Option<&Sun>,
        environment: &PreparedEnvironment,
        brdf: &BrdfTable,
        settings: &RelightSettings,
        targets: &HostTargets,
    ) -> Result<RelitFrame> {
        let mut settings = *settings;
        if targets.composite {
            settings.shade.background = crate::shade::Background::Color([0.0; 3]);
        }
        targets.request_channels(&mut settings);
        let size = settings.render_size(camera.width, camera.height);
        let (mut frame, t) = Self::with_host_targets(
            self,
            |r| r,
            targets,
            size,
            |r| r.render(scene, attributes, bounds, camera, sun, environment, brdf, &settings),
        )?;
        frame.timings.stages.extend(t.stages);
        Ok(frame)
    }

    /// Runs `render` between reading the host's texels from `targets` (when
    /// compositing: its depth hides the splats meanwhile, in place of any
    /// [`Relighter::set_host_depth`]) and writing the frame it returns into
    /// them; `size` is the frame's. `ctx` holds the relighter (`relighter_of`
    /// reaches it) and whatever else `render` needs. Returns the frame and the
    /// copies' timings. The frame must have the median depth channel when
    /// `targets` has a depth image, and be shaded over black when compositing.
    /// A failure once the host's images were read still leaves them in their
    /// `layout_after` (unwritten) and signals the host's semaphores.
    pub fn with_host_targets<C, T: HostFrameSource>(
        ctx: &mut C,
        relighter_of: fn(&mut C) -> &mut Self,
        targets: &HostTargets,
        size: (u32, u32),
        render: impl FnOnce(&mut C) -> Result<T>,
    ) -> Result<(T, Timings)> {
        let this = relighter_of(ctx);
        targets.validate(&this.device, size.0, size.1)?;
        if this.host_writer.is_none() {
            this.host_writer = Some(HostImageWriter::new(&this.device)?);
        }
        let mut pixels: HostPixels = this.writer()?.read(targets)?;
        let hide = targets.composite && targets.depth.is_some();
        let previous = if hide {
            let Some(buffer) = pixels.depth.take() else {
                return Err(Error::Internal("the host's depth was not read".into()));
            };
            let own = HostDepthImage { buffer, width: size.0, height: size.1, convention: targets.depth_convention };
            this.host_depth.replace(own)
        } else {
            None
        };
        let rendered = render(ctx);
        let this = relighter_of(ctx);
        if hide {
            pixels.depth = this.host_depth.take().map(|h| h.buffer);
            this.host_depth = previous;
        }
        let channels: Vec<FrameChannel> = targets.buffers.iter().map(|(c, _)| *c).collect();
        let written = rendered.and_then(|frame| {
            let timings = this.writer()?.write(targets, &frame.outputs(&channels)?, &pixels)?;
            Ok((frame, timings))
        });
        if written.is_err() {
            // The host's waits are consumed: release its images and signal it anyway
            // (the call's own error is the one reported).
            let _ = this.writer().and_then(|w| w.abandon(targets, &pixels));
        }
        written
    }

    fn writer(&self) -> Result<&HostImageWriter> {
        self.host_writer.as_ref().ok_or_else(|| Error::Internal("no host image writer".into()))
    }

    /// Splats `camera`'s G-buffers with `settings`, behind the host's depth
    /// when one is set ([`Relighter::set_host_depth`]); what [`Relighter::render`]
    /// does first, and all a frame without shading needs.
    pub fn splat_camera(
        &mut self,
        scene: &GpuScene,
        camera: &Camera,
        settings: &SplatSettings,
    ) -> Result<(GpuGBuffer, crate::splat::SplatStats)> {
        match &self.host_depth {
            None => self.splatter.render(scene, camera, settings),
            Some(h) => {
                if (h.width, h.height) != (camera.width, camera.height) {
                    return Err(Error::invalid(
                        format!("host depth of {}x{}", h.width, h.height),
                        format!("does not match the rendered frame's {}x{}", camera.width, camera.height),
                    ));
                }
                let frame = self.splatter.render_frame_occluded(scene, camera, settings, &h.buffer, h.convention)?;
                Ok((frame.gbuffer, frame.stats))
            }
        }
    }

    /// Hides the camera's splats behind a host's depth in the frames that
    /// follow ([`Splatter::render_frame_occluded`]; its size must be the
    /// rendered frame's, so at a render scale below 1 the scaled size), or
    /// stops doing so with `None`. Shadows are unchanged: hidden splats still
    /// cast them. The premultiplied result composites over the host's colour.
    pub fn set_host_depth(&mut self, depth: Option<HostDepthImage>) -> Result<()> {
        if let Some(d) = &depth {
            d.convention.validate()?;
        }
        self.host_depth = depth;
        Ok(())
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
        let plan = FramePlan::new(attributes, sun, settings)?;
        let camera = &settings.render_camera(camera);
        let (gbuffer, stats) = self.splat_camera(scene, camera, &plan.splat)?;
        let lights = Lights { bounds, sun: plan.decisions.sun.as_ref(), environment, brdf };
        self.finish(scene, camera, &lights, settings, &plan, gbuffer, stats)
    }

    /// Renders each of `cameras` as [`Relighter::render`] does (the same
    /// frames, in order), with the cameras' splats batched
    /// ([`Splatter::render_batch`]: one submission per step for several
    /// cameras) unless a host depth is set; the cameras share one shadow map
    /// (splatted once for the batch, whether or not
    /// [`Relighter::set_shadow_map_reuse`] keeps it after; with
    /// [`crate::shadow::ShadowSettings::cull_to_receivers`], only where the
    /// batch's cameras look) and each frame is shaded in turn. Every frame is held
    /// until returned: pass as many cameras as memory allows
    /// ([`crate::splat::cameras_per_batch`]).
    #[allow(clippy::too_many_arguments, reason = "Relighter::render's inputs, with several cameras")]
    pub fn render_batch(
        &mut self,
        scene: &GpuScene,
        attributes: &AttributeGroups,
        bounds: &Bounds,
        cameras: &[Camera],
        sun: Option<&Sun>,
        environment: &PreparedEnvironment,
        brdf: &BrdfTable,
        settings: &RelightSettings,
    ) -> Result<Vec<RelitFrame>> {
        let plan = FramePlan::new(attributes, sun, settings)?;
        let cameras: Vec<Camera> = cameras.iter().map(|c| settings.render_camera(c)).collect();
        let splats = match self.host_depth {
            None => self.splatter.render_batch(scene, &cameras, &plan.splat)?,
            Some(_) => cameras.iter().map(|c| self.splat_camera(scene, c, &plan.splat)).collect::<Result<_>>()?,
        };
        let lights = Lights { bounds, sun: plan.decisions.sun.as_ref(), environment, brdf };
        // The cameras of one batch share the shadow map (the same scene, sun and
        // settings: the same map unless it is fitted to each view), reuse on or off.
        let reuse = self.reuse_shadow_map;
        self.reuse_shadow_map = true;
        let frames = self.finish_batch(scene, &cameras, &lights, settings, &plan, splats);
        self.reuse_shadow_map = reuse;
        if !reuse {
            self.shadow_map = None;
        }
        frames
    }

    /// [`Relighter::finish`] for each camera of a batch: every frame's shadow
    /// test first (a map culled to receivers serves the whole batch's), then
    /// the shading in turn.
    fn finish_batch(
        &mut self,
        scene: &GpuScene,
        cameras: &[Camera],
        lights: &Lights<'_>,
        settings: &RelightSettings,
        plan: &FramePlan,
        splats: Vec<(GpuGBuffer, crate::splat::SplatStats)>,
    ) -> Result<Vec<RelitFrame>> {
        let receivers: Vec<(&GpuGBuffer, &Camera)> = splats.iter().map(|(g, _)| g).zip(cameras).collect();
        let shadows = (0..cameras.len())
            .map(|i| self.shadow_step(scene, lights, settings, plan, &receivers, i))
            .collect::<Result<Vec<_>>>()?;
        drop(receivers);
        cameras
            .iter()
            .zip(splats)
            .zip(shadows)
            .map(|((camera, (gbuffer, stats)), shadow)| {
                self.shade_step(camera, lights, settings, plan, gbuffer, stats, shadow)
            })
            .collect()
    }

    /// Steps 2 to 5 of a frame whose G-buffers are splatted: the shadow pass
    /// and the shading.
    #[allow(clippy::too_many_arguments, reason = "one frame's inputs, each of a different stage")]
    fn finish(
        &mut self,
        scene: &GpuScene,
        camera: &Camera,
        lights: &Lights<'_>,
        settings: &RelightSettings,
        plan: &FramePlan,
        gbuffer: GpuGBuffer,
        stats: crate::splat::SplatStats,
    ) -> Result<RelitFrame> {
        let shadow = self.shadow_step(scene, lights, settings, plan, &[(&gbuffer, camera)], 0)?;
        self.shade_step(camera, lights, settings, plan, gbuffer, stats, shadow)
    }

    /// Steps 2 and 3 for the frame of `receivers[this]`: the sun's shadow map
    /// (splatted, or the last frame's) and its test at every pixel, when the
    /// visibility is editable and there is a sun. A map culled to receivers is
    /// culled to all of `receivers` (the frames of one batch), unless it is
    /// fitted to each view.
    fn shadow_step(
        &mut self,
        scene: &GpuScene,
        lights: &Lights<'_>,
        settings: &RelightSettings,
        plan: &FramePlan,
        receivers: &[(&GpuGBuffer, &Camera)],
        this: usize,
    ) -> Result<Option<FrameShadow>> {
        let (Some(sun), true) = (lights.sun, plan.decisions.shadow_pass) else { return Ok(None) };
        let &(gbuffer, camera) =
            receivers.get(this).ok_or_else(|| Error::Internal("a shadow test without its receivers".into()))?;
        let served = if settings.shadow.fit == ShadowFit::SceneBounds { receivers } else { &receivers[this..=this] };
        let mut timings = Timings::default();
        let (visibility, reused) =
            self.shadow_pass(scene, lights.bounds, camera, sun, gbuffer, served, settings, &mut timings)?;
        Ok(Some(FrameShadow { visibility, reused, timings }))
    }

    /// Steps 4 and 5: the shading, with the indirect network's L_ind when one is set.
    #[allow(clippy::too_many_arguments, reason = "one frame's inputs, each of a different stage")]
    fn shade_step(
        &mut self,
        camera: &Camera,
        lights: &Lights<'_>,
        settings: &RelightSettings,
        plan: &FramePlan,
        gbuffer: GpuGBuffer,
        stats: crate::splat::SplatStats,
        shadow: Option<FrameShadow>,
    ) -> Result<RelitFrame> {
        let (mut timings, pairs) = (stats.timings, stats.pairs);
        if let Some(s) = &shadow {
            timings.stages.extend(s.timings.stages.iter().cloned());
        }
        let inputs = ShadeInputs {
            gbuffer: &gbuffer,
            camera,
            environment: lights.environment,
            brdf: lights.brdf,
            sun: lights.sun,
            editable_visibility: shadow.as_ref().map(|s| &s.visibility),
            indirect: None,
        };
        let shaded = match self.network.as_mut() {
            Some(net) => self.shader.shade_with_network(&inputs, &plan.shade, net)?,
            None => self.shader.shade(&inputs, &plan.shade)?,
        };
        timings.stages.extend(shaded.timings.stages.iter().cloned());
        Ok(RelitFrame {
            shaded,
            timings,
            shadow_pass_ran: shadow.is_some(),
            shadow_map_reused: shadow.as_ref().is_some_and(|s| s.reused),
            gbuffer,
            visibility: shadow.map(|s| s.visibility),
            pairs,
            exposure_ev: settings.shade.exposure_ev,
            tone_map: settings.shade.tone_map,
        })
    }

    /// The shadow map of `sun` (reused from the last frame when reuse is on and
    /// nothing it depends on changed; culled to `receivers` where it serves
    /// only them) and the per-pixel visibility of the receivers in `gbuffer`;
    /// returns the visibility and whether the map was reused.
    #[allow(clippy::too_many_arguments, reason = "one pass's inputs, each of a different stage")]
    fn shadow_pass(
        &mut self,
        scene: &GpuScene,
        bounds: &Bounds,
        camera: &Camera,
        sun: &Sun,
        gbuffer: &GpuGBuffer,
        receivers: &[(&GpuGBuffer, &Camera)],
        settings: &RelightSettings,
        timings: &mut Timings,
    ) -> Result<(crate::gpu::Buffer, bool)> {
        let shadow = &settings.shadow;
        if shadow.fit == ShadowFit::Cascades {
            // Cascades serve this camera alone: splatted where its receivers look, never kept.
            self.shadow_map = None;
            let kind = settings.visibility_kind;
            let (visibility, _, t) = self.shadows.cascaded_visibility(
                &mut self.splatter,
                scene,
                bounds,
                sun,
                shadow,
                gbuffer,
                camera,
                kind,
                true,
            )?;
            timings.stages.extend(t.stages);
            return Ok((visibility, false));
        }
        // A map that will not be kept serves this frame's receivers alone: it
        // is splatted only where they look (the same visibility, for less).
        let cull = shadow.cull_to_receivers || !self.reuse_shadow_map;
        let key = ShadowMapKey {
            scene: scene.version(),
            light: light_camera(bounds, sun, shadow.resolution, shadow.fit, Some(camera))?,
            direction: sun.direction,
            depth: shadow.map_depth,
            tile: shadow.tile,
            surface_depth: shadow.map_surface_depth,
            coverage: shadow.map_coverage,
            receivers: cull.then(|| receivers.iter().map(|&(_, c)| c.clone()).collect()),
            splats_kept: settings.visibility_kind == VisibilityKind::Traced,
        };
        let reused = self.reuse_shadow_map && self.shadow_map.as_ref().is_some_and(|(k, _)| *k == key);
        if !reused {
            // Free the old map before splatting the new one.
            self.shadow_map = None;
            // A kept whole-scene map is splatted once per sun, with working buffers
            // sized by the whole scene: the pool's buffers (the camera's, most of
            // which it cannot use) are freed before it, and its own after it, so
            // neither lies beside the other's working set.
            let kept_whole = self.reuse_shadow_map && !cull;
            if kept_whole {
                self.device.release_pooled_memory();
            }
            let light = key.light.clone();
            let mut map = if cull {
                self.shadows.shadow_map_for_receivers(&mut self.splatter, scene, light, sun, shadow, receivers)?
            } else {
                self.shadows.shadow_map_from(&mut self.splatter, scene, light, sun, shadow)?
            };
            // Its stages are named "shadow map …" already.
            timings.stages.extend(map.frame.stats.timings.stages.iter().cloned());
            if self.reuse_shadow_map && settings.visibility_kind == VisibilityKind::Sigmoid {
                // A kept map holds its texels alone: the sigmoid test reads nothing else.
                map.release_splats(&self.device)?;
            }
            if kept_whole {
                self.device.release_pooled_memory();
            }
            self.shadow_map = Some((key, map));
        }
        let Some((_, map)) = &self.shadow_map else {
            return Err(Error::Internal("the shadow pass ran without a shadow map".into()));
        };
        let (visibility, t) = self.shadows.visibility(map, gbuffer, camera, shadow, settings.visibility_kind)?;
        timings.stages.extend(t.stages);
        if !self.reuse_shadow_map {
            self.shadow_map = None;
        }
        Ok((visibility, reused))
    }
}
