//! `srug bench splat`: per-stage splatting times on the demo city, the GPU sort
//! against `sort_unstable`, and the device limits beside them (FMA peak, the
//! blend's arithmetic ceiling, the pair-move floor of a sort pass, the memory
//! bandwidth), with each stage's share of its own floor.

use srug::scene::order::SceneOrder;
use srug::splat::{check_tile, default_chunk_length, TileBounds, DEFAULT_TILE};
use srug::Result;

use crate::args::{spinner, DeviceArgs, Size};
use crate::bench;

/// Arguments of `srug bench splat`.
#[derive(clap::Args, Clone, Debug)]
pub(crate) struct SplatBenchArgs {
    /// Gaussian counts, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "100000,1000000,3000000")]
    gaussians: Vec<usize>,
    /// Image sizes, comma-separated WxH.
    #[arg(long, value_delimiter = ',', default_value = "704x192,1408x384")]
    sizes: Vec<Size>,
    /// Repeats per setting (medians are reported).
    #[arg(long, default_value_t = 3)]
    repeats: usize,
    /// SH degree of the demo city (0 to 3): what the preprocess reads and evaluates.
    #[arg(long, default_value_t = 1)]
    sh_degree: u32,
    /// Keys for the sort comparison.
    #[arg(long, default_value_t = 4_000_000)]
    sort_keys: usize,
    /// Pairs the pair-move floor printed under the table is measured at (apart from --sort-keys;
    /// "sort % of floor" uses it, scaled to each row's pairs, only with --row-floors false).
    #[arg(long, default_value_t = 4_000_000)]
    floor_pairs: u64,
    /// Measure the pair-move floor again at each row's own pairs, and the memory bandwidth, right
    /// after the row's frames: that row's "sort % of floor" takes its own floor, "preprocess % of
    /// floor" the fastest bandwidth of every probe (a host's memory speed moves between probes;
    /// false: the one floor measured at --floor-pairs, scaled, and the one bandwidth, quicker).
    #[arg(long, default_value_t = true, action = clap::ArgAction::Set)]
    row_floors: bool,
    /// Tile edge in pixels: 8, 16 or 32.
    #[arg(long, default_value_t = DEFAULT_TILE)]
    tile: u32,
    /// The splatter's kernel choices (each defaults to the device's).
    #[command(flatten)]
    choices: bench::SplatterChoices,
    /// Which tiles list a splat: ellipse (those that can see it at α ≥ 1/255) or rectangle (its 3σ square).
    #[arg(long, default_value = "ellipse")]
    tile_bounds: TileBounds,
    /// Also time each kernel of the sorts (every pass's histogram, scan and scatter), in runs of
    /// their own, and print where each sort's time goes.
    #[arg(long)]
    sort_kernels: bool,
    /// Instead of the tables, compare values of one kernel choice, frame by frame in turn
    /// (rounds alternating A B, B A): OPTION=A,B[,...], OPTION one of the choices above without
    /// its dashes (e.g. texel-preprocess=true,false); prints each value's stage medians and its
    /// ratios to the first value's frames. The other choices given apply to every value.
    #[arg(long, value_name = "OPTION=A,B")]
    alternate: Option<String>,
    /// The order of the demo city's Gaussians: generated (object by object, so neighbours in the
    /// file are neighbours in space), shuffled (a fixed random order, as a trained scene's file
    /// holds them) or morton (along a Morton curve, as `srug convert --order morton` writes).
    #[arg(long, value_enum, default_value = "generated")]
    order: bench::CityOrder,
    /// Where the city's Gaussians go on the device, as `srug render --scene-order` (auto: along
    /// a Morton curve when they are listed in no spatial order, as --order shuffled lists them).
    #[arg(long, default_value = "auto", value_parser = SceneOrder::parse)]
    scene_order: SceneOrder,
    #[command(flatten)]
    warm_up: bench::WarmUpArgs,
}

/// Wraps the splatter choices for parsing one of them alone.
#[derive(clap::Parser)]
#[command(no_binary_name = true)]
struct OneChoice {
    #[command(flatten)]
    choices: bench::SplatterChoices,
}

