//! The CPU twin of the U-Net: plain loops over f32 tensors with f64
//! accumulation, the same layer order, padding, resize rule and activation
//! as the kernels.

use super::{layers, level_sizes, Activation, ConvWeights, UNetWeights, WinogradTile};
use crate::splat::Channel;

/// A CHW tensor.
#[derive(Clone, Debug, PartialEq)]
pub struct Tensor {
    /// Channels.
    pub channels: usize,
    /// Width.
    pub width: usize,
    /// Height.
    pub height: usize,
    /// `[c][y][x]`.
    pub data: Vec<f64>,
}

impl Tensor {
    /// A tensor from f32 values.
    pub fn from_f32(channels: usize, width: usize, height: usize, data: &[f32]) -> Self {
        Self { channels, width, height, data: data.iter().map(|&v| f64::from(v)).collect() }
    }

    fn at(&self, c: usize, x: usize, y: usize) -> f64 {
        self.data[(c * self.height + y) * self.width + x]
    }

    /// Channel concatenation.
    pub fn concat(&self, other: &Tensor) -> Tensor {
        let mut data = self.data.clone();
        data.extend(&other.data);
        Tensor { channels: self.channels + other.channels, width: self.width, height: self.height, data }
    }
}

fn activate(v: f64, act: Activation) -> f64 {
    match act {
        Activation::None => v,
        Activation::Relu => v.max(0.0),
        Activation::LeakyRelu => {
            if v >= 0.0 {
                v
            } else {
                0.01 * v
            }
        }
    }
}

/// 3×3 convolution, padding 1, `stride`, bias and activation; output ceil(n/stride).
pub fn conv3x3_cpu(x: &Tensor, l: &ConvWeights, stride: usize, act: Activation) -> Tensor {
    assert_eq!(x.channels, l.in_channels, "conv input channels");
    let (ow, oh) = (x.width.div_ceil(stride), x.height.div_ceil(stride));
    let mut data = vec![0.0; l.out_channels * ow * oh];
    for o in 0..l.out_channels {
        for oy in 0..oh {
            for ox in 0..ow {
                let mut acc = f64::from(l.bias[o]);
                for i in 0..l.in_channels {
                    for ky in 0..3 {
                        let iy = (oy * stride + ky) as isize - 1;
                        if iy < 0 || iy >= x.height as isize {
                            continue;
                        }
                        for kx in 0..3 {
                            let ix = (ox * stride + kx) as isize - 1;
                            if ix < 0 || ix >= x.width as isize {
                                continue;
                            }
                            let w = f64::from(l.weight[((o * l.in_channels + i) * 3 + ky) * 3 + kx]);
                            acc += w * x.at(i, ix as usize, iy as usize);
                        }
                    }
                }
                data[(o * oh + oy) * ow + ox] = activate(acc, act);
            }
        }
    }
    Tensor { channels: l.out_channels, width: ow, height: oh, data }
}

/// The stride-1 3×3 convolution of [`conv3x3_cpu`] computed by Winograd
/// `tile` ([`super::winograd`]'s transforms, in f64): equal to it up to
/// rounding, so it checks the transforms the kernel uses.
pub fn winograd_conv3x3_cpu(x: &Tensor, l: &ConvWeights, act: Activation, tile: WinogradTile) -> Tensor {
    let (t, e) = (tile.edge(), tile.patch());
    assert_eq!(x.channels, l.in_channels, "conv input channels");
    let (w, h) = (x.width, x.height);
    let u: Vec<Vec<f64>> = (0..l.out_channels * l.in_channels)
        .map(|oi| tile.weight_transform(&std::array::from_fn(|k| f64::from(l.weight[oi * 9 + k]))))
        .collect();
    let mut data = vec![0.0; l.out_channels * w * h];
    for ty in 0..h.div_ceil(t) {
        for tx in 0..w.div_ceil(t) {
            let v: Vec<Vec<f64>> = (0..l.in_channels)
                .map(|i| {
                    let d: Vec<f64> = (0..e * e)
                        .map(|j| {
                            let (iy, ix) = ((t * ty + j / e) as isize - 1, (t * tx + j % e) as isize - 1);
                            let inside = iy >= 0 && iy < h as isize && ix >= 0 && ix < w as isize;
                            if inside {
                                x.at(i, ix as usize, iy as usize)
                            } else {
                                0.0
                            }
                        })
                        .collect();
                    tile.input_transform(&d)
                })
                .collect();
            for o in 0..l.out_channels {
                let mut m = vec![0.0; e * e];
                for (i, vi) in v.iter().enumerate() {
                    let ui = &u[o * l.in_channels + i];
                    for k in 0..e * e {
                        m[k] += ui[k] * vi[k];
                    }
                }
                for (j, y) in tile.output_transform(&m).iter().enumerate() {
                    let (oy, ox) = (t * ty + j / t, t * tx + j % t);
                    if oy < h && ox < w {
                        data[(o * h + oy) * w + ox] = activate(y + f64::from(l.bias[o]), act);
                    }
                }
            }
        }
    }
    Tensor { channels: l.out_channels, width: w, height: h, data }
}

