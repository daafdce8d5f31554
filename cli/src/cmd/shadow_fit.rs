//! `srug shadow-fit`: shadow-guided completion. With a scene, its cameras and
//! shadow masks, Gaussians grow where no camera sees until the shadows they
//! cast match the masks, and the completed scene is written with the added
//! Gaussians flagged (`srug_added`). Without a scene, the demo: remove the
//! off-screen tower, then grow it back from its shadow.

use std::path::{Path, PathBuf};

use glam::Vec3;
use srug::io;
use srug::io::PlyFormat;
use srug::scene::{demo, Bounds, Camera};
use srug::shadow::completion::{
    complete_demo, complete_from_views, shadow_iou, Completion, CompletionProblem, CompletionSettings, CompletionStep,
    DemoCompletion, ShadowView,
};
use srug::shadow::masks::{find_masks, mask_stem, read_mask, MaskOptions};
use srug::{Error, Result};

use crate::args::{print_line, progress_bar, BoxArg, DeviceArgs, Size, SunPlaceArgs};

/// Arguments of `srug shadow-fit`.
#[derive(clap::Args, Clone, Debug)]
pub(super) struct ShadowFitArgs {
    /// Scene to complete (any format srug reads); without it, the demo's completion runs.
    scene: Option<PathBuf>,
    /// Every camera of the capture (any camera format srug reads); those with a mask are fitted,
    /// and no Gaussian is added where any of them sees.
    #[arg(long, requires = "scene")]
    cameras: Option<PathBuf>,
    /// Folder of shadow masks, one per camera, named as the camera's image (its stem: camera
    /// "frames/0001.jpg" takes 0001.png, .jpg, .exr, ...). White = shadow, black = lit, grey a
    /// probability; transparent pixels are unknown. A mask of another size is resampled.
    #[arg(long, requires = "scene")]
    masks: Option<PathBuf>,
    /// Black = shadow instead.
    #[arg(long, requires = "masks")]
    invert_masks: bool,
    /// Folder of ignore masks named as the masks: white pixels are unknown (not fitted).
    #[arg(long, requires = "masks")]
    ignore_masks: Option<PathBuf>,
    /// Where occluders may be added, xmin,ymin,zmin,xmax,ymax,zmax (default: the box of the
    /// scene's centres between the 0.5% and 99.5% quantiles on each axis, raised by half its
    /// horizontal diagonal).
    #[arg(long, requires = "scene", allow_hyphen_values = true)]
    region: Option<BoxArg>,
    /// Gaussians of the scene the fit may move with the added ones: those whose centre is in
    /// this box (xmin,ymin,zmin,xmax,ymax,zmax) and that no camera sees (flagged srug_moved).
    #[arg(long, requires = "scene", allow_hyphen_values = true)]
    movable: Option<BoxArg>,
    /// Folder for the mask agreement images before and after, per view, and history.csv.
    #[arg(long, requires = "scene")]
    report: Option<PathBuf>,
    /// Demo city size.
    #[arg(long, conflicts_with = "scene")]
    gaussians: Option<usize>,
    /// Demo seed.
    #[arg(long, conflicts_with = "scene")]
    seed: Option<u64>,
    /// Which demo camera receives the shadow.
    #[arg(long, conflicts_with = "scene")]
    camera: Option<usize>,
    /// Fit at this image size WxH (cameras rescaled, masks resampled); the demo's default 352x96,
    /// a scene's cameras their own size.
    #[arg(long)]
    size: Option<Size>,
    /// Where the sun is.
    #[command(flatten)]
    sun: SunPlaceArgs,
    /// Adam steps of the added Gaussians.
    #[arg(long, default_value_t = 60)]
    steps: u32,
    /// Most Gaussians added (0: none, with --fixed-steps: only the fixed visibility is fitted).
    #[arg(long, default_value_t = 4000)]
    added: usize,
    /// L_Vf: first fit the scene's fixed visibility (its visibility attribute, what
    /// `relight --visibility fixed` shows) to the masks for this many Adam steps; only those
    /// values change.
    #[arg(long, default_value_t = 0)]
    fixed_steps: u32,
    /// What the added Gaussians' shadows fit: the masks, or (L_Ve) the fixed visibility rendered
    /// in each view (after --fixed-steps when given).
    #[arg(long, default_value = "masks", value_parser = ["masks", "fixed"])]
    editable_target: String,
    /// The added Gaussians' shadow-map resolution (longer side).
    #[arg(long, default_value_t = 256)]
    resolution: u32,
    /// The added Gaussians' sigmoid sharpness k per metre.
    #[arg(long, default_value_t = 4.0)]
    k: f32,
    /// Output: the completed scene (.ply) with a scene, a folder with the demo (default out/shadow-fit).
    #[arg(long)]
    out: Option<PathBuf>,
}

