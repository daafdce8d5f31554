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
//!    `tile << d | depth key` key per (Gaussian, tile) counted, the depth key
//!    being the depth's float bits less the near plane's, to 16 mantissa
//!    bits, `d` bits wide ([`DepthKey`]: only the bits that vary between the
//!    planes) (for the
//!    texel blend, where the key has room, its top bits also say which blocks
//!    of the tile, half-tile columns × row pairs, the splat reaches:
//!    [`SplatStats::row_masks`]);
//! 3. **sort**: the stable radix sort over the bits in use only;
//! 4. **ranges**: each tile's slice of the sorted pairs;
//! 5. **blend**: per-pixel front-to-back blending into the requested channels
//!    (a subgroup skips the splats that reach none of its blocks: exact, the
//!    same bits as reading every splat).
//!
//! Conventions follow the INRIA and gsplat rasterizers (docs/conventions.md §3): pixel
//! centres at +0.5, α = min(0.99, o·exp(−σ)), skip α < 1/255, stop when
//! T·(1−α) < 1e-4. rgb is composited over the background; every other blended
//! channel is Σ wᵢ xᵢ (premultiplied by alpha; divide by alpha for the mean).
//! [`cpu`] is the f64 twin of every stage.

pub mod backward;
mod channels;
pub mod cpu;
pub mod cpu_backward;
mod forward;
mod layout;

pub use channels::*;
pub use forward::*;
pub(crate) use layout::*;

use crate::error::{Error, Result};
use crate::gpu::ash::vk;
use crate::gpu::{Buffer, Device, DeviceInfo, SpecValue};

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
pub(crate) const TILE_SPEC_IDS: [u32; 2] = [15, 16];

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
pub const BLEND_PIXELS: [u32; 4] = [1, 2, 4, 8];
/// The pixels per invocation of the texel-buffer blend on CPU devices not measured otherwise.
pub const DEFAULT_BLEND_PIXELS: u32 = 2;

/// The pixels per invocation a new [`Splatter`] uses on `info`'s device:
/// 8 on lavapipe from Mesa 25 on, where sharing each fetch and each loop
/// step over eight pixels is fastest; 1 on GPUs, where a tile's pixels are
/// its invocations and more of them run at once (measured on an NVIDIA
/// H200); else [`DEFAULT_BLEND_PIXELS`] (chosen by `srug bench splat
/// --blend-pixels`; docs/bench/splat.md, docs/bench/mesa.md, docs/bench/gpu.md).
pub fn default_blend_pixels(info: &DeviceInfo) -> u32 {
    if info.is_lavapipe_from(25) {
        8
    } else if info.device_type != vk::PhysicalDeviceType::CPU {
        1
    } else {
        DEFAULT_BLEND_PIXELS
    }
}
/// Whether a new [`Splatter`]'s texel-buffer blend evaluates each splat only
/// at the pixels of a lane's row it can reach (`PIXEL_REACH` in
/// `splat_blend_body.glsl`): on lavapipe from Mesa 25 on, whose compiled
/// kernels jump over an `if` no lane of the vector enters, so a pixel column
/// the splat misses in every lane costs a compare; off elsewhere (Mesa
/// 22.3's lavapipe runs both sides of every `if`, where the test is extra
/// work; GPUs not measured). The image is the same either way.
pub fn default_pixel_reach(info: &DeviceInfo) -> bool {
    info.is_lavapipe_from(25)
}
/// Whether a new [`Splatter`]'s texel-buffer blend fetches each key window's
/// wanted splats once, one per lane, and hands them out splat by splat
/// (`WINDOW_FETCH` in `splat_blend_body.glsl`) instead of every lane fetching
/// each splat: on lavapipe from Mesa 25 on, whose texel fetch is a call to
/// an out-of-line function that saves and restores the caller's vector
/// registers, and which jumps over the fetch in windows it does not start;
/// and on GPUs, where a lane's fetches of the next index and then its splat
/// are a chain of memory latencies that one fetch per window overlaps across
/// the subgroup (measured on an NVIDIA H200). Off on other CPU devices
/// (Mesa 22.3's lavapipe runs both sides of every `if`, so it would fetch
/// and hand out every step). The image is the same either way.
pub fn default_window_fetch(info: &DeviceInfo) -> bool {
    info.is_lavapipe_from(25) || info.device_type != vk::PhysicalDeviceType::CPU
}
/// Whether a new [`Splatter`]'s window-fetch blend takes a window's next two
/// splats each loop step (`TWO_SPLATS` in `splat_blend_body.glsl`): on GPUs,
/// where a subgroup's step is a chain of latencies that the second splat's
/// independent reads and exponential overlap (measured on an NVIDIA H200);
/// off on CPU devices, where lavapipe gained nothing from it. The image is
/// the same either way.
pub fn default_two_splats_per_step(info: &DeviceInfo) -> bool {
    info.device_type != vk::PhysicalDeviceType::CPU
}
/// The chunk length a new [`Splatter`] splits long tile lists at
/// ([`Splatter::set_chunk_length`]; 0: none): on GPUs, where one workgroup
/// walks each tile's list and the longest walk bounds the blend; 0 on CPU
/// devices, where every core is busy with other tiles anyway and splitting
/// only adds passes. The image is the same to rounding.
pub fn default_chunk_length(info: &DeviceInfo) -> u32 {
    if info.device_type == vk::PhysicalDeviceType::CPU {
        0
    } else {
        DEFAULT_CHUNK_LENGTH
    }
}
/// The chunk length of [`default_chunk_length`] on GPUs.
pub const DEFAULT_CHUNK_LENGTH: u32 = 1024;
/// The longest chunk [`Splatter::set_chunk_length`] accepts (`list_chunks`'
/// 2·length fits 32 bits).
pub const MAX_CHUNK_LENGTH: u32 = 1 << 30;

