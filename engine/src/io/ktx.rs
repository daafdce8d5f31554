//! KTX2 for environments: reading float lat-long or cube maps (level 0;
//! zstd supercompression) and writing float mip chains (the prepared
//! environment and the BRDF table, so a map is prefiltered once).
//!
//! Accepted formats: R16G16B16A16_SFLOAT, R16G16B16_SFLOAT, R32G32B32A32_SFLOAT,
//! R32G32B32_SFLOAT, B10G11R11_UFLOAT_PACK32, E5B9G9R9_UFLOAT_PACK32. Everything
//! else (8-bit, sRGB, block-compressed, 3D, arrays, BasisLZ or zlib) is
//! refused with the reason.

use std::io::Read;
use std::path::Path;

use ktx2::{Format, SupercompressionScheme};

use super::environment::EnvironmentMap;
use crate::error::{Error, Result};

fn ktx_error(origin: &str, message: impl Into<String>) -> Error {
    Error::Environment { origin: origin.to_string(), message: message.into() }
}

/// Decodes one texel's bytes to RGB.
type TexelDecoder = fn(&[u8]) -> [f32; 3];

/// Bytes per texel and the decoder of one texel for the accepted float formats.
fn float_format(format: Format) -> Option<(usize, TexelDecoder)> {
    fn h(b: &[u8], i: usize) -> f32 {
        half::f16::from_le_bytes([b[2 * i], b[2 * i + 1]]).to_f32()
    }
    fn f(b: &[u8], i: usize) -> f32 {
        f32::from_le_bytes([b[4 * i], b[4 * i + 1], b[4 * i + 2], b[4 * i + 3]])
    }
    fn word(b: &[u8]) -> u32 {
        u32::from_le_bytes([b[0], b[1], b[2], b[3]])
    }
    /// An unsigned small float with a 5-bit exponent (bias 15) and `m` mantissa bits.
    fn small(bits: u32, m: u32) -> f32 {
        let (e, mant) = (bits >> m, bits & ((1 << m) - 1));
        let scale = (1u32 << m) as f32;
        match e {
            0 => mant as f32 / scale * 2f32.powi(-14),
            31 => f32::INFINITY,
            _ => 2f32.powi(e as i32 - 15) * (1.0 + mant as f32 / scale),
        }
    }
    Some(match format {
        Format::R16G16B16A16_SFLOAT => (8, |b| [h(b, 0), h(b, 1), h(b, 2)]),
        Format::R16G16B16_SFLOAT => (6, |b| [h(b, 0), h(b, 1), h(b, 2)]),
        Format::R32G32B32A32_SFLOAT => (16, |b| [f(b, 0), f(b, 1), f(b, 2)]),
        Format::R32G32B32_SFLOAT => (12, |b| [f(b, 0), f(b, 1), f(b, 2)]),
        Format::B10G11R11_UFLOAT_PACK32 => {
            (4, |b| [small(word(b) & 0x7ff, 6), small((word(b) >> 11) & 0x7ff, 6), small(word(b) >> 22, 5)])
        }
        Format::E5B9G9R9_UFLOAT_PACK32 => (4, |b| {
            let w = word(b);
            let scale = 2f32.powi((w >> 27) as i32 - 15 - 9);
            [(w & 0x1ff) as f32 * scale, ((w >> 9) & 0x1ff) as f32 * scale, ((w >> 18) & 0x1ff) as f32 * scale]
        }),
        _ => return None,
    })
}

