//! The host's own images and semaphores, on a device the host lent srug
//! ([`Device::from_raw`](crate::Device::from_raw)): srug reads the host's
//! colour and depth from its images and writes frames into them, ordered
//! against the host's work by semaphores the host passes.
//!
//! Invariants:
//! - Vulkan cannot be asked an image's format, size, usage or layout, so the
//!   host states them in [`HostImage`]; [`HostImage::check`] refuses a
//!   statement srug cannot honour (a format it does not copy, a format without
//!   transfer support on the device, a missing usage flag, a layout of the
//!   wrong aspect). A statement that does not match the image is undefined
//!   behaviour in Vulkan's sense, which the validation layer reports.
//! - An image is single-sampled, 2D, optimal tiling, one mip level and one
//!   layer (level 0, layer 0 are used), owned by srug's queue family or
//!   created with concurrent sharing: srug records no ownership transfer.
//! - srug moves an image from `layout_before` to the transfer layout of its
//!   copy with a barrier whose first scope is every earlier command on the
//!   queue (all stages, all writes), and after its last copy to `layout_after`
//!   with a barrier whose second scope is every later command: on a queue shared with the
//!   host, submission order plus these barriers order the accesses; on
//!   another queue, the host's semaphores do ([`HostSync`]).
//! - Waits are attached to srug's first submission of a call and signals to
//!   its last; srug blocks until its own work is done, so a wait must be on a
//!   semaphore whose signal is already submitted.

use ash::vk;

use crate::buffer::Buffer;
use crate::device::Device;
use crate::error::{GpuError as Error, Result};
use crate::recording::Recording;

/// The image formats srug copies frames into and reads host pixels from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum HostImageFormat {
    /// `VK_FORMAT_R8G8B8A8_UNORM`.
    Rgba8Unorm,
    /// `VK_FORMAT_R8G8B8A8_SRGB`.
    Rgba8Srgb,
    /// `VK_FORMAT_B8G8R8A8_UNORM` (a common swapchain format).
    Bgra8Unorm,
    /// `VK_FORMAT_B8G8R8A8_SRGB`.
    Bgra8Srgb,
    /// `VK_FORMAT_R16G16B16A16_SFLOAT`.
    Rgba16Float,
    /// `VK_FORMAT_R32G32B32A32_SFLOAT`.
    Rgba32Float,
    /// `VK_FORMAT_R32_SFLOAT` (a depth written as colour).
    R32Float,
    /// `VK_FORMAT_D32_SFLOAT` (a depth buffer).
    D32Float,
}

impl HostImageFormat {
    /// Every format, in the order the docs list them.
    pub const ALL: [Self; 8] = [
        Self::Rgba8Unorm,
        Self::Rgba8Srgb,
        Self::Bgra8Unorm,
        Self::Bgra8Srgb,
        Self::Rgba16Float,
        Self::Rgba32Float,
        Self::R32Float,
        Self::D32Float,
    ];

    /// The Vulkan format.
    pub fn vk(self) -> vk::Format {
        match self {
            Self::Rgba8Unorm => vk::Format::R8G8B8A8_UNORM,
            Self::Rgba8Srgb => vk::Format::R8G8B8A8_SRGB,
            Self::Bgra8Unorm => vk::Format::B8G8R8A8_UNORM,
            Self::Bgra8Srgb => vk::Format::B8G8R8A8_SRGB,
            Self::Rgba16Float => vk::Format::R16G16B16A16_SFLOAT,
            Self::Rgba32Float => vk::Format::R32G32B32A32_SFLOAT,
            Self::R32Float => vk::Format::R32_SFLOAT,
            Self::D32Float => vk::Format::D32_SFLOAT,
        }
    }

    /// The srug format of a Vulkan one, or an error listing those srug copies.
    pub fn from_vk(format: vk::Format) -> Result<Self> {
        Self::ALL.into_iter().find(|f| f.vk() == format).ok_or_else(|| {
            let names: Vec<String> = Self::ALL.iter().map(|f| format!("{:?}", f.vk())).collect();
            Error::invalid(format!("image format {format:?}"), format!("is not one srug copies ({})", names.join(", ")))
        })
    }

    /// Bytes per texel in a tightly packed buffer copy.
    pub fn texel_bytes(self) -> u64 {
        match self {
            Self::R32Float | Self::D32Float => 4,
            Self::Rgba8Unorm | Self::Rgba8Srgb | Self::Bgra8Unorm | Self::Bgra8Srgb => 4,
            Self::Rgba16Float => 8,
            Self::Rgba32Float => 16,
        }
    }

    /// Whether the format is a depth format (copied through its depth aspect).
    pub fn is_depth(self) -> bool {
        self == Self::D32Float
    }

