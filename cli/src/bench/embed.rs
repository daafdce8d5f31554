//! What rendering into a host's own images saves: per relit frame, the
//! shared-device path (`Relighter::render_to_host`: the frame packed and copied
//! into the host's image on the GPU) against the host-copy path a host had
//! before (render, read the display values and alpha into host memory and pack
//! RGBA8 there as `srug_renderer_read_image` does, upload the bytes into its
//! image through a staging buffer). Wall clock per frame, median of the
//! frames, with the GPU time of the pack and copy and the CPU time of the
//! read-back and upload beside it; the sun stays, so the shadow map is reused.
//! Composited frames go over a host depth of a wall 10 m away across the
//! left half of the frame (nothing on the right), restored before each.
//! The images are made on srug's own device ([`Device::create_image`]).

use std::time::Instant;

use srug::frame::host_images::HostTargets;
use srug::frame::{Preset, RelightSettings, Relighter};
use srug::gpu::ash::vk;
use srug::gpu::{Device, DeviceImage, HostImageFormat, HostSync};
use srug::scene::activate::GpuScene;
use srug::scene::demo::{demo_city, DemoOptions};
use srug::shade::{BrdfLut, EnvironmentPrep, PrepareSettings, ProceduralSky};
use srug::shadow::Sun;
use srug::splat::HostDepth;
use srug::{Error, Result};

/// What the benchmark runs.
#[derive(Clone, Debug)]
pub struct EmbedSetup {
    /// Gaussians of the demo city.
    pub gaussians: usize,
    /// Its SH degree.
    pub sh_degree: u32,
    /// Image sizes.
    pub sizes: Vec<(u32, u32)>,
    /// Frames measured per path (after one warm-up frame).
    pub frames: usize,
    /// Surface depths for the frames and their shadows (`None`: the preset's).
    pub surface_depth: Option<bool>,
}

