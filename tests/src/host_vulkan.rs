//! A host application's own Vulkan instance and device, made with `ash` the
//! way a game engine makes them, for the tests that lend it to srug
//! (`Device::from_raw`): images with their own memory, staging buffers,
//! semaphores and one-off submissions on the host's queue.

#![allow(clippy::unwrap_used, clippy::expect_used, reason = "test support: a failed unwrap is a failed test")]

use std::ffi::c_void;
use std::sync::Mutex;

use srug::gpu::ash::{self, vk};
use srug::gpu::{EnabledFeatures, RawVulkan};

/// The host's debug messenger callback: warnings and errors into the
/// `Mutex<Vec<String>>` at `user`.
///
/// # Safety
/// Called by the validation layer with valid data; `user` as described.
pub unsafe extern "system" fn hear(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    _types: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    user: *mut c_void,
) -> vk::Bool32 {
    if severity
        .intersects(vk::DebugUtilsMessageSeverityFlagsEXT::WARNING | vk::DebugUtilsMessageSeverityFlagsEXT::ERROR)
    {
        // SAFETY: the layer passes valid callback data for the call's duration.
        let text = unsafe { data.as_ref().and_then(|d| d.message_as_c_str()) }
            .map_or_else(|| "?".to_string(), |m| m.to_string_lossy().into_owned());
        // SAFETY: `user` is the host's `heard`, alive while the messenger is.
        if let Some(heard) = unsafe { user.cast::<Mutex<Vec<String>>>().as_ref() } {
            heard.lock().unwrap_or_else(|p| p.into_inner()).push(text);
        }
    }
    vk::FALSE
}

/// A host's Vulkan objects, destroyed by the host at the end of the test.
pub struct Host {
    /// The loader.
    pub entry: ash::Entry,
    /// The host's instance.
    pub instance: ash::Instance,
    /// The host's own debug messenger.
    pub messenger: (ash::ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT),
    /// What the messenger heard (its user data; boxed so it does not move).
    pub heard: Box<Mutex<Vec<String>>>,
    /// The physical device.
    pub physical: vk::PhysicalDevice,
    /// The host's device.
    pub device: ash::Device,
    /// The queue family (compute and graphics on lavapipe).
    pub family: u32,
    /// What it enabled of srug's features.
    pub enabled: EnabledFeatures,
}

/// A host instance (validation and synchronization validation on, its own
/// messenger) and device (queue family with compute; `bufferDeviceAddress`
/// as asked, `shaderInt64`, `timelineSemaphore`).
pub fn host(enable_bda: bool) -> Host {
    host_with(enable_bda, false)
}

