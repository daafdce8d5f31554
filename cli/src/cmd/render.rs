//! `srug render`: a scene into G-buffers, PNG (rgb) for viewing or a
//! multi-channel float EXR for data, one file per camera.

use std::path::PathBuf;

use indicatif::ProgressBar;
use srug::io;
use srug::scene::activate;
use srug::scene::Camera;
use srug::splat::{
    cameras_per_batch, Channels, GBuffer, NormalSource, SplatSettings, SplatStats, Splatter, TileBounds, BATCH_BYTES,
    DEFAULT_MEDIAN_COVERAGE, DEFAULT_TILE,
};
use srug::{Error, Result};

use crate::args::{
    numbered, output_is_exr, overlapped, print_line, progress_bar, write_all, CameraArgs, ChannelList, DeviceArgs,
    RunOutputs, SceneOrderArgs, Vec3Arg, WriterArgs,
};

/// Arguments of `srug render`.
#[derive(clap::Args, Clone, Debug)]
pub(super) struct RenderArgs {
    /// A scene: PLY, compressed PLY, .splat, .spz, .sog / meta.json or .glb (detected from the content).
    scene: PathBuf,
    #[command(flatten)]
    view: CameraArgs,
    #[command(flatten)]
    order: SceneOrderArgs,
    /// Output file, .png or .exr.
    #[arg(long)]
    out: PathBuf,
    /// Channels: rgb, depth, median_depth, normal, albedo, roughness, metallic, ao,
    /// visibility, materials, all, top_gaussian (the index of each pixel's Gaussian with the
    /// largest blend weight, a 32-bit integer channel), range (distance along each pixel's ray,
    /// depth × the ray's length per unit depth, as lidar measures). EXR holds those listed and alpha (rgb
    /// only if listed); PNG holds only rgb (any other channel needs an .exr output).
    #[arg(long, default_value = "rgb")]
    channels: ChannelList,
    /// Integer PLY properties to render as exact id channels (e.g. semantic,instance): each
    /// pixel holds the id of its Gaussian with the largest blend weight, 4294967295 where no
    /// Gaussian reaches it (signed ids as 32-bit two's complement, so −1 reads the same).
    /// Needs a PLY scene and an .exr output.
    #[arg(long, value_delimiter = ',')]
    ids: Vec<String>,
    /// Background colour r,g,b.
    #[arg(long, default_value = "0,0,0")]
    background: Vec3Arg,
    /// Normals from each Gaussian's stored normal where present (default: shortest axis).
    #[arg(long)]
    stored_normals: bool,
    /// Spherical-harmonic degree used for colour (default: the scene's).
    #[arg(long)]
    sh_degree: Option<u32>,
    /// Tile edge in pixels: 8, 16 or 32.
    #[arg(long, default_value_t = DEFAULT_TILE)]
    tile: u32,
    /// Which tiles list a splat: ellipse (those that can see it at α ≥ 1/255) or rectangle
    /// (its 3σ square, as INRIA's rasterizer); the image is the same, ellipse sorts and blends less.
    #[arg(long, default_value = "ellipse")]
    tile_bounds: TileBounds,
    /// Depths where each pixel's ray meets the splat's plane (its shortest axis)
    /// rather than at the splat's centre (pinhole cameras; docs/stages.md).
    #[arg(long)]
    surface_depth: bool,
    /// Coverage 1 − T at which the median_depth channel reads a pixel's depth,
    /// strictly between 0 and 1 (0.5: the median).
    #[arg(long, default_value_t = DEFAULT_MEDIAN_COVERAGE)]
    median_coverage: f32,
    #[command(flatten)]
    writers: WriterArgs,
}

