//! `srug bench shadow`: the sigmoid shadow pass against the traced pass, the
//! shadow map's accuracy (IoU and mean |V_e − V_t| against the traced
//! visibility) across resolution, k and depth mode, and each preset's
//! accuracy against the analytic block's ray-cast truth. GPU timestamps only.

use srug::error::Result;
use srug::frame::block_accuracy::block_shadow_accuracy;
use srug::frame::{Preset, RelightSettings};
use srug::gpu::Device;
use srug::scene::activate::GpuScene;
use srug::scene::blocks::{block_city, BlockOptions, BlockSplats};
use srug::scene::demo::{demo_city, DemoOptions};
use srug::scene::Bounds;
use srug::shadow::accuracy::ShadowAccuracy;
use srug::shadow::completion::shadow_iou;
use srug::shadow::{DepthMode, ShadowPass, ShadowSettings, Sun, VisibilityKind};
use srug::splat::{Channels, SplatSettings, Splatter};

/// One scene size of the speed table.
#[derive(Clone, Debug)]
pub struct ShadowSpeedRow {
    /// Gaussians in the demo city.
    pub gaussians: usize,
    /// Shadow-map resolution.
    pub resolution: u32,
    /// (Gaussian, tile) pairs of the shadow-map splat.
    pub map_pairs: u64,
    /// Seconds to splat the shadow map (once per sun position; median).
    pub map_seconds: f64,
    /// Seconds of the sigmoid test per frame (median).
    pub sigmoid_seconds: f64,
    /// Seconds of the traced pass per frame (median).
    pub traced_seconds: f64,
}

/// One setting of the accuracy table.
#[derive(Clone, Debug)]
pub struct ShadowAccuracyRow {
    /// Shadow-map resolution.
    pub resolution: u32,
    /// Sigmoid sharpness.
    pub k: f32,
    /// Map depth mode.
    pub depth: DepthMode,
    /// IoU of the shadowed pixels against the traced visibility.
    pub iou: f64,
    /// Mean |V_e − V_t| over receivers with a surface.
    pub mean_abs_diff: f64,
    /// Seconds of the sigmoid test (median).
    pub sigmoid_seconds: f64,
    /// Seconds to splat the map.
    pub map_seconds: f64,
}

/// What the shadow benchmark measures on.
#[derive(Clone, Copy, Debug)]
pub struct ShadowBenchSetup {
    /// Receiver image size.
    pub size: (u32, u32),
    /// Sun (azimuth, elevation) in degrees.
    pub sun: (f32, f32),
    /// Repeats per timing (medians are reported).
    pub repeats: usize,
}

fn repeated(repeats: usize, mut f: impl FnMut() -> Result<f64>) -> Result<f64> {
    let mut v = Vec::new();
    for _ in 0..repeats.max(1) {
        v.push(f()?);
    }
    v.sort_by(f64::total_cmp);
    Ok(v[v.len() / 2])
}

fn bounds_of(scene: &srug::scene::Scene) -> Bounds {
    scene.bounds().unwrap_or(Bounds { min: [0.0; 3], max: [1.0; 3] })
}

/// Speed of the sigmoid test against the traced pass for each demo size.
pub fn shadow_speed(
    device: &Device,
    counts: &[usize],
    resolution: u32,
    setup: &ShadowBenchSetup,
    mut progress: impl FnMut(&str),
) -> Result<Vec<ShadowSpeedRow>> {
    let sun = Sun::from_azimuth_elevation(setup.sun.0, setup.sun.1, [1.0; 3])?;
    let mut splatter = Splatter::new(device)?;
    let pass = ShadowPass::new(device)?;
    let st = ShadowSettings { resolution, ..ShadowSettings::default() };
    let mut rows = Vec::new();
    for &n in counts {
        progress(&format!("{n} Gaussians: generating"));
        let demo = demo_city(&DemoOptions { gaussians: n, ..DemoOptions::default() })?;
        let gpu = GpuScene::upload(device, &demo.scene)?;
        let camera = demo.cameras[0].resized(setup.size.0, setup.size.1);
        let channels = st.receiver_channels();
        let receivers =
            splatter.render_frame(&gpu, &camera, &SplatSettings { channels, ..SplatSettings::default() })?;
        let bounds = bounds_of(&demo.scene);
        progress(&format!("{n} Gaussians: shadow map"));
        let mut pairs = 0;
        let map_seconds = repeated(setup.repeats, || {
            let map = pass.shadow_map(&mut splatter, &gpu, &bounds, &sun, &st, None)?;
            Ok(map.map_or(0.0, |m| {
                pairs = m.frame.stats.pairs;
                m.frame.stats.timings.total_seconds()
            }))
        })?;
        let Some(map) = pass.shadow_map(&mut splatter, &gpu, &bounds, &sun, &st, None)? else { continue };
        progress(&format!("{n} Gaussians: sigmoid and traced passes"));
        let time = |kind| {
            repeated(setup.repeats, || {
                Ok(pass.visibility(&map, &receivers.gbuffer, &camera, &st, kind)?.1.total_seconds())
            })
        };
        rows.push(ShadowSpeedRow {
            gaussians: demo.scene.len(),
            resolution,
            map_pairs: pairs,
            map_seconds,
            sigmoid_seconds: time(VisibilityKind::Sigmoid)?,
            traced_seconds: time(VisibilityKind::Traced)?,
        });
    }
    Ok(rows)
}

