//! `srug bench trade`: speed against accuracy of the quality knobs and the
//! presets on a relit demo frame: CSV, markdown table and a plot with the Pareto front.

use std::path::PathBuf;

use srug::indirect::{UNetConfig, UNetWeights};
use srug::{io, Error, Result};

use crate::args::{spinner, DeviceArgs, Size};
use crate::bench;
use crate::bench::trade::{trade_bench, trade_csv, trade_markdown, TradeSetup};

/// Arguments of `srug bench trade`.
#[derive(clap::Args, Clone, Debug)]
pub(crate) struct TradeBenchArgs {
    /// Demo city size (SH degree 3, materials).
    #[arg(long, default_value_t = 200_000)]
    gaussians: usize,
    /// Output size WxH.
    #[arg(long, default_value = "704x192")]
    size: Size,
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
}

impl TradeBenchArgs {
    /// Runs `srug bench trade`.
    pub(crate) fn run(&self, device_args: &DeviceArgs) -> Result<()> {
        let &Self { gaussians, size, repeats, ref network, ref out } = self;
        let weights = match network.as_str() {
            "none" => None,
            "random" => Some(UNetWeights::random(UNetConfig::default(), 1)),
            path => Some(UNetWeights::load(path)?),
        };
        let setup = TradeSetup { gaussians, size: size.pair(), sun: (260.0, 50.0), repeats, network: weights };
        std::fs::create_dir_all(out).map_err(Error::io(out))?;
        let device = device_args.open()?;
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
        io::write_atomic(&out.join("trade.csv"), trade_csv(&rows).as_bytes())?;
        io::write_atomic(&out.join("trade.md"), format!("{heading}\n\n{table}").as_bytes())?;
        let png = out.join("trade.png");
        let title = format!("srug speed/accuracy, {} at {}x{}", info.name, setup.size.0, setup.size.1);
        let text = bench::plot::trade_plot(&png, &rows, &title)?;
        println!(
            "\nwritten: {}, {}, {}{}",
            out.join("trade.csv").display(),
            out.join("trade.md").display(),
            png.display(),
            if text { "" } else { " (no font found: the plot has no text; set SRUG_PLOT_FONT)" }
        );
        Ok(())
    }
}
