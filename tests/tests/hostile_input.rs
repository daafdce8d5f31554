//! Hostile files: small inputs that declare huge sizes, endless streams and
//! wrapping arithmetic. Each is refused with a message naming the file and
//! what it declared, before anything is allocated for it (issue 39's
//! reproductions, one test each). Runs with the default limits
//! (`srug::io::Limits::DEFAULT`); none of these tests changes them.
#![allow(clippy::unwrap_used, reason = "a failed unwrap is a failed test")]

use srug::indirect::UNetWeights;
use srug::io::ktx::{encode_float_chain, read_environment, read_float_chain, FloatChain};
use srug::io::{read_cameras_json, read_ply, write_exr_channels, EnvironmentMap};
use srug::scene::demo::{demo_city, DemoOptions};
use srug::shade::PreparedEnvironment;
use srug_tests::{assert_no_validation_messages, device};

/// KTX2 header fields (little-endian u32 at these byte offsets).
const KTX_WIDTH: usize = 20;
const KTX_HEIGHT: usize = 24;
const KTX_FACES: usize = 36;

fn put_u32(bytes: &mut [u8], at: usize, v: u32) {
    bytes[at..at + 4].copy_from_slice(&v.to_le_bytes());
}

fn small_chain(zstd: bool, width: u32, height: u32, value: f32) -> Vec<u8> {
    let texels = vec![value; (width * height * 3) as usize];
    let chain = FloatChain { width, height, channels: 3, levels: vec![&texels], metadata: vec![] };
    encode_float_chain(&chain, zstd).unwrap()
}

fn err_of<T>(r: srug::Result<T>) -> String {
    match r {
        Ok(_) => panic!("hostile input was accepted"),
        Err(e) => e.to_string(),
    }
}

/// A 2^30 × 2^30 cube (the size product wraps to 0 in unchecked arithmetic)
/// and a 2^31 one are refused by the side limit before any level is read.
#[test]
fn ktx2_cube_with_wrapping_size_is_refused() {
    for side in [1u32 << 30, 1 << 31] {
        let mut bytes = small_chain(false, 4, 4, 1.0);
        put_u32(&mut bytes, KTX_WIDTH, side);
        put_u32(&mut bytes, KTX_HEIGHT, side);
        put_u32(&mut bytes, KTX_FACES, 6);
        let e = err_of(read_environment(&bytes, "cube.ktx2"));
        assert!(e.contains("cube.ktx2") && e.contains("side limit"), "{e}");
    }
}

/// A zstd level that inflates far past what its header declares stops one
/// byte past the declared size, and a file declaring more than it holds is refused.
#[test]
fn ktx2_zstd_bomb_is_bounded() {
    // 1024 × 512 RGB f32 of zeros: 6 MiB that compress to a few KiB.
    let mut bytes = small_chain(true, 1024, 512, 0.0);
    assert!(bytes.len() < 64 << 10, "the bomb is small: {} bytes", bytes.len());
    put_u32(&mut bytes, KTX_WIDTH, 16);
    put_u32(&mut bytes, KTX_HEIGHT, 8);
    let e = err_of(read_environment(&bytes, "bomb.ktx2"));
    assert!(e.contains("bomb.ktx2") && e.contains("inflates past"), "{e}");
    let e = err_of(read_float_chain(&bytes, "bomb.ktx2"));
    assert!(e.contains("inflates past"), "{e}");
    // Declaring 16384 × 8192 (within the limits) over the same small stream:
    // decoding stops where the data ends, far below the declared 1.5 GiB.
    let mut bytes = small_chain(true, 1024, 512, 0.0);
    put_u32(&mut bytes, KTX_WIDTH, 16384);
    put_u32(&mut bytes, KTX_HEIGHT, 8192);
    let e = err_of(read_environment(&bytes, "short.ktx2"));
    assert!(e.contains("bytes") && e.contains("expected"), "{e}");
}

/// An OpenEXR header whose data window is 100000² (and 1e9²) is refused
/// before a pixel is decoded.
#[test]
fn exr_with_huge_data_window_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("tiny.exr");
    write_exr_channels(&path, 1, 1, &[("rgb", &[0.5f32; 3], 3)]).unwrap();
    let clean = std::fs::read(&path).unwrap();
    let key = b"dataWindow\0box2i\0";
    let at = clean.windows(key.len()).position(|w| w == key).unwrap() + key.len() + 4;
    for max in [99_999i32, 999_999_999] {
        let mut bytes = clean.clone();
        bytes[at + 8..at + 12].copy_from_slice(&max.to_le_bytes());
        bytes[at + 12..at + 16].copy_from_slice(&max.to_le_bytes());
        let hostile = dir.path().join("huge.exr");
        std::fs::write(&hostile, &bytes).unwrap();
        let e = err_of(EnvironmentMap::load(&hostile));
        let side = i64::from(max) + 1;
        let want = format!("data window declares {side}x{side} texels, more than the 16384-texel side limit");
        assert!(e.contains("huge.exr") && e.contains(&want), "{e}");
    }
    let clean_read = EnvironmentMap::load(&path);
    assert!(clean_read.is_ok(), "the unpatched file reads: {:?}", clean_read.err());
}

