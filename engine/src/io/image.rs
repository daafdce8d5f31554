//! Images out: 8-bit PNG for viewing, multi-channel float EXR for data; and
//! images in for comparison (PNG, EXR, Radiance HDR as linear RGB).

use std::path::Path;

use super::atomic::{finish, temp_beside};
use crate::error::{Error, Result};

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
        return Err(Error::invalid(format!("{} values", rgb.len()), format!("are not a {width}x{height} RGB image")));
    }
    let bytes: Vec<u8> = rgb.iter().copied().map(display_byte).collect();
    let tmp = temp_beside(path);
    let written = image::RgbImage::from_raw(width, height, bytes)
        .ok_or_else(|| Error::Internal("PNG buffer size mismatch".into()))
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

/// Writes named channels (`name`, values, floats per pixel) as 32-bit float
/// channels of one EXR layer, R, G, B for `rgb`, A for `alpha`, Z for `depth`,
/// `normal.X/Y/Z`, `<name>.R/G/B` for other three-float channels, `<name>.Y` for one float.
pub fn write_exr_channels(path: &Path, width: u32, height: u32, channels: &[(&str, &[f32], usize)]) -> Result<()> {
    write_exr_layer(path, width, height, channels, &[])
}

/// [`write_exr_channels`] plus 32-bit unsigned integer channels (ids: no
/// blending, no rounding), each named as given.
pub fn write_exr_layer(
    path: &Path,
    width: u32,
    height: u32,
    channels: &[(&str, &[f32], usize)],
    ids: &[(&str, &[u32])],
) -> Result<()> {
    use exr::prelude::{
        AnyChannel, AnyChannels, Encoding, FlatSamples, Image, Layer, LayerAttributes, LineOrder, Vec2, WritableImage,
    };
    let (w, h) = (width as usize, height as usize);
    let mut list: Vec<AnyChannel<FlatSamples>> = Vec::new();
    for &(name, values, k) in channels {
        if values.len() != k * w * h {
            return Err(Error::invalid(
                format!("channel {name} of {} values", values.len()),
                format!("needs {}", k * w * h),
            ));
        }
        for (c, exr_name) in exr_names(name, k).into_iter().enumerate() {
            let plane: Vec<f32> = (0..w * h).map(|p| values[p * k + c]).collect();
            list.push(AnyChannel::new(exr_name.as_str(), FlatSamples::F32(plane)));
        }
    }
    for &(name, values) in ids {
        if values.len() != w * h {
            return Err(Error::invalid(
                format!("id channel {name} of {} values", values.len()),
                format!("needs {}", w * h),
            ));
        }
        list.push(AnyChannel::new(name, FlatSamples::U32(values.to_vec())));
    }
    // Blocks in increasing order: the parallel writer then emits the same bytes every run.
    let encoding = Encoding { line_order: LineOrder::Increasing, ..Encoding::FAST_LOSSLESS };
    let layer = Layer::new(Vec2(w, h), LayerAttributes::named("srug"), encoding, AnyChannels::sort(list.into()));
    let tmp = temp_beside(path);
    let written = Image::from_layer(layer)
        .write()
        .to_file(&tmp)
        .map_err(|e| Error::Io { path: tmp.clone(), source: std::io::Error::other(e) });
    finish(&tmp, path, written)
}
