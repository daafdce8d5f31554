//! `srug bench shadow`: the sigmoid shadow pass against the traced pass, and
//! shadow-map accuracy across resolution, sharpness k and receiver depth mode.

use srug::shadow::ShadowSettings;
use srug::Result;

use crate::args::{spinner, DeviceArgs, Size};
use crate::bench::shadow::{block_accuracy, shadow_accuracy, shadow_speed, ShadowBenchSetup};

/// Arguments of `srug bench shadow`.
#[derive(clap::Args, Clone, Debug)]
pub(crate) struct ShadowBenchArgs {
    /// Demo sizes for the speed table, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "100000,1000000,3000000")]
    gaussians: Vec<usize>,
    /// Demo size for the accuracy table.
    #[arg(long, default_value_t = 200_000)]
    accuracy_gaussians: usize,
    /// Shadow-map resolutions, comma-separated (the largest gives the traced reference).
    #[arg(long, value_delimiter = ',', default_value = "256,512,1024,2048,4096")]
    resolutions: Vec<u32>,
    /// Sigmoid sharpness values k per metre, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "5,50,500")]
    ks: Vec<f32>,
    /// Receiver image size WxH.
    #[arg(long, default_value = "704x192")]
    size: Size,
    /// Repeats per timing (medians are reported).
    #[arg(long, default_value_t = 3)]
    repeats: usize,
}

impl ShadowBenchArgs {
    /// Runs `srug bench shadow`.
    pub(crate) fn run(&self, device_args: &DeviceArgs) -> Result<()> {
        let &Self { ref gaussians, accuracy_gaussians, ref resolutions, ref ks, size, repeats } = self;
        let counts = gaussians;
        let setup = ShadowBenchSetup { size: size.pair(), sun: (260.0, 50.0), repeats };
        let device = device_args.open()?;
        let info = device.info();
        println!(
            "device: {} ({}); receivers {}x{} from demo camera 0; sun azimuth {}°, elevation {}°\n",
            info.name, info.driver, setup.size.0, setup.size.1, setup.sun.0, setup.sun.1
        );
        let bar = spinner("benchmarking");
        let default_resolution = ShadowSettings::default().resolution;
        let speed = shadow_speed(&device, counts, default_resolution, &setup, |m| bar.set_message(m.to_string()))?;
        let accuracy =
            shadow_accuracy(&device, accuracy_gaussians, resolutions, ks, &setup, |m| bar.set_message(m.to_string()))?;
        let block = block_accuracy(&device, |m| bar.set_message(m.to_string()))?;
        bar.finish_and_clear();
        println!("| Gaussians | map | map pairs | map splat ms (once per sun) | sigmoid test ms | traced ms | traced / sigmoid |");
        println!("|---:|---:|---:|---:|---:|---:|---:|");
        for r in &speed {
            println!(
                "| {} | {} | {} | {:.1} | {:.2} | {:.2} | {:.1}× |",
                r.gaussians,
                r.resolution,
                r.map_pairs,
                r.map_seconds * 1e3,
                r.sigmoid_seconds * 1e3,
                r.traced_seconds * 1e3,
                r.traced_seconds / r.sigmoid_seconds
            );
        }
        println!(
            "\naccuracy against the traced visibility ({} Gaussians, traced at {} texels):\n",
            accuracy_gaussians,
            resolutions.iter().max().copied().unwrap_or(0)
        );
        println!("| map | depth | k | IoU | mean abs(V_e - V_t) | sigmoid test ms | map splat ms |");
        println!("|---:|---|---:|---:|---:|---:|---:|");
        for r in &accuracy {
            println!(
                "| {} | {:?} | {} | {:.3} | {:.4} | {:.2} | {:.1} |",
                r.resolution,
                r.depth,
                r.k,
                r.iou,
                r.mean_abs_diff,
                r.sigmoid_seconds * 1e3,
                r.map_seconds * 1e3
            );
        }
        println!(
            "\nagainst the ray-cast truth of the analytic block (3 suns, 3 street cameras at 704x192, each preset as \
             `srug relight` runs it; edge error in full-size pixels):\n"
        );
        println!("| splats | preset | IoU | false shadow | light leak | edge error px |");
        println!("|---|---|---:|---:|---:|---:|");
        for r in &block {
            let a = &r.accuracy;
            println!(
                "| {:?} | {} | {:.3} | {:.2}% | {:.2}% | {:.2} |",
                r.splats,
                r.preset.name(),
                a.iou(),
                100.0 * a.false_shadow_rate(),
                100.0 * a.light_leak_rate(),
                a.edge_error()
            );
        }
        Ok(())
    }
}