/// One level's bytes: at least `expected` of them (more are ignored), with
/// zstd decompression stopped one byte past `expected`, so a small file that
/// claims or inflates to more than its header declares cannot grow the host's
/// memory beyond it.
fn level_bytes(data: &[u8], scheme: Option<SupercompressionScheme>, expected: usize, origin: &str) -> Result<Vec<u8>> {
    let bytes = match scheme {
        None if data.len() >= expected => data[..expected].to_vec(),
        None => data.to_vec(),
        Some(SupercompressionScheme::Zstandard) => {
            let corrupt = |e: &dyn std::fmt::Display| ktx_error(origin, format!("corrupt zstd level data: {e}"));
            let decoder = ruzstd::decoding::StreamingDecoder::new(data).map_err(|e| corrupt(&e))?;
            // Grow with the data actually decoded, never by the declared size alone.
            let mut out = Vec::with_capacity(expected.min(data.len().saturating_mul(4)));
            decoder.take(expected as u64 + 1).read_to_end(&mut out).map_err(|e| corrupt(&e))?;
            if out.len() > expected {
                return Err(ktx_error(
                    origin,
                    format!("a zstd level inflates past the {expected} bytes its header declares"),
                ));
            }
            out
        }
        Some(other) => {
            return Err(ktx_error(
                origin,
                format!("supercompression {other:?} is not supported (only none and Zstandard)"),
            ))
        }
    };
    if bytes.len() < expected {
        return Err(ktx_error(origin, format!("a level holds {} bytes, {expected} expected", bytes.len())));
    }
    Ok(bytes)
}

/// Opens a KTX2 file, after refusing what `ktx2::Reader::new` 0.5.0 would
/// panic on: a basic data format descriptor block with a texel block
/// dimension byte of 255 (the crate adds 1 to it in u8; found by fuzzing).
fn open<'a>(bytes: &'a [u8], origin: &str) -> Result<ktx2::Reader<&'a [u8]>> {
    let word = |at: usize| bytes.get(at..at + 4).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize);
    if let (Some(offset), Some(length)) = (word(48), word(52)) {
        // The DFD: its total size, then blocks of (vendor/type, version/size, 4 model bytes, 4 dimensions, ...).
        let mut at = offset.saturating_add(4);
        let end = offset.saturating_add(length).min(bytes.len());
        while at.saturating_add(16) <= end {
            let (head, size) = (word(at).unwrap_or(0), word(at + 4).unwrap_or(0) >> 16);
            if head == 0 && bytes[at + 12..at + 16].contains(&255) {
                return Err(ktx_error(origin, "its data format descriptor declares a 256-texel block dimension"));
            }
            if size == 0 {
                break;
            }
            at = at.saturating_add(size);
        }
    }
    ktx2::Reader::new(bytes).map_err(|e| ktx_error(origin, format!("not a valid KTX2 file: {e}")))
}

/// Reads a KTX2 environment: a 2D lat-long texture or a cube map, level 0.
pub fn read_environment(bytes: &[u8], origin: &str) -> Result<EnvironmentMap> {
    let reader = open(bytes, origin)?;
    let header = reader.header();
    let format = header.format.ok_or_else(|| {
        ktx_error(origin, "format is VK_FORMAT_UNDEFINED (Basis Universal); environments need a float format")
    })?;
    let (texel_bytes, decode) = float_format(format).ok_or_else(|| {
        ktx_error(
            origin,
            format!(
                "format {format:?} is not a float format; HDR environments need R16G16B16A16_SFLOAT, \
                 R16G16B16_SFLOAT, R32G32B32A32_SFLOAT, R32G32B32_SFLOAT, B10G11R11_UFLOAT_PACK32 or \
                 E5B9G9R9_UFLOAT_PACK32"
            ),
        )
    })?;
    if header.pixel_depth > 0 {
        return Err(ktx_error(origin, "a 3D texture is not an environment (lat-long 2D or cube maps only)"));
    }
    if header.layer_count > 1 {
        return Err(ktx_error(origin, format!("an array of {} layers is not one environment", header.layer_count)));
    }
    let (w, h) = (header.pixel_width as usize, header.pixel_height.max(1) as usize);
    let faces = header.face_count as usize;
    if faces != 1 && faces != 6 {
        return Err(ktx_error(origin, format!("{faces} faces: expected 1 (lat-long) or 6 (cube)")));
    }
    if header.pixel_height == 0 {
        return Err(ktx_error(origin, "a 1D texture is not an environment"));
    }
    let limits = super::limits();
    let expected = limits
        .image_bytes(w as u64, h as u64, faces as u64, texel_bytes as u64)
        .map_err(|e| ktx_error(origin, format!("level 0 {e}")))?;
    if faces == 6 {
        // The cube is resampled to a 4n × 2n lat-long map of RGB f32.
        limits
            .image_bytes(4 * w as u64, 2 * w as u64, 1, 12)
            .map_err(|e| ktx_error(origin, format!("a cube of {w}x{h} faces resampled to lat-long {e}")))?;
    }
    let level = reader.levels().next().ok_or_else(|| ktx_error(origin, "the file has no mip level"))?;
    let data = level_bytes(level.data, header.supercompression_scheme, expected, origin)?;
    let texels: Vec<[f32; 3]> = data[..expected].chunks_exact(texel_bytes).map(decode).collect();
    if faces == 1 {
        let rgb = texels.into_iter().flatten().collect();
        return EnvironmentMap::from_rgb(w as u32, h as u32, rgb, origin);
    }
    if w != h {
        return Err(ktx_error(origin, format!("cube faces are {w}x{h}, not square")));
    }
    let (lw, lh) = (4 * w, 2 * w);
    let mut rgb = Vec::with_capacity(3 * lw * lh);
    for y in 0..lh {
        for x in 0..lw {
            let d = latlong_direction(x, y, lw, lh);
            rgb.extend(cube_sample(&texels, w, d));
        }
    }
    EnvironmentMap::from_rgb(lw as u32, lh as u32, rgb, origin)
}

