//! The sigmoid shadow test's backward pass on the GPU: against its f64 CPU
//! twin on the demo city (same inputs: the GPU's G-buffers), end to end to the
//! Gaussians against central finite differences of the f64 CPU pipeline, and
//! finite at the extremes (k from 1e-3 to 1e9, depth differences of ±1e30, the
//! sun at 0.01° and 90°, receivers on the occluder, an empty shadow map).

#![allow(clippy::unwrap_used, clippy::expect_used, reason = "a failed unwrap is a failed test")]

use glam::Vec3;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;
use srug::gpu::{Buffer, Device};
use srug::scene::activate::GpuScene;
use srug::scene::demo::{demo_city, DemoOptions};
use srug::scene::{Camera, Scene};
use srug::shadow::backward::GpuVisibilityLoss;
use srug::shadow::cpu::{sigmoid_backward_cpu, sigmoid_visibility_cpu, DepthImage, VisibilityLoss};
use srug::shadow::{light_camera, DepthMode, ShadowFilter, ShadowFit, ShadowPass, ShadowSettings, Sun};
use srug::splat::backward::HostGaussianGradients;
use srug::splat::cpu::{render_blends, CpuSplat, DepthAt, Gaussian64, MedianRule, PixelBlend};
use srug::splat::cpu_backward::{blend_backward_cpu, project_backward, GaussianGrad};
use srug::splat::Channel;
use srug::splat::{Channels, NormalSource, SplatFrame, SplatSettings, Splatter, DEFAULT_TILE};
use srug_tests::{assert_no_validation_messages, device, save_comparison};

fn read(d: &Device, b: Option<&Buffer>) -> Vec<f64> {
    d.read_buffer::<f32>(b.expect("gradient present")).unwrap().iter().map(|v| f64::from(*v)).collect()
}

/// |gpu − cpu| ≤ tol·max(|cpu|, floor·max|cpu|) everywhere.
fn close(label: &str, gpu: &[f64], cpu: &[f64], tol: f64, floor: f64, size: (u32, u32)) {
    assert_eq!(gpu.len(), cpu.len(), "{label}: lengths");
    let scale = cpu.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let mut worst = 0.0f64;
    for (i, (g, c)) in gpu.iter().zip(cpu).enumerate() {
        let err = (g - c).abs() / c.abs().max(floor * scale).max(1e-30);
        worst = worst.max(err);
        if err.is_nan() || err > tol {
            let g32: Vec<f32> = gpu.iter().map(|v| *v as f32).collect();
            let c32: Vec<f32> = cpu.iter().map(|v| *v as f32).collect();
            let saved = save_comparison(label, size.0, size.1, 1, &g32, &c32);
            panic!("{label}: element {i}: GPU {g:.6e}, CPU {c:.6e}, scale {scale:.3e} (images: {saved})");
        }
    }
    eprintln!("{label}: worst relative error {worst:.2e} (scale {scale:.3e})");
}

