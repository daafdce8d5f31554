//! Tile-sorted splatting: the forward renderer and its G-buffers.
//!
//! Stages (each a kernel in `spirv/shaders/splat_*.comp`, each timed):
//! 1. **preprocess**, one invocation per Gaussian: activation, near/far
//!    culling, 3D covariance, EWA projection with the Jacobian clamped beyond
//!    the image, +0.3 px² dilation, culling of degenerate and non-finite
//!    values, conic, radius 3·sqrt(λ_max), SH colour, tile rectangle and
//!    the count of its tiles that can see the splat ([`TileBounds`])
//!    (reading the scene through R32F texel-buffer views where the device has
//!    them: [`Splatter::texel_preprocess`]);
//! 2. **scan** of per-Gaussian tile counts, then **keys**: one
//!    `tile << 32 | depth bits` key per (Gaussian, tile) counted;
//! 3. **sort**: the stable radix sort over the bits in use only;
//! 4. **ranges**: each tile's slice of the sorted pairs;
//! 5. **blend**: per-pixel front-to-back blending into the requested channels.
//!
//! Conventions follow the INRIA and gsplat rasterizers (docs/conventions.md §3): pixel
//! centres at +0.5, α = min(0.99, o·exp(−σ)), skip α < 1/255, stop when
//! T·(1−α) < 1e-4. rgb is composited over the background; every other blended
//! channel is Σ wᵢ xᵢ (premultiplied by alpha; divide by alpha for the mean).
//! [`cpu`] is the f64 twin of every stage.

pub mod backward;
pub mod cpu;
pub mod cpu_backward;

use std::sync::Arc;

use bytemuck::{Pod, Zeroable};

use crate::error::{Error, Result};
use crate::gpu::{
    kernels, Binding, BindingKind, Buffer, Device, DeviceAddress, Kernel, KernelDecl, MemoryKind, Recording, SpecValue,
    TexelFormat, Texels, Timings,
};
use crate::primitives::scan::Scan;
use crate::primitives::sort::RadixSort;
use crate::scene::activate::GpuScene;
use crate::scene::{Camera, Projection};

/// The default tile edge in pixels ([`SplatSettings::tile`]).
pub const DEFAULT_TILE: u32 = 16;
/// Tile edges the kernels accept. The edge sets the blend's workgroup (one
/// invocation per pixel, edge² of them), so it trades per-tile overhead and
/// pairs sorted (smaller tiles: more pairs, tighter lists) against wasted
/// work at splat edges (larger tiles: longer lists).
pub const TILE_SIZES: [u32; 3] = [8, 16, 32];
/// The `constant_id`s that carry the tile edge: the per-tile kernels'
/// `local_size_x_id` and `local_size_y_id` (`common.glsl`, `TILE_WORKGROUP`);
/// the preprocess reads the first as `TILE` (keep in sync).
pub const TILE_SPEC_IDS: [u32; 2] = [15, 16];

/// Checks a tile edge against [`TILE_SIZES`].
pub fn check_tile(tile: u32) -> Result<()> {
    if TILE_SIZES.contains(&tile) {
        Ok(())
    } else {
        Err(Error::invalid(format!("tile size {tile}"), format!("is not one of {TILE_SIZES:?}")))
    }
}

/// The tile-edge specialization of a per-tile kernel.
pub(crate) fn tile_spec(tile: u32) -> [(u32, SpecValue); 2] {
    [(TILE_SPEC_IDS[0], SpecValue::U32(tile)), (TILE_SPEC_IDS[1], SpecValue::U32(tile))]
}
/// Pixels per invocation the texel-buffer blend accepts ([`Splatter::set_blend_pixels`]):
/// each divides every tile edge of [`TILE_SIZES`].
pub const BLEND_PIXELS: [u32; 3] = [1, 2, 4];
/// The default pixels per invocation of the texel-buffer blend.
pub const DEFAULT_BLEND_PIXELS: u32 = 2;
/// Bit of the blend's `CHANNELS` specialization constant that blends rgb
/// (keep in sync with `RGB` in `splat_blend_body.glsl`).
pub const RGB_BIT: u32 = 8;
/// Why a G-buffer has no rgb to give.
const NO_RGB: &str = "this G-buffer has no rgb channel (it was splatted with SplatSettings::rgb off)";
/// Bytes of one projected splat (keep in sync with `Splat` in `splat.glsl`).
pub const SPLAT_BYTES: u64 = 64;
/// Bytes of one splat's features (three vec4).
pub const FEATURE_BYTES: u64 = 48;

/// Which G-buffer channels to blend besides rgb and alpha (alpha always
/// produced, rgb unless [`SplatSettings::rgb`] is off).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Channels {
    /// Expected depth Σ wᵢ zᵢ.
    pub depth: bool,
    /// Depth where transmittance first falls to 0.5.
    pub median_depth: bool,
    /// World-space normal Σ wᵢ nᵢ.
    pub normal: bool,
    /// Albedo.
    pub albedo: bool,
    /// Roughness.
    pub roughness: bool,
    /// Metallic.
    pub metallic: bool,
    /// Ambient occlusion.
    pub ao: bool,
    /// Fixed sun visibility.
    pub visibility: bool,
}

impl Channels {
    /// Every channel.
    pub const ALL: Channels = Channels {
        depth: true,
        median_depth: true,
        normal: true,
        albedo: true,
        roughness: true,
        metallic: true,
        ao: true,
        visibility: true,
    };

    /// The `CHANNELS` specialization constant of `splat_blend.comp`, less
    /// its rgb bit ([`RGB_BIT`], from [`SplatSettings::rgb`]).
    pub fn bits(&self) -> u32 {
        [
            self.depth,
            self.median_depth,
            self.normal,
            self.albedo,
            self.roughness,
            self.metallic,
            self.ao,
            self.visibility,
        ]
        .iter()
        .enumerate()
        .map(|(i, on)| u32::from(*on) << i)
        .sum()
    }

