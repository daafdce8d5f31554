//! The f64 CPU twin of the shading stage: environment pyramid, GGX prefilter,
//! irradiance, BRDF table and the two shading kernels, with the same inputs
//! and formulas as `env_*.comp`, `brdf_lut.comp`, `shade_lights.comp` and
//! `shade_compose.comp` (plain loops, no shortcuts).

use std::f64::consts::PI;

use glam::DVec3;

use super::brdf::BrdfLut;
use super::env::level_size;
use super::{Background, ShadeSettings, ShadeTerms, ToneMap, VisibilitySource};
use crate::scene::Camera;
use crate::shadow::Sun;
use crate::splat::Channel;
use crate::splat::GBuffer;

/// N·V is clamped from below (keep in sync with `MIN_NOV` in `brdf.glsl`).
pub(crate) const MIN_NOV: f64 = 1e-4;

/// GGX D.
pub(crate) fn d_ggx(noh: f64, alpha: f64) -> f64 {
    let a2 = alpha * alpha;
    let d = noh * noh * (a2 - 1.0) + 1.0;
    a2 / (PI * d * d).max(1e-30)
}

/// Schlick–Smith G1.
pub(crate) fn g1_schlick(x: f64, k: f64) -> f64 {
    x / (x * (1.0 - k) + k)
}

/// Smith Λ of GGX.
pub(crate) fn lambda_ggx(x: f64, alpha: f64) -> f64 {
    let x2 = (x * x).max(1e-12);
    0.5 * (-1.0 + (1.0 + alpha * alpha * (1.0 - x2) / x2).sqrt())
}

/// Fresnel–Schlick.
pub(crate) fn fresnel_schlick(voh: f64, f0: DVec3) -> DVec3 {
    let f = (1.0 - voh.clamp(0.0, 1.0)).powi(5);
    f0 + (DVec3::ONE - f0) * f
}

/// Point i of an n-point Hammersley set.
pub(crate) fn hammersley(i: u32, n: u32) -> (f64, f64) {
    (f64::from(i) / f64::from(n), f64::from(i.reverse_bits()) * 2.328_306_436_538_696_3e-10)
}

/// GGX half vector around +z.
pub(crate) fn sample_ggx(xi: (f64, f64), alpha: f64) -> DVec3 {
    let phi = 2.0 * PI * xi.0;
    // tan²θ form, as brdf.glsl (keep in sync): exact at α = 0.
    let tan2 = alpha * alpha * xi.1 / (1.0 - xi.1);
    let cos_t = (1.0 + tan2).sqrt().recip();
    let sin_t = tan2.sqrt() * cos_t;
    DVec3::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t)
}

fn tangent_frame(n: DVec3) -> (DVec3, DVec3) {
    let up = if n.z.abs() < 0.999 { DVec3::Z } else { DVec3::X };
    let t = up.cross(n).normalize();
    (t, n.cross(t))
}

/// Texel coordinates of a direction in a w×h lat-long map.
pub fn latlong_coords(d: DVec3, size: (u32, u32)) -> (f64, f64) {
    let phi = d.x.atan2(d.y);
    let theta = d.z.atan2(d.x.hypot(d.y));
    ((0.5 + phi / (2.0 * PI)) * f64::from(size.0), (0.5 - theta / PI) * f64::from(size.1))
}

/// Direction through texel (x, y).
pub fn latlong_direction(x: u32, y: u32, size: (u32, u32)) -> DVec3 {
    let phi = ((f64::from(x) + 0.5) / f64::from(size.0) - 0.5) * 2.0 * PI;
    let theta = (0.5 - (f64::from(y) + 0.5) / f64::from(size.1)) * PI;
    DVec3::new(theta.cos() * phi.sin(), theta.cos() * phi.cos(), theta.sin())
}

fn texel(level: &[f64], size: (u32, u32), x: i64, y: i64) -> DVec3 {
    let x = x.rem_euclid(i64::from(size.0)) as usize;
    let y = y.clamp(0, i64::from(size.1) - 1) as usize;
    let i = 3 * (y * size.0 as usize + x);
    DVec3::new(level[i], level[i + 1], level[i + 2])
}

