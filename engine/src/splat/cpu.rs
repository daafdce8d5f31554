//! The f64 CPU twin of the splatting pipeline: plain, obvious code with the
//! same inputs and the same conventions as the kernels, for tests.
//!
//! Per-tile order is (depth key of the f32 depth, Gaussian index)
//! ([`super::DepthKey`]), which is what the GPU's stable sort of keys emitted
//! in Gaussian order produces.

use glam::{DMat3, DVec2, DVec3};

use super::{Channel, GBuffer, NormalSource, SplatSettings, TileBounds};
use crate::scene::{sh_coefficients, Camera, Projection, Scene};

/// One projected Gaussian.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CpuSplat {
    /// Pixel coordinates of the centre.
    pub mean: DVec2,
    /// Camera z (equirectangular cameras: the distance).
    pub depth: f64,
    /// Activated opacity.
    pub opacity: f64,
    /// Inverse 2D covariance (a, b, c).
    pub conic: [f64; 3],
    /// Radius in pixels.
    pub radius: f64,
    /// SH colour.
    pub color: DVec3,
    /// Tile rectangle [x0, y0, x1, y1) (x1 past the tile columns: a full
    /// panorama's columns continuing at the left edge).
    pub rect: [u32; 4],
    /// The period along x at which the image wraps (a full equirectangular
    /// panorama's width), 0 where it does not.
    pub wrap_period: f64,
    /// normal.xyz, roughness, albedo.rgb, metallic, ao, visibility.
    pub features: [f64; 10],
    /// Surface-depth slope ([`surface_slope`]); zero for centre depths.
    pub depth_slope: [f64; 2],
    /// Whether the camera is orthographic (the slope is then in depth per
    /// pixel, else in relative inverse depth per pixel).
    pub orthographic: bool,
}

impl CpuSplat {
    /// The splat's depth at pixel centre `centre`: its centre's, or where the
    /// pixel's ray meets its plane when it has a surface-depth slope. Twin of
    /// `splat_depth` in `splat_blend_body.glsl`.
    pub fn depth_at(&self, centre: DVec2) -> f64 {
        if self.depth_slope == [0.0; 2] {
            return self.depth;
        }
        let delta = centre - self.mean;
        let s = self.depth_slope[0] * delta.x + self.depth_slope[1] * delta.y;
        if self.orthographic {
            self.depth + s
        } else {
            self.depth / (1.0 + s)
        }
    }
}

/// What a Gaussian's surface-depth slope is computed from (camera space).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct SlopeInputs {
    /// The shortest axis (unturned), camera space.
    pub n: DVec3,
    /// The mean, camera space.
    pub t: DVec3,
    /// Pixels per unit: the focal lengths, or the orthographic scales.
    pub k: DVec2,
    /// Whether the camera is orthographic.
    pub ortho: bool,
    /// 3σ along the view: 3·√Σc[z][z].
    pub extent: f64,
    /// The splat's own 2D covariance JΣcJᵀ (a, b, c), before the dilation.
    pub cov: [f64; 3],
}

/// Gradients of a loss with respect to the [`SlopeInputs`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct SlopeInputGrads {
    pub n: DVec3,
    pub t: DVec3,
    pub extent: f64,
    pub cov: [f64; 3],
}

impl SlopeInputs {
    /// Gaussian `g`'s inputs for `camera`; `None` for lenses other than the
    /// pinhole and for equirectangular cameras (no slope there).
    pub(crate) fn of(g: &Gaussian64, camera: &Camera) -> Option<Self> {
        if !camera.lens.is_pinhole() || camera.depth_is_distance() {
            return None;
        }
        let w = camera.rotation.as_dmat3().transpose();
        let t = w * (g.mean - camera.position.as_dvec3());
        let s = DVec3::new(g.log_scale.x.exp(), g.log_scale.y.exp(), g.log_scale.z.exp());
        let rot = g.rotation_matrix();
        let m = rot * DMat3::from_diagonal(s);
        let cov_cam = w * (m * m.transpose()) * w.transpose();
        let (_, j) = mean_and_jacobian(camera, t);
        let cov2 = j * cov_cam * j.transpose();
        let (k, ortho) = match camera.projection {
            Projection::Pinhole { fx, fy, .. } => (DVec2::new(f64::from(fx), f64::from(fy)), false),
            Projection::Orthographic { sx, sy, .. } => (DVec2::new(f64::from(sx), f64::from(sy)), true),
        };
        Some(Self {
            n: w * rot.col(shortest_axis(s)),
            t,
            k,
            ortho,
            extent: 3.0 * cov_cam.z_axis.z.max(0.0).sqrt(),
            cov: [cov2.x_axis.x, cov2.y_axis.x, cov2.y_axis.y],
        })
    }

    /// The plane's slope before the limit, and the guarded n·t (pinhole) or n.z (orthographic).
    fn unlimited(&self) -> (DVec2, f64) {
        let n = self.n;
        if self.ortho {
            let nz = if n.z.abs() < 1e-6 { 1e-6f64.copysign(n.z) } else { n.z };
            (-DVec2::new(n.x, n.y) / (nz * self.k), nz)
        } else {
            let nt = n.dot(self.t);
            let nt = if nt.abs() < 1e-6 * self.t.z { (1e-6 * self.t.z).copysign(nt) } else { nt };
            (DVec2::new(n.x, n.y) * (self.t.z / nt) / self.k, nt)
        }
    }

    /// 3·√(sᵀ(C + da·I)s): the largest s·Δ over the ellipse ΔᵀC⁻¹Δ ≤ 9.
    fn spread(&self, s: DVec2, da: f64) -> f64 {
        let [a, b, c] = self.cov;
        3.0 * (s.x * s.x * (a + da) + 2.0 * s.x * s.y * b + s.y * s.y * (c + da)).max(0.0).sqrt()
    }

