//! The indirect-light U-Net against its CPU twin (f64 accumulation): random
//! weights at odd and tiny sizes, widths 8 to 128, both align_corners
//! conventions and every activation, on every conv path (direct with texel or
//! device-address inputs, Winograd F(4×4) (on CPU devices) and F(2×2)), and at widths that are multiples of 4
//! with four pixels per texel fetch; zero weights; activations of 1e4; the
//! Winograd twins (both tiles) against direct convolution; and the safetensors loader's
//! errors. Outputs and the arena are pre-filled
//! with NaN, so a value no kernel wrote fails.

#![allow(clippy::unwrap_used, clippy::expect_used, reason = "a failed unwrap is a failed test")]

use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;
use srug::gpu::Device;
use srug::indirect::cpu::{conv3x3_cpu, unet_cpu, unet_cpu_stored, winograd_conv3x3_cpu, Tensor};
use srug::indirect::ConvPath;
use srug::indirect::WinogradTile;
use srug::indirect::{Activation, StoragePrecision, UNet, UNetConfig, UNetWeights};
use srug_tests::{assert_no_validation_messages, device};

const NAN: u32 = srug_tests::NAN_SENTINEL;

const PATHS: [ConvPath; 4] = [ConvPath::Texel, ConvPath::Address, ConvPath::Winograd, ConvPath::Winograd2];

/// Whether Winograd F(4×4) is tested on `d`: where it is the default (CPU devices). On
/// GPUs NVIDIA's compiler spent minutes on each of its pipelines (an H100 and an H200,
/// docs/bench/gpu.md), so there the tests take the other paths and say so.
fn tests_winograd_4x4(d: &Device) -> bool {
    let on = ConvPath::default_for(d.info().device_type, true) == ConvPath::Winograd;
    if !on {
        println!("Winograd F(4×4) left out: not the default on this {:?} device", d.info().device_type);
    }
    on
}

/// The conv paths tested on `d` ([`PATHS`], less Winograd F(4×4) where [`tests_winograd_4x4`] says).
fn paths(d: &Device) -> Vec<ConvPath> {
    let wino4 = tests_winograd_4x4(d);
    PATHS.into_iter().filter(|p| wino4 || *p != ConvPath::Winograd).collect()
}

fn run(d: &Device, weights: &UNetWeights, w: usize, h: usize, scale: f32, seed: u64) -> (Vec<f32>, Tensor) {
    let (gpu, cpu, _) = run_with(d, weights, (w, h), scale, seed, StoragePrecision::Fp32, ConvPath::Texel);
    (gpu, cpu)
}

/// GPU output, the f64 twin, and the twin with fp16-rounded stored activations.
fn run_with(
    d: &Device,
    weights: &UNetWeights,
    (w, h): (usize, usize),
    scale: f32,
    seed: u64,
    precision: StoragePrecision,
    path: ConvPath,
) -> (Vec<f32>, Tensor, Tensor) {
    let mut rng = Pcg64Mcg::seed_from_u64(seed);
    let c = weights.config.in_channels;
    let input: Vec<f32> = (0..c * w * h).map(|_| rng.random_range(-1.0..1.0f32) * scale).collect();
    let buffer = d.upload("input", &input).unwrap();
    let mut net = UNet::with_precision(d, weights, precision).unwrap();
    net.set_prefill(Some(NAN));
    net.set_texel_inputs(path != ConvPath::Address).unwrap();
    net.set_winograd(path.winograd()).unwrap();
    assert_eq!(net.winograd(), path.winograd());
    net.set_vec4_inputs(path == ConvPath::Vec4).unwrap();
    let out = net.infer(&buffer, w as u32, h as u32).unwrap();
    if path != ConvPath::Vec4 {
        assert!(out.vec4_layers.is_empty(), "{path:?} read four pixels per fetch in {:?}", out.vec4_layers);
    }
    let gpu: Vec<f32> = d.read_buffer(&out.output).unwrap();
    let x = Tensor::from_f32(c, w, h, &input);
    (gpu, unet_cpu(weights, &x), unet_cpu_stored(weights, &x, true))
}

