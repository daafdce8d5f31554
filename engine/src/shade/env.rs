//! Environment maps prepared once on the GPU for split-sum lighting
//! ([`EnvironmentPrep`] → [`PreparedEnvironment`]: a prefiltered specular
//! chain and an irradiance map, saved and loaded as KTX2), and the BRDF
//! table's computation ([`EnvironmentPrep::brdf_table`]; the table is
//! [`super::brdf::BrdfTable`]). The host map and its readers are
//! [`crate::io::environment`].

use std::path::Path;
use std::sync::Arc;

use bytemuck::{Pod, Zeroable};

use super::brdf::{BrdfLut, BrdfTable, LutPush};
use crate::error::{Error, Result};
use crate::gpu::{kernels, Buffer, Device, DeviceAddress, Grid, Kernel, KernelDecl, MemoryKind, SpecValue, Timings};
use crate::io::environment::env_error;
pub use crate::io::environment::{EnvironmentMap, MAX_SIDE};
use crate::io::ktx;

/// Sizes and sample counts of the environment preparation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PrepareSettings {
    /// Prefiltered levels (roughness l/(levels−1) at level l), at most the
    /// pyramid's depth.
    pub levels: u32,
    /// GGX samples per prefiltered texel.
    pub samples: u32,
    /// Irradiance map size (lat-long).
    pub irradiance_size: (u32, u32),
    /// Widest pyramid level the irradiance sums over.
    pub irradiance_source_width: u32,
}

impl Default for PrepareSettings {
    fn default() -> Self {
        Self { levels: 6, samples: 128, irradiance_size: (32, 16), irradiance_source_width: 64 }
    }
}

/// An environment prepared for split-sum shading, on the GPU.
pub struct PreparedEnvironment {
    /// Level-0 size of the specular chain (the source map's).
    pub base: (u32, u32),
    /// Prefiltered levels; level l has size base >> l and roughness l/(levels−1).
    pub levels: u32,
    /// The specular chain, RGB floats, levels one after another.
    pub specular: Buffer,
    /// Irradiance map size.
    pub irradiance_size: (u32, u32),
    /// Irradiance E(n), RGB floats, lat-long.
    pub irradiance: Buffer,
    /// GPU time of the preparation (zero when loaded from a file).
    pub timings: Timings,
}

/// Size of level `l` of a chain with level-0 size `base` (keep in sync with `level_size` in `latlong.glsl`).
pub fn level_size(base: (u32, u32), l: u32) -> (u32, u32) {
    ((base.0 >> l).max(1), (base.1 >> l).max(1))
}

/// Texel offset of level `l`.
pub(crate) fn level_offset(base: (u32, u32), l: u32) -> u64 {
    (0..l).map(|i| level_size(base, i)).map(|(w, h)| u64::from(w) * u64::from(h)).sum()
}

/// Pyramid depth: every level until the shorter side reaches 1 texel.
pub fn pyramid_levels(base: (u32, u32)) -> u32 {
    32 - base.0.min(base.1).max(1).leading_zeros()
}

impl PreparedEnvironment {
    /// Reads the specular chain back, one `Vec` per level.
    pub fn read_specular(&self, device: &Device) -> Result<Vec<Vec<f32>>> {
        let all: Vec<f32> = device.read_buffer(&self.specular)?;
        Ok((0..self.levels)
            .map(|l| {
                let (w, h) = level_size(self.base, l);
                let o = 3 * level_offset(self.base, l) as usize;
                all[o..o + 3 * (w * h) as usize].to_vec()
            })
            .collect())
    }

    /// GPU bytes held.
    pub fn bytes(&self) -> u64 {
        self.specular.size() + self.irradiance.size()
    }
}

/// Push constants of `env_downsample.comp` (keep in sync).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub(crate) struct DownsamplePush {
    src: DeviceAddress,
    dst: DeviceAddress,
    src_size: [u32; 2],
    dst_size: [u32; 2],
}
crate::gpu::gpu_layout!(DownsamplePush, "DownsamplePush", [src, dst, src_size, dst_size]);

/// Push constants of `env_prefilter.comp` (keep in sync).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub(crate) struct PrefilterPush {
    pyramid: DeviceAddress,
    dst: DeviceAddress,
    base: [u32; 2],
    dst_size: [u32; 2],
    levels: u32,
    roughness: f32,
    samples: u32,
    pad: u32,
}
crate::gpu::gpu_layout!(
    PrefilterPush,
    "PrefilterPush",
    [pyramid, dst, base, dst_size, levels, roughness, samples, pad]
);

/// Push constants of `env_irradiance.comp` (keep in sync; same layout as downsampling).
pub(crate) type IrradiancePush = DownsamplePush;

/// The environment-preparation kernels.
pub struct EnvironmentPrep {
    device: Device,
    downsample: Arc<Kernel>,
    prefilter: Arc<Kernel>,
    irradiance: Arc<Kernel>,
    lut: [Arc<Kernel>; 2],
}

