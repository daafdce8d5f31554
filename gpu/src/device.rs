//! Instance and device choice, validation, and the device handle.

use std::collections::HashMap;
use std::ffi::{c_void, CStr, CString};
use std::mem::ManuallyDrop;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

use ash::vk;
use gpu_allocator::vulkan::{Allocator, AllocatorCreateDesc};

use crate::error::{vk_error, GpuError as Error, Result};
use crate::format::TexelFormat;
use crate::info::{AdapterSummary, DeviceInfo, MemoryUsage};
use crate::shared::{lock, on_validation_message, pool_limit, BufferPool, Shared, Tracker, ValidationLog};

const VALIDATION_LAYER: &CStr = c"VK_LAYER_KHRONOS_validation";

/// Environment variable that picks the device: an index from `srug info --devices`,
/// `gpu`, `cpu`, or a case-insensitive part of the device name.
pub const DEVICE_ENV: &str = "SRUG_DEVICE";
/// Environment variable that turns the Khronos validation layer on (`1`) or off (`0`).
pub const VALIDATION_ENV: &str = "SRUG_VALIDATION";

/// Which physical device to use.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub enum DeviceSelection {
    /// A discrete GPU, else an integrated one, else anything else (lavapipe).
    #[default]
    Auto,
    /// The first discrete or integrated GPU; an error when there is none.
    Gpu,
    /// The first CPU implementation (lavapipe); an error when there is none.
    Cpu,
    /// The n-th device in enumeration order.
    Index(usize),
    /// The first device whose name contains this text (case-insensitive).
    Name(String),
}

impl std::fmt::Display for DeviceSelection {
    /// The choice in the words of the `--device` syntax.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Auto => write!(f, "automatic device choice"),
            Self::Gpu => write!(f, "device \"gpu\" (a discrete or integrated GPU)"),
            Self::Cpu => write!(f, "device \"cpu\" (a CPU implementation such as lavapipe)"),
            Self::Index(n) => write!(f, "device index {n}"),
            Self::Name(s) => write!(f, "device name \"{s}\""),
        }
    }
}

impl DeviceSelection {
    /// Parses the syntax of [`DEVICE_ENV`].
    pub fn parse(text: &str) -> Self {
        let t = text.trim();
        match t.to_ascii_lowercase().as_str() {
            "" | "auto" => Self::Auto,
            "gpu" => Self::Gpu,
            "cpu" => Self::Cpu,
            _ => t.parse().map(Self::Index).unwrap_or_else(|_| Self::Name(t.to_string())),
        }
    }
}

/// How to create a [`Device`]. `None` fields fall back to the environment.
#[derive(Clone, Debug, Default)]
pub struct DeviceOptions {
    /// Device choice; `None` reads [`DEVICE_ENV`], else [`DeviceSelection::Auto`].
    pub selection: Option<DeviceSelection>,
    /// Khronos validation with synchronization validation; `None` reads [`VALIDATION_ENV`].
    pub validation: Option<bool>,
}
/// The device features srug uses, as enabled on a device (Vulkan cannot
/// report what a device was created with, so a host passing its own device
/// says). srug needs `buffer_device_address` and `shader_int64`; the 16-bit
/// ones enable fp16 paths of the U-Net where present, and
/// `compute_full_subgroups` the sort's block digits.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct EnabledFeatures {
    /// `VkPhysicalDeviceVulkan12Features::bufferDeviceAddress` (required).
    pub buffer_device_address: bool,
    /// `VkPhysicalDeviceFeatures::shaderInt64` (required).
    pub shader_int64: bool,
    /// `VkPhysicalDeviceFeatures::shaderInt16`.
    pub shader_int16: bool,
    /// `VkPhysicalDeviceVulkan12Features::shaderFloat16`.
    pub shader_float16: bool,
    /// `VkPhysicalDeviceVulkan11Features::storageBuffer16BitAccess`.
    pub storage_buffer_16bit_access: bool,
    /// `computeFullSubgroups` (`VK_EXT_subgroup_size_control`, core in
    /// Vulkan 1.3): kernels that place invocations by `gl_SubgroupID` are
    /// built with `REQUIRE_FULL_SUBGROUPS`.
    pub compute_full_subgroups: bool,
}

