//! Winograd F(m×m, 3×3) for the stride-1 convolutions: the transforms shared
//! by the weight packing and the CPU twin, for the two tiles the kernel offers.
//!
//! An m × m output tile of a 3×3 convolution is Y = Aᵀ·[Σ_ci U ⊙ V]·A with
//! U = G·g·Gᵀ (the 3 × 3 kernel g made e × e, e = m + 2, once per layer, on
//! the host) and V = Bᵀ·d·B (the tile's e × e input patch d, in the kernel):
//! e² multiplies per input and output channel instead of 9·m².
//! - F(2×2, 3×3): 16 instead of 36 (2.25× fewer); its transforms' entries are
//!   0, ±½ and ±1, so fp32 rounding stays close to direct convolution's
//!   (2.5e-6 in `vec4_inputs_match_twin`).
//! - F(4×4, 3×3) (Lavin and Gray's points 0, ±1, ±2): 36 instead of 144 (4×
//!   fewer), the default. Entries reach 8 and 1/24, so fp32 rounding adds more
//!   error (up to 1.1e-5 in the same test, within its 1e-4).
//!
//! The kernel (`unet_winograd_body.glsl`) keeps e² accumulators per output
//! channel and tile, so it trades multiplies for accumulator traffic and
//! transform additions; on lavapipe, where every fetch is expensive, the
//! larger tile also needs fewer input and weight fetches per output pixel.
//! The measured comparison with direct convolution is in docs/bench/unet.md.

use super::ConvWeights;
use crate::gpu::ash::vk;

/// Which Winograd transform the stride-1 convolutions use.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum WinogradTile {
    /// F(2×2, 3×3): 2 × 2 output tiles from 4 × 4 patches; the smaller
    /// rounding error.
    F2x2,
    /// F(4×4, 3×3): 4 × 4 output tiles from 6 × 6 patches; fewer multiplies
    /// and fetches, the faster on lavapipe.
    #[default]
    F4x4,
}

/// One tile's transform matrices, row-major.
struct Transforms {
    /// G (e × 3): U = G·g·Gᵀ.
    g: &'static [f64],
    /// Bᵀ (e × e): V = Bᵀ·d·B.
    bt: &'static [f64],
    /// Aᵀ (m × e): Y = Aᵀ·M·A.
    at: &'static [f64],
}

#[rustfmt::skip]
const F2X2: Transforms = Transforms {
    g: &[
        1.0, 0.0, 0.0,
        0.5, 0.5, 0.5,
        0.5, -0.5, 0.5,
        0.0, 0.0, 1.0,
    ],
    bt: &[
        1.0, 0.0, -1.0, 0.0,
        0.0, 1.0, 1.0, 0.0,
        0.0, -1.0, 1.0, 0.0,
        0.0, 1.0, 0.0, -1.0,
    ],
    at: &[
        1.0, 1.0, 1.0, 0.0,
        0.0, 1.0, -1.0, -1.0,
    ],
};

#[rustfmt::skip]
const F4X4: Transforms = Transforms {
    g: &[
        1.0 / 4.0, 0.0, 0.0,
        -1.0 / 6.0, -1.0 / 6.0, -1.0 / 6.0,
        -1.0 / 6.0, 1.0 / 6.0, -1.0 / 6.0,
        1.0 / 24.0, 1.0 / 12.0, 1.0 / 6.0,
        1.0 / 24.0, -1.0 / 12.0, 1.0 / 6.0,
        0.0, 0.0, 1.0,
    ],
    bt: &[
        4.0, 0.0, -5.0, 0.0, 1.0, 0.0,
        0.0, -4.0, -4.0, 1.0, 1.0, 0.0,
        0.0, 4.0, -4.0, -1.0, 1.0, 0.0,
        0.0, -2.0, -1.0, 2.0, 1.0, 0.0,
        0.0, 2.0, -1.0, -2.0, 1.0, 0.0,
        0.0, 4.0, 0.0, -5.0, 0.0, 1.0,
    ],
    at: &[
        1.0, 1.0, 1.0, 1.0, 1.0, 0.0,
        0.0, 1.0, -1.0, 2.0, -2.0, 0.0,
        0.0, 1.0, 1.0, 4.0, 4.0, 0.0,
        0.0, 1.0, -1.0, 8.0, -8.0, 1.0,
    ],
};