    /// Whether the format holds one value per texel (a depth) rather than RGBA.
    pub fn is_single_channel(self) -> bool {
        matches!(self, Self::R32Float | Self::D32Float)
    }

    fn aspect(self) -> vk::ImageAspectFlags {
        if self.is_depth() {
            vk::ImageAspectFlags::DEPTH
        } else {
            vk::ImageAspectFlags::COLOR
        }
    }
}

/// A host's image as the host describes it (srug cannot query these).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HostImage {
    /// The image, created by the host on the device it lent srug.
    pub image: vk::Image,
    /// Its format (one of [`HostImageFormat`]).
    pub format: vk::Format,
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// The usage flags it was created with: srug needs `TRANSFER_DST` to
    /// write it and `TRANSFER_SRC` to read it.
    pub usage: vk::ImageUsageFlags,
    /// Its layout when srug's first submission of the call begins
    /// (`UNDEFINED` discards its contents: only for an image srug does not read).
    pub layout_before: vk::ImageLayout,
    /// The layout srug leaves it in.
    pub layout_after: vk::ImageLayout,
}

/// A host's buffer srug copies a frame's values into, as the host describes it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HostBuffer {
    /// The buffer, created by the host on the device it lent srug.
    pub buffer: vk::Buffer,
    /// Its size in bytes.
    pub size: u64,
    /// The usage flags it was created with (srug needs `TRANSFER_DST`).
    pub usage: vk::BufferUsageFlags,
}

impl HostBuffer {
    /// Checks that srug can write `bytes` into it; `what` names it in the error.
    pub fn check(&self, what: &str, bytes: u64) -> Result<()> {
        let bad = |why: String| Error::invalid(what, why);
        if self.buffer == vk::Buffer::null() {
            return Err(bad("is VK_NULL_HANDLE".into()));
        }
        if !self.usage.contains(vk::BufferUsageFlags::TRANSFER_DST) {
            return Err(bad("lacks usage TRANSFER_DST, which srug needs to write it".into()));
        }
        if self.size < bytes {
            return Err(bad(format!("holds {} bytes, the frame's values {bytes}", self.size)));
        }
        Ok(())
    }
}

/// What srug will do with a [`HostImage`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HostImageAccess {
    /// Read only (copied out).
    Read,
    /// Written only.
    Write,
    /// Read, then written.
    ReadWrite,
}

impl HostImageAccess {
    fn reads(self) -> bool {
        matches!(self, Self::Read | Self::ReadWrite)
    }

    fn writes(self) -> bool {
        matches!(self, Self::Write | Self::ReadWrite)
    }
}

/// A layout usable by an image of this aspect.
fn layout_fits(layout: vk::ImageLayout, depth: bool) -> bool {
    use vk::ImageLayout as L;
    let colour_only = [L::COLOR_ATTACHMENT_OPTIMAL, L::PRESENT_SRC_KHR];
    let depth_only = [
        L::DEPTH_STENCIL_ATTACHMENT_OPTIMAL,
        L::DEPTH_STENCIL_READ_ONLY_OPTIMAL,
        L::DEPTH_ATTACHMENT_OPTIMAL,
        L::DEPTH_READ_ONLY_OPTIMAL,
    ];
    let any = [L::UNDEFINED, L::GENERAL, L::SHADER_READ_ONLY_OPTIMAL, L::TRANSFER_SRC_OPTIMAL, L::TRANSFER_DST_OPTIMAL];
    any.contains(&layout) || if depth { depth_only.contains(&layout) } else { colour_only.contains(&layout) }
}

impl HostImage {
    /// The srug format of this image.
    pub fn host_format(&self) -> Result<HostImageFormat> {
        HostImageFormat::from_vk(self.format)
    }

