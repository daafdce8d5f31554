//! `srug bench completion`: shadow-guided completion on the analytic block at
//! several scene sizes: setup, time per step, steps to converge, IoU against the truth.

use srug::shadow::completion::CompletionSettings;
use srug::Result;

use crate::args::{spinner, DeviceArgs, Size};
use crate::bench::completion::{completion_bench, completion_markdown};

/// Arguments of `srug bench completion`.
#[derive(clap::Args, Clone, Debug)]
pub(crate) struct CompletionBenchArgs {
    /// Surface spacings of the block, metres (0.25 m: about 90k Gaussians, 0.074 m: about 1M).
    #[arg(long, value_delimiter = ',', default_value = "0.25")]
    spacings: Vec<f32>,
    /// Camera image size.
    #[arg(long, default_value = "352x96")]
    size: Size,
    /// Adam steps.
    #[arg(long, default_value_t = 60)]
    steps: u32,
}

impl CompletionBenchArgs {
    /// Runs `srug bench completion`.
    pub(crate) fn run(&self, device_args: &DeviceArgs) -> Result<()> {
        let device = device_args.open()?;
        let info = device.info();
        let settings = CompletionSettings { steps: self.steps, ..CompletionSettings::default() };
        let (w, h) = self.size.pair();
        println!(
            "{} ({}): analytic block without its tallest building, 3 of 4 street cameras' masks at {w}x{h}, \
             up to {} Gaussians added, {} steps\n",
            info.name, info.driver, settings.gaussians, settings.steps
        );
        let bar = spinner("benchmarking");
        let rows = completion_bench(&device, &self.spacings, (w, h), &settings, |m| bar.set_message(m.to_string()));
        bar.finish_and_clear();
        print!("{}", completion_markdown(&rows?, self.steps));
        Ok(())
    }
}
