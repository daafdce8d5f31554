//! The C API called in-process against the Rust API: its shadow forward and
//! backward give exactly the Rust API's visibility and every Gaussian's
//! gradients (occluder path + receiver path), so the ABI's array layouts and
//! its sum of the two paths are right (the Rust path itself is checked against
//! finite differences in shadow_backward.rs); and a scene without materials
//! renders its plain colour with nothing but splatting dispatched.

#![allow(clippy::unwrap_used, clippy::expect_used, reason = "test code: a failure should stop the test")]

use std::ptr::null_mut;

use glam::Vec3;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;
use srug::frame::{Preset, RelightSettings};
use srug::io::{write_ply, PlyFormat};
use srug::scene::activate::GpuScene;
use srug::scene::demo::{demo_city, DemoOptions};
use srug::scene::order::SceneOrder;
use srug::scene::{Camera, Scene};
use srug::shadow::backward::GpuVisibilityLoss;
use srug::shadow::{ShadowPass, ShadowSettings, Sun, VisibilityKind};
use srug::splat::{SplatSettings, Splatter};
use srug_c::*;
use srug_tests::{assert_no_validation_messages, device};

fn ok(s: srug_status) {
    if s != srug_status::SRUG_OK {
        let mut buf = vec![0 as std::ffi::c_char; 1024];
        // SAFETY: a local buffer of the stated length.
        unsafe { srug_last_error(buf.as_mut_ptr(), buf.len(), null_mut()) };
        // SAFETY: NUL-terminated by srug_last_error.
        panic!("{s:?}: {}", unsafe { std::ffi::CStr::from_ptr(buf.as_ptr()) }.to_string_lossy());
    }
}

#[test]
fn abi_shadow_pass_matches_the_rust_api() {
    let dir = tempfile::tempdir().unwrap();
    let city = demo_city(&DemoOptions { seed: 11, gaussians: 3000, sh_degree: 1 }).unwrap().scene;
    write_ply(dir.path().join("city.ply"), &city, PlyFormat::BinaryLittleEndian).unwrap();
    check_shadow_pass(&city, &dir.path().join("city.ply"));
}

/// A scene listed in no spatial order goes onto the device along a Morton curve through the C
/// API too, and its gradients still come back in file order: the Rust API's for the same file.
#[test]
fn abi_gradients_of_an_arranged_scene_are_in_file_order() {
    let dir = tempfile::tempdir().unwrap();
    let city = demo_city(&DemoOptions { seed: 11, gaussians: 3000, sh_degree: 1 }).unwrap().scene;
    let n = city.len();
    let scrambled = city.permuted(&(0..n).map(|i| (i * 7919 + 13) % n).collect::<Vec<_>>());
    let d = device();
    let mut gpu = GpuScene::upload(&d, &scrambled).unwrap();
    assert!(gpu.arrange(&d, SceneOrder::Auto).unwrap(), "the test's premise: the scene is arranged");
    write_ply(dir.path().join("scrambled.ply"), &scrambled, PlyFormat::BinaryLittleEndian).unwrap();
    check_shadow_pass(&scrambled, &dir.path().join("scrambled.ply"));
}

