//! The f64 CPU twin of the shadow kernels: the same inputs (G-buffers read
//! back, the light camera) and the same conventions, plain and obvious.

use glam::{DVec2, DVec3};

use super::{DepthMode, ShadowFilter, ShadowSettings};
use crate::scene::{Camera, Projection, Scene};
use crate::splat::cpu::{preprocess_one, splat_alpha, tile_lists, CpuSplat, PixelBlend, VALUES};
use crate::splat::cpu_backward::PixelGrads;
use crate::splat::Channel;
use crate::splat::{GBuffer, NormalSource};

/// The logit clamp (keep in sync with `LOGIT_LIMIT` in `shadow.glsl`).
pub(crate) const LOGIT_LIMIT: f64 = 30.0;

/// σ(x), stable for any x: e = exp(−|x|) never overflows.
pub(crate) fn stable_sigmoid(x: f64) -> f64 {
    let e = (-x.abs()).exp();
    if x >= 0.0 {
        1.0 / (1.0 + e)
    } else {
        e / (1.0 + e)
    }
}

/// log σ(x) = −softplus(−x) = −(max(−x, 0) + ln(1 + exp(−|x|))), stable for any x.
pub(crate) fn log_sigmoid(x: f64) -> f64 {
    -((-x).max(0.0) + (-x.abs()).exp().ln_1p())
}

/// The clamped shadow logit k·(z_s − z + bias).
pub(crate) fn shadow_logit(zs: f64, z: f64, k: f64, bias: f64) -> f64 {
    (k * (zs - z + bias)).clamp(-LOGIT_LIMIT, LOGIT_LIMIT)
}

/// V = σ(clamped logit): the sigmoid shadow test for one receiver.
pub(crate) fn sigmoid_visibility(zs: f64, z: f64, k: f64, bias: f64) -> f64 {
    stable_sigmoid(shadow_logit(zs, z, k, bias))
}

/// The depth channels of a rendered image in f64 (a receiver G-buffer or a
/// shadow map): Σwz, alpha and median depth per pixel.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DepthImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Σ wᵢ zᵢ (0 where not rendered).
    pub depth_sum: Vec<f64>,
    /// 1 − T.
    pub alpha: Vec<f64>,
    /// Median depth (0 where T never reaches 0.5, or not rendered).
    pub median: Vec<f64>,
    /// Blended normal per pixel (unnormalised; empty where not rendered).
    pub normal: Vec<DVec3>,
}

impl DepthImage {
    /// From G-buffers read back from the GPU (missing channels read as 0).
    pub fn from_gbuffer(g: &GBuffer) -> Self {
        let n = g.alpha.len();
        let wide = |v: Option<&[f32]>| v.map_or(vec![0.0; n], |v| v.iter().map(|x| f64::from(*x)).collect());
        Self {
            width: g.width,
            height: g.height,
            depth_sum: wide(g.get(Channel::Depth)),
            alpha: g.alpha.iter().map(|x| f64::from(*x)).collect(),
            median: wide(g.get(Channel::MedianDepth)),
            normal: g.get(Channel::Normal).map_or(Vec::new(), |v| {
                v.chunks_exact(3).map(|n| DVec3::new(f64::from(n[0]), f64::from(n[1]), f64::from(n[2]))).collect()
            }),
        }
    }

    /// From the f64 twin's per-pixel blends.
    pub fn from_blends(width: u32, height: u32, blends: &[PixelBlend]) -> Self {
        Self {
            width,
            height,
            depth_sum: blends.iter().map(|b| b.values[3]).collect(),
            alpha: blends.iter().map(|b| 1.0 - b.t_final).collect(),
            median: blends.iter().map(|b| b.median).collect(),
            normal: Vec::new(),
        }
    }

