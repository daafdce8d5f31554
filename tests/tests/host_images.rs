//! Relit frames written into a host's own images on the host's device
//! (`Relighter::render_to_host`): the host uploads its colour and depth
//! (a tilted "mesh" across the street, empty elsewhere) and signals a
//! semaphore; srug waits on it, hides the splats behind the host's depth,
//! blends the rest over the host's colour, writes depth and colour into the
//! images and signals another, which the host's read-back waits on. Every
//! texel is checked against the CPU twin (`pack_cpu`) of a frame rendered
//! through the host-memory path (`Relighter::set_host_depth`), in every colour
//! format, with binary and timeline semaphores, without compositing too; the
//! host's messenger and srug's hear nothing. Misstated images are refused.

#![allow(clippy::unwrap_used, clippy::expect_used, reason = "a failed unwrap is a failed test")]

use srug::frame::host_images::{decode_texels, pack_cpu, FrameChannel, FrameValues, HostTargets};
use srug::frame::{HostDepthImage, RelightSettings, Relighter};
use srug::gpu::ash::vk;
use srug::gpu::{Device, HostBuffer, HostImage, HostImageFormat, HostSync, SemaphoreSignal, SemaphoreWait};
use srug::scene::activate::GpuScene;
use srug::scene::demo::{demo_city, DemoOptions};
use srug::scene::{Camera, Scene};
use srug::shade::{BrdfLut, BrdfTable, EnvironmentPrep, PrepareSettings, PreparedEnvironment, ProceduralSky};
use srug::shadow::Sun;
use srug::splat::{Channel, HostDepth};
use srug_tests::assert_no_validation_messages;
use srug_tests::host_vulkan::{host, Host, OwnImage};

const SIZE: (u32, u32) = (176, 48);
const NEAR: f32 = 0.1;
const FAR: f32 = 500.0;

/// The scene and light of every frame here.
struct Inputs {
    scene: Scene,
    gpu: GpuScene,
    camera: Camera,
    sun: Sun,
    env: PreparedEnvironment,
    brdf: BrdfTable,
}

impl Inputs {
    /// `Relighter::render_to_host` of the camera under the sun.
    fn render_to_host(
        &self,
        relighter: &mut Relighter,
        settings: &RelightSettings,
        targets: &HostTargets,
    ) -> srug::Result<srug::frame::RelitFrame> {
        let bounds = self.scene.bounds().unwrap();
        let attributes = self.scene.attributes();
        relighter.render_to_host(
            &self.gpu,
            &attributes,
            &bounds,
            &self.camera,
            Some(&self.sun),
            &self.env,
            &self.brdf,
            settings,
            targets,
        )
    }
}

/// Targets that write `colour` alone, no semaphores.
fn colour_only(colour: HostImage) -> HostTargets {
    HostTargets {
        colour: Some(colour),
        depth: None,
        depth_convention: HostDepth::CameraZ,
        composite: false,
        buffers: Vec::new(),
        sync: HostSync::default(),
    }
}

/// RGBA32F texels `got` must be `frame`'s radiance and (clamped) alpha, bit for bit.
fn assert_texels_are_the_frame(d: &Device, got: &[f32], frame: &srug::frame::RelitFrame) {
    let radiance: Vec<f32> = d.read_buffer(&frame.shaded.radiance).unwrap();
    let alpha: Vec<f32> = d.read_buffer(&frame.gbuffer.alpha).unwrap();
    for (p, texel) in got.chunks_exact(4).enumerate() {
        let expected = [radiance[3 * p], radiance[3 * p + 1], radiance[3 * p + 2], alpha[p].clamp(0.0, 1.0)];
        assert_eq!(texel, expected, "pixel {p}");
    }
}

fn inputs(d: &Device) -> Inputs {
    let city = demo_city(&DemoOptions { gaussians: 20_000, ..DemoOptions::default() }).unwrap();
    let camera = city.cameras[0].resized(SIZE.0, SIZE.1);
    let gpu = GpuScene::upload(d, &city.scene).unwrap();
    let sun = Sun::from_azimuth_elevation(260.0, 50.0, [std::f32::consts::PI; 3]).unwrap();
    let prep = EnvironmentPrep::new(d).unwrap();
    let brdf = prep.brdf_table(BrdfLut::Karis, 65, 256).unwrap();
    let sky = ProceduralSky::new(sun.direction, sun.intensity[0]);
    let env = prep.prepare(&sky.render().unwrap(), &PrepareSettings::default()).unwrap();
    Inputs { scene: city.scene, gpu, camera, sun, env, brdf }
}

