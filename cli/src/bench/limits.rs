//! What the device allows the splatting stages at best, measured in the same
//! run as the stages themselves, so a missed target can be told apart from a
//! device that cannot reach it.
//!
//! - **Blend ceiling** (`bench_blend_ceiling.comp`): the blend's arithmetic
//!   per (pixel, splat) pair with no memory traffic at all, every evaluation
//!   contributing. Under the benchmark's flop counts
//!   ([`BLEND_FLOPS_PER_EVALUATION`], [`BLEND_FLOPS_PER_CONTRIBUTION`]) no
//!   blend can do better; for a real frame, whose evaluations mostly do not
//!   contribute and so count fewer flops at the same cost, the bound is
//!   [`BlendCeiling::for_work`].
//! - **Pair-move floor** (`bench_pair_move.comp`): every (key, value) pair
//!   read once, and written once to the same index, or to where a stable
//!   radix pass of each digit width would put it. Every radix pass does at
//!   least this much, so it bounds a pass from below, and
//!   [`PairMoveFloor::lsd_bound`] bounds a whole LSD radix sort.
//!
//! - **Memory bandwidth** (`bench_bandwidth.comp`): a large buffer read once
//!   front to back, through a texel view or by device address, and copied
//!   once, the fastest way counting: the bytes a memory-bound stage must move
//!   over this rate bound it from below, whichever way the stage reads
//!   ([`MemoryBandwidth`]).
//!
//! The kernels have CPU twins here ([`blend_ceiling_cpu`], [`pair_move_cpu`],
//! [`bandwidth_cpu`]) that the tests check them against.

use bytemuck::{Pod, Zeroable};

use super::{BLEND_FLOPS_PER_CONTRIBUTION, BLEND_FLOPS_PER_EVALUATION};
use srug::error::{Error, Result};
use srug::gpu::{
    kernels, Binding, BindingKind, Buffer, Device, DeviceAddress, Grid, KernelDecl, MemoryKind, SpecValue, TexelFormat,
    Texels,
};

/// Push constants of `bench_blend_ceiling.comp` (keep in sync with its `Push` block).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct BlendCeilingPush {
    /// The output floats (one per invocation).
    pub out_addr: DeviceAddress,
    /// Splats every pixel blends.
    pub splats: u32,
    /// Invocations.
    pub count: u32,
}
srug::gpu::gpu_layout!(BlendCeilingPush, "BlendCeilingPush", [out_addr, splats, count]);

/// Flops each evaluation of the ceiling probe counts: all of them contribute.
pub const BLEND_CEILING_FLOPS: u64 = BLEND_FLOPS_PER_EVALUATION + BLEND_FLOPS_PER_CONTRIBUTION;
/// Most splats the probe blends per pixel while every one still contributes.
pub const BLEND_CEILING_MAX_SPLATS: u32 = 1024;
/// Pixels per invocation the probe accepts: those of the texel-buffer blend
/// and wider, since a blend that kept more pixels per invocation would
/// spread each splat's fetches over more of them.
pub const BLEND_CEILING_PIXELS: [u32; 7] = [1, 2, 4, 8, 16, 32, 64];

fn check_ceiling_args(pixels: u32, splats: u32) -> Result<()> {
    if !BLEND_CEILING_PIXELS.contains(&pixels) {
        return Err(Error::invalid(
            format!("{pixels} pixels per invocation"),
            format!("is not one of {BLEND_CEILING_PIXELS:?}"),
        ));
    }
    if splats > BLEND_CEILING_MAX_SPLATS {
        return Err(Error::invalid(
            format!("{splats} splats per pixel"),
            format!("the probe keeps every evaluation contributing only up to {BLEND_CEILING_MAX_SPLATS}"),
        ));
    }
    Ok(())
}