/// A host application's Vulkan objects for [`Device::from_raw`]. The host
/// keeps owning them: srug never destroys them, and the host must keep them
/// alive until the last [`Device`] handle (and everything made from it) is dropped.
#[derive(Clone)]
pub struct RawVulkan {
    /// The loader entry the instance was created with.
    pub entry: ash::Entry,
    /// The host's instance (Vulkan 1.2 or newer).
    pub instance: ash::Instance,
    /// The physical device `device` was created on.
    pub physical_device: vk::PhysicalDevice,
    /// The host's device.
    pub device: ash::Device,
    /// A queue family of `device` with compute.
    pub queue_family: u32,
    /// The queue of that family srug submits to. srug locks it around its own
    /// submissions; the host must not submit to it concurrently (Vulkan's
    /// external synchronization of a queue), or should give srug a queue of its own.
    /// It must be below the `queueCount` the host created the family with: Vulkan
    /// has no query for that, so srug checks only the family's own `queueCount`.
    pub queue_index: u32,
    /// The features `device` was created with.
    pub enabled: EnabledFeatures,
    /// Collect validation messages ([`Device::take_validation_messages`])
    /// through a debug messenger srug adds to the host's instance; the host
    /// must have enabled `VK_EXT_debug_utils` on it.
    pub validation_messages: bool,
}

/// A Vulkan device with one compute queue. Cheap to clone (shared handle).
#[derive(Clone)]
pub struct Device {
    pub(crate) shared: Arc<Shared>,
    /// Shared by every clone of this handle; its drop empties the kernel cache.
    _cache_owner: Arc<CacheOwner>,
}

/// Empties the kernel cache when the last [`Device`] handle drops, so cached
/// kernels (which hold the shared state) do not keep the device alive forever.
struct CacheOwner(Arc<Shared>);

impl Drop for CacheOwner {
    fn drop(&mut self) {
        let cached = std::mem::take(&mut *lock(&self.0.kernel_cache));
        drop(cached);
    }
}

impl std::fmt::Debug for Device {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Device").field("name", &self.shared.info.name).finish()
    }
}

fn version_string(v: u32) -> String {
    format!("{}.{}.{}", vk::api_version_major(v), vk::api_version_minor(v), vk::api_version_patch(v))
}

fn load_entry() -> Result<ash::Entry> {
    // SAFETY: loading the system Vulkan loader runs its initialisers; we trust the installed loader.
    unsafe { ash::Entry::load() }.map_err(|e| Error::Loader(e.to_string()))
}

fn type_rank(t: vk::PhysicalDeviceType) -> u32 {
    match t {
        vk::PhysicalDeviceType::DISCRETE_GPU => 0,
        vk::PhysicalDeviceType::INTEGRATED_GPU => 1,
        vk::PhysicalDeviceType::VIRTUAL_GPU => 2,
        vk::PhysicalDeviceType::CPU => 3,
        _ => 4,
    }
}

fn name_of(props: &vk::PhysicalDeviceProperties) -> String {
    props.device_name_as_c_str().map(|c| c.to_string_lossy().into_owned()).unwrap_or_default()
}

fn env_flag(name: &str) -> Option<bool> {
    std::env::var(name).ok().map(|v| !matches!(v.trim(), "" | "0" | "false" | "off" | "no"))
}

