//! Stability at the extremes, through the whole pipeline: every case renders
//! a relit frame (splat → shadow map → sigmoid test → shading, and the U-Net
//! where a network is given) and runs the shadow loss backward to the
//! Gaussians (sigmoid backward, then the splat backward of the shadow map and
//! of the receivers). Every output is pre-filled with NaN and must come back
//! finite and within its range (alpha, V and display in [0, 1], radiance and
//! colour non-negative); where a CPU twin is defined the GPU must agree with
//! it on the same inputs: splatted colour and alpha (PSNR ≥ 50 dB, the splat
//! suite's bar), V against the f64 sigmoid twin (≤ 2e-3 absolute), shading
//! against the f64 shading twin given the GPU's G-buffers (≤ 1e-3 relative).
//!
//! Cases: scales of 1e-8 and 1e4, opacity 0 and 1, near-zero and zero
//! quaternions, k from 1e-3 to 1e9, the sun at the horizon and the zenith,
//! roughness and metallic 0 and 1, radiance 1e5, fp16 activations fed values
//! beyond fp16's range, the scene 1e5 units from the origin, a single
//! Gaussian, and 5 million Gaussians.

#![allow(clippy::unwrap_used, clippy::expect_used, reason = "a failed unwrap is a failed test")]

use glam::Vec3;
use srug::frame::{RelightDecisions, RelightSettings, Relighter};
use srug::gpu::Device;
use srug::indirect::{StoragePrecision, UNet, UNetConfig, UNetWeights};
use srug::scene::activate::GpuScene;
use srug::scene::demo::{demo_city, DemoOptions};
use srug::scene::{Camera, Scene};
use srug::shade::cpu::{shade_cpu, ShadeTables};
use srug::shade::{BrdfLut, BrdfTable, EnvironmentPrep, PrepareSettings, PreparedEnvironment, ProceduralSky};
use srug::shadow::backward::GpuVisibilityLoss;
use srug::shadow::cpu::{sigmoid_visibility_cpu, DepthImage};
use srug::shadow::{ShadowPass, ShadowSettings, Sun, VisibilityKind};
use srug::splat::cpu::render_cpu;
use srug::splat::SplatSettings;
use srug_tests::{assert_no_validation_messages, device, move_scene, psnr, save_comparison, NAN_SENTINEL};

const NAN: u32 = NAN_SENTINEL;

/// One extreme.
struct Case {
    name: String,
    scene: Scene,
    camera: Camera,
    sun: Sun,
    settings: RelightSettings,
    /// Network activation storage, when the U-Net runs.
    network: Option<StoragePrecision>,
    /// Compare with the CPU twins (off where the twin would take minutes).
    twins: bool,
}

struct Rig {
    d: Device,
    relighter: Relighter,
    pass: ShadowPass,
    prep: EnvironmentPrep,
    brdf: BrdfTable,
    weights: UNetWeights,
}

impl Rig {
    fn new() -> Self {
        let d = device();
        let prep = EnvironmentPrep::new(&d).unwrap();
        let brdf = prep.brdf_table(BrdfLut::Karis, 33, 256).unwrap();
        let config = UNetConfig { widths: [8, 8, 8, 8, 8], ..UNetConfig::default() };
        Rig {
            relighter: Relighter::new(&d).unwrap(),
            pass: ShadowPass::new(&d).unwrap(),
            prep,
            brdf,
            weights: UNetWeights::random(config, 5),
            d,
        }
    }

    fn environment(&self, sun: &Sun) -> PreparedEnvironment {
        let sky = ProceduralSky::new(sun.direction, sun.intensity[0].max(1e-3)).render().unwrap();
        let small = PrepareSettings { levels: 4, samples: 32, irradiance_size: (16, 8), irradiance_source_width: 32 };
        self.prep.prepare(&sky, &small).unwrap()
    }