    /// Checks that srug can `access` this image on `device`: `what` names it
    /// in the error. The size is the caller's to check against its frame.
    pub fn check(&self, device: &Device, what: &str, access: HostImageAccess) -> Result<HostImageFormat> {
        let bad = |why: String| Error::invalid(what, why);
        if self.image == vk::Image::null() {
            return Err(bad("is VK_NULL_HANDLE".into()));
        }
        let format = HostImageFormat::from_vk(self.format).map_err(|e| match e {
            Error::InvalidArgument { what: format, why } => bad(format!("has {format}, which {why}")),
            other => other,
        })?;
        if self.width == 0 || self.height == 0 {
            return Err(bad(format!("is {}x{}", self.width, self.height)));
        }
        let shared = &device.shared;
        // SAFETY: the physical device the logical one was made on, of this instance.
        let props =
            unsafe { shared.instance.get_physical_device_format_properties(shared.physical_device, format.vk()) };
        let features = props.optimal_tiling_features;
        let needs = [
            (access.reads(), vk::ImageUsageFlags::TRANSFER_SRC, vk::FormatFeatureFlags::TRANSFER_SRC, "read"),
            (access.writes(), vk::ImageUsageFlags::TRANSFER_DST, vk::FormatFeatureFlags::TRANSFER_DST, "write"),
        ];
        for (needed, usage, feature, verb) in needs {
            if !needed {
                continue;
            }
            if !self.usage.contains(usage) {
                return Err(bad(format!("lacks usage {usage:?}, which srug needs to {verb} it")));
            }
            if !features.contains(feature) {
                return Err(bad(format!(
                    "has format {:?}, which this device cannot {verb} by copy ({feature:?})",
                    self.format
                )));
            }
        }
        for (name, layout) in [("layout_before", self.layout_before), ("layout_after", self.layout_after)] {
            if !layout_fits(layout, format.is_depth()) {
                return Err(bad(format!("{name} {layout:?} does not suit a {:?} image", self.format)));
            }
        }
        if self.layout_after == vk::ImageLayout::UNDEFINED {
            return Err(bad("layout_after is UNDEFINED (an image can only leave a call in a defined layout)".into()));
        }
        if access.reads() && self.layout_before == vk::ImageLayout::UNDEFINED {
            return Err(bad("layout_before is UNDEFINED, so there is nothing to read".into()));
        }
        Ok(format)
    }

    /// Bytes of a tightly packed copy of the whole image.
    pub fn packed_bytes(&self) -> Result<u64> {
        let format = self.host_format()?;
        Ok(u64::from(self.width) * u64::from(self.height) * format.texel_bytes())
    }

    fn range(&self, format: HostImageFormat) -> vk::ImageSubresourceRange {
        vk::ImageSubresourceRange::default().aspect_mask(format.aspect()).level_count(1).layer_count(1)
    }

    fn region(&self, format: HostImageFormat) -> vk::BufferImageCopy {
        vk::BufferImageCopy::default()
            .image_subresource(vk::ImageSubresourceLayers::default().aspect_mask(format.aspect()).layer_count(1))
            .image_extent(vk::Extent3D { width: self.width, height: self.height, depth: 1 })
    }
}

impl<'a> Recording<'a> {
    fn host_image_barrier(
        &mut self,
        image: &HostImage,
        format: HostImageFormat,
        from: vk::ImageLayout,
        to: vk::ImageLayout,
    ) {
        let barrier = vk::ImageMemoryBarrier::default()
            .src_access_mask(vk::AccessFlags::MEMORY_WRITE)
            .dst_access_mask(vk::AccessFlags::MEMORY_READ | vk::AccessFlags::MEMORY_WRITE)
            .old_layout(from)
            .new_layout(to)
            .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
            .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
            .image(image.image)
            .subresource_range(image.range(format));
        // SAFETY: recording state; the host vouches for the image (HostImage's contract).
        unsafe {
            self.device().shared.device.cmd_pipeline_barrier(
                self.cmd,
                vk::PipelineStageFlags::ALL_COMMANDS,
                vk::PipelineStageFlags::ALL_COMMANDS,
                vk::DependencyFlags::empty(),
                &[],
                &[],
                &[barrier],
            );
        }
    }

    /// Moves a host image from layout `from` to `to` with no copy (all
    /// stages, all writes before; every later command after).
    pub fn transition_host_image(
        &mut self,
        image: &HostImage,
        from: vk::ImageLayout,
        to: vk::ImageLayout,
    ) -> Result<()> {
        let format = image.host_format()?;
        self.host_image_barrier(image, format, from, to);
        Ok(())
    }

    fn check_copy(&self, image: &HostImage, buffer: &Buffer) -> Result<HostImageFormat> {
        let format = image.host_format()?;
        let bytes = image.packed_bytes()?;
        if buffer.size() < bytes {
            return Err(Error::invalid(
                format!("buffer {}", buffer.name()),
                format!("holds {} bytes, the {}x{} image {bytes}", buffer.size(), image.width, image.height),
            ));
        }
        Ok(format)
    }

    /// Copies a host image, now in layout `from`, into `buffer` (tightly
    /// packed rows); leaves the image in TRANSFER_SRC_OPTIMAL.
    pub fn copy_host_image_to_buffer(
        &mut self,
        image: &HostImage,
        from: vk::ImageLayout,
        buffer: &'a Buffer,
    ) -> Result<()> {
        let format = self.check_copy(image, buffer)?;
        self.check_device(buffer)?;
        let src = vk::ImageLayout::TRANSFER_SRC_OPTIMAL;
        self.host_image_barrier(image, format, from, src);
        // SAFETY: an image of this device in `src` (HostImage's contract) and a live buffer large enough.
        unsafe {
            self.device().shared.device.cmd_copy_image_to_buffer(
                self.cmd,
                image.image,
                src,
                buffer.raw,
                &[image.region(format)],
            );
        }
        Ok(())
    }

