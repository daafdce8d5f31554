//! Every splat scene format against files another tool wrote.
//!
//! The fixtures in tests/data/formats (remade by scripts/format-fixtures.sh)
//! are the fixture scene (`source.ply`, written by srug) converted by
//! PlayCanvas splat-transform 2.7.1 (which runs Niantic's SPZ reference as
//! WASM) and decoded back to PLY by the same tool. Each test reads a fixture
//! with srug and compares every property with the other tool's decode, with
//! the tolerance stated beside it; round trips through srug's own writers are
//! held to the precision each format keeps (the table in docs/formats.md).
#![allow(clippy::unwrap_used, reason = "a failed unwrap is a failed test")]

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use srug::io::{encode_scene, read_scene, read_scene_bytes, SceneFormat};
use srug::scene::Scene;

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("data/formats").join(name)
}

/// The float columns of a binary little-endian PLY's vertex element, by name
/// (no validation: the other tool's decode may hold ±∞ logits).
fn columns(bytes: &[u8]) -> HashMap<String, Vec<f32>> {
    let end = bytes.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
    let header = std::str::from_utf8(&bytes[..end]).unwrap();
    let mut n = 0;
    let mut names = Vec::new();
    for line in header.lines() {
        let w: Vec<&str> = line.split_whitespace().collect();
        match w.as_slice() {
            ["element", "vertex", c] => n = c.parse().unwrap(),
            ["element", other, _] => panic!("unexpected element {other}"),
            ["property", "float", name] => names.push(name.to_string()),
            ["property", ty, name] => panic!("property {name} is {ty}"),
            _ => {}
        }
    }
    let row = names.len() * 4;
    let data = &bytes[end..end + n * row];
    names
        .iter()
        .enumerate()
        .map(|(j, name)| {
            let col = (0..n)
                .map(|i| {
                    let b = &data[i * row + 4 * j..];
                    f32::from_le_bytes([b[0], b[1], b[2], b[3]])
                })
                .collect();
            (name.clone(), col)
        })
        .collect()
}

fn scene_columns(scene: &Scene) -> HashMap<String, Vec<f32>> {
    columns(&encode_scene(scene, SceneFormat::Ply).unwrap())
}

/// Largest difference per property between srug's decode and the reference's,
/// in units of the reference value's f32 spacing (ulps) and absolute; values
/// the reference decodes to ±∞ are checked separately by the caller.
fn worst(ours: &HashMap<String, Vec<f32>>, theirs: &HashMap<String, Vec<f32>>) -> Vec<(String, f64, f64)> {
    let mut out = Vec::new();
    let mut names: Vec<&String> = theirs.keys().collect();
    names.sort();
    for name in names {
        let (a, b) = (&ours[name], &theirs[name]);
        assert_eq!(a.len(), b.len(), "{name}: row counts differ");
        let (mut ulps, mut abs) = (0.0f64, 0.0f64);
        for (x, y) in a.iter().zip(b) {
            if !y.is_finite() {
                continue;
            }
            let d = (f64::from(*x) - f64::from(*y)).abs();
            let spacing = f64::from(f32::from_bits(y.abs().to_bits() + 1) - y.abs());
            ulps = ulps.max(d / spacing);
            abs = abs.max(d);
        }
        out.push((name.clone(), ulps, abs));
    }
    out
}

fn sigmoid(x: f32) -> f64 {
    1.0 / (1.0 + (-f64::from(x)).exp())
}

/// Angle in degrees between the rotations of two (w, x, y, z) quaternions.
fn angle_deg(a: [f32; 4], b: [f32; 4]) -> f64 {
    let n = |q: [f32; 4]| {
        let q = q.map(f64::from);
        let l = q.iter().map(|c| c * c).sum::<f64>().sqrt();
        q.map(|c| c / l)
    };
    let (a, b) = (n(a), n(b));
    let dot = a.iter().zip(&b).map(|(x, y)| x * y).sum::<f64>().abs().min(1.0);
    2.0 * dot.acos().to_degrees()
}

