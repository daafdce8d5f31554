//! The G-buffer channels a frame keeps: which are asked for, their names and
//! the blend kernel's channel bits.

use super::*;
use crate::error::{Error, Result};

/// One optional G-buffer channel: the list, its order (the blend kernel's
/// `CHANNELS` bit is the position), names and sizes are written here once.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Channel {
    /// Expected depth Σ wᵢ zᵢ.
    Depth,
    /// Depth where transmittance first falls to 0.5 (1 − [`crate::splat::SplatSettings::median_coverage`]).
    MedianDepth,
    /// World-space normal.
    Normal,
    /// Albedo.
    Albedo,
    /// Roughness.
    Roughness,
    /// Metallic.
    Metallic,
    /// Ambient occlusion.
    Ao,
    /// Fixed sun visibility.
    Visibility,
}

impl Channel {
    /// Every optional channel, in bit order.
    pub const ALL: [Channel; 8] = [
        Self::Depth,
        Self::MedianDepth,
        Self::Normal,
        Self::Albedo,
        Self::Roughness,
        Self::Metallic,
        Self::Ao,
        Self::Visibility,
    ];

    /// The name on the command line, in EXR layers and in the plan.
    pub fn name(self) -> &'static str {
        match self {
            Self::Depth => "depth",
            Self::MedianDepth => "median_depth",
            Self::Normal => "normal",
            Self::Albedo => "albedo",
            Self::Roughness => "roughness",
            Self::Metallic => "metallic",
            Self::Ao => "ao",
            Self::Visibility => "visibility",
        }
    }

    /// Floats per pixel.
    pub fn floats(self) -> usize {
        match self {
            Self::Normal | Self::Albedo => 3,
            _ => 1,
        }
    }

    /// Its bit in [`Channels::bits`].
    pub fn bit(self) -> u32 {
        1 << (self as u32)
    }

    /// A per-splat feature (read from the splat's feature record, not its depth).
    pub fn is_feature(self) -> bool {
        !matches!(self, Self::Depth | Self::MedianDepth)
    }
}

/// One optional value per [`Channel`]: a G-buffer's channels on the host or
/// the GPU, or their gradients. Indexed by the channel, so code that walks the
/// channels never lists them again.
#[derive(Clone, Debug, PartialEq)]
pub struct PerChannel<T>([Option<T>; Channel::ALL.len()]);

impl<T> Default for PerChannel<T> {
    fn default() -> Self {
        Self(std::array::from_fn(|_| None))
    }
}

impl<T> PerChannel<T> {
    /// The value of `channel`, when present.
    pub fn get(&self, channel: Channel) -> Option<&T> {
        self.0[channel as usize].as_ref()
    }

    /// The value of `channel` to change, when present.
    pub fn get_mut(&mut self, channel: Channel) -> Option<&mut T> {
        self.0[channel as usize].as_mut()
    }

    /// Sets `channel` to `value`.
    pub fn set(&mut self, channel: Channel, value: T) {
        self.0[channel as usize] = Some(value);
    }

    /// Removes `channel`, returning its value.
    pub fn remove(&mut self, channel: Channel) -> Option<T> {
        self.0[channel as usize].take()
    }

    /// `self` with `channel` set to `value`.
    pub fn with(mut self, channel: Channel, value: T) -> Self {
        self.set(channel, value);
        self
    }

    /// The present channels and their values, in bit order.
    pub fn iter(&self) -> impl Iterator<Item = (Channel, &T)> {
        Channel::ALL.into_iter().zip(&self.0).filter_map(|(c, v)| v.as_ref().map(|v| (c, v)))
    }

    /// Which channels are present.
    pub fn present(&self) -> Channels {
        let mut c = Channels::default();
        self.iter().for_each(|(channel, _)| c.set(channel));
        c
    }

    /// A value for every channel `f` returns one for (the first error stops it).
    pub fn try_from_fn<E>(
        mut f: impl FnMut(Channel) -> std::result::Result<Option<T>, E>,
    ) -> std::result::Result<Self, E> {
        let mut out = Self::default();
        for c in Channel::ALL {
            out.0[c as usize] = f(c)?;
        }
        Ok(out)
    }
}

impl<T> FromIterator<(Channel, T)> for PerChannel<T> {
    fn from_iter<I: IntoIterator<Item = (Channel, T)>>(iter: I) -> Self {
        iter.into_iter().fold(Self::default(), |acc, (c, v)| acc.with(c, v))
    }
}

/// Which G-buffer channels to blend besides rgb and alpha (alpha always
/// produced, rgb unless [`SplatSettings::rgb`] is off).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Channels {
    /// Expected depth Σ wᵢ zᵢ.
    pub depth: bool,
    /// Depth where transmittance first falls to 0.5 (1 − [`crate::splat::SplatSettings::median_coverage`]).
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
    /// The index of the Gaussian with the largest blend weight wᵢ = αᵢ Tᵢ at
    /// each pixel (`u32::MAX` where none contributes): not blended, exact, for
    /// ground-truth ids ([`GBuffer::top_gaussian`]).
    pub top_gaussian: bool,
}

