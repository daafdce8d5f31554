//! The Vulkan core on the test device: kernels with push and specialization
//! constants, binding checks, buffers above maxStorageBufferRange, texel-buffer
//! views, timestamps, memory accounting and deferred destruction — all with
//! validation on.

#![allow(clippy::unwrap_used, clippy::expect_used, reason = "a failed unwrap is a failed test")]

use srug_gpu::ash::vk;
use srug_gpu::selftest::{self, affine_cpu, affine_kernel, AffineAddressedPush, AffinePush, AFFINE_BINDINGS};
use srug_gpu::{
    self as gpu, full_subgroup_flags, kernels, specialized_workgroup_size, Binding, BindingKind, Buffer, Device,
    DeviceOptions, DeviceSelection, GpuError as Error, Grid, Kernel, KernelDecl, MemoryKind, SpecValue, TexelFormat,
    Texels, POOL_HEADROOM_BYTES,
};

/// A device with validation on (device choice from `SRUG_DEVICE`, else automatic).
fn device() -> Device {
    match Device::new(&DeviceOptions { selection: None, validation: Some(true) }) {
        Ok(d) => d,
        Err(e) => panic!("cannot create a Vulkan device with validation: {e}"),
    }
}

/// Fails the test when the validation layer said anything.
fn assert_no_validation_messages(device: &Device) {
    assert!(device.validation_enabled(), "validation layer is not running");
    let messages = device.take_validation_messages();
    assert!(messages.is_empty(), "{} validation message(s):\n{}", messages.len(), messages.join("\n"));
}

const NAN: u32 = 0x7fc0_0000;

/// Largest relative error of `got` against the f64 twin; NaN (the sentinel) counts as infinite.
fn max_rel_error(got: &[f32], want: &[f64]) -> f64 {
    assert_eq!(got.len(), want.len());
    got.iter()
        .zip(want)
        .map(|(g, w)| {
            let e = (f64::from(*g) - w).abs() / w.abs().max(1.0);
            if e.is_nan() {
                f64::INFINITY
            } else {
                e
            }
        })
        .fold(0.0, f64::max)
}

#[test]
fn selftest_matches_cpu_twin() {
    let d = device();
    let report = selftest::run(&d, 10_000).unwrap();
    assert!(report.passed(), "max relative error {}", report.max_rel_error);
    assert_no_validation_messages(&d);
}

#[test]
fn validation_messages_are_caught() {
    // Proves the check used by every test can fail.
    let d = device();
    d.provoke_validation_message().unwrap();
    let messages = d.take_validation_messages();
    assert!(!messages.is_empty(), "an invalid call produced no validation message");
    assert!(d.take_validation_messages().is_empty(), "messages are taken once");

    // Synchronization validation is on: an unsynchronized write-after-write is reported.
    let scratch = d.create_buffer("scratch", 256, MemoryKind::Storage).unwrap();
    d.run(|rec| rec.fill_twice_without_barrier(&scratch)).unwrap();
    let messages = d.take_validation_messages();
    assert!(messages.iter().any(|m| m.contains("SYNC-HAZARD")), "no hazard reported: {messages:?}");
}

#[test]
fn kernel_push_and_specialization_constants() {
    let d = device();
    // Not multiples of the workgroup size (64), and enough workgroups for a
    // three-row grid (a mis-indexed second row once passed a two-row test).
    // Devices with 2³¹ − 1 workgroups per row (NVIDIA) never need a second row:
    // there the last size stays one row of 8 Mi elements rather than 1 TB.
    let row = d.info().max_workgroup_count[0].min(65_535) as usize;
    for n in [0usize, 1, 63, 65, 100_003, 2 * row * 64 + 129] {
        let x: Vec<f32> = (0..n).map(|i| ((i * 7919) % 2001) as f32 * 0.01 - 10.0).collect();
        let input = d.upload("x", &x).unwrap();
        for mode in [0u32, 1] {
            let kernel = affine_kernel(&d, mode).unwrap();
            let output = d.create_filled::<f32>("y", n, NAN).unwrap();
            let push = AffinePush { a: -2.5, b: 0.75, count: n as u32, pad: 0 };
            d.run(|rec| {
                rec.dispatch(&kernel, Grid::Items(n as u64), &[Binding::from(&input), Binding::from(&output)], &push)
            })
            .unwrap();
            let y: Vec<f32> = d.read_buffer(&output).unwrap();
            let err = max_rel_error(&y, &affine_cpu(&x, push.a, push.b, mode));
            // fp32: one rounding per operation, at most 3 operations.
            assert!(err <= 4.0 * f64::from(f32::EPSILON), "n={n} mode={mode}: max relative error {err}");
        }
    }
    assert_no_validation_messages(&d);
}