fn quats(c: &HashMap<String, Vec<f32>>) -> Vec<[f32; 4]> {
    (0..c["rot_0"].len()).map(|i| [c["rot_0"][i], c["rot_1"][i], c["rot_2"][i], c["rot_3"][i]]).collect()
}

/// Compressed PLY, SPZ (versions 2, 3 and 4) and SOG written by splat-transform
/// decode to exactly the other tool's values, every property of every
/// Gaussian (the SPZ reference is Niantic's own code compiled to WASM). The
/// one difference allowed: an opacity byte of 0 or 255, which both tools
/// decode to an infinite logit, is a finite logit of the right sign in srug.
#[test]
fn files_another_tool_wrote_decode_bit_exactly_as_that_tool() {
    for name in
        ["st.compressed.ply", "st.v4.spz", "st.v3.spz", "st.v2.spz", "st.sog", "srug.spz", "srug.compressed.ply"]
    {
        let ours = scene_columns(&read_scene(fixture(name)).unwrap());
        let theirs = columns(&std::fs::read(fixture(&format!("{name}.decoded.ply"))).unwrap());
        assert!(theirs.len() >= 59, "{name}: the reference decode has {} properties", theirs.len());
        for (property, ulps, abs) in worst(&ours, &theirs) {
            assert!(ulps == 0.0, "{name}: {property} differs from the reference decode by {ulps} ulp ({abs:e})");
        }
        for (i, (o, t)) in ours["opacity"].iter().zip(&theirs["opacity"]).enumerate() {
            if !t.is_finite() {
                assert!(o.is_finite() && o.abs() > 13.0 && o.signum() == t.signum(), "{name}: row {i}: {o} for {t}");
            }
        }
    }
}

/// srug's `.splat` decodes as antimatter15's viewer does: colour and opacity
/// are the bytes over 255 (SH band 0: (b/255 − 0.5)/C0, opacity its logit) and
/// the rotation is (b − 128)/128. splat-transform maps rotation bytes as
/// b/255·2 − 1 and clamps opacity at 1e-6 instead of 1e-7, so against it the
/// rotations agree within 1.5° (the two byte mappings differ by half a step)
/// and opacities within 1e-6 after the sigmoid.
#[test]
fn splat_decodes_as_the_reference_viewer() {
    let bytes = std::fs::read(fixture("srug.splat")).unwrap();
    let scene = read_scene(fixture("srug.splat")).unwrap();
    for (i, row) in bytes.chunks_exact(32).enumerate() {
        let q = [28, 29, 30, 31].map(|j| (f32::from(row[j]) - 128.0) / 128.0);
        assert_eq!(scene.rotations[i], q, "row {i}");
        let p = [0, 1, 2].map(|a| f32::from_le_bytes(row[4 * a..4 * a + 4].try_into().unwrap()));
        assert_eq!(scene.means[i], p, "row {i}");
        let alpha = f64::from(row[27]) / 255.0;
        assert!((sigmoid(scene.opacity_logits[i]) - alpha).abs() < 2e-7, "row {i}");
    }
    let ours = scene_columns(&scene);
    let theirs = columns(&std::fs::read(fixture("srug.splat.decoded.ply")).unwrap());
    for (property, ulps, abs) in worst(&ours, &theirs) {
        match property.as_str() {
            "x" | "y" | "z" | "scale_0" | "scale_1" | "scale_2" => assert!(ulps <= 1.0, "{property}: {ulps} ulp"),
            "f_dc_0" | "f_dc_1" | "f_dc_2" => assert!(abs <= 2e-7, "{property}: {abs}"),
            _ => {}
        }
    }
    for (i, (a, b)) in quats(&ours).iter().zip(quats(&theirs)).enumerate() {
        assert!(angle_deg(*a, b) < 1.5, "row {i}: rotations {a:?} and {b:?} differ by {}°", angle_deg(*a, b));
    }
    for (o, t) in ours["opacity"].iter().zip(&theirs["opacity"]) {
        assert!((sigmoid(*o) - sigmoid(*t)).abs() <= 1e-6, "opacity {o} vs {t}");
    }
}

