//! Fuzz targets for every loader, shared by the cargo-fuzz harness
//! (`fuzz/`, long runs on nightly) and the fixed-seed smoke run in the test
//! suite (`tests/tests/fuzz_smoke.rs`, stable). A target feeds bytes to one
//! loader: an error is the expected answer to junk, a panic is a finding, and
//! an accepted input must satisfy the loader's invariants (checked here).

#![allow(clippy::expect_used, reason = "test support: seeds made by srug's own writers must succeed")]

use srug::indirect::{UNetConfig, UNetWeights};
use srug::io::ktx::{encode_float_chain, read_environment, read_float_chain, FloatChain};
use srug::io::{parse_cameras_json, read_ply_bytes, write_cameras_json, write_exr_channels, write_ply, PlyFormat};
use srug::io::{EnvironmentMap, Limits};
use srug::scene::Camera;

/// One fuzz target: its name (the cargo-fuzz target and corpus folder), the
/// function under test, and seed inputs written by srug's own writers.
pub struct Target {
    /// Name of the cargo-fuzz target and its corpus folder.
    pub name: &'static str,
    /// Feeds one input to the loader; panics only on a finding.
    pub run: fn(&[u8]),
    /// Valid inputs to start from.
    pub seeds: fn() -> Vec<Vec<u8>>,
}

/// Every target.
pub const TARGETS: &[Target] = &[
    Target { name: "ply", run: ply, seeds: ply_seeds },
    Target { name: "cameras", run: cameras, seeds: camera_seeds },
    Target { name: "environment", run: environment, seeds: environment_seeds },
    Target { name: "ktx2_chain", run: ktx2_chain, seeds: chain_seeds },
    Target { name: "safetensors", run: safetensors, seeds: weight_seeds },
    Target { name: "png", run: png, seeds: png_seeds },
    Target { name: "scenes", run: scenes, seeds: scene_seeds },
    Target { name: "camera_files", run: camera_files, seeds: camera_file_seeds },
];

/// Fuzzed inputs are held to smaller limits than the defaults, so a loader
/// that honours them cannot exhaust the fuzzer's memory.
pub fn fuzz_limits() -> Limits {
    Limits { max_image_side: 4096, max_decoded_bytes: 64 << 20, max_gaussians: 1 << 20, ..Limits::DEFAULT }
}

fn finite(v: &[f32]) -> bool {
    v.iter().all(|x| x.is_finite())
}

/// PLY scenes.
pub fn ply(data: &[u8]) {
    if let Ok(s) = read_ply_bytes(data, "fuzz.ply") {
        assert!(s.means.len() == s.len() && s.opacity_logits.len() == s.len(), "inconsistent scene");
        assert!(s.means.iter().flatten().all(|v| v.is_finite()), "non-finite mean accepted");
    }
}

/// Scenes in every format srug reads, detected from content.
pub fn scenes(data: &[u8]) {
    if let Ok(s) = srug::io::read_scene_bytes(data, "fuzz.scene") {
        assert!(s.validate("fuzz.scene").is_ok(), "a scene that fails validation accepted");
    }
}

/// COLMAP models and transforms.json. Byte 0 picks the form (0: COLMAP
/// binary, 1: COLMAP text, else transforms.json); for COLMAP, bytes 1-4 give
/// the length of the cameras file, the images file follows it.
pub fn camera_files(data: &[u8]) {
    if let Some(Ok(cams)) = parse_camera_files(data) {
        assert!(!cams.is_empty(), "an empty camera list accepted");
        for c in &cams {
            assert!(c.validate().is_ok(), "a camera that fails validation accepted");
        }
    }
}

/// What [`camera_files`] parses; `None` when the input selects nothing.
pub fn parse_camera_files(data: &[u8]) -> Option<Result<Vec<Camera>, srug::scene::SceneError>> {
    let (&form, rest) = data.split_first()?;
    if form < 2 {
        let len = rest.get(..4).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize)?;
        let rest = &rest[4..];
        let (c, i) = rest.split_at(len.min(rest.len()));
        Some(srug::io::parse_colmap(c, i, form == 0))
    } else {
        std::str::from_utf8(rest).ok().map(|text| srug::io::parse_transforms_json(text, "fuzz.json"))
    }
}