/// The choices `--alternate OPTION=A,B,...` stands for: ("OPTION=A", `base` with OPTION set to A), ...
fn alternatives(spec: &str, base: &bench::SplatterChoices) -> Result<Vec<(String, bench::SplatterChoices)>> {
    let bad = |why: String| srug::Error::invalid(format!("--alternate {spec}"), why);
    let (option, values) = spec.split_once('=').ok_or_else(|| bad("is not OPTION=A,B".into()))?;
    let values: Vec<&str> = values.split(',').collect();
    if values.len() < 2 || values.iter().any(|v| v.is_empty()) {
        return Err(bad("needs two values or more, comma-separated".into()));
    }
    values
        .iter()
        .map(|value| {
            let flag = format!("--{option}");
            let one = <OneChoice as clap::Parser>::try_parse_from([flag.as_str(), value])
                .map_err(|e| bad(e.render().to_string().lines().next().unwrap_or_default().to_string()))?;
            Ok((format!("{option}={value}"), base.merged(&one.choices)))
        })
        .collect()
}

impl SplatBenchArgs {
    /// Runs `srug bench splat`.
    pub(crate) fn run(&self, device_args: &DeviceArgs) -> Result<()> {
        let &Self {
            ref gaussians,
            ref sizes,
            repeats,
            sh_degree,
            sort_keys,
            floor_pairs,
            row_floors,
            tile,
            choices,
            tile_bounds,
            sort_kernels,
            ref alternate,
            order,
            scene_order,
            warm_up,
        } = self;
        check_tile(tile)?;
        if sh_degree > 3 {
            return Err(srug::Error::invalid(format!("--sh-degree {sh_degree}"), "is not 0 to 3"));
        }
        let counts = gaussians;
        let sizes: Vec<(u32, u32)> = sizes.iter().map(|s| s.pair()).collect();
        let device = device_args.open()?;
        let info = device.info();
        let peak = bench::fma_peak_gflops(&device, 5)?;
        println!("device: {} ({}), measured FMA peak {peak:.1} GFLOP/s", info.name, info.driver);
        let warm = warm_up.duration(&device);
        if !warm.is_zero() {
            println!("warm-up: {} ms of untimed frames before each row's timed ones", warm.as_millis());
        }
        println!(
            "scene: the demo city (seed 7) at SH degree {sh_degree}{}, its first street camera\n",
            match order {
                bench::CityOrder::Generated => "",
                bench::CityOrder::Shuffled => ", its Gaussians shuffled",
                bench::CityOrder::Morton => ", its Gaussians in Morton order",
            }
        );
        let options = bench::SplatBenchOptions {
            repeats,
            sh_degree,
            choices,
            tile,
            tile_bounds,
            sort_kernels,
            order,
            scene_order,
            warm_up: warm_up.duration(&device),
            row_floors,
        };
        if let Some(spec) = alternate {
            let variants = alternatives(spec, &choices)?;
            let bar = spinner("benchmarking");
            let rows = bench::alternate_bench(&device, counts, &sizes, &options, &variants, |m| {
                bar.set_message(m.to_string())
            })?;
            bar.finish_and_clear();
            print_alternation(&rows, repeats);
            return Ok(());
        }
        let bar = spinner("benchmarking");
        // The blend ceiling before the rows and again after them: the better of the two (as the FMA peak).
        bar.set_message("measuring the blend ceiling");
        let ceiling_before = bench::limits::blend_ceiling(&device, repeats)?;
        let rows = bench::splat_bench(&device, counts, &sizes, &options, |m| bar.set_message(m.to_string()))?;
        bar.set_message("sorting");
        let sort = bench::sort_bench(&device, sort_keys, 32 + 11, repeats, &choices, sort_kernels)?;
        bar.set_message("measuring the blend ceiling, the pair-move floor and the memory bandwidth");
        let ceiling_after = bench::limits::blend_ceiling(&device, repeats)?;
        let ceiling = if ceiling_after.gflops >= ceiling_before.gflops { ceiling_after } else { ceiling_before };
        let floor = bench::limits::pair_move_floor(&device, floor_pairs, repeats)?;
        let bandwidth = bench::limits::memory_bandwidth(&device, bench::bandwidth_probe_bytes(&device), repeats)?;
        // The peak again after the rows: a device slowed while the first probe ran (a
        // busy host) would otherwise inflate every "% of FMA peak"; a peak is the best seen.
        let peak_at_end = bench::fma_peak_gflops(&device, 5)?;
        let first_peak = peak;
        let peak = peak.max(peak_at_end);
        bar.finish_and_clear();
        println!(
            "FMA peak {first_peak:.1} GFLOP/s before the rows and {peak_at_end:.1} after them; the columns take the better, {peak:.1}\n"
        );
        let stage_names: Vec<String> =
            rows.first().map(|r| r.stages.iter().map(|s| s.0.clone()).collect()).unwrap_or_default();
        println!(
            "| Gaussians | size | {} | total ms | pairs | working MiB | scene MiB | G-buffer MiB | blend evals (M) | longest walk | split chunks | blend GFLOP/s | % of FMA peak | ceiling % | preprocess % of floor | sort floor ms | sort % of floor | blend % of ceiling |",
            stage_names.join(" ms | ") + " ms"
        );
        println!(
            "|---:|---|{}---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
            "---:|".repeat(stage_names.len())
        );
        // The preprocess's floor at the fastest read and copy of every bandwidth probe of the run
        // (this host's memory speed moves between probes seconds apart; a floor takes its best).
        let fastest = rows.iter().filter_map(|r| r.bandwidth).fold(bandwidth, |best, b| best.best(&b));
        // Columns over 100%: a stage beat the floor measured for it.
        let mut over_floor = Vec::new();
        for r in &rows {
            let stages: Vec<String> = stage_names
                .iter()
                .map(|n| r.stages.iter().find(|s| &s.0 == n).map_or("-".to_string(), |s| format!("{:.1}", s.1 * 1e3)))
                .collect();
            let mib = |b: u64| b as f64 / (1u64 << 20) as f64;
            let stage = |name: &str| r.stages.iter().find(|s| s.0 == name).map_or(f64::NAN, |s| s.1);
            let preprocess_floor = fastest.floor_seconds(r.preprocess_read_bytes, r.preprocess_write_bytes);
            // Compacted records read the positions in a cull stage before the preprocess: both count.
            let preprocess = stage("preprocess") + r.stages.iter().find(|s| s.0 == "cull").map_or(0.0, |s| s.1);
            // The LSD bound for this row's key width: at the row's own floor, else scaled from the floor's pairs.
            let sort_floor = match &r.sort_floor {
                Some(own) => own.lsd_bound(r.key_bits).map_or(f64::NAN, |(_, s)| s),
                None => {
                    floor.lsd_bound(r.key_bits).map_or(f64::NAN, |(_, s)| s * r.pairs as f64 / floor.keys.max(1) as f64)
                }
            };
            let blend_ceiling = ceiling.for_work(r.blend_evaluations, r.blend_contributions);
            for (column, share) in [
                ("preprocess % of floor", preprocess_floor / preprocess),
                ("sort % of floor", sort_floor / stage("sort")),
                ("blend % of ceiling", r.blend_gflops() / blend_ceiling),
            ] {
                if share > 1.0 && !over_floor.contains(&column) {
                    over_floor.push(column);
                }
            }
            println!(
                "| {} | {}x{} | {} | {:.1} | {} | {:.1} | {:.1} | {:.1} | {:.1} | {} | {} | {:.2} | {:.1} | {:.1} | {:.0} | {:.1} | {:.0} | {:.0} |",
                r.gaussians,
                r.width,
                r.height,
                stages.join(" | "),
                r.total() * 1e3,
                r.pairs,
                mib(r.working_bytes),
                mib(r.scene_bytes),
                mib(r.gbuffer_bytes),
                r.blend_evaluations as f64 * 1e-6,
                r.longest_walk,
                r.chunks,
                r.blend_gflops(),
                r.blend_gflops() / peak * 100.0,
                blend_ceiling / peak * 100.0,
                preprocess_floor / preprocess * 100.0,
                sort_floor * 1e3,
                sort_floor / stage("sort") * 100.0,
                r.blend_gflops() / blend_ceiling * 100.0,
            );
        }
        if !over_floor.is_empty() {
            println!(
                "\nnote: {} above 100 in some rows: a stage ran faster than the floor measured for it, so that probe under-measures this device (a cache the stage hits, or a read path slower than the stage's); those columns overstate the stage",
                over_floor.join(", ")
            );
        }
        println!(
            "\nmemory bandwidth ({} MiB read once, and copied once; the fastest of reading through an RGBA32F texel view or as uvec4s by device address, each invocation reading a run of texels or neighbouring invocations reading neighbouring texels, here {} {}): read {:.1} GB/s, copy {:.1} GB/s moved; \"preprocess % of floor\" is the least time to read every Gaussian's position and the visible ones' other attributes and write their splat records and every tile count at {}, over the measured preprocess (and cull, with compacted records); \"sort floor ms\" the LSD bound below for the row's key bits and pairs ({}), \"sort % of floor\" that bound over the measured sort; \"blend % of ceiling\" the blend's GFLOP/s over its ceiling for the row's mix",
            bandwidth.bytes >> 20,
            match bandwidth.read_through {
                bench::limits::BandwidthRead::Texels => "texel fetches",
                bench::limits::BandwidthRead::Address => "device-address loads",
            },
            match bandwidth.read_layout {
                bench::limits::BandwidthLayout::Runs => "in runs",
                bench::limits::BandwidthLayout::Interleaved => "interleaved",
            },
            bandwidth.read * 1e-9,
            bandwidth.copy * 1e-9,
            if row_floors {
                format!(
                    "the fastest rates of these and every row's own probe (each row's floor line below): read {:.1} GB/s, copy {:.1} GB/s",
                    fastest.read * 1e-9,
                    fastest.copy * 1e-9
                )
            } else {
                "those rates".to_string()
            },
            if row_floors {
                "at a pair-move floor measured at the row's own pairs right after its frames and again after every row"
            } else {
                "scaled from the one pair-move floor below"
            }
        );
        println!(
            "\nblend flops: {} per evaluated pair + {} per contributing pair (exp not counted); pairs counted by replaying the blend on the CPU twin; \"longest walk\" is the most splats one pixel reads before it is done in that replay: one workgroup walks each tile's list, so where the device runs every tile at once (a GPU) the blend lasts at least as long as one walk that far, {}",
            bench::BLEND_FLOPS_PER_EVALUATION,
            bench::BLEND_FLOPS_PER_CONTRIBUTION,
            match choices.chunk_length.unwrap_or_else(|| default_chunk_length(info)) {
                0 => "and no list was split (--chunk-length 0)".to_string(),
                n => format!("unless the list is split: here the texel blend walked lists longer than {} entries in chunks of {n} (more where they would take over 256 MiB; --chunk-length)", 2 * u64::from(n)),
            }
        );
        println!(
            "sort, {} keys on {} bits ({} digits): GPU {:.1} M keys/s, CPU sort_unstable {:.1} M keys/s (ratio {:.2})",
            sort.keys,
            sort.bits,
            sort.digits.name(),
            sort.gpu_keys_per_second * 1e-6,
            sort.cpu_keys_per_second * 1e-6,
            sort.gpu_keys_per_second / sort.cpu_keys_per_second
        );
        println!(
            "blend ceiling (the blend's arithmetic with no memory traffic, every evaluation contributing, {} pixels per invocation; the better of a probe before the rows, {:.1} GFLOP/s, and one after them, {:.1}): {:.1} GFLOP/s, {:.1}% of FMA peak; \"ceiling %\" is that bound on each row's mix of evaluations and contributions",
            ceiling.pixels,
            ceiling_before.gflops,
            ceiling_after.gflops,
            ceiling.gflops,
            ceiling.gflops / peak * 100.0
        );
        let ms = |s: f64| s * 1e3;
        println!(
            "pair-move floor, {} pairs (each read once; written once to the same index): read only {:.1} ms, writing the value {:.1} ms, writing key and value {:.1} ms; writing the value where a radix pass would put it, by digit width in bits, {} ms; to a random index {:.1} ms",
            floor.keys,
            ms(floor.read_seconds),
            ms(floor.value_seconds),
            ms(floor.pair_seconds),
            floor
                .digit_seconds
                .iter()
                .map(|(bits, s)| format!("{bits}: {:.1}", ms(*s)))
                .collect::<Vec<_>>()
                .join(", "),
            ms(floor.random_seconds),
        );
        if rows.iter().any(|r| r.sort_floor.is_some() || r.bandwidth.is_some()) {
            println!("\neach row's own floors (measured as the ones above, the pair-move floor at the row's pairs, right after its frames and again after every row, the faster of the two):");
            for r in &rows {
                let memory = r
                    .bandwidth
                    .map(|b| format!("memory read {:.1} GB/s, copy {:.1} GB/s moved", b.read * 1e-9, b.copy * 1e-9));
                let pairs = r.sort_floor.as_ref().and_then(|own| {
                    let (digit, bound) = own.lsd_bound(r.key_bits)?;
                    Some(format!(
                        "LSD bound {:.1} ms (best digit width {digit} bits); read only {:.1} ms, writing the value {:.1} ms; where a radix pass would put it, by digit width in bits, {} ms; to a random index {:.1} ms",
                        ms(bound),
                        ms(own.read_seconds),
                        ms(own.value_seconds),
                        own.digit_seconds
                            .iter()
                            .map(|(bits, s)| format!("{bits}: {:.1}", ms(*s)))
                            .collect::<Vec<_>>()
                            .join(", "),
                        ms(own.random_seconds),
                    ))
                });
                println!(
                    "- floor of {} Gaussians at {}x{} ({} pairs on {} bits): {}",
                    r.gaussians,
                    r.width,
                    r.height,
                    r.pairs,
                    r.key_bits,
                    memory.into_iter().chain(pairs).collect::<Vec<_>>().join("; ")
                );
            }
        }
        if sort_kernels {
            println!("\nthe sorts' kernels, each timed as a stage of its own (pass, the key bits its digit sorts, kernel), medians:");
            for r in &rows {
                println!(
                    "- {} Gaussians at {}x{} ({} pairs on {} bits): {}",
                    r.gaussians,
                    r.width,
                    r.height,
                    r.pairs,
                    r.key_bits,
                    bench::sort_kernels_line(&r.sort_kernels)
                );
            }
            println!("- {} random keys on {} bits: {}", sort.keys, sort.bits, bench::sort_kernels_line(&sort.kernels));
        }
        if let Some((digit, bound)) = floor.lsd_bound(sort.bits) {
            println!(
                "an LSD radix sort of {}-bit keys needs at least {:.1} ms at these floors (best digit width {digit} bits: each pass writes every pair where it goes and its bucket offsets, and above 4 bits updates a count in memory per key); 2x sort_unstable allows {:.1} ms",
                sort.bits,
                ms(bound),
                ms(floor.keys as f64 / (2.0 * sort.cpu_keys_per_second))
            );
        }
        Ok(())
    }
}

