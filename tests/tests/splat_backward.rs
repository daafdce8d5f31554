//! The splatting backward pass on the GPU against its f64 CPU twin (itself
//! checked against central finite differences in `srug::splat::cpu_backward`)
//! and directly against central finite differences of the CPU forward:
//! every parameter family, every blended channel, pinhole and orthographic.

#![allow(clippy::unwrap_used, clippy::expect_used, reason = "a failed unwrap is a failed test")]

use glam::{DVec3, Vec3};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;
use srug::gpu::{Device, MemoryKind};
use srug::scene::activate::GpuScene;
use srug::scene::{Camera, Materials, Scene};
use srug::splat::backward::{BlendGrads, HostGaussianGradients};
use srug::splat::cpu::{preprocess_params, render_blends, Gaussian64, MedianRule};
use srug::splat::cpu_backward::{blend_backward_cpu, project_backward, GaussianGrad, PixelGrads};
use srug::splat::Channel;
use srug::splat::PerChannel;
use srug::splat::{
    Channels, NormalSource, SplatSettings, Splatter, TileBounds, DEFAULT_MEDIAN_COVERAGE, DEFAULT_TILE, TILE_SIZES,
};
use srug_tests::{assert_no_validation_messages, device, move_scene};

/// Centre depths, the median at one half.
const CENTRE: MedianRule = MedianRule { surface_depth: false, coverage: DEFAULT_MEDIAN_COVERAGE };
/// Surface depths, the median at one half.
const SURFACE: MedianRule = MedianRule { surface_depth: true, coverage: DEFAULT_MEDIAN_COVERAGE };

fn scene(n: usize, seed: u64) -> Scene {
    let mut rng = Pcg64Mcg::seed_from_u64(seed);
    let mut s = Scene::default();
    let mut m = Materials {
        albedo: Some(Vec::new()),
        roughness: Some(Vec::new()),
        metallic: Some(Vec::new()),
        ao: Some(Vec::new()),
        visibility: Some(Vec::new()),
    };
    for _ in 0..n {
        s.means.push([rng.random_range(-1.0..1.0), rng.random_range(-0.7..0.7), rng.random_range(-0.5..0.5)]);
        s.log_scales.push([rng.random_range(-2.5..-1.0), rng.random_range(-2.5..-1.0), rng.random_range(-2.5..-1.0)]);
        s.rotations.push([rng.random_range(0.2..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), 0.3]);
        s.opacity_logits.push(rng.random_range(-1.0..2.5));
        s.sh.extend([rng.random_range(-0.5..0.5), rng.random_range(-0.5..0.5), rng.random_range(-0.5..0.5)]);
        m.albedo.as_mut().unwrap().push([rng.random_range(-2.0..2.0); 3]);
        for v in [&mut m.roughness, &mut m.metallic, &mut m.ao, &mut m.visibility] {
            v.as_mut().unwrap().push(rng.random_range(-2.0..2.0));
        }
    }
    s.materials = m;
    s
}

/// Random per-pixel gradients for every channel, as host f64 and as GPU buffers.
fn random_grads(d: &Device, pixels: usize, seed: u64) -> (PixelGrads, BlendGrads) {
    let mut rng = Pcg64Mcg::seed_from_u64(seed);
    let host = PixelGrads {
        values: (0..pixels).map(|_| std::array::from_fn(|_| rng.random_range(-1.0..1.0))).collect(),
        alpha: (0..pixels).map(|_| rng.random_range(-1.0..1.0)).collect(),
        median: (0..pixels).map(|_| rng.random_range(-1.0..1.0)).collect(),
    };
    let planar = |range: std::ops::Range<usize>| -> Vec<f32> {
        host.values.iter().flat_map(|v| v[range.clone()].iter().map(|x| *x as f32).collect::<Vec<_>>()).collect()
    };
    let up = |name: &str, v: Vec<f32>| d.upload(name, &v).unwrap();
    let grads = BlendGrads {
        rgb: Some(up("d rgb", planar(0..3))),
        alpha: Some(up("d alpha", host.alpha.iter().map(|x| *x as f32).collect())),
        channels: [
            (Channel::Depth, planar(3..4)),
            (Channel::MedianDepth, host.median.iter().map(|x| *x as f32).collect()),
            (Channel::Normal, planar(4..7)),
            (Channel::Roughness, planar(7..8)),
            (Channel::Albedo, planar(8..11)),
            (Channel::Metallic, planar(11..12)),
            (Channel::Ao, planar(12..13)),
            (Channel::Visibility, planar(13..14)),
        ]
        .into_iter()
        .map(|(c, v)| (c, up(c.name(), v)))
        .collect(),
    };
    (host, grads)
}

