//! Sun shadows: the sigmoid shadow map and the traced reference.
//!
//! The scene's depth is splatted from the sun by the splatting pipeline with
//! an orthographic light camera ([`light_camera`]) into a [`ShadowMap`]. Each
//! receiver pixel of a camera G-buffer is turned back into a world point,
//! projected into light space, and compared with the map's four nearest
//! texels through the paper's soft test σ(k·(z − z_receiver + bias)) (the
//! *sigmoid shadow map*; docs/conventions.md §5 has the numerics): one test
//! of their bilinear depth, or their four tests weighted bilinearly
//! ([`ShadowFilter`]). `[ShadowPass::traced]`
//! computes the accurate transmittance toward the sun from the same light
//! splat, the reference the sigmoid test is measured against.
//!
//! Invariants:
//! - the logit is clamped to ±30 and σ evaluated as exp(−|x|)-based, so V_e
//!   is finite for every k and depth difference (k from 1e-3 to 1e9 tested);
//! - expected depths are normalised by alpha (Σwz / Σw); texels and receivers
//!   with alpha below `min_alpha` (or no median crossing) have no surface:
//!   empty texels read as the light's far depth, receivers without a surface
//!   and points outside the map are lit (V = 1);
//! - a sun at or below the horizon gives no sun light: no pass runs and
//!   [`ShadowPass::shadow_map`] returns `None`.
//!
//! [`cpu`] is the f64 twin.

pub mod accuracy;
pub mod backward;
pub mod cascades;
pub mod completion;
pub mod cpu;
mod forward;
mod layout;
pub mod masks;
pub mod sun;

pub use forward::*;
pub(crate) use layout::*;

use glam::Vec3;

pub use self::sun::{solar_position, sun_path, SolarPosition, Sun, UtcTime};
use crate::error::{Error, Result};
use crate::gpu::{Buffer, Device};
use crate::scene::{Bounds, Camera, Projection};
use crate::splat::{Channels, SplatFrame, SplatSettings};

/// Which depth a G-buffer gives for shadows.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum DepthMode {
    /// Depth where transmittance first falls to 1 − the map's or the
    /// receivers' coverage ([`ShadowSettings::map_coverage`],
    /// [`ShadowSettings::receiver_coverage`]): robust at silhouettes.
    #[default]
    Median,
    /// Alpha-normalised blended depth Σwz / Σw: smooth, differentiable, but
    /// mixes depths at silhouettes (light leaks, floating shadows).
    Expected,
    /// Shadow maps only: blended depth with empty space one scene depth
    /// beyond the light's far plane, Σwz + T·(2·far). Differentiable
    /// everywhere, also where nothing is yet (faint Gaussians cast faint
    /// shadows), so optimisation can grow occluders from nothing; a texel needs
    /// about half coverage to shadow what lies behind it.
    ExpectedOverFar,
}

impl DepthMode {
    /// Parses `median` or `expected`.
    pub fn parse(text: &str) -> Result<Self> {
        match text {
            "median" => Ok(Self::Median),
            "expected" => Ok(Self::Expected),
            "expected-over-far" => Ok(Self::ExpectedOverFar),
            other => {
                Err(Error::invalid(format!("depth mode \"{other}\""), "is not median, expected or expected-over-far"))
            }
        }
    }

    /// The depth a texel with nothing in it reads as, for a light camera whose
    /// far plane is `far`: `far` (median, expected), `2·far` (expected over far).
    pub fn empty_depth(self, far: f32) -> f32 {
        match self {
            Self::ExpectedOverFar => 2.0 * far,
            Self::Median | Self::Expected => far,
        }
    }

    fn code(self) -> u32 {
        match self {
            Self::Expected => 0,
            Self::Median => 1,
            Self::ExpectedOverFar => 2,
        }
    }
}

/// What the light camera covers.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ShadowFit {
    /// The whole scene's bounds.
    #[default]
    SceneBounds,
    /// The receiving camera's view frustum clipped to the scene bounds (finer
    /// texels for the same resolution; occluders anywhere in the bounds still
    /// cast, since the depth range stays the scene's).
    ViewFrustum,
    /// [`ShadowSettings::cascades`] maps, each fitted to a slice of the
    /// receiving camera's view depth ([`cascades`]): fine texels near the
    /// camera, coarse far away, a smooth hand-over between them, and texels
    /// snapped to a grid fixed in the world so a moving camera does not make
    /// the edges shimmer. Pinhole cameras; not differentiated.
    Cascades,
}