/// Runs the ceiling probe once: `count` invocations of `pixels` pixels, each
/// blending `splats` splats. Returns each invocation's Σ (T + r + g + b) over
/// its pixels and the GPU seconds.
pub fn blend_ceiling_run(device: &Device, pixels: u32, count: u32, splats: u32) -> Result<(Vec<f32>, f64)> {
    check_ceiling_args(pixels, splats)?;
    let kernel = device.kernel(
        &kernels::BENCH_BLEND_CEILING,
        &KernelDecl {
            bindings: &[],
            push_constant_size: std::mem::size_of::<BlendCeilingPush>(),
            specialization: &[(0, SpecValue::U32(pixels))],
        },
    )?;
    let out = device.create_buffer("blend ceiling sums", u64::from(count.max(1)) * 4, MemoryKind::Storage)?;
    let mut seconds = f64::NAN;
    if count > 0 {
        let t = device.run(|rec| {
            let push = BlendCeilingPush { out_addr: rec.addr(&out)?, splats, count };
            rec.fill(&out, f32::NAN.to_bits())?;
            rec.begin_stage("blend ceiling");
            rec.dispatch(&kernel, Grid::Items(u64::from(count)), &[], &push)
        })?;
        seconds = t.get("blend ceiling").unwrap_or(f64::NAN);
    }
    let mut sums: Vec<f32> = device.read_buffer(&out)?;
    sums.truncate(count as usize);
    Ok((sums, seconds))
}

/// CPU twin of `bench_blend_ceiling.comp` in f64: each invocation's
/// Σ (T + r + g + b), and how many evaluations contributed in all.
pub fn blend_ceiling_cpu(pixels: u32, count: u32, splats: u32) -> (Vec<f64>, u64) {
    let mut contributed = 0u64;
    let sums = (0..count)
        .map(|i| {
            let mut s = 0.0;
            for k in 0..pixels {
                let centre = [f64::from(i % 16) + f64::from(k) / 64.0 + 0.5, f64::from((k + i / 16) % 16) + 0.5];
                let (mut t, mut rgb) = (1.0f64, [0.0f64; 3]);
                for j in 0..splats {
                    let d = [f64::from(j & 15) - centre[0], f64::from((j >> 4) & 15) - centre[1]];
                    let (a, b, c) = (f64::from(1e-4f32), f64::from(1e-5f32), f64::from(1e-4f32));
                    let power = -0.5 * (a * d[0] * d[0] + c * d[1] * d[1]) - b * d[0] * d[1];
                    let alpha = (f64::from(0.005f32) * power.min(0.0).exp()).min(0.99);
                    let next = t * (1.0 - alpha);
                    if power <= 0.0 && alpha >= 1.0 / 255.0 && next >= 1e-4 {
                        let z = f64::from(j) * 1e-6;
                        for (v, base) in rgb.iter_mut().zip([0.25, 0.5, 0.75]) {
                            *v += alpha * t * (base + z);
                        }
                        t = next;
                        contributed += 1;
                    }
                }
                s += t + rgb.iter().sum::<f64>();
            }
            s
        })
        .collect();
    (sums, contributed)
}

/// The blend's arithmetic ceiling on a device.
#[derive(Clone, Copy, Debug)]
pub struct BlendCeiling {
    /// Pixels per invocation that gave the best rate.
    pub pixels: u32,
    /// GFLOP/s under the benchmark's flop counts, every evaluation contributing.
    pub gflops: f64,
}

impl BlendCeiling {
    /// The most GFLOP/s a blend can count on work of `evaluations` evaluated
    /// pairs, `contributions` of them contributing: every evaluation costs at
    /// least what it costs the probe, but the non-contributing ones count
    /// only [`BLEND_FLOPS_PER_EVALUATION`] flops.
    pub fn for_work(&self, evaluations: u64, contributions: u64) -> f64 {
        if evaluations == 0 {
            return self.gflops;
        }
        let counted = evaluations * BLEND_FLOPS_PER_EVALUATION + contributions * BLEND_FLOPS_PER_CONTRIBUTION;
        self.gflops * counted as f64 / (evaluations * BLEND_CEILING_FLOPS) as f64
    }
}

/// Measures the blend ceiling: the best GFLOP/s over [`BLEND_CEILING_PIXELS`]
/// (each the best of `repeats`), 2¹⁸ pixels of 1,024 splats each.
pub fn blend_ceiling(device: &Device, repeats: usize) -> Result<BlendCeiling> {
    let splats = BLEND_CEILING_MAX_SPLATS;
    let mut best = BlendCeiling { pixels: 1, gflops: 0.0 };
    for pixels in BLEND_CEILING_PIXELS {
        let count = (1u32 << 18) / pixels;
        for _ in 0..repeats.max(1) {
            let (_, seconds) = blend_ceiling_run(device, pixels, count, splats)?;
            let flops = f64::from(count) * f64::from(pixels) * f64::from(splats) * BLEND_CEILING_FLOPS as f64;
            let gflops = flops / seconds * 1e-9;
            if gflops > best.gflops {
                best = BlendCeiling { pixels, gflops };
            }
        }
    }
    Ok(best)
}