    /// The inverse of [`Channels::bits`] (bits above 7 are ignored).
    pub fn from_bits(bits: u32) -> Self {
        let on = |i: u32| bits & (1 << i) != 0;
        Channels {
            depth: on(0),
            median_depth: on(1),
            normal: on(2),
            albedo: on(3),
            roughness: on(4),
            metallic: on(5),
            ao: on(6),
            visibility: on(7),
        }
    }

    /// The whole `CHANNELS` specialization constant: [`Channels::bits`] plus
    /// the rgb bit when colour is blended.
    pub fn blend_bits(&self, rgb: bool) -> u32 {
        self.bits() | u32::from(rgb) << RGB_BIT
    }

    /// Whether per-splat features (normal or materials) are needed.
    pub fn needs_features(&self) -> bool {
        self.bits() & 0b1111_1100 != 0
    }

    /// Parses a comma-separated list (`rgb` and `alpha` are accepted: alpha is
    /// always on, rgb is [`SplatSettings::rgb`], see [`Channels::names_rgb`];
    /// `materials` means albedo, roughness, metallic, ao and visibility; `all` everything).
    pub fn parse(list: &str) -> Result<Self> {
        let mut c = Channels::default();
        for item in list.split(',').map(str::trim).filter(|s| !s.is_empty()) {
            match item {
                "rgb" | "alpha" => {}
                "depth" => c.depth = true,
                "median_depth" | "median" => c.median_depth = true,
                "normal" => c.normal = true,
                "albedo" => c.albedo = true,
                "roughness" => c.roughness = true,
                "metallic" => c.metallic = true,
                "ao" => c.ao = true,
                "visibility" => c.visibility = true,
                "materials" => {
                    c = Channels { albedo: true, roughness: true, metallic: true, ao: true, visibility: true, ..c }
                }
                "all" => c = Channels::ALL,
                other => {
                    return Err(Error::invalid(
                        format!("channel \"{other}\""),
                        "is unknown (rgb, alpha, depth, median_depth, normal, albedo, roughness, metallic, ao, \
                         visibility, materials, all)",
                    ))
                }
            }
        }
        Ok(c)
    }

    /// Whether a list [`Channels::parse`] accepts names rgb (`rgb` or `all`):
    /// for callers that blend colour only when asked (`srug render` to EXR).
    pub fn names_rgb(list: &str) -> bool {
        list.split(',').map(str::trim).any(|s| s == "rgb" || s == "all")
    }
}

/// How the blend kernel reads splats; all give the same image.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum BlendVariant {
    /// Each invocation loads every splat of its tile (`splat_blend_portable.comp`).
    PerPixel,
    /// One load per subgroup, broadcast to the others (`splat_blend.comp`); needs
    /// subgroup ballot. The default where available (the faster on lavapipe).
    #[default]
    SubgroupLoads,
    /// Splats staged in shared-memory batches of 256 with whole-tile early exit
    /// (`splat_blend_batched.comp`): the classic GPU design, barrier-heavy.
    SharedBatches,
}

impl BlendVariant {
    /// Parses `per-pixel`, `subgroup` or `batched`.
    pub fn parse(text: &str) -> Result<Self> {
        match text {
            "per-pixel" => Ok(Self::PerPixel),
            "subgroup" => Ok(Self::SubgroupLoads),
            "batched" => Ok(Self::SharedBatches),
            other => Err(Error::invalid(format!("blend variant \"{other}\""), "is not per-pixel, subgroup or batched")),
        }
    }
}

/// Where splat normals come from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum NormalSource {
    /// Each Gaussian's shortest axis.
    #[default]
    ShortestAxis,
    /// The stored normal where present and non-zero, else the shortest axis.
    Stored,
}

/// Which tiles list a splat.
///
/// Both give the same image at every pixel centre (and at every point of a
/// tile for α ≥ 1/255 tests): a tile [`TileBounds::Ellipse`] leaves out could
/// only have seen the splat below 1/255, which the blend skips. They differ in
/// cost only.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum TileBounds {
    /// The tiles of the 3σ rectangle whose square meets the ellipse where the
    /// splat reaches α ≥ 1/255, o·exp(−σ) ≥ 1/255 (widened slightly so that
    /// f32 rounding never drops a contribution). Fewer pairs to key, sort and
    /// blend: 17–43% fewer on the demo city, more where opacities are low.
    #[default]
    Ellipse,
    /// Every tile of the 3σ square rectangle, as INRIA's rasterizer lists them.
    Rectangle,
}

impl std::str::FromStr for TileBounds {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "ellipse" => Ok(Self::Ellipse),
            "rectangle" => Ok(Self::Rectangle),
            other => Err(Error::invalid(format!("tile bounds \"{other}\""), "are not ellipse or rectangle")),
        }
    }
}

/// What to render.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SplatSettings {
    /// Background colour behind rgb.
    pub background: [f32; 3],
    /// Channels besides rgb and alpha.
    pub channels: Channels,
    /// Where normals come from.
    pub normal_source: NormalSource,
    /// Fill every output with this 32-bit word before blending (tests use NaN,
    /// so a pixel the kernel never wrote cannot pass for a value).
    pub prefill: Option<u32>,
    /// Spherical-harmonic degree evaluated for colour, at most the scene's
    /// (`None`: the scene's). Lower degrees drop view-dependent terms for speed.
    pub sh_degree: Option<u32>,
    /// Tile edge in pixels, one of [`TILE_SIZES`]. Splats are listed per tile
    /// out to 3σ, so pixels see a splat's tail out to the tile's edge: the
    /// image changes slightly (far below 1/255) with the tile, the cost more.
    pub tile: u32,
    /// Which tiles list a splat.
    pub tile_bounds: TileBounds,
    /// Blend colour (rgb). Off, the G-buffer has no rgb channel, the
    /// preprocess evaluates no view-dependent colour and the blend reads no
    /// colour: for depth-only renders such as shadow maps, where colour is
    /// a quarter of the blend's reads. Alpha and the other channels are the same.
    pub rgb: bool,
}