impl ShadowFit {
    /// Parses `scene`, `view` or `cascades`.
    pub fn parse(text: &str) -> Result<Self> {
        match text {
            "scene" => Ok(Self::SceneBounds),
            "view" => Ok(Self::ViewFrustum),
            "cascades" => Ok(Self::Cascades),
            other => Err(Error::invalid(format!("shadow fit \"{other}\""), "is not scene, view or cascades")),
        }
    }
}

/// How the shadow test reads the map around a receiver's texel position.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum ShadowFilter {
    /// One test of the bilinearly interpolated depth, σ(k·(Σwᵢzᵢ − z + bias)):
    /// the paper's test, a point sun's razor edge. Near an occluder's outline
    /// the interpolated depth mixes the occluder's with what lies behind it,
    /// so the shadow reaches almost a texel past the outline.
    Depth,
    /// Percentage-closer filtering: the four texels' tests weighted
    /// bilinearly, Σwᵢ·σ(k·(zᵢ − z + bias)). The edge falls where the map's
    /// outline is, a texel wide and smooth rather than a pixel staircase where
    /// texels are larger than pixels; differentiable like the depth test.
    #[default]
    Pcf,
}

impl ShadowFilter {
    /// Parses `depth` or `pcf`.
    pub fn parse(text: &str) -> Result<Self> {
        match text {
            "depth" => Ok(Self::Depth),
            "pcf" => Ok(Self::Pcf),
            other => Err(Error::invalid(format!("shadow filter \"{other}\""), "is not depth or pcf")),
        }
    }

    /// The name [`ShadowFilter::parse`] reads.
    pub fn name(self) -> &'static str {
        match self {
            Self::Depth => "depth",
            Self::Pcf => "pcf",
        }
    }

    /// The `FILTER` specialization constant of the shadow kernels.
    pub(crate) fn code(self) -> u32 {
        match self {
            Self::Depth => 0,
            Self::Pcf => 1,
        }
    }
}

/// The world width of one texel of a light camera (orthographic, square texels).
pub(crate) fn texel_size(light: &Camera) -> f32 {
    match light.projection {
        Projection::Orthographic { sx, .. } => 1.0 / sx,
        Projection::Pinhole { .. } => 0.0,
    }
}

/// The largest tan θ the slope-scaled bias uses (θ ≈ 84°): beyond it a
/// receiver is nearly edge-on to the sun, receives almost no sun light, and an
/// unbounded bias would let its shadows leak.
pub const MAX_SLOPE: f32 = 10.0;

