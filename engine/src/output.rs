//! Writing rendered images: 8-bit PNG for viewing, multi-channel float EXR for data.
//!
//! Both write to a temporary file beside the target and rename it, so a
//! failure leaves nothing behind.

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::splat::GBuffer;

fn temp_beside(path: &Path) -> PathBuf {
    let name = path.file_name().map(|f| f.to_string_lossy().into_owned()).unwrap_or_default();
    path.with_file_name(format!(".{name}.tmp-{}", std::process::id()))
}

fn finish(tmp: &Path, path: &Path, written: Result<()>) -> Result<()> {
    let result = written.and_then(|()| std::fs::rename(tmp, path).map_err(Error::io(path)));
    if result.is_err() {
        let _ = std::fs::remove_file(tmp);
    }
    result
}

/// Writes `bytes` to `path` through a temporary file beside it.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let tmp = temp_beside(path);
    let written = std::fs::write(&tmp, bytes).map_err(Error::io(&tmp));
    finish(&tmp, path, written)
}

/// A display value in [0, 1] as a byte: clamped and rounded; NaN and ±Inf become 0.
pub fn display_byte(v: f32) -> u8 {
    if v.is_finite() {
        (v.clamp(0.0, 1.0) * 255.0).round() as u8
    } else {
        0
    }
}

/// Writes interleaved RGB floats (display values in [0, 1]; clamped, rounded) as an 8-bit PNG.
pub fn write_png(path: impl AsRef<Path>, width: u32, height: u32, rgb: &[f32]) -> Result<()> {
    let path = path.as_ref();
    if rgb.len() != 3 * width as usize * height as usize {
        return Err(Error::InvalidArgument(format!("{} values for a {width}x{height} RGB image", rgb.len())));
    }
    let bytes: Vec<u8> = rgb.iter().copied().map(display_byte).collect();
    let tmp = temp_beside(path);
    let written = image::RgbImage::from_raw(width, height, bytes)
        .ok_or_else(|| Error::InvalidArgument("image size mismatch".into()))
        .and_then(|img| {
            img.save_with_format(&tmp, image::ImageFormat::Png)
                .map_err(|e| Error::Io { path: tmp.clone(), source: std::io::Error::other(e) })
        });
    finish(&tmp, path, written)
}

/// EXR channel names for a G-buffer channel with `k` floats per pixel.
fn exr_names(channel: &str, k: usize) -> Vec<String> {
    match (channel, k) {
        ("rgb", _) => vec!["R".into(), "G".into(), "B".into()],
        ("alpha", _) => vec!["A".into()],
        ("depth", _) => vec!["Z".into()],
        (name, 3) if name == "normal" => ["X", "Y", "Z"].iter().map(|c| format!("{name}.{c}")).collect(),
        (name, 3) => ["R", "G", "B"].iter().map(|c| format!("{name}.{c}")).collect(),
        (name, _) => vec![format!("{name}.Y")],
    }
}

/// Writes every channel of `g` as 32-bit float channels of one EXR layer
/// (R, G, B, A, Z, median_depth.Y, normal.X/Y/Z, albedo.R/G/B, roughness.Y, ...).
pub fn write_exr(path: impl AsRef<Path>, g: &GBuffer) -> Result<()> {
    write_exr_channels(path.as_ref(), g.width, g.height, &g.channels())
}