/// Push constants of `bench_pair_move.comp` (keep in sync with its `Push` block).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct PairMovePush {
    /// The output keys.
    pub keys_out: DeviceAddress,
    /// The output values (checksums with [`PairWrites::None`]).
    pub values_out: DeviceAddress,
    /// Pairs.
    pub count: u32,
    /// Workgroups.
    pub blocks: u32,
}
srug::gpu::gpu_layout!(PairMovePush, "PairMovePush", [keys_out, values_out, count, blocks]);

/// Pairs each invocation of `bench_pair_move.comp` owns (keep in sync with its `ITEMS`).
pub const PAIR_MOVE_ITEMS: u64 = 64;
const PAIR_MOVE_BLOCK: u64 = PAIR_MOVE_ITEMS * 64;

/// What the pair-move probe writes per pair (its `WORDS` constant).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PairWrites {
    /// Nothing: the pairs are only read (each invocation writes the xor of its pairs).
    None,
    /// The value (one 32-bit word), as a pass that sorts indices only would.
    Value,
    /// Key and value (three words), as the radix sort's scatter does.
    Pair,
    /// The value, to the index a random permutation gives it (read from a third view).
    ValueScattered,
}

impl PairWrites {
    fn words(self) -> u32 {
        match self {
            Self::None => 0,
            Self::Value | Self::ValueScattered => 1,
            Self::Pair => 3,
        }
    }
}

/// Runs the pair-move probe once over the first `count` pairs of `keys`
/// (`[u32; 2]` each) and `values`, writing to `keys_out` and `values_out` (at
/// `dest[i]`, a permutation of `0..count`, with [`PairWrites::ValueScattered`]);
/// returns the GPU seconds. Needs RG32UI/R32UI texel-buffer views holding `count`.
#[allow(clippy::too_many_arguments, reason = "the probe's inputs and outputs, each a buffer")]
pub fn pair_move_run(
    device: &Device,
    writes: PairWrites,
    keys: &Buffer,
    values: &Buffer,
    dest: &Buffer,
    count: u64,
    keys_out: &Buffer,
    values_out: &Buffer,
) -> Result<f64> {
    let info = device.info();
    if ![TexelFormat::R32Uint, TexelFormat::Rg32Uint].iter().all(|f| info.texel_formats.contains(f)) {
        return Err(Error::unsupported("this device cannot view buffers as RG32UI/R32UI texels"));
    }
    if count == 0 || count > info.max_texel_buffer_elements || count > u64::from(u32::MAX) {
        return Err(Error::invalid(
            format!("pair-move probe over {count} pairs"),
            format!(
                "needs 1 to {} (the device's texel-buffer limit)",
                info.max_texel_buffer_elements.min(u64::from(u32::MAX))
            ),
        ));
    }
    if keys.size() < count * 8
        || values.size() < count * 4
        || dest.size() < count * 4
        || keys_out.size() < count * 8
        || values_out.size() < count * 4
    {
        return Err(Error::invalid(format!("pair-move probe over {count} pairs"), "a buffer is too small"));
    }
    let kernel = device.kernel(
        &kernels::BENCH_PAIR_MOVE,
        &KernelDecl {
            bindings: &[BindingKind::UniformTexelBuffer; 3],
            push_constant_size: std::mem::size_of::<PairMovePush>(),
            specialization: &[
                (0, SpecValue::U32(writes.words())),
                (1, SpecValue::Bool(writes == PairWrites::ValueScattered)),
            ],
        },
    )?;
    let blocks = count.div_ceil(PAIR_MOVE_BLOCK);
    let views = [
        Binding::Texels(Texels { buffer: keys, offset: 0, elements: count, format: TexelFormat::Rg32Uint }),
        Binding::Texels(Texels { buffer: values, offset: 0, elements: count, format: TexelFormat::R32Uint }),
        Binding::Texels(Texels { buffer: dest, offset: 0, elements: count, format: TexelFormat::R32Uint }),
    ];
    let t = device.run(|rec| {
        let push = PairMovePush {
            keys_out: rec.addr(keys_out)?,
            values_out: rec.addr(values_out)?,
            count: count as u32,
            blocks: blocks as u32,
        };
        rec.begin_stage("pair move");
        rec.dispatch(&kernel, Grid::Groups(blocks), &views, &push)
    })?;
    Ok(t.get("pair move").unwrap_or(f64::NAN))
}