/// The host's "mesh": a plane tilted across the middle half of the frame,
/// from 4 m on its left to 40 m on its right (Vulkan depth), nothing elsewhere.
fn host_depth_values() -> Vec<f32> {
    let convention = HostDepth::Vulkan { near: NEAR, far: FAR };
    let (w, h) = (SIZE.0 as usize, SIZE.1 as usize);
    (0..w * h)
        .map(|p| {
            let x = p % w;
            if (w / 4..3 * w / 4).contains(&x) {
                let z = 4.0 + 36.0 * (x - w / 4) as f64 / (w / 2) as f64;
                let (n, f) = (f64::from(NEAR), f64::from(FAR));
                let d = (f * (z - n) / (z * (f - n))) as f32;
                assert!(convention.camera_z(f64::from(d)).is_finite());
                d
            } else {
                1.0
            }
        })
        .collect()
}

/// The host's colour in `format`: a gradient, opaque where the mesh is, and
/// a half-transparent tint elsewhere.
fn host_colour_bytes(format: HostImageFormat) -> Vec<u8> {
    let (w, h) = (SIZE.0 as usize, SIZE.1 as usize);
    let mut out = Vec::new();
    for p in 0..w * h {
        let (x, y) = (p % w, p / w);
        let rgba =
            [x as f32 / w as f32, y as f32 / h as f32, 0.3, if (w / 4..3 * w / 4).contains(&x) { 1.0 } else { 0.5 }];
        match format {
            HostImageFormat::Rgba8Unorm | HostImageFormat::Rgba8Srgb => {
                out.extend(rgba.map(|v| (v * 255.0).round() as u8));
            }
            HostImageFormat::Bgra8Unorm | HostImageFormat::Bgra8Srgb => {
                out.extend([rgba[2], rgba[1], rgba[0], rgba[3]].map(|v| (v * 255.0).round() as u8));
            }
            HostImageFormat::Rgba16Float => {
                out.extend(rgba.iter().flat_map(|v| half::f16::from_f32(*v * 4.0).to_le_bytes()));
            }
            HostImageFormat::Rgba32Float => out.extend(rgba.iter().flat_map(|v| (v * 4.0).to_le_bytes())),
            HostImageFormat::R32Float | HostImageFormat::D32Float => unreachable!("a colour format"),
        }
    }
    out
}

/// The frame through the host-memory path: premultiplied over black behind
/// the host's depth (compositing) or over the sky; colour, alpha, median depth.
/// The settings of these frames: the defaults with centre depths, for the check
/// that splats behind the mesh are hidden, which reads the unoccluded frame's
/// median depth (with surface depths a later splat can lie nearer at a pixel
/// than the median's; occluded surface depths are checked against the twin in
/// tests/splat.rs).
fn frame_settings() -> RelightSettings {
    let mut settings = RelightSettings::default();
    settings.shadow.surface_depth = false;
    settings
}

fn reference(d: &Device, i: &Inputs, composite: bool) -> (Vec<f32>, Vec<f32>, Vec<f32>) {
    let mut settings = frame_settings();
    settings.extra_channels.median_depth = true;
    let mut relighter = Relighter::new(d).unwrap();
    if composite {
        settings.shade.background = srug::shade::Background::Color([0.0; 3]);
        let buffer = d.upload("host depth", &host_depth_values()).unwrap();
        let convention = HostDepth::Vulkan { near: NEAR, far: FAR };
        let image = HostDepthImage { buffer, width: SIZE.0, height: SIZE.1, convention };
        relighter.set_host_depth(Some(image)).unwrap();
    }
    let bounds = i.scene.bounds().unwrap();
    let f = relighter
        .render(&i.gpu, &i.scene.attributes(), &bounds, &i.camera, Some(&i.sun), &i.env, &i.brdf, &settings)
        .unwrap();
    let median = f.gbuffer.get(Channel::MedianDepth).unwrap();
    (
        d.read_buffer(&f.shaded.radiance).unwrap(),
        d.read_buffer(&f.gbuffer.alpha).unwrap(),
        d.read_buffer(median).unwrap(),
    )
}

