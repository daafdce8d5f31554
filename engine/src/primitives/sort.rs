//! Stable LSD radix sort of (64-bit key, u32 value) pairs on the GPU.
//!
//! Each pass sorts one digit in three steps: a histogram per invocation
//! of its [`sort_items`] consecutive keys (`sort_histogram.comp`), an
//! exclusive scan of that digit-major histogram ([`Scan`]), and a stable
//! scatter (`sort_scatter.comp`). Counts live in registers, never in shared
//! memory: on CPU implementations (lavapipe) shared-memory accesses indexed
//! by lane are loops over the lanes, and the earlier per-workgroup design
//! spent most of its scatter time in them. Only
//! `ceil(bits / 4)` passes run, so callers sort just the bits in use. The
//! kernels use no subgroup operations and no workgroup waits on another, so
//! the sort is correct for any subgroup size (lavapipe's is 8) and needs no
//! forward-progress guarantee. Keys are stored as `[low, high]` u32 pairs.
//! Where the device has RG32UI/R32UI texel buffers and the keys fit one view,
//! both kernels read keys and values through texel-buffer views
//! (`sort_*_texel.comp`: one vector gather per load on lavapipe, where a
//! device-address load is a loop over the lanes); outputs are written by address.
//!
//! Digits are 4 bits, counted in registers, except with wide digits
//! ([`wide_digits`], the default on CPU devices): up to 11 bits a pass
//! (`sort_*_wide_texel.comp`), counted in an array indexed by the digit, over
//! a few long runs of keys (two workgroups of 8 invocations per CPU thread,
//! so the digit-major histogram stays small). A GPU would spill such an array; a CPU
//! lane indexes it cheaply, and the sort makes a third of the passes. The bits
//! are spread evenly over the passes (31 bits: 11 + 10 + 10), and a digit may
//! straddle the key's two words.
//!
//! With block digits ([`SortDigits::Block`], [`default_sort_digits`] on GPUs), up to 8 bits
//! a pass (`sort_*_block.comp`): each workgroup of 128 invocations counts a
//! block of 128 × [`block_items`] keys in shared memory, and after the scan ranks
//! them stably by digit (ballots on the digit's bits within a subgroup,
//! counts across subgroups in shared memory), stages them in digit order
//! and writes each digit's run with neighbouring invocations on
//! neighbouring addresses: the stores a GPU coalesces, where a 4-bit
//! invocation's run scatters every key alone.
//!
//! Packed passes ([`RadixSort::set_packing`], [`RadixSort::record_with`]):
//! once the first pass has sorted its digit, nothing needs those bits again,
//! so where the caller does not read them after the sort ([`PairPacking`])
//! the first pass writes each pair as one 64-bit word: the key's remaining
//! sort bits, the value above them and the key's top bits in place. The
//! middle passes move words (one store a pair where a key and a value are
//! two), the last unpacks into the caller's buffers, so no copy back is
//! needed at any pass count. Block digits stage the pair in shared memory as
//! it came and pack or unpack it on the way out.

use bytemuck::{Pod, Zeroable};
use std::sync::Arc;

use super::scan::Scan;
use crate::error::{Error, Result};
use crate::gpu::ash::vk;
use crate::gpu::{
    kernels, Binding, BindingKind, Buffer, Device, DeviceAddress, DeviceInfo, Grid, Kernel, KernelDecl, KernelInfo,
    MemoryKind, Recording, SpecValue, TexelFormat, Texels,
};

/// Invocations per workgroup (keep in sync with the sort kernels' `WORKGROUP_SIZE_X`).
const SORT_WORKGROUP: u64 = 64;
/// Bits per pass (keep in sync with `RADIX` = 16).
pub(crate) const DIGIT_BITS: u32 = 4;
const RADIX: u64 = 16;

/// Keys per invocation (the kernels' `ITEMS`, specialization constant 0) on a
/// device of `device_type`: 256 on CPU devices (lavapipe), where 2 cores need
/// few invocations and a histogram a quarter the size costs its scan a quarter
/// (docs/bench/splat.md); 64 on GPUs, which need many invocations.
pub fn sort_items(device_type: vk::PhysicalDeviceType) -> u64 {
    if device_type == vk::PhysicalDeviceType::CPU {
        256
    } else {
        64
    }
}

/// Most bits a wide-digit pass sorts (keep in sync with `RADIX` under
/// `WIDE_DIGITS` in `sort_common.glsl`).
pub const WIDE_DIGIT_BITS: u32 = 11;
/// Invocations per workgroup of the wide-digit kernels (keep in sync with
/// `WORKGROUP_SIZE_X` under `WIDE_DIGITS` in `sort_common.glsl`): one CPU
/// SIMD row, so a workgroup is one CPU thread's run of keys.
const WIDE_WORKGROUP: u64 = 8;
/// Keys a wide-digit invocation gets at least, where the keys allow (so its
/// 2^bits counts do not outnumber its keys).
const WIDE_MIN_ITEMS: u64 = 2048;