/// [`host`], with `computeFullSubgroups` (`VK_EXT_subgroup_size_control`,
/// which lavapipe and NVIDIA's driver offer) enabled on the device too where
/// `full_subgroups` asks.
pub fn host_with(enable_bda: bool, full_subgroups: bool) -> Host {
    // SAFETY: loading the system loader.
    let entry = unsafe { ash::Entry::load() }.unwrap();
    let layers = [c"VK_LAYER_KHRONOS_validation".as_ptr()];
    let extensions = [ash::ext::debug_utils::NAME.as_ptr(), ash::ext::validation_features::NAME.as_ptr()];
    let sync = [vk::ValidationFeatureEnableEXT::SYNCHRONIZATION_VALIDATION];
    let mut features = vk::ValidationFeaturesEXT::default().enabled_validation_features(&sync);
    let app = vk::ApplicationInfo::default().api_version(vk::API_VERSION_1_2);
    let create = vk::InstanceCreateInfo::default()
        .application_info(&app)
        .enabled_layer_names(&layers)
        .enabled_extension_names(&extensions)
        .push_next(&mut features);
    // SAFETY: valid create info of locals.
    let instance = unsafe { entry.create_instance(&create, None) }.unwrap();
    let loader = ash::ext::debug_utils::Instance::new(&entry, &instance);
    let heard: Box<Mutex<Vec<String>>> = Box::default();
    let info = vk::DebugUtilsMessengerCreateInfoEXT::default()
        .user_data(std::ptr::from_ref::<Mutex<Vec<String>>>(&heard).cast_mut().cast::<c_void>())
        .message_severity(vk::DebugUtilsMessageSeverityFlagsEXT::WARNING | vk::DebugUtilsMessageSeverityFlagsEXT::ERROR)
        .message_type(vk::DebugUtilsMessageTypeFlagsEXT::GENERAL | vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION)
        .pfn_user_callback(Some(hear));
    // SAFETY: valid create info; the callback is a plain function.
    let messenger = (loader.clone(), unsafe { loader.create_debug_utils_messenger(&info, None) }.unwrap());
    // SAFETY: valid instance.
    let physical = unsafe { instance.enumerate_physical_devices() }.unwrap()[0];
    // SAFETY: valid physical device.
    let families = unsafe { instance.get_physical_device_queue_family_properties(physical) };
    let family = families.iter().position(|f| f.queue_flags.contains(vk::QueueFlags::COMPUTE)).unwrap() as u32;
    let priorities = [1.0f32];
    let queues = [vk::DeviceQueueCreateInfo::default().queue_family_index(family).queue_priorities(&priorities)];
    let mut v12 =
        vk::PhysicalDeviceVulkan12Features::default().buffer_device_address(enable_bda).timeline_semaphore(true);
    let base = vk::PhysicalDeviceFeatures::default().shader_int64(true);
    let mut size_control = vk::PhysicalDeviceSubgroupSizeControlFeatures::default().compute_full_subgroups(true);
    let mut create =
        vk::DeviceCreateInfo::default().queue_create_infos(&queues).enabled_features(&base).push_next(&mut v12);
    // Memory srug exports is imported through this extension (lavapipe offers it).
    // SAFETY: valid physical device.
    let offered = unsafe { instance.enumerate_device_extension_properties(physical) }.unwrap();
    let fd = ash::khr::external_memory_fd::NAME;
    let mut extensions: Vec<_> =
        offered.iter().filter(|e| e.extension_name_as_c_str() == Ok(fd)).map(|_| fd.as_ptr()).collect();
    if full_subgroups {
        extensions.push(ash::ext::subgroup_size_control::NAME.as_ptr());
        create = create.push_next(&mut size_control);
    }
    let create = create.enabled_extension_names(&extensions);
    // SAFETY: valid create info; lavapipe supports these features.
    let device = unsafe { instance.create_device(physical, &create, None) }.unwrap();
    let enabled = EnabledFeatures {
        buffer_device_address: enable_bda,
        shader_int64: true,
        compute_full_subgroups: full_subgroups,
        ..EnabledFeatures::default()
    };
    Host { entry, instance, messenger, heard, physical, device, family, enabled }
}

impl Host {
    /// srug's view of the host's device.
    pub fn raw(&self) -> RawVulkan {
        RawVulkan {
            entry: self.entry.clone(),
            instance: self.instance.clone(),
            physical_device: self.physical,
            device: self.device.clone(),
            queue_family: self.family,
            queue_index: 0,
            enabled: self.enabled,
            validation_messages: true,
        }
    }

    /// The host uses its device after srug is gone, then destroys everything;
    /// returns what its messenger heard meanwhile.
    pub fn finish(self) -> Vec<String> {
        let info = vk::BufferCreateInfo::default().size(256).usage(vk::BufferUsageFlags::STORAGE_BUFFER);
        // SAFETY: the host's own objects, srug's all dropped; destroyed in order.
        unsafe {
            let buffer = self.device.create_buffer(&info, None).unwrap();
            self.device.destroy_buffer(buffer, None);
            self.device.device_wait_idle().unwrap();
            self.device.destroy_device(None);
            self.messenger.0.destroy_debug_utils_messenger(self.messenger.1, None);
            self.instance.destroy_instance(None);
        }
        std::mem::take(&mut *self.heard.lock().unwrap_or_else(|p| p.into_inner()))
    }
}