/// INRIA cameras.json.
pub fn cameras(data: &[u8]) {
    if let Ok(text) = std::str::from_utf8(data) {
        if let Ok(cams) = parse_cameras_json(text, "fuzz.json") {
            assert!(!cams.is_empty(), "an empty list accepted");
            for c in &cams {
                assert!(c.validate().is_ok(), "a camera that fails validation accepted");
            }
        }
    }
}

/// Environment maps: OpenEXR, Radiance .hdr and KTX2 (2D or cube), by content.
pub fn environment(data: &[u8]) {
    let map = EnvironmentMap::from_bytes(data, "fuzz.env");
    if let Ok(m) = map {
        assert_eq!(m.rgb.len(), 3 * m.width as usize * m.height as usize, "size disagrees with texels");
        assert!(finite(&m.rgb) && m.rgb.iter().all(|v| *v >= 0.0), "non-finite or negative radiance accepted");
    }
    // KTX2 bytes also through the KTX2 reader directly (same checks).
    if let Ok(m) = read_environment(data, "fuzz.ktx2") {
        assert!(finite(&m.rgb), "non-finite KTX2 radiance accepted");
    }
}

/// KTX2 float chains (prepared environments and BRDF tables).
pub fn ktx2_chain(data: &[u8]) {
    if let Ok(c) = read_float_chain(data, "fuzz.ktx2") {
        assert!(!c.levels.is_empty(), "a chain without levels accepted");
        assert!(c.levels.iter().all(|l| finite(l)), "non-finite chain value accepted");
    }
}

/// U-Net weights (safetensors).
pub fn safetensors(data: &[u8]) {
    if let Ok(w) = UNetWeights::from_bytes(data, "fuzz.safetensors") {
        assert_eq!(w.layers.len(), 10, "a network without its ten layers accepted");
    }
}

/// PNG images (`srug eval` inputs).
pub fn png(data: &[u8]) {
    if let Ok(img) = srug::metrics::read_png_bytes(data, "fuzz.png") {
        assert_eq!(img.rgb.len(), 3 * img.width as usize * img.height as usize, "size disagrees with pixels");
        assert!(finite(&img.rgb), "non-finite pixel accepted");
    }
}

fn png_seeds() -> Vec<Vec<u8>> {
    let rgb: Vec<f32> = (0..3 * 8 * 4).map(|i| (i % 7) as f32 / 7.0).collect();
    vec![temp_file("seed.png", |p| srug::io::write_png(p, 8, 4, &rgb).expect("PNG written"))]
}

fn temp_file(name: &str, write: impl FnOnce(&std::path::Path)) -> Vec<u8> {
    let dir = tempfile::tempdir().expect("a temporary folder");
    let path = dir.path().join(name);
    write(&path);
    std::fs::read(&path).expect("the file just written")
}

fn ply_seeds() -> Vec<Vec<u8>> {
    let scene = crate::random_scene(5, 1, 3, 2.0);
    [PlyFormat::BinaryLittleEndian, PlyFormat::Ascii]
        .into_iter()
        .map(|f| temp_file("seed.ply", |p| write_ply(p, &scene, f).expect("PLY written")))
        .collect()
}

fn scene_seeds() -> Vec<Vec<u8>> {
    let scene = crate::random_scene(5, 1, 3, 2.0);
    let mut seeds: Vec<Vec<u8>> = srug::io::SceneFormat::ALL
        .into_iter()
        .filter(|f| f.writable())
        .map(|f| srug::io::encode_scene(&scene, f).expect("scene encoded"))
        .collect();
    // Formats srug does not write, as other tools wrote them (tests/data/formats).
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("data/formats");
    for name in ["st.v2.spz", "st.v3.spz", "st.sog"] {
        seeds.push(std::fs::read(dir.join(name)).expect("format fixture"));
    }
    seeds
}

