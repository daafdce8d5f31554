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
