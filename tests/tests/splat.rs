//! The splatting pipeline against its f64 CPU twin: random scenes, the demo
//! city and the real trained scene, every channel, with outputs pre-filled
//! with a NaN sentinel; extremes give finite outputs and no validation message.

#![allow(clippy::unwrap_used, clippy::expect_used, reason = "a failed unwrap is a failed test")]

use glam::Vec3;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;
use srug::gpu::Device;
use srug::scene::activate::GpuScene;
use srug::scene::demo::{demo_city, DemoOptions};
use srug::scene::{read_ply, sh_coefficients, Camera, Scene};
use srug::splat::cpu::render_cpu;
use srug::splat::{Channels, GBuffer, NormalSource, SplatSettings, Splatter};
use srug_tests::{assert_no_validation_messages, device, failure_dir, save_comparison};

const NAN: u32 = 0x7fc0_0000;
/// rgb must agree with the CPU twin to this PSNR (peak 1).
const MIN_PSNR_DB: f64 = 50.0;
/// Largest error allowed in alpha, relative to 1.
const ALPHA_TOLERANCE: f64 = 2e-3;

fn psnr(a: &[f32], b: &[f32]) -> f64 {
    let mse =
        a.iter().zip(b).map(|(x, y)| (f64::from(*x) - f64::from(*y)).powi(2)).sum::<f64>() / a.len().max(1) as f64;
    if mse == 0.0 {
        f64::INFINITY
    } else {
        -10.0 * mse.log10()
    }
}

/// Compares every channel; the tolerance of premultiplied channels scales
/// with their largest value.
fn compare(gpu: &GBuffer, cpu: &GBuffer, label: &str) {
    for ((name, g, k), (_, c, _)) in gpu.channels().into_iter().zip(cpu.channels()) {
        assert!(g.iter().all(|v| v.is_finite()), "{label}: {name} has non-finite values (unwritten sentinel?)");
        let (ok, what) = match name {
            "rgb" => {
                let p = psnr(g, c);
                (p >= MIN_PSNR_DB, format!("PSNR {p:.1} dB < {MIN_PSNR_DB}"))
            }
            _ => {
                let scale = c.iter().fold(1.0f64, |m, v| m.max(f64::from(v.abs())));
                let tol = ALPHA_TOLERANCE * scale;
                let err = g.iter().zip(c).map(|(a, b)| (f64::from(*a) - f64::from(*b)).abs()).fold(0.0, f64::max);
                // Median depth jumps where a near-tie flips which splat crosses T = 0.5: count outliers instead.
                if name == "median_depth" {
                    let bad = g.iter().zip(c).filter(|(a, b)| (f64::from(**a) - f64::from(**b)).abs() > tol).count();
                    (bad * 1000 <= g.len(), format!("{bad} of {} pixels differ by more than {tol:.2e}", g.len()))
                } else {
                    (err <= tol, format!("max error {err:.3e} > {tol:.3e}"))
                }
            }
        };
        if !ok {
            let saved = save_comparison(&format!("{label}_{name}"), gpu.width, gpu.height, k, g, c);
            panic!("{label}: {name}: {what} (images: {saved})");
        }
    }
}

fn render_both(
    d: &Device,
    splatter: &mut Splatter,
    scene: &Scene,
    camera: &Camera,
    settings: &SplatSettings,
    label: &str,
) -> GBuffer {
    let gpu_scene = GpuScene::upload(d, scene).unwrap();
    let (out, stats) = splatter.render(&gpu_scene, camera, settings).unwrap();
    let gpu = out.read(d).unwrap();
    let cpu = render_cpu(scene, camera, settings);
    compare(&gpu, &cpu, label);
    eprintln!("{label}: {} pairs, {} key bits", stats.pairs, stats.key_bits);
    gpu
}

fn random_scene(n: usize, sh_degree: u32, seed: u64, spread: f32) -> Scene {
    let mut rng = Pcg64Mcg::seed_from_u64(seed);
    let k = sh_coefficients(sh_degree);
    let mut s = Scene { sh_degree, ..Scene::default() };
    for _ in 0..n {
        s.means.push([
            rng.random_range(-spread..spread),
            rng.random_range(-spread..spread),
            rng.random_range(-spread..spread),
        ]);
        s.log_scales.push([rng.random_range(-3.0..-0.5), rng.random_range(-3.0..-0.5), rng.random_range(-3.0..-0.5)]);
        s.rotations.push([
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(0.1..1.0),
        ]);
        s.opacity_logits.push(rng.random_range(-2.0..4.0));
        s.sh.extend((0..k * 3).map(|_| rng.random_range(-0.6..0.6f32)));
    }
    s
}

fn all_settings() -> SplatSettings {
    SplatSettings {
        background: [0.2, 0.3, 0.4],
        channels: Channels::ALL,
        normal_source: NormalSource::Stored,
        prefill: Some(NAN),
    }
}

#[test]
fn random_scenes_match_cpu_twin() {
    let d = device();
    let mut splatter = Splatter::new(&d).unwrap();
    let settings = SplatSettings {
        channels: Channels { depth: true, median_depth: true, normal: true, ..Channels::default() },
        ..all_settings()
    };
    for (n, degree, w, h) in [(1usize, 0u32, 64u32, 48u32), (500, 1, 100, 70), (4000, 3, 160, 90)] {
        let scene = random_scene(n, degree, n as u64, 2.0);
        let cam = Camera::look_at(Vec3::new(0.0, -6.0, 0.5), Vec3::ZERO, Vec3::Z, 70.0, w, h).unwrap();
        render_both(&d, &mut splatter, &scene, &cam, &settings, &format!("random_{n}"));
    }
    assert_no_validation_messages(&d);
}

#[test]
fn demo_city_matches_cpu_twin_in_every_channel() {
    let d = device();
    let mut splatter = Splatter::new(&d).unwrap();
    let city = demo_city(&DemoOptions { seed: 7, gaussians: 60_000, sh_degree: 2 }).unwrap();
    let mut cam = city.cameras[1].clone();
    cam.width = 352;
    cam.height = 96;
    if let srug::scene::Projection::Pinhole { fx, fy, cx, cy } = cam.projection {
        cam.projection = srug::scene::Projection::Pinhole { fx: fx / 2.0, fy: fy / 2.0, cx: cx / 2.0, cy: cy / 2.0 };
    }
    let g = render_both(&d, &mut splatter, &city.scene, &cam, &all_settings(), "demo");
    let covered = g.alpha.iter().filter(|a| **a > 0.5).count();
    assert!(covered * 10 > g.alpha.len() * 9, "the street should cover the view: {covered} of {}", g.alpha.len());
    assert_no_validation_messages(&d);
}