/// Largest difference allowed between a texel's channel and the twin's.
fn tolerance(format: HostImageFormat, expected: f64) -> f64 {
    match format {
        HostImageFormat::Rgba16Float => 1e-3 * expected.abs() + 1e-4,
        HostImageFormat::Rgba32Float | HostImageFormat::R32Float | HostImageFormat::D32Float => {
            1e-5 * expected.abs() + 1e-6
        }
        _ => 1.0 / 255.0 + 1e-9,
    }
}

fn compare(format: HostImageFormat, got: &[u8], expected: &[[f64; 4]], what: &str) {
    let got = decode_texels(format, got);
    assert_eq!(got.len(), expected.len(), "{what}");
    let channels = if format.is_single_channel() { 1 } else { 4 };
    let eight_bit = format.texel_bytes() == 4 && !format.is_single_channel();
    let mut worst = 0.0f64;
    for (p, (g, e)) in got.iter().zip(expected).enumerate() {
        for k in 0..channels {
            let e = if eight_bit { e[k].clamp(0.0, 1.0) } else { e[k] };
            let diff = (g[k] - e).abs();
            worst = worst.max(diff);
            assert!(diff <= tolerance(format, e), "{what}: pixel {p} channel {k}: {} against the twin's {e}", g[k]);
        }
    }
    println!("{what}: worst difference {worst:.3e}");
}

struct Case {
    format: HostImageFormat,
    composite: bool,
    timeline: bool,
}