#[test]
fn declarations_are_checked_against_spirv() {
    let d = device();
    let push = std::mem::size_of::<AffinePush>();
    let bad_bindings =
        [BindingKind::StorageBuffer { read_only: false }, BindingKind::StorageBuffer { read_only: false }];
    let cases: Vec<(&str, KernelDecl<'_>)> = vec![
        ("read-only mismatch", KernelDecl { bindings: &bad_bindings, push_constant_size: push, specialization: &[] }),
        (
            "too few bindings",
            KernelDecl { bindings: &AFFINE_BINDINGS[..1], push_constant_size: push, specialization: &[] },
        ),
        ("push size", KernelDecl { bindings: &AFFINE_BINDINGS, push_constant_size: push + 4, specialization: &[] }),
        (
            "unknown constant_id",
            KernelDecl {
                bindings: &AFFINE_BINDINGS,
                push_constant_size: push,
                specialization: &[(9, SpecValue::U32(1))],
            },
        ),
    ];
    for (what, decl) in cases {
        match Kernel::new(&d, &kernels::CORE_AFFINE, &decl) {
            Err(Error::Kernel { kernel, message }) => {
                assert_eq!(kernel, "core_affine");
                assert!(!message.is_empty(), "{what}");
            }
            other => panic!("{what}: expected a kernel error, got {other:?}"),
        }
    }
    // Dispatch-time checks: wrong buffer count and wrong push-constant type.
    let kernel = affine_kernel(&d, 0).unwrap();
    let a = d.upload("a", &[1.0f32; 4]).unwrap();
    let mut rec = d.begin().unwrap();
    assert!(matches!(
        rec.dispatch(
            &kernel,
            Grid::Exact([1, 1, 1]),
            &[Binding::from(&a)],
            &AffinePush { a: 1.0, b: 0.0, count: 4, pad: 0 }
        ),
        Err(Error::Kernel { .. })
    ));
    assert!(matches!(
        rec.dispatch(&kernel, Grid::Exact([1, 1, 1]), &[Binding::from(&a), Binding::from(&a)], &[0u32; 2]),
        Err(Error::Kernel { .. })
    ));
    drop(rec);
    // The table itself: every kernel reflects a workgroup size and set-0 bindings.
    for k in kernels::ALL {
        assert!(k.workgroup_size.iter().all(|s| *s >= 1), "{}", k.name);
        assert!(k.bindings.iter().all(|b| b.set == 0), "{}", k.name);
        assert!(!k.words.is_empty() && k.words[0] == 0x0723_0203, "{}: not SPIR-V", k.name);
    }
    // Full subgroups: read from the SPIR-V (the subgroup's index), built with
    // REQUIRE_FULL_SUBGROUPS only where the device enabled computeFullSubgroups
    // and the subgroup size divides the workgroup's width; refused by name elsewhere.
    let reading: Vec<&str> = kernels::ALL.iter().filter(|k| k.full_subgroups).map(|k| k.name).collect();
    assert_eq!(reading, ["sort_scatter_block"], "the kernels that read gl_SubgroupID");
    let scatter = &kernels::SORT_SCATTER_BLOCK;
    assert!(d.info().full_subgroups || !d.info().is_lavapipe(), "srug enables computeFullSubgroups where offered");
    assert_eq!(
        full_subgroup_flags(&kernels::CORE_AFFINE, [64, 1, 1], d.info()),
        Ok(vk::PipelineShaderStageCreateFlags::empty())
    );
    let mut lacking = d.info().clone();
    lacking.full_subgroups = false;
    let e = full_subgroup_flags(scatter, [128, 1, 1], &lacking).unwrap_err();
    assert!(e.contains("computeFullSubgroups"), "{e}");
    let mut wide = d.info().clone();
    (wide.full_subgroups, wide.subgroup_size) = (true, 64);
    let e = full_subgroup_flags(scatter, [96, 1, 1], &wide).unwrap_err();
    assert!(e.contains("subgroup size 64") && e.contains("96"), "{e}");
    assert_eq!(
        full_subgroup_flags(scatter, [128, 1, 1], &wide),
        Ok(vk::PipelineShaderStageCreateFlags::REQUIRE_FULL_SUBGROUPS)
    );
    assert_eq!(kernels::CORE_AFFINE.spec_constants[0].name, "MODE");
    assert_eq!(kernels::CORE_AFFINE.push_constant_size, 16);
    assert_eq!(kernels::CORE_AFFINE.workgroup_size_ids, [None; 3]);

    // A specialized workgroup size (`local_size_x_id`): the per-tile blend, one
    // invocation per pixel, its edge set by the tile-size constants 15 and 16.
    let blend = &kernels::SPLAT_BLEND_PORTABLE;
    assert_eq!(blend.workgroup_size, [16, 16, 1]);
    assert_eq!(blend.workgroup_size_ids, [Some(15), Some(16), None]);
    let frame = [BindingKind::UniformBuffer];
    let spec = [(15, SpecValue::U32(8)), (16, SpecValue::U32(8))];
    let decl = KernelDecl { bindings: &frame, push_constant_size: 0, specialization: &spec };
    assert_eq!(specialized_workgroup_size(blend, &decl).unwrap(), [8, 8, 1]);
    let k = Kernel::new(&d, blend, &decl).unwrap();
    assert_eq!(k.workgroup_size(), [8, 8, 1]);
    // A 2D workgroup cannot be dispatched as 1D work.
    let u = d.upload("frame", &[0u32; 4]).unwrap();
    let mut rec = d.begin().unwrap();
    assert!(matches!(rec.dispatch(&k, Grid::Items(64), &[Binding::from(&u)], &()), Err(Error::Kernel { .. })));
    drop(rec);
    // Zero, or more invocations than the device allows, is refused before Vulkan sees it.
    let zero = [(15, SpecValue::U32(0))];
    assert!(specialized_workgroup_size(blend, &KernelDecl { specialization: &zero, ..decl }).is_err());
    let edge = f64::from(d.info().max_workgroup_invocations).sqrt() as u32 + 1;
    let huge = [(15, SpecValue::U32(edge)), (16, SpecValue::U32(edge))];
    let e = Kernel::new(&d, blend, &KernelDecl { specialization: &huge, ..decl }).unwrap_err();
    assert!(e.to_string().contains("exceeds this device's limits"), "{e}");
    assert_no_validation_messages(&d);
}

