//! Argument types and groups shared by several subcommands. Every value is
//! parsed by clap through a typed parser (`FromStr` or an engine `parse`), so a
//! bad value is refused before anything runs, with clap's usage message.

use std::path::{Path, PathBuf};
use std::str::FromStr;

use srug::frame::{Preset, RelightSettings};
use srug::gpu::{Device, DeviceOptions, DeviceSelection};
use srug::io;
use srug::scene::activate::GpuScene;
use srug::scene::order::SceneOrder;
use srug::scene::Camera;
use srug::shade::{Background, BrdfLut, ShadeSettings, ToneMap, VisibilitySource};
use srug::shadow::{sun_path, DepthMode, ShadowFilter, ShadowFit, Sun, UtcTime, VisibilityKind};
use srug::splat::Channels;
use srug::{Error, Result};

/// The options every subcommand takes: which device, and validation.
#[derive(clap::Args, Clone, Debug)]
pub struct DeviceArgs {
    /// Device: an index from `srug devices`, `gpu`, `cpu`, or part of a name (default: SRUG_DEVICE, else automatic).
    #[arg(long, global = true, value_parser = parse_selection)]
    pub device: Option<DeviceSelection>,
    /// Run the Khronos validation layer (also SRUG_VALIDATION=1).
    #[arg(long, global = true)]
    pub validation: bool,
}

fn parse_selection(text: &str) -> std::result::Result<DeviceSelection, std::convert::Infallible> {
    Ok(DeviceSelection::parse(text))
}

impl DeviceArgs {
    /// Opens the chosen device.
    pub fn open(&self) -> Result<Device> {
        Ok(Device::new(&DeviceOptions { selection: self.device.clone(), validation: self.validation.then_some(true) })?)
    }
}

/// Frames a run renders from which `--scene-order auto` moves a scene listed in no spatial
/// order: the move costs about what this many frames save on lavapipe (docs/bench/splat.md).
pub const ARRANGE_MIN_FRAMES: usize = 8;

/// Where a loaded scene's Gaussians go on the device (`srug::scene::order`).
#[derive(clap::Args, Clone, Copy, Debug)]
pub struct SceneOrderArgs {
    /// Order of the Gaussians on the device: auto (along a Morton curve through their centres
    /// when the file lists them in no spatial order, as trained scenes do, and the run renders 8
    /// frames or more: faster frames for a move that costs about 8 frames' saving), morton, or
    /// file. The image is the same; ids and outputs stay in file order.
    #[arg(long, default_value = "auto", value_parser = SceneOrder::parse)]
    pub scene_order: SceneOrder,
}

impl SceneOrderArgs {
    /// Arranges `scene` for a run of `frames` frames as `--scene-order` asks, saying so in the log.
    pub fn arrange(&self, device: &Device, scene: &mut GpuScene, frames: usize, path: &Path) -> Result<()> {
        let order = match self.scene_order {
            SceneOrder::Auto if frames < ARRANGE_MIN_FRAMES => SceneOrder::File,
            order => order,
        };
        if scene.arrange(device, order)? {
            log::info!(
                "{}: its Gaussians go onto the device along a Morton curve (--scene-order file keeps the file's order)",
                path.display()
            );
        }
        Ok(())
    }
}

/// An image size, `WxH` (both at least 1).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Size {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
}

impl Size {
    /// `(width, height)`.
    pub fn pair(self) -> (u32, u32) {
        (self.width, self.height)
    }
}

impl FromStr for Size {
    type Err = Error;
    fn from_str(text: &str) -> Result<Self> {
        let bad = || Error::invalid(format!("size \"{text}\""), "is not WxH");
        let (w, h) = text.split_once(['x', 'X']).ok_or_else(bad)?;
        let (width, height): (u32, u32) = (w.trim().parse().map_err(|_| bad())?, h.trim().parse().map_err(|_| bad())?);
        if width == 0 || height == 0 {
            return Err(bad());
        }
        Ok(Self { width, height })
    }
}

/// A point or vector, `x,y,z` (finite numbers).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Vec3Arg(pub glam::Vec3);