/// The chunks the split blend cuts a tile list of `entries` pairs into
/// (`list_chunks` in `splat.glsl`): none where it holds at most
/// 2·`chunk_length` or `chunk_length` is 0, else ⌈entries / chunk_length⌉.
pub fn list_chunks(entries: u32, chunk_length: u32) -> u32 {
    if chunk_length == 0 || entries <= 2 * chunk_length {
        0
    } else {
        entries.div_ceil(chunk_length)
    }
}

/// Bit of the blend's `CHANNELS` specialization constant that blends rgb
/// (keep in sync with `RGB` in `splat_blend_body.glsl`).
pub(crate) const RGB_BIT: u32 = 8;
/// The blend kernel's `CHANNELS` bit for the top-Gaussian index (`TOP` in `splat_blend_body.glsl`).
pub(crate) const TOP_GAUSSIAN_BIT: u32 = 9;
/// Why a G-buffer has no rgb to give.
const NO_RGB: &str = "this G-buffer has no rgb channel (it was splatted with SplatSettings::rgb off)";
/// Bytes of one projected splat (keep in sync with `Splat` in `splat.glsl`).
pub(crate) const SPLAT_BYTES: u64 = 64;
/// Bytes of one splat's features (three vec4).
pub(crate) const FEATURE_BYTES: u64 = 48;
/// Bytes of one splat's features at 16 bits ([`SplatSettings::packed_features`]:
/// three uvec2, `PackedFeatures` in `splat_types.glsl`; [`cpu::pack_features`] is its twin).
pub(crate) const PACKED_FEATURE_BYTES: u64 = 24;

/// Bytes of one splat's features as `settings` store them.
pub(crate) fn feature_bytes(settings: &SplatSettings) -> u64 {
    if settings.packed_features {
        PACKED_FEATURE_BYTES
    } else {
        FEATURE_BYTES
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
    /// so a pixel the kernel never wrote cannot pass for a value), and the
    /// preprocess's per-record tile counts and cull flags before it writes them
    /// (a record it skipped then cannot pass for an empty one).
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
    /// Surface depth: each splat's depth at a pixel is where the pixel's ray
    /// meets the splat's plane (through its mean, normal its shortest axis),
    /// limited to its 3σ extent along the view, instead of its centre's depth;
    /// both depth channels follow. Pinhole and orthographic cameras (other
    /// lenses keep centre depths). Off: the centre depth, as 3DGS. The splat
    /// backward pass differentiates it (through each splat's centre and slope).
    pub surface_depth: bool,
    /// Coverage 1 − T at which the median depth channel reads a pixel's
    /// depth: the depth of the splat that takes T to 1 − this or below (with
    /// surface depths, or a later splat at least this opaque that lies
    /// nearer there); 0 where T never gets there. 0.5 (the default) is the
    /// median; more keeps only what covers a pixel more surely (shadow maps,
    /// [`crate::shadow::ShadowSettings::map_coverage`]). Strictly between 0 and 1.
    pub median_coverage: f32,
    /// Store each splat's normal and materials at 16 bits (24 bytes, not 48:
    /// snorm normal, unorm materials) for the blend to read back: the normal
    /// and material channels then carry a splat's values to within 1/32767 and
    /// 1/65535. Half the features' memory and reads, for frames that are not
    /// differentiated: the backward pass refuses such a frame. Off by default;
    /// the relighter turns it on for its cameras.
    pub packed_features: bool,
    /// Keep splat records (and features) only for the Gaussians that can
    /// reach the image: a first pass culls on each Gaussian's position and
    /// largest scale, a scan of its flags gives each survivor a slot in order,
    /// and only those get a record, so a view that sees a fraction of a large
    /// scene holds that fraction (plus 4 bytes a Gaussian while counting).
    /// The images are the same bits; the pairs name record slots, and a
    /// frame's top-Gaussian channel is mapped back to Gaussian ids
    /// ([`SplatFrame::slot_gaussians`]). One more submission and readback per
    /// call, and a second read of the positions. Off by default (the backward
    /// pass refuses such frames); the relighter turns it on for its cameras.
    pub compact_splats: bool,
}

/// The coverage at which the median depth is read by default (the median).
pub const DEFAULT_MEDIAN_COVERAGE: f32 = 0.5;

/// Checks a [`SplatSettings::median_coverage`] (`what` names the setting in the message).
pub(crate) fn check_median_coverage(what: &str, coverage: f32) -> Result<()> {
    if coverage > 0.0 && coverage < 1.0 {
        Ok(())
    } else {
        Err(Error::invalid(format!("{what} {coverage}"), "must lie strictly between 0 and 1"))
    }
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
            surface_depth: false,
            median_coverage: DEFAULT_MEDIAN_COVERAGE,
            packed_features: false,
            compact_splats: false,
        }
    }
}

