//! The benchmark's device-limit probes (`srug_cli::bench::limits`) against their
//! CPU twins, with validation on: the blend ceiling must compute the blend's
//! arithmetic with every evaluation contributing (else its flop count would
//! be wrong), and the pair-move and bandwidth probes must read and write every
//! pair and texel.

#![allow(clippy::unwrap_used, clippy::expect_used, reason = "a failed unwrap is a failed test")]

use srug::gpu::MemoryKind;
use srug_cli::bench::limits::{
    bandwidth_checksums, bandwidth_cpu, bandwidth_run, blend_ceiling_cpu, blend_ceiling_run, pair_move_cpu,
    pair_move_run, radix_pass_permutation, random_permutation, stable_digit_permutation, BandwidthLayout,
    BandwidthRead, BlendCeiling, MemoryBandwidth, PairMoveFloor, PairWrites, BLEND_CEILING_MAX_SPLATS,
    BLEND_CEILING_PIXELS,
};
use srug_cli::bench::{BLEND_FLOPS_PER_CONTRIBUTION, BLEND_FLOPS_PER_EVALUATION};
use srug_tests::{assert_no_validation_messages, device, save_comparison};

#[test]
fn blend_ceiling_probe_matches_its_twin_and_every_evaluation_contributes() {
    let d = device();
    // 20 rows of 16 invocations: not a multiple of the 64-invocation workgroup.
    let count = 16 * 20;
    for pixels in BLEND_CEILING_PIXELS {
        for splats in [0, 1, 37, BLEND_CEILING_MAX_SPLATS] {
            let (gpu, seconds) = blend_ceiling_run(&d, pixels, count, splats).unwrap();
            let (cpu, contributed) = blend_ceiling_cpu(pixels, count, splats);
            assert!(seconds.is_finite() && seconds >= 0.0, "GPU time {seconds}");
            // Every evaluation contributes, so each counts 12 + 9 flops.
            assert_eq!(contributed, u64::from(count) * u64::from(pixels) * u64::from(splats));
            // f32 against f64 over ≤ 1,024 rounded steps: a random walk of ~√1024 · 6e-8 ≈ 2e-6
            // (1.3e-6 seen on lavapipe).
            let tolerance = 1e-5;
            let worst = gpu
                .iter()
                .zip(&cpu)
                .map(|(g, c)| {
                    let e = (f64::from(*g) - c).abs() / c.abs();
                    if e.is_nan() {
                        f64::INFINITY
                    } else {
                        e
                    }
                })
                .fold(0.0, f64::max);
            if worst > tolerance {
                let cpu32: Vec<f32> = cpu.iter().map(|v| *v as f32).collect();
                let at = save_comparison(&format!("blend_ceiling_{pixels}px_{splats}"), 16, 20, 1, &gpu, &cpu32);
                panic!("{pixels} px, {splats} splats: relative error {worst:e} > {tolerance:e}; images at {at}");
            }
            if splats == 0 {
                // Nothing blended: T = 1 and rgb = 0 at each pixel.
                assert!(gpu.iter().all(|s| *s == pixels as f32), "{gpu:?}");
            }
        }
    }
    assert!(blend_ceiling_run(&d, 3, count, 8).is_err(), "3 pixels per invocation is not a variant");
    assert!(blend_ceiling_run(&d, 128, count, 8).is_err(), "nor is 128");
    assert!(blend_ceiling_run(&d, 2, count, BLEND_CEILING_MAX_SPLATS + 1).is_err(), "too many splats to contribute");
    assert_no_validation_messages(&d);
}

#[test]
fn blend_ceiling_for_a_work_mix_counts_only_the_flops_that_work_would_count() {
    let c = BlendCeiling { pixels: 4, gflops: 42.0 };
    let all = (BLEND_FLOPS_PER_EVALUATION + BLEND_FLOPS_PER_CONTRIBUTION) as f64;
    assert!((c.for_work(1000, 1000) - 42.0).abs() < 1e-12);
    assert!((c.for_work(1000, 0) - 42.0 * BLEND_FLOPS_PER_EVALUATION as f64 / all).abs() < 1e-12);
    assert!((c.for_work(1000, 250) - 42.0 * (12.0 + 0.25 * 9.0) / 21.0).abs() < 1e-12);
    assert_eq!(c.for_work(0, 0), 42.0);
}