impl Device {
    /// Uses a host application's Vulkan device instead of creating one: srug
    /// allocates its own memory on it (gpu-allocator), submits to the given
    /// queue, and destroys only what it created. Checks the API version (1.2),
    /// the queue (a compute family, an index it has) and the required features
    /// (`bufferDeviceAddress`, `shaderInt64`), naming what is missing.
    ///
    /// # Safety
    /// The handles must be valid and belong together (`device` created on
    /// `physical_device` from `instance`, with the queue and the `enabled`
    /// features as stated), and stay valid while any handle of the returned
    /// device or anything made from it lives.
    pub unsafe fn from_raw(raw: RawVulkan) -> Result<Self> {
        let RawVulkan {
            entry,
            instance,
            physical_device,
            device,
            queue_family,
            queue_index,
            enabled,
            validation_messages,
        } = raw;
        // SAFETY: the caller vouches for the handles.
        let props = unsafe { instance.get_physical_device_properties(physical_device) };
        if props.api_version < vk::API_VERSION_1_2 {
            return Err(Error::NoDevice(format!(
                "the host's device {} supports Vulkan {}; srug needs 1.2",
                name_of(&props),
                version_string(props.api_version)
            )));
        }
        // SAFETY: as above.
        let families = unsafe { instance.get_physical_device_queue_family_properties(physical_device) };
        let family = families.get(queue_family as usize).ok_or_else(|| {
            Error::NoDevice(format!("queue family {queue_family}: the device has {} families", families.len()))
        })?;
        if !family.queue_flags.contains(vk::QueueFlags::COMPUTE) {
            return Err(Error::NoDevice(format!("queue family {queue_family} has no compute")));
        }
        if queue_index >= family.queue_count {
            return Err(Error::NoDevice(format!(
                "queue {queue_index} of family {queue_family}: the family has {} queues",
                family.queue_count
            )));
        }
        let supported = supported_features(&instance, physical_device);
        let required = [
            (enabled.buffer_device_address, supported.buffer_device_address, "bufferDeviceAddress (Vulkan 1.2)"),
            (enabled.shader_int64, supported.shader_int64, "shaderInt64"),
        ];
        if let Some((_, _, name)) = required.iter().find(|(on, ..)| !on) {
            return Err(Error::NoDevice(format!("the host's device was created without {name}, which srug needs")));
        }
        let claimed = [
            (enabled.shader_int16, supported.shader_int16, "shaderInt16"),
            (enabled.shader_float16, supported.shader_float16, "shaderFloat16"),
            (enabled.storage_buffer_16bit_access, supported.storage_buffer_16bit_access, "storageBuffer16BitAccess"),
            (enabled.compute_full_subgroups, supported.compute_full_subgroups, "computeFullSubgroups"),
        ];
        if let Some((_, _, name)) = required.iter().chain(&claimed).find(|(on, can, _)| *on && !can) {
            return Err(Error::NoDevice(format!("the host says it enabled {name}, which the device does not support")));
        }
        // SAFETY: as above.
        let index = unsafe { instance.enumerate_physical_devices() }
            .map_err(vk_error("vkEnumeratePhysicalDevices"))?
            .iter()
            .position(|p| *p == physical_device)
            .unwrap_or(0);
        // The host's device: srug does not know which extensions it enabled, so it exports nothing.
        let info = describe(&instance, physical_device, index, queue_family, &enabled, Exports::default());
        let log_box: Option<Box<ValidationLog>> = validation_messages.then(Box::default);
        let debug = match &log_box {
            Some(log) => {
                let user = std::ptr::from_ref::<ValidationLog>(log).cast_mut().cast::<c_void>();
                let info = messenger_create_info(user);
                let loader = ash::ext::debug_utils::Instance::new(&entry, &instance);
                // SAFETY: valid create info; the log outlives the messenger (both live in Shared).
                let messenger = unsafe { loader.create_debug_utils_messenger(&info, None) }.map_err(|e| {
                    Error::MissingComponent(format!(
                        "a debug messenger on the host's instance (is VK_EXT_debug_utils enabled?): {e}"
                    ))
                })?;
                Some((loader, messenger))
            }
            None => None,
        };
        let allocator = new_allocator(&instance, &device, physical_device);
        let allocator = match allocator {
            Ok(a) => a,
            Err(e) => {
                if let Some((loader, messenger)) = &debug {
                    // SAFETY: created above, not used elsewhere.
                    unsafe { loader.destroy_debug_utils_messenger(*messenger, None) };
                }
                return Err(Error::OutOfMemory(format!("creating the allocator: {e}")));
            }
        };
        // SAFETY: the caller vouches that the family has this queue.
        let queue = unsafe { device.get_device_queue(queue_family, queue_index) };
        log::info!("srug on the host's device: {} ({:?}), driver {}", info.name, info.device_type, info.driver);
        Ok(Self::assemble(Parts {
            entry,
            instance,
            debug,
            validation_log: log_box,
            device,
            owns_device: false,
            physical_device,
            queue,
            queue_family,
            allocator,
            info,
        }))
    }

    /// Whether srug created this device (false for [`Device::from_raw`]).
    pub fn owns_vulkan_device(&self) -> bool {
        self.shared.owns_device
    }

    /// Lists the Vulkan devices without creating one.
    pub fn list() -> Result<Vec<AdapterSummary>> {
        let entry = load_entry()?;
        let app = vk::ApplicationInfo::default().api_version(vk::API_VERSION_1_2);
        let create = vk::InstanceCreateInfo::default().application_info(&app);
        // SAFETY: a minimal, valid instance; destroyed below before returning.
        let instance = unsafe { entry.create_instance(&create, None) }.map_err(vk_error("vkCreateInstance"))?;
        // SAFETY: the instance is valid until destroyed at the end of this block.
        let out = unsafe {
            let list = instance.enumerate_physical_devices().map_err(vk_error("vkEnumeratePhysicalDevices"));
            let out = list.map(|pds| {
                pds.iter()
                    .enumerate()
                    .map(|(index, &pd)| {
                        let p = instance.get_physical_device_properties(pd);
                        AdapterSummary {
                            index,
                            name: name_of(&p),
                            device_type: p.device_type,
                            api_version: version_string(p.api_version),
                        }
                    })
                    .collect()
            });
            instance.destroy_instance(None);
            out
        };
        out
    }