/// Most bits a block-digit pass sorts (keep in sync with `RADIX` under
/// `BLOCK_DIGITS` in `sort_common.glsl`).
pub const BLOCK_DIGIT_BITS: u32 = 8;
/// Invocations per workgroup of the block-digit kernels (keep in sync with
/// `WORKGROUP_SIZE_X` under `BLOCK_DIGITS` in `sort_common.glsl`).
const BLOCK_WORKGROUP: u64 = 128;

/// Shared memory the block-digit scatter declares at `items` keys per
/// invocation, bytes (`sort_scatter_block.comp`: 16 subgroups' counts of 256
/// digits, three digit tables, the block's keys and values).
const fn block_shared_bytes(items: u32) -> u32 {
    16 * 256 * 4 + 3 * 256 * 4 + BLOCK_WORKGROUP as u32 * items * 12
}

/// The block-digit kernels' specialization on `info`'s device: [`block_items`] (constant 1).
fn block_specialization(info: &DeviceInfo) -> [(u32, SpecValue); 1] {
    [(1, SpecValue::U32(block_items(info)))]
}

/// Keys per invocation of the block-digit kernels on `info`'s device
/// (`BLOCK_ITEMS`, specialization constant 1): 16 where the scatter's
/// shared memory fits them (longer runs of each digit per block, so wider
/// stores), else 8.
pub fn block_items(info: &DeviceInfo) -> u32 {
    if info.max_shared_memory >= block_shared_bytes(16) {
        16
    } else {
        8
    }
}

/// How many bits a radix pass sorts and how ([`RadixSort::set_digits`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SortDigits {
    /// 4 bits, counted in registers per invocation: any device.
    Four,
    /// Up to 8 bits, ranked per workgroup block in shared memory and written
    /// digit run by digit run ([`block_digits_supported`]).
    Block,
    /// Up to 11 bits, counted per long run of keys in an array indexed by
    /// the digit: CPU devices ([`wide_digits_supported`]; texel inputs).
    Wide,
}

impl SortDigits {
    /// Parses `4`, `block` or `wide`.
    pub fn parse(text: &str) -> Result<Self> {
        match text {
            "4" => Ok(Self::Four),
            "block" => Ok(Self::Block),
            "wide" => Ok(Self::Wide),
            other => Err(Error::invalid(format!("sort digits \"{other}\""), "is not 4, block or wide")),
        }
    }

    /// Most bits a pass of these digits sorts.
    pub fn max_bits(self) -> u32 {
        match self {
            Self::Four => DIGIT_BITS,
            Self::Block => BLOCK_DIGIT_BITS,
            Self::Wide => WIDE_DIGIT_BITS,
        }
    }

    /// The name [`SortDigits::parse`] reads.
    pub fn name(self) -> &'static str {
        match self {
            Self::Four => "4",
            Self::Block => "block",
            Self::Wide => "wide",
        }
    }
}

/// The digits [`RadixSort::new`] sorts with on `info`'s device: wide on CPU
/// devices where [`wide_digits`] says so, block digits on other devices
/// where [`block_digits_supported`], else 4 bits.
pub fn default_sort_digits(info: &DeviceInfo) -> SortDigits {
    if wide_digits(info) {
        SortDigits::Wide
    } else if info.device_type != vk::PhysicalDeviceType::CPU && block_digits_supported(info) {
        SortDigits::Block
    } else {
        SortDigits::Four
    }
}

/// Whether block digits can run on `info`'s device: subgroup ballots, a
/// subgroup size from 8 to 128 that divides the workgroup's 128 invocations
/// (so a workgroup holds at most the 16 subgroups the scatter keeps counts
/// for), full subgroups (`computeFullSubgroups` enabled: the scatter places
/// keys by subgroup index), and room for the scatter's shared memory.
pub fn block_digits_supported(info: &DeviceInfo) -> bool {
    let size = info.subgroup_size;
    info.subgroup_ballot
        && (8..=BLOCK_WORKGROUP as u32).contains(&size)
        && BLOCK_WORKGROUP as u32 % size == 0
        && info.full_subgroups
        && info.max_shared_memory >= block_shared_bytes(8)
}

/// Whether [`RadixSort::new`] sorts with wide digits on `info`'s device: on
/// CPU devices (lavapipe), where a dynamically indexed per-invocation array
/// is ordinary memory; not on GPUs, which would spill it, and not on
/// lavapipe before Mesa 25 ([`wide_digits_supported`]).
pub fn wide_digits(info: &DeviceInfo) -> bool {
    info.device_type == vk::PhysicalDeviceType::CPU && wide_digits_supported(info)
}