#[test]
fn pair_move_probe_reads_and_writes_every_pair() {
    let d = device();
    // Not a multiple of the 4,096 pairs of a workgroup, nor of the 64 of an invocation.
    let n = 10_007u32;
    let mut state = 0x1234_5678_9abc_def1u64;
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state as u32
    };
    let keys: Vec<[u32; 2]> = (0..n).map(|_| [next(), next()]).collect();
    let values: Vec<u32> = (0..n).map(|_| next()).collect();
    let dest = random_permutation(n, 99);
    let mut sorted = dest.clone();
    sorted.sort_unstable();
    assert!(sorted.iter().copied().eq(0..n), "random_permutation is not a permutation");
    let (kb, vb, db) =
        (d.upload("keys", &keys).unwrap(), d.upload("values", &values).unwrap(), d.upload("dest", &dest).unwrap());
    const SENTINEL: u32 = 0xdead_beef;
    let untouched_keys = vec![[SENTINEL; 2]; n as usize];
    let untouched_values = vec![SENTINEL; n as usize];
    let ko = d.create_buffer("keys out", u64::from(n) * 8, MemoryKind::Storage).unwrap();
    let vo = d.create_buffer("values out", u64::from(n) * 4, MemoryKind::Storage).unwrap();
    let checksums = pair_move_cpu(&keys, &values);
    assert_eq!(checksums.len(), (n as usize).div_ceil(64));
    for writes in [PairWrites::None, PairWrites::Value, PairWrites::Pair, PairWrites::ValueScattered] {
        d.write_buffer(&ko, 0, &untouched_keys).unwrap();
        d.write_buffer(&vo, 0, &untouched_values).unwrap();
        let seconds = pair_move_run(&d, writes, &kb, &vb, &db, u64::from(n), &ko, &vo).unwrap();
        assert!(seconds.is_finite() && seconds >= 0.0, "{writes:?}: GPU time {seconds}");
        let got_keys: Vec<[u32; 2]> = d.read_buffer(&ko).unwrap();
        let got_values: Vec<u32> = d.read_buffer(&vo).unwrap();
        let mut want_values = untouched_values.clone();
        match writes {
            PairWrites::None => want_values[..checksums.len()].copy_from_slice(&checksums),
            PairWrites::Value | PairWrites::Pair => want_values.copy_from_slice(&values),
            PairWrites::ValueScattered => {
                for (i, &at) in dest.iter().enumerate() {
                    want_values[at as usize] = values[i];
                }
            }
        }
        let want_keys = if writes == PairWrites::Pair { &keys } else { &untouched_keys };
        assert!(got_keys == *want_keys, "{writes:?}: keys out differ");
        let wrong = got_values.iter().zip(&want_values).filter(|(g, w)| g != w).count();
        assert_eq!(wrong, 0, "{writes:?}: {wrong} of {n} values out differ");
    }
    let err = pair_move_run(&d, PairWrites::Pair, &kb, &vb, &db, 0, &ko, &vo).unwrap_err();
    assert!(err.to_string().contains("0 pairs"), "{err}");
    let err = pair_move_run(&d, PairWrites::Pair, &kb, &vb, &db, u64::from(n) + 1, &ko, &vo).unwrap_err();
    assert!(err.to_string().contains("too small"), "{err}");
    assert_no_validation_messages(&d);
}

#[test]
fn radix_pass_destinations_are_a_stable_partition_by_digit() {
    // Digits 2, 0, 1, 0, 2, 1, 0: zeros first in input order, then ones, then twos.
    assert_eq!(stable_digit_permutation(&[2, 0, 1, 0, 2, 1, 0], 4), vec![5, 0, 3, 1, 6, 4, 2]);
    assert!(stable_digit_permutation(&[], 16).is_empty());
    for bits in [4, 8, 11] {
        let p = radix_pass_permutation(50_000, bits, 7);
        let mut sorted = p.clone();
        sorted.sort_unstable();
        assert!(sorted.iter().copied().eq(0..50_000), "{bits}-bit digits: not a permutation");
        // Runs of consecutive destinations: about one per element once buckets outnumber neighbours' matches.
        let breaks = p.windows(2).filter(|w| w[1] != w[0] + 1).count();
        assert!(breaks > 50_000 * 9 / 10, "{bits}-bit digits: {breaks} breaks, the digits are not random");
    }
}

