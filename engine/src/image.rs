//! Host-side image operations shared by the stages and the tools.

use crate::error::{Error, Result};

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
        return Err(Error::invalid(
            format!("{} values as a {width}x{height} image of {channels} channels", src.len()),
            format!("cannot be resampled to {new_width}x{new_height}"),
        ));
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
