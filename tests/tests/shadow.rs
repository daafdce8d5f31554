//! Sun shadows against their f64 CPU twin and against the demo city's exact
//! visibility: the sigmoid shadow test, the traced reference, the light
//! camera, and the extremes (k from 1e-3 to 1e9, the sun at 0.01° and 90°,
//! below the horizon, an empty shadow map). Outputs are pre-filled with NaN.

#![allow(clippy::unwrap_used, clippy::expect_used, reason = "a failed unwrap is a failed test")]

use glam::Vec3;
use srug::gpu::Device;
use srug::scene::activate::GpuScene;
use srug::scene::demo::{demo_city, DemoCity, DemoOptions};
use srug::scene::{Camera, Scene};
use srug::shadow::backward::GpuVisibilityLoss;
use srug::shadow::completion::shadow_iou;
use srug::shadow::cpu::{sigmoid_visibility_cpu, traced_visibility_cpu, DepthImage};
use srug::shadow::{
    light_camera, DepthMode, ShadowFilter, ShadowFit, ShadowMap, ShadowPass, ShadowSettings, Sun, VisibilityKind,
};
use srug::splat::Channel;
use srug::splat::{Channels, GBuffer, SplatSettings, Splatter};
use srug_tests::{assert_no_validation_messages, device, move_scene, save_comparison};

const NAN: u32 = srug_tests::NAN_SENTINEL;

struct Setup {
    d: Device,
    splatter: Splatter,
    pass: ShadowPass,
    demo: DemoCity,
    gpu_scene: GpuScene,
}

fn setup(gaussians: usize) -> Setup {
    let d = device();
    let demo = demo_city(&DemoOptions { gaussians, ..DemoOptions::default() }).unwrap();
    let gpu_scene = GpuScene::upload(&d, &demo.scene).unwrap();
    Setup { splatter: Splatter::new(&d).unwrap(), pass: ShadowPass::new(&d).unwrap(), demo, gpu_scene, d }
}

/// The twin tests' settings: a plain metre bias and expected receiver depths
/// unless a test says otherwise (the default's slope bias needs receiver
/// normals, which the tests that exercise it render).
fn settings(resolution: u32) -> ShadowSettings {
    ShadowSettings {
        resolution,
        prefill: Some(NAN),
        bias: 0.15,
        slope_bias: 0.0,
        receiver_depth: DepthMode::Expected,
        ..ShadowSettings::default()
    }
}

/// Renders the receiver G-buffer (its depth channels plus the fixed visibility).
fn receiver(s: &mut Setup, camera: &Camera, extra: Channels) -> (srug::splat::GpuGBuffer, GBuffer) {
    let ch = Channels { depth: true, median_depth: true, ..extra };
    let (g, _) = s
        .splatter
        .render(&s.gpu_scene, camera, &SplatSettings { channels: ch, prefill: Some(NAN), ..SplatSettings::default() })
        .unwrap();
    let host = g.read(&s.d).unwrap();
    (g, host)
}

fn shadow_map(s: &mut Setup, sun: &Sun, st: &ShadowSettings, view: Option<&Camera>) -> ShadowMap {
    let bounds = s.demo.scene.bounds().unwrap();
    s.pass.shadow_map(&mut s.splatter, &s.gpu_scene, &bounds, sun, st, view).unwrap().expect("the sun is up")
}

/// The sigmoid test's V on the GPU and its f64 twin's on the same map and
/// receivers (`camera`'s, normals rendered where `st` needs them).
fn sigmoid_and_twin(s: &mut Setup, camera: &Camera, sun: &Sun, st: &ShadowSettings) -> (Vec<f32>, Vec<f64>) {
    let (g, host) = receiver(s, camera, Channels { normal: st.geometric_bias(), ..Channels::default() });
    let map = shadow_map(s, sun, st, Some(camera));
    let map_host = DepthImage::from_gbuffer(&map.frame.gbuffer.read(&s.d).unwrap());
    let host = DepthImage::from_gbuffer(&host);
    let (v, _) = s.pass.visibility(&map, &g, camera, st, VisibilityKind::Sigmoid).unwrap();
    let gpu: Vec<f32> = s.d.read_buffer(&v).unwrap();
    (gpu, sigmoid_visibility_cpu(&map.camera, &map_host, camera, &host, st))
}

fn max_diff(label: &str, camera: &Camera, gpu: &[f32], cpu: &[f64], tol: f64) -> f64 {
    assert!(gpu.iter().all(|v| v.is_finite() && (0.0..=1.0).contains(v)), "{label}: non-finite or out-of-range V");
    let cpu32: Vec<f32> = cpu.iter().map(|v| *v as f32).collect();
    let err = gpu.iter().zip(cpu).map(|(a, b)| (f64::from(*a) - b).abs()).fold(0.0, f64::max);
    if err > tol {
        let saved = save_comparison(label, camera.width, camera.height, 1, gpu, &cpu32);
        panic!("{label}: max |GPU − CPU| {err:.3e} > {tol:.1e} (images: {saved})");
    }
    err
}