/// Comma-separated numbers; `what` says how many in the error.
fn numbers(text: &str, what: &str) -> Result<Vec<f32>> {
    text.split(',')
        .map(|p| p.trim().parse::<f32>())
        .collect::<std::result::Result<_, _>>()
        .map_err(|_| Error::invalid(format!("\"{text}\""), format!("is not {what} comma-separated numbers")))
}

impl FromStr for Vec3Arg {
    type Err = Error;
    fn from_str(text: &str) -> Result<Self> {
        let v = numbers(text, "three")?;
        match v.as_slice() {
            [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok(Self(glam::Vec3::new(*x, *y, *z))),
            _ => Err(Error::invalid(format!("\"{text}\""), "is not three finite numbers")),
        }
    }
}

/// A box, `xmin,ymin,zmin,xmax,ymax,zmax` (finite, min below max on every axis).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoxArg(pub srug::scene::Bounds);

impl FromStr for BoxArg {
    type Err = Error;
    fn from_str(text: &str) -> Result<Self> {
        let v = numbers(text, "six")?;
        match v.as_slice() {
            [a, b, c, d, e, f] if v.iter().all(|x| x.is_finite()) && a < d && b < e && c < f => {
                Ok(Self(srug::scene::Bounds { min: [*a, *b, *c], max: [*d, *e, *f] }))
            }
            _ => Err(Error::invalid(format!("\"{text}\""), "is not xmin,ymin,zmin,xmax,ymax,zmax with min < max")),
        }
    }
}

/// A G-buffer channel list as `--channels` takes it.
#[derive(Clone, Copy, Debug)]
pub struct ChannelList {
    /// The channels beyond alpha and depth.
    pub channels: Channels,
    /// Whether colour was named (`rgb` or `all`).
    pub names_rgb: bool,
    /// Whether the ray-distance channel `range` was named (derived from depth, which it turns on).
    pub range: bool,
}

impl FromStr for ChannelList {
    type Err = Error;
    fn from_str(text: &str) -> Result<Self> {
        let range = text.split(',').map(str::trim).any(|s| s == "range");
        let rest: Vec<&str> = text.split(',').map(str::trim).filter(|s| *s != "range").collect();
        let mut channels = Channels::parse(&rest.join(","))?;
        channels.depth |= range;
        Ok(Self { channels, names_rgb: Channels::names_rgb(text), range })
    }
}

/// `out.png` → `out_003.png`.
pub fn numbered(out: &std::path::Path, i: usize) -> PathBuf {
    let stem = out.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let ext = out.extension().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    out.with_file_name(format!("{stem}_{i:03}.{ext}"))
}

/// Output kind from the file name (`.png` or `.exr`); creates the output's folder.
pub fn output_is_exr(out: &std::path::Path) -> Result<bool> {
    if let Some(parent) = out.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent).map_err(Error::io(parent))?;
    }
    match out.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref() {
        Some("png") => Ok(false),
        Some("exr") => Ok(true),
        _ => Err(Error::invalid(out.display().to_string(), "the output must end in .png or .exr")),
    }
}

/// A spinner on stderr with a message and the elapsed time.
pub fn spinner(message: &str) -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::new_spinner();
    bar.set_style(
        indicatif::ProgressStyle::with_template("{spinner} {msg} [{elapsed}]")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_spinner()),
    );
    bar.set_message(message.to_string());
    bar.enable_steady_tick(std::time::Duration::from_millis(120));
    bar
}

/// A progress bar of `len` steps with `template` (an indicatif template).
pub fn progress_bar(len: u64, template: &str) -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::new(len);
    bar.set_style(
        indicatif::ProgressStyle::with_template(template).unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    bar
}

/// The files a multi-frame run has written so far: when the run fails they
/// are removed (dropping the guard without [`RunOutputs::keep`]), so a failure
/// leaves no output of the run behind.
#[derive(Debug, Default)]
pub struct RunOutputs(Vec<PathBuf>);

impl RunOutputs {
    /// Records a file the run wrote.
    pub fn add(&mut self, path: PathBuf) {
        self.0.push(path);
    }

    /// The run succeeded: its files stay.
    pub fn keep(mut self) {
        self.0.clear();
    }
}

