//! Benchmarks run by `srug bench`: measured with GPU timestamps, never with
//! timed tests. Each run measures the device's FMA peak itself, so kernel
//! efficiency is reported against a ceiling taken on the same machine, now.

pub mod batch;
pub mod completion;
pub mod embed;
pub mod formats;
pub mod limits;
pub mod plot;
pub mod scaling;
pub mod shade;
pub mod shadow;
pub mod trade;
pub mod unet;

use std::time::{Duration, Instant};

use bytemuck::{Pod, Zeroable};

use srug::error::{Error, Result};
use srug::gpu::{kernels, Device, DeviceAddress, Grid, KernelDecl, MemoryKind, Timings};
use srug::primitives::sort::{RadixSort, SortDigits, SORT_COPY_STAGE, SORT_KERNEL_STAGE_PREFIX};
use srug::scene::activate::GpuScene;
use srug::scene::demo::{demo_city, DemoOptions};
use srug::scene::order::SceneOrder;
use srug::splat::{BlendVariant, NormalSource, SplatSettings, Splatter, TileBounds};

/// Untimed frames before a bench's timed ones (`--warm-up-ms`). A GPU idles
/// at a low clock while the host generates or loads a scene and raises it
/// only once it has been busy for a while, so a few timed frames right after
/// would be measured at the idle clock (one H200 lease read the same 3M-Gaussian
/// frame at 1.7 ms and at 7.7 ms). CPU devices run at the host's speed at once.
#[derive(clap::Args, Clone, Copy, Debug, Default)]
pub struct WarmUpArgs {
    /// Render untimed frames for at least this many milliseconds before each row's timed
    /// ones (default: 1000 on GPUs, whose clocks rise only under load; 0 on CPU devices).
    #[arg(long, value_name = "MS")]
    pub warm_up_ms: Option<u64>,
}

impl WarmUpArgs {
    /// The warm-up on `device`: as given, else 1 s on GPUs and none on CPU devices.
    pub fn duration(&self, device: &Device) -> Duration {
        let cpu = device.info().device_type == srug::gpu::ash::vk::PhysicalDeviceType::CPU;
        Duration::from_millis(self.warm_up_ms.unwrap_or(if cpu { 0 } else { 1000 }))
    }
}

/// Runs `frame` (untimed) until `duration` has passed, not at all for zero;
/// returns how many frames ran.
pub fn warm_up(duration: Duration, mut frame: impl FnMut() -> Result<()>) -> Result<usize> {
    let start = Instant::now();
    let mut frames = 0;
    while start.elapsed() < duration {
        frame()?;
        frames += 1;
    }
    Ok(frames)
}

/// Push constants of `bench_fma.comp` (keep in sync with its `Push` block).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct FmaPush {
    /// The output floats.
    pub out_addr: DeviceAddress,
    /// Loop iterations per invocation.
    pub iterations: u32,
    /// Invocations.
    pub count: u32,
}
srug::gpu::gpu_layout!(FmaPush, "FmaPush", [out_addr, iterations, count]);

/// The host's CPU as a bench names it: its model name, x86 family and model,
/// logical CPUs and the widest vector instructions it has. On lavapipe the
/// CPU is the device, and the same "2-core machine" has been CPUs with and
/// without AVX-512, whose JIT code and speeds differ (docs/testing.md,
/// "Which machine"): every table names it.
pub fn host_cpu() -> String {
    let info = std::fs::read_to_string("/proc/cpuinfo").unwrap_or_default();
    host_cpu_from(&info, std::thread::available_parallelism().map_or(0, usize::from), vector_isa())
}

/// [`host_cpu`] from a `/proc/cpuinfo` text (empty where there is none).
pub fn host_cpu_from(cpuinfo: &str, cpus: usize, isa: &str) -> String {
    let field = |name: &str| {
        cpuinfo.lines().find_map(|l| {
            let (key, value) = l.split_once(':')?;
            (key.trim() == name).then(|| value.trim().to_string())
        })
    };
    let model = field("model name").unwrap_or_else(|| std::env::consts::ARCH.to_string());
    let family = match (field("cpu family"), field("model")) {
        (Some(f), Some(m)) => format!(", family {f} model {m}"),
        _ => String::new(),
    };
    format!("{model}{family}, {cpus} CPUs, {isa}")
}

/// The widest x86 vector extension this CPU has (what llvmpipe's JIT can use).
fn vector_isa() -> &'static str {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx512f") {
            return "AVX-512";
        }
        if std::arch::is_x86_feature_detected!("avx2") {
            return "AVX2 (no AVX-512)";
        }
        "SSE/AVX (no AVX2)"
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        std::env::consts::ARCH
    }
}