/// One size's row: median milliseconds per frame.
#[derive(Clone, Debug)]
pub struct EmbedRow {
    /// Image size.
    pub size: (u32, u32),
    /// Shared device, RGBA8 image written.
    pub shared_ms: f64,
    /// Its GPU pack and copy ("host images write" stage).
    pub shared_write_ms: f64,
    /// Shared device, RGBA8 + D32 images read, composited and written.
    pub composited_ms: f64,
    /// Host copy: render, read back, pack, upload.
    pub copy_ms: f64,
    /// Its read-back, CPU pack and upload (wall clock).
    pub copy_transfer_ms: f64,
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

/// Runs the benchmark; `progress` gets a line per size.
pub fn embed_bench(device: &Device, setup: &EmbedSetup, mut progress: impl FnMut(&str)) -> Result<Vec<EmbedRow>> {
    let city =
        demo_city(&DemoOptions { gaussians: setup.gaussians, sh_degree: setup.sh_degree, ..Default::default() })?;
    let scene = GpuScene::upload(device, &city.scene)?;
    let bounds = city.scene.bounds().ok_or_else(|| Error::invalid("scene", "is empty"))?;
    let attributes = city.scene.attributes();
    let sun = Sun::from_azimuth_elevation(260.0, 50.0, [std::f32::consts::PI; 3])?;
    let prep = EnvironmentPrep::new(device)?;
    let sky =
        prep.prepare(&ProceduralSky::new(sun.direction, sun.intensity[0]).render()?, &PrepareSettings::default())?;
    let brdf = prep.brdf_table(BrdfLut::Karis, 129, 1024)?;
    let mut settings = RelightSettings::preset(Preset::Balanced);
    settings.shadow.surface_depth = setup.surface_depth.unwrap_or(settings.shadow.surface_depth);
    let mut relighter = Relighter::new(device)?;
    relighter.set_shadow_map_reuse(true);
    let mut rows = Vec::new();
    for &size in &setup.sizes {
        progress(&format!("{}x{}", size.0, size.1));
        let camera = city.cameras.first().ok_or_else(|| Error::Internal("the demo has no camera".into()))?;
        let camera = camera.resized(size.0, size.1);
        let transfer = vk::ImageUsageFlags::TRANSFER_SRC | vk::ImageUsageFlags::TRANSFER_DST;
        let colour = device.create_image("host colour", HostImageFormat::Rgba8Srgb, size, transfer)?;
        let depth = device.create_image("host depth", HostImageFormat::D32Float, size, transfer)?;
        let stated = |image: &DeviceImage, before| image.host_image(before, vk::ImageLayout::TRANSFER_SRC_OPTIMAL);
        let undefined = vk::ImageLayout::UNDEFINED;
        let write_only = HostTargets {
            colour: Some(stated(&colour, undefined)),
            depth: None,
            depth_convention: HostDepth::Vulkan { near: 0.1, far: 500.0 },
            composite: false,
            buffers: Vec::new(),
            sync: HostSync::default(),
        };
        let kept = vk::ImageLayout::TRANSFER_SRC_OPTIMAL;
        let composited = HostTargets {
            colour: Some(stated(&colour, kept)),
            depth: Some(stated(&depth, kept)),
            composite: true,
            ..write_only.clone()
        };
        let mut shared = |targets: &HostTargets| -> Result<(f64, f64)> {
            let start = Instant::now();
            let frame = relighter.render_to_host(
                &scene,
                &attributes,
                &bounds,
                &camera,
                Some(&sun),
                &sky,
                &brdf,
                &settings,
                targets,
            )?;
            Ok((start.elapsed().as_secs_f64(), frame.timings.get("host images write").unwrap_or(f64::NAN)))
        };
        // The host's mesh for the composited frames: a wall 10 m away over
        // the left half of the frame, nothing on the right (Vulkan depth, 0.1 to 500 m).
        let (near, far) = (0.1f64, 500.0f64);
        let wall = (far * (10.0 - near) / (10.0 * (far - near))) as f32;
        let (w, h) = (size.0 as usize, size.1 as usize);
        let mesh: Vec<f32> = (0..w * h).map(|p| if p % w < w / 2 { wall } else { 1.0 }).collect();
        let mesh = device.upload("host mesh depth", &mesh)?;
        let reset = stated(&depth, undefined);
        // Warm-up (the map, kernels), then the frames; before each composited
        // one (untimed) the mesh's depth goes back into the depth image.
        shared(&write_only)?;
        let mut s = Vec::new();
        let mut s_write = Vec::new();
        let mut c = Vec::new();
        for _ in 0..setup.frames {
            let (t, w) = shared(&write_only)?;
            s.push(t);
            s_write.push(w);
            device.run(|rec| rec.copy_buffer_to_host_image(&mesh, &reset, undefined))?;
            c.push(shared(&composited)?.0);
        }
        let image = stated(&colour, undefined);
        let copy = |r: &mut Relighter| -> Result<(f64, f64)> {
            let start = Instant::now();
            let frame = r.render(&scene, &attributes, &bounds, &camera, Some(&sun), &sky, &brdf, &settings)?;
            let rendered = Instant::now();
            let display: Vec<f32> = device.read_buffer(&frame.shaded.display)?;
            let alpha: Vec<f32> = device.read_buffer(&frame.gbuffer.alpha)?;
            let bytes: Vec<u8> = display
                .chunks_exact(3)
                .zip(&alpha)
                .flat_map(|(c, a)| [c[0], c[1], c[2], *a].map(srug::io::display_byte))
                .collect();
            let staging = device.upload("host staging", &bytes)?;
            device.run(|rec| rec.copy_buffer_to_host_image(&staging, &image, vk::ImageLayout::UNDEFINED))?;
            Ok((start.elapsed().as_secs_f64(), rendered.elapsed().as_secs_f64()))
        };
        copy(&mut relighter)?;
        let mut k = Vec::new();
        let mut k_transfer = Vec::new();
        for _ in 0..setup.frames {
            let (t, x) = copy(&mut relighter)?;
            k.push(t);
            k_transfer.push(x);
        }
        rows.push(EmbedRow {
            size,
            shared_ms: median(s) * 1e3,
            shared_write_ms: median(s_write) * 1e3,
            composited_ms: median(c) * 1e3,
            copy_ms: median(k) * 1e3,
            copy_transfer_ms: median(k_transfer) * 1e3,
        });
    }
    Ok(rows)
}

/// The table.
pub fn embed_markdown(rows: &[EmbedRow]) -> String {
    let mut s = String::from(
        "| size | shared device ms/frame | its GPU pack + copy ms | shared, composited over colour + depth ms/frame | host copy ms/frame | its read-back + pack + upload ms |\n|---|---:|---:|---:|---:|---:|\n",
    );
    for r in rows {
        s += &format!(
            "| {}x{} | {:.1} | {:.2} | {:.1} | {:.1} | {:.1} |\n",
            r.size.0, r.size.1, r.shared_ms, r.shared_write_ms, r.composited_ms, r.copy_ms, r.copy_transfer_ms
        );
    }
    s
}
