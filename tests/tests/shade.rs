//! Deferred shading against its f64 CPU twin and against closed forms: the
//! BRDF tables (both variants) against docs/conventions.md §6's reference values and the
//! r → 0 limit, the environment prefilter and irradiance, the white furnace,
//! the shading kernels on random and extreme G-buffers, and a splatted
//! sun-lit plane against the paper's BRDF evaluated by hand. Outputs are
//! pre-filled with NaN, so an unwritten pixel fails.

#![allow(clippy::unwrap_used, clippy::expect_used, reason = "a failed unwrap is a failed test")]

use glam::{Mat3, Vec3};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;
use srug::gpu::Device;
use srug::scene::Camera;
use srug::shade::cpu::{
    brdf_lut_point, brdf_table_cpu, irradiance_cpu, prefilter_cpu, pyramid_cpu, shade_cpu, ShadeTables,
};
use srug::shade::env::{level_size, pyramid_levels};
use srug::shade::{
    Background, BrdfLut, BrdfTable, EnvironmentMap, EnvironmentPrep, PrepareSettings, PreparedEnvironment, ShadeInputs,
    ShadeSettings, ShadeTerms, Shader, ToneMap, VisibilitySource,
};
use srug::shadow::Sun;
use srug::splat::Channel;
use srug::splat::{GBuffer, GpuGBuffer};
use srug_tests::{assert_no_validation_messages, device, save_comparison};

const NAN: u32 = srug_tests::NAN_SENTINEL;

fn to64(v: &[f32]) -> Vec<f64> {
    v.iter().map(|&x| f64::from(x)).collect()
}

/// Largest |gpu − cpu| / (1 + |cpu|); saves images when above `tol`.
fn rel_err(label: &str, w: u32, h: u32, k: usize, gpu: &[f32], cpu: &[f64], tol: f64) -> f64 {
    assert_eq!(gpu.len(), cpu.len(), "{label}: lengths");
    assert!(gpu.iter().all(|v| v.is_finite()), "{label}: non-finite GPU value (NaN sentinel left or overflow)");
    let err = gpu.iter().zip(cpu).map(|(a, b)| (f64::from(*a) - b).abs() / (1.0 + b.abs())).fold(0.0, f64::max);
    if err > tol {
        let cpu32: Vec<f32> = cpu.iter().map(|v| *v as f32).collect();
        let at = save_comparison(label, w, h, k, gpu, &cpu32);
        panic!("{label}: relative error {err:e} > {tol:e}; images at {at}");
    }
    err
}

#[test]
fn brdf_tables_match_twin_references_and_limits() {
    let d = device();
    let prep = EnvironmentPrep::new(&d).unwrap();
    let (size, samples) = (129u32, 1024u32);
    for variant in [BrdfLut::Karis, BrdfLut::HeightCorrelated] {
        let table = prep.brdf_table(variant, size, samples).unwrap();
        let gpu: Vec<f32> = d.read_buffer(&table.buffer).unwrap();
        let cpu = brdf_table_cpu(variant, size, samples);
        // GPU against twin: same samples, f32 against f64 sums of 1024 terms.
        // Column 0 (N·V clamped to 1e-4) is ill-conditioned in f32 at low roughness:
        // G1(N·L)/N·V with N·L from a cancelling difference. Stated apart.
        let (mut err, mut err_grazing) = (0.0f64, 0.0f64);
        for (t, (a, b)) in gpu.iter().zip(&cpu).enumerate() {
            let e = (f64::from(*a) - b).abs();
            if (t / 2) % size as usize == 0 {
                err_grazing = err_grazing.max(e);
            } else {
                err = err.max(e);
            }
        }
        println!("{variant:?}: max |GPU − CPU| = {err:e} for N·V ≥ 1/128, {err_grazing:e} at N·V = 1e-4");
        // f32 Hammersley points and directions against f64: ≤ 2e-4, far below the 5e-3 sampling error.
        assert!(err <= 2e-4, "{variant:?}: GPU table differs from the twin by {err:e} (tolerance 2e-4)");
        assert!(err_grazing <= 0.1, "{variant:?}: at N·V = 1e-4 the table is off by {err_grazing:e} (tolerance 0.1)");
        let at = |nov: f64, r: f64| {
            let (i, j) = ((nov * f64::from(size - 1)).round() as usize, (r * f64::from(size - 1)).round() as usize);
            let t = 2 * (j * size as usize + i);
            (f64::from(gpu[t]), f64::from(gpu[t + 1]))
        };
        // r = 0: A = 1 − (1 − N·V)⁵, B = (1 − N·V)⁵ (exact up to f32 rounding); small r approaches it.
        for i in 0..size {
            let nov = (f64::from(i) / f64::from(size - 1)).max(1e-4);
            let fc = (1.0 - nov).powi(5);
            let (a, b) = at(f64::from(i) / f64::from(size - 1), 0.0);
            assert!((a - (1.0 - fc)).abs() < 1e-4 && (b - fc).abs() < 1e-4, "r = 0, N·V = {nov}: ({a}, {b})");
            let (a1, b1) = brdf_lut_point(variant, nov, 1e-4, samples);
            assert!((a1 - (1.0 - fc)).abs() < 2e-3 && (b1 - fc).abs() < 2e-3, "r → 0, N·V = {nov}: ({a1}, {b1})");
        }
        // Energy: A + B is the directional albedo of a white metal, ≤ 1; at N·V = 1, B ≈ 0.
        for t in gpu.chunks_exact(2) {
            assert!(
                t[0] >= 0.0 && t[1] >= 0.0 && t[0] + t[1] <= 1.0 + 1e-4,
                "A + B = {} > 1 + 1e-4 (f32 sums of 1024 terms)",
                t[0] + t[1]
            );
        }
        for j in 0..size {
            assert!(at(1.0, f64::from(j) / f64::from(size - 1)).1 < 1e-3, "B at N·V = 1 is not ≈ 0");
        }
        // docs/conventions.md §6 reference values (a 1024-sample table is within ~5e-3).
        let refs: &[(f64, f64, f64, f64)] = match variant {
            BrdfLut::Karis => &[(0.25, 0.25, 0.6570, 0.1734), (0.5, 0.5, 0.7285, 0.0185), (1.0, 1.0, 0.3068, 0.0)],
            BrdfLut::HeightCorrelated => &[(0.5, 0.5, 0.8348, 0.0223), (1.0, 0.25, 0.5867, 0.0109)],
        };
        for &(r, nov, ea, eb) in refs {
            let (a, b) = at(nov, r);
            println!("{variant:?} r={r} N·V={nov}: ({a:.4}, {b:.4}) reference ({ea}, {eb})");
            assert!((a - ea).abs() < 5e-3 && (b - eb).abs() < 5e-3, "{variant:?} r={r} N·V={nov}: ({a}, {b})");
        }
    }
    // The two variants differ (by up to 0.16 in A per docs/conventions.md §6).
    let k = brdf_lut_point(BrdfLut::Karis, 0.5, 0.5, 1024);
    let h = brdf_lut_point(BrdfLut::HeightCorrelated, 0.5, 0.5, 1024);
    assert!((h.0 - k.0) > 0.05, "the variants should differ: {k:?} vs {h:?}");
    assert!(prep.brdf_table(BrdfLut::Karis, 1, 16).is_err());
    assert_no_validation_messages(&d);
}