fn gpu_gradients(
    d: &Device,
    scene: &Scene,
    camera: &Camera,
    bg: [f32; 3],
    grads: &BlendGrads,
) -> HostGaussianGradients {
    gpu_gradients_tiled(d, scene, camera, bg, grads, DEFAULT_TILE, CENTRE).unwrap()
}

fn gpu_gradients_tiled(
    d: &Device,
    scene: &Scene,
    camera: &Camera,
    bg: [f32; 3],
    grads: &BlendGrads,
    tile: u32,
    rule: MedianRule,
) -> srug::Result<HostGaussianGradients> {
    let mut splatter = Splatter::new(d).unwrap();
    let gpu_scene = GpuScene::upload(d, scene).unwrap();
    let settings = SplatSettings {
        background: bg,
        channels: Channels::ALL,
        tile,
        surface_depth: rule.surface_depth,
        median_coverage: rule.coverage,
        ..SplatSettings::default()
    };
    let frame = splatter.render_frame(&gpu_scene, camera, &settings).unwrap();
    let out = splatter.backward(&frame, &gpu_scene, grads, true)?;
    Ok(out.read(d).unwrap())
}

fn flatten(g: &GaussianGrad) -> [(usize, f64); 11] {
    let m = g.mean;
    let s = g.log_scale;
    let r = g.rotation;
    [
        (0, m.x),
        (0, m.y),
        (0, m.z),
        (1, s.x),
        (1, s.y),
        (1, s.z),
        (2, r[0]),
        (2, r[1]),
        (2, r[2]),
        (2, r[3]),
        (3, g.opacity_logit),
    ]
}

fn flatten_gpu(h: &HostGaussianGradients, i: usize) -> [f64; 11] {
    let m = h.means[i].map(f64::from);
    let s = h.log_scales[i].map(f64::from);
    let r = h.rotations[i].map(f64::from);
    [m[0], m[1], m[2], s[0], s[1], s[2], r[0], r[1], r[2], r[3], f64::from(h.opacity_logits[i])]
}

const FAMILIES: [&str; 4] = ["mean", "log_scale", "rotation", "opacity_logit"];

/// Every GPU gradient within relative error `tol` of the CPU value, relative to
/// the larger of |CPU| and 1% of the family's largest |CPU| (below that, fp32
/// rounding of sums dominated by the largest terms is what is measured).
fn compare(label: &str, gpu: &HostGaussianGradients, cpu: &[GaussianGrad], tol: f64) {
    let mut family_max = [0.0f64; 4];
    for g in cpu {
        for (f, v) in flatten(g) {
            family_max[f] = family_max[f].max(v.abs());
        }
    }
    let mut worst = [0.0f64; 4];
    for (i, c) in cpu.iter().enumerate() {
        for ((f, cv), gv) in flatten(c).into_iter().zip(flatten_gpu(gpu, i)) {
            assert!(gv.is_finite(), "{label}: Gaussian {i} {} is not finite", FAMILIES[f]);
            let err = (gv - cv).abs() / cv.abs().max(1e-2 * family_max[f]).max(1e-30);
            worst[f] = worst[f].max(err);
            assert!(err <= tol, "{label}: Gaussian {i} {}: GPU {gv:.6e}, CPU {cv:.6e}", FAMILIES[f]);
        }
    }
    assert!(family_max.iter().all(|m| *m > 0.0), "{label}: a parameter family got no gradient at all");
    eprintln!("{label}: worst relative error per family {worst:?}");
}

fn cpu_gradients(scene: &Scene, camera: &Camera, bg: [f32; 3], host: &PixelGrads) -> Vec<GaussianGrad> {
    cpu_gradients_tiled(scene, camera, bg, host, DEFAULT_TILE, CENTRE)
}