impl EnvironmentPrep {
    /// Builds the kernels.
    pub fn new(device: &Device) -> Result<Self> {
        let lut = |v: BrdfLut| {
            device.kernel(&kernels::BRDF_LUT, &KernelDecl::push::<LutPush>(&[(0, SpecValue::U32(v.code()))]))
        };
        Ok(Self {
            device: device.clone(),
            downsample: device.kernel(&kernels::ENV_DOWNSAMPLE, &KernelDecl::push::<DownsamplePush>(&[]))?,
            prefilter: device.kernel(&kernels::ENV_PREFILTER, &KernelDecl::push::<PrefilterPush>(&[]))?,
            irradiance: device.kernel(&kernels::ENV_IRRADIANCE, &KernelDecl::push::<IrradiancePush>(&[]))?,
            lut: [lut(BrdfLut::Karis)?, lut(BrdfLut::HeightCorrelated)?],
        })
    }

    /// Computes the BRDF table (`size` ≥ 2 texels per side, `samples` ≥ 1).
    pub fn brdf_table(&self, variant: BrdfLut, size: u32, samples: u32) -> Result<BrdfTable> {
        if !(2..=4096).contains(&size) || samples == 0 {
            return Err(Error::invalid(
                format!("BRDF table of size {size} with {samples} samples"),
                "needs a size in 2..=4096 and at least 1 sample",
            ));
        }
        let device = &self.device;
        let buffer = device.create_buffer("brdf table", u64::from(size * size) * 8, MemoryKind::Storage)?;
        let kernel = &self.lut[variant.code() as usize];
        let timings = device.run(|rec| -> Result<()> {
            let push = LutPush { dst: rec.addr(&buffer)?, size, samples };
            rec.begin_stage("brdf table");
            rec.dispatch(kernel, Grid::Items(u64::from(size * size)), &[], &push)?;
            rec.end_stage();
            Ok(())
        })?;
        Ok(BrdfTable { variant, size, samples, buffer, timings })
    }

    /// Prepares `env`: its box pyramid, the GGX-prefiltered chain and the
    /// irradiance map, all on the GPU.
    pub fn prepare(&self, env: &EnvironmentMap, settings: &PrepareSettings) -> Result<PreparedEnvironment> {
        let (iw, ih) = settings.irradiance_size;
        if settings.levels == 0 || settings.samples == 0 {
            return Err(Error::invalid(
                format!("environment preparation with {} levels of {} samples", settings.levels, settings.samples),
                "needs at least one level and one sample",
            ));
        }
        if !(1..=1024).contains(&iw) || !(1..=1024).contains(&ih) {
            return Err(Error::invalid(format!("irradiance map size {iw}x{ih}"), "must be 1..=1024 on each side"));
        }
        let device = &self.device;
        let base = (env.width, env.height);
        let pyramid_n = pyramid_levels(base);
        let levels = settings.levels.min(pyramid_n);
        let pyramid_texels = level_offset(base, pyramid_n);
        let pyramid = device.create_buffer("environment pyramid", pyramid_texels * 12, MemoryKind::Storage)?;
        device.write_buffer(&pyramid, 0, &env.rgb)?;
        let specular =
            device.create_buffer("prefiltered environment", level_offset(base, levels) * 12, MemoryKind::Storage)?;
        let irradiance = device.create_buffer("irradiance", u64::from(iw * ih) * 12, MemoryKind::Storage)?;
        let irr_level = Self::irradiance_level(base, settings);
        let timings = device.run(|rec| -> Result<()> {
            rec.begin_stage("environment pyramid");
            for l in 1..pyramid_n {
                let (s, d) = (level_size(base, l - 1), level_size(base, l));
                let push = DownsamplePush {
                    src: rec.addr_at(&pyramid, 12 * level_offset(base, l - 1))?,
                    dst: rec.addr_at(&pyramid, 12 * level_offset(base, l))?,
                    src_size: [s.0, s.1],
                    dst_size: [d.0, d.1],
                };
                rec.dispatch(&self.downsample, Grid::Items(u64::from(d.0 * d.1)), &[], &push)?;
            }
            rec.end_stage();
            rec.begin_stage("specular prefilter");
            rec.copy(&pyramid, 0, &specular, 0, u64::from(base.0 * base.1) * 12)?;
            for l in 1..levels {
                let d = level_size(base, l);
                let push = PrefilterPush {
                    pyramid: rec.addr(&pyramid)?,
                    dst: rec.addr_at(&specular, 12 * level_offset(base, l))?,
                    base: [base.0, base.1],
                    dst_size: [d.0, d.1],
                    levels: pyramid_n,
                    roughness: l as f32 / (levels - 1) as f32,
                    samples: settings.samples,
                    pad: 0,
                };
                rec.dispatch(&self.prefilter, Grid::Items(u64::from(d.0 * d.1)), &[], &push)?;
            }
            rec.end_stage();
            rec.begin_stage("irradiance");
            let s = level_size(base, irr_level);
            let push = IrradiancePush {
                src: rec.addr_at(&pyramid, 12 * level_offset(base, irr_level))?,
                dst: rec.addr(&irradiance)?,
                src_size: [s.0, s.1],
                dst_size: [iw, ih],
            };
            rec.dispatch(&self.irradiance, Grid::Items(u64::from(iw * ih)), &[], &push)?;
            rec.end_stage();
            Ok(())
        })?;
        Ok(PreparedEnvironment { base, levels, specular, irradiance_size: (iw, ih), irradiance, timings })
    }

