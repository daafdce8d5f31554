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