/// The GLB splat-transform wrote holds the source scene: positions and SH
/// exactly, rotations within 1e-6 of their largest component (the +Y-up turn
/// is undone exactly; the other tool's own turn adds 1e-16 noise), log scales
/// within 2e-7 (the file stores exp(s)), opacities within 1e-7 after the
/// sigmoid (the file stores sigmoid(o) in f32).
#[test]
fn glb_written_by_splat_transform_holds_the_source() {
    let source = srug::io::read_ply(fixture("source.ply")).unwrap();
    let glb = read_scene(fixture("st.glb")).unwrap();
    // Streamed from the file (attribute by attribute) and decoded in memory: the same scene.
    assert!(glb == read_scene_bytes(&std::fs::read(fixture("st.glb")).unwrap(), "memory").unwrap());
    assert_eq!(glb.len(), source.len());
    assert_eq!(glb.sh_degree, 3);
    assert!(glb.means == source.means, "positions differ");
    assert!(glb.sh == source.sh, "SH coefficients differ");
    // splat-transform turns quaternions with float trigonometry (sin 180° = 1.2e-16), so exact up to that.
    for (i, (a, b)) in glb.rotations.iter().zip(&source.rotations).enumerate() {
        let scale = b.iter().map(|c| c.abs()).fold(0.0f32, f32::max);
        assert!(a.iter().zip(b).all(|(x, y)| (x - y).abs() <= 1e-6 * scale), "row {i}: {a:?} vs {b:?}");
    }
    for (a, b) in glb.log_scales.iter().flatten().zip(source.log_scales.iter().flatten()) {
        assert!((a - b).abs() <= 2e-7 * b.abs().max(1.0), "log scale {a} vs {b}");
    }
    for (a, b) in glb.opacity_logits.iter().zip(&source.opacity_logits) {
        assert!((sigmoid(*a) - sigmoid(*b)).abs() <= 1e-7, "opacity {a} vs {b}");
    }
}

/// The formats srug writes, with the fixture scene's error bounds after a
/// round trip through srug's writer and reader (the precision each keeps;
/// docs/formats.md): position (m), rotation (degrees), log scale, opacity
/// after the sigmoid, SH band 0 and higher bands (1e-4° is the noise of
/// measuring an angle through acos in f64).
struct Precision {
    format: SceneFormat,
    position: f64,
    rotation_deg: f64,
    log_scale: f64,
    opacity: f64,
    dc: f64,
    rest: Option<f64>,
}

