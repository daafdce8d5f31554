//! `srug relight` and `srug prefilter`: the command-line side of relighting
//! (argument groups shared with `srug render`).

use std::path::{Path, PathBuf};

use indicatif::{ProgressBar, ProgressStyle};
use srug::gpu::Device;
use srug::scene::{self, activate, Camera};
use srug::shade::relight::{Preset, RelightSettings, Relighter};
use srug::shade::{
    Background, BrdfLut, BrdfTable, EnvironmentMap, EnvironmentPrep, PrepareSettings, PreparedEnvironment,
    ProceduralSky, ShadeSettings, ToneMap, VisibilitySource,
};
use srug::shadow::{sun_path, Sun, UtcTime, VisibilityKind};
use srug::{output, Error, Result};

/// Which cameras to render.
#[derive(clap::Args, Clone, Debug)]
pub struct CameraArgs {
    /// INRIA cameras.json; without it, the look-at options define one camera.
    #[arg(long)]
    pub cameras: Option<PathBuf>,
    /// Render only this camera (default: every camera, numbered outputs).
    #[arg(long)]
    pub index: Option<usize>,
    /// Output size WxH (intrinsics scaled to match); required with look-at cameras.
    #[arg(long)]
    pub size: Option<String>,
    /// Look-at camera: eye position x,y,z.
    #[arg(long, allow_hyphen_values = true)]
    pub eye: Option<String>,
    /// Look-at camera: target x,y,z.
    #[arg(long, default_value = "0,0,0", allow_hyphen_values = true)]
    pub target: String,
    /// Look-at camera: up vector x,y,z.
    #[arg(long, default_value = "0,0,1", allow_hyphen_values = true)]
    pub up: String,
    /// Look-at camera: horizontal field of view in degrees.
    #[arg(long, default_value_t = 60.0)]
    pub fov: f32,
}

impl CameraArgs {
    /// The cameras selected, resized to `--size` when given.
    pub fn resolve(&self) -> Result<Vec<Camera>> {
        let size = self.size.as_deref().map(crate::parse_size).transpose()?;
        let mut cams = match (&self.cameras, &self.eye) {
            (Some(c), _) => scene::read_cameras_json(c)?,
            (None, Some(eye)) => {
                let (w, h) = size.ok_or_else(|| Error::InvalidArgument("--size is required with --eye".into()))?;
                let (eye, target, up) =
                    (crate::parse_vec3(eye)?, crate::parse_vec3(&self.target)?, crate::parse_vec3(&self.up)?);
                vec![Camera::look_at(eye, target, up, self.fov, w, h)?]
            }
            (None, None) => return Err(Error::InvalidArgument("give --cameras or --eye".into())),
        };
        if let Some(i) = self.index {
            let n = cams.len();
            cams = vec![cams
                .into_iter()
                .nth(i)
                .ok_or_else(|| Error::InvalidArgument(format!("--index {i}: there are {n} cameras")))?];
        }
        if let (Some((w, h)), Some(_)) = (size, &self.cameras) {
            for c in &mut cams {
                *c = c.resized(w, h);
            }
        }
        Ok(cams)
    }
}

/// Where the sun is.
#[derive(clap::Args, Clone, Debug)]
pub struct SunArgs {
    /// Sun azimuth, degrees from north toward east.
    #[arg(long, default_value_t = 260.0, allow_negative_numbers = true)]
    pub sun_azimuth: f32,
    /// Sun elevation, degrees (at or below 0: no sun light, no shadow pass).
    #[arg(long, default_value_t = 50.0, allow_negative_numbers = true)]
    pub sun_elevation: f32,
    /// Sun irradiance S_i (π: a white Lambertian surface facing the sun has radiance 1).
    #[arg(long, default_value_t = std::f32::consts::PI)]
    pub sun_intensity: f32,
    /// Sun from a time instead (ISO 8601 with a zone, e.g. 2024-06-21T14:30+02:00); needs --latitude, --longitude.
    #[arg(long)]
    pub sun_time: Option<String>,
    /// Time-lapse: START..END (ISO 8601 times) rendered as --frames frames; needs --latitude, --longitude.
    #[arg(long)]
    pub sun_path: Option<String>,
    /// Frames of the time-lapse.
    #[arg(long, default_value_t = 12)]
    pub frames: u32,
    /// Latitude in degrees (north positive), for --sun-time and --sun-path.
    #[arg(long, allow_negative_numbers = true)]
    pub latitude: Option<f64>,
    /// Longitude in degrees (east positive), for --sun-time and --sun-path.
    #[arg(long, allow_negative_numbers = true)]
    pub longitude: Option<f64>,
}