/// Measures the device's FMA throughput in GFLOP/s (best of `repeats`).
pub fn fma_peak_gflops(device: &Device, repeats: usize) -> Result<f64> {
    let kernel = device.kernel(
        &kernels::BENCH_FMA,
        &KernelDecl { bindings: &[], push_constant_size: std::mem::size_of::<FmaPush>(), specialization: &[] },
    )?;
    let count = 1u32 << 16;
    let iterations = 2048u32;
    let out = device.create_buffer("fma probe", u64::from(count) * 4, MemoryKind::Storage)?;
    let mut best = 0.0f64;
    for _ in 0..repeats.max(1) {
        let t = device.run(|rec| {
            let push = FmaPush { out_addr: rec.addr(&out)?, iterations, count };
            rec.begin_stage("fma");
            rec.dispatch(&kernel, Grid::Items(u64::from(count)), &[], &push)
        })?;
        let seconds = t.get("fma").unwrap_or(f64::NAN);
        let flops = f64::from(count) * f64::from(iterations) * 64.0;
        best = best.max(flops / seconds * 1e-9);
    }
    Ok(best)
}

/// Flops the blend spends per evaluated (pixel, splat) pair: offset (2), the
/// conic's quadratic form (9), opacity scale (1); `exp` and `min` not counted.
pub const BLEND_FLOPS_PER_EVALUATION: u64 = 12;
/// Further flops per contributing pair: transmittance (2), weight (1), rgb (6).
pub const BLEND_FLOPS_PER_CONTRIBUTION: u64 = 9;

/// One row of the splat benchmark.
#[derive(Clone, Debug)]
pub struct SplatBenchRow {
    /// Gaussians in the demo city.
    pub gaussians: usize,
    /// Image size.
    pub width: u32,
    /// Image size.
    pub height: u32,
    /// Median GPU seconds per stage over the repeats, in pipeline order.
    pub stages: Vec<(String, f64)>,
    /// (Gaussian, tile) pairs sorted.
    pub pairs: u64,
    /// Bytes of per-frame working memory.
    pub working_bytes: u64,
    /// Bytes of the scene's parameters on the GPU.
    pub scene_bytes: u64,
    /// Bytes of the G-buffers.
    pub gbuffer_bytes: u64,
    /// (pixel, splat) pairs the blend evaluated, counted by the CPU twin's replay.
    pub blend_evaluations: u64,
    /// Pairs that contributed to a pixel.
    pub blend_contributions: u64,
    /// The most splats one pixel reads before it is done (the CPU twin's
    /// replay): each tile's list is walked by one workgroup, so a blend lasts
    /// at least as long as one walk that far, however many tiles run at once.
    pub longest_walk: u64,
    /// Chunks the split blend walked (0: no list split; `SplatStats::chunks`).
    pub chunks: u64,
    /// Gaussians the preprocess keeps (counted by the CPU twin).
    pub visible: u64,
    /// Key bits the sort sorted.
    pub key_bits: u32,
    /// Bytes the preprocess must read at least: every Gaussian's position,
    /// and the rest of its attributes (SH at the degree used) for the visible ones.
    pub preprocess_read_bytes: u64,
    /// Bytes the preprocess must write at least: a splat record and a tile
    /// count per visible Gaussian, a zero tile count per culled one.
    pub preprocess_write_bytes: u64,
    /// Where asked ([`SplatBenchOptions::sort_kernels`]): the median seconds
    /// of each kernel of the frame's sort, timed in frames of their own
    /// ([`srug::primitives::sort::sort_kernel_stage`] names), in order.
    pub sort_kernels: Vec<(String, f64)>,
    /// Where asked ([`SplatBenchOptions::row_floors`]) and the frame had
    /// pairs: the pair-move floor at [`Self::pairs`], measured right after
    /// the row's timed frames and again after every row, the faster of the two
    /// ([`limits::PairMoveFloor::best`]).
    pub sort_floor: Option<limits::PairMoveFloor>,
    /// Where asked ([`SplatBenchOptions::row_floors`]): the memory
    /// bandwidth ([`bandwidth_probe_bytes`]), measured right after the row's
    /// timed frames and again after every row, the faster rates of the two
    /// (`srug bench splat` prices the preprocess at the fastest rates of
    /// every probe of its run).
    pub bandwidth: Option<limits::MemoryBandwidth>,
}

