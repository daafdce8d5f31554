//! Niantic's `.spz`, every version its reference implementation
//! (nianticlabs/spz, `load-spz.cc`) reads.
//!
//! Versions 1-3 are one gzip stream: a 16-byte header (magic `NGSP`, version,
//! count, SH degree, fractional bits, flags, reserved) then positions, alphas,
//! colours, scales, rotations and SH as planes. Version 4 has a 32-byte
//! plaintext header (adding the stream count and the table-of-contents
//! offset), optional extension records, a table of (compressed, uncompressed)
//! sizes and one zstd stream per plane. Version 1 stores positions as f16;
//! later versions as 24-bit fixed point. Version 2 stores a rotation as the
//! quaternion's x, y, z bytes (w ≥ 0 rebuilt); versions 3 and 4 as the
//! smallest three components (9 bits and a sign each) plus the largest's
//! index. Scales are `(log + 10)·16`, colours `dc·0.15 + 0.5` in bytes, alphas
//! `sigmoid·255`, SH `x·128 + 128`. The frame is right-up-back; srug reads it
//! into the PLY's right-down-forward frame exactly as the reference does with
//! `UnpackOptions{to: RDF}`. Decoding follows the reference in f32 operation
//! by operation, so values agree to the last bit (alphas of 0 and 255, which
//! the reference decodes to ±∞ logits, are kept finite).
//!
//! The writer writes version 4 as the reference's packer does, with the
//! fractional bits lowered where the scene extends past the 24-bit range.

use std::io::Read;

use super::frame::AxisFlip;
use super::splat::byte_logit;
use crate::scene::{sh_coefficients, Materials, Scene, SceneError};

const MAGIC: u32 = 0x5053_474e;
const FLAG_ANTIALIASED: u8 = 0x1;
const FLAG_EXTENSIONS: u8 = 0x2;
const COLOR_SCALE: f32 = 0.15;
/// The SPZ-ADOBE coordinate-system extension record type.
const EXT_COORDINATE_SYSTEM: u32 = 0xADBE_0003;

/// SH coefficients per channel after the constant term for an SPZ degree (0 to 4).
fn sh_dim(degree: u8) -> usize {
    [0, 3, 8, 15, 24][usize::from(degree)]
}

fn err(origin: &str, field: &str, message: impl std::fmt::Display) -> SceneError {
    SceneError { path: origin.into(), row: None, property: Some(field.into()), message: format!("SPZ: {message}") }
}

/// The header fields every version shares.
struct Header {
    version: u32,
    count: usize,
    sh_degree: u8,
    fractional_bits: u8,
    antialiased: bool,
}

impl Header {
    fn parse(b: &[u8], origin: &str) -> Result<Header, SceneError> {
        let u32_at = |i: usize| u32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]]);
        if u32_at(0) != MAGIC {
            return Err(err(origin, "magic", "the header does not start with NGSP"));
        }
        let version = u32_at(4);
        if !(1..=4).contains(&version) {
            return Err(err(origin, "version", format!("version {version} is not one srug reads (1 to 4)")));
        }
        let declared = u32_at(8);
        let count = crate::io::limits()
            .gaussians(u64::from(declared))
            .map_err(|why| err(origin, "numPoints", format!("{declared} points: {why}")))?;
        let sh_degree = b[12];
        if sh_degree > 4 {
            return Err(err(origin, "shDegree", format!("SH degree {sh_degree} is not 0 to 4")));
        }
        let fractional_bits = b[13];
        if fractional_bits > 24 {
            return Err(err(origin, "fractionalBits", format!("{fractional_bits} fractional bits in a 24-bit value")));
        }
        let flags = b[14];
        if flags & !(FLAG_ANTIALIASED | FLAG_EXTENSIONS) != 0 {
            return Err(err(origin, "flags", format!("unknown flag bits 0x{:02x}", flags & !3)));
        }
        if flags & FLAG_EXTENSIONS != 0 && version < 4 {
            return Err(err(
                origin,
                "flags",
                "extension records in a legacy (version 1-3) file are not supported: they change how the data decodes",
            ));
        }
        Ok(Header { version, count, sh_degree, fractional_bits, antialiased: flags & FLAG_ANTIALIASED != 0 })
    }

    fn position_bytes(&self) -> usize {
        if self.version == 1 {
            6
        } else {
            9
        }
    }

    fn rotation_bytes(&self) -> usize {
        if self.version >= 3 {
            4
        } else {
            3
        }
    }

    /// Plane sizes in file order: positions, alphas, colours, scales, rotations, SH.
    fn plane_sizes(&self, origin: &str) -> Result<[usize; 6], SceneError> {
        let n = self.count;
        let per = [self.position_bytes(), 1, 3, 3, self.rotation_bytes(), 3 * sh_dim(self.sh_degree)];
        let mut out = [0; 6];
        for (o, p) in out.iter_mut().zip(per) {
            *o = n.checked_mul(p).ok_or_else(|| err(origin, "numPoints", "the plane sizes overflow"))?;
        }
        Ok(out)
    }
}