/// How a host's depth buffer encodes depth ([`Splatter::render_frame_occluded`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum HostDepth {
    /// Camera z in world units (0, negative or infinite: nothing there).
    CameraZ,
    /// Vulkan's [0, 1] perspective depth, 0 at `near`, 1 at `far` (1: nothing there).
    Vulkan {
        /// Near plane (camera z).
        near: f32,
        /// Far plane (camera z).
        far: f32,
    },
    /// Reversed-Z: 1 at `near`, 0 at `far` (which may be infinite; 0: nothing there).
    ReversedZ {
        /// Near plane (camera z).
        near: f32,
        /// Far plane (camera z; `f32::INFINITY` for an infinite far plane).
        far: f32,
    },
}

impl HostDepth {
    /// Checks the planes: 0 < near < far (far finite, except reversed-Z).
    pub fn validate(&self) -> Result<()> {
        let (near, far, infinite_ok) = match *self {
            Self::CameraZ => return Ok(()),
            Self::Vulkan { near, far } => (near, far, false),
            Self::ReversedZ { near, far } => (near, far, true),
        };
        let far_ok = far.is_finite() || (infinite_ok && far == f32::INFINITY);
        if !(near > 0.0 && near.is_finite() && far_ok && far > near) {
            return Err(Error::invalid(
                format!("host depth planes near {near}, far {far}"),
                "need 0 < near < far (an infinite far only with reversed-Z)",
            ));
        }
        Ok(())
    }

    /// The camera z of a stored value `d` (infinity where nothing is there);
    /// twin of `occluder_z` in `splat_blend_body.glsl`.
    pub fn camera_z(&self, d: f64) -> f64 {
        match *self {
            Self::CameraZ => {
                if d > 0.0 {
                    d
                } else {
                    f64::INFINITY
                }
            }
            Self::Vulkan { near, far } => {
                let (n, f) = (f64::from(near), f64::from(far));
                if d >= 1.0 {
                    f64::INFINITY
                } else {
                    n * f / (f - d * (f - n))
                }
            }
            Self::ReversedZ { near, far } => {
                let (n, f) = (f64::from(near), f64::from(far));
                if d <= 0.0 {
                    f64::INFINITY
                } else if f.is_infinite() {
                    n / d
                } else {
                    n * f / (n + d * (f - n))
                }
            }
        }
    }