    /// Creates a device as `options` say (and the environment, where they are silent).
    pub fn new(options: &DeviceOptions) -> Result<Self> {
        let selection = match &options.selection {
            Some(s) => s.clone(),
            None => std::env::var(DEVICE_ENV).map(|v| DeviceSelection::parse(&v)).unwrap_or_default(),
        };
        let validation = options.validation.or_else(|| env_flag(VALIDATION_ENV)).unwrap_or(false);
        let entry = load_entry()?;

        // Instance, with the validation layer and synchronization validation when asked.
        let mut layers: Vec<*const i8> = Vec::new();
        let mut extensions: Vec<*const i8> = Vec::new();
        if validation {
            // SAFETY: plain enumeration on a loaded entry.
            let available = unsafe { entry.enumerate_instance_layer_properties() }
                .map_err(vk_error("vkEnumerateInstanceLayerProperties"))?;
            if !available.iter().any(|l| l.layer_name_as_c_str().is_ok_and(|n| n == VALIDATION_LAYER)) {
                return Err(Error::MissingComponent(
                    "validation requested but VK_LAYER_KHRONOS_validation is not installed \
                     (Debian package vulkan-validationlayers)"
                        .into(),
                ));
            }
            layers.push(VALIDATION_LAYER.as_ptr());
            extensions.push(ash::ext::debug_utils::NAME.as_ptr());
            extensions.push(ash::ext::validation_features::NAME.as_ptr());
        }
        let log_box: Option<Box<ValidationLog>> = validation.then(Box::default);
        let user_ptr = log_box
            .as_ref()
            .map_or(std::ptr::null_mut(), |b| std::ptr::from_ref::<ValidationLog>(b).cast_mut().cast::<c_void>());
        let mut messenger_info = messenger_create_info(user_ptr);
        let enabled_features = [vk::ValidationFeatureEnableEXT::SYNCHRONIZATION_VALIDATION];
        let mut validation_features =
            vk::ValidationFeaturesEXT::default().enabled_validation_features(&enabled_features);
        let app_name = CString::new("srug").unwrap_or_default();
        let app = vk::ApplicationInfo::default()
            .application_name(&app_name)
            .engine_name(&app_name)
            .api_version(vk::API_VERSION_1_2);
        let mut create = vk::InstanceCreateInfo::default()
            .application_info(&app)
            .enabled_layer_names(&layers)
            .enabled_extension_names(&extensions);
        if validation {
            create = create.push_next(&mut messenger_info).push_next(&mut validation_features);
        }
        // SAFETY: every pointer in `create` refers to locals alive for this call.
        let instance = unsafe { entry.create_instance(&create, None) }.map_err(vk_error("vkCreateInstance"))?;
        let guard = InstanceGuard(&instance);

        let debug = if validation {
            let loader = ash::ext::debug_utils::Instance::new(&entry, &instance);
            let info = vk::DebugUtilsMessengerCreateInfoEXT { p_next: std::ptr::null(), ..messenger_info };
            // SAFETY: valid create info; the user pointer outlives the messenger (both live in Shared).
            let messenger = unsafe { loader.create_debug_utils_messenger(&info, None) }
                .map_err(vk_error("vkCreateDebugUtilsMessengerEXT"))?;
            Some((loader, messenger))
        } else {
            None
        };

        let (physical, index) = match pick_physical(&instance, &selection) {
            Ok(p) => p,
            Err(e) => {
                if let Some((loader, messenger)) = &debug {
                    // SAFETY: created above, not used elsewhere.
                    unsafe { loader.destroy_debug_utils_messenger(*messenger, None) };
                }
                return Err(e);
            }
        };
        let made = make_device(&instance, physical, index);
        let (device, queue, queue_family, info) = match made {
            Ok(m) => m,
            Err(e) => {
                if let Some((loader, messenger)) = &debug {
                    // SAFETY: created above, not used elsewhere.
                    unsafe { loader.destroy_debug_utils_messenger(*messenger, None) };
                }
                return Err(e);
            }
        };
        let allocator = new_allocator(&instance, &device, physical);
        let allocator = match allocator {
            Ok(a) => a,
            Err(e) => {
                // SAFETY: nothing was created from the device yet.
                unsafe { device.destroy_device(None) };
                if let Some((loader, messenger)) = &debug {
                    // SAFETY: created above, not used elsewhere.
                    unsafe { loader.destroy_debug_utils_messenger(*messenger, None) };
                }
                return Err(Error::OutOfMemory(format!("creating the allocator: {e}")));
            }
        };
        std::mem::forget(guard);
        log::info!(
            "srug device #{}: {} ({:?}), driver {}, Vulkan {}, validation {}",
            info.index,
            info.name,
            info.device_type,
            info.driver,
            info.api_version,
            if validation { "on (with synchronization validation)" } else { "off" }
        );
        Ok(Self::assemble(Parts {
            entry,
            instance,
            debug,
            validation_log: log_box,
            device,
            owns_device: true,
            physical_device: physical,
            queue,
            queue_family,
            allocator,
            info,
        }))
    }