/// Shadow quality knobs. The default is the balanced preset's shadow: a
/// 2048 map, 0.3 m plus 3 texels of slope-scaled bias, median depths for the
/// map and the receivers, percentage-closer filtering (chosen on the analytic
/// block, docs/bench/shadow.md).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShadowSettings {
    /// Shadow-map texels along its longer side.
    pub resolution: u32,
    /// Sigmoid sharpness k, per world unit.
    pub k: f32,
    /// Depth bias against self-shadowing, world units (added to z_s − z).
    pub bias: f32,
    /// Slope-scaled bias, in shadow-map texels: adds this many texel widths
    /// times tan θ (θ between the receiver's normal and the sun, tan θ at most
    /// [`MAX_SLOPE`]) to `bias`, so steep receivers, whose depth changes most
    /// across a texel, get the bias they need and facing ones keep contact shadows.
    pub slope_bias: f32,
    /// Normal offset, in shadow-map texels: the receiver point moves along its
    /// normal by this many texel widths times sin θ before the test.
    pub normal_offset: f32,
    /// How the test reads the map around each receiver.
    pub filter: ShadowFilter,
    /// Surface depths ([`crate::splat::SplatSettings::surface_depth`]) for the
    /// receivers: each splat's depth where the pixel's ray meets its plane, not
    /// its centre's. Receivers follow it when rendered with
    /// [`ShadowSettings::receiver_splat`]. Differentiated (the splat backward
    /// takes the slope's gradient back to the Gaussians).
    pub surface_depth: bool,
    /// Surface depths for the shadow map's occluders too. Off in the presets:
    /// the map's median splat is the one whose coverage takes T to one half,
    /// in the order of the splats' centres, so with surface depths one more
    /// faint splat in front (an added occluder's fringe) can hand the median to
    /// a splat whose plane lies deeper at that texel, and lighten it; on the
    /// analytic block it changes no accuracy figure beyond the noise.
    pub map_surface_depth: bool,
    /// Coverage a shadow-map texel's occluders must reach for it to hold an
    /// occluder depth, with [`DepthMode::Median`] maps: the map's
    /// [`SplatSettings::median_coverage`]. At one half a splat's outline out
    /// to where its coverage is 50% casts shadow, so cast shadows are wider
    /// than their casters; more coverage draws the map's outlines inside
    /// (docs/conventions.md, "Shadows"). Strictly between 0 and 1.
    pub map_coverage: f32,
    /// Coverage a receiver pixel's splats must reach for it to hold a
    /// surface, with [`DepthMode::Median`] receivers: the camera frame's
    /// [`SplatSettings::median_coverage`] (its median depth channel follows
    /// it). Below one half a wall whose splats leave gaps (trained scenes'
    /// do) still receives where the camera sees through them to what lies
    /// behind, which would otherwise catch light or shadow as specks.
    /// Strictly between 0 and 1.
    pub receiver_coverage: f32,
    /// Depth of the shadow map.
    pub map_depth: DepthMode,
    /// Depth of the receivers (the camera G-buffer).
    pub receiver_depth: DepthMode,
    /// Light camera fit.
    pub fit: ShadowFit,
    /// Maps with [`ShadowFit::Cascades`], 2 to 4 (each `resolution` texels across).
    pub cascades: u32,
    /// Alpha below which a texel or a receiver has no surface.
    pub min_alpha: f32,
    /// Fill outputs with this 32-bit word first (tests use NaN, so an
    /// unwritten pixel cannot pass for a value).
    pub prefill: Option<u32>,
    /// Tile edge of the shadow map's splatting ([`crate::splat::TILE_SIZES`]).
    pub tile: u32,
    /// Splat the map only in the tiles the frame's receivers look up
    /// ([`ShadowPass::shadow_map_for_receivers`]) even where it is kept for
    /// later frames: the same visibility for less, but a map per camera, or
    /// per batch of cameras (`frame::Relighter::render_batch` culls the
    /// batch's one map to all of them), so it is not reused for another view.
    /// `frame::Relighter` culls anyway whenever its map is not kept
    /// (shadow-map reuse off, one camera).
    pub cull_to_receivers: bool,
}

/// [`ShadowSettings::map_coverage`] by default (and in every preset).
pub const DEFAULT_MAP_COVERAGE: f32 = 0.6;

/// [`ShadowSettings::receiver_coverage`] by default (and in every preset).
pub const DEFAULT_RECEIVER_COVERAGE: f32 = 0.45;

impl Default for ShadowSettings {
    fn default() -> Self {
        Self {
            resolution: 2048,
            k: 50.0,
            bias: 0.8,
            slope_bias: 3.0,
            normal_offset: 0.0,
            filter: ShadowFilter::Pcf,
            surface_depth: true,
            map_surface_depth: false,
            map_coverage: DEFAULT_MAP_COVERAGE,
            receiver_coverage: DEFAULT_RECEIVER_COVERAGE,
            map_depth: DepthMode::Median,
            receiver_depth: DepthMode::Median,
            fit: ShadowFit::SceneBounds,
            cascades: 3,
            min_alpha: 0.5,
            prefill: None,
            tile: crate::splat::DEFAULT_TILE,
            cull_to_receivers: false,
        }
    }
}

impl ShadowSettings {
    /// Checks the values.
    pub fn validate(&self) -> Result<()> {
        crate::splat::check_tile(self.tile)?;
        crate::splat::check_median_coverage("shadow map coverage", self.map_coverage)?;
        crate::splat::check_median_coverage("shadow receiver coverage", self.receiver_coverage)?;
        let rules: [(bool, String, &str); 8] = [
            (
                (16..=16384).contains(&self.resolution),
                format!("shadow map resolution {}", self.resolution),
                "must be 16..=16384 texels",
            ),
            (
                self.k.is_finite() && self.k > 0.0,
                format!("shadow sharpness k {}", self.k),
                "must be positive and finite",
            ),
            (self.bias.is_finite() && self.bias >= 0.0, format!("shadow bias {}", self.bias), "must be finite and ≥ 0"),
            (
                (0.0..=100.0).contains(&self.slope_bias),
                format!("shadow slope bias {} texels", self.slope_bias),
                "must be 0 to 100",
            ),
            (
                (0.0..=100.0).contains(&self.normal_offset),
                format!("shadow normal offset {} texels", self.normal_offset),
                "must be 0 to 100",
            ),
            (
                self.min_alpha > 0.0 && self.min_alpha <= 1.0,
                format!("shadow minimum alpha {}", self.min_alpha),
                "must be in (0, 1]",
            ),
            (
                (2..=cascades::MAX_CASCADES).contains(&self.cascades),
                format!("{} shadow cascades", self.cascades),
                "must be 2 to 4",
            ),
            (
                self.receiver_depth != DepthMode::ExpectedOverFar,
                format!("receiver depth {:?}", self.receiver_depth),
                "must be median or expected",
            ),
        ];
        match rules.into_iter().find(|(ok, ..)| !ok) {
            Some((_, what, why)) => Err(Error::invalid(what, why)),
            None => Ok(()),
        }
    }