    /// The limit's factor: which of its terms binds is what the backward follows.
    fn limits(&self, s: DVec2) -> [f64; 3] {
        let own = self.spread(s, 0.0);
        if self.ortho {
            [1.0, 1.5 * self.extent / own, f64::INFINITY]
        } else {
            [1.0, 1.5 * self.extent / (self.t.z * own), 0.5 / self.spread(s, 0.3)]
        }
    }

    /// The limited slope in f64 (zero where it is not finite).
    pub(crate) fn slope(&self) -> DVec2 {
        let (s, _) = self.unlimited();
        let scale = self.limits(s).into_iter().fold(f64::INFINITY, f64::min);
        let out = s * scale;
        if out.is_finite() {
            out
        } else {
            DVec2::ZERO
        }
    }

    /// Backward of [`SlopeInputs::slope`]: `d` is dL/d slope. The limit's
    /// binding term is differentiated (a tie takes the first), the guards on
    /// n·t and n.z pass no gradient to n, and a slope that was not finite none at all.
    pub(crate) fn backward(&self, d: DVec2) -> SlopeInputGrads {
        let mut g = SlopeInputGrads::default();
        let (s, guarded) = self.unlimited();
        let limits = self.limits(s);
        let (which, scale) =
            limits.iter().enumerate().fold((0, f64::INFINITY), |m, (i, v)| if *v < m.1 { (i, *v) } else { m });
        if !(s * scale).is_finite() {
            return g;
        }
        let mut ds = d * scale;
        let d_scale = d.dot(s);
        // spread(s, da) = 3√q: dq/ds = 2(Cs), dq/d(a, b, c) = (sx², 2·sx·sy, sy²).
        let mut spread_back = |da: f64, d_spread: f64, ds: &mut DVec2| {
            let sp = self.spread(s, da);
            if sp <= 0.0 {
                return;
            }
            let dq = d_spread * 4.5 / sp;
            let [a, b, c] = self.cov;
            *ds += dq * 2.0 * DVec2::new(s.x * (a + da) + s.y * b, s.x * b + s.y * (c + da));
            g.cov[0] += dq * s.x * s.x;
            g.cov[1] += dq * 2.0 * s.x * s.y;
            g.cov[2] += dq * s.y * s.y;
        };
        match which {
            1 => {
                // 1.5·extent / (z·own) pinhole, 1.5·extent / own orthographic.
                let own = self.spread(s, 0.0);
                g.extent += d_scale * scale / self.extent;
                if !self.ortho {
                    g.t.z -= d_scale * scale / self.t.z;
                }
                spread_back(0.0, -d_scale * scale / own, &mut ds);
            }
            2 => {
                let dilated = self.spread(s, 0.3);
                spread_back(0.3, -d_scale * scale / dilated, &mut ds);
            }
            _ => {}
        }
        let n = self.n;
        if self.ortho {
            // s = −n.xy / (nz·k)
            g.n.x -= ds.x / (guarded * self.k.x);
            g.n.y -= ds.y / (guarded * self.k.y);
            if n.z.abs() >= 1e-6 {
                g.n.z += (ds.x * n.x / self.k.x + ds.y * n.y / self.k.y) / (guarded * guarded);
            }
        } else {
            // s = n.xy·r / k with r = z / (n·t)
            let r = self.t.z / guarded;
            g.n.x += ds.x * r / self.k.x;
            g.n.y += ds.y * r / self.k.y;
            let dr = ds.x * n.x / self.k.x + ds.y * n.y / self.k.y;
            // Where n·t is guarded to ±1e-6·z, r is a constant: no gradient.
            if n.dot(self.t).abs() >= 1e-6 * self.t.z {
                g.t.z += dr / guarded;
                let d_nt = -dr * self.t.z / (guarded * guarded);
                g.n += d_nt * self.t;
                g.t += d_nt * n;
            }
        }
        g
    }
}

/// Index of the shortest of three scales (the first of equal ones), as the kernels pick it.
pub(crate) fn shortest_axis(s: DVec3) -> usize {
    if s.x <= s.y && s.x <= s.z {
        0
    } else if s.y <= s.z {
        1
    } else {
        2
    }
}

/// How the depth where each pixel's ray meets Gaussian `g`'s plane (through
/// its mean, normal its shortest axis) changes across `camera`'s image:
/// pinhole, the relative inverse depth per pixel s (1/z = (1/z₀)(1 + s·Δ));
/// orthographic, the depth per pixel (z = z₀ + s·Δ). Limited so that over the
/// splat's own 3σ footprint (JΣJᵀ before the dilation) the depth moves at most
/// 1.5× its 3σ extent along the view and, pinhole, over the dilated footprint at
/// most half of z₀. Zero for lenses other than the pinhole and for
/// equirectangular cameras. Twin of `surface_slope` in `surface_slope.glsl`.
pub fn surface_slope(g: &Gaussian64, camera: &Camera) -> [f64; 2] {
    SlopeInputs::of(g, camera).map_or([0.0; 2], |inputs| inputs.slope().to_array())
}

const C0: f64 = 0.282_094_791_773_878_14;
const C1: f64 = 0.488_602_511_902_919_9;
const C2: [f64; 5] = [
    1.092_548_430_592_079_2,
    -1.092_548_430_592_079_2,
    0.315_391_565_252_520_05,
    -1.092_548_430_592_079_2,
    0.546_274_215_296_039_6,
];
const C3: [f64; 7] = [
    -0.590_043_589_926_643_5,
    2.890_611_442_640_554,
    -0.457_045_799_464_465_8,
    0.373_176_332_590_115_4,
    -0.457_045_799_464_465_8,
    1.445_305_721_320_277,
    -0.590_043_589_926_643_5,
];