/// Bytes the memory-bandwidth probe reads on `device`: 64 MiB on CPU devices,
/// on GPUs four times that, past their last-level caches.
pub fn bandwidth_probe_bytes(device: &Device) -> u64 {
    if device.info().device_type == srug::gpu::ash::vk::PhysicalDeviceType::CPU {
        64 << 20
    } else {
        256 << 20
    }
}

impl SplatBenchRow {
    /// Sum of the stage medians.
    pub fn total(&self) -> f64 {
        self.stages.iter().map(|s| s.1).sum()
    }

    /// Achieved blend GFLOP/s under the stated flop counts.
    pub fn blend_gflops(&self) -> f64 {
        let flops = self.blend_evaluations * BLEND_FLOPS_PER_EVALUATION
            + self.blend_contributions * BLEND_FLOPS_PER_CONTRIBUTION;
        let seconds = self.stages.iter().find(|s| s.0 == "blend").map_or(f64::NAN, |s| s.1);
        flops as f64 / seconds * 1e-9
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

/// The splatter's kernel choices a benchmark can override (`None`: the
/// device's default), for A/B runs of one choice at a time.
#[derive(clap::Args, Clone, Copy, Debug, Default)]
pub struct SplatterChoices {
    /// Blend variant: per-pixel, subgroup or batched (default: subgroup where supported).
    #[arg(long, value_parser = BlendVariant::parse)]
    pub blend: Option<BlendVariant>,
    /// Pixels per invocation of the texel-buffer blend: 1, 2, 4 or 8 (default: 8 on lavapipe from Mesa 25, 1 on GPUs, else 2).
    #[arg(long)]
    pub blend_pixels: Option<u32>,
    /// Evaluate each splat only at the pixels of a blend lane's row it can reach: true or false
    /// (default: true on lavapipe from Mesa 25, else false).
    #[arg(long)]
    pub pixel_reach: Option<bool>,
    /// Fetch each key window's wanted splats once, one per blend lane, and hand them out: true or
    /// false (default: true on lavapipe from Mesa 25 and on GPUs, else false).
    #[arg(long)]
    pub window_fetch: Option<bool>,
    /// With the window fetch, take a window's next two splats each blend step: true or false
    /// (default: true on GPUs, else false).
    #[arg(long)]
    pub two_splats_per_step: Option<bool>,
    /// Split tile lists longer than twice this many entries into chunks of this many, each
    /// blended by a workgroup of its own; 0 splits none (default: 1024 on GPUs, else 0).
    #[arg(long)]
    pub chunk_length: Option<u32>,
    /// Read the scene (preprocess) and the splat records (keys) through texel-buffer views: true
    /// or false (default: true where the device views R32F texels).
    #[arg(long)]
    pub texel_preprocess: Option<bool>,
    /// Digits of the pairs' radix sort (and of the sort comparison): 4, block or wide (default:
    /// wide on lavapipe from Mesa 25, block on GPUs with computeFullSubgroups, else 4).
    #[arg(long, value_parser = SortDigits::parse)]
    pub sort_digits: Option<SortDigits>,
    /// Move each pair as one 64-bit word in every pass of the frames' sort but the last (its
    /// depth bits above the first digit, tile id, splat index and row mask): true or false
    /// (default: true).
    #[arg(long)]
    pub sort_packing: Option<bool>,
    /// Prefix sums (tile counts, the sort's digit counts) in tiles of 2048 values a workgroup
    /// rather than runs of consecutive values an invocation: true or false (default: true on GPUs,
    /// else false).
    #[arg(long)]
    pub scan_tiles: Option<bool>,
    /// Keep splat records only for the Gaussians the view's position cull keeps, counted by a
    /// `cull` stage before the preprocess (`SplatSettings::compact_splats`): true or false
    /// (default: false; the relighter's cameras: true).
    #[arg(long)]
    pub compact_splats: Option<bool>,
}

impl SplatterChoices {
    /// These choices with those `over` makes put in their place.
    pub fn merged(&self, over: &SplatterChoices) -> SplatterChoices {
        let Self {
            blend,
            blend_pixels,
            pixel_reach,
            window_fetch,
            two_splats_per_step,
            chunk_length,
            texel_preprocess,
            sort_digits,
            sort_packing,
            scan_tiles,
            compact_splats,
        } = *over;
        SplatterChoices {
            blend: blend.or(self.blend),
            blend_pixels: blend_pixels.or(self.blend_pixels),
            pixel_reach: pixel_reach.or(self.pixel_reach),
            window_fetch: window_fetch.or(self.window_fetch),
            two_splats_per_step: two_splats_per_step.or(self.two_splats_per_step),
            chunk_length: chunk_length.or(self.chunk_length),
            texel_preprocess: texel_preprocess.or(self.texel_preprocess),
            sort_digits: sort_digits.or(self.sort_digits),
            sort_packing: sort_packing.or(self.sort_packing),
            scan_tiles: scan_tiles.or(self.scan_tiles),
            compact_splats: compact_splats.or(self.compact_splats),
        }
    }

    /// `settings` with the choices that are a frame's settings, not the splatter's.
    pub fn settings(&self, settings: SplatSettings) -> SplatSettings {
        SplatSettings { compact_splats: self.compact_splats.unwrap_or(settings.compact_splats), ..settings }
    }

    /// Makes the choices given on `splatter`.
    pub fn apply(&self, splatter: &mut Splatter) -> Result<()> {
        if let Some(variant) = self.blend {
            splatter.set_blend_variant(variant)?;
        }
        if let Some(pixels) = self.blend_pixels {
            splatter.set_blend_pixels(pixels)?;
        }
        if let Some(on) = self.pixel_reach {
            splatter.set_pixel_reach(on);
        }
        if let Some(on) = self.window_fetch {
            splatter.set_window_fetch(on);
        }
        if let Some(on) = self.two_splats_per_step {
            splatter.set_two_splats_per_step(on);
        }
        if let Some(entries) = self.chunk_length {
            splatter.set_chunk_length(entries)?;
        }
        if let Some(on) = self.texel_preprocess {
            splatter.set_texel_preprocess(on)?;
        }
        if let Some(digits) = self.sort_digits {
            splatter.set_sort_digits(digits)?;
        }
        if let Some(on) = self.sort_packing {
            splatter.set_sort_packing(on)?;
        }
        if let Some(on) = self.scan_tiles {
            splatter.set_scan_tiles(on)?;
        }
        Ok(())
    }
}

/// How [`splat_bench`] renders.
#[derive(Clone, Copy, Debug)]
pub struct SplatBenchOptions {
    /// Repeats per setting (medians are reported).
    pub repeats: usize,
    /// SH degree of the demo city.
    pub sh_degree: u32,
    /// Kernel choices overridden.
    pub choices: SplatterChoices,
    /// Tile edge in pixels.
    pub tile: u32,
    /// Which tiles list a splat.
    pub tile_bounds: TileBounds,
    /// Also time each kernel of the frames' sort, in `repeats` more frames
    /// (apart from the stage times, which the extra timestamps would touch).
    pub sort_kernels: bool,
    /// The order of the demo city's Gaussians ([`bench_city`]).
    pub order: CityOrder,
    /// Where they go on the device ([`GpuScene::arrange`]).
    pub scene_order: SceneOrder,
    /// Untimed frames before each row's timed ones ([`warm_up`]).
    pub warm_up: Duration,
    /// Measure the pair-move floor at each row's own pairs and the memory
    /// bandwidth right after its timed frames ([`SplatBenchRow::sort_floor`],
    /// [`SplatBenchRow::bandwidth`]): no scaling from another pair count, and
    /// more probes of a host whose memory speed moves between them.
    pub row_floors: bool,
}

/// The bench city on the device, arranged as `options` say (reported through `progress`).
fn bench_scene(
    device: &Device,
    city: &srug::scene::demo::DemoCity,
    options: &SplatBenchOptions,
    progress: &mut impl FnMut(&str),
) -> Result<GpuScene> {
    let mut scene = GpuScene::upload(device, &city.scene)?;
    if scene.arrange(device, options.scene_order)? {
        progress("arranged along a Morton curve on the device");
    }
    Ok(scene)
}

/// The order of the benches' demo city's Gaussians ([`bench_city`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum CityOrder {
    /// Object by object, as the generator makes them.
    Generated,
    /// A fixed random order, as a trained scene's file holds them (training
    /// appends the Gaussians it splits and clones).
    Shuffled,
    /// Along a Morton curve through the centres ([`srug::scene::Scene::morton_order`]).
    Morton,
}

/// The demo city (seed 7) the splat benches render, its Gaussians in `order`.
pub fn bench_city(gaussians: usize, sh_degree: u32, order: CityOrder) -> Result<srug::scene::demo::DemoCity> {
    let mut city = demo_city(&DemoOptions { seed: 7, gaussians, sh_degree })?;
    let order = match order {
        CityOrder::Generated => return Ok(city),
        CityOrder::Morton => city.scene.morton_order(),
        CityOrder::Shuffled => {
            // Fisher-Yates with a fixed xorshift stream: the same order every run.
            let mut order: Vec<usize> = (0..city.scene.len()).collect();
            let mut state = 0x2545_f491_4f6c_dd1du64;
            for i in (1..order.len()).rev() {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                order.swap(i, (state % (i as u64 + 1)) as usize);
            }
            order
        }
    };
    city.scene = city.scene.permuted(&order);
    Ok(city)
}

/// Median seconds of each stage over `runs`, in first-seen order, of the
/// stages `keep` takes.
fn stage_medians<'t>(runs: impl IntoIterator<Item = &'t Timings>, keep: impl Fn(&str) -> bool) -> Vec<(String, f64)> {
    let mut per_stage: Vec<(String, Vec<f64>)> = Vec::new();
    for s in runs.into_iter().flat_map(|t| &t.stages).filter(|s| keep(&s.name)) {
        match per_stage.iter_mut().find(|(name, _)| *name == s.name) {
            Some((_, v)) => v.push(s.seconds),
            None => per_stage.push((s.name.clone(), vec![s.seconds])),
        }
    }
    per_stage.into_iter().map(|(n, v)| (n, median(v))).collect()
}

