//! Shared helpers for srug's integration tests.
//!
//! Every GPU test makes its device with [`device`], which turns on the Khronos
//! validation layer with synchronization validation, and ends with
//! [`assert_no_validation_messages`]: any message fails the test that caused it.
//! GPU outputs are pre-filled with [`NAN_SENTINEL`] so "not written" differs from
//! "wrote 0"; [`psnr`] and [`random_scene`] are the comparisons and inputs the
//! stage tests share.

pub mod fuzz;
pub mod host_vulkan;

use std::path::PathBuf;

use rand::{Rng, SeedableRng};
use srug::gpu::{Device, DeviceOptions};
use srug::scene::{sh_coefficients, Scene};

/// The bits of a quiet NaN: what GPU outputs are pre-filled with before a kernel
/// runs (the `prefill` of the stages' settings), so an unwritten value fails
/// every finiteness check.
pub const NAN_SENTINEL: u32 = 0x7fc0_0000;

/// Peak signal-to-noise ratio in dB of `a` against `b` (peak 1); infinite when equal.
pub fn psnr<T: Copy + Into<f64>>(a: &[f32], b: &[T]) -> f64 {
    assert_eq!(a.len(), b.len(), "psnr of slices of different lengths");
    let mse = a.iter().zip(b).map(|(x, y)| (f64::from(*x) - (*y).into()).powi(2)).sum::<f64>() / a.len().max(1) as f64;
    if mse == 0.0 {
        f64::INFINITY
    } else {
        -10.0 * mse.log10()
    }
}

/// `n` random Gaussians of SH degree `sh_degree` from `seed`: means uniform in
/// ±`spread`, log-scales in [−3, −0.5], random rotations, opacity logits in
/// [−2, 4], SH coefficients in ±0.6 — an ordinary scene, not the extremes.
pub fn random_scene(n: usize, sh_degree: u32, seed: u64, spread: f32) -> Scene {
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(seed);
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

/// Moves every mean of `scene` by `offset` (a scene far from the world's origin).
pub fn move_scene(scene: &mut Scene, offset: glam::Vec3) {
    for m in &mut scene.means {
        *m = (glam::Vec3::from(*m) + offset).to_array();
    }
}

/// The scene the committed format fixtures (tests/data/formats) are made
/// from: 400 SH-3 Gaussians of [`random_scene`] with a few extremes (centres
/// 1500 m out, near-transparent and near-opaque, tiny and large scales).
pub fn format_source_scene() -> Scene {
    let mut s = random_scene(400, 3, 33, 40.0);
    s.means[3] = [1500.0, -1200.5, 7.25];
    s.means[4] = [-900.0, 1499.0, -1450.0];
    s.opacity_logits[5] = -9.0;
    s.opacity_logits[6] = 9.0;
    s.log_scales[7] = [-9.5, -6.0, 1.5];
    s.rotations[8] = [0.0, 0.0, 0.0, -2.0];
    s
}

/// A device with validation on (device choice from `SRUG_DEVICE`, else automatic).
pub fn device() -> Device {
    match Device::new(&DeviceOptions { selection: None, validation: Some(true) }) {
        Ok(d) => d,
        Err(e) => panic!("cannot create a Vulkan device with validation: {e}"),
    }
}

/// Fails the test when the validation layer said anything.
pub fn assert_no_validation_messages(device: &Device) {
    assert!(device.validation_enabled(), "validation layer is not running");
    let messages = device.take_validation_messages();
    assert!(messages.is_empty(), "{} validation message(s):\n{}", messages.len(), messages.join("\n"));
}

/// `../shared/data` relative to the workspace root, when present.
pub fn shared_data() -> Option<PathBuf> {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..").join("..").join("shared").join("data");
    root.is_dir().then_some(root)
}

/// Where tests save images and dumps of failures.
pub fn failure_dir() -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("failures");
    let _ = std::fs::create_dir_all(&dir);
    dir
}

/// Saves GPU, CPU and |difference| images of a channel (`k` floats per pixel)
/// as PGM/PPM under [`failure_dir`]; returns where.
pub fn save_comparison(label: &str, width: u32, height: u32, k: usize, gpu: &[f32], cpu: &[f32]) -> String {
    let dir = failure_dir();
    let scale = cpu.iter().chain(gpu).filter(|v| v.is_finite()).fold(1e-12f32, |m, v| m.max(v.abs()));
    let write = |name: &str, values: &mut dyn Iterator<Item = f32>| {
        let channels = if k == 3 { 3 } else { 1 };
        let magic = if channels == 3 { "P6" } else { "P5" };
        let mut bytes = format!("{magic}\n{width} {height}\n255\n").into_bytes();
        for (i, v) in values.enumerate() {
            if k == 3 || i % k == 0 {
                bytes.push((v / scale * 255.0).clamp(0.0, 255.0) as u8);
            }
        }
        let path = dir.join(format!("{label}_{name}.{}", if channels == 3 { "ppm" } else { "pgm" }));
        let _ = std::fs::write(&path, bytes);
    };
    write("gpu", &mut gpu.iter().map(|v| if v.is_finite() { v.abs() } else { scale }));
    write("cpu", &mut cpu.iter().map(|v| v.abs()));
    write("diff", &mut gpu.iter().zip(cpu).map(|(a, b)| if a.is_finite() { (a - b).abs() * 10.0 } else { scale }));
    dir.join(label).display().to_string() + "_{gpu,cpu,diff}"
}
