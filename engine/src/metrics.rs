//! Image quality metrics the paper reports for relighting: PSNR and SSIM.
//!
//! Both run in f64 on the host over interleaved RGB. SSIM follows Wang et al.
//! 2004 as scikit-image computes it with `gaussian_weights=True, sigma=1.5,
//! use_sample_covariance=False`: an 11×11 Gaussian window (σ = 1.5, truncated
//! at 3.5σ and normalised), K1 = 0.01, K2 = 0.03, the mean of the SSIM map over
//! the pixels whose window lies inside the image, averaged over channels.

use std::path::Path;

use crate::error::{Error, Result};

/// An RGB image with values in [0, `peak`] (1 for PNGs read by [`read_image`]).
#[derive(Clone, Debug, PartialEq)]
pub struct RgbImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Interleaved RGB, row-major, 3 floats per pixel.
    pub rgb: Vec<f32>,
}

fn check_pair(a: &RgbImage, b: &RgbImage) -> Result<()> {
    if (a.width, a.height) != (b.width, b.height) {
        return Err(Error::invalid(
            "image pair",
            format!("the images differ in size: {}x{} and {}x{}", a.width, a.height, b.width, b.height),
        ));
    }
    let n = 3 * a.width as usize * a.height as usize;
    if a.rgb.len() != n || b.rgb.len() != n {
        return Err(Error::invalid("image", format!("holds the wrong number of values for its size ({n})")));
    }
    if let Some(i) = a.rgb.iter().chain(&b.rgb).position(|v| !v.is_finite()) {
        return Err(Error::invalid(format!("value {i}"), "is not finite"));
    }
    Ok(())
}

/// Peak signal-to-noise ratio in dB over all channels: 10·log10(peak² / MSE);
/// +∞ for identical images.
pub fn psnr(a: &RgbImage, b: &RgbImage, peak: f64) -> Result<f64> {
    check_pair(a, b)?;
    let mse = a.rgb.iter().zip(&b.rgb).map(|(x, y)| (f64::from(*x) - f64::from(*y)).powi(2)).sum::<f64>()
        / a.rgb.len().max(1) as f64;
    Ok(if mse == 0.0 { f64::INFINITY } else { 10.0 * (peak * peak / mse).log10() })
}

/// The normalised 1-D Gaussian window (σ = 1.5, radius 5).
fn window() -> [f64; 11] {
    let mut w = [0.0; 11];
    for (i, v) in w.iter_mut().enumerate() {
        let x = i as f64 - 5.0;
        *v = (-x * x / (2.0 * 1.5 * 1.5)).exp();
    }
    let sum: f64 = w.iter().sum();
    w.map(|v| v / sum)
}

/// Structural similarity, mean over the valid SSIM map and the three channels.
/// Needs images of at least 11×11 pixels.
pub fn ssim(a: &RgbImage, b: &RgbImage, peak: f64) -> Result<f64> {
    check_pair(a, b)?;
    let (w, h) = (a.width as usize, a.height as usize);
    if w < 11 || h < 11 {
        return Err(Error::invalid(format!("image of {w}x{h}"), "is smaller than the 11x11 pixels SSIM needs"));
    }
    let g = window();
    let (c1, c2) = ((0.01 * peak).powi(2), (0.03 * peak).powi(2));
    let (ow, oh) = (w - 10, h - 10);
    let mut total = 0.0;
    for c in 0..3 {
        let x: Vec<f64> = a.rgb.iter().skip(c).step_by(3).map(|v| f64::from(*v)).collect();
        let y: Vec<f64> = b.rgb.iter().skip(c).step_by(3).map(|v| f64::from(*v)).collect();
        let products: [Vec<f64>; 5] = [
            x.clone(),
            y.clone(),
            x.iter().map(|v| v * v).collect(),
            y.iter().map(|v| v * v).collect(),
            x.iter().zip(&y).map(|(p, q)| p * q).collect(),
        ];
        // Separable valid filtering: rows, then columns.
        let [fx, fy, fxx, fyy, fxy] = products.map(|img| {
            let mut rows = vec![0.0; ow * h];
            for r in 0..h {
                for o in 0..ow {
                    rows[r * ow + o] = (0..11).map(|k| g[k] * img[r * w + o + k]).sum();
                }
            }
            let mut out = vec![0.0; ow * oh];
            for r in 0..oh {
                for o in 0..ow {
                    out[r * ow + o] = (0..11).map(|k| g[k] * rows[(r + k) * ow + o]).sum();
                }
            }
            out
        });
        let mut sum = 0.0;
        for ((((mx, my), sxx), syy), sxy) in fx.iter().zip(&fy).zip(&fxx).zip(&fyy).zip(&fxy) {
            let (vx, vy, cxy) = (sxx - mx * mx, syy - my * my, sxy - mx * my);
            sum += ((2.0 * mx * my + c1) * (2.0 * cxy + c2)) / ((mx * mx + my * my + c1) * (vx + vy + c2));
        }
        total += sum / (ow * oh) as f64;
    }
    Ok(total / 3.0)
}

/// Reads an image for comparison: PNG (8 or 16 bit, scaled to [0, 1]; alpha
/// dropped) or linear EXR / Radiance HDR (RGB as stored, negatives clamped).
pub fn read_image(path: &Path) -> Result<RgbImage> {
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("png") => read_png_bytes(&crate::io::read_file(path)?, &path.display().to_string()),
        Some("exr") | Some("hdr") => {
            let map = crate::shade::EnvironmentMap::load(path)?;
            Ok(RgbImage { width: map.width, height: map.height, rgb: map.rgb })
        }
        _ => Err(Error::invalid(path.display().to_string(), "images must be .png, .exr or .hdr")),
    }
}