#[test]
fn sigmoid_test_and_traced_reference_match_cpu_twin() {
    let mut s = setup(30_000);
    let camera = s.demo.cameras[0].resized(176, 48);
    // A sun from the south-east: the demo's default sun puts nearly all of this
    // view in the off-screen tower's shadow, far beyond the sigmoid's transition.
    let sun = Sun::from_azimuth_elevation(150.0, 40.0, [1.0; 3]).unwrap();
    // The traced pass walks the map's tile lists: every tile edge.
    // Slope bias and normal offset (texels) too: they read the receivers' normals.
    for (map_depth, fit, tile, slope_bias, normal_offset) in [
        (DepthMode::Median, ShadowFit::SceneBounds, 16, 0.0, 0.0),
        (DepthMode::Expected, ShadowFit::ViewFrustum, 16, 0.0, 0.0),
        (DepthMode::Median, ShadowFit::SceneBounds, 8, 0.0, 0.0),
        (DepthMode::Median, ShadowFit::ViewFrustum, 32, 0.0, 0.0),
        (DepthMode::Median, ShadowFit::SceneBounds, 16, 2.0, 1.5),
        (DepthMode::Expected, ShadowFit::ViewFrustum, 16, 0.5, 3.0),
    ] {
        // k = 4 per metre keeps most receivers inside the sigmoid's transition, where
        // a GPU/CPU difference would show.
        // The paper's depth test first, then percentage-closer filtering.
        let st = ShadowSettings {
            map_depth,
            fit,
            k: 4.0,
            tile,
            slope_bias,
            normal_offset,
            filter: ShadowFilter::Depth,
            ..settings(384)
        };
        let (g, host) = receiver(&mut s, &camera, Channels { normal: st.geometric_bias(), ..Channels::default() });
        let map = shadow_map(&mut s, &sun, &st, Some(&camera));
        let map_host = DepthImage::from_gbuffer(&map.frame.gbuffer.read(&s.d).unwrap());
        let host = DepthImage::from_gbuffer(&host);
        let label = format!("shadow_{map_depth:?}_{fit:?}_tile{tile}_slope{slope_bias}_offset{normal_offset}");

        let (v, _) = s.pass.visibility(&map, &g, &camera, &st, VisibilityKind::Sigmoid).unwrap();
        let gpu: Vec<f32> = s.d.read_buffer(&v).unwrap();
        let cpu = sigmoid_visibility_cpu(&map.camera, &map_host, &camera, &host, &st);
        // f32 reconstruction of the receiver point is good to ~1e-6 relative (~1e-4 m
        // here), and its map position to ~3e-5 texel, which bilinear sampling across a
        // depth edge (metres between neighbouring texels) turns into ~1e-4 m of z_s;
        // with k = 4 per metre V moves by k/4 per metre: 5e-4 allows both.
        let err = max_diff(&format!("{label}_sigmoid"), &camera, &gpu, &cpu, 5e-4);
        // Percentage-closer filtering: each texel's exact depth, so only the point's
        // rounding and the weights' (~3e-5 texel) remain; the same bound holds.
        let pcf = ShadowSettings { filter: ShadowFilter::Pcf, ..st };
        let (vp, _) = s.pass.visibility(&map, &g, &camera, &pcf, VisibilityKind::Sigmoid).unwrap();
        let gpu_pcf: Vec<f32> = s.d.read_buffer(&vp).unwrap();
        let cpu_pcf = sigmoid_visibility_cpu(&map.camera, &map_host, &camera, &host, &pcf);
        let err_pcf = max_diff(&format!("{label}_pcf"), &camera, &gpu_pcf, &cpu_pcf, 5e-4);
        let moved = gpu.iter().zip(&gpu_pcf).filter(|(a, b)| (**a - **b).abs() > 1e-2).count();
        assert!(moved > 10, "{label}: the PCF filter changes only {moved} pixels");

        let (t, _) = s.pass.visibility(&map, &g, &camera, &st, VisibilityKind::Traced).unwrap();
        let traced: Vec<f32> = s.d.read_buffer(&t).unwrap();
        let traced_cpu = traced_visibility_cpu(&s.demo.scene, &map.camera, &camera, &host, &st);
        // The GPU projects splats in f32: α differs by ~1e-5 per splat, and a splat whose
        // depth is within rounding of z − bias may be in or out. Count such pixels.
        assert!(traced.iter().all(|v| v.is_finite() && (0.0..=1.0).contains(v)), "{label}: traced out of range");
        let bad = traced.iter().zip(&traced_cpu).filter(|(a, b)| (f64::from(**a) - **b).abs() > 1e-3).count();
        if bad * 200 > traced.len() {
            let c32: Vec<f32> = traced_cpu.iter().map(|v| *v as f32).collect();
            let saved = save_comparison(&format!("{label}_traced"), camera.width, camera.height, 1, &traced, &c32);
            panic!("{label}: traced visibility: {bad} of {} pixels differ by > 1e-3 (images: {saved})", traced.len());
        }
        let partial = gpu.iter().filter(|v| (0.01..0.99).contains(*v)).count();
        let shadowed = gpu.iter().filter(|v| **v < 0.5).count();
        eprintln!("{label}: sigmoid max error {err:.2e}, PCF {err_pcf:.2e} ({partial} pixels in transition, {shadowed} shadowed); traced: {bad} pixels off by > 1e-3");
        assert!(partial > 50 && shadowed > 50, "{label}: too few pixels test the sigmoid's transition");
    }
    // Receivers seen through lenses: each pixel is unprojected along its undistorted ray
    // (Newton in f32 against f64), and the view-frustum fit follows the lens's edges.
    for lens in [
        srug::camera::lens::Lens::RadialTangential { k: [-0.25, 0.06, -0.005, 0.0, 0.0, 0.0], p: [0.001, -0.002] },
        srug::camera::lens::Lens::Fisheye { k: [0.01, -0.002, 0.0003, -0.00004] },
        srug::camera::lens::Lens::Equirectangular,
    ] {
        let cam = match lens {
            // A panorama's frustum is the whole sphere: the fit falls back to the scene.
            srug::camera::lens::Lens::Equirectangular => {
                Camera::panorama(camera.position, camera.rotation, camera.width).unwrap()
            }
            _ => Camera { lens, ..camera.clone() },
        };
        let st = ShadowSettings { fit: ShadowFit::ViewFrustum, k: 4.0, ..settings(384) };
        let (gpu, cpu) = sigmoid_and_twin(&mut s, &cam, &sun, &st);
        // As above, plus the lens's f32 Newton inversion.
        let err = max_diff(&format!("shadow_lens_{lens:?}"), &cam, &gpu, &cpu, 5e-4);
        let partial = gpu.iter().filter(|v| (0.01..0.99).contains(*v)).count();
        eprintln!("lens {lens:?}: sigmoid max error {err:.2e} ({partial} pixels in transition)");
        assert!(partial > 50, "lens {lens:?}: too few pixels test the sigmoid's transition");
    }
    assert_no_validation_messages(&s.d);
}

