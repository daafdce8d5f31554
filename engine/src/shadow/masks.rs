//! Shadow masks: per-photograph images saying where the photograph is in
//! shadow (what MTMT and other shadow detectors write), read, matched to
//! cameras by image name, and turned into target sun visibilities for
//! [`super::completion`].
//!
//! Polarity: white (1) is shadow, black (0) is lit, grey a detector's
//! probability of shadow (the target visibility is 1 − value, soft);
//! [`MaskOptions::invert`] swaps it. Unknown pixels, which the fit ignores:
//! those an image's alpha channel makes transparent (α < 0.5), and those a
//! second, optional ignore mask marks white (≥ 0.5). A mask of another size
//! than its camera is resampled bilinearly (pixel centres at +0.5), unknown
//! where any of its four source pixels is.

use std::path::{Path, PathBuf};

use crate::camera::Camera;
use crate::error::{Error, Result};

/// Extensions a mask may have (case-insensitive).
pub const MASK_EXTENSIONS: [&str; 5] = ["png", "jpg", "jpeg", "exr", "hdr"];

/// A mask as read: the shadow value and whether it is known, per pixel.
#[derive(Clone, Debug, PartialEq)]
pub struct MaskImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// The image value in [0, 1] (mean of its colour channels), row-major.
    pub value: Vec<f32>,
    /// Whether the pixel is known (not transparent).
    pub known: Vec<bool>,
}

/// How masks are read.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MaskOptions {
    /// Black is shadow instead of white.
    pub invert: bool,
}

/// Reads a mask (checked with [`MaskImage::validate`]): PNG or JPEG (8 or 16 bit, grey or colour, with or without
/// alpha: the mean of the colour channels), EXR (its Y channel, else R, else
/// the first; NaN unknown) or Radiance HDR (mean of RGB); floats clamped to [0, 1].
pub fn read_mask(path: &Path) -> Result<MaskImage> {
    let mask = read_mask_unchecked(path)?;
    mask.validate(&path.display().to_string())?;
    Ok(mask)
}

fn read_mask_unchecked(path: &Path) -> Result<MaskImage> {
    let origin = path.display().to_string();
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("exr") => {
            let (width, height, v) = crate::io::environment::read_exr_channel(&crate::io::read_file(path)?, &origin)?;
            let known = v.iter().map(|x| x.is_finite()).collect();
            let value = v.iter().map(|x| if x.is_finite() { x.clamp(0.0, 1.0) } else { 0.0 }).collect();
            Ok(MaskImage { width, height, value, known })
        }
        Some("hdr") => {
            let map = crate::io::EnvironmentMap::load(path)?;
            let value = map.rgb.chunks_exact(3).map(|c| ((c[0] + c[1] + c[2]) / 3.0).clamp(0.0, 1.0)).collect();
            Ok(MaskImage { width: map.width, height: map.height, value, known: vec![true; map.rgb.len() / 3] })
        }
        Some("png") | Some("jpg") | Some("jpeg") => {
            let bytes = crate::io::read_file(path)?;
            let format = if ext.as_deref() == Some("png") { image::ImageFormat::Png } else { image::ImageFormat::Jpeg };
            let l = crate::io::limits();
            let mut reader = image::ImageReader::with_format(std::io::Cursor::new(bytes), format);
            let mut limits = image::Limits::default();
            limits.max_image_width = Some(l.max_image_side);
            limits.max_image_height = Some(l.max_image_side);
            limits.max_alloc = Some(l.max_decoded_bytes);
            reader.limits(limits);
            let img = reader.decode().map_err(|e| Error::invalid(&origin, format!("cannot read the mask: {e}")))?;
            let rgba = img.into_rgba32f();
            let (width, height) = rgba.dimensions();
            let (mut value, mut known) = (Vec::new(), Vec::new());
            for p in rgba.pixels() {
                value.push(((p[0] + p[1] + p[2]) / 3.0).clamp(0.0, 1.0));
                known.push(p[3] >= 0.5);
            }
            Ok(MaskImage { width, height, value, known })
        }
        _ => Err(Error::invalid(&origin, format!("a mask must be one of {}", MASK_EXTENSIONS.join(", ")))),
    }
}

impl MaskImage {
    /// Checks that the mask has pixels and one value and one known flag per
    /// pixel; `origin` names it in the error.
    pub fn validate(&self, origin: &str) -> Result<()> {
        let pixels = self.width as usize * self.height as usize;
        if pixels == 0 || self.value.len() != pixels || self.known.len() != pixels {
            return Err(Error::invalid(
                format!(
                    "mask {origin} ({}x{}, {} values, {} flags)",
                    self.width,
                    self.height,
                    self.value.len(),
                    self.known.len()
                ),
                "needs at least one pixel and one value and flag per pixel",
            ));
        }
        Ok(())
    }

