//! The forward pass: preprocess, scan, keys, sort, ranges and blend, recorded
//! as two submissions (the scan's total sizes the second).

use std::sync::Arc;

use bytemuck::Zeroable;

use super::*;
use crate::error::{Error, Result};
use crate::gpu::{
    kernels, Binding, BindingKind, Buffer, Device, Grid, Kernel, KernelDecl, MemoryKind, SpecValue, TexelFormat,
    Texels, Timings,
};
use crate::primitives::scan::Scan;
use crate::primitives::sort::{PairPacking, RadixSort, SortDigits};
use crate::scene::activate::GpuScene;
use crate::scene::order::ReorderKernels;
use crate::scene::Camera;

/// What one render did, besides its G-buffers.
#[derive(Clone, Debug, Default)]
pub struct SplatStats {
    /// Per-stage GPU times.
    pub timings: Timings,
    /// (Gaussian, tile) pairs sorted.
    pub pairs: u64,
    /// Key bits sorted.
    pub key_bits: u32,
    /// GPU bytes of per-frame working memory (splats, features, keys, ranges,
    /// and the sort's and split blend's scratch, which a batch's frames share).
    pub working_bytes: u64,
    /// Whether the blend skipped splats for the blocks of a tile (half-tile
    /// columns × row pairs) they cannot reach (the texel blend, where each
    /// key has room for the mask).
    pub row_masks: bool,
    /// Chunks the split blend cut the tile lists into ([`Splatter::chunk_length`]; 0: no list split).
    pub chunks: u64,
    /// Splat records the frame holds: one per Gaussian, or with
    /// [`SplatSettings::compact_splats`] one per Gaussian its position cull kept.
    pub records: u64,
}

/// The feature channels' bits (`Channel::bit`: normal to visibility), whose
/// attributes the preprocess reads (`FEATURE_CHANNELS`, its specialization constant 12).
const FEATURE_CHANNEL_BITS: u32 = 252;

/// The SH degree the colour uses: the settings' cap on the scene's, and 0
/// without rgb, where the preprocess evaluates no colour at all (`COLOUR`,
/// its specialization constant 11) and so reads no SH coefficient.
fn sh_degree_used(scene: &GpuScene, settings: &SplatSettings) -> u32 {
    if settings.rgb {
        settings.sh_degree.map_or(scene.sh_degree, |d| d.min(scene.sh_degree))
    } else {
        0
    }
}

/// Mantissa bits the depth key keeps: depths are ordered to a relative
/// 2⁻¹⁶ (0.15 mm at 10 m), far below any splat's extent; splats closer than
/// that keep their scene order (the sort is stable). The 7 bits dropped are
/// two radix passes of 4 bits at the default planes (docs/conventions.md §3).
pub const DEPTH_KEY_MANTISSA_BITS: u32 = 16;

/// The depth half of a pair's sort key (splat_keys.comp `pair_key`): every
/// splat kept has near < depth < far, so its depth's float bits less the
/// near plane's lie in [1, far bits − near bits); shifted right by `shift`
/// (keeping [`DEPTH_KEY_MANTISSA_BITS`] of the mantissa) they fit `bits`
/// bits, and only those need sorting. Where the planes are not
/// 0 < near < far < ∞, the float bits whole (32 bits, no shift).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DepthKey {
    /// Bits the sort orders.
    pub bits: u32,
    /// Low mantissa bits dropped.
    pub shift: u32,
    near_bits: u32,
}

impl DepthKey {
    /// The key of `camera`'s planes.
    pub fn of(camera: &Camera) -> Self {
        let (near, far) = (camera.near, camera.far);
        if !(near > 0.0 && far > near && far.is_finite()) {
            return Self { bits: 32, shift: 0, near_bits: 0 };
        }
        let shift = 23 - DEPTH_KEY_MANTISSA_BITS;
        let span = (far.to_bits() - near.to_bits()) >> shift;
        Self { bits: (32 - span.leading_zeros()).max(1), shift, near_bits: near.to_bits() }
    }

    /// The key of a splat at `depth` (near < depth < far), as the keys kernel computes it.
    pub fn key(&self, depth: f32) -> u32 {
        depth.to_bits().wrapping_sub(self.near_bits) >> self.shift
    }
}

/// Bits of the depth key ([`DepthKey::of`]).
pub fn depth_key_bits(camera: &Camera) -> u32 {
    DepthKey::of(camera).bits
}

/// Whether `info`'s device can run the texel blend (`splat_blend_texel.comp`):
/// RGBA32F, R32UI, RG32UI and RGBA32UI texel-buffer views (splats, keys and
/// values, packed and float features), and subgroup shuffles.
fn texel_blend_supported(info: &DeviceInfo) -> bool {
    info.subgroup_shuffle
        && [TexelFormat::Rgba32Float, TexelFormat::R32Uint, TexelFormat::Rg32Uint, TexelFormat::Rgba32Uint]
            .iter()
            .all(|f| info.texel_formats.contains(f))
}

/// A kernel whose binding 0 is the frame uniform and bindings 1..=`views`
/// texel-buffer views.
/// Sorted pairs a ranges invocation takes (`PAIRS` in splat_ranges_body.glsl): it reads
/// one key more than its pairs, where one pair an invocation reads two (docs/bench/splat.md,
/// "Tile ranges eight pairs an invocation").
const RANGE_PAIRS: u32 = 8;

fn texel_view_kernel(
    device: &Device,
    info: &'static crate::gpu::KernelInfo,
    views: usize,
    specialization: &[(u32, SpecValue)],
) -> Result<Arc<Kernel>> {
    texel_view_kernel_pushing(device, info, views, 0, specialization)
}

/// [`texel_view_kernel`] with `push_constant_size` bytes of push constants.
fn texel_view_kernel_pushing(
    device: &Device,
    info: &'static crate::gpu::KernelInfo,
    views: usize,
    push_constant_size: usize,
    specialization: &[(u32, SpecValue)],
) -> Result<Arc<Kernel>> {
    let mut bindings = vec![BindingKind::UniformBuffer];
    bindings.extend(std::iter::repeat_n(BindingKind::UniformTexelBuffer, views));
    Ok(device.kernel(info, &KernelDecl { bindings: &bindings, push_constant_size, specialization })?)
}

/// The split blend's share of GPU memory at most ([`Splatter::set_chunk_length`]):
/// where a view's chunks would need more, they are made longer.
const CHUNK_MEMORY: u64 = 256 << 20;
/// Floats per chunk and tile pixel: the transmittance, then the partial
/// sums (`PARTIAL_FLOATS` in `splat_blend_body.glsl`).
const CHUNK_FLOATS: u64 = 1 + 19;

/// The chunk length and the most chunk slots a view of `pairs` pairs over
/// `tiles` tiles of `tile` pixels needs at `chunk_length` (`list_chunks`: a
/// split list holds more than 2·length entries, so at most
/// pairs / (2·length + 1) lists split, each into at most entries / length + 1
/// chunks), the length doubled until the chunks fit [`CHUNK_MEMORY`]; `None`
/// where no list can be split.
fn chunk_slots(pairs: u64, tiles: u64, tile: u32, chunk_length: u32) -> Option<(u32, u64)> {
    let slot_bytes = u64::from(tile * tile) * CHUNK_FLOATS * 4;
    let mut length = u64::from(chunk_length);
    while length > 0 && length <= u64::from(MAX_CHUNK_LENGTH) && pairs > 2 * length {
        let slots = pairs.div_ceil(length) + tiles.min(pairs / (2 * length + 1));
        if slots * slot_bytes <= CHUNK_MEMORY {
            return Some((length as u32, slots));
        }
        length *= 2;
    }
    None
}

/// Where `mask` (one u32 per tile, row-major, `tiles_x` a row, `tiles_y`
/// rows; non-zero: wanted) wants tiles: each row's wanted columns `[x0, x1)`
/// (their hull; `[0, 0)` for a row wanting none), and the tiles `[x0, y0, x1,
/// y1)` that hold them all (`[0; 4]` where it wants none). The preprocess culls
/// every splat whose bounding square misses them.
fn wanted_spans(mask: &[u32], tiles_x: u32, tiles_y: u32) -> (Vec<[u32; 2]>, [u32; 4]) {
    let mut rows = vec![[u32::MAX, 0]; tiles_y as usize];
    let mut bounds = [u32::MAX, u32::MAX, 0, 0];
    for (t, _) in mask.iter().enumerate().filter(|(_, &w)| w != 0) {
        let (x, y) = ((t as u64 % u64::from(tiles_x)) as u32, (t as u64 / u64::from(tiles_x)) as u32);
        if let Some(row) = rows.get_mut(y as usize) {
            *row = [row[0].min(x), row[1].max(x + 1)];
        }
        bounds = [bounds[0].min(x), bounds[1].min(y), bounds[2].max(x + 1), bounds[3].max(y + 1)];
    }
    for row in &mut rows {
        if row[0] == u32::MAX {
            *row = [0, 0];
        }
    }
    (rows, if bounds[0] == u32::MAX { [0; 4] } else { bounds })
}