    /// The G-buffer channels a receiver (camera) render needs for these settings.
    pub fn receiver_channels(&self) -> Channels {
        Channels { normal: self.geometric_bias(), ..depth_channels(self.receiver_depth) }
    }

    /// The splat settings of a receiver (camera) render for these settings:
    /// [`ShadowSettings::receiver_channels`], the surface depth and the receiver coverage.
    pub fn receiver_splat(&self) -> SplatSettings {
        SplatSettings {
            channels: self.receiver_channels(),
            surface_depth: self.surface_depth,
            median_coverage: self.receiver_coverage,
            ..SplatSettings::default()
        }
    }

    /// Whether the test reads the receivers' normals (a slope bias or normal offset).
    pub fn geometric_bias(&self) -> bool {
        self.slope_bias > 0.0 || self.normal_offset > 0.0
    }
}

/// The shadow map's G-buffer channel for a depth mode.
pub fn depth_channels(mode: DepthMode) -> Channels {
    match mode {
        DepthMode::Median => Channels { median_depth: true, ..Channels::default() },
        DepthMode::Expected | DepthMode::ExpectedOverFar => Channels { depth: true, ..Channels::default() },
    }
}

/// The light's frame for a scene: the padded bounds' centre (the light-space
/// origin), the rotation looking along the sunlight, and the bounds' depth
/// range along it.
pub(crate) struct LightFrame {
    centre: Vec3,
    rotation: glam::Mat3,
    /// Along the sunlight, and the up the rotation was made with.
    towards: Vec3,
    up: Vec3,
    depth_range: (f32, f32),
    /// The padded bounds.
    lo: Vec3,
    hi: Vec3,
    diagonal: f32,
}

impl LightFrame {
    pub(crate) fn new(bounds: &Bounds, sun: &Sun) -> Result<Self> {
        let (lo, hi) = (Vec3::from_array(bounds.min), Vec3::from_array(bounds.max));
        if !lo.is_finite() || !hi.is_finite() || lo.cmpgt(hi).any() {
            return Err(Error::invalid(format!("scene bounds {lo}..{hi}"), "are not a box"));
        }
        let diagonal = (hi - lo).length();
        // 2% of the size for the splats reaching past their centres, and 0.1% of the
        // distance from the origin, but of no more of it than the scene's size (0.1% of
        // 1e5 m spread a map over 100 m of empty space each side): beyond that, a few f32
        // steps, so the box still holds the bounds once rounded.
        let far = lo.abs().max(hi.abs()).max_element();
        let near = far.min(diagonal);
        let pad = 0.02 * diagonal + 1e-3 * (near + 1.0) + 8.0 * f32::EPSILON * (far - near);
        let (lo, hi) = (lo - pad, hi + pad);
        let centre = 0.5 * (lo + hi);
        let towards = -sun.direction;
        let up = if sun.direction.z.abs() > 0.999 { Vec3::Y } else { Vec3::Z };
        let rotation = crate::camera::look_rotation(centre, centre + towards, up)?;
        let mut frame = Self { centre, rotation, towards, up, depth_range: (0.0, 0.0), lo, hi, diagonal };
        frame.depth_range =
            corners(lo, hi).map(|c| frame.to_light(c).z).fold((f32::MAX, f32::MIN), |(a, b), z| (a.min(z), b.max(z)));
        Ok(frame)
    }

    /// A world point in light space (x, y across the light, z along it).
    pub(crate) fn to_light(&self, p: Vec3) -> Vec3 {
        self.rotation.transpose() * (p - self.centre)
    }

