//! The network's description and weights: architecture from safetensors
//! metadata, PyTorch state_dict tensors, and tensor I/O.

use std::collections::HashMap;
use std::path::Path;

use super::*;
use crate::error::{Error, Result};

/// Activation after every layer but the last.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Activation {
    /// Identity.
    None,
    /// max(x, 0).
    #[default]
    Relu,
    /// x ≥ 0 ? x : 0.01·x.
    LeakyRelu,
}

impl Activation {
    /// Parses `none`, `relu` or `leaky_relu`.
    pub fn parse(text: &str) -> Result<Self> {
        match text {
            "none" | "identity" => Ok(Self::None),
            "relu" => Ok(Self::Relu),
            "leaky_relu" => Ok(Self::LeakyRelu),
            other => Err(Error::invalid(format!("activation \"{other}\""), "is not none, relu or leaky_relu")),
        }
    }

    /// The name written to metadata.
    pub fn name(self) -> &'static str {
        match self {
            Self::None => "none",
            Self::Relu => "relu",
            Self::LeakyRelu => "leaky_relu",
        }
    }

    pub(super) fn code(self) -> u32 {
        match self {
            Self::None => 0,
            Self::Relu => 1,
            Self::LeakyRelu => 2,
        }
    }
}

/// The default input channel order: what the shading stage packs.
pub const DEFAULT_INPUT_ORDER: [&str; 14] = [
    "normal.x",
    "normal.y",
    "normal.z",
    "albedo.r",
    "albedo.g",
    "albedo.b",
    "roughness",
    "metallic",
    "sun.r",
    "sun.g",
    "sun.b",
    "sky.r",
    "sky.g",
    "sky.b",
];

/// The architecture, from the weights file's metadata.
#[derive(Clone, Debug, PartialEq)]
pub struct UNetConfig {
    /// Input channels.
    pub in_channels: usize,
    /// Widths w0..w4 of the five resolutions.
    pub widths: [usize; 5],
    /// Output channels (3: RGB L_ind).
    pub out_channels: usize,
    /// Activation.
    pub activation: Activation,
    /// `F.interpolate(..., align_corners=)`.
    pub align_corners: bool,
    /// Names of the input channels, in order.
    pub input_order: Vec<String>,
}

impl Default for UNetConfig {
    fn default() -> Self {
        Self {
            in_channels: 14,
            widths: [32, 32, 64, 64, 128],
            out_channels: 3,
            activation: Activation::Relu,
            align_corners: false,
            input_order: DEFAULT_INPUT_ORDER.iter().map(|s| s.to_string()).collect(),
        }
    }
}

/// Layer names in execution order, with their (in, out) channels and stride.
pub fn layers(c: &UNetConfig) -> Vec<(&'static str, usize, usize, u32)> {
    let w = c.widths;
    vec![
        ("inc", c.in_channels, w[0], 1),
        ("down1", w[0], w[1], 2),
        ("down2", w[1], w[2], 2),
        ("down3", w[2], w[3], 2),
        ("down4", w[3], w[4], 2),
        ("up1", w[4] + w[3], w[3], 1),
        ("up2", w[3] + w[2], w[2], 1),
        ("up3", w[2] + w[1], w[1], 1),
        ("up4", w[1] + w[0], w[0], 1),
        ("outc", w[0], c.out_channels, 1),
    ]
}

impl UNetConfig {
    /// Bytes of the activation arena for an input size (what [`UNet::arena_bytes`] reports).
    pub fn arena_bytes(&self, width: u32, height: u32, precision: StoragePrecision) -> u64 {
        ArenaLayout::new(self, width as usize, height as usize, precision).total
    }

    /// Weights and biases of the ten convolutions.
    pub fn parameter_count(&self) -> u64 {
        layers(self).iter().map(|&(_, cin, cout, _)| (cin * cout * 9 + cout) as u64).sum()
    }

    /// The safetensors metadata describing this architecture.
    pub fn metadata(&self) -> HashMap<String, String> {
        let w: Vec<String> = self.widths.iter().map(usize::to_string).collect();
        HashMap::from([
            ("architecture".to_string(), "srug-indirect-unet".to_string()),
            ("in_channels".to_string(), self.in_channels.to_string()),
            ("widths".to_string(), w.join(",")),
            ("out_channels".to_string(), self.out_channels.to_string()),
            ("activation".to_string(), self.activation.name().to_string()),
            ("align_corners".to_string(), self.align_corners.to_string()),
            ("input_order".to_string(), self.input_order.join(",")),
        ])
    }