/// Direction through the centre of lat-long texel (x, y) (see `env.rs`).
pub fn latlong_direction(x: usize, y: usize, w: usize, h: usize) -> [f64; 3] {
    use std::f64::consts::PI;
    let phi = ((x as f64 + 0.5) / w as f64 - 0.5) * 2.0 * PI;
    let theta = (0.5 - (y as f64 + 0.5) / h as f64) * PI;
    [theta.cos() * phi.sin(), theta.cos() * phi.cos(), theta.sin()]
}

/// Bilinear sample of a cube map (faces +X, −X, +Y, −Y, +Z, −Z, rows down)
/// along world direction `d`. Cube maps live in a left-handed frame: cube +Y
/// is world up, −Z north and +X west, which makes a cube made from a lat-long
/// map by the usual tools resample back to that map (checked on the shared
/// studio cube against its lat-long source).
fn cube_sample(texels: &[[f32; 3]], n: usize, d: [f64; 3]) -> [f32; 3] {
    let (x, y, z) = (-d[0], d[2], -d[1]);
    let (ax, ay, az) = (x.abs(), y.abs(), z.abs());
    // Major axis, then (sc, tc, ma) as in the Vulkan cube-map table.
    let (face, sc, tc, ma) = if ax >= ay && ax >= az {
        if x > 0.0 {
            (0, -z, -y, ax)
        } else {
            (1, z, -y, ax)
        }
    } else if ay >= az {
        if y > 0.0 {
            (2, x, z, ay)
        } else {
            (3, x, -z, ay)
        }
    } else if z > 0.0 {
        (4, x, -y, az)
    } else {
        (5, -x, -y, az)
    };
    let s = (0.5 * (sc / ma + 1.0) * n as f64 - 0.5).clamp(0.0, n as f64 - 1.0);
    let t = (0.5 * (tc / ma + 1.0) * n as f64 - 0.5).clamp(0.0, n as f64 - 1.0);
    let (s0, t0) = (s.floor() as usize, t.floor() as usize);
    let (s1, t1) = ((s0 + 1).min(n - 1), (t0 + 1).min(n - 1));
    let (fs, ft) = (s - s0 as f64, t - t0 as f64);
    let at = |i: usize, j: usize| texels[face * n * n + j * n + i];
    let mut out = [0.0f32; 3];
    for (c, o) in out.iter_mut().enumerate() {
        let top = f64::from(at(s0, t0)[c]) * (1.0 - fs) + f64::from(at(s1, t0)[c]) * fs;
        let bottom = f64::from(at(s0, t1)[c]) * (1.0 - fs) + f64::from(at(s1, t1)[c]) * fs;
        *o = (top * (1.0 - ft) + bottom * ft) as f32;
    }
    out
}

