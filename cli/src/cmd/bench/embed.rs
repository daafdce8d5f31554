//! `srug bench embed`: per relit frame, rendering into a host's own image
//! against reading the frame back and uploading it (the copy it saves).

use srug::Result;

use crate::args::{spinner, DeviceArgs, Size};
use crate::bench::embed::{embed_bench, embed_markdown, EmbedSetup};

/// Arguments of `srug bench embed`.
#[derive(clap::Args, Clone, Debug)]
pub(crate) struct EmbedBenchArgs {
    /// Gaussians of the demo city.
    #[arg(long, default_value_t = 200_000)]
    gaussians: usize,
    /// SH degree of the demo city.
    #[arg(long, default_value_t = 3)]
    sh_degree: u32,
    /// Image sizes, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "704x192,1408x384")]
    sizes: Vec<Size>,
    /// Frames measured per path and size (medians reported).
    #[arg(long, default_value_t = 5)]
    frames: usize,
    /// Surface depths (`srug relight --shadow-surface-depth`) for the frames and
    /// their shadows; `=false` for centre depths [preset: true].
    #[arg(long, num_args = 0..=1, default_missing_value = "true", require_equals = true)]
    surface_depth: Option<bool>,
}

impl EmbedBenchArgs {
    /// Runs `srug bench embed`.
    pub(crate) fn run(&self, device_args: &DeviceArgs) -> Result<()> {
        if self.frames == 0 {
            return Err(srug::Error::invalid("--frames", "needs at least one frame"));
        }
        let setup = EmbedSetup {
            gaussians: self.gaussians,
            sh_degree: self.sh_degree,
            sizes: self.sizes.iter().map(|s| s.pair()).collect(),
            frames: self.frames,
            surface_depth: self.surface_depth,
        };
        let device = device_args.open()?;
        let info = device.info();
        println!(
            "{} ({}): demo city, {} Gaussians, SH degree {}, balanced preset{}, sun fixed (map reused); wall clock \
             per frame, median of {}\n",
            info.name,
            info.driver,
            setup.gaussians,
            setup.sh_degree,
            match setup.surface_depth {
                Some(true) => " with surface depths",
                Some(false) => " with centre depths",
                None => "",
            },
            setup.frames
        );
        let bar = spinner("benchmarking");
        let rows = embed_bench(&device, &setup, |m| bar.set_message(m.to_string()));
        bar.finish_and_clear();
        print!("{}", embed_markdown(&rows?));
        Ok(())
    }
}