/// Whether [`RadixSort::set_wide_digits`] may turn wide digits on: not on
/// lavapipe before Mesa 25, whose compiled wide kernels crash the process
/// (a segmentation fault inside the driver's code) on a few million keys
/// (Mesa 22.3.6: 4M keys crash, 1M do not; Mesa 25.0.7 sorts 16.8M).
pub fn wide_digits_supported(info: &DeviceInfo) -> bool {
    !(info.is_lavapipe() && info.mesa_version().is_some_and(|(major, _)| major < 25))
}

/// Entries of the digit-major histogram for `count` keys at `items` keys per
/// invocation: one column of `RADIX` counts per invocation of every block.
fn histogram_len(count: u64, items: u64) -> u64 {
    RADIX * count.div_ceil(items * SORT_WORKGROUP) * SORT_WORKGROUP
}

/// Workgroups of a wide-digit pass over `count` keys when the device runs
/// `threads` workgroups at once: two per thread, fewer where the keys are
/// too few for [`WIDE_MIN_ITEMS`] each. Few long runs of keys keep the
/// digit-major histogram (2^bits counts per invocation) and its scan small.
fn wide_blocks(count: u64, threads: u64) -> u64 {
    count.div_ceil(WIDE_WORKGROUP * WIDE_MIN_ITEMS).clamp(1, 2 * threads.max(1))
}

/// The passes of a sort on `bits` bits at most `width` bits each, as (shift,
/// digit bits): as few passes as `width` allows, the bits spread evenly over
/// them (wider digits first).
pub(crate) fn digit_passes(bits: u32, width: u32) -> Vec<(u32, u32)> {
    let passes = bits.div_ceil(width.max(1));
    let mut shift = 0;
    (0..passes)
        .map(|p| {
            let digit = bits / passes + u32::from(p < bits % passes);
            shift += digit;
            (shift - digit, digit)
        })
        .collect()
}

/// Push constants of `sort_histogram.comp` and `sort_scatter.comp` (`SortPush`
/// in `sort_common.glsl`; checked by `check_layout`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub(crate) struct SortPush {
    /// The input keys (`[u32; 2]` each).
    pub keys_in: DeviceAddress,
    /// The input values.
    pub values_in: DeviceAddress,
    /// The output keys.
    pub keys_out: DeviceAddress,
    /// The output values.
    pub values_out: DeviceAddress,
    /// The digit-major histogram (one column per invocation).
    pub hist: DeviceAddress,
    /// Number of pairs.
    pub count: u32,
    /// Bit position of this pass's digit.
    pub shift: u32,
    /// Number of blocks.
    pub blocks: u32,
    /// Mask of this pass's digit: 15, or fewer bits on the last pass.
    pub digit_mask: u32,
    /// Packed passes: the first digit's bits, which the words drop.
    pub pack_drop: u32,
    /// Packed passes: the sort bits a word keeps above the first digit.
    pub pack_field: u32,
    /// Packed passes: the key's top bits a word keeps in place.
    pub pack_high: u32,
    /// Padding.
    pub pack_pad: u32,
}
crate::gpu::gpu_layout!(
    SortPush,
    "SortPush",
    [
        keys_in, values_in, keys_out, values_out, hist, count, shift, blocks, digit_mask, pack_drop, pack_field,
        pack_high, pack_pad
    ]
);

/// What a caller lets a sort drop from its pairs, so that every pass after
/// the first moves each pair as one 64-bit word ([`RadixSort::record_with`]):
/// the key's sort bits above the first digit, the value above them, and the
/// key's top `high_bits` in place. The first pass packs, the last unpacks:
/// one store a pair in every pass but the last, where a key and a value are
/// two. The sorted keys come back with their first digit's bits zeroed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PairPacking {
    /// Low key bits nobody reads after the sort (the first digit may be zeroed if it fits them).
    pub unused_low_bits: u32,
    /// Bits every value fits in (at most 32).
    pub value_bits: u32,
    /// Top key bits, above the sort bits, read after the sort; the key's
    /// bits between the sort bits and these must be zero.
    pub high_bits: u32,
}

impl PairPacking {
    /// Whether a sort on `bits` bits whose first digit has `first_digit` bits can pack its pairs.
    pub fn fits(&self, bits: u32, first_digit: u32) -> bool {
        first_digit <= self.unused_low_bits
            && first_digit < bits
            && self.value_bits <= 32
            && bits + self.high_bits <= 64
            && bits - first_digit + self.value_bits + self.high_bits <= 64
    }
}

/// Scatter kernels of packed passes: packing, moving words, unpacking.
type PackedScatters = [Arc<Kernel>; 3];

/// The packed scatter variants of each scatter kernel ([`RadixSort::set_packing`]),
/// built for the digits the sort takes.
#[derive(Default)]
struct PackedKernels {
    address: Option<PackedScatters>,
    texel: Option<PackedScatters>,
    wide: Option<PackedScatters>,
    block: Option<PackedScatters>,
}

