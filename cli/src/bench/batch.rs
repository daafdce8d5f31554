//! Frames per second of a camera list against its length: `srug render` and
//! `srug relight` runs (this binary, a fresh process each, wall clock:
//! startup, scene load and writing included) to PNG and EXR, and the same
//! frames rendered in process and read back into memory only (what the Python
//! package's numpy outputs cost), with the GPU time per frame beside them:
//! the floor no batching of submissions or overlap of writing can go below.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use glam::Vec3;
use srug::frame::{Preset, RelightSettings, Relighter};
use srug::gpu::Device;
use srug::scene::activate::GpuScene;
use srug::scene::demo::{demo_city, DemoOptions};
use srug::scene::{Camera, Scene};
use srug::shade::{BrdfLut, EnvironmentPrep, PrepareSettings, ProceduralSky};
use srug::shadow::Sun;
use srug::splat::{cameras_per_batch, Channels, SplatSettings, Splatter, BATCH_BYTES};
use srug::{io, Error, Result};

/// What the batch benchmark runs.
#[derive(Clone, Debug)]
pub struct BatchSetup {
    /// Gaussians of the demo city.
    pub gaussians: usize,
    /// Its SH degree.
    pub sh_degree: u32,
    /// Camera counts.
    pub counts: Vec<usize>,
    /// Image size.
    pub size: (u32, u32),
}

/// One camera count's row.
#[derive(Clone, Debug)]
pub struct BatchRow {
    /// Cameras.
    pub count: usize,
    /// Frames per second, in order: render PNG, render EXR, render to memory,
    /// relight PNG, relight EXR, relight to memory.
    pub fps: [f64; 6],
    /// GPU milliseconds per frame: render, relight (in-process runs).
    pub gpu_ms: [f64; 2],
}

/// `n` cameras walking up the demo street from its second camera, 0.6 m apart, at `size`.
pub fn street_walk(city_cameras: &[Camera], n: usize, size: (u32, u32)) -> Result<Vec<Camera>> {
    let base = city_cameras.get(1).ok_or_else(|| Error::Internal("the demo has no second camera".into()))?;
    Ok((0..n)
        .map(|i| Camera {
            name: format!("walk_{i:03}"),
            position: base.position + Vec3::new(0.0, 0.6 * i as f32, 0.0),
            ..base.resized(size.0, size.1)
        })
        .collect())
}

/// Runs the benchmark; `progress` gets a line per measurement.
pub fn batch_bench(device: &Device, setup: &BatchSetup, mut progress: impl FnMut(&str)) -> Result<Vec<BatchRow>> {
    let city = demo_city(&DemoOptions { seed: 7, gaussians: setup.gaussians, sh_degree: setup.sh_degree })?;
    let max = setup.counts.iter().copied().max().unwrap_or(1);
    let walk = street_walk(&city.cameras, max, setup.size)?;
    let dir = std::env::temp_dir().join(format!("srug-bench-batch-{}", std::process::id()));
    std::fs::create_dir_all(&dir).map_err(Error::io(&dir))?;
    let result = (|| {
        let scene_path = dir.join("city.ply");
        io::write_ply(&scene_path, &city.scene, io::PlyFormat::BinaryLittleEndian)?;
        let gpu_scene = GpuScene::upload(device, &city.scene)?;
        let mut rows = Vec::new();
        for &n in &setup.counts {
            let cams = &walk[..n];
            let cam_path = dir.join(format!("cameras_{n}.json"));
            io::write_cameras_json(&cam_path, cams)?;
            let mut fps = [0.0; 6];
            for (k, (command, ext)) in
                [("render", "png"), ("render", "exr"), ("relight", "png"), ("relight", "exr")].into_iter().enumerate()
            {
                progress(&format!("{n} cameras: srug {command} to {ext}"));
                let seconds = run_cli(&dir, command, &scene_path, &cam_path, ext)?;
                fps[if k < 2 { k } else { k + 1 }] = n as f64 / seconds;
            }
            progress(&format!("{n} cameras: in process, to memory"));
            let (render_s, render_gpu) = render_to_memory(device, &gpu_scene, cams)?;
            let (relight_s, relight_gpu) = relight_to_memory(device, &city.scene, &gpu_scene, cams)?;
            fps[2] = n as f64 / render_s;
            fps[5] = n as f64 / relight_s;
            rows.push(BatchRow { count: n, fps, gpu_ms: [render_gpu / n as f64 * 1e3, relight_gpu / n as f64 * 1e3] });
        }
        Ok(rows)
    })();
    let _ = std::fs::remove_dir_all(&dir);
    result
}

