//! Rendering into the host's own Vulkan images (a context made with
//! `srug_context_create_from_vulkan`): [`srug_renderer_render_to_vulkan`].
//! Vulkan handles are `uint64_t` (non-dispatchable) and enumerations
//! `uint32_t`, so the header needs no `vulkan.h`.

use srug::frame::host_images::{FrameChannel, FrameOutputs, HostTargets};
use srug::frame::{HostFrameSource, Relighter};
use srug::gpu::ash::vk::{self, Handle};
use srug::gpu::{HostBuffer, HostImage, HostSync, SemaphoreSignal, SemaphoreWait};

use crate::ffi::*;
use crate::renderer::*;
use crate::{guard, srug_status, Failure, FfiResult};

/// One of the host's images, as the host created it (Vulkan cannot be asked).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct srug_vulkan_image {
    /// `VkImage`: 2D, one mip level and layer, optimal tiling, single-sampled,
    /// on the context's device, owned by srug's queue family or concurrent.
    pub image: u64,
    /// `VkFormat`: colour `R8G8B8A8_UNORM`/`_SRGB`, `B8G8R8A8_UNORM`/`_SRGB`,
    /// `R16G16B16A16_SFLOAT`, `R32G32B32A32_SFLOAT`; depth `R32_SFLOAT`, `D32_SFLOAT`.
    pub format: u32,
    /// Width in texels: the renderer's.
    pub width: u32,
    /// Height in texels: the renderer's.
    pub height: u32,
    /// `VkImageUsageFlags` it was created with: `TRANSFER_DST` to be written,
    /// `TRANSFER_SRC` too to be read (compositing).
    pub usage: u32,
    /// `VkImageLayout` it is in when srug's work begins (`UNDEFINED`: contents
    /// discarded, only when not compositing).
    pub layout_before: u32,
    /// `VkImageLayout` srug leaves it in.
    pub layout_after: u32,
}

/// One of the host's buffers a frame channel is copied into: tightly packed
/// f32, row-major, `srug_channel_components(channel)` per pixel.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct srug_vulkan_buffer {
    /// `VkBuffer` on the context's device.
    pub buffer: u64,
    /// Its size in bytes (at least width × height × components × 4).
    pub size: u64,
    /// `VkBufferUsageFlags` it was created with: `TRANSFER_DST` needed.
    pub usage: u32,
    /// The channel (`SRUG_CHANNEL_*`); G-buffer channels are rendered for it.
    pub channel: srug_channel,
}

/// A host semaphore and a value (timeline semaphores; ignored for binary ones).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct srug_vulkan_semaphore {
    /// `VkSemaphore`.
    pub semaphore: u64,
    /// The value waited for or signalled.
    pub value: u64,
}

/// Where `srug_renderer_render_to_vulkan` writes a frame, and how.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct srug_vulkan_targets {
    /// The colour image, or NULL.
    pub colour: *const srug_vulkan_image,
    /// The depth image (`R32_SFLOAT` or `D32_SFLOAT`), or NULL.
    pub depth: *const srug_vulkan_image,
    /// How the depth image encodes depth (`SRUG_DEPTH_*`), with its planes.
    pub depth_convention: srug_depth_convention,
    /// Near plane (camera z) of the Vulkan and reversed-Z conventions.
    pub near: f32,
    /// Far plane (camera z; `INFINITY` allowed with reversed-Z).
    pub far: f32,
    /// Read the images first: splats behind the host's depth are hidden, the
    /// rest blend over the host's colour, and the depth keeps the nearer.
    pub composite: bool,
    /// Buffers that further channels are copied into, or NULL.
    pub buffers: *const srug_vulkan_buffer,
    /// Entries of `buffers`.
    pub buffer_count: usize,
    /// Semaphores srug's first submission waits on (all stages); their
    /// signals must already be submitted: the call blocks until its work is done.
    pub wait: *const srug_vulkan_semaphore,
    /// Entries of `wait`.
    pub wait_count: usize,
    /// Semaphores srug's last submission signals.
    pub signal: *const srug_vulkan_semaphore,
    /// Entries of `signal`.
    pub signal_count: usize,
}

fn host_image(i: &srug_vulkan_image) -> HostImage {
    HostImage {
        image: vk::Image::from_raw(i.image),
        format: vk::Format::from_raw(i.format as i32),
        width: i.width,
        height: i.height,
        usage: vk::ImageUsageFlags::from_raw(i.usage),
        layout_before: vk::ImageLayout::from_raw(i.layout_before as i32),
        layout_after: vk::ImageLayout::from_raw(i.layout_after as i32),
    }
}

