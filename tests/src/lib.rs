//! Shared helpers for srug's integration tests.
//!
//! Every GPU test makes its device with [`device`], which turns on the Khronos
//! validation layer with synchronization validation, and ends with
//! [`assert_no_validation_messages`]: any message fails the test that caused it.

use std::path::PathBuf;

use srug::gpu::{Device, DeviceOptions};

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
