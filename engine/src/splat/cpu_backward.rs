//! The f64 CPU twin of the splatting backward pass: per-pixel loss gradients
//! of the blended outputs → per-splat gradients of the projected quantities
//! (docs/conventions.md §4) → gradients of each Gaussian's stored parameters (mean,
//! log-scale, quaternion, opacity logit). Plain code for tests; the blend
//! backward keeps every pixel's transmittances instead of dividing them back.
//!
//! Not differentiated (as in gsplat): the radius and tile rectangle (discrete),
//! which splat gives the median depth (its depth is, its α is not), the
//! 1/255, 0.99 and 1e-4 cut-offs (zero gradient where they bite), and the SH
//! colour's dependence on the view direction (colour gradients are returned
//! per splat for the caller to take into SH coefficients).

use glam::{DMat2, DMat3, DVec2, DVec3};

use super::cpu::{
    blend_pixel, mean_and_jacobian, project, shortest_axis, splat_alpha, splat_values, tile_lists, CpuSplat,
    Gaussian64, MedianRule, SlopeInputs, VALUES,
};
use crate::scene::{Camera, Projection};

/// Loss gradients per pixel: d/d(Σwx) for the `VALUES` (rgb composited over
/// the background counts as its rgb entries), d/dalpha and d/d(median depth).
#[derive(Clone, Debug, Default)]
pub struct PixelGrads {
    /// dL/d value sums, per pixel.
    pub values: Vec<[f64; VALUES]>,
    /// dL/dalpha per pixel.
    pub alpha: Vec<f64>,
    /// dL/d median depth per pixel.
    pub median: Vec<f64>,
}

/// Gradients of one splat's projected quantities.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SplatGrad {
    /// dL/d centre (pixels).
    pub mean: DVec2,
    /// dL/d conic (a, b, c).
    pub conic: [f64; 3],
    /// dL/d activated opacity.
    pub opacity: f64,
    /// dL/d blended values (index 3: the centre depth, with the median's share
    /// and, for surface depths, each pixel's depth taken back to it).
    pub values: [f64; VALUES],
    /// dL/d surface-depth slope (zero for centre depths).
    pub slope: DVec2,
}

/// Gradients of one Gaussian's stored parameters.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GaussianGrad {
    /// dL/d mean.
    pub mean: DVec3,
    /// dL/d log-scale.
    pub log_scale: DVec3,
    /// dL/d quaternion (w, x, y, z), unnormalised.
    pub rotation: [f64; 4],
    /// dL/d opacity logit.
    pub opacity_logit: f64,
}

/// Backward of the blend for every pixel of `camera`'s image, given the
/// projected splats (from the forward twin, with their slopes for surface
/// depths), the background and the forward's median rule.
pub fn blend_backward_cpu(
    splats: &[Option<CpuSplat>],
    camera: &Camera,
    background: [f64; 3],
    grads: &PixelGrads,
    tile: u32,
    rule: MedianRule,
) -> Vec<SplatGrad> {
    let lists = tile_lists(splats, camera, tile, crate::splat::TileBounds::default());
    let (w, h) = (camera.width as usize, camera.height as usize);
    let mut out = vec![SplatGrad::default(); splats.len()];
    for y in 0..h {
        for x in 0..w {
            let p = y * w + x;
            let centre = DVec2::new(x as f64 + 0.5, y as f64 + 0.5);
            let b = blend_pixel(lists.at(x, y), splats, centre, f64::INFINITY, rule);
            let dv = &grads.values[p];
            // dL/dα terms shared by every contributor: the alpha output and the background.
            let bg_term = grads.alpha[p] - (0..3).map(|c| background[c] * dv[c]).sum::<f64>();
            let mut behind = [0.0f64; VALUES];
            for c in b.contributions.iter().rev() {
                let Some(s) = &splats[c.index] else { continue };
                let mut x = splat_values(s);
                x[3] = s.depth_at(centre);
                let g = &mut out[c.index];
                let mut d_alpha = bg_term * b.t_final / (1.0 - c.alpha);
                for k in 0..VALUES {
                    if k != 3 {
                        g.values[k] += c.alpha * c.t_before * dv[k];
                    }
                    d_alpha += dv[k] * (x[k] * c.t_before - behind[k] / (1.0 - c.alpha));
                    behind[k] += x[k] * c.alpha * c.t_before;
                }
                let median = if b.median_index == Some(c.index) { grads.median[p] } else { 0.0 };
                let d_z = c.alpha * c.t_before * dv[3] + median;
                if rule.surface_depth {
                    add_surface_depth_gradient(g, s, centre, d_z);
                } else {
                    g.values[3] += d_z;
                }
                add_alpha_gradient(g, s, centre, d_alpha);
            }
        }
    }
    out
}