fn camera_file_seeds() -> Vec<Vec<u8>> {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("data/cameras");
    let read = |p: &str| std::fs::read(dir.join(p)).expect("camera fixture");
    let pair = |form: u8, c: Vec<u8>, i: Vec<u8>| {
        let mut v = vec![form];
        v.extend_from_slice(&(c.len() as u32).to_le_bytes());
        v.extend(c);
        v.extend(i);
        v
    };
    vec![
        pair(0, read("colmap/bin/cameras.bin"), read("colmap/bin/images.bin")),
        pair(1, read("colmap/text/cameras.txt"), read("colmap/text/images.txt")),
        [vec![2u8], read("transforms.json")].concat(),
    ]
}

fn camera_seeds() -> Vec<Vec<u8>> {
    let cam = Camera::look_at(glam::Vec3::new(1.0, 2.0, 3.0), glam::Vec3::ZERO, glam::Vec3::Z, 60.0, 64, 32)
        .expect("a camera");
    let cams = [Camera { name: "a".into(), ..cam.clone() }, Camera { name: "b".into(), ..cam }];
    vec![temp_file("cameras.json", |p| write_cameras_json(p, &cams).expect("cameras written"))]
}

fn small_chain(channels: usize, zstd: bool, levels: usize) -> Vec<u8> {
    let (w, h) = (8u32, 4u32);
    let data: Vec<Vec<f32>> = (0..levels)
        .map(|l| {
            let n = ((w >> l).max(1) * (h >> l).max(1)) as usize * channels;
            (0..n).map(|i| i as f32 * 0.25).collect()
        })
        .collect();
    let chain = FloatChain {
        width: w,
        height: h,
        channels,
        levels: data.iter().map(Vec::as_slice).collect(),
        metadata: vec![("srug.kind".into(), "specular".into())],
    };
    encode_float_chain(&chain, zstd).expect("a chain")
}

fn environment_seeds() -> Vec<Vec<u8>> {
    let rgb: Vec<f32> = (0..3 * 8 * 4).map(|i| i as f32 * 0.1).collect();
    let exr = temp_file("seed.exr", |p| write_exr_channels(p, 8, 4, &[("rgb", &rgb, 3)]).expect("EXR written"));
    // A flat (uncompressed-scanline) Radiance file: header, then 4 × RGBE per pixel.
    let mut hdr = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 2 +X 4\n".to_vec();
    hdr.extend((0..8).flat_map(|i| [100 + i as u8, 90, 80, 128]));
    vec![exr, hdr, small_chain(3, false, 1), small_chain(3, true, 1)]
}

fn chain_seeds() -> Vec<Vec<u8>> {
    vec![small_chain(3, false, 3), small_chain(2, true, 2), small_chain(4, false, 1)]
}

fn weight_seeds() -> Vec<Vec<u8>> {
    let config = UNetConfig { widths: [2, 2, 2, 2, 2], ..UNetConfig::default() };
    vec![UNetWeights::random(config, 1).to_bytes().expect("weights serialized")]
}

/// Deterministic mutations of `seed` for the smoke run: bit flips, byte
/// overwrites with boundary values, truncation, duplication and splices of a
/// declared-size field's neighbourhood.
pub fn mutate(seed: &[u8], rng: &mut impl rand::Rng) -> Vec<u8> {
    let mut v = seed.to_vec();
    let edits = rng.random_range(1..=4);
    for _ in 0..edits {
        if v.is_empty() {
            v.push(rng.random());
            continue;
        }
        let at = rng.random_range(0..v.len());
        match rng.random_range(0..7) {
            0 => v[at] ^= 1 << rng.random_range(0..8),
            1 => v[at] = [0x00, 0xff, 0x7f, 0x80, 0x01][rng.random_range(0..5)],
            2 => {
                let word: [u8; 4] =
                    [u32::MAX, 0x8000_0000, 0x7fff_ffff, 1 << 30, 0][rng.random_range(0..5)].to_le_bytes();
                let end = (at + 4).min(v.len());
                v[at..end].copy_from_slice(&word[..end - at]);
            }
            3 => v.truncate(at),
            4 => {
                let end = rng.random_range(at..=v.len().min(at + 64));
                let chunk = v[at..end].to_vec();
                v.splice(at..at, chunk);
            }
            5 => {
                let n = rng.random_range(1..=v.len().min(16));
                v.drain(at..(at + n).min(v.len()));
            }
            _ => v.insert(at, rng.random()),
        }
    }
    v
}
