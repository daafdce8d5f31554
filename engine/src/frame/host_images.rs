//! Frames written into a host's own Vulkan images, composited over the
//! host's meshes by depth (game engines: docs/embedding.md).
//!
//! A call reads what it needs of the host's images first (its colour and
//! depth, when compositing: one submission that waits on the host's
//! semaphores), renders as usual with the splats hidden behind the host's
//! depth, then packs the frame into the images' texel formats and copies it
//! in (one submission that signals the host's semaphores). Pixels never
//! leave the device.
//!
//! What lands in the images:
//! - 8-bit colour (RGBA8/BGRA8, UNORM or SRGB): a relit frame's display
//!   values (exposure, tone map, sRGB-encoded: the bytes `SRUG_FORMAT_RGBA8_SRGB`
//!   reads), a plain frame's colour as is. Float colour (RGBA16F/RGBA32F):
//!   linear radiance of a relit frame, a plain frame's colour. Alpha: coverage.
//! - Composited, a relit frame's background is black, so its radiance is
//!   premultiplied: float images get `rgb + (1 − α)·host`; 8-bit images blend
//!   in linear light, the splats' straight colour as a display value by α over
//!   the host's decoded display value, and are re-encoded; a plain frame's
//!   colour blends in its own values, as 3DGS composites. Alpha: α + (1 − α)·host α.
//! - Depth (R32F or D32): the camera z where the splats' coverage crosses 50%
//!   (the median depth) in the host's convention, "nothing" where it never
//!   does; composited, the host's value stays bit for bit unless a splat is nearer.

use std::sync::Arc;

use bytemuck::{Pod, Zeroable};

use crate::error::{Error, Result};
use crate::gpu::ash::vk;
use crate::gpu::{
    kernels, Binding, Buffer, Device, DeviceAddress, Grid, HostBuffer, HostImage, HostImageAccess, HostImageFormat,
    HostSync, Kernel, KernelDecl, MemoryKind, Timings,
};
use crate::shade::ToneMap;
use crate::splat::{Channel, HostDepth};

/// The host's images one frame is written into, and how.
#[derive(Clone, Debug, PartialEq)]
pub struct HostTargets {
    /// The colour image (RGBA8/BGRA8 UNORM or SRGB, RGBA16F, RGBA32F).
    pub colour: Option<HostImage>,
    /// The depth image (R32F or D32), in `depth_convention`.
    pub depth: Option<HostImage>,
    /// How the depth image encodes depth.
    pub depth_convention: HostDepth,
    /// Read the images first: splats behind the host's depth are hidden and
    /// the rest blend over the host's colour; the depth keeps the nearer.
    pub composite: bool,
    /// Further frame values copied into the host's buffers (tightly packed
    /// f32, row-major, the channel's components per pixel).
    pub buffers: Vec<(FrameChannel, HostBuffer)>,
    /// The host's semaphores: waited on before the images are touched, signalled when written.
    pub sync: HostSync,
}

/// A frame's per-pixel values a host can have copied into its buffers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameChannel {
    /// The splatted colour (premultiplied).
    Rgb,
    /// Coverage.
    Alpha,
    /// An optional G-buffer channel (splatted with the frame on request).
    GBuffer(Channel),
    /// L_sun of a relit frame.
    SunLight,
    /// L_sky of a relit frame.
    SkyLight,
    /// Linear radiance of a relit frame.
    Radiance,
}

impl FrameChannel {
    /// This channel's buffer in a frame's G-buffers and shading outputs
    /// (`None`: not rendered, or a shading output of a frame without shading).
    pub fn resolve<'a>(
        self,
        gbuffer: &'a crate::splat::GpuGBuffer,
        shaded: Option<&'a crate::shade::ShadedFrame>,
    ) -> Option<&'a Buffer> {
        match self {
            Self::Rgb => gbuffer.rgb.as_ref(),
            Self::Alpha => Some(&gbuffer.alpha),
            Self::GBuffer(c) => gbuffer.get(c),
            Self::SunLight => shaded.map(|s| &s.sun),
            Self::SkyLight => shaded.map(|s| &s.sky),
            Self::Radiance => shaded.map(|s| &s.radiance),
        }
    }

    /// Floats per pixel.
    pub fn components(self) -> usize {
        match self {
            Self::Rgb | Self::SunLight | Self::SkyLight | Self::Radiance => 3,
            Self::Alpha => 1,
            Self::GBuffer(c) => c.floats(),
        }
    }
}

