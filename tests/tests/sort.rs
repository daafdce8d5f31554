//! The GPU prefix sum and radix sort against the CPU: std's stable sort on
//! the masked key (so stability is checked through the values), for random
//! keys, duplicates, all-equal keys, lengths 0, 1, non-multiples of the block,
//! and more than 16 million keys; 4-bit and wide digits; pairs packed into
//! one word a pass where the caller allows ([`PairPacking`]), with every kind of digits.

#![allow(clippy::unwrap_used, clippy::expect_used, reason = "a failed unwrap is a failed test")]

use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;
use srug::gpu::{Device, MemoryKind};
use srug::primitives::scan::{default_scan_tiles, exclusive_scan_cpu, Scan};
use srug::primitives::sort::{
    block_digits_supported, default_sort_digits, sort_items, sort_kernel_stage, wide_digits, wide_digits_supported,
    PairPacking, RadixSort, SortDigits, SortKernel, SORT_COPY_STAGE,
};
use srug_tests::{assert_no_validation_messages, device};

fn gpu_scan(d: &Device, scan: &mut Scan, values: &[u32]) -> Vec<u32> {
    let buffer = d.upload("scan data", values).unwrap();
    scan.reserve(d, values.len() as u64).unwrap();
    d.run(|rec| scan.record(rec, &buffer, values.len() as u64)).unwrap();
    d.read_buffer(&buffer).unwrap()
}

#[test]
fn exclusive_scan_matches_cpu() {
    let d = device();
    // Both shapes on every device: runs of 32 values an invocation, tiles of 2048 a workgroup.
    for tiles in [false, true] {
        let mut scan = Scan::with_tiles(&d, tiles).unwrap();
        assert_eq!(scan.tiles(), tiles);
        let mut rng = Pcg64Mcg::seed_from_u64(1);
        // Runs: one invocation up to 4096 values, then two levels (runs of 32 and longer). Tiles: one
        // tile, a partial second, two levels at 2048·2048, three at 2048·2048 + 1; wrapping sums.
        for n in [
            1usize, 2, 31, 32, 33, 1023, 1024, 1025, 2047, 2048, 2049, 4096, 4097, 5_000, 8192, 8193, 1_048_577,
            4_194_304, 4_194_305,
        ] {
            let values: Vec<u32> = (0..n).map(|_| rng.random_range(0..100)).collect();
            assert_eq!(gpu_scan(&d, &mut scan, &values), exclusive_scan_cpu(&values), "n = {n}, tiles {tiles}");
        }
        let big: Vec<u32> = (0..3000).map(|_| rng.random::<u32>()).collect();
        assert_eq!(gpu_scan(&d, &mut scan, &big), exclusive_scan_cpu(&big), "wrapping, tiles {tiles}");
        // Fewer values than reserved, whose runs are more than the reserved count's (8192: 256 runs of
        // 32; 8300: 252 of 33).
        let mut fresh = Scan::with_tiles(&d, tiles).unwrap();
        fresh.reserve(&d, 8300).unwrap();
        let values: Vec<u32> = (0..8192).map(|_| rng.random_range(0..100)).collect();
        assert_eq!(gpu_scan(&d, &mut fresh, &values), exclusive_scan_cpu(&values), "8192 of 8300, tiles {tiles}");
        // Zero values: nothing to do, no error.
        let empty = d.create_buffer("empty", 0, MemoryKind::Storage).unwrap();
        d.run(|rec| scan.record(rec, &empty, 0)).unwrap();
    }
    // The device's own shape: tiles on GPUs, runs on CPU devices.
    assert_eq!(Scan::new(&d).unwrap().tiles(), default_scan_tiles(d.info().device_type));
    assert_no_validation_messages(&d);
}

/// Sorts on the GPU; returns (keys, values).
fn gpu_sort(d: &Device, sort: &mut RadixSort, keys: &[[u32; 2]], bits: u32) -> (Vec<[u32; 2]>, Vec<u32>) {
    let n = keys.len();
    let values: Vec<u32> = (0..n as u32).collect();
    let kb = d.upload("keys", keys).unwrap();
    let vb = d.upload("values", &values).unwrap();
    sort.reserve(d, n as u64).unwrap();
    d.run(|rec| sort.record(rec, &kb, &vb, n as u64, bits)).unwrap();
    (d.read_buffer(&kb).unwrap(), d.read_buffer(&vb).unwrap())
}