/// A host image and its memory.
#[derive(Clone, Copy, Debug)]
pub struct OwnImage {
    /// The image.
    pub image: vk::Image,
    /// Its memory.
    pub memory: vk::DeviceMemory,
    /// Its aspect.
    pub aspect: vk::ImageAspectFlags,
    /// Width and height.
    pub size: (u32, u32),
}

impl Host {
    /// Queue 0 of the host's family (the one srug is lent too).
    pub fn queue(&self) -> vk::Queue {
        // SAFETY: queue 0 of a family the device was created with.
        unsafe { self.device.get_device_queue(self.family, 0) }
    }

    fn memory_type(&self, bits: u32, flags: vk::MemoryPropertyFlags) -> u32 {
        // SAFETY: valid physical device.
        let props = unsafe { self.instance.get_physical_device_memory_properties(self.physical) };
        (0..props.memory_type_count)
            .find(|&i| bits & (1 << i) != 0 && props.memory_types[i as usize].property_flags.contains(flags))
            .expect("no suitable memory type")
    }

    /// A 2D image of `format` with its own device-local memory.
    pub fn create_image(&self, format: vk::Format, size: (u32, u32), usage: vk::ImageUsageFlags) -> OwnImage {
        let info = vk::ImageCreateInfo::default()
            .image_type(vk::ImageType::TYPE_2D)
            .format(format)
            .extent(vk::Extent3D { width: size.0, height: size.1, depth: 1 })
            .mip_levels(1)
            .array_layers(1)
            .samples(vk::SampleCountFlags::TYPE_1)
            .tiling(vk::ImageTiling::OPTIMAL)
            .usage(usage)
            .initial_layout(vk::ImageLayout::UNDEFINED);
        let aspect =
            if format == vk::Format::D32_SFLOAT { vk::ImageAspectFlags::DEPTH } else { vk::ImageAspectFlags::COLOR };
        // SAFETY: valid create info; memory bound once.
        unsafe {
            let image = self.device.create_image(&info, None).unwrap();
            let req = self.device.get_image_memory_requirements(image);
            let alloc = vk::MemoryAllocateInfo::default()
                .allocation_size(req.size)
                .memory_type_index(self.memory_type(req.memory_type_bits, vk::MemoryPropertyFlags::DEVICE_LOCAL));
            let memory = self.device.allocate_memory(&alloc, None).unwrap();
            self.device.bind_image_memory(image, memory, 0).unwrap();
            OwnImage { image, memory, aspect, size }
        }
    }

    /// Destroys an image made by [`Host::create_image`].
    pub fn destroy_image(&self, image: OwnImage) {
        // SAFETY: the host's own image, idle.
        unsafe {
            self.device.destroy_image(image.image, None);
            self.device.free_memory(image.memory, None);
        }
    }

    /// A binary semaphore, or a timeline one starting at `initial`.
    pub fn semaphore(&self, timeline: Option<u64>) -> vk::Semaphore {
        let mut kind = vk::SemaphoreTypeCreateInfo::default()
            .semaphore_type(vk::SemaphoreType::TIMELINE)
            .initial_value(timeline.unwrap_or(0));
        let mut info = vk::SemaphoreCreateInfo::default();
        if timeline.is_some() {
            info = info.push_next(&mut kind);
        }
        // SAFETY: valid create info.
        unsafe { self.device.create_semaphore(&info, None) }.unwrap()
    }

    /// Destroys a semaphore.
    pub fn destroy_semaphore(&self, semaphore: vk::Semaphore) {
        // SAFETY: the host's own, no longer in use.
        unsafe { self.device.destroy_semaphore(semaphore, None) };
    }

