//! `srug relight`: a scene relit under a sun and a sky, one frame per camera
//! and sun (a sun path gives a time-lapse); also the demo's relit street.

use std::path::{Path, PathBuf};

use indicatif::ProgressBar;
use srug::frame::{Preset, Relighter, RelitFrame};
use srug::gpu::Device;
use srug::indirect::StoragePrecision;
use srug::scene::{self, activate, Camera};
use srug::shade::{
    BrdfLut, BrdfTable, EnvironmentMap, EnvironmentPrep, PrepareSettings, PreparedEnvironment, ProceduralSky, ToneMap,
    VisibilitySource,
};
use srug::shadow::Sun;
use srug::splat::{cameras_per_batch, Channels, SplatSettings, BATCH_BYTES};
use srug::{io, Error, Result};

use crate::args::{
    numbered, output_is_exr, overlapped, print_line, progress_bar, write_all, CameraArgs, DeviceArgs, EnvArgs,
    RunOutputs, SceneOrderArgs, ShadeArgs, SunArgs, WriterArgs,
};

/// Lighting resources reused across frames.
pub(super) struct Lights {
    prep: EnvironmentPrep,
    fixed_env: Option<PreparedEnvironment>,
    /// The given map's brightest direction in the world (the map's rotation
    /// applied) and its ratio to the mean: a sun in the map.
    map_sun: Option<([f64; 3], f64)>,
    /// The BRDF table.
    pub brdf: BrdfTable,
    turbidity: f32,
}

impl Lights {
    /// Prepares (or loads) the environment and the BRDF table.
    pub(super) fn new(device: &Device, args: &EnvArgs) -> Result<Self> {
        let prep = EnvironmentPrep::new(device)?;
        let brdf = prep.brdf_table(args.brdf, 129, 1024)?;
        let mut map_sun = None;
        let fixed_env = match &args.env {
            None => None,
            Some(p) if p.is_dir() => Some(PreparedEnvironment::load(device, p)?),
            Some(p) => {
                let map = EnvironmentMap::load(p)?;
                // The map's frame turned by --env-rotation toward east (as `env_dir` in shade.glsl undoes).
                let ([x, y, z], ratio) = map.brightest();
                let (sin, cos) = f64::from(args.env_rotation).to_radians().sin_cos();
                map_sun = Some(([x * cos + y * sin, -x * sin + y * cos, z], ratio));
                Some(prep.prepare(&map, &PrepareSettings::default())?)
            }
        };
        Ok(Self { prep, fixed_env, map_sun, brdf, turbidity: args.turbidity })
    }

    /// The analytic sun placed on the map's brightest point (`--sun-from-env`).
    pub(super) fn sun_from_map(&self, intensity: f32) -> Result<(String, Sun)> {
        let (d, _) = self.map_sun.ok_or_else(|| {
            Error::invalid("--sun-from-env", "needs --env with a map file (a prepared folder keeps no map)")
        })?;
        let sun = Sun::from_direction(glam::DVec3::from_array(d).as_vec3(), [intensity; 3])?;
        let (a, e) = sun.azimuth_elevation();
        Ok((format!("sun from the map {a:.1}°, {e:.1}°"), sun))
    }

    /// A warning when the environment map holds a sun (a texel 50× the mean
    /// or more) more than 5° away from the analytic sun, which would light and
    /// shadow the scene from elsewhere than the map shows.
    pub(super) fn sun_mismatch(&self, sun: &Sun) -> Option<String> {
        let (d, ratio) = self.map_sun?;
        let s = sun.direction.as_dvec3();
        let angle = glam::DVec3::from_array(d).angle_between(s).to_degrees();
        if ratio < 50.0 || angle <= 5.0 {
            return None;
        }
        let (azimuth, elevation) =
            Sun::from_direction(glam::DVec3::from_array(d).as_vec3(), [1.0; 3]).ok()?.azimuth_elevation();
        let (sa, se) = sun.azimuth_elevation();
        Some(format!(
            "warning: the environment map's sun (brightest point, {ratio:.0}x its mean) is at azimuth {azimuth:.1}°, \
             elevation {elevation:.1}°, {angle:.0}° from the sun used ({sa:.1}°, {se:.1}°); pass --sun-azimuth {azimuth:.1} \
             --sun-elevation {elevation:.1} to light the scene as the map shows"
        ))
    }