/// Whether a stage is one kernel of a sort ([`RadixSort::set_kernel_stages`]).
fn is_sort_kernel(name: &str) -> bool {
    name.starts_with(SORT_KERNEL_STAGE_PREFIX) || name == SORT_COPY_STAGE
}

/// One line of a sort's kernel times ([`SplatBenchRow::sort_kernels`],
/// [`SortBench::kernels`]): each kernel's milliseconds, then the histograms',
/// scans', scatters' and copy's shares of their sum.
pub fn sort_kernels_line(kernels: &[(String, f64)]) -> String {
    if kernels.is_empty() {
        return "no kernel ran (fewer than two pairs, or no timestamps on this device)".into();
    }
    let total: f64 = kernels.iter().map(|k| k.1).sum();
    let share = |kind: &str| {
        let sum: f64 = kernels.iter().filter(|k| k.0.ends_with(kind)).map(|k| k.1).sum();
        format!("{kind} {:.0}%", sum / total * 100.0)
    };
    let each: Vec<String> = kernels
        .iter()
        .map(|(name, s)| format!("{} {:.2}", name.strip_prefix("sort ").unwrap_or(name), s * 1e3))
        .collect();
    let mut shares = vec![share("histogram"), share("scan"), share("scatter")];
    if kernels.iter().any(|k| k.0 == SORT_COPY_STAGE) {
        shares.push(share("copy back"));
    }
    format!("{} ms; of {:.2} ms: {}", each.join(", "), total * 1e3, shares.join(", "))
}

