//! A shadow map splatted only where its receivers look
//! (`ShadowPass::shadow_map_for_receivers`, `ShadowSettings::cull_to_receivers`):
//! the receivers' visibility, sigmoid and traced, is the whole map's bit for
//! bit, with the bias offsets on and off and for several cameras at once;
//! every texel of the culled map is the whole map's or empty; it sorts fewer
//! pairs; and a relit frame with it equals one without, where the relighter
//! culls because it is asked to or because its map is not kept, and where a
//! batch of cameras shares one map culled to all of them.

#![allow(clippy::unwrap_used, clippy::expect_used, reason = "a failed unwrap is a failed test")]

use srug::frame::{RelightSettings, Relighter};
use srug::gpu::Device;
use srug::scene::activate::GpuScene;
use srug::scene::demo::{demo_city, DemoOptions};
use srug::scene::Camera;
use srug::shade::{BrdfLut, EnvironmentPrep, PrepareSettings, ProceduralSky};
use srug::shadow::{ShadowFit, ShadowPass, ShadowSettings, Sun, VisibilityKind};
use srug::splat::{Channel, Splatter};
use srug_tests::{assert_no_validation_messages, device};

fn read(d: &Device, b: &srug::gpu::Buffer) -> Vec<f32> {
    d.read_buffer(b).unwrap()
}

/// The row-major tile, of `tile`-pixel tiles, holding pixel `i` of an image `width` pixels wide.
fn tile_of(i: usize, width: usize, tile: usize) -> usize {
    (i / width / tile) * width.div_ceil(tile) + (i % width) / tile
}

/// A split-blend chunk length short enough to split this test's map lists.
const SHORT_CHUNKS: u32 = 16;

