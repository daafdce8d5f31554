//! The C API as C programs use it: `tests/c/*.c` built with
//! `cc -std=c11 -Wall -Wextra -Werror -pedantic` and AddressSanitizer (with
//! leak detection) and UBSan, linked against `libsrug_c.so`, and run. The
//! rendered demo frame must equal the Rust API's, byte for byte.

#![allow(clippy::unwrap_used, clippy::expect_used, reason = "test code: a failure should stop the test")]

use std::path::{Path, PathBuf};
use std::process::Command;

use srug::frame::{RelightSettings, Relighter};
use srug::io::{read_ply, write_ply, PlyFormat};
use srug::scene::activate::GpuScene;
use srug::scene::demo::{demo_city, DemoOptions};
use srug::scene::Projection;
use srug::shade::{BrdfLut, EnvironmentPrep, PrepareSettings, ProceduralSky, ToneMap};
use srug::shadow::Sun;
use srug::splat::Channels;
use srug_tests::{assert_no_validation_messages, device};

/// Where cargo put the `libsrug_c.so` built with this test: beside this test binary in
/// `target/<profile>/deps` (the copy one level up is refreshed only by `cargo build`).
fn library_dir() -> PathBuf {
    let exe = std::env::current_exe().unwrap();
    let dir = exe.parent().unwrap().to_path_buf();
    assert!(dir.join("libsrug_c.so").exists(), "{} has no libsrug_c.so", dir.display());
    dir
}

/// Builds `tests/c/<name>.c` with warnings as errors and sanitizers.
fn build(name: &str, out_dir: &Path) -> PathBuf {
    build_with(name, out_dir, &[])
}

/// [`build`], linking `libs` too.
fn build_with(name: &str, out_dir: &Path, libs: &[&str]) -> PathBuf {
    let here = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let lib = library_dir();
    let exe = out_dir.join(name);
    let output = Command::new("cc")
        .args(["-std=c11", "-Wall", "-Wextra", "-Werror", "-pedantic", "-g", "-O1", "-fno-omit-frame-pointer"])
        .args(["-fsanitize=address,undefined", "-fno-sanitize-recover=undefined"])
        .arg("-I")
        .arg(here.join("include"))
        .arg(here.join("tests").join("c").join(format!("{name}.c")))
        .arg("-o")
        .arg(&exe)
        .arg(format!("-L{}", lib.display()))
        // DT_RPATH (not RUNPATH) wins over LD_LIBRARY_PATH, whose cargo-set entries
        // name target/<profile>, where a stale libsrug_c.so may lie.
        .arg(format!("-Wl,--disable-new-dtags,-rpath,{}", lib.display()))
        .args(["-lsrug_c", "-lpthread", "-lm", "-ldl"])
        .args(libs)
        .output()
        .expect("cannot run cc (Debian: apt-get install gcc)");
    assert!(
        output.status.success(),
        "cc failed for {name}.c:\n{}{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    );
    exe
}

/// Runs a test program under the sanitizers; returns its stdout.
fn run(exe: &Path, args: &[&Path]) -> String {
    let supp = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests").join("c").join("lsan.supp");
    let output = Command::new(exe)
        .args(args)
        .env("ASAN_OPTIONS", "detect_leaks=1:halt_on_error=1:abort_on_error=0")
        .env("LSAN_OPTIONS", format!("suppressions={}:print_suppressions=0", supp.display()))
        .env("UBSAN_OPTIONS", "print_stacktrace=1:halt_on_error=1")
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&output.stdout).to_string();
    let stderr = String::from_utf8_lossy(&output.stderr);
    println!("{stdout}");
    assert!(output.status.success(), "{} failed ({}):\n{stdout}\n{stderr}", exe.display(), output.status);
    assert!(!stderr.contains("Sanitizer"), "sanitizer report:\n{stderr}");
    stdout
}