/// SH basis value `k` for unit direction `d` (3DGS convention).
pub fn sh_basis(k: usize, d: DVec3) -> f64 {
    let (x, y, z) = (d.x, d.y, d.z);
    let (xx, yy, zz) = (x * x, y * y, z * z);
    match k {
        0 => C0,
        1 => -C1 * y,
        2 => C1 * z,
        3 => -C1 * x,
        4 => C2[0] * x * y,
        5 => C2[1] * y * z,
        6 => C2[2] * (2.0 * zz - xx - yy),
        7 => C2[3] * x * z,
        8 => C2[4] * (xx - yy),
        9 => C3[0] * y * (3.0 * xx - yy),
        10 => C3[1] * x * y * z,
        11 => C3[2] * y * (4.0 * zz - xx - yy),
        12 => C3[3] * z * (2.0 * zz - 3.0 * xx - 3.0 * yy),
        13 => C3[4] * x * (4.0 * zz - xx - yy),
        14 => C3[5] * z * (xx - yy),
        _ => C3[6] * x * (xx - 3.0 * yy),
    }
}

fn sigmoid(x: f64) -> f64 {
    1.0 / (1.0 + (-x).exp())
}

/// GLSL's `packUnorm2x16` of one value: round(clamp(v, 0, 1) · 65535).
fn unorm16(v: f64) -> u32 {
    (v.clamp(0.0, 1.0) * 65535.0).round() as u32
}

/// GLSL's `packSnorm2x16` of one value: round(clamp(v, −1, 1) · 32767) as 16 bits.
fn snorm16(v: f64) -> u32 {
    u32::from((v.clamp(-1.0, 1.0) * 32767.0).round() as i16 as u16)
}

/// The packed words the preprocess writes for features `f` ([`CpuSplat::features`]
/// order): twin of `pack_features` in `splat_types.glsl`, three (low, high) pairs.
pub fn pack_features(f: &[f64; 10]) -> [u32; 6] {
    [
        snorm16(f[0]) | snorm16(f[1]) << 16,
        snorm16(f[2]) | unorm16(f[3]) << 16,
        unorm16(f[4]) | unorm16(f[5]) << 16,
        unorm16(f[6]) | unorm16(f[7]) << 16,
        unorm16(f[8]) | unorm16(f[9]) << 16,
        0,
    ]
}

/// [`pack_features`] undone, as `unpack_features` in `splat_types.glsl` reads
/// them: each value within half a step (1/65535 or 1/32767) of what was packed.
pub fn unpack_features(p: &[u32; 6]) -> [f64; 10] {
    let half = |w: u32, k: u32| (w >> (16 * k)) & 0xffff;
    let unorm = |w, k| f64::from(half(w, k)) / 65535.0;
    let snorm = |w, k| (f64::from(half(w, k) as u16 as i16) / 32767.0).max(-1.0);
    [
        snorm(p[0], 0),
        snorm(p[0], 1),
        snorm(p[1], 0),
        unorm(p[1], 1),
        unorm(p[2], 0),
        unorm(p[2], 1),
        unorm(p[3], 0),
        unorm(p[3], 1),
        unorm(p[4], 0),
        unorm(p[4], 1),
    ]
}

/// The differentiable parameters of one Gaussian in f64, as stored (before activation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gaussian64 {
    /// World-space centre.
    pub mean: DVec3,
    /// Log of the three axis scales.
    pub log_scale: DVec3,
    /// Rotation quaternion (w, x, y, z), any non-zero length.
    pub rotation: [f64; 4],
    /// Opacity before the sigmoid.
    pub opacity_logit: f64,
}

impl Gaussian64 {
    /// Gaussian `i` of `scene`.
    pub fn from_scene(scene: &Scene, i: usize) -> Self {
        Self {
            mean: DVec3::from_array(scene.means[i].map(f64::from)),
            log_scale: DVec3::from_array(scene.log_scales[i].map(f64::from)),
            rotation: scene.rotations[i].map(f64::from),
            opacity_logit: f64::from(scene.opacity_logits[i]),
        }
    }

    /// Rotation matrix of the normalised quaternion, columns as in `splat_preprocess.comp`.
    pub fn rotation_matrix(&self) -> DMat3 {
        let q = self.rotation;
        let norm = q.iter().map(|c| c * c).sum::<f64>().sqrt();
        let [qw, qx, qy, qz] = q.map(|c| c / norm);
        DMat3::from_cols(
            DVec3::new(1.0 - 2.0 * (qy * qy + qz * qz), 2.0 * (qx * qy + qw * qz), 2.0 * (qx * qz - qw * qy)),
            DVec3::new(2.0 * (qx * qy - qw * qz), 1.0 - 2.0 * (qx * qx + qz * qz), 2.0 * (qy * qz + qw * qx)),
            DVec3::new(2.0 * (qx * qz + qw * qy), 2.0 * (qy * qz - qw * qx), 1.0 - 2.0 * (qx * qx + qy * qy)),
        )
    }
}

/// The projected geometry of one Gaussian (the differentiable part of stage 1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Projected {
    /// Pixel coordinates of the centre.
    pub mean: DVec2,
    /// Camera z (equirectangular cameras: the distance).
    pub depth: f64,
    /// Activated opacity.
    pub opacity: f64,
    /// Inverse 2D covariance (a, b, c).
    pub conic: [f64; 3],
    /// Radius in pixels.
    pub radius: f64,
    /// Tile rectangle [x0, y0, x1, y1) (x1 may pass the tile columns, see [`CpuSplat::rect`]).
    pub rect: [u32; 4],
}