/// Through a barrel lens, a fisheye and a 360° panorama, the shadow test still agrees with the
/// demo's exact visibility as well as through the pinhole (IoU ≥ 0.8): the
/// receivers are unprojected along each pixel's true ray.
#[test]
fn shadows_through_lenses_agree_with_the_exact_visibility() {
    let mut s = setup(120_000);
    let street = s.demo.cameras[0].resized(352, 96);
    let sun = Sun::from_direction(s.demo.sun_direction, [1.0; 3]).unwrap();
    let st = settings(1024);
    let barrel = Camera {
        lens: srug::camera::lens::Lens::RadialTangential {
            k: [-0.25, 0.06, -0.005, 0.0, 0.0, 0.0],
            p: [0.001, -0.002],
        },
        ..street.clone()
    };
    let fisheye = Camera {
        width: 192,
        height: 192,
        projection: srug::scene::Projection::Pinhole { fx: 60.0, fy: 60.0, cx: 96.0, cy: 96.0 },
        lens: srug::camera::lens::Lens::Fisheye { k: [0.01, -0.002, 0.0, 0.0] },
        ..street.clone()
    };
    let panorama = Camera::panorama(street.position, street.rotation, 384).unwrap();
    let map = shadow_map(&mut s, &sun, &st, None);
    for (name, camera) in [("barrel", barrel), ("fisheye", fisheye), ("panorama", panorama)] {
        let (g, host) = receiver(&mut s, &camera, Channels { visibility: true, ..Channels::default() });
        let vf: Vec<f32> =
            host.get(Channel::Visibility).unwrap().iter().zip(&host.alpha).map(|(v, a)| v / a.max(1e-6)).collect();
        let (v, _) = s.pass.visibility(&map, &g, &camera, &st, VisibilityKind::Sigmoid).unwrap();
        let ve: Vec<f32> = s.d.read_buffer(&v).unwrap();
        let surface: Vec<bool> = host.alpha.iter().map(|a| *a >= 0.5).collect();
        let iou = shadow_iou(&ve, &vf, &surface);
        let shadowed = vf.iter().zip(&host.alpha).filter(|(v, a)| **a >= 0.5 && **v < 0.5).count();
        let covered = host.alpha.iter().filter(|a| **a >= 0.5).count();
        eprintln!("{name}: IoU(V_e, V_f) {iou:.3}, {shadowed} shadowed pixels, {covered} covered");
        assert!(shadowed > 200, "{name}: the view should contain shadow ({shadowed} pixels)");
        if iou < 0.8 {
            save_comparison(&format!("lens_{name}_ve_vs_vf"), camera.width, camera.height, 1, &ve, &vf);
            panic!("{name}: shadow IoU against the exact visibility {iou:.3} < 0.8");
        }
    }
    assert_no_validation_messages(&s.d);
}