#[test]
fn a_map_splatted_only_where_receivers_look_gives_them_the_same_visibility() {
    let d = device();
    let city = demo_city(&DemoOptions { seed: 5, gaussians: 20_000, sh_degree: 1 }).unwrap();
    let scene = GpuScene::upload(&d, &city.scene).unwrap();
    let bounds = city.scene.bounds().unwrap();
    let sun = Sun::from_azimuth_elevation(260.0, 35.0, [3.0; 3]).unwrap();
    let cameras: Vec<Camera> = city.cameras.iter().take(2).map(|c| c.resized(176, 48)).collect();
    let pass = ShadowPass::new(&d).unwrap();
    let mut splatter = Splatter::new(&d).unwrap();
    let default_chunks = splatter.chunk_length();
    // The last with the split blend's chunks short (on GPUs it is on by default): a
    // wanted tile's list is the same in both maps, so it splits the same way.
    for (settings, chunk_length) in [
        (ShadowSettings { resolution: 512, ..ShadowSettings::default() }, default_chunks),
        (ShadowSettings { resolution: 512, normal_offset: 3.0, tile: 8, ..ShadowSettings::default() }, default_chunks),
        (ShadowSettings { resolution: 512, ..ShadowSettings::default() }, SHORT_CHUNKS),
    ] {
        splatter.set_chunk_length(chunk_length).unwrap();
        let receivers: Vec<_> = cameras
            .iter()
            .map(|c| splatter.render_frame(&scene, c, &settings.receiver_splat()).unwrap().gbuffer)
            .collect();
        let whole = pass.shadow_map(&mut splatter, &scene, &bounds, &sun, &settings, None).unwrap().unwrap();
        let pairs: Vec<_> = receivers.iter().zip(&cameras).collect();
        for chosen in [&pairs[..1], &pairs[..]] {
            let culled = pass
                .shadow_map_for_receivers(&mut splatter, &scene, whole.camera.clone(), &sun, &settings, chosen)
                .unwrap();
            let label = format!(
                "{} camera(s), normal offset {}, tile {}, chunks of {chunk_length}",
                chosen.len(),
                settings.normal_offset,
                settings.tile
            );
            assert!(culled.frame.stats.pairs < whole.frame.stats.pairs, "{label}: no pairs saved");
            // Short chunks split this scene's lists; the device's default may split
            // none of them (on GPUs: 1024 entries, lists past 2048), or is off.
            let chunks = [culled.frame.stats.chunks, whole.frame.stats.chunks];
            if chunk_length == 0 {
                assert_eq!(chunks, [0, 0], "{label}: lists split with splitting off");
            } else if chunk_length == SHORT_CHUNKS {
                assert!(chunks.iter().all(|&c| c > 0), "{label}: lists not split: {chunks:?}");
            }
            println!("{label}: {} of {} map pairs", culled.frame.stats.pairs, whole.frame.stats.pairs);
            for (g, camera) in chosen {
                for kind in [VisibilityKind::Sigmoid, VisibilityKind::Traced] {
                    let (a, _) = pass.visibility(&whole, g, camera, &settings, kind).unwrap();
                    let (b, _) = pass.visibility(&culled, g, camera, &settings, kind).unwrap();
                    let (a, b) = (read(&d, &a), read(&d, &b));
                    assert!(a.iter().map(|v| v.to_bits()).eq(b.iter().map(|v| v.to_bits())), "{label}, {kind:?}");
                    assert!(a.iter().any(|v| *v < 0.5), "{label}: the view has shadow");
                }
            }
            // Every texel of a wanted tile is the whole map's, or empty; the
            // others were not splatted, and read_depth gives them empty.
            let wanted: Vec<u32> = d.read_buffer(culled.wanted_tiles.as_ref().unwrap()).unwrap();
            let (w, tile) = (culled.camera.width as usize, settings.tile as usize);
            let (wa, ca) = (read(&d, &whole.frame.gbuffer.alpha), read(&d, &culled.frame.gbuffer.alpha));
            let depth = |m: &srug::shadow::ShadowMap| read(&d, m.frame.gbuffer.get(Channel::MedianDepth).unwrap());
            let (wd, cd) = (depth(&whole), depth(&culled));
            let (wz, cz) =
                (whole.read_depth(&d, settings.min_alpha).unwrap(), culled.read_depth(&d, settings.min_alpha).unwrap());
            let empty = settings.map_depth.empty_depth(culled.camera.far);
            let mut kept = 0;
            for i in 0..wa.len() {
                if wanted[tile_of(i, w, tile)] == 0 {
                    assert_eq!(cz[i], empty, "{label}: texel {i} of a tile not splatted");
                    continue;
                }
                let same = wa[i].to_bits() == ca[i].to_bits() && wd[i].to_bits() == cd[i].to_bits();
                assert!(same || (ca[i] == 0.0 && cd[i] == 0.0), "{label}: texel {i}");
                assert!(cz[i].to_bits() == wz[i].to_bits() || cz[i] == empty, "{label}: depth of texel {i}");
                kept += usize::from(same && wa[i] > 0.0);
            }
            assert!(kept > 0, "{label}: no covered texel kept");
            assert!(wanted.contains(&0), "{label}: every map tile wanted: nothing culled");
        }
    }

    // The splat in tiles leaves the other tiles' pixels as they were (a NaN
    // prefill here) and writes every pixel of the wanted ones as the whole render.
    let camera = cameras[0].clone();
    let settings = srug::splat::SplatSettings { prefill: Some(srug_tests::NAN_SENTINEL), ..Default::default() };
    let tiles_x = camera.width.div_ceil(settings.tile) as usize;
    let tiles = tiles_x * camera.height.div_ceil(settings.tile) as usize;
    let wanted: Vec<u32> = (0..tiles).map(|t| u32::from(t % 3 != 1)).collect();
    let mask = d.upload("tile mask", &wanted).unwrap();
    let full = read(&d, &splatter.render_frame(&scene, &camera, &settings).unwrap().gbuffer.alpha);
    let part = read(&d, &splatter.render_frame_in_tiles(&scene, &camera, &settings, &mask).unwrap().gbuffer.alpha);
    let (w, tile) = (camera.width as usize, settings.tile as usize);
    for (i, (f, p)) in full.iter().zip(&part).enumerate() {
        if wanted[tile_of(i, w, tile)] == 0 {
            assert!(p.is_nan(), "pixel {i} of a tile not wanted was written");
        } else {
            assert!(p.to_bits() == f.to_bits() || (*p == 0.0 && !f.is_nan()), "pixel {i}: {p} against {f}");
        }
    }
    assert!(full.iter().zip(&part).any(|(f, p)| *f > 0.0 && f.to_bits() == p.to_bits()), "no covered pixel kept");

    // Through the relighter: the same relit frame with the whole map (kept:
    // reuse on), with culling asked for, and culled by itself (reuse off).
    let prep = EnvironmentPrep::new(&d).unwrap();
    let sky = ProceduralSky::new(sun.direction, 3.0).render().unwrap();
    let env = prep.prepare(&sky, &PrepareSettings { samples: 16, ..PrepareSettings::default() }).unwrap();
    let brdf = prep.brdf_table(BrdfLut::Karis, 33, 64).unwrap();
    let attributes = city.scene.attributes();
    let mut frames = Vec::new();
    for (reuse, cull, culled) in [(true, false, false), (true, true, true), (false, false, true)] {
        let mut relighter = Relighter::new(&d).unwrap();
        relighter.set_shadow_map_reuse(reuse);
        let mut settings = RelightSettings::default();
        settings.shadow.cull_to_receivers = cull;
        let f =
            relighter.render(&scene, &attributes, &bounds, &cameras[0], Some(&sun), &env, &brdf, &settings).unwrap();
        assert!(f.shadow_pass_ran);
        let label = format!("reuse {reuse}, cull {cull}");
        assert_eq!(f.timings.get("shadow map receiver tiles").is_some(), culled, "{label}");
        frames.push((read(&d, &f.shaded.radiance), read(&d, f.visibility.as_ref().unwrap())));
    }
    assert!(frames[0] == frames[2], "the map culled by itself relights the frame differently");
    assert!(frames[0] == frames[1], "the culled map relights the frame differently");
    assert_no_validation_messages(&d);
}