/// Renders the demo city at each Gaussian count and size; per-stage medians.
pub fn splat_bench(
    device: &Device,
    counts: &[usize],
    sizes: &[(u32, u32)],
    options: &SplatBenchOptions,
    mut progress: impl FnMut(&str),
) -> Result<Vec<SplatBenchRow>> {
    let SplatBenchOptions { repeats, sh_degree, choices, tile, tile_bounds, sort_kernels, warm_up: warm, .. } =
        *options;
    let settings = choices.settings(SplatSettings { tile, tile_bounds, ..SplatSettings::default() });
    let mut rows = Vec::new();
    let mut splatter = Splatter::new(device)?;
    choices.apply(&mut splatter)?;
    for &n in counts {
        progress(&format!("generating the demo city with {n} Gaussians"));
        let city = bench_city(n, sh_degree, options.order)?;
        let scene = bench_scene(device, &city, options, &mut progress)?;
        for &(w, h) in sizes {
            progress(&format!("{n} Gaussians at {w}x{h}"));
            let cam = city.cameras[0].resized(w, h);
            warm_up(warm, || splatter.render(&scene, &cam, &settings).map(drop))?;
            let mut timings = Vec::new();
            let mut last = None;
            for _ in 0..repeats.max(1) {
                let (g, stats) = splatter.render(&scene, &cam, &settings)?;
                timings.push(stats.timings.clone());
                last = Some((g.bytes(), stats));
            }
            let Some((gbuffer_bytes, stats)) = last else { continue };
            let sort_floor = if options.row_floors && stats.pairs > 0 {
                progress(&format!("{n} Gaussians at {w}x{h}: the pair-move floor at {} pairs", stats.pairs));
                Some(limits::pair_move_floor(device, stats.pairs, repeats)?)
            } else {
                None
            };
            let bandwidth = if options.row_floors {
                progress(&format!("{n} Gaussians at {w}x{h}: the memory bandwidth"));
                Some(limits::memory_bandwidth(device, bandwidth_probe_bytes(device), repeats)?)
            } else {
                None
            };
            let mut kernel_timings = Vec::new();
            if sort_kernels {
                progress(&format!("{n} Gaussians at {w}x{h}: timing the sort's kernels"));
                splatter.set_sort_kernel_stages(true);
                let runs: Result<Vec<_>> =
                    (0..repeats.max(1)).map(|_| Ok(splatter.render(&scene, &cam, &settings)?.1.timings)).collect();
                splatter.set_sort_kernel_stages(false);
                kernel_timings = runs?;
            }
            progress(&format!("{n} Gaussians at {w}x{h}: counting blend work on the CPU"));
            let work = srug::splat::cpu::blend_work(&city.scene, &cam, tile, tile_bounds);
            let visible = (0..city.scene.len())
                .filter(|&i| {
                    srug::splat::cpu::preprocess_one(&city.scene, i, &cam, NormalSource::default(), tile).is_some()
                })
                .count() as u64;
            // Means, then log-scales, rotation, opacity and SH at the degree used.
            let (position, rest) = (12u64, 12 + 16 + 4 + 4 * 3 * u64::from((sh_degree + 1) * (sh_degree + 1)));
            // The 64-byte splat record and a 32-bit tile count.
            let (record, count) = (64u64, 4u64);
            rows.push(SplatBenchRow {
                gaussians: n,
                width: w,
                height: h,
                stages: stage_medians(&timings, |_| true),
                pairs: stats.pairs,
                working_bytes: stats.working_bytes,
                scene_bytes: city.scene.gpu_bytes(),
                gbuffer_bytes,
                blend_evaluations: work.evaluated,
                blend_contributions: work.contributed,
                longest_walk: work.longest_walk,
                chunks: stats.chunks,
                visible,
                key_bits: stats.key_bits,
                preprocess_read_bytes: n as u64 * position + visible * rest,
                preprocess_write_bytes: visible * (record + count) + (n as u64 - visible) * count,
                sort_kernels: stage_medians(&kernel_timings, is_sort_kernel),
                sort_floor,
                bandwidth,
            });
        }
    }
    if options.row_floors {
        // Each row's floors once more, after every row: each keeps the faster of its two.
        for r in &mut rows {
            progress(&format!("{} Gaussians at {}x{}: the floors again", r.gaussians, r.width, r.height));
            if let Some(first) = &r.sort_floor {
                r.sort_floor = Some(first.best(&limits::pair_move_floor(device, r.pairs, repeats)?));
            }
            if let Some(first) = r.bandwidth {
                r.bandwidth =
                    Some(first.best(&limits::memory_bandwidth(device, bandwidth_probe_bytes(device), repeats)?));
            }
        }
    }
    Ok(rows)
}

