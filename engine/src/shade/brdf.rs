//! The environment BRDF table of the split-sum approximation: (A, B) per
//! N·V and roughness, made by [`super::EnvironmentPrep::brdf_table`] and
//! saved or loaded as a two-channel float KTX2 file.

use std::path::Path;

use bytemuck::{Pod, Zeroable};

use super::env::{metadata_value, read_chain};
use crate::error::{Error, Result};
use crate::gpu::{Buffer, Device, DeviceAddress, Timings};
use crate::io::environment::env_error;

/// Which environment BRDF table.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum BrdfLut {
    /// Schlick–Smith G with k = α/2 (Karis 2013, UE4).
    #[default]
    Karis,
    /// Height-correlated Smith GGX (nvdiffrec and the relighting codes built on it).
    HeightCorrelated,
}

impl BrdfLut {
    /// Parses `karis` or `height-correlated`.
    pub fn parse(text: &str) -> Result<Self> {
        match text {
            "karis" => Ok(Self::Karis),
            "height-correlated" => Ok(Self::HeightCorrelated),
            other => Err(Error::invalid(format!("BRDF table \"{other}\""), "is not karis or height-correlated")),
        }
    }

    /// The `VARIANT` specialization constant of `brdf_lut.comp`.
    pub fn code(self) -> u32 {
        match self {
            Self::Karis => 0,
            Self::HeightCorrelated => 1,
        }
    }
}

/// The environment BRDF table on the GPU: (A, B) for N·V = i/(size−1)
/// (columns, clamped ≥ 1e-4) and roughness j/(size−1) (rows).
pub struct BrdfTable {
    /// Which G term.
    pub variant: BrdfLut,
    /// Texels per side.
    pub size: u32,
    /// Hammersley samples per texel.
    pub samples: u32,
    /// `vec2` per texel.
    pub buffer: Buffer,
    /// GPU time of the computation.
    pub timings: Timings,
}

/// Push constants of `brdf_lut.comp` (keep in sync).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub(crate) struct LutPush {
    pub(super) dst: DeviceAddress,
    pub(super) size: u32,
    pub(super) samples: u32,
}
crate::gpu::gpu_layout!(LutPush, "LutPush", [dst, size, samples]);

impl BrdfTable {
    /// Saves the table as a two-channel float KTX2 file.
    pub fn save(&self, device: &Device, path: &Path) -> Result<()> {
        use crate::io::ktx::{write_float_chain, FloatChain};
        let values: Vec<f32> = device.read_buffer(&self.buffer)?;
        let chain = FloatChain {
            width: self.size,
            height: self.size,
            channels: 2,
            levels: vec![&values],
            metadata: vec![
                ("srug.kind".into(), "brdf".into()),
                ("srug.brdf".into(), format!("{:?}", self.variant)),
                ("srug.samples".into(), self.samples.to_string()),
            ],
        };
        write_float_chain(path, &chain, false)
    }

    /// Loads a table written by [`BrdfTable::save`].
    pub fn load(device: &Device, path: &Path) -> Result<Self> {
        let chain = read_chain(path, "brdf", 2)?;
        let origin = path.display().to_string();
        let variant = match metadata_value(&chain, "srug.brdf") {
            Some("Karis") => BrdfLut::Karis,
            Some("HeightCorrelated") => BrdfLut::HeightCorrelated,
            other => return Err(env_error(&origin, format!("unknown BRDF table variant {other:?}"))),
        };
        if chain.width != chain.height || chain.width < 2 {
            return Err(env_error(&origin, format!("a BRDF table is square, ≥ 2: {}x{}", chain.width, chain.height)));
        }
        let samples = metadata_value(&chain, "srug.samples").and_then(|s| s.parse().ok()).unwrap_or(0);
        Ok(Self {
            variant,
            size: chain.width,
            samples,
            buffer: device.upload("brdf table", &chain.levels[0])?,
            timings: Timings::default(),
        })
    }
}

#[cfg(test)]
mod layout_tests {
    use super::LutPush;
    use crate::gpu::{check_layout, kernels};

    /// The push-constant struct matches the GLSL block of its kernel.
    #[test]
    fn push_layout_matches_glsl() {
        assert_eq!(check_layout::<LutPush>(&[&kernels::BRDF_LUT]), Ok(1));
    }
}