    /// Records with `record`, submits to the host's queue waiting on `wait`
    /// and signalling `signal` (semaphore, value), and waits for the fence.
    pub fn submit(
        &self,
        record: impl FnOnce(&ash::Device, vk::CommandBuffer),
        wait: &[(vk::Semaphore, u64)],
        signal: &[(vk::Semaphore, u64)],
    ) {
        let d = &self.device;
        // SAFETY: objects made here, destroyed after the fence wait.
        unsafe {
            let pool = d
                .create_command_pool(&vk::CommandPoolCreateInfo::default().queue_family_index(self.family), None)
                .unwrap();
            let alloc = vk::CommandBufferAllocateInfo::default().command_pool(pool).command_buffer_count(1);
            let cmd = d.allocate_command_buffers(&alloc).unwrap()[0];
            d.begin_command_buffer(cmd, &vk::CommandBufferBeginInfo::default()).unwrap();
            record(d, cmd);
            d.end_command_buffer(cmd).unwrap();
            let (ws, wv): (Vec<_>, Vec<_>) = wait.iter().copied().unzip();
            let (ss, sv): (Vec<_>, Vec<_>) = signal.iter().copied().unzip();
            let stages = vec![vk::PipelineStageFlags::ALL_COMMANDS; ws.len()];
            let mut values =
                vk::TimelineSemaphoreSubmitInfo::default().wait_semaphore_values(&wv).signal_semaphore_values(&sv);
            let cmds = [cmd];
            let submit = vk::SubmitInfo::default()
                .command_buffers(&cmds)
                .wait_semaphores(&ws)
                .wait_dst_stage_mask(&stages)
                .signal_semaphores(&ss)
                .push_next(&mut values);
            let fence = d.create_fence(&vk::FenceCreateInfo::default(), None).unwrap();
            d.queue_submit(self.queue(), &[submit], fence).unwrap();
            d.wait_for_fences(&[fence], true, u64::MAX).unwrap();
            d.destroy_fence(fence, None);
            d.destroy_command_pool(pool, None);
        }
    }

    /// A host-visible buffer of `bytes`, mapped.
    fn staging(&self, bytes: u64) -> (vk::Buffer, vk::DeviceMemory, *mut u8) {
        let info = vk::BufferCreateInfo::default()
            .size(bytes)
            .usage(vk::BufferUsageFlags::TRANSFER_SRC | vk::BufferUsageFlags::TRANSFER_DST);
        // SAFETY: valid create info; memory bound once and mapped whole.
        unsafe {
            let buffer = self.device.create_buffer(&info, None).unwrap();
            let req = self.device.get_buffer_memory_requirements(buffer);
            let flags = vk::MemoryPropertyFlags::HOST_VISIBLE | vk::MemoryPropertyFlags::HOST_COHERENT;
            let alloc = vk::MemoryAllocateInfo::default()
                .allocation_size(req.size)
                .memory_type_index(self.memory_type(req.memory_type_bits, flags));
            let memory = self.device.allocate_memory(&alloc, None).unwrap();
            self.device.bind_buffer_memory(buffer, memory, 0).unwrap();
            let ptr = self.device.map_memory(memory, 0, bytes, vk::MemoryMapFlags::empty()).unwrap().cast::<u8>();
            (buffer, memory, ptr)
        }
    }

    fn free_staging(&self, buffer: vk::Buffer, memory: vk::DeviceMemory) {
        // SAFETY: idle (its submission's fence was waited on).
        unsafe {
            self.device.unmap_memory(memory);
            self.device.destroy_buffer(buffer, None);
            self.device.free_memory(memory, None);
        }
    }

    fn region(image: &OwnImage) -> vk::BufferImageCopy {
        vk::BufferImageCopy::default()
            .image_subresource(vk::ImageSubresourceLayers::default().aspect_mask(image.aspect).layer_count(1))
            .image_extent(vk::Extent3D { width: image.size.0, height: image.size.1, depth: 1 })
    }

    fn barrier(
        d: &ash::Device,
        cmd: vk::CommandBuffer,
        image: &OwnImage,
        from: (vk::ImageLayout, vk::AccessFlags),
        to: (vk::ImageLayout, vk::AccessFlags),
    ) {
        let range = vk::ImageSubresourceRange::default().aspect_mask(image.aspect).level_count(1).layer_count(1);
        let b = vk::ImageMemoryBarrier::default()
            .old_layout(from.0)
            .src_access_mask(from.1)
            .new_layout(to.0)
            .dst_access_mask(to.1)
            .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
            .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
            .image(image.image)
            .subresource_range(range);
        Self::record_barrier(d, cmd, vk::PipelineStageFlags::ALL_COMMANDS, b);
    }

