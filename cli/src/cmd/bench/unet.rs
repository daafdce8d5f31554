//! `srug bench unet`: the indirect-light U-Net, time per inference per size,
//! precision and conv path, GFLOP/s against the FMA peak.

use srug::indirect::ConvPath;
use srug::{Error, Result};

use crate::args::{spinner, DeviceArgs, Size};
use crate::bench;

/// Arguments of `srug bench unet`.
#[derive(clap::Args, Clone, Debug)]
pub(crate) struct UnetBenchArgs {
    /// Widths w0..w4.
    #[arg(long, value_delimiter = ',', default_value = "32,32,64,64,128")]
    widths: Vec<usize>,
    /// Image sizes, comma-separated WxH.
    #[arg(long, value_delimiter = ',', default_value = "704x192,1408x384")]
    sizes: Vec<Size>,
    /// Repeats (medians reported).
    #[arg(long, default_value_t = 3)]
    repeats: usize,
    /// How conv layers run, comma-separated: winograd (Winograd F(4×4,3×3) for the stride-1
    /// layers, direct convolution for stride 2, four pixels per fetch where a layer's width is a
    /// multiple of 4), winograd2 (the same with Winograd F(2×2,3×3)), vec4 (direct convolution
    /// for every layer, texel inputs, four pixels per fetch where the width allows), texel (the
    /// same, one pixel per fetch), address (device addresses, the fallback). Default: the
    /// device's (winograd on a CPU device such as lavapipe, texel on a GPU, address without texel views)
    #[arg(long, value_delimiter = ',')]
    inputs: Vec<ConvPath>,
}

impl UnetBenchArgs {
    /// Runs `srug bench unet`.
    pub(crate) fn run(&self, device_args: &DeviceArgs) -> Result<()> {
        let &Self { ref widths, ref sizes, repeats, ref inputs } = self;
        let w: [usize; 5] = widths
            .as_slice()
            .try_into()
            .map_err(|_| Error::invalid(format!("--widths {widths:?}"), "is not five numbers"))?;
        let sizes: Vec<(u32, u32)> = sizes.iter().map(|s| s.pair()).collect();
        let device = device_args.open()?;
        let info = device.info();
        let peak = bench::fma_peak_gflops(&device, 5)?;
        println!(
            "device: {} ({}), measured FMA peak {peak:.1} GFLOP/s; widths {w:?}, 14 input channels\n",
            info.name, info.driver
        );
        let bar = spinner("benchmarking");
        let rows = bench::unet::unet_bench(&device, w, &sizes, inputs, repeats, |m| bar.set_message(m.to_string()))?;
        // The peak again after the rows; the column takes the better (a peak is the best seen).
        let peak_at_end = bench::fma_peak_gflops(&device, 5)?;
        let first_peak = peak;
        let peak = peak.max(peak_at_end);
        bar.finish_and_clear();
        println!(
            "FMA peak {first_peak:.1} GFLOP/s before the rows and {peak_at_end:.1} after them; \"% of FMA peak\" takes the better, {peak:.1}\n"
        );
        println!("| size | storage | conv | ms (median) | ms (min) | GFLOP | GFLOP/s | % of FMA peak | arena MiB |");
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
}
