//! `srug devices`: the Vulkan devices, in the order `--device N` counts them.

use srug::gpu::Device;
use srug::Result;

/// Runs `srug devices`.
pub(super) fn run() -> Result<()> {
    for a in Device::list()? {
        println!("#{} {} ({:?}, Vulkan {})", a.index, a.name, a.device_type, a.api_version);
    }
    Ok(())
}