    /// Depth of pixel `p`: median, Σwz / alpha, or Σwz + T·`empty`; `None`
    /// without a surface (never for [`DepthMode::ExpectedOverFar`]).
    pub fn depth(&self, mode: DepthMode, p: usize, min_alpha: f64, empty: f64) -> Option<f64> {
        match mode {
            DepthMode::Median => (self.median[p] > 0.0).then_some(self.median[p]),
            DepthMode::Expected => (self.alpha[p] >= min_alpha).then(|| self.depth_sum[p] / self.alpha[p]),
            DepthMode::ExpectedOverFar => Some(self.depth_sum[p] + (1.0 - self.alpha[p]) * empty),
        }
    }

    /// Adds dL/d(depth of pixel p) = `g` into per-pixel gradients of the channels.
    fn depth_backward(&self, mode: DepthMode, p: usize, g: f64, empty: f64, out: &mut PixelGrads) {
        match mode {
            DepthMode::Median => out.median[p] += g,
            DepthMode::Expected => {
                let a = self.alpha[p];
                out.values[p][3] += g / a;
                out.alpha[p] -= g * self.depth_sum[p] / (a * a);
            }
            DepthMode::ExpectedOverFar => {
                out.values[p][3] += g;
                out.alpha[p] -= g * empty;
            }
        }
    }
}

/// The shadow map's texel depths z_s (empty texels at `empty`).
pub(crate) fn resolve_depths(mode: DepthMode, map: &GBuffer, min_alpha: f32, empty: f32) -> Vec<f32> {
    let img = DepthImage::from_gbuffer(map);
    (0..map.alpha.len())
        .map(|p| img.depth(mode, p, f64::from(min_alpha), f64::from(empty)).map_or(empty, |z| z as f32))
        .collect()
}

/// World point seen at pixel `p` of `camera` at camera depth `z`.
pub fn unproject(camera: &Camera, p: usize, z: f64) -> DVec3 {
    let w = camera.width as usize;
    let px = DVec2::new((p % w) as f64 + 0.5, (p / w) as f64 + 0.5);
    let c = match camera.projection {
        Projection::Pinhole { .. } => {
            let [u, v, w] = camera.pixel_direction([px.x, px.y]).unwrap_or([0.0, 0.0, 1.0]);
            DVec3::new(u * z, v * z, w * z)
        }
        Projection::Orthographic { sx, sy, cx, cy } => {
            DVec3::new((px.x - f64::from(cx)) / f64::from(sx), (px.y - f64::from(cy)) / f64::from(sy), z)
        }
    };
    camera.rotation.as_dmat3() * c + camera.position.as_dvec3()
}

/// Light-space (u, v) texel coordinates (centres at +0.5) and depth of a world point.
pub(crate) fn light_coords(light: &Camera, world: DVec3) -> (DVec2, f64) {
    let t = light.rotation.as_dmat3().transpose() * (world - light.position.as_dvec3());
    let Projection::Orthographic { sx, sy, cx, cy } = light.projection else {
        unreachable!("light cameras are orthographic")
    };
    (DVec2::new(f64::from(sx) * t.x + f64::from(cx), f64::from(sy) * t.y + f64::from(cy)), t.z)
}

/// The bilinear footprint of `uv` in a `w`×`h` map: four texel indices (clamped
/// to the edge) and their weights, ordered (x0,y0), (x1,y0), (x0,y1), (x1,y1).
pub fn bilinear(uv: DVec2, w: u32, h: u32) -> ([usize; 4], [f64; 4]) {
    let s = uv - 0.5;
    let f = s.floor();
    let fr = s - f;
    let clampx = |x: f64| x.clamp(0.0, f64::from(w - 1)) as usize;
    let clampy = |y: f64| y.clamp(0.0, f64::from(h - 1)) as usize;
    let (x0, x1, y0, y1) = (clampx(f.x), clampx(f.x + 1.0), clampy(f.y), clampy(f.y + 1.0));
    let w_ = w as usize;
    (
        [y0 * w_ + x0, y0 * w_ + x1, y1 * w_ + x0, y1 * w_ + x1],
        [(1.0 - fr.x) * (1.0 - fr.y), fr.x * (1.0 - fr.y), (1.0 - fr.x) * fr.y, fr.x * fr.y],
    )
}