/// Builds `info`'s three packed variants (`PACKED_IN` / `PACKED_OUT`,
/// specialization constants 2 and 3) with `views` texel views and the
/// scatter's own `specialization`.
fn packed_scatters(
    device: &Device,
    info: &'static KernelInfo,
    views: usize,
    specialization: &[(u32, SpecValue)],
) -> Result<PackedScatters> {
    let variant = |packed_in: bool, packed_out: bool| {
        let mut specialization = specialization.to_vec();
        specialization.extend([(2, SpecValue::Bool(packed_in)), (3, SpecValue::Bool(packed_out))]);
        let decl = KernelDecl {
            bindings: &[BindingKind::UniformTexelBuffer; 4][..views],
            push_constant_size: std::mem::size_of::<SortPush>(),
            specialization: &specialization,
        };
        device.kernel(info, &decl)
    };
    Ok([variant(false, true)?, variant(true, true)?, variant(true, false)?])
}

/// The kernels of one radix pass, as [`RadixSort::set_kernel_stages`] times them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SortKernel {
    /// Counting each block's digits.
    Histogram,
    /// The exclusive scan of the counts.
    Scan,
    /// Writing every pair where its digit puts it.
    Scatter,
}

impl SortKernel {
    /// The kernel's name in stage names.
    pub fn name(self) -> &'static str {
        match self {
            Self::Histogram => "histogram",
            Self::Scan => "scan",
            Self::Scatter => "scatter",
        }
    }
}

/// Prefix of every stage [`RadixSort::set_kernel_stages`] adds.
pub const SORT_KERNEL_STAGE_PREFIX: &str = "sort pass ";
/// The stage of the copy back after an odd number of unpacked passes.
pub const SORT_COPY_STAGE: &str = "sort copy back";

/// The stage name of one kernel of pass `pass` (from 1), whose digit is
/// `digit` bits at bit `shift` of the key as it came: "sort pass 2 (bits
/// 8-15) scatter".
pub fn sort_kernel_stage(pass: usize, shift: u32, digit: u32, kernel: SortKernel) -> String {
    format!("{SORT_KERNEL_STAGE_PREFIX}{pass} (bits {shift}-{}) {}", shift + digit - 1, kernel.name())
}

/// The sort kernels and their scratch memory.
pub struct RadixSort {
    histogram: Arc<Kernel>,
    scatter: Arc<Kernel>,
    /// Variants reading keys and values through texel-buffer views; `None`
    /// where the device cannot view RG32UI/R32UI buffers.
    texel: Option<(Arc<Kernel>, Arc<Kernel>)>,
    use_texel: bool,
    /// Wide-digit variants (texel inputs only); `None` until first chosen.
    wide: Option<(Arc<Kernel>, Arc<Kernel>)>,
    /// Block-digit variants; `None` until first chosen.
    block: Option<(Arc<Kernel>, Arc<Kernel>)>,
    /// Keys a block-digit workgroup ranks ([`block_items`] per invocation).
    block_keys: u64,
    /// Packed scatter variants; `None` while packing is off.
    packed: Option<PackedKernels>,
    digits: SortDigits,
    /// Workgroups the device runs at once, for [`wide_blocks`]: on a CPU
    /// device, this host's hardware threads.
    threads: u64,
    max_texels: u64,
    /// Keys per invocation ([`sort_items`]).
    items: u64,
    scan: Scan,
    keys_tmp: Option<Buffer>,
    values_tmp: Option<Buffer>,
    hist: Option<Buffer>,
    capacity: u64,
    /// Each pass's kernels timed as stages of their own ([`RadixSort::set_kernel_stages`]).
    kernel_stages: bool,
}

impl RadixSort {
    /// Builds the kernels, with the device's [`sort_items`] and
    /// [`default_sort_digits`] (wide digits where it can also read the keys
    /// through texel views).
    pub fn new(device: &Device) -> Result<Self> {
        let mut sort = Self::with_items(device, sort_items(device.info().device_type))?;
        match default_sort_digits(device.info()) {
            SortDigits::Wide if sort.texel.is_none() => {}
            digits => sort.set_digits(device, digits)?,
        }
        Ok(sort)
    }