impl HostTargets {
    /// Adds what these targets read to `settings`: the median depth for a
    /// depth image, the G-buffer channels of the host buffers, and the
    /// splatted colour where one reads it ([`FrameChannel::Rgb`]).
    pub fn request_channels(&self, settings: &mut crate::frame::RelightSettings) {
        if self.depth.is_some() {
            settings.extra_channels.median_depth = true;
        }
        for (c, _) in &self.buffers {
            match c {
                FrameChannel::GBuffer(c) => settings.extra_channels.set(*c),
                FrameChannel::Rgb => settings.rgb = true,
                _ => {}
            }
        }
    }

    /// Checks every image for a `width`×`height` frame on `device`; returns
    /// the colour and depth formats.
    pub fn validate(
        &self,
        device: &Device,
        width: u32,
        height: u32,
    ) -> Result<(Option<HostImageFormat>, Option<HostImageFormat>)> {
        if self.colour.is_none() && self.depth.is_none() && self.buffers.is_empty() {
            return Err(Error::invalid("host targets", "name no image and no buffer"));
        }
        self.depth_convention.validate()?;
        self.sync.check("host targets").map_err(user_error)?;
        let access = if self.composite { HostImageAccess::ReadWrite } else { HostImageAccess::Write };
        let mut formats = [None, None];
        for (i, (name, image)) in [("colour image", &self.colour), ("depth image", &self.depth)].into_iter().enumerate()
        {
            let Some(image) = image else { continue };
            let format = image.check(device, name, access).map_err(user_error)?;
            if format.is_single_channel() != (i == 1) {
                return Err(Error::invalid(
                    format!("{name} of format {:?}", image.format),
                    if i == 1 { "is not a depth format (R32_SFLOAT or D32_SFLOAT)" } else { "is not a colour format" },
                ));
            }
            if (image.width, image.height) != (width, height) {
                return Err(Error::invalid(
                    format!("{name} of {}x{}", image.width, image.height),
                    format!("does not match the rendered frame's {width}x{height}"),
                ));
            }
            formats[i] = Some(format);
        }
        let pixels = u64::from(width) * u64::from(height);
        for (channel, buffer) in &self.buffers {
            let bytes = pixels * channel.components() as u64 * 4;
            buffer.check(&format!("host buffer for {channel:?}"), bytes).map_err(user_error)?;
        }
        if let (Some(c), Some(d)) = (&self.colour, &self.depth) {
            if c.image == d.image {
                return Err(Error::invalid("host targets", "name one image as both colour and depth"));
            }
        }
        Ok((formats[0], formats[1]))
    }
}

/// A statement of the host's refused by the core: the caller's error, not srug's.
fn user_error(e: crate::gpu::GpuError) -> Error {
    match e {
        crate::gpu::GpuError::InvalidArgument { what, why } => Error::invalid(what, why),
        other => other.into(),
    }
}

/// A rendered frame's buffers, as the writer reads them.
#[derive(Clone, Debug)]
pub struct FrameOutputs<'a> {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// 3 floats per pixel: a relit frame's linear radiance or a plain frame's colour.
    pub colour: &'a Buffer,
    /// Coverage.
    pub alpha: &'a Buffer,
    /// Median depth (camera z, 0 where none), for a depth image.
    pub median_depth: Option<&'a Buffer>,
    /// For a relit frame: the exposure in EV and the tone map of its display values.
    pub display: Option<(f32, ToneMap)>,
    /// The frame's buffers for `HostTargets::buffers`, in their order (`None`: not rendered).
    pub channels: Vec<Option<&'a Buffer>>,
}

/// The host's texels read before a composited frame.
#[derive(Debug, Default)]
pub struct HostPixels {
    /// The colour image's texels, packed.
    pub colour: Option<Buffer>,
    /// The depth image's values, one f32 per pixel.
    pub depth: Option<Buffer>,
    /// Whether the read's submission waited on the host's semaphores.
    waited: bool,
}