    fn tables(&self, env: &PreparedEnvironment) -> ShadeTables {
        let to64 = |v: Vec<f32>| v.into_iter().map(f64::from).collect::<Vec<_>>();
        ShadeTables {
            base: env.base,
            specular: env.read_specular(&self.d).unwrap().into_iter().map(to64).collect(),
            irradiance_size: env.irradiance_size,
            irradiance: to64(self.d.read_buffer(&env.irradiance).unwrap()),
            lut_size: self.brdf.size,
            lut: to64(self.d.read_buffer(&self.brdf.buffer).unwrap()),
        }
    }
}

fn all_finite(label: &str, what: &str, v: &[f32]) {
    if let Some(i) = v.iter().position(|x| !x.is_finite()) {
        panic!("{label}: {what}[{i}] = {} (of {})", v[i], v.len());
    }
}

fn within(label: &str, what: &str, v: &[f32], lo: f32, hi: f32) {
    all_finite(label, what, v);
    if let Some(i) = v.iter().position(|x| *x < lo || *x > hi) {
        panic!("{label}: {what}[{i}] = {} outside [{lo}, {hi}]", v[i]);
    }
}

/// Renders, checks ranges and twins, runs the backward pass; returns the display image.
fn run(rig: &mut Rig, case: &Case) -> Vec<f32> {
    let label = case.name.as_str();
    let d = rig.d.clone();
    let gpu = GpuScene::upload(&d, &case.scene).unwrap();
    let attributes = case.scene.attributes();
    let bounds = case.scene.bounds().unwrap();
    let env = rig.environment(&case.sun);
    let mut settings = case.settings;
    // The splat's own colour too, checked against its twin below.
    settings.rgb = true;
    settings.shade.prefill = Some(NAN);
    settings.shadow.prefill = Some(NAN);
    match case.network {
        Some(p) => {
            let mut net = UNet::with_precision(&d, &rig.weights, p).unwrap();
            net.set_prefill(Some(NAN));
            rig.relighter.set_network(Some(net));
        }
        None => rig.relighter.set_network(None),
    }
    let relit = rig
        .relighter
        .render(&gpu, &attributes, &bounds, &case.camera, Some(&case.sun), &env, &rig.brdf, &settings)
        .unwrap_or_else(|e| panic!("{label}: {e}"));
    let camera = settings.render_camera(&case.camera);
    let g = relit.gbuffer.read(&d).unwrap();
    within(label, "alpha", &g.alpha, 0.0, 1.0);
    within(label, "colour", g.rgb_values().unwrap(), 0.0, f32::MAX);
    for (name, values, _) in g.channels() {
        all_finite(label, name, values);
    }
    let image = relit.shaded.read(&d).unwrap();
    within(label, "display", &image.display, 0.0, 1.0);
    within(label, "radiance", &image.radiance, 0.0, f32::MAX);
    within(label, "L_sun", &image.sun, 0.0, f32::MAX);
    within(label, "L_sky", &image.sky, 0.0, f32::MAX);
    let visibility: Option<Vec<f32>> = relit.visibility.as_ref().map(|v| d.read_buffer(v).unwrap());
    if let Some(v) = &visibility {
        within(label, "V", v, 0.0, 1.0);
    }
    let indirect: Option<Vec<f32>> = relit.shaded.indirect.as_ref().map(|b| d.read_buffer(b).unwrap());
    if let Some(ind) = &indirect {
        all_finite(label, "L_ind", ind);
    }
    assert_eq!(relit.shaded.indirect.is_some(), case.network.is_some(), "{label}: inference iff a network");

    if case.twins {
        // Splat twin on the same scene and render camera.
        let splat = SplatSettings { channels: Default::default(), sh_degree: settings.sh_degree, ..Default::default() };
        let cpu = render_cpu(&case.scene, &camera, &splat);
        let (g_rgb, cpu_rgb) = (g.rgb_values().unwrap(), cpu.rgb_values().unwrap());
        let (p_rgb, p_alpha) = (psnr(g_rgb, &to64(cpu_rgb)), psnr(&g.alpha, &to64(&cpu.alpha)));
        if p_rgb < 50.0 || p_alpha < 50.0 {
            let at = save_comparison(&format!("stability_{label}_rgb"), camera.width, camera.height, 3, g_rgb, cpu_rgb);
            panic!("{label}: splat against its twin: rgb {p_rgb:.1} dB, alpha {p_alpha:.1} dB (< 50; images {at})");
        }
        // Shading twin on the GPU's G-buffers, visibility and L_ind.
        let decisions = RelightDecisions::new(&attributes, Some(&case.sun), &settings).unwrap();
        let mut shade = settings.shade;
        shade.visibility = decisions.visibility;
        let planar: Option<Vec<f32>> = indirect.clone();
        let cpu = shade_cpu(
            &g,
            &camera,
            &rig.tables(&env),
            decisions.sun.as_ref(),
            &shade,
            visibility.as_deref(),
            planar.as_deref(),
        );
        let worst = image
            .radiance
            .iter()
            .zip(&cpu.radiance)
            .map(|(a, b)| (f64::from(*a) - b).abs() / (1.0 + b.abs()))
            .fold(0.0, f64::max);
        if worst.is_nan() || worst > 1e-3 {
            let c32: Vec<f32> = cpu.radiance.iter().map(|v| *v as f32).collect();
            let at = save_comparison(
                &format!("stability_{label}_radiance"),
                camera.width,
                camera.height,
                3,
                &image.radiance,
                &c32,
            );
            panic!("{label}: shading against its twin: relative error {worst:e} > 1e-3 (images {at})");
        }
    }

    // The shadow loss backward, from a sigmoid test on its own.
    if case.sun.above_horizon() {
        let st = ShadowSettings { prefill: Some(NAN), ..settings.shadow };
        let splatter = rig.relighter.splatter();
        let receivers = splatter.render_frame(&gpu, &camera, &st.receiver_splat()).unwrap();
        let map = rig.pass.shadow_map(splatter, &gpu, &bounds, &case.sun, &st, Some(&camera)).unwrap().unwrap();
        let (v, _) = rig.pass.visibility(&map, &receivers.gbuffer, &camera, &st, VisibilityKind::Sigmoid).unwrap();
        let v: Vec<f32> = d.read_buffer(&v).unwrap();
        within(label, "V (sigmoid)", &v, 0.0, 1.0);
        if case.twins {
            let map_img = DepthImage::from_gbuffer(&map.frame.gbuffer.read(&d).unwrap());
            let rec_img = DepthImage::from_gbuffer(&receivers.gbuffer.read(&d).unwrap());
            let cpu = sigmoid_visibility_cpu(&map.camera, &map_img, &camera, &rec_img, &st);
            // Receivers whose z_s − z sits within 1e-4·|z| of the sigmoid's steep middle
            // are ill-conditioned at large k; counted apart, not compared.
            let worst = v.iter().zip(&cpu).map(|(a, b)| (f64::from(*a) - b).abs()).fold(0.0, f64::max);
            if worst > 2e-3 && st.k <= 1e3 {
                let c32: Vec<f32> = cpu.iter().map(|x| *x as f32).collect();
                let at = save_comparison(&format!("stability_{label}_v"), camera.width, camera.height, 1, &v, &c32);
                panic!("{label}: V against its twin: max error {worst:e} > 2e-3 (images {at})");
            }
        }
        let ones = d.upload("dL/dV", &vec![1.0f32; v.len()]).unwrap();
        let b = rig.pass.backward(&map, &receivers.gbuffer, &camera, &st, GpuVisibilityLoss::Upstream(&ones)).unwrap();
        assert!(b.k.is_finite() && b.loss.is_finite(), "{label}: dL/dk {} loss {}", b.k, b.loss);
        let splatter = rig.relighter.splatter();
        for (frame, grads, which) in [(&map.frame, &b.map, "map"), (&receivers, &b.receiver, "receivers")] {
            let gg = splatter.backward(frame, &gpu, grads, false).unwrap().read(&d).unwrap();
            let flat: Vec<f32> = gg
                .means
                .iter()
                .flatten()
                .chain(gg.log_scales.iter().flatten())
                .chain(gg.rotations.iter().flatten())
                .chain(&gg.opacity_logits)
                .copied()
                .collect();
            all_finite(label, &format!("dL/dGaussians through the {which}"), &flat);
        }
    }
    assert_no_validation_messages(&d);
    println!("{label}: finite and in range{}", if case.twins { ", agrees with the twins" } else { "" });
    image.display
}