    /// Reads the architecture from metadata (missing keys take the defaults,
    /// except that a present key must parse).
    pub(crate) fn from_metadata(meta: &HashMap<String, String>, origin: &str) -> Result<Self> {
        let bad =
            |key: &str, v: &str| Error::invalid(format!("{origin}: metadata \"{key}\" = \"{v}\""), "cannot be read");
        let mut c = Self::default();
        if let Some(a) = meta.get("architecture") {
            if a != "srug-indirect-unet" {
                return Err(Error::invalid(format!("{origin}: architecture \"{a}\""), "is not srug-indirect-unet"));
            }
        }
        // Widths are bounded as they are read: nothing is sized by one before this check.
        let max = crate::io::limits().max_channels;
        let num = |key: &str, v: &str| {
            let n = v.trim().parse::<usize>().ok().filter(|n| *n > 0).ok_or_else(|| bad(key, v))?;
            if n > max {
                return Err(Error::invalid(
                    format!("{origin}: metadata \"{key}\" = {n}"),
                    format!("is wider than the {max}-channel limit"),
                ));
            }
            Ok(n)
        };
        if let Some(v) = meta.get("in_channels") {
            c.in_channels = num("in_channels", v)?;
        }
        if let Some(v) = meta.get("out_channels") {
            c.out_channels = num("out_channels", v)?;
        }
        if let Some(v) = meta.get("widths") {
            let w: Vec<usize> = v.split(',').map(|t| num("widths", t)).collect::<Result<_>>()?;
            c.widths = w.try_into().map_err(|_| bad("widths", v))?;
        }
        if let Some(v) = meta.get("activation") {
            c.activation = Activation::parse(v.trim()).map_err(|_| bad("activation", v))?;
        }
        if let Some(v) = meta.get("align_corners") {
            c.align_corners = match v.trim().to_ascii_lowercase().as_str() {
                "true" | "1" => true,
                "false" | "0" => false,
                _ => return Err(bad("align_corners", v)),
            };
        }
        if let Some(v) = meta.get("input_order") {
            c.input_order = v.split(',').map(|s| s.trim().to_string()).collect();
        } else if c.in_channels != DEFAULT_INPUT_ORDER.len() {
            c.input_order = (0..c.in_channels).map(|i| format!("input.{i}")).collect();
        }
        if c.input_order.len() != c.in_channels {
            return Err(Error::invalid(
                format!("{origin}: input_order"),
                format!("names {} channels, in_channels is {}", c.input_order.len(), c.in_channels),
            ));
        }
        Ok(c)
    }
}

/// One convolution's parameters (OIHW weights).
#[derive(Clone, Debug, PartialEq)]
pub struct ConvWeights {
    /// Input channels.
    pub in_channels: usize,
    /// Output channels.
    pub out_channels: usize,
    /// `[out][in][3][3]`.
    pub weight: Vec<f32>,
    /// `[out]`.
    pub bias: Vec<f32>,
}

/// A whole network's weights.
#[derive(Clone, Debug, PartialEq)]
pub struct UNetWeights {
    /// Architecture.
    pub config: UNetConfig,
    /// The ten layers in [`layers`] order.
    pub layers: Vec<ConvWeights>,
}

impl UNetWeights {
    /// Random weights (He-uniform, bias ±0.1) for tests and benchmarks.
    pub fn random(config: UNetConfig, seed: u64) -> Self {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(seed);
        let layers = layers(&config)
            .into_iter()
            .map(|(_, ci, co, _)| {
                let bound = (6.0 / (ci as f32 * 9.0)).sqrt();
                ConvWeights {
                    in_channels: ci,
                    out_channels: co,
                    weight: (0..co * ci * 9).map(|_| rng.random_range(-bound..bound)).collect(),
                    bias: (0..co).map(|_| rng.random_range(-0.1..0.1)).collect(),
                }
            })
            .collect();
        Self { config, layers }
    }

    /// Reads a safetensors file (float32, float16 or bfloat16 tensors).
    pub fn load(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        let bytes = crate::io::read_file(path)?;
        Self::from_bytes(&bytes, &path.display().to_string())
    }

    /// Parses safetensors bytes; a missing tensor or a shape mismatch is an
    /// error naming the tensor.
    pub fn from_bytes(bytes: &[u8], origin: &str) -> Result<Self> {
        let bad = |m: String| Error::invalid(origin, m);
        let (_, meta) =
            safetensors::SafeTensors::read_metadata(bytes).map_err(|e| bad(format!("not a safetensors file: {e}")))?;
        let config = UNetConfig::from_metadata(&meta.metadata().clone().unwrap_or_default(), origin)?;
        let st = safetensors::SafeTensors::deserialize(bytes).map_err(|e| bad(format!("corrupt safetensors: {e}")))?;
        let mut out = Vec::new();
        for (name, ci, co, _) in layers(&config) {
            let get = |suffix: &str, shape: &[usize]| -> Result<Vec<f32>> {
                let key = format!("{name}.{suffix}");
                let t = st.tensor(&key).map_err(|_| bad(format!("tensor \"{key}\" is missing")))?;
                if t.shape() != shape {
                    return Err(bad(format!("tensor \"{key}\" has shape {:?}, expected {shape:?}", t.shape())));
                }
                let v = tensor_f32(&t).map_err(|m| bad(format!("tensor \"{key}\": {m}")))?;
                if let Some(i) = v.iter().position(|x| !x.is_finite()) {
                    return Err(bad(format!("tensor \"{key}\" element {i} is {}", v[i])));
                }
                Ok(v)
            };
            out.push(ConvWeights {
                in_channels: ci,
                out_channels: co,
                weight: get("weight", &[co, ci, 3, 3])?,
                bias: get("bias", &[co])?,
            });
        }
        Ok(Self { config, layers: out })
    }