/// A pair-move floor of 1,000 pairs with round times.
fn example_floor() -> PairMoveFloor {
    PairMoveFloor {
        keys: 1000,
        read_seconds: 0.006,
        value_seconds: 0.009,
        pair_seconds: 0.020,
        digit_seconds: vec![(4, 0.010), (8, 0.025), (11, 0.040)],
        random_seconds: 0.05,
    }
}

#[test]
fn lsd_bound_takes_the_cheapest_digit_width() {
    let floor = example_floor();
    // A pass: scatter (10 ms at widths 4–7, 25 at 8–10, 40 from 11) + 9 µs × 2^width of offsets
    // + 3 ms of counting (9 − 6) above 4 bits. 43 bits: 4 bits, 11 × 10.144 = 111.6 ms; 7 bits,
    // 7 × 14.152 = 99.1; 8 bits, 6 × 30.304 = 181.8; 11 bits, 4 × 61.43 = 245.7: 7 bits wins.
    let pass = |scatter: f64, width: i32, counted: bool| {
        scatter + 0.009 * 2f64.powi(width) / 1000.0 + if counted { 0.003 } else { 0.0 }
    };
    let (width, seconds) = floor.lsd_bound(43).unwrap();
    assert_eq!(width, 7);
    assert!((seconds - 7.0 * pass(0.010, 7, true)).abs() < 1e-12, "{seconds}");
    // 12 bits: 4 bits (3 × 10.144 = 30.4) beats 6 bits (2 × 13.576 = 27.2)? No: 6 bits wins.
    let (width, seconds) = floor.lsd_bound(12).unwrap();
    assert_eq!(width, 6);
    assert!((seconds - 2.0 * pass(0.010, 6, true)).abs() < 1e-12, "{seconds}");
    // 8 bits: 4 bits, 2 × 10.144 = 20.3, beats 8 bits in one pass (25 + 2.3 + 3 = 30.3).
    let (width, seconds) = floor.lsd_bound(8).unwrap();
    assert_eq!(width, 4);
    assert!((seconds - 2.0 * pass(0.010, 4, false)).abs() < 1e-12, "{seconds}");
    // 3 bits: narrower than any timed width, so the contiguous write: 1 pass of 9 + 0.072 ms.
    let (width, seconds) = floor.lsd_bound(3).unwrap();
    assert_eq!(width, 3);
    assert!((seconds - pass(0.009, 3, false)).abs() < 1e-12, "{seconds}");
    assert!(floor.lsd_bound(0).is_none());
    // Noise that makes a narrower width dearer than a wider one: the wider one's time bounds
    // both. 4 bits in one pass: 20 ms (not the 30 timed at 4 bits) + 16 offsets at 25 µs.
    let noisy = PairMoveFloor {
        read_seconds: 0.022,
        value_seconds: 0.025,
        digit_seconds: vec![(4, 0.030), (8, 0.020)],
        ..floor
    };
    let (width, seconds) = noisy.lsd_bound(4).unwrap();
    assert_eq!(width, 4);
    assert!((seconds - (0.020 + 0.025 * 16.0 / 1000.0)).abs() < 1e-12, "{seconds}");
}

#[test]
fn the_best_of_two_floors_takes_each_time_at_its_least() {
    let first = PairMoveFloor { value_seconds: 0.012, ..example_floor() };
    let second = PairMoveFloor {
        read_seconds: 0.008,
        pair_seconds: 0.030,
        digit_seconds: vec![(4, 0.015), (8, 0.020), (11, 0.035)],
        random_seconds: 0.04,
        ..example_floor()
    };
    let best = first.best(&second);
    assert_eq!(best.keys, 1000);
    assert_eq!(
        (best.read_seconds, best.value_seconds, best.pair_seconds, best.random_seconds),
        (0.006, 0.009, 0.020, 0.04)
    );
    assert_eq!(best.digit_seconds, vec![(4, 0.010), (8, 0.020), (11, 0.035)]);
    // Either way round, and never above either floor's bound.
    assert_eq!(second.best(&first).digit_seconds, best.digit_seconds);
    let bound = |f: &PairMoveFloor| f.lsd_bound(31).unwrap().1;
    assert!(bound(&best) <= bound(&first).min(bound(&second)), "{} {} {}", bound(&best), bound(&first), bound(&second));
}