/// The targets a C caller described.
///
/// # Safety
/// As `srug_renderer_render_to_vulkan`'s `targets`.
unsafe fn targets_of(t: *const srug_vulkan_targets) -> FfiResult<HostTargets> {
    if t.is_null() {
        return Err(null("targets"));
    }
    // SAFETY: non-null, and the caller's contract.
    let t = unsafe { &*t };
    // SAFETY: NULL or one image, by the caller's contract.
    let colour = unsafe { t.colour.as_ref() }.map(host_image);
    // SAFETY: as above.
    let depth = unsafe { t.depth.as_ref() }.map(host_image);
    // SAFETY: `wait_count` entries at `wait`, by the caller's contract.
    let wait = unsafe { slice(t.wait, t.wait_count, "targets->wait") }?;
    // SAFETY: as above.
    let signal = unsafe { slice(t.signal, t.signal_count, "targets->signal") }?;
    // SAFETY: as above.
    let buffers = unsafe { slice(t.buffers, t.buffer_count, "targets->buffers") }?;
    let buffers = buffers
        .iter()
        .map(|b| {
            let channel = frame_channel(b.channel).ok_or_else(|| invalid(format!("unknown channel {}", b.channel)))?;
            let buffer = HostBuffer {
                buffer: vk::Buffer::from_raw(b.buffer),
                size: b.size,
                usage: vk::BufferUsageFlags::from_raw(b.usage),
            };
            Ok((channel, buffer))
        })
        .collect::<FfiResult<Vec<_>>>()?;
    Ok(HostTargets {
        colour,
        depth,
        depth_convention: depth_convention(t.depth_convention, t.near, t.far)?,
        composite: t.composite,
        buffers,
        sync: HostSync {
            wait: wait
                .iter()
                .map(|s| SemaphoreWait { semaphore: vk::Semaphore::from_raw(s.semaphore), value: s.value })
                .collect(),
            signal: signal
                .iter()
                .map(|s| SemaphoreSignal { semaphore: vk::Semaphore::from_raw(s.semaphore), value: s.value })
                .collect(),
        },
    })
}

impl HostFrameSource for Frame {
    fn outputs(&self, channels: &[FrameChannel]) -> srug::Result<FrameOutputs<'_>> {
        let (colour, display) = match &self.shaded {
            Some(s) => (&s.radiance, self.display),
            None => (self.gbuffer.rgb_buffer()?, None),
        };
        Ok(FrameOutputs {
            width: self.gbuffer.width,
            height: self.gbuffer.height,
            colour,
            alpha: &self.gbuffer.alpha,
            median_depth: self.gbuffer.get(srug::splat::Channel::MedianDepth),
            display,
            channels: channels.iter().map(|c| c.resolve(&self.gbuffer, self.shaded.as_ref())).collect(),
        })
    }
}

impl RendererObject {
    fn render_to_vulkan(&mut self, scene: &crate::scene::SceneObject, targets: &HostTargets) -> FfiResult {
        if self.device.owns_vulkan_device() {
            return Err(Failure::new(
                srug_status::SRUG_ERROR_WRONG_ORDER,
                "the renderer's context opened its own Vulkan device: render into host images needs a context made \
                 by srug_context_create_from_vulkan on the images' device (or srug_renderer_export_image)",
            ));
        }
        self.render_into(scene, targets)
    }

    /// Renders into `targets` (images of the renderer's device).
    fn render_into(&mut self, scene: &crate::scene::SceneObject, targets: &HostTargets) -> FfiResult {
        let saved = self.settings;
        if targets.composite {
            self.settings.shade.background = srug::shade::Background::Color([0.0; 3]);
        }
        targets.request_channels(&mut self.settings);
        let size = self.settings.render_size(self.width, self.height);
        // The render's own failure (its status and message) is reported as it is.
        let mut failure = None;
        let result = Relighter::with_host_targets(
            self,
            |r| &mut r.relighter,
            targets,
            size,
            |r| match r.render(scene) {
                Ok(()) => r.frame.take().ok_or_else(|| srug::Error::Internal("the render left no frame".into())),
                Err(f) => {
                    let message = f.message.clone();
                    failure = Some(f);
                    Err(srug::Error::Internal(message))
                }
            },
        );
        self.settings = saved;
        if let Some(f) = failure {
            return Err(f);
        }
        let (frame, timings) = result?;
        if let Some(t) = self.timings.as_mut() {
            t.stages.extend(timings.stages);
        }
        self.frame = Some(frame);
        Ok(())
    }
}

