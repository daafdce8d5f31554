//! Winograd F(2×2, 3×3) for the stride-1 convolutions: the transforms shared
//! by the weight packing and the CPU twin.
//!
//! A 2 × 2 output tile of a 3×3 convolution is Y = Aᵀ·[Σ_ci U ⊙ V]·A with
//! U = G·g·Gᵀ (the 3 × 3 kernel g made 4 × 4, once per layer, on the host) and
//! V = Bᵀ·d·B (the tile's 4 × 4 input patch d, in the kernel): 16 multiplies
//! per input channel and output channel instead of 36. The kernel
//! (`unet_winograd_texel.comp`) keeps 16 accumulators per output channel and
//! tile where direct convolution keeps 4 per 2 × 2 pixels, so it trades
//! multiplies for accumulator traffic and transform additions; which path is
//! faster depends on the device (measured by `srug bench unet --inputs
//! vec4,winograd`). The
//! transforms' entries are 0, ±1 and ±½, so fp32 rounding adds little error
//! (the tests hold both paths to the same tolerance).

use super::ConvWeights;

/// 2 × 2 output tiles per invocation of the Winograd kernel (`TT`), side by
/// side along x: each weight fetch serves all of them, and a row of 8 tiles
/// reads its input patch four pixels per fetch. Measured on lavapipe at
/// 704×192 fp32 (up4 layer, 64 → 32 channels; direct convolution 130 ms):
/// 8 tiles 118–123 ms, 6 tiles 134 ms, 4 tiles 187 ms, 16 tiles 140 ms (and
/// llvmpipe then compiles the kernel for over five minutes). Earlier, one tile of
/// 4 channels per invocation took 276 ms.
pub const WINOGRAD_TILES: usize = 8;

/// Input channels per step of the Winograd kernel (`CH`): fetched and
/// transformed first, then multiplied, so each accumulator is loaded and
/// stored once per step. Measured with 8 tiles (same run as above): 1 channel
/// 138 ms, 2 channels 118 ms, 4 channels 122 ms (and three minutes to compile).
pub const WINOGRAD_CHUNK: usize = 2;

/// U = G·g·Gᵀ of one 3 × 3 kernel `g` (row-major), row-major 4 × 4, with
/// G = [1 0 0; ½ ½ ½; ½ −½ ½; 0 0 1].
pub fn weight_transform(g: &[f64; 9]) -> [f64; 16] {
    const G: [[f64; 3]; 4] = [[1.0, 0.0, 0.0], [0.5, 0.5, 0.5], [0.5, -0.5, 0.5], [0.0, 0.0, 1.0]];
    let mut gg = [[0.0; 3]; 4];
    for (i, row) in gg.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = (0..3).map(|k| G[i][k] * g[3 * k + j]).sum();
        }
    }
    let mut u = [0.0; 16];
    for i in 0..4 {
        for j in 0..4 {
            u[4 * i + j] = (0..3).map(|k| gg[i][k] * G[j][k]).sum();
        }
    }
    u
}

/// V = Bᵀ·d·B of one 4 × 4 patch (row-major), with
/// Bᵀ = [1 0 −1 0; 0 1 1 0; 0 −1 1 0; 0 1 0 −1].
pub fn input_transform(d: &[f64; 16]) -> [f64; 16] {
    let mut t = [0.0; 16];
    for j in 0..4 {
        t[j] = d[j] - d[8 + j];
        t[4 + j] = d[4 + j] + d[8 + j];
        t[8 + j] = d[8 + j] - d[4 + j];
        t[12 + j] = d[4 + j] - d[12 + j];
    }
    let mut v = [0.0; 16];
    for i in 0..4 {
        v[4 * i] = t[4 * i] - t[4 * i + 2];
        v[4 * i + 1] = t[4 * i + 1] + t[4 * i + 2];
        v[4 * i + 2] = t[4 * i + 2] - t[4 * i + 1];
        v[4 * i + 3] = t[4 * i + 1] - t[4 * i + 3];
    }
    v
}

/// Y = Aᵀ·m·A of one 4 × 4 product sum (row-major) as a 2 × 2 tile
/// (row-major), with Aᵀ = [1 1 1 0; 0 1 −1 −1].
pub fn output_transform(m: &[f64; 16]) -> [f64; 4] {
    let mut t = [0.0; 8];
    for j in 0..4 {
        t[j] = m[j] + m[4 + j] + m[8 + j];
        t[4 + j] = m[4 + j] - m[8 + j] - m[12 + j];
    }
    let mut y = [0.0; 4];
    for i in 0..2 {
        y[2 * i] = t[4 * i] + t[4 * i + 1] + t[4 * i + 2];
        y[2 * i + 1] = t[4 * i + 1] - t[4 * i + 2] - t[4 * i + 3];
    }
    y
}

/// Texels (RGBA32F) of a layer's packed Winograd weights: output channels
/// padded to the kernel's channel block (`super::channel_block`).
pub fn winograd_weight_texels(in_channels: usize, out_channels: usize) -> usize {
    let block = super::channel_block(out_channels, true);
    out_channels.div_ceil(block) * block / 4 * in_channels * 16
}

/// Packs a layer's transformed weights for `unet_winograd_texel.comp`:
/// `[oc/4][ic][16][4]` floats (one RGBA32F texel per block of 4 output
/// channels, input channel and k; keep in sync), output channels past the
/// layer's, up to a whole kernel channel block, zero.
pub fn pack_winograd(l: &ConvWeights) -> Vec<f32> {
    let n = 4;
    let mut w = vec![0.0f32; winograd_weight_texels(l.in_channels, l.out_channels) * 4];
    for o in 0..l.out_channels {
        for i in 0..l.in_channels {
            let at = (o * l.in_channels + i) * 9;
            let g: [f64; 9] = std::array::from_fn(|t| f64::from(l.weight[at + t]));
            let u = weight_transform(&g);
            for (k, v) in u.iter().enumerate() {
                w[(((o / n) * l.in_channels + i) * 16 + k) * n + o % n] = *v as f32;
            }
        }
    }
    w
}
