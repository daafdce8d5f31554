//! Environment maps on the host: lat-long RGB radiance ([`EnvironmentMap`]),
//! read from OpenEXR, Radiance .hdr or KTX2 files ([`super::ktx`]).
//!
//! Convention (keep in sync with `latlong.glsl`; docs/conventions.md): world z up; column
//! u = 0.5 + φ/2π with φ the azimuth from north (+y) toward east (+x); row
//! v = 0.5 − θ/π with θ the elevation. The image centre looks north at the
//! horizon; the top row is the zenith. Cube maps are read in the left-handed
//! cube-map frame: cube +Y up (world +z), −Z north (world +y), +X west.
//!
//! Invariants: every texel is finite, ≥ 0 and ≤ [`MAX_RADIANCE`] (lossy EXR
//! compression leaves small negatives, which are clamped to 0; brighter texels
//! are clamped with a warning; NaN or infinite values are refused with the
//! texel named).

use std::path::Path;

use crate::error::{Error, Result};

/// Lat-long radiance, RGB floats, rows top (zenith) to bottom (nadir).
#[derive(Clone, Debug, PartialEq)]
pub struct EnvironmentMap {
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// 3 floats per texel, row-major.
    pub rgb: Vec<f32>,
}

pub(crate) fn env_error(origin: &str, message: impl Into<String>) -> Error {
    Error::Environment { origin: origin.to_string(), message: message.into() }
}

/// The file formats an environment map is read from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EnvironmentFormat {
    /// OpenEXR (any compression the exr crate reads).
    Exr,
    /// Radiance RGBE.
    Hdr,
    /// KTX2 with a float format.
    Ktx2,
}

impl EnvironmentFormat {
    /// The format `bytes` start with, by their magic bytes.
    pub fn detect(bytes: &[u8]) -> Option<Self> {
        const KTX2: [u8; 12] = [0xAB, 0x4B, 0x54, 0x58, 0x20, 0x32, 0x30, 0xBB, 0x0D, 0x0A, 0x1A, 0x0A];
        if bytes.starts_with(&[0x76, 0x2f, 0x31, 0x01]) {
            Some(Self::Exr)
        } else if bytes.starts_with(&KTX2) {
            Some(Self::Ktx2)
        } else if bytes.starts_with(b"#?") {
            Some(Self::Hdr)
        } else {
            None
        }
    }

    /// The format's name in messages.
    pub fn name(self) -> &'static str {
        match self {
            Self::Exr => "OpenEXR",
            Self::Hdr => "Radiance .hdr",
            Self::Ktx2 => "KTX2",
        }
    }
}

/// Largest radiance kept (brighter texels are clamped to it, with a
/// warning): far above the sun's, and low enough that prefiltering, shading
/// and exposure stay finite in f32.
pub const MAX_RADIANCE: f32 = 1.0e12;

/// Largest accepted side, texels (a 16k×8k map is 1.5 GiB of f32).
pub const MAX_SIDE: u32 = 16384;

impl EnvironmentMap {
    /// A map from raw texels: checks the size, refuses NaN or infinite values
    /// (naming the texel) and clamps negatives to 0.
    pub fn from_rgb(width: u32, height: u32, mut rgb: Vec<f32>, origin: &str) -> Result<Self> {
        if width == 0 || height == 0 || width > MAX_SIDE || height > MAX_SIDE {
            return Err(env_error(origin, format!("size {width}x{height} is outside 1..={MAX_SIDE}")));
        }
        if rgb.len() != 3 * width as usize * height as usize {
            return Err(env_error(origin, format!("{} values for {width}x{height} RGB texels", rgb.len())));
        }
        if let Some(i) = rgb.iter().position(|v| !v.is_finite()) {
            let t = i / 3;
            return Err(env_error(
                origin,
                format!(
                    "texel ({}, {}) channel {} is {} (environment radiance must be finite)",
                    t % width as usize,
                    t / width as usize,
                    ["R", "G", "B"][i % 3],
                    rgb[i]
                ),
            ));
        }
        let mut clamped = 0usize;
        for v in &mut rgb {
            if *v > MAX_RADIANCE {
                clamped += 1;
            }
            *v = v.clamp(0.0, MAX_RADIANCE);
        }
        if clamped > 0 {
            log::warn!(
                "{origin}: {clamped} texel values above {MAX_RADIANCE:e} clamped to it (the sun's radiance is about 1.6e9)"
            );
        }
        Ok(Self { width, height, rgb })
    }