/// Projects one Gaussian: near/far culling, EWA with the clamped Jacobian,
/// dilation, conic, radius and rectangle of `tile`-pixel tiles; `None` when culled.
pub fn project(g: &Gaussian64, camera: &Camera, tile: u32) -> Option<Projected> {
    let r_c2w = camera.rotation.as_dmat3();
    let w = r_c2w.transpose();
    let t = w * (g.mean - camera.position.as_dvec3());
    let (near, far) = (f64::from(camera.near), f64::from(camera.far));
    let depth = if camera.depth_is_distance() { t.length() } else { t.z };
    if !(depth > near && depth < far) {
        return None;
    }
    let s = DVec3::new(g.log_scale.x.exp(), g.log_scale.y.exp(), g.log_scale.z.exp());
    let m = g.rotation_matrix() * DMat3::from_diagonal(s);
    let cov_cam = w * (m * m.transpose()) * w.transpose();
    let (mut mean, j) =
        if camera.lens.is_pinhole() { mean_and_jacobian(camera, t) } else { lens_mean_and_jacobian(camera, t)? };
    let cov2 = j * cov_cam * j.transpose();
    let (a, b, c) = (cov2.x_axis.x + 0.3, cov2.y_axis.x, cov2.y_axis.y + 0.3);
    let det = a * c - b * b;
    if det.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) || !det.is_finite() || !mean.is_finite() {
        return None;
    }
    let conic = [c / det, -b / det, a / det];
    let mid = 0.5 * (a + c);
    let lambda = mid + (mid * mid - det).max(0.1).sqrt();
    let radius = (3.0 * lambda.sqrt()).ceil();
    if !radius.is_finite() || conic.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let tiles = DVec2::new(f64::from(camera.width.div_ceil(tile)), f64::from(camera.height.div_ceil(tile)));
    let tile = f64::from(tile);
    let mut lo = ((mean - radius) / tile).floor().clamp(DVec2::ZERO, tiles);
    let mut hi = (((mean + radius) / tile).floor() + 1.0).clamp(DVec2::ZERO, tiles);
    if let Some(period) = camera.wrap_period() {
        // As the kernel: the mean wrapped into [0, period), columns past the
        // right edge continuing at the left.
        let period = f64::from(period);
        mean.x -= period * (mean.x / period).floor();
        let (mut a, mut b) = (mean.x - radius, mean.x + radius);
        if a < 0.0 {
            (a, b) = (a + period, b + period);
        }
        lo.x = (a / tile).floor();
        hi.x = if b <= period {
            ((b / tile).floor() + 1.0).min(tiles.x)
        } else {
            tiles.x + ((b - period) / tile).floor() + 1.0
        };
        if 2.0 * radius >= period {
            (lo.x, hi.x) = (0.0, tiles.x);
        }
        hi.x = hi.x.min(lo.x + tiles.x);
    }
    let rect = [lo.x as u32, lo.y as u32, hi.x as u32, hi.y as u32];
    if rect[2] <= rect[0] || rect[3] <= rect[1] {
        return None;
    }
    Some(Projected { mean, depth, opacity: sigmoid(g.opacity_logit), conic, radius, rect })
}

/// Pixel position of camera point `t` and the projection's Jacobian (rows 0
/// and 1; the pinhole's clamped beyond 1.3× the half field of view).
pub(crate) fn mean_and_jacobian(camera: &Camera, t: DVec3) -> (DVec2, DMat3) {
    match camera.projection {
        Projection::Pinhole { fx, fy, cx, cy } => {
            let (fx, fy, cx, cy) = (f64::from(fx), f64::from(fy), f64::from(cx), f64::from(cy));
            let (limx, limy) = jacobian_limits(camera);
            let tx = (t.x / t.z).clamp(-limx, limx) * t.z;
            let ty = (t.y / t.z).clamp(-limy, limy) * t.z;
            let j = DMat3::from_cols(
                DVec3::new(fx / t.z, 0.0, 0.0),
                DVec3::new(0.0, fy / t.z, 0.0),
                DVec3::new(-fx * tx / (t.z * t.z), -fy * ty / (t.z * t.z), 0.0),
            );
            (DVec2::new(fx * t.x / t.z + cx, fy * t.y / t.z + cy), j)
        }
        Projection::Orthographic { sx, sy, cx, cy } => {
            let (sx, sy) = (f64::from(sx), f64::from(sy));
            let j = DMat3::from_cols(DVec3::new(sx, 0.0, 0.0), DVec3::new(0.0, sy, 0.0), DVec3::ZERO);
            (DVec2::new(sx * t.x + f64::from(cx), sy * t.y + f64::from(cy)), j)
        }
    }
}

/// Pixel position and Jacobian through the camera's lens (no clamp); `None`
/// where the lens cannot image the point.
fn lens_mean_and_jacobian(camera: &Camera, t: DVec3) -> Option<(DVec2, DMat3)> {
    let Projection::Pinhole { fx, fy, cx, cy } = camera.projection else { return None };
    let (fx, fy) = (f64::from(fx), f64::from(fy));
    let p = t.to_array();
    let d = camera.lens.distort_within(p, camera.lens_limit())?;
    let jn = camera.lens.jacobian(p)?;
    let j = DMat3::from_cols(
        DVec3::new(fx * jn[0][0], fy * jn[1][0], 0.0),
        DVec3::new(fx * jn[0][1], fy * jn[1][1], 0.0),
        DVec3::new(fx * jn[0][2], fy * jn[1][2], 0.0),
    );
    Some((DVec2::new(fx * d[0] + f64::from(cx), fy * d[1] + f64::from(cy)), j))
}