#[test]
fn the_best_of_two_bandwidths_takes_the_faster_read_and_copy() {
    let probe = |read: f64, copy: f64| MemoryBandwidth {
        bytes: 64 << 20,
        read,
        copy,
        read_layout: BandwidthLayout::Runs,
        read_through: BandwidthRead::Texels,
    };
    let best = probe(18e9, 9e9).best(&probe(12e9, 14e9));
    assert_eq!((best.read, best.copy), (18e9, 14e9));
    // A faster probe prices the same bytes in less time.
    assert!(best.floor_seconds(1 << 30, 1 << 29) < probe(18e9, 9e9).floor_seconds(1 << 30, 1 << 29));
}

#[test]
fn bandwidth_probe_reads_and_copies_every_texel() {
    let d = device();
    // A count that leaves the last invocation a partial run of texels.
    let count: usize = 64 * 64 * 3 + 37;
    // Every component differs from texel to texel, so a component left out changes the checksums.
    let texels: Vec<[f32; 4]> =
        (0..count).map(|i| [i as f32, -(i as f32) * 0.5, 1e-3 * i as f32, 7.0 + 3.0 * i as f32]).collect();
    let source = d.upload("bandwidth source", &texels).unwrap();
    // Runs: 193 invocations; interleaved: 3 full blocks of 64 lanes and 37 lanes of the last.
    assert_eq!(bandwidth_checksums(count as u64, BandwidthLayout::Runs), 193);
    assert_eq!(bandwidth_checksums(count as u64, BandwidthLayout::Interleaved), 229);
    for (layout, read) in [BandwidthLayout::Runs, BandwidthLayout::Interleaved]
        .into_iter()
        .flat_map(|layout| [BandwidthRead::Texels, BandwidthRead::Address].map(|read| (layout, read)))
    {
        let n = bandwidth_checksums(count as u64, layout) as usize;
        let sums = d.create_filled::<u32>("sums", n, 0xdead_beef).unwrap();
        let seconds = bandwidth_run(&d, false, layout, read, &source, count as u64, &sums).unwrap();
        assert!(seconds.is_finite() && seconds > 0.0, "{seconds}");
        let gpu: Vec<u32> = d.read_buffer(&sums).unwrap();
        assert_eq!(gpu, bandwidth_cpu(&texels, layout), "read-only checksums, {layout:?}, {read:?}");
        let copy = d.create_filled::<u32>("copy", 4 * count, f32::NAN.to_bits()).unwrap();
        bandwidth_run(&d, true, layout, read, &source, count as u64, &copy).unwrap();
        let copied: Vec<[f32; 4]> = d.read_buffer(&copy).unwrap();
        let same = copied.iter().zip(&texels).all(|(a, b)| a.map(f32::to_bits) == b.map(f32::to_bits));
        assert!(same, "copy, {layout:?}, {read:?}");
        // Clear refusals.
        assert!(bandwidth_run(&d, false, layout, read, &source, 0, &sums).is_err(), "no texels");
        let small = bandwidth_run(&d, true, layout, read, &source, count as u64, &sums);
        assert!(small.is_err(), "copy into too small a buffer");
        let past = count as u64 + 1;
        assert!(bandwidth_run(&d, false, layout, read, &source, past, &sums).is_err(), "more texels than the source");
        if layout == BandwidthLayout::Interleaved {
            let few = d.create_filled::<u32>("few sums", 193, 0).unwrap();
            let refused = bandwidth_run(&d, false, layout, read, &source, count as u64, &few);
            assert!(refused.is_err(), "too few checksums");
        }
    }
    assert_no_validation_messages(&d);
}