#[test]
fn shadows_agree_with_the_demo_exact_visibility() {
    // The demo's per-Gaussian visibility is exact (a ray toward the sun against the
    // analytic boxes), so the rendered fixed visibility V_f is the ground truth the
    // paper supervises with. Both shadow estimates must agree with it on most pixels.
    let mut s = setup(120_000);
    let camera = s.demo.cameras[0].resized(352, 96);
    let sun = Sun::from_direction(s.demo.sun_direction, [1.0; 3]).unwrap();
    let st = settings(1024);
    let (g, host) = receiver(&mut s, &camera, Channels { visibility: true, ..Channels::default() });
    let map = shadow_map(&mut s, &sun, &st, None);
    let vf: Vec<f32> =
        host.get(Channel::Visibility).unwrap().iter().zip(&host.alpha).map(|(v, a)| v / a.max(1e-6)).collect();
    let (v, _) = s.pass.visibility(&map, &g, &camera, &st, VisibilityKind::Sigmoid).unwrap();
    let ve: Vec<f32> = s.d.read_buffer(&v).unwrap();
    let (t, _) = s.pass.visibility(&map, &g, &camera, &st, VisibilityKind::Traced).unwrap();
    let vt: Vec<f32> = s.d.read_buffer(&t).unwrap();
    let surface: Vec<bool> = host.alpha.iter().map(|a| *a >= 0.5).collect();
    let iou_e = shadow_iou(&ve, &vf, &surface);
    let iou_t = shadow_iou(&vt, &vf, &surface);
    let iou_et = shadow_iou(&ve, &vt, &surface);
    eprintln!("IoU(V_e, V_f) {iou_e:.3}, IoU(V_t, V_f) {iou_t:.3}, IoU(V_e, V_t) {iou_et:.3}");
    let shadowed = vf.iter().zip(&host.alpha).filter(|(v, a)| **a >= 0.5 && **v < 0.5).count();
    assert!(shadowed > 500, "the demo view should contain shadow ({shadowed} pixels)");
    if iou_e < 0.8 || iou_t < 0.8 {
        save_comparison("demo_ve_vs_vf", camera.width, camera.height, 1, &ve, &vf);
        save_comparison("demo_vt_vs_vf", camera.width, camera.height, 1, &vt, &vf);
        panic!("shadow IoU against the exact visibility too low: V_e {iou_e:.3}, V_t {iou_t:.3}");
    }
    assert_no_validation_messages(&s.d);
}

/// The shadow test far from the world's origin matches its twin as it does
/// near it: receivers are rebuilt relative to their camera and taken to the
/// light through that camera's light-space position (the host's, in f64), so
/// no coordinate of 1e5 m enters a sum that cancels. Rebuilding world points
/// and projecting them as rotation · point + translation instead put V
/// 2.7e-2 off the twin here before the change (tolerance 5e-4, as near the
/// origin).
#[test]
fn far_from_the_origin_the_shadow_test_matches_cpu_twin() {
    let d = device();
    let mut demo = demo_city(&DemoOptions { gaussians: 30_000, ..DemoOptions::default() }).unwrap();
    let offset = Vec3::new(1.0e5, -7.0e4, 30.0);
    move_scene(&mut demo.scene, offset);
    let gpu_scene = GpuScene::upload(&d, &demo.scene).unwrap();
    let mut s = Setup { splatter: Splatter::new(&d).unwrap(), pass: ShadowPass::new(&d).unwrap(), demo, gpu_scene, d };
    let camera = s.demo.cameras[0].resized(176, 48);
    let camera = Camera { position: camera.position + offset, ..camera };
    let sun = Sun::from_azimuth_elevation(150.0, 40.0, [1.0; 3]).unwrap();
    for (fit, slope_bias, normal_offset) in [(ShadowFit::SceneBounds, 0.0, 0.0), (ShadowFit::ViewFrustum, 0.5, 2.0)] {
        let st =
            ShadowSettings { fit, k: 4.0, slope_bias, normal_offset, filter: ShadowFilter::Depth, ..settings(384) };
        let (gpu, cpu) = sigmoid_and_twin(&mut s, &camera, &sun, &st);
        let label = format!("shadow_far_{fit:?}");
        let err = max_diff(&label, &camera, &gpu, &cpu, 5e-4);
        let partial = gpu.iter().filter(|v| (0.01..0.99).contains(*v)).count();
        let shadowed = gpu.iter().filter(|v| **v < 0.5).count();
        eprintln!("{label}: sigmoid max error {err:.2e} ({partial} pixels in transition, {shadowed} shadowed)");
        assert!(partial > 50 && shadowed > 50, "{label}: too few pixels test the sigmoid's transition");
    }
    assert_no_validation_messages(&s.d);
}