    /// The frame uniform's `occluder` vector.
    pub(crate) fn packed(&self) -> [f32; 4] {
        match *self {
            Self::CameraZ => [0.0; 4],
            Self::Vulkan { near, far } => [1.0, near, far, 0.0],
            Self::ReversedZ { near, far } => [2.0, near, far, 0.0],
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
    /// The optional channels kept ([`Channels`]): planar, 3 floats per
    /// pixel for normal and albedo, else 1. Blended values are Σ wᵢ xᵢ
    /// (divide by alpha for the mean); median depth is the depth where T
    /// first falls to 1 − [`SplatSettings::median_coverage`] (0 where it never does).
    pub channels: PerChannel<Vec<f32>>,
    /// Per pixel, the index of the Gaussian with the largest blend weight
    /// (`u32::MAX` where none contributes), when [`Channels::top_gaussian`]
    /// was asked for: maps a pixel to a Gaussian's ids exactly.
    pub top_gaussian: Option<Vec<u32>>,
}

impl GBuffer {
    /// Writes every channel as 32-bit float channels of one EXR layer (R, G,
    /// B, A, Z, median_depth.Y, normal.X/Y/Z, albedo.R/G/B, roughness.Y, ...).
    pub fn write_exr(&self, path: impl AsRef<std::path::Path>) -> Result<()> {
        self.write_exr_with_ids(path, &[])
    }

    /// The ray-distance (range) channel of a frame rendered from `camera`:
    /// the depth channel times each pixel's [`crate::scene::Camera::ray_length_per_depth`]
    /// (premultiplied by alpha like depth; 0 where the lens sends no ray);
    /// `None` without a depth channel.
    pub fn ray_distance(&self, camera: &crate::scene::Camera) -> Option<Vec<f32>> {
        let depth = self.get(Channel::Depth)?;
        let w = self.width as usize;
        Some(
            depth
                .iter()
                .enumerate()
                .map(|(p, d)| {
                    let px = [(p % w) as f64 + 0.5, (p / w) as f64 + 0.5];
                    camera.ray_length_per_depth(px).map_or(0.0, |s| (f64::from(*d) * s) as f32)
                })
                .collect(),
        )
    }

    /// [`GBuffer::write_exr`] plus, where [`GBuffer::top_gaussian`] was kept, a
    /// `top_gaussian` channel and one 32-bit integer channel per `(name, ids)`:
    /// each pixel holds the id of its top Gaussian (`u32::MAX` where none).
    pub fn write_exr_with_ids(&self, path: impl AsRef<std::path::Path>, ids: &[(&str, &[u32])]) -> Result<()> {
        self.write_exr_with(path, &[], ids)
    }

    /// [`GBuffer::write_exr_with_ids`] with more float channels (name, values, floats per pixel).
    pub fn write_exr_with(
        &self,
        path: impl AsRef<std::path::Path>,
        extra: &[(&str, &[f32], usize)],
        ids: &[(&str, &[u32])],
    ) -> Result<()> {
        let mapped: Vec<(&str, Vec<u32>)> = match &self.top_gaussian {
            Some(top) => ids
                .iter()
                .map(|(name, values)| {
                    let pick = |g: &u32| values.get(*g as usize).copied().unwrap_or(u32::MAX);
                    (*name, top.iter().map(pick).collect())
                })
                .collect(),
            None if ids.is_empty() => Vec::new(),
            None => return Err(Error::invalid("id channels", "need the top_gaussian channel in the G-buffer")),
        };
        let mut uints: Vec<(&str, &[u32])> =
            self.top_gaussian.as_deref().map(|t| ("top_gaussian", t)).into_iter().collect();
        uints.extend(mapped.iter().map(|(n, v)| (*n, v.as_slice())));
        let mut floats = self.channels();
        floats.extend_from_slice(extra);
        crate::io::write_exr_layer(path.as_ref(), self.width, self.height, &floats, &uints)
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
        out.extend(Channel::ALL.into_iter().filter_map(|c| self.get(c).map(|v| (c.name(), v, c.floats()))));
        out
    }

    /// The values of an optional channel, when it was kept.
    pub fn get(&self, channel: Channel) -> Option<&[f32]> {
        self.channels.get(channel).map(Vec::as_slice)
    }

    /// The values of an optional channel to change, when it was kept.
    pub fn get_mut(&mut self, channel: Channel) -> Option<&mut [f32]> {
        self.channels.get_mut(channel).map(Vec::as_mut_slice)
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
    /// The optional channels kept, laid out as in [`GBuffer::channels`].
    pub channels: PerChannel<Buffer>,
    /// `uint[P]`, [`GBuffer::top_gaussian`].
    pub top_gaussian: Option<Buffer>,
}

impl GpuGBuffer {
    /// The rgb channel, or an error naming why it is absent.
    pub fn rgb_buffer(&self) -> Result<&Buffer> {
        self.rgb.as_ref().ok_or_else(|| Error::invalid("rgb channel", NO_RGB))
    }

    /// An optional channel's buffer, when it was kept.
    pub fn get(&self, channel: Channel) -> Option<&Buffer> {
        self.channels.get(channel)
    }

    /// Reads every channel back.
    pub fn read(&self, device: &Device) -> Result<GBuffer> {
        Ok(GBuffer {
            width: self.width,
            height: self.height,
            rgb: self.rgb.as_ref().map(|b| device.read_buffer::<f32>(b)).transpose()?,
            alpha: device.read_buffer(&self.alpha)?,
            channels: PerChannel::try_from_fn(|c| self.get(c).map(|b| device.read_buffer::<f32>(b)).transpose())?,
            top_gaussian: self.top_gaussian.as_ref().map(|b| device.read_buffer::<u32>(b)).transpose()?,
        })
    }

    /// GPU bytes held by the channels.
    pub fn bytes(&self) -> u64 {
        let opt = self.rgb.iter().chain(self.channels.iter().map(|(_, b)| b)).chain(&self.top_gaussian);
        self.alpha.size() + opt.map(Buffer::size).sum::<u64>()
    }
}