/// Stage names once each, splat stages in pipeline order ([`srug::splat::SPLAT_STAGES`]), others after.
pub fn splat_stage_order<'a>(names: impl IntoIterator<Item = &'a String>) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    for name in names {
        if !out.contains(name) {
            out.push(name.clone());
        }
    }
    let place = |n: &String| srug::splat::SPLAT_STAGES.iter().position(|s| s == n).unwrap_or(usize::MAX);
    out.sort_by_key(place);
    out
}

/// One scene and size of [`alternate_bench`]: each choice's median stage
/// times, and each stage's ratio to the first choice's, frame pair by frame pair.
#[derive(Clone, Debug)]
pub struct AlternateRow {
    /// Gaussians in the demo city.
    pub gaussians: usize,
    /// Image size.
    pub width: u32,
    /// Image size.
    pub height: u32,
    /// Each choice's name and median seconds per stage, in pipeline order.
    pub choices: Vec<(String, Vec<(String, f64)>)>,
    /// For each choice after the first: per stage, and for the whole frame
    /// ("total"), the median, least and greatest of its frames' times over
    /// the first choice's frame of the same round.
    pub ratios: Vec<Vec<(String, Ratio)>>,
}

/// Median, least and greatest of a set of ratios.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ratio {
    /// The median.
    pub median: f64,
    /// The least.
    pub min: f64,
    /// The greatest.
    pub max: f64,
}

impl Ratio {
    /// The median, least and greatest of `values` (NaN for none).
    pub fn of(values: &[f64]) -> Ratio {
        let fold = |f: fn(f64, f64) -> f64, start| values.iter().copied().fold(start, f);
        if values.is_empty() {
            return Ratio { median: f64::NAN, min: f64::NAN, max: f64::NAN };
        }
        Ratio {
            median: median(values.to_vec()),
            min: fold(f64::min, f64::INFINITY),
            max: fold(f64::max, f64::NEG_INFINITY),
        }
    }
}

