//! The G-buffer channels a frame keeps: which are asked for, their names and
//! the blend kernel's channel bits.

use super::*;
use crate::error::{Error, Result};

/// Which G-buffer channels to blend besides rgb and alpha (alpha always
/// produced, rgb unless [`SplatSettings::rgb`] is off).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Channels {
    /// Expected depth Σ wᵢ zᵢ.
    pub depth: bool,
    /// Depth where transmittance first falls to 0.5.
    pub median_depth: bool,
    /// World-space normal Σ wᵢ nᵢ.
    pub normal: bool,
    /// Albedo.
    pub albedo: bool,
    /// Roughness.
    pub roughness: bool,
    /// Metallic.
    pub metallic: bool,
    /// Ambient occlusion.
    pub ao: bool,
    /// Fixed sun visibility.
    pub visibility: bool,
}

impl Channels {
    /// Every channel.
    pub const ALL: Channels = Channels {
        depth: true,
        median_depth: true,
        normal: true,
        albedo: true,
        roughness: true,
        metallic: true,
        ao: true,
        visibility: true,
    };

    /// The `CHANNELS` specialization constant of `splat_blend.comp`, less
    /// its rgb bit ([`RGB_BIT`], from [`SplatSettings::rgb`]).
    pub fn bits(&self) -> u32 {
        [
            self.depth,
            self.median_depth,
            self.normal,
            self.albedo,
            self.roughness,
            self.metallic,
            self.ao,
            self.visibility,
        ]
        .iter()
        .enumerate()
        .map(|(i, on)| u32::from(*on) << i)
        .sum()
    }

    /// The inverse of [`Channels::bits`] (bits above 7 are ignored).
    pub fn from_bits(bits: u32) -> Self {
        let on = |i: u32| bits & (1 << i) != 0;
        Channels {
            depth: on(0),
            median_depth: on(1),
            normal: on(2),
            albedo: on(3),
            roughness: on(4),
            metallic: on(5),
            ao: on(6),
            visibility: on(7),
        }
    }

    /// The whole `CHANNELS` specialization constant: [`Channels::bits`] plus
    /// the rgb bit when colour is blended.
    pub fn blend_bits(&self, rgb: bool) -> u32 {
        self.bits() | u32::from(rgb) << RGB_BIT
    }

    /// Whether per-splat features (normal or materials) are needed.
    pub fn needs_features(&self) -> bool {
        self.bits() & 0b1111_1100 != 0
    }

    /// Parses a comma-separated list (`rgb` and `alpha` are accepted: alpha is
    /// always on, rgb is [`SplatSettings::rgb`], see [`Channels::names_rgb`];
    /// `materials` means albedo, roughness, metallic, ao and visibility; `all` everything).
    pub fn parse(list: &str) -> Result<Self> {
        let mut c = Channels::default();
        for item in list.split(',').map(str::trim).filter(|s| !s.is_empty()) {
            match item {
                "rgb" | "alpha" => {}
                "depth" => c.depth = true,
                "median_depth" | "median" => c.median_depth = true,
                "normal" => c.normal = true,
                "albedo" => c.albedo = true,
                "roughness" => c.roughness = true,
                "metallic" => c.metallic = true,
                "ao" => c.ao = true,
                "visibility" => c.visibility = true,
                "materials" => {
                    c = Channels { albedo: true, roughness: true, metallic: true, ao: true, visibility: true, ..c }
                }
                "all" => c = Channels::ALL,
                other => {
                    return Err(Error::invalid(
                        format!("channel \"{other}\""),
                        "is unknown (rgb, alpha, depth, median_depth, normal, albedo, roughness, metallic, ao, \
                         visibility, materials, all)",
                    ))
                }
            }
        }
        Ok(c)
    }

    /// Whether a list [`Channels::parse`] accepts names rgb (`rgb` or `all`):
    /// for callers that blend colour only when asked (`srug render` to EXR).
    pub fn names_rgb(list: &str) -> bool {
        list.split(',').map(str::trim).any(|s| s == "rgb" || s == "all")
    }
}