    /// What the device is and can do.
    pub fn info(&self) -> &DeviceInfo {
        &self.shared.info
    }

    /// Whether the validation layer is running.
    pub fn validation_enabled(&self) -> bool {
        self.shared.validation_log.is_some()
    }

    /// Takes the validation messages emitted since the last call (warnings and
    /// errors only). Tests fail on any.
    pub fn take_validation_messages(&self) -> Vec<String> {
        self.shared.take_validation_messages()
    }

    /// GPU memory allocated by srug now and at its peak.
    pub fn memory_usage(&self) -> MemoryUsage {
        MemoryUsage {
            current_bytes: self.shared.current_bytes.load(Ordering::Relaxed),
            peak_bytes: self.shared.peak_bytes.load(Ordering::Relaxed),
            pooled_bytes: lock(&self.shared.pool).bytes,
            fresh_allocations: self.shared.fresh_allocations.load(Ordering::Relaxed),
        }
    }

    /// Frees the buffers kept for reuse ([`MemoryUsage::pooled_bytes`]) and
    /// returns how many bytes that released. srug keeps at most an eighth of
    /// the device's largest device-local heap (256 MiB to 4 GiB) of them, and
    /// never so much that in use and kept would pass the most ever in use
    /// (staging buffers: [`POOL_HEADROOM_BYTES`](crate::POOL_HEADROOM_BYTES) more); it
    /// frees them itself when an allocation finds no memory.
    pub fn release_pooled_memory(&self) -> u64 {
        self.shared.drain_pool()
    }

    /// Restarts peak counting from the current usage.
    pub fn reset_peak_memory(&self) {
        let now = self.shared.current_bytes.load(Ordering::Relaxed);
        self.shared.peak_bytes.store(now, Ordering::Relaxed);
    }

    /// Makes one deliberately invalid (but harmless) Vulkan call: a buffer with
    /// no usage flags. Tests use it to prove validation messages are caught.
    #[doc(hidden)]
    pub fn provoke_validation_message(&self) -> Result<()> {
        let info = vk::BufferCreateInfo::default().size(16).usage(vk::BufferUsageFlags::empty());
        // SAFETY: invalid usage on purpose; the driver accepts it and the buffer is destroyed at once.
        unsafe {
            let buffer = self.shared.device.create_buffer(&info, None).map_err(vk_error("vkCreateBuffer"))?;
            self.shared.device.destroy_buffer(buffer, None);
        }
        Ok(())
    }

    /// Waits for all submitted work and frees every resource waiting on it.
    pub fn wait_idle(&self) -> Result<()> {
        let last = lock(&self.shared.tracker).submitted;
        self.shared.maintain(Some(last))
    }
}

/// What a [`Device`] is made of, from [`Device::new`] or [`Device::from_raw`].
struct Parts {
    entry: ash::Entry,
    instance: ash::Instance,
    debug: Option<(ash::ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT)>,
    validation_log: Option<Box<ValidationLog>>,
    device: ash::Device,
    owns_device: bool,
    physical_device: vk::PhysicalDevice,
    queue: vk::Queue,
    queue_family: u32,
    allocator: Allocator,
    info: DeviceInfo,
}

impl Device {
    fn assemble(p: Parts) -> Self {
        // SAFETY: a valid physical device of this instance.
        let memory = unsafe { p.instance.get_physical_device_memory_properties(p.physical_device) };
        let heap = memory.memory_heaps[..memory.memory_heap_count as usize]
            .iter()
            .filter(|h| h.flags.contains(vk::MemoryHeapFlags::DEVICE_LOCAL))
            .map(|h| h.size)
            .max()
            .unwrap_or(0);
        let shared = Arc::new(Shared {
            _entry: p.entry,
            instance: p.instance,
            debug: p.debug,
            validation_log: p.validation_log,
            device: p.device,
            owns_device: p.owns_device,
            physical_device: p.physical_device,
            queue: Mutex::new(p.queue),
            queue_family: p.queue_family,
            allocator: Mutex::new(ManuallyDrop::new(p.allocator)),
            tracker: Mutex::new(Tracker::default()),
            info: p.info,
            current_bytes: AtomicU64::new(0),
            peak_bytes: AtomicU64::new(0),
            high_water_bytes: AtomicU64::new(0),
            fresh_allocations: AtomicU64::new(0),
            pool: Mutex::new(BufferPool::new(pool_limit(heap))),
            kernel_cache: Mutex::new(HashMap::new()),
        });
        Self { _cache_owner: Arc::new(CacheOwner(shared.clone())), shared }
    }
}