#[test]
fn buffers_above_max_storage_buffer_range() {
    let d = device();
    let range = d.info().max_storage_buffer_range;
    // 32 MiB past the binding limit (160 MiB on lavapipe), and not a multiple of the staging chunk.
    let n = ((range + (32 << 20)) / 4) as usize + 12_345;
    let x: Vec<f32> = (0..n).map(|i| (i % 65_521) as f32 - 30_000.5).collect();

    // Bit-exact round trip through staging.
    let big = d.upload("big x", &x).unwrap();
    assert!(big.size() > range);
    let back: Vec<f32> = d.read_buffer(&big).unwrap();
    assert!(
        back.iter().zip(&x).all(|(a, b)| a.to_bits() == b.to_bits()),
        "round trip above {range} bytes is not bit-exact"
    );
    drop(back);

    // Binding it through a descriptor is refused with a clear error...
    let kernel = affine_kernel(&d, 0).unwrap();
    let out = d.create_buffer("big y", big.size(), MemoryKind::Storage).unwrap();
    let mut rec = d.begin().unwrap();
    match rec.dispatch(
        &kernel,
        Grid::Items(n as u64),
        &[Binding::from(&big), Binding::from(&out)],
        &AffinePush { a: 1.0, b: 0.0, count: n as u32, pad: 0 },
    ) {
        Err(Error::Kernel { message, .. }) => assert!(message.contains("maxStorageBufferRange"), "{message}"),
        other => panic!("expected a range error, got {other:?}"),
    }
    drop(rec);

    // ...and reaching it by device address works.
    let addressed = Kernel::new(
        &d,
        &kernels::CORE_AFFINE_ADDRESSED,
        &KernelDecl {
            bindings: &[],
            push_constant_size: std::mem::size_of::<AffineAddressedPush>(),
            specialization: &[],
        },
    )
    .unwrap();
    d.run(|rec| rec.fill(&out, NAN)).unwrap();
    d.run(|rec| {
        let push =
            AffineAddressedPush { x: rec.addr(&big)?, y: rec.addr(&out)?, a: 0.5, b: 3.0, count: n as u32, pad: 0 };
        rec.dispatch(&addressed, Grid::Items(n as u64), &[], &push)
    })
    .unwrap();
    let y: Vec<f32> = d.read_buffer(&out).unwrap();
    let expected = affine_cpu(&x, 0.5, 3.0, 0);
    let err = max_rel_error(&y, &expected);
    let first_bad = y.iter().zip(&expected).position(|(a, b)| (f64::from(*a) - b).abs() > 1e-6 * b.abs());
    let bad = y.iter().zip(&expected).filter(|(a, b)| (f64::from(**a) - **b).abs() > 1e-6 * b.abs()).count();
    let unwritten = y.iter().filter(|v| v.is_nan()).count();
    let first_unwritten = y.iter().position(|v| v.is_nan());
    assert!(
        err <= 2.0 * f64::from(f32::EPSILON),
        "max relative error {err}: {unwritten} of {n} unwritten (the first at index {first_unwritten:?}), \
         {bad} wrong, the first at index {first_bad:?} (byte offset {:?}): {:?} instead of {:?}",
        first_bad.map(|i| 4 * i as u64),
        first_bad.map(|i| y[i]),
        first_bad.map(|i| expected[i])
    );
    assert_no_validation_messages(&d);
}