/// A tile mask bounds the preprocess's position cull (the wanted tiles' bounds,
/// then each tile row's wanted columns): with compacted records, a mask wanting
/// one corner block of tiles, or two opposite corner tiles, keeps records for
/// the Gaussians near them alone, far fewer than the frame without a mask, and
/// the wanted tiles' pixels are the whole render's bit for bit; a mask wanting no
/// tile keeps no record and lists no pair.
#[test]
fn a_tile_mask_bounds_the_position_cull() {
    let d = device();
    let city = demo_city(&DemoOptions { seed: 5, gaussians: 20_000, sh_degree: 1 }).unwrap();
    let scene = GpuScene::upload(&d, &city.scene).unwrap();
    let camera = city.cameras[0].resized(176, 48);
    let mut splatter = Splatter::new(&d).unwrap();
    let settings = srug::splat::SplatSettings {
        prefill: Some(srug_tests::NAN_SENTINEL),
        compact_splats: true,
        ..Default::default()
    };
    let tiles_x = camera.width.div_ceil(settings.tile) as usize;
    let tiles = tiles_x * camera.height.div_ceil(settings.tile) as usize;
    let full = splatter.render_frame(&scene, &camera, &settings).unwrap();
    let all = full.stats.records;
    let (w, tile) = (camera.width as usize, settings.tile as usize);
    let f = read(&d, &full.gbuffer.alpha);
    // The 3 × 2 tiles at the top left (11 × 3 in all); two opposite corner tiles,
    // whose bounds are the whole image but each tile row's wanted columns one tile.
    let block: Vec<u32> = (0..tiles).map(|t| u32::from(t % tiles_x < 3 && t / tiles_x < 2)).collect();
    let corners: Vec<u32> = (0..tiles).map(|t| u32::from(t == 0 || t == tiles - 1)).collect();
    for (label, wanted) in [("corner block", block), ("two corner tiles", corners)] {
        let mask = d.upload("tile mask", &wanted).unwrap();
        let part = splatter.render_frame_in_tiles(&scene, &camera, &settings, &mask).unwrap();
        let records = part.stats.records;
        println!("{label}: {records} of {all} records, {} of {} pairs", part.stats.pairs, full.stats.pairs);
        assert!(records > 0 && records * 2 < all, "{label}: {records} of {all} records kept");
        let p = read(&d, &part.gbuffer.alpha);
        for (i, (f, p)) in f.iter().zip(&p).enumerate() {
            if wanted[tile_of(i, w, tile)] == 0 {
                assert!(p.is_nan(), "{label}: pixel {i} of a tile not wanted was written");
            } else {
                assert_eq!(p.to_bits(), f.to_bits(), "{label}: pixel {i}");
            }
        }
        let kept = f.iter().zip(&p).any(|(f, p)| *f > 0.0 && f.to_bits() == p.to_bits());
        assert!(kept, "{label}: no covered pixel kept");
    }
    let none = d.upload("empty tile mask", &vec![0u32; tiles]).unwrap();
    let empty = splatter.render_frame_in_tiles(&scene, &camera, &settings, &none).unwrap();
    assert_eq!((empty.stats.records, empty.stats.pairs), (0, 0), "a mask wanting no tile");
    assert_no_validation_messages(&d);
}