    /// The orthographic light camera over light-space `min..max` (x, y) with
    /// `resolution` square texels along the longer side, covering the
    /// scene's whole depth range.
    pub(crate) fn camera(&self, min: glam::Vec2, max: glam::Vec2, resolution: u32) -> Result<Camera> {
        let extent = (max - min).max(glam::Vec2::splat(1e-6 * self.diagonal.max(1e-6)));
        let long = extent.max_element();
        let width = ((resolution as f32 * extent.x / long).round() as u32).max(1);
        let height = ((resolution as f32 * extent.y / long).round() as u32).max(1);
        let depth = self.depth_range.1 - self.depth_range.0;
        let near = 1e-3 * depth.max(1e-6);
        let eye_light = Vec3::new(0.5 * (min.x + max.x), 0.5 * (min.y + max.y), self.depth_range.0 - 2.0 * near);
        let eye = self.centre + self.rotation * eye_light;
        // Texels are square: the extent along the shorter side is rounded up to whole texels.
        let texel = long / resolution as f32;
        let mut camera = Camera::orthographic(
            eye,
            self.towards,
            self.up,
            width as f32 * texel,
            height as f32 * texel,
            width,
            height,
            near,
            depth + 4.0 * near,
        )?;
        camera.name = "sun".into();
        Ok(camera)
    }
}

/// The eight corners of the box `a..b`.
fn corners(a: Vec3, b: Vec3) -> impl Iterator<Item = Vec3> {
    (0..8).map(move |i| Vec3::new([a.x, b.x][i & 1], [a.y, b.y][(i >> 1) & 1], [a.z, b.z][i >> 2]))
}

/// The orthographic camera looking along the sunlight that covers `bounds`
/// (padded), or with [`ShadowFit::ViewFrustum`] the part of them `view`
/// sees, with `resolution` texels along its longer side and square texels.
/// [`ShadowFit::Cascades`] has a camera per cascade ([`cascades::cascade_cameras`]).
pub fn light_camera(
    bounds: &Bounds,
    sun: &Sun,
    resolution: u32,
    fit: ShadowFit,
    view: Option<&Camera>,
) -> Result<Camera> {
    if resolution == 0 || resolution > 16384 {
        return Err(Error::invalid(format!("shadow-map resolution {resolution}"), "is not in 1..=16384"));
    }
    let frame = LightFrame::new(bounds, sun)?;
    let (lo, hi) = (frame.lo, frame.hi);
    let (xy_lo, xy_hi) = match (fit, view) {
        (ShadowFit::ViewFrustum, Some(v)) => frustum_box(v, lo, hi).unwrap_or((lo, hi)),
        (ShadowFit::ViewFrustum, None) => {
            return Err(Error::invalid("view-frustum shadow fit", "needs the view camera"))
        }
        (ShadowFit::Cascades, _) => {
            return Err(Error::invalid(
                "cascaded shadow fit",
                "has a light camera per cascade (shadow::cascades), and no single map: use the scene or view fit",
            ))
        }
        (ShadowFit::SceneBounds, _) => (lo, hi),
    };
    let (mut min, mut max) = (glam::Vec2::splat(f32::MAX), glam::Vec2::splat(f32::MIN));
    for c in corners(xy_lo, xy_hi) {
        let l = frame.to_light(c).truncate();
        min = min.min(l);
        max = max.max(l);
    }
    frame.camera(min, max, resolution)
}

/// The box of `view`'s frustum (far plane at the farthest bounds corner)
/// clipped to [lo, hi]; `None` where they do not meet.
fn frustum_box(view: &Camera, lo: Vec3, hi: Vec3) -> Option<(Vec3, Vec3)> {
    let far = (0..8)
        .map(|i| Vec3::new([lo.x, hi.x][i & 1], [lo.y, hi.y][(i >> 1) & 1], [lo.z, hi.z][i >> 2]))
        .map(|c| view.world_to_camera(c).z)
        .fold(view.near, f32::max)
        .min(view.far);
    let (w, h) = (view.width as f32, view.height as f32);
    let mut bmin = Vec3::splat(f32::MAX);
    let mut bmax = Vec3::splat(f32::MIN);
    for z in [view.near, far] {
        // Corners and edge midpoints: through a lens an edge may bulge past its corners.
        for (u, v) in
            [(0.0, 0.0), (w, 0.0), (0.0, h), (w, h), (w * 0.5, 0.0), (w * 0.5, h), (0.0, h * 0.5), (w, h * 0.5)]
        {
            let c = match view.projection {
                Projection::Pinhole { .. } => {
                    let [x, y, w] = view.pixel_direction([f64::from(u), f64::from(v)])?;
                    if w <= 0.0 {
                        // A fisheye seeing past 90°: no box of the frustum.
                        return None;
                    }
                    Vec3::new(x as f32 * z, y as f32 * z, z)
                }
                Projection::Orthographic { sx, sy, cx, cy } => Vec3::new((u - cx) / sx, (v - cy) / sy, z),
            };
            let p = view.rotation * c + view.position;
            bmin = bmin.min(p);
            bmax = bmax.max(p);
        }
    }
    let (a, b) = (bmin.max(lo), bmax.min(hi));
    (a.cmplt(b).all() && a.is_finite() && b.is_finite()).then_some((a, b))
}