/// A smooth environment with a small bright sun (1e3).
fn test_environment(w: u32, h: u32) -> EnvironmentMap {
    let mut rgb = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let (u, v) = ((f64::from(x) + 0.5) / f64::from(w), (f64::from(y) + 0.5) / f64::from(h));
            let sun = if (u - 0.3).abs() < 0.03 && (v - 0.25).abs() < 0.04 { 1e3 } else { 0.0 };
            rgb.push((0.2 + 0.8 * (1.0 - v) + sun) as f32);
            rgb.push((0.3 + 0.5 * (6.0 * u).sin().abs() + sun) as f32);
            rgb.push((1.0 - 0.7 * v + 0.2 * (9.0 * u).cos() + sun) as f32);
        }
    }
    EnvironmentMap::from_rgb(w, h, rgb, "test").unwrap()
}

fn tables(d: &Device, env: &PreparedEnvironment, brdf: &BrdfTable) -> ShadeTables {
    ShadeTables {
        base: env.base,
        specular: env.read_specular(d).unwrap().iter().map(|l| to64(l)).collect(),
        irradiance_size: env.irradiance_size,
        irradiance: to64(&d.read_buffer::<f32>(&env.irradiance).unwrap()),
        lut_size: brdf.size,
        lut: to64(&d.read_buffer::<f32>(&brdf.buffer).unwrap()),
    }
}

#[test]
fn prefilter_and_irradiance_match_twin() {
    let d = device();
    let prep = EnvironmentPrep::new(&d).unwrap();
    let env = test_environment(64, 32);
    let settings = PrepareSettings { levels: 5, samples: 64, irradiance_size: (16, 8), irradiance_source_width: 16 };
    let prepared = prep.prepare(&env, &settings).unwrap();
    assert_eq!(prepared.levels, 5);
    let gpu = prepared.read_specular(&d).unwrap();
    let pyramid = pyramid_cpu(&env.rgb, (64, 32));
    assert_eq!(pyramid.len() as u32, pyramid_levels((64, 32)));
    assert_eq!(gpu[0], env.rgb, "level 0 is the source");
    for (l, level) in gpu.iter().enumerate().skip(1) {
        let size = level_size((64, 32), l as u32);
        let r = l as f64 / 4.0;
        let cpu = prefilter_cpu(&pyramid, (64, 32), r, 64, size);
        // Scaled by the level's largest value: the sun is 1e3, the sky ≈ 1.
        let scale = cpu.iter().fold(1.0f64, |m, v| m.max(v.abs()));
        let err = level.iter().zip(&cpu).map(|(a, b)| (f64::from(*a) - b).abs()).fold(0.0, f64::max) / scale;
        println!("prefilter level {l} (r = {r}): max error {err:e} of the level maximum {scale:.1}");
        if err > 1e-4 {
            let worst = level
                .iter()
                .zip(&cpu)
                .map(|(a, b)| (f64::from(*a) - b).abs())
                .enumerate()
                .fold((0, 0.0), |m, (i, e)| if e > m.1 { (i, e) } else { m })
                .0;
            println!("worst at texel {} channel {}: GPU {} CPU {}", worst / 3, worst % 3, level[worst], cpu[worst]);
            let cpu32: Vec<f32> = cpu.iter().map(|v| *v as f32).collect();
            let at = save_comparison(&format!("prefilter_{l}"), size.0, size.1, 3, level, &cpu32);
            panic!("prefilter level {l}: error {err:e} > 1e-4 of the maximum; images at {at}");
        }
    }
    let il = EnvironmentPrep::irradiance_level((64, 32), &settings) as usize;
    let irr_cpu = irradiance_cpu(&pyramid[il], level_size((64, 32), il as u32), (16, 8));
    let irr: Vec<f32> = d.read_buffer(&prepared.irradiance).unwrap();
    let err = rel_err("irradiance", 16, 8, 3, &irr, &irr_cpu, 1e-4);
    println!("irradiance: relative error {err:e}");
    // A uniform environment prefilters to itself and has irradiance π (normalised kernel).
    let white = prep.prepare(&EnvironmentMap::uniform([1.0; 3], 32, 16).unwrap(), &settings).unwrap();
    for level in white.read_specular(&d).unwrap() {
        assert!(level.iter().all(|v| (v - 1.0).abs() < 1e-5), "a white environment prefilters to 1");
    }
    let irr: Vec<f32> = d.read_buffer(&white.irradiance).unwrap();
    assert!(irr.iter().all(|v| (f64::from(*v) - std::f64::consts::PI).abs() < 1e-4), "white irradiance is π");
    assert!(prep.prepare(&env, &PrepareSettings { samples: 0, ..settings }).is_err());
    assert_no_validation_messages(&d);
}

/// A host G-buffer and its GPU copy.
fn upload(d: &Device, g: &GBuffer) -> GpuGBuffer {
    GpuGBuffer {
        width: g.width,
        height: g.height,
        rgb: g.rgb.as_ref().map(|v| d.upload("rgb", v).unwrap()),
        alpha: d.upload("alpha", &g.alpha).unwrap(),
        channels: g.channels.iter().map(|(c, v)| (c, d.upload(c.name(), v).unwrap())).collect(),
        top_gaussian: None,
    }
}

/// Random premultiplied G-buffer; every fourth pixel takes an extreme
/// (roughness and metallic 0 or 1, a normal perpendicular to the view, alpha 0 or tiny).
fn random_gbuffer(w: u32, h: u32, camera: &Camera, seed: u64) -> GBuffer {
    let mut rng = Pcg64Mcg::seed_from_u64(seed);
    let n = (w * h) as usize;
    let mut g = GBuffer {
        width: w,
        height: h,
        rgb: Some(vec![0.0; 3 * n]),
        alpha: vec![0.0; n],
        channels: Channel::ALL.into_iter().filter(|c| c.is_feature()).map(|c| (c, vec![0.0; c.floats() * n])).collect(),
        top_gaussian: None,
    };
    for p in 0..n {
        let extreme = p % 4 == 0;
        let alpha: f32 = match p % 13 {
            0 => 0.0,
            1 => 1e-3,
            _ if extreme => 1.0,
            _ => rng.random_range(0.05..1.0),
        };
        g.alpha[p] = alpha;
        let mut nrm = Vec3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
        if extreme && p % 8 == 0 {
            // N·V = 0: a normal perpendicular to the pixel's ray.
            let ray = camera.rotation * Vec3::new((p as u32 % w) as f32 + 0.5 - 0.5 * w as f32, 0.0, 200.0);
            nrm = ray.cross(Vec3::Z).normalize();
        }
        let pick =
            |rng: &mut Pcg64Mcg| if extreme { f32::from(rng.random_bool(0.5)) } else { rng.random_range(0.0..1.0) };
        let (r, m) = (pick(&mut rng), pick(&mut rng));
        for c in 0..3 {
            g.get_mut(Channel::Normal).unwrap()[3 * p + c] = nrm[c] * alpha * 0.8;
            g.get_mut(Channel::Albedo).unwrap()[3 * p + c] = rng.random_range(0.0..1.0f32) * alpha;
        }
        g.get_mut(Channel::Roughness).unwrap()[p] = r * alpha;
        g.get_mut(Channel::Metallic).unwrap()[p] = m * alpha;
        g.get_mut(Channel::Ao).unwrap()[p] = rng.random_range(0.0..1.0f32) * alpha;
        g.get_mut(Channel::Visibility).unwrap()[p] = rng.random_range(0.0..1.0f32) * alpha;
    }
    g
}