/// Where a receiver pixel lands in the map and its depth bias: (uv, z, bias)
/// for a surface inside the map. With a slope bias or normal offset, the
/// receiver's normal n (faced toward the camera) at angle θ to the sun moves
/// the point by n·offset·sin θ and adds slope bias·min(tan θ, `MAX_SLOPE`).
pub(crate) fn receiver_in_light(
    light: &Camera,
    camera: &Camera,
    receiver: &DepthImage,
    settings: &ShadowSettings,
    p: usize,
) -> Option<(DVec2, f64, f64)> {
    let z = receiver.depth(settings.receiver_depth, p, f64::from(settings.min_alpha), 0.0)?;
    let mut world = unproject(camera, p, z);
    let mut bias = f64::from(settings.bias);
    let n = receiver.normal.get(p).copied().unwrap_or(DVec3::ZERO);
    if settings.geometric_bias() && n.length() > 1e-12 {
        let mut n = n.normalize();
        if n.dot(world - camera.position.as_dvec3()) > 0.0 {
            n = -n;
        }
        let texel = f64::from(super::texel_size(light));
        let toward_sun = -(light.rotation.as_dmat3() * DVec3::Z);
        let c = n.dot(toward_sun).clamp(0.0, 1.0);
        let sin = (1.0 - c * c).max(0.0).sqrt();
        world += n * (f64::from(settings.normal_offset) * texel * sin);
        bias += f64::from(settings.slope_bias) * texel * (sin / c.max(1e-6)).min(f64::from(super::MAX_SLOPE));
    }
    let (uv, lz) = light_coords(light, world);
    let inside = uv.x >= 0.0 && uv.y >= 0.0 && uv.x < f64::from(light.width) && uv.y < f64::from(light.height);
    inside.then_some((uv, lz, bias))
}

/// Texel depths z_s of a shadow map (empty texels at [`DepthMode::empty_depth`]).
fn texel_depths(light: &Camera, map: &DepthImage, settings: &ShadowSettings) -> Vec<f64> {
    (0..map.alpha.len())
        .map(|i| {
            let empty = f64::from(settings.map_depth.empty_depth(light.far));
            map.depth(settings.map_depth, i, f64::from(settings.min_alpha), empty).unwrap_or(empty)
        })
        .collect()
}

/// The sigmoid shadow test for every receiver pixel.
pub fn sigmoid_visibility_cpu(
    light: &Camera,
    map: &DepthImage,
    camera: &Camera,
    receiver: &DepthImage,
    settings: &ShadowSettings,
) -> Vec<f64> {
    let zs_texels = texel_depths(light, map, settings);
    (0..receiver.alpha.len())
        .map(|p| {
            let Some((uv, z, bias)) = receiver_in_light(light, camera, receiver, settings, p) else { return 1.0 };
            let (t, w) = bilinear(uv, light.width, light.height);
            let k = f64::from(settings.k);
            match settings.filter {
                ShadowFilter::Depth => {
                    let zs: f64 = t.iter().zip(w).map(|(i, w)| w * zs_texels[*i]).sum();
                    sigmoid_visibility(zs, z, k, bias)
                }
                ShadowFilter::Pcf => {
                    t.iter().zip(w).map(|(i, w)| w * sigmoid_visibility(zs_texels[*i], z, k, bias)).sum()
                }
            }
        })
        .collect()
}