impl Default for SplatSettings {
    fn default() -> Self {
        Self {
            background: [0.0; 3],
            channels: Channels::default(),
            normal_source: NormalSource::default(),
            prefill: None,
            sh_degree: None,
            tile: DEFAULT_TILE,
            tile_bounds: TileBounds::default(),
            rgb: true,
        }
    }
}

/// G-buffers on the host; planar per channel, row-major, rgb/normal/albedo interleaved by 3.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct GBuffer {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Colour over the background, 3 floats per pixel (absent where
    /// [`SplatSettings::rgb`] was off).
    pub rgb: Option<Vec<f32>>,
    /// 1 − final transmittance.
    pub alpha: Vec<f32>,
    /// Σ wᵢ zᵢ.
    pub depth: Option<Vec<f32>>,
    /// Depth where T first falls to 0.5 (0 where it never does).
    pub median_depth: Option<Vec<f32>>,
    /// Σ wᵢ nᵢ, 3 floats per pixel.
    pub normal: Option<Vec<f32>>,
    /// Σ wᵢ albedoᵢ, 3 floats per pixel.
    pub albedo: Option<Vec<f32>>,
    /// Σ wᵢ roughnessᵢ.
    pub roughness: Option<Vec<f32>>,
    /// Σ wᵢ metallicᵢ.
    pub metallic: Option<Vec<f32>>,
    /// Σ wᵢ aoᵢ.
    pub ao: Option<Vec<f32>>,
    /// Σ wᵢ visibilityᵢ.
    pub visibility: Option<Vec<f32>>,
}

impl GBuffer {
    /// Writes every channel as 32-bit float channels of one EXR layer (R, G,
    /// B, A, Z, median_depth.Y, normal.X/Y/Z, albedo.R/G/B, roughness.Y, ...).
    pub fn write_exr(&self, path: impl AsRef<std::path::Path>) -> Result<()> {
        crate::io::write_exr_channels(path.as_ref(), self.width, self.height, &self.channels())
    }

    /// The rgb channel, or an error naming why it is absent.
    pub fn rgb_values(&self) -> Result<&[f32]> {
        self.rgb.as_deref().ok_or_else(|| Error::invalid("rgb channel", NO_RGB))
    }

    /// The channels present as (name, values, floats per pixel), rgb (when
    /// blended) and alpha first.
    pub fn channels(&self) -> Vec<(&'static str, &[f32], usize)> {
        let mut out: Vec<_> = self.rgb.as_deref().map(|v| ("rgb", v, 3)).into_iter().collect();
        out.push(("alpha", self.alpha.as_slice(), 1));
        let optional: [(&'static str, &Option<Vec<f32>>, usize); 8] = [
            ("depth", &self.depth, 1),
            ("median_depth", &self.median_depth, 1),
            ("normal", &self.normal, 3),
            ("albedo", &self.albedo, 3),
            ("roughness", &self.roughness, 1),
            ("metallic", &self.metallic, 1),
            ("ao", &self.ao, 1),
            ("visibility", &self.visibility, 1),
        ];
        out.extend(optional.into_iter().filter_map(|(n, v, k)| v.as_deref().map(|v| (n, v, k))));
        out
    }
}

/// Frame parameters shared by every splat kernel: `Frame` in `splat.glsl`
/// (std140; checked against it by `check_layout`). The camera and sizes are
/// set on the host; every address is filled by `FrameUniform::record` in the
/// recording that dispatches with it, which keeps each buffer alive.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct FrameUniform {
    rot0: [f32; 4],
    rot1: [f32; 4],
    rot2: [f32; 4],
    translation: [f32; 4],
    intrinsics: [f32; 4],
    clip: [f32; 4],
    eye: [f32; 4],
    view_dir: [f32; 4],
    background: [f32; 4],
    size: [u32; 4],
    counts: [u32; 4],
    means: DeviceAddress,
    log_scales: DeviceAddress,
    rotations: DeviceAddress,
    opacity_logits: DeviceAddress,
    sh: DeviceAddress,
    normals: DeviceAddress,
    albedo: DeviceAddress,
    roughness: DeviceAddress,
    metallic: DeviceAddress,
    ao: DeviceAddress,
    visibility: DeviceAddress,
    splats: DeviceAddress,
    features: DeviceAddress,
    tile_counts: DeviceAddress,
    keys: DeviceAddress,
    values: DeviceAddress,
    ranges: DeviceAddress,
    g_rgb: DeviceAddress,
    pair_tiles: DeviceAddress,
    unused0: DeviceAddress,
    g_alpha: DeviceAddress,
    g_depth: DeviceAddress,
    g_median_depth: DeviceAddress,
    g_normal: DeviceAddress,
    g_albedo: DeviceAddress,
    g_roughness: DeviceAddress,
    g_metallic: DeviceAddress,
    g_ao: DeviceAddress,
    g_visibility: DeviceAddress,
    unused1: DeviceAddress,
}
crate::gpu::gpu_layout!(
    FrameUniform,
    "Frame",
    [
        rot0,
        rot1,
        rot2,
        translation,
        intrinsics,
        clip,
        eye,
        view_dir,
        background,
        size,
        counts,
        means,
        log_scales,
        rotations,
        opacity_logits,
        sh,
        normals,
        albedo,
        roughness,
        metallic,
        ao,
        visibility,
        splats,
        features,
        tile_counts,
        keys,
        values,
        ranges,
        g_rgb,
        pair_tiles,
        unused0,
        g_alpha,
        g_depth,
        g_median_depth,
        g_normal,
        g_albedo,
        g_roughness,
        g_metallic,
        g_ao,
        g_visibility,
        unused1
    ]
);

