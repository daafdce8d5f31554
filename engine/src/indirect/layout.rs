//! How the network's work and data are laid out on the GPU: the push-constant
//! blocks the kernels read (checked against the GLSL), level sizes, and the
//! channel and pixel blocking of each kernel variant.

use bytemuck::{Pod, Zeroable};

use super::*;
use crate::gpu::DeviceAddress;

/// Sizes (width, height) of the five resolutions for an input size.
pub fn level_sizes(width: usize, height: usize) -> [(usize, usize); 5] {
    let mut s = [(width, height); 5];
    for l in 1..5 {
        s[l] = (s[l - 1].0.div_ceil(2), s[l - 1].1.div_ceil(2));
    }
    s
}

/// The level whose feature maps layer `i` reads (the order of [`layers`]:
/// inc, down1..down4, up1..up4, outc; an up layer reads the resized deeper
/// level and the skip at the skip's level).
pub(super) fn input_level(i: usize) -> usize {
    match i {
        0 | 9 => 0,
        1..=4 => i - 1,
        _ => 8 - i,
    }
}

/// Push constants of `unet_conv.comp` (keep in sync).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub(crate) struct ConvPush {
    pub(super) a: DeviceAddress,
    pub(super) b: DeviceAddress,
    pub(super) o: DeviceAddress,
    pub(super) partial: DeviceAddress,
    pub(super) ca: u32,
    pub(super) cb: u32,
    pub(super) oc: u32,
    pub(super) ic0: u32,
    pub(super) ic1: u32,
    pub(super) flags: u32,
    pub(super) in_size: [u32; 2],
    pub(super) out_size: [u32; 2],
}
crate::gpu::gpu_layout!(ConvPush, "ConvPush", [a, b, o, partial, ca, cb, oc, ic0, ic1, flags, in_size, out_size]);

/// Floats in one weight pass's uniform buffer (64 KiB, the least
/// `maxUniformBufferRange` Vulkan guarantees; keep in sync with `wts[4096]`
/// vec4s in `unet_conv.comp`).
pub(crate) const CONV_UBO_FLOATS: usize = 16384;

/// Push constants of `unet_upsample.comp` (keep in sync).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub(crate) struct UpsamplePush {
    pub(super) src: DeviceAddress,
    pub(super) dst: DeviceAddress,
    pub(super) in_size: [u32; 2],
    pub(super) out_size: [u32; 2],
    pub(super) channels: u32,
    pub(super) align_corners: u32,
}
crate::gpu::gpu_layout!(UpsamplePush, "UpsamplePush", [src, dst, in_size, out_size, channels, align_corners]);

/// Output channels per invocation of a layer (the `OCB` specialization
/// constant of `unet_conv.comp`), for inputs read through texel-buffer views
/// (`texel`: 8, or 4 below 8 channels) or by device address (16, or 8 below 16).
pub(crate) fn channel_block(out_channels: usize, texel: bool) -> usize {
    let wide = if texel { 8 } else { 16 };
    if out_channels >= wide {
        wide
    } else {
        wide / 2
    }
}

/// Output pixels per invocation along x (the `PX` specialization constant of
/// `unet_conv.comp`, at most 8). With [`channel_block`] an invocation keeps
/// PX·OCB fp32 accumulators; on lavapipe every one is a SIMD register, and
/// past about 48 they spill. The choice is measured; docs/bench/unet.md
/// ("Tuning") has the figures behind it.
pub(crate) fn pixel_block(out_channels: usize, texel: bool) -> usize {
    match (channel_block(out_channels, texel), texel) {
        (8, true) => 5,
        (4, true) => 8,
        (ob, _) => 32 / ob,
    }
}

/// Output pixels per invocation along x when the inputs are read four pixels
/// per texel (`VEC4` in `unet_conv.comp`): 16 with 8 output channels per
/// invocation, 8 with 4 (PX·STRIDE a multiple of 4, so a row segment starts
/// one pixel before a texel boundary). 128 accumulators compile quickly once
/// every loop over them is unrolled (figures: docs/bench/unet.md, "Tuning").
pub(crate) fn vec4_pixel_block(out_channels: usize) -> usize {
    if channel_block(out_channels, true) == 8 {
        16
    } else {
        8
    }
}

/// Whether the resize to an `out_width`-wide level writes four pixels per
/// invocation (`FOUR` in `unet_upsample.comp`): each row's pixels then start
/// on a 16-byte boundary (arena tensors are 256-byte aligned).
pub(crate) fn resize_four(out_width: usize) -> bool {
    out_width % 4 == 0
}