fn max_abs(gpu: &[f32], cpu: &Tensor) -> f64 {
    assert_eq!(gpu.len(), cpu.data.len());
    assert!(gpu.iter().all(|v| v.is_finite()), "non-finite output (NaN sentinel left or overflow)");
    gpu.iter().zip(&cpu.data).map(|(a, b)| (f64::from(*a) - b).abs()).fold(0.0, f64::max)
}

#[test]
fn unet_matches_twin_at_odd_and_tiny_sizes() {
    let d = device();
    let cases = [
        ([32usize, 32, 64, 64, 128], Activation::Relu, false, 37usize, 23usize),
        ([8, 16, 32, 64, 128], Activation::LeakyRelu, true, 37, 23),
        ([8, 8, 8, 8, 8], Activation::Relu, true, 1, 1),
        ([8, 8, 16, 16, 16], Activation::None, false, 2, 2),
        ([12, 20, 24, 40, 48], Activation::Relu, false, 17, 5),
    ];
    // Every conv path: texel-buffer views (the default here), device addresses, both Winograd tiles.
    let paths = paths(&d);
    for ((widths, activation, align_corners, w, h), path) in
        cases.into_iter().flat_map(|c| paths.iter().map(move |p| (c, *p)))
    {
        let config = UNetConfig { widths, activation, align_corners, ..UNetConfig::default() };
        let weights = UNetWeights::random(config, 3);
        let (gpu, cpu, _) = run_with(&d, &weights, (w, h), 1.0, 7, StoragePrecision::Fp32, path);
        let err = max_abs(&gpu, &cpu);
        let peak = cpu.data.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        println!("widths {widths:?} {activation:?} align_corners {align_corners} at {w}x{h}, {path:?}: max |GPU − CPU| {err:.2e} (outputs up to {peak:.2})");
        assert!(err <= 1e-4, "fp32 U-Net differs from the twin by {err:e} (tolerance 1e-4)");
        assert!(peak > 1e-3, "the outputs are all ~0: the check would prove nothing");
    }
    let net = UNet::new(&d, &UNetWeights::random(UNetConfig::default(), 1)).unwrap();
    assert!(net.texel_inputs(), "lavapipe (and every GPU tried) reads R32F texel buffers: a texel path is the default");
    let default = ConvPath::default_for(d.info().device_type, true);
    assert_eq!(net.conv_path(), default, "Winograd F(4×4) on CPU devices, direct texel convolution on GPUs");
    assert_no_validation_messages(&d);
}