#[test]
fn light_camera_covers_the_scene_and_the_frustum_fit_is_tighter() {
    let demo = demo_city(&DemoOptions { gaussians: 5_000, ..DemoOptions::default() }).unwrap();
    let bounds = demo.scene.bounds().unwrap();
    for (az, el) in [(270.0, 25.0), (135.0, 0.01), (0.0, 90.0), (10.0, 60.0)] {
        let sun = Sun::from_azimuth_elevation(az, el, [1.0; 3]).unwrap();
        let cam = light_camera(&bounds, &sun, 512, ShadowFit::SceneBounds, None).unwrap();
        assert_eq!(cam.width.max(cam.height), 512, "sun {az}/{el}: {}x{}", cam.width, cam.height);
        assert!((cam.rotation.z_axis + sun.direction).length() < 1e-5, "looks along the sunlight");
        for p in &demo.scene.means {
            assert!(cam.sees(Vec3::from_array(*p)), "sun {az}/{el}: the light camera misses {p:?}");
        }
        let view = &demo.cameras[0];
        let tight = light_camera(&bounds, &sun, 512, ShadowFit::ViewFrustum, Some(view)).unwrap();
        let texel = |c: &Camera| match c.projection {
            srug::scene::Projection::Orthographic { sx, .. } => 1.0 / sx,
            srug::scene::Projection::Pinhole { .. } => unreachable!(),
        };
        assert!(texel(&tight) <= texel(&cam) * 1.0001, "frustum fit texel {} > {}", texel(&tight), texel(&cam));
        // The same scene 1e5 m from the origin gets a map as fine (within 1%), not one spread
        // over empty space by a margin that grows with the distance (0.1% of it: texels
        // 0.913 against 0.394 m for the first sun), and the map still holds every point.
        let offset = Vec3::new(1.0e5, -7.0e4, 30.0);
        let moved = |p: [f32; 3]| (Vec3::from_array(p) + offset).to_array();
        let far_bounds = srug::scene::Bounds { min: moved(bounds.min), max: moved(bounds.max) };
        let far = light_camera(&far_bounds, &sun, 512, ShadowFit::SceneBounds, None).unwrap();
        assert!(
            (texel(&far) - texel(&cam)).abs() <= 1e-2 * texel(&cam),
            "sun {az}/{el}: texel {} far from the origin, {} near it",
            texel(&far),
            texel(&cam)
        );
        for p in &demo.scene.means {
            assert!(far.sees(Vec3::from_array(moved(*p))), "sun {az}/{el}: the far light camera misses {p:?}");
        }
        // Every scene point the view sees projects inside the tight map.
        for p in demo.scene.means.iter().map(|p| Vec3::from_array(*p)).filter(|p| view.sees(*p)) {
            let l = tight.project(tight.world_to_camera(p));
            assert!(l.x >= 0.0 && l.y >= 0.0 && l.x < tight.width as f32 && l.y < tight.height as f32);
        }
    }
    let up = Sun::from_direction(Vec3::Z, [1.0; 3]).unwrap();
    assert!(light_camera(&bounds, &up, 0, ShadowFit::SceneBounds, None).is_err(), "zero resolution");
    assert!(light_camera(&bounds, &up, 64, ShadowFit::ViewFrustum, None).is_err(), "frustum fit without a view");
}

#[test]
fn extremes_give_finite_visibility() {
    let mut s = setup(8_000);
    let camera = s.demo.cameras[0].resized(88, 24);
    let (g, host) = receiver(&mut s, &camera, Channels::default());
    let host = DepthImage::from_gbuffer(&host);
    // k from 1e-3 to 1e9 and the sun from grazing to overhead.
    for el in [0.01f32, 25.0, 90.0] {
        let sun = Sun::from_azimuth_elevation(265.0, el, [1.0; 3]).unwrap();
        let base = settings(256);
        let map = shadow_map(&mut s, &sun, &base, None);
        let map_host = DepthImage::from_gbuffer(&map.frame.gbuffer.read(&s.d).unwrap());
        for k in [1e-3f32, 1.0, 50.0, 1e4, 1e9] {
            let runs = [
                (VisibilityKind::Sigmoid, ShadowFilter::Depth),
                (VisibilityKind::Sigmoid, ShadowFilter::Pcf),
                (VisibilityKind::Traced, ShadowFilter::Depth),
            ];
            for (kind, filter) in runs {
                let st = ShadowSettings { k, filter, ..base };
                let (v, _) = s.pass.visibility(&map, &g, &camera, &st, kind).unwrap();
                let v: Vec<f32> = s.d.read_buffer(&v).unwrap();
                let label = format!("el {el} k {k} {kind:?} {}", filter.name());
                assert!(v.iter().all(|x| x.is_finite() && (0.0..=1.0).contains(x)), "{label}");
                // Below k = 50 per metre the f32/f64 difference (~1e-4 m in z) moves V by ≤ k/4 · 1e-4.
                if kind == VisibilityKind::Sigmoid && k <= 50.0 {
                    let cpu = sigmoid_visibility_cpu(&map.camera, &map_host, &camera, &host, &st);
                    max_diff(&format!("extreme_el{el}_k{k}_{}", filter.name()), &camera, &v, &cpu, 2e-3);
                }
            }
        }
    }
    // A sun below the horizon: no pass, no sun light.
    let below = Sun::from_azimuth_elevation(265.0, -3.0, [1.0; 3]).unwrap();
    let bounds = s.demo.scene.bounds().unwrap();
    let none = s.pass.shadow_map(&mut s.splatter, &s.gpu_scene, &bounds, &below, &settings(64), None).unwrap();
    assert!(none.is_none());
    assert!(s.pass.shadow_map(&mut s.splatter, &s.gpu_scene, &bounds, &below, &settings(0), None).is_err());
    assert_no_validation_messages(&s.d);
}