fn check_sort(d: &Device, sort: &mut RadixSort, keys: &[[u32; 2]], bits: u32, label: &str) {
    let (got_keys, got_values) = gpu_sort(d, sort, keys, bits);
    let mask = if bits >= 64 { u64::MAX } else { (1u64 << bits) - 1 };
    let key64 = |k: [u32; 2]| (u64::from(k[1]) << 32 | u64::from(k[0])) & mask;
    let mut want: Vec<u32> = (0..keys.len() as u32).collect();
    want.sort_by_key(|&i| key64(keys[i as usize])); // std's stable sort
    if got_values != want {
        let first = got_values.iter().zip(&want).position(|(a, b)| a != b).unwrap_or(0);
        panic!("{label}: order differs first at {first}: got value {} want {}", got_values[first], want[first]);
    }
    // Keys travel with their values, untouched (all 64 bits).
    assert!(got_values.iter().zip(&got_keys).all(|(&v, k)| keys[v as usize] == *k), "{label}: keys were altered");
}

/// With its kernels timed as stages of their own, the sort names every pass's
/// histogram, scan and scatter in order, its digits covering the key's bits
/// once, the copy back exactly where an odd number of unpacked passes needs
/// it, and sorts as before.
#[test]
fn sort_kernel_stages_name_every_pass_and_keep_the_order() {
    let d = device();
    let mut rng = Pcg64Mcg::seed_from_u64(11);
    let mut kinds = vec![SortDigits::Four];
    if wide_digits_supported(d.info()) {
        kinds.push(SortDigits::Wide);
    }
    if block_digits_supported(d.info()) {
        kinds.push(SortDigits::Block);
    }
    let n = 20_000usize;
    let keys: Vec<[u32; 2]> = (0..n).map(|_| [rng.random(), rng.random()]).collect();
    let values: Vec<u32> = (0..n as u32).collect();
    for digits in kinds {
        let mut sort = RadixSort::new(&d).unwrap();
        sort.set_digits(&d, digits).unwrap();
        sort.set_kernel_stages(true);
        assert!(sort.kernel_stages());
        sort.set_packing(&d, true).unwrap();
        sort.reserve(&d, n as u64).unwrap();
        for (bits, packing) in
            [(43u32, None), (31, None), (31, Some(PairPacking { unused_low_bits: 16, value_bits: 15, high_bits: 0 }))]
        {
            let label = format!("{} digits, {bits} bits, packing {packing:?}", digits.name());
            // Packed keys hold nothing above their sort bits (no top bits kept here).
            let keys: Vec<[u32; 2]> = match packing {
                Some(_) => keys.iter().map(|k| [k[0] & ((1u32 << bits) - 1), 0]).collect(),
                None => keys.clone(),
            };
            let kb = d.upload("keys", &keys).unwrap();
            let vb = d.upload("values", &values).unwrap();
            let timings = d.run(|rec| sort.record_with(rec, &kb, &vb, n as u64, bits, packing)).unwrap();
            // The passes the sort takes: as few as the digit width allows, the bits spread evenly.
            let passes = bits.div_ceil(digits.max_bits());
            let mut want = Vec::new();
            let mut shift = 0;
            for pass in 0..passes {
                let digit = (bits - shift).div_ceil(passes - pass);
                for kernel in [SortKernel::Histogram, SortKernel::Scan, SortKernel::Scatter] {
                    want.push(sort_kernel_stage(pass as usize + 1, shift, digit, kernel));
                }
                shift += digit;
            }
            assert_eq!(shift, bits, "{label}");
            let packed = packing.is_some_and(|p| p.fits(bits, bits.div_ceil(passes)));
            if passes % 2 == 1 && !packed {
                want.push(SORT_COPY_STAGE.to_string());
            }
            let names: Vec<&str> = timings.stages.iter().map(|s| s.name.as_str()).collect();
            assert_eq!(names, want, "{label}");
            assert!(timings.stages.iter().all(|s| s.seconds.is_finite() && s.seconds >= 0.0), "{label}: {timings}");
            // Still sorted, stably, the keys unchanged but for a packed sort's first digit.
            let (got_keys, got_values): (Vec<[u32; 2]>, Vec<u32>) =
                (d.read_buffer(&kb).unwrap(), d.read_buffer(&vb).unwrap());
            let key64 = |k: [u32; 2]| u64::from(k[1]) << 32 | u64::from(k[0]);
            let mut order: Vec<u32> = (0..n as u32).collect();
            order.sort_by_key(|&i| key64(keys[i as usize]) & ((1u64 << bits) - 1));
            let zeroed = if packed { (1u64 << bits.div_ceil(passes)) - 1 } else { 0 };
            for (at, &i) in order.iter().enumerate() {
                let want = (key64(keys[i as usize]) & !zeroed, i);
                assert_eq!((key64(got_keys[at]), got_values[at]), want, "{label}: pair {at}");
            }
        }
    }
    assert_no_validation_messages(&d);
}

