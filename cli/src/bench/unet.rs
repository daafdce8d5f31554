//! `srug bench unet`: one inference of the indirect-light U-Net (random
//! weights of the given widths, 14 input channels) per image size, storage
//! precision and conv path (direct convolution reading inputs through
//! texel-buffer views or by device address, or Winograd F(4×4, 3×3) or
//! F(2×2, 3×3) for the stride-1 layers),
//! per-layer GPU times, and achieved GFLOP/s against the FMA peak
//! measured in the same run.

use super::median;
use srug::error::Result;
use srug::gpu::Device;
use srug::indirect::{ConvPath, StoragePrecision, UNet, UNetConfig, UNetWeights};

/// One (size, precision, path) row.
#[derive(Clone, Debug)]
pub struct UNetRow {
    /// Image size.
    pub size: (u32, u32),
    /// Storage precision label.
    pub precision: &'static str,
    /// How the conv layers ran.
    pub path: ConvPath,
    /// Median seconds per inference.
    pub seconds: f64,
    /// Minimum seconds per inference.
    pub min_seconds: f64,
    /// Flops of one inference (2 per multiply-add).
    pub flops: f64,
    /// Per-layer median seconds, in execution order.
    pub layers: Vec<(String, f64)>,
    /// Activation arena bytes.
    pub arena_bytes: u64,
}

/// The benchmark's network input: uniform in [0, 1) from a fixed seed, so every
/// run and every path sees the same values, and the activations vary like a
/// real G-buffer's rather than being one constant per layer.
fn bench_input(len: usize) -> Vec<f32> {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(7);
    (0..len).map(|_| rng.random_range(0.0..1.0)).collect()
}

/// Runs the benchmark.
pub fn unet_bench(
    device: &Device,
    widths: [usize; 5],
    sizes: &[(u32, u32)],
    paths: &[ConvPath],
    repeats: usize,
    progress: impl Fn(&str),
) -> Result<Vec<UNetRow>> {
    let weights = UNetWeights::random(UNetConfig { widths, ..UNetConfig::default() }, 1);
    let mut precisions = vec![StoragePrecision::Fp32];
    if device.info().storage_16bit {
        precisions.push(StoragePrecision::Fp16);
    }
    let mut rows = Vec::new();
    for &(w, h) in sizes {
        // No paths given: each precision's default on this device.
        let runs: Vec<_> = if paths.is_empty() {
            precisions
                .iter()
                .map(|&p| Ok((p, UNet::with_precision(device, &weights, p)?.conv_path())))
                .collect::<Result<_>>()?
        } else {
            precisions.iter().flat_map(|&p| paths.iter().map(move |&t| (p, t))).collect()
        };
        for (precision, path) in runs {
            let mut net = UNet::with_precision(device, &weights, precision)?;
            net.set_texel_inputs(path != ConvPath::Address)?;
            net.set_winograd(path.winograd())?;
            net.set_vec4_inputs(path == ConvPath::Vec4 || path.winograd().is_some())?;
            progress(&format!("U-Net at {w}x{h}, {precision:?}, {} convolution", path.label()));
            let input = device.upload("u-net input", &bench_input(14 * (w * h) as usize))?;
            net.infer(&input, w, h)?;
            let mut totals = Vec::new();
            let mut per_layer: Vec<(String, Vec<f64>)> = Vec::new();
            for _ in 0..repeats.max(1) {
                let out = net.infer(&input, w, h)?;
                totals.push(out.timings.total_seconds());
                for (i, s) in out.timings.stages.iter().enumerate() {
                    if per_layer.len() <= i {
                        per_layer.push((s.name.clone(), Vec::new()));
                    }
                    per_layer[i].1.push(s.seconds);
                }
            }
            let min_seconds = totals.iter().copied().fold(f64::INFINITY, f64::min);
            rows.push(UNetRow {
                size: (w, h),
                precision: if precision == StoragePrecision::Fp16 { "fp16" } else { "fp32" },
                path,
                seconds: median(totals),
                min_seconds,
                flops: weights.flops(w as usize, h as usize),
                layers: per_layer.into_iter().map(|(n, v)| (n, median(v))).collect(),
                arena_bytes: net.arena_bytes(w, h),
            });
        }
    }
    Ok(rows)
}