#[test]
fn shared_weight_fetches_give_the_same_bits() {
    // Each lane of a subgroup fetches its share of a weight block and the
    // subgroup broadcasts them (the default on lavapipe from Mesa 25): the
    // same weights in the same sums, so the same output bit for bit, for the
    // Winograd kernels at both tiles and the direct texel kernels with one
    // and four pixels per fetch, at both precisions, also where a layer's
    // edge is partial (37×23; 40×24 has layers four pixels per fetch can read).
    let d = device();
    let info = d.info();
    let mesa_25 = info.is_lavapipe() && info.mesa_version().is_some_and(|(major, _)| major >= 25);
    let config = UNetConfig { widths: [8, 16, 32, 64, 128], ..UNetConfig::default() };
    let channels = config.in_channels;
    let weights = UNetWeights::random(config, 5);
    let mut rng = Pcg64Mcg::seed_from_u64(11);
    let mut tiles = vec![Some(WinogradTile::F2x2)];
    if tests_winograd_4x4(&d) {
        tiles.push(Some(WinogradTile::F4x4));
    }
    // The Winograd tiles with the device's default fetches, then direct convolution of every
    // layer (no Winograd), one pixel per fetch, then four.
    let paths: Vec<(Option<WinogradTile>, Option<bool>)> =
        tiles.into_iter().map(|t| (t, None)).chain([(None, Some(false)), (None, Some(true))]).collect();
    if !(info.subgroup_ballot && 64 % info.subgroup_size == 0) {
        eprintln!("skipping: subgroup size {} or no subgroup broadcast", info.subgroup_size);
        return;
    }
    for precision in [StoragePrecision::Fp32, StoragePrecision::Fp16] {
        if precision == StoragePrecision::Fp16 && !info.storage_16bit {
            continue;
        }
        let mut net = UNet::with_precision(&d, &weights, precision).unwrap();
        let expected = if mesa_25 { info.subgroup_size } else { 0 };
        assert_eq!(net.weight_fetch_lanes(), expected, "default on {}", info.driver);
        net.set_prefill(Some(NAN));
        let default_vec4 = net.vec4_inputs();
        for &(tile, vec4) in &paths {
            net.set_winograd(tile).unwrap();
            if vec4 == Some(true) && net.set_vec4_inputs(true).is_err() {
                eprintln!("no four-pixel fetches on {}: that path is left out", info.driver);
                continue;
            }
            net.set_vec4_inputs(vec4.unwrap_or(default_vec4)).unwrap();
            if let Some(vec4) = vec4 {
                assert_eq!(net.conv_path(), if vec4 { ConvPath::Vec4 } else { ConvPath::Texel });
            }
            for (w, h) in [(37u32, 23u32), (40, 24)] {
                let input: Vec<f32> =
                    (0..channels * (w * h) as usize).map(|_| rng.random_range(-1.0..1.0f32)).collect();
                let buffer = d.upload("input", &input).unwrap();
                let mut outputs = Vec::new();
                for on in [false, true] {
                    net.set_shared_weight_fetches(on).unwrap();
                    assert_eq!(net.weight_fetch_lanes(), if on { info.subgroup_size } else { 0 });
                    let out = net.infer(&buffer, w, h).unwrap();
                    outputs.push(d.read_buffer::<f32>(&out.output).unwrap());
                }
                assert!(outputs[0].iter().all(|v| v.is_finite()) && outputs[0].iter().any(|v| v.abs() > 1e-3));
                let bits = |o: &[f32]| o.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
                assert_eq!(
                    bits(&outputs[0]),
                    bits(&outputs[1]),
                    "{tile:?} vec4 {vec4:?} {precision:?} {w}x{h}: shared weight fetches changed the output"
                );
            }
        }
    }
    assert_no_validation_messages(&d);
}

#[test]
fn default_conv_path_follows_the_device_type() {
    use srug::gpu::ash::vk::PhysicalDeviceType as T;
    // Winograd where LLVM compiles it (lavapipe); direct texel convolution on GPUs, where
    // NVIDIA's compiler did not build the Winograd F(4×4) kernel within a minute (docs/bench/unet.md).
    assert_eq!(ConvPath::default_for(T::CPU, true), ConvPath::Winograd);
    for gpu in [T::DISCRETE_GPU, T::INTEGRATED_GPU, T::VIRTUAL_GPU, T::OTHER] {
        assert_eq!(ConvPath::default_for(gpu, true), ConvPath::Texel, "{gpu:?}");
        assert_eq!(ConvPath::default_for(gpu, false), ConvPath::Address, "{gpu:?}");
    }
    assert_eq!(ConvPath::default_for(T::CPU, false), ConvPath::Address);
    assert!(ConvPath::Winograd.vec4() && ConvPath::Vec4.vec4() && !ConvPath::Texel.vec4() && !ConvPath::Address.vec4());
}

/// The layers that read four pixels per fetch at `w`×`h`: those whose input
/// width (the level it reads) is a multiple of 4.
fn expected_vec4_layers(w: usize, h: usize) -> Vec<&'static str> {
    let levels = srug::indirect::level_sizes(w, h);
    // Input level of inc, down1..down4, up1..up4, outc.
    let input_level = [0, 0, 1, 2, 3, 3, 2, 1, 0, 0];
    let names = ["inc", "down1", "down2", "down3", "down4", "up1", "up2", "up3", "up4", "outc"];
    names.iter().zip(input_level).filter(|(_, l)| levels[*l].0 % 4 == 0).map(|(n, _)| *n).collect()
}