#[test]
fn empty_shadow_map_and_receivers_on_an_occluder() {
    let d = device();
    let mut splatter = Splatter::new(&d).unwrap();
    let mut pass = ShadowPass::new(&d).unwrap();
    // A ground plane of flat Gaussians under a transparent (opacity 0) floating slab:
    // the shadow map of the slab is empty, so everything is lit; receivers lie
    // exactly on the plane that is also the only occluder.
    let mut scene = Scene::default();
    // Splats 3 cm across: the bias (15 cm) exceeds their extent along the light, as it must
    // for any surface to not shadow itself.
    for i in 0..40 {
        for j in 0..40 {
            scene.means.push([i as f32 * 0.04 - 0.8, j as f32 * 0.04 - 0.8, 0.0]);
            scene.log_scales.push([(0.03f32).ln(), (0.03f32).ln(), (1e-4f32).ln()]);
            scene.rotations.push([1.0, 0.0, 0.0, 0.0]);
            scene.opacity_logits.push(6.0);
            scene.sh.extend([0.5, 0.5, 0.5]);
        }
    }
    let mut slab = scene.clone();
    for p in &mut slab.means {
        p[2] = 5.0;
    }
    for o in &mut slab.opacity_logits {
        *o = -40.0;
    }
    let mut both = scene.clone();
    both.means.extend(&slab.means);
    both.log_scales.extend(&slab.log_scales);
    both.rotations.extend(&slab.rotations);
    both.opacity_logits.extend(&slab.opacity_logits);
    both.sh.extend(&slab.sh);
    both.validate("test").unwrap();
    let gpu_scene = GpuScene::upload(&d, &both).unwrap();
    let camera = Camera::look_at(Vec3::new(0.0, -1.5, 0.8), Vec3::new(0.0, 0.0, 0.0), Vec3::Z, 60.0, 64, 48).unwrap();
    let ch = Channels { depth: true, median_depth: true, ..Channels::default() };
    let (g, host) = {
        let (g, _) =
            splatter.render(&gpu_scene, &camera, &SplatSettings { channels: ch, ..SplatSettings::default() }).unwrap();
        let h = g.read(&d).unwrap();
        (g, h)
    };
    let sun = Sun::from_azimuth_elevation(200.0, 50.0, [1.0; 3]).unwrap();
    let bounds = both.bounds().unwrap();
    for map_depth in [DepthMode::Median, DepthMode::Expected] {
        let st = ShadowSettings { map_depth, ..settings(256) };
        let map = pass.shadow_map(&mut splatter, &gpu_scene, &bounds, &sun, &st, None).unwrap().unwrap();
        let (v, _) = pass.visibility(&map, &g, &camera, &st, VisibilityKind::Sigmoid).unwrap();
        let v: Vec<f32> = d.read_buffer(&v).unwrap();
        let (t, _) = pass.visibility(&map, &g, &camera, &st, VisibilityKind::Traced).unwrap();
        let t: Vec<f32> = d.read_buffer(&t).unwrap();
        // Receivers on the plane: lit by both (the bias keeps the plane from shadowing itself).
        let covered: Vec<usize> = (0..host.alpha.len()).filter(|p| host.alpha[*p] > 0.9).collect();
        assert!(covered.len() > 200, "the plane should fill the view");
        let lit_e = covered.iter().filter(|p| v[**p] > 0.99).count();
        let lit_t = covered.iter().filter(|p| t[**p] > 0.99).count();
        assert!(
            lit_e * 100 >= covered.len() * 98,
            "{map_depth:?}: {lit_e} of {} receivers lit (sigmoid)",
            covered.len()
        );
        assert_eq!(lit_t, covered.len(), "{map_depth:?}: traced must see nothing above the plane");

        // The same map with no receivers at all: an empty shadow map of the slab alone.
        let empty_scene = GpuScene::upload(&d, &slab).unwrap();
        let empty = pass.shadow_map(&mut splatter, &empty_scene, &bounds, &sun, &st, None).unwrap().unwrap();
        let depths = empty.read_depth(&d, st.min_alpha).unwrap();
        assert!(depths.iter().all(|z| *z == empty.camera.far), "an empty map is at the far depth everywhere");
        let (v, _) = pass.visibility(&empty, &g, &camera, &st, VisibilityKind::Sigmoid).unwrap();
        let v: Vec<f32> = d.read_buffer(&v).unwrap();
        assert!(v.iter().all(|x| *x > 0.99), "nothing casts a shadow in an empty map");
        // Its backward: finite, and nothing to move (every receiver saturated lit).
        let n = (camera.width * camera.height) as usize;
        let ones = d.upload("dL/dV", &vec![1.0f32; n]).unwrap();
        let halves = d.upload("V_f", &vec![0.5f32; n]).unwrap();
        for loss in [GpuVisibilityLoss::Upstream(&ones), GpuVisibilityLoss::Bce(&halves)] {
            let b = pass.backward(&empty, &g, &camera, &st, loss).unwrap();
            assert!(b.k.is_finite() && b.loss.is_finite());
            let texel: Vec<f32> = d.read_buffer(&b.texel_depth).unwrap();
            assert!(texel.iter().all(|x| x.is_finite()), "{map_depth:?}: non-finite texel gradient");
        }
    }
    // Settings that cannot be used are refused with a message.
    let bad = ShadowSettings { k: f32::NAN, ..settings(64) };
    let err = pass.shadow_map(&mut splatter, &gpu_scene, &bounds, &sun, &bad, None).err().unwrap();
    assert!(err.to_string().contains("k NaN"), "{err}");
    assert_no_validation_messages(&d);
}