/// The buffers a splat frame's kernels reach by address.
pub(crate) struct FrameBuffers<'b> {
    pub(crate) scene: &'b GpuScene,
    pub(crate) splats: &'b Buffer,
    pub(crate) features: Option<&'b Buffer>,
    pub(crate) tile_counts: &'b Buffer,
    /// Absent before the sort's buffers exist and after they are freed.
    pub(crate) keys: Option<&'b Buffer>,
    pub(crate) values: Option<&'b Buffer>,
    pub(crate) pair_tiles: Option<&'b Buffer>,
    pub(crate) ranges: &'b Buffer,
    pub(crate) out: &'b GpuGBuffer,
}

impl FrameUniform {
    /// Takes every address from `b` through `rec` (which keeps the buffers
    /// borrowed until it is submitted) and writes the uniform into `uniform`
    /// as a recorded command.
    pub(crate) fn record<'a>(
        mut self,
        rec: &mut Recording<'a>,
        uniform: &'a Buffer,
        b: &FrameBuffers<'a>,
    ) -> Result<()> {
        let s = b.scene;
        self.means = rec.addr(&s.means)?;
        self.log_scales = rec.addr(&s.log_scales)?;
        self.rotations = rec.addr(&s.rotations)?;
        self.opacity_logits = rec.addr(&s.opacity_logits)?;
        self.sh = rec.addr(&s.sh)?;
        self.normals = rec.addr_or_null(s.normals.as_ref())?;
        self.albedo = rec.addr_or_null(s.albedo.as_ref())?;
        self.roughness = rec.addr_or_null(s.roughness.as_ref())?;
        self.metallic = rec.addr_or_null(s.metallic.as_ref())?;
        self.ao = rec.addr_or_null(s.ao.as_ref())?;
        self.visibility = rec.addr_or_null(s.visibility.as_ref())?;
        self.splats = rec.addr(b.splats)?;
        self.features = rec.addr_or_null(b.features)?;
        self.tile_counts = rec.addr(b.tile_counts)?;
        self.keys = rec.addr_or_null(b.keys)?;
        self.values = rec.addr_or_null(b.values)?;
        self.ranges = rec.addr(b.ranges)?;
        self.pair_tiles = rec.addr_or_null(b.pair_tiles)?;
        let o = b.out;
        self.g_rgb = rec.addr_or_null(o.rgb.as_ref())?;
        self.g_alpha = rec.addr(&o.alpha)?;
        self.g_depth = rec.addr_or_null(o.depth.as_ref())?;
        self.g_median_depth = rec.addr_or_null(o.median_depth.as_ref())?;
        self.g_normal = rec.addr_or_null(o.normal.as_ref())?;
        self.g_albedo = rec.addr_or_null(o.albedo.as_ref())?;
        self.g_roughness = rec.addr_or_null(o.roughness.as_ref())?;
        self.g_metallic = rec.addr_or_null(o.metallic.as_ref())?;
        self.g_ao = rec.addr_or_null(o.ao.as_ref())?;
        self.g_visibility = rec.addr_or_null(o.visibility.as_ref())?;
        Ok(rec.update(uniform, 0, &self)?)
    }
}

/// G-buffers on the GPU.
pub struct GpuGBuffer {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `float[3P]`, absent where [`SplatSettings::rgb`] was off.
    pub rgb: Option<Buffer>,
    /// `float[P]`.
    pub alpha: Buffer,
    /// Optional channels, as in [`GBuffer`].
    pub depth: Option<Buffer>,
    /// Median depth.
    pub median_depth: Option<Buffer>,
    /// Normal, `float[3P]`.
    pub normal: Option<Buffer>,
    /// Albedo, `float[3P]`.
    pub albedo: Option<Buffer>,
    /// Roughness.
    pub roughness: Option<Buffer>,
    /// Metallic.
    pub metallic: Option<Buffer>,
    /// Ambient occlusion.
    pub ao: Option<Buffer>,
    /// Visibility.
    pub visibility: Option<Buffer>,
}

impl GpuGBuffer {
    /// The rgb channel, or an error naming why it is absent.
    pub fn rgb_buffer(&self) -> Result<&Buffer> {
        self.rgb.as_ref().ok_or_else(|| Error::invalid("rgb channel", NO_RGB))
    }

    /// Reads every channel back.
    pub fn read(&self, device: &Device) -> Result<GBuffer> {
        let opt = |b: &Option<Buffer>| b.as_ref().map(|b| device.read_buffer::<f32>(b)).transpose();
        Ok(GBuffer {
            width: self.width,
            height: self.height,
            rgb: opt(&self.rgb)?,
            alpha: device.read_buffer(&self.alpha)?,
            depth: opt(&self.depth)?,
            median_depth: opt(&self.median_depth)?,
            normal: opt(&self.normal)?,
            albedo: opt(&self.albedo)?,
            roughness: opt(&self.roughness)?,
            metallic: opt(&self.metallic)?,
            ao: opt(&self.ao)?,
            visibility: opt(&self.visibility)?,
        })
    }

    /// GPU bytes held by the channels.
    pub fn bytes(&self) -> u64 {
        let opt = [
            &self.rgb,
            &self.depth,
            &self.median_depth,
            &self.normal,
            &self.albedo,
            &self.roughness,
            &self.metallic,
            &self.ao,
            &self.visibility,
        ];
        self.alpha.size() + opt.iter().filter_map(|b| b.as_ref().map(Buffer::size)).sum::<u64>()
    }
}