fn test_camera(w: u32, h: u32) -> Camera {
    Camera::look_at(Vec3::new(0.0, -10.0, 3.0), Vec3::new(0.0, 0.0, 0.0), Vec3::Z, 70.0, w, h).unwrap()
}

/// Shading inputs without editable visibility or indirect light.
fn inputs<'a>(
    env: &'a PreparedEnvironment,
    brdf: &'a BrdfTable,
    gbuffer: &'a GpuGBuffer,
    camera: &'a Camera,
    sun: Option<&'a Sun>,
) -> ShadeInputs<'a> {
    ShadeInputs { gbuffer, camera, environment: env, brdf, sun, editable_visibility: None, indirect: None }
}

struct Lit {
    d: Device,
    shader: Shader,
    env: PreparedEnvironment,
    brdf: BrdfTable,
}

fn lit(env: &EnvironmentMap, variant: BrdfLut) -> Lit {
    let d = device();
    let prep = EnvironmentPrep::new(&d).unwrap();
    let settings = PrepareSettings { levels: 5, samples: 32, irradiance_size: (16, 8), irradiance_source_width: 16 };
    let env = prep.prepare(env, &settings).unwrap();
    let brdf = prep.brdf_table(variant, 33, 256).unwrap();
    Lit { shader: Shader::new(&d).unwrap(), env, brdf, d }
}

#[test]
fn shading_matches_twin_on_random_and_extreme_gbuffers() {
    let (w, h) = (37u32, 23u32);
    let camera = test_camera(w, h);
    let host = random_gbuffer(w, h, &camera, 5);
    let mut rng = Pcg64Mcg::seed_from_u64(9);
    let editable: Vec<f32> = (0..w * h).map(|_| rng.random_range(0.0..1.0)).collect();
    let indirect: Vec<f32> = (0..3 * w * h).map(|_| rng.random_range(0.0..0.2)).collect();
    let suns = [
        Sun::from_azimuth_elevation(120.0, 35.0, [3.0, 2.9, 2.7]).unwrap(),
        Sun::from_azimuth_elevation(10.0, 89.9, [1e5; 3]).unwrap(),
        Sun::from_azimuth_elevation(300.0, -5.0, [3.0; 3]).unwrap(),
    ];
    let mut s = lit(&test_environment(64, 32), BrdfLut::Karis);
    let g = upload(&s.d, &host);
    let ev = s.d.upload("V_e", &editable).unwrap();
    let ind = s.d.upload("L_ind", &indirect).unwrap();
    let t = tables(&s.d, &s.env, &s.brdf);
    let cases: Vec<(&str, ShadeSettings, Option<&Sun>, bool)> = vec![
        ("editable", ShadeSettings { prefill: Some(NAN), ..ShadeSettings::default() }, Some(&suns[0]), true),
        (
            "fixed-aces-rotated",
            ShadeSettings {
                visibility: VisibilitySource::Fixed,
                tone_map: ToneMap::Aces,
                env_rotation_degrees: 77.0,
                exposure_ev: -1.5,
                prefill: Some(NAN),
                ..ShadeSettings::default()
            },
            Some(&suns[0]),
            false,
        ),
        (
            "radiance-1e5",
            ShadeSettings {
                visibility: VisibilitySource::None,
                env_intensity: 1e5,
                tone_map: ToneMap::Reinhard,
                background: Background::Color([0.1, 0.2, 0.3]),
                prefill: Some(NAN),
                ..ShadeSettings::default()
            },
            Some(&suns[1]),
            false,
        ),
        ("sun-below-horizon", ShadeSettings { prefill: Some(NAN), ..ShadeSettings::default() }, Some(&suns[2]), true),
        (
            "black-environment-sun-only-terms",
            ShadeSettings {
                env_intensity: 0.0,
                terms: ShadeTerms { sky_diffuse: false, ..ShadeTerms::ALL },
                prefill: Some(NAN),
                ..ShadeSettings::default()
            },
            Some(&suns[0]),
            true,
        ),
    ];
    for (label, settings, sun, with_indirect) in cases {
        let inputs = ShadeInputs {
            editable_visibility: Some(&ev),
            indirect: with_indirect.then_some(&ind),
            ..inputs(&s.env, &s.brdf, &g, &camera, sun)
        };
        let out = s.shader.shade(&inputs, &settings).unwrap().read(&s.d).unwrap();
        let cpu = shade_cpu(&host, &camera, &t, sun, &settings, Some(&editable), with_indirect.then_some(&indirect));
        let e_sun = rel_err(&format!("{label}_sun"), w, h, 3, &out.sun, &cpu.sun, 1e-4);
        let e_sky = rel_err(&format!("{label}_sky"), w, h, 3, &out.sky, &cpu.sky, 1e-4);
        let e_rad = rel_err(&format!("{label}_radiance"), w, h, 3, &out.radiance, &cpu.radiance, 1e-4);
        let e_dis = rel_err(&format!("{label}_display"), w, h, 3, &out.display, &cpu.display, 1e-3);
        assert!(out.display.iter().all(|v| (0.0..=1.0).contains(v)), "{label}: display outside [0, 1]");
        println!(
            "{label}: relative errors sun {e_sun:.1e}, sky {e_sky:.1e}, radiance {e_rad:.1e}, display {e_dis:.1e}"
        );
        if label == "sun-below-horizon" {
            assert!(out.sun.iter().all(|v| *v == 0.0), "no sun light below the horizon");
        }
    }
    // Through lenses: each pixel's view direction comes from undistorting it (Newton in f32 on
    // the GPU, in f64 in the twin), same tolerances.
    for lens in [
        srug::camera::lens::Lens::RadialTangential { k: [-0.25, 0.06, -0.005, 0.0, 0.0, 0.0], p: [0.001, -0.002] },
        srug::camera::lens::Lens::Fisheye { k: [0.01, -0.002, 0.0003, -0.00004] },
        srug::camera::lens::Lens::Equirectangular,
    ] {
        let mut cam = Camera { lens, ..camera.clone() };
        if lens == srug::camera::lens::Lens::Equirectangular {
            // A full panorama: every pixel a direction all around, behind the camera too.
            let (wf, hf) = (w as f32, h as f32);
            cam.projection = srug::scene::Projection::Pinhole {
                fx: wf / std::f32::consts::TAU,
                fy: hf / std::f32::consts::PI,
                cx: wf * 0.5,
                cy: hf * 0.5,
            };
        }
        let settings = ShadeSettings { prefill: Some(NAN), ..ShadeSettings::default() };
        let inputs =
            ShadeInputs { editable_visibility: Some(&ev), ..inputs(&s.env, &s.brdf, &g, &cam, Some(&suns[0])) };
        let out = s.shader.shade(&inputs, &settings).unwrap().read(&s.d).unwrap();
        let cpu = shade_cpu(&host, &cam, &t, Some(&suns[0]), &settings, Some(&editable), None);
        let label = format!("{lens:?}").chars().take(12).collect::<String>();
        let e_sun = rel_err(&format!("lens_{label}_sun"), w, h, 3, &out.sun, &cpu.sun, 1e-4);
        let e_sky = rel_err(&format!("lens_{label}_sky"), w, h, 3, &out.sky, &cpu.sky, 1e-4);
        println!("lens {label}: relative errors sun {e_sun:.1e}, sky {e_sky:.1e}");
        // The lens matters: the same G-buffer seen through the pinhole shades differently.
        let pinhole = shade_cpu(&host, &camera, &t, Some(&suns[0]), &settings, Some(&editable), None);
        let moved = pinhole.sky.iter().zip(&cpu.sky).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        assert!(moved > 1e-3, "{label}: the lens changed no pixel's sky light ({moved:e})");
    }
    // Misuse: editable visibility without its buffer; a G-buffer without albedo.
    let bad = inputs(&s.env, &s.brdf, &g, &camera, Some(&suns[0]));
    assert!(s.shader.shade(&bad, &ShadeSettings::default()).is_err());
    let mut plain = upload(&s.d, &host);
    plain.channels.remove(Channel::Albedo);
    let no_albedo = ShadeInputs { gbuffer: &plain, ..bad };
    let err =
        s.shader.shade(&no_albedo, &ShadeSettings { visibility: VisibilitySource::None, ..ShadeSettings::default() });
    assert!(err.is_err_and(|e| e.to_string().contains("albedo")));
    assert_no_validation_messages(&s.d);
}

