//! The `srug` command line.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::{Duration, Instant};

mod cli_relight;

use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use srug::gpu::{self, Device, DeviceOptions, DeviceSelection};
use srug::output;
use srug::scene::{self, activate, demo, human_bytes, PlyFormat};
use srug::splat::{Channels, NormalSource, SplatSettings, Splatter};
use srug::Error;

#[derive(Parser)]
#[command(name = "srug", version, about = "Render and relight 3D Gaussian Splatting city scenes with Vulkan compute")]
struct Cli {
    /// Device: an index from `srug devices`, `gpu`, `cpu`, or part of a name (default: SRUG_DEVICE, else automatic).
    #[arg(long, global = true)]
    device: Option<String>,
    /// Run the Khronos validation layer (also SRUG_VALIDATION=1).
    #[arg(long, global = true)]
    validation: bool,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Print a scene's Gaussian count, SH degree, attribute groups, bounds and GPU memory.
    Info {
        /// A 3DGS PLY file.
        scene: PathBuf,
        /// Also list the stages, G-buffer channels, shader variants and GPU memory a relit
        /// frame of the scene will take with the options below (nothing is rendered).
        #[arg(long)]
        plan: bool,
        /// Image size of the planned frame.
        #[arg(long, default_value = "704x192")]
        size: String,
        /// Extra G-buffer channels to keep (as for `srug render --channels`).
        #[arg(long, default_value = "rgb")]
        channels: String,
        #[command(flatten)]
        sun: cli_relight::SunArgs,
        #[command(flatten)]
        shade: cli_relight::ShadeArgs,
        /// Indirect-light network weights (safetensors).
        #[arg(long)]
        indirect: Option<PathBuf>,
        /// Activation storage of the indirect network: fp32 or fp16.
        #[arg(long, default_value = "fp32")]
        indirect_precision: String,
    },
    /// List the Vulkan devices.
    Devices,
    /// PSNR and SSIM of rendered images against references (the paper's relighting metrics):
    /// two files, or two folders whose images are paired by name.
    Eval {
        /// Reference image or folder (.png, .exr, .hdr).
        reference: PathBuf,
        /// Rendered image or folder.
        rendered: PathBuf,
        /// Peak value (data range): 1 for PNGs; for linear EXR, the value that counts as white.
        #[arg(long, default_value_t = 1.0)]
        peak: f64,
        /// Also write the per-image figures as CSV.
        #[arg(long)]
        csv: Option<PathBuf>,
    },
    /// Benchmarks (GPU timestamps; markdown tables on stdout).
    Bench {
        #[command(subcommand)]
        what: BenchKind,
    },
    /// Render a scene into G-buffers: PNG (rgb) for viewing, multi-channel float EXR for data.
    Render {
        /// A 3DGS PLY file.
        scene: PathBuf,
        #[command(flatten)]
        view: cli_relight::CameraArgs,
        /// Output file, .png or .exr.
        #[arg(long)]
        out: PathBuf,
        /// Channels: rgb, depth, median_depth, normal, albedo, roughness, metallic, ao,
        /// visibility, materials, all. EXR holds those listed and alpha (rgb only if listed);
        /// PNG shows rgb.
        #[arg(long, default_value = "rgb")]
        channels: String,
        /// Background colour r,g,b.
        #[arg(long, default_value = "0,0,0")]
        background: String,
        /// Normals from each Gaussian's stored normal where present (default: shortest axis).
        #[arg(long)]
        stored_normals: bool,
        /// Spherical-harmonic degree used for colour (default: the scene's).
        #[arg(long)]
        sh_degree: Option<u32>,
        /// Tile edge in pixels: 8, 16 or 32.
        #[arg(long, default_value_t = srug::splat::DEFAULT_TILE)]
        tile: u32,
        /// Which tiles list a splat: ellipse (those that can see it at α ≥ 1/255) or rectangle
        /// (its 3σ square, as INRIA's rasterizer); the image is the same, ellipse sorts and blends less.
        #[arg(long, default_value = "ellipse")]
        tile_bounds: srug::splat::TileBounds,
    },
    /// Relight a scene with materials: sun (Cook–Torrance, sigmoid shadow map) and sky
    /// (split-sum image-based lighting); a sun path renders a time-lapse.
    Relight(Box<cli_relight::RelightArgs>),
    /// Run the indirect-light U-Net once on an NCHW float32 tensor named `input`; writes `output`
    /// (to check an exported network against PyTorch).
    Unet {
        /// Weights: safetensors with PyTorch state_dict names, the architecture in its metadata.
        #[arg(long)]
        weights: PathBuf,
        /// Input safetensors with a tensor `input` of shape [1, C, H, W].
        #[arg(long)]
        input: PathBuf,
        /// Output safetensors (tensor `output`, [1, 3, H, W] float32).
        #[arg(long)]
        out: PathBuf,
        /// Activation storage between layers: fp32 or fp16 (arithmetic is fp32 either way).
        #[arg(long, default_value = "fp32")]
        precision: String,
    },
    /// Prefilter an environment map once (GGX chain and irradiance) and save it as KTX2 files in a folder
    /// that `--env` accepts.
    Prefilter {
        /// An .exr, .hdr or .ktx2 environment.
        env: PathBuf,
        /// Output folder (specular.ktx2, irradiance.ktx2).
        #[arg(long)]
        out: PathBuf,
        /// Prefiltered levels (roughness level/(levels−1)).
        #[arg(long, default_value_t = 6)]
        levels: u32,
        /// GGX samples per texel.
        #[arg(long, default_value_t = 128)]
        samples: u32,
        /// Zstandard supercompression.
        #[arg(long)]
        zstd: bool,
    },
    /// The main job on the built-in demo city: generate it, write it, check the GPU on it, and render it.
    Demo {
        /// Number of Gaussians.
        #[arg(long, default_value_t = 200_000)]
        gaussians: usize,
        /// Random seed.
        #[arg(long, default_value_t = 7)]
        seed: u64,
        /// SH degree (0 to 3).
        #[arg(long, default_value_t = 1)]
        sh_degree: u32,
        /// Output folder for demo_city.ply and cameras.json.
        #[arg(long, default_value = "out/demo")]
        out: PathBuf,
    },
    /// Shadow-guided completion on the demo: remove the off-screen tower, then grow Gaussians
    /// where no camera sees until they cast its shadow again (Adam on the shadow loss alone).
    ShadowFit {
        /// Demo city size.
        #[arg(long, default_value_t = 40_000)]
        gaussians: usize,
        /// Demo seed.
        #[arg(long, default_value_t = 7)]
        seed: u64,
        /// Adam steps.
        #[arg(long, default_value_t = 60)]
        steps: u32,
        /// Gaussians added where no camera sees.
        #[arg(long, default_value_t = 4000)]
        added: usize,
        /// Which demo camera receives the shadow.
        #[arg(long, default_value_t = 0)]
        camera: usize,
        /// Receiver image size WxH.
        #[arg(long, default_value = "352x96")]
        size: String,
        /// Sun azimuth, degrees from north toward east.
        #[arg(long, default_value_t = 260.0, allow_negative_numbers = true)]
        sun_azimuth: f32,
        /// Sun elevation, degrees.
        #[arg(long, default_value_t = 50.0, allow_negative_numbers = true)]
        sun_elevation: f32,
        /// Shadow-map resolution (longer side).
        #[arg(long, default_value_t = 256)]
        resolution: u32,
        /// Sigmoid sharpness k per metre.
        #[arg(long, default_value_t = 4.0)]
        k: f32,
        /// Output folder.
        #[arg(long, default_value = "out/shadow-fit")]
        out: PathBuf,
    },
}