/// A float image chain to write: level 0 first, each level half the previous.
pub struct FloatChain<'a> {
    /// Level-0 width.
    pub width: u32,
    /// Level-0 height.
    pub height: u32,
    /// Floats per texel (2: R32G32_SFLOAT, 3: R32G32B32_SFLOAT, 4: R32G32B32A32_SFLOAT).
    pub channels: usize,
    /// Texels per level, row-major.
    pub levels: Vec<&'a [f32]>,
    /// Key/value metadata (the `KTXwriter` key is added).
    pub metadata: Vec<(String, String)>,
}

fn align(v: &mut Vec<u8>, to: usize) {
    while v.len() % to != 0 {
        v.push(0);
    }
}

/// Writes a KTX2 file (optionally zstd-supercompressed), through a temporary
/// file beside the target so a failure leaves nothing behind.
pub(crate) fn write_float_chain(path: impl AsRef<Path>, chain: &FloatChain<'_>, zstd: bool) -> Result<()> {
    let bytes = encode_float_chain(chain, zstd)?;
    crate::io::write_atomic(path.as_ref(), &bytes)
}

/// The bytes of a KTX2 file holding `chain`.
pub fn encode_float_chain(chain: &FloatChain<'_>, zstd: bool) -> Result<Vec<u8>> {
    let format = match chain.channels {
        2 => Format::R32G32_SFLOAT,
        3 => Format::R32G32B32_SFLOAT,
        4 => Format::R32G32B32A32_SFLOAT,
        n => return Err(Error::invalid(format!("{n} channels per texel"), "cannot be written to KTX2")),
    };
    let n = chain.levels.len();
    for (l, level) in chain.levels.iter().enumerate() {
        let (w, h) = ((chain.width >> l).max(1) as usize, (chain.height >> l).max(1) as usize);
        if level.len() != w * h * chain.channels {
            return Err(Error::invalid(
                format!("KTX2 level {l} of {} floats", level.len()),
                format!("does not hold {w}x{h} texels"),
            ));
        }
    }
    let (mut basic, type_size) = ktx2::dfd::Basic::from_format(format)
        .map_err(|e| Error::Internal(format!("no KTX2 descriptor for {format:?}: {e:?}")))?;
    if zstd {
        basic.bytes_planes = [0; 8];
    }
    let block = ktx2::dfd::Block::Basic(basic).to_vec();
    let mut dfd = ((block.len() + 4) as u32).to_le_bytes().to_vec();
    dfd.extend(block);
    let mut kvd = Vec::new();
    let mut pairs = vec![("KTXwriter".to_string(), format!("srug {}", env!("CARGO_PKG_VERSION")))];
    pairs.extend(chain.metadata.iter().cloned());
    pairs.sort();
    for (k, v) in &pairs {
        let entry_len = k.len() + 1 + v.len() + 1;
        kvd.extend((entry_len as u32).to_le_bytes());
        kvd.extend(k.as_bytes());
        kvd.push(0);
        kvd.extend(v.as_bytes());
        kvd.push(0);
        align(&mut kvd, 4);
    }
    let index_end = ktx2::Header::LENGTH + n * ktx2::LevelIndex::LENGTH;
    let dfd_offset = index_end;
    let kvd_offset = dfd_offset + dfd.len();
    let mut body = Vec::new();
    body.extend(&dfd);
    body.extend(&kvd);
    // Level data, smallest level first; uncompressed levels aligned to lcm(texel, 4).
    let texel = 4 * chain.channels;
    let alignment = if zstd { 1 } else { texel * 4 / gcd(texel, 4) };
    let mut indices = vec![ktx2::LevelIndex { byte_offset: 0, byte_length: 0, uncompressed_byte_length: 0 }; n];
    for l in (0..n).rev() {
        let raw: &[u8] = bytemuck::cast_slice(chain.levels[l]);
        let data = if zstd {
            ruzstd::encoding::compress_to_vec(raw, ruzstd::encoding::CompressionLevel::Fastest)
        } else {
            raw.to_vec()
        };
        while (index_end + body.len()) % alignment != 0 {
            body.push(0);
        }
        indices[l] = ktx2::LevelIndex {
            byte_offset: (index_end + body.len()) as u64,
            byte_length: data.len() as u64,
            uncompressed_byte_length: raw.len() as u64,
        };
        body.extend(data);
    }
    let header = ktx2::Header {
        format: Some(format),
        type_size,
        pixel_width: chain.width,
        pixel_height: chain.height,
        pixel_depth: 0,
        layer_count: 0,
        face_count: 1,
        level_count: n as u32,
        supercompression_scheme: zstd.then_some(SupercompressionScheme::Zstandard),
        index: ktx2::Index {
            dfd_byte_offset: dfd_offset as u32,
            dfd_byte_length: dfd.len() as u32,
            kvd_byte_offset: if kvd.is_empty() { 0 } else { kvd_offset as u32 },
            kvd_byte_length: kvd.len() as u32,
            sgd_byte_offset: 0,
            sgd_byte_length: 0,
        },
    };
    let mut out = header.as_bytes().to_vec();
    for i in &indices {
        out.extend(i.as_bytes());
    }
    out.extend(body);
    Ok(out)
}