/// One line of progress.
fn step_line(s: &CompletionStep) -> String {
    let views: Vec<String> = s.view_iou.iter().map(|v| format!("{v:.3}")).collect();
    if s.stage == "fixed" {
        return format!(
            "fixed visibility step {:3}: loss {:.4}, IoU {:.3} (views {})",
            s.step,
            s.loss,
            s.iou,
            views.join(" ")
        );
    }
    format!(
        "step {:3}: loss {:.4}, shadow IoU {:.3} (views {}), missing-shadow IoU {:.3}, {} added",
        s.step,
        s.loss,
        s.iou,
        views.join(" "),
        s.missing_iou,
        s.gaussians
    )
}

/// Runs the completion with a progress bar; returns it and the history as CSV rows.
fn run_with_progress(
    steps: u64,
    run: impl FnOnce(&mut dyn FnMut(&CompletionStep)) -> Result<Completion>,
) -> Result<(Completion, Vec<String>)> {
    let bar = progress_bar(steps, "{bar:30} {pos}/{len} {msg} [{elapsed}, ETA {eta}]");
    let mut lines = Vec::new();
    let result = run(&mut |s| {
        print_line(&bar, &step_line(s));
        bar.set_message(format!("IoU {:.3}", s.iou));
        bar.inc(1);
        lines.push(format!("{},{},{},{},{},{}", s.stage, s.step, s.loss, s.iou, s.missing_iou, s.gaussians));
    });
    bar.finish_and_clear();
    Ok((result?, lines))
}

fn write_history(path: &Path, lines: &[String]) -> Result<()> {
    let text = format!("stage,step,loss,shadow_iou,missing_shadow_iou,added\n{}\n", lines.join("\n"));
    io::write_atomic(path, text.as_bytes())
}

/// The mask agreement as colours: lit in both light grey, shadow in both dark
/// grey, shadow the mask has and the render lacks red, shadow the render has
/// and the mask lacks blue, unknown or no surface black.
fn agreement(v: &[f32], target: &[f32], mask: &[bool]) -> Vec<f32> {
    v.iter()
        .zip(target)
        .zip(mask)
        .flat_map(|((v, t), m)| match (*m, *v < 0.5, *t < 0.5) {
            (false, _, _) => [0.0, 0.0, 0.0],
            (true, false, false) => [0.85, 0.85, 0.85],
            (true, true, true) => [0.25, 0.25, 0.25],
            (true, false, true) => [0.9, 0.1, 0.1],
            (true, true, false) => [0.1, 0.3, 0.9],
        })
        .collect()
}

impl ShadowFitArgs {
    /// Progress reports: each stage's steps plus its initial state.
    fn total_steps(&self) -> u64 {
        let fixed =
            if self.fixed_steps > 0 || self.editable_target == "fixed" { u64::from(self.fixed_steps) + 1 } else { 0 };
        let grow = if self.added > 0 { u64::from(self.steps) + 1 } else { 0 };
        fixed + grow
    }

    fn settings(&self) -> CompletionSettings {
        let mut settings = CompletionSettings {
            steps: self.steps,
            gaussians: self.added,
            fixed_steps: self.fixed_steps,
            editable_from_fixed: self.editable_target == "fixed",
            movable: self.movable.map(|BoxArg(b)| b),
            ..CompletionSettings::default()
        };
        settings.shadow.resolution = self.resolution;
        settings.shadow.k = self.k;
        settings
    }

    /// The one sun, above the horizon.
    fn sun(&self) -> Result<srug::shadow::Sun> {
        let (label, sun) = self.sun.resolve(std::f32::consts::PI)?;
        if !sun.above_horizon() {
            return Err(Error::invalid(
                format!("sun {label}"),
                "is at or below the horizon: it casts no shadow to fit (it must be above the horizon)",
            ));
        }
        Ok(sun)
    }

    /// Runs `srug shadow-fit`.
    pub(super) fn run(&self, device_args: &DeviceArgs) -> Result<()> {
        match &self.scene {
            Some(scene) => self.run_scene(scene, device_args),
            None => self.run_demo(device_args),
        }
    }