#[test]
fn white_furnace() {
    let (w, h) = (32u32, 16u32);
    let camera = test_camera(w, h);
    let mut host = random_gbuffer(w, h, &camera, 11);
    // Albedo 1, ambient occlusion 1, full coverage; normals, roughness and metallic stay random and extreme.
    for p in 0..(w * h) as usize {
        let a = 1.0;
        let old = host.alpha[p].max(1e-3);
        host.alpha[p] = a;
        for c in 0..3 {
            host.get_mut(Channel::Albedo).unwrap()[3 * p + c] = 1.0;
            host.get_mut(Channel::Normal).unwrap()[3 * p + c] /= old;
        }
        host.get_mut(Channel::Roughness).unwrap()[p] /= old;
        host.get_mut(Channel::Metallic).unwrap()[p] /= old;
        host.get_mut(Channel::Ao).unwrap()[p] = 1.0;
    }
    let mut s = lit(&EnvironmentMap::uniform([1.0; 3], 64, 32).unwrap(), BrdfLut::Karis);
    let g = upload(&s.d, &host);
    let run = |s: &mut Lit, terms: ShadeTerms, metallic: Option<f32>| {
        let mut hm = host.clone();
        if let Some(m) = metallic {
            hm.get_mut(Channel::Metallic).unwrap().iter_mut().for_each(|v| *v = m);
        }
        let gm = upload(&s.d, &hm);
        let inputs = inputs(&s.env, &s.brdf, if metallic.is_some() { &gm } else { &g }, &camera, None);
        let settings = ShadeSettings { terms, prefill: Some(NAN), ..ShadeSettings::default() };
        s.shader.shade(&inputs, &settings).unwrap().read(&s.d).unwrap()
    };
    // Diffuse alone, metallic 0: exactly the albedo, 1.
    let diffuse = run(&mut s, ShadeTerms { sky_diffuse: true, ..none() }, Some(0.0));
    let err = diffuse.radiance.iter().map(|v| (f64::from(*v) - 1.0).abs()).fold(0.0, f64::max);
    println!("white furnace diffuse: max |L − 1| = {err:e}");
    assert!(err < 1e-5, "white furnace: diffuse returns {err:e} away from 1");
    // Specular alone: F0 from metallic; never above 1 (white metal: A + B ≤ 1).
    for m in [None, Some(0.0), Some(1.0)] {
        let spec = run(&mut s, ShadeTerms { sky_specular: true, ..none() }, m);
        let max = spec.radiance.iter().copied().fold(0.0f32, f32::max);
        let min = spec.radiance.iter().copied().fold(f32::INFINITY, f32::min);
        println!("white furnace specular (metallic {m:?}): {min:.4} ..= {max:.4}");
        assert!(max <= 1.0 + 1e-5 && min >= 0.0, "white furnace: specular {min}..{max} outside [0, 1]");
    }
    assert_no_validation_messages(&s.d);
}

fn none() -> ShadeTerms {
    ShadeTerms { sun_diffuse: false, sun_specular: false, sky_diffuse: false, sky_specular: false }
}

#[test]
fn splatted_sunlit_plane_matches_closed_form() {
    use srug::scene::{Materials, Scene};
    use srug::splat::{Channels, SplatSettings, Splatter};
    // A dense plane of flat discs at z = 0 with albedo 0.6/0.4/0.2, roughness 0.5, metallic 0.
    let (albedo, rough) = ([0.6f32, 0.4, 0.2], 0.5f32);
    let logit = |p: f32| (p / (1.0 - p)).ln();
    let mut scene = Scene { sh_degree: 0, ..Scene::default() };
    let step = 0.25f32;
    for i in -60..=60 {
        for j in -60..=60 {
            scene.means.push([i as f32 * step, j as f32 * step, 0.0]);
            scene.log_scales.push([(0.3f32).ln(), (0.3f32).ln(), (1e-4f32).ln()]);
            scene.rotations.push([1.0, 0.0, 0.0, 0.0]);
            scene.opacity_logits.push(logit(0.95));
            scene.sh.extend([0.0f32; 3]);
        }
    }
    let n = scene.means.len();
    scene.materials = Materials {
        albedo: Some(vec![albedo.map(logit); n]),
        roughness: Some(vec![logit(rough); n]),
        metallic: Some(vec![logit(1e-6); n]),
        ao: Some(vec![logit(1.0 - 1e-6); n]),
        visibility: None,
    };
    let mut s = lit(&EnvironmentMap::uniform([0.0; 3], 16, 8).unwrap(), BrdfLut::Karis);
    let gpu_scene = srug::scene::activate::GpuScene::upload(&s.d, &scene).unwrap();
    let camera = Camera::look_at(Vec3::new(-3.0, -6.0, 4.0), Vec3::ZERO, Vec3::Z, 50.0, 48, 32).unwrap();
    let mut splatter = Splatter::new(&s.d).unwrap();
    let ch = Channels { normal: true, albedo: true, roughness: true, metallic: true, ao: true, ..Channels::default() };
    let (g, _) = splatter
        .render(&gpu_scene, &camera, &SplatSettings { channels: ch, prefill: Some(NAN), ..SplatSettings::default() })
        .unwrap();
    let sun = Sun::from_azimuth_elevation(200.0, 40.0, [2.0, 2.0, 2.0]).unwrap();
    let inputs = inputs(&s.env, &s.brdf, &g, &camera, Some(&sun));
    let settings = ShadeSettings {
        visibility: VisibilitySource::None,
        background: Background::Color([0.0; 3]),
        prefill: Some(NAN),
        ..ShadeSettings::default()
    };
    let out = s.shader.shade(&inputs, &settings).unwrap().read(&s.d).unwrap();
    let host = g.read(&s.d).unwrap();
    // The paper's BRDF at each pixel's own angles, written out independently.
    let pi = std::f64::consts::PI;
    let (nrm, l) = (glam::DVec3::Z, sun.direction.as_dvec3());
    let r = f64::from(rough);
    let mut worst = 0.0f64;
    let mut checked = 0;
    for p in 0..(48 * 32) {
        if host.alpha[p] < 0.999 {
            continue;
        }
        let (px, py) = ((p % 48) as f64 + 0.5, (p / 48) as f64 + 0.5);
        let srug::scene::Projection::Pinhole { fx, fy, cx, cy } = camera.projection else { unreachable!() };
        let ray = (Mat3::as_dmat3(&camera.rotation)
            * glam::DVec3::new((px - f64::from(cx)) / f64::from(fx), (py - f64::from(cy)) / f64::from(fy), 1.0))
        .normalize();
        let v = -ray;
        let h = (v + l).normalize();
        let (nol, nov, noh, voh) = (nrm.dot(l), nrm.dot(v), nrm.dot(h), v.dot(h));
        let a2 = (r * r) * (r * r);
        let dd = a2 / (pi * (noh * noh * (a2 - 1.0) + 1.0).powi(2));
        let k = (r + 1.0).powi(2) / 8.0;
        let gg = nov / (nov * (1.0 - k) + k) * nol / (nol * (1.0 - k) + k);
        for (c, a) in albedo.iter().map(|&a| f64::from(a)).enumerate() {
            let f = 0.04 + 0.96 * (1.0 - voh).powi(5);
            let fr = a / pi + dd * f * gg / (4.0 * nol * nov);
            let expected = fr * 2.0 * nol * f64::from(host.alpha[p]);
            let got = f64::from(out.radiance[3 * p + c]);
            worst = worst.max((got - expected).abs() / expected);
        }
        checked += 1;
    }
    println!("sun-lit plane: {checked} covered pixels, worst relative error {worst:e}");
    assert!(checked > 500, "the plane covers too few pixels ({checked})");
    assert!(worst < 2e-3, "sun-lit plane: relative error {worst:e} ≥ 2e-3 against the closed form");
    assert_no_validation_messages(&s.d);
}

