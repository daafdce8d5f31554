//! `srug bench scaling`: relit frame time and GPU memory against Gaussian count
//! and against pixel count, with fitted log-log slopes (balanced preset, demo city).

use srug::Result;

use crate::args::{spinner, DeviceArgs, Size};
use crate::bench::scaling::{scaling_bench, scaling_markdown, ScalingSetup};

/// Arguments of `srug bench scaling`.
#[derive(clap::Args, Clone, Debug)]
pub(crate) struct ScalingBenchArgs {
    /// Gaussian counts, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "10000,30000,100000,300000,1000000,3000000")]
    gaussians: Vec<usize>,
    /// Image size of the Gaussian sweep.
    #[arg(long, default_value = "704x192")]
    size: Size,
    /// Image sizes of the pixel sweep, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "176x48,352x96,704x192,1408x384,2816x768")]
    sizes: Vec<Size>,
    /// Gaussian count of the pixel sweep.
    #[arg(long, default_value_t = 200_000)]
    pixel_sweep_gaussians: usize,
    /// Frames per point (medians reported).
    #[arg(long, default_value_t = 3)]
    repeats: usize,
    #[command(flatten)]
    warm_up: crate::bench::WarmUpArgs,
}

impl ScalingBenchArgs {
    /// Runs `srug bench scaling`.
    pub(crate) fn run(&self, device_args: &DeviceArgs) -> Result<()> {
        let &Self { ref gaussians, size, ref sizes, pixel_sweep_gaussians, repeats, warm_up } = self;
        let device = device_args.open()?;
        let setup = ScalingSetup {
            counts: gaussians.clone(),
            size: size.pair(),
            sizes: sizes.iter().map(|s| s.pair()).collect(),
            gaussians: pixel_sweep_gaussians,
            repeats,
            warm_up: warm_up.duration(&device),
        };
        let info = device.info();
        println!("{} ({}): relit demo frames, balanced preset, no network", info.name, info.driver);
        if !setup.warm_up.is_zero() {
            println!("warm-up: {} ms of untimed frames before each row's timed ones", setup.warm_up.as_millis());
        }
        println!();
        let bar = spinner("benchmarking");
        let result = scaling_bench(&device, &setup, |m| bar.set_message(m.to_string()));
        bar.finish_and_clear();
        let (by_count, by_size) = result?;
        println!("against Gaussians at {}x{}:\n\n{}", setup.size.0, setup.size.1, scaling_markdown(&by_count, false));
        println!("against pixels with {} Gaussians:\n\n{}", setup.gaussians, scaling_markdown(&by_size, true));
        Ok(())
    }
}
