//! `srug bench <area>`: the benchmarks (GPU timestamps; markdown tables on stdout).
//! The measuring code lives in [`crate::bench`]; these files parse, run and print.

mod batch;
mod completion;
mod embed;
mod formats;
mod scaling;
mod shade;
mod shadow;
mod splat;
mod trade;
mod unet;

use srug::Result;

use crate::args::DeviceArgs;

/// The benchmark areas.
#[derive(clap::Subcommand, Clone, Debug)]
pub(super) enum BenchCommand {
    /// Per-stage splatting times on the demo city; GPU sort against sort_unstable; FMA peak.
    Splat(splat::SplatBenchArgs),
    /// Indirect-light U-Net: time per inference per size and precision, GFLOP/s against the FMA peak.
    Unet(unet::UnetBenchArgs),
    /// Deferred shading time per frame per image size; one-time environment prefilter cost per size.
    Shade(shade::ShadeBenchArgs),
    /// Speed against accuracy of the quality knobs and the presets on a relit demo frame:
    /// CSV, markdown table and a PNG plot with the Pareto front.
    Trade(trade::TradeBenchArgs),
    /// Relit frame time and GPU memory against Gaussian count and against pixel count, with
    /// fitted log-log slopes (balanced preset, demo city).
    Scaling(scaling::ScalingBenchArgs),
    /// Scene files: load time, size and host memory per format (no GPU).
    Formats(formats::FormatBenchArgs),
    /// Frames per second against the number of cameras: `srug render`/`relight` to PNG and EXR,
    /// and in-process renders into memory, with the GPU time per frame.
    Batch(batch::BatchBenchArgs),
    /// Sigmoid shadow pass against the traced pass; shadow-map accuracy across resolution, k and depth mode.
    Shadow(shadow::ShadowBenchArgs),
    /// Shadow-guided completion on the analytic block: setup, time per step, steps to converge and
    /// shadow IoU against the truth, per scene size.
    Completion(completion::CompletionBenchArgs),
    /// Rendering into a host's own Vulkan image against reading the frame back and uploading it,
    /// per relit frame and image size.
    Embed(embed::EmbedBenchArgs),
}

impl BenchCommand {
    /// Runs the benchmark.
    pub(super) fn run(&self, device: &DeviceArgs) -> Result<()> {
        // The host first: on lavapipe it is the device, and its vector ISA moves every figure.
        println!("host: {}", crate::bench::host_cpu());
        match self {
            Self::Splat(a) => a.run(device),
            Self::Unet(a) => a.run(device),
            Self::Shade(a) => a.run(device),
            Self::Trade(a) => a.run(device),
            Self::Scaling(a) => a.run(device),
            Self::Shadow(a) => a.run(device),
            Self::Formats(a) => a.run(),
            Self::Batch(a) => a.run(device),
            Self::Completion(a) => a.run(device),
            Self::Embed(a) => a.run(device),
        }
    }
}