#[test]
fn timestamps_time_each_stage() {
    let d = device();
    if d.info().timestamp_valid_bits == 0 {
        eprintln!("skipped: the device has no timestamps on its compute queue");
        return;
    }
    let n = 1 << 20;
    let x = vec![1.0f32; n];
    let input = d.upload("x", &x).unwrap();
    let output = d.create_filled::<f32>("y", n, NAN).unwrap();
    let k0 = affine_kernel(&d, 0).unwrap();
    let k1 = affine_kernel(&d, 1).unwrap();
    let push = AffinePush { a: 1.0, b: 1.0, count: n as u32, pad: 0 };
    let timings = d
        .run(|rec| {
            rec.begin_stage("first");
            rec.dispatch(&k0, Grid::Items(n as u64), &[Binding::from(&input), Binding::from(&output)], &push)?;
            rec.begin_stage("second");
            for _ in 0..4 {
                rec.dispatch(&k1, Grid::Items(n as u64), &[Binding::from(&input), Binding::from(&output)], &push)?;
            }
            rec.end_stage();
            rec.fill(&output, 0)
        })
        .unwrap();
    let names: Vec<&str> = timings.stages.iter().map(|s| s.name.as_str()).collect();
    assert_eq!(names, ["first", "second"]);
    for s in &timings.stages {
        assert!(s.seconds > 0.0 && s.seconds < 60.0, "{}: {} s", s.name, s.seconds);
    }
    assert_eq!(timings.get("missing"), None);
    assert!((timings.total_seconds() - timings.stages.iter().map(|s| s.seconds).sum::<f64>()).abs() < 1e-12);
    assert_no_validation_messages(&d);
}

#[test]
fn memory_accounting_and_deferred_destruction() {
    let d = device();
    d.wait_idle().unwrap();
    let before = d.memory_usage();
    d.reset_peak_memory();
    let n = 1 << 22;
    let x = vec![2.0f32; n];
    let input = d.upload("x", &x).unwrap();
    let output = d.create_filled::<f32>("y", n, NAN).unwrap();
    let during = d.memory_usage();
    assert!(during.current_bytes >= before.current_bytes + 2 * 4 * n as u64, "{before:?} -> {during:?}");
    assert!(during.peak_bytes >= during.current_bytes);

    // Submit, drop both buffers while the GPU may still run, then wait: the
    // buffers must outlive the work (validation would report a use after free).
    let kernel = affine_kernel(&d, 1).unwrap();
    let mut rec = d.begin().unwrap();
    rec.dispatch(
        &kernel,
        Grid::Items(n as u64),
        &[Binding::from(&input), Binding::from(&output)],
        &AffinePush { a: 1.0, b: 0.0, count: n as u32, pad: 0 },
    )
    .unwrap();
    let submission = d.submit(rec).unwrap();
    drop(input);
    drop(output);
    drop(kernel);
    submission.wait().unwrap();
    d.wait_idle().unwrap();
    let after = d.memory_usage();
    assert_eq!(after.current_bytes, before.current_bytes, "memory not returned");
    assert!(after.peak_bytes >= during.current_bytes);

    // A submission dropped without waiting is cleaned up too.
    let tmp = d.create_filled::<f32>("tmp", 1024, 0).unwrap();
    let mut rec = d.begin().unwrap();
    rec.fill(&tmp, 1).unwrap();
    drop(d.submit(rec).unwrap());
    drop(tmp);
    d.wait_idle().unwrap();
    assert_eq!(d.memory_usage().current_bytes, before.current_bytes);
    assert_no_validation_messages(&d);
}