/// What one render did, besides its G-buffers.
#[derive(Clone, Debug, Default)]
pub struct SplatStats {
    /// Per-stage GPU times.
    pub timings: Timings,
    /// (Gaussian, tile) pairs sorted.
    pub pairs: u64,
    /// Key bits sorted.
    pub key_bits: u32,
    /// GPU bytes of per-frame working memory (splats, features, keys, sort scratch, ranges).
    pub working_bytes: u64,
}

/// One rendered frame with the per-frame buffers later stages walk again:
/// the traced shadow reference and the backward pass read the projected
/// splats, the sorted pair list and the per-tile ranges.
pub struct SplatFrame {
    /// The G-buffers.
    pub gbuffer: GpuGBuffer,
    /// What the render did.
    pub stats: SplatStats,
    /// The camera it was rendered from.
    pub camera: Camera,
    /// Projected splats, [`SPLAT_BYTES`] each (culled ones have an empty rectangle).
    pub splats: Buffer,
    /// Per-Gaussian offsets into the unsorted pair list (exclusive scan of tile counts), n + 1 values.
    pub pair_offsets: Buffer,
    /// Gaussian index of each sorted pair.
    pub sorted_gaussians: Buffer,
    /// Tile id of each unsorted pair: each Gaussian's pairs from its offset on,
    /// in increasing tile order (the keys kernel's padding last, with id = tiles).
    /// The backward pass finds a pair's gradient record by searching these.
    pub pair_tiles: Buffer,
    /// Per-tile [start, end) into the sorted pairs, `uvec2` per tile.
    pub ranges: Buffer,
    /// Per-splat features (normal, materials) when any feature channel was rendered.
    pub features: Option<Buffer>,
    /// The frame uniform (camera, sizes, every address above), for the backward
    /// pass, which rewrites its addresses in its own recording (`params`).
    pub uniform: Buffer,
    /// The uniform's camera and sizes, from which each recording that
    /// dispatches with `uniform` writes it again with its own addresses.
    pub(crate) params: FrameUniform,
    /// [`Buffer::id`] of the scene's means, to check the backward pass gets the same scene.
    pub(crate) scene_means: u64,
    /// Gaussians in the scene.
    pub(crate) gaussians: u64,
    /// Tile edge in pixels it was rendered with.
    pub tile: u32,
}

impl SplatFrame {
    /// Tiles across and down.
    pub fn tiles(&self) -> (u32, u32) {
        (self.camera.width.div_ceil(self.tile), self.camera.height.div_ceil(self.tile))
    }
}

/// The splatting pipeline: kernels (one variant per channel set, built on
/// first use) and the sort's scratch memory, reused across frames.
pub struct Splatter {
    device: Device,
    ranges: Arc<Kernel>,
    blend_variant: BlendVariant,
    texel_blend: bool,
    texel_preprocess: bool,
    blend_pixels: u32,
    scan: Scan,
    sort: RadixSort,
}

const FRAME_BINDING: [BindingKind; 1] = [BindingKind::UniformBuffer];

fn frame_kernel(
    device: &Device,
    info: &'static srug_gpu::KernelInfo,
    spec: &[(u32, SpecValue)],
) -> Result<Arc<Kernel>> {
    Ok(Kernel::cached(
        device,
        info,
        &KernelDecl { bindings: &FRAME_BINDING, push_constant_size: 0, specialization: spec },
    )?)
}

/// Camera parameters for the frame uniform.
fn camera_frame(camera: &Camera, frame: &mut FrameUniform) -> Result<()> {
    if camera.width == 0 || camera.height == 0 {
        return Err(Error::invalid(format!("image size {}x{}", camera.width, camera.height), "is empty"));
    }
    let r = camera.rotation;
    let w = r.transpose();
    let t = -(w * camera.position);
    for (row, col) in
        [&mut frame.rot0, &mut frame.rot1, &mut frame.rot2].into_iter().zip([r.x_axis, r.y_axis, r.z_axis])
    {
        *row = [col.x, col.y, col.z, 0.0];
    }
    let (kind, k, limits) = match camera.projection {
        Projection::Pinhole { fx, fy, cx, cy } => {
            (0.0, [fx, fy, cx, cy], [1.3 * 0.5 * camera.width as f32 / fx, 1.3 * 0.5 * camera.height as f32 / fy])
        }
        Projection::Orthographic { sx, sy, cx, cy } => (1.0, [sx, sy, cx, cy], [0.0, 0.0]),
    };
    frame.translation = [t.x, t.y, t.z, kind];
    frame.intrinsics = k;
    frame.clip = [camera.near, camera.far, limits[0], limits[1]];
    frame.eye = [camera.position.x, camera.position.y, camera.position.z, 0.0];
    frame.view_dir = [r.z_axis.x, r.z_axis.y, r.z_axis.z, 0.0];
    let valid = frame.translation.iter().chain(&frame.intrinsics).chain(&frame.clip).all(|v| v.is_finite());
    if !valid || camera.near.partial_cmp(&camera.far) != Some(std::cmp::Ordering::Less) {
        return Err(Error::invalid("camera", "has non-finite or inverted parameters"));
    }
    Ok(())
}