fn precisions(source: &Scene) -> Vec<Precision> {
    let b = source.bounds().unwrap();
    let extent = (0..3).map(|a| f64::from(b.max[a] - b.min[a])).fold(0.0, f64::max);
    let scale_range = source.log_scales.iter().flatten().fold(0.0f64, |m, v| m.max(f64::from(v.abs()))) * 2.0;
    vec![
        Precision {
            format: SceneFormat::Ply,
            position: 0.0,
            rotation_deg: 1e-4,
            log_scale: 0.0,
            opacity: 0.0,
            dc: 0.0,
            rest: Some(0.0),
        },
        Precision {
            format: SceneFormat::Glb,
            position: 0.0,
            rotation_deg: 1e-4,
            log_scale: 1e-6,
            opacity: 1e-7,
            dc: 0.0,
            rest: Some(0.0),
        },
        // 12 fractional bits; 9-bit smallest-three; 1/16 log steps; 8-bit colour over ±3.3; 5 and 4 significant SH bits.
        Precision {
            format: SceneFormat::Spz,
            position: 0.5 / 4096.0 + 1e-6,
            rotation_deg: 0.25,
            log_scale: 1.0 / 32.0 + 1e-6,
            opacity: 0.5 / 255.0 + 1e-6,
            dc: 0.5 / (0.15 * 255.0) + 1e-6,
            rest: Some(8.5 / 128.0 + 1e-6),
        },
        // Within each 256-Gaussian chunk: 10-bit (worst axis) position and log scale, 10-bit rotation, 8-bit colour and SH over −4..4.
        Precision {
            format: SceneFormat::CompressedPly,
            position: 0.5 * extent / 1023.0 + 1e-6,
            rotation_deg: 0.2,
            log_scale: 0.5 * scale_range / 1023.0 + 1e-6,
            opacity: 0.5 / 255.0 + 1e-6,
            dc: 0.5 / 255.0 / 0.282 * 1.2 + 1e-6,
            rest: Some(0.5 * 8.0 / 256.0 + 1e-6),
        },
        // 16 bits of the log range, ≤ 1.5 m at 1500 m (checked per Gaussian in sog_writes_nearest_codebook_entries);
        // 8-bit rotation components (truncated); codebooks (checked there too) and a palette.
        Precision {
            format: SceneFormat::Sog,
            position: 1501.0 * (2.0 * 1501f64.ln() / 65535.0) * 1.01,
            rotation_deg: 1.5,
            log_scale: f64::INFINITY,
            opacity: 1.0 / 255.0 + 1e-6,
            dc: f64::INFINITY,
            rest: Some(f64::INFINITY),
        },
        // f32 position and scale; colour, opacity and rotation in truncated bytes (1/128 per component: ≤ 2°).
        Precision {
            format: SceneFormat::Splat,
            position: 0.0,
            rotation_deg: 2.0,
            log_scale: 1e-6,
            opacity: 1.0 / 255.0 + 1e-6,
            dc: 1.0 / 255.0 / 0.282 + 1e-6,
            rest: None,
        },
    ]
}

/// Each writable format round-trips the fixture scene within the precision
/// it keeps, and the written bytes are detected as that format.
#[test]
fn round_trips_keep_each_formats_precision() {
    let source = srug_tests::format_source_scene();
    let k = 16;
    for p in precisions(&source) {
        let bytes = encode_scene(&source, p.format).unwrap();
        assert_eq!(SceneFormat::detect(&bytes), Some(p.format), "{} output is detected", p.format);
        let back = read_scene_bytes(&bytes, "round trip").unwrap();
        assert_eq!(back.len(), source.len(), "{}", p.format);
        let name = p.format.name();
        let mut worst = [0.0f64; 6];
        for g in 0..source.len() {
            // The compressed PLY and SOG reorder Gaussians (Morton order); match by nearest centre.
            let h = if matches!(p.format, SceneFormat::CompressedPly | SceneFormat::Sog) {
                (0..back.len())
                    .min_by(|&a, &b| {
                        let d = |i: usize| (0..3).map(|x| (back.means[i][x] - source.means[g][x]).powi(2)).sum::<f32>();
                        d(a).total_cmp(&d(b))
                    })
                    .unwrap()
            } else {
                g
            };
            for a in 0..3 {
                worst[0] = worst[0].max(f64::from((back.means[h][a] - source.means[g][a]).abs()));
                worst[2] = worst[2].max(f64::from((back.log_scales[h][a] - source.log_scales[g][a]).abs()));
                worst[4] = worst[4]
                    .max(f64::from((back.sh[h * back.sh.len() / back.len() + a] - source.sh[g * k * 3 + a]).abs()));
            }
            worst[1] = worst[1].max(angle_deg(back.rotations[h], source.rotations[g]));
            worst[3] = worst[3].max((sigmoid(back.opacity_logits[h]) - sigmoid(source.opacity_logits[g])).abs());
            if p.rest.is_some() {
                for j in 3..k * 3 {
                    worst[5] = worst[5].max(f64::from((back.sh[h * k * 3 + j] - source.sh[g * k * 3 + j]).abs()));
                }
            }
        }
        let limits = [p.position, p.rotation_deg, p.log_scale, p.opacity, p.dc, p.rest.unwrap_or(0.0)];
        let what = ["position", "rotation (deg)", "log scale", "opacity", "SH band 0", "SH bands 1-3"];
        for i in 0..6 {
            assert!(worst[i] <= limits[i], "{name}: {} error {:e} above its bound {:e}", what[i], worst[i], limits[i]);
        }
        println!(
            "{name:15} position {:.2e} rotation {:.3}° log-scale {:.2e} opacity {:.2e} dc {:.2e} rest {:.2e}",
            worst[0], worst[1], worst[2], worst[3], worst[4], worst[5]
        );
        if p.rest.is_none() {
            assert_eq!(back.sh_degree, 0, "{name} keeps colour only");
        } else {
            assert_eq!(back.sh_degree, 3, "{name} keeps every band");
        }
    }
}