    /// Builds the kernels with `items` keys per invocation (1 to 65,536).
    pub fn with_items(device: &Device, items: u64) -> Result<Self> {
        if !(1..=65_536).contains(&items) {
            return Err(Error::invalid(format!("{items} keys per sort invocation"), "is not 1 to 65536"));
        }
        let info = device.info();
        let specialization = [(0, SpecValue::U32(items as u32))];
        let decl = KernelDecl {
            bindings: &[],
            push_constant_size: std::mem::size_of::<SortPush>(),
            specialization: &specialization,
        };
        let texel = if [TexelFormat::R32Uint, TexelFormat::Rg32Uint].iter().all(|f| info.texel_formats.contains(f)) {
            let views = |n: usize| KernelDecl {
                bindings: &[BindingKind::UniformTexelBuffer; 2][..n],
                push_constant_size: std::mem::size_of::<SortPush>(),
                specialization: &specialization,
            };
            Some((
                device.kernel(&kernels::SORT_HISTOGRAM_TEXEL, &views(1))?,
                device.kernel(&kernels::SORT_SCATTER_TEXEL, &views(2))?,
            ))
        } else {
            None
        };
        Ok(Self {
            histogram: device.kernel(&kernels::SORT_HISTOGRAM, &decl)?,
            scatter: device.kernel(&kernels::SORT_SCATTER, &decl)?,
            use_texel: texel.is_some(),
            texel,
            wide: None,
            block: None,
            block_keys: BLOCK_WORKGROUP * 8,
            packed: None,
            digits: SortDigits::Four,
            threads: std::thread::available_parallelism().map_or(1, |n| n.get() as u64),
            max_texels: info.max_texel_buffer_elements,
            items,
            scan: Scan::new(device)?,
            keys_tmp: None,
            values_tmp: None,
            hist: None,
            capacity: 0,
            kernel_stages: false,
        })
    }

    /// Whether the scans of the digit counts work in tiles ([`Scan::tiles`]).
    pub fn scan_tiles(&self) -> bool {
        self.scan.tiles()
    }

    /// Chooses tiles or runs for the scans of the digit counts ([`Scan::set_tiles`]).
    pub fn set_scan_tiles(&mut self, device: &Device, tiles: bool) -> Result<()> {
        self.scan.set_tiles(device, tiles)
    }

    /// Whether [`RadixSort::record_with`] times each kernel as a stage of its own.
    pub fn kernel_stages(&self) -> bool {
        self.kernel_stages
    }

    /// Times each pass's histogram, scan and scatter, and the copy back, as
    /// stages of their own, named by [`sort_kernel_stage`] (for benchmarks:
    /// each ends the recording's open stage, so a caller's own "sort" stage
    /// covers only what comes before the first).
    pub fn set_kernel_stages(&mut self, on: bool) {
        self.kernel_stages = on;
    }

    /// Makes sure scratch memory fits sorts of up to `count` pairs.
    pub fn reserve(&mut self, device: &Device, count: u64) -> Result<()> {
        if count <= self.capacity {
            return Ok(());
        }
        if count > u64::from(u32::MAX) {
            return Err(Error::invalid(format!("sort of {count} pairs"), "exceeds 2³² − 1 pairs"));
        }
        self.keys_tmp = Some(device.create_buffer("sort keys (ping-pong)", count * 8, MemoryKind::Storage)?);
        // Packed passes ping-pong 64-bit words through both scratch buffers.
        let value_bytes = if self.packed.is_some() { 8 } else { 4 };
        self.values_tmp =
            Some(device.create_buffer("sort values (ping-pong)", count * value_bytes, MemoryKind::Storage)?);
        let mut entries = histogram_len(count, self.items);
        match self.digits {
            SortDigits::Wide => {
                entries = entries.max((1 << WIDE_DIGIT_BITS) * wide_blocks(count, self.threads) * WIDE_WORKGROUP)
            }
            SortDigits::Block => entries = entries.max((1 << BLOCK_DIGIT_BITS) * count.div_ceil(self.block_keys)),
            SortDigits::Four => {}
        }
        self.hist = Some(device.create_buffer("sort histogram", entries * 4, MemoryKind::Storage)?);
        self.scan.reserve(device, entries)?;
        self.capacity = count;
        Ok(())
    }

    /// Keys per invocation ([`sort_items`] unless made [`RadixSort::with_items`]).
    pub fn items(&self) -> u64 {
        self.items
    }

    /// Whether the kernels read keys and values through texel-buffer views
    /// (where the keys fit `maxTexelBufferElements`) rather than by device
    /// address. On by default where the device supports RG32UI/R32UI views.
    pub fn texel_inputs(&self) -> bool {
        self.texel.is_some() && self.use_texel
    }

    /// Chooses how the kernels read their inputs (see [`RadixSort::texel_inputs`]);
    /// turning texel inputs on where the device lacks them is an error.
    pub fn set_texel_inputs(&mut self, on: bool) -> Result<()> {
        if on && self.texel.is_none() {
            return Err(Error::unsupported("this device cannot read sort keys through uniform texel buffers"));
        }
        self.use_texel = on;
        Ok(())
    }

    /// The digits passes sort ([`RadixSort::set_digits`]; wide digits only
    /// with texel inputs, where the keys fit one view: otherwise 4 bits).
    pub fn digits(&self) -> SortDigits {
        self.digits
    }

    /// Keys each block-digit workgroup ranks (128 invocations × [`block_items`]).
    pub fn block_keys(&self) -> u64 {
        self.block_keys
    }

    /// Whether passes sort wide digits ([`RadixSort::digits`]).
    pub fn wide_digits(&self) -> bool {
        self.digits == SortDigits::Wide
    }

    /// Chooses wide or 4-bit digits ([`RadixSort::set_digits`]).
    pub fn set_wide_digits(&mut self, device: &Device, on: bool) -> Result<()> {
        self.set_digits(device, if on { SortDigits::Wide } else { SortDigits::Four })
    }