/// Reads up to `expected` bytes, growing with what is decoded (never with the
/// declared size alone), and says whether the stream had more.
fn read_bounded(mut r: impl Read, expected: usize, hint: usize) -> std::io::Result<(Vec<u8>, bool)> {
    let mut out = Vec::with_capacity(expected.min(hint));
    (&mut r).take(expected as u64).read_to_end(&mut out)?;
    let mut extra = [0u8; 1];
    let more = r.read(&mut extra)? > 0;
    Ok((out, more))
}

/// Decodes an SPZ file.
pub(crate) fn read(bytes: &[u8], origin: &str) -> Result<Scene, SceneError> {
    if bytes.starts_with(&[0x1f, 0x8b]) {
        read_legacy(bytes, origin)
    } else if bytes.len() >= 4 && u32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]) == MAGIC {
        read_v4(bytes, origin)
    } else {
        Err(err(origin, "magic", "neither a gzip stream (versions 1-3) nor an NGSP header (version 4)"))
    }
}

fn read_legacy(bytes: &[u8], origin: &str) -> Result<Scene, SceneError> {
    let corrupt = |e: std::io::Error| err(origin, "gzip stream", format!("corrupt or truncated gzip data: {e}"));
    let mut gz = flate2::read::GzDecoder::new(bytes);
    let mut head = [0u8; 16];
    gz.read_exact(&mut head).map_err(corrupt)?;
    let header = Header::parse(&head, origin)?;
    if header.version == 4 {
        return Err(err(origin, "version", "version 4 inside a gzip stream (version 4 files are not gzip-compressed)"));
    }
    let sizes = header.plane_sizes(origin)?;
    let total: usize = sizes.iter().sum();
    let (payload, more) = read_bounded(&mut gz, total, bytes.len().saturating_mul(8)).map_err(corrupt)?;
    if payload.len() < total {
        return Err(err(
            origin,
            "numPoints",
            format!(
                "the file is truncated: {} points need {total} bytes of data, the stream holds {}",
                header.count,
                payload.len()
            ),
        ));
    }
    if more {
        return Err(err(
            origin,
            "numPoints",
            format!("more data follows the {} points the header declares", header.count),
        ));
    }
    let mut planes = [&payload[..0]; 6];
    let mut at = 0;
    for (p, s) in planes.iter_mut().zip(sizes) {
        *p = &payload[at..at + s];
        at += s;
    }
    unpack(&header, planes, origin)
}