/// CPU twin of `bench_pair_move.comp` with [`PairWrites::None`]: the xor of
/// key halves and value over each invocation's pairs.
pub fn pair_move_cpu(keys: &[[u32; 2]], values: &[u32]) -> Vec<u32> {
    keys.chunks(PAIR_MOVE_ITEMS as usize)
        .zip(values.chunks(PAIR_MOVE_ITEMS as usize))
        .map(|(k, v)| k.iter().zip(v).fold(0, |s, (k, v)| s ^ k[0] ^ k[1] ^ v))
        .collect()
}

/// The pair-move floor for `keys` pairs (the best of the repeats).
#[derive(Clone, Debug)]
pub struct PairMoveFloor {
    /// Pairs moved.
    pub keys: u64,
    /// Seconds to read every pair once.
    pub read_seconds: f64,
    /// Seconds to read every pair and write its value.
    pub value_seconds: f64,
    /// Seconds to read every pair and write it whole.
    pub pair_seconds: f64,
    /// Seconds to read every pair and a destination and write the value
    /// there, for destinations as a stable radix pass over random digits of
    /// each width from 1 to [`PAIR_MOVE_MAX_DIGIT_BITS`] bits would give them.
    pub digit_seconds: Vec<(u32, f64)>,
    /// The same for a random permutation.
    pub random_seconds: f64,
}

/// The pair-move floor times scattered writes for every digit width from 1 to this.
pub const PAIR_MOVE_MAX_DIGIT_BITS: u32 = 22;
/// Widest digit whose counts [`PairMoveFloor::lsd_bound`] lets a pass keep in
/// registers for free (the sort's own 16 counts per invocation); wider digits
/// need 2^width compare-and-adds per key in registers, or a memory update.
pub const REGISTER_DIGIT_BITS: u32 = 4;

impl PairMoveFloor {
    /// The faster of two floors over the same pairs, time by time (a floor
    /// is the best a device showed; interference only ever slows a probe).
    pub fn best(&self, other: &PairMoveFloor) -> PairMoveFloor {
        let digit_seconds = self
            .digit_seconds
            .iter()
            .map(|&(bits, s)| {
                let theirs = other.digit_seconds.iter().find(|d| d.0 == bits).map_or(s, |d| d.1);
                (bits, s.min(theirs))
            })
            .collect();
        PairMoveFloor {
            keys: self.keys,
            read_seconds: self.read_seconds.min(other.read_seconds),
            value_seconds: self.value_seconds.min(other.value_seconds),
            pair_seconds: self.pair_seconds.min(other.pair_seconds),
            digit_seconds,
            random_seconds: self.random_seconds.min(other.random_seconds),
        }
    }

    /// Least time an LSD radix sort of `bits`-bit keys could take at these
    /// floors, over every digit width from 1 to `bits`: (digit width, seconds).
    /// Each of its ⌈bits / width⌉ passes
    /// - writes every pair at least as a value, where a pass of that width
    ///   puts it: more buckets never scatter the writes less, so a pass costs
    ///   at least the cheapest timing at its width or wider, and an untimed
    ///   width at least the widest timed width below it (the contiguous write
    ///   below the narrowest);
    /// - writes its 2^width bucket offsets at least once (at the contiguous
    ///   write's cost per word);
    /// - above [`REGISTER_DIGIT_BITS`], counts each key's digit with at least
    ///   one per-lane memory update, priced as a per-lane write without its
    ///   read (the contiguous write less the read-only time). Narrower digits
    ///   can be counted in registers, and that is not counted at all.
    ///
    /// Reading the keys again to count them is not counted either.
    pub fn lsd_bound(&self, bits: u32) -> Option<(u32, f64)> {
        let per_word = self.value_seconds / self.keys.max(1) as f64;
        let scatter = |width: u32| {
            let below = self.digit_seconds.iter().map(|d| d.0).filter(|t| *t <= width).max();
            let from = below.unwrap_or(0);
            let wider = self.digit_seconds.iter().filter(|d| d.0 >= from).map(|d| d.1).fold(f64::INFINITY, f64::min);
            if below.is_none() {
                wider.min(self.value_seconds)
            } else {
                wider
            }
        };
        let update = (self.value_seconds - self.read_seconds).max(0.0);
        (1..=bits)
            .map(|width| {
                let offsets = per_word * 2f64.powf(f64::from(width));
                let counting = if width > REGISTER_DIGIT_BITS { update } else { 0.0 };
                (width, f64::from(bits.div_ceil(width)) * (scatter(width) + offsets + counting))
            })
            .min_by(|a, b| a.1.total_cmp(&b.1))
    }
}