/// The texel formats the texel preprocess views the scene's means,
/// log-scales, rotations, opacity logits and SH coefficients in (arrays of
/// `bytes` each), or `None` where the device cannot view them all so within
/// `max_texels` elements: one fetch per attribute where the device views
/// them so (means and log-scales as RGB32F; rotations and, where a
/// Gaussian's SH fill whole vec4s, the SH as RGBA32F), R32F otherwise. A
/// view's limit counts its own elements, so a 10M-Gaussian SH-3 scene (480M
/// floats of SH) is viewed as 120M RGBA32F texels.
fn preprocess_view_formats(
    formats: &[TexelFormat],
    max_texels: u64,
    bytes: [u64; 5],
    sh_degree: u32,
) -> Option<[TexelFormat; 5]> {
    if !formats.contains(&TexelFormat::R32Float) {
        return None;
    }
    let or_r32 =
        |wanted: TexelFormat, ok: bool| if ok && formats.contains(&wanted) { wanted } else { TexelFormat::R32Float };
    let triple = or_r32(TexelFormat::Rgb32Float, true);
    let chosen = [
        triple,
        triple,
        or_r32(TexelFormat::Rgba32Float, true),
        TexelFormat::R32Float,
        or_r32(TexelFormat::Rgba32Float, crate::scene::sh_coefficients(sh_degree) * 3 % 4 == 0),
    ];
    chosen.iter().zip(bytes).all(|(f, b)| b / f.bytes() <= max_texels).then_some(chosen)
}

/// What selects a blend kernel: its channel bits, tile edge, and which
/// specialization each of its options takes.
#[derive(Clone, Copy, Debug)]
struct BlendOptions {
    bits: u32,
    tile: u32,
    /// The texel-buffer reads (`splat_blend_texel.comp`).
    texel: bool,
    /// A full panorama: offsets wrap along x.
    wrap_x: bool,
    /// Surface depth.
    surface: bool,
    /// A host's depth hides splats.
    occluded: bool,
    /// Row masks in the keys (texel blend only).
    row_masks: bool,
    /// Only the tiles of the frame's tile mask are blended.
    tile_mask: bool,
    /// The split blend's pass (`CHUNK_PASS`: 0 whole lists, 1 chunk
    /// transmittance, 2 chunk blend, 3 merge; texel blend only).
    chunk_pass: u32,
    /// Entries per chunk; 0: no list is split.
    chunk_length: u32,
    /// [`SplatSettings::median_coverage`].
    median_coverage: f32,
    /// [`SplatSettings::packed_features`].
    packed_features: bool,
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
    /// Projected splats, `SPLAT_BYTES` each, one per Gaussian or, compacted,
    /// per slot (those culled after their slot was given have a tile count of 0).
    pub splats: Buffer,
    /// Per-record offsets into the unsorted pair list (exclusive scan of tile counts), records + 1 values.
    pub pair_offsets: Buffer,
    /// Record of each sorted pair: its Gaussian, or compacted its slot.
    pub sorted_gaussians: Buffer,
    /// Compacted records ([`SplatSettings::compact_splats`]): each slot's
    /// Gaussian, in increasing order; `None` where record i is Gaussian i.
    pub slot_gaussians: Option<Buffer>,
    /// Tile id of each unsorted pair: each Gaussian's pairs from its offset on,
    /// in increasing tile order (the keys kernel's padding last, with id = tiles).
    /// The backward pass finds a pair's gradient record by searching these.
    /// Frames from [`Splatter::render_frame`], [`Splatter::render_frame_in_tiles`]
    /// and [`Splatter::render_frames`] have them; [`Splatter::render`],
    /// [`Splatter::render_batch`], [`Splatter::render_frame_occluded`] (whose
    /// frames the backward pass refuses) and the relighter's shadow maps,
    /// none of which is differentiated, write none.
    pub pair_tiles: Option<Buffer>,
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
    /// Whether its depths are surface depths ([`SplatSettings::surface_depth`]).
    pub surface_depth: bool,
    /// Its median depth's coverage ([`SplatSettings::median_coverage`]).
    pub median_coverage: f32,
    /// Whether its features are stored at 16 bits ([`SplatSettings::packed_features`]).
    pub packed_features: bool,
    /// Whether a host's depth hid splats ([`Splatter::render_frame_occluded`]).
    pub occluded: bool,
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
    pub(super) device: Device,
    blend_variant: BlendVariant,
    texel_blend: bool,
    texel_preprocess: bool,
    blend_pixels: u32,
    pixel_reach: bool,
    window_fetch: bool,
    two_splats_per_step: bool,
    chunk_length: u32,
    chunk_scratch: ChunkScratch,
    scan: Scan,
    sort: RadixSort,
}

impl Splatter {
    /// Builds the fixed kernels; channel variants are built on first use.
    pub fn new(device: &Device) -> Result<Self> {
        Ok(Self {
            device: device.clone(),
            blend_variant: if device.info().subgroup_ballot {
                BlendVariant::SubgroupLoads
            } else {
                BlendVariant::PerPixel
            },
            texel_blend: texel_blend_supported(device.info()),
            texel_preprocess: device.info().texel_formats.contains(&TexelFormat::R32Float),
            blend_pixels: default_blend_pixels(device.info()),
            pixel_reach: default_pixel_reach(device.info()),
            window_fetch: default_window_fetch(device.info()),
            two_splats_per_step: default_two_splats_per_step(device.info()),
            chunk_length: default_chunk_length(device.info()),
            chunk_scratch: ChunkScratch::default(),
            scan: Scan::new(device)?,
            sort: {
                let mut sort = RadixSort::new(device)?;
                sort.set_packing(device, true)?;
                sort
            },
        })
    }

    /// Whether the subgroup-load blend reads each contribution's colour and
    /// features through texel-buffer views (where the splats fit
    /// `maxTexelBufferElements`) rather than by device address. On by default
    /// where the device has RGBA32F and R32UI texel buffers and subgroup
    /// shuffles (the window fetch hands each splat from its lane by shuffle);
    /// the image is the same.
    pub fn texel_blend(&self) -> bool {
        self.texel_blend
    }

    /// Chooses how the subgroup-load blend reads colour and features (see
    /// [`Splatter::texel_blend`]); on where the device lacks the views or
    /// subgroup shuffles is an error.
    pub fn set_texel_blend(&mut self, on: bool) -> Result<()> {
        if on && !texel_blend_supported(self.device.info()) {
            return Err(Error::unsupported(
                "the texel blend needs RGBA32F/R32UI texel buffers and subgroup shuffles in compute shaders",
            ));
        }
        self.texel_blend = on;
        Ok(())
    }

    /// Whether the preprocess reads the Gaussians' means, log-scales,
    /// rotations, opacity logits and SH coefficients through texel-buffer
    /// views (where each array fits `maxTexelBufferElements`; one fetch per
    /// attribute where the device views RGB32F and RGBA32F, else R32F) rather
    /// than by device address, and the keys kernel reads the splats and their
    /// tile offsets through RGBA32UI and R32UI views where the device has them.
    /// On by default where the device has R32F texel buffers; the splats and
    /// keys are the same.
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

    /// The digits the pairs' radix sort passes take
    /// ([`crate::primitives::sort::default_sort_digits`] unless set).
    pub fn sort_digits(&self) -> SortDigits {
        self.sort.digits()
    }

    /// Chooses the sort's digits ([`RadixSort::set_digits`]); the order is
    /// the same, a stable sort on the same keys.
    pub fn set_sort_digits(&mut self, digits: SortDigits) -> Result<()> {
        self.sort.set_digits(&self.device, digits)
    }

    /// Whether the sort's passes after the first move each pair as one
    /// 64-bit word (its depth bits above the first digit, tile id, splat
    /// index and row mask; [`RadixSort::set_packing`]) where they fit: on by
    /// default.
    pub fn sort_packing(&self) -> bool {
        self.sort.packing()
    }

    /// Chooses whether the sort packs pairs ([`Splatter::sort_packing`]); the order is the same.
    pub fn set_sort_packing(&mut self, on: bool) -> Result<()> {
        self.sort.set_packing(&self.device, on)
    }

    /// Whether the frame's prefix sums (the tile counts, the sort's digit
    /// counts) work in tiles, the GPUs' default, or runs ([`Scan`]).
    pub fn scan_tiles(&self) -> bool {
        self.scan.tiles()
    }

    /// Chooses tiles or runs for the frame's prefix sums ([`Splatter::scan_tiles`]); the sums are the same.
    pub fn set_scan_tiles(&mut self, on: bool) -> Result<()> {
        self.scan.set_tiles(&self.device, on)?;
        self.sort.set_scan_tiles(&self.device, on)
    }