fn read_v4(bytes: &[u8], origin: &str) -> Result<Scene, SceneError> {
    if bytes.len() < 32 {
        return Err(err(
            origin,
            "header",
            format!("the file is {} bytes, shorter than the 32-byte header", bytes.len()),
        ));
    }
    let header = Header::parse(&bytes[..16], origin)?;
    if header.version != 4 {
        return Err(err(origin, "version", format!("a plaintext NGSP header with version {}", header.version)));
    }
    let streams = usize::from(bytes[15]);
    let toc = u32::from_le_bytes([bytes[16], bytes[17], bytes[18], bytes[19]]) as usize;
    let sizes = header.plane_sizes(origin)?;
    let expected_streams = if header.sh_degree > 0 { 6 } else { 5 };
    if streams != expected_streams {
        return Err(err(
            origin,
            "numStreams",
            format!("{streams} streams, expected {expected_streams} for SH degree {}", header.sh_degree),
        ));
    }
    if toc < 32 || toc > bytes.len() {
        return Err(err(origin, "tocByteOffset", format!("offset {toc} is outside 32..{}", bytes.len())));
    }
    let stored_rdf = bytes[14] & FLAG_EXTENSIONS != 0 && read_extensions(&bytes[32..toc], origin)?;
    let toc_end = toc + 16 * streams;
    if toc_end > bytes.len() {
        return Err(err(origin, "table of contents", "the file is truncated inside the table of contents"));
    }
    let mut planes: Vec<Vec<u8>> = Vec::with_capacity(6);
    let mut at = toc_end;
    for s in 0..streams {
        let e = &bytes[toc + 16 * s..toc + 16 * s + 16];
        let compressed = u64::from_le_bytes([e[0], e[1], e[2], e[3], e[4], e[5], e[6], e[7]]);
        let uncompressed = u64::from_le_bytes([e[8], e[9], e[10], e[11], e[12], e[13], e[14], e[15]]);
        let name = ["positions", "alphas", "colors", "scales", "rotations", "sh"][s];
        let want = sizes[s];
        if uncompressed != want as u64 {
            return Err(err(
                origin,
                name,
                format!("stream declares {uncompressed} bytes, {} points need {want}", header.count),
            ));
        }
        let end = usize::try_from(compressed)
            .ok()
            .and_then(|c| at.checked_add(c))
            .filter(|&end| end <= bytes.len())
            .ok_or_else(|| err(origin, name, "the file is truncated: the stream runs past its end"))?;
        let data = &bytes[at..end];
        at = end;
        let corrupt = |e: &dyn std::fmt::Display| err(origin, name, format!("corrupt zstd stream: {e}"));
        let plane = if want == 0 && data.is_empty() {
            Vec::new()
        } else {
            let decoder = ruzstd::decoding::StreamingDecoder::new(data).map_err(|e| corrupt(&e))?;
            let (plane, more) = read_bounded(decoder, want, data.len().saturating_mul(16)).map_err(|e| corrupt(&e))?;
            if plane.len() != want || more {
                return Err(err(
                    origin,
                    name,
                    format!("stream inflates to a size other than the {want} bytes declared"),
                ));
            }
            plane
        };
        planes.push(plane);
    }
    if at != bytes.len() {
        return Err(err(origin, "file size", format!("{} bytes follow the last stream", bytes.len() - at)));
    }
    planes.resize(6, Vec::new());
    let refs = [0, 1, 2, 3, 4, 5].map(|i| planes[i].as_slice());
    let mut scene = unpack(&header, refs, origin)?;
    if stored_rdf {
        // The file declares the PLY's frame: undo the RUB → RDF change unpack made.
        AxisFlip::RUB_RDF.apply(&mut scene);
    }
    Ok(scene)
}

/// Walks the version-4 extension records (type, byte length, payload) and
/// says whether the data is stored in RDF rather than the default RUB. Only
/// the coordinate-system extension changes decoding; frames other than RUB
/// and RDF are refused.
fn read_extensions(zone: &[u8], origin: &str) -> Result<bool, SceneError> {
    let mut at = 0;
    let mut stored_rdf = false;
    while at + 8 <= zone.len() {
        let ty = u32::from_le_bytes([zone[at], zone[at + 1], zone[at + 2], zone[at + 3]]);
        let len = u32::from_le_bytes([zone[at + 4], zone[at + 5], zone[at + 6], zone[at + 7]]) as usize;
        let payload = zone
            .get(at + 8..at + 8 + len)
            .ok_or_else(|| err(origin, "extensions", format!("record 0x{ty:08x} runs past the header zone")))?;
        if ty == EXT_COORDINATE_SYSTEM {
            // The reference's CoordinateSystem enum: 0 = unspecified (stored as is), 4 = RUB, 6 = RDF.
            stored_rdf = match payload.first() {
                Some(0 | 4) => false,
                Some(6) => true,
                other => {
                    return Err(err(
                        origin,
                        "SPZ_ADOBE_coordinate_system",
                        format!("coordinate system {other:?} is not RUB or RDF; srug does not convert it"),
                    ))
                }
            };
        } else {
            log::info!("{origin}: SPZ extension record 0x{ty:08x} ({len} bytes) does not affect rendering; skipped");
        }
        at += 8 + len;
    }
    if at != zone.len() {
        return Err(err(origin, "extensions", "the header zone ends inside an extension record"));
    }
    Ok(stored_rdf)
}