#[allow(clippy::too_many_lines, reason = "one frame's whole exchange between host and srug, in order")]
fn run_case(h: &Host, shared: &Device, i: &Inputs, relighter: &mut Relighter, case: &Case) {
    let what = format!("{:?}, composite {}, timeline {}", case.format, case.composite, case.timeline);
    let usage = vk::ImageUsageFlags::TRANSFER_SRC | vk::ImageUsageFlags::TRANSFER_DST;
    let colour = h.create_image(case.format.vk(), SIZE, usage | vk::ImageUsageFlags::COLOR_ATTACHMENT);
    let depth = h.create_image(vk::Format::D32_SFLOAT, SIZE, usage | vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT);
    let host_colour = host_colour_bytes(case.format);
    let host_depth: Vec<u8> = host_depth_values().iter().flat_map(|v| v.to_le_bytes()).collect();
    let (ready, done) = if case.timeline {
        let t = h.semaphore(Some(0));
        (t, t)
    } else {
        (h.semaphore(None), h.semaphore(None))
    };
    let (ready_value, done_value) = if case.timeline { (1, 2) } else { (0, 0) };
    let colour_layout = vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL;
    let depth_layout = vk::ImageLayout::DEPTH_STENCIL_ATTACHMENT_OPTIMAL;
    if case.composite {
        h.upload_image(&colour, &host_colour, colour_layout, &[]);
        h.upload_image(&depth, &host_depth, depth_layout, &[(ready, ready_value)]);
    } else {
        // Nothing to read: a sentinel (255 bytes, NaN floats) srug must overwrite;
        // 8-bit images are stated as undefined (contents discarded).
        h.upload_image(&colour, &vec![0xff; host_colour.len()], colour_layout, &[]);
        h.upload_image(&depth, &vec![0xff; host_depth.len()], depth_layout, &[(ready, ready_value)]);
    }
    let discard = !case.composite && case.format.texel_bytes() == 4;
    let stated = |image: &OwnImage, format: vk::Format, layout| HostImage {
        image: image.image,
        format,
        width: SIZE.0,
        height: SIZE.1,
        usage,
        layout_before: if discard { vk::ImageLayout::UNDEFINED } else { layout },
        layout_after: vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
    };
    let targets = HostTargets {
        colour: Some(stated(&colour, case.format.vk(), colour_layout)),
        depth: Some(stated(&depth, vk::Format::D32_SFLOAT, depth_layout)),
        depth_convention: HostDepth::Vulkan { near: NEAR, far: FAR },
        composite: case.composite,
        buffers: Vec::new(),
        sync: HostSync {
            wait: vec![SemaphoreWait { semaphore: ready, value: ready_value }],
            signal: vec![SemaphoreSignal { semaphore: done, value: done_value }],
        },
    };
    let settings = frame_settings();
    let frame = i.render_to_host(relighter, &settings, &targets).unwrap();
    assert!(frame.timings.get("host images write").is_some(), "{what}: {:?}", frame.timings);
    let after = vk::ImageLayout::TRANSFER_SRC_OPTIMAL;
    let got_colour = h.download_image(&colour, host_colour.len(), after, &[(done, done_value)]);
    let got_depth = h.download_image(&depth, host_depth.len(), after, &[]);
    assert_no_validation_messages(shared);

    let (c, a, m) = reference(shared, i, case.composite);
    let values = FrameValues {
        colour: &c,
        alpha: &a,
        median_depth: &m,
        display: Some((settings.shade.exposure_ev, settings.shade.tone_map)),
    };
    let convention = targets.depth_convention;
    let host_c = case.composite.then_some(&host_colour[..]);
    let host_d = case.composite.then_some(&host_depth[..]);
    compare(case.format, &got_colour, &pack_cpu(case.format, &values, convention, host_c), &format!("colour, {what}"));
    let expected_depth = pack_cpu(HostImageFormat::D32Float, &values, convention, host_d);
    compare(HostImageFormat::D32Float, &got_depth, &expected_depth, &format!("depth, {what}"));
    if case.composite {
        // Against the unoccluded frame: where its coverage crosses c (its median
        // depth's coverage, the shadow receivers') well behind the mesh, the
        // splats in front cover less than c; well in front of it, at least c.
        let (_, _, m0) = reference(shared, i, false);
        let c = frame_settings().shadow.receiver_coverage;
        let convention = HostDepth::Vulkan { near: NEAR, far: FAR };
        let host_z: Vec<f64> = host_depth_values().iter().map(|&v| convention.camera_z(f64::from(v))).collect();
        let mesh = |p: usize| host_z[p].is_finite();
        let behind: Vec<usize> = (0..a.len()).filter(|&p| mesh(p) && f64::from(m0[p]) > host_z[p] + 1.0).collect();
        let front: Vec<usize> =
            (0..a.len()).filter(|&p| mesh(p) && m0[p] > 0.0 && f64::from(m0[p]) < host_z[p] - 1.0).collect();
        let hidden = behind.iter().filter(|&&p| a[p] < c).count();
        let kept = front.iter().filter(|&&p| a[p] >= c).count();
        println!("{what}: hidden {hidden} of {} behind, kept {kept} of {} in front", behind.len(), front.len());
        assert!(behind.len() > 500 && front.len() > 100, "{what}: the mesh cuts through the street");
        assert_eq!(hidden, behind.len(), "{what}: splats behind the mesh hidden");
        assert_eq!(kept, front.len(), "{what}: splats in front of the mesh kept");
    }
    for s in if case.timeline { vec![ready] } else { vec![ready, done] } {
        h.destroy_semaphore(s);
    }
    h.destroy_image(colour);
    h.destroy_image(depth);
}

#[test]
fn relit_frames_land_in_the_hosts_images_composited_by_depth() {
    let h = host(true);
    {
        // SAFETY: the host's handles belong together and outlive srug's device.
        let shared = unsafe { Device::from_raw(h.raw()) }.unwrap();
        let i = inputs(&shared);
        let mut relighter = Relighter::new(&shared).unwrap();
        let cases = [
            Case { format: HostImageFormat::Rgba8Srgb, composite: true, timeline: false },
            Case { format: HostImageFormat::Bgra8Unorm, composite: true, timeline: true },
            Case { format: HostImageFormat::Rgba16Float, composite: true, timeline: false },
            Case { format: HostImageFormat::Rgba32Float, composite: true, timeline: true },
            Case { format: HostImageFormat::Rgba8Unorm, composite: false, timeline: false },
            Case { format: HostImageFormat::Rgba32Float, composite: false, timeline: true },
        ];
        for case in &cases {
            run_case(&h, &shared, &i, &mut relighter, case);
        }
        assert_no_validation_messages(&shared);
    }
    let heard = h.finish();
    assert!(heard.is_empty(), "the host's messenger heard: {heard:?}");
}