/// Chains dL/dz of splat `s`'s surface depth at `centre` into its centre
/// depth, centre and slope (`CpuSplat::depth_at`).
fn add_surface_depth_gradient(g: &mut SplatGrad, s: &CpuSplat, centre: DVec2, d_z: f64) {
    let delta = centre - s.mean;
    let slope = DVec2::from_array(s.depth_slope);
    let u = slope.dot(delta);
    if s.orthographic {
        // z = z₀ + s·Δ, Δ = centre − mean.
        g.values[3] += d_z;
        g.mean -= d_z * slope;
        g.slope += d_z * delta;
    } else {
        // z = z₀ / (1 + s·Δ).
        let inv = 1.0 / (1.0 + u);
        let dz_du = -s.depth * inv * inv;
        g.values[3] += d_z * inv;
        g.mean -= d_z * dz_du * slope;
        g.slope += d_z * dz_du * delta;
    }
}

/// Chains dL/dα of splat `s` at `centre` into its opacity, conic and centre.
fn add_alpha_gradient(g: &mut SplatGrad, s: &CpuSplat, centre: DVec2, d_alpha: f64) {
    let d = s.mean - centre;
    let power = -0.5 * (s.conic[0] * d.x * d.x + s.conic[2] * d.y * d.y) - s.conic[1] * d.x * d.y;
    let gauss = power.exp();
    if s.opacity * gauss > 0.99 || splat_alpha(s, centre).is_none() {
        return; // clamped or skipped: α does not move with the geometry
    }
    g.opacity += gauss * d_alpha;
    let d_power = s.opacity * gauss * d_alpha;
    g.conic[0] += -0.5 * d.x * d.x * d_power;
    g.conic[1] += -d.x * d.y * d_power;
    g.conic[2] += -0.5 * d.y * d.y * d_power;
    g.mean += -DVec2::new(s.conic[0] * d.x + s.conic[1] * d.y, s.conic[1] * d.x + s.conic[2] * d.y) * d_power;
}

/// dR/dq̂ for the rotation matrix of a unit quaternion (w, x, y, z): entry
/// [c][r] (column c, row r) holds ∂R[r][c]/∂(w, x, y, z).
fn rotation_partials(q: [f64; 4]) -> [[[f64; 4]; 3]; 3] {
    let [w, x, y, z] = q;
    [
        [[0.0, 0.0, -4.0 * y, -4.0 * z], [2.0 * z, 2.0 * y, 2.0 * x, 2.0 * w], [-2.0 * y, 2.0 * z, -2.0 * w, 2.0 * x]],
        [[-2.0 * z, 2.0 * y, 2.0 * x, -2.0 * w], [0.0, -4.0 * x, 0.0, -4.0 * z], [2.0 * x, 2.0 * w, 2.0 * z, 2.0 * y]],
        [[2.0 * y, 2.0 * z, 2.0 * w, 2.0 * x], [-2.0 * x, -2.0 * w, 2.0 * z, 2.0 * y], [0.0, -4.0 * x, -4.0 * y, 0.0]],
    ]
}