impl WinogradTile {
    /// The output tile's edge m (`WT` in `unet_winograd_body.glsl`; keep in sync).
    pub const fn edge(self) -> usize {
        match self {
            Self::F2x2 => 2,
            Self::F4x4 => 4,
        }
    }

    /// The transformed tile's edge e = m + 2: an output tile's input patch is e × e.
    pub const fn patch(self) -> usize {
        self.edge() + 2
    }

    /// Output tiles per invocation of the kernel (`TT`), side by side along
    /// x: each weight fetch serves all of them, and their row reads its input
    /// patch four pixels per fetch, so m·TT is a multiple of 4 (every
    /// invocation's row starts on a four-pixel texel, and with F(2×2) two
    /// tiles' rows make one four-pixel store). llvmpipe's compile time grows
    /// with TT·CH; the chosen values are measured (docs/bench/unet.md, "Tuning").
    pub const fn tiles_per_invocation(self) -> usize {
        match self {
            Self::F2x2 => 8,
            Self::F4x4 => 4,
        }
    }

    /// Input channels per step of the kernel (`CH`): fetched and transformed
    /// first, then multiplied, so each accumulator is loaded and stored once
    /// per step (see [`WinogradTile::tiles_per_invocation`] for the sweep).
    pub const fn channels_per_step(self) -> usize {
        2
    }

    fn transforms(self) -> &'static Transforms {
        match self {
            Self::F2x2 => &F2X2,
            Self::F4x4 => &F4X4,
        }
    }

    /// U = G·g·Gᵀ of one 3 × 3 kernel `g` (row-major): row-major e × e.
    pub(crate) fn weight_transform(self, g: &[f64; 9]) -> Vec<f64> {
        let t = self.transforms();
        sandwich(t.g, g, t.g, 3)
    }

    /// V = Bᵀ·d·B of one e × e input patch (row-major).
    pub(crate) fn input_transform(self, d: &[f64]) -> Vec<f64> {
        let t = self.transforms();
        sandwich(t.bt, d, t.bt, self.patch())
    }

    /// Y = Aᵀ·m·A of one e × e product sum (row-major): the m × m output tile, row-major.
    pub(crate) fn output_transform(self, m: &[f64]) -> Vec<f64> {
        let t = self.transforms();
        sandwich(t.at, m, t.at, self.patch())
    }
}

// Every invocation's row of tiles spans a multiple of 4 pixels (`unet_winograd_body.glsl`'s fetches and stores).
const _: () = {
    let (a, b) = (WinogradTile::F2x2, WinogradTile::F4x4);
    assert!(a.edge() * a.tiles_per_invocation() % 4 == 0 && b.edge() * b.tiles_per_invocation() % 4 == 0);
};

/// L·X·Rᵀ for X (`n` × `n`, row-major) and L, R (`rows` × `n`, row-major): row-major.
fn sandwich(l: &[f64], x: &[f64], r: &[f64], n: usize) -> Vec<f64> {
    let (lr, rr) = (l.len() / n, r.len() / n);
    let lx: Vec<f64> = (0..lr * n).map(|at| (0..n).map(|k| l[(at / n) * n + k] * x[k * n + at % n]).sum()).collect();
    (0..lr * rr).map(|at| (0..n).map(|k| lx[(at / rr) * n + k] * r[(at % rr) * n + k]).sum()).collect()
}

/// Texels (RGBA32F) of a layer's packed Winograd weights: output channels
/// padded to the kernel's channel block (`super::channel_block`).
pub(crate) fn winograd_weight_texels(tile: WinogradTile, in_channels: usize, out_channels: usize) -> usize {
    let block = super::channel_block(out_channels, true);
    out_channels.div_ceil(block) * block / 4 * in_channels * tile.patch() * tile.patch()
}