    /// Records one image barrier from `src` stages to every later command.
    fn record_barrier(
        d: &ash::Device,
        cmd: vk::CommandBuffer,
        src: vk::PipelineStageFlags,
        b: vk::ImageMemoryBarrier<'_>,
    ) {
        // SAFETY: recording state; the host's own image.
        unsafe {
            d.cmd_pipeline_barrier(
                cmd,
                src,
                vk::PipelineStageFlags::ALL_COMMANDS,
                vk::DependencyFlags::empty(),
                &[],
                &[],
                &[b],
            );
        }
    }

    /// Writes `bytes` (tightly packed texels) into `image`, leaving it in
    /// `layout`, and signals `signal`.
    pub fn upload_image(
        &self,
        image: &OwnImage,
        bytes: &[u8],
        layout: vk::ImageLayout,
        signal: &[(vk::Semaphore, u64)],
    ) {
        let (buffer, memory, ptr) = self.staging(bytes.len() as u64);
        // SAFETY: the mapping holds `bytes.len()` bytes.
        unsafe { std::ptr::copy_nonoverlapping(bytes.as_ptr(), ptr, bytes.len()) };
        let record = |d: &ash::Device, cmd| {
            Self::barrier(
                d,
                cmd,
                image,
                (vk::ImageLayout::UNDEFINED, vk::AccessFlags::empty()),
                (vk::ImageLayout::TRANSFER_DST_OPTIMAL, vk::AccessFlags::TRANSFER_WRITE),
            );
            // SAFETY: recording state; buffer and image live.
            unsafe {
                d.cmd_copy_buffer_to_image(
                    cmd,
                    buffer,
                    image.image,
                    vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                    &[Self::region(image)],
                );
            }
            Self::barrier(
                d,
                cmd,
                image,
                (vk::ImageLayout::TRANSFER_DST_OPTIMAL, vk::AccessFlags::TRANSFER_WRITE),
                (layout, vk::AccessFlags::MEMORY_READ | vk::AccessFlags::MEMORY_WRITE),
            );
        };
        self.submit(record, &[], signal);
        self.free_staging(buffer, memory);
    }

    /// Reads `bytes` of tightly packed texels from `image` (in `layout`),
    /// after waiting on `wait`; leaves it in `layout`.
    pub fn download_image(
        &self,
        image: &OwnImage,
        bytes: usize,
        layout: vk::ImageLayout,
        wait: &[(vk::Semaphore, u64)],
    ) -> Vec<u8> {
        let (buffer, memory, ptr) = self.staging(bytes as u64);
        let record = |d: &ash::Device, cmd| {
            Self::barrier(
                d,
                cmd,
                image,
                (layout, vk::AccessFlags::MEMORY_WRITE),
                (vk::ImageLayout::TRANSFER_SRC_OPTIMAL, vk::AccessFlags::TRANSFER_READ),
            );
            // SAFETY: recording state; buffer and image live.
            unsafe {
                d.cmd_copy_image_to_buffer(
                    cmd,
                    image.image,
                    vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
                    buffer,
                    &[Self::region(image)],
                );
            }
            Self::barrier(
                d,
                cmd,
                image,
                (vk::ImageLayout::TRANSFER_SRC_OPTIMAL, vk::AccessFlags::empty()),
                (layout, vk::AccessFlags::empty()),
            );
            let to_host = vk::MemoryBarrier::default()
                .src_access_mask(vk::AccessFlags::TRANSFER_WRITE)
                .dst_access_mask(vk::AccessFlags::HOST_READ);
            // SAFETY: recording state.
            unsafe {
                d.cmd_pipeline_barrier(
                    cmd,
                    vk::PipelineStageFlags::TRANSFER,
                    vk::PipelineStageFlags::HOST,
                    vk::DependencyFlags::empty(),
                    &[to_host],
                    &[],
                    &[],
                );
            }
        };
        self.submit(record, wait, &[]);
        let mut out = vec![0u8; bytes];
        // SAFETY: the mapping holds `bytes` bytes, written and made visible before the fence.
        unsafe { std::ptr::copy_nonoverlapping(ptr, out.as_mut_ptr(), bytes) };
        self.free_staging(buffer, memory);
        out
    }