/// Renders each scene and size with every one of `choices` (a name and the
/// splatter choices it stands for; at least two), one frame each in turn,
/// `repeats` rounds, the order reversed every other round (A B, B A, ...),
/// so a machine whose speed drifts during the run slows every choice alike.
/// Each choice has a splatter of its own.
pub fn alternate_bench(
    device: &Device,
    counts: &[usize],
    sizes: &[(u32, u32)],
    options: &SplatBenchOptions,
    choices: &[(String, SplatterChoices)],
    mut progress: impl FnMut(&str),
) -> Result<Vec<AlternateRow>> {
    if choices.len() < 2 {
        return Err(Error::invalid(format!("{} choices to alternate", choices.len()), "needs two or more"));
    }
    let base = SplatSettings { tile: options.tile, tile_bounds: options.tile_bounds, ..SplatSettings::default() };
    let settings: Vec<SplatSettings> = choices.iter().map(|(_, c)| c.settings(base)).collect();
    let mut splatters = Vec::with_capacity(choices.len());
    for (_, c) in choices {
        let mut splatter = Splatter::new(device)?;
        c.apply(&mut splatter)?;
        splatters.push(splatter);
    }
    let mut rows = Vec::new();
    for &n in counts {
        progress(&format!("generating the demo city with {n} Gaussians"));
        let city = bench_city(n, options.sh_degree, options.order)?;
        let scene = bench_scene(device, &city, options, &mut progress)?;
        for &(w, h) in sizes {
            progress(&format!("{n} Gaussians at {w}x{h}"));
            let cam = city.cameras[0].resized(w, h);
            // One warm-up frame each (the first frame reserves scratch memory and builds
            // kernels), then the device's warm-up, the values in turn.
            for (splatter, settings) in splatters.iter_mut().zip(&settings) {
                splatter.render(&scene, &cam, settings)?;
            }
            let mut next = 0;
            warm_up(options.warm_up, || {
                next = (next + 1) % splatters.len();
                splatters[next].render(&scene, &cam, &settings[next]).map(drop)
            })?;
            let mut timings: Vec<Vec<Timings>> = vec![Vec::new(); choices.len()];
            for round in 0..options.repeats.max(1) {
                let order: Vec<usize> =
                    if round % 2 == 0 { (0..choices.len()).collect() } else { (0..choices.len()).rev().collect() };
                for i in order {
                    timings[i].push(splatters[i].render(&scene, &cam, &settings[i])?.1.timings);
                }
            }
            // Every choice's stages (a compacted frame's `cull` too), then the whole frame.
            let mut stage_names =
                splat_stage_order(timings.iter().filter_map(|t| t.first()).flat_map(|t| &t.stages).map(|s| &s.name));
            stage_names.push("total".to_string());
            let seconds = |t: &Timings, name: &str| {
                if name == "total" {
                    t.total_seconds()
                } else {
                    t.stages.iter().find(|s| s.name == name).map_or(f64::NAN, |s| s.seconds)
                }
            };
            let ratios = (1..choices.len())
                .map(|i| {
                    stage_names
                        .iter()
                        .map(|name| {
                            let r: Vec<f64> = timings[i]
                                .iter()
                                .zip(&timings[0])
                                .map(|(b, a)| seconds(b, name) / seconds(a, name))
                                .filter(|r| r.is_finite())
                                .collect();
                            (name.clone(), Ratio::of(&r))
                        })
                        .collect()
                })
                .collect();
            rows.push(AlternateRow {
                gaussians: n,
                width: w,
                height: h,
                choices: choices
                    .iter()
                    .zip(&timings)
                    .map(|((name, _), t)| (name.clone(), stage_medians(t, |_| true)))
                    .collect(),
                ratios,
            });
        }
    }
    Ok(rows)
}

/// GPU radix sort against `sort_unstable` on the CPU, same keys, same run.
#[derive(Clone, Debug)]
pub struct SortBench {
    /// Keys sorted.
    pub keys: usize,
    /// Key bits sorted.
    pub bits: u32,
    /// The digits the GPU sort took ([`RadixSort::digits`]).
    pub digits: SortDigits,
    /// GPU keys per second (median).
    pub gpu_keys_per_second: f64,
    /// CPU `sort_unstable` keys per second (median), on 64-bit (key, value) words.
    pub cpu_keys_per_second: f64,
    /// Where asked: the median seconds of each of the GPU sort's kernels,
    /// timed in sorts of their own, in order (as [`SplatBenchRow::sort_kernels`]).
    pub kernels: Vec<(String, f64)>,
}

