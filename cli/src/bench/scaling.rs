//! `srug bench scaling`: how a relit frame's GPU time and memory grow with the
//! Gaussian count (at a fixed image size) and with the pixel count (at a fixed
//! Gaussian count), with the least-squares slope of log time against log size.
//!
//! Each point renders the demo city's camera 0 with the balanced preset
//! (sigmoid shadow map 2048, no network) and reports per-stage-group medians.
//! Memory is the device's peak allocation during the frame above what was
//! held before it (G-buffers, splats, keys, sort scratch, shadow map), next to
//! the scene's own parameter bytes.

use super::median;
use super::trade::{group_seconds, STAGE_GROUPS};
use srug::error::{Error, Result};
use srug::frame::{Preset, RelightSettings, Relighter};
use srug::gpu::Device;
use srug::scene::activate::GpuScene;
use srug::scene::demo::{demo_city, DemoOptions};
use srug::shade::{BrdfLut, EnvironmentPrep, PrepareSettings, ProceduralSky};
use srug::shadow::Sun;

/// One measured point.
#[derive(Clone, Debug)]
pub struct ScalingRow {
    /// Gaussians in the demo city.
    pub gaussians: usize,
    /// Image size.
    pub size: (u32, u32),
    /// Median frame GPU seconds.
    pub seconds: f64,
    /// Median seconds per stage group ([`STAGE_GROUPS`] order).
    pub groups: Vec<(&'static str, f64)>,
    /// Bytes of the scene's parameters on the GPU.
    pub scene_bytes: u64,
    /// Peak GPU bytes the frame allocated above what was held before it.
    pub frame_bytes: u64,
    /// (Gaussian, tile) pairs the camera splat sorted.
    pub pairs: u64,
}

/// Least-squares slope of ln y against ln x over the points with positive
/// values; NaN with fewer than two.
pub fn loglog_slope(points: &[(f64, f64)]) -> f64 {
    let logs: Vec<(f64, f64)> =
        points.iter().filter(|(x, y)| *x > 0.0 && *y > 0.0).map(|(x, y)| (x.ln(), y.ln())).collect();
    if logs.len() < 2 {
        return f64::NAN;
    }
    let n = logs.len() as f64;
    let (mx, my) = logs.iter().fold((0.0, 0.0), |(a, b), (x, y)| (a + x / n, b + y / n));
    let (sxy, sxx) = logs.iter().fold((0.0, 0.0), |(a, b), (x, y)| (a + (x - mx) * (y - my), b + (x - mx) * (x - mx)));
    if sxx == 0.0 {
        f64::NAN
    } else {
        sxy / sxx
    }
}

/// What the scaling benchmark sweeps.
#[derive(Clone, Debug)]
pub struct ScalingSetup {
    /// Gaussian counts for the first sweep, at `size`.
    pub counts: Vec<usize>,
    /// Image size of the first sweep.
    pub size: (u32, u32),
    /// Image sizes for the second sweep, at `gaussians`.
    pub sizes: Vec<(u32, u32)>,
    /// Gaussian count of the second sweep.
    pub gaussians: usize,
    /// Frames per point.
    pub repeats: usize,
    /// Untimed frames before each point's timed ones ([`super::warm_up`]).
    pub warm_up: std::time::Duration,
}

/// The two sweeps: by Gaussian count, then by image size.
pub fn scaling_bench(
    device: &Device,
    setup: &ScalingSetup,
    mut progress: impl FnMut(&str),
) -> Result<(Vec<ScalingRow>, Vec<ScalingRow>)> {
    let sun = Sun::from_azimuth_elevation(260.0, 50.0, [std::f32::consts::PI; 3])?;
    let prep = EnvironmentPrep::new(device)?;
    let brdf = prep.brdf_table(BrdfLut::Karis, 129, 1024)?;
    let env =
        prep.prepare(&ProceduralSky::new(sun.direction, sun.intensity[0]).render()?, &PrepareSettings::default())?;
    let mut relighter = Relighter::new(device)?;
    let settings = RelightSettings::preset(Preset::Balanced);
    let mut measure = |n: usize, sizes: &[(u32, u32)], progress: &mut dyn FnMut(&str)| -> Result<Vec<ScalingRow>> {
        progress(&format!("{n} Gaussians: generating"));
        let city = demo_city(&DemoOptions { seed: 7, gaussians: n, sh_degree: 1 })?;
        let gpu = GpuScene::upload(device, &city.scene)?;
        let attributes = city.scene.attributes();
        let bounds = city.scene.bounds().ok_or_else(|| Error::invalid("demo city", "is empty"))?;
        let mut rows = Vec::new();
        for &(w, h) in sizes {
            let camera = city.cameras[0].resized(w, h);
            let (mut seconds, mut groups) = (Vec::new(), vec![Vec::new(); STAGE_GROUPS.len()]);
            let (mut frame_bytes, mut pairs) = (0u64, 0u64);
            super::warm_up(setup.warm_up, || {
                relighter.render(&gpu, &attributes, &bounds, &camera, Some(&sun), &env, &brdf, &settings).map(drop)
            })?;
            for r in 0..setup.repeats.max(1) {
                progress(&format!("{n} Gaussians at {w}x{h} ({}/{})", r + 1, setup.repeats.max(1)));
                device.reset_peak_memory();
                let before = device.memory_usage().current_bytes;
                let relit =
                    relighter.render(&gpu, &attributes, &bounds, &camera, Some(&sun), &env, &brdf, &settings)?;
                frame_bytes = frame_bytes.max(device.memory_usage().peak_bytes.saturating_sub(before));
                pairs = relit.pairs;
                seconds.push(relit.timings.total_seconds());
                for (i, t) in group_seconds(&relit.timings).into_iter().enumerate() {
                    groups[i].push(t);
                }
            }
            rows.push(ScalingRow {
                gaussians: n,
                size: (w, h),
                seconds: median(seconds),
                groups: STAGE_GROUPS.iter().zip(groups).map(|(g, v)| (*g, median(v))).collect(),
                scene_bytes: city.scene.gpu_bytes(),
                frame_bytes,
                pairs,
            });
        }
        Ok(rows)
    };
    let mut by_count = Vec::new();
    for &n in &setup.counts {
        by_count.extend(measure(n, &[setup.size], &mut progress)?);
    }
    let by_size = measure(setup.gaussians, &setup.sizes, &mut progress)?;
    Ok((by_count, by_size))
}

/// A sweep as a markdown table, with the fitted slopes of total and per-group
/// time against `x` (Gaussians or pixels) in a last row.
pub fn scaling_markdown(rows: &[ScalingRow], by_pixels: bool) -> String {
    let x = |r: &ScalingRow| if by_pixels { f64::from(r.size.0) * f64::from(r.size.1) } else { r.gaussians as f64 };
    let mut s = String::from("| Gaussians | size | pixels | pairs | frame ms |");
    for g in STAGE_GROUPS.iter().take(4) {
        s += &format!(" {g} ms |");
    }
    s += " scene MiB | frame peak MiB |\n|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n";
    let mib = |b: u64| b as f64 / (1024.0 * 1024.0);
    for r in rows {
        s += &format!(
            "| {} | {}x{} | {} | {} | {:.1} |",
            r.gaussians,
            r.size.0,
            r.size.1,
            r.size.0 * r.size.1,
            r.pairs,
            r.seconds * 1e3
        );
        for (_, t) in r.groups.iter().take(4) {
            s += &format!(" {:.1} |", t * 1e3);
        }
        s += &format!(" {:.1} | {:.1} |\n", mib(r.scene_bytes), mib(r.frame_bytes));
    }
    let slope = |f: &dyn Fn(&ScalingRow) -> f64| {
        let v = loglog_slope(&rows.iter().map(|r| (x(r), f(r))).collect::<Vec<_>>());
        format!("{v:.2}")
    };
    s += &format!(
        "| **log-log slope** against {} | | | {} | {} |",
        if by_pixels { "pixels" } else { "Gaussians" },
        slope(&|r| r.pairs as f64),
        slope(&|r| r.seconds)
    );
    for i in 0..4 {
        s += &format!(" {} |", slope(&|r| r.groups[i].1));
    }
    s += &format!(" {} | {} |\n", slope(&|r| r.scene_bytes as f64), slope(&|r| r.frame_bytes as f64));
    s
}

#[cfg(test)]
mod tests {
    use super::loglog_slope;

    #[test]
    fn slope_of_power_laws() {
        let linear: Vec<(f64, f64)> = [1e4, 1e5, 1e6].iter().map(|x| (*x, 3.0 * x)).collect();
        assert!((loglog_slope(&linear) - 1.0).abs() < 1e-12);
        let sqrt: Vec<(f64, f64)> = [4.0, 16.0, 64.0, 256.0].iter().map(|x: &f64| (*x, 2.0 * x.sqrt())).collect();
        assert!((loglog_slope(&sqrt) - 0.5).abs() < 1e-12);
        assert!(loglog_slope(&[(1.0, 2.0)]).is_nan(), "one point has no slope");
        assert!(loglog_slope(&[(1.0, 2.0), (1.0, 3.0)]).is_nan(), "one x has no slope");
    }
}