fn to64(v: &[f32]) -> Vec<f64> {
    v.iter().map(|x| f64::from(*x)).collect()
}

/// A small street of the demo city and its first camera at 96×32.
fn street() -> (Scene, Camera) {
    let city = demo_city(&DemoOptions { gaussians: 4000, seed: 3, sh_degree: 1 }).unwrap();
    (city.scene, city.cameras[0].resized(96, 32))
}

fn base_settings() -> RelightSettings {
    let mut s = RelightSettings::preset(srug::frame::Preset::Balanced);
    s.shadow.resolution = 256;
    s
}

fn sun(azimuth: f32, elevation: f32, intensity: f32) -> Sun {
    Sun::from_azimuth_elevation(azimuth, elevation, [intensity; 3]).unwrap()
}

fn case(name: &str, scene: Scene, camera: &Camera) -> Case {
    Case {
        name: name.into(),
        scene,
        camera: camera.clone(),
        sun: sun(260.0, 50.0, std::f32::consts::PI),
        settings: base_settings(),
        network: None,
        twins: true,
    }
}

#[test]
fn extreme_gaussians_stay_finite_and_match_twins() {
    let mut rig = Rig::new();
    let (scene, camera) = street();
    run(&mut rig, &case("baseline", scene.clone(), &camera));

    let mut s = scene.clone();
    for (i, l) in s.log_scales.iter_mut().enumerate() {
        if i % 7 == 0 {
            *l = [1e-8f32.ln(); 3];
        } else if i % 97 == 0 {
            *l = [1e4f32.ln(); 3];
        }
    }
    run(&mut rig, &case("scales_1e-8_and_1e4", s, &camera));

    let mut s = scene.clone();
    for (i, o) in s.opacity_logits.iter_mut().enumerate() {
        *o = match i % 3 {
            0 => -1e4,
            1 => 1e4,
            _ => *o,
        };
    }
    run(&mut rig, &case("opacity_0_and_1", s, &camera));

    let mut s = scene.clone();
    for (i, q) in s.rotations.iter_mut().enumerate() {
        match i % 4 {
            0 => *q = [1e-30, 0.0, 0.0, 0.0],
            1 => *q = [0.0, 1e-20, -1e-20, 1e-25],
            2 => *q = [0.0; 4],
            _ => {}
        }
    }
    run(&mut rig, &case("near_zero_quaternions", s, &camera));

    // One Gaussian, large enough to cover a good part of the view.
    let mut one = Scene { sh_degree: scene.sh_degree, ..Scene::default() };
    let k = srug::scene::sh_coefficients(scene.sh_degree) * 3;
    let i = scene.len() / 2;
    one.means.push(scene.means[i]);
    one.log_scales.push([0.5f32.ln(); 3]);
    one.rotations.push([1.0, 0.0, 0.0, 0.0]);
    one.opacity_logits.push(3.0);
    one.sh.extend_from_slice(&scene.sh[i * k..(i + 1) * k]);
    one.normals = scene.normals.as_ref().map(|n| vec![n[i]]);
    let m = &scene.materials;
    one.materials.albedo = m.albedo.as_ref().map(|v| vec![v[i]]);
    one.materials.roughness = m.roughness.as_ref().map(|v| vec![v[i]]);
    one.materials.metallic = m.metallic.as_ref().map(|v| vec![v[i]]);
    one.materials.ao = m.ao.as_ref().map(|v| vec![v[i]]);
    one.materials.visibility = m.visibility.as_ref().map(|v| vec![v[i]]);
    let target = Vec3::from_array(scene.means[i]);
    let cam = Camera::look_at(target + Vec3::new(0.0, -3.0, 1.5), target, Vec3::Z, 60.0, 48, 32).unwrap();
    run(&mut rig, &case("single_gaussian", one, &cam));
}