/// A 73-byte Radiance file declaring 1000000 × 1000000 is refused by its header.
#[test]
fn hdr_with_huge_header_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("huge.hdr");
    let mut bytes = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 1000000 +X 1000000\n".to_vec();
    bytes.extend([128u8; 16]);
    std::fs::write(&path, &bytes).unwrap();
    let e = err_of(EnvironmentMap::load(&path));
    assert!(e.contains("huge.hdr") && e.contains("side limit"), "{e}");
}

/// Safetensors metadata declaring 2^64−1 or 40 million channels is refused
/// as it is parsed, naming the key.
#[test]
fn safetensors_with_huge_widths_is_refused() {
    for (key, value) in
        [("in_channels", "18446744073709551615"), ("in_channels", "40000000"), ("widths", "8,16,32,64,40000000")]
    {
        let header = format!("{{\"__metadata__\":{{\"{key}\":\"{value}\"}}}}");
        let mut bytes = (header.len() as u64).to_le_bytes().to_vec();
        bytes.extend(header.as_bytes());
        let e = err_of(UNetWeights::from_bytes(&bytes, "net.safetensors"));
        assert!(e.contains("net.safetensors") && e.contains(key) && e.contains("limit"), "{e}");
    }
}

/// Endless streams (a link named like a scene, a map or weights pointing at
/// `/dev/zero`) are refused before a byte is read.
#[cfg(unix)]
#[test]
fn endless_streams_are_refused_by_every_loader() {
    let dir = tempfile::tempdir().unwrap();
    let link = |name: &str| {
        let p = dir.path().join(name);
        std::os::unix::fs::symlink("/dev/zero", &p).unwrap();
        p
    };
    let check = |e: String, name: &str| assert!(e.contains(name) && e.contains("not a regular file"), "{e}");
    check(err_of(read_ply(link("scene.ply"))), "scene.ply");
    check(err_of(read_cameras_json(link("cameras.json"))), "cameras.json");
    for name in ["sky.exr", "sky.hdr", "sky.ktx2"] {
        check(err_of(EnvironmentMap::load(link(name))), name);
    }
    check(err_of(UNetWeights::load(link("net.safetensors"))), "net.safetensors");
}

/// A PLY header or a demo request for 2^40 (or usize::MAX) Gaussians is
/// refused before anything is allocated.
#[test]
fn huge_gaussian_counts_are_refused() {
    for gaussians in [1usize << 40, usize::MAX] {
        let e = err_of(demo_city(&DemoOptions { seed: 1, gaussians, sh_degree: 1 }));
        assert!(e.contains("Gaussians") && e.contains("limit"), "{e}");
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("huge.ply");
    let header = "ply\nformat binary_little_endian 1.0\nelement vertex 1099511627776\nproperty float x\nend_header\n";
    std::fs::write(&path, header).unwrap();
    let e = err_of(read_ply(&path));
    assert!(e.contains("huge.ply") && e.contains("limit"), "{e}");
}

/// A prepared environment folder whose specular chain declares wrapping
/// sizes is refused at load (it used to load and make the next render read
/// out of bounds).
#[test]
fn prepared_environment_with_wrapping_sizes_is_refused() {
    let d = device();
    let dir = tempfile::tempdir().unwrap();
    let mut spec = small_chain(false, 8, 4, 1.0);
    put_u32(&mut spec, KTX_WIDTH, 1 << 30);
    put_u32(&mut spec, KTX_HEIGHT, 1 << 30);
    std::fs::write(dir.path().join("specular.ktx2"), &spec).unwrap();
    std::fs::write(dir.path().join("irradiance.ktx2"), small_chain(false, 4, 2, 1.0)).unwrap();
    let e = err_of(PreparedEnvironment::load(&d, dir.path()));
    assert!(e.contains("specular.ktx2") && e.contains("side limit"), "{e}");
    assert_no_validation_messages(&d);
}

/// cameras.json values finite in f64 but not in f32 (a focal length or a
/// position of 1e39) are refused at load, naming the file and the camera; an
/// empty list is refused too.
#[test]
fn cameras_that_overflow_f32_are_refused_at_load() {
    let camera = |fx: f64, x: f64| {
        format!(
            "{{\"id\": 0, \"img_name\": \"street_07\", \"width\": 64, \"height\": 32, \"position\": [{x}, 0, 1], \
             \"rotation\": [[1, 0, 0], [0, 1, 0], [0, 0, 1]], \"fx\": {fx}, \"fy\": 40}}"
        )
    };
    for (text, words) in [
        (format!("[{}]", camera(1e39, 0.0)), ["street_07", "focal lengths"]),
        (format!("[{}, {}]", camera(40.0, 0.0), camera(40.0, 1e39)), ["street_07", "position"]),
        ("[]".to_string(), ["cams.json", "no camera"]),
    ] {
        let e = srug::io::parse_cameras_json(&text, "cams.json").unwrap_err().to_string();
        assert!(e.contains("cams.json") && words.iter().all(|w| e.contains(w)), "{e}");
    }
    assert!(srug::io::parse_cameras_json(&format!("[{}]", camera(40.0, 3.0)), "ok.json").is_ok());
}

/// EXR output is byte-identical run to run (blocks written in increasing
/// order even by the parallel writer).
#[test]
fn exr_output_is_byte_reproducible() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (300u32, 200u32);
    let rgb: Vec<f32> = (0..3 * w * h).map(|i| ((i * 7919) % 1000) as f32 / 1000.0).collect();
    let depth: Vec<f32> = (0..w * h).map(|i| (i % 977) as f32).collect();
    let mut files = Vec::new();
    for run in 0..3 {
        let path = dir.path().join(format!("run{run}.exr"));
        write_exr_channels(&path, w, h, &[("rgb", &rgb, 3), ("depth", &depth, 1)]).unwrap();
        files.push(std::fs::read(&path).unwrap());
    }
    assert!(files.windows(2).all(|p| p[0] == p[1]), "EXR bytes differ between runs");
}