fn format_time(t: &UtcTime) -> String {
    let s = t.seconds.round() as u64;
    format!("{}-{:02}-{:02}T{:02}:{:02}Z", t.year, t.month, t.day, s / 3600, (s / 60) % 60)
}

impl SunArgs {
    /// The suns of every frame, with a label for each.
    pub fn resolve(&self) -> Result<Vec<(String, Sun)>> {
        let intensity = [self.sun_intensity; 3];
        let place = || match (self.latitude, self.longitude) {
            (Some(a), Some(o)) => Ok((a, o)),
            _ => Err(Error::InvalidArgument("--sun-time and --sun-path need --latitude and --longitude".into())),
        };
        if let Some(path) = &self.sun_path {
            let (a, b) = path
                .split_once("..")
                .ok_or_else(|| Error::InvalidArgument(format!("--sun-path \"{path}\" is not START..END")))?;
            let (lat, lon) = place()?;
            let frames = sun_path(&UtcTime::parse(a)?, &UtcTime::parse(b)?, self.frames, lat, lon)?;
            return frames
                .iter()
                .map(|(t, p)| {
                    let sun = Sun::from_azimuth_elevation(p.azimuth as f32, p.elevation as f32, intensity)?;
                    Ok((format!("{} (sun {:.1}°, {:.1}°)", format_time(t), p.azimuth, p.elevation), sun))
                })
                .collect();
        }
        if let Some(time) = &self.sun_time {
            let (lat, lon) = place()?;
            let t = UtcTime::parse(time)?;
            let p = srug::shadow::solar_position(&t, lat, lon)?;
            let sun = Sun::from_azimuth_elevation(p.azimuth as f32, p.elevation as f32, intensity)?;
            return Ok(vec![(format!("{} (sun {:.1}°, {:.1}°)", format_time(&t), p.azimuth, p.elevation), sun)]);
        }
        let sun = Sun::from_azimuth_elevation(self.sun_azimuth, self.sun_elevation, intensity)?;
        Ok(vec![(format!("sun {:.1}°, {:.1}°", self.sun_azimuth, self.sun_elevation), sun)])
    }
}

/// The sky.
#[derive(clap::Args, Clone, Debug)]
pub struct EnvArgs {
    /// Environment: .exr, .hdr or .ktx2 file, or a folder from `srug prefilter`
    /// (default: a procedural clear sky for the sun).
    #[arg(long)]
    pub env: Option<PathBuf>,
    /// Environment rotation about the up axis, degrees toward east.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub env_rotation: f32,
    /// Environment radiance scale.
    #[arg(long, default_value_t = 1.0)]
    pub env_intensity: f32,
    /// Turbidity of the procedural sky (2 clear … 10 hazy).
    #[arg(long, default_value_t = 3.0)]
    pub turbidity: f32,
    /// Environment BRDF table: karis or height-correlated.
    #[arg(long, default_value = "karis")]
    pub brdf: String,
}

/// Lighting resources reused across frames.
pub struct Lights {
    prep: EnvironmentPrep,
    fixed_env: Option<PreparedEnvironment>,
    /// The BRDF table.
    pub brdf: BrdfTable,
    turbidity: f32,
}

impl Lights {
    /// Prepares (or loads) the environment and the BRDF table.
    pub fn new(device: &Device, args: &EnvArgs) -> Result<Self> {
        let prep = EnvironmentPrep::new(device)?;
        let variant = BrdfLut::parse(&args.brdf)?;
        let brdf = prep.brdf_table(variant, 129, 1024)?;
        let fixed_env = match &args.env {
            None => None,
            Some(p) if p.is_dir() => Some(PreparedEnvironment::load(device, p)?),
            Some(p) => Some(prep.prepare(&EnvironmentMap::load(p)?, &PrepareSettings::default())?),
        };
        Ok(Self { prep, fixed_env, brdf, turbidity: args.turbidity })
    }