/// Bilinear sample (u wraps, v clamps).
pub(crate) fn latlong_sample(level: &[f64], size: (u32, u32), d: DVec3) -> DVec3 {
    let (sx, sy) = latlong_coords(d, size);
    let (sx, sy) = (sx - 0.5, sy - 0.5);
    let (fx, fy) = (sx.floor(), sy.floor());
    let (wx, wy) = (sx - fx, sy - fy);
    let (x, y) = (fx as i64, fy as i64);
    let top = texel(level, size, x, y).lerp(texel(level, size, x + 1, y), wx);
    let bottom = texel(level, size, x, y + 1).lerp(texel(level, size, x + 1, y + 1), wx);
    top.lerp(bottom, wy)
}

/// Trilinear sample of a chain (`levels[l]` has size `level_size(base, l)`).
pub(crate) fn latlong_sample_lod(levels: &[Vec<f64>], base: (u32, u32), d: DVec3, lod: f64) -> DVec3 {
    let n = levels.len();
    let lod = lod.clamp(0.0, (n - 1) as f64);
    let l0 = lod.floor() as usize;
    let l1 = (l0 + 1).min(n - 1);
    let t = lod - l0 as f64;
    let a = latlong_sample(&levels[l0], level_size(base, l0 as u32), d);
    if t == 0.0 || l1 == l0 {
        return a;
    }
    a.lerp(latlong_sample(&levels[l1], level_size(base, l1 as u32), d), t)
}

/// One 2×2 box step of the pyramid.
pub(crate) fn downsample_cpu(src: &[f64], size: (u32, u32)) -> Vec<f64> {
    let d = ((size.0 >> 1).max(1), (size.1 >> 1).max(1));
    let mut out = Vec::with_capacity(3 * (d.0 * d.1) as usize);
    for y in 0..d.1 {
        for x in 0..d.0 {
            let (x0, y0) = ((2 * x).min(size.0 - 1), (2 * y).min(size.1 - 1));
            let (x1, y1) = ((2 * x + 1).min(size.0 - 1), (2 * y + 1).min(size.1 - 1));
            let s = [(x0, y0), (x1, y0), (x0, y1), (x1, y1)]
                .iter()
                .map(|&(a, b)| texel(src, size, i64::from(a), i64::from(b)))
                .sum::<DVec3>()
                * 0.25;
            out.extend(s.to_array());
        }
    }
    out
}

/// The whole pyramid of an environment, level 0 first.
pub fn pyramid_cpu(rgb: &[f32], base: (u32, u32)) -> Vec<Vec<f64>> {
    let n = super::env::pyramid_levels(base);
    let mut levels = vec![rgb.iter().map(|&v| f64::from(v)).collect::<Vec<_>>()];
    for l in 1..n {
        let next = downsample_cpu(&levels[l as usize - 1], level_size(base, l - 1));
        levels.push(next);
    }
    levels
}

/// One prefiltered level of roughness `r` from the pyramid.
pub fn prefilter_cpu(pyramid: &[Vec<f64>], base: (u32, u32), r: f64, samples: u32, dst: (u32, u32)) -> Vec<f64> {
    let mut out = Vec::with_capacity(3 * (dst.0 * dst.1) as usize);
    let alpha = r * r;
    let texel_solid_angle = 4.0 * PI / f64::from(base.0 * base.1);
    for y in 0..dst.1 {
        for x in 0..dst.0 {
            let n = latlong_direction(x, y, dst);
            let c = if r <= 0.0 {
                latlong_sample(&pyramid[0], base, n)
            } else {
                let (t, b) = tangent_frame(n);
                let (mut sum, mut weight) = (DVec3::ZERO, 0.0);
                for s in 0..samples {
                    let hl = sample_ggx(hammersley(s, samples), alpha);
                    let h = hl.x * t + hl.y * b + hl.z * n;
                    let l = 2.0 * hl.z * h - n;
                    let nol = n.dot(l);
                    if nol <= 0.0 {
                        continue;
                    }
                    let pdf = d_ggx(hl.z, alpha) * 0.25;
                    let sample_solid_angle = 1.0 / (f64::from(samples) * pdf + 1e-30);
                    let lod = (0.5 * (sample_solid_angle / texel_solid_angle).log2() + 1.0).max(0.0);
                    sum += latlong_sample_lod(pyramid, base, l.normalize(), lod) * nol;
                    weight += nol;
                }
                if weight > 0.0 {
                    sum / weight
                } else {
                    latlong_sample(&pyramid[0], base, n)
                }
            };
            out.extend(c.to_array());
        }
    }
    out
}

