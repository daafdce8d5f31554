//! Images and semaphores exported as POSIX file descriptors
//! (`VK_KHR_external_memory_fd`, `VK_KHR_external_semaphore_fd`), for a host
//! that keeps srug on a Vulkan device of its own and imports srug's output
//! into its device.
//!
//! Invariants:
//! - Only devices srug created export (it enables the extensions where the
//!   physical device offers them; [`crate::DeviceInfo::external_memory_fd`]);
//!   elsewhere creation fails with [`GpuError::Unsupported`] naming the extension.
//! - An exported image has a dedicated allocation of opaque-fd memory; each
//!   [`ExportedImage::export_fd`] returns a new descriptor that the caller
//!   owns (importing it into Vulkan transfers that ownership to the importer).
//!   The importer must create an identical image ([`ExportedImage::info`]) on
//!   a physical device with the same device and driver UUIDs.
//! - Dropping the export frees srug's image and memory once its submissions
//!   are done; memory the host imported stays alive until the host frees it.

use std::os::fd::{FromRawFd, OwnedFd};
use std::sync::Arc;

use ash::vk;

use crate::device::Device;
use crate::error::{vk_error, GpuError as Error, Result};
use crate::host_image::{HostImage, HostImageFormat};
use crate::shared::{Garbage, Shared};

/// What an importer needs to recreate an exported image.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ExportedImageInfo {
    /// The format.
    pub format: HostImageFormat,
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// The usage flags it was created with.
    pub usage: vk::ImageUsageFlags,
    /// Bytes of its memory (`allocationSize` of the import).
    pub allocation_size: u64,
    /// The device and driver UUIDs the importer's physical device must match.
    pub device_uuid: [u8; 16],
    /// As above.
    pub driver_uuid: [u8; 16],
}

/// A 2D image (one level and layer, optimal tiling) whose memory can be
/// exported as an opaque fd.
pub struct ExportedImage {
    shared: Arc<Shared>,
    raw: vk::Image,
    memory: vk::DeviceMemory,
    info: ExportedImageInfo,
}

impl Drop for ExportedImage {
    fn drop(&mut self) {
        self.shared.retire(Garbage::ExportedImage(self.raw, self.memory));
    }
}

impl ExportedImage {
    /// What an importer needs.
    pub fn info(&self) -> ExportedImageInfo {
        self.info
    }

    /// The image as a [`HostImage`] for srug to write ([`crate::Recording`]'s copies).
    pub fn host_image(&self, layout_before: vk::ImageLayout, layout_after: vk::ImageLayout) -> HostImage {
        HostImage {
            image: self.raw,
            format: self.info.format.vk(),
            width: self.info.width,
            height: self.info.height,
            usage: self.info.usage,
            layout_before,
            layout_after,
        }
    }

    /// A new file descriptor of the image's memory; the caller owns it.
    pub fn export_fd(&self) -> Result<OwnedFd> {
        let loader = ash::khr::external_memory_fd::Device::new(&self.shared.instance, &self.shared.device);
        let info = vk::MemoryGetFdInfoKHR::default()
            .memory(self.memory)
            .handle_type(vk::ExternalMemoryHandleTypeFlags::OPAQUE_FD);
        // SAFETY: memory allocated exportable as an opaque fd on this device, with the extension enabled.
        let fd = unsafe { loader.get_memory_fd(&info) }.map_err(vk_error("vkGetMemoryFdKHR"))?;
        // SAFETY: vkGetMemoryFdKHR returns a new descriptor the caller owns.
        Ok(unsafe { OwnedFd::from_raw_fd(fd) })
    }
}