#[test]
fn environment_files_load_or_are_refused_clearly() {
    let Some(data) = srug_tests::shared_data() else {
        println!("skipped: ../shared/data is absent");
        return;
    };
    for name in ["city.exr", "sunrise.exr", "sunset.exr", "studio_256.hdr"] {
        let env = EnvironmentMap::load(data.join("hdri").join(name)).unwrap();
        assert!(env.rgb.iter().all(|v| v.is_finite() && *v >= 0.0), "{name}: negative or non-finite texel");
        println!("{name}: {}x{}, max {:.1}", env.width, env.height, env.max_value());
        assert_eq!((env.width, env.height), if name.ends_with(".hdr") { (256, 128) } else { (1024, 512) });
    }
    let city = EnvironmentMap::load(data.join("hdri/city.exr")).unwrap();
    assert!(city.max_value() > 1e4, "city.exr holds the sun (about 34,000)");
    let mut loaded = 0;
    for entry in std::fs::read_dir(data.join("ktx2")).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap().to_string_lossy().to_string();
        match EnvironmentMap::load(&path) {
            Ok(env) => {
                println!("{name}: loaded {}x{}", env.width, env.height);
                assert_eq!(name, "studio_cube_rgba16f_mips.ktx2", "only the float cube map is an environment");
                assert_eq!((env.width, env.height), (256, 128), "a 64² cube becomes a 256×128 lat-long map");
                assert!(env.max_value() > 0.0 && env.rgb.iter().all(|v| v.is_finite()));
                loaded += 1;
            }
            Err(e) => {
                let text = e.to_string();
                println!("{name}: refused: {text}");
                assert!(text.contains(&name), "the message names the file: {text}");
                assert!(
                    ["not a float format", "3D texture", "array of", "VK_FORMAT_UNDEFINED", "not a valid KTX2"]
                        .iter()
                        .any(|w| text.contains(w)),
                    "the message says why: {text}"
                );
            }
        }
    }
    assert_eq!(loaded, 1);
}

#[test]
fn bad_environment_inputs_get_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let junk = dir.path().join("junk.exr");
    std::fs::write(&junk, b"not an exr at all").unwrap();
    let e = EnvironmentMap::load(&junk).unwrap_err().to_string();
    assert!(e.contains("junk.exr"), "{e}");
    let hdr = dir.path().join("junk.hdr");
    std::fs::write(&hdr, b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 4 +X 4\n\x02").unwrap();
    assert!(EnvironmentMap::load(&hdr).unwrap_err().to_string().contains("junk.hdr"));
    let png = dir.path().join("sky.png");
    std::fs::write(&png, b"x").unwrap();
    assert!(EnvironmentMap::load(&png).unwrap_err().to_string().contains(".exr, .hdr or .ktx2"));
    let missing = EnvironmentMap::load(dir.path().join("missing.exr")).unwrap_err().to_string();
    assert!(missing.contains("missing.exr"), "{missing}");
    // NaN texels are refused with the texel named; small negatives are clamped.
    let mut rgb = vec![0.5f32; 3 * 8 * 4];
    rgb[3 * (2 * 8 + 5) + 1] = f32::NAN;
    let e = EnvironmentMap::from_rgb(8, 4, rgb.clone(), "t").unwrap_err().to_string();
    assert!(e.contains("texel (5, 2) channel G"), "{e}");
    rgb[3 * (2 * 8 + 5) + 1] = -0.004;
    assert_eq!(EnvironmentMap::from_rgb(8, 4, rgb, "t").unwrap().texel(5, 2)[1], 0.0);
    assert!(EnvironmentMap::from_rgb(0, 4, vec![], "t").is_err());
    // A NaN in an EXR file names the texel too.
    let mut g = GBuffer { width: 4, height: 2, rgb: Some(vec![1.0; 24]), alpha: vec![1.0; 8], ..GBuffer::default() };
    g.rgb.as_mut().unwrap()[3 * 6] = f32::INFINITY;
    let exr = dir.path().join("inf.exr");
    g.write_exr(&exr).unwrap();
    let e = EnvironmentMap::load(&exr).unwrap_err().to_string();
    assert!(e.contains("inf.exr") && e.contains("texel (2, 1) channel R"), "{e}");
}

#[test]
fn ktx2_float_chains_round_trip_with_and_without_zstd() {
    use srug::shade::ktx::{encode_float_chain, read_environment, read_float_chain, FloatChain};
    let env = test_environment(16, 8);
    let half: Vec<f32> = (0..8 * 4 * 3).map(|i| i as f32 * 0.25).collect();
    for zstd in [false, true] {
        let chain = FloatChain {
            width: 16,
            height: 8,
            channels: 3,
            levels: vec![&env.rgb, &half],
            metadata: vec![("srug.test".into(), "1".into())],
        };
        let bytes = encode_float_chain(&chain, zstd).unwrap();
        let back = read_float_chain(&bytes, "mem").unwrap();
        assert_eq!(back.levels, vec![env.rgb.clone(), half.clone()], "zstd {zstd}");
        assert!(back.metadata.iter().any(|(k, v)| k == "srug.test" && v == "1"));
        let as_env = read_environment(&bytes, "mem").unwrap();
        assert_eq!(as_env, env, "zstd {zstd}: level 0 as an environment");
        // Truncated files are refused, not read past their end.
        assert!(read_environment(&bytes[..bytes.len() - 7], "mem").is_err());
    }
}