    /// The pyramid level the irradiance is summed over, for the CPU twin.
    pub fn irradiance_level(base: (u32, u32), settings: &PrepareSettings) -> u32 {
        let n = pyramid_levels(base);
        (0..n).find(|&l| level_size(base, l).0 <= settings.irradiance_source_width.max(1)).unwrap_or(n - 1)
    }
}

/// File names of a prepared environment folder.
pub const SPECULAR_FILE: &str = "specular.ktx2";
/// Irradiance file in a prepared environment folder.
pub const IRRADIANCE_FILE: &str = "irradiance.ktx2";

pub(super) fn metadata_value<'a>(chain: &'a ktx::ReadChain, key: &str) -> Option<&'a str> {
    chain.metadata.iter().find(|(k, _)| k == key).map(|(_, v)| v.as_str())
}

pub(super) fn read_chain(path: &Path, kind: &str, channels: usize) -> Result<ktx::ReadChain> {
    let origin = path.display().to_string();
    let bytes = crate::io::read_file(path)?;
    let chain = ktx::read_float_chain(&bytes, &origin)?;
    if metadata_value(&chain, "srug.kind") != Some(kind) || chain.channels != channels {
        return Err(env_error(&origin, format!("not a srug {kind} file (its srug.kind metadata or channels differ)")));
    }
    Ok(chain)
}

impl PreparedEnvironment {
    /// Saves the prefiltered chain and the irradiance map as KTX2 files
    /// ([`SPECULAR_FILE`], [`IRRADIANCE_FILE`]) in `dir`, so a map is prefiltered once.
    pub fn save(&self, device: &Device, dir: &Path, zstd: bool) -> Result<()> {
        use ktx::{write_float_chain, FloatChain};
        std::fs::create_dir_all(dir).map_err(Error::io(dir))?;
        let levels = self.read_specular(device)?;
        let chain = FloatChain {
            width: self.base.0,
            height: self.base.1,
            channels: 3,
            levels: levels.iter().map(Vec::as_slice).collect(),
            metadata: vec![
                ("srug.kind".into(), "specular".into()),
                ("srug.layout".into(), "lat-long, z up, u = 0.5 + azimuth/360 from north toward east".into()),
                ("srug.roughness".into(), format!("level / {}", self.levels.saturating_sub(1))),
            ],
        };
        write_float_chain(dir.join(SPECULAR_FILE), &chain, zstd)?;
        let irr: Vec<f32> = device.read_buffer(&self.irradiance)?;
        let chain = FloatChain {
            width: self.irradiance_size.0,
            height: self.irradiance_size.1,
            channels: 3,
            levels: vec![&irr],
            metadata: vec![("srug.kind".into(), "irradiance".into())],
        };
        write_float_chain(dir.join(IRRADIANCE_FILE), &chain, zstd)
    }

    /// Loads a folder written by [`PreparedEnvironment::save`].
    pub fn load(device: &Device, dir: &Path) -> Result<Self> {
        let spec = read_chain(&dir.join(SPECULAR_FILE), "specular", 3)?;
        let irr = read_chain(&dir.join(IRRADIANCE_FILE), "irradiance", 3)?;
        let base = (spec.width, spec.height);
        if spec.levels.len() as u32 > pyramid_levels(base) {
            return Err(env_error(
                &dir.display().to_string(),
                format!("{} specular levels, more than a {}x{} pyramid has", spec.levels.len(), base.0, base.1),
            ));
        }
        let flat: Vec<f32> = spec.levels.concat();
        if flat.iter().chain(&irr.levels[0]).any(|v| *v < 0.0) {
            return Err(env_error(&dir.display().to_string(), "negative radiance in a prepared environment"));
        }
        Ok(Self {
            base: (spec.width, spec.height),
            levels: spec.levels.len() as u32,
            specular: device.upload("prefiltered environment", &flat)?,
            irradiance_size: (irr.width, irr.height),
            irradiance: device.upload("irradiance", &irr.levels[0])?,
            timings: Timings::default(),
        })
    }
}

#[cfg(test)]
mod layout_tests {
    use super::{DownsamplePush, PrefilterPush};
    use crate::gpu::{check_layout, kernels};

    /// The push-constant structs match the GLSL blocks of their kernels.
    #[test]
    fn push_layouts_match_glsl() {
        assert_eq!(check_layout::<DownsamplePush>(&[&kernels::ENV_DOWNSAMPLE, &kernels::ENV_IRRADIANCE]), Ok(2));
        assert_eq!(check_layout::<PrefilterPush>(&[&kernels::ENV_PREFILTER]), Ok(1));
    }
}