#[test]
fn radix_sort_matches_std_sort() {
    let d = device();
    let sort = RadixSort::new(&d).unwrap();
    assert!(sort.texel_inputs(), "lavapipe reads RG32UI/R32UI texel buffers, so that path is the default");
    assert_eq!(sort.items(), sort_items(d.info().device_type), "the device's keys per invocation");
    assert_eq!(sort.wide_digits(), wide_digits(d.info()), "wide digits by default on CPU devices only");
    let mesa_25 = d.info().mesa_version().is_some_and(|(major, _)| major >= 25);
    assert_eq!(wide_digits_supported(d.info()), mesa_25 || !d.info().is_lavapipe(), "wide digits from Mesa 25 on");
    // 4-bit digits: GPUs' 64 keys per invocation and CPU devices' 256 (and an odd count); both input paths.
    for items in [64, 256, 7] {
        let mut sort = RadixSort::with_items(&d, items).unwrap();
        assert!(!sort.wide_digits(), "with_items sorts 4-bit digits");
        for texel in [true, false] {
            sort.set_texel_inputs(texel).unwrap();
            sort_cases(&d, &mut sort);
        }
    }
    // Block digits (8 bits a pass, ranked per block of 128 × 8 or 16 keys in shared memory;
    // GPUs' default): lavapipe's subgroups of 8 give a workgroup the most subgroups they allow.
    let cpu = d.info().device_type == srug::gpu::ash::vk::PhysicalDeviceType::CPU;
    let want = match (wide_digits(d.info()), !cpu && block_digits_supported(d.info())) {
        (true, _) => SortDigits::Wide,
        (false, true) => SortDigits::Block,
        (false, false) => SortDigits::Four,
    };
    assert_eq!(default_sort_digits(d.info()), want, "wide on CPU devices where they can, block on GPUs, else 4 bits");
    assert_eq!(RadixSort::new(&d).unwrap().digits(), want);
    assert!(block_digits_supported(d.info()), "lavapipe and the lent GPUs: ballots, subgroups of 8 or 32, 32 KiB");
    let mut sort = RadixSort::with_items(&d, 64).unwrap();
    sort.set_digits(&d, SortDigits::Block).unwrap();
    assert_eq!(sort.digits(), SortDigits::Block);
    sort_cases(&d, &mut sort);
    let block = sort.block_keys() as usize;
    assert!(block == 1024 || block == 2048, "128 invocations × 8 or 16 keys: {block}");
    // Whole blocks only, and one key past them; digits all alike within each block (every run one digit).
    for n in [2 * block, 3 * block + 1] {
        let keys: Vec<[u32; 2]> =
            (0..n as u32).map(|i| [(i / block as u32).wrapping_mul(0x0101_0101), i % 5]).collect();
        check_sort(&d, &mut sort, &keys, 35, &format!("block digits, {n} keys in runs"));
    }
    assert_eq!(SortDigits::parse("block").unwrap(), SortDigits::Block);
    let refused = SortDigits::parse("16").err().map(|e| e.to_string()).unwrap_or_default();
    assert!(refused.contains("\"16\"") && refused.contains("block"), "{refused}");
    // Wide digits (11 bits a pass, some straddling the key's two words); refused
    // where they crash the driver (lavapipe before Mesa 25), with a message.
    let mut sort = RadixSort::new(&d).unwrap();
    if !wide_digits_supported(d.info()) {
        let refused = sort.set_wide_digits(&d, true).err().map(|e| e.to_string()).unwrap_or_default();
        assert!(refused.contains("Mesa 25"), "wide digits before Mesa 25: {refused}");
        eprintln!("skipping the wide-digit cases: {refused}");
        assert_no_validation_messages(&d);
        return;
    }
    sort.set_wide_digits(&d, true).unwrap();
    sort_cases(&d, &mut sort);
    // Turned on after a reserve for 4-bit digits: recording is refused until the next reserve sizes the histogram.
    let mut sort = RadixSort::with_items(&d, 256).unwrap();
    sort.reserve(&d, 100_000).unwrap();
    sort.set_wide_digits(&d, true).unwrap();
    let keys: Vec<[u32; 2]> = (0..100_000u32).map(|i| [i.wrapping_mul(2_654_435_761), 0]).collect();
    let (kb, vb) = (d.upload("keys", &keys).unwrap(), d.upload("values", &vec![0u32; keys.len()]).unwrap());
    let refused = d.run(|rec| sort.record(rec, &kb, &vb, keys.len() as u64, 32));
    assert!(refused.is_err(), "a wide sort before its reserve must be refused: {refused:?}");
    check_sort(&d, &mut sort, &keys, 32, "wide after 4-bit reserve");
    assert!(RadixSort::with_items(&d, 0).is_err() && RadixSort::with_items(&d, 1 << 17).is_err());
    assert_no_validation_messages(&d);
}