fn demo_files(dir: &Path) -> (PathBuf, PathBuf) {
    let city = demo_city(&DemoOptions { seed: 7, gaussians: 20_000, sh_degree: 1 }).unwrap();
    let ply = dir.join("demo.ply");
    write_ply(&ply, &city.scene, PlyFormat::BinaryLittleEndian).unwrap();
    let cam = &city.cameras[0];
    let Projection::Pinhole { fx, fy, cx, cy } = cam.projection else { panic!("the demo camera is a pinhole") };
    let m = glam::Mat4::from_cols(
        cam.rotation.x_axis.extend(0.0),
        cam.rotation.y_axis.extend(0.0),
        cam.rotation.z_axis.extend(0.0),
        cam.position.extend(1.0),
    );
    let mut text = format!("{} {} {fx:e} {fy:e} {cx:e} {cy:e}\n", cam.width, cam.height);
    for v in m.to_cols_array() {
        text += &format!("{v:e} ");
    }
    text += &format!("\n{:e} {:e} 260 50\n", cam.near, cam.far);
    let camera = dir.join("camera.txt");
    std::fs::write(&camera, text).unwrap();
    srug::io::write_cameras_json(dir.join("cameras.json"), &city.cameras).unwrap();
    (ply, camera)
}

/// The frame `render.c` makes, through the Rust API.
fn rust_frame(ply: &Path) -> Vec<u8> {
    let d = device();
    let scene = read_ply(ply).unwrap();
    let city = demo_city(&DemoOptions { seed: 7, gaussians: 20_000, sh_degree: 1 }).unwrap();
    let camera = city.cameras[0].clone();
    let gpu = GpuScene::upload(&d, &scene).unwrap();
    let sun = Sun::from_azimuth_elevation(260.0, 50.0, [std::f32::consts::PI; 3]).unwrap();
    let prep = EnvironmentPrep::new(&d).unwrap();
    let brdf = prep.brdf_table(BrdfLut::Karis, 129, 1024).unwrap();
    let mut sky = ProceduralSky::new(sun.direction, sun.intensity[0]);
    sky.turbidity = 3.0;
    let env = prep.prepare(&sky.render().unwrap(), &PrepareSettings::default()).unwrap();
    let mut settings = RelightSettings::default();
    (settings.shadow.bias, settings.shadow.slope_bias) = (0.8, 3.0);
    settings.shadow.receiver_depth = srug::shadow::DepthMode::Median;
    settings.shade.tone_map = ToneMap::Aces;
    settings.extra_channels = Channels { depth: true, normal: true, ..Channels::default() };
    let mut relighter = Relighter::new(&d).unwrap();
    let relit = relighter
        .render(&gpu, &scene.attributes(), &scene.bounds().unwrap(), &camera, Some(&sun), &env, &brdf, &settings)
        .unwrap();
    assert!(relit.shadow_pass_ran);
    let display: Vec<f32> = d.read_buffer(&relit.shaded.display).unwrap();
    let alpha: Vec<f32> = d.read_buffer(&relit.gbuffer.alpha).unwrap();
    assert_no_validation_messages(&d);
    display.chunks_exact(3).zip(&alpha).flat_map(|(c, a)| [c[0], c[1], c[2], *a]).map(srug::io::display_byte).collect()
}

#[test]
fn c_program_renders_the_demo_like_the_rust_api() {
    let dir = tempfile::tempdir().unwrap();
    let (ply, camera) = demo_files(dir.path());
    let exe = build("render", dir.path());
    let out = dir.path().join("frame.rgba");
    run(&exe, &[&ply, &camera, &out, &dir.path().join("cameras.json")]);
    let c_frame = std::fs::read(&out).unwrap();
    let rust = rust_frame(&ply);
    assert_eq!(c_frame.len(), rust.len(), "frame sizes");
    let differing = c_frame.iter().zip(&rust).filter(|(a, b)| a != b).count();
    if differing > 0 {
        let f = |b: &[u8]| b.chunks_exact(4).flat_map(|p| [p[0], p[1], p[2]]).map(|v| f32::from(v) / 255.0).collect();
        let (c, r): (Vec<f32>, Vec<f32>) = (f(&c_frame), f(&rust));
        let at = srug_tests::save_comparison("c_api_frame", 704, 192, 3, &c, &r);
        println!("C frame (gpu), Rust frame (cpu) and difference saved to {at}");
    }
    // Same kernels, same inputs, same device: identical bytes.
    assert_eq!(differing, 0, "{differing} of {} bytes differ from the Rust API's frame", rust.len());
    let lit = rust.chunks_exact(4).filter(|p| p[0] > 0 || p[1] > 0 || p[2] > 0).count();
    assert!(lit > rust.len() / 8, "the frame is mostly black ({lit} lit pixels)");
}

#[test]
fn c_host_program_lends_srug_its_vulkan_device() {
    let dir = tempfile::tempdir().unwrap();
    let exe = build_with("host", dir.path(), &["-lvulkan"]);
    let out = run(&exe, &[]);
    assert!(out.contains("srug's frame equals its own device's; host messenger heard 0 message(s)"), "{out}");
    assert!(out.contains("SRUG_ERROR_NO_DEVICE") && out.contains("bufferDeviceAddress"), "{out}");
}

