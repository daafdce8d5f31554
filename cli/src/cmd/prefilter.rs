//! `srug prefilter`: prepares an environment once (GGX chain and irradiance)
//! and saves it as KTX2 files in a folder that `--env` accepts.

use std::path::{Path, PathBuf};

use srug::gpu::Device;
use srug::shade::{EnvironmentMap, EnvironmentPrep, PrepareSettings};
use srug::Result;

use crate::args::DeviceArgs;

/// Arguments of `srug prefilter`.
#[derive(clap::Args, Clone, Debug)]
pub(super) struct PrefilterArgs {
    /// An .exr, .hdr or .ktx2 environment.
    env: PathBuf,
    /// Output folder (specular.ktx2, irradiance.ktx2).
    #[arg(long)]
    out: PathBuf,
    /// Prefiltered levels (roughness level/(levels−1)).
    #[arg(long, default_value_t = 6)]
    levels: u32,
    /// GGX samples per texel.
    #[arg(long, default_value_t = 128)]
    samples: u32,
    /// Zstandard supercompression.
    #[arg(long)]
    zstd: bool,
}

impl PrefilterArgs {
    /// Runs `srug prefilter`.
    pub(super) fn run(&self, device: &DeviceArgs) -> Result<()> {
        let settings = PrepareSettings { levels: self.levels, samples: self.samples, ..Default::default() };
        prefilter(&device.open()?, &self.env, &self.out, &settings, self.zstd)
    }
}

fn prefilter(device: &Device, env: &Path, out: &Path, settings: &PrepareSettings, zstd: bool) -> Result<()> {
    let map = EnvironmentMap::load(env)?;
    let prep = EnvironmentPrep::new(device)?;
    let prepared = prep.prepare(&map, settings)?;
    prepared.save(device, out, zstd)?;
    println!(
        "{}: {}x{}, {} levels, {} samples: {:.0} ms GPU ({}); written to {}",
        env.display(),
        map.width,
        map.height,
        prepared.levels,
        settings.samples,
        prepared.timings.total_seconds() * 1e3,
        prepared.timings,
        out.display()
    );
    Ok(())
}
