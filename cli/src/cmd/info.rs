//! `srug info`: a scene's Gaussian count, SH degree, attribute groups, bounds
//! and GPU memory; with `--plan`, the passes a relit frame of it will run.

use std::path::PathBuf;

use srug::indirect::{StoragePrecision, UNetWeights};
use srug::io;
use srug::splat::Splatter;
use srug::Result;

use crate::args::{spinner, ChannelList, DeviceArgs, ShadeArgs, Size, SunArgs};

/// Arguments of `srug info`.
#[derive(clap::Args, Clone, Debug)]
pub(super) struct InfoArgs {
    /// A scene: PLY, compressed PLY, .splat, .spz, .sog / meta.json or .glb (detected from the content).
    scene: PathBuf,
    /// Also list the stages, G-buffer channels, shader variants and GPU memory a relit
    /// frame of the scene will take with the options below (nothing is rendered).
    #[arg(long)]
    plan: bool,
    /// Image size of the planned frame.
    #[arg(long, default_value = "704x192")]
    size: Size,
    /// Extra G-buffer channels to keep (as for `srug render --channels`).
    #[arg(long, default_value = "rgb")]
    channels: ChannelList,
    #[command(flatten)]
    sun: SunArgs,
    #[command(flatten)]
    shade: ShadeArgs,
    /// Indirect-light network weights (safetensors).
    #[arg(long)]
    indirect: Option<PathBuf>,
    /// Activation storage of the indirect network: fp32 or fp16.
    #[arg(long, default_value = "fp32", value_parser = StoragePrecision::parse)]
    indirect_precision: StoragePrecision,
}

impl InfoArgs {
    /// Runs `srug info`.
    pub(super) fn run(&self, device_args: &DeviceArgs) -> Result<()> {
        let Self { scene: path, plan, size, channels, sun, shade, indirect, indirect_precision } = self;
        let bar = spinner(&format!("reading {}", path.display()));
        let scene = io::read_scene(path);
        bar.finish_and_clear();
        let scene = scene?;
        println!("{}", path.display());
        print!("{}", scene.summary());
        if let (Some(file), Some(morton)) = (scene.median_step(None), scene.median_step(Some(&scene.morton_order()))) {
            // Neighbours in the file far apart in space (a trained scene's order) splat markedly slower.
            let hint = if !srug::scene::order::in_spatial_order(&scene.means) {
                format!(
                    "; in no spatial order: runs of {} frames or more put them on the device along a Morton curve \
                     (--scene-order); `srug convert --order morton` saves that order in the file, for every run",
                    crate::args::ARRANGE_MIN_FRAMES
                )
            } else {
                String::new()
            };
            println!("order: consecutive centres a median {file:.3} apart (in Morton order {morton:.3}){hint}");
        }
        if *plan {
            let (width, height) = size.pair();
            let mut relight = shade.settings()?;
            relight.extra_channels = channels.channels;
            let sun = sun.resolve()?.first().map(|(_, s)| *s);
            let precision = *indirect_precision;
            let weights = indirect.as_ref().map(UNetWeights::load).transpose()?;
            let device = device_args.open()?;
            let blend = Splatter::new(&device)?.blend_variant();
            let settings = srug::frame::plan::PlanSettings {
                width,
                height,
                sun,
                relight,
                network: weights.as_ref().map(|w| (&w.config, precision)),
                blend,
            };
            let p = srug::frame::plan::plan_frame(&scene, &settings)?;
            println!("\nplan for a {width}x{height} frame on {}:", device.info().name);
            print!("{}", p.text());
        }
        Ok(())
    }
}