/// Limits of x/z and y/z in the pinhole Jacobian.
pub(crate) fn jacobian_limits(camera: &Camera) -> (f64, f64) {
    match camera.projection {
        Projection::Pinhole { fx, fy, .. } => {
            (1.3 * 0.5 * f64::from(camera.width) / f64::from(fx), 1.3 * 0.5 * f64::from(camera.height) / f64::from(fy))
        }
        Projection::Orthographic { .. } => (f64::INFINITY, f64::INFINITY),
    }
}

/// Stage 1 for one Gaussian, with `tile`-pixel tiles; `None` when culled.
pub fn preprocess_one(
    scene: &Scene,
    i: usize,
    camera: &Camera,
    normal_source: NormalSource,
    tile: u32,
) -> Option<CpuSplat> {
    preprocess_with(&Gaussian64::from_scene(scene, i), scene, i, camera, normal_source, tile)
}

/// Stage 1 for Gaussian `i` of `scene` with its geometry replaced by `g`
/// (colour and materials still from `scene`); for finite differences.
pub(crate) fn preprocess_with(
    g: &Gaussian64,
    scene: &Scene,
    i: usize,
    camera: &Camera,
    normal_source: NormalSource,
    tile: u32,
) -> Option<CpuSplat> {
    let g = *g;
    let pr = project(&g, camera, tile)?;
    let p = g.mean;
    let r_c2w = camera.rotation.as_dmat3();
    let s = DVec3::new(g.log_scale.x.exp(), g.log_scale.y.exp(), g.log_scale.z.exp());
    let rot = g.rotation_matrix();
    let ortho = matches!(camera.projection, Projection::Orthographic { .. });
    let view_dir = r_c2w.z_axis;
    let dir = if ortho { view_dir } else { (p - camera.position.as_dvec3()).normalize() };
    let k = sh_coefficients(scene.sh_degree);
    let mut color = DVec3::ZERO;
    for coef in 0..k {
        let o = (i * k + coef) * 3;
        color += sh_basis(coef, dir)
            * DVec3::new(f64::from(scene.sh[o]), f64::from(scene.sh[o + 1]), f64::from(scene.sh[o + 2]));
    }
    let color = (color + 0.5).max(DVec3::ZERO);

    let mut n = DVec3::ZERO;
    if normal_source == NormalSource::Stored {
        if let Some(normals) = &scene.normals {
            n = DVec3::from_array(normals[i].map(f64::from));
        }
    }
    if n == DVec3::ZERO {
        n = if s.x <= s.y && s.x <= s.z {
            rot.x_axis
        } else if s.y <= s.z {
            rot.y_axis
        } else {
            rot.z_axis
        };
    }
    let mut n = n.normalize();
    let toward = if ortho { -view_dir } else { camera.position.as_dvec3() - p };
    if n.dot(toward) < 0.0 {
        n = -n;
    }
    let m = &scene.materials;
    let one = |v: &Option<Vec<f32>>| v.as_ref().map_or(0.0, |v| sigmoid(f64::from(v[i])));
    let albedo = m.albedo.as_ref().map_or([0.0; 3], |a| a[i].map(|v| sigmoid(f64::from(v))));
    let features = [
        n.x,
        n.y,
        n.z,
        one(&m.roughness),
        albedo[0],
        albedo[1],
        albedo[2],
        one(&m.metallic),
        one(&m.ao),
        one(&m.visibility),
    ];
    Some(CpuSplat {
        mean: pr.mean,
        depth: pr.depth,
        opacity: pr.opacity,
        conic: pr.conic,
        radius: pr.radius,
        color,
        rect: pr.rect,
        features,
        wrap_period: camera.wrap_period().map_or(0.0, f64::from),
        depth_slope: [0.0; 2],
        orthographic: matches!(camera.projection, Projection::Orthographic { .. }),
    })
}

/// α of splat `s` at pixel centre `centre`: min(0.99, o·exp(−σ)); `None` where
/// the blend skips it (σ < 0 or α < 1/255).
pub(crate) fn splat_alpha(s: &CpuSplat, centre: DVec2) -> Option<f64> {
    let mut d = s.mean - centre;
    if s.wrap_period > 0.0 {
        // The copy of the splat nearest the pixel.
        d.x -= s.wrap_period * (d.x / s.wrap_period + 0.5).floor();
    }
    let power = -0.5 * (s.conic[0] * d.x * d.x + s.conic[2] * d.y * d.y) - s.conic[1] * d.x * d.y;
    if power > 0.0 {
        return None;
    }
    let alpha = (s.opacity * power.exp()).min(0.99);
    (alpha >= 1.0 / 255.0).then_some(alpha)
}

/// Tile columns `[x0, x1)` of tile row `ty` (within the splat's rectangle)
/// whose `tile`-pixel square can see splat `s` at α ≥ 1/255, widened as the
/// kernels widen it: o·exp(−½dᵀQd) ≥ 1/255 ⇔ dᵀQd ≤ r² = 2·ln(255·o), taken as
/// 1.01·r² + 0.01, squares grown by 0.01 px; rows keep their whole rectangle
/// row where det Q ≤ 1e-4·a·c (too ill-conditioned for f32).
/// Twin of `tile_row_span` in `splat.glsl`.
pub fn tile_row_span(s: &CpuSplat, ty: u32, tile: u32) -> (u32, u32) {
    let [rx0, _, rx1, _] = s.rect;
    let empty = (rx0, rx0);
    let r2 = 2.02 * (255.0 * s.opacity).ln() + 0.01;
    if r2.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        return empty;
    }
    let [a, b, c] = s.conic;
    let det = a * c - b * b;
    if det.partial_cmp(&(1e-4 * a * c)) != Some(std::cmp::Ordering::Greater) {
        return (rx0, rx1);
    }
    let t = f64::from(tile);
    let y_max = (r2 * a / det).sqrt();
    let lo = (f64::from(ty) * t - 0.01 - s.mean.y).max(-y_max);
    let hi = (f64::from(ty) * t + t + 0.01 - s.mean.y).min(y_max);
    if lo > hi || lo.is_nan() || hi.is_nan() {
        return empty;
    }
    // The right edge (−b·y + sqrt(r²·a − det·y²)) / a is concave in y, largest
    // at y = −y_side; the left edge is convex, smallest at y = +y_side.
    let y_side = b * (r2 / (c * det)).sqrt();
    let (yr, yl) = ((-y_side).clamp(lo, hi), y_side.clamp(lo, hi));
    let xr = (-b * yr + (r2 * a - det * yr * yr).max(0.0).sqrt()) / a;
    let xl = (-b * yl - (r2 * a - det * yl * yl).max(0.0).sqrt()) / a;
    if xl.partial_cmp(&xr) == Some(std::cmp::Ordering::Greater) || xl.is_nan() || xr.is_nan() {
        return (rx0, rx1);
    }
    let first = ((s.mean.x + xl - 0.01) / t - 1.0).ceil();
    let last = ((s.mean.x + xr + 0.01) / t).floor();
    let x0 = first.clamp(f64::from(rx0), f64::from(rx1));
    let x1 = (last + 1.0).clamp(x0, f64::from(rx1));
    (x0 as u32, x1 as u32)
}