#[test]
fn shadow_backward_matches_cpu_twin() {
    let d = device();
    let demo = demo_city(&DemoOptions { gaussians: 30_000, ..DemoOptions::default() }).unwrap();
    let gpu_scene = GpuScene::upload(&d, &demo.scene).unwrap();
    let mut splatter = Splatter::new(&d).unwrap();
    let mut pass = ShadowPass::new(&d).unwrap();
    let camera = demo.cameras[0].resized(176, 48);
    // A sun from the south-east: the default sun puts most of this view in the
    // off-screen tower's shadow, far beyond the sigmoid's transition.
    let sun = Sun::from_azimuth_elevation(150.0, 40.0, [1.0; 3]).unwrap();
    let bounds = demo.scene.bounds().unwrap();
    let ch = Channels { depth: true, median_depth: true, visibility: true, normal: true, ..Channels::default() };
    let receivers =
        splatter.render_frame(&gpu_scene, &camera, &SplatSettings { channels: ch, ..Default::default() }).unwrap();
    let host_rec = receivers.gbuffer.read(&d).unwrap();
    let rec_img = DepthImage::from_gbuffer(&host_rec);
    let pixels = (camera.width * camera.height) as usize;
    let mut rng = Pcg64Mcg::seed_from_u64(3);
    let upstream: Vec<f32> = (0..pixels).map(|_| rng.random_range(-1.0..1.0)).collect();
    // V_f: the demo's exact visibility, alpha-normalised; every tenth pixel −1 (left out).
    let vf: Vec<f32> = host_rec
        .get(Channel::Visibility)
        .unwrap()
        .iter()
        .zip(&host_rec.alpha)
        .enumerate()
        .map(|(i, (v, a))| if i % 10 == 3 { -1.0 } else { (v / a.max(1e-6)).clamp(0.0, 1.0) })
        .collect();
    let upstream_buf = d.upload("dL/dV", &upstream).unwrap();
    let vf_buf = d.upload("V_f", &vf).unwrap();
    // Two with a slope bias and normal offset (texels), which hold the normals fixed; the
    // last three with percentage-closer filtering.
    let (depth, pcf) = (ShadowFilter::Depth, ShadowFilter::Pcf);
    for (map_depth, receiver_depth, bce, slope_bias, normal_offset, filter) in [
        (DepthMode::Median, DepthMode::Expected, false, 0.0, 0.0, depth),
        (DepthMode::Expected, DepthMode::Median, false, 0.0, 0.0, depth),
        (DepthMode::Median, DepthMode::Expected, true, 0.0, 0.0, depth),
        (DepthMode::ExpectedOverFar, DepthMode::Expected, true, 0.0, 0.0, depth),
        (DepthMode::Median, DepthMode::Expected, false, 1.5, 1.0, depth),
        (DepthMode::Median, DepthMode::Median, true, 2.0, 2.0, depth),
        (DepthMode::Median, DepthMode::Expected, false, 0.0, 0.0, pcf),
        (DepthMode::Expected, DepthMode::Median, true, 0.0, 0.0, pcf),
        (DepthMode::ExpectedOverFar, DepthMode::Expected, true, 1.5, 1.0, pcf),
    ] {
        let st = ShadowSettings {
            filter,
            resolution: 384,
            k: 4.0,
            map_depth,
            receiver_depth,
            slope_bias,
            normal_offset,
            ..ShadowSettings::default()
        };
        let map = pass.shadow_map(&mut splatter, &gpu_scene, &bounds, &sun, &st, None).unwrap().unwrap();
        let map_img = DepthImage::from_gbuffer(&map.frame.gbuffer.read(&d).unwrap());
        let loss = if bce { GpuVisibilityLoss::Bce(&vf_buf) } else { GpuVisibilityLoss::Upstream(&upstream_buf) };
        let gpu = pass.backward(&map, &receivers.gbuffer, &camera, &st, loss).unwrap();
        let up64: Vec<f64> = upstream.iter().map(|v| f64::from(*v)).collect();
        let vf64: Vec<f64> = vf.iter().map(|v| f64::from(*v)).collect();
        let cpu_loss = if bce { VisibilityLoss::Bce(&vf64) } else { VisibilityLoss::Upstream(&up64) };
        let cpu = sigmoid_backward_cpu(&map.camera, &map_img, &camera, &rec_img, &st, cpu_loss);
        let label = format!(
            "{map_depth:?}_{receiver_depth:?}_bce{bce}_slope{slope_bias}_offset{normal_offset}_{}",
            filter.name()
        );
        let msize = (map.camera.width, map.camera.height);
        let csize = (camera.width, camera.height);
        // fp32 against f64 on the same inputs: 1e-2 relative, floor 1% of the largest value.
        // Texel coordinates (hundreds of texels) carry ~3e-5 texel of fp32 rounding, which
        // small bilinear weights and the city's depth edges (tens of metres per texel)
        // amplify. The smooth scene below holds 1e-3 end to end.
        let texel: Vec<f64> = d.read_buffer::<f32>(&gpu.texel_depth).unwrap().iter().map(|v| f64::from(*v)).collect();
        close(&format!("{label}_texel_depth"), &texel, &cpu.texel_depth, 1e-2, 1e-2, msize);
        let light: Vec<f64> = d.read_buffer::<f32>(&gpu.light_depth).unwrap().iter().map(|v| f64::from(*v)).collect();
        close(&format!("{label}_light_depth"), &light, &cpu.light_depth, 1e-2, 1e-2, csize);
        let (map_channel, rec_channel) = (map_depth, receiver_depth);
        let pick = |g: &srug::splat::backward::BlendGrads, m: DepthMode| match m {
            DepthMode::Median => read(&d, g.get(Channel::MedianDepth)),
            DepthMode::Expected | DepthMode::ExpectedOverFar => read(&d, g.get(Channel::Depth)),
        };
        let cpu_pick = |g: &srug::splat::cpu_backward::PixelGrads, m: DepthMode| -> Vec<f64> {
            match m {
                DepthMode::Median => g.median.clone(),
                DepthMode::Expected | DepthMode::ExpectedOverFar => g.values.iter().map(|v| v[3]).collect(),
            }
        };
        close(
            &format!("{label}_map_depth"),
            &pick(&gpu.map, map_channel),
            &cpu_pick(&cpu.map, map_channel),
            1e-2,
            1e-2,
            msize,
        );
        close(
            &format!("{label}_receiver_depth"),
            &pick(&gpu.receiver, rec_channel),
            &cpu_pick(&cpu.receiver, rec_channel),
            1e-2,
            1e-2,
            csize,
        );
        if map_channel != DepthMode::Median {
            close(&format!("{label}_map_alpha"), &read(&d, gpu.map.alpha.as_ref()), &cpu.map.alpha, 1e-2, 1e-2, msize);
        }
        if rec_channel == DepthMode::Expected {
            close(
                &format!("{label}_receiver_alpha"),
                &read(&d, gpu.receiver.alpha.as_ref()),
                &cpu.receiver.alpha,
                1e-2,
                1e-2,
                csize,
            );
        }
        // dL/dk sums signed per-pixel terms (random ±1 upstream) that cancel, each carrying
        // fp32 rounding of z_s − z (~1e-5 m of ~100 m): 1e-2 relative.
        assert!((gpu.k - cpu.k).abs() <= 1e-2 * cpu.k.abs().max(1e-6), "{label}: dL/dk GPU {} CPU {}", gpu.k, cpu.k);
        assert!(
            (gpu.loss - cpu.loss).abs() <= 1e-4 * cpu.loss.abs().max(1e-6),
            "{label}: loss GPU {} CPU {}",
            gpu.loss,
            cpu.loss
        );
        assert!(cpu.texel_depth.iter().filter(|v| **v != 0.0).count() > 100, "{label}: too few texels with gradient");
        // Deterministic: a second run gives the same bits.
        let again = pass.backward(&map, &receivers.gbuffer, &camera, &st, loss).unwrap();
        let texel2: Vec<f32> = d.read_buffer(&again.texel_depth).unwrap();
        let texel1: Vec<f32> = d.read_buffer(&gpu.texel_depth).unwrap();
        assert!(texel1.iter().zip(&texel2).all(|(a, b)| a.to_bits() == b.to_bits()), "{label}: not repeatable");
        eprintln!("{label}: dL/dk {:.4e}, loss {:.4e}, {} receivers", gpu.k, gpu.loss, gpu.receivers);
    }
    assert_no_validation_messages(&d);
}