    /// A constant environment (the white furnace uses radiance 1).
    pub fn uniform(radiance: [f32; 3], width: u32, height: u32) -> Result<Self> {
        let rgb = (0..width as usize * height as usize).flat_map(|_| radiance).collect();
        Self::from_rgb(width, height, rgb, "uniform environment")
    }

    /// Reads `.exr` (any compression the exr crate reads, DWAB included), `.hdr`
    /// (Radiance RGBE) or `.ktx2` (float formats, 2D lat-long or cube, zstd
    /// supercompression; level 0 is used). Other files get an error naming why.
    pub fn load(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        let origin = path.display().to_string();
        let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).unwrap_or_default();
        let named = match ext.as_str() {
            "exr" => EnvironmentFormat::Exr,
            "hdr" => EnvironmentFormat::Hdr,
            "ktx2" => EnvironmentFormat::Ktx2,
            other => {
                return Err(env_error(
                    &origin,
                    format!("unknown extension \".{other}\" (environment maps are .exr, .hdr or .ktx2)"),
                ))
            }
        };
        let bytes = super::read_file(path)?;
        match EnvironmentFormat::detect(&bytes) {
            Some(held) if held != named => {
                Err(env_error(&origin, format!("is named .{ext} but holds {} data", held.name())))
            }
            _ => Self::from_bytes(&bytes, &origin),
        }
    }

    /// Reads an environment map from bytes, its format detected from the
    /// content (OpenEXR, Radiance .hdr or KTX2 magic); `origin` names it in errors.
    pub fn from_bytes(bytes: &[u8], origin: &str) -> Result<Self> {
        match EnvironmentFormat::detect(bytes) {
            Some(EnvironmentFormat::Exr) => read_exr(bytes, origin),
            Some(EnvironmentFormat::Hdr) => read_hdr(bytes, origin),
            Some(EnvironmentFormat::Ktx2) => super::ktx::read_environment(bytes, origin),
            None => Err(env_error(origin, "is not an OpenEXR, Radiance .hdr or KTX2 file (no known magic bytes)")),
        }
    }

    /// Texel (x, y) as RGB.
    pub fn texel(&self, x: u32, y: u32) -> [f32; 3] {
        let i = 3 * (y as usize * self.width as usize + x as usize);
        [self.rgb[i], self.rgb[i + 1], self.rgb[i + 2]]
    }

    /// The direction (world, z up) of the map's brightest texel by
    /// luminance, and how many times the map's mean luminance it is: a
    /// clear-sky HDRI's sun stands out by orders of magnitude, an overcast
    /// sky's brightest texel by little.
    pub fn brightest(&self) -> ([f64; 3], f64) {
        let lum = |t: &[f32]| 0.2126 * f64::from(t[0]) + 0.7152 * f64::from(t[1]) + 0.0722 * f64::from(t[2]);
        let (mut best, mut peak, mut sum) = (0usize, -1.0f64, 0.0f64);
        for (i, t) in self.rgb.chunks_exact(3).enumerate() {
            let l = lum(t);
            sum += l;
            if l > peak {
                (best, peak) = (i, l);
            }
        }
        let n = (self.width as usize * self.height as usize).max(1);
        let (w, h) = (self.width as usize, self.height as usize);
        let direction = super::ktx::latlong_direction(best % w.max(1), best / w.max(1), w, h);
        let mean = sum / n as f64;
        (direction, if mean > 0.0 { peak / mean } else { 0.0 })
    }

    /// Largest channel value.
    pub fn max_value(&self) -> f32 {
        self.rgb.iter().copied().fold(0.0, f32::max)
    }
}