    /// The environment for a sun: the given one, or a procedural sky made for it.
    pub fn environment(&self, sun: &Sun) -> Result<EnvRef<'_>> {
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
pub enum EnvRef<'a> {
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

/// Shading options. Quality knobs default to the preset's values; explicit
/// options override them.
#[derive(clap::Args, Clone, Debug)]
pub struct ShadeArgs {
    /// Quality preset: fast, balanced or reference (`srug bench trade` measures them).
    #[arg(long, default_value = "balanced")]
    pub preset: String,
    /// Sun visibility: editable (shadow map), fixed (the Gaussians' V_f) or none.
    #[arg(long, default_value = "editable")]
    pub visibility: String,
    /// Exposure in stops.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub exposure: f32,
    /// Tone map: clamp, reinhard or aces.
    #[arg(long, default_value = "aces")]
    pub tone_map: String,
    /// Background r,g,b instead of the environment.
    #[arg(long)]
    pub background: Option<String>,
    /// Shadow-map resolution [preset: fast 512, balanced 2048, reference 4096].
    #[arg(long)]
    pub shadow_resolution: Option<u32>,
    /// Sigmoid sharpness k per metre [preset: 50].
    #[arg(long)]
    pub shadow_k: Option<f32>,
    /// Shadow depth bias, metres; at least the splats' extent along the light, or lit
    /// surfaces shadow themselves [preset: 0.5, which suits the demo city].
    #[arg(long, allow_negative_numbers = true)]
    pub shadow_bias: Option<f32>,
    /// Receiver depth for the shadow test: median or expected [preset: median].
    #[arg(long)]
    pub receiver_depth: Option<String>,
    /// Shadow test: sigmoid (differentiable) or traced (exact transmittance)
    /// [preset: reference traced, else sigmoid].
    #[arg(long)]
    pub shadow_test: Option<String>,
    /// Spherical-harmonic degree used for colour [preset: fast 0, else the scene's].
    #[arg(long)]
    pub sh_degree: Option<u32>,
    /// Render at this fraction of the output size, then upsample bilinearly
    /// [preset: fast 0.5, else 1].
    #[arg(long)]
    pub render_scale: Option<f32>,
    /// Tile edge in pixels for the camera's and the shadow map's splatting: 8, 16 or 32 [preset: 16].
    #[arg(long)]
    pub tile: Option<u32>,
}

impl ShadeArgs {
    /// The preset named by `--preset`.
    pub fn preset(&self) -> Result<Preset> {
        Preset::parse(&self.preset)
    }

    /// The relighting settings: the preset's, with the options given on top.
    pub fn settings(&self) -> Result<RelightSettings> {
        let mut s = RelightSettings::preset(self.preset()?);
        s.shade = ShadeSettings {
            visibility: VisibilitySource::parse(&self.visibility)?,
            exposure_ev: self.exposure,
            tone_map: ToneMap::parse(&self.tone_map)?,
            background: match &self.background {
                Some(b) => Background::Color(crate::parse_vec3(b)?.to_array()),
                None => Background::Environment,
            },
            ..ShadeSettings::default()
        };
        let sh = &mut s.shadow;
        sh.resolution = self.shadow_resolution.unwrap_or(sh.resolution);
        sh.k = self.shadow_k.unwrap_or(sh.k);
        sh.bias = self.shadow_bias.unwrap_or(sh.bias);
        if let Some(d) = &self.receiver_depth {
            sh.receiver_depth = srug::shadow::DepthMode::parse(d)?;
        }
        if let Some(t) = &self.shadow_test {
            s.visibility_kind = match t.as_str() {
                "sigmoid" => VisibilityKind::Sigmoid,
                "traced" => VisibilityKind::Traced,
                other => {
                    return Err(Error::InvalidArgument(format!("--shadow-test \"{other}\" is not sigmoid or traced")))
                }
            };
        }
        if self.sh_degree.is_some() {
            s.sh_degree = self.sh_degree;
        }
        s.render_scale = self.render_scale.unwrap_or(s.render_scale);
        if let Some(tile) = self.tile {
            s.tile = tile;
            s.shadow.tile = tile;
        }
        s.validate()?;
        Ok(s)
    }
}

/// Output kind from the file name (`.png` or `.exr`); creates the output's folder.
pub fn output_is_exr(out: &Path) -> Result<bool> {
    if let Some(parent) = out.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent).map_err(Error::io(parent))?;
    }
    match out.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref() {
        Some("png") => Ok(false),
        Some("exr") => Ok(true),
        _ => Err(Error::InvalidArgument(format!("{}: the output must end in .png or .exr", out.display()))),
    }
}