    /// The environment for a sun: the given one, or a procedural sky made for it.
    pub(super) fn environment(&self, sun: &Sun) -> Result<EnvRef<'_>> {
        if let Some(e) = &self.fixed_env {
            return Ok(EnvRef::Given(e));
        }
        let mut sky = ProceduralSky::new(sun.direction, sun.intensity[0]);
        sky.turbidity = self.turbidity;
        let map = sky.render()?;
        Ok(EnvRef::Sky(Box::new(self.prep.prepare(&map, &PrepareSettings::default())?)))
    }
}

/// The given environment or one made for a frame.
pub(super) enum EnvRef<'a> {
    /// From `--env`.
    Given(&'a PreparedEnvironment),
    /// A procedural sky.
    Sky(Box<PreparedEnvironment>),
}

impl std::ops::Deref for EnvRef<'_> {
    type Target = PreparedEnvironment;
    fn deref(&self) -> &PreparedEnvironment {
        match self {
            Self::Given(e) => e,
            Self::Sky(e) => e,
        }
    }
}

/// Writes a relit frame: PNG of the display image, or EXR with the linear
/// radiance (R, G, B) plus L_sun, L_sky, (planar) L_ind when it was computed
/// and the sun visibility V (`visibility.Y`) when the shadow pass ran.
pub(super) fn write_relit(
    path: &Path,
    exr: bool,
    image: &srug::shade::ShadedImage,
    indirect: Option<&[f32]>,
    visibility: Option<&[f32]>,
) -> Result<()> {
    if exr {
        let n = image.width as usize * image.height as usize;
        let interleaved: Option<Vec<f32>> = indirect.map(|v| (0..3 * n).map(|i| v[(i % 3) * n + i / 3]).collect());
        let mut channels: Vec<(&str, &[f32], usize)> =
            vec![("rgb", &image.radiance, 3), ("sun", &image.sun, 3), ("sky", &image.sky, 3)];
        if let Some(ind) = &interleaved {
            channels.push(("indirect", ind, 3));
        }
        if let Some(v) = visibility {
            channels.push(("visibility", v, 1));
        }
        io::write_exr_channels(path, image.width, image.height, &channels)
    } else {
        io::write_png(path, image.width, image.height, &image.display)
    }
}

/// Arguments of `srug relight`.
#[derive(clap::Args, Clone, Debug)]
pub(super) struct RelightArgs {
    /// A scene with material attributes (albedo at least): a PLY, or any format srug reads.
    pub scene: PathBuf,
    #[command(flatten)]
    pub view: CameraArgs,
    #[command(flatten)]
    pub order: SceneOrderArgs,
    #[command(flatten)]
    pub sun: SunArgs,
    #[command(flatten)]
    pub env: EnvArgs,
    #[command(flatten)]
    pub shade: ShadeArgs,
    /// Indirect-light network weights (safetensors); without them no indirect light is computed.
    #[arg(long)]
    pub indirect: Option<PathBuf>,
    /// Activation storage of the indirect network: fp32 or fp16 [preset: fast fp16, else fp32].
    #[arg(long, value_parser = StoragePrecision::parse)]
    pub indirect_precision: Option<StoragePrecision>,
    /// Output file: .png (display image) or .exr (linear radiance, L_sun, L_sky, L_ind, sun visibility V); numbered when several frames.
    #[arg(long)]
    pub out: PathBuf,
    #[command(flatten)]
    pub writers: WriterArgs,
}

impl RelightArgs {
    /// Runs `srug relight`.
    pub(super) fn run(&self, device: &DeviceArgs) -> Result<()> {
        relight(&device.open()?, self)
    }
}

