//! The shadow pass: the map splatted from the sun, and the per-pixel
//! visibility of the receivers by the sigmoid test or the traced reference.

use std::sync::Arc;

use super::*;
use crate::error::{Error, Result};
use crate::gpu::{
    kernels, Binding, BindingKind, Buffer, Device, Grid, Kernel, KernelDecl, MemoryKind, SpecValue, Timings,
};
use crate::primitives::sort::RadixSort;
use crate::scene::activate::GpuScene;
use crate::scene::{Bounds, Camera, Projection};
use crate::splat::{GpuGBuffer, SplatSettings, Splatter};

/// A kernel per [`ShadowFilter`], indexed by its code.
pub(super) type PerFilter = [Arc<Kernel>; 2];

/// The shadow kernels (forward and backward) and the backward's sort scratch.
pub struct ShadowPass {
    pub(super) device: Device,
    pub(super) test: PerFilter,
    pub(super) traced: Arc<Kernel>,
    pub(super) backward_upstream: PerFilter,
    pub(super) backward_bce: PerFilter,
    pub(super) bins: Arc<Kernel>,
    pub(super) gather: Arc<Kernel>,
    pub(super) sort: RadixSort,
    pub(super) receiver_tiles: Arc<Kernel>,
    pub(super) tile_dilate: Arc<Kernel>,
    pub(super) cascade_blend: Arc<Kernel>,
    /// Whether maps keep their pairs' tile ids ([`ShadowPass::set_map_pair_tiles`]).
    pub(super) map_pair_tiles: bool,
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
        let one = [BindingKind::UniformBuffer];
        let decl = KernelDecl { bindings: &one, push_constant_size: 0, specialization: &[] };
        let two = [BindingKind::UniformBuffer, BindingKind::UniformBuffer];
        // FILTER is specialization constant 1 of the test and backward kernels.
        let per_filter = |info, bindings: &[BindingKind], push: usize, loss: Option<u32>| -> Result<PerFilter> {
            let make = |filter: ShadowFilter| {
                let mut spec = vec![(1, SpecValue::U32(filter.code()))];
                spec.extend(loss.map(|l| (0, SpecValue::U32(l))));
                device.kernel(info, &KernelDecl { bindings, push_constant_size: push, specialization: &spec })
            };
            Ok([make(ShadowFilter::Depth)?, make(ShadowFilter::Pcf)?])
        };
        Ok(Self {
            device: device.clone(),
            test: per_filter(&kernels::SHADOW_TEST, &one, 0, None)?,
            traced: device.kernel(&kernels::SHADOW_TRACED, &decl)?,
            backward_upstream: per_filter(&kernels::SHADOW_BACKWARD, &two, 4, Some(0))?,
            backward_bce: per_filter(&kernels::SHADOW_BACKWARD, &two, 4, Some(1))?,
            bins: device.kernel(
                &kernels::SHADOW_BINS,
                &KernelDecl {
                    bindings: &[],
                    push_constant_size: std::mem::size_of::<backward::BinsPush>(),
                    specialization: &[],
                },
            )?,
            gather: device.kernel(
                &kernels::SHADOW_TEXEL_GRADS,
                &KernelDecl { bindings: &two, push_constant_size: 0, specialization: &[] },
            )?,
            sort: RadixSort::new(device)?,
            receiver_tiles: device.kernel(&kernels::SHADOW_RECEIVER_TILES, &decl)?,
            tile_dilate: device.kernel(
                &kernels::SHADOW_TILE_DILATE,
                &KernelDecl {
                    bindings: &[],
                    push_constant_size: std::mem::size_of::<TileDilatePush>(),
                    specialization: &[],
                },
            )?,
            cascade_blend: device.kernel(
                &kernels::SHADOW_CASCADE_BLEND,
                &KernelDecl {
                    bindings: &one,
                    push_constant_size: std::mem::size_of::<CascadePush>(),
                    specialization: &[],
                },
            )?,
            map_pair_tiles: true,
        })
    }

    /// Whether the maps this pass splats keep their pairs' tile ids
    /// ([`crate::splat::SplatFrame::pair_tiles`]; on by default), which only the backward pass
    /// reads: the relighter, which never differentiates its maps, turns them off.
    pub(crate) fn set_map_pair_tiles(&mut self, on: bool) {
        self.map_pair_tiles = on;
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
    pub(crate) fn shadow_map_from(
        &self,
        splatter: &mut Splatter,
        scene: &GpuScene,
        camera: Camera,
        sun: &Sun,
        settings: &ShadowSettings,
    ) -> Result<ShadowMap> {
        self.splat_map(splatter, scene, camera, sun, settings, None)
    }

    /// The map's splat, in the tiles `mask` wants (all without one).
    fn splat_map(
        &self,
        splatter: &mut Splatter,
        scene: &GpuScene,
        camera: Camera,
        sun: &Sun,
        settings: &ShadowSettings,
        mask: Option<&Buffer>,
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
            surface_depth: settings.map_surface_depth,
            median_coverage: settings.map_coverage,
            ..SplatSettings::default()
        };
        let mut frame = splatter.render_frame_for(scene, &camera, &splat, mask, self.map_pair_tiles)?;
        for stage in &mut frame.stats.timings.stages {
            stage.name = format!("shadow map {}", stage.name);
        }
        Ok(ShadowMap::new(camera, *sun, settings.map_depth, frame))
    }

    /// The shadow map from light camera `camera` (as [`ShadowPass::shadow_map`]
    /// makes it) splatted only in the map tiles that `receivers` (G-buffers
    /// with the cameras they were rendered from, as for
    /// [`ShadowPass::visibility`]) look up, and around them: casters elsewhere
    /// cost nothing, and every one of those receivers gets exactly the
    /// visibility the whole map gives (off-screen casters included: the
    /// culling is in light space). The map serves only those receivers: its
    /// G-buffer is written in those tiles alone ([`ShadowMap::wanted_tiles`]).
    pub fn shadow_map_for_receivers(
        &self,
        splatter: &mut Splatter,
        scene: &GpuScene,
        camera: Camera,
        sun: &Sun,
        settings: &ShadowSettings,
        receivers: &[(&GpuGBuffer, &Camera)],
    ) -> Result<ShadowMap> {
        self.shadow_map_for_receivers_in(splatter, scene, camera, sun, settings, receivers, (0.0, f32::MAX))
    }

    /// [`ShadowPass::shadow_map_for_receivers`] for the receivers whose camera
    /// depth lies in `depths` only (a cascade's slice): the others may see a
    /// wrong visibility in it.
    #[allow(clippy::too_many_arguments, reason = "the map's inputs and the receivers it serves")]
    pub(crate) fn shadow_map_for_receivers_in(
        &self,
        splatter: &mut Splatter,
        scene: &GpuScene,
        camera: Camera,
        sun: &Sun,
        settings: &ShadowSettings,
        receivers: &[(&GpuGBuffer, &Camera)],
        depths: (f32, f32),
    ) -> Result<ShadowMap> {
        let device = &self.device;
        let tile = settings.tile;
        let tiles = (camera.width.div_ceil(tile), camera.height.div_ceil(tile));
        let mask_bytes = u64::from(tiles.0) * u64::from(tiles.1) * 4;
        // The tiles under the receivers' points, then those and their neighbours.
        let centres = device.create_buffer("shadow receiver tiles", mask_bytes, MemoryKind::Storage)?;
        let mask = device.create_buffer("shadow tile mask", mask_bytes, MemoryKind::Storage)?;
        let uniforms = receivers
            .iter()
            .map(|(g, c)| {
                let (mut u, inputs) = receiver_uniform(&camera, settings.map_depth, (tiles.0, tile), g, c, settings)?;
                u.receiver_range = [depths.0, depths.1, 0.0, 0.0];
                let buffer = device.create_buffer(
                    "receiver tiles uniform",
                    std::mem::size_of::<ShadowUniform>() as u64,
                    MemoryKind::Storage,
                )?;
                Ok((u, inputs, buffer, u64::from(c.width) * u64::from(c.height)))
            })
            .collect::<Result<Vec<_>>>()?;
        let marked = device.run(|rec| -> Result<()> {
            rec.fill(&centres, 0)?;
            rec.begin_stage("shadow map receiver tiles");
            for (u, inputs, buffer, pixels) in &uniforms {
                u.record_receiver_tiles(rec, buffer, inputs, &centres)?;
                rec.dispatch(&self.receiver_tiles, Grid::Items(*pixels), &[Binding::from(buffer)], &())?;
            }
            let push = TileDilatePush {
                centres: rec.addr(&centres)?,
                wanted: rec.addr(&mask)?,
                tiles_x: tiles.0,
                tiles_y: tiles.1,
            };
            rec.dispatch(&self.tile_dilate, Grid::Items(u64::from(tiles.0) * u64::from(tiles.1)), &[], &push)?;
            rec.end_stage();
            Ok(())
        })?;
        let mut map = self.splat_map(splatter, scene, camera, sun, settings, Some(&mask))?;
        let mut stages = marked.stages;
        stages.append(&mut map.frame.stats.timings.stages);
        map.frame.stats.timings.stages = stages;
        map.wanted_tiles = Some(mask);
        Ok(map)
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
        if kind == VisibilityKind::Traced {
            map.check_splats("the traced visibility")?;
        }
        let device = &self.device;
        let pixels = u64::from(camera.width) * u64::from(camera.height);
        let out = device.create_buffer("visibility", pixels * 4, MemoryKind::Storage)?;
        let (u, inputs) = shadow_uniform(map, gbuffer, camera, settings)?;
        let uniform =
            device.create_buffer("shadow uniform", std::mem::size_of::<ShadowUniform>() as u64, MemoryKind::Storage)?;
        let (kernel, stage) = match kind {
            VisibilityKind::Sigmoid => (&self.test[settings.filter.code() as usize], "sigmoid shadow test"),
            VisibilityKind::Traced => (&self.traced, "traced visibility"),
        };
        let timings = device.run(|rec| -> Result<()> {
            u.record(rec, &uniform, &inputs, Some(&out))?;
            if let Some(word) = settings.prefill {
                rec.fill(&out, word)?;
            }
            rec.begin_stage(stage);
            rec.dispatch(kernel, Grid::Items(pixels), &[Binding::from(&uniform)], &())?;
            rec.end_stage();
            Ok(())
        })?;
        Ok((out, timings))
    }
}