    fn run_scene(&self, scene_path: &Path, device_args: &DeviceArgs) -> Result<()> {
        let cameras_path =
            self.cameras.as_ref().ok_or_else(|| Error::invalid("shadow-fit SCENE", "needs --cameras"))?;
        let masks_dir = self.masks.as_ref().ok_or_else(|| Error::invalid("shadow-fit SCENE", "needs --masks DIR"))?;
        let out = self.out.as_ref().ok_or_else(|| Error::invalid("shadow-fit SCENE", "needs --out COMPLETED.ply"))?;
        if !out.extension().is_some_and(|e| e.eq_ignore_ascii_case("ply")) {
            return Err(Error::invalid(
                format!("--out {}", out.display()),
                "must be a .ply file (it carries the srug_added flag)",
            ));
        }
        let sun = self.sun()?;
        let scene = io::read_scene(scene_path)?;
        let mut cameras = io::read_cameras(cameras_path)?;
        if let Some(size) = self.size {
            let (w, h) = size.pair();
            cameras = cameras.iter().map(|c| c.resized(w, h)).collect();
        }
        let (found, unmatched) = find_masks(masks_dir, &cameras)?;
        let options = MaskOptions { invert: self.invert_masks };
        let mut views = Vec::new();
        let mut uniform = 0;
        for (camera, mask) in cameras.iter().zip(&found) {
            let Some(path) = mask else {
                println!("camera \"{}\": no mask in {}, skipped", camera.name, masks_dir.display());
                continue;
            };
            let image = read_mask(path)?;
            let ignore = match &self.ignore_masks {
                Some(dir) => {
                    let (hits, _) = find_masks(dir, std::slice::from_ref(camera))?;
                    hits[0].as_deref().map(read_mask).transpose()?
                }
                None => None,
            };
            if image.is_uniform() {
                uniform += 1;
                eprintln!(
                    "warning: mask {} is all one value (all shadow or all lit at 0.5): check it and --invert-masks",
                    path.display()
                );
            }
            views.push(ShadowView { camera: camera.clone(), target: image.target(camera, ignore.as_ref(), options)? });
        }
        for f in &unmatched {
            eprintln!("warning: mask {} matches no camera (names: {})", f.display(), camera_names(&cameras));
        }
        if views.is_empty() {
            return Err(Error::invalid(
                format!("masks in {}", masks_dir.display()),
                format!("match no camera: name them as the cameras' images ({})", camera_names(&cameras)),
            ));
        }
        if uniform == views.len() {
            return Err(Error::invalid(
                format!("masks in {}", masks_dir.display()),
                "are each all one value: nothing tells shadow from light",
            ));
        }
        let region = match self.region {
            Some(BoxArg(b)) => b,
            None => {
                default_region(&scene.core_bounds(0.005).ok_or_else(|| Error::invalid("scene", "has no Gaussians"))?)
            }
        };
        let device = device_args.open()?;
        println!(
            "fitting {} of {} cameras' masks, {} Gaussians, up to {} added in {:?}..{:?}",
            views.len(),
            cameras.len(),
            scene.len(),
            self.added,
            region.min,
            region.max
        );
        let settings = self.settings();
        let problem = CompletionProblem { scene: &scene, region: &region, views: &views, cameras: &cameras, sun: &sun };
        let start = std::time::Instant::now();
        let (c, lines) =
            run_with_progress(self.total_steps(), |p| complete_from_views(&device, &problem, &settings, p))?;
        let seconds = start.elapsed().as_secs_f64();
        let added: Vec<bool> = (0..c.scene.len()).map(|i| i >= c.first_added).collect();
        let moved: Vec<bool> =
            (0..c.scene.len()).map(|i| (c.first_added - c.moved..c.first_added).contains(&i)).collect();
        let flags: &[(&str, &[bool])] = &[("srug_added", &added), ("srug_moved", &moved)];
        io::write_ply_with_flags(out, &c.scene, PlyFormat::BinaryLittleEndian, flags)?;
        if let Some(dir) = &self.report {
            std::fs::create_dir_all(dir).map_err(Error::io(dir))?;
            for (view, o) in views.iter().zip(&c.views) {
                let (w, h) = (view.camera.width, view.camera.height);
                let stem = mask_stem(&view.camera);
                let mut images = vec![("before", &o.without), ("after", &o.after)];
                if let Some((before, after)) = &o.fixed {
                    images.extend([("fixed_before", before), ("fixed_after", after)]);
                }
                for (name, v) in images.into_iter().filter(|(_, v)| !v.is_empty()) {
                    let png = dir.join(format!("agreement_{stem}_{name}.png"));
                    io::write_png(&png, w, h, &agreement(v, &view.target, &o.mask))?;
                }
            }
            write_history(&dir.join("history.csv"), &lines)?;
        }
        for (view, o) in views.iter().zip(&c.views) {
            if !o.after.is_empty() {
                println!(
                    "camera \"{}\": shadow IoU against its mask {:.3} → {:.3}",
                    view.camera.name,
                    shadow_iou(&o.without, &view.target, &o.mask),
                    shadow_iou(&o.after, &view.target, &o.mask)
                );
            }
            if let Some((before, after)) = &o.fixed {
                println!(
                    "camera \"{}\": fixed visibility IoU against its mask {:.3} → {:.3}",
                    view.camera.name,
                    shadow_iou(before, &view.target, &o.mask),
                    shadow_iou(after, &view.target, &o.mask)
                );
            }
        }
        println!(
            "added {} Gaussians (flagged srug_added), moved {} (srug_moved), {} added inside a camera's view, in \
             {seconds:.1} s ({:.0} ms per step)",
            c.added(),
            c.moved,
            c.visible_added,
            1e3 * seconds / self.total_steps().max(1) as f64
        );
        println!("scene: {}", out.display());
        if let Some(dir) = &self.report {
            println!("report: {}/agreement_*_{{before,after}}.png, history.csv", dir.display());
        }
        report_validation(&device);
        Ok(())
    }

