//! The built-in environment: a procedural clear sky driven by the sun
//! direction (Preetham, Shirley & Smits 1999, "A practical analytic model for
//! daylight"), so relighting needs no file.
//!
//! Units: radiance relative to the sun's S_i, taking S_i as 100 klux at normal
//! incidence, so a sky of zenith luminance Y kcd/m² has radiance Y·S_i/100
//! (about 0.05·S_i at midday). The sun disc itself is not in the map (L_sun
//! adds it analytically). Below the horizon: a grey ground lit by sun and
//! sky. With the sun below the horizon the sky fades out over the 18° of
//! astronomical twilight.

use glam::Vec3;

use super::env::EnvironmentMap;
use super::ktx::latlong_direction;
use crate::error::Result;

/// Parameters of the procedural sky.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProceduralSky {
    /// Unit vector toward the sun (world, z up).
    pub sun_direction: Vec3,
    /// Sun intensity S_i the sky is scaled with.
    pub sun_intensity: f32,
    /// Atmospheric turbidity (2 very clear … 10 hazy).
    pub turbidity: f32,
    /// Albedo of the ground below the horizon.
    pub ground_albedo: f32,
    /// Map size.
    pub size: (u32, u32),
}

impl ProceduralSky {
    /// A clear sky (turbidity 3, ground albedo 0.2, 256×128) for a sun.
    pub fn new(sun_direction: Vec3, sun_intensity: f32) -> Self {
        Self { sun_direction, sun_intensity, turbidity: 3.0, ground_albedo: 0.2, size: (256, 128) }
    }

    /// Renders the lat-long map.
    pub fn render(&self) -> Result<EnvironmentMap> {
        let (w, h) = (self.size.0 as usize, self.size.1 as usize);
        let sun = self.sun_direction.as_dvec3().normalize_or_zero();
        let t = f64::from(self.turbidity.clamp(1.7, 20.0));
        let elevation = sun.z.clamp(-1.0, 1.0).asin();
        // Twilight: the horizon sky fades over the 18° of astronomical twilight (cubic: a
        // quarter of its light at 4.5° below, 3.7% at 12°), so a low sun still lights the scene.
        let twilight = ((elevation.to_degrees() + 18.0) / 18.0).clamp(0.0, 1.0).powi(3).min(1.0);
        // The model holds for a sun above the horizon; below it, the horizon sky fades.
        let theta_s = (std::f64::consts::FRAC_PI_2 - elevation).clamp(0.0, std::f64::consts::FRAC_PI_2 - 0.02);
        let sun_model = glam::DVec3::new(sun.x, sun.y, theta_s.cos()).normalize_or_zero();
        let (yz, xz, yz_c) = zenith(t, theta_s);
        let scale = f64::from(self.sun_intensity.max(0.0)) / 100.0 * twilight;
        let mut rgb = vec![0.0f32; 3 * w * h];
        let mut sky_irradiance = 0.0f64;
        let mut horizon = [0.0f64; 3];
        for y in 0..h {
            let row_top = (0.5 - y as f64 / h as f64) * std::f64::consts::PI;
            let row_bottom = (0.5 - (y + 1) as f64 / h as f64) * std::f64::consts::PI;
            let solid_angle = 2.0 * std::f64::consts::PI / w as f64 * (row_top.sin() - row_bottom.sin());
            for x in 0..w {
                let d = latlong_direction(x, y, w, h);
                if d[2] < 0.0 {
                    continue;
                }
                let cos_theta = d[2].max(0.01);
                let dv = glam::DVec3::from_array(d);
                let gamma = dv.dot(sun_model).clamp(-1.0, 1.0).acos();
                let lum = yz * perez(&PEREZ_Y, t, cos_theta, gamma) / perez(&PEREZ_Y, t, 1.0, theta_s);
                let cx = xz * perez(&PEREZ_X, t, cos_theta, gamma) / perez(&PEREZ_X, t, 1.0, theta_s);
                let cy = yz_c * perez(&PEREZ_YC, t, cos_theta, gamma) / perez(&PEREZ_YC, t, 1.0, theta_s);
                let c = xyy_to_linear_srgb(cx, cy, lum * scale);
                let i = 3 * (y * w + x);
                for k in 0..3 {
                    rgb[i + k] = c[k].max(0.0) as f32;
                }
                sky_irradiance += f64::from(rgb[i] + rgb[i + 1] + rgb[i + 2]) / 3.0 * d[2] * solid_angle;
                if y == h / 2 - 1 {
                    for k in 0..3 {
                        horizon[k] += c[k].max(0.0) / w as f64;
                    }
                }
            }
        }
        // Ground: Lambertian, lit by the sun and the sky; tinted by the horizon colour.
        let sun_irradiance = f64::from(self.sun_intensity.max(0.0)) * sun.z.max(0.0);
        let ground = f64::from(self.ground_albedo) * (sun_irradiance + sky_irradiance) / std::f64::consts::PI;
        let mean_horizon = (horizon[0] + horizon[1] + horizon[2]) / 3.0;
        let tint = if mean_horizon > 0.0 { horizon.map(|c| c / mean_horizon) } else { [1.0; 3] };
        for y in 0..h {
            for x in 0..w {
                if latlong_direction(x, y, w, h)[2] < 0.0 {
                    let i = 3 * (y * w + x);
                    for k in 0..3 {
                        rgb[i + k] = (ground * (0.5 + 0.5 * tint[k])) as f32;
                    }
                }
            }
        }
        EnvironmentMap::from_rgb(self.size.0, self.size.1, rgb, "procedural sky")
    }
}