/// Renders `scene` as `srug_renderer_render` does and writes the frame into
/// the host's images (`targets`), on the host's device: the context must come
/// from `srug_context_create_from_vulkan` and the images from that device,
/// at the renderer's size (a preset rendering below full size is refused).
/// Colour images get a relit frame's display values (8-bit formats: exposure,
/// tone map, sRGB-encoded, as `SRUG_FORMAT_RGBA8_SRGB` reads) or its linear
/// radiance (float formats), a plain frame's colour as is; alpha is coverage.
/// A depth image gets the camera z where the splats' coverage crosses 50%, in
/// `depth_convention` ("nothing" where it never does). With `composite`, the
/// images are read first: splats behind the depth image's values are hidden,
/// the rest blend over the colour image (relit frames over black, in linear
/// light; 8-bit images as display values), and the depth keeps the host's
/// value unless a splat is nearer. `buffers` get further channels
/// (`SRUG_CHANNEL_*`, the G-buffer ones rendered for the purpose) as
/// tightly packed f32. Barriers cover every pipeline stage before
/// srug's first access and after its last; the images end in `layout_after`.
/// The frame stays readable (`srug_renderer_read_image`, `_read_channel`).
/// Every image statement is checked before any work (format, usage, size,
/// layouts; `SRUG_ERROR_INVALID_ARGUMENT` naming it; no semaphore touched); a
/// statement that does not match the image itself is undefined behaviour, as
/// in Vulkan. A failure after the images were read still signals `signal`
/// and leaves them, unwritten, in `layout_after`.
///
/// # Safety
/// `targets` NULL or valid for reads, its pointers NULL or valid for their
/// counts; the handles in it valid on the context's device.
#[no_mangle]
pub unsafe extern "C" fn srug_renderer_render_to_vulkan(
    renderer: *mut srug_renderer,
    scene: *const crate::scene::srug_scene,
    targets: *const srug_vulkan_targets,
) -> srug_status {
    guard("srug_renderer_render_to_vulkan", || {
        // SAFETY: the caller's contract.
        let targets = unsafe { targets_of(targets) }?;
        with_renderer_and_scene(renderer, scene, |r, _, s| r.render_to_vulkan(s, &targets))
    })
}

/// An image srug exported for a host on another device (`srug_renderer_export_image`).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct srug_exported_image {
    /// Its memory as an opaque POSIX file descriptor (`VK_EXTERNAL_MEMORY_HANDLE_TYPE_OPAQUE_FD_BIT`),
    /// owned by the caller: import it (Vulkan then owns it) or close it.
    pub fd: i32,
    /// `VkFormat`, as asked.
    pub format: u32,
    /// Width: the renderer's.
    pub width: u32,
    /// Height: the renderer's.
    pub height: u32,
    /// `VkImageUsageFlags` it was created with (`TRANSFER_SRC | TRANSFER_DST | SAMPLED`):
    /// the importer's image must be created alike (2D, one level and layer,
    /// optimal tiling, `VkExternalMemoryImageCreateInfo` with the opaque-fd type).
    pub usage: u32,
    /// `allocationSize` of the import (a dedicated allocation).
    pub allocation_size: u64,
    /// The importer's physical device must have this `deviceUUID` ...
    pub device_uuid: [u8; 16],
    /// ... and this `driverUUID`.
    pub driver_uuid: [u8; 16],
}

/// Makes an image at the renderer's size whose memory the host imports into
/// its own device, for hosts that keep srug on a device of its own (a context
/// from `srug_context_create`). `vk_format` as for
/// `srug_renderer_render_to_vulkan`'s colour images. A later call replaces the
/// image (the host's imports of the old one stay valid until it frees them).
/// Devices without `VK_KHR_external_memory_fd`: `SRUG_ERROR_UNSUPPORTED`.
///
/// # Safety
/// `out` valid for one write.
#[no_mangle]
pub unsafe extern "C" fn srug_renderer_export_image(
    renderer: *mut srug_renderer,
    vk_format: u32,
    out: *mut srug_exported_image,
) -> srug_status {
    guard("srug_renderer_export_image", || {
        check_out(out, "out")?;
        with_renderer(renderer, |r| {
            let format = srug::gpu::HostImageFormat::from_vk(vk::Format::from_raw(vk_format as i32))
                .map_err(|e| invalid(e.to_string()))?;
            if format.is_single_channel() {
                return Err(invalid(format!("format {:?} is a depth format: export a colour one", format.vk())));
            }
            let usage =
                vk::ImageUsageFlags::TRANSFER_SRC | vk::ImageUsageFlags::TRANSFER_DST | vk::ImageUsageFlags::SAMPLED;
            let image =
                r.device.create_exported_image(format, (r.width, r.height), usage).map_err(srug::Error::from)?;
            let fd = image.export_fd().map_err(srug::Error::from)?;
            let info = image.info();
            r.exported = Some((image, false));
            let description = srug_exported_image {
                fd: std::os::fd::IntoRawFd::into_raw_fd(fd),
                format: vk_format,
                width: info.width,
                height: info.height,
                usage: usage.as_raw(),
                allocation_size: info.allocation_size,
                device_uuid: info.device_uuid,
                driver_uuid: info.driver_uuid,
            };
            // SAFETY: checked non-null; the caller's contract.
            unsafe { write_out(out, "out", description) }
        })
    })
}