/// Accuracy of the sigmoid test against the traced visibility (taken at the
/// highest resolution given) across resolutions, k and both depth modes.
pub fn shadow_accuracy(
    device: &Device,
    gaussians: usize,
    resolutions: &[u32],
    ks: &[f32],
    setup: &ShadowBenchSetup,
    mut progress: impl FnMut(&str),
) -> Result<Vec<ShadowAccuracyRow>> {
    let sun = Sun::from_azimuth_elevation(setup.sun.0, setup.sun.1, [1.0; 3])?;
    let mut splatter = Splatter::new(device)?;
    let pass = ShadowPass::new(device)?;
    progress("generating");
    let demo = demo_city(&DemoOptions { gaussians, ..DemoOptions::default() })?;
    let gpu = GpuScene::upload(device, &demo.scene)?;
    let camera = demo.cameras[0].resized(setup.size.0, setup.size.1);
    let base = ShadowSettings::default();
    // Both depths (the map's mode varies) and the normals its slope bias reads.
    let channels = Channels { depth: true, median_depth: true, ..base.receiver_channels() };
    let receivers = splatter.render_frame(&gpu, &camera, &SplatSettings { channels, ..SplatSettings::default() })?;
    let alpha: Vec<f32> = device.read_buffer(&receivers.gbuffer.alpha)?;
    let mask: Vec<bool> = alpha.iter().map(|a| *a >= base.min_alpha).collect();
    let covered = mask.iter().filter(|m| **m).count().max(1);
    let bounds = bounds_of(&demo.scene);
    let top = resolutions.iter().copied().max().unwrap_or(base.resolution);
    progress("traced reference");
    let reference_settings = ShadowSettings { resolution: top, ..base };
    let Some(map) = pass.shadow_map(&mut splatter, &gpu, &bounds, &sun, &reference_settings, None)? else {
        return Ok(Vec::new());
    };
    let (t, _) = pass.visibility(&map, &receivers.gbuffer, &camera, &reference_settings, VisibilityKind::Traced)?;
    let traced: Vec<f32> = device.read_buffer(&t)?;
    drop(map);
    let mut rows = Vec::new();
    for &resolution in resolutions {
        for depth in [DepthMode::Median, DepthMode::Expected] {
            let st = ShadowSettings { resolution, map_depth: depth, ..base };
            progress(&format!("{resolution} texels, {depth:?} depth"));
            let Some(map) = pass.shadow_map(&mut splatter, &gpu, &bounds, &sun, &st, None)? else { continue };
            let map_seconds = map.frame.stats.timings.total_seconds();
            for &k in ks {
                let st = ShadowSettings { k, ..st };
                let (v, _) = pass.visibility(&map, &receivers.gbuffer, &camera, &st, VisibilityKind::Sigmoid)?;
                let v: Vec<f32> = device.read_buffer(&v)?;
                let diff: f64 = v
                    .iter()
                    .zip(&traced)
                    .zip(&mask)
                    .filter(|(_, m)| **m)
                    .map(|((a, b), _)| f64::from((a - b).abs()))
                    .sum();
                let sigmoid_seconds = repeated(setup.repeats, || {
                    Ok(pass
                        .visibility(&map, &receivers.gbuffer, &camera, &st, VisibilityKind::Sigmoid)?
                        .1
                        .total_seconds())
                })?;
                rows.push(ShadowAccuracyRow {
                    resolution,
                    k,
                    depth,
                    iou: shadow_iou(&v, &traced, &mask),
                    mean_abs_diff: diff / covered as f64,
                    sigmoid_seconds,
                    map_seconds,
                });
            }
        }
    }
    Ok(rows)
}

/// One sampling and preset on the analytic block.
#[derive(Clone, Debug)]
pub struct BlockAccuracyRow {
    /// How the block's surfaces are sampled.
    pub splats: BlockSplats,
    /// The preset.
    pub preset: Preset,
    /// Over every sun and camera.
    pub accuracy: ShadowAccuracy,
}

/// Every preset's shadows against the analytic block's ray-cast truth (three
/// suns, three street cameras), with ideal and rough splats.
pub fn block_accuracy(device: &Device, mut progress: impl FnMut(&str)) -> Result<Vec<BlockAccuracyRow>> {
    let mut splatter = Splatter::new(device)?;
    let pass = ShadowPass::new(device)?;
    let mut rows = Vec::new();
    for splats in [BlockSplats::Ideal, BlockSplats::Rough] {
        progress(&format!("analytic block, {splats:?} splats"));
        let city = block_city(&BlockOptions { splats, ..BlockOptions::default() })?;
        let scene = GpuScene::upload(device, &city.scene)?;
        for preset in Preset::ALL {
            let settings = RelightSettings::preset(preset);
            let per_sun =
                block_shadow_accuracy(device, &mut splatter, &pass, &city, &scene, &settings, None, &mut |_| Ok(()))?;
            let mut accuracy = ShadowAccuracy::default();
            per_sun.iter().for_each(|(_, a)| accuracy.add(a));
            rows.push(BlockAccuracyRow { splats, preset, accuracy });
        }
    }
    Ok(rows)
}
