//! The sigmoid shadow test's backward pass on the GPU.
//!
//! Per receiver pixel (`shadow_backward.comp`): dL/dx from upstream dL/dV or
//! from the paper's BCE visibility loss, then dL/dk, dL/dz, the receiver
//! G-buffer's depth gradients, and dL/dz_s to spread over the pixel's four
//! bilinear texels. The spread is a gather, not an atomic scatter: pixels are
//! sorted (stable radix sort) by the first texel of their footprint
//! (`shadow_bins.comp` finds each texel's run) and each texel sums the runs
//! of itself and its three up-left neighbours in a fixed order
//! (`shadow_texel_grads.comp`), so gradients are bit-for-bit repeatable.
//! The results are [`BlendGrads`] for the shadow map's and the receivers'
//! splat frames: [`crate::splat::Splatter::backward`] takes them to the Gaussians.

use bytemuck::{Pod, Zeroable};

use super::{shadow_uniform, DepthMode, ShadowMap, ShadowPass, ShadowSettings};
use crate::error::{Error, Result};
use crate::gpu::{Binding, Buffer, DeviceAddress, Grid, MemoryKind, Timings};
use crate::scene::Camera;
use crate::splat::backward::BlendGrads;
use crate::splat::{Channel, GpuGBuffer, PerChannel};

/// What drives the backward pass (per receiver pixel, float each).
#[derive(Clone, Copy)]
pub enum GpuVisibilityLoss<'a> {
    /// Upstream gradients dL/dV_e.
    Upstream(&'a Buffer),
    /// The visibility loss: mean BCE(V_e, V_f) over receivers with a surface
    /// inside the map, given V_f (see [`super::cpu::VisibilityLoss::Bce`]).
    Bce(&'a Buffer),
}

/// Gradients from the sigmoid shadow test.
pub struct ShadowBackward {
    /// For the shadow map's splat frame (its depth channel, and alpha for expected depth).
    pub map: BlendGrads,
    /// For the receivers' splat frame.
    pub receiver: BlendGrads,
    /// dL/dz_s per shadow-map texel.
    pub texel_depth: Buffer,
    /// dL/dz per receiver pixel (light-space depth, map position held fixed).
    pub light_depth: Buffer,
    /// dL/dk.
    pub k: f64,
    /// The BCE loss (0 with upstream gradients).
    pub loss: f64,
    /// Receivers with a surface inside the map.
    pub receivers: u32,
    /// GPU time per stage.
    pub timings: Timings,
}

/// Addresses for the backward kernels: `ShadowBackward` in
/// `shadow_backward.glsl` (std140; checked against it by `check_layout`),
/// filled in the recording.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub(crate) struct ShadowBackwardUniform {
    upstream: DeviceAddress,
    loss: DeviceAddress,
    dk: DeviceAddress,
    light_depth: DeviceAddress,
    d_receiver_depth: DeviceAddress,
    d_receiver_alpha: DeviceAddress,
    bin_keys: DeviceAddress,
    bin_pixels: DeviceAddress,
    records: DeviceAddress,
    bin_ranges: DeviceAddress,
    texel_depth: DeviceAddress,
    d_map_depth: DeviceAddress,
    d_map_alpha: DeviceAddress,
    receiver_count: DeviceAddress,
    counts: [u32; 4],
}
crate::gpu::gpu_layout!(
    ShadowBackwardUniform,
    "ShadowBackward",
    [
        upstream,
        loss,
        dk,
        light_depth,
        d_receiver_depth,
        d_receiver_alpha,
        bin_keys,
        bin_pixels,
        records,
        bin_ranges,
        texel_depth,
        d_map_depth,
        d_map_alpha,
        receiver_count,
        counts
    ]
);

/// Push constants of `shadow_bins.comp` (its `BinsPush` block; checked by `check_layout`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub(crate) struct BinsPush {
    keys: DeviceAddress,
    ranges: DeviceAddress,
    count: u32,
    none: u32,
}
crate::gpu::gpu_layout!(BinsPush, "BinsPush", [keys, ranges, count, none]);

fn depth_grads(mode: DepthMode, depth: Buffer, alpha: Option<Buffer>) -> BlendGrads {
    match mode {
        DepthMode::Median => {
            BlendGrads { channels: PerChannel::default().with(Channel::MedianDepth, depth), ..BlendGrads::default() }
        }
        DepthMode::Expected | DepthMode::ExpectedOverFar => {
            BlendGrads { channels: PerChannel::default().with(Channel::Depth, depth), alpha, ..BlendGrads::default() }
        }
    }
}