#[test]
fn misstated_host_images_and_semaphores_are_refused_by_name() {
    let d = srug_tests::device();
    let i = inputs(&d);
    let mut relighter = Relighter::new(&d).unwrap();
    let usage = vk::ImageUsageFlags::TRANSFER_SRC | vk::ImageUsageFlags::TRANSFER_DST;
    let image = |n: u64, format: vk::Format| HostImage {
        // Never touched: every statement here is refused before any work.
        image: vk::Handle::from_raw(n),
        format,
        width: SIZE.0,
        height: SIZE.1,
        usage,
        layout_before: vk::ImageLayout::GENERAL,
        layout_after: vk::ImageLayout::GENERAL,
    };
    let good = HostTargets {
        colour: Some(image(1, vk::Format::R8G8B8A8_SRGB)),
        depth: Some(image(2, vk::Format::D32_SFLOAT)),
        depth_convention: HostDepth::Vulkan { near: NEAR, far: FAR },
        composite: true,
        buffers: Vec::new(),
        sync: HostSync::default(),
    };
    let buffer = |size: u64, usage: vk::BufferUsageFlags| HostBuffer { buffer: vk::Handle::from_raw(3), size, usage };
    let colour = |f: &dyn Fn(&mut HostImage)| {
        let mut t = good.clone();
        f(t.colour.as_mut().unwrap());
        t
    };
    let cases: Vec<(HostTargets, &str)> = vec![
        (colour(&|c| c.format = vk::Format::R8_UNORM), "R8_UNORM"),
        (colour(&|c| c.format = vk::Format::D32_SFLOAT), "not a colour format"),
        (colour(&|c| c.width = 100), "does not match the rendered frame's 176x48"),
        (colour(&|c| c.usage = vk::ImageUsageFlags::TRANSFER_DST), "lacks usage TRANSFER_SRC"),
        (colour(&|c| c.image = vk::Image::null()), "VK_NULL_HANDLE"),
        (colour(&|c| c.layout_before = vk::ImageLayout::UNDEFINED), "nothing to read"),
        (colour(&|c| c.layout_after = vk::ImageLayout::UNDEFINED), "layout_after is UNDEFINED"),
        (colour(&|c| c.layout_after = vk::ImageLayout::DEPTH_STENCIL_ATTACHMENT_OPTIMAL), "does not suit"),
        (HostTargets { depth: Some(image(2, vk::Format::R8G8B8A8_UNORM)), ..good.clone() }, "not a depth format"),
        (HostTargets { depth: Some(image(1, vk::Format::D32_SFLOAT)), ..good.clone() }, "both colour and depth"),
        (HostTargets { colour: None, depth: None, ..good.clone() }, "name no image and no buffer"),
        (
            HostTargets {
                buffers: vec![(
                    FrameChannel::GBuffer(Channel::Normal),
                    buffer(100, vk::BufferUsageFlags::TRANSFER_DST),
                )],
                ..good.clone()
            },
            "holds 100 bytes, the frame's values 101376",
        ),
        (
            HostTargets {
                buffers: vec![(FrameChannel::Alpha, buffer(1 << 20, vk::BufferUsageFlags::TRANSFER_SRC))],
                ..good.clone()
            },
            "lacks usage TRANSFER_DST",
        ),
        (HostTargets { depth_convention: HostDepth::Vulkan { near: 0.0, far: FAR }, ..good.clone() }, "near 0"),
        (
            HostTargets {
                sync: HostSync {
                    wait: vec![SemaphoreWait { semaphore: vk::Semaphore::null(), value: 0 }],
                    signal: vec![],
                },
                ..good.clone()
            },
            "semaphore is VK_NULL_HANDLE",
        ),
    ];
    let settings = RelightSettings::default();
    for (targets, expected) in cases {
        let e = i.render_to_host(&mut relighter, &settings, &targets).err().map(|e| e.to_string()).unwrap_or_default();
        assert!(e.contains(expected), "expected \"{expected}\" in: {e}");
    }
    // The fast preset renders at half size: images of the camera's size do not fit it.
    let fast = RelightSettings::preset(srug::frame::Preset::Fast);
    let e = i.render_to_host(&mut relighter, &fast, &good).err().map(|e| e.to_string()).unwrap_or_default();
    assert!(e.contains("does not match the rendered frame's 88x24"), "{e}");
    assert_no_validation_messages(&d);
}