    /// Serializes to safetensors bytes (float32, PyTorch names, metadata).
    pub fn to_bytes(&self) -> Result<Vec<u8>> {
        let names = layers(&self.config);
        let mut tensors = Vec::new();
        for ((name, ci, co, _), l) in names.iter().zip(&self.layers) {
            tensors.push((format!("{name}.weight"), vec![*co, *ci, 3, 3], bytemuck::cast_slice(&l.weight).to_vec()));
            tensors.push((format!("{name}.bias"), vec![*co], bytemuck::cast_slice(&l.bias).to_vec()));
        }
        let views: Vec<(String, safetensors::tensor::TensorView<'_>)> = tensors
            .iter()
            .map(|(n, s, d)| {
                safetensors::tensor::TensorView::new(safetensors::Dtype::F32, s.clone(), d).map(|v| (n.clone(), v))
            })
            .collect::<Result<_, _>>()
            .map_err(|e| Error::Internal(format!("cannot serialize weights: {e}")))?;
        safetensors::serialize(views, Some(self.config.metadata()))
            .map_err(|e| Error::Internal(format!("cannot serialize weights: {e}")))
    }

    /// Multiply-adds of one inference at `width`×`height`, ×2 for flops.
    pub fn flops(&self, width: usize, height: usize) -> f64 {
        let sizes = level_sizes(width, height);
        let at = [0, 1, 2, 3, 4, 3, 2, 1, 0, 0];
        layers(&self.config)
            .iter()
            .zip(at)
            .map(|((_, ci, co, _), l)| 2.0 * 9.0 * (*ci * *co) as f64 * (sizes[l].0 * sizes[l].1) as f64)
            .sum()
    }
}

/// A float tensor's values as f32 (F32, F16 or BF16, little endian).
pub(crate) fn tensor_f32(t: &safetensors::tensor::TensorView<'_>) -> std::result::Result<Vec<f32>, String> {
    let d = t.data();
    Ok(match t.dtype() {
        safetensors::Dtype::F32 => d.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect(),
        safetensors::Dtype::F16 => d.chunks_exact(2).map(|b| half::f16::from_le_bytes([b[0], b[1]]).to_f32()).collect(),
        safetensors::Dtype::BF16 => {
            d.chunks_exact(2).map(|b| half::bf16::from_le_bytes([b[0], b[1]]).to_f32()).collect()
        }
        other => return Err(format!("dtype {other:?} is not a float type (F32, F16, BF16)")),
    })
}

/// Reads a tensor named `name` of shape `[1, C, H, W]` or `[C, H, W]` from
/// safetensors bytes: (C, H, W, values).
pub fn read_tensor(bytes: &[u8], name: &str, origin: &str) -> Result<(usize, usize, usize, Vec<f32>)> {
    let bad = |m: String| Error::invalid(origin, m);
    let st = safetensors::SafeTensors::deserialize(bytes).map_err(|e| bad(format!("not a safetensors file: {e}")))?;
    let t = st.tensor(name).map_err(|_| bad(format!("tensor \"{name}\" is missing")))?;
    let (c, h, w) = match t.shape() {
        [1, c, h, w] | [c, h, w] => (*c, *h, *w),
        other => return Err(bad(format!("tensor \"{name}\" has shape {other:?}, expected [1, C, H, W]"))),
    };
    let v = tensor_f32(&t).map_err(|m| bad(format!("tensor \"{name}\": {m}")))?;
    if let Some(i) = v.iter().position(|x| !x.is_finite()) {
        return Err(bad(format!("tensor \"{name}\" element {i} is {}", v[i])));
    }
    Ok((c, h, w, v))
}

/// Safetensors bytes holding one float32 tensor `name` of shape `[1, C, H, W]`.
pub fn tensor_bytes(name: &str, c: usize, h: usize, w: usize, values: &[f32]) -> Result<Vec<u8>> {
    let view =
        safetensors::tensor::TensorView::new(safetensors::Dtype::F32, vec![1, c, h, w], bytemuck::cast_slice(values))
            .map_err(|e| Error::Internal(format!("cannot serialize {name}: {e}")))?;
    safetensors::serialize([(name.to_string(), view)], None)
        .map_err(|e| Error::Internal(format!("cannot serialize {name}: {e}")))
}
