//! Inference: the executor that packs the inputs, plans the arena and records
//! every layer of a pass.

use std::collections::HashMap;
use std::sync::Arc;

use super::*;
use crate::error::{Error, Result};
use crate::gpu::{
    kernels, Binding, BindingKind, Buffer, Device, DeviceAddress, Grid, Kernel, KernelDecl, MemoryKind, SpecValue,
    TexelFormat, Texels, Timings,
};
use crate::splat::Channel;

/// The deferred buffers the network reads (see [`DEFAULT_INPUT_ORDER`]).
pub struct NetworkInputs<'a> {
    /// The camera's G-buffers (normal and albedo required).
    pub gbuffer: &'a crate::splat::GpuGBuffer,
    /// L_sun, RGB per pixel.
    pub sun: &'a Buffer,
    /// L_sky, RGB per pixel.
    pub sky: &'a Buffer,
    /// Alpha below which a pixel has no surface.
    pub min_alpha: f32,
}

/// The network on the GPU: kernels, packed weights and the activation arena.
pub struct UNet {
    device: Device,
    config: UNetConfig,
    precision: StoragePrecision,
    convs: HashMap<ConvKey, Arc<Kernel>>,
    /// The resize with one and with four output pixels per invocation ([`resize_four`]).
    upsample: [Arc<Kernel>; 2],
    upsample_texel: Option<[Arc<Kernel>; 2]>,
    /// The exact-2× resize from a four-pixel view ([`resize_exact2`]), where the device has RGBA views.
    upsample_exact2: Option<Arc<Kernel>>,
    pack: Arc<Kernel>,
    /// Packed weights for device-address inputs, then for texel inputs (empty without them).
    weights: [Vec<LayerBuffers>; 2],
    /// Winograd kernels per [`WinogradKey`]; built at the first inference of a size that needs them.
    winograd_kernels: HashMap<WinogradKey, Arc<Kernel>>,
    /// Transformed weights per layer (`None` for stride 2) for the tile they were made for;
    /// empty until Winograd is first chosen.
    winograd_weights: Option<(WinogradTile, Vec<Option<Buffer>>)>,
    /// The weights as loaded, for the Winograd transform.
    host_layers: Vec<ConvWeights>,
    arena: Option<Buffer>,
    prefill: Option<u32>,
    texel: bool,
    /// Texel inputs read four pixels per fetch where a layer's width allows.
    vec4: bool,
    winograd: Option<WinogradTile>,
    /// Lanes that share the texel conv and Winograd weights' fetches (0: none; [`UNet::weight_fetch_lanes`]).
    weight_lanes: u32,
}

/// A Winograd kernel variant: tile, activation code, fp16 output, output channel block, four-pixel
/// inputs, lanes sharing weight fetches.
type WinogradKey = (WinogradTile, u32, bool, usize, bool, u32);

/// How activations are stored between layers; arithmetic is fp32 either way.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum StoragePrecision {
    /// 32-bit floats.
    #[default]
    Fp32,
    /// 16-bit floats (half the arena; needs the device's 16-bit storage).
    /// The network's input and output stay fp32; weights stay fp32.
    Fp16,
}

impl StoragePrecision {
    /// Parses `fp32` or `fp16`.
    pub fn parse(text: &str) -> Result<Self> {
        match text {
            "fp32" => Ok(Self::Fp32),
            "fp16" => Ok(Self::Fp16),
            other => Err(Error::invalid(format!("precision \"{other}\""), "is not fp32 or fp16")),
        }
    }

    /// Bytes per stored activation.
    pub fn bytes(self) -> u64 {
        match self {
            Self::Fp32 => 4,
            Self::Fp16 => 2,
        }
    }
}

/// A conv kernel variant: stride, activation, output block, input and output
/// in fp16, pixel block, inputs through texel-buffer views, four pixels per
/// fetch, lanes sharing weight fetches (texel kernels).
type ConvKey = (u32, u32, u32, bool, bool, u32, bool, bool, u32);

/// One layer's weights on the GPU: a buffer per pass (a uniform buffer for
/// device-address kernels, one RGBA32F texel view for texel kernels), the bias.
struct LayerBuffers {
    passes: Vec<Buffer>,
    bias: Buffer,
    chunk: usize,
}

/// One inference's output and timings.
pub struct UNetOutput {
    /// CHW float32, `out_channels` × height × width.
    pub output: Buffer,
    /// Per-layer GPU times.
    pub timings: Timings,
    /// The layers that read their inputs four pixels per texel fetch
    /// ([`UNet::vec4_inputs`]), in execution order.
    pub vec4_layers: Vec<&'static str>,
    /// The up layers whose resize ran the exact-2× kernel (`resize_exact2`), in execution order.
    pub exact_resizes: Vec<&'static str>,
}

/// One convolution of a pass: inputs A and B (the concatenation), levels, output.
#[derive(Clone, Copy)]
struct Step {
    layer: usize,
    a: Src,
    ca: usize,
    b: Src,
    cb: usize,
    lin: usize,
    lout: usize,
    /// Byte offset of the output in the arena; `None`: the network's output buffer.
    out: Option<u64>,
}

