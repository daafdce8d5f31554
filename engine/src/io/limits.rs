//! Resource limits for everything srug reads, in one place.
//!
//! Every loader checks the sizes a file declares (image sides, decoded
//! bytes, tensor widths, Gaussian counts) with checked arithmetic against
//! these limits and against the file's real length **before** it allocates,
//! and reads whole only regular files (a stream such as `/dev/zero` or a FIFO
//! is refused up front). Decompression is bounded by the size the header
//! declares. The limits are process-wide; [`set_limits`] changes them (a
//! simulator with a 32k environment map raises `max_image_side`).

use std::io::Read;
use std::path::Path;
use std::sync::RwLock;

use crate::error::{Error, Result};

/// The budget every loader checks against.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Limits {
    /// Largest file read whole, bytes.
    pub max_file_bytes: u64,
    /// Largest image or texture side, texels (environment maps, KTX2 levels, EXR/HDR).
    pub max_image_side: u32,
    /// Most bytes one decoded image or texture may take on the host.
    pub max_decoded_bytes: u64,
    /// Most Gaussians in one scene (files and the demo generator).
    pub max_gaussians: u64,
    /// Widest U-Net layer, channels.
    pub max_channels: usize,
}

impl Limits {
    /// The defaults: 64 GiB files, 16384-texel sides, 4 GiB per decoded
    /// image, 200 million Gaussians, 4096 channels.
    pub const DEFAULT: Limits = Limits {
        max_file_bytes: 64 << 30,
        max_image_side: 16384,
        max_decoded_bytes: 4 << 30,
        max_gaussians: 200_000_000,
        max_channels: 4096,
    };

    /// Bytes of an image `width` × `height` × `layers` with `texel_bytes`
    /// each, when every side and the total are within the limits; otherwise
    /// the reason, in words.
    pub fn image_bytes(
        &self,
        width: u64,
        height: u64,
        layers: u64,
        texel_bytes: u64,
    ) -> std::result::Result<usize, String> {
        let side = u64::from(self.max_image_side);
        if width == 0 || height == 0 {
            return Err(format!("declares an empty {width}x{height} image"));
        }
        if width > side || height > side {
            return Err(format!("declares {width}x{height} texels, more than the {side}-texel side limit"));
        }
        let bytes = width
            .checked_mul(height)
            .and_then(|v| v.checked_mul(layers))
            .and_then(|v| v.checked_mul(texel_bytes))
            .filter(|b| *b <= self.max_decoded_bytes)
            .ok_or_else(|| {
                format!(
                    "declares {width}x{height}x{layers} texels of {texel_bytes} bytes, more than the {} MiB decode limit",
                    self.max_decoded_bytes >> 20
                )
            })?;
        usize::try_from(bytes).map_err(|_| format!("declares {bytes} bytes, more than this machine can address"))
    }

    /// `count` Gaussians when within the limit; otherwise the reason.
    pub fn gaussians(&self, count: u64) -> std::result::Result<usize, String> {
        if count > self.max_gaussians {
            return Err(format!("{count} Gaussians is more than the limit of {}", self.max_gaussians));
        }
        usize::try_from(count).map_err(|_| format!("{count} Gaussians cannot be addressed on this machine"))
    }
}

impl Default for Limits {
    fn default() -> Self {
        Self::DEFAULT
    }
}

static LIMITS: RwLock<Limits> = RwLock::new(Limits::DEFAULT);

/// The limits in force.
pub fn limits() -> Limits {
    LIMITS.read().map_or(Limits::DEFAULT, |l| *l)
}

/// Replaces the limits for every later load in this process.
pub fn set_limits(limits: Limits) {
    if let Ok(mut l) = LIMITS.write() {
        *l = limits;
    }
}

/// Reads a whole regular file of at most [`Limits::max_file_bytes`]:
/// devices, FIFOs and other streams are refused before a byte is read, and a
/// file that grows while it is read stops at the limit.
pub fn read_file(path: impl AsRef<Path>) -> Result<Vec<u8>> {
    let path = path.as_ref();
    let file = std::fs::File::open(path).map_err(Error::io(path))?;
    let meta = file.metadata().map_err(Error::io(path))?;
    if !meta.is_file() {
        return Err(Error::invalid(
            path.display().to_string(),
            "is not a regular file (devices, pipes and other streams cannot be read whole)",
        ));
    }
    let max = limits().max_file_bytes;
    if meta.len() > max {
        return Err(Error::invalid(
            path.display().to_string(),
            format!("is {} bytes, more than the {max}-byte file limit", meta.len()),
        ));
    }
    let mut bytes = Vec::with_capacity(usize::try_from(meta.len()).unwrap_or(0));
    file.take(max + 1).read_to_end(&mut bytes).map_err(Error::io(path))?;
    if bytes.len() as u64 > max {
        return Err(Error::invalid(path.display().to_string(), format!("grew past the {max}-byte file limit")));
    }
    Ok(bytes)
}

/// [`read_file`] as UTF-8 text.
pub fn read_text(path: impl AsRef<Path>) -> Result<String> {
    let path = path.as_ref();
    String::from_utf8(read_file(path)?)
        .map_err(|e| Error::invalid(path.display().to_string(), format!("is not UTF-8 text: {e}")))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, reason = "a failed unwrap is a failed test")]
    use super::*;

    #[test]
    fn image_sizes_are_checked_without_overflow() {
        let l = Limits::DEFAULT;
        assert_eq!(l.image_bytes(4, 2, 1, 12), Ok(96));
        // 2^30 × 2^30 × 6 faces × 8 bytes wraps u64; refused by the side limit first.
        assert!(l.image_bytes(1 << 30, 1 << 30, 6, 8).is_err());
        let wide = Limits { max_image_side: u32::MAX, ..l };
        let e = wide.image_bytes(1 << 31, 1 << 31, 6, 16).unwrap_err();
        assert!(e.contains("decode limit"), "{e}");
        assert!(l.image_bytes(0, 5, 1, 4).is_err());
        assert!(l.image_bytes(16384, 16384, 6, 16).is_err(), "6 GiB is over the 4 GiB decode limit");
    }

    #[test]
    fn gaussian_counts_are_bounded() {
        assert_eq!(Limits::DEFAULT.gaussians(10), Ok(10));
        assert!(Limits::DEFAULT.gaussians(1 << 40).unwrap_err().contains("limit"));
        assert!(Limits::DEFAULT.gaussians(u64::MAX).is_err());
    }

    #[cfg(unix)]
    #[test]
    fn streams_and_devices_are_refused() {
        let e = read_file("/dev/zero").unwrap_err().to_string();
        assert!(e.contains("/dev/zero") && e.contains("not a regular file"), "{e}");
        let e = read_file("/definitely/missing").unwrap_err().to_string();
        assert!(e.contains("/definitely/missing"), "{e}");
    }
}