/// A shadow map: the scene splatted from the sun, with the frame kept for the
/// traced pass and the backward pass (until [`ShadowMap::release_splats`]).
pub struct ShadowMap {
    /// The light camera.
    pub camera: Camera,
    /// The sun it was made for.
    pub sun: Sun,
    /// Which depth its texels hold.
    pub depth: DepthMode,
    /// The light-space splat (G-buffers: alpha plus the depth channel).
    pub frame: SplatFrame,
    /// For a map splatted only where receivers look
    /// ([`ShadowPass::shadow_map_for_receivers`]): one u32 per map tile
    /// (`ShadowSettings::tile`, row-major), non-zero where the map was
    /// splatted. Elsewhere `frame`'s G-buffer was not written.
    pub wanted_tiles: Option<Buffer>,
    /// Whether `frame`'s splats, pair lists and tile ranges were freed
    /// ([`ShadowMap::release_splats`]).
    splats_released: bool,
}

impl ShadowMap {
    /// A map of `frame`, its splats kept.
    pub(crate) fn new(camera: Camera, sun: Sun, depth: DepthMode, frame: SplatFrame) -> Self {
        Self { camera, sun, depth, frame, wanted_tiles: None, splats_released: false }
    }

    /// Frees the frame's splat records, pair lists, tile ranges and features,
    /// keeping its texels (the G-buffer), its camera and its wanted tiles:
    /// all that the sigmoid test ([`VisibilityKind::Sigmoid`]) reads. A map
    /// kept for later frames then holds its texels alone, not per-Gaussian
    /// records (640 MB at 10M Gaussians). The traced test and the backward
    /// pass refuse it after; the frame's buffers are 4-byte stand-ins.
    pub fn release_splats(&mut self, device: &Device) -> Result<()> {
        let stand_in = |name: &str| device.create_buffer(name, 4, crate::gpu::MemoryKind::Storage);
        self.frame.splats = stand_in("shadow map splats (released)")?;
        self.frame.pair_offsets = stand_in("shadow map pair offsets (released)")?;
        self.frame.sorted_gaussians = stand_in("shadow map sorted pairs (released)")?;
        self.frame.ranges = stand_in("shadow map tile ranges (released)")?;
        self.frame.features = None;
        self.frame.pair_tiles = None;
        self.splats_released = true;
        Ok(())
    }

    /// Whether [`ShadowMap::release_splats`] freed the frame's splats.
    pub fn splats_released(&self) -> bool {
        self.splats_released
    }

    /// Refuses a map whose splats were released, for `what`, which reads them.
    pub(crate) fn check_splats(&self, what: &str) -> Result<()> {
        if self.splats_released {
            return Err(Error::invalid(
                "shadow map",
                format!("its splats were released (ShadowMap::release_splats); {what} reads them"),
            ));
        }
        Ok(())
    }

    /// The world width of one texel (texels are square).
    pub fn texel_size(&self) -> f32 {
        texel_size(&self.camera)
    }

    /// The texels' depth z_s on the host (empty texels, and those of tiles a
    /// culled map did not splat: `DepthMode::empty_depth`).
    pub fn read_depth(&self, device: &Device, min_alpha: f32) -> Result<Vec<f32>> {
        let g = self.frame.gbuffer.read(device)?;
        let empty = self.depth.empty_depth(self.camera.far);
        let mut depths = cpu::resolve_depths(self.depth, &g, min_alpha, empty);
        if let Some(mask) = &self.wanted_tiles {
            let wanted: Vec<u32> = device.read_buffer(mask)?;
            let tile = self.frame.tile.max(1) as usize;
            let width = self.camera.width as usize;
            let tiles_x = width.div_ceil(tile);
            for (p, z) in depths.iter_mut().enumerate() {
                let t = (p / width / tile) * tiles_x + (p % width) / tile;
                if wanted.get(t).is_none_or(|w| *w == 0) {
                    *z = empty;
                }
            }
        }
        Ok(depths)
    }
}