#[derive(Subcommand)]
enum BenchKind {
    /// Per-stage splatting times on the demo city; GPU sort against sort_unstable; FMA peak.
    Splat {
        /// Gaussian counts, comma-separated.
        #[arg(long, default_value = "100000,1000000,3000000")]
        gaussians: String,
        /// Image sizes, comma-separated WxH.
        #[arg(long, default_value = "704x192,1408x384")]
        sizes: String,
        /// Repeats per setting (medians are reported).
        #[arg(long, default_value_t = 3)]
        repeats: usize,
        /// Keys for the sort comparison.
        #[arg(long, default_value_t = 4_000_000)]
        sort_keys: usize,
        /// Blend variant: per-pixel, subgroup or batched (default: subgroup where supported).
        #[arg(long)]
        blend: Option<String>,
        /// Tile edge in pixels: 8, 16 or 32.
        #[arg(long, default_value_t = srug::splat::DEFAULT_TILE)]
        tile: u32,
        /// Pixels per invocation of the texel-buffer blend: 1, 2 or 4 (default 2).
        #[arg(long)]
        blend_pixels: Option<u32>,
        /// Which tiles list a splat: ellipse (those that can see it at α ≥ 1/255) or rectangle (its 3σ square).
        #[arg(long, default_value = "ellipse")]
        tile_bounds: srug::splat::TileBounds,
    },
    /// Indirect-light U-Net: time per inference per size and precision, GFLOP/s against the FMA peak.
    Unet {
        /// Widths w0..w4.
        #[arg(long, default_value = "32,32,64,64,128")]
        widths: String,
        /// Image sizes, comma-separated WxH.
        #[arg(long, default_value = "704x192,1408x384")]
        sizes: String,
        /// Repeats (medians reported).
        #[arg(long, default_value_t = 3)]
        repeats: usize,
        /// How conv layers run, comma-separated: winograd (the default where the device has
        /// texel-buffer views: Winograd F(4×4,3×3) for the stride-1 layers, direct convolution for
        /// stride 2, four pixels per fetch where a layer's width is a multiple of 4), winograd2 (the
        /// same with Winograd F(2×2,3×3)), vec4 (direct
        /// convolution for every layer, texel inputs, four pixels per fetch where the width allows),
        /// texel (the same, one pixel per fetch), address (device addresses, the fallback).
        #[arg(long, default_value = "winograd")]
        inputs: String,
    },
    /// Deferred shading time per frame per image size; one-time environment prefilter cost per size.
    Shade {
        /// Demo city size for the G-buffers.
        #[arg(long, default_value_t = 200_000)]
        gaussians: usize,
        /// Image sizes, comma-separated WxH.
        #[arg(long, default_value = "704x192,1408x384")]
        sizes: String,
        /// Environment sizes to prefilter, comma-separated WxH.
        #[arg(long, default_value = "256x128,512x256,1024x512,2048x1024")]
        env_sizes: String,
        /// Repeats per timing (medians are reported).
        #[arg(long, default_value_t = 3)]
        repeats: usize,
    },
    /// Speed against accuracy of the quality knobs and the presets on a relit demo frame:
    /// CSV, markdown table and a PNG plot with the Pareto front.
    Trade {
        /// Demo city size (SH degree 3, materials).
        #[arg(long, default_value_t = 200_000)]
        gaussians: usize,
        /// Output size WxH.
        #[arg(long, default_value = "704x192")]
        size: String,
        /// Frames per setting (median, min and max reported).
        #[arg(long, default_value_t = 5)]
        repeats: usize,
        /// Indirect-light network: a safetensors file, `random` (seeded random weights of the
        /// default architecture), or `none` (no inference, no fp16/fp32 row).
        #[arg(long, default_value = "none")]
        network: String,
        /// Output folder for trade.csv, trade.md and trade.png.
        #[arg(long, default_value = "out/bench-trade")]
        out: PathBuf,
    },
    /// Relit frame time and GPU memory against Gaussian count and against pixel count, with
    /// fitted log-log slopes (balanced preset, demo city).
    Scaling {
        /// Gaussian counts, comma-separated.
        #[arg(long, default_value = "10000,30000,100000,300000,1000000,3000000")]
        gaussians: String,
        /// Image size of the Gaussian sweep.
        #[arg(long, default_value = "704x192")]
        size: String,
        /// Image sizes of the pixel sweep, comma-separated.
        #[arg(long, default_value = "176x48,352x96,704x192,1408x384,2816x768")]
        sizes: String,
        /// Gaussian count of the pixel sweep.
        #[arg(long, default_value_t = 200_000)]
        pixel_sweep_gaussians: usize,
        /// Frames per point (medians reported).
        #[arg(long, default_value_t = 3)]
        repeats: usize,
    },
    /// Sigmoid shadow pass against the traced pass; shadow-map accuracy across resolution, k and depth mode.
    Shadow {
        /// Demo sizes for the speed table, comma-separated.
        #[arg(long, default_value = "100000,1000000,3000000")]
        gaussians: String,
        /// Demo size for the accuracy table.
        #[arg(long, default_value_t = 200_000)]
        accuracy_gaussians: usize,
        /// Shadow-map resolutions, comma-separated (the largest gives the traced reference).
        #[arg(long, default_value = "256,512,1024,2048,4096")]
        resolutions: String,
        /// Sigmoid sharpness values k per metre, comma-separated.
        #[arg(long, default_value = "5,50,500")]
        ks: String,
        /// Receiver image size WxH.
        #[arg(long, default_value = "704x192")]
        size: String,
        /// Repeats per timing (medians are reported).
        #[arg(long, default_value_t = 3)]
        repeats: usize,
    },
}