/// The shadow pass's visibility and gradients through the C API against the Rust API's for
/// `host`, which the C API reads from `ply` (the Rust side arranges it as the C API does).
fn check_shadow_pass(host: &Scene, ply: &std::path::Path) {
    let (w, h) = (96u32, 48u32);
    let (eye, target, up) = ([-30.0f32, -2.0, 6.0], [10.0f32, -2.0, 2.0], [0.0f32, 0.0, 1.0]);
    let (res, k, bias) = (256u32, 20.0f32, 0.5f32);
    let pixels = (w * h) as usize;
    let mut rng = Pcg64Mcg::seed_from_u64(3);
    let dl_dv: Vec<f32> = (0..pixels).map(|_| rng.random_range(-1.0..1.0)).collect();

    // Through the C API.
    let path = std::ffi::CString::new(ply.to_str().unwrap()).unwrap();
    let (mut ctx, mut scene, mut r) = (null_mut(), null_mut(), null_mut());
    let mut v_abi = vec![f32::NAN; pixels];
    let mut count = 0usize;
    // SAFETY: out-pointers to locals; arrays of the stated lengths.
    unsafe {
        ok(srug_context_create(std::ptr::null(), SRUG_CONTEXT_VALIDATION, &mut ctx));
        ok(srug_scene_from_file(ctx, path.as_ptr(), &mut scene));
        ok(srug_scene_info(scene, &mut count, null_mut()));
        ok(srug_renderer_create(ctx, w, h, 0, &mut r));
        ok(srug_renderer_set_camera_look_at(r, eye.as_ptr(), target.as_ptr(), up.as_ptr(), 80.0));
        ok(srug_renderer_set_sun(r, 250.0, 35.0, [1.0f32; 3].as_ptr()));
        ok(srug_renderer_set_shadow(r, res, k, bias));
        ok(srug_renderer_shadow_forward(r, scene, v_abi.as_mut_ptr(), pixels));
    }
    let mut g = vec![f32::NAN; count * 11];
    let (gm, rest) = g.split_at_mut(3 * count);
    let (gl, rest) = rest.split_at_mut(3 * count);
    let (gr, go) = rest.split_at_mut(4 * count);
    let grads = srug_gaussian_gradients {
        means: gm.as_mut_ptr(),
        log_scales: gl.as_mut_ptr(),
        rotations: gr.as_mut_ptr(),
        opacity_logits: go.as_mut_ptr(),
        count,
    };
    let mut messages = 1usize;
    // SAFETY: as above; `grads` points into `g`, alive until the end.
    unsafe {
        ok(srug_renderer_shadow_backward(r, scene, dl_dv.as_ptr(), pixels, &grads));
        ok(srug_context_take_validation_messages(ctx, &mut messages, null_mut(), 0));
        ok(srug_renderer_destroy(r));
        ok(srug_scene_destroy(scene));
        ok(srug_context_destroy(ctx));
    }
    assert_eq!(messages, 0, "validation messages through the C API");

    // Through the Rust API.
    let d = device();
    let mut gpu = GpuScene::upload(&d, host).unwrap();
    gpu.arrange(&d, SceneOrder::Auto).unwrap();
    let camera = Camera::look_at(Vec3::from(eye), Vec3::from(target), Vec3::from(up), 80.0, w, h).unwrap();
    let sun = Sun::from_azimuth_elevation(250.0, 35.0, [1.0; 3]).unwrap();
    // The renderer's default is the balanced preset: its slope bias stays.
    let st = ShadowSettings { resolution: res, k, bias, ..RelightSettings::preset(Preset::Balanced).shadow };
    let mut splatter = Splatter::new(&d).unwrap();
    let mut pass = ShadowPass::new(&d).unwrap();
    let receivers = splatter.render_frame(&gpu, &camera, &st.receiver_splat()).unwrap();
    let bounds = host.bounds().unwrap();
    let map = pass.shadow_map(&mut splatter, &gpu, &bounds, &sun, &st, Some(&camera)).unwrap().unwrap();
    let (v, _) = pass.visibility(&map, &receivers.gbuffer, &camera, &st, VisibilityKind::Sigmoid).unwrap();
    let v_rust: Vec<f32> = d.read_buffer(&v).unwrap();
    assert_eq!(v_abi, v_rust, "visibility through the C API differs");
    let shadowed = v_rust.iter().filter(|v| **v < 0.5).count();
    assert!(shadowed > 0 && shadowed < pixels, "{shadowed} of {pixels} shadowed: a degenerate view");

    let up_buf = d.upload("dL/dV", &dl_dv).unwrap();
    let b = pass.backward(&map, &receivers.gbuffer, &camera, &st, GpuVisibilityLoss::Upstream(&up_buf)).unwrap();
    let a = splatter.backward(&map.frame, &gpu, &b.map, false).unwrap().read(&d).unwrap();
    let c = splatter.backward(&receivers, &gpu, &b.receiver, false).unwrap().read(&d).unwrap();
    assert_no_validation_messages(&d);
    let mut nonzero = 0;
    for i in 0..count {
        let expect: Vec<f32> = (0..3)
            .map(|j| a.means[i][j] + c.means[i][j])
            .chain((0..3).map(|j| a.log_scales[i][j] + c.log_scales[i][j]))
            .chain((0..4).map(|j| a.rotations[i][j] + c.rotations[i][j]))
            .chain([a.opacity_logits[i] + c.opacity_logits[i]])
            .collect();
        let got: Vec<f32> = gm[3 * i..3 * i + 3]
            .iter()
            .chain(&gl[3 * i..3 * i + 3])
            .chain(&gr[4 * i..4 * i + 4])
            .chain([&go[i]])
            .copied()
            .collect();
        assert_eq!(got, expect, "Gaussian {i}: gradients through the C API differ");
        nonzero += expect.iter().filter(|v| **v != 0.0).count();
    }
    assert!(nonzero > 0, "no gradient reached any Gaussian");
    println!("{count} Gaussians, {shadowed}/{pixels} shadowed pixels, {nonzero} non-zero gradient entries: identical");
}