/// Irradiance map from one pyramid level (normalised cosine kernel).
pub fn irradiance_cpu(level: &[f64], src: (u32, u32), dst: (u32, u32)) -> Vec<f64> {
    let mut out = Vec::with_capacity(3 * (dst.0 * dst.1) as usize);
    let dphi = 2.0 * PI / f64::from(src.0);
    for y in 0..dst.1 {
        for x in 0..dst.0 {
            let n = latlong_direction(x, y, dst);
            let (mut sum, mut weight) = (DVec3::ZERO, 0.0);
            for sy in 0..src.1 {
                let top = (0.5 - f64::from(sy) / f64::from(src.1)) * PI;
                let bottom = (0.5 - f64::from(sy + 1) / f64::from(src.1)) * PI;
                let solid_angle = dphi * (top.sin() - bottom.sin());
                for sx in 0..src.0 {
                    let c = n.dot(latlong_direction(sx, sy, src)).max(0.0) * solid_angle;
                    sum += c * texel(level, src, i64::from(sx), i64::from(sy));
                    weight += c;
                }
            }
            let e = if weight > 0.0 { sum * (PI / weight) } else { DVec3::ZERO };
            out.extend(e.to_array());
        }
    }
    out
}

/// The split-sum (A, B) at one (N·V, roughness) by `samples` Hammersley points.
pub fn brdf_lut_point(variant: BrdfLut, nov: f64, r: f64, samples: u32) -> (f64, f64) {
    let nov = nov.max(MIN_NOV);
    let alpha = r * r;
    let v = DVec3::new((1.0 - nov * nov).sqrt(), 0.0, nov);
    let (mut a, mut b) = (0.0, 0.0);
    for s in 0..samples {
        let h = sample_ggx(hammersley(s, samples), alpha);
        let voh = v.dot(h);
        let l = 2.0 * voh * h - v;
        let nol = l.z;
        if nol <= 0.0 {
            continue;
        }
        let (noh, voh) = (h.z.max(0.0), voh.max(0.0));
        let g = match variant {
            BrdfLut::Karis => {
                let k = alpha * 0.5;
                g1_schlick(nov, k) * g1_schlick(nol, k)
            }
            BrdfLut::HeightCorrelated => 1.0 / (1.0 + lambda_ggx(nov, alpha) + lambda_ggx(nol, alpha)),
        };
        let g_vis = g * voh / (noh * nov).max(1e-30);
        let fc = (1.0 - voh).powi(5);
        a += (1.0 - fc) * g_vis;
        b += fc * g_vis;
    }
    (a / f64::from(samples), b / f64::from(samples))
}

/// The whole table: (A, B) for N·V = i/(size−1), roughness j/(size−1).
pub fn brdf_table_cpu(variant: BrdfLut, size: u32, samples: u32) -> Vec<f64> {
    let mut out = Vec::with_capacity(2 * (size * size) as usize);
    let step = f64::from(size - 1);
    for j in 0..size {
        for i in 0..size {
            let (a, b) = brdf_lut_point(variant, f64::from(i) / step, f64::from(j) / step, samples);
            out.extend([a, b]);
        }
    }
    out
}

/// Bilinear lookup in a table from [`brdf_table_cpu`] (or the GPU's).
pub(crate) fn brdf_table_lookup(table: &[f64], size: u32, nov: f64, r: f64) -> (f64, f64) {
    let ts = f64::from(size - 1);
    let (sx, sy) = (nov * ts, r * ts);
    let (fx, fy) = (sx.min(ts - 1.0).floor(), sy.min(ts - 1.0).floor());
    let (wx, wy) = (sx - fx, sy - fy);
    let base = fy as usize * size as usize + fx as usize;
    let at = |i: usize| (table[2 * i], table[2 * i + 1]);
    let lerp = |p: (f64, f64), q: (f64, f64), t: f64| (p.0 + (q.0 - p.0) * t, p.1 + (q.1 - p.1) * t);
    let s = size as usize;
    lerp(lerp(at(base), at(base + 1), wx), lerp(at(base + s), at(base + s + 1), wx), wy)
}