/// The fp16 bits the fp16-storage kernels store for `v` (`half_bits` in
/// `unet_storage.glsl`, step by step; keep in sync): rounded to nearest even
/// (subnormals included), saturated to ±65504, NaN to a quiet NaN.
pub fn half_bits(v: f32) -> u16 {
    let f = v.to_bits();
    let a = (f & 0x7fff_ffff).min(0x477f_e000);
    let normal = a.wrapping_add(0xc800_0fff + ((a >> 13) & 1)) >> 13;
    let subnormal = (f32::from_bits(a) + 0.5).to_bits() - 0x3f00_0000;
    let bits = if a < 0x3880_0000 { subnormal } else { normal };
    let bits = if f & 0x7fff_ffff > 0x7f80_0000 { 0x7e00 } else { bits };
    // At most 0x7e00 | 0x8000: the cast keeps every bit.
    (((f >> 16) & 0x8000) | bits) as u16
}

/// PyTorch's bilinear source index rule along one axis.
fn source(d: usize, n_in: usize, n_out: usize, align_corners: bool) -> (usize, usize, f64) {
    let s = if align_corners {
        if n_out > 1 {
            d as f64 * (n_in - 1) as f64 / (n_out - 1) as f64
        } else {
            0.0
        }
    } else {
        ((d as f64 + 0.5) * n_in as f64 / n_out as f64 - 0.5).max(0.0)
    };
    let i0 = (s.floor() as usize).min(n_in - 1);
    (i0, (i0 + 1).min(n_in - 1), s - i0 as f64)
}

/// Bilinear resize to `width`×`height` (`F.interpolate(mode="bilinear")`).
pub(crate) fn upsample_cpu(x: &Tensor, width: usize, height: usize, align_corners: bool) -> Tensor {
    let mut data = Vec::with_capacity(x.channels * width * height);
    for c in 0..x.channels {
        for y in 0..height {
            let (y0, y1, ty) = source(y, x.height, height, align_corners);
            for xo in 0..width {
                let (x0, x1, tx) = source(xo, x.width, width, align_corners);
                let top = x.at(c, x0, y0) * (1.0 - tx) + x.at(c, x1, y0) * tx;
                let bottom = x.at(c, x0, y1) * (1.0 - tx) + x.at(c, x1, y1) * tx;
                data.push(top * (1.0 - ty) + bottom * ty);
            }
        }
    }
    Tensor { channels: x.channels, width, height, data }
}

/// The whole network on one input.
pub fn unet_cpu(weights: &UNetWeights, input: &Tensor) -> Tensor {
    unet_cpu_stored(weights, input, false)
}

/// Rounds to the nearest fp16, saturating at ±65504 (as the fp16 kernels store).
pub(crate) fn round_half(t: &mut Tensor) {
    for v in &mut t.data {
        *v = f64::from(half::f16::from_f64(v.clamp(-65504.0, 65504.0)).to_f32());
    }
}

/// The network with every stored activation (each layer's output but the
/// last, and each resized tensor) rounded to fp16 when `half`, as with
/// fp16 storage; arithmetic stays f64.
pub fn unet_cpu_stored(weights: &UNetWeights, input: &Tensor, half: bool) -> Tensor {
    let c = &weights.config;
    let names = layers(c);
    let act = c.activation;
    let store = |mut t: Tensor| {
        if half {
            round_half(&mut t);
        }
        t
    };
    let conv = |i: usize, x: &Tensor, a: Activation| {
        let y = conv3x3_cpu(x, &weights.layers[i], names[i].3 as usize, a);
        if i + 1 < names.len() {
            store(y)
        } else {
            y
        }
    };
    let s = level_sizes(input.width, input.height);
    let mut f = vec![conv(0, input, act)];
    for i in 1..5 {
        let next = conv(i, &f[i - 1], act);
        f.push(next);
    }
    let mut u = f[4].clone();
    for (k, level) in [3usize, 2, 1, 0].into_iter().enumerate() {
        let up = store(upsample_cpu(&u, s[level].0, s[level].1, c.align_corners));
        u = conv(5 + k, &up.concat(&f[level]), act);
    }
    conv(9, &u, Activation::None)
}

/// The network input from host deferred buffers (as `unet_pack.comp`): CHW,
/// 14 channels; `sun` and `sky` are RGB per pixel.
pub fn pack_cpu(g: &crate::splat::GBuffer, sun: &[f32], sky: &[f32], min_alpha: f32) -> Tensor {
    let (w, h) = (g.width as usize, g.height as usize);
    let n = w * h;
    let mut data = vec![0.0f64; 14 * n];
    for p in 0..n {
        let a = f64::from(g.alpha[p]);
        if a < f64::from(min_alpha) {
            continue;
        }
        let ia = 1.0 / a;
        let nv = g.get(Channel::Normal).map_or([0.0; 3], |v| [v[3 * p], v[3 * p + 1], v[3 * p + 2]].map(f64::from));
        let len = (nv[0] * nv[0] + nv[1] * nv[1] + nv[2] * nv[2]).sqrt();
        let mut v = [0.0f64; 14];
        if len > 1e-12 {
            for c in 0..3 {
                v[c] = nv[c] / len;
            }
        }
        let one = |b: Option<&[f32]>, fallback: f64| b.map_or(fallback, |b| (f64::from(b[p]) * ia).clamp(0.0, 1.0));
        for c in 0..3 {
            v[3 + c] = g.get(Channel::Albedo).map_or(0.0, |b| (f64::from(b[3 * p + c]) * ia).clamp(0.0, 1.0));
            v[8 + c] = f64::from(sun[3 * p + c]);
            v[11 + c] = f64::from(sky[3 * p + c]);
        }
        v[6] = one(g.get(Channel::Roughness), 1.0);
        v[7] = one(g.get(Channel::Metallic), 0.0);
        for (c, x) in v.iter().enumerate() {
            data[c * n + p] = *x;
        }
    }
    Tensor { channels: 14, width: w, height: h, data }
}