/// Backward of [`project`] (and, with `normal_from_rotation`, of the
/// shortest-axis normal): gradients of the stored parameters from a splat's
/// gradients; zero where the Gaussian is culled.
pub fn project_backward(
    g: &Gaussian64,
    camera: &Camera,
    grad: &SplatGrad,
    normal_from_rotation: bool,
    tile: u32,
) -> GaussianGrad {
    let Some(pr) = project(g, camera, tile) else { return GaussianGrad::default() };
    let w = camera.rotation.as_dmat3().transpose();
    let t = w * (g.mean - camera.position.as_dvec3());
    let s = DVec3::new(g.log_scale.x.exp(), g.log_scale.y.exp(), g.log_scale.z.exp());
    let r = g.rotation_matrix();
    let m = r * DMat3::from_diagonal(s);
    let cov_world = m * m.transpose();
    let cov_cam = w * cov_world * w.transpose();
    let (_, j) = mean_and_jacobian(camera, t);

    // Conic = inverse of the dilated 2D covariance Σ2: dΣ2 = −Σ2⁻¹ G Σ2⁻¹, with G the
    // gradient as a symmetric matrix (the conic's b is both off-diagonal entries).
    let [ca, cb, cc] = pr.conic;
    let conic = DMat2::from_cols(glam::DVec2::new(ca, cb), glam::DVec2::new(cb, cc));
    let gm = DMat2::from_cols(
        glam::DVec2::new(grad.conic[0], 0.5 * grad.conic[1]),
        glam::DVec2::new(0.5 * grad.conic[1], grad.conic[2]),
    );
    let mut d_cov2 = -(conic * gm * conic);
    // The surface-depth slope: from the shortest axis, the mean, 3σ along the
    // view and the undilated 2D covariance.
    let slope = (grad.slope != DVec2::ZERO).then(|| SlopeInputs::of(g, camera)).flatten().map(|inputs| {
        let back = inputs.backward(grad.slope);
        let [a, b, c] = back.cov;
        d_cov2 += DMat2::from_cols(DVec2::new(a, 0.5 * b), DVec2::new(0.5 * b, c));
        back
    });
    // Σ2 = J Σc Jᵀ (top-left 2×2): as a 3×3 with the third row/column zero.
    let g2 = DMat3::from_cols(
        DVec3::new(d_cov2.x_axis.x, d_cov2.x_axis.y, 0.0),
        DVec3::new(d_cov2.y_axis.x, d_cov2.y_axis.y, 0.0),
        DVec3::ZERO,
    );
    let mut d_cov_cam = j.transpose() * g2 * j;
    let d_j = 2.0 * g2 * j * cov_cam;
    let mut d_t = DVec3::new(0.0, 0.0, grad.values[3]);
    if let Some(back) = &slope {
        // extent = 3√Σc[z][z]
        if cov_cam.z_axis.z > 0.0 {
            d_cov_cam.z_axis.z += back.extent * 1.5 / cov_cam.z_axis.z.sqrt();
        }
        d_t += back.t;
    }

    // Camera-space position: depth, centre and the Jacobian.
    match camera.projection {
        Projection::Pinhole { fx, fy, .. } => {
            let (fx, fy) = (f64::from(fx), f64::from(fy));
            let z2 = t.z * t.z;
            d_t.x += grad.mean.x * fx / t.z;
            d_t.y += grad.mean.y * fy / t.z;
            d_t.z -= grad.mean.x * fx * t.x / z2 + grad.mean.y * fy * t.y / z2;
            // J = [[fx/z, 0, −fx·tx'/z²], [0, fy/z, −fy·ty'/z²]], tx' = clamp(x/z)·z.
            let (limx, limy) = super::cpu::jacobian_limits(camera);
            d_t.z += d_j.x_axis.x * (-fx / z2) + d_j.y_axis.y * (-fy / z2);
            for (row, f, lim, tc) in [(0usize, fx, limx, t.x), (1, fy, limy, t.y)] {
                let d = d_j.z_axis[row];
                let ratio = tc / t.z;
                if ratio.abs() <= lim {
                    // J[row][2] = −f·tc/z²
                    if row == 0 {
                        d_t.x += d * (-f / z2);
                    } else {
                        d_t.y += d * (-f / z2);
                    }
                    d_t.z += d * (2.0 * f * tc / (z2 * t.z));
                } else {
                    // J[row][2] = −f·(±lim)/z
                    d_t.z += d * (f * lim.copysign(ratio) / z2);
                }
            }
        }
        Projection::Orthographic { sx, sy, .. } => {
            d_t.x += grad.mean.x * f64::from(sx);
            d_t.y += grad.mean.y * f64::from(sy);
        }
    }

    // Σw = M Mᵀ, M = R·S; Σc = W Σw Wᵀ.
    let d_cov_world = w.transpose() * d_cov_cam * w;
    let d_m = (d_cov_world + d_cov_world.transpose()) * m;
    let mut d_r = DMat3::from_cols(d_m.x_axis * s.x, d_m.y_axis * s.y, d_m.z_axis * s.z);
    let d_s = DVec3::new(r.x_axis.dot(d_m.x_axis), r.y_axis.dot(d_m.y_axis), r.z_axis.dot(d_m.z_axis));

    // Shortest-axis normal, turned toward the camera: n = ±R[:, k].
    let dn = DVec3::new(grad.values[4], grad.values[5], grad.values[6]);
    if normal_from_rotation && dn != DVec3::ZERO {
        let k = shortest_axis(s);
        let col = r.col(k);
        let toward = match camera.projection {
            Projection::Orthographic { .. } => -camera.rotation.as_dmat3().z_axis,
            Projection::Pinhole { .. } => camera.position.as_dvec3() - g.mean,
        };
        let sign = if col.dot(toward) < 0.0 { -1.0 } else { 1.0 };
        *d_r.col_mut(k) += sign * dn;
    }

    // The slope's normal n = W·R[:, shortest].
    if let Some(back) = &slope {
        *d_r.col_mut(shortest_axis(s)) += w.transpose() * back.n;
    }

    let q = g.rotation;
    let norm = q.iter().map(|c| c * c).sum::<f64>().sqrt();
    let qn = q.map(|c| c / norm);
    let partials = rotation_partials(qn);
    let mut d_qn = [0.0f64; 4];
    for (c, column) in partials.iter().enumerate() {
        for (r_, entry) in column.iter().enumerate() {
            let gr = d_r.col(c)[r_];
            for (dq, e) in d_qn.iter_mut().zip(entry) {
                *dq += gr * e;
            }
        }
    }
    let dot: f64 = d_qn.iter().zip(&qn).map(|(a, b)| a * b).sum();
    let rotation = [0, 1, 2, 3].map(|i| (d_qn[i] - qn[i] * dot) / norm);

    GaussianGrad {
        mean: w.transpose() * d_t,
        log_scale: d_s * s,
        rotation,
        opacity_logit: grad.opacity * pr.opacity * (1.0 - pr.opacity),
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, reason = "a failed unwrap is a failed test")]
    use glam::Vec3;
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64Mcg;

    use super::*;
    use crate::scene::Scene;
    use crate::splat::cpu::{preprocess_params, render_blends, DepthAt};
    use crate::splat::{NormalSource, DEFAULT_MEDIAN_COVERAGE, DEFAULT_TILE};

    /// A few overlapping Gaussians in front of the camera, with normals from rotation.
    fn scene(rng: &mut Pcg64Mcg, n: usize) -> Scene {
        let mut s = Scene::default();
        for _ in 0..n {
            s.means.push([rng.random_range(-1.0..1.0), rng.random_range(-0.7..0.7), rng.random_range(-0.5..0.5)]);
            s.log_scales.push([
                rng.random_range(-2.2f32..-1.0),
                rng.random_range(-2.2f32..-1.0),
                rng.random_range(-2.2f32..-1.0),
            ]);
            s.rotations.push([
                rng.random_range(0.2..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                0.3,
            ]);
            s.opacity_logits.push(rng.random_range(-1.0..2.0));
            s.sh.extend([rng.random_range(-0.5..0.5), rng.random_range(-0.5..0.5), rng.random_range(-0.5..0.5)]);
        }
        s
    }

    /// L = Σ_p weights·(values, alpha, median) over the image.
    fn loss(
        params: &[Gaussian64],
        scene: &Scene,
        camera: &Camera,
        bg: [f64; 3],
        wts: &PixelGrads,
        rule: MedianRule,
    ) -> f64 {
        let (_, blends) = render_blends(params, scene, camera, NormalSource::ShortestAxis, DEFAULT_TILE, rule);
        let mut total = 0.0;
        for (p, b) in blends.iter().enumerate() {
            let mut v = b.values;
            for c in 0..3 {
                v[c] += b.t_final * bg[c];
            }
            total += v.iter().zip(&wts.values[p]).map(|(a, b)| a * b).sum::<f64>();
            total += (1.0 - b.t_final) * wts.alpha[p] + b.median * wts.median[p];
        }
        total
    }

    fn check(camera: &Camera, seed: u64, depth: DepthAt) {
        check_at(camera, seed, depth, DEFAULT_MEDIAN_COVERAGE);
    }

    /// As `check`, the median read at `coverage`.
    fn check_at(camera: &Camera, seed: u64, depth: DepthAt, coverage: f32) {
        let mut rng = Pcg64Mcg::seed_from_u64(seed);
        let scene = scene(&mut rng, 12);
        let params: Vec<Gaussian64> = (0..scene.len()).map(|i| Gaussian64::from_scene(&scene, i)).collect();
        let pixels = (camera.width * camera.height) as usize;
        let wts = PixelGrads {
            values: (0..pixels).map(|_| std::array::from_fn(|_| rng.random_range(-1.0..1.0))).collect(),
            alpha: (0..pixels).map(|_| rng.random_range(-1.0..1.0)).collect(),
            median: (0..pixels).map(|_| rng.random_range(-1.0..1.0)).collect(),
        };
        let bg = [0.2, 0.5, 0.9];
        let splats = preprocess_params(&params, &scene, camera, NormalSource::ShortestAxis, DEFAULT_TILE, depth);
        let rule = MedianRule::new(depth, coverage);
        let splat_grads = blend_backward_cpu(&splats, camera, bg, &wts, DEFAULT_TILE, rule);
        let mut worst = 0.0f64;
        let mut significant = 0;
        for (i, g) in params.iter().enumerate() {
            let analytic = project_backward(g, camera, &splat_grads[i], true, DEFAULT_TILE);
            // Central differences, step 1e-6 (f64; far below any feature of the loss).
            let h = 1e-6;
            let fd = |perturb: &dyn Fn(&mut Gaussian64, f64)| {
                let mut plus = params.clone();
                perturb(&mut plus[i], h);
                let mut minus = params.clone();
                perturb(&mut minus[i], -h);
                (loss(&plus, &scene, camera, bg, &wts, rule) - loss(&minus, &scene, camera, bg, &wts, rule)) / (2.0 * h)
            };
            let mut pairs: Vec<(&str, f64, f64)> = Vec::new();
            for k in 0..3 {
                pairs.push(("mean", analytic.mean[k], fd(&|g, d| g.mean[k] += d)));
                pairs.push(("log_scale", analytic.log_scale[k], fd(&|g, d| g.log_scale[k] += d)));
            }
            for k in 0..4 {
                pairs.push(("rotation", analytic.rotation[k], fd(&|g, d| g.rotation[k] += d)));
            }
            pairs.push(("opacity_logit", analytic.opacity_logit, fd(&|g, d| g.opacity_logit += d)));
            for (name, a, f) in pairs {
                // Relative error against the larger of |fd| and a floor of 1e-6 (FD noise).
                let err = (a - f).abs() / f.abs().max(1e-6);
                worst = worst.max(err);
                significant += usize::from(f.abs() > 1e-3);
                assert!(err <= 1e-3, "Gaussian {i} {name}: analytic {a:.9e}, finite difference {f:.9e}");
            }
        }
        assert!(splat_grads.iter().any(|g| g.mean != DVec2::ZERO), "no gradient reached any splat");
        if depth.is_surface() {
            let sloped = splat_grads.iter().filter(|g| g.slope.length() > 1e-3).count();
            assert!(sloped >= 6, "only {sloped} splats got a slope gradient");
        }
        // Most of the 12 × 14 derivatives must be far from zero, or the test proves little.
        assert!(significant >= 100, "only {significant} derivatives above 1e-3");
        eprintln!("worst relative error {worst:.2e} over {significant} significant derivatives");
    }

    #[test]
    fn pinhole_gradients_match_finite_differences() {
        let camera = Camera::look_at(Vec3::new(0.3, -0.2, -3.0), Vec3::ZERO, Vec3::Y, 50.0, 40, 28).unwrap();
        check(&camera, 3, DepthAt::Centre);
    }

    #[test]
    fn pinhole_surface_depth_gradients_match_finite_differences() {
        let camera = Camera::look_at(Vec3::new(0.3, -0.2, -3.0), Vec3::ZERO, Vec3::Y, 50.0, 40, 28).unwrap();
        check(&camera, 3, DepthAt::Surface);
        check(&camera, 6, DepthAt::Surface);
    }

    #[test]
    fn orthographic_surface_depth_gradients_match_finite_differences() {
        let camera =
            Camera::orthographic(Vec3::new(0.0, 0.0, -3.0), Vec3::Z, Vec3::Y, 2.6, 2.0, 36, 28, 0.01, 10.0).unwrap();
        check(&camera, 4, DepthAt::Surface);
    }

    #[test]
    fn orthographic_gradients_match_finite_differences() {
        let camera =
            Camera::orthographic(Vec3::new(0.0, 0.0, -3.0), Vec3::Z, Vec3::Y, 2.6, 2.0, 36, 28, 0.01, 10.0).unwrap();
        check(&camera, 4, DepthAt::Centre);
    }

    /// A median read at more coverage (shadow maps' `map_coverage`) moves its gradient to another splat.
    #[test]
    fn gradients_of_a_median_at_more_coverage_match_finite_differences() {
        let camera =
            Camera::orthographic(Vec3::new(0.0, 0.0, -3.0), Vec3::Z, Vec3::Y, 2.6, 2.0, 36, 28, 0.01, 10.0).unwrap();
        check_at(&camera, 4, DepthAt::Centre, 0.6);
        check_at(&camera, 4, DepthAt::Surface, 0.7);
        let camera = Camera::look_at(Vec3::new(0.3, -0.2, -3.0), Vec3::ZERO, Vec3::Y, 50.0, 40, 28).unwrap();
        check_at(&camera, 3, DepthAt::Surface, 0.6);
    }

    #[test]
    fn clamped_jacobian_gradients_match_finite_differences() {
        // A narrow field of view puts several centres beyond 1.3× the half-angle.
        let camera = Camera::look_at(Vec3::new(0.0, 0.0, -3.0), Vec3::ZERO, Vec3::Y, 15.0, 40, 28).unwrap();
        check(&camera, 5, DepthAt::Centre);
    }
}
