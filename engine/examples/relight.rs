//! Relights the demo city's first street camera under a west-south-west sun
//! and a procedural sky, and writes `relit.png`: the README's Rust example.
//!
//! `cargo run --release -p srug --example relight`

use srug::frame::{Preset, RelightSettings, Relighter};
use srug::gpu::{Device, DeviceOptions};
use srug::scene::{activate::GpuScene, demo};
use srug::shade::{BrdfLut, EnvironmentPrep, PrepareSettings, ProceduralSky};
use srug::shadow::Sun;

fn main() -> srug::Result<()> {
    let device = Device::new(&DeviceOptions::default())?;
    // Or a trained scene and its cameras: srug::io::read_ply(path)?, srug::io::read_cameras_json(path)?.
    let city = demo::demo_city(&demo::DemoOptions { gaussians: 50_000, ..Default::default() })?;
    let (scene, camera) = (&city.scene, &city.cameras[0]);
    let gpu_scene = GpuScene::upload(&device, scene)?;

    let sun = Sun::from_azimuth_elevation(260.0, 50.0, [std::f32::consts::PI; 3])?;
    let prep = EnvironmentPrep::new(&device)?;
    let sky =
        prep.prepare(&ProceduralSky::new(sun.direction, sun.intensity[0]).render()?, &PrepareSettings::default())?;
    let brdf = prep.brdf_table(BrdfLut::Karis, 129, 1024)?;

    let mut relighter = Relighter::new(&device)?;
    let settings = RelightSettings::preset(Preset::Balanced);
    let bounds = scene.bounds().ok_or_else(|| srug::Error::invalid("scene", "is empty"))?;
    let frame =
        relighter.render(&gpu_scene, &scene.attributes(), &bounds, camera, Some(&sun), &sky, &brdf, &settings)?;
    let image = frame.shaded.read(&device)?;
    srug::io::write_png("relit.png", image.width, image.height, &image.display)?;
    println!("relit.png: {} ms GPU", (frame.timings.total_seconds() * 1e3).round());
    Ok(())
}