/// The prepared lighting tables as f64, for [`shade_cpu`].
pub struct ShadeTables {
    /// Specular chain level-0 size.
    pub base: (u32, u32),
    /// Specular chain, one `Vec` per level.
    pub specular: Vec<Vec<f64>>,
    /// Irradiance size.
    pub irradiance_size: (u32, u32),
    /// Irradiance texels.
    pub irradiance: Vec<f64>,
    /// BRDF table size.
    pub lut_size: u32,
    /// BRDF table, (A, B) per texel.
    pub lut: Vec<f64>,
}

/// The twin's outputs, RGB per pixel.
pub struct ShadedCpu {
    /// L_sun.
    pub sun: Vec<f64>,
    /// L_sky.
    pub sky: Vec<f64>,
    /// Linear radiance over the background.
    pub radiance: Vec<f64>,
    /// Display values.
    pub display: Vec<f64>,
}

fn pixel_ray(camera: &Camera, p: usize) -> DVec3 {
    let w = camera.width as usize;
    let (px, py) = ((p % w) as f64 + 0.5, (p / w) as f64 + 0.5);
    let c = camera.pixel_direction([px, py]).map_or(DVec3::Z, DVec3::from);
    (camera.rotation.as_dmat3() * c).normalize()
}

fn env_dir(d: DVec3, rho: f64) -> DVec3 {
    let (s, c) = rho.sin_cos();
    DVec3::new(d.x * c - d.y * s, d.x * s + d.y * c, d.z)
}