/// Whether the resize from level size `from` to `to` (width, height) runs the
/// exact-2× kernel (`EXACT2` in `unet_upsample.comp`): `to` is exactly twice
/// `from` with align_corners false, so every output pixel is ¼ / ¾ of two
/// source pixels per axis, and the source rows start on four-pixel texels.
pub(crate) fn resize_exact2(from: (usize, usize), to: (usize, usize), align_corners: bool) -> bool {
    !align_corners && to == (2 * from.0, 2 * from.1) && vec4_fits(from.0)
}

/// Whether a layer whose input rows are `in_width` pixels wide can read its
/// inputs four pixels per texel: every row must start on a texel boundary.
pub(crate) fn vec4_fits(in_width: usize) -> bool {
    in_width % 4 == 0
}

/// Input channels per pass of a layer. Texel-input kernels read the weights
/// through one RGBA32F view, so a layer is one pass; device-address kernels
/// read them from a uniform buffer and take as many channels per pass as fit
/// one with every output block.
pub(crate) fn pass_channels(in_channels: usize, out_channels: usize, texel: bool) -> usize {
    if texel {
        return in_channels.max(1);
    }
    let ob = channel_block(out_channels, texel);
    (CONV_UBO_FLOATS / (out_channels.div_ceil(ob) * ob * 9)).max(1)
}

/// Floats of one layer's packed weights on the texel path (one pass: every
/// input channel, output channels padded to the block).
pub(crate) fn texel_weight_floats(in_channels: usize, out_channels: usize) -> usize {
    let ob = channel_block(out_channels, true);
    out_channels.div_ceil(ob) * ob * in_channels * 9
}

/// Packs OIHW weights per pass of [`pass_channels`] input channels, each
/// `[oc/B][ic − ic0][9][B]` (B = [`channel_block`]): for device-address
/// kernels in a zero-padded buffer of [`CONV_UBO_FLOATS`] per pass, for
/// texel-input kernels in one buffer of [`texel_weight_floats`]; and the bias
/// padded to a multiple of B.
pub(crate) fn pack_conv(l: &ConvWeights, texel: bool) -> (Vec<Vec<f32>>, Vec<f32>) {
    let ob = channel_block(l.out_channels, texel);
    let chunk = pass_channels(l.in_channels, l.out_channels, texel);
    let passes = l.in_channels.div_ceil(chunk);
    let floats = if texel { texel_weight_floats(l.in_channels, l.out_channels) } else { CONV_UBO_FLOATS };
    let mut w = vec![vec![0.0f32; floats]; passes];
    for o in 0..l.out_channels {
        for i in 0..l.in_channels {
            let (k, il) = (i / chunk, i % chunk);
            for t in 0..9 {
                w[k][(((o / ob) * chunk + il) * 9 + t) * ob + o % ob] = l.weight[(o * l.in_channels + i) * 9 + t];
            }
        }
    }
    let mut b = vec![0.0f32; l.out_channels.div_ceil(ob) * ob];
    b[..l.out_channels].copy_from_slice(&l.bias);
    (w, b)
}

/// Push constants of `unet_pack.comp` (keep in sync).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub(crate) struct PackPush {
    pub(super) normal: DeviceAddress,
    pub(super) albedo: DeviceAddress,
    pub(super) roughness: DeviceAddress,
    pub(super) metallic: DeviceAddress,
    pub(super) alpha: DeviceAddress,
    pub(super) sun: DeviceAddress,
    pub(super) sky: DeviceAddress,
    pub(super) o: DeviceAddress,
    pub(super) pixels: u32,
    pub(super) min_alpha: f32,
}
crate::gpu::gpu_layout!(
    PackPush,
    "PackPush",
    [normal, albedo, roughness, metallic, alpha, sun, sky, o, pixels, min_alpha]
);

#[cfg(test)]
mod layout_tests {
    use super::{ConvPush, PackPush, UpsamplePush};
    use crate::gpu::{check_layout, kernels};

    /// The push-constant structs match the GLSL blocks of every kernel that declares them.
    #[test]
    fn push_layouts_match_glsl() {
        let conv = check_layout::<ConvPush>(kernels::ALL);
        assert!(conv.as_ref().is_ok_and(|n| *n == 8), "{conv:?}");
        let upsample = check_layout::<UpsamplePush>(kernels::ALL);
        assert!(upsample.as_ref().is_ok_and(|n| *n == 4), "{upsample:?}");
        assert_eq!(check_layout::<PackPush>(&[&kernels::UNET_PACK]), Ok(1));
    }
}