/// The ground-and-blob scene of the CPU chain test, with its cameras.
fn blob_scene() -> (Scene, Camera, Camera) {
    let mut rng = Pcg64Mcg::seed_from_u64(11);
    let mut s = Scene::default();
    for i in 0..7 {
        for j in 0..7 {
            s.means.push([
                i as f32 * 0.25 - 0.75 + rng.random_range(-0.03..0.03),
                j as f32 * 0.25 - 0.75 + rng.random_range(-0.03..0.03),
                rng.random_range(-0.01..0.01),
            ]);
            s.log_scales.push([(0.16f32).ln(), (0.16f32).ln(), (0.01f32).ln()]);
            s.rotations.push([1.0, rng.random_range(-0.05..0.05), rng.random_range(-0.05..0.05), 0.1]);
            s.opacity_logits.push(rng.random_range(1.0..3.0));
            s.sh.extend([0.1, 0.1, 0.1]);
        }
    }
    for _ in 0..5 {
        s.means.push([rng.random_range(-0.3..0.1), rng.random_range(-0.2..0.2), rng.random_range(0.4..0.6)]);
        s.log_scales.push([rng.random_range(-2.3..-1.6), rng.random_range(-2.3..-1.6), rng.random_range(-2.3..-1.6)]);
        s.rotations.push([rng.random_range(0.3..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), 0.2]);
        s.opacity_logits.push(rng.random_range(0.0..2.0));
        s.sh.extend([0.1, 0.1, 0.1]);
    }
    let sun = Sun::from_azimuth_elevation(250.0, 50.0, [1.0; 3]).unwrap();
    let light = light_camera(&s.bounds().unwrap(), &sun, 40, ShadowFit::SceneBounds, None).unwrap();
    let camera = Camera::look_at(Vec3::new(0.0, -2.2, 1.8), Vec3::ZERO, Vec3::Z, 55.0, 36, 28).unwrap();
    (s, light, camera)
}

/// The blob scene on the GPU, with its sun and the stages that splat and shade it.
struct BlobRig {
    d: Device,
    scene: Scene,
    light: Camera,
    camera: Camera,
    sun: Sun,
    bounds: srug::scene::Bounds,
    gpu_scene: GpuScene,
    splatter: Splatter,
    pass: ShadowPass,
}

fn blob_rig() -> BlobRig {
    let d = device();
    let (scene, light, camera) = blob_scene();
    let sun = Sun::from_azimuth_elevation(250.0, 50.0, [1.0; 3]).unwrap();
    let bounds = scene.bounds().unwrap();
    let gpu_scene = GpuScene::upload(&d, &scene).unwrap();
    let splatter = Splatter::new(&d).unwrap();
    let pass = ShadowPass::new(&d).unwrap();
    BlobRig { d, scene, light, camera, sun, bounds, gpu_scene, splatter, pass }
}

fn add(total: &mut HostGaussianGradients, g: &HostGaussianGradients) {
    if total.means.is_empty() {
        *total = g.clone();
        return;
    }
    for i in 0..g.means.len() {
        for c in 0..3 {
            total.means[i][c] += g.means[i][c];
            total.log_scales[i][c] += g.log_scales[i][c];
        }
        for c in 0..4 {
            total.rotations[i][c] += g.rotations[i][c];
        }
        total.opacity_logits[i] += g.opacity_logits[i];
    }
}