/// Cascaded shadow maps on the demo street: each cascade's map splatted where
/// the receivers look (as the relighter does) and tested alone, their
/// visibilities blended by depth on the CPU twin equal the GPU's blend; the
/// cascades' shadows agree with the whole-scene map's (the off-screen tower's
/// included), and the output is fully written over a NaN sentinel.
#[test]
fn cascaded_shadow_maps_blend_like_the_twin_and_shadow_like_the_scene_map() {
    let mut s = setup(30_000);
    let camera = s.demo.cameras[0].resized(352, 96);
    let sun = Sun::from_azimuth_elevation(150.0, 40.0, [1.0; 3]).unwrap();
    let bounds = s.demo.scene.bounds().unwrap();
    let st = ShadowSettings { fit: ShadowFit::Cascades, cascades: 3, resolution: 1024, ..settings(1024) };
    let (g, host) = receiver(&mut s, &camera, Channels::default());
    let (blended, cascades, timings) = s
        .pass
        .cascaded_visibility(
            &mut s.splatter,
            &s.gpu_scene,
            &bounds,
            &sun,
            &st,
            &g,
            &camera,
            VisibilityKind::Sigmoid,
            true,
        )
        .unwrap();
    assert_eq!(cascades.len(), 3);
    assert!(timings.stages.iter().any(|t| t.name == "shadow cascade blend"));
    let gpu: Vec<f32> = s.d.read_buffer(&blended).unwrap();
    assert!(gpu.iter().all(|v| v.is_finite() && (0.0..=1.0).contains(v)), "cascaded V unwritten or out of range");
    // Slices tile the view: each starts where the previous hands over, finer texels first.
    for pair in cascades.windows(2) {
        assert_eq!(pair[1].near, pair[0].blend_start);
        assert!(pair[0].near < pair[0].blend_start && pair[0].blend_start < pair[0].far);
        assert!(pair[0].texel() < pair[1].texel());
    }
    // Each cascade alone, then the twin's blend.
    let receivers = [(&g, &camera)];
    let mut per_cascade = Vec::new();
    for c in &cascades {
        let map = s
            .pass
            .shadow_map_for_receivers(&mut s.splatter, &s.gpu_scene, c.camera.clone(), &sun, &st, &receivers)
            .unwrap();
        let (v, _) = s.pass.visibility(&map, &g, &camera, &st, VisibilityKind::Sigmoid).unwrap();
        per_cascade.push(s.d.read_buffer::<f32>(&v).unwrap().iter().map(|x| f64::from(*x)).collect::<Vec<f64>>());
    }
    let img = DepthImage::from_gbuffer(&host);
    let depths: Vec<Option<f64>> =
        (0..img.alpha.len()).map(|p| img.depth(st.receiver_depth, p, f64::from(st.min_alpha), 0.0)).collect();
    let cpu = srug::shadow::cascades::blend_cascades_cpu(&per_cascade, &depths, &cascades);
    // The blend is one lerp in fp32 of the same inputs: 1e-6.
    max_diff("cascade_blend", &camera, &gpu, &cpu, 1e-6);
    // Every cascade serves some receivers, and some pixels lie in a hand-over band.
    for (i, c) in cascades.iter().enumerate() {
        let served = depths.iter().flatten().filter(|z| **z > f64::from(c.near) && **z <= f64::from(c.far)).count();
        assert!(served > 50, "cascade {i} serves only {served} pixels");
    }
    let banded = depths
        .iter()
        .flatten()
        .filter(|z| cascades.iter().take(2).any(|c| **z > f64::from(c.blend_start) && **z <= f64::from(c.far)))
        .count();
    assert!(banded > 20, "only {banded} pixels in the hand-over bands");
    // Against the whole-scene map: the same shadows but at the edges.
    let scene_st = ShadowSettings { fit: ShadowFit::SceneBounds, resolution: 2048, ..st };
    let map = shadow_map(&mut s, &sun, &scene_st, None);
    let (v, _) = s.pass.visibility(&map, &g, &camera, &scene_st, VisibilityKind::Sigmoid).unwrap();
    let whole: Vec<f32> = s.d.read_buffer(&v).unwrap();
    let (a, b): (Vec<bool>, Vec<bool>) = gpu.iter().zip(&whole).map(|(x, y)| (*x < 0.5, *y < 0.5)).unzip();
    let both = a.iter().zip(&b).filter(|(x, y)| **x && **y).count();
    let either = a.iter().zip(&b).filter(|(x, y)| **x || **y).count();
    let iou = both as f64 / either.max(1) as f64;
    eprintln!("cascades against the scene map: shadow IoU {iou:.3} over {either} pixels");
    assert!(either > 500 && iou > 0.9, "cascaded shadows differ from the scene map's: IoU {iou:.3}");
    // A camera far outside the scene (an aerial view 600 m away): its slices lie around the
    // scene, not in the empty space before it, so its shadows are there too.
    let centre = (Vec3::from_array(bounds.min) + Vec3::from_array(bounds.max)) * 0.5;
    let aerial = Camera::look_at(centre + Vec3::new(-500.0, -100.0, 300.0), centre, Vec3::Z, 25.0, 176, 48).unwrap();
    let (ga, _) = receiver(&mut s, &aerial, Channels::default());
    let kind = VisibilityKind::Sigmoid;
    let (va, cascades, _) = s
        .pass
        .cascaded_visibility(&mut s.splatter, &s.gpu_scene, &bounds, &sun, &st, &ga, &aerial, kind, true)
        .unwrap();
    assert!(cascades[0].near > 100.0, "the first slice starts at {} m", cascades[0].near);
    let map = shadow_map(&mut s, &sun, &scene_st, None);
    let (vw, _) = s.pass.visibility(&map, &ga, &aerial, &scene_st, kind).unwrap();
    let (a, b): (Vec<f32>, Vec<f32>) = (s.d.read_buffer(&va).unwrap(), s.d.read_buffer(&vw).unwrap());
    let both = a.iter().zip(&b).filter(|(x, y)| **x < 0.5 && **y < 0.5).count();
    let either = a.iter().zip(&b).filter(|(x, y)| **x < 0.5 || **y < 0.5).count();
    let iou = both as f64 / either.max(1) as f64;
    eprintln!("aerial view: cascades against the scene map, shadow IoU {iou:.3} over {either} pixels");
    assert!(either > 100 && iou > 0.8, "an aerial view's cascaded shadows: IoU {iou:.3}");
    assert_no_validation_messages(&s.d);
}

