//! Small scene files that claim huge counts are refused before srug
//! allocates for them: a counting allocator measures the peak the reader
//! reaches above its start. One test, so nothing else runs in this process
//! while it measures.
#![allow(clippy::unwrap_used, reason = "a failed unwrap is a failed test")]

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

use srug::io::{encode_scene, read_scene_as, SceneFormat};

struct Counting;

static CURRENT: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

// SAFETY: forwards to the system allocator; only counts.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let now = CURRENT.fetch_add(layout.size(), Ordering::SeqCst) + layout.size();
        PEAK.fetch_max(now, Ordering::SeqCst);
        // SAFETY: the caller's layout contract is passed on unchanged.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        CURRENT.fetch_sub(layout.size(), Ordering::SeqCst);
        // SAFETY: `ptr` came from `alloc` with this layout.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// Reads `bytes` as `format`, expecting a refusal; returns the message and the peak bytes allocated meanwhile.
fn measure(bytes: &[u8], format: SceneFormat, origin: &str) -> (String, usize) {
    let base = CURRENT.load(Ordering::SeqCst);
    PEAK.store(base, Ordering::SeqCst);
    let result = read_scene_as(bytes, format, origin);
    let peak = PEAK.load(Ordering::SeqCst) - base;
    match result {
        Ok(s) => panic!("{origin}: a bomb was accepted ({} Gaussians)", s.len()),
        Err(e) => (e.to_string(), peak),
    }
}

fn put_u32(bytes: &mut [u8], at: usize, v: u32) {
    bytes[at..at + 4].copy_from_slice(&v.to_le_bytes());
}

fn put_u64(bytes: &mut [u8], at: usize, v: u64) {
    bytes[at..at + 8].copy_from_slice(&v.to_le_bytes());
}

const BUDGET: usize = 16 << 20;

#[test]
fn small_files_claiming_huge_counts_are_refused_before_allocating() {
    let scene = srug_tests::random_scene(100, 1, 5, 10.0);
    let spz = encode_scene(&scene, SceneFormat::Spz).unwrap();
    // The counter sees a real decode: 100 Gaussians of degree 1 take more than 10 KB.
    let base = CURRENT.load(Ordering::SeqCst);
    PEAK.store(base, Ordering::SeqCst);
    assert_eq!(read_scene_as(&spz, SceneFormat::Spz, "ok.spz").unwrap().len(), 100);
    assert!(PEAK.load(Ordering::SeqCst) - base > 10_000, "the counting allocator saw no allocation");

    // Billions of points: over the Gaussian limit.
    let mut billions = spz.clone();
    put_u32(&mut billions, 8, u32::MAX);
    let (e, peak) = measure(&billions, SceneFormat::Spz, "billions.spz");
    assert!(e.contains("numPoints") && e.contains("limit"), "{e}");
    assert!(peak < BUDGET, "peak {peak} bytes");

    // 150 million points (inside the limit) with the table of contents made to agree:
    // the streams are far too short, found without inflating 9 GB.
    let n = 150_000_000u64;
    let mut claimed = spz.clone();
    put_u32(&mut claimed, 8, n as u32);
    for (s, per) in [9u64, 1, 3, 3, 4, 9].iter().enumerate() {
        put_u64(&mut claimed, 32 + 16 * s + 8, n * per);
    }
    let (e, peak) = measure(&claimed, SceneFormat::Spz, "claimed.spz");
    assert!(e.contains("claimed.spz") && e.contains("SPZ"), "{e}");
    assert!(peak < BUDGET, "peak {peak} bytes: {e}");

    // A legacy gzip stream whose header claims 150 million points.
    let legacy = {
        use std::io::Write;
        let mut raw = vec![0u8; 16];
        raw[..4].copy_from_slice(b"NGSP");
        put_u32(&mut raw, 4, 2);
        put_u32(&mut raw, 8, n as u32);
        raw[13] = 12;
        raw.extend(std::iter::repeat_n(7u8, 4096));
        let mut w = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
        w.write_all(&raw).unwrap();
        w.finish().unwrap()
    };
    let (e, peak) = measure(&legacy, SceneFormat::Spz, "legacy.spz");
    assert!(e.contains("truncated"), "{e}");
    assert!(peak < BUDGET, "peak {peak} bytes");

    // A compressed PLY header declaring 150 million vertices over a few bytes.
    let cply = format!(
        "ply\nformat binary_little_endian 1.0\nelement chunk {}\n{}element vertex {n}\n{}end_header\n",
        n.div_ceil(256),
        [
            "min_x",
            "min_y",
            "min_z",
            "max_x",
            "max_y",
            "max_z",
            "min_scale_x",
            "min_scale_y",
            "min_scale_z",
            "max_scale_x",
            "max_scale_y",
            "max_scale_z"
        ]
        .map(|p| format!("property float {p}\n"))
        .concat(),
        ["packed_position", "packed_rotation", "packed_scale", "packed_color"]
            .map(|p| format!("property uint {p}\n"))
            .concat(),
    );
    let (e, peak) = measure(cply.as_bytes(), SceneFormat::CompressedPly, "big.compressed.ply");
    assert!(e.contains("truncated"), "{e}");
    assert!(peak < BUDGET, "peak {peak} bytes");

    // A GLB whose accessors claim 150 million elements.
    let glb = encode_scene(&scene, SceneFormat::Glb).unwrap();
    let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    let mut json: serde_json::Value = serde_json::from_slice(&glb[20..20 + json_len]).unwrap();
    for a in json["accessors"].as_array_mut().unwrap() {
        a["count"] = serde_json::json!(n);
    }
    let mut text = serde_json::to_vec(&json).unwrap();
    while text.len() % 4 != 0 {
        text.push(b' ');
    }
    let bin = &glb[20 + json_len..];
    let mut big = Vec::new();
    big.extend_from_slice(b"glTF");
    big.extend_from_slice(&2u32.to_le_bytes());
    big.extend_from_slice(&((12 + 8 + text.len() + bin.len()) as u32).to_le_bytes());
    big.extend_from_slice(&(text.len() as u32).to_le_bytes());
    big.extend_from_slice(&0x4E4F_534Au32.to_le_bytes());
    big.extend_from_slice(&text);
    big.extend_from_slice(bin);
    let (e, peak) = measure(&big, SceneFormat::Glb, "big.glb");
    assert!(e.contains("150000000 elements do not fit"), "{e}");
    assert!(peak < BUDGET, "peak {peak} bytes");
    // An accessor without a buffer view (all zeros by glTF's rules) claiming as many.
    for a in json["accessors"].as_array_mut().unwrap() {
        a.as_object_mut().unwrap().remove("bufferView");
    }
    let zeros = serde_json::to_vec(&json).unwrap();
    let mut padded = zeros.clone();
    while padded.len() % 4 != 0 {
        padded.push(b' ');
    }
    let mut lazy = Vec::new();
    lazy.extend_from_slice(b"glTF");
    lazy.extend_from_slice(&2u32.to_le_bytes());
    lazy.extend_from_slice(&((12 + 8 + padded.len()) as u32).to_le_bytes());
    lazy.extend_from_slice(&(padded.len() as u32).to_le_bytes());
    lazy.extend_from_slice(&0x4E4F_534Au32.to_le_bytes());
    lazy.extend_from_slice(&padded);
    let (e, peak) = measure(&lazy, SceneFormat::Glb, "zeros.glb");
    assert!(e.contains("no buffer view"), "{e}");
    assert!(peak < BUDGET, "peak {peak} bytes");
}