#[test]
fn freed_buffers_are_pooled_and_taken_by_the_next_of_their_kind_and_size() {
    let d = device();
    d.wait_idle().unwrap();
    // A high-water mark above everything below, so no buffer here is freed to stay under it.
    drop(d.create_buffer("high water", 64 << 20, MemoryKind::Storage).unwrap());
    d.wait_idle().unwrap();
    d.release_pooled_memory();
    let n = 1usize << 20;
    drop(d.create_filled::<f32>("first", n, NAN).unwrap());
    d.wait_idle().unwrap();
    let pooled = d.memory_usage().pooled_bytes;
    assert!(pooled >= 4 * n as u64, "a freed 4 MiB storage buffer is kept: {pooled} bytes pooled");

    // A storage buffer an eighth smaller takes it (a quarter larger at most):
    // a kernel over its asked-for size, validation on, computes as on fresh memory.
    let m = n - n / 8;
    let x: Vec<f32> = (0..m).map(|i| i as f32 * 0.25).collect();
    let fresh = d.memory_usage().fresh_allocations;
    let input = d.create_buffer("input", 4 * m as u64, MemoryKind::Storage).unwrap();
    let taken = pooled - d.memory_usage().pooled_bytes;
    assert!(taken >= 4 * n as u64, "it took the pooled buffer ({taken} bytes taken)");
    assert_eq!(d.memory_usage().fresh_allocations, fresh, "a pooled buffer taken is no fresh allocation");
    d.write_buffer(&input, 0, &x).unwrap();
    let output = d.create_filled::<f32>("output", m, NAN).unwrap();
    let kernel = affine_kernel(&d, 0).unwrap();
    let mut rec = d.begin().unwrap();
    rec.dispatch(
        &kernel,
        Grid::Items(m as u64),
        &[Binding::from(&input), Binding::from(&output)],
        &AffinePush { a: 2.0, b: 1.0, count: m as u32, pad: 0 },
    )
    .unwrap();
    d.submit(rec).unwrap().wait().unwrap();
    let y: Vec<f32> = d.read_buffer(&output).unwrap();
    assert_eq!(y.len(), m);
    assert_eq!(max_rel_error(&y, &affine_cpu(&x, 2.0, 1.0, 0)), 0.0);

    // Half the size, or another kind, takes nothing; release frees what is kept.
    d.wait_idle().unwrap();
    let before = d.memory_usage().pooled_bytes;
    drop(input);
    d.wait_idle().unwrap();
    let kept = d.memory_usage().pooled_bytes;
    assert!(kept >= before + 4 * m as u64);
    let fresh = d.memory_usage().fresh_allocations;
    let small = d.create_buffer("small", 2 * n as u64, MemoryKind::Storage).unwrap();
    // The only pooled buffer of this size is the storage one.
    let staging = d.create_buffer("staging", 4 * n as u64, MemoryKind::Upload).unwrap();
    assert_eq!(d.memory_usage().pooled_bytes, kept, "neither takes the pooled storage buffer");
    assert_eq!(d.memory_usage().fresh_allocations, fresh + 2, "both took new memory");
    drop((small, staging, output));
    d.wait_idle().unwrap();
    let released = d.release_pooled_memory();
    assert!(released >= kept, "{released} of {kept} bytes released");
    assert_eq!(d.memory_usage().pooled_bytes, 0);
    assert_no_validation_messages(&d);
}

/// Bytes the pool gains when `buffer` is dropped (its size as `MemoryUsage::pooled_bytes` counts it).
fn pooled_after_dropping(d: &Device, buffer: Buffer) -> u64 {
    let before = d.memory_usage().pooled_bytes;
    drop(buffer);
    d.wait_idle().unwrap();
    d.memory_usage().pooled_bytes - before
}

#[test]
fn pooled_and_in_use_memory_stay_within_the_most_ever_in_use() {
    let d = device();
    d.wait_idle().unwrap();
    d.release_pooled_memory();
    let mib = 1u64 << 20;
    let storage = |name: &str, bytes: u64| d.create_buffer(name, bytes, MemoryKind::Storage).unwrap();
    let held = |d: &Device| {
        let m = d.memory_usage();
        m.current_bytes + m.pooled_bytes
    };

    // 8 MiB in use at once, then pooled: the 6 MiB one is taken again.
    let (big, small) = (storage("big", 6 * mib), storage("small", 2 * mib));
    let most = held(&d);
    let kept_big = pooled_after_dropping(&d, big);
    let kept_small = pooled_after_dropping(&d, small);
    assert!(kept_big >= 6 * mib && kept_small >= 2 * mib);
    let again = storage("again", 6 * mib);
    assert_eq!(d.memory_usage().pooled_bytes, kept_small, "the 6 MiB one is taken again");

    // A fresh buffer that would take in use and pooled past the busiest
    // moment frees the oldest pooled buffer first.
    let other = storage("other", mib / 2);
    assert_eq!(d.memory_usage().pooled_bytes, 0, "the 2 MiB one is freed for the 0.5 MiB one");
    assert!(held(&d) <= most, "{} bytes held, {most} at most", held(&d));

    // Within it, the pool stays.
    let kept_again = pooled_after_dropping(&d, again);
    let one = storage("one", mib);
    assert_eq!(d.memory_usage().pooled_bytes, kept_again, "1.5 + 6 MiB stay within 8");
    assert!(held(&d) <= most, "{} bytes held, {most} at most", held(&d));

    // More than ever in use at once (1.5 + 9 MiB): what is pooled is freed
    // first, not held beside the larger work.
    let larger = storage("larger", 9 * mib);
    assert_eq!(d.memory_usage().pooled_bytes, 0, "the pool is emptied before the new high");
    let m = d.memory_usage();
    assert!(m.current_bytes >= 9 * mib + 3 * mib / 2, "{m:?}");

    // Staging buffers of several sizes, as a streamed load writes each
    // attribute of a block, stay pooled at the mark (within the headroom).
    let staging = |name: &str, bytes: u64| d.create_buffer(name, bytes, MemoryKind::Upload).unwrap();
    let kept_a = pooled_after_dropping(&d, staging("staging a", 2 * mib));
    let kept_b = pooled_after_dropping(&d, staging("staging b", mib));
    assert!(POOL_HEADROOM_BYTES >= 2 * mib);
    assert!(d.memory_usage().pooled_bytes >= kept_a + kept_b, "both staging buffers stay pooled");
    drop((larger, other, one));
    d.wait_idle().unwrap();
    assert!(d.memory_usage().pooled_bytes >= 9 * mib, "freed buffers are pooled again");
    assert_no_validation_messages(&d);
}