/// Sorts `n` random splat-like keys on `bits` bits on the GPU and with `sort_unstable`.
/// `choices` may override the device's default sort digits and scan shape.
pub fn sort_bench(
    device: &Device,
    n: usize,
    bits: u32,
    repeats: usize,
    choices: &SplatterChoices,
    kernels: bool,
) -> Result<SortBench> {
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    let mask = if bits >= 64 { u64::MAX } else { (1u64 << bits) - 1 };
    let keys64: Vec<u64> = (0..n).map(|_| next() & mask).collect();
    let keys: Vec<[u32; 2]> = keys64.iter().map(|k| [*k as u32, (*k >> 32) as u32]).collect();
    let values: Vec<u32> = (0..n as u32).collect();
    let kb = device.upload("bench keys", &keys)?;
    let vb = device.upload("bench values", &values)?;
    let mut sort = RadixSort::new(device)?;
    if let Some(digits) = choices.sort_digits {
        sort.set_digits(device, digits)?;
    }
    if let Some(on) = choices.scan_tiles {
        sort.set_scan_tiles(device, on)?;
    }
    sort.reserve(device, n as u64)?;
    let mut gpu = Vec::new();
    let mut cpu = Vec::new();
    for _ in 0..repeats.max(1) {
        device.write_buffer(&kb, 0, &keys)?;
        let t = device.run(|rec| {
            rec.begin_stage("sort");
            sort.record(rec, &kb, &vb, n as u64, bits)
        })?;
        gpu.push(n as f64 / t.get("sort").unwrap_or(f64::NAN));
        // The CPU sorts (key, value) packed the same way the GPU carries them.
        let mut pairs: Vec<(u64, u32)> = keys64.iter().copied().zip(values.iter().copied()).collect();
        let started = Instant::now();
        pairs.sort_unstable_by_key(|p| p.0);
        cpu.push(n as f64 / started.elapsed().as_secs_f64());
        std::hint::black_box(&pairs);
    }
    let mut kernel_timings = Vec::new();
    if kernels {
        sort.set_kernel_stages(true);
        for _ in 0..repeats.max(1) {
            device.write_buffer(&kb, 0, &keys)?;
            kernel_timings.push(device.run(|rec| sort.record(rec, &kb, &vb, n as u64, bits))?);
        }
    }
    Ok(SortBench {
        keys: n,
        bits,
        digits: sort.digits(),
        gpu_keys_per_second: median(gpu),
        cpu_keys_per_second: median(cpu),
        kernels: stage_medians(&kernel_timings, is_sort_kernel),
    })
}

#[cfg(test)]
mod tests {
    use super::host_cpu_from;

    #[test]
    fn host_cpu_names_model_family_and_isa() {
        let info =
            "processor\t: 0\nvendor_id\t: AuthenticAMD\ncpu family\t: 25\nmodel\t\t: 1\nmodel name\t: AMD EPYC\n";
        assert_eq!(
            host_cpu_from(info, 2, "AVX2 (no AVX-512)"),
            "AMD EPYC, family 25 model 1, 2 CPUs, AVX2 (no AVX-512)"
        );
        assert_eq!(host_cpu_from("", 4, "AVX-512"), format!("{}, 4 CPUs, AVX-512", std::env::consts::ARCH));
    }

    use std::time::{Duration, Instant};

    use super::warm_up;

    #[test]
    fn warm_up_renders_until_its_time_has_passed_and_stops_at_an_error() {
        let mut frames = 0;
        let ran = warm_up(Duration::ZERO, || {
            frames += 1;
            Ok(())
        });
        assert_eq!((ran.ok(), frames), (Some(0), 0), "no frame for no warm-up");

        let start = Instant::now();
        let ran = warm_up(Duration::from_millis(30), || {
            frames += 1;
            std::thread::sleep(Duration::from_millis(4));
            Ok(())
        });
        assert!(start.elapsed() >= Duration::from_millis(30), "stopped before its time");
        assert_eq!(ran.ok(), Some(frames));
        assert!(frames >= 1);

        let mut calls = 0;
        let ran = warm_up(Duration::from_secs(60), || {
            calls += 1;
            if calls == 2 {
                return Err(srug::Error::invalid("frame", "failed"));
            }
            Ok(())
        });
        assert!(ran.is_err() && calls == 2, "the first error ends the warm-up: {calls} calls");
    }
}