/// What drives the shadow backward pass.
#[derive(Clone, Copy, Debug)]
pub enum VisibilityLoss<'a> {
    /// Upstream gradients dL/dV_e per receiver pixel. Beyond the ±30 logit
    /// clamp V_e is constant and the gradient is zero.
    Upstream(&'a [f64]),
    /// The paper's visibility loss: the mean over receivers with a surface
    /// inside the map of BCE(V_e, V_f), V_f per pixel (a negative V_f leaves
    /// the pixel out), in stable log-sigmoid form on the logit
    /// (clamped to ±`BCE_LOGIT_LIMIT`, so confidently wrong pixels keep their
    /// gradient σ(x) − V_f).
    Bce(&'a [f64]),
}

/// The logit clamp of the BCE loss (keep in sync with `shadow_backward.comp`).
pub(crate) const BCE_LOGIT_LIMIT: f64 = 1e4;

/// Gradients from the sigmoid shadow test.
#[derive(Clone, Debug, Default)]
pub struct ShadowGradients {
    /// The BCE loss (0 for upstream gradients).
    pub loss: f64,
    /// dL/dk.
    pub k: f64,
    /// dL/dz_s per shadow-map texel.
    pub texel_depth: Vec<f64>,
    /// dL/dz per receiver pixel (its light-space depth, the map position held fixed).
    pub light_depth: Vec<f64>,
    /// dL/d the shadow map's channels (light image), for the splat backward.
    pub map: PixelGrads,
    /// dL/d the receiver G-buffer's depth channels (camera image), through
    /// the receiver's light depth and its position in the map.
    pub receiver: PixelGrads,
}

fn zero_grads(n: usize) -> PixelGrads {
    PixelGrads { values: vec![[0.0; VALUES]; n], alpha: vec![0.0; n], median: vec![0.0; n] }
}

/// Backward of [`sigmoid_visibility_cpu`].
pub fn sigmoid_backward_cpu(
    light: &Camera,
    map: &DepthImage,
    camera: &Camera,
    receiver: &DepthImage,
    settings: &ShadowSettings,
    loss: VisibilityLoss<'_>,
) -> ShadowGradients {
    let zs_texels = texel_depths(light, map, settings);
    let k = f64::from(settings.k);
    let n = receiver.alpha.len();
    let mut out = ShadowGradients {
        texel_depth: vec![0.0; zs_texels.len()],
        light_depth: vec![0.0; n],
        map: zero_grads(zs_texels.len()),
        receiver: zero_grads(n),
        ..ShadowGradients::default()
    };
    let min_alpha = f64::from(settings.min_alpha);
    let counted = |p: usize| match loss {
        VisibilityLoss::Bce(target) => target[p] >= 0.0,
        VisibilityLoss::Upstream(_) => true,
    };
    let surfaces =
        (0..n).filter(|p| counted(*p) && receiver_in_light(light, camera, receiver, settings, *p).is_some()).count();
    let Projection::Orthographic { sx, sy, .. } = light.projection else {
        unreachable!("light cameras are orthographic")
    };
    let light_w = light.rotation.as_dmat3().transpose();
    for p in 0..n {
        if !counted(p) {
            continue;
        }
        let Some((uv, z, bias)) = receiver_in_light(light, camera, receiver, settings, p) else { continue };
        let (t, w) = bilinear(uv, light.width, light.height);
        // The receiver's camera depth moves its world point along the pixel ray,
        // which moves both its light depth and where it samples the map.
        let ray = unproject(camera, p, 1.0) - unproject(camera, p, 0.0);
        let d_light = light_w * ray;
        let d_uv = DVec2::new(f64::from(sx) * d_light.x, f64::from(sy) * d_light.y);
        let s = uv - 0.5;
        let f = s - s.floor();
        // ∂/∂u and ∂/∂v of a bilinear blend of four values.
        let slope = |q: [f64; 4]| {
            ((q[1] - q[0]) * (1.0 - f.y) + (q[3] - q[2]) * f.y, (q[2] - q[0]) * (1.0 - f.x) + (q[3] - q[1]) * f.x)
        };
        if settings.filter == ShadowFilter::Pcf {
            // V = Σ wᵢσ(xᵢ); dL/dxᵢ per texel and dL/dwᵢ (hᵢ) for the weights' motion.
            let zt = t.map(|i| zs_texels[i]);
            let raw = zt.map(|zi| k * (zi - z + bias));
            let (mut d_x, mut h) = ([0.0; 4], [0.0; 4]);
            match loss {
                VisibilityLoss::Upstream(g) => {
                    for j in 0..4 {
                        let xc = raw[j].clamp(-LOGIT_LIMIT, LOGIT_LIMIT);
                        h[j] = g[p] * stable_sigmoid(xc);
                        if raw[j].abs() < LOGIT_LIMIT {
                            d_x[j] = g[p] * w[j] * stable_sigmoid(xc) * stable_sigmoid(-xc);
                        }
                    }
                }
                VisibilityLoss::Bce(target) => {
                    // In log space: log V = log Σ wᵢσ(xᵢ), log(1 − V) = log Σ wᵢσ(−xᵢ).
                    let x = raw.map(|r| r.clamp(-BCE_LOGIT_LIMIT, BCE_LOGIT_LIMIT));
                    let log_sum = |sign: f64| {
                        let terms: Vec<f64> =
                            (0..4).filter(|j| w[*j] > 0.0).map(|j| w[j].ln() + log_sigmoid(sign * x[j])).collect();
                        let m = terms.iter().fold(f64::MIN, |a, b| a.max(*b));
                        m + terms.iter().map(|t| (t - m).exp()).sum::<f64>().ln()
                    };
                    let (log_v, log_u) = (log_sum(1.0), log_sum(-1.0));
                    let (vf, n) = (target[p], surfaces as f64);
                    out.loss -= (vf * log_v + (1.0 - vf) * log_u) / n;
                    for j in 0..4 {
                        let (ls, ln) = (log_sigmoid(x[j]), log_sigmoid(-x[j]));
                        h[j] = -(vf * (ls - log_v).exp() + (1.0 - vf) * (ln - log_u).exp()) / n;
                        if w[j] > 0.0 && raw[j].abs() < BCE_LOGIT_LIMIT {
                            let (r, q) = (w[j] * (ls - log_v).exp(), w[j] * (ln - log_u).exp());
                            d_x[j] = (-vf * r * stable_sigmoid(-x[j]) + (1.0 - vf) * q * stable_sigmoid(x[j])) / n;
                        }
                    }
                }
            }
            let mut d_z = 0.0;
            for j in 0..4 {
                out.texel_depth[t[j]] += k * d_x[j];
                out.k += d_x[j] * (zt[j] - z + bias);
                d_z -= k * d_x[j];
            }
            out.light_depth[p] = d_z;
            let (dl_du, dl_dv) = slope(h);
            let d_camera_depth = d_z * d_light.z + dl_du * d_uv.x + dl_dv * d_uv.y;
            receiver.depth_backward(settings.receiver_depth, p, d_camera_depth, 0.0, &mut out.receiver);
            continue;
        }
        let zs: f64 = t.iter().zip(w).map(|(i, w)| w * zs_texels[*i]).sum();
        let raw = k * (zs - z + bias);
        let d_logit = match loss {
            VisibilityLoss::Upstream(g) => {
                if raw.abs() >= LOGIT_LIMIT {
                    continue;
                }
                let s = stable_sigmoid(raw);
                g[p] * s * (1.0 - s)
            }
            VisibilityLoss::Bce(target) => {
                let x = raw.clamp(-BCE_LOGIT_LIMIT, BCE_LOGIT_LIMIT);
                let vf = target[p];
                out.loss -= (vf * log_sigmoid(x) + (1.0 - vf) * log_sigmoid(-x)) / surfaces as f64;
                if raw.abs() >= BCE_LOGIT_LIMIT {
                    continue;
                }
                (stable_sigmoid(x) - vf) / surfaces as f64
            }
        };
        let d_zs = d_logit * k;
        let d_z = -d_logit * k;
        out.k += d_logit * (zs - z + bias);
        out.light_depth[p] = d_z;
        for (i, wi) in t.iter().zip(w) {
            out.texel_depth[*i] += d_zs * wi;
        }
        let (d_zs_du, d_zs_dv) = slope(t.map(|i| zs_texels[i]));
        let d_camera_depth = d_z * d_light.z + d_zs * (d_zs_du * d_uv.x + d_zs_dv * d_uv.y);
        receiver.depth_backward(settings.receiver_depth, p, d_camera_depth, 0.0, &mut out.receiver);
    }
    for (i, g) in out.texel_depth.iter().enumerate() {
        let empty = f64::from(settings.map_depth.empty_depth(light.far));
        if *g != 0.0 && map.depth(settings.map_depth, i, min_alpha, empty).is_some() {
            map.depth_backward(settings.map_depth, i, *g, empty, &mut out.map);
        }
    }
    out
}

/// The traced reference for every receiver pixel: Π(1 − αᵢ) over the light
/// splats nearer the sun than z − bias in the receiver's light tile, α taken
/// at the ray's exact light-space position; 0 once below 1e-4.
pub fn traced_visibility_cpu(
    scene: &Scene,
    light: &Camera,
    camera: &Camera,
    receiver: &DepthImage,
    settings: &ShadowSettings,
) -> Vec<f64> {
    let splats: Vec<Option<CpuSplat>> =
        (0..scene.len()).map(|i| preprocess_one(scene, i, light, NormalSource::ShortestAxis, settings.tile)).collect();
    let lists = tile_lists(&splats, light, settings.tile, crate::splat::TileBounds::default());
    (0..receiver.alpha.len())
        .map(|p| {
            let Some((uv, z, bias)) = receiver_in_light(light, camera, receiver, settings, p) else { return 1.0 };
            let limit = z - bias;
            let mut t = 1.0;
            for &(_, i) in lists.at(uv.x as usize, uv.y as usize) {
                let Some(s) = &splats[i] else { continue };
                if s.depth >= limit {
                    break;
                }
                let Some(alpha) = splat_alpha(s, uv) else { continue };
                t *= 1.0 - alpha;
                if t < 1e-4 {
                    return 0.0;
                }
            }
            t
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sigmoid_is_stable_and_exact_at_the_extremes() {
        for x in [-1e30, -800.0, -30.0, -17.0, 0.0, 17.0, 30.0, 800.0, 1e30] {
            let s = stable_sigmoid(x);
            assert!(s.is_finite() && (0.0..=1.0).contains(&s), "σ({x}) = {s}");
            assert!((s + stable_sigmoid(-x) - 1.0).abs() < 1e-15);
            assert!(log_sigmoid(x).is_finite() || x < -1e300);
        }
        assert!((log_sigmoid(-800.0) + 800.0).abs() < 1e-9);
        assert!((log_sigmoid(2.0) - stable_sigmoid(2.0).ln()).abs() < 1e-15);
        for k in [1e-3, 1.0, 1e9] {
            for dz in [0.0, 1e30, -1e30] {
                let v = sigmoid_visibility(dz, 0.0, k, 0.0);
                assert!(v.is_finite());
                if dz == 0.0 {
                    assert_eq!(v, 0.5);
                }
            }
        }
        assert!(sigmoid_visibility(1.0, 0.0, 1e9, 0.0) > 1.0 - 1e-12);
        assert!(sigmoid_visibility(-1.0, 0.0, 1e9, 0.0) < 1e-12);
    }

    #[test]
    fn bilinear_weights_sum_to_one_and_clamp_at_edges() {
        for uv in [DVec2::new(0.0, 0.0), DVec2::new(3.99, 0.25), DVec2::new(1.5, 1.5), DVec2::new(2.2, 3.7)] {
            let (t, w) = bilinear(uv, 4, 4);
            assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
            assert!(t.iter().all(|i| *i < 16));
        }
        let (t, w) = bilinear(DVec2::new(1.5, 2.5), 4, 4);
        assert_eq!(t[0], 2 * 4 + 1);
        assert!((w[0] - 1.0).abs() < 1e-12);
    }
}