#[test]
fn prepared_environment_and_brdf_table_round_trip_through_ktx2() {
    let d = device();
    let prep = EnvironmentPrep::new(&d).unwrap();
    let settings = PrepareSettings { levels: 4, samples: 16, irradiance_size: (8, 4), irradiance_source_width: 16 };
    let env = prep.prepare(&test_environment(32, 16), &settings).unwrap();
    let brdf = prep.brdf_table(BrdfLut::HeightCorrelated, 17, 64).unwrap();
    let dir = tempfile::tempdir().unwrap();
    for zstd in [false, true] {
        let sub = dir.path().join(format!("zstd_{zstd}"));
        env.save(&d, &sub, zstd).unwrap();
        let back = PreparedEnvironment::load(&d, &sub).unwrap();
        assert_eq!((back.base, back.levels, back.irradiance_size), (env.base, env.levels, env.irradiance_size));
        assert_eq!(back.read_specular(&d).unwrap(), env.read_specular(&d).unwrap());
        assert_eq!(d.read_buffer::<f32>(&back.irradiance).unwrap(), d.read_buffer::<f32>(&env.irradiance).unwrap());
    }
    let path = dir.path().join("brdf.ktx2");
    brdf.save(&d, &path).unwrap();
    let back = BrdfTable::load(&d, &path).unwrap();
    assert_eq!((back.variant, back.size, back.samples), (BrdfLut::HeightCorrelated, 17, 64));
    assert_eq!(d.read_buffer::<f32>(&back.buffer).unwrap(), d.read_buffer::<f32>(&brdf.buffer).unwrap());
    // A table is not an environment folder, and a missing folder is named.
    std::fs::copy(&path, dir.path().join("zstd_false").join("specular.ktx2")).unwrap();
    let e = PreparedEnvironment::load(&d, &dir.path().join("zstd_false")).err().unwrap().to_string();
    assert!(e.contains("not a srug specular file"), "{e}");
    assert!(PreparedEnvironment::load(&d, &dir.path().join("nowhere")).is_err());
    assert_no_validation_messages(&d);
}

#[test]
fn relit_demo_street_shows_the_offscreen_towers_shadow() {
    use srug::frame::{RelightSettings, Relighter};
    use srug::scene::activate::GpuScene;
    use srug::scene::demo::{demo_city, DemoOptions};
    use srug::shadow::completion::without_offscreen_tower;
    use srug::shadow::{ShadowFit, ShadowSettings};
    let d = device();
    let city = demo_city(&DemoOptions { gaussians: 30_000, ..DemoOptions::default() }).unwrap();
    let camera = city.cameras[0].resized(176, 48);
    let sun = Sun::from_azimuth_elevation(260.0, 50.0, [std::f32::consts::PI; 3]).unwrap();
    let prep = EnvironmentPrep::new(&d).unwrap();
    let sky = srug::shade::ProceduralSky::new(sun.direction, sun.intensity[0]).render().unwrap();
    let env = prep.prepare(&sky, &PrepareSettings::default()).unwrap();
    let brdf = prep.brdf_table(BrdfLut::Karis, 33, 256).unwrap();
    // The whole scene's map, and cascades fitted to the camera's view: casters
    // outside the view stay in every cascade's map.
    for fit in [ShadowFit::SceneBounds, ShadowFit::Cascades] {
        let shadow = ShadowSettings { resolution: 1024, prefill: Some(NAN), fit, ..ShadowSettings::default() };
        let settings = RelightSettings {
            shadow,
            shade: ShadeSettings { prefill: Some(NAN), ..ShadeSettings::default() },
            ..RelightSettings::default()
        };
        let mut relighter = Relighter::new(&d).unwrap();
        let bounds = city.scene.bounds().unwrap();
        let mut render = |scene: &srug::scene::Scene| {
            let gs = GpuScene::upload(&d, scene).unwrap();
            let f = relighter
                .render(&gs, &scene.attributes(), &bounds, &camera, Some(&sun), &env, &brdf, &settings)
                .unwrap();
            assert!(f.shadow_pass_ran);
            assert!(!f.timings.stages.iter().any(|t| t.name == "inc"), "no weights: no inference");
            let cascaded = f.timings.stages.iter().any(|t| t.name == "shadow cascade blend");
            assert_eq!(cascaded, fit == ShadowFit::Cascades, "{fit:?}");
            f.shaded.read(&d).unwrap()
        };
        let with = render(&city.scene);
        let without = render(&without_offscreen_tower(&city));
        assert!(with.radiance.iter().chain(&without.radiance).all(|v| v.is_finite() && *v >= 0.0));
        // Pixels the tower darkens (L_sun drops by more than half) and none it brightens.
        let n = (176 * 48) as usize;
        let sun_of =
            |img: &srug::shade::ShadedImage, p: usize| img.sun[3 * p] + img.sun[3 * p + 1] + img.sun[3 * p + 2];
        let darkened = (0..n).filter(|&p| sun_of(&with, p) < 0.5 * sun_of(&without, p)).count();
        let brightened = (0..n).filter(|&p| sun_of(&with, p) > 1.01 * sun_of(&without, p) + 1e-4).count();
        println!(
            "{fit:?}: the tower darkens {darkened} of {n} pixels ({:.1}%), brightens {brightened}",
            100.0 * darkened as f64 / n as f64
        );
        assert!(darkened as f64 > 0.05 * n as f64, "{fit:?}: the off-screen tower's shadow should be in view");
        assert_eq!(brightened, 0, "{fit:?}: an added occluder cannot brighten anything");
    }
    assert_no_validation_messages(&d);
}

#[test]
fn cube_map_resamples_onto_its_latlong_source() {
    let Some(data) = srug_tests::shared_data() else {
        println!("skipped: ../shared/data is absent");
        return;
    };
    // The shared studio cube and the shared studio lat-long map come from the same HDRI.
    let cube = EnvironmentMap::load(data.join("ktx2/studio_cube_rgba16f_mips.ktx2")).unwrap();
    let latlong = EnvironmentMap::load(data.join("hdri/studio_256.hdr")).unwrap();
    assert_eq!((cube.width, cube.height), (latlong.width, latlong.height));
    let (w, h) = (cube.width as usize, cube.height as usize);
    let lum = |e: &EnvironmentMap, x: usize, y: usize| {
        let t = e.texel(x as u32, y as u32);
        f64::from(t[0] + t[1] + t[2]).ln_1p()
    };
    // Mean squared log-luminance difference with the cube turned by `shift` columns, optionally mirrored.
    let err = |shift: usize, mirror: bool| {
        let mut e = 0.0;
        for y in 0..h {
            for x in 0..w {
                let xc = if mirror { w - 1 - x } else { x };
                e += (lum(&cube, (xc + shift) % w, y) - lum(&latlong, x, y)).powi(2);
            }
        }
        e / (w * h) as f64
    };
    let aligned = err(0, false);
    // Every mirrored placement, and rotations by more than 8 columns (11°).
    let far = |s: usize| s.min(w - s) > 8;
    let other = (0..w).flat_map(|s| [(s, true), (s, false)]).filter(|&(s, m)| m || far(s)).map(|(s, m)| err(s, m));
    let best_other = other.fold(f64::INFINITY, f64::min);
    println!(
        "cube vs lat-long: {aligned:.4} as read, {best_other:.4} for the best mirror or rotation by more than 11°"
    );
    assert!(aligned < 0.05, "the cube map does not resample onto its source ({aligned})");
    assert!(best_other > 2.0 * aligned, "orientation ambiguous: {aligned} vs {best_other}");
}