/// A scene without materials renders its plain 3DGS colour through the C API
/// with no shading kernel dispatched (and no shadow pass, though a sun is set).
#[test]
fn abi_renders_plain_colour_without_materials() {
    let mut city = demo_city(&DemoOptions { seed: 2, gaussians: 2000, sh_degree: 1 }).unwrap();
    city.scene.materials = srug::scene::Materials::default();
    let dir = tempfile::tempdir().unwrap();
    let ply = dir.path().join("plain.ply");
    srug::io::write_ply(&ply, &city.scene, srug::io::PlyFormat::BinaryLittleEndian).unwrap();
    let bytes = std::fs::read(&ply).unwrap();
    let (w, h) = (64u32, 32u32);
    let (eye, target, up) = ([-30.0f32, -2.0, 6.0], [10.0f32, -2.0, 2.0], [0.0f32, 0.0, 1.0]);
    let (mut ctx, mut scene, mut r) = (null_mut(), null_mut(), null_mut());
    let mut image = vec![f32::NAN; (w * h * 4) as usize];
    let (mut materials, mut stages) = (9u32, 0usize);
    let mut names = Vec::new();
    // SAFETY: out-pointers to locals; buffers of the stated lengths.
    unsafe {
        ok(srug_context_create(std::ptr::null(), SRUG_CONTEXT_VALIDATION, &mut ctx));
        ok(srug_scene_from_memory(ctx, bytes.as_ptr(), bytes.len(), &mut scene));
        ok(srug_scene_info(scene, null_mut(), &mut materials));
        ok(srug_renderer_create(ctx, w, h, 0, &mut r));
        ok(srug_renderer_set_camera_look_at(r, eye.as_ptr(), target.as_ptr(), up.as_ptr(), 80.0));
        ok(srug_renderer_set_sun(r, 250.0, 35.0, [1.0f32; 3].as_ptr()));
        ok(srug_renderer_render(r, scene));
        ok(srug_renderer_read_image(r, SRUG_FORMAT_RGBA32F_LINEAR, image.as_mut_ptr().cast(), image.len() * 4, 0));
        ok(srug_renderer_stage_count(r, &mut stages));
        for i in 0..stages {
            let mut name = [0 as std::ffi::c_char; 64];
            let mut seconds = 0.0;
            ok(srug_renderer_stage(r, i, name.as_mut_ptr(), name.len(), &mut seconds));
            names.push(std::ffi::CStr::from_ptr(name.as_ptr()).to_string_lossy().into_owned());
        }
        let mut sun_light = vec![0.0f32; (w * h * 3) as usize];
        let s = srug_renderer_read_channel(r, SRUG_CHANNEL_SUN_LIGHT, sun_light.as_mut_ptr(), sun_light.len());
        assert_eq!(s, srug_status::SRUG_ERROR_WRONG_ORDER, "a plain frame has no L_sun");
        ok(srug_renderer_destroy(r));
        ok(srug_scene_destroy(scene));
        ok(srug_context_destroy(ctx));
    }
    assert_eq!(materials, 0);
    assert_eq!(names, ["preprocess", "scan", "keys", "sort", "ranges", "blend"], "only splatting ran");

    // The image is the splatted colour, as the Rust API renders it.
    let d = device();
    let gpu = GpuScene::upload(&d, &srug::io::read_ply(&ply).unwrap()).unwrap();
    let camera = Camera::look_at(Vec3::from(eye), Vec3::from(target), Vec3::from(up), 80.0, w, h).unwrap();
    let (g, _) = Splatter::new(&d).unwrap().render(&gpu, &camera, &SplatSettings::default()).unwrap();
    let g = g.read(&d).unwrap();
    let expect: Vec<f32> =
        g.rgb_values().unwrap().chunks_exact(3).zip(&g.alpha).flat_map(|(c, a)| [c[0], c[1], c[2], *a]).collect();
    assert_eq!(image, expect);
    assert!(g.alpha.iter().any(|a| *a > 0.5), "the view shows the scene");
    assert_no_validation_messages(&d);
}