    /// Resampled to `width`×`height` (bilinear, unknown where any of the four
    /// source pixels is); itself when the size matches. Needs a valid mask
    /// ([`MaskImage::validate`]).
    pub fn resampled(&self, width: u32, height: u32) -> MaskImage {
        if (width, height) == (self.width, self.height) {
            return self.clone();
        }
        let (sw, sh) = (self.width as usize, self.height as usize);
        let mut value = Vec::with_capacity((width * height) as usize);
        let mut known = Vec::with_capacity(value.capacity());
        for y in 0..height {
            let fy = ((f64::from(y) + 0.5) * sh as f64 / f64::from(height) - 0.5).clamp(0.0, (sh - 1) as f64);
            let (y0, ty) = (fy.floor() as usize, fy - fy.floor());
            let y1 = (y0 + 1).min(sh - 1);
            for x in 0..width {
                let fx = ((f64::from(x) + 0.5) * sw as f64 / f64::from(width) - 0.5).clamp(0.0, (sw - 1) as f64);
                let (x0, tx) = (fx.floor() as usize, fx - fx.floor());
                let x1 = (x0 + 1).min(sw - 1);
                let at = |xx: usize, yy: usize| f64::from(self.value[yy * sw + xx]);
                let top = at(x0, y0) * (1.0 - tx) + at(x1, y0) * tx;
                let bottom = at(x0, y1) * (1.0 - tx) + at(x1, y1) * tx;
                value.push((top * (1.0 - ty) + bottom * ty) as f32);
                known.push([(x0, y0), (x1, y0), (x0, y1), (x1, y1)].iter().all(|(a, b)| self.known[b * sw + a]));
            }
        }
        MaskImage { width, height, value, known }
    }

    /// The target sun visibility for `camera`: 1 − shadow value (the value
    /// itself with `invert`), −1 where unknown here or white in `ignore`.
    pub fn target(&self, camera: &Camera, ignore: Option<&MaskImage>, options: MaskOptions) -> Result<Vec<f32>> {
        self.validate(&format!("of camera \"{}\"", camera.name))?;
        if let Some(i) = ignore {
            i.validate(&format!("ignoring pixels of camera \"{}\"", camera.name))?;
        }
        let mask = self.resampled(camera.width, camera.height);
        let ignore = ignore.map(|i| i.resampled(camera.width, camera.height));
        Ok((0..mask.value.len())
            .map(|p| {
                let ignored = ignore.as_ref().is_some_and(|i| !i.known[p] || i.value[p] >= 0.5);
                if !mask.known[p] || ignored {
                    -1.0
                } else if options.invert {
                    mask.value[p]
                } else {
                    1.0 - mask.value[p]
                }
            })
            .collect())
    }

    /// Whether every known pixel says the same (all shadow or all lit at 0.5).
    pub fn is_uniform(&self) -> bool {
        let mut classes = self.value.iter().zip(&self.known).filter(|(_, k)| **k).map(|(v, _)| *v >= 0.5);
        match classes.next() {
            None => true,
            Some(first) => classes.all(|c| c == first),
        }
    }
}

/// The name a mask of `camera` has, without extension: the camera's image
/// name without its folder and extension ("frames/0001.jpg" → "0001").
pub fn mask_stem(camera: &Camera) -> String {
    let name = Path::new(&camera.name);
    name.file_stem().map_or_else(|| camera.name.clone(), |s| s.to_string_lossy().into_owned())
}