#[test]
fn frames_land_in_an_image_srug_made_on_its_own_device() {
    let d = srug_tests::device();
    let i = inputs(&d);
    let mut relighter = Relighter::new(&d).unwrap();
    let usage = vk::ImageUsageFlags::TRANSFER_SRC | vk::ImageUsageFlags::TRANSFER_DST;
    let image = d.create_image("target", HostImageFormat::Rgba32Float, SIZE, usage).unwrap();
    let targets = colour_only(image.host_image(vk::ImageLayout::UNDEFINED, vk::ImageLayout::TRANSFER_SRC_OPTIMAL));
    let settings = frame_settings();
    let frame = i.render_to_host(&mut relighter, &settings, &targets).unwrap();
    let texels = d.create_filled::<u32>("texels", SIZE.0 as usize * SIZE.1 as usize * 4, 0xffff_ffff).unwrap();
    let stated = image.host_image(vk::ImageLayout::TRANSFER_SRC_OPTIMAL, vk::ImageLayout::TRANSFER_SRC_OPTIMAL);
    d.run(|rec| rec.copy_host_image_to_buffer(&stated, stated.layout_before, &texels)).unwrap();
    let got: Vec<f32> = d.read_buffer(&texels).unwrap();
    assert_texels_are_the_frame(&d, &got, &frame);
    assert_no_validation_messages(&d);
}

/// srug on a device of its own (the separate-device path): it renders into
/// an image whose memory it exports as an opaque fd, releases it to
/// `VK_QUEUE_FAMILY_EXTERNAL`; the host imports the fd into an image on its
/// own device (another VkDevice and VkInstance), acquires it and reads the
/// frame back bit for bit. Semaphore export is refused by name where the
/// device lacks `VK_KHR_external_semaphore_fd` (lavapipe does).
#[test]
fn a_host_on_another_device_imports_the_frame_srug_exported() {
    let d = srug_tests::device();
    if !d.info().external_memory_fd {
        let e = d.create_exported_image(HostImageFormat::Rgba32Float, SIZE, vk::ImageUsageFlags::TRANSFER_DST).err();
        let e = e.map(|e| e.to_string()).unwrap_or_default();
        assert!(e.contains("VK_KHR_external_memory_fd"), "{e}");
        println!("skipped the import: {} does not offer VK_KHR_external_memory_fd", d.info().name);
        return;
    }
    let i = inputs(&d);
    let mut relighter = Relighter::new(&d).unwrap();
    let usage = vk::ImageUsageFlags::TRANSFER_SRC | vk::ImageUsageFlags::TRANSFER_DST;
    let exported = d.create_exported_image(HostImageFormat::Rgba32Float, SIZE, usage).unwrap();
    let general = vk::ImageLayout::GENERAL;
    let targets = colour_only(exported.host_image(vk::ImageLayout::UNDEFINED, general));
    let settings = frame_settings();
    let frame = i.render_to_host(&mut relighter, &settings, &targets).unwrap();
    let stated = exported.host_image(general, general);
    d.run(|rec| rec.transfer_host_image_external(&stated, general, false)).unwrap();
    let info = exported.info();
    let fd = exported.export_fd().unwrap();
    match d.create_exported_semaphore() {
        Ok(_) => println!("{} exports semaphores", d.info().name),
        Err(e) => assert!(e.to_string().contains("VK_KHR_external_semaphore_fd"), "{e}"),
    }
    assert_no_validation_messages(&d);

    let h = host(true);
    let mut ids = vk::PhysicalDeviceIDProperties::default();
    let mut props = vk::PhysicalDeviceProperties2::default().push_next(&mut ids);
    // SAFETY: valid physical device of the host's instance.
    unsafe { h.instance.get_physical_device_properties2(h.physical, &mut props) };
    assert_eq!((ids.device_uuid, ids.driver_uuid), (info.device_uuid, info.driver_uuid), "the same GPU and driver");
    let imported = h.import_image(fd, info.format.vk(), (info.width, info.height), info.usage, info.allocation_size);
    h.acquire_external(&imported, general);
    let bytes = h.download_image(&imported, SIZE.0 as usize * SIZE.1 as usize * 16, general, &[]);
    let got: Vec<f32> = bytemuck::pod_collect_to_vec(&bytes);
    assert_texels_are_the_frame(&d, &got, &frame);
    drop(exported);
    h.destroy_image(imported);
    let heard = h.finish();
    assert!(heard.is_empty(), "the host's messenger heard: {heard:?}");
    assert_no_validation_messages(&d);
}