/// The debug messenger srug listens with: warnings, errors and info of every
/// type, into the [`ValidationLog`] at `user`.
fn messenger_create_info(user: *mut c_void) -> vk::DebugUtilsMessengerCreateInfoEXT<'static> {
    vk::DebugUtilsMessengerCreateInfoEXT::default()
        .message_severity(
            vk::DebugUtilsMessageSeverityFlagsEXT::WARNING
                | vk::DebugUtilsMessageSeverityFlagsEXT::ERROR
                | vk::DebugUtilsMessageSeverityFlagsEXT::INFO,
        )
        .message_type(
            vk::DebugUtilsMessageTypeFlagsEXT::GENERAL
                | vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION
                | vk::DebugUtilsMessageTypeFlagsEXT::PERFORMANCE,
        )
        .pfn_user_callback(Some(on_validation_message))
        .user_data(user)
}

/// srug's memory allocator on `device` (buffer device addresses on).
fn new_allocator(
    instance: &ash::Instance,
    device: &ash::Device,
    physical_device: vk::PhysicalDevice,
) -> std::result::Result<Allocator, gpu_allocator::AllocationError> {
    Allocator::new(&AllocatorCreateDesc {
        instance: instance.clone(),
        device: device.clone(),
        physical_device,
        debug_settings: Default::default(),
        buffer_device_address: true,
        allocation_sizes: Default::default(),
    })
}

/// Destroys the instance if device creation fails half-way.
struct InstanceGuard<'a>(&'a ash::Instance);

impl Drop for InstanceGuard<'_> {
    fn drop(&mut self) {
        // SAFETY: only reached on an error path, before anything else owns the instance.
        unsafe { self.0.destroy_instance(None) };
    }
}

fn pick_physical(instance: &ash::Instance, selection: &DeviceSelection) -> Result<(vk::PhysicalDevice, usize)> {
    // SAFETY: valid instance.
    let devices = unsafe { instance.enumerate_physical_devices() }.map_err(vk_error("vkEnumeratePhysicalDevices"))?;
    let props: Vec<_> = devices
        .iter()
        // SAFETY: handles come from the enumeration above.
        .map(|&pd| unsafe { instance.get_physical_device_properties(pd) })
        .collect();
    let usable = |i: usize| props[i].api_version >= vk::API_VERSION_1_2;
    let listing = || {
        props
            .iter()
            .enumerate()
            .map(|(i, p)| format!("#{i} {} ({:?})", name_of(p), p.device_type))
            .collect::<Vec<_>>()
            .join(", ")
    };
    if devices.is_empty() {
        return Err(Error::NoDevice("no Vulkan device found (install mesa-vulkan-drivers for lavapipe)".into()));
    }
    let chosen = match selection {
        DeviceSelection::Auto => {
            (0..devices.len()).filter(|&i| usable(i)).min_by_key(|&i| (type_rank(props[i].device_type), i))
        }
        DeviceSelection::Gpu => (0..devices.len()).find(|&i| usable(i) && type_rank(props[i].device_type) <= 1),
        DeviceSelection::Cpu => {
            (0..devices.len()).find(|&i| usable(i) && props[i].device_type == vk::PhysicalDeviceType::CPU)
        }
        DeviceSelection::Index(n) => (*n < devices.len()).then_some(*n),
        DeviceSelection::Name(s) => {
            let s = s.to_lowercase();
            (0..devices.len()).find(|&i| name_of(&props[i]).to_lowercase().contains(&s))
        }
    };
    let i = chosen.ok_or_else(|| Error::NoDevice(format!("{selection} matches none of: {}", listing())))?;
    if !usable(i) {
        return Err(Error::NoDevice(format!(
            "#{i} {} supports only Vulkan {}; srug needs 1.2",
            name_of(&props[i]),
            version_string(props[i].api_version)
        )));
    }
    Ok((devices[i], i))
}