/// The up layers whose resize is exactly 2× from a source width that is a multiple of 4 (align_corners false).
fn expected_exact_resizes(w: usize, h: usize, align_corners: bool) -> Vec<&'static str> {
    let s = srug::indirect::level_sizes(w, h);
    let names = ["up1", "up2", "up3", "up4"];
    // up1 resizes level 4 to level 3, …, up4 level 1 to level 0.
    let exact = |k: usize| {
        let (from, to) = (s[4 - k], s[3 - k]);
        !align_corners && to == (2 * from.0, 2 * from.1) && from.0 % 4 == 0
    };
    (0..4).filter(|&k| exact(k)).map(|k| names[k]).collect()
}

#[test]
fn vec4_inputs_match_twin() {
    // Four pixels per texel fetch where a level's width is a multiple of 4:
    // 64×12 every layer (heights down to 1), 36×20 only the full-resolution
    // ones, 24×6 with partial pixel blocks (24 = 1.5 blocks of 16, 3 of 8 in outc; 6 at down-levels;
    // Winograd: 1.5 rows of four 4 × 4 tiles, 1.5 tile rows), 40×9 an odd height (2.5 rows of
    // Winograd tiles, the last tile row a quarter inside).
    // Exact-2× resizes (align_corners false): 64×12 three of four (8×2 → 16×3 is not 2×),
    // 544×16 three (34 is no multiple of 4) with 17, 34 and 68 four-pixel texels per source row.
    let d = device();
    let cases = [
        ([32usize, 32, 64, 64, 128], Activation::Relu, false, 64usize, 12usize),
        ([8, 16, 32, 64, 128], Activation::LeakyRelu, true, 36, 20),
        ([12, 20, 24, 40, 48], Activation::None, true, 24, 6),
        ([8, 8, 16, 16, 16], Activation::Relu, false, 40, 9),
        ([8, 8, 8, 8, 8], Activation::LeakyRelu, false, 544, 16),
    ];
    let mut precisions = vec![StoragePrecision::Fp32];
    if d.info().storage_16bit {
        precisions.push(StoragePrecision::Fp16);
    }
    // Direct convolution and both Winograd tiles (their rows of tiles also read four pixels per fetch and
    // store four per write; F(2×2) a pair of tiles' rows per write).
    let mut tiles = vec![None, Some(WinogradTile::F2x2)];
    if tests_winograd_4x4(&d) {
        tiles.push(Some(WinogradTile::F4x4));
    }
    let mut runs = Vec::new();
    for c in cases {
        for p in &precisions {
            runs.extend(tiles.iter().map(|wino| (c, *p, *wino)));
        }
    }
    for ((widths, activation, align_corners, w, h), precision, wino) in runs {
        let config = UNetConfig { widths, activation, align_corners, ..UNetConfig::default() };
        let weights = UNetWeights::random(config, 9);
        let mut rng = Pcg64Mcg::seed_from_u64(5);
        let input: Vec<f32> = (0..14 * w * h).map(|_| rng.random_range(-1.0..1.0f32)).collect();
        let buffer = d.upload("input", &input).unwrap();
        let mut net = UNet::with_precision(&d, &weights, precision).unwrap();
        net.set_prefill(Some(NAN));
        let default = ConvPath::default_for(d.info().device_type, true).vec4();
        assert_eq!(
            net.vec4_inputs(),
            default,
            "four-pixel fetches by default on CPU devices (RGBA views), not on GPUs"
        );
        net.set_vec4_inputs(true).unwrap();
        net.set_winograd(wino).unwrap();
        let out = net.infer(&buffer, w as u32, h as u32).unwrap();
        assert_eq!(out.vec4_layers, expected_vec4_layers(w, h), "{w}x{h}: layers reading four pixels per fetch");
        assert!(!out.vec4_layers.is_empty());
        let exact_ups = expected_exact_resizes(w, h, align_corners);
        assert_eq!(out.exact_resizes, exact_ups, "{w}x{h}: up layers resizing by the exact-2× kernel");
        let gpu: Vec<f32> = d.read_buffer(&out.output).unwrap();
        let x = Tensor::from_f32(14, w, h, &input);
        let (exact, rounded) = (unet_cpu(&weights, &x), unet_cpu_stored(&weights, &x, true));
        let peak = exact.data.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(peak > 1e-3, "the outputs are all ~0: the check would prove nothing");
        let err = max_abs(&gpu, &exact);
        println!("{precision:?} widths {widths:?} at {w}x{h}, Winograd {wino:?}, vec4 in {:?}: max |GPU − CPU| {err:.2e} (outputs up to {peak:.2})", out.vec4_layers);
        if precision == StoragePrecision::Fp32 {
            assert!(
                err <= 1e-4,
                "fp32 vec4 U-Net (Winograd {wino:?}) differs from the twin by {err:e} (tolerance 1e-4)"
            );
        } else {
            // As fp16_storage_matches_twin_within_its_precision.
            assert!(err / peak <= 1e-2, "fp16 vec4 (Winograd {wino:?}): relative error {:e} > 1e-2", err / peak);
            let rel_rounded = max_abs(&gpu, &rounded) / peak;
            assert!(rel_rounded <= 2e-3, "fp16 vec4 (Winograd {wino:?}) vs the rounded twin: {rel_rounded:e} > 2e-3");
        }
    }
    assert_no_validation_messages(&d);
}

