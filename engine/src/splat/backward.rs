//! The splatting backward pass: per-pixel loss gradients of any blended
//! G-buffer channel → gradients of every Gaussian's stored parameters.
//!
//! Two kernels, no atomics, deterministic: `splat_backward_tiles.comp` (one
//! workgroup per tile) replays each pixel's blend, walks it back to front
//! (docs/conventions.md §4) and sums the tile's pixels per splat, in pixel order through
//! shared memory, into one record per (tile, splat) pair;
//! `splat_backward_gaussians.comp` (one invocation per Gaussian) sums its
//! records in order and chains them through the projection. The records sit
//! where the forward's keys kernel put the pairs (found by binary search in
//! [`SplatFrame::pair_tiles`]), so no second sort is needed. The tile kernel
//! loads each splat once per subgroup (subgroup ballot).
//!
//! Cost on lavapipe: the barriers between batches of splats dominate (a
//! barrier spills every invocation's state); subgroupAdd reductions were
//! slower there still.
//!
//! What is not differentiated is listed in [`super::cpu_backward`], the f64 twin.

use bytemuck::{Pod, Zeroable};
use std::sync::Arc;

use super::{Channel, FrameBuffers, PerChannel, SplatFrame, Splatter};
use crate::error::{Error, Result};
use crate::gpu::{
    kernels, Binding, BindingKind, Buffer, Device, DeviceAddress, Grid, Kernel, KernelDecl, MemoryKind, SpecValue,
    Timings,
};
use crate::scene::activate::GpuScene;
use crate::scene::order::{ReorderKernels, RowMap};

/// Per-pixel loss gradients of the blended channels (layout as
/// [`super::GpuGBuffer`]: planar, rgb/normal/albedo 3 floats per pixel).
/// Absent channels have zero gradient and cost nothing.
#[derive(Default)]
pub struct BlendGrads {
    /// dL/d rgb (composited over the background).
    pub rgb: Option<Buffer>,
    /// dL/d alpha.
    pub alpha: Option<Buffer>,
    /// dL/d of each optional channel.
    pub channels: PerChannel<Buffer>,
}

impl BlendGrads {
    /// The `GRADS` specialization constant (keep in sync with
    /// `splat_backward.glsl`): the channel bits, then rgb and alpha.
    pub fn bits(&self) -> u32 {
        let n = Channel::ALL.len();
        self.channels.present().bits() | u32::from(self.rgb.is_some()) << n | u32::from(self.alpha.is_some()) << (n + 1)
    }

    /// The gradient of an optional channel, when given.
    pub fn get(&self, channel: Channel) -> Option<&Buffer> {
        self.channels.get(channel)
    }

    fn buffers(&self) -> Vec<(&Buffer, u64, &'static str)> {
        let fixed = [(&self.rgb, 3, "rgb"), (&self.alpha, 1, "alpha")];
        fixed
            .into_iter()
            .filter_map(|(b, k, n)| b.as_ref().map(|b| (b, k, n)))
            .chain(self.channels.iter().map(|(c, b)| (b, c.floats() as u64, c.name())))
            .collect()
    }
}

/// Gradients of every Gaussian's stored parameters, on the GPU.
pub struct GaussianGradients {
    /// dL/d mean, 3 floats each.
    pub means: Buffer,
    /// dL/d log-scale, 3 floats each.
    pub log_scales: Buffer,
    /// dL/d quaternion (w, x, y, z), 4 floats each.
    pub rotations: Buffer,
    /// dL/d opacity logit.
    pub opacity_logits: Buffer,
    /// dL/d blended values when asked for: 16 floats each (rgb, 0, normal.xyz,
    /// roughness, albedo.rgb, metallic, ao, visibility, 0, 0).
    pub values: Option<Buffer>,
    /// GPU time of the two kernels.
    pub timings: Timings,
}