/// Decodes the planes exactly as the reference's `unpackGaussians`, then
/// changes RUB to RDF.
fn unpack(h: &Header, planes: [&[u8]; 6], origin: &str) -> Result<Scene, SceneError> {
    let [positions, alphas, colors, scales, rotations, sh] = planes;
    let n = h.count;
    let dim = sh_dim(h.sh_degree);
    let degree = u32::from(h.sh_degree.min(3));
    let k = sh_coefficients(degree);
    if h.sh_degree > 3 {
        log::warn!("{origin}: SPZ SH degree 4 is beyond what srug renders; band 4 is dropped");
    }
    if h.antialiased {
        log::info!(
            "{origin}: the SPZ was trained with antialiasing (mip-splatting); srug renders it without the 2D filter"
        );
    }
    let mut scene = Scene {
        means: Vec::with_capacity(n),
        normals: None,
        sh_degree: degree,
        sh: Vec::with_capacity(n * k * 3),
        opacity_logits: Vec::with_capacity(n),
        log_scales: Vec::with_capacity(n),
        rotations: Vec::with_capacity(n),
        materials: Materials::default(),
        extra_properties: Vec::new(),
    };
    let scale = (1.0f64 / f64::from(1u32 << h.fractional_bits.min(24))) as f32;
    for i in 0..n {
        let mut p = [0.0f32; 3];
        for (a, v) in p.iter_mut().enumerate() {
            *v = if h.version == 1 {
                let b = &positions[(i * 3 + a) * 2..];
                half::f16::from_le_bytes([b[0], b[1]]).to_f32()
            } else {
                let b = &positions[(i * 3 + a) * 3..];
                let mut fixed = i32::from(b[0]) | i32::from(b[1]) << 8 | i32::from(b[2]) << 16;
                if fixed & 0x80_0000 != 0 {
                    fixed |= !0xff_ffff;
                }
                fixed as f32 * scale
            };
        }
        scene.means.push(p);
        scene.log_scales.push([0, 1, 2].map(|a| f32::from(scales[i * 3 + a]) / 16.0 - 10.0));
        let xyzw = if h.version >= 3 {
            smallest_three(&rotations[i * 4..i * 4 + 4])
        } else {
            let r = &rotations[i * 3..i * 3 + 3];
            let xyz = [0, 1, 2].map(|a| f32::from(r[a]) * (1.0f32 / 127.5) + -1.0);
            let sq = xyz[0] * xyz[0] + xyz[1] * xyz[1] + xyz[2] * xyz[2];
            [xyz[0], xyz[1], xyz[2], (1.0f32 - sq).max(0.0).sqrt()]
        };
        scene.rotations.push([xyzw[3], xyzw[0], xyzw[1], xyzw[2]]);
        scene.opacity_logits.push(alpha_logit(alphas[i]));
        for c in 0..3 {
            scene.sh.push((f32::from(colors[i * 3 + c]) / 255.0 - 0.5) / COLOR_SCALE);
        }
        for coef in 0..k - 1 {
            for c in 0..3 {
                scene.sh.push((f32::from(sh[(i * dim + coef) * 3 + c]) - 128.0) / 128.0);
            }
        }
    }
    AxisFlip::RUB_RDF.apply(&mut scene);
    scene.validate(origin)?;
    Ok(scene)
}

/// The reference's `invSigmoid(alpha / 255)` in f32, with 0 and 255 kept finite.
fn alpha_logit(a: u8) -> f32 {
    if a == 0 || a == 255 {
        return byte_logit(a);
    }
    let x = f32::from(a) / 255.0;
    (x / (1.0 - x)).ln()
}

/// The reference's smallest-three quaternion decode, in its f32 order of
/// operations; returns (x, y, z, w).
fn smallest_three(r: &[u8]) -> [f32; 4] {
    const MASK: u32 = (1 << 9) - 1;
    const SQRT1_2: f32 = std::f32::consts::FRAC_1_SQRT_2;
    let mut comp = u32::from_le_bytes([r[0], r[1], r[2], r[3]]);
    let largest = (comp >> 30) as usize;
    let mut q = [0.0f32; 4];
    let mut sum = 0.0f32;
    for i in (0..4).rev() {
        if i != largest {
            let mag = comp & MASK;
            let neg = (comp >> 9) & 1;
            comp >>= 10;
            q[i] = SQRT1_2 * mag as f32 / MASK as f32;
            if neg == 1 {
                q[i] = -q[i];
            }
            sum += q[i] * q[i];
        }
    }
    q[largest] = (1.0f32 - sum).sqrt();
    q
}