#[test]
fn device_selection() {
    assert_eq!(DeviceSelection::parse("2"), DeviceSelection::Index(2));
    assert_eq!(DeviceSelection::parse("GPU"), DeviceSelection::Gpu);
    assert_eq!(DeviceSelection::parse(" cpu "), DeviceSelection::Cpu);
    assert_eq!(DeviceSelection::parse(""), DeviceSelection::Auto);
    assert_eq!(DeviceSelection::parse("llvmpipe"), DeviceSelection::Name("llvmpipe".into()));

    let adapters = Device::list().unwrap();
    assert!(!adapters.is_empty());
    // Picking the first listed device by name and by index gives that device.
    let first = &adapters[0];
    for sel in [DeviceSelection::Index(0), DeviceSelection::Name(first.name.to_uppercase())] {
        let d = Device::new(&DeviceOptions { selection: Some(sel), validation: Some(true) }).unwrap();
        assert_eq!(d.info().name, first.name);
        assert!(d.info().subgroup_size >= 1);
        assert_no_validation_messages(&d);
    }
    for sel in [DeviceSelection::Index(adapters.len()), DeviceSelection::Name("no such device, surely".into())] {
        match Device::new(&DeviceOptions { selection: Some(sel.clone()), validation: Some(false) }) {
            Err(Error::NoDevice(m)) => assert!(m.contains(&first.name), "the error lists the devices: {m}"),
            other => panic!("{sel:?}: expected NoDevice, got {other:?}"),
        }
    }
}

#[test]
fn grid_1d_covers_every_invocation() {
    let limits = [65_535, 65_535, 65_535];
    assert_eq!(gpu::grid_1d(0, 64, limits), Some([0, 1, 1]));
    assert_eq!(gpu::grid_1d(1, 64, limits), Some([1, 1, 1]));
    assert_eq!(gpu::grid_1d(64 * 65_535, 64, limits), Some([65_535, 1, 1]));
    assert_eq!(gpu::grid_1d(64 * 65_535 + 1, 64, limits), Some([32_768, 2, 1]));
    // Past one row the rows are even: under one spare group per row.
    for count in [1u64, 63, 64, 65, 10_000_000, 64 * 65_535 * 3 + 1, 1 << 32] {
        let [x, y, _] = gpu::grid_1d(count, 64, limits).unwrap();
        let (groups, covered) = (count.div_ceil(64), u64::from(x) * u64::from(y));
        assert!(x <= limits[0] && y <= limits[1], "{count}: {x}x{y}");
        assert!(covered >= groups && covered - groups < u64::from(y), "{count}: {x}x{y}");
    }
    assert_eq!(gpu::grid_1d(u64::MAX / 2, 64, limits), None);
}

#[test]
fn impossible_allocations_are_errors() {
    // Validation off: exceeding the heap is what this test does on purpose.
    let d = Device::new(&DeviceOptions { selection: None, validation: Some(false) }).unwrap();
    match d.create_buffer("too big", 1 << 44, MemoryKind::Storage) {
        Err(Error::OutOfMemory(m)) => assert!(m.contains("too big"), "{m}"),
        other => panic!("expected out-of-memory, got {other:?}"),
    }
    // The device still works afterwards.
    assert!(selftest::run(&d, 1000).unwrap().passed());
    assert_eq!(d.memory_usage().current_bytes, 0);
    let n = usize::MAX / 2;
    assert!(matches!(d.create_filled::<[f32; 4]>("overflow", n, 0), Err(Error::InvalidArgument { .. })));
}