/// sRGB encoding of a linear value (clamped to [0, 1]).
pub fn srgb_encode(c: f64) -> f64 {
    let c = c.clamp(0.0, 1.0);
    if c <= 0.003_130_8 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

/// sRGB decoding of an encoded value (clamped to [0, 1]).
pub fn srgb_decode(c: f64) -> f64 {
    let c = c.clamp(0.0, 1.0);
    if c <= 0.040_45 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// Tone map `op` of one linear value.
pub fn tone_map(c: f64, op: ToneMap) -> f64 {
    match op {
        ToneMap::Clamp => c,
        ToneMap::Reinhard => c / (1.0 + c),
        ToneMap::Aces => (c * (2.51 * c + 0.03)) / (c * (2.43 * c + 0.59) + 0.14),
    }
}

/// Shades a host G-buffer like `shade_lights.comp` then `shade_compose.comp`.
/// `editable` is V_e per pixel; `indirect` L_ind (planar: R plane, G plane, B plane).
pub fn shade_cpu(
    g: &GBuffer,
    camera: &Camera,
    tables: &ShadeTables,
    sun: Option<&Sun>,
    settings: &ShadeSettings,
    editable: Option<&[f32]>,
    indirect: Option<&[f32]>,
) -> ShadedCpu {
    let pixels = g.width as usize * g.height as usize;
    let sun = sun.filter(|s| s.above_horizon());
    let visibility = if sun.is_none() { VisibilitySource::None } else { settings.visibility };
    let terms: ShadeTerms = settings.terms;
    let rho = f64::from(settings.env_rotation_degrees).to_radians();
    let intensity = f64::from(settings.env_intensity);
    let levels = tables.specular.len();
    let f3 =
        |v: Option<&[f32]>, p: usize| v.map(|v| DVec3::new(v[3 * p].into(), v[3 * p + 1].into(), v[3 * p + 2].into()));
    let f1 = |v: Option<&[f32]>, p: usize, ia: f64, fallback: f64| {
        v.map_or(fallback, |v| (f64::from(v[p]) * ia).clamp(0.0, 1.0))
    };
    let mut out = ShadedCpu {
        sun: vec![0.0; 3 * pixels],
        sky: vec![0.0; 3 * pixels],
        radiance: vec![0.0; 3 * pixels],
        display: vec![0.0; 3 * pixels],
    };
    let min_alpha = f64::from(settings.min_alpha);
    for p in 0..pixels {
        let alpha = f64::from(g.alpha[p]);
        let ray = pixel_ray(camera, p);
        let (mut l_sun, mut l_sky) = (DVec3::ZERO, DVec3::ZERO);
        if alpha >= min_alpha {
            let ia = 1.0 / alpha;
            let v = -ray;
            let n = f3(g.get(Channel::Normal), p).unwrap_or(DVec3::ZERO);
            let n = if n.length() > 1e-12 { n.normalize() } else { v };
            let albedo = (f3(g.get(Channel::Albedo), p).unwrap_or(DVec3::ZERO) * ia).clamp(DVec3::ZERO, DVec3::ONE);
            let r = f1(g.get(Channel::Roughness), p, ia, 1.0);
            let m = f1(g.get(Channel::Metallic), p, ia, 0.0);
            let ao = f1(g.get(Channel::Ao), p, ia, 1.0);
            let vis = match visibility {
                VisibilitySource::None => 1.0,
                VisibilitySource::Fixed => f1(g.get(Channel::Visibility), p, ia, 1.0),
                VisibilitySource::Editable => editable.map_or(1.0, |e| f64::from(e[p]).clamp(0.0, 1.0)),
            };
            let f0 = DVec3::splat(0.04).lerp(albedo, m);
            let diffuse = (1.0 - m) * albedo / PI;
            let nov = n.dot(v).max(MIN_NOV);
            let alpha_r = r * r;
            if let Some(s) = sun {
                let l = s.direction.as_dvec3();
                let nol = n.dot(l);
                if nol > 0.0 && vis > 0.0 {
                    let hv = v + l;
                    let h = if hv.length() > 1e-12 { hv.normalize() } else { n };
                    let (noh, voh) = (n.dot(h).max(0.0), v.dot(h).max(0.0));
                    let k = (r + 1.0) * (r + 1.0) / 8.0;
                    let g = g1_schlick(nov, k) * g1_schlick(nol, k);
                    let spec = d_ggx(noh, alpha_r) * fresnel_schlick(voh, f0) * g / (4.0 * nov);
                    let mut f = DVec3::ZERO;
                    if terms.sun_diffuse {
                        f += diffuse * nol;
                    }
                    if terms.sun_specular {
                        f += spec;
                    }
                    l_sun = f * DVec3::from_array(s.intensity.map(f64::from)) * vis;
                }
            }
            if terms.sky_diffuse {
                let e = latlong_sample(&tables.irradiance, tables.irradiance_size, env_dir(n, rho)) * intensity;
                l_sky += diffuse * e * ao;
            }
            if terms.sky_specular {
                let refl = 2.0 * n.dot(v) * n - v;
                let pre = latlong_sample_lod(
                    &tables.specular,
                    tables.base,
                    env_dir(refl.normalize(), rho),
                    r * (levels - 1) as f64,
                ) * intensity;
                let (a, b) = brdf_table_lookup(&tables.lut, tables.lut_size, nov, r);
                l_sky += pre * (f0 * a + DVec3::splat(b));
            }
        }
        let alpha_c = alpha.clamp(0.0, 1.0);
        let mut lo = DVec3::ZERO;
        if alpha_c >= min_alpha {
            lo = l_sun + l_sky;
            if let Some(ind) = indirect {
                lo += DVec3::new(ind[p].into(), ind[pixels + p].into(), ind[2 * pixels + p].into());
            }
        }
        let bg = match settings.background {
            Background::Environment => latlong_sample(&tables.specular[0], tables.base, env_dir(ray, rho)) * intensity,
            Background::Color(c) => DVec3::from_array(c.map(f64::from)),
        };
        let radiance = alpha_c * lo + (1.0 - alpha_c) * bg;
        let exposure = 2f64.powf(f64::from(settings.exposure_ev));
        for c in 0..3 {
            out.sun[3 * p + c] = l_sun[c];
            out.sky[3 * p + c] = l_sky[c];
            out.radiance[3 * p + c] = radiance[c];
            let t = tone_map((radiance[c] * exposure).max(0.0), settings.tone_map).max(0.0);
            out.display[3 * p + c] = srgb_encode(t);
        }
    }
    out
}