impl RenderArgs {
    /// Runs `srug render`.
    pub(super) fn run(&self, device_args: &DeviceArgs) -> Result<()> {
        let Self {
            scene: path,
            view,
            order,
            out,
            channels,
            ids,
            background,
            stored_normals,
            sh_degree,
            tile,
            tile_bounds,
            surface_depth,
            median_coverage,
            writers,
        } = self;
        let is_exr = output_is_exr(out)?;
        if !ids.is_empty() && !is_exr {
            return Err(Error::invalid(
                format!("--ids {}", ids.join(",")),
                format!("needs an .exr output; {} can hold only the colour", out.display()),
            ));
        }
        // A PNG is the colour; an EXR holds what was asked for.
        if !is_exr && channels.channels != Channels::default() {
            let names: Vec<&str> = channels.channels.iter().map(|c| c.name()).collect();
            return Err(Error::invalid(
                format!("--channels {}", names.join(",")),
                format!("needs an .exr output; {} can hold only the colour", out.display()),
            ));
        }
        let rgb = !is_exr || channels.names_rgb;
        let (cams, _) = view.resolve_numbered()?;
        let numbered_outputs = view.numbers_outputs(cams.len());
        let id_values = if ids.is_empty() { Vec::new() } else { io::read_ply_ids(path, ids)? };
        let id_channels: Vec<(&str, &[u32])> =
            ids.iter().map(String::as_str).zip(id_values.iter().map(Vec::as_slice)).collect();
        let mut channel_set = channels.channels;
        channel_set.top_gaussian |= !ids.is_empty();
        let device = device_args.open()?;
        // Straight to the device: the host never holds the whole scene.
        let mut gpu_scene = activate::GpuScene::load(&device, path)?.gpu;
        order.arrange(&device, &mut gpu_scene, cams.len(), path)?;
        let mut splatter = Splatter::new(&device)?;
        let settings = SplatSettings {
            background: background.0.to_array(),
            channels: channel_set,
            normal_source: if *stored_normals { NormalSource::Stored } else { NormalSource::ShortestAxis },
            prefill: None,
            sh_degree: *sh_degree,
            tile: *tile,
            tile_bounds: *tile_bounds,
            rgb,
            surface_depth: *surface_depth,
            median_coverage: *median_coverage,
            // Feature channels go to the user's files as floats.
            packed_features: false,
            compact_splats: false,
        };
        let bar = if cams.len() > 1 {
            progress_bar(cams.len() as u64, "{bar:40} {pos}/{len} cameras [{elapsed} < {eta}]")
        } else {
            ProgressBar::hidden()
        };
        let mut written = RunOutputs::default();
        let writers = writers.count();
        let encode = |(target, g, _, cam): &(PathBuf, GBuffer, SplatStats, &Camera)| -> Result<()> {
            if is_exr {
                let range = if channels.range { g.ray_distance(cam) } else { None };
                let extra: Vec<(&str, &[f32], usize)> = range.as_deref().map(|r| ("range", r, 1)).into_iter().collect();
                g.write_exr_with(target, &extra, &id_channels)
            } else {
                io::write_png(target, g.width, g.height, g.rgb_values()?)
            }
        };
        // Cameras in batches (one submission per step for the batch); batch
        // k + 1 splats while batch k is encoded and written.
        let largest = cams.iter().map(|(_, cam)| cam).max_by_key(|cam| u64::from(cam.width) * u64::from(cam.height));
        let batch = largest.map_or(1, |cam| cameras_per_batch(gpu_scene.count as u64, cam, &settings, BATCH_BYTES));
        overlapped(
            cams.chunks(batch),
            1,
            |chunk| -> Result<Vec<_>> {
                let cameras: Vec<_> = chunk.iter().map(|(_, cam)| cam.clone()).collect();
                let frames = splatter.render_batch(&gpu_scene, &cameras, &settings)?;
                let mut read = Vec::with_capacity(frames.len());
                for ((number, cam), (gpu, stats)) in chunk.iter().zip(frames) {
                    let target = if numbered_outputs { numbered(out, *number) } else { out.clone() };
                    read.push((target, gpu.read(&device)?, stats, cam));
                }
                Ok(read)
            },
            |frames| -> Result<()> {
                let results = write_all(&frames, writers, encode);
                let mut first_error = None;
                // In camera order; every file written is recorded (removed if the run fails).
                for ((target, g, stats, _), result) in frames.into_iter().zip(results) {
                    if let Err(e) = result {
                        first_error.get_or_insert(e);
                        continue;
                    }
                    let ms = stats.timings.total_seconds() * 1e3;
                    let line = format!("{} ({}x{}, {ms:.1} ms GPU)", target.display(), g.width, g.height);
                    log::debug!("{}: {}", target.display(), stats.timings);
                    written.add(target);
                    bar.inc(1);
                    print_line(&bar, &line);
                }
                first_error.map_or(Ok(()), Err)
            },
        )?;
        bar.finish_and_clear();
        written.keep();
        Ok(())
    }
}