impl Splatter {
    /// Builds the fixed kernels; channel variants are built on first use.
    pub fn new(device: &Device) -> Result<Self> {
        Ok(Self {
            device: device.clone(),
            ranges: frame_kernel(device, &kernels::SPLAT_RANGES, &[])?,
            blend_variant: if device.info().subgroup_ballot {
                BlendVariant::SubgroupLoads
            } else {
                BlendVariant::PerPixel
            },
            texel_blend: [TexelFormat::Rgba32Float, TexelFormat::R32Uint]
                .iter()
                .all(|f| device.info().texel_formats.contains(f)),
            texel_preprocess: device.info().texel_formats.contains(&TexelFormat::R32Float),
            blend_pixels: DEFAULT_BLEND_PIXELS,
            scan: Scan::new(device)?,
            sort: RadixSort::new(device)?,
        })
    }

    /// Whether the subgroup-load blend reads each contribution's colour and
    /// features through texel-buffer views (where the splats fit
    /// `maxTexelBufferElements`) rather than by device address. On by default
    /// where the device has RGBA32F texel buffers; the image is the same.
    pub fn texel_blend(&self) -> bool {
        self.texel_blend
    }

    /// Chooses how the subgroup-load blend reads colour and features (see
    /// [`Splatter::texel_blend`]); on where the device lacks the views is an error.
    pub fn set_texel_blend(&mut self, on: bool) -> Result<()> {
        let formats = [TexelFormat::Rgba32Float, TexelFormat::R32Uint];
        if on && !formats.iter().all(|f| self.device.info().texel_formats.contains(f)) {
            return Err(Error::unsupported("this device cannot read splats through RGBA32F/R32UI texel buffers"));
        }
        self.texel_blend = on;
        Ok(())
    }

    /// Whether the preprocess reads the Gaussians' means, log-scales,
    /// rotations, opacity logits and SH coefficients through R32F texel-buffer
    /// views (where each array fits `maxTexelBufferElements`) rather than by
    /// device address. On by default where the device has R32F texel buffers;
    /// the splats are the same.
    pub fn texel_preprocess(&self) -> bool {
        self.texel_preprocess
    }

    /// Chooses how the preprocess reads the scene (see
    /// [`Splatter::texel_preprocess`]); on where the device lacks R32F views is an error.
    pub fn set_texel_preprocess(&mut self, on: bool) -> Result<()> {
        if on && !self.device.info().texel_formats.contains(&TexelFormat::R32Float) {
            return Err(Error::unsupported("this device cannot read the scene through R32F texel buffers"));
        }
        self.texel_preprocess = on;
        Ok(())
    }

    /// Pixels each invocation of the texel-buffer blend shades ([`BLEND_PIXELS`]).
    pub fn blend_pixels(&self) -> u32 {
        self.blend_pixels
    }

    /// Sets the pixels per invocation of the texel-buffer blend, one of
    /// [`BLEND_PIXELS`]; the image does not change, only how the fetches are shared.
    pub fn set_blend_pixels(&mut self, pixels: u32) -> Result<()> {
        if !BLEND_PIXELS.contains(&pixels) {
            return Err(Error::invalid(
                format!("{pixels} pixels per blend invocation"),
                format!("is not one of {BLEND_PIXELS:?}"),
            ));
        }
        self.blend_pixels = pixels;
        Ok(())
    }

    /// The blend variant in use (subgroup loads where the device has subgroup
    /// ballot, else per-pixel loads).
    pub fn blend_variant(&self) -> BlendVariant {
        self.blend_variant
    }

    /// Chooses the blend variant; subgroup loads need subgroup ballot support.
    pub fn set_blend_variant(&mut self, variant: BlendVariant) -> Result<()> {
        if variant == BlendVariant::SubgroupLoads && !self.device.info().subgroup_ballot {
            return Err(Error::unsupported("subgroup ballot in compute shaders"));
        }
        self.blend_variant = variant;
        Ok(())
    }

    /// The blend kernel for channel bits `bits`, `tile` and the texel path,
    /// from the device's kernel cache.
    fn blend_kernel(&self, bits: u32, tile: u32, texel: bool) -> Result<Arc<Kernel>> {
        let pixels = if texel { self.blend_pixels } else { 1 };
        let info = match (self.blend_variant, texel) {
            (BlendVariant::PerPixel, _) => &kernels::SPLAT_BLEND_PORTABLE,
            (BlendVariant::SubgroupLoads, false) => &kernels::SPLAT_BLEND,
            (BlendVariant::SubgroupLoads, true) => &kernels::SPLAT_BLEND_TEXEL,
            (BlendVariant::SharedBatches, _) => &kernels::SPLAT_BLEND_BATCHED,
        };
        let mut spec = vec![(0, SpecValue::U32(bits))];
        spec.extend(tile_spec(tile));
        if self.blend_variant == BlendVariant::SharedBatches {
            // 36 bytes of shared memory per staged splat: at most 256 (9 KiB).
            spec.push((1, SpecValue::U32((tile * tile).min(256))));
        }
        if texel {
            // PIXELS per invocation along x: TILE / PIXELS invocations across.
            spec[1].1 = SpecValue::U32(tile / pixels);
            spec.push((2, SpecValue::U32(pixels)));
            // The frame; splats, features and sorted indices as texel-buffer views.
            let mut bindings = vec![BindingKind::UniformBuffer];
            bindings.extend([BindingKind::UniformTexelBuffer; 3]);
            Ok(Kernel::cached(
                &self.device,
                info,
                &KernelDecl { bindings: &bindings, push_constant_size: 0, specialization: &spec },
            )?)
        } else {
            frame_kernel(&self.device, info, &spec)
        }
    }

    /// Renders `scene` from `camera` into new G-buffers.
    pub fn render(
        &mut self,
        scene: &GpuScene,
        camera: &Camera,
        settings: &SplatSettings,
    ) -> Result<(GpuGBuffer, SplatStats)> {
        let frame = self.render_frame(scene, camera, settings)?;
        Ok((frame.gbuffer, frame.stats))
    }