/// Where a conv input lies: the network's input buffer (fp32) or the arena.
#[derive(Clone, Copy)]
struct Src {
    /// Byte offset in its buffer.
    offset: u64,
    /// In the input buffer rather than the arena.
    input: bool,
    /// Stored as fp16.
    half: bool,
}

/// Byte offsets of every tensor of a pass in the arena, and its total size.
pub(super) struct ArenaLayout {
    pub(super) f: [u64; 5],
    pub(super) u: [u64; 4],
    pub(super) resized: u64,
    pub(super) partial: u64,
    pub(super) total: u64,
}

impl ArenaLayout {
    pub(super) fn new(c: &UNetConfig, width: usize, height: usize, precision: StoragePrecision) -> Self {
        let s = level_sizes(width, height);
        let px = |l: usize| (s[l].0 * s[l].1) as u64;
        let w = c.widths.map(|x| x as u64);
        let e = precision.bytes();
        let mut at = 0u64;
        let mut take = |bytes: u64| {
            let o = at;
            // 256: the largest minTexelBufferOffsetAlignment Vulkan allows, so every tensor can be a view.
            at += bytes.div_ceil(256) * 256;
            o
        };
        let f = [0, 1, 2, 3, 4].map(|l| take(e * w[l] * px(l)));
        // up1..up4 outputs: w3 at level 3, w2 at 2, w1 at 1, w0 at 0.
        let u = [(3, 3), (2, 2), (1, 1), (0, 0)].map(|(wi, l)| take(e * w[wi] * px(l)));
        // The resized tensor before each up conv: the previous level's channels at the skip's size.
        let resized = take(e * [w[4] * px(3), w[3] * px(2), w[2] * px(1), w[1] * px(0)].into_iter().max().unwrap_or(0));
        // fp32 partial sums of a layer run in several passes: its output channels at its resolution.
        let at_level = [0, 1, 2, 3, 4, 3, 2, 1, 0, 0];
        let partial = take(
            4 * layers(c)
                .iter()
                .zip(at_level)
                .filter(|((_, ci, co, _), _)| *ci > pass_channels(*ci, *co, false))
                .map(|((_, _, co, _), l)| *co as u64 * px(l))
                .max()
                .unwrap_or(0),
        );
        Self { f, u, resized, partial, total: at }
    }
}

impl UNet {
    /// Uploads the weights and builds the kernels (fp32 activations).
    pub fn new(device: &Device, weights: &UNetWeights) -> Result<Self> {
        Self::with_precision(device, weights, StoragePrecision::Fp32)
    }