    /// Copies `buffer` (tightly packed rows of the image's texels) into a host
    /// image now in layout `from`; leaves it in its `layout_after`.
    pub fn copy_buffer_to_host_image(
        &mut self,
        buffer: &'a Buffer,
        image: &HostImage,
        from: vk::ImageLayout,
    ) -> Result<()> {
        let format = self.check_copy(image, buffer)?;
        self.check_device(buffer)?;
        let dst = vk::ImageLayout::TRANSFER_DST_OPTIMAL;
        // The buffer was written by a kernel: the global barrier, then the layout's.
        self.before_command();
        self.host_image_barrier(image, format, from, dst);
        // SAFETY: as in copy_host_image_to_buffer.
        unsafe {
            self.device().shared.device.cmd_copy_buffer_to_image(
                self.cmd,
                buffer.raw,
                image.image,
                dst,
                &[image.region(format)],
            );
        }
        self.host_image_barrier(image, format, dst, image.layout_after);
        Ok(())
    }

    /// Releases a host image (in `layout`, left there) from srug's queue
    /// family to `VK_QUEUE_FAMILY_EXTERNAL` after srug's last write, or with
    /// `acquire` takes it back before srug's next access: an image whose
    /// memory another device imports passes between the devices so, the other
    /// device acquiring and releasing it in turn (same layout).
    pub fn transfer_host_image_external(
        &mut self,
        image: &HostImage,
        layout: vk::ImageLayout,
        acquire: bool,
    ) -> Result<()> {
        let format = image.host_format()?;
        let own = self.device().shared.queue_family;
        let (src, dst) = if acquire { (vk::QUEUE_FAMILY_EXTERNAL, own) } else { (own, vk::QUEUE_FAMILY_EXTERNAL) };
        let (src_access, dst_access) = if acquire {
            (vk::AccessFlags::empty(), vk::AccessFlags::MEMORY_READ | vk::AccessFlags::MEMORY_WRITE)
        } else {
            (vk::AccessFlags::MEMORY_WRITE, vk::AccessFlags::empty())
        };
        let barrier = vk::ImageMemoryBarrier::default()
            .src_access_mask(src_access)
            .dst_access_mask(dst_access)
            .old_layout(layout)
            .new_layout(layout)
            .src_queue_family_index(src)
            .dst_queue_family_index(dst)
            .image(image.image)
            .subresource_range(image.range(format));
        let (src_stage, dst_stage) = if acquire {
            (vk::PipelineStageFlags::TOP_OF_PIPE, vk::PipelineStageFlags::ALL_COMMANDS)
        } else {
            (vk::PipelineStageFlags::ALL_COMMANDS, vk::PipelineStageFlags::BOTTOM_OF_PIPE)
        };
        // SAFETY: recording state on srug's queue family; the image is srug's or the host's as stated.
        unsafe {
            self.device().shared.device.cmd_pipeline_barrier(
                self.cmd,
                src_stage,
                dst_stage,
                vk::DependencyFlags::empty(),
                &[],
                &[],
                &[barrier],
            );
        }
        Ok(())
    }

    /// Copies `bytes` of `src` to the start of a host's buffer (checked with
    /// [`HostBuffer::check`]); the copy is ordered before every later command
    /// on the queue.
    pub fn copy_to_host_buffer(&mut self, src: &'a Buffer, dst: &HostBuffer, bytes: u64) -> Result<()> {
        self.check_device(src)?;
        dst.check("host buffer", bytes)?;
        if src.size() < bytes {
            return Err(Error::invalid(format!("buffer {}", src.name()), format!("holds fewer than {bytes} bytes")));
        }
        self.before_command();
        let region = vk::BufferCopy { src_offset: 0, dst_offset: 0, size: bytes };
        let after = vk::MemoryBarrier::default()
            .src_access_mask(vk::AccessFlags::TRANSFER_WRITE)
            .dst_access_mask(vk::AccessFlags::MEMORY_READ | vk::AccessFlags::MEMORY_WRITE);
        // SAFETY: a live buffer of this device and the host's buffer (its contract), in bounds.
        unsafe {
            let d = &self.device().shared.device;
            d.cmd_copy_buffer(self.cmd, src.raw, dst.buffer, &[region]);
            d.cmd_pipeline_barrier(
                self.cmd,
                vk::PipelineStageFlags::TRANSFER,
                vk::PipelineStageFlags::ALL_COMMANDS,
                vk::DependencyFlags::empty(),
                &[after],
                &[],
                &[],
            );
        }
        Ok(())
    }
}