/// [`GaussianGradients`] on the host.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct HostGaussianGradients {
    /// dL/d mean.
    pub means: Vec<[f32; 3]>,
    /// dL/d log-scale.
    pub log_scales: Vec<[f32; 3]>,
    /// dL/d quaternion.
    pub rotations: Vec<[f32; 4]>,
    /// dL/d opacity logit.
    pub opacity_logits: Vec<f32>,
    /// dL/d blended values, 16 per Gaussian.
    pub values: Option<Vec<[f32; 16]>>,
}

impl GaussianGradients {
    /// Reads the gradients back.
    pub fn read(&self, device: &Device) -> Result<HostGaussianGradients> {
        Ok(HostGaussianGradients {
            means: device.read_buffer(&self.means)?,
            log_scales: device.read_buffer(&self.log_scales)?,
            rotations: device.read_buffer(&self.rotations)?,
            opacity_logits: device.read_buffer(&self.opacity_logits)?,
            values: self.values.as_ref().map(|v| device.read_buffer(v)).transpose()?,
        })
    }
}

/// Addresses for the backward kernels: `Backward` in `splat_backward.glsl`
/// (std140; checked against it by `check_layout`), filled in the recording.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub(crate) struct BackwardUniform {
    d_rgb: DeviceAddress,
    d_alpha: DeviceAddress,
    d_depth: DeviceAddress,
    d_median_depth: DeviceAddress,
    d_normal: DeviceAddress,
    d_albedo: DeviceAddress,
    d_roughness: DeviceAddress,
    d_metallic: DeviceAddress,
    d_ao: DeviceAddress,
    d_visibility: DeviceAddress,
    pairs: DeviceAddress,
    unused0: DeviceAddress,
    d_means: DeviceAddress,
    d_log_scales: DeviceAddress,
    d_rotations: DeviceAddress,
    d_opacity_logits: DeviceAddress,
    d_values: DeviceAddress,
    unused1: DeviceAddress,
}
crate::gpu::gpu_layout!(
    BackwardUniform,
    "Backward",
    [
        d_rgb,
        d_alpha,
        d_depth,
        d_median_depth,
        d_normal,
        d_albedo,
        d_roughness,
        d_metallic,
        d_ao,
        d_visibility,
        pairs,
        unused0,
        d_means,
        d_log_scales,
        d_rotations,
        d_opacity_logits,
        d_values,
        unused1
    ]
);

/// Floats per (tile, splat) record for gradient set `bits`, with the slope's
/// two for surface depths (keep in sync with `STRIDE`).
fn record_stride(bits: u32, surface_depth: bool) -> u64 {
    8 + if bits & 256 != 0 { 4 } else { 0 } + if bits & 252 != 0 { 12 } else { 0 } + if surface_depth { 2 } else { 0 }
}

/// The two backward kernels for one gradient set.
pub(super) struct BackwardKernels {
    tiles: Arc<Kernel>,
    gaussians: Arc<Kernel>,
}