/// Radiance near f32's maximum (finite, so not refused) is clamped to
/// `MAX_RADIANCE` at load, and prefiltering it stays finite (it used to write
/// Inf into the prepared chain).
#[test]
fn near_maximal_radiance_stays_finite_through_prefiltering() {
    use srug::io::environment::MAX_RADIANCE;
    use srug::shade::{EnvironmentPrep, PrepareSettings};
    let (w, h) = (64u32, 32u32);
    let rgb: Vec<f32> = (0..3 * w * h).map(|i| if i % 5 == 0 { 3.0e38 } else { 1.0 }).collect();
    let map = EnvironmentMap::from_rgb(w, h, rgb, "bright.hdr").unwrap();
    assert_eq!(map.max_value(), MAX_RADIANCE);
    let d = device();
    let prepared = EnvironmentPrep::new(&d).unwrap().prepare(&map, &PrepareSettings::default()).unwrap();
    let levels = prepared.read_specular(&d).unwrap();
    assert!(levels.iter().flatten().all(|v| v.is_finite() && *v >= 0.0), "non-finite prefiltered radiance");
    let irradiance: Vec<f32> = d.read_buffer(&prepared.irradiance).unwrap();
    assert!(irradiance.iter().all(|v| v.is_finite()), "non-finite irradiance");
    assert_no_validation_messages(&d);
}

/// A KTX2 descriptor with a texel block dimension byte of 255 made the ktx2
/// crate (0.5.0) panic on an u8 overflow (found by the fuzz smoke run); it is
/// refused before the crate parses it.
#[test]
fn ktx2_descriptor_that_panics_the_parser_is_refused() {
    let mut bytes = small_chain(false, 4, 2, 1.0);
    let dfd = u32::from_le_bytes(bytes[48..52].try_into().unwrap()) as usize;
    bytes[dfd + 4 + 12] = 255;
    for e in [err_of(read_environment(&bytes, "dfd.ktx2")), err_of(read_float_chain(&bytes, "dfd.ktx2").map(|_| ()))] {
        assert!(e.contains("dfd.ktx2") && e.contains("256-texel"), "{e}");
    }
}

/// A file named as one format but holding another is reported as such.
#[test]
fn environment_extension_and_content_must_agree() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sky.exr");
    std::fs::write(&path, small_chain(false, 4, 2, 1.0)).unwrap();
    let e = err_of(EnvironmentMap::load(&path));
    assert!(e.contains("sky.exr") && e.contains("named .exr but holds KTX2"), "{e}");
    assert!(EnvironmentMap::from_bytes(&std::fs::read(&path).unwrap(), "mem").is_ok(), "detected from content");
}

/// A DWAB chunk whose counters declare a 17 TB AC section (a mutation of
/// the shared sunset map, found by the long fuzz run) made the exr crate abort
/// allocating; the counters are checked against the chunk's pixels first.
#[test]
fn exr_dwa_chunk_with_huge_counters_is_refused() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("data/dwab_huge_ac_count.exr");
    let e = err_of(EnvironmentMap::from_bytes(&std::fs::read(&path).unwrap(), "dwab.exr"));
    assert!(e.contains("dwab.exr") && e.contains("DWA-compressed chunk declares"), "{e}");
    // The real DWAB maps it came from still read.
    match shared_hdri() {
        Some(dir) => {
            for name in ["city.exr", "sunrise.exr", "sunset.exr"] {
                let m = EnvironmentMap::load(dir.join(name)).unwrap();
                assert_eq!((m.width, m.height), (1024, 512), "{name}");
            }
        }
        None => println!("skipped the shared maps: ../shared/data is absent"),
    }
}

fn shared_hdri() -> Option<std::path::PathBuf> {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/hdri");
    dir.is_dir().then_some(dir)
}