/// Writes named channels (`name`, values, floats per pixel) as 32-bit float
/// channels of one EXR layer, named as [`write_exr`] names them.
pub fn write_exr_channels(path: &Path, width: u32, height: u32, channels: &[(&str, &[f32], usize)]) -> Result<()> {
    use exr::prelude::{
        AnyChannel, AnyChannels, Encoding, FlatSamples, Image, Layer, LayerAttributes, Vec2, WritableImage,
    };
    let (w, h) = (width as usize, height as usize);
    let mut list: Vec<AnyChannel<FlatSamples>> = Vec::new();
    for &(name, values, k) in channels {
        if values.len() != k * w * h {
            return Err(Error::InvalidArgument(format!(
                "channel {name} holds {} values, not {}",
                values.len(),
                k * w * h
            )));
        }
        for (c, exr_name) in exr_names(name, k).into_iter().enumerate() {
            let plane: Vec<f32> = (0..w * h).map(|p| values[p * k + c]).collect();
            list.push(AnyChannel::new(exr_name.as_str(), FlatSamples::F32(plane)));
        }
    }
    let layer =
        Layer::new(Vec2(w, h), LayerAttributes::named("srug"), Encoding::FAST_LOSSLESS, AnyChannels::sort(list.into()));
    let tmp = temp_beside(path);
    let written = Image::from_layer(layer)
        .write()
        .to_file(&tmp)
        .map_err(|e| Error::Io { path: tmp.clone(), source: std::io::Error::other(e) });
    finish(&tmp, path, written)
}

/// Bilinear resampling of an interleaved image (`channels` floats per pixel,
/// pixel centres at +0.5, edges clamped) from `width`×`height` to
/// `new_width`×`new_height`. Upscales a frame rendered at a lower render scale.
pub fn resample_bilinear(
    src: &[f32],
    (width, height): (u32, u32),
    channels: usize,
    (new_width, new_height): (u32, u32),
) -> Result<Vec<f32>> {
    let (w, h) = (width as usize, height as usize);
    if w == 0 || h == 0 || new_width == 0 || new_height == 0 || src.len() != w * h * channels {
        return Err(Error::InvalidArgument(format!(
            "cannot resample {} values as a {width}x{height} image of {channels} channels to {new_width}x{new_height}",
            src.len()
        )));
    }
    let (sx, sy) = (f64::from(width) / f64::from(new_width), f64::from(height) / f64::from(new_height));
    let axis = |i: u32, scale: f64, n: usize| {
        let x = ((f64::from(i) + 0.5) * scale - 0.5).clamp(0.0, (n - 1) as f64);
        let x0 = x.floor() as usize;
        (x0, (x0 + 1).min(n - 1), x - x0 as f64)
    };
    let mut out = Vec::with_capacity(new_width as usize * new_height as usize * channels);
    for y in 0..new_height {
        let (y0, y1, fy) = axis(y, sy, h);
        for x in 0..new_width {
            let (x0, x1, fx) = axis(x, sx, w);
            for c in 0..channels {
                let at = |xx: usize, yy: usize| f64::from(src[(yy * w + xx) * channels + c]);
                let top = at(x0, y0) * (1.0 - fx) + at(x1, y0) * fx;
                let bottom = at(x0, y1) * (1.0 - fx) + at(x1, y1) * fx;
                out.push((top * (1.0 - fy) + bottom * fy) as f32);
            }
        }
    }
    Ok(out)
}

#[cfg(test)]
#[allow(clippy::unwrap_used, reason = "a failed unwrap is a failed test")]
mod tests {
    use super::resample_bilinear;

    #[test]
    fn bilinear_resampling_keeps_constants_and_linear_ramps() {
        let constant = vec![0.25f32; 4 * 3 * 2];
        let up = resample_bilinear(&constant, (4, 3), 2, (9, 7)).unwrap();
        assert!(up.iter().all(|v| (*v - 0.25).abs() < 1e-7));
        // A ramp in x at pixel centres upsampled ×2: interior samples stay on the ramp.
        let ramp: Vec<f32> = (0..8).map(|x| x as f32 + 0.5).collect();
        let up = resample_bilinear(&ramp, (8, 1), 1, (16, 1)).unwrap();
        for (i, v) in up.iter().enumerate().skip(1).take(14) {
            assert!((v - (i as f32 + 0.5) / 2.0).abs() < 1e-6, "{i}: {v}");
        }
        assert_eq!(resample_bilinear(&ramp, (8, 1), 1, (8, 1)).unwrap(), ramp);
        assert!(resample_bilinear(&ramp, (4, 1), 1, (8, 1)).is_err(), "wrong length");
        assert!(resample_bilinear(&ramp, (8, 1), 1, (0, 1)).is_err(), "empty target");
    }
}