#[test]
fn texel_buffer_views() {
    let d = device();
    let info = d.info().clone();
    assert!(info.texel_formats.contains(&TexelFormat::R32Float), "R32F uniform texel buffers are mandatory in Vulkan");
    assert_eq!(
        kernels::CORE_TEXEL_COPY.bindings[0].kind,
        BindingKind::UniformTexelBuffer,
        "the build script reflects textureBuffer"
    );
    let decl = KernelDecl {
        bindings: &[BindingKind::UniformTexelBuffer, BindingKind::StorageBuffer { read_only: false }],
        push_constant_size: 4,
        specialization: &[],
    };
    let copy = Kernel::new(&d, &kernels::CORE_TEXEL_COPY, &decl).unwrap();
    let align = info.min_texel_buffer_offset_alignment;
    println!(
        "maxTexelBufferElements {}, minTexelBufferOffsetAlignment {align}, formats {:?}",
        info.max_texel_buffer_elements, info.texel_formats
    );
    let n = 1000usize;
    // The views start `align` elements in: byte offsets of 4·align (fp32) and 2·align (fp16).
    let first = align as usize;
    let values: Vec<f32> = (0..n + first).map(|i| (i as f32 - 400.25) * 0.37).collect();
    let out = d.create_buffer("copy", (n * 4) as u64, MemoryKind::Storage).unwrap();
    let mut cases = vec![(TexelFormat::R32Float, d.upload("fp32", &values).unwrap())];
    if info.texel_formats.contains(&TexelFormat::R16Float) {
        let halves: Vec<u16> = values.iter().map(|v| half::f16::from_f32(*v).to_bits()).collect();
        cases.push((TexelFormat::R16Float, d.upload("fp16", &halves).unwrap()));
    }
    for (format, buffer) in &cases {
        let view = Texels { buffer, offset: first as u64 * format.bytes(), elements: n as u64, format: *format };
        d.run(|rec| rec.fill(&out, NAN)).unwrap();
        d.run(|rec| {
            rec.dispatch(&copy, Grid::Exact(grid(n)), &[Binding::Texels(view), Binding::Buffer(&out)], &(n as u32))
        })
        .unwrap();
        let got: Vec<f32> = d.read_buffer(&out).unwrap();
        // The twin: the element itself, rounded to fp16 for an R16F view.
        let want: Vec<f32> = values[first..first + n]
            .iter()
            .map(|v| if *format == TexelFormat::R16Float { half::f16::from_f32(*v).to_f32() } else { *v })
            .collect();
        let bad = got.iter().zip(&want).filter(|(a, b)| a.to_bits() != b.to_bits()).count();
        assert_eq!(
            bad, 0,
            "{format:?} view at element {first}: {bad} of {n} differ (first got {}, want {})",
            got[0], want[0]
        );
    }

    // Misuse is a clear error, before anything is recorded.
    let (_, buffer) = &cases[0];
    let expect = |bindings: &[Binding<'_>], needle: &str| {
        let mut rec = d.begin().unwrap();
        match rec.dispatch(&copy, Grid::Exact(grid(n)), bindings, &(n as u32)) {
            Err(Error::Kernel { message, .. }) => assert!(message.contains(needle), "{needle}: {message}"),
            other => panic!("expected an error containing {needle}, got {other:?}"),
        }
    };
    let view = |offset: u64, elements: u64| Texels { buffer, offset, elements, format: TexelFormat::R32Float };
    if align > 1 {
        expect(&[Binding::Texels(view(align / 2, 4)), Binding::Buffer(&out)], "minTexelBufferOffsetAlignment");
    }
    expect(
        &[Binding::Texels(view(0, info.max_texel_buffer_elements + 1)), Binding::Buffer(&out)],
        "maxTexelBufferElements",
    );
    expect(&[Binding::Texels(view(0, buffer.size() / 4 + 1)), Binding::Buffer(&out)], "overrun");
    expect(&[Binding::Buffer(buffer), Binding::Buffer(&out)], "is a texel buffer");
    expect(&[Binding::Texels(view(0, 4)), Binding::Texels(view(0, 4))], "buffer block");
    assert_no_validation_messages(&d);
}

fn grid(n: usize) -> [u32; 3] {
    [n.div_ceil(64) as u32, 1, 1]
}

/// Host push-constant structs match the blocks their shaders declare, and the
/// check fails on a struct that does not.
#[test]
fn host_layouts_match_their_glsl_blocks() {
    // Block names repeat across kernels ("Push"): check against the kernels a struct serves.
    assert_eq!(gpu::check_layout::<AffinePush>(&[&kernels::CORE_AFFINE]), Ok(1));
    assert_eq!(gpu::check_layout::<AffineAddressedPush>(kernels::ALL), Ok(1));
    // Fields swapped: same size, wrong offsets.
    #[repr(C)]
    #[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
    struct Swapped {
        b: f32,
        a: f32,
        count: u32,
        pad: u32,
    }
    gpu::gpu_layout!(Swapped, "Push", [b, a, count, pad]);
    let e = gpu::check_layout::<Swapped>(&[&kernels::CORE_AFFINE]).unwrap_err();
    assert!(e.contains("core_affine") && e.contains("does not match"), "{e}");
    // A block name no kernel declares checks nothing.
    #[repr(C)]
    #[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
    struct Orphan {
        a: f32,
    }
    gpu::gpu_layout!(Orphan, "NoSuchBlock", [a]);
    assert_eq!(gpu::check_layout::<Orphan>(kernels::ALL), Ok(0));
}