/// Reads OpenEXR bytes: the header's data windows are checked against the
/// limits before any pixel is decoded.
pub(crate) fn read_exr(bytes: &[u8], origin: &str) -> Result<EnvironmentMap> {
    use exr::prelude::*;
    let not_exr = |e: exr::error::Error| env_error(origin, format!("not a readable OpenEXR RGB image: {e}"));
    check_exr(bytes, origin, |_| 12)?;
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .rgba_channels(
            |resolution, _| (resolution.width(), vec![0.0f32; 3 * resolution.width() * resolution.height()]),
            |(w, data): &mut (usize, Vec<f32>), pos, (r, g, b, _a): (f32, f32, f32, f32)| {
                let i = 3 * (pos.y() * *w + pos.x());
                data[i] = r;
                data[i + 1] = g;
                data[i + 2] = b;
            },
        )
        .first_valid_layer()
        .all_attributes()
        // On the calling thread: the parallel reader leaves decompression jobs running on its
        // thread pool after it returns an error (found by fuzzing), holding their buffers.
        .non_parallel()
        .from_buffered(std::io::Cursor::new(bytes))
        .map_err(not_exr)?;
    let size = image.layer_data.size;
    let (_, data) = image.layer_data.channel_data.pixels;
    EnvironmentMap::from_rgb(size.width() as u32, size.height() as u32, data, origin)
}

/// Checks an OpenEXR's data windows against the limits (`bytes_per_pixel`
/// decoded for each layer) and its DWA chunks, before any pixel is decoded.
fn check_exr(bytes: &[u8], origin: &str, bytes_per_pixel: impl Fn(&exr::meta::header::Header) -> u64) -> Result<()> {
    let not_exr = |e: exr::error::Error| env_error(origin, format!("not a readable OpenEXR image: {e}"));
    let meta = exr::meta::MetaData::read_from_buffered(std::io::Cursor::new(bytes), false).map_err(not_exr)?;
    let limits = super::limits();
    for header in &meta.headers {
        let size = header.layer_size;
        limits
            .image_bytes(size.width() as u64, size.height() as u64, 1, bytes_per_pixel(header))
            .map_err(|e| env_error(origin, format!("its data window {e}")))?;
    }
    check_dwa_chunks(bytes, origin)
}

/// Reads one channel of an OpenEXR image (width, height, row-major values):
/// `Y`, else `R`, else the first; the same limits and checks as [`read_exr`].
/// For single-channel images such as masks.
pub(crate) fn read_exr_channel(bytes: &[u8], origin: &str) -> Result<(u32, u32, Vec<f32>)> {
    use exr::prelude::*;
    let not_exr = |e: exr::error::Error| env_error(origin, format!("not a readable OpenEXR image: {e}"));
    check_exr(bytes, origin, |h| 4 * h.channels.list.len() as u64)?;
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .non_parallel()
        .from_buffered(std::io::Cursor::new(bytes))
        .map_err(not_exr)?;
    let size = image.layer_data.size;
    let channels = &image.layer_data.channel_data.list;
    let named = |n: &str| channels.iter().find(|c| c.name.to_string() == n);
    let channel =
        named("Y").or_else(|| named("R")).or(channels.first()).ok_or_else(|| env_error(origin, "has no channel"))?;
    Ok((size.width() as u32, size.height() as u32, channel.sample_data.values_as_f32().collect()))
}

/// A DWA-compressed layer: the bound on a chunk's counters, rows per
/// scan-line chunk, bytes per pixel, data window top, height and width.
type DwaLayer = (u64, usize, usize, i32, usize, usize);