impl Device {
    /// Creates a `width`×`height` image of `format` with `usage` whose memory
    /// can be exported ([`ExportedImage::export_fd`]).
    pub fn create_exported_image(
        &self,
        format: HostImageFormat,
        (width, height): (u32, u32),
        usage: vk::ImageUsageFlags,
    ) -> Result<ExportedImage> {
        let shared = &self.shared;
        if !shared.info.external_memory_fd {
            return Err(Error::Unsupported(format!(
                "exporting images needs VK_KHR_external_memory_fd on a device srug created; {} {}",
                shared.info.name,
                if shared.owns_device { "does not offer it" } else { "is the host's" }
            )));
        }
        if width == 0 || height == 0 {
            return Err(Error::invalid("exported image", format!("is {width}x{height}")));
        }
        let handle = vk::ExternalMemoryHandleTypeFlags::OPAQUE_FD;
        let mut external = vk::ExternalMemoryImageCreateInfo::default().handle_types(handle);
        let info = crate::image::image_info(format, (width, height), usage).push_next(&mut external);
        let d = &shared.device;
        // SAFETY: valid create info on a live device with the extension enabled.
        let raw = unsafe { d.create_image(&info, None) }.map_err(vk_error("vkCreateImage"))?;
        // SAFETY: `raw` was just created on this device.
        let req = unsafe { d.get_image_memory_requirements(raw) };
        // SAFETY: the physical device the logical one was made on.
        let props = unsafe { shared.instance.get_physical_device_memory_properties(shared.physical_device) };
        let kind = (0..props.memory_type_count).find(|&i| {
            req.memory_type_bits & (1 << i) != 0
                && props.memory_types[i as usize].property_flags.contains(vk::MemoryPropertyFlags::DEVICE_LOCAL)
        });
        let Some(kind) = kind else {
            // SAFETY: unused image, created above.
            unsafe { d.destroy_image(raw, None) };
            return Err(Error::Unsupported("no device-local memory type for an exported image".into()));
        };
        let mut dedicated = vk::MemoryDedicatedAllocateInfo::default().image(raw);
        let mut export = vk::ExportMemoryAllocateInfo::default().handle_types(handle);
        let alloc = vk::MemoryAllocateInfo::default()
            .allocation_size(req.size)
            .memory_type_index(kind)
            .push_next(&mut dedicated)
            .push_next(&mut export);
        // SAFETY: valid allocate info for this image.
        let memory = match unsafe { d.allocate_memory(&alloc, None) } {
            Ok(m) => m,
            Err(e) => {
                // SAFETY: unused image, created above.
                unsafe { d.destroy_image(raw, None) };
                return Err(vk_error("vkAllocateMemory")(e));
            }
        };
        let image = ExportedImage {
            shared: shared.clone(),
            raw,
            memory,
            info: ExportedImageInfo {
                format,
                width,
                height,
                usage,
                allocation_size: req.size,
                device_uuid: shared.info.device_uuid,
                driver_uuid: shared.info.driver_uuid,
            },
        };
        // SAFETY: dedicated memory of the required size for this image.
        unsafe { d.bind_image_memory(raw, memory, 0) }.map_err(vk_error("vkBindImageMemory"))?;
        Ok(image)
    }

    /// A binary semaphore exportable as an opaque fd: a host on another
    /// device imports [`ExportedSemaphore::export_fd`] and waits on what srug
    /// signals through it ([`crate::HostSync`]).
    pub fn create_exported_semaphore(&self) -> Result<ExportedSemaphore> {
        let shared = &self.shared;
        if !shared.info.external_semaphore_fd {
            return Err(Error::Unsupported(format!(
                "exporting semaphores needs VK_KHR_external_semaphore_fd on a device srug created; {} {}",
                shared.info.name,
                if shared.owns_device { "does not offer it" } else { "is the host's" }
            )));
        }
        let mut export =
            vk::ExportSemaphoreCreateInfo::default().handle_types(vk::ExternalSemaphoreHandleTypeFlags::OPAQUE_FD);
        let info = vk::SemaphoreCreateInfo::default().push_next(&mut export);
        // SAFETY: valid create info on a live device with the extension enabled.
        let raw = unsafe { shared.device.create_semaphore(&info, None) }.map_err(vk_error("vkCreateSemaphore"))?;
        Ok(ExportedSemaphore { shared: shared.clone(), raw })
    }
}

/// A binary semaphore whose payload can be exported as an opaque fd.
pub struct ExportedSemaphore {
    shared: Arc<Shared>,
    raw: vk::Semaphore,
}

impl ExportedSemaphore {
    /// The semaphore, to signal through [`crate::HostSync`].
    pub fn semaphore(&self) -> vk::Semaphore {
        self.raw
    }

    /// A new file descriptor of the semaphore; the caller owns it.
    pub fn export_fd(&self) -> Result<OwnedFd> {
        let loader = ash::khr::external_semaphore_fd::Device::new(&self.shared.instance, &self.shared.device);
        let info = vk::SemaphoreGetFdInfoKHR::default()
            .semaphore(self.raw)
            .handle_type(vk::ExternalSemaphoreHandleTypeFlags::OPAQUE_FD);
        // SAFETY: a semaphore created exportable as an opaque fd on this device.
        let fd = unsafe { loader.get_semaphore_fd(&info) }.map_err(vk_error("vkGetSemaphoreFdKHR"))?;
        // SAFETY: vkGetSemaphoreFdKHR returns a new descriptor the caller owns.
        Ok(unsafe { OwnedFd::from_raw_fd(fd) })
    }
}

impl Drop for ExportedSemaphore {
    fn drop(&mut self) {
        self.shared.retire(Garbage::Semaphore(self.raw));
    }
}