/// Writes a relit frame: PNG of the display image, or EXR with the linear
/// radiance (R, G, B) plus L_sun, L_sky and (planar) L_ind when it was computed.
pub fn write_relit(path: &Path, exr: bool, image: &srug::shade::ShadedImage, indirect: Option<&[f32]>) -> Result<()> {
    if exr {
        let n = image.width as usize * image.height as usize;
        let interleaved: Option<Vec<f32>> = indirect.map(|v| (0..3 * n).map(|i| v[(i % 3) * n + i / 3]).collect());
        let mut channels: Vec<(&str, &[f32], usize)> =
            vec![("rgb", &image.radiance, 3), ("sun", &image.sun, 3), ("sky", &image.sky, 3)];
        if let Some(ind) = &interleaved {
            channels.push(("indirect", ind, 3));
        }
        output::write_exr_channels(path, image.width, image.height, &channels)
    } else {
        output::write_png(path, image.width, image.height, &image.display)
    }
}

/// Arguments of `srug relight`.
#[derive(clap::Args, Clone, Debug)]
pub struct RelightArgs {
    /// A 3DGS PLY file with material attributes (albedo at least).
    pub scene: PathBuf,
    #[command(flatten)]
    pub view: CameraArgs,
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
    #[arg(long)]
    pub indirect_precision: Option<String>,
    /// Output file: .png (display image) or .exr (linear radiance, L_sun, L_sky, L_ind); numbered when several frames.
    #[arg(long)]
    pub out: PathBuf,
}

/// `srug relight`.
pub fn relight(device: &Device, args: &RelightArgs) -> Result<()> {
    let RelightArgs { scene: scene_path, view, sun, env, shade, indirect, indirect_precision, out } = args;
    let precision = match indirect_precision {
        Some(p) => srug::indirect::StoragePrecision::parse(p)?,
        None => shade.preset()?.indirect_precision(),
    };
    let exr = output_is_exr(out)?;
    let cams = view.resolve()?;
    let suns = sun.resolve()?;
    let settings = shade.settings()?;
    let scene = scene::read_ply(scene_path)?;
    let attributes = scene.attributes();
    if !attributes.shadeable() {
        return Err(Error::InvalidArgument(format!(
            "{}: the scene has no albedo attribute, so it cannot be relit; `srug render` renders its colour",
            scene_path.display()
        )));
    }
    let bounds = scene.bounds().ok_or_else(|| Error::InvalidArgument("the scene is empty".into()))?;
    let gpu_scene = activate::GpuScene::upload(device, &scene)?;
    let lights = Lights::new(device, env)?;
    let mut relighter = Relighter::new(device)?;
    // The scene does not change during the run: a frame under the previous frame's sun reuses its shadow map.
    relighter.set_shadow_map_reuse(true);
    if let Some(path) = indirect {
        let weights = srug::indirect::UNetWeights::load(path)?;
        relighter.set_network(Some(srug::indirect::UNet::with_precision(device, &weights, precision)?));
    }
    let mut settings = settings;
    settings.shade.env_rotation_degrees = env.env_rotation;
    settings.shade.env_intensity = env.env_intensity;
    let total = (cams.len() * suns.len()) as u64;
    let bar = if total > 1 { ProgressBar::new(total) } else { ProgressBar::hidden() };
    bar.set_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} frames [{elapsed} < {eta}] {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let mut frame = 0;
    for (label, s) in &suns {
        let environment = lights.environment(s)?;
        for (ci, cam) in cams.iter().enumerate() {
            let target = if total > 1 { crate::numbered(out, frame) } else { out.to_path_buf() };
            let relit = relighter.render(
                &gpu_scene,
                &attributes,
                &bounds,
                cam,
                Some(s),
                &environment,
                &lights.brdf,
                &settings,
            )?;
            let image = relit.shaded.read(device)?.resampled(cam.width, cam.height)?;
            let indirect = match &relit.shaded.indirect {
                Some(b) => Some(resample_planar(&device.read_buffer::<f32>(b)?, &relit.shaded, cam)?),
                None => None,
            };
            write_relit(&target, exr, &image, indirect.as_deref())?;
            let line = format!(
                "{} camera {} {label}: {:.0} ms GPU{}",
                target.display(),
                view.index.unwrap_or(ci),
                relit.timings.total_seconds() * 1e3,
                match (relit.shadow_pass_ran, relit.shadow_map_reused) {
                    (false, _) => " (no shadow pass)",
                    (true, true) => " (shadow map reused)",
                    (true, false) => "",
                }
            );
            if bar.is_hidden() {
                println!("{line}");
            } else {
                bar.println(line);
            }
            bar.inc(1);
            frame += 1;
        }
    }
    bar.finish_and_clear();
    Ok(())
}