/// The twin's gradients.
fn cpu_gradients_tiled(
    scene: &Scene,
    camera: &Camera,
    bg: [f32; 3],
    host: &PixelGrads,
    tile: u32,
    rule: MedianRule,
) -> Vec<GaussianGrad> {
    let params: Vec<Gaussian64> = (0..scene.len()).map(|i| Gaussian64::from_scene(scene, i)).collect();
    let splats = preprocess_params(&params, scene, camera, NormalSource::ShortestAxis, tile, rule.depth());
    let sg = blend_backward_cpu(&splats, camera, bg.map(f64::from), host, tile, rule);
    (0..scene.len()).map(|i| project_backward(&Gaussian64::from_scene(scene, i), camera, &sg[i], true, tile)).collect()
}

/// A pinhole camera, a narrow one (Jacobians clamped) and an orthographic one.
fn twin_cameras() -> [(&'static str, Camera); 3] {
    [
        ("pinhole", Camera::look_at(Vec3::new(0.3, -0.2, -3.0), Vec3::ZERO, Vec3::Y, 50.0, 75, 53).unwrap()),
        ("narrow", Camera::look_at(Vec3::new(0.0, 0.0, -3.0), Vec3::ZERO, Vec3::Y, 20.0, 64, 40).unwrap()),
        (
            "orthographic",
            Camera::orthographic(Vec3::new(0.0, 0.0, -3.0), Vec3::Z, Vec3::Y, 2.6, 2.0, 67, 51, 0.01, 10.0).unwrap(),
        ),
    ]
}

#[test]
fn gpu_backward_matches_cpu_twin_in_every_channel() {
    let d = device();
    let bg = [0.2, 0.4, 0.7];
    let cameras = twin_cameras();
    for (seed, (name, camera)) in cameras.iter().enumerate() {
        let scene = scene(300, seed as u64);
        let pixels = (camera.width * camera.height) as usize;
        let (host, grads) = random_grads(&d, pixels, 100 + seed as u64);
        let gpu = gpu_gradients(&d, &scene, camera, bg, &grads);
        let cpu = cpu_gradients(&scene, camera, bg, &host);
        // fp32 on the GPU (transmittance recovered by division, long sums) against f64.
        compare(name, &gpu, &cpu, 1e-3);
        // Value gradients (rgb and features) are returned per Gaussian.
        let values = gpu.values.as_ref().expect("asked for value gradients");
        assert!(values.iter().all(|v| v.iter().all(|x| x.is_finite())));
        assert!(values.iter().any(|v| v[4] != 0.0 && v[0] != 0.0), "{name}: no value gradients");
    }
    assert_no_validation_messages(&d);
}

/// 1e5 m from the world's origin the gradients match the twin as near it:
/// the backward takes each mean to the camera as R·(p − c) like the forward
/// (docs/conventions.md §8). As R·p + t (forward and backward), Gaussian 0's
/// mean gradient was 7.46e-2 against the twin's 2.95e-2.
#[test]
fn gpu_backward_matches_cpu_twin_far_from_the_origin() {
    let d = device();
    let bg = [0.2, 0.4, 0.7];
    let offset = Vec3::new(1.0e5, -7.0e4, 30.0);
    let mut scene = scene(300, 0);
    move_scene(&mut scene, offset);
    let [(_, camera), ..] = twin_cameras();
    let camera = Camera { position: camera.position + offset, ..camera };
    let (host, grads) = random_grads(&d, (camera.width * camera.height) as usize, 100);
    let gpu = gpu_gradients(&d, &scene, &camera, bg, &grads);
    let cpu = cpu_gradients(&scene, &camera, bg, &host);
    compare("far_pinhole", &gpu, &cpu, 1e-3);
    assert_no_validation_messages(&d);
}

#[test]
fn gpu_backward_matches_cpu_twin_with_surface_depths() {
    // Each splat's depth at a pixel where the ray meets its plane: the depth
    // and median gradients also reach its centre and its slope, and through the
    // slope its shortest axis, mean and covariances (the twin's chain is checked
    // against central differences in srug::splat::cpu_backward).
    let d = device();
    let bg = [0.2, 0.4, 0.7];
    let cameras = twin_cameras();
    for (seed, (name, camera)) in cameras.iter().enumerate() {
        let scene = scene(300, 20 + seed as u64);
        let pixels = (camera.width * camera.height) as usize;
        let (host, grads) = random_grads(&d, pixels, 120 + seed as u64);
        let gpu = gpu_gradients_tiled(&d, &scene, camera, bg, &grads, DEFAULT_TILE, SURFACE).unwrap();
        let cpu = cpu_gradients_tiled(&scene, camera, bg, &host, DEFAULT_TILE, SURFACE);
        compare(&format!("{name}, surface depths"), &gpu, &cpu, 1e-3);
        // The slope's share is not negligible: without it the twin differs.
        let centre = cpu_gradients_tiled(&scene, camera, bg, &host, DEFAULT_TILE, CENTRE);
        let moved = cpu.iter().zip(&centre).filter(|(a, b)| (a.rotation[1] - b.rotation[1]).abs() > 1e-3).count();
        assert!(moved >= 30, "{name}: only {moved} quaternion gradients changed with surface depths");
        // The median read at 70% coverage (as shadow maps read theirs past one half):
        // its gradient goes to other splats, as the twin's.
        let deeper = MedianRule { coverage: 0.7, ..SURFACE };
        let gpu = gpu_gradients_tiled(&d, &scene, camera, bg, &grads, DEFAULT_TILE, deeper).unwrap();
        let cpu_deeper = cpu_gradients_tiled(&scene, camera, bg, &host, DEFAULT_TILE, deeper);
        compare(&format!("{name}, surface depths, median at 0.7"), &gpu, &cpu_deeper, 1e-3);
        let moved = cpu_deeper.iter().zip(&cpu).filter(|(a, b)| (a.mean - b.mean).length() > 1e-3).count();
        assert!(moved >= 10, "{name}: only {moved} mean gradients changed with the median at 0.7");
    }
    assert_no_validation_messages(&d);
}

#[test]
fn backward_gives_the_same_gradients_for_ellipse_and_rectangle_tile_bounds() {
    // Ellipse bounds drop (tile, splat) pairs whose records would be zero, and
    // the backward finds each record by searching the pair tiles: the sums, in
    // the same order less some zeros, must be bit for bit the same.
    let d = device();
    let bg = [0.2, 0.4, 0.7];
    let camera = Camera::look_at(Vec3::new(0.3, -0.2, -3.0), Vec3::ZERO, Vec3::Y, 50.0, 75, 53).unwrap();
    let mut scene = scene(300, 9);
    // Some faint Gaussians (opacity 0.0025 to 0.05) so that whole rectangles shrink.
    for (i, o) in scene.opacity_logits.iter_mut().enumerate() {
        if i % 3 == 0 {
            *o = -6.0 + (i % 9) as f32;
        }
    }
    let pixels = (camera.width * camera.height) as usize;
    let (_, grads) = random_grads(&d, pixels, 109);
    let gpu_scene = GpuScene::upload(&d, &scene).unwrap();
    let mut splatter = Splatter::new(&d).unwrap();
    let mut runs = Vec::new();
    for tile_bounds in [TileBounds::Rectangle, TileBounds::Ellipse] {
        let settings = SplatSettings { background: bg, channels: Channels::ALL, tile_bounds, ..Default::default() };
        let frame = splatter.render_frame(&gpu_scene, &camera, &settings).unwrap();
        let g = splatter.backward(&frame, &gpu_scene, &grads, true).unwrap().read(&d).unwrap();
        runs.push((frame.stats.pairs, g));
    }
    let ((rect_pairs, rect), (ellipse_pairs, ellipse)) = (&runs[0], &runs[1]);
    assert!(ellipse_pairs < rect_pairs, "ellipse bounds list fewer pairs: {ellipse_pairs} against {rect_pairs}");
    assert!(rect.means.iter().flatten().any(|x| *x != 0.0), "some mean gradient is non-zero");
    assert_eq!(rect.means, ellipse.means);
    assert_eq!(rect.log_scales, ellipse.log_scales);
    assert_eq!(rect.rotations, ellipse.rotations);
    assert_eq!(rect.opacity_logits, ellipse.opacity_logits);
    assert_eq!(rect.values, ellipse.values);
    eprintln!("{rect_pairs} rectangle pairs, {ellipse_pairs} ellipse pairs: the same gradients");
    assert_no_validation_messages(&d);
}

#[test]
fn gpu_backward_matches_cpu_twin_at_every_tile_size() {
    let d = device();
    let bg = [0.2, 0.4, 0.7];
    let camera = Camera::look_at(Vec3::new(0.3, -0.2, -3.0), Vec3::ZERO, Vec3::Y, 50.0, 75, 53).unwrap();
    let scene = scene(300, 5);
    let pixels = (camera.width * camera.height) as usize;
    let (host, grads) = random_grads(&d, pixels, 105);
    let mut ran = 0;
    for tile in TILE_SIZES {
        // Every pixel's terms of a batch of at least one splat: 24 floats per pixel with every channel.
        let needed = tile * tile * 24 * 4 + 64;
        match gpu_gradients_tiled(&d, &scene, &camera, bg, &grads, tile, CENTRE) {
            Ok(gpu) => {
                assert!(needed <= d.info().max_shared_memory, "tile {tile} ran with too little shared memory");
                let cpu = cpu_gradients_tiled(&scene, &camera, bg, &host, tile, CENTRE);
                compare(&format!("tile {tile}"), &gpu, &cpu, 1e-3);
                ran += 1;
            }
            Err(e) => {
                // Only for lack of shared memory (tile 32 on lavapipe's 32 KiB), with a clear message.
                assert!(needed > d.info().max_shared_memory, "tile {tile}: {e}");
                let text = e.to_string();
                assert!(text.contains("shared memory") && text.contains("tile size 32"), "{text}");
                eprintln!("tile {tile}: refused as expected: {text}");
            }
        }
    }
    assert!(ran >= 1, "no tile size ran");
    assert_no_validation_messages(&d);
}

#[test]
fn gpu_backward_matches_central_finite_differences() {
    // A small scene so the f64 forward can be rerun for every parameter.
    let d = device();
    let scene = scene(16, 9);
    let camera = Camera::look_at(Vec3::new(0.3, -0.2, -3.0), Vec3::ZERO, Vec3::Y, 50.0, 40, 28).unwrap();
    let pixels = (camera.width * camera.height) as usize;
    let (host, grads) = random_grads(&d, pixels, 77);
    let bg = [0.1, 0.2, 0.3];
    let gpu = gpu_gradients(&d, &scene, &camera, bg, &grads);
    let params: Vec<Gaussian64> = (0..scene.len()).map(|i| Gaussian64::from_scene(&scene, i)).collect();
    let loss = |p: &[Gaussian64]| -> f64 {
        let (_, blends) = render_blends(p, &scene, &camera, NormalSource::ShortestAxis, DEFAULT_TILE, CENTRE);
        let mut total = 0.0;
        for (px, b) in blends.iter().enumerate() {
            for (k, (v, w)) in b.values.iter().zip(&host.values[px]).enumerate() {
                let composited = v + bg.get(k).map_or(0.0, |c| b.t_final * f64::from(*c));
                total += composited * w;
            }
            total += (1.0 - b.t_final) * host.alpha[px] + b.median * host.median[px];
        }
        total
    };
    let h = 1e-6;
    let mut fd = Vec::new();
    for i in 0..params.len() {
        let mut g = GaussianGrad::default();
        let diff = |f: &dyn Fn(&mut Gaussian64, f64)| {
            let (mut a, mut b) = (params.clone(), params.clone());
            f(&mut a[i], h);
            f(&mut b[i], -h);
            (loss(&a) - loss(&b)) / (2.0 * h)
        };
        let mut m = DVec3::ZERO;
        let mut s = DVec3::ZERO;
        for k in 0..3 {
            m[k] = diff(&|p, e| p.mean[k] += e);
            s[k] = diff(&|p, e| p.log_scale[k] += e);
        }
        g.mean = m;
        g.log_scale = s;
        for k in 0..4 {
            g.rotation[k] = diff(&|p, e| p.rotation[k] += e);
        }
        g.opacity_logit = diff(&|p, e| p.opacity_logit += e);
        fd.push(g);
    }
    compare("finite differences", &gpu, &fd, 1e-3);
    assert_no_validation_messages(&d);
}

#[test]
fn backward_refuses_mismatched_inputs() {
    let d = device();
    let s = scene(50, 1);
    let camera = Camera::look_at(Vec3::new(0.0, 0.0, -3.0), Vec3::ZERO, Vec3::Y, 50.0, 32, 32).unwrap();
    let mut splatter = Splatter::new(&d).unwrap();
    let gpu_scene = GpuScene::upload(&d, &s).unwrap();
    let other = GpuScene::upload(&d, &s).unwrap();
    let frame = splatter.render_frame(&gpu_scene, &camera, &SplatSettings::default()).unwrap();
    let short =
        BlendGrads { alpha: Some(d.create_buffer("short", 16, MemoryKind::Storage).unwrap()), ..BlendGrads::default() };
    let e = splatter.backward(&frame, &gpu_scene, &short, false).err().unwrap().to_string();
    assert!(e.contains("alpha") && e.contains("needs"), "{e}");
    let ok = BlendGrads {
        alpha: Some(d.create_filled::<f32>("ones", 32 * 32, 1.0f32.to_bits()).unwrap()),
        ..BlendGrads::default()
    };
    let e = splatter.backward(&frame, &other, &ok, false).err().unwrap().to_string();
    assert!(e.contains("another scene"), "{e}");
    // `Splatter::render` drops its frame and so writes no pair tiles: the same image, bit for
    // bit; a frame without them is refused, naming what is missing.
    let (rendered, _) = splatter.render(&gpu_scene, &camera, &SplatSettings::default()).unwrap();
    let (rendered, kept) = (rendered.read(&d).unwrap(), frame.gbuffer.read(&d).unwrap());
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&rendered.alpha), bits(&kept.alpha));
    assert_eq!(rendered.rgb.as_deref().map(bits), kept.rgb.as_deref().map(bits));
    let mut bare = splatter.render_frame(&gpu_scene, &camera, &SplatSettings::default()).unwrap();
    assert!(bare.pair_tiles.take().is_some(), "render_frame keeps the pair tiles");
    let e = splatter.backward(&bare, &gpu_scene, &ok, false).err().unwrap().to_string();
    assert!(e.contains("pair tiles"), "{e}");
    let normal = d.create_filled::<f32>("n", 3 * 32 * 32, 0).unwrap();
    let features =
        BlendGrads { channels: PerChannel::default().with(Channel::Normal, normal), ..BlendGrads::default() };
    let e = splatter.backward(&frame, &gpu_scene, &features, false).err().unwrap().to_string();
    assert!(e.contains("feature"), "{e}");
    // Zero upstream gradient gives exactly zero gradients.
    let zero = BlendGrads { alpha: Some(d.create_filled::<f32>("zero", 32 * 32, 0).unwrap()), ..BlendGrads::default() };
    let g = splatter.backward(&frame, &gpu_scene, &zero, false).unwrap().read(&d).unwrap();
    assert!(g.means.iter().flatten().chain(g.opacity_logits.iter()).all(|v| *v == 0.0));
    assert_no_validation_messages(&d);
}

