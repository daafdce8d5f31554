//! What a device is and can do, as plain data: the one description every
//! other module reads (a leaf: it imports only the format table).

use ash::vk;

use crate::format::TexelFormat;

/// What the chosen device is and can do.
#[derive(Clone, Debug)]
pub struct DeviceInfo {
    /// Index in enumeration order.
    pub index: usize,
    /// `deviceName`.
    pub name: String,
    /// Driver name and info, e.g. "llvmpipe" / "Mesa 22.3.6".
    pub driver: String,
    /// `driverID` (`MESA_LLVMPIPE` for lavapipe).
    pub driver_id: vk::DriverId,
    /// Discrete, integrated, virtual, CPU or other.
    pub device_type: vk::PhysicalDeviceType,
    /// Vulkan API version as "major.minor.patch".
    pub api_version: String,
    /// `maxStorageBufferRange`: the largest buffer a descriptor can bind.
    pub max_storage_buffer_range: u64,
    /// `maxComputeSharedMemorySize`.
    pub max_shared_memory: u32,
    /// `maxComputeWorkGroupCount`.
    pub max_workgroup_count: [u32; 3],
    /// `maxComputeWorkGroupSize`.
    pub max_workgroup_size: [u32; 3],
    /// `maxComputeWorkGroupInvocations`.
    pub max_workgroup_invocations: u32,
    /// Subgroup size (8 on lavapipe; never assume 32).
    pub subgroup_size: u32,
    /// Whether `computeFullSubgroups` is enabled on the device: kernels that
    /// place invocations by `gl_SubgroupID` can be built with every subgroup
    /// full (`REQUIRE_FULL_SUBGROUPS`), which Vulkan promises only so.
    pub full_subgroups: bool,
    /// Subgroup ballot operations (elect, broadcast) in compute shaders.
    pub subgroup_ballot: bool,
    /// Subgroup shuffle operations in compute shaders.
    pub subgroup_shuffle: bool,
    /// Nanoseconds per timestamp tick.
    pub timestamp_period_ns: f64,
    /// Valid bits of a timestamp on the compute queue; 0 when unsupported.
    pub timestamp_valid_bits: u32,
    /// fp16 arithmetic in shaders.
    pub shader_float16: bool,
    /// 16-bit values in storage buffers.
    pub storage_16bit: bool,
    /// `maxTexelBufferElements`: the most elements one texel-buffer view holds.
    pub max_texel_buffer_elements: u64,
    /// `minTexelBufferOffsetAlignment`, in bytes.
    pub min_texel_buffer_offset_alignment: u64,
    /// The [`TexelFormat`]s usable as uniform texel buffers.
    pub texel_formats: Vec<TexelFormat>,
    /// Whether srug enabled `VK_KHR_external_memory_fd` (on devices it
    /// creates, where offered): images can be exported ([`crate::ExportedImage`]).
    pub external_memory_fd: bool,
    /// Whether srug enabled `VK_KHR_external_semaphore_fd`: semaphores can be exported.
    pub external_semaphore_fd: bool,
    /// `VkPhysicalDeviceIDProperties::deviceUUID`: an importer of exported
    /// memory must be on a physical device with the same one.
    pub device_uuid: [u8; 16],
    /// `VkPhysicalDeviceIDProperties::driverUUID`: and the same driver.
    pub driver_uuid: [u8; 16],
}

impl DeviceInfo {
    /// Whether the device is Mesa's lavapipe (llvmpipe), the CPU driver.
    pub fn is_lavapipe(&self) -> bool {
        self.driver_id == vk::DriverId::MESA_LLVMPIPE
    }

    /// The Mesa release (major, minor) of a Mesa driver, read from its driver
    /// info ("Mesa 25.0.7-2~bpo12+1"); `None` for other drivers.
    pub fn mesa_version(&self) -> Option<(u32, u32)> {
        mesa_version_of(&self.driver)
    }

    /// Whether the device is lavapipe from Mesa `major` on: the kernels'
    /// CPU-only choices (which fetches are calls, which `if`s jump) follow it.
    pub fn is_lavapipe_from(&self, major: u32) -> bool {
        self.is_lavapipe() && self.mesa_version().is_some_and(|(m, _)| m >= major)
    }
}

/// The (major, minor) after "Mesa " in a driver string.
pub(crate) fn mesa_version_of(driver: &str) -> Option<(u32, u32)> {
    let (_, rest) = driver.split_once("Mesa ")?;
    let mut numbers = rest.split(|c: char| !c.is_ascii_digit());
    let major = numbers.next()?.parse().ok()?;
    let minor = numbers.next()?.parse().ok()?;
    Some((major, minor))
}

/// GPU memory in use, as counted by srug's allocations.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MemoryUsage {
    /// Bytes allocated now.
    pub current_bytes: u64,
    /// Most bytes allocated at once since creation or the last [`Device::reset_peak_memory`](crate::Device::reset_peak_memory).
    pub peak_bytes: u64,
    /// Bytes of freed buffers kept for reuse by later ones of the same kind
    /// and about the same size (at most an eighth of the largest device-local
    /// heap, 256 MiB to 4 GiB, and never so much that in use and kept would
    /// pass the most ever in use, staging buffers [`POOL_HEADROOM_BYTES`](crate::POOL_HEADROOM_BYTES)
    /// more: a new allocation frees the oldest first; not in `current_bytes`;
    /// [`Device::release_pooled_memory`](crate::Device::release_pooled_memory) frees them).
    pub pooled_bytes: u64,
    /// Allocations since the device was made that took new memory rather
    /// than a pooled buffer (images included).
    pub fresh_allocations: u64,
}

/// A device as listed before choosing one.
#[derive(Clone, Debug)]
pub struct AdapterSummary {
    /// Index in enumeration order (what [`DeviceSelection::Index`](crate::DeviceSelection::Index) takes).
    pub index: usize,
    /// `deviceName`.
    pub name: String,
    /// Discrete, integrated, CPU...
    pub device_type: vk::PhysicalDeviceType,
    /// Vulkan API version.
    pub api_version: String,
}

#[cfg(test)]
mod tests {
    use super::mesa_version_of;

    #[test]
    fn mesa_versions_parse_from_driver_strings() {
        assert_eq!(mesa_version_of("llvmpipe Mesa 22.3.6 (LLVM 15.0.6)"), Some((22, 3)));
        assert_eq!(mesa_version_of("llvmpipe Mesa 25.0.7-2~bpo12+1 (LLVM 15.0.6)"), Some((25, 0)));
        assert_eq!(mesa_version_of("NVIDIA 550.54.14"), None);
        assert_eq!(mesa_version_of("radv Mesa x.y"), None);
    }
}