/// Planar RGB `v` of `frame`'s size resampled to the camera's size.
fn resample_planar(v: &[f32], frame: &srug::shade::ShadedFrame, cam: &Camera) -> Result<Vec<f32>> {
    let n = frame.width as usize * frame.height as usize;
    if (frame.width, frame.height) == (cam.width, cam.height) || v.len() != 3 * n {
        return Ok(v.to_vec());
    }
    let mut out = Vec::new();
    for plane in v.chunks_exact(n) {
        out.extend(output::resample_bilinear(plane, (frame.width, frame.height), 1, (cam.width, cam.height))?);
    }
    Ok(out)
}

/// `srug prefilter`: prepares an environment once and saves it as KTX2.
pub fn prefilter(device: &Device, env: &Path, out: &Path, settings: &PrepareSettings, zstd: bool) -> Result<()> {
    let map = EnvironmentMap::load(env)?;
    let prep = EnvironmentPrep::new(device)?;
    let prepared = prep.prepare(&map, settings)?;
    prepared.save(device, out, zstd)?;
    println!(
        "{}: {}x{}, {} levels, {} samples: {:.0} ms GPU ({}); written to {}",
        env.display(),
        map.width,
        map.height,
        prepared.levels,
        settings.samples,
        prepared.timings.total_seconds() * 1e3,
        prepared
            .timings
            .stages
            .iter()
            .map(|s| format!("{} {:.1} ms", s.name, s.seconds * 1e3))
            .collect::<Vec<_>>()
            .join(", "),
        out.display()
    );
    Ok(())
}

/// The demo's relit street: camera 0 under a west-south-west sun (azimuth
/// 260°, elevation 50°) that throws the off-screen tower's shadow into view,
/// with the procedural sky; writes `demo_relit.png`. Returns a summary line.
pub fn relight_demo(
    device: &Device,
    city: &scene::demo::DemoCity,
    gpu_scene: &activate::GpuScene,
    out: &Path,
) -> Result<String> {
    let sun = Sun::from_azimuth_elevation(260.0, 50.0, [std::f32::consts::PI; 3])?;
    let env = EnvArgs { env: None, env_rotation: 0.0, env_intensity: 1.0, turbidity: 3.0, brdf: "karis".into() };
    let lights = Lights::new(device, &env)?;
    let environment = lights.environment(&sun)?;
    let shade = ShadeArgs {
        preset: "balanced".into(),
        visibility: "editable".into(),
        exposure: 0.0,
        tone_map: "aces".into(),
        background: None,
        shadow_resolution: None,
        shadow_k: None,
        shadow_bias: None,
        receiver_depth: None,
        shadow_test: None,
        sh_degree: None,
        render_scale: None,
        tile: None,
    };
    let settings = shade.settings()?;
    let attributes = city.scene.attributes();
    let bounds = city.scene.bounds().ok_or_else(|| Error::InvalidArgument("the demo is empty".into()))?;
    let mut relighter = Relighter::new(device)?;
    let camera = &city.cameras[0];
    let relit =
        relighter.render(gpu_scene, &attributes, &bounds, camera, Some(&sun), &environment, &lights.brdf, &settings)?;
    let image = relit.shaded.read(device)?;
    let path = out.join("demo_relit.png");
    write_relit(&path, false, &image, None)?;
    let stages = relit
        .timings
        .stages
        .iter()
        .map(|s| format!("{} {:.1} ms", s.name, s.seconds * 1e3))
        .collect::<Vec<_>>()
        .join(", ");
    Ok(format!(
        "relit street (sun azimuth 260°, elevation 50°, procedural sky, sigmoid shadow map 2048): {} ({:.0} ms GPU: {stages})",
        path.display(),
        relit.timings.total_seconds() * 1e3
    ))
}