#[test]
fn shading_with_the_indirect_network_matches_twin() {
    use srug::indirect::cpu::{pack_cpu, unet_cpu};
    use srug::indirect::{UNet, UNetConfig, UNetWeights};
    let (w, h) = (37u32, 23u32);
    let camera = test_camera(w, h);
    let host = random_gbuffer(w, h, &camera, 21);
    let sun = Sun::from_azimuth_elevation(120.0, 35.0, [3.0; 3]).unwrap();
    let mut s = lit(&test_environment(64, 32), BrdfLut::HeightCorrelated);
    let g = upload(&s.d, &host);
    let weights = UNetWeights::random(UNetConfig { widths: [8, 8, 16, 16, 32], ..UNetConfig::default() }, 8);
    let mut net = UNet::new(&s.d, &weights).unwrap();
    net.set_prefill(Some(NAN));
    let inputs = inputs(&s.env, &s.brdf, &g, &camera, Some(&sun));
    let settings =
        ShadeSettings { visibility: VisibilitySource::Fixed, prefill: Some(NAN), ..ShadeSettings::default() };
    let frame = s.shader.shade_with_network(&inputs, &settings, &mut net).unwrap();
    assert!(frame.timings.stages.iter().any(|t| t.name == "indirect input"), "the network ran");
    let out = frame.read(&s.d).unwrap();
    let gpu_ind: Vec<f32> = s.d.read_buffer(frame.indirect.as_ref().unwrap()).unwrap();
    // The twin from the GPU's own L_sun and L_sky (each checked against the twin elsewhere).
    let input = pack_cpu(&host, &out.sun, &out.sky, settings.min_alpha);
    let ind = unet_cpu(&weights, &input);
    let err = gpu_ind.iter().zip(&ind.data).map(|(a, b)| (f64::from(*a) - b).abs()).fold(0.0, f64::max);
    println!("L_ind: max |GPU − CPU| {err:.2e}");
    assert!(err <= 1e-4, "L_ind differs from the twin by {err:e}");
    let ind32: Vec<f32> = ind.data.iter().map(|v| *v as f32).collect();
    let t = tables(&s.d, &s.env, &s.brdf);
    let cpu = shade_cpu(&host, &camera, &t, Some(&sun), &settings, None, Some(&ind32));
    let e = rel_err("with_network_radiance", w, h, 3, &out.radiance, &cpu.radiance, 1e-4);
    println!("radiance with L_ind: relative error {e:.1e}");
    // Without the network, the same frame has no indirect light and runs no inference.
    let plain = s.shader.shade(&inputs, &settings).unwrap();
    assert!(plain.indirect.is_none() && !plain.timings.stages.iter().any(|t| t.name == "indirect input"));
    assert_no_validation_messages(&s.d);
}

#[test]
fn relighter_reuses_the_shadow_map_only_while_it_is_current() {
    use srug::frame::{RelightSettings, Relighter};
    use srug::scene::activate::GpuScene;
    use srug::scene::demo::{demo_city, DemoOptions};
    use srug::shadow::{ShadowFit, ShadowSettings};
    let d = device();
    let city = demo_city(&DemoOptions { seed: 4, gaussians: 5000, sh_degree: 1 }).unwrap();
    let cams = [city.cameras[0].resized(176, 48), city.cameras[1].resized(176, 48)];
    let sun_a = Sun::from_azimuth_elevation(260.0, 50.0, [3.0; 3]).unwrap();
    let sun_b = Sun::from_azimuth_elevation(120.0, 35.0, [3.0; 3]).unwrap();
    let prep = EnvironmentPrep::new(&d).unwrap();
    let sky = srug::shade::ProceduralSky::new(sun_a.direction, 3.0).render().unwrap();
    let env = prep.prepare(&sky, &PrepareSettings { samples: 16, ..PrepareSettings::default() }).unwrap();
    let brdf = prep.brdf_table(BrdfLut::Karis, 33, 64).unwrap();
    let mut settings = RelightSettings {
        shadow: ShadowSettings { resolution: 256, prefill: Some(NAN), ..ShadowSettings::default() },
        shade: ShadeSettings { prefill: Some(NAN), ..ShadeSettings::default() },
        ..RelightSettings::default()
    };
    let bounds = city.scene.bounds().unwrap();
    let attributes = city.scene.attributes();
    let mut gpu = GpuScene::upload(&d, &city.scene).unwrap();
    let mut reusing = Relighter::new(&d).unwrap();
    assert!(!reusing.shadow_map_reuse(), "off by default");
    reusing.set_shadow_map_reuse(true);
    let mut fresh = Relighter::new(&d).unwrap();

    // A frame: the scene, a camera index, the sun and the settings.
    type Frame<'a> = (&'a GpuScene, usize, &'a Sun, &'a RelightSettings);
    // (visibility, radiance) of a frame; checks the reuse flag against `expect_reused` and that a
    // reused map's splat is absent from the timings while the shadow test still runs.
    let step = |relighter: &mut Relighter, (gpu, cam, sun, settings): Frame<'_>, expect_reused: bool, label: &str| {
        let f = relighter.render(gpu, &attributes, &bounds, &cams[cam], Some(sun), &env, &brdf, settings).unwrap();
        let names: Vec<&str> = f.timings.stages.iter().map(|s| s.name.as_str()).collect();
        assert!(f.shadow_pass_ran, "{label}");
        assert_eq!(f.shadow_map_reused, expect_reused, "{label}: stages {names:?}");
        assert_eq!(names.iter().any(|n| n.starts_with("shadow map ")), !expect_reused, "{label}: {names:?}");
        assert!(names.contains(&"sigmoid shadow test"), "{label}: {names:?}");
        let v: Vec<f32> = d.read_buffer(f.visibility.as_ref().unwrap()).unwrap();
        assert!(v.iter().all(|x| x.is_finite()), "{label}: NaN sentinel left in the visibility");
        (v, f.shaded.read(&d).unwrap().radiance)
    };
    // Each frame of the reusing relighter equals a fresh relighter's, bit for bit.
    let mut check = |reusing: &mut Relighter,
                     gpu: &GpuScene,
                     cam: usize,
                     sun: &Sun,
                     settings: &RelightSettings,
                     expect_reused: bool,
                     label: &str| {
        let got = step(reusing, (gpu, cam, sun, settings), expect_reused, label);
        let want = step(&mut fresh, (gpu, cam, sun, settings), false, label);
        assert!(got == want, "{label}: a reused map must give the fresh map's frame exactly");
        got.0
    };
    check(&mut reusing, &gpu, 0, &sun_a, &settings, false, "first frame");
    let a1 = check(&mut reusing, &gpu, 1, &sun_a, &settings, true, "same sun, another camera");
    check(&mut reusing, &gpu, 1, &sun_b, &settings, false, "the sun moved");
    check(&mut reusing, &gpu, 1, &sun_a, &settings, false, "the sun moved back");
    check(&mut reusing, &gpu, 1, &sun_a, &settings, true, "same frame again");
    // A brighter sun in the same direction lights differently but casts the same map.
    let bright = Sun { intensity: [6.0, 5.0, 4.0], ..sun_a };
    check(&mut reusing, &gpu, 1, &bright, &settings, true, "same direction, new intensity");

    // Gaussians written in place and marked: a new map, and it sees the new geometry.
    let lifted: Vec<f32> = city.scene.means.iter().flat_map(|m| [m[0], m[1] + 40.0, m[2]]).collect();
    d.write_buffer(&gpu.means, 0, &lifted).unwrap();
    gpu.mark_changed();
    let lifted_v = check(&mut reusing, &gpu, 1, &sun_a, &settings, false, "scene marked changed");
    assert!(lifted_v != a1, "moving every Gaussian must change the visibility");
    let restored: Vec<f32> = city.scene.means.iter().flatten().copied().collect();
    d.write_buffer(&gpu.means, 0, &restored).unwrap();
    gpu.mark_changed();
    let back = check(&mut reusing, &gpu, 1, &sun_a, &settings, false, "scene restored");
    assert!(back == a1, "restoring the Gaussians restores the visibility");
    // Another upload of the same scene is another scene.
    let other = GpuScene::upload(&d, &city.scene).unwrap();
    assert_ne!(other.version(), gpu.version());
    check(&mut reusing, &other, 1, &sun_a, &settings, false, "another upload");

    // Map settings are part of the key; the view is, with a view-fitted map.
    settings.shadow.resolution = 320;
    check(&mut reusing, &other, 1, &sun_a, &settings, false, "new resolution");
    settings.shadow.fit = ShadowFit::ViewFrustum;
    check(&mut reusing, &other, 1, &sun_a, &settings, false, "view-fitted");
    check(&mut reusing, &other, 1, &sun_a, &settings, true, "view-fitted, same view");
    check(&mut reusing, &other, 0, &sun_a, &settings, false, "view-fitted, another view");
    // Receiver-side settings do not need a new map.
    settings.shadow.k *= 2.0;
    check(&mut reusing, &other, 0, &sun_a, &settings, true, "new sharpness k");

    reusing.set_shadow_map_reuse(false);
    check(&mut reusing, &other, 0, &sun_a, &settings, false, "reuse turned off");
    check(&mut reusing, &other, 0, &sun_a, &settings, false, "still off");
    assert_no_validation_messages(&d);
}