/// Renders `scene` as `srug_renderer_render` does into the exported image
/// (`srug_renderer_export_image`), as `srug_renderer_render_to_vulkan` writes
/// a colour image without compositing, and returns when the GPU is done. The
/// image is left in `VK_IMAGE_LAYOUT_GENERAL`, released to
/// `VK_QUEUE_FAMILY_EXTERNAL`: the host's first barrier on its imported image
/// acquires it (from `VK_QUEUE_FAMILY_EXTERNAL`, GENERAL to GENERAL) before
/// reading and releases it back (to `VK_QUEUE_FAMILY_EXTERNAL`) before the
/// next call, which acquires it for srug. The frame stays readable as usual.
#[no_mangle]
pub extern "C" fn srug_renderer_render_to_exported(
    renderer: *mut srug_renderer,
    scene: *const crate::scene::srug_scene,
) -> srug_status {
    guard("srug_renderer_render_to_exported", || {
        with_renderer_and_scene(renderer, scene, |r, _, s| {
            let general = vk::ImageLayout::GENERAL;
            let Some((exported, released)) = r.exported.as_mut() else {
                return Err(wrong_order("no exported image (srug_renderer_export_image first)"));
            };
            // After the first frame the image is the host's until srug takes it back.
            let before = if *released { general } else { vk::ImageLayout::UNDEFINED };
            let image = exported.host_image(before, general);
            if *released {
                r.device
                    .run(|rec| rec.transfer_host_image_external(&image, general, true))
                    .map_err(srug::Error::from)?;
            }
            let signal = r.exported_semaphore.as_ref().map(|s| SemaphoreSignal { semaphore: s.semaphore(), value: 0 });
            let targets = HostTargets {
                colour: Some(image),
                depth: None,
                depth_convention: srug::splat::HostDepth::CameraZ,
                composite: false,
                buffers: Vec::new(),
                sync: HostSync::default(),
            };
            r.render_into(s, &targets)?;
            // The release is the call's last submission: it signals the exported semaphore, if any.
            let sync = HostSync { wait: Vec::new(), signal: signal.into_iter().collect() };
            r.device
                .run_synced(&sync, |rec| rec.transfer_host_image_external(&image, general, false))
                .map_err(srug::Error::from)?;
            if let Some((_, released)) = r.exported.as_mut() {
                *released = true;
            }
            Ok(())
        })
    })
}

/// Makes a binary semaphore that each `srug_renderer_render_to_exported`
/// signals when its frame is written, exported as an opaque POSIX fd in
/// `*fd` (the caller's: import it into a `VkSemaphore` with
/// `vkImportSemaphoreFdKHR` and wait on it before reading the imported image,
/// instead of relying on the call's return). A later call replaces it.
/// Devices without `VK_KHR_external_semaphore_fd` (lavapipe among them):
/// `SRUG_ERROR_UNSUPPORTED` naming it.
///
/// # Safety
/// `fd` valid for one write.
#[no_mangle]
pub unsafe extern "C" fn srug_renderer_export_semaphore(renderer: *mut srug_renderer, fd: *mut i32) -> srug_status {
    guard("srug_renderer_export_semaphore", || {
        check_out(fd, "fd")?;
        with_renderer(renderer, |r| {
            let semaphore = r.device.create_exported_semaphore().map_err(srug::Error::from)?;
            let exported = semaphore.export_fd().map_err(srug::Error::from)?;
            r.exported_semaphore = Some(semaphore);
            // SAFETY: checked non-null; the caller's contract.
            unsafe { write_out(fd, "fd", std::os::fd::IntoRawFd::into_raw_fd(exported)) }
        })
    })
}
