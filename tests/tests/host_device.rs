//! srug on a host application's Vulkan device (`Device::from_raw`): the host
//! creates its own instance (validation and synchronization validation on)
//! and device, srug renders on them exactly as on a device of its own, and
//! after srug is dropped the host's device is still the host's, working, with
//! nothing of srug's left on it (the host's own messenger hears no validation
//! message, leaks at vkDestroyDevice included). Missing features and wrong
//! queues are refused with their names; a device without full subgroups
//! sorts without block digits, which refuse it by name.

#![allow(clippy::unwrap_used, clippy::expect_used, reason = "a failed unwrap is a failed test")]

use srug::gpu::{Device, EnabledFeatures, RawVulkan};
use srug::primitives::sort::{block_digits_supported, default_sort_digits, RadixSort, SortDigits};
use srug::scene::activate::GpuScene;
use srug::scene::demo::{demo_city, DemoOptions};
use srug::splat::{Channels, SplatSettings, Splatter};
use srug_tests::host_vulkan::{host, host_with};
use srug_tests::{assert_no_validation_messages, device};

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
    let own_device = device();
    let own = render(&own_device);
    let h = host(true);
    {
        // SAFETY: the host's handles belong together and outlive srug's device.
        let shared = unsafe { Device::from_raw(h.raw()) }.unwrap();
        assert!(!shared.owns_vulkan_device());
        assert_eq!(shared.info().name, own_device.info().name, "the host's physical device");
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
    // One past the family's queues (1 on lavapipe, 16 on an H100's family 0).
    // SAFETY: valid handles.
    let families = unsafe { h.instance.get_physical_device_queue_family_properties(h.physical) };
    let past = families[h.family as usize].queue_count;
    let wrong_queue = RawVulkan { queue_index: past, ..h.raw() };
    // SAFETY: as above.
    let e = unsafe { Device::from_raw(wrong_queue) }.err().map(|e| e.to_string()).unwrap_or_default();
    assert!(e.contains(&format!("queue {past} of family")), "{e}");
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

/// Block sort digits place keys by subgroup index, which Vulkan fixes only
/// for pipelines built with full subgroups: on a host device without
/// `computeFullSubgroups` they are refused by name (and never the default),
/// on one with it they sort, with no validation message either way. (The
/// layer reports the flag without the feature on srug's own device,
/// VUID-VkPipelineShaderStageCreateInfo-flags-02785, but was seen silent on a
/// host's; the refusal here is srug's own check.)
#[test]
fn block_sort_digits_need_full_subgroups_on_a_host_device() {
    let keys: Vec<[u32; 2]> = (0..5000u32).map(|i| [i.wrapping_mul(2_654_435_761) >> 4, 0]).collect();
    let mut want: Vec<u32> = (0..keys.len() as u32).collect();
    want.sort_by_key(|&i| keys[i as usize][0]); // std's stable sort
    for full in [false, true] {
        let h = host_with(true, full);
        {
            // SAFETY: the host's handles belong together and outlive srug's device.
            let shared = unsafe { Device::from_raw(h.raw()) }.unwrap();
            assert_eq!(shared.info().full_subgroups, full, "as the host enabled it");
            assert_eq!(block_digits_supported(shared.info()), full, "block digits only with full subgroups");
            let mut sort = RadixSort::with_items(&shared, 64).unwrap();
            let chosen = sort.set_digits(&shared, SortDigits::Block);
            if full {
                chosen.unwrap();
                sort.reserve(&shared, keys.len() as u64).unwrap();
                let kb = shared.upload("keys", &keys).unwrap();
                let values: Vec<u32> = (0..keys.len() as u32).collect();
                let vb = shared.upload("values", &values).unwrap();
                shared.run(|rec| sort.record(rec, &kb, &vb, keys.len() as u64, 28)).unwrap();
                let got: Vec<u32> = shared.read_buffer(&vb).unwrap();
                assert_eq!(got, want, "block digits on the host's device: the stable order");
            } else {
                let e = chosen.err().map(|e| e.to_string()).unwrap_or_default();
                assert!(e.contains("computeFullSubgroups enabled (here: no)"), "{e}");
                assert_ne!(default_sort_digits(shared.info()), SortDigits::Block);
            }
            assert_no_validation_messages(&shared);
        }
        let heard = h.finish();
        assert!(heard.is_empty(), "the host's messenger heard: {heard:?}");
    }
}