/// Decodes PNG bytes for comparison (8 or 16 bit, scaled to [0, 1]; alpha
/// dropped) within the image limits ([`crate::io::Limits`]); `origin` names it in errors.
pub fn read_png_bytes(bytes: &[u8], origin: &str) -> Result<RgbImage> {
    let bad = |e: image::ImageError| Error::invalid(origin, format!("cannot read the PNG: {e}"));
    let l = crate::io::limits();
    let mut reader = image::ImageReader::with_format(std::io::Cursor::new(bytes), image::ImageFormat::Png);
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(l.max_image_side);
    limits.max_image_height = Some(l.max_image_side);
    limits.max_alloc = Some(l.max_decoded_bytes);
    reader.limits(limits);
    let img = reader.decode().map_err(bad)?.into_rgb32f();
    Ok(RgbImage { width: img.width(), height: img.height(), rgb: img.into_raw() })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, reason = "tests")]
    use super::*;

    fn image(w: u32, h: u32, f: impl Fn(usize, usize, usize) -> f32) -> RgbImage {
        let mut rgb = Vec::new();
        for y in 0..h as usize {
            for x in 0..w as usize {
                rgb.extend((0..3).map(|c| f(x, y, c)));
            }
        }
        RgbImage { width: w, height: h, rgb }
    }

    #[test]
    fn identical_images_are_perfect() {
        let a = image(23, 17, |x, y, c| ((x * 7 + y * 3 + c) % 11) as f32 / 10.0);
        assert_eq!(psnr(&a, &a, 1.0).unwrap(), f64::INFINITY);
        assert!((ssim(&a, &a, 1.0).unwrap() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn closed_forms() {
        // A constant offset d: MSE = d², PSNR = −20·log10(d).
        let a = image(16, 16, |x, y, _| ((x + y) % 5) as f32 / 8.0);
        let b = RgbImage { rgb: a.rgb.iter().map(|v| v + 0.125).collect(), ..a.clone() };
        assert!((psnr(&a, &b, 1.0).unwrap() - 20.0 * 8f64.log10()).abs() < 1e-9);
        // Constant images: only the luminance term, (2μxμy + C1) / (μx² + μy² + C1).
        let (p, q) = (0.25f32, 0.75f32);
        let s = ssim(&image(12, 14, |_, _, _| p), &image(12, 14, |_, _, _| q), 1.0).unwrap();
        let c1 = 1e-4;
        let expect = (2.0 * 0.25 * 0.75 + c1) / (0.25f64.powi(2) + 0.75f64.powi(2) + c1);
        assert!((s - expect).abs() < 1e-12, "{s} vs {expect}");
    }

    /// Values from scikit-image 0.26 (`structural_similarity(a, b, gaussian_weights=True,
    /// sigma=1.5, use_sample_covariance=False, data_range=1, channel_axis=-1)` and
    /// `peak_signal_noise_ratio`) on the same float64 images, computed once on a machine
    /// that has it (the images are defined below).
    #[test]
    fn agrees_with_scikit_image() {
        // a = ((37x + 91y + 53c) mod 256)/255, b adds (xy mod 29) before the mod; 40×31.
        let a = image(40, 31, |x, y, c| ((x * 37 + y * 91 + c * 53) % 256) as f32 / 255.0);
        let b = image(40, 31, |x, y, c| ((x * 37 + y * 91 + c * 53 + (x * y) % 29) % 256) as f32 / 255.0);
        // a2 = 0.5 + 0.4 sin(x/5 + c) cos(y/7), b2 = a2 + 0.05 cos(xy/13).
        let f = |x: usize, y: usize, c: usize| 0.5 + 0.4 * (x as f64 / 5.0 + c as f64).sin() * (y as f64 / 7.0).cos();
        let a2 = image(40, 31, |x, y, c| f(x, y, c) as f32);
        let b2 = image(40, 31, |x, y, c| (f(x, y, c) + 0.05 * ((x * y) as f64 / 13.0).cos()) as f32);
        // The images are stored in f32 here (float64 there): agreement to 1e-6.
        for (got, want) in [
            (ssim(&a, &b, 1.0).unwrap(), 0.702_094_583_354_788_2),
            (psnr(&a, &b, 1.0).unwrap(), 13.305_505_069_747_15),
            (ssim(&a2, &b2, 1.0).unwrap(), 0.875_274_806_988_493_9),
            (psnr(&a2, &b2, 1.0).unwrap(), 28.865_110_261_857_133),
        ] {
            assert!((got - want).abs() < 1e-6 * want.abs(), "{got} vs scikit-image {want}");
        }
    }

    #[test]
    fn bad_pairs_are_refused() {
        let a = image(12, 12, |_, _, _| 0.5);
        assert!(psnr(&a, &image(12, 13, |_, _, _| 0.5), 1.0).is_err());
        assert!(ssim(&image(10, 12, |_, _, _| 0.5), &image(10, 12, |_, _, _| 0.5), 1.0).is_err());
        let nan = image(12, 12, |x, _, _| if x == 3 { f32::NAN } else { 0.5 });
        assert!(psnr(&a, &nan, 1.0).unwrap_err().to_string().contains("not finite"));
    }
}