type Perez = [[f64; 2]; 5];
const PEREZ_Y: Perez = [[0.1787, -1.4630], [-0.3554, 0.4275], [-0.0227, 5.3251], [0.1206, -2.5771], [-0.0670, 0.3703]];
const PEREZ_X: Perez =
    [[-0.0193, -0.2592], [-0.0665, 0.0008], [-0.0004, 0.2125], [-0.0641, -0.8989], [-0.0033, 0.0452]];
const PEREZ_YC: Perez =
    [[-0.0167, -0.2608], [-0.0950, 0.0092], [-0.0079, 0.2102], [-0.0441, -1.6537], [-0.0109, 0.0529]];

/// Perez's luminance distribution F(θ, γ) for turbidity t.
fn perez(c: &Perez, t: f64, cos_theta: f64, gamma: f64) -> f64 {
    let [a, b, cc, d, e] = c.map(|[m, k]| m * t + k);
    (1.0 + a * (b / cos_theta).exp()) * (1.0 + cc * (d * gamma).exp() + e * gamma.cos().powi(2))
}

/// Zenith luminance (kcd/m²) and chromaticity (x, y) for turbidity t and sun zenith angle θs.
fn zenith(t: f64, ts: f64) -> (f64, f64, f64) {
    let chi = (4.0 / 9.0 - t / 120.0) * (std::f64::consts::PI - 2.0 * ts);
    let y = ((4.0453 * t - 4.9710) * chi.tan() - 0.2155 * t + 2.4192).max(0.0);
    let (t2, ts2, ts3) = (t * t, ts * ts, ts * ts * ts);
    let x = t2 * (0.00166 * ts3 - 0.00375 * ts2 + 0.00209 * ts)
        + t * (-0.02903 * ts3 + 0.06377 * ts2 - 0.03202 * ts + 0.00394)
        + (0.11693 * ts3 - 0.21196 * ts2 + 0.06052 * ts + 0.25886);
    let yc = t2 * (0.00275 * ts3 - 0.00610 * ts2 + 0.00317 * ts)
        + t * (-0.04214 * ts3 + 0.08970 * ts2 - 0.04153 * ts + 0.00516)
        + (0.15346 * ts3 - 0.26756 * ts2 + 0.06670 * ts + 0.26688);
    (y, x, yc)
}

/// CIE xyY to linear sRGB (D65).
fn xyy_to_linear_srgb(x: f64, y: f64, lum: f64) -> [f64; 3] {
    if y <= 0.0 {
        return [0.0; 3];
    }
    let (cx, cz) = (x / y * lum, (1.0 - x - y) / y * lum);
    [
        3.2406 * cx - 1.5372 * lum - 0.4986 * cz,
        -0.9689 * cx + 1.8758 * lum + 0.0415 * cz,
        0.0557 * cx - 0.2040 * lum + 1.0570 * cz,
    ]
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, reason = "a failed unwrap is a failed test")]
    use super::*;

    fn mean(elevation_degrees: f32) -> f64 {
        let e = elevation_degrees.to_radians();
        let sky = ProceduralSky { size: (64, 32), ..ProceduralSky::new(Vec3::new(0.0, e.cos(), e.sin()), 3.0) };
        let map = sky.render().unwrap();
        map.rgb.iter().map(|v| f64::from(*v)).sum::<f64>() / map.rgb.len() as f64
    }

    /// A sun below the horizon still lights the sky through twilight, fading
    /// as it sinks, and the sky is dark only past 18° below.
    #[test]
    fn twilight_fades_over_eighteen_degrees() {
        let m: Vec<f64> = [5.0, 0.0, -3.0, -8.0, -14.0, -19.0].into_iter().map(mean).collect();
        assert!(m.windows(2).all(|p| p[1] < p[0]), "the sky darkens as the sun sinks: {m:?}");
        assert!(m[3] > 0.0 && m[4] > 0.0, "twilight sky below the horizon: {m:?}");
        assert_eq!(m[5], 0.0, "night below 18°");
    }
}