/// Measures the pair-move floor over `n` pairs.
pub fn pair_move_floor(device: &Device, n: u64, repeats: usize) -> Result<PairMoveFloor> {
    if n == 0 || n > u64::from(u32::MAX) {
        return Err(Error::invalid(format!("pair-move floor over {n} pairs"), "needs 1 to 2³² − 1"));
    }
    let keys: Vec<[u32; 2]> = (0..n as u32).map(|i| [i.wrapping_mul(0x9e37_79b9), i]).collect();
    let values: Vec<u32> = (0..n as u32).collect();
    let kb = device.upload("pair-move keys", &keys)?;
    let vb = device.upload("pair-move values", &values)?;
    let db = device.create_buffer("pair-move destinations", n.max(1) * 4, MemoryKind::Storage)?;
    let ko = device.create_buffer("pair-move keys out", n.max(1) * 8, MemoryKind::Storage)?;
    let vo = device.create_buffer("pair-move values out", n.max(1) * 4, MemoryKind::Storage)?;
    // A floor: the best of the repeats (interference only ever slows a run).
    let time = |writes| -> Result<f64> {
        let runs: Result<Vec<f64>> =
            (0..repeats.max(1)).map(|_| pair_move_run(device, writes, &kb, &vb, &db, n, &ko, &vo)).collect();
        Ok(runs?.into_iter().fold(f64::INFINITY, f64::min))
    };
    let scattered = |dest: Vec<u32>| -> Result<f64> {
        device.write_buffer(&db, 0, &dest)?;
        time(PairWrites::ValueScattered)
    };
    let digit_seconds = (1..=PAIR_MOVE_MAX_DIGIT_BITS)
        .map(|bits| Ok((bits, scattered(radix_pass_permutation(n as u32, bits, 0x2545_f491))?)))
        .collect::<Result<Vec<_>>>()?;
    let random_seconds = scattered(random_permutation(n as u32, 0x2545_f491))?;
    Ok(PairMoveFloor {
        keys: n,
        read_seconds: time(PairWrites::None)?,
        value_seconds: time(PairWrites::Value)?,
        pair_seconds: time(PairWrites::Pair)?,
        digit_seconds,
        random_seconds,
    })
}

/// Where a stable radix pass puts each of `n` elements whose digits are
/// random `bits`-bit numbers (at most 24; from `seed`): a permutation of `0..n`.
pub fn radix_pass_permutation(n: u32, bits: u32, seed: u64) -> Vec<u32> {
    let mut state = seed | 1;
    let buckets = 1usize << bits.min(24);
    let digits: Vec<usize> = (0..n)
        .map(|_| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 32) as usize % buckets
        })
        .collect();
    stable_digit_permutation(&digits, buckets)
}

/// Where a stable counting sort by `digits` (each below `buckets`) puts each element.
pub fn stable_digit_permutation(digits: &[usize], buckets: usize) -> Vec<u32> {
    let mut next = vec![0u32; buckets];
    for &d in digits {
        next[d] += 1;
    }
    let mut sum = 0;
    for c in &mut next {
        (*c, sum) = (sum, sum + *c);
    }
    digits
        .iter()
        .map(|&d| {
            next[d] += 1;
            next[d] - 1
        })
        .collect()
}

/// A permutation of `0..n` (Fisher–Yates on a xorshift stream from `seed`).
pub fn random_permutation(n: u32, seed: u64) -> Vec<u32> {
    let mut state = seed | 1;
    let mut p: Vec<u32> = (0..n).collect();
    for i in (1..p.len()).rev() {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        p.swap(i, (state % (i as u64 + 1)) as usize);
    }
    p
}

/// Push constants of `bench_bandwidth.comp` (keep in sync with its `BandwidthPush` block).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct BandwidthPush {
    /// The source, read by address ([`BandwidthRead::Address`]).
    pub src_addr: DeviceAddress,
    /// The copy (16 bytes a texel), or one checksum per invocation.
    pub out_addr: DeviceAddress,
    /// Texels.
    pub count: u32,
    /// Workgroups.
    pub blocks: u32,
}
srug::gpu::gpu_layout!(BandwidthPush, "BandwidthPush", [src_addr, out_addr, count, blocks]);