/// Wall seconds of one `srug <command>` run over the cameras file, writing `ext` files.
fn run_cli(dir: &Path, command: &str, scene: &Path, cameras: &Path, ext: &str) -> Result<f64> {
    let exe = std::env::current_exe().map_err(Error::io("the srug executable"))?;
    let out_dir: PathBuf = dir.join(format!("out_{command}_{ext}"));
    let _ = std::fs::remove_dir_all(&out_dir);
    let out = out_dir.join(format!("f.{ext}"));
    let start = Instant::now();
    let o = Command::new(&exe)
        .arg(command)
        .arg(scene)
        .arg("--cameras")
        .arg(cameras)
        .arg("--out")
        .arg(&out)
        .env_remove("SRUG_VALIDATION")
        .output()
        .map_err(Error::io(&exe))?;
    let seconds = start.elapsed().as_secs_f64();
    if !o.status.success() {
        return Err(Error::Internal(format!(
            "srug {command} failed: {}",
            String::from_utf8_lossy(&o.stderr).lines().last().unwrap_or("")
        )));
    }
    let _ = std::fs::remove_dir_all(&out_dir);
    Ok(seconds)
}

/// Wall and GPU seconds to render every camera and read its colour and alpha into memory.
fn render_to_memory(device: &Device, scene: &GpuScene, cams: &[Camera]) -> Result<(f64, f64)> {
    let mut splatter = Splatter::new(device)?;
    let settings = SplatSettings::default();
    // Kernels compiled before the clock starts.
    splatter.render(scene, &cams[0], &settings)?;
    let (w, h) = (cams[0].width as usize, cams[0].height as usize);
    let (mut rgb, mut alpha) = (vec![0.0f32; cams.len() * w * h * 3], vec![0.0f32; cams.len() * w * h]);
    // In batches, as the Python package renders (one submission per step for each).
    let batch = cameras_per_batch(scene.count as u64, &cams[0], &settings, BATCH_BYTES);
    let (start, mut gpu) = (Instant::now(), 0.0);
    for (b, chunk) in cams.chunks(batch).enumerate() {
        for (k, (g, stats)) in splatter.render_batch(scene, chunk, &settings)?.into_iter().enumerate() {
            let i = b * batch + k;
            device.read_buffer_into(g.rgb_buffer()?, &mut rgb[i * w * h * 3..(i + 1) * w * h * 3])?;
            device.read_buffer_into(&g.alpha, &mut alpha[i * w * h..(i + 1) * w * h])?;
            gpu += stats.timings.total_seconds();
        }
    }
    Ok((start.elapsed().as_secs_f64(), gpu))
}

/// Wall and GPU seconds to relight every camera (balanced preset, sun at
/// azimuth 260°, elevation 50°, procedural sky: `srug relight`'s defaults) and
/// read its linear radiance into memory.
fn relight_to_memory(device: &Device, host: &Scene, scene: &GpuScene, cams: &[Camera]) -> Result<(f64, f64)> {
    let sun = Sun::from_azimuth_elevation(260.0, 50.0, [std::f32::consts::PI; 3])?;
    let prep = EnvironmentPrep::new(device)?;
    let sky =
        prep.prepare(&ProceduralSky::new(sun.direction, sun.intensity[0]).render()?, &PrepareSettings::default())?;
    let brdf = prep.brdf_table(BrdfLut::Karis, 129, 1024)?;
    let mut relighter = Relighter::new(device)?;
    relighter.set_shadow_map_reuse(true);
    let settings = RelightSettings::preset(Preset::Balanced);
    let bounds = host.bounds().ok_or_else(|| Error::invalid("scene", "is empty"))?;
    let attributes = host.attributes();
    let frames = |r: &mut Relighter, cams: &[Camera]| {
        r.render_batch(scene, &attributes, &bounds, cams, Some(&sun), &sky, &brdf, &settings)
    };
    frames(&mut relighter, &cams[..1])?;
    let (w, h) = (cams[0].width as usize, cams[0].height as usize);
    let mut radiance = vec![0.0f32; cams.len() * w * h * 3];
    // In batches, as `srug relight` and the Python package relight.
    let estimate = SplatSettings { channels: Channels::ALL, ..SplatSettings::default() };
    let batch = cameras_per_batch(scene.count as u64, &cams[0], &estimate, BATCH_BYTES);
    let (start, mut gpu) = (Instant::now(), 0.0);
    for (b, chunk) in cams.chunks(batch).enumerate() {
        for (k, relit) in frames(&mut relighter, chunk)?.into_iter().enumerate() {
            let i = b * batch + k;
            device.read_buffer_into(&relit.shaded.radiance, &mut radiance[i * w * h * 3..(i + 1) * w * h * 3])?;
            gpu += relit.timings.total_seconds();
        }
    }
    Ok((start.elapsed().as_secs_f64(), gpu))
}

/// The table.
pub fn batch_markdown(rows: &[BatchRow]) -> String {
    let mut s = String::from(
        "| cameras | render PNG fps | render EXR fps | render to memory fps | relight PNG fps | relight EXR fps | relight to memory fps | render GPU ms/frame | relight GPU ms/frame |\n|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    for r in rows {
        let f = r.fps;
        s += &format!(
            "| {} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.1} | {:.1} |\n",
            r.count, f[0], f[1], f[2], f[3], f[4], f[5], r.gpu_ms[0], r.gpu_ms[1]
        );
    }
    s
}