/// The texel-packing uniform: `HostPack` in `host_image_pack.comp` (std140;
/// checked against it by `check_layout`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub(crate) struct PackUniform {
    size: [u32; 4],
    display: [f32; 4],
    depth: [f32; 4],
    colour: DeviceAddress,
    alpha: DeviceAddress,
    median_depth: DeviceAddress,
    host: DeviceAddress,
    out_texels: DeviceAddress,
}
crate::gpu::gpu_layout!(PackUniform, "HostPack", [size, display, depth, colour, alpha, median_depth, host, out_texels]);

/// `flags` bit: blend over (or keep the nearer of) the host's texels.
const COMPOSITE: u32 = 1;
/// `flags` bit: the colour is radiance to encode as display values.
const DISPLAY: u32 = 2;

/// The kernel's texel-format code.
fn format_code(format: HostImageFormat) -> u32 {
    use HostImageFormat as F;
    match format {
        F::Rgba8Unorm | F::Rgba8Srgb => 0,
        F::Bgra8Unorm | F::Bgra8Srgb => 1,
        F::Rgba16Float => 2,
        F::Rgba32Float => 3,
        F::R32Float | F::D32Float => 4,
    }
}

fn is_8bit(format: HostImageFormat) -> bool {
    format_code(format) <= 1
}

/// Copies frames into host images (and the host's texels out of them).
pub struct HostImageWriter {
    device: Device,
    pack: Arc<Kernel>,
}

impl HostImageWriter {
    /// Builds the packing kernel.
    pub fn new(device: &Device) -> Result<Self> {
        Ok(Self { device: device.clone(), pack: device.kernel(&kernels::HOST_IMAGE_PACK, &KernelDecl::uniform(&[]))? })
    }

    /// Copies the host's colour and depth out of `targets`' images when
    /// compositing (waiting on the host's semaphores); nothing otherwise.
    pub fn read(&self, targets: &HostTargets) -> Result<HostPixels> {
        if !targets.composite {
            return Ok(HostPixels::default());
        }
        let make = |image: &Option<HostImage>, name: &str| -> Result<Option<Buffer>> {
            match image {
                Some(i) => Ok(Some(self.device.create_buffer(name, i.packed_bytes()?, MemoryKind::Storage)?)),
                None => Ok(None),
            }
        };
        let colour = make(&targets.colour, "host colour texels")?;
        let depth = make(&targets.depth, "host depth values")?;
        self.device.run_synced(&targets.sync.waits_only(), |rec| -> Result<()> {
            rec.begin_stage("host images read");
            for (image, buffer) in [(&targets.colour, &colour), (&targets.depth, &depth)] {
                if let (Some(image), Some(buffer)) = (image, buffer) {
                    rec.copy_host_image_to_buffer(image, image.layout_before, buffer)?;
                }
            }
            rec.end_stage();
            Ok(())
        })?;
        Ok(HostPixels { colour, depth, waited: true })
    }

    /// After a failure once [`HostImageWriter::read`] has run (the host's
    /// waits consumed): leaves the images unwritten in their `layout_after`
    /// and signals the host's semaphores, so a host waiting on them does not
    /// hang on a call that returned an error.
    pub fn abandon(&self, targets: &HostTargets, host: &HostPixels) -> Result<()> {
        if !host.waited {
            return Ok(());
        }
        self.device.run_synced(&targets.sync.signals_only(), |rec| -> Result<()> {
            for image in [&targets.colour, &targets.depth].into_iter().flatten() {
                rec.transition_host_image(image, vk::ImageLayout::TRANSFER_SRC_OPTIMAL, image.layout_after)?;
            }
            Ok(())
        })?;
        Ok(())
    }