    fn run_demo(&self, device_args: &DeviceArgs) -> Result<()> {
        let defaults = DemoCompletion::default();
        let sun = self.sun()?;
        let (azimuth, elevation) = sun.azimuth_elevation();
        let options = DemoCompletion {
            demo: demo::DemoOptions {
                gaussians: self.gaussians.unwrap_or(defaults.demo.gaussians),
                seed: self.seed.unwrap_or(7),
                ..demo::DemoOptions::default()
            },
            camera: self.camera.unwrap_or(defaults.camera),
            size: self.size.map_or(defaults.size, Size::pair),
            sun: (azimuth, elevation),
            settings: self.settings(),
        };
        let out = self.out.clone().unwrap_or_else(|| PathBuf::from("out/shadow-fit"));
        let device = device_args.open()?;
        let mut target = Vec::new();
        let mut removed = 0;
        let mut camera = None;
        let (c, lines) = run_with_progress(self.total_steps(), |p| {
            let r = complete_demo(&device, &options, p)?;
            (target, removed, camera) = (r.target, r.removed, Some(r.camera));
            Ok(r.completion)
        })?;
        let camera = camera.ok_or_else(|| Error::invalid("demo completion", "returned no camera"))?;
        std::fs::create_dir_all(&out).map_err(Error::io(&out))?;
        let v = &c.views[0];
        let (w, h) = (camera.width, camera.height);
        let grey = |v: &[f32]| -> Vec<f32> { v.iter().flat_map(|x| [*x, *x, *x]).collect() };
        let mut images = vec![("target", &target), ("without", &v.without), ("before", &v.before), ("after", &v.after)];
        if let Some((before, after)) = &v.fixed {
            images.extend([("fixed_before", before), ("fixed_after", after)]);
        }
        // Without added Gaussians (--added 0) only the fixed visibility has images.
        for (name, v) in images.into_iter().filter(|(_, v)| !v.is_empty()) {
            io::write_png(out.join(format!("visibility_{name}.png")), w, h, &grey(v))?;
        }
        let ply = out.join("completed.ply");
        let flags: Vec<bool> = (0..c.scene.len()).map(|i| i >= c.first_added).collect();
        io::write_ply_with_flags(&ply, &c.scene, PlyFormat::BinaryLittleEndian, &[("srug_added", &flags)])?;
        let csv = out.join("history.csv");
        write_history(&csv, &lines)?;
        let editable: Vec<_> = c.history.iter().filter(|s| s.stage == "editable").collect();
        if let Some((before, after)) = &v.fixed {
            println!(
                "fixed visibility IoU against the target: {:.3} → {:.3}",
                shadow_iou(before, &target, &v.mask),
                shadow_iou(after, &target, &v.mask)
            );
        }
        if let (Some(a), Some(b)) = (editable.first(), editable.last()) {
            println!("removed the off-screen tower ({removed} Gaussians); added {} where no camera sees", c.added());
            println!(
                "shadow IoU: {:.3} without the tower, {:.3} at the start, {:.3} after {} steps",
                shadow_iou(&v.without, &target, &v.mask),
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
        println!("images: {}/visibility_*.png", out.display());
        println!("scene: {}", ply.display());
        println!("history: {}", csv.display());
        report_validation(&device);
        Ok(())
    }
}

/// The scene's core bounds (its centres between the 0.5% and 99.5% quantiles
/// on each axis, floaters left out) raised by half their horizontal diagonal:
/// what is missing may be taller than anything the cameras saw.
fn default_region(b: &Bounds) -> Bounds {
    let (lo, hi) = (Vec3::from_array(b.min), Vec3::from_array(b.max));
    let diagonal = (hi - lo).truncate().length();
    Bounds { min: b.min, max: [b.max[0], b.max[1], b.max[2] + 0.5 * diagonal.max(1.0)] }
}

/// The first few camera names, for messages.
fn camera_names(cameras: &[Camera]) -> String {
    let names: Vec<String> = cameras.iter().take(3).map(|c| format!("\"{}\"", mask_stem(c))).collect();
    let more = if cameras.len() > 3 { ", ..." } else { "" };
    format!("{}{more}", names.join(", "))
}

fn report_validation(device: &srug::gpu::Device) {
    let messages = device.take_validation_messages();
    if device.validation_enabled() {
        println!("validation messages: {}", messages.len());
    }
}