impl ShadowPass {
    /// Backward of [`ShadowPass::visibility`] with [`super::VisibilityKind::Sigmoid`].
    pub fn backward(
        &mut self,
        map: &ShadowMap,
        gbuffer: &GpuGBuffer,
        camera: &Camera,
        settings: &ShadowSettings,
        loss: GpuVisibilityLoss<'_>,
    ) -> Result<ShadowBackward> {
        map.check_splats("the backward pass")?;
        let device = self.device.clone();
        let (u, inputs) = shadow_uniform(map, gbuffer, camera, settings)?;
        let pixels = u64::from(camera.width) * u64::from(camera.height);
        let texels = u64::from(map.camera.width) * u64::from(map.camera.height);
        let (upstream, bce) = match loss {
            GpuVisibilityLoss::Upstream(b) => (b, false),
            GpuVisibilityLoss::Bce(b) => (b, true),
        };
        if upstream.size() < pixels * 4 {
            return Err(Error::invalid(
                format!("visibility gradient or target of {} bytes", upstream.size()),
                format!("does not fit {}x{} receivers ({} bytes)", camera.width, camera.height, pixels * 4),
            ));
        }
        if pixels >= u64::from(u32::MAX) || texels >= u64::from(u32::MAX) {
            return Err(Error::invalid("image or shadow map", "is too large for the backward pass"));
        }
        let f = |name: &str, n: u64| device.create_buffer(name, n * 4, MemoryKind::Storage);
        let loss_px = f("shadow loss per pixel", pixels)?;
        let dk_px = f("dL/dk per pixel", pixels)?;
        let light_depth = f("dL/dz per pixel", pixels)?;
        let receiver_depth = f("dL/d receiver depth", pixels)?;
        let receiver_alpha =
            (settings.receiver_depth == DepthMode::Expected).then(|| f("dL/d receiver alpha", pixels)).transpose()?;
        let keys = f("shadow bin keys", 2 * pixels)?;
        let order = f("shadow bin pixels", pixels)?;
        let records = f("shadow pixel records", 8 * pixels)?;
        let ranges = f("shadow bin ranges", 2 * texels)?;
        let texel_depth = f("dL/dz_s", texels)?;
        let map_depth = f("dL/d map depth", texels)?;
        let map_alpha = (map.depth != DepthMode::Median).then(|| f("dL/d map alpha", texels)).transpose()?;
        let count = f("shadow receiver count", 1)?;
        let shadow_u = device.create_buffer(
            "shadow uniform",
            std::mem::size_of::<super::ShadowUniform>() as u64,
            MemoryKind::Storage,
        )?;
        let backward_u = device.create_buffer(
            "shadow backward uniform",
            std::mem::size_of::<ShadowBackwardUniform>() as u64,
            MemoryKind::Storage,
        )?;
        let key_bits = 64 - texels.leading_zeros();
        self.sort.reserve(&device, pixels)?;
        let filter = settings.filter.code() as usize;
        let kernel = if bce { &self.backward_bce[filter] } else { &self.backward_upstream[filter] };
        let (bins, gather, sort) = (&self.bins, &self.gather, &self.sort);
        let timings = device.run(|rec| -> Result<()> {
            u.record(rec, &shadow_u, &inputs, None)?;
            let bu = ShadowBackwardUniform {
                upstream: rec.addr(upstream)?,
                loss: rec.addr(&loss_px)?,
                dk: rec.addr(&dk_px)?,
                light_depth: rec.addr(&light_depth)?,
                d_receiver_depth: rec.addr(&receiver_depth)?,
                d_receiver_alpha: rec.addr_or_null(receiver_alpha.as_ref())?,
                bin_keys: rec.addr(&keys)?,
                bin_pixels: rec.addr(&order)?,
                records: rec.addr(&records)?,
                bin_ranges: rec.addr(&ranges)?,
                texel_depth: rec.addr(&texel_depth)?,
                d_map_depth: rec.addr(&map_depth)?,
                d_map_alpha: rec.addr_or_null(map_alpha.as_ref())?,
                receiver_count: rec.addr(&count)?,
                counts: [pixels as u32, texels as u32, texels as u32, 0],
            };
            rec.update(&backward_u, 0, &bu)?;
            let both = [Binding::from(&shadow_u), Binding::from(&backward_u)];
            rec.begin_stage("shadow backward");
            rec.fill(&count, 0)?;
            rec.dispatch(kernel, Grid::Items(pixels), &both, &0u32)?;
            rec.dispatch(kernel, Grid::Items(pixels), &both, &1u32)?;
            rec.begin_stage("shadow gradient gather");
            sort.record(rec, &keys, &order, pixels, key_bits)?;
            rec.fill(&ranges, 0)?;
            let push = BinsPush {
                keys: rec.addr(&keys)?,
                ranges: rec.addr(&ranges)?,
                count: pixels as u32,
                none: texels as u32,
            };
            rec.dispatch(bins, Grid::Items(pixels), &[], &push)?;
            rec.dispatch(gather, Grid::Items(texels), &both, &())?;
            rec.end_stage();
            Ok(())
        })?;
        let sum = |b: &Buffer| -> Result<f64> { Ok(device.read_buffer::<f32>(b)?.iter().map(|v| f64::from(*v)).sum()) };
        let k = sum(&dk_px)?;
        let loss_value = if bce { sum(&loss_px)? } else { 0.0 };
        let receivers = device.read_buffer::<u32>(&count)?[0];
        Ok(ShadowBackward {
            map: depth_grads(map.depth, map_depth, map_alpha),
            receiver: depth_grads(settings.receiver_depth, receiver_depth, receiver_alpha),
            texel_depth,
            light_depth,
            k,
            loss: loss_value,
            receivers,
            timings,
        })
    }
}