/// A call that fails once it has read the host's images (here: a scene
/// without materials cannot be relit, found after the read) still signals
/// the host's semaphore and leaves its images unwritten in their
/// `layout_after`, so a host waiting on it does not hang.
#[test]
fn a_failed_call_still_signals_the_host_and_releases_its_images() {
    let h = host(true);
    {
        // SAFETY: the host's handles belong together and outlive srug's device.
        let shared = unsafe { Device::from_raw(h.raw()) }.unwrap();
        let mut i = inputs(&shared);
        let mut plain = i.scene.clone();
        plain.materials = srug::scene::Materials::default();
        i.gpu = GpuScene::upload(&shared, &plain).unwrap();
        let format = HostImageFormat::Rgba8Unorm;
        let usage = vk::ImageUsageFlags::TRANSFER_SRC | vk::ImageUsageFlags::TRANSFER_DST;
        let colour = h.create_image(format.vk(), SIZE, usage);
        let depth = h.create_image(vk::Format::D32_SFLOAT, SIZE, usage);
        let host_colour = host_colour_bytes(format);
        let host_depth: Vec<u8> = host_depth_values().iter().flat_map(|v| v.to_le_bytes()).collect();
        let timeline = h.semaphore(Some(0));
        let general = vk::ImageLayout::GENERAL;
        h.upload_image(&colour, &host_colour, general, &[]);
        h.upload_image(&depth, &host_depth, general, &[(timeline, 1)]);
        let stated = |image: &OwnImage, format: vk::Format| HostImage {
            image: image.image,
            format,
            width: SIZE.0,
            height: SIZE.1,
            usage,
            layout_before: general,
            layout_after: vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
        };
        let targets = HostTargets {
            colour: Some(stated(&colour, format.vk())),
            depth: Some(stated(&depth, vk::Format::D32_SFLOAT)),
            depth_convention: HostDepth::Vulkan { near: NEAR, far: FAR },
            composite: true,
            buffers: Vec::new(),
            sync: HostSync {
                wait: vec![SemaphoreWait { semaphore: timeline, value: 1 }],
                signal: vec![SemaphoreSignal { semaphore: timeline, value: 2 }],
            },
        };
        let mut relighter = Relighter::new(&shared).unwrap();
        let e = i.render_to_host(&mut relighter, &RelightSettings::default(), &targets).err();
        let e = e.map(|e| e.to_string()).unwrap_or_default();
        assert!(e.contains("albedo"), "{e}");
        assert!(h.wait_timeline(timeline, 2, 10_000_000_000), "the host's semaphore was never signalled");
        let after = vk::ImageLayout::TRANSFER_SRC_OPTIMAL;
        assert_eq!(h.download_image(&colour, host_colour.len(), after, &[]), host_colour, "colour written");
        assert_eq!(h.download_image(&depth, host_depth.len(), after, &[]), host_depth, "depth written");
        assert_no_validation_messages(&shared);
        h.destroy_semaphore(timeline);
        h.destroy_image(colour);
        h.destroy_image(depth);
    }
    let heard = h.finish();
    assert!(heard.is_empty(), "the host's messenger heard: {heard:?}");
}