/// Packs a layer's transformed weights for `unet_winograd_body.glsl`:
/// `[oc/4][ic][e·e][4]` floats (one RGBA32F texel per block of 4 output
/// channels, input channel and k; keep in sync), output channels past the
/// layer's, up to a whole kernel channel block, zero.
pub(crate) fn pack_winograd(tile: WinogradTile, l: &ConvWeights) -> Vec<f32> {
    let n = 4;
    let ee = tile.patch() * tile.patch();
    let mut w = vec![0.0f32; winograd_weight_texels(tile, l.in_channels, l.out_channels) * 4];
    for o in 0..l.out_channels {
        for i in 0..l.in_channels {
            let at = (o * l.in_channels + i) * 9;
            let g: [f64; 9] = std::array::from_fn(|t| f64::from(l.weight[at + t]));
            for (k, v) in tile.weight_transform(&g).iter().enumerate() {
                w[(((o / n) * l.in_channels + i) * ee + k) * n + o % n] = *v as f32;
            }
        }
    }
    w
}

/// How the conv layers run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ConvPath {
    /// Direct convolution, inputs through texel-buffer views, four pixels per
    /// fetch where a layer's width is a multiple of 4, else one.
    Vec4,
    /// Direct convolution, inputs through texel-buffer views, one pixel per fetch.
    Texel,
    /// Direct convolution, inputs by device address.
    Address,
    /// Winograd F(4×4, 3×3) for the stride-1 layers (texel inputs, four
    /// pixels per fetch where the width allows), direct for stride 2; the
    /// default on CPU devices ([`ConvPath::default_for`]).
    Winograd,
    /// As [`ConvPath::Winograd`] with F(2×2, 3×3).
    Winograd2,
}

impl ConvPath {
    /// The label in tables and on the command line.
    pub fn label(self) -> &'static str {
        match self {
            Self::Vec4 => "vec4",
            Self::Texel => "texel",
            Self::Address => "address",
            Self::Winograd => "winograd",
            Self::Winograd2 => "winograd2",
        }
    }

    /// The path a new [`UNet`](super::UNet) takes on a device of `device_type`
    /// that has (`texel_views`) or lacks the texel-buffer formats the texel
    /// paths read. On a CPU device (lavapipe) Winograd F(4×4): it does a quarter
    /// of the multiplies, and LLVM compiles its large unrolled kernels.
    /// On GPUs direct convolution, one pixel per fetch: the Winograd kernels'
    /// hundreds of live accumulators per invocation exceed a GPU's registers, and
    /// NVIDIA's compiler spends minutes on them (docs/bench/unet.md has the
    /// figures of each path on both). Device addresses where texel views are missing.
    pub fn default_for(device_type: vk::PhysicalDeviceType, texel_views: bool) -> Self {
        match (texel_views, device_type) {
            (false, _) => Self::Address,
            (true, vk::PhysicalDeviceType::CPU) => Self::Winograd,
            (true, _) => Self::Texel,
        }
    }

    /// Whether the path reads four pixels per texel fetch where a layer's width allows.
    pub fn vec4(self) -> bool {
        matches!(self, Self::Vec4 | Self::Winograd | Self::Winograd2)
    }

    /// The Winograd transform of the stride-1 layers, if any.
    pub fn winograd(self) -> Option<WinogradTile> {
        match self {
            Self::Winograd => Some(WinogradTile::F4x4),
            Self::Winograd2 => Some(WinogradTile::F2x2),
            Self::Vec4 | Self::Texel | Self::Address => None,
        }
    }
}

impl std::str::FromStr for ConvPath {
    type Err = crate::Error;
    fn from_str(text: &str) -> crate::Result<Self> {
        [Self::Winograd, Self::Winograd2, Self::Vec4, Self::Texel, Self::Address]
            .into_iter()
            .find(|p| p.label() == text.trim())
            .ok_or_else(|| {
                crate::Error::invalid(
                    format!("conv path \"{text}\""),
                    "is not winograd, winograd2, vec4, texel or address",
                )
            })
    }
}