    /// Packs `frame` into `targets`' images (over `host`'s texels when
    /// compositing) and signals the host's semaphores; waits on them too when
    /// [`HostImageWriter::read`] did not.
    pub fn write(&self, targets: &HostTargets, frame: &FrameOutputs<'_>, host: &HostPixels) -> Result<Timings> {
        let (colour_format, depth_format) = targets.validate(&self.device, frame.width, frame.height)?;
        if depth_format.is_some() && frame.median_depth.is_none() {
            return Err(Error::Internal("a depth image to write, but the frame has no median depth".into()));
        }
        let pixels = u64::from(frame.width) * u64::from(frame.height);
        let sync = if host.waited { targets.sync.signals_only() } else { targets.sync.clone() };
        let jobs = [(&targets.colour, colour_format, &host.colour), (&targets.depth, depth_format, &host.depth)];
        let mut outputs = Vec::new();
        for (image, format, texels) in jobs {
            let (Some(image), Some(format)) = (image, format) else { continue };
            if targets.composite && texels.is_none() {
                return Err(Error::Internal("a composited write without the host's texels".into()));
            }
            let buffer = self.device.create_buffer("host image texels", image.packed_bytes()?, MemoryKind::Storage)?;
            let uniform = self.device.create_buffer(
                "host pack uniform",
                std::mem::size_of::<PackUniform>() as u64,
                MemoryKind::Storage,
            )?;
            outputs.push((image, format, texels.as_ref(), buffer, uniform));
        }
        if frame.channels.len() != targets.buffers.len() {
            return Err(Error::Internal("the frame's channels do not match the host buffers".into()));
        }
        let mut copies = Vec::new();
        for ((channel, host_buffer), source) in targets.buffers.iter().zip(&frame.channels) {
            let Some(source) = source else {
                return Err(Error::invalid(
                    format!("host buffer for {channel:?}"),
                    "asks for a value the frame does not have (shading outputs exist only for relit frames)",
                ));
            };
            copies.push((*source, host_buffer, pixels * channel.components() as u64 * 4));
        }
        let timings = self.device.run_synced(&sync, |rec| -> Result<()> {
            rec.begin_stage("host images write");
            for (source, host_buffer, bytes) in &copies {
                rec.copy_to_host_buffer(source, host_buffer, *bytes)?;
            }
            for (image, format, texels, buffer, uniform) in &outputs {
                let mut flags = if targets.composite { COMPOSITE } else { 0 };
                let mut display = [1.0, 0.0, 0.0, 0.0];
                if let (Some((ev, tone)), true) = (frame.display, is_8bit(*format)) {
                    flags |= DISPLAY;
                    display = [2f32.powf(ev), tone.code() as f32, 0.0, 0.0];
                }
                let u = PackUniform {
                    size: [frame.width, frame.height, format_code(*format), flags],
                    display,
                    depth: targets.depth_convention.packed(),
                    colour: rec.addr(frame.colour)?,
                    alpha: rec.addr(frame.alpha)?,
                    median_depth: rec.addr_or_null(frame.median_depth)?,
                    host: rec.addr_or_null(*texels)?,
                    out_texels: rec.addr(buffer)?,
                };
                rec.update(uniform, 0, &u)?;
                rec.dispatch(&self.pack, Grid::Items(pixels), &[Binding::from(uniform)], &())?;
                // A composited image was left in the read's layout.
                let from = if host.waited { vk::ImageLayout::TRANSFER_SRC_OPTIMAL } else { image.layout_before };
                rec.copy_buffer_to_host_image(buffer, image, from)?;
            }
            rec.end_stage();
            Ok(())
        })?;
        Ok(timings)
    }
}

/// A frame's values on the host, for [`pack_cpu`].
#[derive(Clone, Copy, Debug)]
pub struct FrameValues<'a> {
    /// 3 per pixel, as [`FrameOutputs::colour`].
    pub colour: &'a [f32],
    /// Coverage.
    pub alpha: &'a [f32],
    /// Median depth (camera z, 0: none); may be empty for colour formats.
    pub median_depth: &'a [f32],
    /// As [`FrameOutputs::display`].
    pub display: Option<(f32, ToneMap)>,
}

/// The texels of `bytes` (tightly packed, `format`) as RGBA values (8-bit
/// ones in [0, 1], BGRA reordered to RGBA; a depth in the first).
pub fn decode_texels(format: HostImageFormat, bytes: &[u8]) -> Vec<[f64; 4]> {
    use HostImageFormat as F;
    let n = bytes.len() / format.texel_bytes() as usize;
    (0..n)
        .map(|i| {
            let t = &bytes[i * format.texel_bytes() as usize..(i + 1) * format.texel_bytes() as usize];
            let f32_at = |k: usize| f64::from(f32::from_le_bytes([t[4 * k], t[4 * k + 1], t[4 * k + 2], t[4 * k + 3]]));
            let unorm = |k: usize| f64::from(t[k]) / 255.0;
            match format {
                F::Rgba8Unorm | F::Rgba8Srgb => [unorm(0), unorm(1), unorm(2), unorm(3)],
                F::Bgra8Unorm | F::Bgra8Srgb => [unorm(2), unorm(1), unorm(0), unorm(3)],
                F::Rgba16Float => {
                    let h = |k: usize| f64::from(half::f16::from_le_bytes([t[2 * k], t[2 * k + 1]]).to_f32());
                    [h(0), h(1), h(2), h(3)]
                }
                F::Rgba32Float => [f32_at(0), f32_at(1), f32_at(2), f32_at(3)],
                F::R32Float | F::D32Float => [f32_at(0), 0.0, 0.0, 0.0],
            }
        })
        .collect()
}