/// The table of `srug bench splat --alternate`: each value's stage medians,
/// then each later value's ratios to the first.
fn print_alternation(rows: &[bench::AlternateRow], repeats: usize) {
    let Some(first) = rows.first() else { return };
    let names = bench::splat_stage_order(first.choices.iter().flat_map(|c| &c.1).map(|s| &s.0));
    let stages: Vec<&str> = names.iter().map(String::as_str).collect();
    println!(
        "each value renders one frame in turn, {} rounds (A B, then B A, ...), after a warm-up frame each; \
         ratios are a value's frame over the first value's frame of the same round: median (least-greatest)\n",
        repeats.max(1)
    );
    println!("| Gaussians | size | choice | {} ms | total ms |", stages.join(" ms | "));
    println!("|---:|---|---|{}---:|", "---:|".repeat(stages.len()));
    for r in rows {
        for (name, medians) in &r.choices {
            let ms: Vec<String> = stages
                .iter()
                .map(|n| medians.iter().find(|s| s.0 == *n).map_or("-".into(), |s| format!("{:.1}", s.1 * 1e3)))
                .collect();
            let total: f64 = medians.iter().map(|s| s.1).sum();
            println!(
                "| {} | {}x{} | {name} | {} | {:.1} |",
                r.gaussians,
                r.width,
                r.height,
                ms.join(" | "),
                total * 1e3
            );
        }
        for (i, ratios) in r.ratios.iter().enumerate() {
            let cells: Vec<String> = stages
                .iter()
                .copied()
                .chain(std::iter::once("total"))
                .map(|n| {
                    ratios
                        .iter()
                        .find(|s| s.0 == n)
                        .filter(|(_, q)| q.median.is_finite())
                        .map_or("-".into(), |(_, q)| format!("{:.2} ({:.2}-{:.2})", q.median, q.min, q.max))
                })
                .collect();
            println!(
                "| {} | {}x{} | {} / {} | {} |",
                r.gaussians,
                r.width,
                r.height,
                r.choices[i + 1].0,
                r.choices[0].0,
                cells.join(" | ")
            );
        }
    }
}