#[test]
fn a_batch_shares_one_map_culled_to_all_its_cameras() {
    let d = device();
    let city = demo_city(&DemoOptions { seed: 5, gaussians: 20_000, sh_degree: 1 }).unwrap();
    let scene = GpuScene::upload(&d, &city.scene).unwrap();
    let bounds = city.scene.bounds().unwrap();
    let sun = Sun::from_azimuth_elevation(260.0, 35.0, [3.0; 3]).unwrap();
    let cameras: Vec<Camera> = city.cameras.iter().take(3).map(|c| c.resized(176, 48)).collect();
    let prep = EnvironmentPrep::new(&d).unwrap();
    let sky = ProceduralSky::new(sun.direction, 3.0).render().unwrap();
    let env = prep.prepare(&sky, &PrepareSettings { samples: 16, ..PrepareSettings::default() }).unwrap();
    let brdf = prep.brdf_table(BrdfLut::Karis, 33, 64).unwrap();
    let attributes = city.scene.attributes();
    let batch = |cull: bool, fit: ShadowFit| {
        let mut relighter = Relighter::new(&d).unwrap();
        let mut settings = RelightSettings::default();
        settings.shadow.cull_to_receivers = cull;
        settings.shadow.fit = fit;
        let frames =
            relighter.render_batch(&scene, &attributes, &bounds, &cameras, Some(&sun), &env, &brdf, &settings).unwrap();
        assert_eq!(frames.len(), cameras.len());
        frames
            .iter()
            .map(|f| {
                assert!(f.shadow_pass_ran);
                let culled = f.timings.get("shadow map receiver tiles").is_some();
                let splatted = f.timings.stages.iter().any(|s| s.name.starts_with("shadow map"));
                let pixels = (read(&d, &f.shaded.radiance), read(&d, f.visibility.as_ref().unwrap()));
                (pixels, f.shadow_map_reused, splatted, culled)
            })
            .collect::<Vec<_>>()
    };
    let whole = batch(false, ShadowFit::SceneBounds);
    let culled = batch(true, ShadowFit::SceneBounds);
    // One map for the batch, culled to where all three cameras look: splatted
    // with the first frame (its stages in that frame's timings), reused by the others.
    let flags: Vec<_> = culled.iter().map(|(_, reused, splatted, culled)| (*reused, *splatted, *culled)).collect();
    assert_eq!(flags, [(false, true, true), (true, false, false), (true, false, false)]);
    assert_eq!(whole.iter().map(|w| (w.1, w.3)).collect::<Vec<_>>(), [(false, false), (true, false), (true, false)]);
    for (i, (w, c)) in whole.iter().zip(&culled).enumerate() {
        assert!(w.0 == c.0, "camera {i}: the batch's culled map relights the frame differently");
    }
    // Fitted to each view, each camera's map is its own, culled to its own receivers.
    let fitted = batch(true, ShadowFit::ViewFrustum);
    let flags: Vec<_> = fitted.iter().map(|(_, reused, splatted, culled)| (*reused, *splatted, *culled)).collect();
    assert_eq!(flags, [(false, true, true); 3]);
    let fitted_alone = batch(false, ShadowFit::ViewFrustum);
    for (i, (a, c)) in fitted_alone.iter().zip(&fitted).enumerate() {
        assert!(a.0 == c.0, "camera {i}: a view-fitted map culled to its receivers relights differently");
    }
    assert_no_validation_messages(&d);
}
