//! `srug bench shade`: deferred shading time per frame per image size, and the
//! one-time environment prefilter cost per environment size.

use srug::Result;

use crate::args::{spinner, DeviceArgs, Size};
use crate::bench;

/// Arguments of `srug bench shade`.
#[derive(clap::Args, Clone, Debug)]
pub(crate) struct ShadeBenchArgs {
    /// Demo city size for the G-buffers.
    #[arg(long, default_value_t = 200_000)]
    gaussians: usize,
    /// Image sizes, comma-separated WxH.
    #[arg(long, value_delimiter = ',', default_value = "704x192,1408x384")]
    sizes: Vec<Size>,
    /// Environment sizes to prefilter, comma-separated WxH.
    #[arg(long, value_delimiter = ',', default_value = "256x128,512x256,1024x512,2048x1024")]
    env_sizes: Vec<Size>,
    /// Repeats per timing (medians are reported).
    #[arg(long, default_value_t = 3)]
    repeats: usize,
}

impl ShadeBenchArgs {
    /// Runs `srug bench shade`.
    pub(crate) fn run(&self, device_args: &DeviceArgs) -> Result<()> {
        let &Self { gaussians, ref sizes, ref env_sizes, repeats } = self;
        let sizes: Vec<(u32, u32)> = sizes.iter().map(|s| s.pair()).collect();
        let env_sizes: Vec<(u32, u32)> = env_sizes.iter().map(|s| s.pair()).collect();
        let device = device_args.open()?;
        let info = device.info();
        println!("device: {} ({}); G-buffers of demo camera 0 with {gaussians} Gaussians\n", info.name, info.driver);
        let bar = spinner("benchmarking");
        let r = bench::shade::shade_bench(&device, gaussians, &sizes, &env_sizes, repeats, |m| {
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
}