/// Detection reads the content, not the name: every fixture is detected as
/// its format, and a file whose extension names another format still reads.
#[test]
fn formats_are_detected_from_content() {
    let cases = [
        ("source.ply", SceneFormat::Ply),
        ("st.compressed.ply", SceneFormat::CompressedPly),
        ("st.v4.spz", SceneFormat::Spz),
        ("st.v3.spz", SceneFormat::Spz),
        ("st.v2.spz", SceneFormat::Spz),
        ("st.sog", SceneFormat::Sog),
        ("st.glb", SceneFormat::Glb),
        ("srug.splat", SceneFormat::Splat),
    ];
    let dir = tempfile::tempdir().unwrap();
    for (name, format) in cases {
        let bytes = std::fs::read(fixture(name)).unwrap();
        assert_eq!(SceneFormat::detect(&bytes), Some(format), "{name}");
        let expected = read_scene(fixture(name)).unwrap();
        let misnamed = dir.path().join(if format == SceneFormat::Ply { "scene.spz" } else { "scene.ply" });
        std::fs::write(&misnamed, &bytes).unwrap();
        assert!(read_scene(&misnamed).unwrap() == expected, "{name} read under another extension");
    }
    assert_eq!(SceneFormat::detect(b"hello, world"), None);
    let e = read_scene_bytes(b"hello, world", "notes.txt").unwrap_err().to_string();
    assert!(e.contains("notes.txt") && e.contains("not a scene file"), "{e}");
}

fn refuse(bytes: &[u8], format: SceneFormat, origin: &str) -> String {
    match srug::io::read_scene_as(bytes, format, origin) {
        Ok(s) => panic!("{origin}: a bad {format} file was accepted ({} Gaussians)", s.len()),
        Err(e) => e.to_string(),
    }
}

fn put_u32(bytes: &mut [u8], at: usize, v: u32) {
    bytes[at..at + 4].copy_from_slice(&v.to_le_bytes());
}

fn gunzip(bytes: &[u8]) -> Vec<u8> {
    use std::io::Read;
    let mut out = Vec::new();
    flate2::read::GzDecoder::new(bytes).read_to_end(&mut out).unwrap();
    out
}

fn gzip(bytes: &[u8]) -> Vec<u8> {
    use std::io::Write;
    let mut w = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    w.write_all(bytes).unwrap();
    w.finish().unwrap()
}

/// Every format cut short anywhere is refused with the file and the format
/// named (a `.splat` has no header: cut at a row boundary it is a valid
/// smaller scene, so its cuts fall inside rows).
#[test]
fn truncated_files_are_refused_naming_the_format() {
    let cases = [
        ("st.compressed.ply", SceneFormat::CompressedPly, "compressed PLY"),
        ("st.v4.spz", SceneFormat::Spz, "SPZ"),
        ("st.v3.spz", SceneFormat::Spz, "SPZ"),
        ("st.v2.spz", SceneFormat::Spz, "SPZ"),
        ("st.sog", SceneFormat::Sog, "SOG"),
        ("st.glb", SceneFormat::Glb, "GLB"),
        ("srug.splat", SceneFormat::Splat, ".splat"),
    ];
    for (name, format, word) in cases {
        let bytes = std::fs::read(fixture(name)).unwrap();
        for cut in [1, 17, 33, bytes.len() / 3 + 3, bytes.len() / 2 + 5, bytes.len() - 1] {
            let e = refuse(&bytes[..cut], format, name);
            assert!(e.contains(name) && e.contains(word), "{name} cut at {cut}: {e}");
        }
    }
    let e = refuse(&[], SceneFormat::Splat, "empty.splat");
    assert!(e.contains("empty"), "{e}");
}