/// The compute queue family srug picks on `physical`: one with timestamps where there is one.
fn compute_family(instance: &ash::Instance, physical: vk::PhysicalDevice) -> Result<u32> {
    // SAFETY: `physical` comes from this instance.
    let families = unsafe { instance.get_physical_device_queue_family_properties(physical) };
    families
        .iter()
        .position(|f| f.queue_flags.contains(vk::QueueFlags::COMPUTE) && f.timestamp_valid_bits > 0)
        .or_else(|| families.iter().position(|f| f.queue_flags.contains(vk::QueueFlags::COMPUTE)))
        .map(|f| f as u32)
        .ok_or_else(|| Error::NoDevice("the device has no compute queue".into()))
}

/// Whether `physical` offers `VK_EXT_subgroup_size_control` (srug's
/// instance is Vulkan 1.2, so the extension's structure is how it reaches
/// `computeFullSubgroups`).
fn has_subgroup_size_control(instance: &ash::Instance, physical: vk::PhysicalDevice) -> bool {
    // SAFETY: valid physical device.
    let extensions = unsafe { instance.enumerate_device_extension_properties(physical) }.unwrap_or_default();
    extensions.iter().any(|e| e.extension_name_as_c_str() == Ok(ash::ext::subgroup_size_control::NAME))
}

/// What `physical` supports of the features srug uses.
fn supported_features(instance: &ash::Instance, physical: vk::PhysicalDevice) -> EnabledFeatures {
    let mut f11 = vk::PhysicalDeviceVulkan11Features::default();
    let mut f12 = vk::PhysicalDeviceVulkan12Features::default();
    let mut size_control = vk::PhysicalDeviceSubgroupSizeControlFeatures::default();
    let mut features = vk::PhysicalDeviceFeatures2::default().push_next(&mut f11).push_next(&mut f12);
    let size_control_known = has_subgroup_size_control(instance, physical);
    if size_control_known {
        features = features.push_next(&mut size_control);
    }
    // SAFETY: valid physical device and feature chain (the extension's
    // structure only where the device offers the extension).
    unsafe { instance.get_physical_device_features2(physical, &mut features) };
    let base = features.features;
    EnabledFeatures {
        buffer_device_address: f12.buffer_device_address == vk::TRUE,
        shader_int64: base.shader_int64 == vk::TRUE,
        shader_int16: base.shader_int16 == vk::TRUE,
        shader_float16: f12.shader_float16 == vk::TRUE,
        storage_buffer_16bit_access: f11.storage_buffer16_bit_access == vk::TRUE,
        compute_full_subgroups: size_control_known && size_control.compute_full_subgroups == vk::TRUE,
    }
}

/// The [`DeviceInfo`] of `physical` (enumeration index `index`) used through
/// queue family `family` with `enabled` features.
fn describe(
    instance: &ash::Instance,
    physical: vk::PhysicalDevice,
    index: usize,
    family: u32,
    enabled: &EnabledFeatures,
    exports: Exports,
) -> DeviceInfo {
    // SAFETY: `physical` comes from this instance.
    let families = unsafe { instance.get_physical_device_queue_family_properties(physical) };
    let family_timestamps = families.get(family as usize).map_or(0, |f| f.timestamp_valid_bits);
    let mut driver = vk::PhysicalDeviceDriverProperties::default();
    let mut subgroup = vk::PhysicalDeviceSubgroupProperties::default();
    let mut ids = vk::PhysicalDeviceIDProperties::default();
    let mut props2 =
        vk::PhysicalDeviceProperties2::default().push_next(&mut driver).push_next(&mut subgroup).push_next(&mut ids);
    // SAFETY: valid physical device and property chain.
    unsafe { instance.get_physical_device_properties2(physical, &mut props2) };
    let props = props2.properties;
    let limits = props.limits;
    DeviceInfo {
        index,
        name: name_of(&props),
        driver: format!(
            "{} {}",
            driver.driver_name_as_c_str().map(|c| c.to_string_lossy().into_owned()).unwrap_or_default(),
            driver.driver_info_as_c_str().map(|c| c.to_string_lossy().into_owned()).unwrap_or_default()
        ),
        driver_id: driver.driver_id,
        device_type: props.device_type,
        api_version: version_string(props.api_version),
        max_storage_buffer_range: u64::from(limits.max_storage_buffer_range),
        max_shared_memory: limits.max_compute_shared_memory_size,
        max_workgroup_count: limits.max_compute_work_group_count,
        max_workgroup_size: limits.max_compute_work_group_size,
        max_workgroup_invocations: limits.max_compute_work_group_invocations,
        subgroup_size: subgroup.subgroup_size,
        full_subgroups: enabled.compute_full_subgroups,
        subgroup_ballot: subgroup.supported_stages.contains(vk::ShaderStageFlags::COMPUTE)
            && subgroup
                .supported_operations
                .contains(vk::SubgroupFeatureFlags::BASIC | vk::SubgroupFeatureFlags::BALLOT),
        subgroup_shuffle: subgroup.supported_stages.contains(vk::ShaderStageFlags::COMPUTE)
            && subgroup.supported_operations.contains(vk::SubgroupFeatureFlags::SHUFFLE),
        timestamp_period_ns: f64::from(limits.timestamp_period),
        timestamp_valid_bits: if limits.timestamp_compute_and_graphics == vk::TRUE { family_timestamps } else { 0 },
        shader_float16: enabled.shader_float16,
        storage_16bit: enabled.storage_buffer_16bit_access && enabled.shader_int16,
        max_texel_buffer_elements: u64::from(limits.max_texel_buffer_elements),
        min_texel_buffer_offset_alignment: limits.min_texel_buffer_offset_alignment.max(1),
        texel_formats: TexelFormat::ALL
            .into_iter()
            .filter(|f| {
                // SAFETY: valid physical device.
                let props = unsafe { instance.get_physical_device_format_properties(physical, f.vk()) };
                props.buffer_features.contains(vk::FormatFeatureFlags::UNIFORM_TEXEL_BUFFER)
            })
            .collect(),
        external_memory_fd: exports.memory_fd,
        external_semaphore_fd: exports.semaphore_fd,
        device_uuid: ids.device_uuid,
        driver_uuid: ids.driver_uuid,
    }
}