/// The reference's smallest-three encode of an (x, y, z, w) quaternion.
fn pack_smallest_three(q: [f32; 4]) -> [u8; 4] {
    let norm = (q.iter().map(|c| c * c).sum::<f32>()).sqrt();
    let q = q.map(|c| c / norm);
    let mut largest = 0;
    for i in 1..4 {
        if q[i].abs() > q[largest].abs() {
            largest = i;
        }
    }
    let negate = q[largest] < 0.0;
    let mut comp = largest as u32;
    for (i, c) in q.iter().enumerate() {
        if i != largest {
            let neg = u32::from((*c < 0.0) ^ negate);
            let mag = (511.0 * (c.abs() / std::f32::consts::FRAC_1_SQRT_2) + 0.5) as u32;
            comp = (comp << 10) | (neg << 9) | mag.min(511);
        }
    }
    comp.to_le_bytes()
}

fn to_byte(x: f32) -> u8 {
    x.round().clamp(0.0, 255.0) as u8
}

/// The reference's SH quantization to `bits` significant bits (legacy range −1..1).
fn quantize_sh(x: f32, bits: u32) -> u8 {
    let bucket = 1i32 << (8 - bits);
    let q = (x * 128.0).round() as i32 + 128;
    let q = (q + bucket / 2) / bucket * bucket;
    q.clamp(0, 255) as u8
}

/// Encodes a scene as SPZ version 4 (degree ≤ 3 SH at the reference's default
/// 5 bits for band 1 and 4 for the rest).
pub(crate) fn encode(scene: &Scene) -> Result<Vec<u8>, String> {
    let n = scene.len();
    let count = u32::try_from(n).map_err(|_| format!("{n} Gaussians do not fit SPZ's 32-bit count"))?;
    let k = sh_coefficients(scene.sh_degree);
    let mut s = scene.clone();
    AxisFlip::RUB_RDF.apply(&mut s);
    let extent = s.means.iter().flat_map(|p| p.iter().map(|v| v.abs())).fold(0.0f32, f32::max);
    // 12 fractional bits (0.24 mm) as the reference writes, fewer where the scene would overflow 24 bits.
    let mut fractional_bits = 12u8;
    while fractional_bits > 0 && extent * (1u32 << fractional_bits) as f32 >= 8_388_607.0 {
        fractional_bits -= 1;
    }
    let fixed_scale = (1u32 << fractional_bits) as f32;
    let mut planes: [Vec<u8>; 6] = Default::default();
    for g in 0..n {
        for v in s.means[g] {
            let fixed = (v * fixed_scale).round() as i32;
            planes[0].extend_from_slice(&fixed.to_le_bytes()[..3]);
        }
        planes[1].push(to_byte(255.0 / (1.0 + (-s.opacity_logits[g]).exp())));
        for c in 0..3 {
            planes[2].push(to_byte(s.sh[g * k * 3 + c] * (COLOR_SCALE * 255.0) + 0.5 * 255.0));
        }
        for v in s.log_scales[g] {
            planes[3].push(to_byte((v + 10.0) * 16.0));
        }
        let [w, x, y, z] = s.rotations[g];
        planes[4].extend_from_slice(&pack_smallest_three([x, y, z, w]));
        for coef in 1..k {
            let bits = if coef < 4 { 5 } else { 4 };
            for c in 0..3 {
                planes[5].push(quantize_sh(s.sh[(g * k + coef) * 3 + c], bits));
            }
        }
    }
    let streams = if scene.sh_degree > 0 { 6 } else { 5 };
    let compressed: Vec<Vec<u8>> = planes[..streams]
        .iter()
        .map(|p| ruzstd::encoding::compress_to_vec(p.as_slice(), ruzstd::encoding::CompressionLevel::Fastest))
        .collect();
    let mut out = Vec::with_capacity(32 + 16 * streams + compressed.iter().map(Vec::len).sum::<usize>());
    out.extend_from_slice(&MAGIC.to_le_bytes());
    out.extend_from_slice(&4u32.to_le_bytes());
    out.extend_from_slice(&count.to_le_bytes());
    out.extend_from_slice(&[scene.sh_degree as u8, fractional_bits, 0, streams as u8]);
    out.extend_from_slice(&32u32.to_le_bytes());
    out.extend_from_slice(&[0u8; 12]);
    for (c, p) in compressed.iter().zip(&planes) {
        out.extend_from_slice(&(c.len() as u64).to_le_bytes());
        out.extend_from_slice(&(p.len() as u64).to_le_bytes());
    }
    for c in &compressed {
        out.extend_from_slice(c);
    }
    Ok(out)
}