#[test]
fn a_batch_of_relit_cameras_is_each_camera_relit_alone() {
    // Relighter::render_batch splats the cameras together (one submission per
    // step) and shades each in turn: every frame (radiance, its parts and the
    // sun visibility) must be the frame Relighter::render gives alone, with
    // and without a kept shadow map, at a render scale below 1 too. The
    // batch's cameras share one shadow map either way.
    use srug::frame::{RelightSettings, Relighter};
    use srug::scene::activate::GpuScene;
    use srug::scene::demo::{demo_city, DemoOptions};
    use srug::shadow::ShadowSettings;
    let d = device();
    let city = demo_city(&DemoOptions { seed: 4, gaussians: 5000, sh_degree: 1 }).unwrap();
    let cams: Vec<Camera> =
        (0..5).map(|i| city.cameras[i % city.cameras.len()].resized(96 + 8 * i as u32, 40)).collect();
    let sun = Sun::from_azimuth_elevation(260.0, 50.0, [3.0; 3]).unwrap();
    let prep = EnvironmentPrep::new(&d).unwrap();
    let sky = srug::shade::ProceduralSky::new(sun.direction, 3.0).render().unwrap();
    let env = prep.prepare(&sky, &PrepareSettings { samples: 16, ..PrepareSettings::default() }).unwrap();
    let brdf = prep.brdf_table(BrdfLut::Karis, 33, 64).unwrap();
    let bounds = city.scene.bounds().unwrap();
    let attributes = city.scene.attributes();
    let gpu = GpuScene::upload(&d, &city.scene).unwrap();
    let read = |f: &srug::frame::RelitFrame| {
        let img = f.shaded.read(&d).unwrap();
        let v: Vec<f32> = d.read_buffer(f.visibility.as_ref().unwrap()).unwrap();
        (img.radiance, img.sun, img.sky, v, f.pairs)
    };
    for (reuse, scale) in [(false, 1.0), (true, 1.0), (true, 0.5)] {
        let settings = RelightSettings {
            shadow: ShadowSettings { resolution: 256, prefill: Some(NAN), ..ShadowSettings::default() },
            shade: ShadeSettings { prefill: Some(NAN), ..ShadeSettings::default() },
            render_scale: scale,
            ..RelightSettings::default()
        };
        let mut batched = Relighter::new(&d).unwrap();
        batched.set_shadow_map_reuse(reuse);
        let mut alone = Relighter::new(&d).unwrap();
        alone.set_shadow_map_reuse(reuse);
        let frames =
            batched.render_batch(&gpu, &attributes, &bounds, &cams, Some(&sun), &env, &brdf, &settings).unwrap();
        assert_eq!(frames.len(), cams.len());
        for (i, (f, cam)) in frames.iter().zip(&cams).enumerate() {
            let want = alone.render(&gpu, &attributes, &bounds, cam, Some(&sun), &env, &brdf, &settings).unwrap();
            assert_eq!((f.shaded.width, f.shaded.height), (want.shaded.width, want.shaded.height), "camera {i}");
            assert_eq!(f.shadow_map_reused, i > 0, "camera {i}, reuse {reuse}: one map for the batch");
            assert!(read(f) == read(&want), "camera {i}, reuse {reuse}, scale {scale}: the batched frame differs");
        }
    }
    assert_no_validation_messages(&d);
}

/// Shading never reads the scene's own colour: a relit frame splats it (and reads the SH)
/// only when `RelightSettings::rgb` asks, and its light is the same bits either way; the rgb it
/// then gives is a plain splat's, bit for bit.
#[test]
fn a_relit_frame_splats_the_scenes_colour_only_when_asked() {
    use srug::frame::{RelightSettings, Relighter};
    use srug::scene::activate::GpuScene;
    use srug::scene::demo::{demo_city, DemoOptions};
    use srug::splat::{SplatSettings, Splatter};
    let d = device();
    let city = demo_city(&DemoOptions { seed: 4, gaussians: 5000, sh_degree: 2 }).unwrap();
    let cam = city.cameras[0].resized(176, 48);
    let sun = Sun::from_azimuth_elevation(260.0, 50.0, [3.0; 3]).unwrap();
    let prep = EnvironmentPrep::new(&d).unwrap();
    let sky = srug::shade::ProceduralSky::new(sun.direction, 3.0).render().unwrap();
    let env = prep.prepare(&sky, &PrepareSettings { samples: 16, ..PrepareSettings::default() }).unwrap();
    let brdf = prep.brdf_table(BrdfLut::Karis, 33, 64).unwrap();
    let (bounds, attributes) = (city.scene.bounds().unwrap(), city.scene.attributes());
    let gpu = GpuScene::upload(&d, &city.scene).unwrap();
    let mut relighter = Relighter::new(&d).unwrap();
    let mut relit = |settings: &RelightSettings| {
        relighter.render(&gpu, &attributes, &bounds, &cam, Some(&sun), &env, &brdf, settings).unwrap()
    };
    let plain = relit(&RelightSettings::default());
    assert!(plain.gbuffer.rgb.is_none(), "the colour was splatted unasked");
    let asked = relit(&RelightSettings { rgb: true, ..RelightSettings::default() });
    let light = |f: &srug::frame::RelitFrame| f.shaded.read(&d).unwrap().radiance;
    assert!(light(&plain) == light(&asked), "the colour changed the light");
    let rgb: Vec<f32> = d.read_buffer(asked.gbuffer.rgb.as_ref().unwrap()).unwrap();
    let settings = RelightSettings::default();
    let splat = SplatSettings {
        tile: settings.tile,
        surface_depth: settings.shadow.surface_depth,
        median_coverage: settings.shadow.receiver_coverage,
        ..SplatSettings::default()
    };
    let (g, _) = Splatter::new(&d).unwrap().render(&gpu, &cam, &splat).unwrap();
    let own: Vec<f32> = d.read_buffer(g.rgb.as_ref().unwrap()).unwrap();
    assert!(rgb.iter().any(|v| *v > 0.0), "the street has colour");
    assert!(rgb.iter().zip(&own).all(|(a, b)| a.to_bits() == b.to_bits()), "not a plain splat's rgb");
    assert_no_validation_messages(&d);
}
