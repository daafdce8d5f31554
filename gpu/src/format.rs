//! Texel formats and their Vulkan conversions (a leaf).

use ash::vk;

/// Element formats of texel-buffer views: what `texelFetch` on a
/// `textureBuffer` converts to float, or a `utextureBuffer` returns as uints.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum TexelFormat {
    /// 32-bit float.
    R32Float,
    /// 16-bit float (widened to fp32 by the fetch; no 16-bit storage feature needed).
    R16Float,
    /// 32-bit unsigned integer (`utextureBuffer`).
    R32Uint,
    /// Two 32-bit unsigned integers (`utextureBuffer`, `.xy`), e.g. a 64-bit key as (low, high).
    Rg32Uint,
    /// Four 32-bit floats (`textureBuffer`, a `vec4` per element).
    Rgba32Float,
    /// Four 16-bit floats (`textureBuffer`, widened to a `vec4` per element).
    Rgba16Float,
    /// Three 32-bit floats (`textureBuffer`, `.xyz`), e.g. a position; optional in Vulkan.
    Rgb32Float,
    /// Four 32-bit unsigned integers (`utextureBuffer`, a `uvec4` per element): any 16-byte record's bits.
    Rgba32Uint,
}

impl TexelFormat {
    /// Every format, in the order [`DeviceInfo::texel_formats`](crate::DeviceInfo::texel_formats) lists them.
    pub const ALL: [Self; 8] = [
        Self::R32Float,
        Self::R16Float,
        Self::R32Uint,
        Self::Rg32Uint,
        Self::Rgba32Float,
        Self::Rgba16Float,
        Self::Rgb32Float,
        Self::Rgba32Uint,
    ];

    /// The Vulkan format.
    pub fn vk(self) -> vk::Format {
        match self {
            Self::R32Float => vk::Format::R32_SFLOAT,
            Self::R16Float => vk::Format::R16_SFLOAT,
            Self::R32Uint => vk::Format::R32_UINT,
            Self::Rg32Uint => vk::Format::R32G32_UINT,
            Self::Rgba32Float => vk::Format::R32G32B32A32_SFLOAT,
            Self::Rgba16Float => vk::Format::R16G16B16A16_SFLOAT,
            Self::Rgb32Float => vk::Format::R32G32B32_SFLOAT,
            Self::Rgba32Uint => vk::Format::R32G32B32A32_UINT,
        }
    }

    /// Bytes per element.
    pub fn bytes(self) -> u64 {
        match self {
            Self::R32Float | Self::R32Uint => 4,
            Self::R16Float => 2,
            Self::Rg32Uint | Self::Rgba16Float => 8,
            Self::Rgb32Float => 12,
            Self::Rgba32Float | Self::Rgba32Uint => 16,
        }
    }
}