impl Drop for RunOutputs {
    fn drop(&mut self) {
        for path in &self.0 {
            if std::fs::remove_file(path).is_ok() {
                eprintln!("removed {} (the run failed)", path.display());
            }
        }
    }
}

/// How many threads encode and write a run's output files.
#[derive(clap::Args, Clone, Debug, Default)]
pub struct WriterArgs {
    /// Threads that encode and write the output files of a batch of cameras while the next
    /// batch renders (default: as many as the cores the process may use). The files are the
    /// same bytes whatever the count.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=256))]
    pub writers: Option<u32>,
}

impl WriterArgs {
    /// The writer threads for a run.
    pub fn count(&self) -> usize {
        self.writers.map_or_else(|| std::thread::available_parallelism().map_or(1, usize::from), |n| n as usize)
    }
}

/// Runs `write` on every item with up to `writers` threads (items dealt out
/// in turn); each item's result, in the items' order.
pub fn write_all<T: Sync>(items: &[T], writers: usize, write: impl Fn(&T) -> Result<()> + Sync) -> Vec<Result<()>> {
    let writers = writers.clamp(1, items.len().max(1));
    if writers == 1 {
        return items.iter().map(&write).collect();
    }
    let mut results: Vec<Option<Result<()>>> = (0..items.len()).map(|_| None).collect();
    std::thread::scope(|scope| {
        let handles: Vec<_> = (0..writers)
            .map(|w| {
                let write = &write;
                scope.spawn(move || {
                    items
                        .iter()
                        .enumerate()
                        .skip(w)
                        .step_by(writers)
                        .map(|(i, item)| (i, write(item)))
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        for handle in handles {
            match handle.join() {
                Ok(done) => done.into_iter().for_each(|(i, r)| results[i] = Some(r)),
                Err(_) => results.iter_mut().filter(|r| r.is_none()).for_each(|r| {
                    *r = Some(Err(Error::Internal("an output writer panicked".into())));
                }),
            }
        }
    });
    results.into_iter().map(|r| r.unwrap_or_else(|| Err(Error::Internal("an output was not written".into())))).collect()
}

/// Prints a line of a run's log above `bar`, or to stdout where the bar is
/// hidden (one item, or no terminal): batch logs keep every line.
pub fn print_line(bar: &indicatif::ProgressBar, line: &str) {
    if bar.is_hidden() {
        println!("{line}");
    } else {
        bar.println(line);
    }
}

/// A time span `START..END` of two ISO 8601 times.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TimeSpan {
    /// The first instant.
    pub start: UtcTime,
    /// The last instant.
    pub end: UtcTime,
}

impl FromStr for TimeSpan {
    type Err = Error;
    fn from_str(text: &str) -> Result<Self> {
        let (a, b) = text.split_once("..").ok_or_else(|| Error::invalid(format!("\"{text}\""), "is not START..END"))?;
        Ok(Self { start: UtcTime::parse(a)?, end: UtcTime::parse(b)? })
    }
}

fn parse_shadow_test(text: &str) -> Result<VisibilityKind> {
    match text {
        "sigmoid" => Ok(VisibilityKind::Sigmoid),
        "traced" => Ok(VisibilityKind::Traced),
        other => Err(Error::invalid(format!("--shadow-test \"{other}\""), "is not sigmoid or traced")),
    }
}

/// A render scale in (0, 1] (the library's 0, "the preset's", is not a value a user can ask for).
fn parse_render_scale(text: &str) -> Result<f32> {
    match text.trim().parse::<f32>() {
        Ok(v) if v > 0.0 && v <= 1.0 => Ok(v),
        _ => Err(Error::invalid(format!("--render-scale {text}"), "is not a number in (0, 1]")),
    }
}

/// Which cameras to render.
#[derive(clap::Args, Clone, Debug)]
pub struct CameraArgs {
    /// Cameras: INRIA cameras.json, a COLMAP sparse model (its folder or its cameras/images
    /// file, text or binary) or a nerfstudio/instant-ngp transforms.json, detected from the
    /// content; without it, the look-at options define one camera.
    #[arg(long, conflicts_with_all = ["eye", "target", "up", "fov"])]
    pub cameras: Option<PathBuf>,
    /// Render only this camera (default: every camera, numbered outputs).
    #[arg(long, conflicts_with = "shard")]
    pub index: Option<usize>,
    /// Render only shard I of N (0-based): the I-th of N contiguous, near-equal runs of the
    /// cameras, for array jobs (Slurm, Kubernetes). Outputs keep each camera's number in the
    /// whole list, so shards never overwrite each other.
    #[arg(long)]
    pub shard: Option<Shard>,
    /// Output size WxH (intrinsics scaled to match); required with look-at cameras.
    #[arg(long)]
    pub size: Option<Size>,
    /// Look-at camera: eye position x,y,z.
    #[arg(long, allow_hyphen_values = true)]
    pub eye: Option<Vec3Arg>,
    /// Look-at camera: target x,y,z.
    #[arg(long, default_value = "0,0,0", allow_hyphen_values = true)]
    pub target: Vec3Arg,
    /// Look-at camera: up vector x,y,z.
    #[arg(long, default_value = "0,0,1", allow_hyphen_values = true)]
    pub up: Vec3Arg,
    /// Look-at camera: horizontal field of view in degrees.
    #[arg(long, default_value_t = 60.0)]
    pub fov: f32,
    /// Render each camera as a 360° × 180° equirectangular panorama WIDTH × WIDTH/2 from its
    /// position, its view direction at the centre column (depth: distance from the camera).
    #[arg(long, conflicts_with_all = ["size", "fov"])]
    pub panorama: Option<u32>,
}

/// `--shard I/N`: part I (0-based) of N.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    /// Which part, 0 ≤ index < count.
    pub index: usize,
    /// How many parts.
    pub count: usize,
}

impl Shard {
    /// The range of `n` items shard `index` of `count` takes: contiguous, sizes differing by at most one.
    pub fn range(self, n: usize) -> std::ops::Range<usize> {
        (self.index * n / self.count)..((self.index + 1) * n / self.count)
    }
}

impl FromStr for Shard {
    type Err = Error;
    fn from_str(text: &str) -> Result<Self> {
        let bad = || Error::invalid(format!("shard \"{text}\""), "is not I/N with 0 ≤ I < N");
        let (i, n) = text.split_once('/').ok_or_else(bad)?;
        let (index, count): (usize, usize) =
            (i.trim().parse().map_err(|_| bad())?, n.trim().parse().map_err(|_| bad())?);
        if index >= count {
            return Err(bad());
        }
        Ok(Self { index, count })
    }
}

impl CameraArgs {
    /// The cameras selected, resized to `--size` when given.
    pub fn resolve(&self) -> Result<Vec<Camera>> {
        Ok(self.resolve_numbered()?.0.into_iter().map(|(_, c)| c).collect())
    }

    /// Whether outputs carry camera numbers: several cameras, or a shard of them.
    pub fn numbers_outputs(&self, selected: usize) -> bool {
        self.shard.is_some() || selected > 1
    }

    /// The cameras selected, each with its number in the whole list (what a
    /// numbered output carries), resized to `--size` when given, and the
    /// whole list's length.
    pub fn resolve_numbered(&self) -> Result<(Vec<(usize, Camera)>, usize)> {
        let size = self.size.map(Size::pair);
        let mut cams = match (&self.cameras, &self.eye) {
            (Some(c), _) => io::read_cameras(c)?,
            (None, Some(eye)) if self.panorama.is_some() => {
                // Made a panorama below, like every camera.
                vec![Camera::look_at(eye.0, self.target.0, self.up.0, 60.0, 2, 1)?]
            }
            (None, Some(eye)) => {
                let (w, h) = size.ok_or_else(|| Error::invalid("--eye", "needs --size"))?;
                vec![Camera::look_at(eye.0, self.target.0, self.up.0, self.fov, w, h)?]
            }
            (None, None) => return Err(Error::invalid("camera", "give --cameras or --eye")),
        };
        let n = cams.len();
        let mut numbers: Vec<usize> = (0..n).collect();
        if let Some(i) = self.index {
            cams = vec![cams
                .into_iter()
                .nth(i)
                .ok_or_else(|| Error::invalid(format!("--index {i}"), format!("there are {n} cameras")))?];
            numbers = vec![i];
        }
        if let Some(shard) = self.shard {
            let range = shard.range(n);
            if range.is_empty() {
                return Err(Error::invalid(
                    format!("--shard {}/{}", shard.index, shard.count),
                    format!("is empty: there are only {n} cameras"),
                ));
            }
            cams = cams.drain(range.clone()).collect();
            numbers = range.collect();
        }
        if let Some(width) = self.panorama {
            for c in &mut cams {
                let pano = Camera::panorama(c.position, c.rotation, width)
                    .map_err(|e| Error::invalid(format!("--panorama {width}"), e.to_string()))?;
                *c = Camera { name: std::mem::take(&mut c.name), near: c.near, far: c.far, ..pano };
            }
        }
        if let (Some((w, h)), Some(_)) = (size, &self.cameras) {
            for c in &mut cams {
                let (from, to) = (f64::from(c.width) / f64::from(c.height), f64::from(w) / f64::from(h));
                if (from / to - 1.0).abs() > 0.01 {
                    eprintln!(
                        "warning: --size {w}x{h} stretches camera \"{}\" ({}x{}): aspect ratio {from:.3} becomes {to:.3}",
                        c.name, c.width, c.height
                    );
                }
                *c = c.resized(w, h);
            }
        }
        Ok((numbers.into_iter().zip(cams).collect(), n))
    }
}

/// Where the sun is at one moment: by angles, or by a time and a place.
#[derive(clap::Args, Clone, Debug)]
pub struct SunPlaceArgs {
    /// Sun azimuth, degrees from north toward east.
    #[arg(long, default_value_t = 260.0, allow_negative_numbers = true)]
    pub sun_azimuth: f32,
    /// Sun elevation, degrees (at or below 0: no sun light, no shadow pass).
    #[arg(long, default_value_t = 50.0, allow_negative_numbers = true)]
    pub sun_elevation: f32,
    /// Sun from a time instead (ISO 8601 with a zone, e.g. 2024-06-21T14:30+02:00); needs --latitude, --longitude.
    #[arg(long, value_parser = UtcTime::parse, conflicts_with_all = ["sun_azimuth", "sun_elevation"])]
    pub sun_time: Option<UtcTime>,
    /// Latitude in degrees (north positive), for a sun from a time.
    #[arg(long, allow_negative_numbers = true)]
    pub latitude: Option<f64>,
    /// Longitude in degrees (east positive), for a sun from a time.
    #[arg(long, allow_negative_numbers = true)]
    pub longitude: Option<f64>,
}

impl SunPlaceArgs {
    /// Latitude and longitude, both given.
    fn place(&self) -> Result<(f64, f64)> {
        match (self.latitude, self.longitude) {
            (Some(a), Some(o)) => Ok((a, o)),
            _ => Err(Error::invalid("--sun-time and --sun-path", "need --latitude and --longitude")),
        }
    }

    /// The sun with a label.
    pub fn resolve(&self, intensity: f32) -> Result<(String, Sun)> {
        let intensity = [intensity; 3];
        if let Some(t) = self.sun_time {
            let (lat, lon) = self.place()?;
            let p = srug::shadow::solar_position(&t, lat, lon)?;
            let sun = Sun::from_azimuth_elevation(p.azimuth as f32, p.elevation as f32, intensity)?;
            return Ok((format!("{} (sun {:.1}°, {:.1}°)", format_time(&t), p.azimuth, p.elevation), sun));
        }
        let sun = Sun::from_azimuth_elevation(self.sun_azimuth, self.sun_elevation, intensity)?;
        Ok((format!("sun {:.1}°, {:.1}°", self.sun_azimuth, self.sun_elevation), sun))
    }
}

/// Where the sun is, or its path.
#[derive(clap::Args, Clone, Debug)]
pub struct SunArgs {
    /// The sun at one moment.
    #[command(flatten)]
    pub at: SunPlaceArgs,
    /// Place the sun on the environment map's brightest point (its own sun), with --env FILE.
    #[arg(long, conflicts_with_all = ["sun_azimuth", "sun_elevation", "sun_time", "sun_path"])]
    pub sun_from_env: bool,
    /// Sun irradiance S_i (π: a white Lambertian surface facing the sun has radiance 1).
    #[arg(long, default_value_t = std::f32::consts::PI)]
    pub sun_intensity: f32,
    /// Time-lapse: START..END (ISO 8601 times) rendered as --frames frames; needs --latitude, --longitude.
    #[arg(long, conflicts_with_all = ["sun_azimuth", "sun_elevation", "sun_time"])]
    pub sun_path: Option<TimeSpan>,
    /// Frames of the time-lapse.
    #[arg(long, default_value_t = 12)]
    pub frames: u32,
}

fn format_time(t: &UtcTime) -> String {
    let s = t.seconds.round() as u64;
    format!("{}-{:02}-{:02}T{:02}:{:02}Z", t.year, t.month, t.day, s / 3600, (s / 60) % 60)
}

impl SunArgs {
    /// The suns of every frame, with a label for each.
    pub fn resolve(&self) -> Result<Vec<(String, Sun)>> {
        if self.sun_from_env {
            return Err(Error::invalid("--sun-from-env", "applies to `srug relight --env FILE` only"));
        }
        if let Some(span) = &self.sun_path {
            let (lat, lon) = self.at.place()?;
            let intensity = [self.sun_intensity; 3];
            let frames = sun_path(&span.start, &span.end, self.frames, lat, lon)?;
            return frames
                .iter()
                .map(|(t, p)| {
                    let sun = Sun::from_azimuth_elevation(p.azimuth as f32, p.elevation as f32, intensity)?;
                    Ok((format!("{} (sun {:.1}°, {:.1}°)", format_time(t), p.azimuth, p.elevation), sun))
                })
                .collect();
        }
        Ok(vec![self.at.resolve(self.sun_intensity)?])
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
    #[arg(long, default_value = "karis", value_parser = BrdfLut::parse)]
    pub brdf: BrdfLut,
}

/// Shading options. Quality knobs default to the preset's values; explicit
/// options override them.
#[derive(clap::Args, Clone, Debug)]
pub struct ShadeArgs {
    /// Quality preset: fast, balanced or reference (`srug bench trade` measures them).
    #[arg(long, default_value = "balanced", value_parser = Preset::parse)]
    pub preset: Preset,
    /// Sun visibility: editable (shadow map), fixed (the Gaussians' V_f) or none.
    #[arg(long, default_value = "editable", value_parser = VisibilitySource::parse)]
    pub visibility: VisibilitySource,
    /// Exposure in stops.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub exposure: f32,
    /// Tone map: clamp, reinhard or aces.
    #[arg(long, default_value = "aces", value_parser = ToneMap::parse)]
    pub tone_map: ToneMap,
    /// Background r,g,b instead of the environment.
    #[arg(long)]
    pub background: Option<Vec3Arg>,
    /// Shadow-map resolution [preset: fast 1024, balanced 2048, reference 4096].
    #[arg(long)]
    pub shadow_resolution: Option<u32>,
    /// What the shadow map covers: scene (the whole scene's bounds), view (the
    /// camera's view frustum within them: finer texels; casters anywhere still cast)
    /// or cascades (a map per slice of the view's depth, fine near the camera) [preset: scene].
    #[arg(long, value_parser = ShadowFit::parse)]
    pub shadow_fit: Option<ShadowFit>,
    /// Maps with `--shadow-fit cascades`, 2 to 4, each `--shadow-resolution` texels [default: 3].
    #[arg(long)]
    pub shadow_cascades: Option<u32>,
    /// Splat the shadow map only where the frames' receivers look it up (the same
    /// shadows, for less; one map per batch of cameras, so not reused across batches)
    /// [default: on for one camera, off for several, which share one map per sun].
    #[arg(long)]
    pub shadow_cull: bool,
    /// Sigmoid sharpness k per metre [preset: 50].
    #[arg(long)]
    pub shadow_k: Option<f32>,
    /// Shadow depth bias, metres; at least the splats' extent along the light, or lit
    /// surfaces shadow themselves [preset: 0.8].
    #[arg(long, allow_negative_numbers = true)]
    pub shadow_bias: Option<f32>,
    /// Slope-scaled shadow bias in shadow-map texels, times tan θ of the
    /// receiver's angle to the sun [preset: 3].
    #[arg(long, allow_negative_numbers = true)]
    pub shadow_slope_bias: Option<f32>,
    /// Normal offset of the shadow receivers in shadow-map texels, times sin θ [preset: 0].
    #[arg(long, allow_negative_numbers = true)]
    pub shadow_normal_offset: Option<f32>,
    /// Shadow-map filter: pcf (the four nearest texels' tests, weighted
    /// bilinearly: edges a texel wide, where the map's outline is) or depth (one
    /// test of the bilinear depth: the paper's razor edge) [preset: pcf].
    #[arg(long, value_parser = ShadowFilter::parse)]
    pub shadow_filter: Option<ShadowFilter>,
    /// Surface depths for the shadow map and its receivers (and the depth
    /// channels written): where each ray meets the splat's plane; `=false` for
    /// the splats' centre depths [preset: true].
    #[arg(long, num_args = 0..=1, default_missing_value = "true", require_equals = true)]
    pub shadow_surface_depth: Option<bool>,
    /// Surface depths for the shadow map's occluders too [preset: false].
    #[arg(long, num_args = 0..=1, default_missing_value = "true", require_equals = true)]
    pub shadow_map_surface_depth: Option<bool>,
    /// Coverage a shadow-map texel's occluders must reach for it to cast
    /// shadow (median map depths), strictly between 0 and 1: at 0.5 the
    /// splats' half-coverage outline casts, widening shadows; more draws them
    /// in [preset: 0.6].
    #[arg(long)]
    pub shadow_map_coverage: Option<f32>,
    /// Coverage a pixel's splats must reach for it to receive shadow (median
    /// receiver depths; the median_depth channel written follows it), strictly
    /// between 0 and 1: below 0.5 a wall with gaps between its splats still
    /// receives, where the camera sees through to what lies behind [preset: 0.45].
    #[arg(long)]
    pub shadow_receiver_coverage: Option<f32>,
    /// Receiver depth for the shadow test: median or expected [preset: median].
    #[arg(long, value_parser = DepthMode::parse)]
    pub receiver_depth: Option<DepthMode>,
    /// Shadow test: sigmoid (differentiable) or traced (exact transmittance)
    /// [preset: reference traced, else sigmoid].
    #[arg(long, value_parser = parse_shadow_test)]
    pub shadow_test: Option<VisibilityKind>,
    /// Spherical-harmonic degree used for colour [preset: fast 0, else the scene's].
    #[arg(long)]
    pub sh_degree: Option<u32>,
    /// Render at this fraction of the output size, then upsample bilinearly
    /// [preset: fast 0.5, else 1].
    #[arg(long, value_parser = parse_render_scale)]
    pub render_scale: Option<f32>,
    /// Tile edge in pixels for the camera's and the shadow map's splatting: 8, 16 or 32 [preset: 16].
    #[arg(long)]
    pub tile: Option<u32>,
}

impl ShadeArgs {
    /// The relighting settings: the preset's, with the options given on top.
    pub fn settings(&self) -> Result<RelightSettings> {
        let mut s = RelightSettings::preset(self.preset);
        s.shade = ShadeSettings {
            visibility: self.visibility,
            exposure_ev: self.exposure,
            tone_map: self.tone_map,
            background: match self.background {
                Some(b) => Background::Color(b.0.to_array()),
                None => Background::Environment,
            },
            ..ShadeSettings::default()
        };
        let sh = &mut s.shadow;
        sh.resolution = self.shadow_resolution.unwrap_or(sh.resolution);
        sh.fit = self.shadow_fit.unwrap_or(sh.fit);
        sh.cascades = self.shadow_cascades.unwrap_or(sh.cascades);
        sh.k = self.shadow_k.unwrap_or(sh.k);
        sh.bias = self.shadow_bias.unwrap_or(sh.bias);
        sh.slope_bias = self.shadow_slope_bias.unwrap_or(sh.slope_bias);
        sh.normal_offset = self.shadow_normal_offset.unwrap_or(sh.normal_offset);
        sh.filter = self.shadow_filter.unwrap_or(sh.filter);
        sh.surface_depth = self.shadow_surface_depth.unwrap_or(sh.surface_depth);
        sh.map_surface_depth = self.shadow_map_surface_depth.unwrap_or(sh.map_surface_depth);
        sh.map_coverage = self.shadow_map_coverage.unwrap_or(sh.map_coverage);
        sh.receiver_coverage = self.shadow_receiver_coverage.unwrap_or(sh.receiver_coverage);
        sh.cull_to_receivers |= self.shadow_cull;
        sh.receiver_depth = self.receiver_depth.unwrap_or(sh.receiver_depth);
        s.visibility_kind = self.shadow_test.unwrap_or(s.visibility_kind);
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

/// Runs `produce` on each item on this thread (the GPU work and its readback)
/// while `consume` encodes and writes earlier results on a second thread: at
/// most `depth` results wait between the two, so camera i + 1 renders while
/// camera i is being written. Stops at the first error of either side and
/// returns it (the producer's first).
pub fn overlapped<I, T, P, C>(items: I, depth: usize, mut produce: P, mut consume: C) -> Result<()>
where
    I: IntoIterator,
    T: Send,
    P: FnMut(I::Item) -> Result<T>,
    C: FnMut(T) -> Result<()> + Send,
{
    let (send, receive) = std::sync::mpsc::sync_channel::<T>(depth.max(1));
    std::thread::scope(|scope| {
        let writer = scope.spawn(move || -> Result<()> {
            for item in receive {
                consume(item)?;
            }
            Ok(())
        });
        let mut produced = Ok(());
        for item in items {
            match produce(item) {
                // A closed channel: the writer stopped on an error, which join reports.
                Ok(t) => {
                    if send.send(t).is_err() {
                        break;
                    }
                }
                Err(e) => {
                    produced = Err(e);
                    break;
                }
            }
        }
        drop(send);
        let written = writer.join().unwrap_or_else(|_| Err(Error::Internal("the output writer panicked".into())));
        produced.and(written)
    })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, reason = "a failed unwrap is a failed test")]
    use super::*;

    /// Every item written once, each result at its item's place, whatever the writer count.
    #[test]
    fn write_all_returns_each_result_in_item_order() {
        for writers in [1, 2, 3, 8, 40] {
            let calls = std::sync::atomic::AtomicUsize::new(0);
            let items: Vec<u32> = (0..20).collect();
            let results = write_all(&items, writers, |&i| {
                calls.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                if i % 3 == 0 {
                    Err(Error::invalid(format!("item {i}"), "fails"))
                } else {
                    Ok(())
                }
            });
            assert_eq!(calls.into_inner(), 20, "{writers} writers");
            for (i, r) in results.iter().enumerate() {
                match r {
                    Ok(()) => assert!(i % 3 != 0, "{writers} writers: item {i}"),
                    Err(e) => assert!(i % 3 == 0 && e.to_string().contains(&format!("item {i}:")), "{writers}: {e}"),
                }
            }
        }
        assert!(write_all(&[] as &[u32], 4, |_| Ok(())).is_empty());
    }

    /// Results reach the writer in order; a producer error stops the run after
    /// the writer has taken what came before; a writer error stops the producer.
    #[test]
    fn overlapped_keeps_order_and_stops_at_the_first_error() {
        let mut seen = Vec::new();
        overlapped(
            0..50,
            2,
            |i| Ok(i * 10),
            |v| {
                seen.push(v);
                Ok(())
            },
        )
        .unwrap();
        assert_eq!(seen, (0..50).map(|i| i * 10).collect::<Vec<_>>());

        let mut seen = Vec::new();
        let e = overlapped(
            0..50,
            2,
            |i| if i == 7 { Err(Error::invalid("item 7", "fails")) } else { Ok(i) },
            |v| {
                seen.push(v);
                Ok(())
            },
        );
        assert!(e.unwrap_err().to_string().contains("item 7"));
        assert_eq!(seen, (0..7).collect::<Vec<_>>());

        let mut produced = 0;
        let e = overlapped(
            0..1000,
            2,
            |i| {
                produced += 1;
                Ok(i)
            },
            |v| if v == 3 { Err(Error::invalid("write 3", "fails")) } else { Ok(()) },
        );
        assert!(e.unwrap_err().to_string().contains("write 3"));
        assert!(produced < 10, "the producer went on for {produced} items after the writer failed");
    }
}