#[test]
fn backward_of_a_frame_without_rgb() {
    let d = device();
    let s = scene(80, 2);
    let camera = Camera::look_at(Vec3::new(0.0, 0.0, -3.0), Vec3::ZERO, Vec3::Y, 50.0, 32, 24).unwrap();
    let mut splatter = Splatter::new(&d).unwrap();
    let gpu_scene = GpuScene::upload(&d, &s).unwrap();
    let on = splatter.render_frame(&gpu_scene, &camera, &SplatSettings::default()).unwrap();
    let off =
        splatter.render_frame(&gpu_scene, &camera, &SplatSettings { rgb: false, ..SplatSettings::default() }).unwrap();
    let mut rng = Pcg64Mcg::seed_from_u64(4);
    let up: Vec<f32> = (0..32 * 24).map(|_| rng.random_range(-1.0..1.0)).collect();
    let alpha = BlendGrads { alpha: Some(d.upload("dL/dalpha", &up).unwrap()), ..BlendGrads::default() };
    // Alpha gradients do not depend on colour: the same, bit for bit, without it.
    let g_on = splatter.backward(&on, &gpu_scene, &alpha, false).unwrap().read(&d).unwrap();
    let g_off = splatter.backward(&off, &gpu_scene, &alpha, false).unwrap().read(&d).unwrap();
    assert!(g_on.means.iter().flatten().any(|v| *v != 0.0), "the alpha gradient reaches the means");
    assert_eq!(g_on, g_off);
    // An rgb gradient needs the colour the frame did not blend.
    let rgb =
        BlendGrads { rgb: Some(d.create_filled::<f32>("dL/drgb", 3 * 32 * 24, 0).unwrap()), ..BlendGrads::default() };
    let e = splatter.backward(&off, &gpu_scene, &rgb, false).err().unwrap().to_string();
    assert!(e.contains("rgb"), "{e}");
    assert_no_validation_messages(&d);
}