impl Splatter {
    /// Gradients of every Gaussian of `scene` from per-pixel gradients of
    /// `frame`'s blended channels. `frame` must have been rendered from this
    /// `scene`, with the features when feature gradients are given.
    /// `with_values` also returns the per-Gaussian gradients of the blended values.
    pub fn backward(
        &mut self,
        frame: &SplatFrame,
        scene: &GpuScene,
        grads: &BlendGrads,
        with_values: bool,
    ) -> Result<GaussianGradients> {
        let device = self.device.clone();
        let info = device.info().clone();
        if !info.subgroup_ballot {
            return Err(Error::unsupported(
                "the splat backward pass needs subgroup ballot (elect, broadcast) in compute shaders",
            ));
        }
        frame.camera.require_no_lens("the splat backward pass")?;
        if frame.occluded {
            return Err(Error::unsupported("the splat backward pass of frames hidden behind a host's depth"));
        }
        if frame.scene_means != scene.means.id() || frame.gaussians != scene.count as u64 {
            return Err(Error::invalid("splat frame", "was rendered from another scene"));
        }
        if frame.slot_gaussians.is_some() {
            return Err(Error::invalid(
                "splat frame",
                "holds records for its listed Gaussians only (render it with SplatSettings::compact_splats off)",
            ));
        }
        let Some(pair_tiles) = frame.pair_tiles.as_ref() else {
            return Err(Error::invalid("splat frame", "keeps no pair tiles (render it with Splatter::render_frame)"));
        };
        let pixels = u64::from(frame.camera.width) * u64::from(frame.camera.height);
        for (b, k, name) in grads.buffers() {
            if b.size() < k * pixels * 4 {
                return Err(Error::invalid(
                    format!("gradient of {name} ({} bytes)", b.size()),
                    format!(
                        "does not fit the {}x{} frame, which needs {} bytes",
                        frame.camera.width,
                        frame.camera.height,
                        k * pixels * 4
                    ),
                ));
            }
        }
        let bits = grads.bits();
        if bits & 252 != 0 && frame.features.is_none() {
            return Err(Error::invalid(
                "feature gradient",
                "needs a frame rendered with a feature channel (normal or materials)",
            ));
        }
        if bits & 252 != 0 && frame.packed_features {
            return Err(Error::invalid(
                "feature gradient",
                "needs a frame whose features are stored as floats (SplatSettings::packed_features off)",
            ));
        }
        if grads.rgb.is_some() && frame.gbuffer.rgb.is_none() {
            // Its splats' colours were not evaluated (the records hold 0).
            return Err(Error::invalid("rgb gradient", "needs a frame rendered with rgb (SplatSettings::rgb on)"));
        }
        let tile = frame.tile;
        let k = {
            // Splats per barrier: as many as every pixel's terms (batch × stride ×
            // tile² floats) fit in shared memory (32 KiB on lavapipe) and one
            // invocation per (splat, component) can sum them (batch × stride ≤ tile²).
            let stride = record_stride(bits, frame.surface_depth) as u32;
            let shared = info.max_shared_memory;
            let pixels = tile * tile;
            let batch = ((shared - 64) / 4 / (pixels * stride)).min(pixels / stride);
            if batch == 0 {
                return Err(Error::unsupported(format!(
                    "the splat backward pass at tile size {tile} needs {} bytes of shared memory, more than the \
                     {shared} it may use here; render the frame with a smaller tile",
                    pixels * stride * 4 + 64
                )));
            }
            let [x, y] = super::tile_spec(tile);
            let surface = (2, SpecValue::Bool(frame.surface_depth));
            let mut spec = vec![(0, SpecValue::U32(bits)), surface, (1, SpecValue::U32(batch)), x, y];
            let gaussians_spec = spec[..2].to_vec();
            // The transmittance at which the forward blend read the median.
            if frame.median_coverage != super::DEFAULT_MEDIAN_COVERAGE {
                spec.push((3, SpecValue::F32(1.0 - frame.median_coverage)));
            }
            let with_spec = KernelDecl {
                bindings: &[BindingKind::UniformBuffer, BindingKind::UniformBuffer],
                push_constant_size: 0,
                specialization: &spec,
            };
            BackwardKernels {
                tiles: device.kernel(&kernels::SPLAT_BACKWARD_TILES, &with_spec)?,
                gaussians: device.kernel(
                    &kernels::SPLAT_BACKWARD_GAUSSIANS,
                    &KernelDecl { specialization: &gaussians_spec, ..with_spec },
                )?,
            }
        };
        let n = frame.gaussians;
        let stride = record_stride(bits, frame.surface_depth);
        let pairs =
            device.create_buffer("backward pair records", frame.stats.pairs * stride * 4, MemoryKind::Storage)?;
        let gradients = |suffix: &str| -> Result<GaussianGradients> {
            let f = |name: &str, floats: u64| {
                device.create_buffer(&format!("{name}{suffix}"), n * floats * 4, MemoryKind::Storage)
            };
            Ok(GaussianGradients {
                means: f("dL/d means", 3)?,
                log_scales: f("dL/d log-scales", 3)?,
                rotations: f("dL/d rotations", 4)?,
                opacity_logits: f("dL/d opacity logits", 1)?,
                values: with_values.then(|| f("dL/d values", 16)).transpose()?,
                timings: Timings::default(),
            })
        };
        let out = gradients("")?;
        // An arranged scene's gradients leave in file order (scene::order): gathered into these.
        let file_rows = match scene.row_order() {
            Some(order) => Some((order, ReorderKernels::new(&device)?, gradients(", file order")?)),
            None => None,
        };
        let uniform = device.create_buffer(
            "backward uniform",
            std::mem::size_of::<BackwardUniform>() as u64,
            MemoryKind::Storage,
        )?;
        let (tiles_x, tiles_y) = frame.tiles();
        let timings = device.run(|rec| -> Result<()> {
            let buffers = FrameBuffers {
                scene,
                splats: Some(&frame.splats),
                features: frame.features.as_ref(),
                tile_counts: Some(&frame.pair_offsets),
                keys: None,
                values: Some(&frame.sorted_gaussians),
                pair_tiles: Some(pair_tiles),
                ranges: &frame.ranges,
                out: &frame.gbuffer,
                occluder: None,
                tile_mask: None,
                visible_slots: None,
                slot_gaussians: None,
                wanted_rows: None,
            };
            frame.params.record(rec, &frame.uniform, &buffers)?;
            let g = grads;
            let u = BackwardUniform {
                d_rgb: rec.addr_or_null(g.rgb.as_ref())?,
                d_alpha: rec.addr_or_null(g.alpha.as_ref())?,
                d_depth: rec.addr_or_null(g.channels.get(Channel::Depth))?,
                d_median_depth: rec.addr_or_null(g.channels.get(Channel::MedianDepth))?,
                d_normal: rec.addr_or_null(g.channels.get(Channel::Normal))?,
                d_albedo: rec.addr_or_null(g.channels.get(Channel::Albedo))?,
                d_roughness: rec.addr_or_null(g.channels.get(Channel::Roughness))?,
                d_metallic: rec.addr_or_null(g.channels.get(Channel::Metallic))?,
                d_ao: rec.addr_or_null(g.channels.get(Channel::Ao))?,
                d_visibility: rec.addr_or_null(g.channels.get(Channel::Visibility))?,
                pairs: rec.addr(&pairs)?,
                d_means: rec.addr(&out.means)?,
                d_log_scales: rec.addr(&out.log_scales)?,
                d_rotations: rec.addr(&out.rotations)?,
                d_opacity_logits: rec.addr(&out.opacity_logits)?,
                d_values: rec.addr_or_null(out.values.as_ref())?,
                ..BackwardUniform::default()
            };
            rec.update(&uniform, 0, &u)?;
            rec.begin_stage("backward blend");
            rec.fill(&pairs, 0)?;
            rec.dispatch(
                &k.tiles,
                Grid::Groups(u64::from(tiles_x) * u64::from(tiles_y)),
                &[Binding::from(&frame.uniform), Binding::from(&uniform)],
                &(),
            )?;
            rec.begin_stage("backward projection");
            rec.dispatch(&k.gaussians, Grid::Items(n), &[Binding::from(&frame.uniform), Binding::from(&uniform)], &())?;
            if let Some((order, map, file)) = &file_rows {
                let kinds = [
                    (&out.means, &file.means, 3),
                    (&out.log_scales, &file.log_scales, 3),
                    (&out.rotations, &file.rotations, 4),
                    (&out.opacity_logits, &file.opacity_logits, 1),
                ];
                let values = out.values.as_ref().zip(file.values.as_ref()).map(|(d, f)| (d, f, 16));
                for (device_rows, file_rows, w) in kinds.into_iter().chain(values) {
                    let rows = RowMap::Gather(order.file_to_device());
                    map.record_rows(rec, (device_rows, w, 0), (file_rows, w, 0), rows, n, w)?;
                }
            }
            rec.end_stage();
            Ok(())
        })?;
        match file_rows {
            Some((_, _, file)) => Ok(GaussianGradients { timings, ..file }),
            None => Ok(GaussianGradients { timings, ..out }),
        }
    }
}