/// The tiles of row `ty` that list splat `s` under `bounds`.
pub(crate) fn listed_columns(s: &CpuSplat, ty: u32, tile: u32, bounds: TileBounds) -> std::ops::Range<u32> {
    let (x0, x1) = match bounds {
        // A rectangle that wraps (past the last column) keeps whole rows.
        TileBounds::Ellipse
            if s.wrap_period == 0.0 || f64::from(s.rect[2]) <= (s.wrap_period / f64::from(tile)).ceil() =>
        {
            tile_row_span(s, ty, tile)
        }
        _ => (s.rect[0], s.rect[2]),
    };
    x0..x1
}

/// Per-tile lists of visible splats in blend order: (f32 depth bits, index);
/// `splats` projected with the same `tile`.
pub(crate) fn tile_lists(splats: &[Option<CpuSplat>], camera: &Camera, tile: u32, bounds: TileBounds) -> TileLists {
    let tiles_x = camera.width.div_ceil(tile) as usize;
    let tiles_y = camera.height.div_ceil(tile) as usize;
    let mut lists: Vec<Vec<(u32, usize)>> = vec![Vec::new(); tiles_x * tiles_y];
    let depth_key = super::DepthKey::of(camera);
    for (i, s) in splats.iter().enumerate() {
        if let Some(s) = s {
            for ty in s.rect[1]..s.rect[3] {
                for tx in listed_columns(s, ty, tile, bounds) {
                    let tx = tx as usize % tiles_x;
                    lists[ty as usize * tiles_x + tx].push((depth_key.key(s.depth as f32), i));
                }
            }
        }
    }
    for l in &mut lists {
        l.sort_unstable();
    }
    TileLists { lists, tiles_x, tile: tile as usize }
}

/// Per-tile splat lists, looked up by pixel.
pub(crate) struct TileLists {
    lists: Vec<Vec<(u32, usize)>>,
    tiles_x: usize,
    tile: usize,
}

impl TileLists {
    /// The list of the tile holding pixel (x, y).
    pub(crate) fn at(&self, x: usize, y: usize) -> &[(u32, usize)] {
        &self.lists[(y / self.tile) * self.tiles_x + x / self.tile]
    }
}

/// Work the blend does, counted by replaying it on the CPU twin.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BlendWork {
    /// (pixel, splat) pairs evaluated: every list entry a pixel reads, the
    /// one that ends it included.
    pub evaluated: u64,
    /// Pairs that contributed.
    pub contributed: u64,
    /// The most list entries one pixel reads before it is done. A tile's
    /// list is walked in order by one workgroup, so however many run at
    /// once, a blend lasts at least as long as one walk that far.
    pub longest_walk: u64,
}

/// Work the blend does (see [`BlendWork`]), for benchmarks' flop accounting.
pub fn blend_work(scene: &Scene, camera: &Camera, tile: u32, bounds: TileBounds) -> BlendWork {
    let splats: Vec<Option<CpuSplat>> =
        (0..scene.len()).map(|i| preprocess_one(scene, i, camera, NormalSource::ShortestAxis, tile)).collect();
    let lists = tile_lists(&splats, camera, tile, bounds);
    let mut work = BlendWork::default();
    for y in 0..camera.height as usize {
        for x in 0..camera.width as usize {
            let centre = DVec2::new(x as f64 + 0.5, y as f64 + 0.5);
            let mut t = 1.0f64;
            let mut walk = 0u64;
            for &(_, i) in lists.at(x, y) {
                let Some(s) = &splats[i] else { continue };
                walk += 1;
                let Some(alpha) = splat_alpha(s, centre) else { continue };
                let next = t * (1.0 - alpha);
                if next < 1e-4 {
                    break;
                }
                work.contributed += 1;
                t = next;
            }
            work.evaluated += walk;
            work.longest_walk = work.longest_walk.max(walk);
        }
    }
    work
}

/// Values blended per splat: rgb, depth, then the ten features (normal.xyz,
/// roughness, albedo.rgb, metallic, ao, visibility).
pub(crate) const VALUES: usize = 14;

/// The blended values of a splat.
pub(crate) fn splat_values(s: &CpuSplat) -> [f64; VALUES] {
    let mut v = [0.0; VALUES];
    v[..3].copy_from_slice(&s.color.to_array());
    v[3] = s.depth;
    v[4..].copy_from_slice(&s.features);
    v
}

/// One splat that contributed to a pixel.
#[derive(Clone, Copy, Debug)]
pub struct Contribution {
    /// Gaussian index.
    pub index: usize,
    /// Its α at the pixel.
    pub alpha: f64,
    /// Transmittance before it.
    pub t_before: f64,
}