#[test]
fn zero_weights_large_activations_and_arena_reuse() {
    let d = device();
    let config = UNetConfig { widths: [8, 8, 16, 16, 32], ..UNetConfig::default() };
    let mut zero = UNetWeights::random(config.clone(), 1);
    for l in &mut zero.layers {
        l.weight.iter_mut().for_each(|v| *v = 0.0);
        l.bias.iter_mut().for_each(|v| *v = 0.0);
    }
    let (gpu, _) = run(&d, &zero, 9, 7, 1.0, 2);
    assert!(gpu.iter().all(|v| *v == 0.0), "zero weights give exactly zero");
    // Bias only: the output is outc's bias everywhere.
    let mut bias_only = zero.clone();
    bias_only.layers[9].bias = vec![0.25, -0.5, 1.0];
    let (gpu, _) = run(&d, &bias_only, 9, 7, 1.0, 2);
    for (c, b) in [0.25f32, -0.5, 1.0].iter().enumerate() {
        assert!(gpu[c * 63..(c + 1) * 63].iter().all(|v| v == b), "channel {c} is not its bias");
    }
    // Activations of 1e4: finite, and still the twin's (relative 1e-5 of the output scale).
    let weights = UNetWeights::random(config, 5);
    let (gpu, cpu) = run(&d, &weights, 13, 11, 1e4, 3);
    let peak = cpu.data.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let err = max_abs(&gpu, &cpu);
    println!("inputs of 1e4: outputs up to {peak:.3e}, max |GPU − CPU| {err:.2e}");
    assert!(peak > 1e3 && err <= 1e-5 * peak, "large activations: error {err:e} of {peak:e}");
    // The arena is sized once and reused for smaller inputs.
    let mut net = UNet::new(&d, &weights).unwrap();
    let input = d.upload("input", &vec![0.5f32; 14 * 40 * 30]).unwrap();
    net.infer(&input, 40, 30).unwrap();
    let held = net.arena_capacity();
    assert_eq!(held, net.arena_bytes(40, 30));
    net.infer(&input, 21, 13).unwrap();
    assert_eq!(net.arena_capacity(), held, "a smaller pass reuses the arena");
    println!("arena at 40x30: {held} bytes; at 704x192: {} bytes", net.arena_bytes(704, 192));
    assert!(net.infer(&input, 100, 100).is_err(), "an input buffer too small for the size is refused");
    assert!(net.infer(&input, 0, 4).is_err());
    assert_no_validation_messages(&d);
}