/// Counts that disagree with the data are refused with the field named.
#[test]
fn counts_that_disagree_with_the_data_are_refused() {
    let source = srug_tests::format_source_scene();
    // SPZ v4: one point more than the streams hold.
    let mut spz = encode_scene(&source, SceneFormat::Spz).unwrap();
    put_u32(&mut spz, 8, 401);
    let e = refuse(&spz, SceneFormat::Spz, "a.spz");
    assert!(e.contains("positions") && e.contains("401 points"), "{e}");
    // SPZ v3 (gzip): one point fewer than the stream holds, and one more.
    let raw = gunzip(&std::fs::read(fixture("st.v3.spz")).unwrap());
    for (count, words) in [(399, "more data follows"), (401, "truncated")] {
        let mut r = raw.clone();
        put_u32(&mut r, 8, count);
        let e = refuse(&gzip(&r), SceneFormat::Spz, "b.spz");
        assert!(e.contains("numPoints") && e.contains(words), "{count}: {e}");
    }
    // Compressed PLY: a vertex count the chunks do not cover.
    let text = std::fs::read(fixture("st.compressed.ply")).unwrap();
    let at = text.windows(19).position(|w| w == b"element vertex 400\n").unwrap();
    let mut cply = text.clone();
    cply[at + 15..at + 18].copy_from_slice(b"700");
    let e = refuse(&cply, SceneFormat::CompressedPly, "c.compressed.ply");
    assert!(e.contains("chunk") && e.contains("700 Gaussians"), "{e}");
    // .splat: a partial row.
    let mut splat = std::fs::read(fixture("srug.splat")).unwrap();
    splat.extend_from_slice(&[0; 5]);
    let e = refuse(&splat, SceneFormat::Splat, "d.splat");
    assert!(e.contains("32-byte rows"), "{e}");
    // GLB: an accessor that claims more elements than its buffer view holds.
    let glb = encode_scene(&source, SceneFormat::Glb).unwrap();
    let at = glb.windows(11).position(|w| w == b"\"count\":400").unwrap();
    let mut bad = glb.clone();
    bad[at..at + 11].copy_from_slice(b"\"count\":900");
    let e = refuse(&bad, SceneFormat::Glb, "e.glb");
    assert!(e.contains("900 elements do not fit"), "{e}");
}