#[test]
fn shadow_gradients_reach_the_gaussians_like_finite_differences() {
    let BlobRig { d, scene, light, camera, sun, bounds, gpu_scene, mut splatter, mut pass } = blob_rig();
    let mut rng = Pcg64Mcg::seed_from_u64(5);
    let pixels = (camera.width * camera.height) as usize;
    let weights: Vec<f64> = (0..pixels).map(|_| rng.random_range(-1.0..1.0)).collect();
    let w32: Vec<f32> = weights.iter().map(|v| *v as f32).collect();
    let upstream = d.upload("dL/dV", &w32).unwrap();
    for (map_depth, receiver_depth, filter) in [
        (DepthMode::Median, DepthMode::Expected, ShadowFilter::Depth),
        (DepthMode::Expected, DepthMode::Expected, ShadowFilter::Depth),
        (DepthMode::ExpectedOverFar, DepthMode::Median, ShadowFilter::Depth),
        (DepthMode::Expected, DepthMode::Expected, ShadowFilter::Pcf),
    ] {
        let st = ShadowSettings {
            filter,
            resolution: 40,
            k: 6.0,
            bias: 0.02,
            slope_bias: 0.0,
            map_depth,
            receiver_depth,
            ..ShadowSettings::default()
        };
        let map = pass.shadow_map(&mut splatter, &gpu_scene, &bounds, &sun, &st, None).unwrap().unwrap();
        assert_eq!(map.camera, light, "the GPU path fits the same light camera");
        let ch = Channels { depth: true, median_depth: true, ..Channels::default() };
        let settings = SplatSettings { channels: ch, median_coverage: st.receiver_coverage, ..Default::default() };
        let receivers: SplatFrame = splatter.render_frame(&gpu_scene, &camera, &settings).unwrap();
        let sb = pass.backward(&map, &receivers.gbuffer, &camera, &st, GpuVisibilityLoss::Upstream(&upstream)).unwrap();
        let mut total = HostGaussianGradients::default();
        add(&mut total, &splatter.backward(&map.frame, &gpu_scene, &sb.map, false).unwrap().read(&d).unwrap());
        add(&mut total, &splatter.backward(&receivers, &gpu_scene, &sb.receiver, false).unwrap().read(&d).unwrap());

        // Central finite differences of the f64 CPU pipeline: L = Σ w·V_e.
        let params: Vec<Gaussian64> = (0..scene.len()).map(|i| Gaussian64::from_scene(&scene, i)).collect();
        let chain = Chain {
            scene: scene.clone(),
            light: light.clone(),
            camera: camera.clone(),
            settings: st,
            depth: DepthAt::Centre,
        };
        let loss = |p: &[Gaussian64]| chain.loss(p, VisibilityLoss::Upstream(&weights));
        let h = 1e-6;
        let mut rows: Vec<(usize, usize, f64, f64)> = Vec::new(); // (Gaussian, family, gpu, fd)
        for i in 0..params.len() {
            let diff = |f: &dyn Fn(&mut Gaussian64, f64)| {
                let (mut a, mut b) = (params.clone(), params.clone());
                f(&mut a[i], h);
                f(&mut b[i], -h);
                (loss(&a) - loss(&b)) / (2.0 * h)
            };
            for c in 0..3 {
                rows.push((i, 0, f64::from(total.means[i][c]), diff(&|p, e| p.mean[c] += e)));
                rows.push((i, 1, f64::from(total.log_scales[i][c]), diff(&|p, e| p.log_scale[c] += e)));
            }
            for c in 0..4 {
                rows.push((i, 2, f64::from(total.rotations[i][c]), diff(&|p, e| p.rotation[c] += e)));
            }
            rows.push((i, 3, f64::from(total.opacity_logits[i]), diff(&|p, e| p.opacity_logit += e)));
        }
        let names = ["mean", "log_scale", "rotation", "opacity_logit"];
        for (fam, name) in names.iter().enumerate() {
            let scale = rows.iter().filter(|r| r.1 == fam).fold(0.0f64, |m, r| m.max(r.3.abs()));
            assert!(scale > 0.0, "{name}: no gradient");
            let mut worst = 0.0f64;
            for r in rows.iter().filter(|r| r.1 == fam) {
                // Relative error ≤ 1e-3 above a floor of 1% of the family's largest derivative:
                // the GPU is fp32 end to end (G-buffer depths, z_s − z + bias) while the finite
                // differences are f64, so small derivatives carry fp32 rounding of large terms.
                let err = (r.2 - r.3).abs() / r.3.abs().max(1e-2 * scale);
                worst = worst.max(err);
                assert!(
                    err <= 1e-3,
                    "{:?}: Gaussian {} {}: GPU {:.6e}, finite difference {:.6e}",
                    map_depth,
                    r.0,
                    name,
                    r.2,
                    r.3
                );
            }
            eprintln!("{map_depth:?}/{receiver_depth:?} {}: worst relative error {worst:.2e}", name);
        }
        let blob = rows.iter().filter(|r| r.0 >= 49 && r.3.abs() > 1e-6).count();
        assert!(blob >= 20, "the floating blob must get gradient from its shadow ({blob})");
    }
    assert_no_validation_messages(&d);
}

