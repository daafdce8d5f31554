//! `srug bench batch`: frames per second against the number of cameras, for
//! `srug render` and `srug relight` to PNG and EXR and for in-process renders
//! read into memory (the Python package's path), with the GPU time per frame.

use srug::Result;

use crate::args::{spinner, DeviceArgs, Size};
use crate::bench::batch::{batch_bench, batch_markdown, BatchSetup};

/// Arguments of `srug bench batch`.
#[derive(clap::Args, Clone, Debug)]
pub(crate) struct BatchBenchArgs {
    /// Gaussians of the demo city.
    #[arg(long, default_value_t = 200_000)]
    gaussians: usize,
    /// SH degree of the demo city.
    #[arg(long, default_value_t = 3)]
    sh_degree: u32,
    /// Camera counts (cameras walking up the demo street), comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "1,8,64")]
    counts: Vec<usize>,
    /// Image size.
    #[arg(long, default_value = "704x192")]
    size: Size,
}

impl BatchBenchArgs {
    /// Runs `srug bench batch`.
    pub(crate) fn run(&self, device_args: &DeviceArgs) -> Result<()> {
        if self.counts.contains(&0) {
            return Err(srug::Error::invalid("--counts", "needs counts of at least one camera"));
        }
        let setup = BatchSetup {
            gaussians: self.gaussians,
            sh_degree: self.sh_degree,
            counts: self.counts.clone(),
            size: self.size.pair(),
        };
        let device = device_args.open()?;
        let info = device.info();
        println!(
            "{} ({}): demo city, {} Gaussians, SH degree {}, {}x{}; srug runs are whole processes (startup, \
             scene load, writing); to memory is in process after warm-up\n",
            info.name, info.driver, setup.gaussians, setup.sh_degree, setup.size.0, setup.size.1
        );
        let bar = spinner("benchmarking");
        let rows = batch_bench(&device, &setup, |m| bar.set_message(m.to_string()));
        bar.finish_and_clear();
        print!("{}", batch_markdown(&rows?));
        Ok(())
    }
}
