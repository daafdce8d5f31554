//! srug on a host application's Vulkan device (`Device::from_raw`): the host
//! creates its own instance (validation and synchronization validation on)
//! and device, srug renders on them exactly as on a device of its own, and
//! after srug is dropped the host's device is still the host's, working, with
//! nothing of srug's left on it (the host's own messenger hears no validation
//! message, leaks at vkDestroyDevice included). Missing features and wrong
//! queues are refused with their names.

#![allow(clippy::unwrap_used, clippy::expect_used, reason = "a failed unwrap is a failed test")]

use std::ffi::c_void;
use std::sync::Mutex;

use srug::gpu::ash::{self, vk};
use srug::gpu::{Device, EnabledFeatures, RawVulkan};
use srug::scene::activate::GpuScene;
use srug::scene::demo::{demo_city, DemoOptions};
use srug::splat::{Channels, SplatSettings, Splatter};
use srug_tests::{assert_no_validation_messages, device};

/// The host's own debug messenger: warnings and errors into the `Mutex<Vec<String>>` at `user`.
unsafe extern "system" fn hear(
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
struct Host {
    entry: ash::Entry,
    instance: ash::Instance,
    messenger: (ash::ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT),
    /// What the messenger heard (its user data; boxed so it does not move).
    heard: Box<Mutex<Vec<String>>>,
    physical: vk::PhysicalDevice,
    device: ash::Device,
    family: u32,
    enabled: EnabledFeatures,
}

fn host(enable_bda: bool) -> Host {
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
    let mut v12 = vk::PhysicalDeviceVulkan12Features::default().buffer_device_address(enable_bda);
    let base = vk::PhysicalDeviceFeatures::default().shader_int64(true);
    let create =
        vk::DeviceCreateInfo::default().queue_create_infos(&queues).enabled_features(&base).push_next(&mut v12);
    // SAFETY: valid create info; lavapipe supports these features.
    let device = unsafe { instance.create_device(physical, &create, None) }.unwrap();
    let enabled =
        EnabledFeatures { buffer_device_address: enable_bda, shader_int64: true, ..EnabledFeatures::default() };
    Host { entry, instance, messenger, heard, physical, device, family, enabled }
}

impl Host {
    fn raw(&self) -> RawVulkan {
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
    fn finish(self) -> Vec<String> {
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

#[test]
fn srug_renders_on_a_host_device_as_on_its_own_and_leaves_it_to_the_host() {
    let city = demo_city(&DemoOptions { gaussians: 20_000, ..DemoOptions::default() }).unwrap();
    let camera = city.cameras[0].resized(176, 48);
    let settings =
        SplatSettings { channels: Channels { depth: true, ..Channels::default() }, ..SplatSettings::default() };
    let render = |d: &Device| {
        let scene = GpuScene::upload(d, &city.scene).unwrap();
        let mut splatter = Splatter::new(d).unwrap();
        let (g, _) = splatter.render(&scene, &camera, &settings).unwrap();
        g.read(d).unwrap()
    };
    let own = render(&device());
    let h = host(true);
    {
        // SAFETY: the host's handles belong together and outlive srug's device.
        let shared = unsafe { Device::from_raw(h.raw()) }.unwrap();
        assert!(!shared.owns_vulkan_device());
        assert!(shared.info().name.contains("llvmpipe"), "{}", shared.info().name);
        let on_host = render(&shared);
        assert_eq!(on_host, own, "the same frame on the host's device and on srug's own");
        assert_no_validation_messages(&shared);
        // srug's messenger on the host's instance reports validation messages (so would the host's).
        shared.provoke_validation_message().unwrap();
        assert!(!shared.take_validation_messages().is_empty(), "a messenger on the host's instance");
        h.heard.lock().unwrap_or_else(|p| p.into_inner()).clear();
        let again = render(&shared);
        assert_eq!(again, own);
        assert_no_validation_messages(&shared);
    }
    let heard = h.finish();
    assert!(heard.is_empty(), "the host's messenger heard: {heard:?}");
}

#[test]
fn a_host_device_without_what_srug_needs_is_refused_by_name() {
    let h = host(false);
    // SAFETY: valid handles; from_raw refuses before using the device.
    let e = unsafe { Device::from_raw(h.raw()) }.err().map(|e| e.to_string()).unwrap_or_default();
    assert!(e.contains("bufferDeviceAddress"), "{e}");
    let wrong_family = RawVulkan { queue_family: 99, ..h.raw() };
    // SAFETY: as above.
    let e = unsafe { Device::from_raw(wrong_family) }.err().map(|e| e.to_string()).unwrap_or_default();
    assert!(e.contains("queue family 99"), "{e}");
    let wrong_queue = RawVulkan { queue_index: 5, ..h.raw() };
    // SAFETY: as above.
    let e = unsafe { Device::from_raw(wrong_queue) }.err().map(|e| e.to_string()).unwrap_or_default();
    assert!(e.contains("queue 5"), "{e}");
    let overclaimed = RawVulkan {
        enabled: EnabledFeatures { buffer_device_address: true, shader_int64: false, ..EnabledFeatures::default() },
        ..h.raw()
    };
    // SAFETY: as above.
    let e = unsafe { Device::from_raw(overclaimed) }.err().map(|e| e.to_string()).unwrap_or_default();
    assert!(e.contains("shaderInt64"), "{e}");
    let heard = h.finish();
    assert!(heard.is_empty(), "the host's messenger heard: {heard:?}");
}