#[test]
fn extreme_lights_and_materials_stay_finite_and_match_twins() {
    let mut rig = Rig::new();
    let (scene, camera) = street();
    for k in [1e-3f32, 1.0, 1e3, 1e9] {
        let mut c = case(&format!("k_{k:e}"), scene.clone(), &camera);
        c.settings.shadow.k = k;
        run(&mut rig, &c);
    }
    for (name, elevation) in [("sun_at_horizon", 0.01f32), ("sun_on_horizon", 0.0), ("sun_at_zenith", 90.0)] {
        let mut c = case(name, scene.clone(), &camera);
        c.sun = sun(260.0, elevation, std::f32::consts::PI);
        run(&mut rig, &c);
    }
    for (rough, metal) in [(0.0f32, 0.0f32), (0.0, 1.0), (1.0, 0.0), (1.0, 1.0)] {
        let mut s = scene.clone();
        let logit = |x: f32| if x == 0.0 { -1e4 } else { 1e4 };
        s.materials.roughness = Some(vec![logit(rough); s.len()]);
        s.materials.metallic = Some(vec![logit(metal); s.len()]);
        run(&mut rig, &case(&format!("roughness_{rough}_metallic_{metal}"), s, &camera));
    }
    let mut c = case("radiance_1e5", scene.clone(), &camera);
    c.sun = sun(200.0, 40.0, 1e5);
    c.settings.shade.env_intensity = 1e5;
    c.network = Some(StoragePrecision::Fp32);
    run(&mut rig, &c);
    // L_sun and L_sky of 1e5 exceed fp16's 65504: the fp16 network must stay finite.
    if rig.d.info().storage_16bit {
        let mut c = case("fp16_overflow", scene.clone(), &camera);
        c.sun = sun(200.0, 40.0, 1e5);
        c.settings.shade.env_intensity = 1e5;
        c.network = Some(StoragePrecision::Fp16);
        run(&mut rig, &c);
    } else {
        println!("fp16_overflow skipped: the device has no 16-bit storage");
    }
}