/// One pixel blended front to back in f64.
#[derive(Clone, Debug)]
pub struct PixelBlend {
    /// Σ wᵢ xᵢ for each of the `VALUES` (no background).
    pub values: [f64; VALUES],
    /// Final transmittance.
    pub t_final: f64,
    /// Depth where T first falls to 1 − the median coverage ([`MedianRule`];
    /// 0 where it never does).
    pub median: f64,
    /// The splat giving the median depth.
    pub median_index: Option<usize>,
    /// The contributing splat with the largest weight wᵢ = αᵢ Tᵢ (the first of equal ones).
    pub top: Option<usize>,
    /// Its weight.
    pub top_weight: f64,
    /// Contributing splats in blend order.
    pub contributions: Vec<Contribution>,
}

/// Which splat gives a pixel's median depth (the blend kernel's
/// `accumulate_select`): the one whose coverage takes T to 1 − `coverage` or
/// below, or, with surface depths, a later one at least `coverage` opaque
/// lying nearer at the pixel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MedianRule {
    /// Surface depths (a later splat can be nearer at a pixel).
    pub surface_depth: bool,
    /// [`crate::splat::SplatSettings::median_coverage`].
    pub coverage: f32,
}

impl MedianRule {
    /// The rule for `depth` at `coverage`.
    pub fn new(depth: DepthAt, coverage: f32) -> Self {
        Self { surface_depth: depth.is_surface(), coverage }
    }

    /// The depths the rule's splats have.
    pub fn depth(self) -> DepthAt {
        if self.surface_depth {
            DepthAt::Surface
        } else {
            DepthAt::Centre
        }
    }

    /// The transmittance the median is read at, rounded as the kernel's
    /// (an f32 specialization constant, 1 − coverage).
    fn transmittance(self) -> f64 {
        f64::from(1.0 - self.coverage)
    }

    /// The opacity a later, nearer splat needs to take the median over (the
    /// kernel's 1 − its transmittance, in f32).
    fn opaque(self) -> f64 {
        f64::from(1.0 - (1.0 - self.coverage))
    }
}

/// Blends the splats of `list` (blend order) at pixel centre `centre`,
/// skipping those whose depth there is not in front of `limit` (a host's depth).
pub(crate) fn blend_pixel(
    list: &[(u32, usize)],
    splats: &[Option<CpuSplat>],
    centre: DVec2,
    limit: f64,
    rule: MedianRule,
) -> PixelBlend {
    let (median_t, opaque) = (rule.transmittance(), rule.opaque());
    let mut out = PixelBlend {
        values: [0.0; VALUES],
        t_final: 1.0,
        median: 0.0,
        median_index: None,
        top: None,
        top_weight: 0.0,
        contributions: Vec::new(),
    };
    let mut t = 1.0f64;
    for &(_, i) in list {
        let Some(s) = &splats[i] else { continue };
        let Some(alpha) = splat_alpha(s, centre) else { continue };
        let depth = s.depth_at(centre);
        // Behind (or at) the host's depth, or NaN: hidden, as `z < limit` fails in the kernel.
        if depth.partial_cmp(&limit) != Some(std::cmp::Ordering::Less) {
            continue;
        }
        let next = t * (1.0 - alpha);
        if next < 1e-4 {
            break;
        }
        let w = alpha * t;
        let mut values = splat_values(s);
        values[3] = depth;
        for (acc, x) in out.values.iter_mut().zip(values) {
            *acc += w * x;
        }
        if t > median_t && next <= median_t {
            out.median = depth;
            out.median_index = Some(i);
        }
        // With surface depths a later splat (in centre order) can be nearer at this
        // pixel: one opaque enough there is the surface the ray meets first.
        if rule.surface_depth && t <= median_t && alpha >= opaque && depth < out.median {
            out.median = depth;
            out.median_index = Some(i);
        }
        if w > out.top_weight {
            out.top = Some(i);
            out.top_weight = w;
        }
        out.contributions.push(Contribution { index: i, alpha, t_before: t });
        t = next;
    }
    out.t_final = t;
    out
}

/// Which depth the twin's splats have at a pixel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DepthAt {
    /// Each splat's centre depth.
    Centre,
    /// Where the pixel's ray meets the splat's plane.
    Surface,
}

impl DepthAt {
    /// Whether the depths are surface depths.
    pub fn is_surface(self) -> bool {
        self != Self::Centre
    }
}

/// Stage 1 in f64 for geometry `params` (colour and materials from `scene`),
/// with the slopes `depth` asks for.
pub fn preprocess_params(
    params: &[Gaussian64],
    scene: &Scene,
    camera: &Camera,
    normal_source: NormalSource,
    tile: u32,
    depth: DepthAt,
) -> Vec<Option<CpuSplat>> {
    let slope = |g: &Gaussian64| match depth {
        DepthAt::Centre => [0.0; 2],
        DepthAt::Surface => surface_slope(g, camera),
    };
    params
        .iter()
        .enumerate()
        .map(|(i, g)| {
            preprocess_with(g, scene, i, camera, normal_source, tile).map(|s| CpuSplat { depth_slope: slope(g), ..s })
        })
        .collect()
}