fn gcd(a: usize, b: usize) -> usize {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
    }
}

/// A float chain read back: level sizes, channels, texels and metadata.
pub struct ReadChain {
    /// Level-0 width.
    pub width: u32,
    /// Level-0 height.
    pub height: u32,
    /// Floats per texel.
    pub channels: usize,
    /// Texels per level, level 0 first.
    pub levels: Vec<Vec<f32>>,
    /// Key/value metadata.
    pub metadata: Vec<(String, String)>,
}

/// Reads a float chain written by `write_float_chain` (any R32 float format, every level).
pub fn read_float_chain(bytes: &[u8], origin: &str) -> Result<ReadChain> {
    let reader = open(bytes, origin)?;
    let header = reader.header();
    let channels = match header.format {
        Some(Format::R32G32_SFLOAT) => 2,
        Some(Format::R32G32B32_SFLOAT) => 3,
        Some(Format::R32G32B32A32_SFLOAT) => 4,
        other => return Err(ktx_error(origin, format!("format {other:?} is not a 32-bit float chain"))),
    };
    if header.face_count != 1 || header.layer_count > 1 || header.pixel_depth > 0 || header.pixel_height == 0 {
        return Err(ktx_error(origin, "expected one 2D image with mip levels"));
    }
    let limits = super::limits();
    let mut levels = Vec::new();
    let mut total = 0u64;
    for (l, level) in reader.levels().enumerate() {
        if l >= 32 {
            return Err(ktx_error(origin, "more than 32 mip levels"));
        }
        let (w, h) = ((header.pixel_width >> l).max(1) as usize, (header.pixel_height >> l).max(1) as usize);
        let expected = limits
            .image_bytes(w as u64, h as u64, 1, channels as u64 * 4)
            .map_err(|e| ktx_error(origin, format!("level {l} {e}")))?;
        total += expected as u64;
        if total > limits.max_decoded_bytes {
            return Err(ktx_error(
                origin,
                format!("its levels add up to more than the {} MiB decode limit", limits.max_decoded_bytes >> 20),
            ));
        }
        let data = level_bytes(level.data, header.supercompression_scheme, expected, origin)?;
        let floats: Vec<f32> =
            data[..expected].chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
        if let Some(i) = floats.iter().position(|v| !v.is_finite()) {
            return Err(ktx_error(origin, format!("level {l} value {i} is {} (must be finite)", floats[i])));
        }
        levels.push(floats);
    }
    let metadata = reader
        .key_value_data()
        .map(|(k, v)| (k.to_string(), String::from_utf8_lossy(v).trim_end_matches('\0').to_string()))
        .collect();
    if levels.is_empty() {
        return Err(ktx_error(origin, "the file has no mip level"));
    }
    Ok(ReadChain { width: header.pixel_width, height: header.pixel_height, channels, levels, metadata })
}