impl Channels {
    /// Every blended channel (not [`Channels::top_gaussian`]).
    pub const ALL: Channels = Channels {
        depth: true,
        median_depth: true,
        normal: true,
        albedo: true,
        roughness: true,
        metallic: true,
        ao: true,
        visibility: true,
        top_gaussian: false,
    };

    /// Whether `channel` is kept.
    pub fn has(&self, channel: Channel) -> bool {
        match channel {
            Channel::Depth => self.depth,
            Channel::MedianDepth => self.median_depth,
            Channel::Normal => self.normal,
            Channel::Albedo => self.albedo,
            Channel::Roughness => self.roughness,
            Channel::Metallic => self.metallic,
            Channel::Ao => self.ao,
            Channel::Visibility => self.visibility,
        }
    }

    /// Keeps `channel`.
    pub fn set(&mut self, channel: Channel) {
        let flag = match channel {
            Channel::Depth => &mut self.depth,
            Channel::MedianDepth => &mut self.median_depth,
            Channel::Normal => &mut self.normal,
            Channel::Albedo => &mut self.albedo,
            Channel::Roughness => &mut self.roughness,
            Channel::Metallic => &mut self.metallic,
            Channel::Ao => &mut self.ao,
            Channel::Visibility => &mut self.visibility,
        };
        *flag = true;
    }

    /// The kept channels, in bit order.
    pub fn iter(self) -> impl Iterator<Item = Channel> {
        Channel::ALL.into_iter().filter(move |c| self.has(*c))
    }

    /// The `CHANNELS` specialization constant of `splat_blend.comp`, less
    /// its rgb bit (`RGB_BIT`, from [`SplatSettings::rgb`]).
    pub fn bits(&self) -> u32 {
        self.iter().map(Channel::bit).sum()
    }

    /// The inverse of [`Channels::bits`] (bits above 7 are ignored; the top-Gaussian flag is off).
    pub fn from_bits(bits: u32) -> Self {
        let mut c = Channels::default();
        for channel in Channel::ALL.into_iter().filter(|ch| bits & ch.bit() != 0) {
            c.set(channel);
        }
        c
    }

    /// The whole `CHANNELS` specialization constant: [`Channels::bits`] plus
    /// the rgb bit when colour is blended.
    pub fn blend_bits(&self, rgb: bool) -> u32 {
        self.bits() | u32::from(rgb) << RGB_BIT | u32::from(self.top_gaussian) << TOP_GAUSSIAN_BIT
    }

    /// Whether per-splat features (normal or materials) are needed.
    pub fn needs_features(&self) -> bool {
        self.iter().any(Channel::is_feature)
    }

    /// Parses a comma-separated list (`rgb` and `alpha` are accepted: alpha is
    /// always on, rgb is [`SplatSettings::rgb`], see [`Channels::names_rgb`];
    /// `materials` means albedo, roughness, metallic, ao and visibility; `all` everything).
    pub fn parse(list: &str) -> Result<Self> {
        let mut c = Channels::default();
        for item in list.split(',').map(str::trim).filter(|s| !s.is_empty()) {
            if let Some(channel) = Channel::ALL.into_iter().find(|ch| ch.name() == item) {
                c.set(channel);
                continue;
            }
            match item {
                "rgb" | "alpha" => {}
                "median" => c.median_depth = true,
                "top_gaussian" => c.top_gaussian = true,
                "materials" => {
                    c = Channels { albedo: true, roughness: true, metallic: true, ao: true, visibility: true, ..c }
                }
                "all" => c = Channels::ALL,
                other => {
                    return Err(Error::invalid(
                        format!("channel \"{other}\""),
                        "is unknown (rgb, alpha, depth, median_depth, normal, albedo, roughness, metallic, ao, \
                         visibility, materials, all, top_gaussian)",
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

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, reason = "a failed unwrap is a failed test")]
    use super::{Channel, Channels};

    /// Bits, names and parsing agree for every channel and every set of them.
    #[test]
    fn channel_list_round_trips() {
        for mask in 0..256u32 {
            assert_eq!(Channels::from_bits(mask).bits(), mask);
        }
        for (i, c) in Channel::ALL.into_iter().enumerate() {
            assert_eq!(c.bit(), 1 << i);
            let parsed = Channels::parse(c.name()).unwrap();
            assert_eq!(parsed.iter().collect::<Vec<_>>(), [c], "{}", c.name());
        }
        assert_eq!(Channels::ALL.iter().count(), 8);
        assert_eq!(Channels::ALL.iter().map(|c| c.floats()).sum::<usize>(), 2 * 3 + 6);
        let names: Vec<&str> = Channel::ALL.into_iter().map(Channel::name).collect();
        assert_eq!(Channels::parse(&names.join(",")).unwrap(), Channels::ALL);
        let top = Channels::parse("depth,top_gaussian").unwrap();
        assert!(top.top_gaussian && top.depth && top.iter().count() == 1);
        assert_eq!(top.blend_bits(false), 1 | 1 << super::TOP_GAUSSIAN_BIT);
    }
}