/// Cascades are refused where they cannot work: a lens model, an
/// orthographic view, a count outside 2..=4; and a single light camera
/// cannot be asked for a cascaded fit.
#[test]
fn cascades_refuse_what_they_cannot_slice() {
    let s = setup(2_000);
    let bounds = s.demo.scene.bounds().unwrap();
    let sun = Sun::from_azimuth_elevation(150.0, 40.0, [1.0; 3]).unwrap();
    let camera = s.demo.cameras[0].resized(176, 48);
    let ok = srug::shadow::cascades::cascade_cameras(&bounds, &sun, 512, &camera, 3).unwrap();
    assert_eq!(ok.len(), 3);
    for n in [0, 1, 5] {
        let e = srug::shadow::cascades::cascade_cameras(&bounds, &sun, 512, &camera, n).unwrap_err();
        assert!(e.to_string().contains("cascades"), "{e}");
    }
    let ortho =
        Camera::orthographic(Vec3::new(0.0, 0.0, 50.0), -Vec3::Z, Vec3::Y, 10.0, 10.0, 64, 64, 0.1, 100.0).unwrap();
    assert!(srug::shadow::cascades::cascade_cameras(&bounds, &sun, 512, &ortho, 3).is_err());
    let e = light_camera(&bounds, &sun, 512, ShadowFit::Cascades, Some(&camera)).unwrap_err();
    assert!(e.to_string().contains("cascade"), "{e}");
    let bad = ShadowSettings { fit: ShadowFit::Cascades, cascades: 7, ..settings(512) };
    assert!(bad.validate().is_err());
}

/// A kept map released to its texels (`ShadowMap::release_splats`, what the
/// relighter keeps between frames) frees its per-Gaussian records, tests its
/// receivers bit for bit as before, and refuses the traced test and the
/// backward pass, which read the splats, with a message.
#[test]
fn a_map_released_to_its_texels_tests_the_same_and_refuses_what_reads_splats() {
    let mut s = setup(20_000);
    let camera = s.demo.cameras[0].resized(176, 48);
    let sun = Sun::from_direction(s.demo.sun_direction, [1.0; 3]).unwrap();
    let st = settings(512);
    let (g, _) = receiver(&mut s, &camera, Channels::default());
    let mut map = shadow_map(&mut s, &sun, &st, None);
    let (v, _) = s.pass.visibility(&map, &g, &camera, &st, VisibilityKind::Sigmoid).unwrap();
    let before: Vec<f32> = s.d.read_buffer(&v).unwrap();
    let splat_bytes = map.frame.splats.size() + map.frame.sorted_gaussians.size();
    s.d.wait_idle().unwrap();
    let in_use = s.d.memory_usage().current_bytes;
    assert!(!map.splats_released());
    map.release_splats(&s.d).unwrap();
    s.d.wait_idle().unwrap();
    let freed = in_use.saturating_sub(s.d.memory_usage().current_bytes);
    assert!(map.splats_released() && freed >= splat_bytes, "{freed} bytes freed, the splats took {splat_bytes}");
    let (v, _) = s.pass.visibility(&map, &g, &camera, &st, VisibilityKind::Sigmoid).unwrap();
    let after: Vec<f32> = s.d.read_buffer(&v).unwrap();
    assert!(before.iter().zip(&after).all(|(a, b)| a.to_bits() == b.to_bits()), "the released map tests differently");
    assert!(before.iter().any(|v| *v < 0.5) && before.iter().any(|v| *v > 0.5), "no shadow edge to compare");
    let traced = s.pass.visibility(&map, &g, &camera, &st, VisibilityKind::Traced).err().unwrap();
    assert!(traced.to_string().contains("its splats were released"), "{traced}");
    let ones = s.d.upload("dL/dV", &vec![1.0f32; (camera.width * camera.height) as usize]).unwrap();
    let backward = s.pass.backward(&map, &g, &camera, &st, GpuVisibilityLoss::Upstream(&ones)).err().unwrap();
    assert!(backward.to_string().contains("the backward pass reads them"), "{backward}");
    assert_no_validation_messages(&s.d);
}
