#![no_main]
//! cargo-fuzz target `camera_files`: `srug_tests::fuzz::camera_files` under the fuzz limits.

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    static LIMITS: std::sync::Once = std::sync::Once::new();
    LIMITS.call_once(|| srug::io::set_limits(srug_tests::fuzz::fuzz_limits()));
    srug_tests::fuzz::camera_files(data);
});
