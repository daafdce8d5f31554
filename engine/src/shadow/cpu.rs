//! The f64 CPU twin of the shadow kernels: the same inputs (G-buffers read
//! back, the light camera) and the same conventions, plain and obvious.

use glam::{DVec2, DVec3};

use super::{DepthMode, ShadowSettings};
use crate::scene::{Camera, Projection, Scene};
use crate::splat::cpu::{preprocess_one, splat_alpha, tile_lists, CpuSplat};
use crate::splat::{GBuffer, NormalSource, TILE};

/// The logit clamp (keep in sync with `LOGIT_LIMIT` in `shadow.glsl`).
pub const LOGIT_LIMIT: f64 = 30.0;

/// σ(x), stable for any x: e = exp(−|x|) never overflows.
pub fn stable_sigmoid(x: f64) -> f64 {
    let e = (-x.abs()).exp();
    if x >= 0.0 {
        1.0 / (1.0 + e)
    } else {
        e / (1.0 + e)
    }
}

/// log σ(x) = −softplus(−x) = −(max(−x, 0) + ln(1 + exp(−|x|))), stable for any x.
pub fn log_sigmoid(x: f64) -> f64 {
    -((-x).max(0.0) + (-x.abs()).exp().ln_1p())
}

/// The clamped shadow logit k·(z_s − z + bias).
pub fn shadow_logit(zs: f64, z: f64, k: f64, bias: f64) -> f64 {
    (k * (zs - z + bias)).clamp(-LOGIT_LIMIT, LOGIT_LIMIT)
}

/// V = σ(clamped logit): the sigmoid shadow test for one receiver.
pub fn sigmoid_visibility(zs: f64, z: f64, k: f64, bias: f64) -> f64 {
    stable_sigmoid(shadow_logit(zs, z, k, bias))
}

/// Depth of one pixel: median, or expected normalised by alpha; `None`
/// without a surface.
fn pixel_depth(mode: DepthMode, g: &GBuffer, p: usize, min_alpha: f64) -> Option<f64> {
    match mode {
        DepthMode::Median => {
            let z = f64::from(g.median_depth.as_ref()?[p]);
            (z > 0.0).then_some(z)
        }
        DepthMode::Expected => {
            let a = f64::from(g.alpha[p]);
            (a >= min_alpha).then(|| f64::from(g.depth.as_ref().map_or(f32::NAN, |d| d[p])) / a)
        }
    }
}

/// The shadow map's texel depths z_s (empty texels at `far`).
pub fn resolve_depths(mode: DepthMode, map: &GBuffer, min_alpha: f32, far: f32) -> Vec<f32> {
    (0..map.alpha.len()).map(|p| pixel_depth(mode, map, p, f64::from(min_alpha)).map_or(far, |z| z as f32)).collect()
}

/// World point seen at pixel `p` of `camera` at camera depth `z`.
pub fn unproject(camera: &Camera, p: usize, z: f64) -> DVec3 {
    let w = camera.width as usize;
    let px = DVec2::new((p % w) as f64 + 0.5, (p / w) as f64 + 0.5);
    let c = match camera.projection {
        Projection::Pinhole { fx, fy, cx, cy } => {
            DVec3::new((px.x - f64::from(cx)) / f64::from(fx) * z, (px.y - f64::from(cy)) / f64::from(fy) * z, z)
        }
        Projection::Orthographic { sx, sy, cx, cy } => {
            DVec3::new((px.x - f64::from(cx)) / f64::from(sx), (px.y - f64::from(cy)) / f64::from(sy), z)
        }
    };
    camera.rotation.as_dmat3() * c + camera.position.as_dvec3()
}

/// Light-space (u, v) texel coordinates (centres at +0.5) and depth of a world point.
pub fn light_coords(light: &Camera, world: DVec3) -> (DVec2, f64) {
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

/// Where a receiver pixel lands in the map: (uv, z) for a surface inside the map.
pub fn receiver_in_light(
    light: &Camera,
    camera: &Camera,
    receiver: &GBuffer,
    settings: &ShadowSettings,
    p: usize,
) -> Option<(DVec2, f64)> {
    let z = pixel_depth(settings.receiver_depth, receiver, p, f64::from(settings.min_alpha))?;
    let (uv, lz) = light_coords(light, unproject(camera, p, z));
    let inside = uv.x >= 0.0 && uv.y >= 0.0 && uv.x < f64::from(light.width) && uv.y < f64::from(light.height);
    inside.then_some((uv, lz))
}

/// The sigmoid shadow test for every receiver pixel, given the map's texel
/// depths (from [`resolve_depths`]).
pub fn sigmoid_visibility_cpu(
    light: &Camera,
    map_depths: &[f32],
    camera: &Camera,
    receiver: &GBuffer,
    settings: &ShadowSettings,
) -> Vec<f64> {
    (0..receiver.alpha.len())
        .map(|p| {
            let Some((uv, z)) = receiver_in_light(light, camera, receiver, settings, p) else { return 1.0 };
            let (t, w) = bilinear(uv, light.width, light.height);
            let zs: f64 = t.iter().zip(w).map(|(i, w)| w * f64::from(map_depths[*i])).sum();
            sigmoid_visibility(zs, z, f64::from(settings.k), f64::from(settings.bias))
        })
        .collect()
}

/// The traced reference for every receiver pixel: Π(1 − αᵢ) over the light
/// splats nearer the sun than z − bias in the receiver's light tile, α taken
/// at the ray's exact light-space position; 0 once below 1e-4.
pub fn traced_visibility_cpu(
    scene: &Scene,
    light: &Camera,
    camera: &Camera,
    receiver: &GBuffer,
    settings: &ShadowSettings,
) -> Vec<f64> {
    let splats: Vec<Option<CpuSplat>> =
        (0..scene.len()).map(|i| preprocess_one(scene, i, light, NormalSource::ShortestAxis)).collect();
    let lists = tile_lists(&splats, light);
    let tiles_x = light.width.div_ceil(TILE) as usize;
    (0..receiver.alpha.len())
        .map(|p| {
            let Some((uv, z)) = receiver_in_light(light, camera, receiver, settings, p) else { return 1.0 };
            let tile = (uv.y as usize / TILE as usize) * tiles_x + uv.x as usize / TILE as usize;
            let limit = z - f64::from(settings.bias);
            let mut t = 1.0;
            for &(_, i) in &lists[tile] {
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