/// With surface depths (map and receivers), the GPU's gradients to every
/// Gaussian against the twin's chain (itself against central differences in
/// `cpu_shadow_chain_gradients_match_finite_differences_with_surface_depths`).
#[test]
fn shadow_gradients_with_surface_depths_match_the_twin() {
    let BlobRig { d, scene, light, camera, sun, bounds, gpu_scene, mut splatter, mut pass } = blob_rig();
    let mut rng = Pcg64Mcg::seed_from_u64(8);
    let pixels = (camera.width * camera.height) as usize;
    let targets: Vec<f64> = (0..pixels).map(|_| rng.random_range(0.0..1.0)).collect();
    let t32: Vec<f32> = targets.iter().map(|v| *v as f32).collect();
    let target = d.upload("V_f", &t32).unwrap();
    let params: Vec<Gaussian64> = (0..scene.len()).map(|i| Gaussian64::from_scene(&scene, i)).collect();
    for (map_depth, receiver_depth) in
        [(DepthMode::Median, DepthMode::Median), (DepthMode::Expected, DepthMode::Expected)]
    {
        let st = ShadowSettings {
            resolution: 40,
            k: 6.0,
            bias: 0.02,
            slope_bias: 0.0,
            map_depth,
            receiver_depth,
            surface_depth: true,
            map_surface_depth: true,
            // Not the presets' 0.6: there one receiver's PCF taps straddle a 2.6 m step
            // in the map with V ≈ 0.005 (BCE ∝ 1/V), where one f32 ulp of its depth moves
            // V by 5e-4 (the twin on the GPU's receivers against its own), beyond what the
            // 1e-3 comparison can absorb. The other backward tests run at the presets'.
            map_coverage: 0.55,
            ..ShadowSettings::default()
        };
        let map = pass.shadow_map(&mut splatter, &gpu_scene, &bounds, &sun, &st, None).unwrap().unwrap();
        assert!(map.frame.surface_depth, "the map is splatted with surface depths");
        let ch = Channels { depth: true, median_depth: true, ..Channels::default() };
        let settings = SplatSettings { channels: ch, surface_depth: true, ..st.receiver_splat() };
        let receivers = splatter.render_frame(&gpu_scene, &camera, &settings).unwrap();
        let sb = pass.backward(&map, &receivers.gbuffer, &camera, &st, GpuVisibilityLoss::Bce(&target)).unwrap();
        let mut total = HostGaussianGradients::default();
        add(&mut total, &splatter.backward(&map.frame, &gpu_scene, &sb.map, false).unwrap().read(&d).unwrap());
        add(&mut total, &splatter.backward(&receivers, &gpu_scene, &sb.receiver, false).unwrap().read(&d).unwrap());

        let chain = Chain {
            scene: scene.clone(),
            light: light.clone(),
            camera: camera.clone(),
            settings: st,
            depth: DepthAt::Surface,
        };
        let (twin, _) = chain.gradients(&params, VisibilityLoss::Bce(&targets));
        let centre = Chain { depth: DepthAt::Centre, ..chain }.gradients(&params, VisibilityLoss::Bce(&targets)).0;
        // (Gaussian, family, GPU, twin, twin with centre depths)
        let mut rows: Vec<(usize, usize, f64, f64, f64)> = Vec::new();
        for i in 0..params.len() {
            let (g, t, c) = (&total, &twin[i], &centre[i]);
            for k in 0..3 {
                rows.push((i, 0, f64::from(g.means[i][k]), t.mean[k], c.mean[k]));
                rows.push((i, 1, f64::from(g.log_scales[i][k]), t.log_scale[k], c.log_scale[k]));
            }
            for k in 0..4 {
                rows.push((i, 2, f64::from(g.rotations[i][k]), t.rotation[k], c.rotation[k]));
            }
        }
        for (family, name) in ["mean", "log_scale", "rotation"].iter().enumerate() {
            let all: Vec<&(usize, usize, f64, f64, f64)> = rows.iter().filter(|r| r.1 == family).collect();
            let scale = all.iter().fold(0.0f64, |m, r| m.max(r.3.abs()));
            assert!(scale > 0.0, "{name}: no gradient");
            let mut worst = 0.0f64;
            for (i, _, gpu, cpu, _) in &all {
                // As the finite-difference test above: relative 1e-3 above 1% of the family's largest.
                let err = (gpu - cpu).abs() / cpu.abs().max(1e-2 * scale);
                worst = worst.max(err);
                assert!(err <= 1e-3, "{map_depth:?}: Gaussian {i} {name}: GPU {gpu:.6e}, twin {cpu:.6e}");
            }
            // Surface depths change the gradients: the test would see a centre-depth backward.
            let changed = all.iter().filter(|r| (r.3 - r.4).abs() > 1e-2 * scale).count();
            assert!(changed >= 10, "{map_depth:?} {name}: only {changed} gradients differ from centre depths'");
            eprintln!("{map_depth:?}/{receiver_depth:?} {name}: worst relative error {worst:.2e}, {changed} changed");
        }
    }
    assert_no_validation_messages(&d);
}