/// Texels each invocation of `bench_bandwidth.comp` reads (keep in sync with its `ITEMS`).
pub const BANDWIDTH_ITEMS: u64 = 64;
const BANDWIDTH_BLOCK: u64 = BANDWIDTH_ITEMS * 64;

/// How the bandwidth probe's invocations split the buffer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BandwidthLayout {
    /// Each invocation reads `BANDWIDTH_ITEMS` consecutive texels (CPU devices vectorize this best).
    Runs,
    /// A workgroup's block is read lane by lane: neighbouring invocations read
    /// neighbouring texels (GPUs coalesce this).
    Interleaved,
}

/// How the bandwidth probe reads the buffer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BandwidthRead {
    /// Through an RGBA32F texel-buffer view, as srug's texel kernels read.
    Texels,
    /// As uvec4s by device address: a GPU's plain loads.
    Address,
}

/// Runs the bandwidth probe once over the first `count` RGBA32F texels of
/// `source` (finite values) in `layout`, read as `read` says: read only
/// (writing one checksum per invocation into `out`), or with `copy` each
/// texel copied to the same index of `out`. Returns the GPU seconds.
pub fn bandwidth_run(
    device: &Device,
    copy: bool,
    layout: BandwidthLayout,
    read: BandwidthRead,
    source: &Buffer,
    count: u64,
    out: &Buffer,
) -> Result<f64> {
    let info = device.info();
    if !info.texel_formats.contains(&TexelFormat::Rgba32Float) {
        return Err(Error::unsupported("this device cannot view buffers as RGBA32F texels"));
    }
    let limit = info.max_texel_buffer_elements.min(u64::from(u32::MAX));
    if count == 0 || count > limit {
        return Err(Error::invalid(format!("bandwidth probe over {count} texels"), format!("needs 1 to {limit}")));
    }
    let sums = bandwidth_checksums(count, layout) * 4;
    if source.size() < count * 16 || out.size() < if copy { count * 16 } else { sums } {
        return Err(Error::invalid(format!("bandwidth probe over {count} texels"), "a buffer is too small"));
    }
    let kernel = device.kernel(
        &kernels::BENCH_BANDWIDTH,
        &KernelDecl {
            bindings: &[BindingKind::UniformTexelBuffer],
            push_constant_size: std::mem::size_of::<BandwidthPush>(),
            specialization: &[
                (0, SpecValue::Bool(copy)),
                (1, SpecValue::Bool(layout == BandwidthLayout::Interleaved)),
                (2, SpecValue::Bool(read == BandwidthRead::Address)),
            ],
        },
    )?;
    let blocks = count.div_ceil(BANDWIDTH_BLOCK);
    let view =
        [Binding::Texels(Texels { buffer: source, offset: 0, elements: count, format: TexelFormat::Rgba32Float })];
    let t = device.run(|rec| {
        let push = BandwidthPush {
            src_addr: rec.addr(source)?,
            out_addr: rec.addr(out)?,
            count: count as u32,
            blocks: blocks as u32,
        };
        rec.begin_stage("bandwidth");
        rec.dispatch(&kernel, Grid::Groups(blocks), &view, &push)
    })?;
    Ok(t.get("bandwidth").unwrap_or(f64::NAN))
}

/// How many checksums the read-only probe writes over `count` texels in
/// `layout` (one per invocation that reads a texel).
pub fn bandwidth_checksums(count: u64, layout: BandwidthLayout) -> u64 {
    match layout {
        BandwidthLayout::Runs => count.div_ceil(BANDWIDTH_ITEMS),
        BandwidthLayout::Interleaved => count / BANDWIDTH_BLOCK * 64 + (count % BANDWIDTH_BLOCK).min(64),
    }
}