    /// Chooses the digits passes sort, building their kernels the first
    /// time; digits the device cannot run are an error: wide digits without
    /// RG32UI, R32UI and RGBA32UI texel inputs or where
    /// [`wide_digits_supported`] says no, block digits where
    /// [`block_digits_supported`] says no. Call [`RadixSort::reserve`] after
    /// a change: the histogram may need more scratch memory.
    pub fn set_digits(&mut self, device: &Device, digits: SortDigits) -> Result<()> {
        match digits {
            SortDigits::Wide => {
                if !wide_digits_supported(device.info()) {
                    return Err(Error::unsupported(
                        "wide sort digits on lavapipe before Mesa 25 (they crash it on a few million keys): 4-bit digits",
                    ));
                }
                if self.wide.is_none() {
                    if self.texel.is_none() || !device.info().texel_formats.contains(&TexelFormat::Rgba32Uint) {
                        return Err(Error::unsupported(
                            "this device cannot read sort keys through RG32UI, R32UI and RGBA32UI uniform texel buffers",
                        ));
                    }
                    // Keys (RG32UI) and, in the scatter, values (R32UI); then the same two and four per RGBA32UI texel.
                    let views = |n: usize| KernelDecl {
                        bindings: &[BindingKind::UniformTexelBuffer; 4][..n],
                        push_constant_size: std::mem::size_of::<SortPush>(),
                        specialization: &[],
                    };
                    self.wide = Some((
                        device.kernel(&kernels::SORT_HISTOGRAM_WIDE_TEXEL, &views(2))?,
                        device.kernel(&kernels::SORT_SCATTER_WIDE_TEXEL, &views(4))?,
                    ));
                }
            }
            SortDigits::Block => {
                if !block_digits_supported(device.info()) {
                    let info = device.info();
                    return Err(Error::unsupported(format!(
                        "block sort digits need subgroup ballots, a subgroup size from 8 to 128 dividing 128 \
                         (this device: {}), computeFullSubgroups enabled (here: {}) and {} bytes of shared \
                         memory",
                        info.subgroup_size,
                        if info.full_subgroups { "yes" } else { "no" },
                        block_shared_bytes(8)
                    )));
                }
                if self.block.is_none() {
                    let specialization = block_specialization(device.info());
                    let decl = KernelDecl::push::<SortPush>(&specialization);
                    self.block = Some((
                        device.kernel(&kernels::SORT_HISTOGRAM_BLOCK, &decl)?,
                        device.kernel(&kernels::SORT_SCATTER_BLOCK, &decl)?,
                    ));
                    self.block_keys = BLOCK_WORKGROUP * u64::from(block_items(device.info()));
                }
            }
            SortDigits::Four => {}
        }
        if self.packed.is_some() {
            self.build_packed(device, digits)?;
        }
        if digits != self.digits {
            // The histogram was sized for the other digits: size it again at the next reserve.
            self.capacity = 0;
        }
        self.digits = digits;
        Ok(())
    }

    /// Whether [`RadixSort::record_with`] may pack pairs ([`RadixSort::set_packing`]).
    pub fn packing(&self) -> bool {
        self.packed.is_some()
    }

    /// Lets [`RadixSort::record_with`] move pairs as packed words where its
    /// caller's [`PairPacking`] allows (building the packed scatter kernels
    /// the first time). Call [`RadixSort::reserve`] after a change: packed
    /// passes need 8 bytes of the values' scratch a pair.
    pub fn set_packing(&mut self, device: &Device, on: bool) -> Result<()> {
        if on == self.packed.is_some() {
            return Ok(());
        }
        self.packed = None;
        if on {
            self.packed = Some(PackedKernels::default());
            self.build_packed(device, self.digits)?;
        }
        self.capacity = 0;
        Ok(())
    }

    /// Builds the packed scatters `digits` take that are not built yet (4-bit
    /// digits: by address and, where the device has them, through texel views).
    fn build_packed(&mut self, device: &Device, digits: SortDigits) -> Result<()> {
        let Some(packed) = self.packed.as_mut() else {
            return Ok(());
        };
        let items = [(0, SpecValue::U32(self.items as u32))];
        match digits {
            SortDigits::Four => {
                if packed.address.is_none() {
                    packed.address = Some(packed_scatters(device, &kernels::SORT_SCATTER, 0, &items)?);
                }
                if packed.texel.is_none() && self.texel.is_some() {
                    packed.texel = Some(packed_scatters(device, &kernels::SORT_SCATTER_TEXEL, 2, &items)?);
                }
            }
            SortDigits::Wide if packed.wide.is_none() => {
                packed.wide = Some(packed_scatters(device, &kernels::SORT_SCATTER_WIDE_TEXEL, 4, &[])?);
            }
            SortDigits::Block if packed.block.is_none() => {
                let specialization = block_specialization(device.info());
                packed.block = Some(packed_scatters(device, &kernels::SORT_SCATTER_BLOCK, 0, &specialization)?);
            }
            SortDigits::Wide | SortDigits::Block => {}
        }
        Ok(())
    }