/// `Recording::update` writes in command order: a fill, an update over part of
/// the buffer, and a copy after it see each other's results.
#[test]
fn recorded_updates_are_ordered_with_other_commands() {
    let d = device();
    let a = d.create_buffer("a", 64, MemoryKind::Storage).unwrap();
    let b = d.create_buffer("b", 64, MemoryKind::Storage).unwrap();
    d.run(|rec| {
        rec.fill(&a, NAN)?;
        rec.update(&a, 16, &[1.0f32, 2.0, 3.0, 4.0])?;
        rec.copy(&a, 0, &b, 0, 64)?;
        rec.update(&b, 60, &5.0f32)?;
        rec.fill_words(&b, 9, 3, 7)
    })
    .unwrap();
    let got: Vec<u32> = d.read_buffer(&b).unwrap();
    let mut want = vec![NAN; 16];
    want[4..8].copy_from_slice(&[1.0f32, 2.0, 3.0, 4.0].map(f32::to_bits));
    want[9..12].copy_from_slice(&[7; 3]);
    want[15] = 5.0f32.to_bits();
    assert_eq!(got, want);
    // Out of bounds, unaligned, empty or over 64 KiB: refused before recording.
    let big = d.create_buffer("big", 1 << 17, MemoryKind::Storage).unwrap();
    let staging = d.create_buffer("staging", 64, MemoryKind::Upload).unwrap();
    let mut rec = d.begin().unwrap();
    assert!(rec.update(&a, 60, &[0u32; 2]).is_err());
    assert!(rec.update(&a, 2, &0u32).is_err());
    assert!(rec.update(&a, 0, &[0u8; 0]).is_err());
    assert!(rec.update_bytes(&big, 0, &vec![0u8; 65540]).is_err());
    assert!(rec.fill_words(&a, 15, 2, 0).is_err(), "past the end");
    assert!(rec.fill_words(&a, 3, 0, 0).is_err(), "no words");
    assert!(rec.fill_words(&a, u64::MAX, 1, 0).is_err(), "an overflowing range");
    // A buffer without a device address (staging) has no address to give.
    assert!(rec.addr(&staging).is_err());
    assert!(rec.addr_or_null(None).unwrap().is_null());
    assert!(!rec.addr(&a).unwrap().is_null());
    assert!(rec.addr_at(&a, 64).is_ok(), "the end (an empty region) is valid");
    assert!(rec.addr_at(&a, 65).is_err(), "past the end");
    drop(rec);
    assert_no_validation_messages(&d);
}

/// `Device::kernel` builds a variant once and shares it; other specializations
/// are other kernels; the cache lets go of its kernels when the last device
/// handle drops.
#[test]
fn kernel_cache_shares_variants_and_lets_go_with_the_device() {
    let d = device();
    let decl = |mode: &'static [(u32, SpecValue)]| KernelDecl {
        bindings: &AFFINE_BINDINGS,
        push_constant_size: std::mem::size_of::<AffinePush>(),
        specialization: mode,
    };
    const LINEAR: &[(u32, SpecValue)] = &[(0, SpecValue::U32(0))];
    const SQUARE: &[(u32, SpecValue)] = &[(0, SpecValue::U32(1))];
    let a = d.kernel(&kernels::CORE_AFFINE, &decl(LINEAR)).unwrap();
    let b = d.clone().kernel(&kernels::CORE_AFFINE, &decl(LINEAR)).unwrap();
    assert!(std::sync::Arc::ptr_eq(&a, &b), "the same variant is built once");
    let c = d.kernel(&kernels::CORE_AFFINE, &decl(SQUARE)).unwrap();
    assert!(!std::sync::Arc::ptr_eq(&a, &c));
    assert_eq!(d.cached_kernels(), 2);
    // A declaration the SPIR-V refuses is an error, and nothing is cached.
    let bad = KernelDecl { bindings: &AFFINE_BINDINGS[..1], push_constant_size: 16, specialization: LINEAR };
    assert!(matches!(d.kernel(&kernels::CORE_AFFINE, &bad), Err(Error::Kernel { .. })));
    assert_eq!(d.cached_kernels(), 2);
    assert_no_validation_messages(&d);
    drop(b);
    assert_eq!(std::sync::Arc::strong_count(&a), 2, "the cache holds one reference");
    drop(d);
    assert_eq!(std::sync::Arc::strong_count(&a), 1, "dropping the device empties the cache");
}
