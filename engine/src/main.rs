//! The `srug` command line.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::{Duration, Instant};

use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use srug::gpu::{self, Device, DeviceOptions, DeviceSelection};
use srug::scene::{self, activate, demo, human_bytes, PlyFormat};

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
    },
    /// List the Vulkan devices.
    Devices,
    /// The main job on the built-in demo city: generate it, write it, and check the GPU on it.
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
    Device::new(&DeviceOptions {
        selection: cli_device.as_deref().map(DeviceSelection::parse),
        validation: validation.then_some(true),
    })
}

fn run(cli: Cli) -> srug::Result<()> {
    match cli.command {
        Command::Info { scene: path } => {
            let bar = spinner(&format!("reading {}", path.display()));
            let scene = scene::read_ply(&path);
            bar.finish_and_clear();
            let scene = scene?;
            println!("{}", path.display());
            print!("{}", scene.summary());
            Ok(())
        }
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
            let mem = device.memory_usage();
            println!("GPU memory: {} in use, {} peak", human_bytes(mem.current_bytes), human_bytes(mem.peak_bytes));
            let messages = device.take_validation_messages();
            if device.validation_enabled() {
                println!("validation messages: {}", messages.len());
            }
            println!("scene: {}", ply.display());
            println!("cameras: {}", cameras.display());
            if !report.passed() || !ok || !messages.is_empty() {
                return Err(srug::Error::InvalidArgument("the GPU disagreed with the CPU twin (see above)".into()));
            }
            Ok(())
        }
    }
}
