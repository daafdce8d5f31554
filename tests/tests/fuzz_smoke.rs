//! The fixed-seed fuzz smoke run: every loader's target (`srug_tests::fuzz`)
//! on its seeds and on deterministic mutations of them. A panic is a finding:
//! the input is written to `target/fuzz-findings/<target>-<n>.bin` and the
//! test fails. Long coverage-guided runs use the same targets through
//! cargo-fuzz (`scripts/fuzz.sh`, docs/testing.md).
#![allow(clippy::unwrap_used, reason = "a failed unwrap is a failed test")]

use rand::SeedableRng;
use srug_tests::fuzz::{fuzz_limits, mutate, TARGETS};

/// Mutated inputs per target: a few seconds each on the CI machine.
const MUTATIONS: usize = 200_000;

#[test]
fn every_loader_survives_mutated_inputs() {
    srug::io::set_limits(fuzz_limits());
    let quiet = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    let mut findings = Vec::new();
    for target in TARGETS {
        let seeds = (target.seeds)();
        assert!(!seeds.is_empty(), "{} has seeds", target.name);
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(0x5eed);
        let inputs = seeds.clone().into_iter().chain((0..MUTATIONS).map(|i| mutate(&seeds[i % seeds.len()], &mut rng)));
        for (n, input) in inputs.enumerate() {
            if std::panic::catch_unwind(|| (target.run)(&input)).is_err() {
                let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/fuzz-findings");
                std::fs::create_dir_all(&dir).unwrap();
                let path = dir.join(format!("{}-{n}.bin", target.name));
                std::fs::write(&path, &input).unwrap();
                findings.push(path.display().to_string());
            }
        }
    }
    std::panic::set_hook(quiet);
    assert!(findings.is_empty(), "loaders panicked on: {findings:?}");
}

/// The seeds themselves are accepted: the targets reach past the first check.
#[test]
fn every_seed_is_a_valid_input() {
    use srug::io::ktx::read_float_chain;
    for target in TARGETS {
        for seed in (target.seeds)() {
            let accepted = match target.name {
                "ply" => srug::io::read_ply_bytes(&seed, "seed").is_ok(),
                "cameras" => srug::io::parse_cameras_json(std::str::from_utf8(&seed).unwrap(), "seed").is_ok(),
                "environment" => srug::io::EnvironmentMap::from_bytes(&seed, "seed").is_ok(),
                "ktx2_chain" => read_float_chain(&seed, "seed").is_ok(),
                "safetensors" => srug::indirect::UNetWeights::from_bytes(&seed, "seed").is_ok(),
                "png" => srug::metrics::read_png_bytes(&seed, "seed").is_ok(),
                "scenes" => srug::io::read_scene_bytes(&seed, "seed").is_ok(),
                "camera_files" => matches!(srug_tests::fuzz::parse_camera_files(&seed), Some(Ok(_))),
                other => panic!("unknown target {other}"),
            };
            assert!(accepted, "a {} seed is refused", target.name);
        }
    }
}