fn sort_cases(d: &Device, sort: &mut RadixSort) {
    let texel = match sort.digits() {
        SortDigits::Wide => "true (wide digits)".to_string(),
        SortDigits::Block => "false (block digits)".to_string(),
        SortDigits::Four => format!("{} ({} keys per invocation)", sort.texel_inputs(), sort.items()),
    };
    let mut rng = Pcg64Mcg::seed_from_u64(2);
    let random =
        |rng: &mut Pcg64Mcg, n: usize| -> Vec<[u32; 2]> { (0..n).map(|_| [rng.random(), rng.random()]).collect() };
    // Around block edges: 64 × items keys per workgroup (4096 at 64, 16,384 at 256); below and
    // past four keys (wide passes read keys two and values four per texel, the rest one by one).
    for n in [0usize, 1, 2, 3, 5, 6, 7, 63, 64, 1023, 1024, 1025, 4095, 4097, 16_383, 16_384, 16_385, 100_003] {
        check_sort(d, sort, &random(&mut rng, n), 64, &format!("random n={n}, texel {texel}"));
    }
    // Only the bits in use: keys with junk above `bits` sort by the low bits alone, stably.
    for bits in [1u32, 13, 31, 32, 33, 42, 43] {
        check_sort(d, sort, &random(&mut rng, 30_001), bits, &format!("bits={bits}, texel {texel}"));
    }
    // Duplicates (stability), all-equal keys, already sorted, reversed.
    let dups: Vec<[u32; 2]> = (0..50_000).map(|_| [rng.random_range(0..7), rng.random_range(0..3)]).collect();
    check_sort(d, sort, &dups, 64, &format!("duplicates, texel {texel}"));
    check_sort(d, sort, &vec![[0xdead_beef, 0x1234]; 20_000], 64, &format!("all equal, texel {texel}"));
    let sorted: Vec<[u32; 2]> = (0..20_000u32).map(|i| [i * 3, i / 100]).collect();
    check_sort(d, sort, &sorted, 40, &format!("sorted, texel {texel}"));
    let reversed: Vec<[u32; 2]> = sorted.iter().rev().copied().collect();
    check_sort(d, sort, &reversed, 40, &format!("reversed, texel {texel}"));
    // Splat-like keys: tile id above positive float depth bits.
    let splat: Vec<[u32; 2]> =
        (0..60_000).map(|_| [rng.random_range(0.01f32..500.0).to_bits(), rng.random_range(0..1320)]).collect();
    check_sort(d, sort, &splat, 32 + 11, &format!("tile|depth keys, texel {texel}"));
}