fn relight(device: &Device, args: &RelightArgs) -> Result<()> {
    let RelightArgs { scene: scene_path, view, order, sun, env, shade, indirect, indirect_precision, out, writers } =
        args;
    let writers = writers.count();
    let precision = indirect_precision.unwrap_or_else(|| shade.preset.indirect_precision());
    let exr = output_is_exr(out)?;
    let (cams, all_cameras) = view.resolve_numbered()?;
    // With --sun-from-env the sun comes from the map, once it is loaded.
    let suns = if sun.sun_from_env { Vec::new() } else { sun.resolve()? };
    let settings = shade.settings()?;
    // Straight to the device: the host never holds the whole scene.
    let activate::LoadedScene { gpu: mut gpu_scene, attributes, bounds } =
        activate::GpuScene::load(device, scene_path)?;
    if !attributes.shadeable() {
        return Err(Error::invalid(
            scene_path.display().to_string(),
            "the scene has no albedo attribute, so it cannot be relit; `srug render` renders its colour",
        ));
    }
    let bounds = bounds.ok_or_else(|| Error::invalid("scene", "is empty"))?;
    let lights = Lights::new(device, env)?;
    let suns = if sun.sun_from_env { vec![lights.sun_from_map(sun.sun_intensity)?] } else { suns };
    order.arrange(device, &mut gpu_scene, cams.len() * suns.len(), scene_path)?;
    let mut relighter = Relighter::new(device)?;
    // The scene does not change during the run: a frame under the previous frame's sun reuses its shadow map.
    relighter.set_shadow_map_reuse(true);
    if let Some(path) = indirect {
        let weights = srug::indirect::UNetWeights::load(path)?;
        relighter.set_network(Some(srug::indirect::UNet::with_precision(device, &weights, precision)?));
    }
    let mut settings = settings;
    // One camera: each sun's map serves that camera alone, so it is splatted
    // only where the camera looks (the same shadows, for less).
    settings.shadow.cull_to_receivers |= cams.len() == 1;
    settings.shade.env_rotation_degrees = env.env_rotation;
    settings.shade.env_intensity = env.env_intensity;
    let total = (cams.len() * suns.len()) as u64;
    let bar = if total > 1 {
        progress_bar(total, "{bar:40} {pos}/{len} frames [{elapsed} < {eta}] {msg}")
    } else {
        ProgressBar::hidden()
    };
    if let Some(warning) = suns.first().and_then(|(_, s)| lights.sun_mismatch(s)) {
        eprintln!("{warning}");
    }
    let mut written = RunOutputs::default();
    // Frames in sun-major order, each sun's cameras in batches (their splats
    // one submission per step); batch b + 1 renders while batch b is encoded and written.
    let largest = cams.iter().map(|(_, cam)| cam).max_by_key(|cam| u64::from(cam.width) * u64::from(cam.height));
    let estimate = SplatSettings { channels: Channels::ALL, ..SplatSettings::default() };
    let batch = largest.map_or(1, |cam| cameras_per_batch(gpu_scene.count as u64, cam, &estimate, BATCH_BYTES));
    let batches = suns.iter().enumerate().flat_map(|(si, sun)| cams.chunks(batch).map(move |c| (si, sun, c)));
    let mut environment: Option<(usize, EnvRef<'_>)> = None;
    let mut frame = 0;
    overlapped(
        batches,
        1,
        |(si, (label, s), chunk)| -> Result<Vec<_>> {
            if environment.as_ref().is_none_or(|(i, _)| *i != si) {
                environment = Some((si, lights.environment(s)?));
            }
            let env =
                environment.as_ref().map(|(_, e)| &**e).ok_or_else(|| Error::Internal("no environment".into()))?;
            let cameras: Vec<Camera> = chunk.iter().map(|(_, cam)| cam.clone()).collect();
            let relit = relighter.render_batch(
                &gpu_scene,
                &attributes,
                &bounds,
                &cameras,
                Some(s),
                env,
                &lights.brdf,
                &settings,
            )?;
            let mut outputs = Vec::with_capacity(relit.len());
            for ((number, cam), relit) in chunk.iter().zip(relit) {
                // A shard's frames keep their number in the whole run (sun-major), so shards never collide.
                let target = match view.shard {
                    Some(_) => numbered(out, si * all_cameras + number),
                    None if total > 1 => numbered(out, frame),
                    None => out.to_path_buf(),
                };
                frame += 1;
                outputs.push(relit_outputs(device, target, &relit, cam, exr, number, label)?);
            }
            Ok(outputs)
        },
        |frames| -> Result<()> {
            let results = write_all(&frames, writers, |(target, image, indirect, visibility, _)| {
                write_relit(target, exr, image, indirect.as_deref(), visibility.as_deref())
            });
            let mut first_error = None;
            // In camera order; every file written is recorded (removed if the run fails).
            for ((target, _, _, _, line), result) in frames.into_iter().zip(results) {
                if let Err(e) = result {
                    first_error.get_or_insert(e);
                    continue;
                }
                written.add(target);
                print_line(&bar, &line);
                bar.inc(1);
            }
            first_error.map_or(Ok(()), Err)
        },
    )?;
    bar.finish_and_clear();
    written.keep();
    Ok(())
}

/// What a relit frame writes (read back at the camera's size) and its progress line.
type RelitOutputs = (PathBuf, srug::shade::ShadedImage, Option<Vec<f32>>, Option<Vec<f32>>, String);

/// Reads `relit` back for writing to `target`.
fn relit_outputs(
    device: &Device,
    target: PathBuf,
    relit: &RelitFrame,
    cam: &Camera,
    exr: bool,
    number: &usize,
    label: &str,
) -> Result<RelitOutputs> {
    let image = relit.shaded.read(device)?.resampled(cam.width, cam.height)?;
    let indirect = match &relit.shaded.indirect {
        Some(b) => Some(resample_planar(&device.read_buffer::<f32>(b)?, &relit.shaded, cam)?),
        None => None,
    };
    let visibility = match (&relit.visibility, exr) {
        (Some(b), true) => {
            let v = device.read_buffer::<f32>(b)?;
            let size = (relit.shaded.width, relit.shaded.height);
            Some(srug::image::resample_bilinear(&v, size, 1, (cam.width, cam.height))?)
        }
        _ => None,
    };
    log::debug!("{}: {}; memory {:?}", target.display(), relit.timings, device.memory_usage());
    let line = format!(
        "{} camera {} {label}: {:.0} ms GPU{}",
        target.display(),
        number,
        relit.timings.total_seconds() * 1e3,
        match (relit.shadow_pass_ran, relit.shadow_map_reused) {
            (false, _) => " (no shadow pass)",
            (true, true) => " (shadow map reused)",
            (true, false) => "",
        }
    );
    Ok((target, image, indirect, visibility, line))
}

/// Planar RGB `v` of `frame`'s size resampled to the camera's size.
fn resample_planar(v: &[f32], frame: &srug::shade::ShadedFrame, cam: &Camera) -> Result<Vec<f32>> {
    let n = frame.width as usize * frame.height as usize;
    if (frame.width, frame.height) == (cam.width, cam.height) || v.len() != 3 * n {
        return Ok(v.to_vec());
    }
    let mut out = Vec::new();
    for plane in v.chunks_exact(n) {
        out.extend(srug::image::resample_bilinear(plane, (frame.width, frame.height), 1, (cam.width, cam.height))?);
    }
    Ok(out)
}

/// The demo's relit street: camera 0 under a west-south-west sun (azimuth
/// 260°, elevation 50°) that throws the off-screen tower's shadow into view,
/// with the procedural sky; writes `demo_relit.png`. Returns a summary line.
pub(crate) fn relight_demo(
    device: &Device,
    city: &scene::demo::DemoCity,
    gpu_scene: &activate::GpuScene,
    out: &Path,
) -> Result<String> {
    let sun = Sun::from_azimuth_elevation(260.0, 50.0, [std::f32::consts::PI; 3])?;
    let env = EnvArgs { env: None, env_rotation: 0.0, env_intensity: 1.0, turbidity: 3.0, brdf: BrdfLut::Karis };
    let lights = Lights::new(device, &env)?;
    let environment = lights.environment(&sun)?;
    let shade = ShadeArgs {
        preset: Preset::Balanced,
        visibility: VisibilitySource::Editable,
        exposure: 0.0,
        tone_map: ToneMap::Aces,
        background: None,
        shadow_resolution: None,
        shadow_k: None,
        shadow_bias: None,
        shadow_slope_bias: None,
        shadow_normal_offset: None,
        shadow_filter: None,
        shadow_surface_depth: None,
        shadow_map_surface_depth: None,
        shadow_map_coverage: None,
        shadow_receiver_coverage: None,
        shadow_fit: None,
        shadow_cascades: None,
        shadow_cull: false,
        receiver_depth: None,
        shadow_test: None,
        sh_degree: None,
        render_scale: None,
        tile: None,
    };
    let settings = shade.settings()?;
    let attributes = city.scene.attributes();
    let bounds = city.scene.bounds().ok_or_else(|| Error::invalid("demo scene", "is empty"))?;
    let mut relighter = Relighter::new(device)?;
    let camera = &city.cameras[0];
    let relit =
        relighter.render(gpu_scene, &attributes, &bounds, camera, Some(&sun), &environment, &lights.brdf, &settings)?;
    let image = relit.shaded.read(device)?;
    let path = out.join("demo_relit.png");
    write_relit(&path, false, &image, None, None)?;
    let stages = &relit.timings;
    Ok(format!(
        "relit street (sun azimuth 260°, elevation 50°, procedural sky, sigmoid shadow map 2048): {} ({:.0} ms GPU: {stages})",
        path.display(),
        relit.timings.total_seconds() * 1e3
    ))
}