    /// Times each kernel of the frames' sort as a stage of its own instead of
    /// one "sort" stage ([`RadixSort::set_kernel_stages`]): for benchmarks.
    pub fn set_sort_kernel_stages(&mut self, on: bool) {
        self.sort.set_kernel_stages(on);
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

    /// Whether the texel-buffer blend evaluates each splat only at the pixels
    /// of a lane's row it can reach ([`default_pixel_reach`] says where it is on).
    pub fn pixel_reach(&self) -> bool {
        self.pixel_reach
    }

    /// Turns the texel-buffer blend's per-pixel reach test on or off (see
    /// [`Splatter::pixel_reach`]); the image does not change, only what is evaluated.
    pub fn set_pixel_reach(&mut self, on: bool) {
        self.pixel_reach = on;
    }

    /// Whether the texel-buffer blend fetches each key window's wanted splats
    /// once, one per lane ([`default_window_fetch`] says where it is on).
    pub fn window_fetch(&self) -> bool {
        self.window_fetch
    }

    /// Turns the texel-buffer blend's per-window fetch on or off (see
    /// [`Splatter::window_fetch`]); the image does not change, only how splats are read.
    pub fn set_window_fetch(&mut self, on: bool) {
        self.window_fetch = on;
    }

    /// Whether each step of the window-fetch blend takes a window's next two
    /// splats (their reads and exponentials independent of each other, then
    /// accumulated in order) rather than one ([`default_two_splats_per_step`]
    /// says where it is on).
    pub fn two_splats_per_step(&self) -> bool {
        self.two_splats_per_step
    }

    /// Turns two splats per blend step on or off (see
    /// [`Splatter::two_splats_per_step`]; it takes effect with the window
    /// fetch); the image does not change.
    pub fn set_two_splats_per_step(&mut self, on: bool) {
        self.two_splats_per_step = on;
    }

    /// Entries per chunk of the split blend (0: no list is split;
    /// [`default_chunk_length`]): the texel blend cuts a tile's list longer
    /// than twice this into chunks of this many entries, each walked by a
    /// workgroup of its own, then adds the chunks up in order (frames in
    /// front of a host's depth are not split). Where a view's chunks would
    /// take more than 256 MiB, its chunks are made longer.
    pub fn chunk_length(&self) -> u32 {
        self.chunk_length
    }

    /// Sets the split blend's chunk length (see [`Splatter::chunk_length`]);
    /// 0 splits no list. The image is the same to rounding: each chunk
    /// starts from the transmittance the ones before it leave.
    pub fn set_chunk_length(&mut self, entries: u32) -> Result<()> {
        if entries > MAX_CHUNK_LENGTH {
            return Err(Error::invalid(
                format!("chunk length {entries}"),
                format!("exceeds the {MAX_CHUNK_LENGTH} entries a chunk may hold"),
            ));
        }
        self.chunk_length = entries;
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

    /// The blend kernel for `options`, from the device's kernel cache.
    fn blend_kernel(&self, options: BlendOptions) -> Result<Arc<Kernel>> {
        let BlendOptions {
            bits,
            tile,
            texel,
            wrap_x,
            surface,
            occluded,
            row_masks,
            tile_mask,
            chunk_pass,
            chunk_length,
            median_coverage,
            packed_features,
        } = options;
        // The transmittance pass blends nothing and needs no depth.
        let (bits, surface) = if chunk_pass == 1 { (0, false) } else { (bits, surface) };
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
        if wrap_x {
            spec.push((3, SpecValue::Bool(true)));
        }
        if surface {
            spec.push((4, SpecValue::Bool(true)));
        }
        if occluded {
            spec.push((5, SpecValue::Bool(true)));
        }
        if packed_features && bits & 252 != 0 {
            spec.push((14, SpecValue::Bool(true)));
        }
        if median_coverage != DEFAULT_MEDIAN_COVERAGE {
            spec.push((13, SpecValue::F32(1.0 - median_coverage)));
        }
        if row_masks {
            spec.push((6, SpecValue::Bool(true)));
        }
        if tile_mask {
            spec.push((8, SpecValue::Bool(true)));
        }
        if texel {
            // PIXELS per invocation along x: TILE / PIXELS invocations across.
            spec[1].1 = SpecValue::U32(tile / pixels);
            spec.push((2, SpecValue::U32(pixels)));
            if self.pixel_reach {
                spec.push((7, SpecValue::Bool(true)));
            }
            if self.window_fetch {
                spec.push((9, SpecValue::Bool(true)));
                if self.two_splats_per_step {
                    spec.push((10, SpecValue::Bool(true)));
                }
            }
            if chunk_pass != 0 {
                spec.push((11, SpecValue::U32(chunk_pass)));
            }
            if chunk_length != 0 {
                spec.push((12, SpecValue::U32(chunk_length)));
            }
            // The frame; splats, features, sorted indices and pair row masks as
            // texel-buffer views; the split blend's buffers as push constants.
            let push = std::mem::size_of::<ChunkPush>();
            texel_view_kernel_pushing(&self.device, info, 4, push, &spec)
        } else {
            Ok(self.device.kernel(info, &KernelDecl::uniform(&spec))?)
        }
    }

    /// Renders `scene` from `camera` into new G-buffers.
    pub fn render(
        &mut self,
        scene: &GpuScene,
        camera: &Camera,
        settings: &SplatSettings,
    ) -> Result<(GpuGBuffer, SplatStats)> {
        // The frame is dropped: nothing will differentiate it, so no pair tiles.
        let frame =
            self.render_view(scene, View { camera, occluder: None, tile_mask: None, pair_tiles: false }, settings)?;
        Ok((frame.gbuffer, frame.stats))
    }

    /// Renders like [`Splatter::render`] and keeps the per-frame buffers.
    pub fn render_frame(&mut self, scene: &GpuScene, camera: &Camera, settings: &SplatSettings) -> Result<SplatFrame> {
        self.render_frame_with(scene, camera, settings, None)
    }

    /// Renders like [`Splatter::render_frame`] in front of a host's depth:
    /// `depth` holds one f32 per pixel (row-major, the camera's size) in the
    /// `convention` given; a splat whose depth at a pixel is not in front of
    /// the host's there is hidden (it neither contributes nor occludes), so
    /// compositing the premultiplied result over the host's colour,
    /// `rgb + (1 − alpha)·host`, puts the splats in front of the host's meshes
    /// and behind them where the meshes are nearer. Pinhole cameras; the
    /// splat backward pass refuses such frames.
    pub fn render_frame_occluded(
        &mut self,
        scene: &GpuScene,
        camera: &Camera,
        settings: &SplatSettings,
        depth: &Buffer,
        convention: HostDepth,
    ) -> Result<SplatFrame> {
        convention.validate()?;
        let need = u64::from(camera.width) * u64::from(camera.height) * 4;
        if depth.size() < need {
            return Err(Error::invalid(
                format!("host depth buffer of {} bytes", depth.size()),
                format!("is smaller than {need} bytes (one f32 per pixel of {}x{})", camera.width, camera.height),
            ));
        }
        if camera.depth_is_distance() {
            return Err(Error::invalid("host depth", "needs a camera whose depth is camera z (not a panorama)"));
        }
        self.render_frame_with(scene, camera, settings, Some((depth, convention)))
    }

    /// Renders only the tiles `tile_mask` wants (one u32 per tile of
    /// `camera` at `settings.tile`, row-major, non-zero: wanted): splats get
    /// pairs only there, and only their pixels are written, which in the
    /// wanted tiles are [`Splatter::render_frame`]'s, bit for bit (the same
    /// splats in the same order). The other tiles' pixels are not written:
    /// they hold whatever the G-buffer's buffers held (`settings.prefill`
    /// where set). A shadow map needs only the tiles its receivers look up
    /// (`ShadowSettings::cull_to_receivers`).
    pub fn render_frame_in_tiles(
        &mut self,
        scene: &GpuScene,
        camera: &Camera,
        settings: &SplatSettings,
        tile_mask: &Buffer,
    ) -> Result<SplatFrame> {
        self.render_frame_for(scene, camera, settings, Some(tile_mask), true)
    }

    /// [`Splatter::render_frame`], or with a tile mask [`Splatter::render_frame_in_tiles`],
    /// keeping the pairs' tile ids or not ([`SplatFrame::pair_tiles`]).
    pub(crate) fn render_frame_for(
        &mut self,
        scene: &GpuScene,
        camera: &Camera,
        settings: &SplatSettings,
        tile_mask: Option<&Buffer>,
        pair_tiles: bool,
    ) -> Result<SplatFrame> {
        let Some(tile_mask) = tile_mask else {
            return self.render_view(scene, View { camera, occluder: None, tile_mask: None, pair_tiles }, settings);
        };
        let tile = u64::from(settings.tile.max(1));
        let tiles = u64::from(camera.width).div_ceil(tile) * u64::from(camera.height).div_ceil(tile);
        if tile_mask.size() < tiles * 4 {
            return Err(Error::invalid(
                format!("tile mask of {} bytes", tile_mask.size()),
                format!("is smaller than one u32 per tile ({tiles} tiles)"),
            ));
        }
        if camera.wrap_period().is_some() {
            return Err(Error::invalid("tile mask", "needs a camera whose tiles do not wrap (not a full panorama)"));
        }
        self.render_view(scene, View { camera, occluder: None, tile_mask: Some(tile_mask), pair_tiles }, settings)
    }

    fn render_frame_with(
        &mut self,
        scene: &GpuScene,
        camera: &Camera,
        settings: &SplatSettings,
        occluder: Option<(&Buffer, HostDepth)>,
    ) -> Result<SplatFrame> {
        // The backward pass refuses frames hidden behind a host's depth: they need no pair tiles.
        let pair_tiles = occluder.is_none();
        self.render_view(scene, View { camera, occluder, tile_mask: None, pair_tiles }, settings)
    }

    /// One view's frame ([`Splatter::render_views`] of just it).
    fn render_view(&mut self, scene: &GpuScene, view: View<'_>, settings: &SplatSettings) -> Result<SplatFrame> {
        let frame = self.render_views(scene, &[view], settings)?.pop();
        frame.ok_or_else(|| Error::Internal("a one-camera render returned no frame".into()))
    }

    /// Renders `scene` from each of `cameras` with the same settings: the
    /// frames [`Splatter::render_frame`] gives for each (the same bits), but
    /// with one GPU submission per step for up to [`FRAMES_PER_SUBMISSION`]
    /// cameras at a time (their preprocessing and scans, one read of all their
    /// pair counts, then their sorts and blends), not two submissions and a
    /// readback per camera. Every frame's buffers are held until returned, so
    /// the caller chooses how many cameras to pass at once.
    pub fn render_frames(
        &mut self,
        scene: &GpuScene,
        cameras: &[Camera],
        settings: &SplatSettings,
    ) -> Result<Vec<SplatFrame>> {
        self.render_cameras(scene, cameras, settings, true)
    }

    /// [`Splatter::render_frames`], keeping the pair tiles or not ([`View::pair_tiles`]).
    fn render_cameras(
        &mut self,
        scene: &GpuScene,
        cameras: &[Camera],
        settings: &SplatSettings,
        pair_tiles: bool,
    ) -> Result<Vec<SplatFrame>> {
        let views: Vec<View<'_>> =
            cameras.iter().map(|camera| View { camera, occluder: None, tile_mask: None, pair_tiles }).collect();
        let mut frames = Vec::with_capacity(cameras.len());
        for group in views.chunks(FRAMES_PER_SUBMISSION) {
            frames.extend(self.render_views(scene, group, settings)?);
        }
        Ok(frames)
    }

    /// Renders like [`Splatter::render_frames`] and keeps only the G-buffers
    /// and stats, as [`Splatter::render`] does for one camera.
    pub fn render_batch(
        &mut self,
        scene: &GpuScene,
        cameras: &[Camera],
        settings: &SplatSettings,
    ) -> Result<Vec<(GpuGBuffer, SplatStats)>> {
        // The frames are dropped: nothing will differentiate them, so no pair tiles.
        let frames = self.render_cameras(scene, cameras, settings, false)?;
        Ok(frames.into_iter().map(|f| (f.gbuffer, f.stats)).collect())
    }

    /// Everything [`Splatter::render_views`] needs to know about one view
    /// before its splats are counted: its uniform, G-buffers and, compacted,
    /// the Gaussians' flags ([`Splatter::reserve_records`] adds the records).
    fn prepare_view(&self, scene: &GpuScene, view: &View<'_>, settings: &SplatSettings) -> Result<PendingView> {
        let device = &self.device;
        let (camera, tile, ch) = (view.camera, settings.tile, settings.channels);
        let n = scene.count as u64;
        let (w, h) = (camera.width, camera.height);
        let (tiles_x, tiles_y) = (w.div_ceil(tile), h.div_ceil(tile));
        let tiles = u64::from(tiles_x) * u64::from(tiles_y);
        let pixels = u64::from(w) * u64::from(h);
        // Tile columns and rows below 2^22 (a wrapping panorama's rectangle reaches twice
        // across): the kernels count them in floats (`whole_to_uint`, exact below 2^23).
        if tiles >= 1 << 32 || pixels * 3 >= 1 << 32 || tiles_x >= 1 << 22 || tiles_y >= 1 << 22 {
            return Err(Error::invalid(format!("image {w}x{h}"), "is too large"));
        }
        let mut frame = FrameUniform::zeroed();
        camera_frame(camera, &mut frame)?;
        frame.background = [settings.background[0], settings.background[1], settings.background[2], 0.0];
        frame.occluder = view.occluder.map_or([0.0; 4], |(_, c)| c.packed());
        frame.size = [w, h, tiles_x, tiles_y];
        // The position cull keeps splats for the image's tiles, or a mask's wanted ones
        // (their bounds, and each tile row's wanted columns).
        let mut wanted_rows = None;
        frame.cull_tiles = match view.tile_mask {
            Some(mask) => {
                let words: Vec<u32> = device.read_buffer(mask)?;
                let (rows, bounds) = wanted_spans(words.get(..tiles as usize).unwrap_or(&words), tiles_x, tiles_y);
                wanted_rows = Some(device.upload("wanted tile rows", &rows)?);
                bounds
            }
            None => [0, 0, tiles_x, tiles_y],
        };
        let sh_used = sh_degree_used(scene, settings);
        frame.counts =
            [n as u32, scene.sh_degree | sh_used << 8, u32::from(settings.normal_source == NormalSource::Stored), 0];

        let f = |name: &str, floats: u64| device.create_buffer(name, floats * 4, MemoryKind::Storage);
        let opt = |on: bool, name: &str, floats: u64| on.then(|| f(name, floats)).transpose();
        let out = GpuGBuffer {
            width: w,
            height: h,
            rgb: opt(settings.rgb, "gbuffer rgb", 3 * pixels)?,
            alpha: f("gbuffer alpha", pixels)?,
            channels: PerChannel::try_from_fn(|c| {
                opt(ch.has(c), &format!("gbuffer {}", c.name()), c.floats() as u64 * pixels)
            })?,
            top_gaussian: opt(ch.top_gaussian, "gbuffer top gaussian", pixels)?,
        };
        Ok(PendingView {
            camera: camera.clone(),
            frame,
            out,
            visible: settings
                .compact_splats
                .then(|| device.create_buffer("visible slots", (n + 1) * 4, MemoryKind::Storage))
                .transpose()?,
            records: None,
            wanted_rows,
            ranges: device.create_buffer("tile ranges", tiles * 8, MemoryKind::Storage)?,
            uniform: device.create_buffer(
                "splat frame",
                std::mem::size_of::<FrameUniform>() as u64,
                MemoryKind::Storage,
            )?,
            tiles,
        })
    }

    /// A view's splat records: `count` records (with slot ids where compacted).
    fn reserve_records(&self, settings: &SplatSettings, count: u64) -> Result<SplatRecords> {
        let device = &self.device;
        let storage = |name: &str, bytes: u64| device.create_buffer(name, bytes, MemoryKind::Storage);
        Ok(SplatRecords {
            splats: storage("splats", count * SPLAT_BYTES)?,
            features: settings
                .channels
                .needs_features()
                .then(|| storage("splat features", count * feature_bytes(settings)))
                .transpose()?,
            tile_counts: storage("tile counts", (count + 1) * 4)?,
            slot_gaussians: settings.compact_splats.then(|| storage("slot gaussians", count * 4)).transpose()?,
            count,
        })
    }

    /// The sort's and blend's buffers and kernels for a view of `pairs` pairs.
    fn plan_sort(
        &self,
        view: &View<'_>,
        pending: &PendingView,
        settings: &SplatSettings,
        pairs: u64,
    ) -> Result<SortPlan> {
        let device = &self.device;
        let (tile, tiles, n) = (settings.tile, pending.tiles, u64::from(pending.frame.counts[0]));
        let max_texels = device.info().max_texel_buffer_elements;
        // Tile ids 0..=tiles (`tiles` marks the keys kernel's padding) above the depth key.
        let depth_key = DepthKey::of(view.camera);
        let depth_bits = depth_key.bits;
        let key_bits = depth_bits + (64 - tiles.leading_zeros());
        // Texel-buffer reads where the device has RGBA32F/R32UI views and the splats and pairs fit them.
        let texel = self.texel_blend
            && self.blend_variant == BlendVariant::SubgroupLoads
            && n > 0
            && 4 * n <= max_texels
            && 2 * pairs <= max_texels;
        // The texel blend skips a splat for the blocks of its tile it cannot
        // reach: each key's high word carries them above the tile id where
        // both fit (splat_keys.comp).
        let row_masks = texel && key_bits + tile <= 64;
        let depth_spec = (3, SpecValue::U32(depth_bits));
        let range_pairs = (4, SpecValue::U32(RANGE_PAIRS));
        let ellipse = SpecValue::Bool(settings.tile_bounds == TileBounds::Ellipse);
        let mask = (4, SpecValue::Bool(view.tile_mask.is_some()));
        let shift = (5, SpecValue::U32(depth_key.shift));
        let keys_spec = [
            (1, ellipse),
            (2, SpecValue::Bool(row_masks)),
            depth_spec,
            mask,
            shift,
            (6, SpecValue::Bool(view.pair_tiles)),
            tile_spec(tile)[0],
        ];
        // The keys kernel reads the splats and offsets through texel views where it can.
        let texel_keys = self.texel_preprocess
            && [TexelFormat::Rgba32Uint, TexelFormat::R32Uint].iter().all(|f| device.info().texel_formats.contains(f))
            && 4 * n <= max_texels
            && n < max_texels;
        let keys_kernel = if texel_keys {
            texel_view_kernel(device, &kernels::SPLAT_KEYS_TEXEL, 2, &keys_spec)?
        } else {
            device.kernel(&kernels::SPLAT_KEYS, &KernelDecl::uniform(&keys_spec))?
        };
        // The ranges kernel reads the sorted keys through an RG32UI view with the keys kernel's texel reads.
        let texel_ranges =
            texel_keys && device.info().texel_formats.contains(&TexelFormat::Rg32Uint) && pairs <= max_texels;
        let blend = |chunk_pass, chunk_length| BlendOptions {
            bits: settings.channels.blend_bits(settings.rgb),
            tile,
            texel,
            wrap_x: view.camera.wrap_period().is_some(),
            surface: settings.surface_depth,
            occluded: view.occluder.is_some(),
            row_masks,
            tile_mask: view.tile_mask.is_some(),
            chunk_pass,
            chunk_length,
            median_coverage: settings.median_coverage,
            packed_features: settings.packed_features,
        };
        // The split blend: texel blends not in front of a host's depth, where a list can split.
        let chunks = match chunk_slots(pairs, tiles, tile, self.chunk_length) {
            Some((length, slots)) if texel && view.occluder.is_none() => Some(ChunkPlan {
                length,
                slots,
                pixels: u64::from(tile * tile),
                counts: device.kernel(
                    &kernels::SPLAT_CHUNK_COUNTS,
                    &KernelDecl {
                        bindings: &[BindingKind::UniformBuffer],
                        push_constant_size: std::mem::size_of::<ChunkCountPush>(),
                        specialization: &[(0, SpecValue::U32(length))],
                    },
                )?,
                passes: [
                    self.blend_kernel(blend(1, length))?,
                    self.blend_kernel(blend(2, length))?,
                    self.blend_kernel(blend(3, length))?,
                ],
            }),
            _ => None,
        };
        let chunk_length = chunks.as_ref().map_or(0, |c| c.length);
        Ok(SortPlan {
            keys: device.create_buffer("sort keys", pairs * 8, MemoryKind::Storage)?,
            values: device.create_buffer("sort values", pairs * 4, MemoryKind::Storage)?,
            pair_tiles: if view.pair_tiles {
                Some(device.create_buffer("pair tiles", pairs * 4, MemoryKind::Storage)?)
            } else {
                None
            },
            keys_kernel,
            texel_keys,
            ranges_kernel: if texel_ranges {
                texel_view_kernel(device, &kernels::SPLAT_RANGES_TEXEL, 1, &[depth_spec, range_pairs])?
            } else {
                device.kernel(&kernels::SPLAT_RANGES, &KernelDecl::uniform(&[depth_spec, range_pairs]))?
            },
            texel_ranges,
            blend: self.blend_kernel(blend(0, chunk_length))?,
            chunks,
            pairs,
            key_bits,
            // Nothing reads a sorted key's depth bits; the values are record indices below n.
            packing: PairPacking {
                unused_low_bits: depth_bits,
                value_bits: u64::BITS - n.saturating_sub(1).leading_zeros(),
                high_bits: if row_masks { tile } else { 0 },
            },
            texel,
            row_masks,
        })
    }

    /// Renders `views` (at most [`FRAMES_PER_SUBMISSION`]) with two
    /// submissions: preprocess and scan of every view, then keys, sort,
    /// ranges and blend of every view; compacted records
    /// ([`SplatSettings::compact_splats`]) add a first one, the position cull
    /// and its scan, whose totals size the records.
    fn render_views(
        &mut self,
        scene: &GpuScene,
        views: &[View<'_>],
        settings: &SplatSettings,
    ) -> Result<Vec<SplatFrame>> {
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
        check_median_coverage("median coverage", settings.median_coverage)?;
        let n = scene.count as u64;
        if n >= u64::from(u32::MAX) {
            return Err(Error::invalid(format!("scene of {n} Gaussians"), "exceeds the 2³² − 1 the kernels index"));
        }
        if views.is_empty() {
            return Ok(Vec::new());
        }
        // The scene arrays the texel preprocess views (binding 1 on), each in its format.
        let scene_inputs = [&scene.means, &scene.log_scales, &scene.rotations, &scene.opacity_logits, &scene.sh];
        let formats = preprocess_view_formats(
            &device.info().texel_formats,
            device.info().max_texel_buffer_elements,
            scene_inputs.map(Buffer::size),
            scene.sh_degree,
        )
        .filter(|_| self.texel_preprocess && n > 0);
        let texel_preprocess = formats.is_some();
        let ellipse = SpecValue::Bool(settings.tile_bounds == TileBounds::Ellipse);
        let surface = SpecValue::Bool(settings.surface_depth);
        let features = SpecValue::Bool(ch.needs_features());
        let packed = SpecValue::Bool(ch.needs_features() && settings.packed_features);
        // The SH degree used (as in each view's uniform, `FrameUniform::counts`).
        let sh_used = SpecValue::U32(sh_degree_used(scene, settings));
        // Every view of one call masks its tiles or none does (one preprocess kernel).
        let masked = views.iter().any(|v| v.tile_mask.is_some());
        if masked && views.iter().any(|v| v.tile_mask.is_none()) {
            return Err(Error::Internal("views of one render either all mask their tiles or none does".into()));
        }
        let mask_spec = SpecValue::Bool(masked);
        let formats = formats.unwrap_or([TexelFormat::R32Float; 5]);
        let vec3_inputs = texel_preprocess && formats[0] == TexelFormat::Rgb32Float;
        let vec4_inputs = texel_preprocess && formats[2] == TexelFormat::Rgba32Float;
        let sh_vec4 = texel_preprocess && formats[4] == TexelFormat::Rgba32Float;
        let mut preprocess_spec = vec![
            (0, features),
            (1, ellipse),
            (2, surface),
            (3, sh_used),
            (5, mask_spec),
            (9, packed),
            // Without rgb no SH coefficient is read (the records' colour is 0).
            (11, SpecValue::Bool(settings.rgb)),
            // Only the attributes of the feature channels blended are read.
            (12, SpecValue::U32(ch.bits() & FEATURE_CHANNEL_BITS)),
            tile_spec(tile)[0],
        ];
        if texel_preprocess {
            preprocess_spec.extend([
                (6, SpecValue::Bool(vec4_inputs)),
                (7, SpecValue::Bool(sh_vec4)),
                (8, SpecValue::Bool(vec3_inputs)),
            ]);
        }
        // COMPACT (spec 10): 0 a record per Gaussian; 1 flag the position cull's
        // survivors; 2 their records at the scanned slots.
        let compact = settings.compact_splats;
        let preprocess_kernel = |stage: u32| -> Result<Arc<Kernel>> {
            let mut spec = preprocess_spec.clone();
            spec.push((10, SpecValue::U32(stage)));
            if texel_preprocess {
                texel_view_kernel(&device, &kernels::SPLAT_PREPROCESS_TEXEL, 5, &spec)
            } else {
                Ok(device.kernel(&kernels::SPLAT_PREPROCESS, &KernelDecl::uniform(&spec))?)
            }
        };
        let preprocess = preprocess_kernel(if compact { 2 } else { 0 })?;
        let cull = compact.then(|| preprocess_kernel(1)).transpose()?;
        let mut pending =
            views.iter().map(|view| self.prepare_view(scene, view, settings)).collect::<Result<Vec<_>>>()?;
        self.scan.reserve(&device, n + 1)?;
        let readback = |name| device.create_buffer(name, 4 * views.len() as u64, MemoryKind::Readback);
        let texel_inputs = texel_preprocess.then_some((scene_inputs, formats));
        let scan = &self.scan;

        // Phase 0, compacted records: flag and scan the Gaussians the position cull keeps; each total sizes its records.
        let mut phase0_marks = Vec::with_capacity(views.len());
        let (phase0, records) = match &cull {
            Some(cull) => {
                let totals = readback("visible counts")?;
                let timings = device.run(|rec| -> Result<()> {
                    for (i, (p, view)) in pending.iter().zip(views).enumerate() {
                        phase0_marks.push(rec.stages_begun());
                        let visible = p.visible.as_ref().ok_or_else(|| Error::Internal("no visible slots".into()))?;
                        p.frame.record(rec, &p.uniform, &p.buffers(scene, view, None))?;
                        rec.begin_stage("cull");
                        // The cull writes every Gaussian's flag; the scan's total word starts at 0.
                        if let Some(word) = settings.prefill {
                            rec.fill(visible, word)?;
                        }
                        rec.fill_words(visible, n, 1, 0)?;
                        dispatch_preprocess(rec, cull, &p.uniform, texel_inputs, n)?;
                        scan.record(rec, visible, n + 1)?;
                        rec.end_stage();
                        rec.copy(visible, 4 * n, &totals, 4 * i as u64, 4)?;
                    }
                    Ok(())
                })?;
                let counts: Vec<u32> = device.read_mapped(&totals)?;
                (Some(timings), counts.into_iter().map(u64::from).collect())
            }
            None => (None, vec![n; views.len()]),
        };
        for (p, &count) in pending.iter_mut().zip(&records) {
            p.records = Some(self.reserve_records(settings, count)?);
        }
        let counts = readback("pair counts")?;

        // Phase 1, every view: preprocess and scan the tile counts; each total sizes its phase 2.
        let preprocess = &*preprocess;
        let mut phase1_marks = Vec::with_capacity(views.len());
        let phase1 = device.run(|rec| -> Result<()> {
            for (i, (p, view)) in pending.iter().zip(views).enumerate() {
                phase1_marks.push(rec.stages_begun());
                let r = p.records()?;
                p.frame.record(rec, &p.uniform, &p.buffers(scene, view, None))?;
                rec.begin_stage("preprocess");
                // The kernel writes every record's count (0 where it culls); the scan's total word starts at 0.
                if let Some(word) = settings.prefill {
                    rec.fill(&r.tile_counts, word)?;
                }
                rec.fill_words(&r.tile_counts, r.count, 1, 0)?;
                dispatch_preprocess(rec, preprocess, &p.uniform, texel_inputs, n)?;
                rec.begin_stage("scan");
                scan.record(rec, &r.tile_counts, r.count + 1)?;
                rec.end_stage();
                rec.copy(&r.tile_counts, 4 * r.count, &counts, 4 * i as u64, 4)?;
            }
            Ok(())
        })?;
        let pair_counts: Vec<u32> = device.read_mapped(&counts)?;
        for p in &mut pending {
            // The slots are in the records now; later kernels index records.
            p.visible = None;
        }

        // Phase 2, every view: keys, sort, ranges, blend.
        let plans = views
            .iter()
            .zip(&mut pending)
            .zip(&pair_counts)
            .map(|((view, p), &pairs)| {
                p.frame.counts[0] = p.records()?.count as u32;
                p.frame.counts[3] = pairs;
                self.plan_sort(view, p, settings, u64::from(pairs))
            })
            .collect::<Result<Vec<_>>>()?;
        self.sort.reserve(&device, plans.iter().map(|s| s.pairs).max().unwrap_or(0))?;
        // The split blend scans each view's chunk counts into its scratch, shared by the views.
        for (c, p) in plans.iter().zip(&pending).filter_map(|(s, p)| s.chunks.as_ref().map(|c| (c, p))) {
            self.scan.reserve(&device, p.tiles + 1)?;
            self.chunk_scratch.reserve(&device, p.tiles, c.slots, c.pixels)?;
        }
        let (sort, scan, chunk_scratch) = (&self.sort, &self.scan, &self.chunk_scratch);
        // Each view's chunk count (the split blend's), read back with the frame where any view splits.
        let chunk_counts = plans
            .iter()
            .any(|s| s.chunks.is_some())
            .then(|| device.create_buffer("chunk counts", 4 * views.len() as u64, MemoryKind::Readback))
            .transpose()?;
        // Top-Gaussian ids leave as the scene's: record slots mapped to their
        // Gaussians (compacted), an arranged scene's rows to file order (scene::order).
        let id_map = (ch.top_gaussian && (compact || scene.row_order().is_some()))
            .then(|| ReorderKernels::new(&device))
            .transpose()?;
        let mut phase2_marks = Vec::with_capacity(views.len());
        let phase2 = device.run(|rec| -> Result<()> {
            if let Some(counts) = &chunk_counts {
                rec.fill(counts, 0)?;
            }
            for (i, ((p, s), view)) in pending.iter().zip(&plans).zip(views).enumerate() {
                phase2_marks.push(rec.stages_begun());
                let r = p.records()?;
                p.frame.record(rec, &p.uniform, &p.buffers(scene, view, Some(s)))?;
                if let Some(word) = settings.prefill {
                    for b in [&p.out.alpha]
                        .into_iter()
                        .chain(p.out.rgb.as_ref())
                        .chain(p.out.channels.iter().map(|(_, b)| b))
                        .chain(&p.out.top_gaussian)
                    {
                        rec.fill(b, word)?;
                    }
                }
                if s.pairs > 0 {
                    rec.begin_stage("keys");
                    if s.texel_keys {
                        let bindings = [
                            Binding::Buffer(&p.uniform),
                            Binding::Texels(Texels {
                                buffer: &r.splats,
                                offset: 0,
                                elements: 4 * r.count,
                                format: TexelFormat::Rgba32Uint,
                            }),
                            Binding::Texels(Texels {
                                buffer: &r.tile_counts,
                                offset: 0,
                                elements: r.count + 1,
                                format: TexelFormat::R32Uint,
                            }),
                        ];
                        rec.dispatch(&s.keys_kernel, Grid::Items(r.count), &bindings, &())?;
                    } else {
                        rec.dispatch(&s.keys_kernel, Grid::Items(r.count), &[Binding::from(&p.uniform)], &())?;
                    }
                    rec.begin_stage("sort");
                    sort.record_with(rec, &s.keys, &s.values, s.pairs, s.key_bits, Some(s.packing))?;
                }
                rec.begin_stage("ranges");
                rec.fill(&p.ranges, 0)?;
                if s.pairs > 0 && s.texel_ranges {
                    let keys = Texels { buffer: &s.keys, offset: 0, elements: s.pairs, format: TexelFormat::Rg32Uint };
                    let bindings = [Binding::Buffer(&p.uniform), Binding::Texels(keys)];
                    rec.dispatch(&s.ranges_kernel, Grid::Items(s.pairs.div_ceil(RANGE_PAIRS.into())), &bindings, &())?;
                } else if s.pairs > 0 {
                    let grid = Grid::Items(s.pairs.div_ceil(RANGE_PAIRS.into()));
                    rec.dispatch(&s.ranges_kernel, grid, &[Binding::from(&p.uniform)], &())?;
                }
                rec.begin_stage("blend");
                let mut chunk_push = ChunkPush::zeroed();
                if let Some(c) = &s.chunks {
                    let unreserved = || Error::Internal("the split blend's scratch was not reserved".into());
                    let (first_slots, transmittance, partials) = chunk_scratch.buffers().ok_or_else(unreserved)?;
                    let counts = chunk_counts.as_ref().ok_or_else(unreserved)?;
                    chunk_push = ChunkPush {
                        slots: rec.addr(first_slots)?,
                        transmittance: rec.addr(transmittance)?,
                        partials: rec.addr(partials)?,
                    };
                    // Each tile's chunk count, scanned into its first slot.
                    rec.fill(first_slots, 0)?;
                    let push = ChunkCountPush { counts: chunk_push.slots };
                    rec.dispatch(&c.counts, Grid::Items(p.tiles), &[Binding::from(&p.uniform)], &push)?;
                    scan.record(rec, first_slots, p.tiles + 1)?;
                    rec.copy(first_slots, 4 * p.tiles, counts, 4 * i as u64, 4)?;
                }
                if s.texel {
                    let view = |buffer, elements| {
                        Binding::Texels(Texels { buffer, offset: 0, elements, format: TexelFormat::Rgba32Float })
                    };
                    let uints = |buffer, elements| {
                        Binding::Texels(Texels { buffer, offset: 0, elements, format: TexelFormat::R32Uint })
                    };
                    // Features, three texels a splat: RG32UI when packed, else RGBA32UI
                    // (the floats' bits); without them the kernel never reads binding 2,
                    // and a texel of the splats stands in.
                    let format = if settings.packed_features { TexelFormat::Rg32Uint } else { TexelFormat::Rgba32Uint };
                    let words = |buffer, elements| Binding::Texels(Texels { buffer, offset: 0, elements, format });
                    let features = r.features.as_ref().map_or(words(&r.splats, 1), |fb| words(fb, 3 * r.count));
                    let bindings = [
                        Binding::Buffer(&p.uniform),
                        view(&r.splats, 4 * r.count),
                        features,
                        uints(&s.values, s.pairs),
                        uints(&s.keys, 2 * s.pairs),
                    ];
                    rec.dispatch(&s.blend, Grid::Groups(p.tiles), &bindings, &chunk_push)?;
                    if let Some(c) = &s.chunks {
                        let [transmittance, chunk_blend, merge] = &c.passes;
                        rec.dispatch(transmittance, Grid::Groups(c.slots), &bindings, &chunk_push)?;
                        rec.dispatch(chunk_blend, Grid::Groups(c.slots), &bindings, &chunk_push)?;
                        rec.dispatch(merge, Grid::Groups(p.tiles), &bindings, &chunk_push)?;
                    }
                } else {
                    rec.dispatch(&s.blend, Grid::Groups(p.tiles), &[Binding::from(&p.uniform)], &())?;
                }
                if let (Some(top), Some(map)) = (&p.out.top_gaussian, &id_map) {
                    let pixels = u64::from(p.camera.width) * u64::from(p.camera.height);
                    if let Some(slots) = &r.slot_gaussians {
                        map.record_ids_through(rec, top, pixels, slots, r.count)?;
                    }
                    if let Some(order) = scene.row_order() {
                        map.record_ids(rec, top, pixels, order)?;
                    }
                }
                rec.end_stage();
            }
            Ok(())
        })?;

        let chunks: Vec<u32> = match &chunk_counts {
            Some(counts) => device.read_mapped(counts)?,
            None => vec![0; views.len()],
        };
        let phase0 = match phase0 {
            Some(timings) => split_timings(timings, &phase0_marks),
            None => vec![Timings::default(); views.len()],
        };
        let phase1 = split_timings(phase1, &phase1_marks);
        let phase2 = split_timings(phase2, &phase2_marks);
        let scratch = self.sort.scratch_bytes() + self.scan.scratch_bytes() + self.chunk_scratch.bytes();
        let mut frames = Vec::with_capacity(views.len());
        for ((((((p, s), view), mut timings), preprocess), later), chunks) in
            pending.into_iter().zip(plans).zip(views).zip(phase0).zip(phase1).zip(phase2).zip(chunks)
        {
            timings.stages.extend(preprocess.stages);
            timings.stages.extend(later.stages);
            let r = p.records.ok_or_else(|| Error::Internal("a view's records were not reserved".into()))?;
            let working_bytes = r.splats.size()
                + r.features.as_ref().map_or(0, Buffer::size)
                + r.tile_counts.size()
                + r.slot_gaussians.as_ref().map_or(0, Buffer::size)
                + s.keys.size()
                + s.values.size()
                + s.pair_tiles.as_ref().map_or(0, Buffer::size)
                + p.ranges.size()
                + scratch;
            frames.push(SplatFrame {
                gbuffer: p.out,
                stats: SplatStats {
                    timings,
                    pairs: s.pairs,
                    key_bits: s.key_bits,
                    working_bytes,
                    row_masks: s.row_masks,
                    chunks: u64::from(chunks),
                    records: r.count,
                },
                camera: p.camera,
                splats: r.splats,
                pair_offsets: r.tile_counts,
                sorted_gaussians: s.values,
                slot_gaussians: r.slot_gaussians,
                pair_tiles: s.pair_tiles,
                ranges: p.ranges,
                features: r.features,
                uniform: p.uniform,
                params: p.frame,
                scene_means: scene.means.id(),
                gaussians: n,
                tile,
                surface_depth: settings.surface_depth,
                median_coverage: settings.median_coverage,
                packed_features: settings.packed_features && settings.channels.needs_features(),
                occluded: view.occluder.is_some(),
            });
        }
        Ok(frames)
    }
}

/// One preprocess dispatch over `n` Gaussians: the scene's arrays viewed as
/// texels in their formats (`texel_inputs`), or addressed through the uniform.
fn dispatch_preprocess<'a>(
    rec: &mut crate::gpu::Recording<'a>,
    kernel: &'a Kernel,
    uniform: &'a Buffer,
    texel_inputs: Option<([&'a Buffer; 5], [TexelFormat; 5])>,
    n: u64,
) -> Result<()> {
    match texel_inputs {
        Some((inputs, formats)) => {
            let mut bindings = vec![Binding::Buffer(uniform)];
            bindings.extend(inputs.iter().zip(formats).map(|(&buffer, format)| {
                let elements = buffer.size() / format.bytes();
                Binding::Texels(Texels { buffer, offset: 0, elements, format })
            }));
            rec.dispatch(kernel, Grid::Items(n), &bindings, &())?;
        }
        None => rec.dispatch(kernel, Grid::Items(n), &[Binding::from(uniform)], &())?,
    }
    Ok(())
}

/// The timed stages of a splat frame, in pipeline order ([`SplatStats::timings`]):
/// `cull` only with [`SplatSettings::compact_splats`]; a relit frame's shadow
/// map names its own with a `shadow map ` prefix.
pub const SPLAT_STAGES: [&str; 7] = ["cull", "preprocess", "scan", "keys", "sort", "ranges", "blend"];

/// Cameras whose preprocessing, and then whose sorts and blends, one
/// submission records ([`Splatter::render_frames`]); within the timestamp
/// queries one recording holds.
pub const FRAMES_PER_SUBMISSION: usize = 16;

/// Per-frame memory a batch of cameras may hold at once by default
/// ([`cameras_per_batch`]).
pub const BATCH_BYTES: u64 = 256 << 20;

/// How many cameras of `camera`'s size to pass to one
/// [`Splatter::render_frames`] call for a scene of `gaussians` so that the
/// batch's per-frame buffers stay near `budget` bytes, estimated from the
/// splat records, features and tile counts per Gaussian, about two sorted
/// pairs per Gaussian, and the G-buffer floats per pixel; at least 1, at
/// most [`FRAMES_PER_SUBMISSION`].
pub fn cameras_per_batch(gaussians: u64, camera: &Camera, settings: &SplatSettings, budget: u64) -> usize {
    let ch = settings.channels;
    let pixels = u64::from(camera.width) * u64::from(camera.height);
    let floats = 1
        + 3 * u64::from(settings.rgb)
        + ch.iter().map(|c| c.floats() as u64).sum::<u64>()
        + u64::from(ch.top_gaussian);
    let features = if ch.needs_features() { feature_bytes(settings) } else { 0 };
    let per_frame = gaussians.saturating_mul(SPLAT_BYTES + features + 4 + 2 * 16).saturating_add(pixels * floats * 4);
    (budget / per_frame.max(1)).clamp(1, FRAMES_PER_SUBMISSION as u64) as usize
}

/// One camera of a batch, with the host's depth it is rendered in front of.
#[derive(Clone, Copy)]
struct View<'a> {
    camera: &'a Camera,
    occluder: Option<(&'a Buffer, HostDepth)>,
    /// One u32 per tile, non-zero where pairs are wanted; `None`: every tile.
    tile_mask: Option<&'a Buffer>,
    /// Whether the frame keeps its pairs' tile ids ([`SplatFrame::pair_tiles`]).
    pair_tiles: bool,
}

/// A view's buffers before its pairs are counted.
struct PendingView {
    camera: Camera,
    frame: FrameUniform,
    out: GpuGBuffer,
    /// Compacted records: each Gaussian's flag, then its slot, until the records are written.
    visible: Option<Buffer>,
    /// Its splat records, once their count is known ([`Splatter::reserve_records`]).
    records: Option<SplatRecords>,
    /// With a tile mask: each tile row's wanted columns (`wanted_spans`).
    wanted_rows: Option<Buffer>,
    ranges: Buffer,
    uniform: Buffer,
    tiles: u64,
}

/// One view's splat records and what is kept per record.
struct SplatRecords {
    splats: Buffer,
    features: Option<Buffer>,
    /// Each record's tile count, then (scanned) its first pair; count + 1 u32.
    tile_counts: Buffer,
    /// Compacted: each record's Gaussian.
    slot_gaussians: Option<Buffer>,
    count: u64,
}

impl PendingView {
    fn records(&self) -> Result<&SplatRecords> {
        self.records.as_ref().ok_or_else(|| Error::Internal("a view's records were not reserved".into()))
    }

    /// The buffers its uniform addresses: the records' once reserved, the sort's once `sort` exists.
    fn buffers<'a>(&'a self, scene: &'a GpuScene, view: &View<'a>, sort: Option<&'a SortPlan>) -> FrameBuffers<'a> {
        let records = self.records.as_ref();
        FrameBuffers {
            scene,
            splats: records.map(|r| &r.splats),
            features: records.and_then(|r| r.features.as_ref()),
            tile_counts: records.map(|r| &r.tile_counts),
            visible_slots: self.visible.as_ref(),
            slot_gaussians: records.and_then(|r| r.slot_gaussians.as_ref()),
            keys: sort.map(|s| &s.keys),
            values: sort.map(|s| &s.values),
            pair_tiles: sort.and_then(|s| s.pair_tiles.as_ref()),
            ranges: &self.ranges,
            out: &self.out,
            occluder: view.occluder.map(|(b, _)| b),
            tile_mask: view.tile_mask,
            wanted_rows: self.wanted_rows.as_ref(),
        }
    }
}

/// A view's sort and blend, once its pairs are counted.
struct SortPlan {
    keys: Buffer,
    values: Buffer,
    /// `None` where the view keeps none ([`View::pair_tiles`]).
    pair_tiles: Option<Buffer>,
    keys_kernel: Arc<Kernel>,
    /// The keys kernel reads through texel views (`splat_keys_texel.comp`).
    texel_keys: bool,
    ranges_kernel: Arc<Kernel>,
    /// `ranges_kernel` reads the sorted keys through an RG32UI texel view.
    texel_ranges: bool,
    blend: Arc<Kernel>,
    /// The split blend, where a list of this view is long enough.
    chunks: Option<ChunkPlan>,
    pairs: u64,
    key_bits: u32,
    /// What the sort may drop to pack the pairs.
    packing: PairPacking,
    texel: bool,
    row_masks: bool,
}

/// The split blend's scratch memory, shared by every view of a call (their
/// blends run one after another), grown to the largest.
#[derive(Default)]
struct ChunkScratch {
    /// Each tile's first slot (then the total): its `list_chunks`, scanned.
    first_slots: Option<Buffer>,
    /// Per slot and tile pixel, the chunk's transmittance product.
    transmittance: Option<Buffer>,
    /// Per slot, partial sum and tile pixel, the chunk's blend.
    partials: Option<Buffer>,
}

impl ChunkScratch {
    /// Makes sure the buffers fit `tiles` tiles and `slots` slots of `pixels` pixels.
    fn reserve(&mut self, device: &Device, tiles: u64, slots: u64, pixels: u64) -> Result<()> {
        let grow = |b: &mut Option<Buffer>, name: &str, floats: u64| -> Result<()> {
            if b.as_ref().is_none_or(|b| b.size() < floats * 4) {
                *b = Some(device.create_buffer(name, floats * 4, MemoryKind::Storage)?);
            }
            Ok(())
        };
        grow(&mut self.first_slots, "chunk slots", tiles + 1)?;
        grow(&mut self.transmittance, "chunk transmittance", slots * pixels)?;
        grow(&mut self.partials, "chunk partials", slots * pixels * (CHUNK_FLOATS - 1))
    }

    /// The first slots, transmittance and partials, once reserved.
    fn buffers(&self) -> Option<(&Buffer, &Buffer, &Buffer)> {
        Some((self.first_slots.as_ref()?, self.transmittance.as_ref()?, self.partials.as_ref()?))
    }

    /// GPU bytes held.
    fn bytes(&self) -> u64 {
        [&self.first_slots, &self.transmittance, &self.partials]
            .iter()
            .filter_map(|b| b.as_ref().map(Buffer::size))
            .sum()
    }
}

/// A view's split blend (`CHUNK_PASS` in `splat_blend_body.glsl`).
struct ChunkPlan {
    /// Entries per chunk.
    length: u32,
    /// Chunk slots at most: the workgroups of passes 1 and 2.
    slots: u64,
    /// Pixels of a tile.
    pixels: u64,
    /// `splat_chunk_counts.comp`.
    counts: Arc<Kernel>,
    /// The blend's passes 1 (transmittance), 2 (chunk blend) and 3 (merge).
    passes: [Arc<Kernel>; 3],
}

/// Splits one submission's stage timings at `marks` (the stage count when
/// each view's recording began), one [`Timings`] per view.
fn split_timings(timings: Timings, marks: &[usize]) -> Vec<Timings> {
    let mut stages = timings.stages;
    let mut out: Vec<Timings> = Vec::with_capacity(marks.len());
    for &mark in marks.iter().rev() {
        let tail = stages.split_off(mark.min(stages.len()));
        out.push(Timings { stages: tail });
    }
    out.reverse();
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wanted_spans_hold_every_wanted_tile_and_no_more() {
        // 5 × 3 tiles: wanted (1, 0), (3, 2), (2, 1) and (4, 1).
        let mut mask = vec![0u32; 15];
        for (x, y) in [(1, 0), (3, 2), (2, 1), (4, 1)] {
            mask[y * 5 + x] = 7;
        }
        assert_eq!(wanted_spans(&mask, 5, 3), (vec![[1, 2], [2, 5], [3, 4]], [1, 0, 5, 3]));
        assert_eq!(wanted_spans(&[0; 15], 5, 3), (vec![[0, 0]; 3], [0; 4]), "none wanted: nothing kept");
        let mut one = vec![0u32; 15];
        one[14] = 1;
        assert_eq!(wanted_spans(&one, 5, 3), (vec![[0, 0], [0, 0], [4, 5]], [4, 2, 5, 3]), "the last tile alone");
        assert_eq!(wanted_spans(&[1; 15], 5, 3), (vec![[0, 5]; 3], [0, 0, 5, 3]), "every tile");
    }

    #[test]
    fn chunk_slots_hold_every_split_list_within_the_memory_cap() {
        assert_eq!((list_chunks(48, 24), list_chunks(49, 24), list_chunks(72, 24), list_chunks(73, 24)), (0, 3, 3, 4));
        assert_eq!((list_chunks(u32::MAX, 0), list_chunks(0, 24)), (0, 0));
        // No list can split: no plan.
        assert_eq!(chunk_slots(48, 10, 16, 24), None);
        assert_eq!(chunk_slots(1_000_000, 528, 16, 0), None);
        // Lists of many shapes (pairs spread over the tiles, a few long ones): the
        // chunks they split into never exceed the slots planned.
        let mut state = 12345u64;
        let mut next = |m: u64| {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (state >> 33) % m
        };
        for _ in 0..200 {
            let tiles = 1 + next(3000);
            let length = [1, 7, 24, 4096][next(4) as usize];
            let lists: Vec<u64> =
                (0..tiles).map(|_| if next(10) == 0 { next(200_000) } else { next(3 * length + 2) }).collect();
            let pairs: u64 = lists.iter().sum();
            let chunks: u64 = lists.iter().map(|&n| u64::from(list_chunks(n as u32, length as u32))).sum();
            match chunk_slots(pairs, tiles, 16, length as u32) {
                Some((l, slots)) => {
                    let at_l: u64 = lists.iter().map(|&n| u64::from(list_chunks(n as u32, l))).sum();
                    assert!(at_l <= slots, "{tiles} tiles, length {l}: {at_l} chunks in {slots} slots");
                    assert!(slots * 256 * CHUNK_FLOATS * 4 <= CHUNK_MEMORY);
                }
                None => assert_eq!(chunks, 0, "{tiles} tiles, {pairs} pairs at {length}: lists split but no plan"),
            }
        }
        // 30M pairs at 16 entries a chunk would need 37 GiB: the chunks grow until they fit.
        let grown = chunk_slots(30_000_000, 100_000, 32, 16);
        assert!(grown.is_some_and(|(l, slots)| l > 16 && slots * 1024 * CHUNK_FLOATS * 4 <= CHUNK_MEMORY), "{grown:?}");
    }

    #[test]
    fn preprocess_views_count_their_own_elements_against_the_limit() {
        use TexelFormat::{R32Float as R, Rgb32Float as Rgb, Rgba32Float as Rgba};
        let all = [R, Rgb, Rgba];
        let limit = 134_217_728; // lavapipe's maxTexelBufferElements
                                 // Bytes of a scene of `n` Gaussians at SH degree `d`: means, log-scales, rotations, opacities, SH.
        let bytes = |n: u64, d: u32| [12 * n, 12 * n, 16 * n, 4 * n, 12 * n * crate::scene::sh_coefficients(d) as u64];
        // 10M SH 3: 480M floats of SH, 120M RGBA32F texels: viewed.
        assert_eq!(preprocess_view_formats(&all, limit, bytes(10_000_000, 3), 3), Some([Rgb, Rgb, Rgba, R, Rgba]));
        // SH 1 fills vec4s too; SH 0 and 2 do not (R32F), and 10M SH 2 (270M floats) exceeds the limit.
        assert_eq!(preprocess_view_formats(&all, limit, bytes(1000, 1), 1), Some([Rgb, Rgb, Rgba, R, Rgba]));
        assert_eq!(preprocess_view_formats(&all, limit, bytes(1000, 2), 2), Some([Rgb, Rgb, Rgba, R, R]));
        assert_eq!(preprocess_view_formats(&all, limit, bytes(10_000_000, 2), 2), None);
        // 12M SH 3 needs 144M RGBA32F texels: too many.
        assert_eq!(preprocess_view_formats(&all, limit, bytes(12_000_000, 3), 3), None);
        // Without vector formats everything is R32F, counted as floats.
        assert_eq!(preprocess_view_formats(&[R], limit, bytes(1000, 3), 3), Some([R; 5]));
        assert_eq!(preprocess_view_formats(&[R], limit, bytes(12_000_000, 1), 1), None);
        // Without R32F, no texel preprocess at all.
        assert_eq!(preprocess_view_formats(&[Rgb, Rgba], limit, bytes(1000, 3), 3), None);
    }
}