    /// Renders like [`Splatter::render`] and keeps the per-frame buffers.
    pub fn render_frame(&mut self, scene: &GpuScene, camera: &Camera, settings: &SplatSettings) -> Result<SplatFrame> {
        let device = self.device.clone();
        let ch = settings.channels;
        let missing = [
            (ch.albedo, &scene.albedo, "albedo"),
            (ch.roughness, &scene.roughness, "roughness"),
            (ch.metallic, &scene.metallic, "metallic"),
            (ch.ao, &scene.ao, "ao"),
            (ch.visibility, &scene.visibility, "visibility"),
        ];
        if let Some((_, _, name)) = missing.iter().find(|(want, have, _)| *want && have.is_none()) {
            return Err(Error::invalid(
                format!("channel {name}"),
                format!("was requested but the scene has no {name}"),
            ));
        }
        let tile = settings.tile;
        check_tile(tile)?;
        let features = ch.needs_features();
        let n = scene.count as u64;
        if n >= u64::from(u32::MAX) {
            return Err(Error::invalid(format!("scene of {n} Gaussians"), "exceeds the 2³² − 1 the kernels index"));
        }
        // The scene arrays the texel preprocess views (binding 1 on), each as R32F.
        let scene_inputs = [&scene.means, &scene.log_scales, &scene.rotations, &scene.opacity_logits, &scene.sh];
        let max_texels = device.info().max_texel_buffer_elements;
        let texel_preprocess =
            self.texel_preprocess && n > 0 && scene_inputs.iter().all(|b| b.size() / 4 <= max_texels);
        let bounds = settings.tile_bounds;
        let ellipse = SpecValue::Bool(bounds == TileBounds::Ellipse);
        let preprocess_spec = [(0, SpecValue::Bool(features)), (1, ellipse), tile_spec(tile)[0]];
        let preprocess = if texel_preprocess {
            let mut bindings = vec![BindingKind::UniformBuffer];
            bindings.extend([BindingKind::UniformTexelBuffer; 5]);
            Kernel::cached(
                &device,
                &kernels::SPLAT_PREPROCESS_TEXEL,
                &KernelDecl { bindings: &bindings, push_constant_size: 0, specialization: &preprocess_spec },
            )?
        } else {
            frame_kernel(&device, &kernels::SPLAT_PREPROCESS, &preprocess_spec)?
        };
        let (w, h) = (camera.width, camera.height);
        let (tiles_x, tiles_y) = (w.div_ceil(tile), h.div_ceil(tile));
        let tiles = u64::from(tiles_x) * u64::from(tiles_y);
        let pixels = u64::from(w) * u64::from(h);
        if tiles >= 1 << 32 || pixels * 3 >= 1 << 32 {
            return Err(Error::invalid(format!("image {w}x{h}"), "is too large"));
        }
        let mut frame = FrameUniform::zeroed();
        camera_frame(camera, &mut frame)?;
        frame.background = [settings.background[0], settings.background[1], settings.background[2], 0.0];
        frame.size = [w, h, tiles_x, tiles_y];
        // Without rgb the colour is never read: degree 0 spares the SH reads.
        let sh_used =
            if settings.rgb { settings.sh_degree.map_or(scene.sh_degree, |d| d.min(scene.sh_degree)) } else { 0 };
        frame.counts =
            [n as u32, scene.sh_degree | sh_used << 8, u32::from(settings.normal_source == NormalSource::Stored), 0];

        let f = |name: &str, floats: u64| device.create_buffer(name, floats * 4, MemoryKind::Storage);
        let opt = |on: bool, name: &str, floats: u64| on.then(|| f(name, floats)).transpose();
        let out = GpuGBuffer {
            width: w,
            height: h,
            rgb: opt(settings.rgb, "gbuffer rgb", 3 * pixels)?,
            alpha: f("gbuffer alpha", pixels)?,
            depth: opt(ch.depth, "gbuffer depth", pixels)?,
            median_depth: opt(ch.median_depth, "gbuffer median depth", pixels)?,
            normal: opt(ch.normal, "gbuffer normal", 3 * pixels)?,
            albedo: opt(ch.albedo, "gbuffer albedo", 3 * pixels)?,
            roughness: opt(ch.roughness, "gbuffer roughness", pixels)?,
            metallic: opt(ch.metallic, "gbuffer metallic", pixels)?,
            ao: opt(ch.ao, "gbuffer ao", pixels)?,
            visibility: opt(ch.visibility, "gbuffer visibility", pixels)?,
        };
        let splats = device.create_buffer("splats", n * SPLAT_BYTES, MemoryKind::Storage)?;
        let feature_buf = features
            .then(|| device.create_buffer("splat features", n * FEATURE_BYTES, MemoryKind::Storage))
            .transpose()?;
        let tile_counts = device.create_buffer("tile counts", (n + 1) * 4, MemoryKind::Storage)?;
        let ranges = device.create_buffer("tile ranges", tiles * 8, MemoryKind::Storage)?;
        let uniform =
            device.create_buffer("splat frame", std::mem::size_of::<FrameUniform>() as u64, MemoryKind::Storage)?;
        self.scan.reserve(&device, n + 1)?;

        // Phase 1: preprocess and scan the tile counts; the total sizes phase 2.
        let preprocess = &*preprocess;
        let scan = &self.scan;
        let mut timings = device.run(|rec| -> Result<()> {
            let buffers = FrameBuffers {
                scene,
                splats: &splats,
                features: feature_buf.as_ref(),
                tile_counts: &tile_counts,
                keys: None,
                values: None,
                pair_tiles: None,
                ranges: &ranges,
                out: &out,
            };
            frame.record(rec, &uniform, &buffers)?;
            rec.begin_stage("preprocess");
            rec.fill(&tile_counts, 0)?;
            if texel_preprocess {
                let mut bindings = vec![Binding::Buffer(&uniform)];
                bindings.extend(scene_inputs.iter().map(|&buffer| {
                    Binding::Texels(Texels {
                        buffer,
                        offset: 0,
                        elements: buffer.size() / 4,
                        format: TexelFormat::R32Float,
                    })
                }));
                rec.dispatch_1d_bound(preprocess, &bindings, &(), n)?;
            } else {
                rec.dispatch_1d(preprocess, &[&uniform], &(), n)?;
            }
            rec.begin_stage("scan");
            scan.record(rec, &tile_counts, n + 1)
        })?;
        let pairs = u64::from(device.read_range::<u32>(&tile_counts, n, 1)?[0]);

        // Phase 2: keys, sort, ranges, blend.
        let keys = device.create_buffer("sort keys", pairs * 8, MemoryKind::Storage)?;
        let values = device.create_buffer("sort values", pairs * 4, MemoryKind::Storage)?;
        let pair_tiles = device.create_buffer("pair tiles", pairs * 4, MemoryKind::Storage)?;
        self.sort.reserve(&device, pairs)?;
        frame.counts[3] = pairs as u32;
        // Tile ids 0..=tiles: `tiles` marks the keys kernel's padding (splat_keys.comp).
        let key_bits = 32 + (64 - tiles.leading_zeros());
        let keys_kernel = frame_kernel(&device, &kernels::SPLAT_KEYS, &[(1, ellipse), tile_spec(tile)[0]])?;
        // Texel-buffer reads where the device has RGBA32F/R32UI views and the splats and pairs fit them.
        let texel = self.texel_blend
            && self.blend_variant == BlendVariant::SubgroupLoads
            && n > 0
            && 4 * n <= max_texels
            && pairs <= max_texels;
        let blend = self.blend_kernel(ch.blend_bits(settings.rgb), tile, texel)?;
        let (sort, keys_kernel, ranges_kernel, blend) = (&self.sort, &*keys_kernel, &*self.ranges, &*blend);
        let outputs: Vec<&Buffer> = [&out.alpha]
            .into_iter()
            .chain(
                [
                    &out.rgb,
                    &out.depth,
                    &out.median_depth,
                    &out.normal,
                    &out.albedo,
                    &out.roughness,
                    &out.metallic,
                    &out.ao,
                    &out.visibility,
                ]
                .into_iter()
                .flatten(),
            )
            .collect();
        let phase2 = device.run(|rec| -> Result<()> {
            let buffers = FrameBuffers {
                scene,
                splats: &splats,
                features: feature_buf.as_ref(),
                tile_counts: &tile_counts,
                keys: Some(&keys),
                values: Some(&values),
                pair_tiles: Some(&pair_tiles),
                ranges: &ranges,
                out: &out,
            };
            frame.record(rec, &uniform, &buffers)?;
            if let Some(word) = settings.prefill {
                for b in &outputs {
                    rec.fill(b, word)?;
                }
            }
            if pairs > 0 {
                rec.begin_stage("keys");
                rec.dispatch_1d(keys_kernel, &[&uniform], &(), n)?;
                rec.begin_stage("sort");
                sort.record(rec, &keys, &values, pairs, key_bits)?;
            }
            rec.begin_stage("ranges");
            rec.fill(&ranges, 0)?;
            if pairs > 0 {
                rec.dispatch_1d(ranges_kernel, &[&uniform], &(), pairs)?;
            }
            rec.begin_stage("blend");
            if texel {
                let view = |buffer, elements| {
                    Binding::Texels(Texels { buffer, offset: 0, elements, format: TexelFormat::Rgba32Float })
                };
                // Without features the kernel never reads binding 2; the splats stand in.
                let features = feature_buf.as_ref().map_or(view(&splats, 4 * n), |fb| view(fb, 3 * n));
                rec.dispatch_groups_bound(
                    blend,
                    &[
                        Binding::Buffer(&uniform),
                        view(&splats, 4 * n),
                        features,
                        Binding::Texels(Texels {
                            buffer: &values,
                            offset: 0,
                            elements: pairs,
                            format: TexelFormat::R32Uint,
                        }),
                    ],
                    &(),
                    tiles,
                )?;
            } else {
                rec.dispatch_groups(blend, &[&uniform], &(), tiles)?;
            }
            rec.end_stage();
            Ok(())
        })?;
        timings.stages.extend(phase2.stages);
        let working_bytes = splats.size()
            + feature_buf.as_ref().map_or(0, Buffer::size)
            + tile_counts.size()
            + keys.size()
            + values.size()
            + pair_tiles.size()
            + ranges.size()
            + self.sort.scratch_bytes()
            + self.scan.scratch_bytes();
        Ok(SplatFrame {
            gbuffer: out,
            stats: SplatStats { timings, pairs, key_bits, working_bytes },
            camera: camera.clone(),
            splats,
            pair_offsets: tile_counts,
            sorted_gaussians: values,
            pair_tiles,
            ranges,
            features: feature_buf,
            uniform,
            params: frame,
            scene_means: scene.means.id(),
            gaussians: n,
            tile,
        })
    }
}

#[cfg(test)]
mod layout_tests {
    use super::backward::BackwardUniform;
    use super::FrameUniform;
    use crate::gpu::{check_layout, kernels};

    /// The host structs match the GLSL blocks of every kernel that declares them.
    #[test]
    fn uniform_layouts_match_glsl() {
        let frame = check_layout::<FrameUniform>(kernels::ALL);
        assert!(frame.as_ref().is_ok_and(|n| *n >= 6), "{frame:?}");
        let backward = check_layout::<BackwardUniform>(kernels::ALL);
        assert!(backward.as_ref().is_ok_and(|n| *n == 2), "{backward:?}");
    }
}