    /// Imports memory another device exported as an opaque fd (ownership of
    /// `fd` passes to Vulkan) into a new image of that description.
    pub fn import_image(
        &self,
        fd: std::os::fd::OwnedFd,
        format: vk::Format,
        size: (u32, u32),
        usage: vk::ImageUsageFlags,
        allocation_size: u64,
    ) -> OwnImage {
        use std::os::fd::IntoRawFd;
        let handle = vk::ExternalMemoryHandleTypeFlags::OPAQUE_FD;
        let mut external = vk::ExternalMemoryImageCreateInfo::default().handle_types(handle);
        let info = vk::ImageCreateInfo::default()
            .image_type(vk::ImageType::TYPE_2D)
            .format(format)
            .extent(vk::Extent3D { width: size.0, height: size.1, depth: 1 })
            .mip_levels(1)
            .array_layers(1)
            .samples(vk::SampleCountFlags::TYPE_1)
            .tiling(vk::ImageTiling::OPTIMAL)
            .usage(usage)
            .initial_layout(vk::ImageLayout::UNDEFINED)
            .push_next(&mut external);
        // SAFETY: valid create info; the fd's memory was made for an identical image.
        unsafe {
            let image = self.device.create_image(&info, None).unwrap();
            let req = self.device.get_image_memory_requirements(image);
            let mut dedicated = vk::MemoryDedicatedAllocateInfo::default().image(image);
            let mut import = vk::ImportMemoryFdInfoKHR::default().handle_type(handle).fd(fd.into_raw_fd());
            let alloc = vk::MemoryAllocateInfo::default()
                .allocation_size(allocation_size)
                .memory_type_index(self.memory_type(req.memory_type_bits, vk::MemoryPropertyFlags::DEVICE_LOCAL))
                .push_next(&mut dedicated)
                .push_next(&mut import);
            let memory = self.device.allocate_memory(&alloc, None).unwrap();
            self.device.bind_image_memory(image, memory, 0).unwrap();
            OwnImage { image, memory, aspect: vk::ImageAspectFlags::COLOR, size }
        }
    }

    /// Acquires an imported image (in `layout`, kept) from `VK_QUEUE_FAMILY_EXTERNAL`.
    pub fn acquire_external(&self, image: &OwnImage, layout: vk::ImageLayout) {
        let family = self.family;
        self.submit(
            |d, cmd| {
                let range =
                    vk::ImageSubresourceRange::default().aspect_mask(image.aspect).level_count(1).layer_count(1);
                let b = vk::ImageMemoryBarrier::default()
                    .old_layout(layout)
                    .new_layout(layout)
                    .dst_access_mask(vk::AccessFlags::MEMORY_READ)
                    .src_queue_family_index(vk::QUEUE_FAMILY_EXTERNAL)
                    .dst_queue_family_index(family)
                    .image(image.image)
                    .subresource_range(range);
                Self::record_barrier(d, cmd, vk::PipelineStageFlags::TOP_OF_PIPE, b);
            },
            &[],
            &[],
        );
    }

    /// Waits up to `timeout_ns` for timeline `semaphore` to reach `value`; whether it did.
    pub fn wait_timeline(&self, semaphore: vk::Semaphore, value: u64, timeout_ns: u64) -> bool {
        let semaphores = [semaphore];
        let values = [value];
        let info = vk::SemaphoreWaitInfo::default().semaphores(&semaphores).values(&values);
        // SAFETY: a timeline semaphore of this device.
        match unsafe { self.device.wait_semaphores(&info, timeout_ns) } {
            Ok(()) => true,
            Err(vk::Result::TIMEOUT) => false,
            Err(e) => panic!("vkWaitSemaphores: {e}"),
        }
    }
}
