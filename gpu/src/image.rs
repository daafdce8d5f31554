//! Images srug creates on its own device for callers that render into
//! images ([`crate::HostImage`]) without owning the device: a benchmark, or
//! a host that keeps srug on a device of its own. Memory comes from srug's
//! allocator; a dropped image is destroyed once every submission made before
//! the drop has finished, as buffers are.

use std::sync::atomic::Ordering;
use std::sync::Arc;

use ash::vk;
use gpu_allocator::vulkan::{AllocationCreateDesc, AllocationScheme};
use gpu_allocator::MemoryLocation;

use crate::device::Device;
use crate::error::{vk_error, GpuError as Error, Result};
use crate::host_image::{HostImage, HostImageFormat};
use crate::shared::{lock, Garbage, Shared};

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
        let allocation = lock(&shared.allocator).allocate(&AllocationCreateDesc {
            name,
            requirements,
            location: MemoryLocation::GpuOnly,
            linear: false,
            allocation_scheme: AllocationScheme::GpuAllocatorManaged,
        });
        let allocation = match allocation {
            Ok(a) => a,
            Err(e) => {
                // SAFETY: unused image, created above.
                unsafe { shared.device.destroy_image(raw, None) };
                return Err(Error::OutOfMemory(format!("image {name} ({width}x{height}): {e}")));
            }
        };
        // SAFETY: memory and offset come from an allocation meeting the requirements.
        let bound = unsafe { shared.device.bind_image_memory(raw, allocation.memory(), allocation.offset()) };
        if let Err(e) = bound {
            let _ = lock(&shared.allocator).free(allocation);
            // SAFETY: unused image, created above.
            unsafe { shared.device.destroy_image(raw, None) };
            return Err(vk_error("vkBindImageMemory")(e));
        }
        let bytes = allocation.size();
        let now = shared.current_bytes.fetch_add(bytes, Ordering::Relaxed) + bytes;
        shared.peak_bytes.fetch_max(now, Ordering::Relaxed);
        Ok(DeviceImage { shared: shared.clone(), raw, allocation: Some(allocation), format, width, height, usage })
    }
}