/// The fd exports srug enabled on a device it created.
#[derive(Clone, Copy, Debug, Default)]
struct Exports {
    memory_fd: bool,
    semaphore_fd: bool,
}

/// Which of the fd export extensions `physical` offers.
fn supported_exports(instance: &ash::Instance, physical: vk::PhysicalDevice) -> Exports {
    // SAFETY: valid physical device.
    let extensions = unsafe { instance.enumerate_device_extension_properties(physical) }.unwrap_or_default();
    let has = |name: &std::ffi::CStr| extensions.iter().any(|e| e.extension_name_as_c_str() == Ok(name));
    Exports {
        memory_fd: has(ash::khr::external_memory_fd::NAME),
        semaphore_fd: has(ash::khr::external_semaphore_fd::NAME),
    }
}

fn make_device(
    instance: &ash::Instance,
    physical: vk::PhysicalDevice,
    index: usize,
) -> Result<(ash::Device, vk::Queue, u32, DeviceInfo)> {
    let family = compute_family(instance, physical)?;
    let supported = supported_features(instance, physical);
    if !supported.buffer_device_address {
        return Err(Error::NoDevice("the device lacks bufferDeviceAddress, which srug needs for large scenes".into()));
    }
    let exports = supported_exports(instance, physical);
    let info = describe(instance, physical, index, family, &supported, exports);
    let mut extensions = Vec::new();
    if exports.memory_fd {
        extensions.push(ash::khr::external_memory_fd::NAME.as_ptr());
    }
    if exports.semaphore_fd {
        extensions.push(ash::khr::external_semaphore_fd::NAME.as_ptr());
    }
    if supported.compute_full_subgroups {
        extensions.push(ash::ext::subgroup_size_control::NAME.as_ptr());
    }
    let priorities = [1.0f32];
    let queue_info = [vk::DeviceQueueCreateInfo::default().queue_family_index(family).queue_priorities(&priorities)];
    let mut en11 = vk::PhysicalDeviceVulkan11Features::default()
        .storage_buffer16_bit_access(supported.storage_buffer_16bit_access);
    let mut en12 = vk::PhysicalDeviceVulkan12Features::default()
        .buffer_device_address(true)
        .shader_float16(supported.shader_float16);
    let mut en_size_control = vk::PhysicalDeviceSubgroupSizeControlFeatures::default().compute_full_subgroups(true);
    let en_base =
        vk::PhysicalDeviceFeatures::default().shader_int64(supported.shader_int64).shader_int16(supported.shader_int16);
    let mut create = vk::DeviceCreateInfo::default()
        .queue_create_infos(&queue_info)
        .enabled_extension_names(&extensions)
        .enabled_features(&en_base)
        .push_next(&mut en11)
        .push_next(&mut en12);
    if supported.compute_full_subgroups {
        create = create.push_next(&mut en_size_control);
    }
    // SAFETY: features were checked as supported; pointers refer to locals.
    let device = unsafe { instance.create_device(physical, &create, None) }.map_err(vk_error("vkCreateDevice"))?;
    // SAFETY: queue 0 of the family requested above.
    let queue = unsafe { device.get_device_queue(family, 0) };
    Ok((device, queue, family, info))
}
