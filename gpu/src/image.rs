//! Images srug creates on its own device for callers that render into
//! images ([`crate::HostImage`]) without owning the device: a benchmark, or
//! a host that keeps srug on a device of its own. Memory comes from srug's
//! allocator; a dropped image is destroyed once every submission made before
//! the drop has finished, as buffers are.

use std::sync::Arc;

use ash::vk;
use gpu_allocator::MemoryLocation;

use crate::device::Device;
use crate::error::{vk_error, GpuError as Error, Result};
use crate::host_image::{HostImage, HostImageFormat};
use crate::shared::{Garbage, Shared};

/// A 2D image (one level, one layer, optimal tiling) on srug's device.
pub struct DeviceImage {
    shared: Arc<Shared>,
    raw: vk::Image,
    allocation: Option<gpu_allocator::vulkan::Allocation>,
    format: HostImageFormat,
    width: u32,
    height: u32,
    usage: vk::ImageUsageFlags,
}

impl Drop for DeviceImage {
    fn drop(&mut self) {
        if let Some(allocation) = self.allocation.take() {
            self.shared.retire(Garbage::Image(self.raw, allocation));
        }
    }
}

impl DeviceImage {
    /// The image as a [`HostImage`] in `layout_before`, to be left in `layout_after`.
    pub fn host_image(&self, layout_before: vk::ImageLayout, layout_after: vk::ImageLayout) -> HostImage {
        HostImage {
            image: self.raw,
            format: self.format.vk(),
            width: self.width,
            height: self.height,
            usage: self.usage,
            layout_before,
            layout_after,
        }
    }
}

/// The create info of srug's 2D images: one level and layer, optimal
/// tiling, single-sampled, starting undefined.
pub(crate) fn image_info<'a>(
    format: HostImageFormat,
    (width, height): (u32, u32),
    usage: vk::ImageUsageFlags,
) -> vk::ImageCreateInfo<'a> {
    vk::ImageCreateInfo::default()
        .image_type(vk::ImageType::TYPE_2D)
        .format(format.vk())
        .extent(vk::Extent3D { width, height, depth: 1 })
        .mip_levels(1)
        .array_layers(1)
        .samples(vk::SampleCountFlags::TYPE_1)
        .tiling(vk::ImageTiling::OPTIMAL)
        .usage(usage)
        .initial_layout(vk::ImageLayout::UNDEFINED)
}

impl Device {
    /// Creates a `width`×`height` image of `format` with `usage`, in device memory.
    pub fn create_image(
        &self,
        name: &str,
        format: HostImageFormat,
        (width, height): (u32, u32),
        usage: vk::ImageUsageFlags,
    ) -> Result<DeviceImage> {
        let shared = &self.shared;
        if width == 0 || height == 0 {
            return Err(Error::invalid(format!("image {name}"), format!("is {width}x{height}")));
        }
        let info = image_info(format, (width, height), usage);
        // SAFETY: valid create info on a live device.
        let raw = unsafe { shared.device.create_image(&info, None) }.map_err(vk_error("vkCreateImage"))?;
        // SAFETY: `raw` was just created on this device.
        let requirements = unsafe { shared.device.get_image_memory_requirements(raw) };
        let d = &shared.device;
        let allocation = shared.allocate_bound(
            &format!("image {name} ({width}x{height})"),
            name,
            requirements,
            MemoryLocation::GpuOnly,
            false,
            "vkBindImageMemory",
            // SAFETY: memory and offset come from an allocation meeting the requirements.
            |memory, offset| unsafe { d.bind_image_memory(raw, memory, offset) },
            // SAFETY: unused image, created above.
            || unsafe { d.destroy_image(raw, None) },
        )?;
        Ok(DeviceImage { shared: shared.clone(), raw, allocation: Some(allocation), format, width, height, usage })
    }
}