#[test]
fn safetensors_round_trip_and_clear_errors() {
    let config = UNetConfig {
        widths: [8, 8, 16, 16, 24],
        activation: Activation::LeakyRelu,
        align_corners: true,
        ..UNetConfig::default()
    };
    let weights = UNetWeights::random(config, 9);
    let bytes = weights.to_bytes().unwrap();
    assert!(UNetWeights::from_bytes(&bytes, "mem").is_ok_and(|w| w == weights), "round trip");
    let error = |b: &[u8]| match UNetWeights::from_bytes(b, "w.safetensors") {
        Ok(_) => panic!("accepted a bad file"),
        Err(e) => e.to_string(),
    };
    // Edits of the JSON header that keep its length.
    let edit = |from: &str, to: &str| {
        assert_eq!(from.len(), to.len());
        let end = 8 + u64::from_le_bytes(bytes[..8].try_into().unwrap()) as usize;
        let header = String::from_utf8(bytes[8..end].to_vec()).unwrap();
        assert!(header.contains(from), "{from} not in the header");
        let mut b = bytes.clone();
        b.splice(8..end, header.replace(from, to).into_bytes());
        b
    };
    // Metadata widths that disagree with the tensors: the error names the tensor and the shapes.
    let msg = error(&edit("8,8,16,16,24", "8,8,16,16,32"));
    assert!(msg.contains("w.safetensors") && msg.contains("down4.weight") && msg.contains("shape"), "{msg}");
    let msg = error(&edit("\"up3.bias\"", "\"up3.biaz\""));
    assert!(msg.contains("\"up3.bias\" is missing"), "{msg}");
    let msg = error(&edit("\"leaky_relu\"", "\"sigmoidx__\""));
    assert!(msg.contains("activation"), "{msg}");
    assert!(error(b"not safetensors").contains("w.safetensors"));
    let msg = UNetWeights::load("/nonexistent/w.safetensors").err().map(|e| e.to_string()).unwrap_or_default();
    assert!(msg.contains("w.safetensors"), "{msg}");
}

#[test]
fn fp16_storage_matches_twin_within_its_precision() {
    let d = device();
    if !d.info().storage_16bit {
        println!("skipped: the device has no 16-bit storage");
        return;
    }
    let cases = [
        ([32usize, 32, 64, 64, 128], Activation::Relu, false, 37usize, 23usize, 1.0f32),
        ([8, 16, 32, 64, 128], Activation::LeakyRelu, true, 37, 23, 1.0),
        ([8, 8, 8, 8, 8], Activation::Relu, true, 1, 1, 1.0),
        ([8, 8, 16, 16, 16], Activation::None, false, 2, 2, 1.0),
        ([16, 16, 32, 32, 64], Activation::Relu, false, 13, 11, 1e4),
    ];
    let paths = paths(&d);
    for ((widths, activation, align_corners, w, h, scale), path) in
        cases.into_iter().flat_map(|c| paths.iter().map(move |p| (c, *p)))
    {
        let config = UNetConfig { widths, activation, align_corners, ..UNetConfig::default() };
        let weights = UNetWeights::random(config, 3);
        let (gpu, exact, rounded) = run_with(&d, &weights, (w, h), scale, 7, StoragePrecision::Fp16, path);
        let peak = exact.data.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let rel = max_abs(&gpu, &exact) / peak;
        // Against the twin that rounds what the kernels store: only fp32-vs-f64 arithmetic and
        // rounding ties remain (one fp16 step of the largest stored value, relative).
        let rel_rounded = max_abs(&gpu, &rounded) / peak;
        println!("fp16 storage, widths {widths:?} at {w}x{h}, inputs ×{scale}, {path:?}: relative error {rel:.2e} (vs fp16-rounded twin {rel_rounded:.2e})");
        assert!(rel <= 1e-2, "fp16 storage: relative error {rel:e} > 1e-2");
        assert!(rel_rounded <= 2e-3, "fp16 storage vs the rounded twin: {rel_rounded:e} > 2e-3");
    }
    // The fp16 arena is about half the fp32 one.
    let weights = UNetWeights::random(UNetConfig::default(), 1);
    let a32 = UNet::new(&d, &weights).unwrap().arena_bytes(704, 192);
    let a16 = UNet::with_precision(&d, &weights, StoragePrecision::Fp16).unwrap().arena_bytes(704, 192);
    println!("arena at 704x192: fp32 {a32} bytes, fp16 {a16} bytes");
    assert!(a16 < a32 * 7 / 10);
    assert_no_validation_messages(&d);
}

