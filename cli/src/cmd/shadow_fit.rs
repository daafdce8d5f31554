//! `srug shadow-fit`: shadow-guided completion on the demo — remove the
//! off-screen tower, then grow Gaussians where no camera sees until they cast
//! its shadow again (Adam on the shadow loss alone).

use std::path::PathBuf;

use srug::io;
use srug::io::PlyFormat;
use srug::scene::demo;
use srug::shadow::completion::{complete_demo, shadow_iou, CompletionSettings, DemoCompletion};
use srug::{Error, Result};

use crate::args::{print_line, progress_bar, DeviceArgs, Size};

/// Arguments of `srug shadow-fit`.
#[derive(clap::Args, Clone, Debug)]
pub(super) struct ShadowFitArgs {
    /// Demo city size.
    #[arg(long, default_value_t = 40_000)]
    gaussians: usize,
    /// Demo seed.
    #[arg(long, default_value_t = 7)]
    seed: u64,
    /// Adam steps.
    #[arg(long, default_value_t = 60)]
    steps: u32,
    /// Gaussians added where no camera sees.
    #[arg(long, default_value_t = 4000)]
    added: usize,
    /// Which demo camera receives the shadow.
    #[arg(long, default_value_t = 0)]
    camera: usize,
    /// Receiver image size WxH.
    #[arg(long, default_value = "352x96")]
    size: Size,
    /// Sun azimuth, degrees from north toward east.
    #[arg(long, default_value_t = 260.0, allow_negative_numbers = true)]
    sun_azimuth: f32,
    /// Sun elevation, degrees.
    #[arg(long, default_value_t = 50.0, allow_negative_numbers = true)]
    sun_elevation: f32,
    /// Shadow-map resolution (longer side).
    #[arg(long, default_value_t = 256)]
    resolution: u32,
    /// Sigmoid sharpness k per metre.
    #[arg(long, default_value_t = 4.0)]
    k: f32,
    /// Output folder.
    #[arg(long, default_value = "out/shadow-fit")]
    out: PathBuf,
}

impl ShadowFitArgs {
    /// Runs `srug shadow-fit`.
    pub(super) fn run(&self, device_args: &DeviceArgs) -> Result<()> {
        let &Self { gaussians, seed, steps, added, camera, size, sun_azimuth, sun_elevation, resolution, k, ref out } =
            self;
        let mut settings = CompletionSettings { steps, gaussians: added, ..CompletionSettings::default() };
        settings.shadow.resolution = resolution;
        settings.shadow.k = k;
        let options = DemoCompletion {
            demo: demo::DemoOptions { gaussians, seed, ..demo::DemoOptions::default() },
            camera,
            size: size.pair(),
            sun: (sun_azimuth, sun_elevation),
            settings,
        };
        std::fs::create_dir_all(out).map_err(Error::io(out))?;
        let device = device_args.open()?;
        let bar = progress_bar(u64::from(steps) + 1, "{bar:30} {pos}/{len} {msg} [{elapsed}, ETA {eta}]");
        let mut lines = Vec::new();
        let result = complete_demo(&device, &options, &mut |s| {
            let line = format!(
                "step {:3}: loss {:.4}, shadow IoU {:.3}, missing-shadow IoU {:.3}",
                s.step, s.loss, s.iou, s.missing_iou
            );
            print_line(&bar, &line);
            bar.set_message(format!("IoU {:.3}", s.iou));
            bar.inc(1);
            lines.push(format!("{},{},{},{}", s.step, s.loss, s.iou, s.missing_iou));
        });
        bar.finish_and_clear();
        let result = result?;
        let c = &result.completion;
        let (w, h) = (result.camera.width, result.camera.height);
        let grey = |v: &[f32]| -> Vec<f32> { v.iter().flat_map(|x| [*x, *x, *x]).collect() };
        for (name, v) in
            [("target", &result.target), ("without", &c.without), ("before", &c.before), ("after", &c.after)]
        {
            io::write_png(out.join(format!("visibility_{name}.png")), w, h, &grey(v))?;
        }
        let ply = out.join("completed.ply");
        io::write_ply(&ply, &c.scene, PlyFormat::BinaryLittleEndian)?;
        let csv = out.join("history.csv");
        let text = format!("step,loss,shadow_iou,missing_shadow_iou\n{}\n", lines.join("\n"));
        std::fs::write(&csv, text).map_err(Error::io(&csv))?;
        let (first, last) = (c.history.first(), c.history.last());
        if let (Some(a), Some(b)) = (first, last) {
            println!(
                "removed the off-screen tower ({} Gaussians); added {} where no camera sees",
                result.removed,
                c.scene.len() - c.first_added
            );
            println!(
                "shadow IoU: {:.3} without the tower, {:.3} at the start, {:.3} after {} steps",
                shadow_iou(&c.without, &result.target, &c.mask),
                a.iou,
                b.iou,
                b.step
            );
            println!(
                "missing-shadow IoU (receivers the scene alone leaves lit): {:.3} → {:.3}",
                a.missing_iou, b.missing_iou
            );
            println!("added Gaussians that ended inside a camera's view: {}", c.visible_added);
        }
        println!("images: {}/visibility_{{target,without,before,after}}.png", out.display());
        println!("scene: {}", ply.display());
        println!("history: {}", csv.display());
        let messages = device.take_validation_messages();
        if device.validation_enabled() {
            println!("validation messages: {}", messages.len());
        }
        Ok(())
    }
}