#[test]
fn radix_sort_more_than_16_million_keys() {
    let d = device();
    let mut sort = RadixSort::new(&d).unwrap();
    let mut rng = Pcg64Mcg::seed_from_u64(3);
    let n = (1usize << 24) + 4_321;
    let keys: Vec<[u32; 2]> = (0..n).map(|_| [rng.random(), rng.random_range(0..256)]).collect();
    check_sort(&d, &mut sort, &keys, 40, "16M+ (texel views)");
    sort.set_texel_inputs(false).unwrap();
    check_sort(&d, &mut sort, &keys, 40, "16M+ (device addresses)");
    assert_no_validation_messages(&d);
}

/// Sorts `keys` and `values` with `packing`; checks them against std's stable
/// sort on the low `bits` bits, every key and value carried along, and the
/// keys' first digit zeroed exactly when the sort packed (`want_packed`).
fn check_packed_sort(
    d: &Device,
    sort: &mut RadixSort,
    (keys, values): (&[[u32; 2]], &[u32]),
    bits: u32,
    packing: PairPacking,
    want_packed: bool,
    label: &str,
) {
    let n = keys.len();
    let kb = d.upload("keys", keys).unwrap();
    let vb = d.upload("values", values).unwrap();
    sort.reserve(d, n as u64).unwrap();
    d.run(|rec| sort.record_with(rec, &kb, &vb, n as u64, bits, Some(packing))).unwrap();
    let (got_keys, got_values): (Vec<[u32; 2]>, Vec<u32>) = (d.read_buffer(&kb).unwrap(), d.read_buffer(&vb).unwrap());
    let key64 = |k: [u32; 2]| u64::from(k[1]) << 32 | u64::from(k[0]);
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by_key(|&i| key64(keys[i]) & ((1u64 << bits) - 1)); // std's stable sort
                                                                   // The first digit: passes as few as the width allows, the bits spread evenly (wider first).
    let width = sort.digits().max_bits();
    let first_digit = bits.div_ceil(bits.div_ceil(width));
    let zeroed = if want_packed { (1u64 << first_digit) - 1 } else { 0 };
    for (at, &i) in order.iter().enumerate() {
        let want = (key64(keys[i]) & !zeroed, values[i]);
        let got = (key64(got_keys[at]), got_values[at]);
        assert_eq!(got, want, "{label}: pair {at} of {n} (from {i}), packed: {want_packed}");
    }
}

