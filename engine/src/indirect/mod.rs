//! Indirect light: the paper's U-Net, predicting L_ind from the G-buffers
//! (normal, albedo, roughness, metallic, L_sun, L_sky), run in GLSL.
//!
//! The network (ten 3×3 convolutions, padding 1): `inc` (in → w0), `down1..4`
//! (stride 2: w0 → w1 → w2 → w3 → w4), `up1..4` (bilinear resize to the
//! skip's exact size, concatenation with the skip, conv: w4+w3 → w3,
//! w3+w2 → w2, w2+w1 → w1, w1+w0 → w0), `outc` (w0 → out, no activation).
//! The activation follows every other layer. Weights come from safetensors
//! files with PyTorch state_dict names (`inc.weight`, `inc.bias`, ...) in OIHW
//! layout, the architecture in the file's metadata ([`UNetConfig`]);
//! `tools/indirect_unet.py` defines the same module in PyTorch and exports it.
//!
//! Kernels: `unet_conv.comp` (fused bias and activation, reading the two
//! halves of a concatenation from separate tensors, so skips are never
//! copied) and `unet_upsample.comp`. Both read their inputs through
//! texel-buffer views of the arena where the device has them and a tensor
//! fits `maxTexelBufferElements` (`*_texel.comp`: on lavapipe a `texelFetch`
//! is one vector gather, a device-address load a loop over the lanes), else
//! by device address; the two paths use different channel blocks, so the
//! weights are packed once per path. Tensors are CHW float32 (batch 1); every
//! activation of a pass lives in one arena buffer reused across frames while
//! the size allows. Any input size works (stride-2 outputs are ceil(n/2)).
//! Where texel views exist the stride-1 layers run by Winograd F(4×4, 3×3)
//! by default, or F(2×2, 3×3) on request ([`winograd`], [`UNet::set_winograd`]).
//! [`cpu`] is the f64-accumulating twin.

pub mod cpu;
mod forward;
mod layout;
mod weights;
pub mod winograd;

pub use forward::*;
pub use layout::*;
pub use weights::*;
pub use winograd::{ConvPath, WinogradTile};

use crate::gpu::DeviceInfo;

/// Lanes of a subgroup that fetch a weight block's texels side by side and
/// broadcast them (`WEIGHT_LANES` in `unet_conv_body.glsl`'s texel kernels
/// and `unet_winograd_body.glsl`), or 0 for every lane fetching every texel.
/// Every lane of a workgroup reads the same weights (its output block); on
/// lavapipe from Mesa 25, whose texel fetch is a call around which the kernel
/// saves and restores its vector registers, one call then serves a
/// subgroup's worth of texels (docs/bench/unet.md). Needs subgroup broadcast
/// and whole subgroups in the kernels' 64 invocations; elsewhere (Mesa 22.3
/// fetches inline, GPUs not measured) 0.
pub(crate) fn weight_lanes(info: &DeviceInfo) -> u32 {
    if info.is_lavapipe_from(25) && weight_sharing_supported(info) {
        info.subgroup_size
    } else {
        0
    }
}

/// Whether the texel conv and Winograd kernels can share weight fetches on
/// `info`'s device: subgroup broadcast, and subgroups that fill their 64 invocations.
pub(crate) fn weight_sharing_supported(info: &DeviceInfo) -> bool {
    let size = info.subgroup_size;
    info.subgroup_ballot && size > 1 && 64 % size == 0
}