fn main() -> ExitCode {
    env_logger::Builder::from_env(env_logger::Env::default().default_filter_or("srug=info"))
        .format_timestamp(None)
        .init();
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

fn spinner(message: &str) -> ProgressBar {
    let bar = ProgressBar::new_spinner();
    bar.set_style(
        ProgressStyle::with_template("{spinner} {msg} [{elapsed}]")
            .unwrap_or_else(|_| ProgressStyle::default_spinner()),
    );
    bar.set_message(message.to_string());
    bar.enable_steady_tick(Duration::from_millis(120));
    bar
}

fn open_device(cli_device: &Option<String>, validation: bool) -> srug::Result<Device> {
    Ok(Device::new(&DeviceOptions {
        selection: cli_device.as_deref().map(DeviceSelection::parse),
        validation: validation.then_some(true),
    })?)
}

fn parse_vec3(text: &str) -> srug::Result<glam::Vec3> {
    let v: Vec<f32> = text
        .split(',')
        .map(|p| p.trim().parse::<f32>())
        .collect::<Result<_, _>>()
        .map_err(|_| srug::Error::InvalidArgument(format!("\"{text}\" is not three comma-separated numbers")))?;
    match v.as_slice() {
        [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok(glam::Vec3::new(*x, *y, *z)),
        _ => Err(srug::Error::InvalidArgument(format!("\"{text}\" is not three finite numbers"))),
    }
}

fn parse_size(text: &str) -> srug::Result<(u32, u32)> {
    let bad = || srug::Error::InvalidArgument(format!("size \"{text}\" is not WxH"));
    let (w, h) = text.split_once(['x', 'X']).ok_or_else(bad)?;
    let (w, h): (u32, u32) = (w.trim().parse().map_err(|_| bad())?, h.trim().parse().map_err(|_| bad())?);
    if w == 0 || h == 0 {
        return Err(bad());
    }
    Ok((w, h))
}

/// `out.png` → `out_003.png`.
fn numbered(out: &std::path::Path, i: usize) -> PathBuf {
    let stem = out.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let ext = out.extension().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    out.with_file_name(format!("{stem}_{i:03}.{ext}"))
}

fn run(cli: Cli) -> srug::Result<()> {
    match cli.command {
        Command::Info { scene: path, plan, size, channels, sun, shade, indirect, indirect_precision } => {
            let bar = spinner(&format!("reading {}", path.display()));
            let scene = scene::read_ply(&path);
            bar.finish_and_clear();
            let scene = scene?;
            println!("{}", path.display());
            print!("{}", scene.summary());
            if plan {
                let (width, height) = parse_size(&size)?;
                let mut relight = shade.settings()?;
                relight.extra_channels = Channels::parse(&channels)?;
                let sun = sun.resolve()?.first().map(|(_, s)| *s);
                let precision = srug::indirect::StoragePrecision::parse(&indirect_precision)?;
                let weights = indirect.as_ref().map(srug::indirect::UNetWeights::load).transpose()?;
                let device = open_device(&cli.device, cli.validation)?;
                let blend = Splatter::new(&device)?.blend_variant();
                let settings = srug::plan::PlanSettings {
                    width,
                    height,
                    sun,
                    relight,
                    network: weights.as_ref().map(|w| (&w.config, precision)),
                    blend,
                };
                let p = srug::plan::plan_frame(&scene, &settings)?;
                println!("\nplan for a {width}x{height} frame on {}:", device.info().name);
                print!("{}", p.text());
            }
            Ok(())
        }
        Command::Render {
            scene: path,
            view,
            out,
            channels,
            background,
            stored_normals,
            sh_degree,
            tile,
            tile_bounds,
        } => {
            let is_exr = cli_relight::output_is_exr(&out)?;
            // A PNG is the colour; an EXR holds what was asked for.
            let rgb = !is_exr || Channels::names_rgb(&channels);
            let channels = Channels::parse(&channels)?;
            let cams = view.resolve()?;
            let index = view.index;
            let scene = scene::read_ply(&path)?;
            let device = open_device(&cli.device, cli.validation)?;
            let gpu_scene = activate::GpuScene::upload(&device, &scene)?;
            let mut splatter = Splatter::new(&device)?;
            let settings = SplatSettings {
                background: parse_vec3(&background)?.to_array(),
                channels,
                normal_source: if stored_normals { NormalSource::Stored } else { NormalSource::ShortestAxis },
                prefill: None,
                sh_degree,
                tile,
                tile_bounds,
                rgb,
            };
            let bar = if cams.len() > 1 { ProgressBar::new(cams.len() as u64) } else { ProgressBar::hidden() };
            bar.set_style(
                ProgressStyle::with_template("{bar:40} {pos}/{len} cameras [{elapsed} < {eta}]")
                    .unwrap_or_else(|_| ProgressStyle::default_bar()),
            );
            for (i, cam) in cams.iter().enumerate() {
                let target = if cams.len() > 1 { numbered(&out, index.unwrap_or(i)) } else { out.clone() };
                let (gpu, stats) = splatter.render(&gpu_scene, cam, &settings)?;
                let g = gpu.read(&device)?;
                if is_exr {
                    output::write_exr(&target, &g)?;
                } else {
                    output::write_png(&target, g.width, g.height, g.rgb_values()?)?;
                }
                bar.inc(1);
                bar.println(format!(
                    "{} ({}x{}, {:.1} ms GPU)",
                    target.display(),
                    g.width,
                    g.height,
                    stats.timings.total_seconds() * 1e3
                ));
            }
            bar.finish_and_clear();
            Ok(())
        }
        Command::Relight(args) => {
            let device = open_device(&cli.device, cli.validation)?;
            cli_relight::relight(&device, &args)
        }
        Command::Unet { weights, input, out, precision } => {
            let precision = srug::indirect::StoragePrecision::parse(&precision)?;
            let net = srug::indirect::UNetWeights::load(&weights)?;
            let bytes = std::fs::read(&input).map_err(srug::Error::io(&input))?;
            let (c, h, w, values) = srug::indirect::read_tensor(&bytes, "input", &input.display().to_string())?;
            if c != net.config.in_channels {
                return Err(srug::Error::InvalidArgument(format!(
                    "{}: input has {c} channels, the network takes {}",
                    input.display(),
                    net.config.in_channels
                )));
            }
            let device = open_device(&cli.device, cli.validation)?;
            let mut unet = srug::indirect::UNet::with_precision(&device, &net, precision)?;
            let buffer = device.upload("u-net input", &values)?;
            let result = unet.infer(&buffer, w as u32, h as u32)?;
            let output: Vec<f32> = device.read_buffer(&result.output)?;
            let bytes = srug::indirect::tensor_bytes("output", net.config.out_channels, h, w, &output)?;
            output::write_atomic(&out, &bytes)?;
            println!(
                "{}: {}x{} in, {} out channels; {:.1} ms GPU, {:.2} GFLOP, arena {}",
                out.display(),
                w,
                h,
                net.config.out_channels,
                result.timings.total_seconds() * 1e3,
                net.flops(w, h) * 1e-9,
                human_bytes(unet.arena_capacity())
            );
            Ok(())
        }
        Command::Prefilter { env, out, levels, samples, zstd } => {
            let device = open_device(&cli.device, cli.validation)?;
            let settings = srug::shade::PrepareSettings { levels, samples, ..Default::default() };
            cli_relight::prefilter(&device, &env, &out, &settings, zstd)
        }
        Command::Bench {
            what: BenchKind::Splat { gaussians, sizes, repeats, sort_keys, blend, tile, blend_pixels, tile_bounds },
        } => {
            let blend = blend.as_deref().map(srug::splat::BlendVariant::parse).transpose()?;
            srug::splat::check_tile(tile)?;
            let counts: Vec<usize> =
                gaussians.split(',').map(|t| t.trim().parse::<usize>()).collect::<Result<_, _>>().map_err(|_| {
                    srug::Error::InvalidArgument(format!("--gaussians \"{gaussians}\" is not a list of counts"))
                })?;
            let sizes: Vec<(u32, u32)> = sizes.split(',').map(parse_size).collect::<srug::Result<_>>()?;
            let device = open_device(&cli.device, cli.validation)?;
            let info = device.info();
            let peak = srug::bench::fma_peak_gflops(&device, 5)?;
            println!("device: {} ({}), measured FMA peak {peak:.1} GFLOP/s\n", info.name, info.driver);
            let bar = spinner("benchmarking");
            let options = srug::bench::SplatBenchOptions { repeats, blend, blend_pixels, tile, tile_bounds };
            let rows =
                srug::bench::splat_bench(&device, &counts, &sizes, &options, |m| bar.set_message(m.to_string()))?;
            bar.set_message("sorting");
            let sort = srug::bench::sort_bench(&device, sort_keys, 32 + 11, repeats)?;
            bar.set_message("measuring the blend ceiling and the pair-move floor");
            let ceiling = srug::bench::limits::blend_ceiling(&device, repeats)?;
            let floor = srug::bench::limits::pair_move_floor(&device, sort_keys as u64, repeats)?;
            bar.finish_and_clear();
            let stage_names: Vec<String> =
                rows.first().map(|r| r.stages.iter().map(|s| s.0.clone()).collect()).unwrap_or_default();
            println!(
                "| Gaussians | size | {} | total ms | pairs | working MiB | scene MiB | G-buffer MiB | blend evals (M) | blend GFLOP/s | % of FMA peak | ceiling % |",
                stage_names.join(" ms | ") + " ms"
            );
            println!("|---:|---|{}---:|---:|---:|---:|---:|---:|---:|---:|---:|", "---:|".repeat(stage_names.len()));
            for r in &rows {
                let stages: Vec<String> = stage_names
                    .iter()
                    .map(|n| {
                        r.stages.iter().find(|s| &s.0 == n).map_or("-".to_string(), |s| format!("{:.1}", s.1 * 1e3))
                    })
                    .collect();
                let mib = |b: u64| b as f64 / (1u64 << 20) as f64;
                println!(
                    "| {} | {}x{} | {} | {:.1} | {} | {:.1} | {:.1} | {:.1} | {:.1} | {:.2} | {:.1} | {:.1} |",
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
                    r.blend_gflops(),
                    r.blend_gflops() / peak * 100.0,
                    ceiling.for_work(r.blend_evaluations, r.blend_contributions) / peak * 100.0
                );
            }
            println!(
                "\nblend flops: {} per evaluated pair + {} per contributing pair (exp not counted); pairs counted by replaying the blend on the CPU twin",
                srug::bench::BLEND_FLOPS_PER_EVALUATION,
                srug::bench::BLEND_FLOPS_PER_CONTRIBUTION
            );
            println!(
                "sort, {} keys on {} bits: GPU {:.1} M keys/s, CPU sort_unstable {:.1} M keys/s (ratio {:.2})",
                sort.keys,
                sort.bits,
                sort.gpu_keys_per_second * 1e-6,
                sort.cpu_keys_per_second * 1e-6,
                sort.gpu_keys_per_second / sort.cpu_keys_per_second
            );
            println!(
                "blend ceiling (the blend's arithmetic with no memory traffic, every evaluation contributing, {} pixels per invocation): {:.1} GFLOP/s, {:.1}% of FMA peak; \"ceiling %\" is that bound on each row's mix of evaluations and contributions",
                ceiling.pixels,
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
        Command::Bench { what: BenchKind::Unet { widths, sizes, repeats, inputs } } => {
            let w: Vec<usize> =
                widths.split(',').map(|t| t.trim().parse::<usize>()).collect::<Result<_, _>>().map_err(|_| {
                    srug::Error::InvalidArgument(format!("--widths \"{widths}\" is not five comma-separated numbers"))
                })?;
            let w: [usize; 5] =
                w.try_into().map_err(|_| srug::Error::InvalidArgument("--widths needs five numbers".into()))?;
            let sizes: Vec<(u32, u32)> = sizes.split(',').map(parse_size).collect::<srug::Result<_>>()?;
            let device = open_device(&cli.device, cli.validation)?;
            let info = device.info();
            let peak = srug::bench::fma_peak_gflops(&device, 5)?;
            println!(
                "device: {} ({}), measured FMA peak {peak:.1} GFLOP/s; widths {w:?}, 14 input channels\n",
                info.name, info.driver
            );
            let bar = spinner("benchmarking");
            use srug::bench::unet::ConvPath;
            let paths: Vec<ConvPath> = inputs
                .split(',')
                .map(|t| {
                    [ConvPath::Vec4, ConvPath::Texel, ConvPath::Address, ConvPath::Winograd, ConvPath::Winograd2]
                        .into_iter()
                        .find(|p| p.label() == t.trim())
                        .ok_or_else(|| {
                            srug::Error::InvalidArgument(format!(
                                "--inputs: \"{t}\" is not vec4, texel, address, winograd or winograd2"
                            ))
                        })
                })
                .collect::<srug::Result<_>>()?;
            let rows =
                srug::bench::unet::unet_bench(&device, w, &sizes, &paths, repeats, |m| bar.set_message(m.to_string()))?;
            bar.finish_and_clear();
            println!(
                "| size | storage | conv | ms (median) | ms (min) | GFLOP | GFLOP/s | % of FMA peak | arena MiB |"
            );
            println!("|---|---|---|---:|---:|---:|---:|---:|---:|");
            for r in &rows {
                let gflops = r.flops * 1e-9 / r.seconds;
                println!(
                    "| {}x{} | {} | {} | {:.1} | {:.1} | {:.2} | {:.1} | {:.0}% | {:.1} |",
                    r.size.0,
                    r.size.1,
                    r.precision,
                    r.path.label(),
                    r.seconds * 1e3,
                    r.min_seconds * 1e3,
                    r.flops * 1e-9,
                    gflops,
                    gflops / peak * 100.0,
                    r.arena_bytes as f64 / (1u64 << 20) as f64
                );
            }
            for r in &rows {
                println!(
                    "\n{}x{} {} {} per layer: {}",
                    r.size.0,
                    r.size.1,
                    r.precision,
                    r.path.label(),
                    r.layers.iter().map(|(n, s)| format!("{n} {:.1} ms", s * 1e3)).collect::<Vec<_>>().join(", ")
                );
            }
            Ok(())
        }
        Command::Bench { what: BenchKind::Shade { gaussians, sizes, env_sizes, repeats } } => {
            let sizes: Vec<(u32, u32)> = sizes.split(',').map(parse_size).collect::<srug::Result<_>>()?;
            let env_sizes: Vec<(u32, u32)> = env_sizes.split(',').map(parse_size).collect::<srug::Result<_>>()?;
            let device = open_device(&cli.device, cli.validation)?;
            let info = device.info();
            println!(
                "device: {} ({}); G-buffers of demo camera 0 with {gaussians} Gaussians\n",
                info.name, info.driver
            );
            let bar = spinner("benchmarking");
            let r = srug::bench::shade::shade_bench(&device, gaussians, &sizes, &env_sizes, repeats, |m| {
                bar.set_message(m.to_string())
            })?;
            bar.finish_and_clear();
            println!("| size | shade lights ms | shade compose ms | shading ms per frame |");
            println!("|---|---:|---:|---:|");
            for row in &r.shading {
                println!(
                    "| {}x{} | {:.2} | {:.2} | {:.2} |",
                    row.size.0,
                    row.size.1,
                    row.lights_seconds * 1e3,
                    row.compose_seconds * 1e3,
                    (row.lights_seconds + row.compose_seconds) * 1e3
                );
            }
            println!("\none-time environment preparation (6 levels, 128 GGX samples per texel, 32x16 irradiance):\n");
            println!("| environment | levels | pyramid ms | GGX prefilter ms | irradiance ms | total ms | GPU MiB |");
            println!("|---|---:|---:|---:|---:|---:|---:|");
            for row in &r.prefilter {
                println!(
                    "| {}x{} | {} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} |",
                    row.size.0,
                    row.size.1,
                    row.levels,
                    row.pyramid_seconds * 1e3,
                    row.prefilter_seconds * 1e3,
                    row.irradiance_seconds * 1e3,
                    (row.pyramid_seconds + row.prefilter_seconds + row.irradiance_seconds) * 1e3,
                    row.bytes as f64 / (1u64 << 20) as f64
                );
            }
            println!();
            for (variant, seconds) in &r.brdf_seconds {
                println!("BRDF table {variant:?} (129x129, 1024 samples): {:.1} ms", seconds * 1e3);
            }
            Ok(())
        }
        Command::Bench { what: BenchKind::Trade { gaussians, size, repeats, network, out } } => {
            use srug::bench::trade::{trade_bench, trade_csv, trade_markdown, TradeSetup};
            let weights = match network.as_str() {
                "none" => None,
                "random" => Some(srug::indirect::UNetWeights::random(srug::indirect::UNetConfig::default(), 1)),
                path => Some(srug::indirect::UNetWeights::load(path)?),
            };
            let setup =
                TradeSetup { gaussians, size: parse_size(&size)?, sun: (260.0, 50.0), repeats, network: weights };
            std::fs::create_dir_all(&out).map_err(srug::Error::io(&out))?;
            let device = open_device(&cli.device, cli.validation)?;
            let info = device.info();
            let heading = format!(
                "{} ({}): demo city {} Gaussians (SH 3), camera 0 at {}x{}, sun 260°/50°, procedural sky, network {}",
                info.name, info.driver, gaussians, setup.size.0, setup.size.1, network
            );
            println!("{heading}\n");
            let bar = spinner("benchmarking");
            let rows = trade_bench(&device, &setup, |m| bar.set_message(m.to_string()));
            bar.finish_and_clear();
            let rows = rows?;
            let table = trade_markdown(&rows);
            print!("{table}");
            srug::output::write_atomic(&out.join("trade.csv"), trade_csv(&rows).as_bytes())?;
            srug::output::write_atomic(&out.join("trade.md"), format!("{heading}\n\n{table}").as_bytes())?;
            let png = out.join("trade.png");
            let title = format!("srug speed/accuracy, {} at {}x{}", info.name, setup.size.0, setup.size.1);
            let text = srug::bench::plot::trade_plot(&png, &rows, &title)?;
            println!(
                "\nwritten: {}, {}, {}{}",
                out.join("trade.csv").display(),
                out.join("trade.md").display(),
                png.display(),
                if text { "" } else { " (no font found: the plot has no text; set SRUG_PLOT_FONT)" }
            );
            Ok(())
        }
        Command::Bench { what: BenchKind::Scaling { gaussians, size, sizes, pixel_sweep_gaussians, repeats } } => {
            use srug::bench::scaling::{scaling_bench, scaling_markdown, ScalingSetup};
            let counts =
                gaussians.split(',').map(|t| t.trim().parse::<usize>()).collect::<Result<Vec<_>, _>>().map_err(
                    |_| srug::Error::InvalidArgument(format!("--gaussians \"{gaussians}\" is not a list of counts")),
                )?;
            let setup = ScalingSetup {
                counts,
                size: parse_size(&size)?,
                sizes: sizes.split(',').map(parse_size).collect::<srug::Result<_>>()?,
                gaussians: pixel_sweep_gaussians,
                repeats,
            };
            let device = open_device(&cli.device, cli.validation)?;
            let info = device.info();
            println!("{} ({}): relit demo frames, balanced preset, no network\n", info.name, info.driver);
            let bar = spinner("benchmarking");
            let result = scaling_bench(&device, &setup, |m| bar.set_message(m.to_string()));
            bar.finish_and_clear();
            let (by_count, by_size) = result?;
            println!(
                "against Gaussians at {}x{}:\n\n{}",
                setup.size.0,
                setup.size.1,
                scaling_markdown(&by_count, false)
            );
            println!("against pixels with {} Gaussians:\n\n{}", setup.gaussians, scaling_markdown(&by_size, true));
            Ok(())
        }
        Command::Bench {
            what: BenchKind::Shadow { gaussians, accuracy_gaussians, resolutions, ks, size, repeats },
        } => {
            use srug::bench::shadow::{shadow_accuracy, shadow_speed, ShadowBenchSetup};
            fn list<T: std::str::FromStr>(flag: &str, text: &str) -> srug::Result<Vec<T>> {
                text.split(',').map(|t| t.trim().parse::<T>()).collect::<Result<_, _>>().map_err(|_| {
                    srug::Error::InvalidArgument(format!(
                        "--{flag} \"{text}\" is not a comma-separated list of numbers"
                    ))
                })
            }
            let counts: Vec<usize> = list("gaussians", &gaussians)?;
            let resolutions: Vec<u32> = list("resolutions", &resolutions)?;
            let ks: Vec<f32> = list("ks", &ks)?;
            let setup = ShadowBenchSetup { size: parse_size(&size)?, sun: (260.0, 50.0), repeats };
            let device = open_device(&cli.device, cli.validation)?;
            let info = device.info();
            println!(
                "device: {} ({}); receivers {}x{} from demo camera 0; sun azimuth {}°, elevation {}°\n",
                info.name, info.driver, setup.size.0, setup.size.1, setup.sun.0, setup.sun.1
            );
            let bar = spinner("benchmarking");
            let default_resolution = srug::shadow::ShadowSettings::default().resolution;
            let speed = shadow_speed(&device, &counts, default_resolution, &setup, |m| bar.set_message(m.to_string()))?;
            let accuracy = shadow_accuracy(&device, accuracy_gaussians, &resolutions, &ks, &setup, |m| {
                bar.set_message(m.to_string())
            })?;
            bar.finish_and_clear();
            println!("| Gaussians | map | map pairs | map splat ms (once per sun) | sigmoid test ms | traced ms | traced / sigmoid |");
            println!("|---:|---:|---:|---:|---:|---:|---:|");
            for r in &speed {
                println!(
                    "| {} | {} | {} | {:.1} | {:.2} | {:.2} | {:.1}× |",
                    r.gaussians,
                    r.resolution,
                    r.map_pairs,
                    r.map_seconds * 1e3,
                    r.sigmoid_seconds * 1e3,
                    r.traced_seconds * 1e3,
                    r.traced_seconds / r.sigmoid_seconds
                );
            }
            println!(
                "\naccuracy against the traced visibility ({} Gaussians, traced at {} texels):\n",
                accuracy_gaussians,
                resolutions.iter().max().copied().unwrap_or(0)
            );
            println!("| map | depth | k | IoU | mean abs(V_e - V_t) | sigmoid test ms | map splat ms |");
            println!("|---:|---|---:|---:|---:|---:|---:|");
            for r in &accuracy {
                println!(
                    "| {} | {:?} | {} | {:.3} | {:.4} | {:.2} | {:.1} |",
                    r.resolution,
                    r.depth,
                    r.k,
                    r.iou,
                    r.mean_abs_diff,
                    r.sigmoid_seconds * 1e3,
                    r.map_seconds * 1e3
                );
            }
            Ok(())
        }
        Command::ShadowFit {
            gaussians,
            seed,
            steps,
            added,
            camera,
            size,
            sun_azimuth,
            sun_elevation,
            resolution,
            k,
            out,
        } => {
            use srug::shadow::completion::{complete_demo, CompletionSettings, DemoCompletion};
            let mut settings = CompletionSettings { steps, gaussians: added, ..CompletionSettings::default() };
            settings.shadow.resolution = resolution;
            settings.shadow.k = k;
            let options = DemoCompletion {
                demo: demo::DemoOptions { gaussians, seed, ..demo::DemoOptions::default() },
                camera,
                size: parse_size(&size)?,
                sun: (sun_azimuth, sun_elevation),
                settings,
            };
            std::fs::create_dir_all(&out).map_err(srug::Error::io(&out))?;
            let device = open_device(&cli.device, cli.validation)?;
            let bar = ProgressBar::new(u64::from(steps) + 1);
            bar.set_style(
                ProgressStyle::with_template("{bar:30} {pos}/{len} {msg} [{elapsed}, ETA {eta}]")
                    .unwrap_or_else(|_| ProgressStyle::default_bar()),
            );
            let mut lines = Vec::new();
            let result = complete_demo(&device, &options, &mut |s| {
                let line = format!(
                    "step {:3}: loss {:.4}, shadow IoU {:.3}, missing-shadow IoU {:.3}",
                    s.step, s.loss, s.iou, s.missing_iou
                );
                if bar.is_hidden() {
                    println!("{line}");
                } else {
                    bar.println(&line);
                }
                bar.set_message(format!("IoU {:.3}", s.iou));
                bar.inc(1);
                lines.push(format!("{},{},{},{}", s.step, s.loss, s.iou, s.missing_iou));
            });
            bar.finish_and_clear();
            let result = result?;
            let c = &result.completion;
            let (w, h) = (result.camera.width, result.camera.height);
            let grey = |v: &[f32]| -> Vec<f32> { v.iter().flat_map(|x| [*x, *x, *x]).collect() };
            for (name, v) in
                [("target", &result.target), ("without", &c.without), ("before", &c.before), ("after", &c.after)]
            {
                output::write_png(out.join(format!("visibility_{name}.png")), w, h, &grey(v))?;
            }
            let ply = out.join("completed.ply");
            scene::write_ply(&ply, &c.scene, PlyFormat::BinaryLittleEndian)?;
            let csv = out.join("history.csv");
            let text = format!("step,loss,shadow_iou,missing_shadow_iou\n{}\n", lines.join("\n"));
            std::fs::write(&csv, text).map_err(srug::Error::io(&csv))?;
            let (first, last) = (c.history.first(), c.history.last());
            if let (Some(a), Some(b)) = (first, last) {
                println!(
                    "removed the off-screen tower ({} Gaussians); added {} where no camera sees",
                    result.removed,
                    c.scene.len() - c.first_added
                );
                println!(
                    "shadow IoU: {:.3} without the tower, {:.3} at the start, {:.3} after {} steps",
                    srug::shadow::completion::shadow_iou(&c.without, &result.target, &c.mask),
                    a.iou,
                    b.iou,
                    b.step
                );
                println!(
                    "missing-shadow IoU (receivers the scene alone leaves lit): {:.3} → {:.3}",
                    a.missing_iou, b.missing_iou
                );
                println!("added Gaussians that ended inside a camera's view: {}", c.visible_added);
            }
            println!("images: {}/visibility_{{target,without,before,after}}.png", out.display());
            println!("scene: {}", ply.display());
            println!("history: {}", csv.display());
            let messages = device.take_validation_messages();
            if device.validation_enabled() {
                println!("validation messages: {}", messages.len());
            }
            Ok(())
        }
        Command::Eval { reference, rendered, peak, csv } => evaluate(&reference, &rendered, peak, csv.as_deref()),
        Command::Devices => {
            for a in Device::list()? {
                println!("#{} {} ({:?}, Vulkan {})", a.index, a.name, a.device_type, a.api_version);
            }
            Ok(())
        }
        Command::Demo { gaussians, seed, sh_degree, out } => {
            let bar = spinner(&format!("generating the demo city ({gaussians} Gaussians)"));
            let started = Instant::now();
            let city = demo::demo_city(&demo::DemoOptions { seed, gaussians, sh_degree });
            bar.finish_and_clear();
            let city = city?;
            println!("demo city generated in {:.2} s (seed {seed})", started.elapsed().as_secs_f64());
            print!("{}", city.scene.summary());

            std::fs::create_dir_all(&out).map_err(srug::Error::io(&out))?;
            let ply = out.join("demo_city.ply");
            let cameras = out.join("cameras.json");
            let bar = spinner(&format!("writing {}", ply.display()));
            let written = scene::write_ply(&ply, &city.scene, PlyFormat::BinaryLittleEndian)
                .and_then(|()| scene::write_cameras_json(&cameras, &city.cameras));
            bar.finish_and_clear();
            written?;

            let device = open_device(&cli.device, cli.validation)?;
            let info = device.info();
            println!(
                "device: {} ({:?}), driver {}, Vulkan {}, subgroup {}",
                info.name, info.device_type, info.driver, info.api_version, info.subgroup_size
            );

            let report = gpu::selftest::run(&device, 1 << 20)?;
            println!(
                "GPU self-test: {} ({} values, 2 kernel variants, max relative error {:.1e}; {})",
                if report.passed() { "passed" } else { "FAILED" },
                report.elements,
                report.max_rel_error,
                report
                    .stage_seconds
                    .iter()
                    .map(|(n, s)| format!("{n} {:.3} ms", s * 1e3))
                    .collect::<Vec<_>>()
                    .join(", ")
            );

            let bar = spinner("uploading and activating the scene on the GPU");
            let gpu_scene = activate::GpuScene::upload(&device, &city.scene)?;
            let kernel = activate::activate_kernel(&device)?;
            let activated = activate::activate(&device, &kernel, &gpu_scene)?;
            let cov: Vec<[f32; 6]> = device.read_buffer(&activated.covariances)?;
            let opacity: Vec<f32> = device.read_buffer(&activated.opacities)?;
            bar.finish_and_clear();
            let twin = activate::activate_cpu(&city.scene);
            let mut max_err = 0.0f64;
            for (i, (c, o)) in twin.iter().enumerate() {
                let scale = c.iter().fold(0.0f64, |m, v| m.max(v.abs())).max(1e-30);
                for a in 0..6 {
                    max_err = max_err.max((f64::from(cov[i][a]) - c[a]).abs() / scale);
                }
                max_err = max_err.max((f64::from(opacity[i]) - o).abs());
            }
            let ok = max_err < 1e-5;
            println!(
                "scene activation on the GPU: {} (max error against the f64 CPU twin {:.1e}, {:.3} ms GPU)",
                if ok { "matches" } else { "MISMATCH" },
                max_err,
                activated.timings.total_seconds() * 1e3
            );
            let mut splatter = Splatter::new(&device)?;
            let settings = SplatSettings { background: [0.55, 0.7, 0.9], ..SplatSettings::default() };
            let (gbuffer, stats) = splatter.render(&gpu_scene, &city.cameras[0], &settings)?;
            let g = gbuffer.read(&device)?;
            let image = out.join("demo_city.png");
            output::write_png(&image, g.width, g.height, g.rgb_values()?)?;
            println!(
                "rendered camera {} ({}x{}): {} pairs sorted on {} bits; GPU {}",
                city.cameras[0].name,
                g.width,
                g.height,
                stats.pairs,
                stats.key_bits,
                stats
                    .timings
                    .stages
                    .iter()
                    .map(|s| format!("{} {:.2} ms", s.name, s.seconds * 1e3))
                    .collect::<Vec<_>>()
                    .join(", ")
            );
            let relit = cli_relight::relight_demo(&device, &city, &gpu_scene, &out)?;
            println!("{relit}");
            let mem = device.memory_usage();
            println!("GPU memory: {} in use, {} peak", human_bytes(mem.current_bytes), human_bytes(mem.peak_bytes));
            let messages = device.take_validation_messages();
            if device.validation_enabled() {
                println!("validation messages: {}", messages.len());
            }
            println!("scene: {}", ply.display());
            println!("cameras: {}", cameras.display());
            println!("image: {}", image.display());
            if !report.passed() || !ok || !messages.is_empty() {
                return Err(srug::Error::InvalidArgument("the GPU disagreed with the CPU twin (see above)".into()));
            }
            Ok(())
        }
    }
}

/// Image pairs for `srug eval`: two files, or the images of two folders matched by file stem.
fn eval_pairs(reference: &Path, rendered: &Path) -> srug::Result<Vec<(String, PathBuf, PathBuf)>> {
    let is_image = |p: &Path| {
        matches!(
            p.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref(),
            Some("png" | "exr" | "hdr")
        )
    };
    if reference.is_file() && rendered.is_file() {
        let name = rendered.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        return Ok(vec![(name, reference.to_path_buf(), rendered.to_path_buf())]);
    }
    if !(reference.is_dir() && rendered.is_dir()) {
        return Err(Error::InvalidArgument(format!(
            "{} and {} must both be image files or both be folders",
            reference.display(),
            rendered.display()
        )));
    }
    let list = |dir: &Path| -> srug::Result<Vec<PathBuf>> {
        let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
            .map_err(Error::io(dir))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| is_image(p))
            .collect();
        v.sort();
        Ok(v)
    };
    let stem = |p: &Path| p.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let refs = list(reference)?;
    let mut pairs = Vec::new();
    for r in list(rendered)? {
        if let Some(q) = refs.iter().find(|q| stem(q) == stem(&r)) {
            pairs.push((stem(&r), q.clone(), r));
        } else {
            eprintln!("warning: {} has no reference in {}", r.display(), reference.display());
        }
    }
    if pairs.is_empty() {
        return Err(Error::InvalidArgument(format!(
            "no image of {} has a reference of the same name in {}",
            rendered.display(),
            reference.display()
        )));
    }
    Ok(pairs)
}

/// `srug eval`: PSNR and SSIM per image pair and their means.
fn evaluate(reference: &Path, rendered: &Path, peak: f64, csv: Option<&Path>) -> srug::Result<()> {
    if !(peak > 0.0 && peak.is_finite()) {
        return Err(Error::InvalidArgument(format!("--peak {peak} must be positive")));
    }
    let mut rows = Vec::new();
    println!("| image | PSNR (dB) | SSIM |\n|---|---:|---:|");
    for (name, r, q) in eval_pairs(reference, rendered)? {
        let (a, b) = (srug::metrics::read_image(&r)?, srug::metrics::read_image(&q)?);
        let context = |e: Error| Error::InvalidArgument(format!("{} against {}: {e}", q.display(), r.display()));
        let p = srug::metrics::psnr(&a, &b, peak).map_err(context)?;
        let s = srug::metrics::ssim(&a, &b, peak).map_err(context)?;
        println!("| {name} | {p:.3} | {s:.4} |");
        rows.push((name, p, s));
    }
    let n = rows.len() as f64;
    // The mean PSNR of identical pairs is infinite; say so rather than average it away.
    let mean_p = rows.iter().map(|r| r.1).sum::<f64>() / n;
    let mean_s = rows.iter().map(|r| r.2).sum::<f64>() / n;
    println!("| mean of {} | {mean_p:.3} | {mean_s:.4} |", rows.len());
    if let Some(path) = csv {
        let mut text = String::from("image,psnr_db,ssim\n");
        for (name, p, s) in &rows {
            text += &format!("{name},{p},{s}\n");
        }
        srug::output::write_atomic(path, text.as_bytes())?;
    }
    Ok(())
}