#[test]
fn packed_radix_sort_matches_std_sort() {
    let d = device();
    let mut rng = Pcg64Mcg::seed_from_u64(4);
    // Keys of `bits` random sort bits and `high` random top bits, zero between; values of `value_bits` bits.
    let mut pairs = |n: usize, bits: u32, high: u32, value_bits: u32| -> (Vec<[u32; 2]>, Vec<u32>) {
        let sort_mask = (1u64 << bits) - 1;
        let high_mask = if high == 0 { 0 } else { u64::MAX << (64 - high) };
        let value_mask = if value_bits == 32 { u32::MAX } else { (1u32 << value_bits) - 1 };
        // Few distinct sort keys in half the cases, so stability shows.
        let spread = if n % 2 == 0 { sort_mask } else { 7 };
        (0..n)
            .map(|_| {
                let key = (rng.random::<u64>() & sort_mask & spread) | (rng.random::<u64>() & high_mask);
                ([key as u32, (key >> 32) as u32], rng.random::<u32>() & value_mask)
            })
            .unzip()
    };
    let mut sorts: Vec<(String, RadixSort)> = Vec::new();
    for (items, texel) in [(256, true), (64, false)] {
        let mut sort = RadixSort::with_items(&d, items).unwrap();
        sort.set_texel_inputs(texel).unwrap();
        sorts.push((format!("4-bit digits, texel {texel}"), sort));
    }
    if wide_digits_supported(d.info()) {
        let mut sort = RadixSort::new(&d).unwrap();
        sort.set_digits(&d, SortDigits::Wide).unwrap();
        sorts.push(("wide digits".into(), sort));
    }
    let mut block = RadixSort::with_items(&d, 64).unwrap();
    block.set_digits(&d, SortDigits::Block).unwrap();
    sorts.push(("block digits".into(), block));
    for (name, sort) in &mut sorts {
        assert!(!sort.packing(), "{name}: packing is off until asked for");
        sort.set_packing(&d, true).unwrap();
        assert!(sort.packing());
        let width = sort.digits().max_bits();
        // (bits, high bits, value bits): the splat frame's 31 and 33 bits with 16-bit row masks
        // and 20- or 24-bit splat indices, whole 32-bit values, a key reaching bit 63, two passes.
        for (bits, high, value_bits) in [(31, 16, 20), (33, 16, 24), (31, 0, 32), (48, 16, 4), (2 * width, 32, 1)] {
            let packing = PairPacking { unused_low_bits: bits, value_bits, high_bits: high };
            let first_digit = bits.div_ceil(bits.div_ceil(width));
            let packable = bits.div_ceil(width) >= 2 && packing.fits(bits, first_digit);
            for n in [0usize, 1, 2, 3, 5, 1025, 30_001, 100_004] {
                let label = format!("{name}, {n} pairs on {bits} bits, {high} high, {value_bits}-bit values");
                let (keys, values) = pairs(n, bits, high, value_bits);
                check_packed_sort(&d, sort, (&keys, &values), bits, packing, packable && n > 1, &label);
            }
        }
        // Where the packing does not fit (the first digit is read after the sort; the word
        // would need 65 bits), or one pass sorts everything, the pairs move whole.
        let (keys, values) = pairs(20_000, 31, 16, 24);
        let low_read = PairPacking { unused_low_bits: 3, value_bits: 24, high_bits: 16 };
        check_packed_sort(&d, sort, (&keys, &values), 31, low_read, false, &format!("{name}, low bits read"));
        let (keys, values) = pairs(20_000, 31, 16, 32);
        let too_wide = PairPacking { unused_low_bits: 31, value_bits: 32, high_bits: 16 };
        check_packed_sort(&d, sort, (&keys, &values), 31, too_wide, false, &format!("{name}, 65-bit words"));
        let (keys, values) = pairs(20_000, width, 16, 24);
        let one_pass = PairPacking { unused_low_bits: width, value_bits: 24, high_bits: 16 };
        check_packed_sort(&d, sort, (&keys, &values), width, one_pass, false, &format!("{name}, one pass"));
        // Off again: whole pairs.
        sort.set_packing(&d, false).unwrap();
        let (keys, values) = pairs(20_000, 31, 16, 20);
        let fits = PairPacking { unused_low_bits: 31, value_bits: 20, high_bits: 16 };
        check_packed_sort(&d, sort, (&keys, &values), 31, fits, false, &format!("{name}, packing off"));
    }
    // Turned on after a reserve: recording is refused until the next reserve sizes the scratch.
    let mut sort = RadixSort::with_items(&d, 256).unwrap();
    sort.reserve(&d, 1000).unwrap();
    sort.set_packing(&d, true).unwrap();
    let (kb, vb) = (d.upload("keys", &[[0u32; 2]; 1000]).unwrap(), d.upload("values", &[0u32; 1000]).unwrap());
    let packing = PairPacking { unused_low_bits: 31, value_bits: 10, high_bits: 0 };
    let refused = d.run(|rec| sort.record_with(rec, &kb, &vb, 1000, 31, Some(packing)));
    assert!(refused.is_err(), "a packed sort before its reserve must be refused: {refused:?}");
    assert_no_validation_messages(&d);
}

#[test]
fn pair_packing_fits_only_words_of_64_bits_that_drop_unread_bits() {
    let splat = PairPacking { unused_low_bits: 21, value_bits: 24, high_bits: 16 };
    assert!(splat.fits(31, 11) && splat.fits(33, 11));
    assert!(!splat.fits(31, 4), "27 + 24 + 16 bits");
    assert!(PairPacking { value_bits: 20, ..splat }.fits(31, 4), "27 + 20 + 16 bits");
    assert!(!splat.fits(31, 22), "the first digit reaches bits read after the sort");
    assert!(!splat.fits(40, 11), "29 + 24 + 16 bits");
    assert!(!splat.fits(11, 11), "nothing left to sort after the first digit");
    assert!(!splat.fits(49, 4), "the sort bits overlap the kept top bits");
    assert!(PairPacking { unused_low_bits: 64, value_bits: 32, high_bits: 0 }.fits(43, 11));
    assert!(!PairPacking { unused_low_bits: 64, value_bits: 33, high_bits: 0 }.fits(20, 10), "values over 32 bits");
}