#[test]
fn a_scene_far_from_the_origin_renders_like_one_at_it() {
    let mut rig = Rig::new();
    let (scene, camera) = street();
    let near = run(&mut rig, &case("at_origin", scene.clone(), &camera));
    // Urban scenes in world coordinates: 1e5 units out, f32 positions keep ~8 mm.
    let offset = Vec3::new(1e5, -1e5, 0.0);
    let mut far = scene.clone();
    move_scene(&mut far, offset);
    let mut cam = camera.clone();
    cam.position += offset;
    let far_image = run(&mut rig, &case("1e5_from_origin", far, &cam));
    let p = psnr(&far_image, &to64(&near));
    println!("display 1e5 from the origin against at the origin: {p:.1} dB");
    assert!(p >= 30.0, "moving the scene 1e5 units changed the image: {p:.1} dB");
}

#[test]
fn five_million_gaussians_stay_finite() {
    let mut rig = Rig::new();
    let city = demo_city(&DemoOptions { gaussians: 5_000_000, seed: 7, sh_degree: 0 }).unwrap();
    let mut c = case("5M_gaussians", city.scene, &city.cameras[0].resized(64, 24));
    c.twins = false;
    let display = run(&mut rig, &c);
    assert!(display.iter().any(|v| *v > 0.05), "5M: the frame is black");
}