#[test]
fn shadow_backward_is_finite_at_the_extremes() {
    let d = device();
    let demo = demo_city(&DemoOptions { gaussians: 8_000, ..DemoOptions::default() }).unwrap();
    let gpu_scene = GpuScene::upload(&d, &demo.scene).unwrap();
    let mut splatter = Splatter::new(&d).unwrap();
    let mut pass = ShadowPass::new(&d).unwrap();
    let camera = demo.cameras[0].resized(88, 24);
    let bounds = demo.scene.bounds().unwrap();
    let ch = Channels { depth: true, median_depth: true, ..Channels::default() };
    let receivers =
        splatter.render_frame(&gpu_scene, &camera, &SplatSettings { channels: ch, ..Default::default() }).unwrap();
    let pixels = (camera.width * camera.height) as usize;
    let ones = d.upload("dL/dV", &vec![1.0f32; pixels]).unwrap();
    let halves = d.upload("V_f", &vec![0.5f32; pixels]).unwrap();
    for el in [0.01f32, 30.0, 90.0] {
        let sun = Sun::from_azimuth_elevation(265.0, el, [1.0; 3]).unwrap();
        // The map depends on neither k nor the bias.
        let base = ShadowSettings {
            resolution: 128,
            slope_bias: 0.0,
            receiver_depth: DepthMode::Expected,
            ..ShadowSettings::default()
        };
        let map = pass.shadow_map(&mut splatter, &gpu_scene, &bounds, &sun, &base, None).unwrap().unwrap();
        for k in [1e-3f32, 1.0, 1e4, 1e9] {
            // Bias is ≥ 0 (ShadowSettings::validate); 0 and 1e30 are its extremes.
            for (bias, filter) in
                [0.15f32, 0.0, 1e30].into_iter().flat_map(|b| [(b, ShadowFilter::Depth), (b, ShadowFilter::Pcf)])
            {
                let st = ShadowSettings { k, bias, filter, ..base };
                for loss in [GpuVisibilityLoss::Upstream(&ones), GpuVisibilityLoss::Bce(&halves)] {
                    let b = pass.backward(&map, &receivers.gbuffer, &camera, &st, loss).unwrap();
                    let label = format!("el {el} k {k} bias {bias} filter {}", filter.name());
                    assert!(b.k.is_finite() && b.loss.is_finite(), "{label}: dk {} loss {}", b.k, b.loss);
                    for v in [
                        read(&d, b.map.get(Channel::MedianDepth)),
                        read(&d, b.receiver.get(Channel::Depth)),
                        read(&d, b.receiver.alpha.as_ref()),
                    ] {
                        assert!(v.iter().all(|x| x.is_finite()), "{label}: non-finite gradient");
                    }
                    // On to the Gaussians at the extremes of k (the slow part; once each).
                    if bias == 0.15 && (k == 1e-3 || k == 1e9) {
                        let g = splatter.backward(&map.frame, &gpu_scene, &b.map, false).unwrap().read(&d).unwrap();
                        assert!(g.means.iter().flatten().chain(&g.opacity_logits).all(|x| x.is_finite()), "{label}");
                    }
                    if bias == 1e30 {
                        // Saturated everywhere: V is constant, so upstream gradients vanish.
                        if matches!(loss, GpuVisibilityLoss::Upstream(_)) {
                            assert_eq!(b.k, 0.0, "{label}");
                        }
                    }
                }
            }
        }
        // Surface depths for the map and the receivers, to the Gaussians (planes seen
        // edge-on by the grazing sun: their slopes are at the limit).
        let st =
            ShadowSettings { surface_depth: true, map_surface_depth: true, receiver_depth: DepthMode::Median, ..base };
        let map = pass.shadow_map(&mut splatter, &gpu_scene, &bounds, &sun, &st, None).unwrap().unwrap();
        let settings = SplatSettings { channels: ch, surface_depth: true, ..Default::default() };
        let surface_receivers = splatter.render_frame(&gpu_scene, &camera, &settings).unwrap();
        for k in [1e-3f32, 1e9] {
            let st = ShadowSettings { k, ..st };
            let b = pass.backward(&map, &surface_receivers.gbuffer, &camera, &st, GpuVisibilityLoss::Bce(&halves));
            let b = b.unwrap();
            for (frame, grads) in [(&map.frame, &b.map), (&surface_receivers, &b.receiver)] {
                let g = splatter.backward(frame, &gpu_scene, grads, false).unwrap().read(&d).unwrap();
                let all = g.means.iter().flatten().chain(g.log_scales.iter().flatten());
                let all = all.chain(g.rotations.iter().flatten()).chain(&g.opacity_logits);
                assert!(all.clone().all(|x| x.is_finite()), "el {el} k {k}: surface depths, non-finite gradient");
                // k = 1e9 saturates every logit at its clamp, where the test passes no gradient.
                if k == 1e-3 {
                    assert!(all.clone().any(|x| *x != 0.0), "el {el} k {k}: surface depths, no gradient at all");
                }
            }
        }
    }
    assert_no_validation_messages(&d);
}