/// exr 1.74 allocates what a DWAA/DWAB chunk's counters declare before it
/// decodes the chunk (a crafted one asked for 17 TB and aborted the process;
/// found by fuzzing). Every DWA chunk's sizes and counts are checked against
/// the pixels a chunk can hold first: at most 256 rows (DWAB; DWAA 32) of the
/// data window's width, or one tile, times the channels, 8 bytes a sample.
fn check_dwa_chunks(bytes: &[u8], origin: &str) -> Result<()> {
    use exr::block::chunk::CompressedBlock;
    use exr::compression::Compression;
    use exr::meta::BlockDescription;
    let not_exr = |e: exr::error::Error| env_error(origin, format!("not a readable OpenEXR RGB image: {e}"));
    let reader = exr::block::read(std::io::Cursor::new(bytes), false).map_err(not_exr)?;
    let layers: Vec<Option<DwaLayer>> = reader
        .meta_data()
        .headers
        .iter()
        .map(|h| {
            let rows = match h.compression {
                Compression::DWAA(_) => 32,
                Compression::DWAB(_) => 256,
                _ => return None,
            };
            let round8 = |n: usize| n.div_ceil(8) as u64 * 8;
            let pixels = match h.blocks {
                BlockDescription::Tiles(t) => round8(t.tile_size.width()) * round8(t.tile_size.height()),
                BlockDescription::ScanLines => 256 * round8(h.layer_size.width()),
            };
            let bound = pixels.saturating_mul(h.channels.list.len() as u64).saturating_mul(8);
            let (top, size) = (h.own_attributes.layer_position.y(), h.layer_size);
            Some((bound, rows, h.channels.bytes_per_pixel, top, size.height(), size.width()))
        })
        .collect();
    if layers.iter().all(Option::is_none) {
        return Ok(());
    }
    for chunk in reader.all_chunks(false).map_err(not_exr)? {
        let chunk = chunk.map_err(not_exr)?;
        let Some((bound, rows, bpp, top, height, width)) = layers.get(chunk.layer_index).copied().flatten() else {
            continue;
        };
        let data = match &chunk.compressed_block {
            CompressedBlock::ScanLine(b) => {
                // A chunk compression would not have shrunk is stored raw: no leader to check.
                let below = usize::try_from(i64::from(b.y_coordinate) - i64::from(top)).unwrap_or(0);
                let raw = rows.min(height.saturating_sub(below)) * width * bpp;
                if b.compressed_pixels_le.len() == raw {
                    continue;
                }
                &b.compressed_pixels_le
            }
            CompressedBlock::Tile(b) => &b.compressed_pixels_le,
            _ => continue,
        };
        // The chunk leader: version, then nine sizes and counts, then the AC coder (u64 each).
        let counter = |i: usize| data.get(8 * i..8 * i + 8).map(|b| u64::from_le_bytes(b.try_into().unwrap_or([0; 8])));
        if let Some(value) = (1..10).filter_map(counter).find(|v| *v > bound) {
            return Err(env_error(
                origin,
                format!(
                    "a DWA-compressed chunk declares a section of {value}, more than the {bound} its pixels can hold"
                ),
            ));
        }
    }
    Ok(())
}

/// Reads Radiance RGBE bytes.
pub(crate) fn read_hdr(bytes: &[u8], origin: &str) -> Result<EnvironmentMap> {
    use image::ImageDecoder;
    let mut decoder = image::codecs::hdr::HdrDecoder::new(std::io::Cursor::new(bytes))
        .map_err(|e| env_error(origin, format!("not a Radiance .hdr file: {e}")))?;
    let l = super::limits();
    let (w, h) = decoder.dimensions();
    l.image_bytes(u64::from(w), u64::from(h), 1, 12).map_err(|e| env_error(origin, format!("its header {e}")))?;
    let mut image_limits = image::Limits::default();
    image_limits.max_image_width = Some(l.max_image_side);
    image_limits.max_image_height = Some(l.max_image_side);
    image_limits.max_alloc = Some(l.max_decoded_bytes);
    decoder.set_limits(image_limits).map_err(|e| env_error(origin, format!("is over the decode limits: {e}")))?;
    let img = image::DynamicImage::from_decoder(decoder)
        .map_err(|e| env_error(origin, format!("corrupt Radiance .hdr data: {e}")))?
        .to_rgb32f();
    let (w, h) = img.dimensions();
    EnvironmentMap::from_rgb(w, h, img.into_raw(), origin)
}