/// CPU twin of `bench_bandwidth.comp` read only: the xor of each invocation's
/// texels' bits in `layout` (one entry per invocation that reads any texel).
pub fn bandwidth_cpu(texels: &[[f32; 4]], layout: BandwidthLayout) -> Vec<u32> {
    let xor = |t: &[f32; 4]| t.iter().fold(0, |s, v| s ^ v.to_bits());
    let items = BANDWIDTH_ITEMS as usize;
    match layout {
        BandwidthLayout::Runs => texels.chunks(items).map(|c| c.iter().map(xor).fold(0, |s, x| s ^ x)).collect(),
        BandwidthLayout::Interleaved => texels
            .chunks(BANDWIDTH_BLOCK as usize)
            .flat_map(|block| {
                (0..64.min(block.len()))
                    .map(move |lane| block.iter().skip(lane).step_by(64).map(xor).fold(0, |s, x| s ^ x))
            })
            .collect(),
    }
}

/// The device's streaming bandwidth (the best of the repeats).
#[derive(Clone, Copy, Debug)]
pub struct MemoryBandwidth {
    /// Bytes of the buffer read.
    pub bytes: u64,
    /// Bytes read per second, reading once.
    pub read: f64,
    /// Bytes moved (read and written) per second, copying once.
    pub copy: f64,
    /// The layout that read fastest (the copy takes its own best).
    pub read_layout: BandwidthLayout,
    /// How the fastest read read (the copy takes its own best).
    pub read_through: BandwidthRead,
}

impl MemoryBandwidth {
    /// The faster read and the faster copy of two probes (a floor takes the
    /// best a device showed); the rest from `self`.
    pub fn best(&self, other: &MemoryBandwidth) -> MemoryBandwidth {
        MemoryBandwidth { read: self.read.max(other.read), copy: self.copy.max(other.copy), ..*self }
    }

    /// Least seconds to read `read` bytes and write `written` bytes at these
    /// rates: a written byte costs what copying it costs beyond reading it.
    pub fn floor_seconds(&self, read: u64, written: u64) -> f64 {
        let per_write = (2.0 / self.copy - 1.0 / self.read).max(0.0);
        read as f64 / self.read + written as f64 * per_write
    }
}

/// Measures the streaming bandwidth over a buffer of `bytes` (rounded to whole
/// texels): the best of the repeats, of both layouts and of both ways to read.
pub fn memory_bandwidth(device: &Device, bytes: u64, repeats: usize) -> Result<MemoryBandwidth> {
    let count = (bytes / 16).max(1);
    let texels: Vec<[f32; 4]> = (0..count).map(|i| [i as f32, 1.0, 2.0, 3.0]).collect();
    let source = device.upload("bandwidth source", &texels)?;
    let out = device.create_buffer("bandwidth out", count * 16, MemoryKind::Storage)?;
    let best = |copy, layout, read| -> Result<f64> {
        let runs: Result<Vec<f64>> =
            (0..repeats.max(1)).map(|_| bandwidth_run(device, copy, layout, read, &source, count, &out)).collect();
        Ok(runs?.into_iter().fold(f64::INFINITY, f64::min))
    };
    let mut fastest_read = (f64::INFINITY, BandwidthLayout::Runs, BandwidthRead::Texels);
    let mut fastest_copy = f64::INFINITY;
    for read in [BandwidthRead::Texels, BandwidthRead::Address] {
        for layout in [BandwidthLayout::Runs, BandwidthLayout::Interleaved] {
            let seconds = best(false, layout, read)?;
            if seconds < fastest_read.0 {
                fastest_read = (seconds, layout, read);
            }
            fastest_copy = fastest_copy.min(best(true, layout, read)?);
        }
    }
    let (read, read_layout, read_through) = fastest_read;
    Ok(MemoryBandwidth {
        bytes: count * 16,
        read: (count * 16) as f64 / read,
        copy: (count * 32) as f64 / fastest_copy,
        read_layout,
        read_through,
    })
}

#[cfg(test)]
mod layout_tests {
    use super::{BandwidthPush, BlendCeilingPush, PairMovePush};
    use crate::bench::FmaPush;
    use srug::gpu::{check_layout, kernels};

    /// The probes' push-constant structs match their kernels' GLSL blocks.
    #[test]
    fn push_layouts_match_glsl() {
        assert_eq!(check_layout::<BlendCeilingPush>(&[&kernels::BENCH_BLEND_CEILING]), Ok(1));
        assert_eq!(check_layout::<PairMovePush>(&[&kernels::BENCH_PAIR_MOVE]), Ok(1));
        assert_eq!(check_layout::<FmaPush>(&[&kernels::BENCH_FMA]), Ok(1));
        assert_eq!(check_layout::<BandwidthPush>(&[&kernels::BENCH_BANDWIDTH]), Ok(1));
    }
}