#[test]
fn c_host_program_composites_srug_over_its_rasterized_mesh_in_its_own_images() {
    let dir = tempfile::tempdir().unwrap();
    // Debian's shaderc archives, users before what they use (as spirv/shaderc-link links them).
    let shaderc = [
        "-lshaderc_combined",
        "-lglslang",
        "-lMachineIndependent",
        "-lOSDependent",
        "-lGenericCodeGen",
        "-lOGLCompiler",
        "-lSPIRV",
        "-lglslang-default-resource-limits",
        "-lSPIRV-Tools-opt",
        "-lSPIRV-Tools",
        "-lstdc++",
    ];
    let exe = build_with("composite", dir.path(), &[&["-lvulkan"][..], &shaderc].concat());
    let ppm = dir.path().join("composite.ppm");
    let out = run(&exe, &[&ppm]);
    assert!(out.contains("composite: 100 frames of 256x96, worst PSNR"), "{out}");
    assert!(out.contains("host messenger heard 0 message(s)"), "{out}");
    assert!(out.contains("SRUG_ERROR_INVALID_ARGUMENT"), "{out}");
    if let Ok(at) = std::env::var("SRUG_COMPOSITE_PPM") {
        std::fs::copy(&ppm, at).unwrap();
    }
}

#[test]
fn c_host_on_its_own_device_imports_the_frames_srug_exports() {
    let dir = tempfile::tempdir().unwrap();
    let exe = build_with("export", dir.path(), &["-lvulkan"]);
    let out = run(&exe, &[]);
    assert!(out.contains("export: 4 frames imported into the host's device equal srug's"), "{out}");
    assert!(out.contains("host messenger heard 0 message(s)"), "{out}");
    assert!(out.contains("SRUG_ERROR_WRONG_ORDER") && out.contains("SRUG_ERROR_INVALID_ARGUMENT"), "{out}");
}

#[test]
fn c_program_gets_errors_for_every_misuse() {
    let dir = tempfile::tempdir().unwrap();
    let (ply, _) = demo_files(dir.path());
    let exe = build("misuse", dir.path());
    let stdout = run(&exe, &[&ply]);
    assert!(stdout.contains("misuse: ok"), "{stdout}");
    assert!(stdout.contains("SRUG_ERROR_INVALID_HANDLE"), "{stdout}");
}

#[test]
fn python_ctypes_example_renders_a_frame() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("frame.png");
    let script = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..").join("examples").join("render_frame.py");
    let output = Command::new("python3")
        .arg(&script)
        .arg("--library")
        .arg(library_dir().join("libsrug_c.so"))
        .args(["--gaussians", "5000", "--size", "352x96", "--out"])
        .arg(&out)
        .output()
        .expect("cannot run python3 (Debian: apt-get install python3)");
    let stdout = String::from_utf8_lossy(&output.stdout);
    println!("{stdout}");
    assert!(output.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&output.stderr));
    let img = image::open(&out).unwrap().to_rgba8();
    assert_eq!(img.dimensions(), (352, 96));
    let first = img.get_pixel(0, 0);
    let varied = img.pixels().filter(|p| *p != first).count();
    assert!(varied > 352 * 96 / 2, "the frame is nearly uniform ({varied} pixels differ from the first)");
    assert!(stdout.contains("covered pixels"), "{stdout}");
}

#[test]
fn minimal_example_links_against_the_static_library() {
    let dir = tempfile::tempdir().unwrap();
    let here = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let exe = dir.path().join("minimal");
    // The system libraries are what `cargo rustc -p srug-bindings --lib --crate-type staticlib
    // -- --print native-static-libs` lists.
    let output = Command::new("cc")
        .args(["-std=c11", "-Wall", "-Wextra", "-Werror", "-pedantic"])
        .arg("-I")
        .arg(here.join("include"))
        .arg(here.join("..").join("examples").join("minimal.c"))
        .arg(library_dir().join("libsrug_c.a"))
        .args(["-ldl", "-lgcc_s", "-lutil", "-lrt", "-lpthread", "-lm", "-o"])
        .arg(&exe)
        .output()
        .unwrap();
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let stdout = run(&exe, &[]);
    assert!(stdout.contains("rendered 352x96"), "{stdout}");
}