/// The CPU pipeline of the shadow loss for the blob scene: f64 forward, twin backward.
struct Chain {
    scene: Scene,
    light: Camera,
    camera: Camera,
    settings: ShadowSettings,
    /// The splats' depths (surface depths when `settings.surface_depth`).
    depth: DepthAt,
}

impl Chain {
    /// The map's (light's) camera and median rule, or the receivers'.
    fn view(&self, map: bool) -> (&Camera, MedianRule) {
        if map {
            (&self.light, MedianRule::new(self.depth, self.settings.map_coverage))
        } else {
            (&self.camera, MedianRule::new(self.depth, self.settings.receiver_coverage))
        }
    }

    fn blends(&self, params: &[Gaussian64], map: bool) -> (Vec<Option<CpuSplat>>, Vec<PixelBlend>) {
        let (cam, rule) = self.view(map);
        render_blends(params, &self.scene, cam, NormalSource::ShortestAxis, DEFAULT_TILE, rule)
    }

    fn images(&self, params: &[Gaussian64]) -> (DepthImage, DepthImage) {
        let (lb, cb) = (self.blends(params, true).1, self.blends(params, false).1);
        (
            DepthImage::from_blends(self.light.width, self.light.height, &lb),
            DepthImage::from_blends(self.camera.width, self.camera.height, &cb),
        )
    }

    fn loss(&self, params: &[Gaussian64], loss: VisibilityLoss<'_>) -> f64 {
        let (map, rec) = self.images(params);
        match loss {
            VisibilityLoss::Upstream(w) => {
                let v = sigmoid_visibility_cpu(&self.light, &map, &self.camera, &rec, &self.settings);
                v.iter().zip(w).map(|(a, b)| a * b).sum()
            }
            VisibilityLoss::Bce(_) => {
                sigmoid_backward_cpu(&self.light, &map, &self.camera, &rec, &self.settings, loss).loss
            }
        }
    }

    fn gradients(&self, params: &[Gaussian64], loss: VisibilityLoss<'_>) -> (Vec<GaussianGrad>, f64) {
        let (map, rec) = self.images(params);
        let g = sigmoid_backward_cpu(&self.light, &map, &self.camera, &rec, &self.settings, loss);
        let mut out = vec![GaussianGrad::default(); params.len()];
        for (map, pg) in [(true, &g.map), (false, &g.receiver)] {
            let (cam, rule) = self.view(map);
            let (splats, _) = self.blends(params, map);
            let sg = blend_backward_cpu(&splats, cam, [0.0; 3], pg, DEFAULT_TILE, rule);
            for (i, p) in params.iter().enumerate() {
                let d = project_backward(p, cam, &sg[i], false, DEFAULT_TILE);
                let o = &mut out[i];
                o.mean += d.mean;
                o.log_scale += d.log_scale;
                o.opacity_logit += d.opacity_logit;
                for k in 0..4 {
                    o.rotation[k] += d.rotation[k];
                }
            }
        }
        (out, g.k)
    }
}