/// CPU twin of `host_image_pack.comp` in f64: each pixel's values as
/// [`decode_texels`] gives them, before quantization to the format. `host`
/// is the image's texels before the frame when compositing.
pub fn pack_cpu(
    format: HostImageFormat,
    frame: &FrameValues<'_>,
    depth: HostDepth,
    host: Option<&[u8]>,
) -> Vec<[f64; 4]> {
    use crate::shade::cpu::{srgb_decode, srgb_encode, tone_map};
    let host = host.map(|b| decode_texels(format, b));
    let (n, f) = match depth {
        HostDepth::CameraZ => (0.0, 0.0),
        HostDepth::Vulkan { near, far } | HostDepth::ReversedZ { near, far } => (f64::from(near), f64::from(far)),
    };
    let stored = |z: f64| match depth {
        HostDepth::CameraZ => z,
        HostDepth::Vulkan { .. } => (f * (z - n) / (z * (f - n))).clamp(0.0, 1.0),
        HostDepth::ReversedZ { .. } if f.is_infinite() => (n / z).clamp(0.0, 1.0),
        HostDepth::ReversedZ { .. } => (n * (f - z) / (z * (f - n))).clamp(0.0, 1.0),
    };
    let empty = if matches!(depth, HostDepth::Vulkan { .. }) { 1.0 } else { 0.0 };
    let pixels = frame.alpha.len();
    (0..pixels)
        .map(|p| {
            let h = host.as_ref().map(|h| h[p]);
            if format.is_single_channel() {
                let z = f64::from(frame.median_depth[p]);
                let splat = if z > 0.0 { stored(z) } else { empty };
                let value = match h {
                    Some(h) if !(z > 0.0 && z < depth.camera_z(h[0])) => h[0],
                    // A nearer splat never stores a value behind the host's.
                    Some(h) if depth.camera_z(h[0]).is_finite() => match depth {
                        HostDepth::ReversedZ { .. } => splat.max(h[0]),
                        HostDepth::CameraZ | HostDepth::Vulkan { .. } => splat.min(h[0]),
                    },
                    _ => splat,
                };
                return [value, 0.0, 0.0, 0.0];
            }
            let c = [0, 1, 2].map(|k| f64::from(frame.colour[3 * p + k]));
            let a = f64::from(frame.alpha[p]).clamp(0.0, 1.0);
            let display = |v: f64, (ev, op): (f32, ToneMap)| {
                srgb_encode(tone_map((v * 2f64.powf(f64::from(ev))).max(0.0), op).max(0.0))
            };
            match (frame.display.filter(|_| is_8bit(format)), h) {
                (Some(d), Some(h)) => {
                    let mix = |k: usize| {
                        let straight = if a > 0.0 { c[k] / a } else { 0.0 };
                        srgb_encode(a * srgb_decode(display(straight, d)) + (1.0 - a) * srgb_decode(h[k]))
                    };
                    [mix(0), mix(1), mix(2), a + (1.0 - a) * h[3]]
                }
                (Some(d), None) => [display(c[0], d), display(c[1], d), display(c[2], d), a],
                (None, h) => {
                    let h = h.unwrap_or([0.0; 4]);
                    [c[0] + (1.0 - a) * h[0], c[1] + (1.0 - a) * h[1], c[2] + (1.0 - a) * h[2], a + (1.0 - a) * h[3]]
                }
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::{check_layout, kernels};

    #[test]
    fn pack_uniform_matches_the_glsl_block() {
        assert_eq!(check_layout::<PackUniform>(&[&kernels::HOST_IMAGE_PACK]), Ok(1));
    }
}
