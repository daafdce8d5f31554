//! `srug demo`: the main job on the built-in demo city — generate it, write
//! it, check the GPU against its CPU twins on it, render it and relight it.

use std::path::PathBuf;
use std::time::Instant;

use srug::gpu;
use srug::io;
use srug::io::PlyFormat;
use srug::scene::{activate, demo, human_bytes};
use srug::splat::{SplatSettings, Splatter};
use srug::{Error, Result};

use crate::args::{spinner, DeviceArgs};

/// Arguments of `srug demo`.
#[derive(clap::Args, Clone, Debug)]
pub(super) struct DemoArgs {
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
}

impl DemoArgs {
    /// Runs `srug demo`.
    pub(super) fn run(&self, device_args: &DeviceArgs) -> Result<()> {
        let &Self { gaussians, seed, sh_degree, ref out } = self;
        // The device first: a run that cannot have one writes nothing.
        let device = device_args.open()?;
        let info = device.info();
        println!(
            "device: {} ({:?}), driver {}, Vulkan {}, subgroup {}",
            info.name, info.device_type, info.driver, info.api_version, info.subgroup_size
        );

        let bar = spinner(&format!("generating the demo city ({gaussians} Gaussians)"));
        let started = Instant::now();
        let city = demo::demo_city(&demo::DemoOptions { seed, gaussians, sh_degree });
        bar.finish_and_clear();
        let city = city?;
        println!("demo city generated in {:.2} s (seed {seed})", started.elapsed().as_secs_f64());
        print!("{}", city.scene.summary());

        std::fs::create_dir_all(out).map_err(Error::io(out))?;
        let ply = out.join("demo_city.ply");
        let cameras = out.join("cameras.json");
        let bar = spinner(&format!("writing {}", ply.display()));
        let written = io::write_ply(&ply, &city.scene, PlyFormat::BinaryLittleEndian)
            .and_then(|()| io::write_cameras_json(&cameras, &city.cameras));
        bar.finish_and_clear();
        written?;

        let report = gpu::selftest::run(&device, 1 << 20)?;
        println!(
            "GPU self-test: {} ({} values, 2 kernel variants, max relative error {:.1e}; {})",
            if report.passed() { "passed" } else { "FAILED" },
            report.elements,
            report.max_rel_error,
            report.stage_seconds.iter().map(|(n, s)| format!("{n} {:.3} ms", s * 1e3)).collect::<Vec<_>>().join(", ")
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
        io::write_png(&image, g.width, g.height, g.rgb_values()?)?;
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
        let relit = super::relight::relight_demo(&device, &city, &gpu_scene, out)?;
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
            return Err(Error::Internal("the GPU disagreed with the CPU twin (see above)".into()));
        }
        Ok(())
    }
}