    /// Uploads the weights and builds the kernels for `precision`.
    pub fn with_precision(device: &Device, weights: &UNetWeights, precision: StoragePrecision) -> Result<Self> {
        let config = weights.config.clone();
        let expected = layers(&config);
        if weights.layers.len() != expected.len()
            || weights.layers.iter().zip(&expected).any(|(l, e)| {
                (l.in_channels, l.out_channels) != (e.1, e.2) || l.weight.len() != e.1 * e.2 * 9 || l.bias.len() != e.2
            })
        {
            return Err(Error::invalid("U-Net weights", "do not match their configuration"));
        }
        let half = precision == StoragePrecision::Fp16;
        if half && !device.info().storage_16bit {
            return Err(Error::unsupported("fp16 activation storage needs storageBuffer16BitAccess"));
        }
        let info = device.info();
        let texel_formats =
            if half { &[TexelFormat::R32Float, TexelFormat::R16Float][..] } else { &[TexelFormat::R32Float] };
        let texel_formats = texel_formats.iter().chain([&TexelFormat::Rgba32Float]);
        let texel = texel_formats.into_iter().all(|f| info.texel_formats.contains(f));
        let vec4_formats = if half { &[TexelFormat::Rgba16Float][..] } else { &[] };
        let vec4 = texel && vec4_formats.iter().all(|f| info.texel_formats.contains(f));
        let default_path = ConvPath::default_for(info.device_type, texel);
        let weight_lanes = super::weight_lanes(info);
        let mut convs = HashMap::new();
        // (texel, vec4): device addresses always; texel views and four-pixel texel views where supported.
        let variants = [(false, false), (texel, false), (texel, vec4)];
        Self::build_convs(device, &config, half, &variants, weight_lanes, &mut convs)?;
        // One and four output pixels per invocation (`FOUR`, constant_id 0).
        let resize = |module: &'static srug_gpu::KernelInfo, bindings: &[BindingKind]| -> Result<[Arc<Kernel>; 2]> {
            let kernel = |four: bool| {
                let spec = [(0, SpecValue::Bool(four))];
                let push_constant_size = std::mem::size_of::<UpsamplePush>();
                device.kernel(module, &KernelDecl { bindings, push_constant_size, specialization: &spec })
            };
            Ok([kernel(false)?, kernel(true)?])
        };
        let upsample = resize(if half { &kernels::UNET_UPSAMPLE_HALF } else { &kernels::UNET_UPSAMPLE }, &[])?;
        let texel_module = if half { &kernels::UNET_UPSAMPLE_TEXEL_HALF } else { &kernels::UNET_UPSAMPLE_TEXEL };
        let upsample_texel = if texel { Some(resize(texel_module, &[BindingKind::UniformTexelBuffer])?) } else { None };
        // `EXACT2` (constant_id 1).
        let upsample_exact2 = if vec4 {
            let spec = [(1, SpecValue::Bool(true))];
            let bindings = &[BindingKind::UniformTexelBuffer];
            let push_constant_size = std::mem::size_of::<UpsamplePush>();
            Some(device.kernel(texel_module, &KernelDecl { bindings, push_constant_size, specialization: &spec })?)
        } else {
            None
        };
        let pack = device.kernel(
            &kernels::UNET_PACK,
            &KernelDecl { bindings: &[], push_constant_size: std::mem::size_of::<PackPush>(), specialization: &[] },
        )?;
        // Packed per input path (their channel blocks differ); none for texel where the device lacks it.
        let pack_layers = |texel: bool| -> Result<Vec<LayerBuffers>> {
            weights
                .layers
                .iter()
                .zip(&expected)
                .map(|(l, (name, ..))| {
                    let (passes, b) = pack_conv(l, texel);
                    let passes = passes
                        .iter()
                        .enumerate()
                        .map(|(k, w)| device.upload(&format!("{name} weights {k}"), w))
                        .collect::<srug_gpu::Result<_>>()?;
                    let bias = device.upload(&format!("{name} bias"), &b)?;
                    Ok(LayerBuffers { passes, bias, chunk: pass_channels(l.in_channels, l.out_channels, texel) })
                })
                .collect()
        };
        let host_layers = weights.layers.clone();
        let weights = [pack_layers(false)?, if texel { pack_layers(true)? } else { Vec::new() }];
        let mut net = Self {
            device: device.clone(),
            config,
            precision,
            convs,
            upsample,
            upsample_texel,
            upsample_exact2,
            pack,
            weights,
            winograd_kernels: HashMap::new(),
            winograd_weights: None,
            host_layers,
            arena: None,
            prefill: None,
            texel,
            vec4: vec4 && default_path.vec4(),
            winograd: None,
            weight_lanes,
        };
        net.set_winograd(default_path.winograd())?;
        Ok(net)
    }

    /// The Winograd kernel variant of layer `i` ([`WinogradKey`]): activation
    /// (none for the last) and fp16 output (not for the last).
    fn winograd_key(&self, tile: WinogradTile, i: usize, half: bool, vec4: bool) -> WinogradKey {
        let all = layers(&self.config);
        let last = i + 1 == all.len();
        let co = all[i].2;
        let act = if last { 0 } else { self.config.activation.code() };
        (tile, act, half && !last, channel_block(co, true), vec4, self.weight_lanes)
    }

    /// Lanes of a subgroup that fetch the texel conv and Winograd kernels'
    /// weights side by side and broadcast them (the weights are the same in
    /// every lane), or 0 where every lane fetches every weight: the subgroup
    /// size on lavapipe from Mesa 25, whose texel fetch is a call, else 0 (see
    /// `indirect::weight_lanes`). The output does not change.
    pub fn weight_fetch_lanes(&self) -> u32 {
        self.weight_lanes
    }

    /// Shares the weight fetches of the texel conv and Winograd kernels
    /// across each subgroup (`true`: its size, which needs subgroup broadcast
    /// and whole subgroups in 64 invocations) or not (see
    /// [`UNet::weight_fetch_lanes`]); builds the conv kernels that needs.
    pub fn set_shared_weight_fetches(&mut self, on: bool) -> Result<()> {
        let info = self.device.info();
        let size = info.subgroup_size;
        if on && !super::weight_sharing_supported(info) {
            return Err(Error::unsupported(format!(
                "sharing U-Net weight fetches needs subgroup broadcast and a subgroup size dividing 64 (this device: {size})"
            )));
        }
        let lanes = if on { size } else { 0 };
        let mut texel_variants: Vec<(bool, bool)> = self.convs.keys().filter(|k| k.6).map(|k| (k.6, k.7)).collect();
        texel_variants.sort_unstable();
        texel_variants.dedup();
        let half = self.precision == StoragePrecision::Fp16;
        Self::build_convs(&self.device, &self.config, half, &texel_variants, lanes, &mut self.convs)?;
        self.weight_lanes = lanes;
        Ok(())
    }

    /// The Winograd transform the stride-1 layers run by
    /// (`unet_winograd_body.glsl`), where their inputs go through texel-buffer
    /// views, or `None` for direct convolution. F(4×4, 3×3) by default on CPU
    /// devices with texel views, direct convolution on GPUs
    /// ([`ConvPath::default_for`]). Its kernels are built at the first
    /// inference of a size that needs them.
    pub fn winograd(&self) -> Option<WinogradTile> {
        self.winograd
    }

    /// Chooses a Winograd transform, or direct convolution (`None`), for the
    /// stride-1 layers (see [`UNet::winograd`]); Winograd without texel
    /// inputs on the device is an error. All compute the same sums up to
    /// rounding ([`winograd`] has the error of each).
    pub fn set_winograd(&mut self, tile: Option<WinogradTile>) -> Result<()> {
        if let Some(tile) = tile {
            if !self.convs.keys().any(|k| k.6) {
                return Err(Error::unsupported(
                    "Winograd convolution needs texel-buffer inputs, which this device lacks",
                ));
            }
            if self.winograd_weights.as_ref().is_none_or(|(t, _)| *t != tile) {
                self.build_winograd(tile)?;
            }
        }
        self.winograd = tile;
        Ok(())
    }

    /// Uploads the stride-1 layers' weights transformed for `tile`.
    fn build_winograd(&mut self, tile: WinogradTile) -> Result<()> {
        // Drop the other tile's first: only one set is kept.
        self.winograd_weights = None;
        let mut weights = Vec::new();
        for ((name, _, _, stride), l) in layers(&self.config).iter().zip(&self.host_layers) {
            weights.push(if *stride == 1 {
                let packed = winograd::pack_winograd(tile, l);
                Some(self.device.upload(&format!("{name} winograd weights"), &packed)?)
            } else {
                None
            });
        }
        self.winograd_weights = Some((tile, weights));
        Ok(())
    }

    /// Builds the Winograd kernels the stride-1 layers need at `width` × `height`
    /// that are not built yet: llvmpipe takes tens of seconds per variant with
    /// a cold shader cache, so only the variants a size needs are made.
    fn build_winograd_kernels(&mut self, tile: WinogradTile, width: usize, height: usize) -> Result<()> {
        let half = self.precision == StoragePrecision::Fp16;
        let s = level_sizes(width, height);
        for (i, (_, _, _, stride)) in layers(&self.config).iter().enumerate() {
            let vec4 = self.vec4 && vec4_fits(s[input_level(i)].0);
            let key = self.winograd_key(tile, i, half, vec4);
            if *stride != 1 || self.winograd_kernels.contains_key(&key) {
                continue;
            }
            let (_, act, half_out, block, _, lanes) = key;
            let mut spec = vec![
                (1, SpecValue::U32(act)),
                (2, SpecValue::U32(tile.tiles_per_invocation() as u32)),
                (3, SpecValue::U32(block as u32)),
                (4, SpecValue::U32(tile.channels_per_step() as u32)),
                (5, SpecValue::Bool(vec4)),
                (6, SpecValue::U32(lanes)),
            ];
            if half {
                spec.push((11, SpecValue::Bool(half_out)));
            }
            let view = BindingKind::UniformTexelBuffer;
            let code = match (tile, half) {
                (WinogradTile::F2x2, false) => &kernels::UNET_WINOGRAD2_TEXEL,
                (WinogradTile::F2x2, true) => &kernels::UNET_WINOGRAD2_TEXEL_HALF,
                (WinogradTile::F4x4, false) => &kernels::UNET_WINOGRAD_TEXEL,
                (WinogradTile::F4x4, true) => &kernels::UNET_WINOGRAD_TEXEL_HALF,
            };
            let kernel = self.device.kernel(
                code,
                &KernelDecl {
                    bindings: &[view, BindingKind::StorageBuffer { read_only: true }, view, view],
                    push_constant_size: std::mem::size_of::<ConvPush>(),
                    specialization: &spec,
                },
            )?;
            self.winograd_kernels.insert(key, kernel);
        }
        Ok(())
    }

    /// Builds the conv kernels of every layer for each (texel, vec4) input
    /// variant with `lanes` sharing the texel kernels' weight fetches
    /// ([`UNet::weight_fetch_lanes`]), those not in `convs` yet.
    fn build_convs(
        device: &Device,
        config: &UNetConfig,
        half: bool,
        variants: &[(bool, bool)],
        lanes: u32,
        convs: &mut HashMap<ConvKey, Arc<Kernel>>,
    ) -> Result<()> {
        let keys = variants.iter().flat_map(|&v| (0..layers(config).len()).map(move |i| (i, v)));
        for key in keys.map(|(i, (t, v))| Self::conv_key(config, i, half, t, v, lanes)) {
            if let std::collections::hash_map::Entry::Vacant(e) = convs.entry(key) {
                let texel = key.6;
                let mut spec = vec![
                    (0, SpecValue::U32(key.0)),
                    (1, SpecValue::U32(key.1)),
                    (2, SpecValue::U32(key.2)),
                    (3, SpecValue::U32(key.5)),
                ];
                if half && !texel {
                    spec.push((10, SpecValue::Bool(key.3)));
                }
                if half {
                    spec.push((11, SpecValue::Bool(key.4)));
                }
                if texel {
                    spec.push((4, SpecValue::Bool(key.7)));
                    spec.push((6, SpecValue::U32(key.8)));
                }
                let module = match (texel, half) {
                    (false, false) => &kernels::UNET_CONV,
                    (false, true) => &kernels::UNET_CONV_HALF,
                    (true, false) => &kernels::UNET_CONV_TEXEL,
                    (true, true) => &kernels::UNET_CONV_TEXEL_HALF,
                };
                // Texel kernels: weights, bias, input A, input B; address kernels: weights, bias.
                let weights = if texel { BindingKind::UniformTexelBuffer } else { BindingKind::UniformBuffer };
                let views = [BindingKind::UniformTexelBuffer; 2];
                let all: Vec<BindingKind> = [weights, BindingKind::StorageBuffer { read_only: true }]
                    .into_iter()
                    .chain(views.into_iter().take(if texel { 2 } else { 0 }))
                    .collect();
                e.insert(device.kernel(
                    module,
                    &KernelDecl {
                        bindings: &all,
                        push_constant_size: std::mem::size_of::<ConvPush>(),
                        specialization: &spec,
                    },
                )?);
            }
        }
        Ok(())
    }

    /// The kernel variant of layer `i`: its stride, activation (none for the
    /// last), output block, and fp16 input (not for the first) and output (not for the last).
    fn conv_key(config: &UNetConfig, i: usize, half: bool, texel: bool, vec4: bool, lanes: u32) -> ConvKey {
        let l = layers(config);
        let (_, _, co, stride) = l[i];
        let last = i + 1 == l.len();
        let act = if last { 0 } else { config.activation.code() };
        (
            stride,
            act,
            channel_block(co, texel) as u32,
            half && i > 0,
            half && !last,
            if vec4 { vec4_pixel_block(co) } else { pixel_block(co, texel) } as u32,
            texel,
            vec4,
            if texel { lanes } else { 0 },
        )
    }

    /// Whether conv layers read their inputs through texel-buffer views
    /// (where each input fits `maxTexelBufferElements`) rather than by device
    /// address. On by default where the device supports the formats.
    pub fn texel_inputs(&self) -> bool {
        self.texel
    }

    /// Chooses how conv layers read their inputs (see [`UNet::texel_inputs`]);
    /// turning texel inputs on where the device lacks them is an error. The
    /// two paths compute the same sums (benchmarks and tests compare them).
    pub fn set_texel_inputs(&mut self, on: bool) -> Result<()> {
        if on && !self.convs.keys().any(|k| k.6) {
            return Err(Error::unsupported("this device cannot read U-Net activations through uniform texel buffers"));
        }
        self.texel = on;
        Ok(())
    }

    /// The conv path this network runs now ([`ConvPath`]; Winograd with
    /// one-pixel fetches reads as its tile's path).
    pub fn conv_path(&self) -> ConvPath {
        match (self.texel, self.winograd, self.vec4) {
            (false, ..) => ConvPath::Address,
            (true, Some(WinogradTile::F4x4), _) => ConvPath::Winograd,
            (true, Some(WinogradTile::F2x2), _) => ConvPath::Winograd2,
            (true, None, true) => ConvPath::Vec4,
            (true, None, false) => ConvPath::Texel,
        }
    }

    /// Whether texel-input layers read four pixels per fetch (RGBA views)
    /// where their input width is a multiple of 4 (`vec4_fits`); other
    /// layers read one pixel per fetch. On by default where the device has
    /// the formats and the default path reads four ([`ConvPath::default_for`]).
    pub fn vec4_inputs(&self) -> bool {
        self.vec4
    }

    /// Chooses whether texel-input layers read four pixels per fetch (see
    /// [`UNet::vec4_inputs`]); on where the device lacks RGBA views is an error.
    pub fn set_vec4_inputs(&mut self, on: bool) -> Result<()> {
        if on && !self.convs.keys().any(|k| k.7) {
            return Err(Error::unsupported("this device cannot view U-Net activations as RGBA texel buffers"));
        }
        self.vec4 = on;
        Ok(())
    }

    /// The architecture.
    pub fn config(&self) -> &UNetConfig {
        &self.config
    }

    /// Fill the arena and the output with this 32-bit word before each pass
    /// (tests use NaN, so a value no kernel wrote cannot pass).
    pub fn set_prefill(&mut self, word: Option<u32>) {
        self.prefill = word;
    }

    /// Bytes of the arena held now (0 before the first pass); it grows only
    /// when a larger input needs it.
    pub fn arena_capacity(&self) -> u64 {
        self.arena.as_ref().map_or(0, Buffer::size)
    }

    /// Bytes of the activation arena for an input size.
    pub fn arena_bytes(&self, width: u32, height: u32) -> u64 {
        ArenaLayout::new(&self.config, width as usize, height as usize, self.precision).total
    }

    /// How activations are stored.
    pub fn precision(&self) -> StoragePrecision {
        self.precision
    }

    /// GPU bytes of the packed weights.
    pub fn weight_bytes(&self) -> u64 {
        self.weights.iter().flatten().map(|l| l.passes.iter().map(Buffer::size).sum::<u64>() + l.bias.size()).sum()
    }

    /// Predicts L_ind (CHW, 3 × pixels) from the deferred buffers: packs the
    /// input in [`DEFAULT_INPUT_ORDER`], then runs the network. Refuses a
    /// network whose metadata asks for another input order.
    pub fn predict(&mut self, inputs: &NetworkInputs<'_>) -> Result<UNetOutput> {
        if self.config.input_order.iter().map(String::as_str).ne(DEFAULT_INPUT_ORDER) || self.config.out_channels != 3 {
            return Err(Error::invalid(
                format!(
                    "network with inputs [{}] and {} outputs",
                    self.config.input_order.join(","),
                    self.config.out_channels
                ),
                format!("the shading stage feeds {} and reads 3 output channels", DEFAULT_INPUT_ORDER.join(",")),
            ));
        }
        let g = inputs.gbuffer;
        let (normal, albedo) = match (g.get(Channel::Normal), g.get(Channel::Albedo)) {
            (Some(n), Some(a)) => (n, a),
            _ => {
                return Err(Error::invalid(
                    "G-buffer",
                    "lacks the normal and albedo channels the indirect network needs",
                ))
            }
        };
        let pixels = u64::from(g.width) * u64::from(g.height);
        if inputs.sun.size() < pixels * 12 || inputs.sky.size() < pixels * 12 {
            return Err(Error::invalid("L_sun or L_sky buffer", "is smaller than the image"));
        }
        let packed = self.device.create_buffer("u-net input", pixels * 14 * 4, MemoryKind::Storage)?;
        let pixel_count =
            u32::try_from(pixels).map_err(|_| Error::invalid(format!("image of {pixels} pixels"), "is too large"))?;
        let pack = &self.pack;
        let mut timings = self.device.run(|rec| -> Result<()> {
            let push = PackPush {
                normal: rec.addr(normal)?,
                albedo: rec.addr(albedo)?,
                roughness: rec.addr_or_null(g.get(Channel::Roughness))?,
                metallic: rec.addr_or_null(g.get(Channel::Metallic))?,
                alpha: rec.addr(&g.alpha)?,
                sun: rec.addr(inputs.sun)?,
                sky: rec.addr(inputs.sky)?,
                o: rec.addr(&packed)?,
                pixels: pixel_count,
                min_alpha: inputs.min_alpha,
            };
            rec.begin_stage("indirect input");
            rec.dispatch(pack, Grid::Items(pixels), &[], &push)?;
            rec.end_stage();
            Ok(())
        })?;
        let out = self.infer(&packed, g.width, g.height)?;
        timings.stages.extend(out.timings.stages);
        Ok(UNetOutput { output: out.output, timings, ..out })
    }

    /// Runs the network on `input` (CHW float32, `in_channels` × `height` × `width`).
    pub fn infer(&mut self, input: &Buffer, width: u32, height: u32) -> Result<UNetOutput> {
        let c = self.config.clone();
        let (w, h) = (width as usize, height as usize);
        if w == 0 || h == 0 || w > 16384 || h > 16384 {
            return Err(Error::invalid(format!("U-Net input size {width}x{height}"), "is outside 1..=16384"));
        }
        if input.size() < (c.in_channels * w * h * 4) as u64 {
            return Err(Error::invalid(
                format!("U-Net input buffer of {} bytes", input.size()),
                format!(
                    "is smaller than {} channels at {width}x{height} need ({})",
                    c.in_channels,
                    c.in_channels * w * h * 4
                ),
            ));
        }
        // Winograd runs only on texel inputs (else the layers fall back to direct convolution).
        if let Some(tile) = self.winograd.filter(|_| self.texel) {
            self.build_winograd_kernels(tile, w, h)?;
        }
        let layout = ArenaLayout::new(&c, w, h, self.precision);
        let need = layout.total;
        if self.arena.as_ref().is_none_or(|a| a.size() < need) {
            self.arena = None;
            self.arena = Some(self.device.create_buffer("u-net arena", need, MemoryKind::Storage)?);
        }
        let arena = self.arena.as_ref().ok_or_else(|| Error::Internal("U-Net inference without an arena".into()))?;
        let output =
            self.device.create_buffer("u-net output", (c.out_channels * w * h * 4) as u64, MemoryKind::Storage)?;
        let s = level_sizes(w, h);
        let size = |l: usize| [s[l].0 as u32, s[l].1 as u32];
        let half = self.precision == StoragePrecision::Fp16;
        let convs = &self.convs;
        let kernel = |i: usize, texel: bool, vec4: bool| {
            convs
                .get(&Self::conv_key(&c, i, half, texel, vec4, self.weight_lanes))
                .ok_or_else(|| Error::Internal("a U-Net kernel variant was not built".into()))
        };
        let max_groups = self.device.info().max_workgroup_count;
        let names = layers(&c);
        let weights = &self.weights;
        let winograd = |i: usize, vec4: bool| -> Option<(WinogradTile, &Kernel, &Buffer)> {
            let (tile, weights) = self.winograd_weights.as_ref().filter(|(t, _)| Some(*t) == self.winograd)?;
            let k = self.winograd_kernels.get(&self.winograd_key(*tile, i, half, vec4))?;
            Some((*tile, k, weights.get(i)?.as_ref()?))
        };
        let upsample = &self.upsample;
        let upsample_texel = self.upsample_texel.as_ref().filter(|_| self.texel);
        let prefill = self.prefill;
        let wd = c.widths;
        // inc, the four downsamplings, the four up stages (resized ++ skip), outc.
        let arena_src = |offset: u64| Src { offset, input: false, half };
        let none = Src { offset: 0, input: true, half: false };
        let mut steps = vec![Step {
            layer: 0,
            a: none,
            ca: c.in_channels,
            b: none,
            cb: 0,
            lin: 0,
            lout: 0,
            out: Some(layout.f[0]),
        }];
        for l in 1..5 {
            let (a, ca, out) = (arena_src(layout.f[l - 1]), wd[l - 1], Some(layout.f[l]));
            steps.push(Step { layer: l, a, ca, b: none, cb: 0, lin: l - 1, lout: l, out });
        }
        for k in 0..4 {
            let level = 3 - k;
            steps.push(Step {
                layer: 5 + k,
                a: arena_src(layout.resized),
                ca: wd[level + 1],
                b: arena_src(layout.f[level]),
                cb: wd[level],
                lin: level,
                lout: level,
                out: Some(layout.u[k]),
            });
        }
        steps.push(Step { layer: 9, a: arena_src(layout.u[3]), ca: wd[0], b: none, cb: 0, lin: 0, lout: 0, out: None });
        let max_texels = self.device.info().max_texel_buffer_elements;
        let texel = self.texel;
        // An input as a texel-buffer view: one element per texel, or four consecutive ones (`four`;
        // `elements` a multiple of 4 then).
        let view = |src: Src, elements: usize, four: bool| Texels {
            buffer: if src.input { input } else { arena },
            offset: src.offset,
            elements: (if four { elements / 4 } else { elements }) as u64,
            format: match (src.half, four) {
                (false, false) => TexelFormat::R32Float,
                (true, false) => TexelFormat::R16Float,
                (false, true) => TexelFormat::Rgba32Float,
                (true, true) => TexelFormat::Rgba16Float,
            },
        };
        // What each up layer resizes first: (source address, channels, source level).
        let resize_from = [
            (arena_src(layout.f[4]), wd[4], 4),
            (arena_src(layout.u[0]), wd[3], 3),
            (arena_src(layout.u[1]), wd[2], 2),
            (arena_src(layout.u[2]), wd[1], 1),
        ];
        let mut vec4_layers = Vec::new();
        let mut exact_resizes = Vec::new();
        let upsample_exact2 = self.upsample_exact2.as_ref().filter(|_| self.texel && self.vec4);
        let timings = self.device.run(|rec| {
            // Every address the kernels follow, through the recording that keeps its buffer alive.
            macro_rules! address {
                ($src:expr) => {
                    if $src.input {
                        rec.addr_at(input, $src.offset)?
                    } else {
                        rec.addr_at(arena, $src.offset)?
                    }
                };
            }
            if let Some(word) = prefill {
                rec.fill(arena, word)?;
                rec.fill(&output, word)?;
            }
            for &Step { layer: li, a, ca, b, cb, lin, lout, out } in &steps {
                let out = match out {
                    Some(offset) => rec.addr_at(arena, offset)?,
                    None => rec.addr(&output)?,
                };
                let (name, _, co, _) = names[li];
                if (5..9).contains(&li) {
                    let (src, ch, from) = resize_from[li - 5];
                    let push = UpsamplePush {
                        src: address!(src),
                        dst: rec.addr_at(arena, layout.resized)?,
                        in_size: size(from),
                        out_size: size(lout),
                        channels: ch as u32,
                        align_corners: u32::from(c.align_corners),
                    };
                    rec.begin_stage(&format!("{name} resize"));
                    let four = resize_four(s[lout].0);
                    // x along the workgroup (four pixels per invocation with `four`), a row per grid y, a
                    // channel per grid z.
                    let per_group = if four { 256 } else { 64 };
                    let grid = [s[lout].0.div_ceil(per_group) as u32, s[lout].1 as u32, ch as u32];
                    if grid[1] > max_groups[1] || grid[2] > max_groups[2] {
                        return Err(Error::invalid(
                            format!("{name} resize"),
                            format!("{grid:?} workgroups exceed the device's limits"),
                        ));
                    }
                    let elements = ch * s[from].0 * s[from].1;
                    let k = usize::from(four);
                    let fits = elements as u64 <= max_texels;
                    let exact = upsample_exact2.filter(|_| fits && resize_exact2(s[from], s[lout], c.align_corners));
                    match (exact, upsample_texel.filter(|_| fits)) {
                        (Some(kernel), _) => {
                            // Four source pixels per invocation along x, a source row per grid y.
                            exact_resizes.push(name);
                            let grid = [(s[from].0 / 4).div_ceil(64) as u32, s[from].1 as u32, ch as u32];
                            rec.dispatch(
                                kernel,
                                Grid::Exact(grid),
                                &[Binding::Texels(view(src, elements, true))],
                                &push,
                            )?
                        }
                        (None, Some(ks)) => rec.dispatch(
                            &ks[k],
                            Grid::Exact(grid),
                            &[Binding::Texels(view(src, elements, false))],
                            &push,
                        )?,
                        (None, None) => rec.dispatch(&upsample[k], Grid::Exact(grid), &[], &push)?,
                    }
                    rec.end_stage();
                }
                let in_plane = s[lin].0 * s[lin].1;
                let cin = ca + cb;
                // Texel-buffer views where the device has them and both inputs and the weights fit one view.
                let weight_texels = texel_weight_floats(cin, co) / 4;
                let use_texel =
                    texel && (ca.max(cb) * in_plane) as u64 <= max_texels && weight_texels as u64 <= max_texels;
                let layer = &weights[usize::from(use_texel)][li];
                let use_vec4 = use_texel && self.vec4 && vec4_fits(s[lin].0);
                // Winograd (a row of tiles × a channel block per invocation, four pixels per fetch where
                // the width allows: every row of tiles starts on a texel) where chosen and its weights fit
                // a view, else direct convolution (a pixel block × channel block per invocation).
                let wino = winograd(li, use_vec4)
                    .filter(|_| use_texel)
                    .map(|(tile, k, u)| (tile, k, u, winograd::winograd_weight_texels(tile, cin, co)))
                    .filter(|(.., texels)| *texels as u64 <= max_texels);
                let (k, invocations, ob) = match wino {
                    Some((tile, k, ..)) => (
                        k,
                        s[lout].0.div_ceil(tile.edge()).div_ceil(tile.tiles_per_invocation())
                            * s[lout].1.div_ceil(tile.edge()),
                        channel_block(co, true),
                    ),
                    None => (
                        &**kernel(li, use_texel, use_vec4)?,
                        s[lout].0.div_ceil(if use_vec4 { vec4_pixel_block(co) } else { pixel_block(co, use_texel) })
                            * s[lout].1,
                        channel_block(co, use_texel),
                    ),
                };
                let groups = invocations.div_ceil(64) as u32;
                // Output blocks vary fastest: consecutive workgroups read the same input rows.
                let gz = groups.div_ceil(max_groups[1]);
                let grid = [co.div_ceil(ob) as u32, groups.div_ceil(gz), gz];
                if grid[0] > max_groups[0] || grid[2] > max_groups[2] {
                    return Err(Error::invalid(
                        name.to_string(),
                        format!("{grid:?} workgroups exceed the device's limits"),
                    ));
                }
                // Four pixels per fetch, by Winograd or direct convolution.
                if use_vec4 {
                    vec4_layers.push(name);
                }
                rec.begin_stage(name);
                let last = layer.passes.len() - 1;
                for (pass, ubo) in layer.passes.iter().enumerate() {
                    let push = ConvPush {
                        a: address!(a),
                        b: if cb > 0 { address!(b) } else { DeviceAddress::NULL },
                        o: out,
                        partial: rec.addr_at(arena, layout.partial)?,
                        ca: ca as u32,
                        cb: cb as u32,
                        oc: co as u32,
                        ic0: (pass * layer.chunk) as u32,
                        ic1: ((pass + 1) * layer.chunk).min(cin) as u32,
                        flags: u32::from(pass == 0) | u32::from(pass == last) << 1,
                        in_size: size(lin),
                        out_size: size(lout),
                    };
                    if use_texel {
                        // A layer without a skip binds A's view twice; the kernel never reads B then.
                        let vb =
                            if cb > 0 { view(b, cb * in_plane, use_vec4) } else { view(a, ca * in_plane, use_vec4) };
                        // The texel path has one pass, so Winograd's weights replace it.
                        let (buffer, elements) = wino.map_or((ubo, weight_texels), |(_, _, u, t)| (u, t));
                        let weights =
                            Texels { buffer, offset: 0, elements: elements as u64, format: TexelFormat::Rgba32Float };
                        let bound = [
                            Binding::Texels(weights),
                            Binding::Buffer(&layer.bias),
                            Binding::Texels(view(a, ca * in_plane, use_vec4)),
                            Binding::Texels(vb),
                        ];
                        rec.dispatch(k, Grid::Exact(grid), &bound, &push)?;
                    } else {
                        rec.dispatch(k, Grid::Exact(grid), &[Binding::from(ubo), Binding::from(&layer.bias)], &push)?;
                    }
                }
                rec.end_stage();
            }
            Ok(())
        })?;
        Ok(UNetOutput { output, timings, vec4_layers, exact_resizes })
    }
}
