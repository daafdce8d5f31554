//! Benchmarks of the Vulkan core, scene activation and splatting: staged
//! upload and readback throughput, activation time against Gaussian count,
//! and a whole splat frame of the demo city. `cargo bench -p srug-benches --bench core`.
//! Per-stage GPU times come from `srug bench splat`.

#![allow(clippy::unwrap_used, clippy::expect_used, reason = "a benchmark that cannot set up should stop loudly")]

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use srug::gpu::{Device, DeviceOptions};
use srug::scene::activate::{activate, activate_kernel, GpuScene};
use srug::scene::demo::{demo_city, DemoOptions};
use srug::splat::{SplatSettings, Splatter};

fn transfers(c: &mut Criterion) {
    let device = Device::new(&DeviceOptions::default()).expect("a Vulkan device");
    let mut group = c.benchmark_group("transfer");
    group.sample_size(10);
    for mib in [16usize, 256] {
        let data = vec![1.5f32; mib << 18];
        let buffer = device.upload("bench", &data).unwrap();
        group.throughput(Throughput::Bytes((mib << 20) as u64));
        group.bench_with_input(BenchmarkId::new("upload", format!("{mib} MiB")), &data, |b, data| {
            b.iter(|| device.write_buffer(&buffer, 0, data).unwrap());
        });
        group.bench_with_input(BenchmarkId::new("readback", format!("{mib} MiB")), &buffer, |b, buffer| {
            b.iter(|| device.read_buffer::<f32>(buffer).unwrap());
        });
    }
    group.finish();
}

fn activation(c: &mut Criterion) {
    let device = Device::new(&DeviceOptions::default()).expect("a Vulkan device");
    let kernel = activate_kernel(&device).unwrap();
    let mut group = c.benchmark_group("activate");
    group.sample_size(10);
    for n in [10_000usize, 300_000, 3_000_000] {
        let city = demo_city(&DemoOptions { seed: 1, gaussians: n, sh_degree: 0 }).unwrap();
        let scene = GpuScene::upload(&device, &city.scene).unwrap();
        group.throughput(Throughput::Elements(n as u64));
        group.bench_with_input(BenchmarkId::from_parameter(n), &scene, |b, scene| {
            b.iter(|| activate(&device, &kernel, scene).unwrap());
        });
    }
    group.finish();
}

fn splat(c: &mut Criterion) {
    let device = Device::new(&DeviceOptions::default()).expect("a Vulkan device");
    let mut splatter = Splatter::new(&device).unwrap();
    let mut group = c.benchmark_group("splat frame");
    group.sample_size(10);
    for n in [100_000usize, 1_000_000] {
        let city = demo_city(&DemoOptions { seed: 7, gaussians: n, sh_degree: 1 }).unwrap();
        let scene = GpuScene::upload(&device, &city.scene).unwrap();
        for (w, h) in [(704u32, 192u32), (1408, 384)] {
            let cam = city.cameras[0].resized(w, h);
            group.throughput(Throughput::Elements(n as u64));
            group.bench_function(BenchmarkId::new(format!("{n}"), format!("{w}x{h}")), |b| {
                b.iter(|| splatter.render(&scene, &cam, &SplatSettings::default()).unwrap());
            });
        }
    }
    group.finish();
}

#[allow(missing_docs, reason = "criterion_group! generates an undocumented function")]
mod group {
    use super::*;
    criterion_group!(benches, transfers, activation, splat);
}
criterion_main!(group::benches);