#[test]
fn winograd_twin_equals_direct_convolution() {
    // The f64 Winograd transforms against plain 3×3 convolution: equal up to
    // f64 rounding at even, odd and tiny sizes (partial tiles, all-padding patches).
    let mut rng = Pcg64Mcg::seed_from_u64(11);
    for (w, h, ci, co) in [(1usize, 1usize, 3usize, 2usize), (2, 2, 1, 1), (5, 3, 4, 5), (37, 23, 6, 7), (8, 6, 2, 3)] {
        let weight: Vec<f32> = (0..co * ci * 9).map(|_| rng.random_range(-1.0..1.0f32)).collect();
        let bias: Vec<f32> = (0..co).map(|_| rng.random_range(-1.0..1.0f32)).collect();
        let layer = srug::indirect::ConvWeights { in_channels: ci, out_channels: co, weight, bias };
        let input: Vec<f32> = (0..ci * w * h).map(|_| rng.random_range(-2.0..2.0f32)).collect();
        let x = Tensor::from_f32(ci, w, h, &input);
        let runs = [Activation::None, Activation::Relu, Activation::LeakyRelu]
            .into_iter()
            .flat_map(|act| [WinogradTile::F2x2, WinogradTile::F4x4].map(|tile| (act, tile)));
        for (act, tile) in runs {
            let direct = conv3x3_cpu(&x, &layer, 1, act);
            let wino = winograd_conv3x3_cpu(&x, &layer, act, tile);
            assert_eq!((wino.width, wino.height, wino.channels), (w, h, co));
            let err = direct.data.iter().zip(&wino.data).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
            let peak = direct.data.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            assert!(
                peak > 0.1 && err <= 1e-12 * peak.max(1.0),
                "{tile:?} {w}x{h} {ci}->{co} {act:?}: {err:e} (peak {peak})"
            );
        }
    }
}

#[test]
fn fp16_store_conversion_rounds_to_nearest_even_and_saturates() {
    // The twin of the kernels' fp32 → fp16 conversion (`half_bits`) against the `half` crate on every
    // fp16 value, the ties between neighbours and one fp32 step either side, and random values.
    use srug::indirect::cpu::half_bits;
    let expected = |v: f32| -> u16 {
        let sign = if v.is_sign_negative() { 0x8000 } else { 0 };
        if v.is_nan() {
            sign | 0x7e00
        } else if v.abs() > 65504.0 {
            sign | 0x7bff
        } else {
            half::f16::from_f32(v).to_bits()
        }
    };
    let mut values =
        vec![f32::NAN, f32::INFINITY, f32::NEG_INFINITY, 1e30, -1e30, 65504.0, 65519.0, 65520.0, 0.0, -0.0];
    for h in 0u16..0x7c00 {
        let (x, next) = (half::f16::from_bits(h).to_f32(), half::f16::from_bits(h + 1).to_f32());
        let tie = (x + next) / 2.0;
        let up = |v: f32| f32::from_bits(v.to_bits() + 1);
        let down = |v: f32| if v == 0.0 { v } else { f32::from_bits(v.to_bits() - 1) };
        for v in [x, up(x), down(x), tie, up(tie), down(tie)] {
            values.extend([v, -v]);
        }
    }
    let mut rng = Pcg64Mcg::seed_from_u64(13);
    values.extend((0..200_000).map(|_| rng.random_range(-1.0f32..1.0) * 2.0f32.powi(rng.random_range(-30..20))));
    for &v in &values {
        let (got, want) = (half_bits(v), expected(v));
        assert_eq!(got, want, "{v:e} (bits {:#010x}): {got:#06x} against {want:#06x}", v.to_bits());
    }
}