    /// GPU bytes of scratch memory held.
    pub(crate) fn scratch_bytes(&self) -> u64 {
        [&self.keys_tmp, &self.values_tmp, &self.hist].iter().filter_map(|b| b.as_ref().map(Buffer::size)).sum::<u64>()
            + self.scan.scratch_bytes()
    }

    /// Records a stable sort of the first `count` pairs of `keys` (`[u32; 2]`
    /// each, low word first) and `values` by the low `bits` bits of the keys.
    /// The result is left in `keys` and `values`.
    pub fn record<'a>(
        &'a self,
        rec: &mut Recording<'a>,
        keys: &'a Buffer,
        values: &'a Buffer,
        count: u64,
        bits: u32,
    ) -> Result<()> {
        self.record_with(rec, keys, values, count, bits, None)
    }

    /// [`RadixSort::record`], moving the pairs as packed words in every pass
    /// but the last where packing is on ([`RadixSort::set_packing`]), the
    /// sort makes two passes or more, and `packing`
    /// fits them ([`PairPacking::fits`]); otherwise as `record`. Packed, the
    /// sorted keys' first-digit bits come back zero.
    pub fn record_with<'a>(
        &'a self,
        rec: &mut Recording<'a>,
        keys: &'a Buffer,
        values: &'a Buffer,
        count: u64,
        bits: u32,
        packing: Option<PairPacking>,
    ) -> Result<()> {
        let (Some(keys_tmp), Some(values_tmp), Some(hist)) = (&self.keys_tmp, &self.values_tmp, &self.hist) else {
            return if count == 0 {
                Ok(())
            } else {
                Err(Error::Internal("RadixSort::record before RadixSort::reserve".into()))
            };
        };
        if count > self.capacity || keys.size() < count * 8 || values.size() < count * 4 || bits > 64 {
            return Err(Error::invalid(
                format!("sort of {count} pairs on {bits} bits"),
                format!(
                    "exceeds the capacity {} or the buffers (keys {} bytes, values {} bytes)",
                    self.capacity,
                    keys.size(),
                    values.size()
                ),
            ));
        }
        if count <= 1 || bits == 0 {
            return Ok(());
        }
        // Texel-buffer views where the device has them and the keys fit one view.
        let texel = self.texel.as_ref().filter(|_| self.use_texel && count <= self.max_texels);
        let wide = self.wide.as_ref().filter(|_| self.digits == SortDigits::Wide && texel.is_some());
        let block = self.block.as_ref().filter(|_| self.digits == SortDigits::Block);
        let (blocks, digits) = match (wide, block) {
            (Some(_), _) => (wide_blocks(count, self.threads), SortDigits::Wide),
            (None, Some(_)) => (count.div_ceil(self.block_keys), SortDigits::Block),
            (None, None) => (count.div_ceil(self.items * SORT_WORKGROUP), SortDigits::Four),
        };
        let passes = digit_passes(bits, digits.max_bits());
        // The packed scatters of this sort's kernels, where its packing fits.
        let packed = match (&self.packed, packing) {
            (Some(kernels), Some(p))
                if passes.len() >= 2 && p.fits(bits, passes[0].1) && values_tmp.size() >= count * 8 =>
            {
                match (block, wide, texel) {
                    (Some(_), _, _) => kernels.block.as_ref(),
                    (None, Some(_), _) => kernels.wide.as_ref(),
                    (None, None, Some(_)) => kernels.texel.as_ref(),
                    (None, None, None) => kernels.address.as_ref(),
                }
            }
            _ => None,
        };
        let last = passes.len() - 1;
        // Packed words drop the first digit's bits and keep the caller's top bits.
        let drop = packed.map_or(0, |_| passes[0].1);
        let pack_high = packing.map_or(0, |p| p.high_bits);
        let mut src = (keys, values);
        let mut dst = (keys_tmp, values_tmp);
        for (pass, &(shift, digit)) in passes.iter().enumerate() {
            // Packed: (keys, values) → keys_tmp → values_tmp → keys_tmp … → (keys, values), the
            // words read through views of their one buffer (the value views stand in, unread).
            if packed.is_some() {
                dst = if pass == last {
                    (keys, values)
                } else if pass % 2 == 0 {
                    (keys_tmp, keys_tmp)
                } else {
                    (values_tmp, values_tmp)
                };
            }
            let push = SortPush {
                keys_in: rec.addr(src.0)?,
                values_in: rec.addr(src.1)?,
                keys_out: rec.addr(dst.0)?,
                values_out: rec.addr(dst.1)?,
                hist: rec.addr(hist)?,
                count: count as u32,
                shift: if pass == 0 { shift } else { shift - drop },
                blocks: blocks as u32,
                digit_mask: (1u32 << digit) - 1,
                pack_drop: drop,
                pack_field: bits - drop,
                pack_high,
                pack_pad: 0,
            };
            let view = |buffer: &'a Buffer, elements: u64, format: TexelFormat| {
                Binding::Texels(Texels { buffer, offset: 0, elements, format })
            };
            let (key_view, value_view) =
                (view(src.0, count, TexelFormat::Rg32Uint), view(src.1, count, TexelFormat::R32Uint));
            // Wide passes: keys two and values four per RGBA32UI texel (whole texels only; below
            // four keys the kernel reads no value quad, and the R32UI view stands in).
            let key_pairs = view(src.0, count / 2, TexelFormat::Rgba32Uint);
            let value_quads = if count >= 4 { view(src.1, count / 4, TexelFormat::Rgba32Uint) } else { value_view };
            let wide_histogram_views = [key_view, key_pairs];
            let wide_scatter_views = [key_view, value_view, key_pairs, value_quads];
            let texel_views = [key_view, value_view];
            // Each pass: its histogram kernel and views, its scatter kernel and
            // views, and the histogram's columns per block of keys.
            let (histogram, histogram_views, scatter, scatter_views, columns): (
                &Kernel,
                &[Binding<'a>],
                &Kernel,
                &[Binding<'a>],
                u64,
            ) = match (block, wide, texel) {
                (Some((h, s)), _, _) => (&**h, &[], &**s, &[], 1),
                (None, Some((h, s)), _) => (&**h, &wide_histogram_views, &**s, &wide_scatter_views, WIDE_WORKGROUP),
                (None, None, Some((h, s))) => (&**h, &texel_views[..1], &**s, &texel_views, SORT_WORKGROUP),
                (None, None, None) => (&*self.histogram, &[], &*self.scatter, &[], SORT_WORKGROUP),
            };
            // Packed: the first pass packs, the last unpacks, the others move words.
            let variant = match pass {
                0 => 0,
                p if p == last => 2,
                _ => 1,
            };
            let scatter = packed.map_or(scatter, |variants| &*variants[variant]);
            let stage = |rec: &mut Recording<'a>, kernel: SortKernel| {
                if self.kernel_stages {
                    rec.begin_stage(&sort_kernel_stage(pass + 1, shift, digit, kernel));
                }
            };
            stage(rec, SortKernel::Histogram);
            rec.dispatch(histogram, Grid::Groups(blocks), histogram_views, &push)?;
            stage(rec, SortKernel::Scan);
            self.scan.record(rec, hist, (1u64 << digit) * blocks * columns)?;
            stage(rec, SortKernel::Scatter);
            rec.dispatch(scatter, Grid::Groups(blocks), scatter_views, &push)?;
            std::mem::swap(&mut src, &mut dst);
        }
        if packed.is_none() && passes.len() % 2 == 1 {
            if self.kernel_stages {
                rec.begin_stage(SORT_COPY_STAGE);
            }
            rec.copy(keys_tmp, 0, keys, 0, count * 8)?;
            rec.copy(values_tmp, 0, values, 0, count * 4)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn digit_passes_cover_the_bits_once_in_as_few_even_passes_as_the_width_allows() {
        assert_eq!(digit_passes(31, 11), [(0, 11), (11, 10), (21, 10)]);
        assert_eq!(digit_passes(43, 11), [(0, 11), (11, 11), (22, 11), (33, 10)]);
        assert_eq!(digit_passes(31, 4), [(0, 4), (4, 4), (8, 4), (12, 4), (16, 4), (20, 4), (24, 4), (28, 3)]);
        assert_eq!(digit_passes(1, 11), [(0, 1)]);
        assert!(digit_passes(0, 11).is_empty());
        for bits in 1..=64 {
            for width in [4, WIDE_DIGIT_BITS] {
                let passes = digit_passes(bits, width);
                assert_eq!(passes.len() as u32, bits.div_ceil(width), "{bits} bits at {width}");
                let mut next = 0;
                for &(shift, digit) in &passes {
                    assert!(shift == next && (1..=width).contains(&digit), "{bits} bits at {width}: {passes:?}");
                    next += digit;
                }
                assert_eq!(next, bits);
            }
        }
    }

    #[test]
    fn wide_passes_give_each_thread_workgroups_and_each_invocation_its_keys() {
        assert_eq!(wide_blocks(1, 2), 1);
        assert_eq!(wide_blocks(WIDE_WORKGROUP * WIDE_MIN_ITEMS, 2), 1);
        assert_eq!(wide_blocks(WIDE_WORKGROUP * WIDE_MIN_ITEMS + 1, 2), 2);
        assert_eq!(wide_blocks(10_000_000, 2), 4);
        assert_eq!(wide_blocks(10_000_000, 16), 32);
        assert_eq!(wide_blocks(10_000_000, 0), 2);
    }
}
