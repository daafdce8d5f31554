//! Winograd F(4×4, 3×3) for the stride-1 convolutions: the transforms shared
//! by the weight packing and the CPU twin.
//!
//! A 4 × 4 output tile of a 3×3 convolution is Y = Aᵀ·[Σ_ci U ⊙ V]·A with
//! U = G·g·Gᵀ (the 3 × 3 kernel g made 6 × 6, once per layer, on the host) and
//! V = Bᵀ·d·B (the tile's 6 × 6 input patch d, in the kernel): 36 multiplies
//! per input and output channel instead of 144 (F(2×2, 3×3): 16 instead of
//! 36). The kernel (`unet_winograd_texel.comp`) keeps 36 accumulators per
//! output channel and tile, so it trades multiplies for accumulator traffic
//! and transform additions; on lavapipe, where every fetch is expensive, the
//! larger tile also needs fewer input and weight fetches per output pixel.
//! The transforms' entries (Lavin and Gray's points 0, ±1, ±2) reach 8 and
//! 1/24, so fp32 rounding adds more error than F(2×2, 3×3) — measured up to
//! 1.1e-5 against 2.5e-6 in `vec4_inputs_match_twin`, within the tests' 1e-4.

use super::ConvWeights;

/// Output tiles per invocation of the Winograd kernel (`TT`), side by side
/// along x: each weight fetch serves all of them, and their row reads its
/// input patch four pixels per fetch. Measured on lavapipe at 704×192
/// (`srug bench unet --inputs winograd`, whole network fp32; direct
/// convolution about 343 ms): 4 tiles × 2 channels per step 218 ms, 6 × 2
/// 223 ms (the 88-pixel level then runs 3.7 blocks a row: up1 14.6 against
/// 10.7 ms), 4 × 1 242 ms. llvmpipe's compile time grows with TT·CH: with a
/// cold shader cache about 45 s per variant set at 4 × 1 and over 2 minutes at 6 × 2.
/// With 2 × 2 tiles (F(2×2, 3×3), at 85afd8b and before) the best was 8 tiles × 2
/// channels, 268 ms.
pub const WINOGRAD_TILES: usize = 4;

/// Input channels per step of the Winograd kernel (`CH`): fetched and
/// transformed first, then multiplied, so each accumulator is loaded and
/// stored once per step (see [`WINOGRAD_TILES`] for the sweep).
pub const WINOGRAD_CHUNK: usize = 2;

/// The output tile's edge (`WT` in `unet_winograd_body.glsl`; keep in sync).
/// A multiple of 4, so every tile row starts on a four-pixel texel.
pub const WINOGRAD_TILE: usize = 4;
const _: () = assert!(WINOGRAD_TILE % 4 == 0);

/// The transformed tile's edge: an output tile's input patch is `E` × `E`.
pub const E: usize = WINOGRAD_TILE + 2;

/// G (E × 3): U = G·g·Gᵀ.
const G: [[f64; 3]; E] = [
    [1.0 / 4.0, 0.0, 0.0],
    [-1.0 / 6.0, -1.0 / 6.0, -1.0 / 6.0],
    [-1.0 / 6.0, 1.0 / 6.0, -1.0 / 6.0],
    [1.0 / 24.0, 1.0 / 12.0, 1.0 / 6.0],
    [1.0 / 24.0, -1.0 / 12.0, 1.0 / 6.0],
    [0.0, 0.0, 1.0],
];

/// Bᵀ (E × E): V = Bᵀ·d·B.
const BT: [[f64; E]; E] = [
    [4.0, 0.0, -5.0, 0.0, 1.0, 0.0],
    [0.0, -4.0, -4.0, 1.0, 1.0, 0.0],
    [0.0, 4.0, -4.0, -1.0, 1.0, 0.0],
    [0.0, -2.0, -1.0, 2.0, 1.0, 0.0],
    [0.0, 2.0, -1.0, -2.0, 1.0, 0.0],
    [0.0, 4.0, 0.0, -5.0, 0.0, 1.0],
];

/// Aᵀ (WINOGRAD_TILE × E): Y = Aᵀ·M·A.
const AT: [[f64; E]; WINOGRAD_TILE] = [
    [1.0, 1.0, 1.0, 1.0, 1.0, 0.0],
    [0.0, 1.0, -1.0, 2.0, -2.0, 0.0],
    [0.0, 1.0, 1.0, 4.0, 4.0, 0.0],
    [0.0, 1.0, -1.0, 8.0, -8.0, 1.0],
];

/// L·X·Rᵀ for X (`n` × `n`, row-major) and L, R (`r` × `n`): row-major `r` × `r`.
fn sandwich<const N: usize>(l: &[[f64; N]], x: &[f64], r: &[[f64; N]]) -> Vec<f64> {
    let rows = l.len();
    let lx: Vec<f64> = (0..rows * N).map(|at| (0..N).map(|k| l[at / N][k] * x[k * N + at % N]).sum()).collect();
    (0..rows * r.len()).map(|at| (0..N).map(|k| lx[(at / r.len()) * N + k] * r[at % r.len()][k]).sum()).collect()
}

/// U = G·g·Gᵀ of one 3 × 3 kernel `g` (row-major): row-major E × E.
pub fn weight_transform(g: &[f64; 9]) -> Vec<f64> {
    sandwich(&G, g, &G)
}

/// V = Bᵀ·d·B of one E × E input patch (row-major).
pub fn input_transform(d: &[f64]) -> Vec<f64> {
    sandwich(&BT, d, &BT)
}

/// Y = Aᵀ·m·A of one E × E product sum (row-major): the output tile, row-major.
pub fn output_transform(m: &[f64]) -> Vec<f64> {
    sandwich(&AT, m, &AT)
}

/// Texels (RGBA32F) of a layer's packed Winograd weights: output channels
/// padded to the kernel's channel block (`super::channel_block`).
pub fn winograd_weight_texels(in_channels: usize, out_channels: usize) -> usize {
    let block = super::channel_block(out_channels, true);
    out_channels.div_ceil(block) * block / 4 * in_channels * E * E
}

/// Packs a layer's transformed weights for `unet_winograd_texel.comp`:
/// `[oc/4][ic][E·E][4]` floats (one RGBA32F texel per block of 4 output
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
                w[(((o / n) * l.in_channels + i) * E * E + k) * n + o % n] = *v as f32;
            }
        }
    }
    w
}