fn check_chain(map_depth: DepthMode, receiver_depth: DepthMode, bce: bool, filter: ShadowFilter, surface: bool) {
    let (scene, light, camera) = blob_scene();
    let settings = ShadowSettings {
        k: 6.0,
        bias: 0.02,
        slope_bias: 0.0,
        map_depth,
        receiver_depth,
        filter,
        surface_depth: surface,
        map_surface_depth: surface,
        ..ShadowSettings::default()
    };
    let depth = if surface { DepthAt::Surface } else { DepthAt::Centre };
    let chain = Chain { scene, light, camera, settings, depth };
    let params: Vec<Gaussian64> = (0..chain.scene.len()).map(|i| Gaussian64::from_scene(&chain.scene, i)).collect();
    let mut rng = Pcg64Mcg::seed_from_u64(5);
    let n = (chain.camera.width * chain.camera.height) as usize;
    // BCE targets in [0, 1], a tenth of them negative (left out of the loss).
    let data: Vec<f64> = (0..n)
        .map(|i| if bce && i % 10 == 3 { -1.0 } else { rng.random_range(if bce { 0.0..1.0 } else { -1.0..1.0 }) })
        .collect();
    let loss = if bce { VisibilityLoss::Bce(&data) } else { VisibilityLoss::Upstream(&data) };
    let (grads, dk) = chain.gradients(&params, loss);
    let h = 1e-6;
    let fd = |perturb: &dyn Fn(&mut Vec<Gaussian64>, f64)| {
        let mut plus = params.clone();
        perturb(&mut plus, h);
        let mut minus = params.clone();
        perturb(&mut minus, -h);
        (chain.loss(&plus, loss) - chain.loss(&minus, loss)) / (2.0 * h)
    };
    let mut checked = Vec::new();
    for i in 0..params.len() {
        let a = grads[i];
        for c in 0..3 {
            checked.push((i, "mean", a.mean[c], fd(&|p, d| p[i].mean[c] += d)));
            checked.push((i, "log_scale", a.log_scale[c], fd(&|p, d| p[i].log_scale[c] += d)));
        }
        for c in 0..4 {
            checked.push((i, "rotation", a.rotation[c], fd(&|p, d| p[i].rotation[c] += d)));
        }
        checked.push((i, "opacity_logit", a.opacity_logit, fd(&|p, d| p[i].opacity_logit += d)));
    }
    let scale = checked.iter().fold(0.0f64, |m, c| m.max(c.3.abs()));
    let mut significant = 0;
    for (i, name, a, f) in &checked {
        // Relative error ≤ 1e-3 against the larger of |fd| and 1e-4 of the largest
        // derivative (below that, rounding in the summed loss, ~1e-14, divided by the
        // step dominates the finite difference).
        let err = (a - f).abs() / f.abs().max(1e-4 * scale);
        assert!(err <= 1e-3, "Gaussian {i} {name}: analytic {a:.9e}, finite difference {f:.9e}");
        significant += usize::from(f.abs() > 1e-3 * scale);
    }
    // The blob (the last five) must receive gradient from the shadow it casts.
    let blob = checked.iter().filter(|c| c.0 >= 49 && c.3.abs() > 1e-3 * scale).count();
    assert!(blob >= 20, "only {blob} blob derivatives are significant");
    assert!(significant >= 100, "only {significant} significant derivatives");
    // dL/dk by finite differences of k.
    let mut shifted = chain.settings;
    let hk = 1e-6 * f64::from(shifted.k);
    let base = shifted.k;
    let loss_k = |k: f64, st: &mut ShadowSettings| {
        st.k = k as f32;
        let c = Chain {
            scene: chain.scene.clone(),
            light: chain.light.clone(),
            camera: chain.camera.clone(),
            settings: *st,
            depth: chain.depth,
        };
        c.loss(&params, loss)
    };
    // k is f32 in the settings: use a step that f32 represents exactly.
    let kp = f64::from(base) + hk;
    let km = f64::from(base) - hk;
    let (kp32, km32) = (f64::from(kp as f32), f64::from(km as f32));
    let fd_k = (loss_k(kp32, &mut shifted) - loss_k(km32, &mut shifted)) / (kp32 - km32);
    assert!((dk - fd_k).abs() <= 1e-3 * fd_k.abs().max(1e-9), "dL/dk {dk:.9e} vs finite difference {fd_k:.9e}");
    eprintln!(
        "{map_depth:?}/{receiver_depth:?}/bce {bce}/{}/surface {surface}: {significant} significant derivatives, \
         dL/dk {dk:.4e}",
        filter.name()
    );
}

/// The CPU twin's shadow chain (analytic, through both splats) against central
/// finite differences of the f64 pipeline, for every map depth mode, the BCE
/// loss and both filters, with centre depths.
#[test]
fn cpu_shadow_chain_gradients_match_finite_differences() {
    let (depth, pcf) = (ShadowFilter::Depth, ShadowFilter::Pcf);
    check_chain(DepthMode::Median, DepthMode::Expected, false, depth, false);
    check_chain(DepthMode::Expected, DepthMode::Expected, false, depth, false);
    check_chain(DepthMode::Expected, DepthMode::Median, true, depth, false);
    check_chain(DepthMode::ExpectedOverFar, DepthMode::Expected, true, depth, false);
    check_chain(DepthMode::Median, DepthMode::Expected, false, pcf, false);
    check_chain(DepthMode::Expected, DepthMode::Median, true, pcf, false);
    check_chain(DepthMode::ExpectedOverFar, DepthMode::Expected, true, pcf, false);
}

/// As above with surface depths for the map's occluders and the receivers
/// (the presets' median depths, both losses, both filters).
#[test]
fn cpu_shadow_chain_gradients_match_finite_differences_with_surface_depths() {
    let (depth, pcf) = (ShadowFilter::Depth, ShadowFilter::Pcf);
    check_chain(DepthMode::Median, DepthMode::Median, false, pcf, true);
    check_chain(DepthMode::Median, DepthMode::Median, true, pcf, true);
    check_chain(DepthMode::Median, DepthMode::Expected, false, depth, true);
    check_chain(DepthMode::Expected, DepthMode::Median, true, pcf, true);
}
