//! A quick end-to-end check of the device: upload, two kernel variants chosen
//! by specialization, push constants, timestamps and readback, compared with a
//! CPU twin. `srug demo` and `srug info` run it; tests use the same kernels.

use bytemuck::{Pod, Zeroable};

use crate::{kernels, Binding, BindingKind, Device, DeviceAddress, Grid, Kernel, KernelDecl, Result, SpecValue};

/// Push constants of `core_affine.comp` (the GLSL `Push` block; checked by [`check_layout`](crate::check_layout)).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct AffinePush {
    /// Multiplier.
    pub a: f32,
    /// Offset.
    pub b: f32,
    /// Number of elements.
    pub count: u32,
    /// Padding to the GLSL block size.
    pub pad: u32,
}
crate::gpu_layout!(AffinePush, "Push", [a, b, count, pad]);

/// Push constants of `core_affine_addressed.comp` (the GLSL `AddressedPush` block).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct AffineAddressedPush {
    /// The input floats.
    pub x: DeviceAddress,
    /// The output floats.
    pub y: DeviceAddress,
    /// Multiplier.
    pub a: f32,
    /// Offset.
    pub b: f32,
    /// Number of elements.
    pub count: u32,
    /// Padding to the GLSL block size.
    pub pad: u32,
}
crate::gpu_layout!(AffineAddressedPush, "AddressedPush", [x, y, a, b, count, pad]);

/// The bindings `core_affine.comp` declares.
pub const AFFINE_BINDINGS: [BindingKind; 2] =
    [BindingKind::StorageBuffer { read_only: true }, BindingKind::StorageBuffer { read_only: false }];

/// Builds `core_affine` with `MODE` = `mode` (0: a·x + b, 1: a·x² + b).
pub fn affine_kernel(device: &Device, mode: u32) -> Result<Kernel> {
    Kernel::new(
        device,
        &kernels::CORE_AFFINE,
        &KernelDecl {
            bindings: &AFFINE_BINDINGS,
            push_constant_size: std::mem::size_of::<AffinePush>(),
            specialization: &[(0, SpecValue::U32(mode))],
        },
    )
}

/// CPU twin of `core_affine.comp`, in f64.
pub fn affine_cpu(x: &[f32], a: f32, b: f32, mode: u32) -> Vec<f64> {
    let (a, b) = (f64::from(a), f64::from(b));
    x.iter().map(|&v| if mode == 0 { a * f64::from(v) + b } else { a * f64::from(v) * f64::from(v) + b }).collect()
}

/// What the self-test measured.
#[derive(Clone, Debug)]
pub struct SelfTestReport {
    /// Elements processed per variant.
    pub elements: usize,
    /// Largest |GPU − CPU| relative to max(1, |CPU|) over both variants.
    pub max_rel_error: f64,
    /// GPU time of each variant's dispatch, in seconds.
    pub stage_seconds: Vec<(String, f64)>,
}

impl SelfTestReport {
    /// Whether the GPU agreed with the CPU twin within fp32 rounding (1e-6 relative).
    pub fn passed(&self) -> bool {
        self.max_rel_error <= 1e-6
    }
}

/// Runs both `core_affine` variants over `n` values and compares them with the CPU twin.
pub fn run(device: &Device, n: usize) -> Result<SelfTestReport> {
    let x: Vec<f32> = (0..n).map(|i| ((i % 1000) as f32 - 500.0) * 0.01).collect();
    let input = device.upload("selftest x", &x)?;
    let mut max_rel_error = 0.0f64;
    let mut stage_seconds = Vec::new();
    for mode in [0u32, 1] {
        let kernel = affine_kernel(device, mode)?;
        let output = device.create_filled::<f32>("selftest y", n, 0x7fc0_0000)?;
        let push = AffinePush { a: 1.5, b: -0.25, count: n as u32, pad: 0 };
        let stage = format!("affine mode {mode}");
        let timings = device.run(|rec| {
            rec.begin_stage(&stage);
            rec.dispatch(&kernel, Grid::Items(n as u64), &[Binding::from(&input), Binding::from(&output)], &push)
        })?;
        let y: Vec<f32> = device.read_buffer(&output)?;
        for (got, want) in y.iter().zip(affine_cpu(&x, push.a, push.b, mode)) {
            let e = (f64::from(*got) - want).abs() / want.abs().max(1.0);
            max_rel_error = max_rel_error.max(if e.is_nan() { f64::INFINITY } else { e });
        }
        stage_seconds.push((stage, timings.get(&format!("affine mode {mode}")).unwrap_or(0.0)));
    }
    Ok(SelfTestReport { elements: n, max_rel_error, stage_seconds })
}
