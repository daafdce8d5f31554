//! Only what a scene requires runs, and `srug::frame::plan` says so before it runs:
//! the plan's decisions are checked against what the renderer dispatched
//! (every dispatch is inside a timed stage, so the stage names list them).

#![allow(clippy::unwrap_used, clippy::expect_used, reason = "test code: a failure should stop the test")]

use srug::frame::plan::{plan_frame, PlanSettings};
use srug::frame::{RelightSettings, Relighter};
use srug::indirect::{StoragePrecision, UNet, UNetConfig, UNetWeights};
use srug::scene::activate::GpuScene;
use srug::scene::demo::{demo_city, DemoOptions};
use srug::shade::{BrdfLut, EnvironmentPrep, PrepareSettings, ProceduralSky};
use srug::shadow::Sun;
use srug::splat::{BlendVariant, Channels, Splatter};
use srug_tests::{assert_no_validation_messages, device};

#[test]
fn plan_matches_what_runs_and_nothing_unneeded_runs() {
    let d = device();
    let city = demo_city(&DemoOptions { seed: 4, gaussians: 5000, sh_degree: 1 }).unwrap();
    let camera = city.cameras[0].resized(176, 48);
    let gpu = GpuScene::upload(&d, &city.scene).unwrap();
    let bounds = city.scene.bounds().unwrap();
    let attributes = city.scene.attributes();
    let prep = EnvironmentPrep::new(&d).unwrap();
    let brdf = prep.brdf_table(BrdfLut::Karis, 33, 64).unwrap();
    let small = PrepareSettings { samples: 16, ..PrepareSettings::default() };
    let mut relighter = Relighter::new(&d).unwrap();
    let blend = Splatter::new(&d).unwrap().blend_variant();
    let config = UNetConfig { widths: [8, 8, 8, 8, 8], ..UNetConfig::default() };
    let weights = UNetWeights::random(config.clone(), 3);
    let mut settings = RelightSettings::default();
    settings.shadow.resolution = 256;
    settings.extra_channels = Channels { depth: true, ..Channels::default() };

    let sun_up = Sun::from_azimuth_elevation(250.0, 40.0, [3.0; 3]).unwrap();
    let sun_down = Sun::from_azimuth_elevation(250.0, -5.0, [3.0; 3]).unwrap();
    for (sun, network) in [(Some(sun_up), false), (Some(sun_down), false), (None, true), (Some(sun_up), true)] {
        let plan = plan_frame(
            &city.scene,
            &PlanSettings {
                width: camera.width,
                height: camera.height,
                sun,
                relight: settings,
                network: network.then_some((&config, StoragePrecision::Fp32)),
                blend,
            },
        )
        .unwrap();
        relighter.set_network(network.then(|| UNet::new(&d, &weights).unwrap()));
        let sky = ProceduralSky::new(sun.map_or(sun_up.direction, |s| s.direction), 3.0).render().unwrap();
        let env = prep.prepare(&sky, &small).unwrap();
        let relit =
            relighter.render(&gpu, &attributes, &bounds, &camera, sun.as_ref(), &env, &brdf, &settings).unwrap();
        let names: Vec<&str> = relit.timings.stages.iter().map(|s| s.name.as_str()).collect();
        let label = format!("sun {:?}, network {network}: stages {names:?}\n{}", sun.map(|s| s.direction), plan.text());
        println!("{label}");
        let has = |part: &str| names.iter().any(|n| n.contains(part));

        let above = sun.is_some_and(|s| s.above_horizon());
        assert!(plan.decisions.shading, "{label}");
        assert_eq!(plan.decisions.shadow_pass, above, "{label}");
        assert_eq!(relit.shadow_pass_ran, above, "{label}");
        assert_eq!(has("shadow"), above, "shadow stages iff a sun is up: {label}");
        assert_eq!(plan.stages.iter().any(|s| s.name.contains("shadow")), above, "{label}");
        // The shadow-map splat says when a sequence can skip it (Relighter::set_shadow_map_reuse).
        let map_note = plan.stages.iter().find(|s| s.name == "splat (shadow map)").map(|s| s.note.as_str());
        assert_eq!(map_note.is_some_and(|n| n.contains("shadow-map reuse")), above, "{label}");
        // The shadow map blends depth and alpha, no colour; the camera splat blends colour.
        let kernels = |name: &str| plan.stages.iter().find(|s| s.name == name).map(|s| s.kernels.clone());
        // The presets' depths: surface depths for the camera (the receivers), centre for the map.
        if let Some(k) = kernels("splat (shadow map)") {
            assert!(k.contains("alpha") && !k.contains("rgb") && k.contains("centre depths"), "{k}");
        }
        let camera = kernels("splat (camera)");
        assert!(camera.is_some_and(|k| k.contains("rgb, alpha") && k.contains("surface depths")), "{label}");
        if let Some(k) = kernels("sigmoid shadow test") {
            assert!(k.contains("filter pcf") && k.contains("bias = 0.8 m + 3 texels"), "{k}");
        }
        assert!(has("shade lights") && has("shade compose"), "{label}");
        assert_eq!(has("indirect input"), network, "inference iff weights: {label}");
        assert_eq!(plan.stages.iter().any(|s| s.name.contains("U-Net")), network, "{label}");
        assert_eq!(relit.shaded.indirect.is_some(), network, "{label}");

        // The G-buffer holds exactly the planned channels.
        let g = &relit.gbuffer;
        let made = g.channels.present();
        assert_eq!(made, plan.decisions.channels, "{label}");
        assert!(made.depth, "the extra channel asked for is there");
        assert!(plan.stages[0].bytes >= g.bytes(), "the camera stage's known bytes cover its G-buffer: {label}");
    }

    // Without materials: the plan shades nothing, and the relighter refuses rather than shade.
    let mut plain = city.scene.clone();
    plain.materials = srug::scene::Materials::default();
    let plan = plan_frame(
        &plain,
        &PlanSettings {
            width: 176,
            height: 48,
            sun: Some(sun_up),
            relight: settings,
            network: Some((&config, StoragePrecision::Fp32)),
            blend: BlendVariant::PerPixel,
        },
    )
    .unwrap();
    assert!(!plan.decisions.shading && !plan.decisions.shadow_pass, "{}", plan.text());
    assert_eq!(plan.stages.len(), 1, "only the splat runs:\n{}", plan.text());
    assert!(plan.skipped.iter().any(|s| s.contains("no albedo")), "{}", plan.text());
    assert_eq!(plan.decisions.channels, settings.extra_channels);
    assert_no_validation_messages(&d);
}