/// Unknown versions and flags are refused, not guessed at.
#[test]
fn unknown_versions_and_flags_are_refused() {
    let source = srug_tests::format_source_scene();
    let spz = encode_scene(&source, SceneFormat::Spz).unwrap();
    let mut v5 = spz.clone();
    put_u32(&mut v5, 4, 5);
    assert!(refuse(&v5, SceneFormat::Spz, "v5.spz").contains("version 5"));
    let mut flags = spz.clone();
    flags[14] = 0x80;
    let e = refuse(&flags, SceneFormat::Spz, "f.spz");
    assert!(e.contains("flags") && e.contains("0x80"), "{e}");
    let mut legacy = gunzip(&std::fs::read(fixture("st.v3.spz")).unwrap());
    legacy[14] |= 0x2;
    let e = refuse(&gzip(&legacy), SceneFormat::Spz, "x.spz");
    assert!(e.contains("extension records"), "{e}");
    let mut glb = encode_scene(&source, SceneFormat::Glb).unwrap();
    put_u32(&mut glb, 4, 1);
    assert!(refuse(&glb, SceneFormat::Glb, "v1.glb").contains("container version 1"));
    // SOG: a meta.json of version 3, and one without a version (the legacy layout).
    let dir = tempfile::tempdir().unwrap();
    for (meta, words) in
        [(r#"{"version": 3, "count": 1, "means": {}}"#, "version 3"), (r#"{"count": 1, "means": {}}"#, "version 1")]
    {
        let path = dir.path().join("meta.json");
        std::fs::write(&path, meta).unwrap();
        let e = read_scene(&path).unwrap_err().to_string();
        assert!(e.contains("SOG") && e.contains(words), "{e}");
    }
}

/// Values that decode to NaN or infinity are refused with the row and property named.
#[test]
fn non_finite_values_after_decoding_are_refused() {
    let mut splat = std::fs::read(fixture("srug.splat")).unwrap();
    splat[32 * 7 + 4..32 * 7 + 8].copy_from_slice(&f32::NAN.to_le_bytes());
    let e = refuse(&splat, SceneFormat::Splat, "nan.splat");
    assert!(e.contains("row 7") && e.contains("property y") && e.contains("NaN"), "{e}");
    let mut scale = std::fs::read(fixture("srug.splat")).unwrap();
    scale[32 * 2 + 16..32 * 2 + 20].copy_from_slice(&f32::INFINITY.to_le_bytes());
    let e = refuse(&scale, SceneFormat::Splat, "inf.splat");
    assert!(e.contains("row 2") && e.contains("scale_y"), "{e}");
    // A compressed PLY chunk bound of +inf makes every position in the chunk infinite.
    let mut cply = std::fs::read(fixture("st.compressed.ply")).unwrap();
    let data = cply.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
    cply[data + 12..data + 16].copy_from_slice(&f32::INFINITY.to_le_bytes());
    let e = refuse(&cply, SceneFormat::CompressedPly, "inf.compressed.ply");
    assert!(e.contains("row 0") && e.contains("value is"), "{e}");
}

/// srug's SOG writer: every position within one 16-bit step of the log range
/// (truncation), and every log scale and DC colour the codebook entry nearest
/// the source value (the codebooks themselves come from a 1D k-means).
#[test]
fn sog_writes_nearest_codebook_entries() {
    use std::io::Read;
    let source = srug_tests::format_source_scene();
    let bytes = encode_scene(&source, SceneFormat::Sog).unwrap();
    let back = read_scene_bytes(&bytes, "srug.sog").unwrap();
    let mut zip = zip::ZipArchive::new(std::io::Cursor::new(&bytes)).unwrap();
    let mut text = String::new();
    zip.by_name("meta.json").unwrap().read_to_string(&mut text).unwrap();
    let meta: serde_json::Value = serde_json::from_str(&text).unwrap();
    let code = |key: &str| -> Vec<f64> {
        meta[key]["codebook"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect()
    };
    let (scale_code, dc_code) = (code("scales"), code("sh0"));
    let log = |v: f64| v.signum() * (v.abs() + 1.0).ln();
    let range: Vec<f64> = (0..3)
        .map(|a| meta["means"]["maxs"][a].as_f64().unwrap() - meta["means"]["mins"][a].as_f64().unwrap())
        .collect();
    let nearest = |codebook: &[f64], v: f64| codebook.iter().map(|c| (c - v).abs()).fold(f64::INFINITY, f64::min);
    let k = 16;
    for g in 0..source.len() {
        let h = (0..back.len())
            .find(|&h| {
                (0..3).all(|a| {
                    (log(f64::from(back.means[h][a])) - log(f64::from(source.means[g][a]))).abs()
                        <= range[a] / 65535.0 * 1.001
                })
            })
            .unwrap_or_else(|| panic!("Gaussian {g}: no decoded centre within one step"));
        for a in 0..3 {
            let (s, d) = (f64::from(source.log_scales[g][a]), f64::from(back.log_scales[h][a]));
            assert!((s - d).abs() <= nearest(&scale_code, s) + 1e-6, "Gaussian {g} log scale {s} → {d}");
            let (s, d) = (f64::from(source.sh[g * k * 3 + a]), f64::from(back.sh[h * k * 3 + a]));
            assert!((s - d).abs() <= nearest(&dc_code, s) + 1e-6, "Gaussian {g} colour {s} → {d}");
        }
    }
}