/// Stages 1–5 in f64 for geometry `params` (colour and materials from
/// `scene`): the projected splats (with the depths `rule` asks for) and
/// every pixel's blend, row-major, its median picked by `rule`.
pub fn render_blends(
    params: &[Gaussian64],
    scene: &Scene,
    camera: &Camera,
    normal_source: NormalSource,
    tile: u32,
    rule: MedianRule,
) -> (Vec<Option<CpuSplat>>, Vec<PixelBlend>) {
    let splats = preprocess_params(params, scene, camera, normal_source, tile, rule.depth());
    let lists = tile_lists(&splats, camera, tile, TileBounds::default());
    let w = camera.width as usize;
    let blends = (0..w * camera.height as usize)
        .map(|p| {
            let (x, y) = (p % w, p / w);
            let centre = DVec2::new(x as f64 + 0.5, y as f64 + 0.5);
            blend_pixel(lists.at(x, y), &splats, centre, f64::INFINITY, rule)
        })
        .collect();
    (splats, blends)
}

/// Stages 1–5 on the CPU.
pub fn render_cpu(scene: &Scene, camera: &Camera, settings: &SplatSettings) -> GBuffer {
    render_cpu_with(scene, camera, settings, None)
}

/// [`render_cpu`] in front of a host's depth (one value per pixel in
/// `convention`), as [`crate::splat::Splatter::render_frame_occluded`].
pub fn render_cpu_occluded(
    scene: &Scene,
    camera: &Camera,
    settings: &SplatSettings,
    depth: &[f32],
    convention: crate::splat::HostDepth,
) -> GBuffer {
    render_cpu_with(scene, camera, settings, Some((depth, convention)))
}

fn render_cpu_with(
    scene: &Scene,
    camera: &Camera,
    settings: &SplatSettings,
    occluder: Option<(&[f32], crate::splat::HostDepth)>,
) -> GBuffer {
    let truncated;
    let scene = match settings.sh_degree {
        Some(d) if d < scene.sh_degree => {
            truncated = scene.with_sh_degree(d);
            &truncated
        }
        _ => scene,
    };
    let (w, h) = (camera.width as usize, camera.height as usize);
    let mut splats: Vec<Option<CpuSplat>> =
        (0..scene.len()).map(|i| preprocess_one(scene, i, camera, settings.normal_source, settings.tile)).collect();
    if settings.surface_depth {
        for (i, s) in splats.iter_mut().enumerate() {
            if let Some(s) = s {
                s.depth_slope = surface_slope(&Gaussian64::from_scene(scene, i), camera);
            }
        }
    }
    let lists = tile_lists(&splats, camera, settings.tile, settings.tile_bounds);
    let rule = MedianRule { surface_depth: settings.surface_depth, coverage: settings.median_coverage };
    let ch = settings.channels;
    let p = w * h;
    let opt = |on: bool, k: usize| on.then(|| vec![0.0f32; k * p]);
    let mut g = GBuffer {
        width: camera.width,
        height: camera.height,
        rgb: opt(settings.rgb, 3),
        alpha: vec![0.0; p],
        channels: ch.iter().map(|c| (c, vec![0.0f32; c.floats() * p])).collect(),
        top_gaussian: ch.top_gaussian.then(|| vec![u32::MAX; p]),
    };
    let bg = settings.background.map(f64::from);
    for y in 0..h {
        for x in 0..w {
            let px = y * w + x;
            let limit =
                occluder.and_then(|(d, c)| d.get(px).map(|v| c.camera_z(f64::from(*v)))).unwrap_or(f64::INFINITY);
            let centre = DVec2::new(x as f64 + 0.5, y as f64 + 0.5);
            let b = blend_pixel(lists.at(x, y), &splats, centre, limit, rule);
            if let Some(rgb) = &mut g.rgb {
                for (c, out) in rgb[3 * px..3 * px + 3].iter_mut().enumerate() {
                    *out = (b.values[c] + b.t_final * bg[c]) as f32;
                }
            }
            g.alpha[px] = (1.0 - b.t_final) as f32;
            if let (Some(top), Some(i)) = (&mut g.top_gaussian, b.top) {
                top[px] = i as u32;
            }
            let f = &b.values[4..];
            for (c, vals) in [
                (Channel::Depth, &b.values[3..4]),
                (Channel::MedianDepth, &[b.median][..]),
                (Channel::Normal, &f[0..3]),
                (Channel::Roughness, &f[3..4]),
                (Channel::Albedo, &f[4..7]),
                (Channel::Metallic, &f[7..8]),
                (Channel::Ao, &f[8..9]),
                (Channel::Visibility, &f[9..10]),
            ] {
                if let Some(v) = g.get_mut(c) {
                    for (k, val) in vals.iter().enumerate() {
                        v[vals.len() * px + k] = *val as f32;
                    }
                }
            }
        }
    }
    g
}

#[cfg(test)]
mod tests {
    use super::{pack_features, unpack_features};

    #[test]
    fn packed_features_round_trip_within_half_a_step_and_clamp_to_their_ranges() {
        let values = [
            [-1.0, 1.0, 0.0, 0.0, 1.0, 0.5, 0.25, 1.0 / 3.0, 0.999_99, 1e-9],
            [0.577_35, -0.577_35, 0.577_35, 0.7, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6],
        ];
        for f in values {
            let back = unpack_features(&pack_features(&f));
            for (k, (b, v)) in back.iter().zip(&f).enumerate() {
                let half_step = if k < 3 { 0.5 / 32767.0 } else { 0.5 / 65535.0 };
                assert!((b - v).abs() <= half_step + 1e-15, "feature {k}: {v} came back {b}");
            }
        }
        // Out of range: clamped as GLSL's packSnorm2x16 / packUnorm2x16 do; -1 and 1 exact.
        let back = unpack_features(&pack_features(&[-2.0, 2.0, -1.0, -0.5, 1.5, 0.0, 1.0, 7.0, -3.0, 0.0]));
        assert_eq!(back, [-1.0, 1.0, -1.0, 0.0, 1.0, 0.0, 1.0, 1.0, 0.0, 0.0]);
        assert_eq!(pack_features(&[0.0; 10])[5], 0, "the last word is padding");
    }
}