/// Which file of `dir` is each camera's mask: `Some(path)` per camera, in
/// order (`None`: no mask), and the mask files that match no camera. Two
/// files for one camera (`0001.png` and `0001.jpg`) are an error.
pub fn find_masks(dir: &Path, cameras: &[Camera]) -> Result<(Vec<Option<PathBuf>>, Vec<PathBuf>)> {
    let entries = std::fs::read_dir(dir).map_err(Error::io(dir))?;
    let mut files: Vec<PathBuf> = Vec::new();
    for e in entries {
        let path = e.map_err(Error::io(dir))?.path();
        let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
        if path.is_file() && ext.is_some_and(|e| MASK_EXTENSIONS.contains(&e.as_str())) {
            files.push(path);
        }
    }
    files.sort();
    let stem = |p: &Path| p.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let mut used = vec![false; files.len()];
    let mut found = Vec::with_capacity(cameras.len());
    for camera in cameras {
        let want = mask_stem(camera);
        let hits: Vec<usize> = (0..files.len()).filter(|i| stem(&files[*i]) == want).collect();
        if hits.len() > 1 {
            return Err(Error::invalid(
                format!("masks for camera \"{}\"", camera.name),
                format!("are ambiguous: {} and {}", files[hits[0]].display(), files[hits[1]].display()),
            ));
        }
        for &i in &hits {
            used[i] = true;
        }
        found.push(hits.first().map(|i| files[*i].clone()));
    }
    let unmatched = files.into_iter().zip(used).filter(|(_, u)| !u).map(|(f, _)| f).collect();
    Ok((found, unmatched))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, reason = "tests")]
    use super::*;

    fn camera(name: &str, w: u32, h: u32) -> Camera {
        let mut c = Camera::look_at(glam::Vec3::ZERO, glam::Vec3::X, glam::Vec3::Z, 60.0, w, h).unwrap();
        c.name = name.into();
        c
    }

    #[test]
    fn white_is_shadow_unknown_is_negative_and_sizes_resample() {
        // 4×2: white, black, grey, transparent; then black, white, black, white.
        let m = MaskImage {
            width: 4,
            height: 2,
            value: vec![1.0, 0.0, 0.25, 1.0, 0.0, 1.0, 0.0, 1.0],
            known: vec![true, true, true, false, true, true, true, true],
        };
        let c = camera("a", 4, 2);
        assert_eq!(m.target(&c, None, MaskOptions::default()).unwrap(), [0.0, 1.0, 0.75, -1.0, 1.0, 0.0, 1.0, 0.0]);
        assert_eq!(
            m.target(&c, None, MaskOptions { invert: true }).unwrap(),
            [1.0, 0.0, 0.25, -1.0, 0.0, 1.0, 0.0, 1.0]
        );
        let mut ignore = m.clone();
        ignore.known = vec![true; 8];
        ignore.value = vec![0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0];
        assert_eq!(m.target(&c, Some(&ignore), MaskOptions::default()).unwrap()[4], -1.0);
        // Inconsistent sizes are an error, not a panic.
        let broken = MaskImage { width: 4, height: 2, value: vec![0.0; 3], known: vec![true; 8] };
        assert!(broken.target(&c, None, MaskOptions::default()).is_err());
        let empty = MaskImage { width: 0, height: 0, value: vec![], known: vec![] };
        assert!(m.target(&c, Some(&empty), MaskOptions::default()).is_err());
        // Half the size: each output pixel is the mean of a 2×2 block (centres line up);
        // the block holding the transparent pixel is unknown.
        let half = m.resampled(2, 1);
        assert_eq!(half.value[0], 0.5);
        assert_eq!(half.known, [true, false]);
        assert!(!m.is_uniform());
        let flat = MaskImage { width: 2, height: 1, value: vec![0.9, 0.7], known: vec![true, true] };
        assert!(flat.is_uniform());
    }

    #[test]
    fn masks_read_from_files_other_tools_wrote() {
        let dir = tempfile::tempdir().unwrap();
        // 16-bit grey with alpha (the image crate's PNG encoder): white shadow, a transparent pixel.
        let mut img = image::ImageBuffer::<image::LumaA<u16>, Vec<u16>>::new(3, 1);
        img.put_pixel(0, 0, image::LumaA([65535, 65535]));
        img.put_pixel(1, 0, image::LumaA([0, 65535]));
        img.put_pixel(2, 0, image::LumaA([32768, 0]));
        img.save(dir.path().join("a.png")).unwrap();
        let m = read_mask(&dir.path().join("a.png")).unwrap();
        assert_eq!((m.width, m.height, m.known.as_slice()), (3, 1, [true, true, false].as_slice()));
        assert_eq!(&m.value[..2], &[1.0, 0.0]);
        // A one-channel float EXR (the exr crate), as detectors save probabilities.
        use exr::prelude::*;
        let y = FlatSamples::F32(vec![0.25, 0.75, 2.0, f32::NAN]);
        let layer = Layer::new(
            (2, 2),
            LayerAttributes::named("mask"),
            Encoding::FAST_LOSSLESS,
            AnyChannels::sort(SmallVec::from_vec(vec![AnyChannel::new("Y", y)])),
        );
        Image::from_layer(layer).write().to_file(dir.path().join("b.exr")).unwrap();
        let m = read_mask(&dir.path().join("b.exr")).unwrap();
        assert_eq!((m.width, m.height), (2, 2));
        assert_eq!(m.value, [0.25, 0.75, 1.0, 0.0]);
        assert_eq!(m.known, [true, true, true, false]);
        // Not an image: a clear error naming the file.
        std::fs::write(dir.path().join("c.png"), b"not a png").unwrap();
        let e = read_mask(&dir.path().join("c.png")).unwrap_err().to_string();
        assert!(e.contains("c.png") && e.contains("cannot read the mask"), "{e}");
    }

    #[test]
    fn masks_match_cameras_by_image_stem() {
        let dir = tempfile::tempdir().unwrap();
        for f in ["0001.png", "0002.jpg", "0009.png", "notes.txt"] {
            std::fs::write(dir.path().join(f), b"x").unwrap();
        }
        let cams = [camera("frames/0001.jpg", 4, 2), camera("0002", 4, 2), camera("0003.jpg", 4, 2)];
        let (found, unmatched) = find_masks(dir.path(), &cams).unwrap();
        assert_eq!(found[0].as_deref(), Some(dir.path().join("0001.png").as_path()));
        assert_eq!(found[1].as_deref(), Some(dir.path().join("0002.jpg").as_path()));
        assert_eq!(found[2], None);
        assert_eq!(unmatched, [dir.path().join("0009.png")]);
        std::fs::write(dir.path().join("0001.exr"), b"x").unwrap();
        let e = find_masks(dir.path(), &cams).unwrap_err();
        assert!(e.to_string().contains("ambiguous"), "{e}");
    }
}
